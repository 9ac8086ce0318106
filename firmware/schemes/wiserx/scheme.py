"""WiSER-X (Jadhav et al., arXiv 2412.19876; ../shared/schemes/wiserx.md; issue 24) as a
scheme: coordination from UWB ranges and WiFi AoA bearings alone. Nothing goes on the
LoRa air, except in the `lora` variant (its dialect, records.py).

Per robot, in its own odometry frame:

- relsense task (10 Hz): the UWB and AoA samples into one track per teammate (relpos: the
  EKF behind the spec's bearing and range rules, silence-detected failure with revival);
  every insert_period_s this robot's own position and each freshly updated teammate
  estimate go into the hgrid (with omega = min(1, 1 / Tr Sigma)), and a teammate's tau
  follows its track's liveness;
- planning stage: every waypoint of the shared planner is a viewpoint. filter_waypoints
  evaluates I, I_0 and the loss ratio of eqs. (4)-(7) on the local map; from the soft fill
  on it drops the invalid ones (ratio > invalid_ratio), at the hard fill (if enabled) all of
  them, so the robot stops when none is left (the shared planner's end of exploration).
  rank gives each candidate its gain beta I (eqs. 2, 3) for the shared choice by gain per
  metre of path (U = beta I / C), and keeps the current target, alone, until the path
  left to it is commit_share of its first (commitment).

Variants: `complete` (default; the spec's fix of section 5.8: disc fill, 25 m^2 footprint,
soft 0.85, hard off; kappa1 = 0.8 r), `paper` (the authors' >= 2 points per cell, 5 m^2
footprint, soft 0.85, hard 0.95, kappa1 = r / 2), `blind` (the same code without relative sensing: beta = 1, no loss, fill from
own positions only; needs neither UWB nor AoA), `lora` (complete, plus wiserx.md 5.6's digest
over LoRa: every digest_period_s one record of 64 hgrid cells this robot filled by its own
positions, round robin; a teammate heard on LoRa at all, its heartbeat included, is alive,
and the cells it said it filled count as filled while it is; the spec's pseudo-points for
the loss term are not built).

Deviations from the paper, on purpose: viewpoints are the shared planner's waypoints
(reachable places with unknown in LiDAR view) rather than the centre and extremes of PCA-split
frontier clusters; C is the shared planner's path length (A14); without deployment knowledge
(services.deployment) the boundary is a fallback_boundary_m square round the start and every
cell counts.
"""
from __future__ import annotations

import math

import numpy as np

from firmware.scheduler import Task
from firmware.schemes.base import (PRIORITY_INFO, Candidate, OwnPlaces, PlanningView, Scheme, Services,
                                   cost_along_graph)
from firmware.schemes.wiserx import utility as U
from firmware.schemes.wiserx.hgrid import HGrid
from firmware.schemes.wiserx.params import WiserxParams
from firmware.schemes.wiserx.records import CELLS_PER_CHUNK, DIALECT, MAX_CHUNKS, cells_of_chunk, chunk_fields
from firmware.schemes.wiserx.relpos import COUNTERS, RelPos
from firmware.services.grid_paths import walls_crossed
from hal.samples import OdometrySample

RELSENSE_HZ = 10.0


