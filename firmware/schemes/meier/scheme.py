"""Meier, Stachniss, Burgard (ECMR 2005) as a scheme: polygon maps under a split-rate budget,
target broadcast and utility discount (meier.md).

Variant `polygons` (the paper's scheme, over LoRa): every meier_update_s the robot's own map
is pooled into its monotone coarse raster (raster.CoarseRaster) and, unless all the robot
has sent is over meier_radio_share of what its link sustains, the polygon map follows its
boundary (tracker.PolygonTracker: the forced updates, and as many edge splits as the split
rate's token bucket and the budget hold, none while meier_backlog_max polygon records still
wait on the link), and the vertices it changed go out as `poly` records, the forced ones
first. A teammate that finds frames of this robot missing (gaps in the link's sequence
numbers) names them in `poly_nack` records, and this robot sends the polygon records they
carried again (not a repair lost in turn: the summaries find what that leaves);
what that cannot name (frames lost beyond the link's window, a request lost, the last frame
before a silence) the block summaries find: while nothing of its polygons waits, the robot
sends a `poly_sum` of one block of its vertex ids every meier_sum_period_s, and a teammate
whose copy differs names the parts in a `poly_ask`, which this robot answers with their
newest records; between changes a slow round robin re-sends live vertices and which ids
are alive.
Teammates' records build their polygon maps (replica.Replica, a pure function of the records
held), rasterised into a team layer that fills the cells this robot has not observed itself
(LocalMap.team): it plans on the combined map.

Variant `targets`: the coordination alone (the dense baseline adds dense maps to it for the
paper's comparison, `meier-full`).

Both: the robot broadcasts its target (`target` records: on a new target, every
meier_target_keepalive_s, and a release when it has none) and discounts candidates near
teammates' targets (coordination.discount). Beyond the local window it routes along a graph
of its own places, as the no-sharing baseline does.
"""
from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from firmware import kernels
from firmware.scheduler import Task
from firmware.schemes.base import (PRIORITY_INFO, PRIORITY_MOTION, PRIORITY_STATUS, Candidate, OwnPlaces, PlanningView,
                                   Scheme, Services, cost_along_graph)
from firmware.schemes.meier.coordination import TARGET_SEQ_MOD, TeamTargets, discount
from firmware.schemes.meier.polygons import EDGE_SPLIT
from firmware.schemes.meier.raster import CoarseRaster, rasterise_rings
from firmware.schemes.meier.records import (DIALECT, LATTICE_M, POLY, alive_record, alive_values, nack_seqs,
                                            nack_values, poly_record, poly_values)
from firmware.schemes.meier.replica import AliveRecord, PolyRecord, Replica
from firmware.schemes.meier.tracker import PolygonTracker
from hal.samples import OdometrySample

# Link priorities of polygon records: what the map forces (a vertex gone, a ring broken or
# new) before refinement, refinement before the refresh.
PRIORITY_FORCED = PRIORITY_MOTION
PRIORITY_SPLIT = PRIORITY_INFO
PRIORITY_REFRESH = 0
# Records of the slow refresh round robin, per second, sent only while nothing else waits.
REFRESH_RECORDS_PER_S = 0.5
# The byte budget (meier_radio_share) saves up at most this long a quiet spell, and a burst
# of traffic holds splits back for at most this long.
BUDGET_HORIZON_S = 10.0
# A block asked for is not asked for again before this many summaries went by: its records
# are on their way (the sender summarises only once they have left).
ASK_AGAIN_SUMS = 3
# Link keys of records sent again (repairs), told apart from first sends ("poly",
# "poly_alive") so that a repair lost in turn is not sent again on request.
POLY_AGAIN, ALIVE_AGAIN = "poly_again", "poly_alive_again"
# A frame that left the air is read by every receiver within this long (a few ticks).
NEWS_READ_S = 0.2
# Coarse cells around an own waypoint beyond the local window that a teammate's map must
# show known for the waypoint to count as explored by the team.
COVERED_RADIUS_CELLS = 1


