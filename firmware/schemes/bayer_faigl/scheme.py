"""Bayer & Faigl (2024): a 12-byte topological map shared over LoRa, with Greedy or MinPos
target choice (IV-C).

Each robot drops a vertex record every d_build of travel (Table I: where it was, the
information it still expects there, e_inf), revises e_inf at its own vertices as its
waypoints change, settles teammates' places it finds empty, and plans on the union of what
it heard (services.topo_map folds it, a pure function of the records held). Its stage of
planning: the presence rule drops own waypoints teammates covered (presence.py); W_inf
vertices (teammates' places with information left) join the own waypoints as targets; costs
beyond the local window come from the topological graph; MinPos ranks a target by how many
teammates are closer to it (eq. 6), Greedy ranks them all alike.
"""
from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from firmware import kernels
from firmware.schemes.base import (PRIORITY_INFO, PRIORITY_MOTION, Candidate, PlanningView, Scheme, Services,
                                   cost_along_graph)
from firmware.schemes.bayer_faigl.presence import PresenceRule
from firmware.schemes.bayer_faigl.records import DIALECT, MAX_INFO_VERSION, e_inf_bit_to_code
from firmware.services.pose import TravelMilestones
from firmware.services.targets import REACHED, Target
from firmware.services.topo_map import TOPO_FIELDS
from hal.samples import OdometrySample

# An information-change record is sent when a vertex's e_inf code moves this far from what
# this robot last said there (one code step is 4.4 %, so 8 steps is about a third), or falls
# to zero.
INFO_CODE_STEP = 8


