"""Bayer & Faigl's presence rule (IV-A: drop a waypoint when another robot was within d_cam
of it), made safe for real maps, and the breaker for the deadlock it can cause. See
PresenceRule.drop_waypoints_seen_by_others and the README's "Notes and limits"."""
from __future__ import annotations

import numpy as np

from firmware import kernels
from firmware.schemes.base import Services
from firmware.services.grid_paths import lines_of_sight
from firmware.services.targets import Target
from firmware.services.team_view import unseen_after_team_view_bit
from firmware.services.waypoints import Waypoint


class PresenceRule:
    def __init__(self, services: Services) -> None:
        self.s = services
        self.dropped = 0       # waypoints dropped, counted per planning cycle
        self.revived = 0       # waypoints taken back by revive_shared_frontiers
        self._given_up: list[Waypoint] = []   # what the rule dropped, for the breaker

    @property
    def given_up(self) -> list[Waypoint]:
        """What the rule dropped and the breaker may still take back (a copy)."""
        return list(self._given_up)

    def drop_waypoints_seen_by_others(self, sight: np.ndarray, target: Target | None,
                                      seen_only: bool = False) -> list[Waypoint]:
        """Bayer & Faigl: a waypoint is removed when another robot reported its presence
        closer than d_cam. Taken literally that cancels what nobody looked at (robots leaving
        a common staging area cancel each other's waypoints; a robot passing the door of a
        room cancels the room), so a report only raises the question, and what the others
        could have seen answers it:
        - the report comes from a place this robot has not visited itself and, where the
          local map holds both ends, no wall stands between it and the waypoint;
        - the cells in line of sight within d_cam of every place others reported (as far as
          our map can tell: our known walls block the view, unknown cells do not) are taken
          as seen, and if the waypoint still has presence_keep_bit of information beyond
          them, it stays.
        - with presence_holds_target, waypoints within the cluster radius of the robot's own
          current target stay: the cover counted changes as the window moves (it is cast from
          the places inside it), and a robot giving way every time swung between two targets
          for minutes (maze_b, MinPos, seed 5: 1014 m).
        Whether the teammate still holds information at its place does not matter: what it
        saw from there is seen, and what it has left is its own waypoint, shared as e_inf.
        (Counting only places with e_inf 0 left robots re-exploring what teammates had seen
        whenever those still had anything nearby: on maze_b, MinPos drove 1.3 times as far as
        with dense maps over ten seeds.)
        With seen_only (a robot's last look before it stops), only the places whose sender
        reports no information left there (e_inf 0) count: the teammate saw what was around
        them, where a place still promising information says it did not.
        And a waypoint within finished_place_near_m of a place whose teammate reports no
        information left there (e_inf 0), with no known wall between them, is dropped
        before any view is cast: the teammate saw it from there and says so. The cast view
        alone misses that: one of the waypoint's info_rays slipping between the teammates'
        rays to full range counts about 1100 bit, more than presence_keep_bit, and robots
        drove across the map to waypoints teammates had finished with.
        Returns the waypoints it dropped."""
        if not len(self.s.topo) or not self.s.waypoints.items:
            return []
        items = self.s.waypoints.items
        held = []   # the current target's, exempt
        t = target
        if t is not None and not t.from_team and self.s.params.presence_holds_target:
            r2 = self.s.params.waypoint_cluster_radius_m ** 2
            near_target = [(w.x_m - t.x_m) ** 2 + (w.y_m - t.y_m) ** 2 < r2 for w in items]
            held = [w for w, near in zip(items, near_target) if near]
            items = [w for w, near in zip(items, near_target) if not near]
        others = self._places_of_others()
        finished = others[self.s.topo.e_inf_codes()[others] == 0]
        if seen_only:
            others = finished
        items, seen_there = self._split_by_finished_places(items, sight, finished)
        keep, dropped = self._split_by_team_view(items, sight, others)
        dropped = seen_there + dropped
        self.s.waypoints.items = held + keep
        self.dropped += len(dropped)
        return dropped

    def remember_given_up(self, dropped: list[Waypoint], sight: np.ndarray) -> None:
        """Keep the waypoints the presence rule dropped (one per cluster radius, the latest)
        for revive_shared_frontiers, which may need them long after the robot left: forget
        those that are banned, or that our own map now shows to hold too little."""
        r2 = self.s.params.waypoint_cluster_radius_m ** 2
        kept = [g for g in self._given_up if not self.s.waypoints.is_banned(g.x_m, g.y_m)
                and all((g.x_m - w.x_m) ** 2 + (g.y_m - w.y_m) ** 2 >= r2 for w in dropped)]
        self._given_up = kept + list(dropped)
        ij, inside = self.s.local_map.cells_of(np.array([(g.x_m, g.y_m) for g in self._given_up]).reshape(-1, 2))
        if inside.any():
            cells = kernels.observable_unknown(sight, ij[inside, 0], ij[inside, 1], self.s.params.info_rays,
                                               self.s.params.d_cam_m / self.s.params.resolution_m)
            for k, c in zip(np.nonzero(inside)[0], cells):
                self._given_up[k].e_bit = float(c) * self.s.params.entropy_per_cell_bit
            self._given_up = [g for g in self._given_up if g.e_bit >= self.s.params.min_cluster_entropy_bit]

    def revive_shared_frontiers(self, sight: np.ndarray) -> list[Waypoint]:
        """The presence rule's deadlock breaker, for a robot left with no target at all and
        no teammate still exploring (every one it heard of reported done).

        Robots that pass close to each other (a staging area, a shared corridor) each drop
        a frontier there on account of the others' places, and when every one of them does,
        nobody explores what lies beyond: the cave:1:60x60 greedy mission of seed 4 ended at
        51 % coverage so. A teammate's place within shared_view_m of one of our own places
        saw about what we saw from there, and our map shows that this was not enough; so the
        waypoints given up (remember_given_up) are judged again without those places. Only
        the last robot does it: while a teammate explores, what it was left may still be its
        next target, and robots with nothing to do driving back to check cost more than they
        find (on seed 2 of the same cave, p_max went from 354 to 516 m).
        Never a waypoint that a teammate stood within revive_clear_m of: it saw what the
        waypoint promised. In the cave's deadlock the nearest teammate place was 8.4 m from
        the frontier; the waypoints the breaker took back without this test on seed 0 (p_max
        884 m instead of 452 m with the presence rule's 900 bit as the threshold below, 590 m
        with revive_min_bit) mostly had one within 1.5 m.
        And only a waypoint holding revive_min_bit, a region worth the trip: with the
        presence rule's own 900 bit, the last robot of seed 1 drove 169 m more for 1143 bit
        and found nothing the team had not seen."""
        others = self._places_of_others(apart_m=self.s.params.shared_view_m)
        everyone_elses = self.s.topo.positions()[self._places_of_others()]
        clear2 = self.s.params.revive_clear_m ** 2
        big = [g for g in self._given_up if g.e_bit >= self.s.params.revive_min_bit
               and not (((everyone_elses - (g.x_m, g.y_m)) ** 2).sum(axis=1) < clear2).any()]
        revived, _ = self._split_by_team_view(big, sight, others)
        return revived

    def _places_of_others(self, apart_m: float = 0.0) -> np.ndarray:
        """Indices of the places teammates reported and this robot did not, leaving out those
        within apart_m of one of this robot's own places (0: none left out)."""
        mine = self.s.topo.visited_by(self.s.robot_id)
        others = np.nonzero(self.s.topo.visited_by_others(self.s.robot_id) & ~mine)[0]
        if apart_m > 0 and len(others) and mine.any():
            xy = self.s.topo.positions()
            d2 = ((xy[others, None, :] - xy[mine][None, :, :]) ** 2).sum(axis=2).min(axis=1)
            others = others[d2 > apart_m ** 2]
        return others

    def _split_by_finished_places(self, items: list[Waypoint], sight: np.ndarray,
                                  finished: np.ndarray) -> tuple[list[Waypoint], list[Waypoint]]:
        """(kept, dropped): drop the waypoints within finished_place_near_m of one of the
        places `finished` (teammates' places reporting e_inf 0) in line of sight of it in the
        local map. Both ends must be in the window; beyond it the test is left to the
        team-view rule."""
        near_m = self.s.params.finished_place_near_m
        if near_m <= 0 or len(finished) == 0 or not items:
            return list(items), []
        xy = self.s.topo.positions()[finished]
        wxy = np.array([(w.x_m, w.y_m) for w in items])
        wk, vk = np.nonzero(np.hypot(xy[None, :, 0] - wxy[:, 0, None], xy[None, :, 1] - wxy[:, 1, None]) < near_m)
        w_ij, w_inside = self.s.local_map.cells_of(wxy)
        v_ij, v_inside = self.s.local_map.cells_of(xy)
        pick = w_inside[wk] & v_inside[vk]
        wk, vk = wk[pick], vk[pick]
        seen = np.zeros(len(items), bool)
        if len(wk):
            clear = lines_of_sight(sight, w_ij[wk, 0], w_ij[wk, 1], v_ij[vk, 0], v_ij[vk, 1])
            seen[wk[clear]] = True
        return ([w for w, s in zip(items, seen) if not s], [w for w, s in zip(items, seen) if s])

    def _split_by_team_view(self, items: list[Waypoint], sight: np.ndarray,
                            others: np.ndarray) -> tuple[list[Waypoint], list[Waypoint]]:
        """(kept, dropped): the presence rule of drop_waypoints_seen_by_others for the
        waypoints `items`, with `others` the indices of the teammates' places it counts."""
        if len(others) == 0 or not items:
            return list(items), []
        p = self.s.params
        xy = self.s.topo.positions()
        wxy = np.array([(w.x_m, w.y_m) for w in items])
        near = np.hypot(xy[others, 0][None, :] - wxy[:, 0, None], xy[others, 1][None, :] - wxy[:, 1, None]) < p.d_cam_m
        w_ij, w_inside = self.s.local_map.cells_of(wxy)
        v_ij, v_inside = self.s.local_map.cells_of(xy[others])
        # A report counts when it comes from outside the window or no known wall stands
        # between the place and the waypoint. Each waypoint's first near place is tried
        # first: it nearly always counts, and then the others need no line of sight.
        wk, vk = np.nonzero(near & w_inside[:, None])
        first = np.diff(wk, prepend=-1) != 0
        is_reported = np.zeros(len(items), bool)
        for stage in (first, ~first):
            pick = stage & ~is_reported[wk]
            w_at, v_at = wk[pick], vk[pick]
            counts = ~v_inside[v_at]
            ask = ~counts
            counts[ask] = lines_of_sight(sight, w_ij[w_at[ask], 0], w_ij[w_at[ask], 1], v_ij[v_at[ask], 0], v_ij[v_at[ask], 1])
            is_reported[w_at[counts]] = True
        # Outside the window there is nothing to check against: a report stands.
        out_dropped = ~w_inside & near.any(axis=1)
        keep = [w for w, r, d in zip(items, is_reported, out_dropped) if not r and not d]
        dropped = [w for w, d in zip(items, out_dropped) if d]
        if is_reported.any():
            reported = [w for w, r in zip(items, is_reported) if r]
            lm = self.s.local_map
            unseen_bit = unseen_after_team_view_bit(sight, lm.row0, lm.col0, wxy[is_reported], xy[others], p)
            for w, left in zip(reported, unseen_bit):
                (keep if left >= p.presence_keep_bit else dropped).append(w)
        return keep, dropped