class Meier(Scheme):
    name = "meier"
    doc = "Meier et al.'s polygon maps under a split-rate budget, target broadcast and utility discount"
    variants = {"polygons": "polygon maps over LoRa within a split rate, target broadcast and utility discount",
                "targets": "target broadcast and utility discount, no maps shared"}
    default_variant = "polygons"
    dialect = DIALECT
    needs = frozenset({"radio", "shared_frame"})

    def attach(self, services: Services) -> None:
        super().attach(services)
        p = services.params
        self._places = OwnPlaces(services)
        self.team_targets = TeamTargets(p.meier_target_expiry_s)
        self._target_seq = 0
        self._said: tuple[float, float] | None = None      # the target last claimed on the air
        self._said_us = 0
        self.counts = {"target_records_sent": 0, "poly_records_sent": 0, "poly_alive_records_sent": 0,
                       "edge_splits": 0, "records_dropped_by_link": 0, "nack_records_sent": 0,
                       "sum_records_sent": 0, "ask_records_sent": 0,
                       "poly_records_sent_again": 0, "updates_deferred": 0}
        self.records_by_kind = [0] * 5      # poly records by kind (polygons.REFRESH .. EMERGED)
        self._team_news = False             # the team layer changed since wake_up() last looked
        self._finished = False              # the robot stopped: no more splits or refresh
        self._woken_us = 0
        self._rescored_us = -(1 << 62)      # when the waypoints beyond the window were last re-scored
        if self.variant != "polygons":
            self.counts["waypoints_explored_beyond_window"] = 0
            return
        k = LATTICE_M / p.resolution_m
        if abs(k - round(k)) > 1e-9:
            raise ValueError(f"scheme meier: resolution_m = {p.resolution_m:g} m does not divide the polygons' "
                             f"lattice of {LATTICE_M:g} m")
        self._k = round(k)
        self.own = CoarseRaster(self._k)
        self.tracker = PolygonTracker(services.robot_id, p.meier_eps_m / LATTICE_M, p.meier_type_min_run,
                                      round(p.meier_junction_hold_m / LATTICE_M),
                                      min_region_cells=math.pi * p.robot_radius_m ** 2 / LATTICE_M ** 2,
                                      min_hole_cells=p.meier_min_hole_m2 / LATTICE_M ** 2)
        self._tokens = 0.0
        self._untraced = False      # the own raster changed since the polygons last followed it
        radio_Bps = services.radio_Bps
        self._budget_Bps = None if radio_Bps is None else p.meier_radio_share * radio_Bps
        self._credit_B = 0.0        # bytes of the budget not yet used (negative: overdrawn)
        self._bytes_seen = 0        # services.bytes_sent() when the budget was last brought up to date
        # vertex id (or -block-1) -> (priority, record, whether it goes again: a repair)
        self._outbox: dict[int, tuple[int, PolyRecord | AliveRecord, bool]] = {}
        self._refresh_credit = 0.0
        self._outbox_us = self._news_until_us = 0     # the outbox task's clock; has_news until then
        self.replicas: dict[int, Replica] = {}
        self._asked: dict[int, set[int]] = {}      # teammate -> its lost frames this robot asked for
        self._sum_us = -(1 << 62)                   # when the last poly_sum went (outbox clock)
        self._sum_block = 0                         # the block the next poly_sum summarises
        self._asked_block_us: dict[tuple[int, int], int] = {}   # (teammate, block) -> when asked for
        self._asked_us: dict[int, int] = {}         # teammate -> when its lost frames were last asked for
        # Per teammate, kept while its replica's version is the same: its rings as arrays,
        # and their raster on the team layer's last grid.
        self._sender_arrays: dict[int, tuple[int, tuple | None]] = {}
        self._sender_rasters: dict[int, tuple[tuple, np.ndarray]] = {}
        # The team layer on the last grid asked for (the window's, asked for several times
        # a cycle): (the layer it came from, the grid, the cells).
        self._team_cells_held: tuple[tuple, tuple, np.ndarray] | None = None
        self._team: tuple[np.ndarray, int, int] | None = None     # team layer (coarse), its row0, col0
        self._team_stale = False
        self._drawn_us = -(1 << 62)                 # when the team layer was last drawn (outbox clock)
        services.local_map.team = self

    def tasks(self) -> list[Task]:
        if self.variant != "polygons":
            return []
        return [Task("polygons", 1.0 / self.s.params.meier_update_s, self._task_polygons),
                Task("poly_outbox", self.s.rates.radio_hz, self._task_outbox)]

    # --- own polygons -----------------------------------------------------------------
    def _task_polygons(self, now_us: int) -> None:
        s, p = self.s, self.s.params
        lm = s.local_map
        self._untraced |= self.own.merge(lm.state_of(0, lm.n, 0, lm.n), lm.row0, lm.col0)
        self._tokens = min(max(1.0, p.meier_split_rate_hz * p.meier_update_s),
                           self._tokens + p.meier_split_rate_hz * p.meier_update_s)
        backlog = len(self._outbox) + self._poly_queued()
        splits = int(self._tokens) if backlog < p.meier_backlog_max and not self._finished else 0
        if self._budget_Bps is not None:
            sent = s.bytes_sent()
            horizon_B = self._budget_Bps * BUDGET_HORIZON_S
            self._credit_B = min(horizon_B, max(-horizon_B, self._credit_B + self._budget_Bps * p.meier_update_s
                                                - (sent - self._bytes_seen)))
            self._bytes_seen = sent
            if self._credit_B < 0:
                # Over the budget, what the map forces waits too: fewer, larger updates,
                # in which a boundary that came and went in between costs nothing.
                self.counts["updates_deferred"] += 1
                return
            splits = min(splits, int(self._credit_B // POLY.size_bytes))
        records = self.tracker.update(self.own.cells, splits, self.own.row0, self.own.col0)
        self._untraced = False
        self._tokens -= self.tracker.splits
        self.counts["edge_splits"] += self.tracker.splits
        for r in records:
            self._post(r, PRIORITY_SPLIT if r.kind == EDGE_SPLIT else PRIORITY_FORCED)
        if not self._outbox and not self._poly_queued() and not self._finished and self._credit_B >= 0:
            self._refresh_credit = min(1.0, self._refresh_credit + REFRESH_RECORDS_PER_S * p.meier_update_s)
            if self._refresh_credit >= 1.0:
                self._refresh_credit -= 1.0
                for r in self.tracker.map.refresh_next(1):
                    self._post(r, PRIORITY_REFRESH)

    def _poly_queued(self) -> int:
        """Vertex records waiting on the link."""
        return self.s.queued("poly") + self.s.queued("poly_gone")

    def _post(self, r: PolyRecord | AliveRecord, priority: int, again: bool = False) -> None:
        """Into the outbox; a newer state of the same vertex (or block) replaces one waiting.
        A record sent `again` repairs a teammate's copy; it stays a repair only if what it
        replaces was one too."""
        key = r.vertex_id if isinstance(r, PolyRecord) else -1 - r.block
        held = self._outbox.pop(key, None)
        if held is not None:
            priority, again = max(priority, held[0]), again and held[2]
        self._outbox[key] = (priority, r, again)

    def _task_outbox(self, now_us: int) -> None:
        """Feed the link from the outbox, the most urgent first, keeping at most
        meier_backlog_max polygon records queued there; with nothing of the map left to
        send, a block's summary now and then."""
        s = self.s
        self._ask_for_lost_frames(now_us)
        waiting = self._poly_queued() + s.queued("poly_alive") + s.queued("poly_nack")
        self._outbox_us = now_us
        if waiting or self._outbox:
            self._news_until_us = now_us + int(NEWS_READ_S * 1e6)
        self._news_until_us = max(self._news_until_us, s.on_air_until_us() + int(NEWS_READ_S * 1e6))
        if not waiting and not self._outbox:
            self._send_summary(now_us)
        room = s.params.meier_backlog_max - waiting
        if room <= 0 or not self._outbox:
            return
        order = sorted(self._outbox, key=lambda key: -self._outbox[key][0])   # stable: oldest first within a priority
        for key in order[:room]:
            priority, r, again = self._outbox.pop(key)
            if isinstance(r, PolyRecord):
                ok = s.send(*poly_values(r), priority, key=(POLY_AGAIN if again else "poly", r.vertex_id))
                self.counts["poly_records_sent"] += 1
                self.records_by_kind[r.kind] += 1
            else:
                ok = s.send("poly_alive", alive_values(r), priority,
                            key=(ALIVE_AGAIN if again else "poly_alive", r.block))
                self.counts["poly_alive_records_sent"] += 1
            if not ok:
                self.counts["records_dropped_by_link"] += 1

    def _ask_for_lost_frames(self, now_us: int) -> None:
        """Name each teammate's frames this robot lost (once each) in poly_nack records."""
        for rid in sorted(self.s.roster.members()):
            lost = self.s.missed_from(rid)
            asked = self._asked.setdefault(rid, set())
            new = [seq for seq in lost if seq not in asked]
            self._asked[rid] = asked & set(lost) | set(new)
            for values in nack_values(self.s.robot_id, rid, new):
                self.s.send("poly_nack", values, PRIORITY_FORCED)
                self.counts["nack_records_sent"] += 1
                self._asked_us[rid] = now_us

    def _send_summary(self, now_us: int) -> None:
        """Every meier_sum_period_s, the digest of the next block of this robot's vertex ids
        (round robin): sent only once every record made has left, so a receiver's copy that
        differs from it lost something."""
        m = self.tracker.map
        blocks = m.blocks()
        if not blocks or now_us - self._sum_us < self.s.params.meier_sum_period_s * 1e6:
            return
        self._sum_us = now_us
        block = self._sum_block % blocks
        self._sum_block = block + 1
        values = {"sender_id": self.s.robot_id, "block": block, "upto": m.next_stamp}
        values.update({f"part{k}": d for k, d in enumerate(m.block_digests(block))})
        self.s.send("poly_sum", values, PRIORITY_REFRESH, key="poly_sum")
        self.counts["sum_records_sent"] += 1

    def _compare_summary(self, values: Mapping[str, int], now_us: int) -> None:
        """A teammate's summary of a block against this robot's copy: asks for the parts
        that differ, unless the copy holds a record made since the summary (records of one
        frame arrive grouped by type, not in the order made: the next summary will tell), or
        it asked the teammate for the block, or for lost frames, less than ASK_AGAIN_SUMS
        summaries ago (what it asked for is on its way)."""
        sender, block = values["sender_id"], values["block"]
        replica = self.replicas.get(sender, Replica())
        parts = sum(1 << k for k, d in enumerate(replica.block_digests(block)) if d != values[f"part{k}"])
        if not parts or replica.holds_since(block, values["upto"]):
            return
        wait_us = ASK_AGAIN_SUMS * self.s.params.meier_sum_period_s * 1e6
        asked_us = max(self._asked_us.get(sender, -wait_us), self._asked_block_us.get((sender, block), -wait_us))
        if now_us - asked_us < wait_us:
            return
        self._asked_block_us[(sender, block)] = now_us
        self.s.send("poly_ask", {"sender_id": self.s.robot_id, "of_id": sender, "block": block, "parts": parts},
                    PRIORITY_FORCED)
        self.counts["ask_records_sent"] += 1

    def _send_block_again(self, block: int, parts: int) -> None:
        """A teammate's copy of some parts of a block differs: the newest record of each of
        their vertices goes again, as it was."""
        for r in self.tracker.map.block_records(block, parts):
            self._post(r, PRIORITY_FORCED, again=True)
            self.counts["poly_records_sent_again"] += 1

    def _send_again(self, seqs: list[int]) -> None:
        """A teammate lost these frames of this robot: the polygon records they carried go
        again, as they were (the newest of each vertex; which ids of a block are alive now).
        Repairs lost in turn are left to the block summaries: a teammate that lost a repair
        has most often heard the record it repeats, and asking again for every lost repair
        made repairs of repairs most of what a robot sent where teammates go in and out of
        range."""
        for seq in seqs:
            for key in self.s.keys_sent_in(seq):
                kind, which = key if isinstance(key, tuple) and len(key) == 2 else (None, None)
                r = self.tracker.map.last_record(which) if kind == "poly" else (
                    self.tracker.map.alive_block(which) if kind == "poly_alive" else None)
                if r is not None:
                    self._post(r, PRIORITY_FORCED, again=True)
                    self.counts["poly_records_sent_again"] += 1

    # --- teammates' polygons ----------------------------------------------------------
    def on_record(self, rtype: str, values: Mapping[str, int], now_us: int) -> None:
        if rtype == "target":
            self.team_targets.heard(values["sender_id"], values["x_cm"] / 100.0, values["y_cm"] / 100.0,
                                    bool(values["claimed"]), values["target_seq"], now_us)
            return
        if self.variant != "polygons" or values["sender_id"] == self.s.robot_id:
            return
        if rtype == "poly_nack":
            if values["of_id"] == self.s.robot_id:
                self._send_again(nack_seqs(values))
            return
        if rtype == "poly_ask":
            if values["of_id"] == self.s.robot_id:
                self._send_block_again(values["block"], values["parts"])
            return
        if rtype == "poly_sum":
            self._compare_summary(values, now_us)
            return
        record = alive_record(values) if rtype == "poly_alive" else poly_record(rtype, values)
        self.replicas.setdefault(record.sender_id, Replica()).add(record)
        self._team_stale = True

    def wake_up(self, now_us: int) -> bool:
        """The team layer changed since this robot last looked: a teammate's map may now
        show a way on where it stopped. It looks at most every known_map_refresh_s (a look
        is a plan over everything mapped)."""
        news = self._team_news or (self.variant == "polygons" and self._team_stale)
        if not news or now_us - self._woken_us < self.s.params.known_map_refresh_s * 1e6:
            return False
        self._team_news, self._woken_us = False, now_us
        self._finished = False
        return True

    def on_finished(self, frontiers_left_xy: np.ndarray) -> None:
        self._finished = True

    def has_news(self) -> bool:
        """Polygon records waiting, in the outbox or on the link, or on the air until less
        than NEWS_READ_S ago (not yet read by every receiver), or an update of the polygons
        waiting for the budget."""
        return self.variant == "polygons" and (self._outbox_us < self._news_until_us or self._untraced)

    def _team_layer(self) -> tuple[np.ndarray, int, int] | None:
        """The team layer (coarse cells, row0, col0), drawn again when it is used after
        news, at most every meier_update_s."""
        if self._team_stale and self._outbox_us - self._drawn_us >= self.s.params.meier_update_s * 1e6:
            self._drawn_us = self._outbox_us
            self._rebuild_team_layer()
        return self._team

    def _rebuild_team_layer(self) -> None:
        """Every teammate's polygons rasterised, occupied over free over unknown (meier.md
        1.5)."""
        self._team_stale = False
        self._team_news = True
        per_sender = []
        for sender in sorted(self.replicas):
            corners = self._corners_of(sender)
            if corners is not None:
                per_sender.append((sender, corners))
        if not per_sender:
            self._team = None
            return
        corners = np.concatenate([c[0] for _, c in per_sender])
        (c_lo, r_lo), (c_hi, r_hi) = corners.min(axis=0) - 1, corners.max(axis=0) + 1
        # No farther than meier_team_extent_m from the window's centre: what teammates say
        # beyond is of no use yet, and a record's coordinates reach 3 km.
        lm = self.s.local_map
        reach = int(self.s.params.meier_team_extent_m / LATTICE_M)
        mid_r, mid_c = (lm.row0 + lm.n // 2) // self._k, (lm.col0 + lm.n // 2) // self._k
        r_lo, r_hi = max(int(r_lo), mid_r - reach), min(int(r_hi), mid_r + reach)
        c_lo, c_hi = max(int(c_lo), mid_c - reach), min(int(c_hi), mid_c + reach)
        if r_hi <= r_lo or c_hi <= c_lo:
            self._team = None
            return
        shape = (r_hi - r_lo, c_hi - c_lo)
        team = np.zeros(shape, np.uint8)
        for sender, _ in per_sender:
            np.maximum(team, self._raster_of(sender, shape, r_lo, c_lo), out=team)
        self._team = (team, r_lo, c_lo)

    def _corners_of(self, sender: int) -> tuple[np.ndarray, list[np.ndarray], list[np.ndarray]] | None:
        """A teammate's rings as arrays: all corners, each ring's corners and wall flags;
        None if it has none. Kept until its records change."""
        replica = self.replicas[sender]
        held = self._sender_arrays.get(sender)
        if held is None or held[0] != replica.version:
            rings = replica.rings()
            arrays = None
            if rings:
                lattice = [np.array([(v.x_lat, v.y_lat) for v in ring], np.int64) for ring in rings]
                arrays = (np.concatenate(lattice), lattice, [np.array([v.edge_type == 1 for v in ring]) for ring in rings])
            held = self._sender_arrays[sender] = (replica.version, arrays)
        return held[1]

    def _raster_of(self, sender: int, shape: tuple[int, int], r_lo: int, c_lo: int) -> np.ndarray:
        """A teammate's rings rasterised on the team layer's grid; drawn again only when its
        records or the grid changed (most news is one teammate's)."""
        key = (self.replicas[sender].version, shape, r_lo, c_lo)
        held = self._sender_rasters.get(sender)
        if held is None or held[0] != key:
            _, lattice, wall = self._corners_of(sender)
            held = self._sender_rasters[sender] = (key, rasterise_rings(lattice, wall, shape, r_lo, c_lo))
        return held[1]

    def _team_cells(self, row0: int, col0: int, rows: int, cols: int) -> np.ndarray | None:
        """The team layer on the fine grid of `rows` x `cols` anchored at global fine cell
        (row0, col0); None if there is none."""
        drawn = self._team_layer()
        if drawn is None:
            return None
        grid = (row0, col0, rows, cols)
        held = self._team_cells_held
        if held is not None and held[0] is drawn and held[1] == grid:
            return held[2]
        team, t_r0, t_c0 = drawn
        cr = (row0 + np.arange(rows)) // self._k - t_r0
        cc = (col0 + np.arange(cols)) // self._k - t_c0
        rin = (cr >= 0) & (cr < team.shape[0])
        cin = (cc >= 0) & (cc < team.shape[1])
        out = np.zeros((rows, cols), np.uint8)
        if rin.any() and cin.any():
            out[np.ix_(rin, cin)] = team[np.ix_(cr[rin], cc[cin])]
        self._team_cells_held = (drawn, grid, out)
        return out

    # --- the team layer as the local map sees it (services.local_map.TeamView) ----------
    def fill_unknown(self, state: np.ndarray, row0: int, col0: int) -> None:
        team = self._team_cells(row0, col0, *state.shape)
        if team is not None:
            fill = (state == kernels.UNKNOWN) & (team != kernels.UNKNOWN)
            state[fill] = team[fill]

    def extent(self) -> tuple[int, int, int, int] | None:
        drawn = self._team_layer()
        if drawn is None:
            return None
        team, r0, c0 = drawn
        k = self._k
        return r0 * k, c0 * k, (r0 + team.shape[0]) * k, (c0 + team.shape[1]) * k

    # --- coordination -----------------------------------------------------------------
    def filter_waypoints(self, view: PlanningView) -> None:
        """Own waypoints beyond the local window whose surroundings a teammate's map shows
        known are explored (inside the window the combined map re-scores them). Without
        polygons, what the robot knows beyond its window (with dense maps, its teammates'
        scans) re-scores them every known_map_refresh_s: Algorithm 1 has no other way to
        learn that a teammate explored a place, and the team would drive to all of them."""
        if self.variant != "polygons":
            if view.now_us - self._rescored_us >= self.s.params.known_map_refresh_s * 1e6:
                self._rescored_us = view.now_us
                self.counts["waypoints_explored_beyond_window"] += self.s.waypoints.rescore_beyond_window(
                    self.s.local_map)
            return
        if self._team_layer() is None:
            return
        lm, k, r = self.s.local_map, self._k, COVERED_RADIUS_CELLS
        res = lm.p.resolution_m
        keep = []
        for w in self.s.waypoints.items:
            wi, wj = lm.cell_of(w.x_m, w.y_m)
            if lm.in_window(wi, wj):
                keep.append(w)
                continue
            gi, gj = math.floor(w.y_m / res), math.floor(w.x_m / res)
            around = self._team_cells(gi - r * k, gj - r * k, (2 * r + 1) * k, (2 * r + 1) * k)
            if not (around != kernels.UNKNOWN).all():
                keep.append(w)
        self.s.waypoints.items[:] = keep

    def rank(self, view: PlanningView, own: list[Candidate]) -> list[Candidate]:
        p = self.s.params
        cost_along_graph(view, own)
        done = {rid for rid, m in self.s.roster.members().items() if m.done}
        targets = [xy for rid, xy in self.team_targets.active(view.now_us).items()
                   if rid not in done and (p.meier_discount_all or rid < self.s.robot_id)]
        discount(own, targets, self.s.local_map, view.sight, p.meier_max_range_m, p.meier_beta_per_m)
        return own

    def after_plan(self, pose: OdometrySample, now_us: int) -> None:
        """Broadcast the target (Algorithm 1, line 8): a new one, a keep-alive, a release."""
        p, target = self.s.params, self.s.current_target()
        if target is not None:
            moved = self._said is None or math.dist(self._said, (target.x_m, target.y_m)) > p.meier_target_move_m
            if moved:
                self._target_seq = (self._target_seq + 1) % TARGET_SEQ_MOD
            if moved or now_us - self._said_us >= p.meier_target_keepalive_s * 1e6:
                self._said, self._said_us = (target.x_m, target.y_m), now_us
                self._send_target(target.x_m, target.y_m, True)
        elif self._said is not None:
            self._target_seq = (self._target_seq + 1) % TARGET_SEQ_MOD
            self._send_target(*self._said, False)
            self._said = None

    def _send_target(self, x_m: float, y_m: float, claimed: bool) -> None:
        self.s.send("target", {"sender_id": self.s.robot_id, "x_cm": round(x_m * 100), "y_cm": round(y_m * 100),
                               "claimed": int(claimed), "target_seq": self._target_seq},
                    PRIORITY_STATUS, key="target")
        self.counts["target_records_sent"] += 1

    def on_travel(self, pose: OdometrySample, now_us: int) -> None:
        self._places.on_travel(pose)

    # --- for the host -----------------------------------------------------------------
    def polygons(self) -> list[list[tuple[int, int, int, int]]]:
        """This robot's polygon map: rings of (vertex id, x_lat, y_lat, edge type)."""
        if self.variant != "polygons":
            return []
        m = self.tracker.map
        return [[(v, *m.vertex(v)) for v in ring] for ring in m.rings()]

    def polygons_of(self, sender: int) -> list[list[tuple[int, int, int, int]]]:
        """A teammate's polygon map as this robot holds it, in the same form."""
        replica = self.replicas.get(sender) if self.variant == "polygons" else None
        if replica is None:
            return []
        return [[(v.vertex_id, v.x_lat, v.y_lat, v.edge_type) for v in ring] for ring in replica.rings()]

    def observed(self) -> tuple[np.ndarray, int, int] | None:
        """This robot's own observed area on the polygons' lattice (its monotone coarse
        raster) and the raster's global (row0, col0); None without polygons."""
        return (self.own.cells, self.own.row0, self.own.col0) if self.variant == "polygons" else None

    def team_layer(self) -> tuple[np.ndarray, int, int] | None:
        """What this robot's teammates' polygons say, on the same lattice; None if nothing."""
        return self._team_layer() if self.variant == "polygons" else None

    def stats(self) -> dict[str, int]:
        kinds = ("refresh", "edge_split", "vanished", "broken", "emerged")
        out = dict(self.counts)
        if self.variant == "polygons":
            out.update({f"poly_{k}_records": n for k, n in zip(kinds, self.records_by_kind)})
            out["polygon_vertices"] = len(self.tracker.map.live_vertices())
        return out

    def drawables(self) -> dict:
        if self.variant != "polygons":
            return {}
        rings = self.polygons()
        pts = np.array([(x, y) for ring in rings for _, x, y, _ in ring], np.float64).reshape(-1, 2) * LATTICE_M
        segs = [((a[1], a[2]), (b[1], b[2])) for ring in rings for a, b in zip(ring, ring[1:] + ring[:1])]
        return {"title": "own polygon map (red: vertices of frontier edges)", "what": "vertices",
                "points": pts, "segments": np.array(segs, np.float64).reshape(-1, 2, 2) * LATTICE_M,
                "highlight": np.array([t == 0 for ring in rings for *_, t in ring], bool)}