class BayerFaigl(Scheme):
    name = "bayer-faigl"
    doc = "Bayer & Faigl's 12-byte topological map over LoRa"
    variants = {"greedy": "closest target on the shared topological map",
                "minpos": "lowest MinPos rank on the shared topological map, ties by Greedy"}
    default_variant = "minpos"
    dialect = DIALECT
    needs = frozenset({"radio", "shared_frame"})

    def attach(self, services: Services) -> None:
        super().attach(services)
        self.presence = PresenceRule(services)
        self._milestones = TravelMilestones(services.params.d_build_m)
        self._dropped_this_cycle: list = []
        self.stale_team_targets = 0
        # Team places (W_inf vertices) this robot found nothing at since after_plan last
        # settled them: stale in its own map, or reached. Its word there settles them.
        self._places_emptied: list[tuple[float, float]] = []

    # --- what the robot hears and does ------------------------------------------------
    def on_record(self, rtype: str, values: Mapping[str, int], now_us: int) -> None:
        self.s.topo.add(tuple(values[f] for f in TOPO_FIELDS))
        if values["presence"]:
            self.s.roster.heard_at(values["sender_id"], values["x_cm"] / 100.0, values["y_cm"] / 100.0, now_us)

    def on_travel(self, pose: OdometrySample, now_us: int) -> None:
        """A record every d_build of travel: where the robot has been, what it saw there,
        and the information it still expects around it (Table I)."""
        x_m, y_m = pose.x_m, pose.y_m
        if not self._milestones.due(x_m, y_m) or not self.s.has_planned():
            return  # the record carries the information here, known only after a first plan
        topo = self.s.topo
        _, _, e = self._vertex_information((x_m, y_m))
        # Passing a place again: this record speaks for the vertex it will join, so it has to
        # outrank what this robot said there before.
        version = 0
        near = topo.nearest(x_m, y_m)
        if near is not None and math.dist(topo.positions()[near], (x_m, y_m)) < self.s.params.d_build_m:
            version = min(MAX_INFO_VERSION, int(topo.word_of(self.s.robot_id)[0][near]) + 1)
        self._publish((self.s.robot_id, round(x_m * 100), round(y_m * 100), 0, 1, e_inf_bit_to_code(e[-1]), version),
                      PRIORITY_MOTION)
        self._milestones.mark(x_m, y_m)

    def on_target_outcome(self, target: Target, outcome: str) -> None:
        if outcome == REACHED and target.from_team:
            self._places_emptied.append((target.x_m, target.y_m))

    def after_plan(self, pose: OdometrySample, now_us: int) -> None:
        self._report_information_changes()
        self._settle_team_places()

    # --- the planning stage -----------------------------------------------------------
    def filter_waypoints(self, view: PlanningView) -> None:
        self._dropped_this_cycle = self.presence.drop_waypoints_seen_by_others(view.sight, view.target,
                                                                               seen_only=view.closing)

    def rank(self, view: PlanningView, own: list[Candidate]) -> list[Candidate]:
        p = self.s.params
        candidates = own + self._team_targets(view.sight)
        if p.shared_view_m > 0:
            self.presence.remember_given_up(self._dropped_this_cycle, view.sight)
        if not candidates and self.presence.given_up and not self.s.roster.any_active(view.now_us):
            revived = self.presence.revive_shared_frontiers(view.sight)
            self.s.waypoints.items.extend(revived)
            self.presence.revived += len(revived)
            candidates = [Candidate(w.x_m, w.y_m, w.e_bit, False) for w in revived]
        cost_along_graph(view, candidates)
        if self.variant == "minpos":
            self._minpos_ranks(candidates, view.blocked_edges, view.now_us)
        return candidates

    def _team_targets(self, sight: np.ndarray) -> list[Candidate]:
        """W_inf: vertices of the shared map with obtainable information that this robot has
        not visited, minus banned places (W_t is W united with these, eq. 5).

        A W_inf vertex inside the local map is checked against it: if this robot's own map
        shows less than e_min of unknown in view within 2 d_cam of it, the vertex's e_inf is
        stale for us (a lost information record, or we saw the place from elsewhere) and it
        is not a target. 2 d_cam, not d_cam: e_inf counts the sender's waypoints nearest to
        the vertex, which see d_cam around themselves and lie up to a sensor range away
        from it. Beyond the window the shared map is all we know, and the vertex stands."""
        topo, p = self.s.topo, self.s.params
        if not len(topo):
            return []
        xy = topo.positions()
        open_ = (topo.e_inf_codes() > 0) & ~topo.visited_by(self.s.robot_id)
        open_[open_] &= ~self.s.waypoints.banned_mask(xy[open_, 0], xy[open_, 1])
        ks = np.nonzero(open_)[0]
        if not len(ks):
            return []
        ij, inside = self.s.local_map.cells_of(xy[ks])
        keep = np.ones(len(ks), bool)
        if inside.any():
            cells = kernels.observable_unknown(sight, ij[inside, 0], ij[inside, 1], p.info_rays,
                                               2.0 * p.d_cam_m / p.resolution_m)
            keep[inside] = cells * p.entropy_per_cell_bit >= p.min_cluster_entropy_bit
        self.stale_team_targets += int((~keep).sum())
        self._places_emptied.extend((float(xy[k, 0]), float(xy[k, 1])) for k in ks[~keep])
        return [Candidate(float(xy[k, 0]), float(xy[k, 1]), 0.0, True) for k in ks[keep]]

    def _minpos_ranks(self, candidates: list[Candidate], blocked_edges: frozenset, now_us: int) -> None:
        """Eq. 6: a target's rank counts the other robots with a shorter topological path
        to it than this robot's."""
        topo = self.s.topo
        for c in candidates:
            c.rank = 0
        for _rid, (ox, oy) in self.s.roster.active(now_us).items():
            src, dist, _ = topo.costs_from(ox, oy, blocked_edges)
            if src is None:
                continue
            sx, sy = topo.positions()[src]
            lead = math.hypot(sx - ox, sy - oy)
            others = topo.costs_to(dist, [c.x_m for c in candidates], [c.y_m for c in candidates])
            for c, other in zip(candidates, others):
                if float(other) + lead < c.graph_cost_m:
                    c.rank += 1

    # --- the shared topological map ---------------------------------------------------
    def _vertex_information(self, extra_xy: tuple[float, float] | None = None
                            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(vertex indices, positions, e_inf in bits) of the places this robot visited, plus
        extra_xy (index -1): each waypoint's information counts at the closest one (eq. 4)."""
        topo = self.s.topo
        idx = np.nonzero(topo.visited_by(self.s.robot_id))[0] if len(topo) else np.zeros(0, np.int64)
        xy = topo.positions()[idx] if len(idx) else np.zeros((0, 2))
        if extra_xy is not None:
            idx = np.append(idx, -1)
            xy = np.vstack([xy, [extra_xy]])
        e = np.zeros(len(xy))
        items = self.s.waypoints.items
        if len(xy) and items:
            w = np.array([(it.x_m, it.y_m) for it in items])
            nearest = np.argmin((w[:, None, 0] - xy[None, :, 0]) ** 2 + (w[:, None, 1] - xy[None, :, 1]) ** 2, axis=1)
            np.add.at(e, nearest, [it.e_bit for it in items])
        return idx, xy, e

    def _publish(self, record: tuple[int, int, int, int, int, int, int], priority: int) -> None:
        """Own records go into the own map at once and onto the air."""
        self.s.topo.add(record)
        if self.s.send is not None:
            self.s.send("topo", dict(zip(TOPO_FIELDS, record)), priority)

    def _report_information_changes(self) -> None:
        """A record when the information this robot holds at one of its vertices has moved
        clearly away from what it last said there: down (a waypoint there was covered or
        handed to a teammate) or up (it saw more from there). Each carries the next revision,
        so it replaces the robot's earlier word in every map, whatever the arrival order."""
        idx, xy, e = self._vertex_information()
        if not len(idx):
            return
        revision, said = (a.tolist() for a in self.s.topo.word_of(self.s.robot_id))
        for k, (x, y), e_bit in zip(idx.tolist(), xy.tolist(), e.tolist()):
            self._say_information(x, y, e_inf_bit_to_code(e_bit), revision[k], said[k])

    def _settle_team_places(self) -> None:
        """A teammate's place that promised information (e_inf > 0) but where this robot's own
        map shows none, or that this robot reached, gets this robot's word: the information it
        holds there itself, usually none. A vertex takes the smallest of its senders' words,
        so one robot's "nothing here" spares the rest of the team the trip. Without it, a
        stale e_inf (its sender still holds a waypoint that teammates covered) draws every
        robot there in turn."""
        places = self._places_emptied
        self._places_emptied = []
        if not places:
            return
        topo = self.s.topo
        xy = topo.positions()
        revision, said = topo.word_of(self.s.robot_id)
        for x, y in places:
            k = topo.nearest(x, y)
            if k is None or math.dist(xy[k], (x, y)) > 0.01:
                continue
            code = e_inf_bit_to_code(float(self._vertex_information((x, y))[2][-1]))
            if self._say_information(x, y, code, int(revision[k]), int(said[k])):
                revision[k] += 1    # the same place may come twice in one batch
                said[k] = code

    def _say_information(self, x_m: float, y_m: float, code: int, revision: int, said: int) -> bool:
        """Send this robot's word `code` for the vertex at (x, y), with the next revision, if
        it is worth a record: the robot has no word there yet (revision -1), or the new one
        has moved clearly away from what it said (INFO_CODE_STEP, or down to zero). True if
        it was sent."""
        if revision >= MAX_INFO_VERSION:
            return False
        if revision >= 0 and (code == said or (code != 0 and abs(code - said) < INFO_CODE_STEP)):
            return False
        self._publish((self.s.robot_id, round(x_m * 100), round(y_m * 100), 0, 0, code, revision + 1), PRIORITY_INFO)
        return True

    # --- for the host -----------------------------------------------------------------
    def stats(self) -> dict[str, int]:
        return {"waypoints_dropped_by_presence": self.presence.dropped,
                "waypoints_revived": self.presence.revived,
                "team_targets_stale": self.stale_team_targets}

    def drawables(self) -> dict:
        topo = self.s.topo
        xy = topo.positions()
        return {"title": "topological map (red rings: vertices with obtainable information)",
                "points": xy, "segments": xy[topo.edges] if len(topo.edges) else np.zeros((0, 2, 2)),
                "highlight": topo.e_inf_codes() > 0, "what": "vertices"}