class Wiserx(Scheme):
    name = "wiserx"
    doc = "WiSER-X: teammates located by UWB range and WiFi AoA alone, nothing sent over LoRa (but in `lora`)"
    variants = {
        "complete": "overlap loss from UWB/AoA teammate tracks; soft termination on a disc-filled hgrid over a "
                    "25 m2 footprint, no hard stop (the spec's fix)",
        "paper": "the paper's hgrid: >= 2 positions per cell over a 5 m2 footprint, soft 0.85 and hard 0.95",
        "blind": "the same without relative sensing (no loss, beta = 1, own positions only): the apples-to-apples "
                 "baseline",
        "lora": "complete, plus an 11-byte digest of the own filled hgrid cells over LoRa every 20 s: teammates out "
                "of UWB and WiFi reach stay alive and their fill counts",
    }
    default_variant = "complete"
    needs = frozenset({"uwb", "aoa"})
    params_type = WiserxParams
    dialect = DIALECT          # sent by the `lora` variant only

    @classmethod
    def default_params(cls, variant: str) -> WiserxParams:
        if variant == "paper":
            return WiserxParams.paper()
        if variant == "blind":
            return WiserxParams(relative_sensing=False)
        if variant == "lora":
            return WiserxParams(lora_digest=True)
        return WiserxParams()

    def __init__(self, variant: str = "", params: WiserxParams | None = None) -> None:
        super().__init__(variant)
        self.params = params if params is not None else self.default_params(self.variant)

    def needs_of(self) -> frozenset[str]:
        return (self.needs if self.params.relative_sensing else frozenset()) | \
            (frozenset({"radio"}) if self.params.lora_digest else frozenset())

    # --- setup ----------------------------------------------------------------------------
    def attach(self, services: Services) -> None:
        super().attach(services)
        p = self.params
        self._places = OwnPlaces(services)
        self.relpos = RelPos(services.robot_id, p)
        d = services.deployment
        if d is not None:
            self.hgrid = HGrid(services.robot_id, d.boundary_m, d.origin, p, d.navigable_m2, d.plan_cell_m)
        else:
            start = services.pose_at(0) or (0.0, 0.0, 0.0)
            half = 0.5 * p.fallback_boundary_m
            self.hgrid = HGrid(services.robot_id, (start[0] - half, start[1] - half, start[0] + half, start[1] + half),
                               (0.0, 0.0, 0.0), p)
        self._next_insert_us = 0
        self._now_us = 0
        self._info: dict[tuple[float, float], tuple[float, float]] = {}   # waypoint -> (I, I_0), last evaluated
        self._commit: tuple[tuple[float, float], float] | None = None     # target, its first path length
        self.fill = 0.0
        self.soft = self.hard = False
        self._first_us = {"soft": -1, "hard": -1, "finished": -1}
        self._count = {"waypoints_invalid": 0, "waypoints_dropped_hard": 0, "estimates_outside": 0,
                       "estimates_recorded": 0, "committed_cycles": 0, "digests_sent": 0, "digests_heard": 0,
                       "digests_other_grid": 0}
        self._next_chunk = 0

    def tasks(self) -> list[Task]:
        tasks = [Task("relsense", RELSENSE_HZ, self._relsense)]
        if self.params.lora_digest:
            tasks.append(Task("hgrid_digest", 1.0 / self.params.digest_period_s, self._send_digest))
        return tasks

    # --- sensing and recording ------------------------------------------------------------
    def _relsense(self, now_us: int) -> None:
        s, p = self.s, self.params
        ranges = s.uwb.ranges() if s.uwb is not None else ()
        bearings = s.aoa.bearings() if s.aoa is not None else ()
        if p.relative_sensing:
            self.relpos.feed(ranges, bearings, s.pose_at, self._walls_between() if p.nlos_from_map else None)
            if p.lora_digest:
                self._heard_on_lora()
            self.relpos.check_silence(now_us)
            for peer, track in self.relpos.tracks.items():
                self.hgrid.set_alive(peer, track.alive)
        if now_us >= self._next_insert_us:
            self._record(now_us)
            period_us = round(p.insert_period_s * 1e6)
            self._next_insert_us = (now_us // period_us + 1) * period_us

    def _walls_between(self):
        """walls_between(own_xy, other_xy) on the local map as it is now: the walls it shows
        on the straight line, up to the window's edge (A30)."""
        lm = self.s.local_map
        state = None

        def walls_between(a: tuple[float, float], b: tuple[float, float]) -> int:
            nonlocal state
            if state is None:
                state = lm.state_of(0, lm.n, 0, lm.n)
            (i0, j0), (i1, j1) = lm.cell_of(*a), lm.cell_of(*b)
            return walls_crossed(state, i0, j0, i1, j1)
        return walls_between

    # --- the LoRa digest (the `lora` variant, wiserx.md 5.6) --------------------------------
    def _heard_on_lora(self) -> None:
        """A teammate heard on LoRa (any frame: its heartbeat every 10 s, its digests) since
        its last UWB or AoA sample is alive: out of UWB and WiFi reach is not failed."""
        for peer, member in self.s.roster.members().items():
            track = self.relpos.track(peer)
            if track.heard_us is None or member.heard_us > track.heard_us:
                track.heard(member.heard_us)

    def _n_chunks(self) -> int:
        return min(MAX_CHUNKS, -(-self.hgrid.nx * self.hgrid.ny // CELLS_PER_CHUNK))

    def _send_digest(self, now_us: int) -> None:
        """One chunk of the cells this robot filled by its own positions, round robin."""
        if self.s.send is None:
            return
        chunk, n = self._next_chunk, self._n_chunks()
        self._next_chunk = (chunk + 1) % n
        values = {"sender_id": self.s.robot_id, "chunk": chunk, "chunks_m1": n - 1,
                  "done": int(self._first_us["finished"] >= 0), "fill_pct": int(round(100 * self.fill)),
                  **chunk_fields(self.hgrid.own_filled().ravel(), chunk)}
        if self.s.send("hgrid", values, PRIORITY_INFO, key=("hgrid", chunk)):
            self._count["digests_sent"] += 1

    def on_record(self, rtype: str, values, now_us: int) -> None:
        if rtype != "hgrid" or values["sender_id"] == self.s.robot_id:
            return
        if values["chunks_m1"] + 1 != self._n_chunks():
            self._count["digests_other_grid"] += 1      # a robot told of another boundary
            return
        self._count["digests_heard"] += 1
        self.hgrid.hear(values["sender_id"], cells_of_chunk(values["chunk"], values["bitmap_hi"], values["bitmap_lo"],
                                                            self.hgrid.nx * self.hgrid.ny))

    def has_news(self) -> bool:
        return bool(self.s.queued("hgrid")) if self.params.lora_digest else False

    def _record(self, now_us: int) -> None:
        """This robot's position, and each teammate's estimate updated within two insertion
        periods (A19), inside the boundary (A26)."""
        p = self.params
        own = self.s.pose_at(now_us)
        if own is None:
            return
        self.hgrid.insert(self.s.robot_id, own[0], own[1], 1.0, now_us)
        if not p.relative_sensing:
            return
        for e in self.relpos.estimates(now_us, 2.0 * p.insert_period_s):
            if not self.hgrid.inside(e.x_m, e.y_m, p.boundary_margin_m):
                self._count["estimates_outside"] += 1
                continue
            self.hgrid.insert(e.peer_id, e.x_m, e.y_m, U.weight(e.trace_m2), now_us)
            self._count["estimates_recorded"] += 1

    def on_travel(self, pose: OdometrySample, now_us: int) -> None:
        self._places.on_travel(pose)

    # --- the planning stage ---------------------------------------------------------------
    def _evaluate(self, view: PlanningView) -> None:
        """(I, I_0) of every waypoint inside the local window, on this cycle's map and loss;
        those outside keep what they had when last inside."""
        s, p = self.s, self.params
        items = s.waypoints.items
        if not items:
            return
        lm = s.local_map
        res = s.params.resolution_m
        xs = np.array([w.x_m for w in items])
        ys = np.array([w.y_m for w in items])
        ij, inside = lm.cells_of(np.column_stack([xs, ys]))
        if not inside.any():
            return
        blocks = U.UnknownBlocks.from_sight(view.sight, lm.row0, lm.col0, res, p.info_cell_m)
        loss = np.zeros(len(blocks.x_m))
        if p.relative_sensing and len(blocks.x_m):
            px, py, omega = self.hgrid.teammate_points()
            reach = U.loss_reach_m(p.kappa1_m, p.kappa2_m)
            near = (px >= blocks.x_m.min() - reach) & (px <= blocks.x_m.max() + reach) & \
                   (py >= blocks.y_m.min() - reach) & (py <= blocks.y_m.max() + reach)
            loss = U.block_loss(blocks, px[near], py[near], omega[near], p.kappa1_m, p.kappa2_m)
        info, info0 = U.information(blocks, loss, xs[inside], ys[inside], p.sensor_range_m, p.kappa1_m, p.kappa2_m)
        for k, i, i0 in zip(np.flatnonzero(inside), info, info0):
            self._info[(items[k].x_m, items[k].y_m)] = (float(i), float(i0))

    def _info_of(self, x_m: float, y_m: float, e_bit: float) -> tuple[float, float]:
        """(I, I_0) of a waypoint; one never evaluated (beyond the window since it was made)
        counts its unknown cells in view, with no loss."""
        got = self._info.get((x_m, y_m))
        if got is None:
            cells = e_bit / self.s.params.entropy_per_cell_bit
            got = (cells, cells)
        return got

    def filter_waypoints(self, view: PlanningView) -> None:
        p = self.params
        self._evaluate(view)
        self.fill = self.hgrid.fill()
        self.soft = self.fill >= p.soft_fill
        self.hard = p.hard_enabled and self.fill >= p.hard_fill
        for name, reached in (("soft", self.soft), ("hard", self.hard)):
            if reached and self._first_us[name] < 0:
                self._first_us[name] = view.now_us
        wp = self.s.waypoints
        if self.hard:
            self._count["waypoints_dropped_hard"] += len(wp.items)
            wp.items = []
        elif self.soft:
            keep = []
            for w in wp.items:
                info, info0 = self._info_of(w.x_m, w.y_m, w.e_bit)
                if float(U.loss_ratio(info, info0)) > p.invalid_ratio:
                    self._count["waypoints_invalid"] += 1
                else:
                    keep.append(w)
            wp.items = keep
        live = {(w.x_m, w.y_m) for w in wp.items}
        self._info = {k: v for k, v in self._info.items() if k in live}

    def rank(self, view: PlanningView, own: list[Candidate]) -> list[Candidate]:
        p = self.params
        cost_along_graph(view, own)
        if not own:
            return own
        est = self.relpos.estimates(view.now_us, p.fresh_s) if p.relative_sensing else []
        xs = np.array([c.x_m for c in own])
        ys = np.array([c.y_m for c in own])
        beta = U.proximity(xs, ys, np.array([e.x_m for e in est]), np.array([e.y_m for e in est]),
                           p.beta_min_distance_m)
        for c, b in zip(own, beta):
            c.gain = float(b) * self._info_of(c.x_m, c.y_m, c.e_bit)[0]
            c.rank = 0
        self._hold_target(view, own)
        return own

    def _hold_target(self, view: PlanningView, candidates: list[Candidate]) -> None:
        """Commitment: the current target alone is a candidate of the first rank until the
        path left to it is commit_share of its path when it was chosen."""
        t = view.target
        if t is None:
            self._commit = None
            return
        key = (t.x_m, t.y_m)
        if self._commit is None or self._commit[0] != key:
            self._commit = (key, t.cost_m)
        held = [c for c in candidates if (c.x_m, c.y_m) == key]
        if held and math.isfinite(t.cost_m) and t.cost_m > self.params.commit_share * self._commit[1]:
            for c in candidates:
                c.rank = 0 if c is held[0] else 1
            self._count["committed_cycles"] += 1

    def after_plan(self, pose: OdometrySample, now_us: int) -> None:
        self._now_us = now_us

    def on_finished(self, frontiers_left_xy: np.ndarray) -> None:
        if self._first_us["finished"] < 0:
            self._first_us["finished"] = self._now_us

    # --- for the host -----------------------------------------------------------------------
    def stats(self) -> dict[str, int]:
        counts = self.relpos.counts() if self.params.relative_sensing else dict.fromkeys(COUNTERS, 0)
        by_robot = self.hgrid.counts_by_robot()
        own = by_robot.get(self.s.robot_id, 0)
        return {**{f"uwb_aoa_{k}": v for k, v in counts.items()},
                **self._count,
                "hgrid_points_own": own, "hgrid_points_teammates": sum(by_robot.values()) - own,
                "hgrid_cells_footprint": int(self.hgrid.footprint.sum()),
                "hgrid_fill_permille": int(round(1000 * self.fill)),
                "soft_at_s": self._first_us["soft"] // 1_000_000 if self._first_us["soft"] >= 0 else -1,
                "hard_at_s": self._first_us["hard"] // 1_000_000 if self._first_us["hard"] >= 0 else -1,
                "stopped_at_s": self._first_us["finished"] // 1_000_000 if self._first_us["finished"] >= 0 else -1,
                "teammates_failed_now": sum(1 for t in self.relpos.tracks.values() if not t.alive)}

    def drawables(self) -> dict:
        x, y, robot, _, _ = self.hgrid.arrays()
        return {"title": "hgrid: own positions and teammates' estimates (red: teammates')",
                "points": np.column_stack([x, y]) if len(x) else np.zeros((0, 2)),
                "highlight": robot != self.s.robot_id, "what": "recorded positions"}
