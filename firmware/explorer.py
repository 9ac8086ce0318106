"""One planning cycle of the explorer: map layers, reachability, waypoints, target choice
(Greedy or MinPos, Bayer & Faigl IV-C), and a path to the target through the local map or,
beyond it, along the topological graph."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from firmware import kernels
from firmware.local_map import LocalMap
from firmware.params import ExplorationParams
from firmware.team import TeamView
from firmware.topo_map import TopoMap
from firmware.waypoints import Waypoint, WaypointSet


@dataclass
class Target:
    x_m: float
    y_m: float
    cost_m: float
    from_team: bool = False    # a vertex with obtainable information from the shared map (W_inf)


@dataclass
class Plan:
    target: Target | None
    path_xy: np.ndarray            # world points to follow, robot first
    done: bool                     # nothing left to explore that this robot can reach


def traversable_near(traversable: np.ndarray, i: int, j: int, radius_cells: int) -> np.ndarray:
    """The traversable cells (rows of i, j) within a square of radius_cells around (i, j),
    nearest first, lowest index on ties."""
    n_r, n_c = traversable.shape
    i0, i1 = max(i - radius_cells, 0), min(i + radius_cells + 1, n_r)
    j0, j1 = max(j - radius_cells, 0), min(j + radius_cells + 1, n_c)
    cells = np.argwhere(traversable[i0:i1, j0:j1]) + np.array([i0, j0])
    d2 = (cells[:, 0] - i) ** 2 + (cells[:, 1] - j) ** 2
    return cells[np.lexsort((cells[:, 1], cells[:, 0], d2))]


def nearest_traversable(traversable: np.ndarray, i: int, j: int, radius_cells: int) -> tuple[int, int] | None:
    """The traversable cell closest to (i, j) within a square of radius_cells (lowest index on ties)."""
    cells = traversable_near(traversable, i, j, radius_cells)
    return (int(cells[0, 0]), int(cells[0, 1])) if len(cells) else None


def escape_start(traversable: np.ndarray, i: int, j: int, radius_cells: int) -> tuple[int, int] | None:
    """Where to plan from when the robot's own cell (i, j) is not traversable (pushed near a
    wall, or the map changed under it): the traversable cell within a square of radius_cells
    that lies in the largest connected region, the nearest of those (lowest index on ties).
    The nearest cell alone can lie in a sliver the safety margin cuts off: in a doorway of the
    Intel lab (one robot, seed 3, with waypoints down to 20 bit) every target looked
    unreachable from such a sliver, all were dropped after their strikes, and the mission
    ended at 0.93 coverage."""
    cells = traversable_near(traversable, i, j, radius_cells)
    counted = np.zeros(len(cells), bool)
    best, best_cells = None, -1
    for k in range(len(cells)):
        if counted[k]:
            continue
        region = kernels.reachable_cells(traversable, int(cells[k, 0]), int(cells[k, 1]))
        counted |= region[cells[:, 0], cells[:, 1]]
        size = int(region.sum())
        if size > best_cells:
            best, best_cells = (int(cells[k, 0]), int(cells[k, 1])), size
    return best


class GridPaths:
    """Shortest paths in the local map from the robot's cell, settled only as far as asked:
    a plan needs the costs of its candidate cells and the route to one of them, seldom the
    whole window, and the search is most of a plan's time. Cells settle in the same order
    as in a full search (kernels.dijkstra_settle), so every answer is the full search's."""

    def __init__(self, traversable: np.ndarray, cell_cost: np.ndarray, start_i: int, start_j: int,
                 arrays: tuple | None = None):
        """arrays: kernels.dijkstra_arrays of the window's shape to reuse (the previous
        plan's GridPaths.arrays); they are overwritten."""
        self._traversable = traversable
        self._cell_cost = cell_cost
        self.reachable = kernels.reachable_cells(traversable, start_i, start_j)
        if arrays is None or arrays[0].shape != traversable.shape:
            arrays = kernels.dijkstra_arrays(*traversable.shape)
        self.arrays = arrays
        kernels.dijkstra_start(traversable, start_i, start_j, *arrays)
        self.dist, self.parent, *self._heap = arrays

    def settle(self, i: np.ndarray, j: np.ndarray) -> None:
        """Make dist and parent final at the cells (i, j) that are reachable."""
        i = np.asarray(i, np.int64)
        j = np.asarray(j, np.int64)
        ok = self.reachable[i, j]
        if ok.any():
            kernels.dijkstra_settle(self._traversable, self._cell_cost, self.dist, self.parent, *self._heap,
                                    i[ok] * self.dist.shape[1] + j[ok])

    def path(self, goal_i: int, goal_j: int) -> list[tuple[int, int]]:
        """Cells from the start to a reachable goal."""
        self.settle(np.array([goal_i]), np.array([goal_j]))
        return extract_path(self.parent, goal_i, goal_j)


def extract_path(parent: np.ndarray, goal_i: int, goal_j: int) -> list[tuple[int, int]]:
    cols = parent.shape[1]
    cells = [(goal_i, goal_j)]
    flat = parent[goal_i, goal_j]
    while flat >= 0:
        i, j = divmod(int(flat), cols)
        cells.append((i, j))
        flat = parent[i, j]
    cells.reverse()
    return cells


def line_of_sight(state: np.ndarray, i0: int, j0: int, i1: int, j1: int) -> bool:
    """No OCCUPIED cell on the straight segment between two cells of the local map."""
    steps = max(abs(i1 - i0), abs(j1 - j0))
    if steps == 0:
        return True
    t = np.linspace(0.0, 1.0, steps + 1)
    ii = np.round(i0 + (i1 - i0) * t).astype(np.int64)
    jj = np.round(j0 + (j1 - j0) * t).astype(np.int64)
    return not bool((state[ii, jj] == kernels.OCCUPIED).any())


@dataclass
class _Candidate:
    x_m: float
    y_m: float
    e_bit: float
    from_team: bool
    cost_m: float = math.inf        # this robot's cost (local map where it can, else the graph)
    graph_cost_m: float = math.inf  # this robot's cost on the topological graph (for MinPos)
    rank: int = 0


class Explorer:
    def __init__(self, params: ExplorationParams, local_map: LocalMap, topo: TopoMap, team: TeamView) -> None:
        self.p = params
        self.map = local_map
        self.topo = topo
        self.team = team
        self.waypoints = WaypointSet(params)
        self.target: Target | None = None
        self._best_progress_m = math.inf
        self._progress_stamp_us = 0
        self._time_on_us: dict[tuple[float, float], int] = {}
        self._budget_us: dict[tuple[float, float], int] = {}
        self._last_track_us = 0
        self.dropped_unreachable = 0
        self.dropped_stalled = 0
        self.dropped_by_presence = 0
        self.revived = 0               # waypoints taken back by _revive_shared_frontiers
        self._given_up: list[Waypoint] = []   # what the presence rule dropped, for that
        self.stale_team_targets = 0
        self.reached = 0
        self.seen_on_way = 0
        # Team places (W_inf vertices, metres) this robot found nothing at since the agent
        # last collected them: stale in its own map, or reached. Its word there settles them.
        self.team_places_emptied: list[tuple[float, float]] = []
        # Per target without a route: (strikes, when the last one counted).
        self._strikes: dict[tuple[float, float], tuple[int, int]] = {}
        self._search_arrays: tuple | None = None   # GridPaths' arrays, reused plan after plan
        # Edges of the shared map that this robot's own map shows crossing a wall.
        self.blocked_edges: set[tuple[tuple[int, int], tuple[int, int]]] = set()

    def _path_xy(self, cells: list[tuple[int, int]]) -> np.ndarray:
        return np.array([self.map.center_of(i, j) for i, j in cells], np.float64).reshape(-1, 2)

    def _in_window(self, i: int, j: int) -> bool:
        return 0 <= i < self.map.n and 0 <= j < self.map.n

    def _cells_of(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Local-map cells (rows of i, j) of world points, and which of them are in the window."""
        ij = np.array([self.map.cell_of(x, y) for x, y in xy], np.int64).reshape(-1, 2)
        return ij, (ij >= 0).all(axis=1) & (ij < self.map.n).all(axis=1)

    def plan(self, x_m: float, y_m: float, now_us: int) -> Plan:
        p = self.p
        res = p.resolution_m
        layers = self.map.layers()
        ri, rj = self.map.cell_of(x_m, y_m)
        start = (ri, rj) if layers.traversable[ri, rj] else \
            escape_start(layers.traversable, ri, rj, int(math.ceil(p.escape_radius_m / res)))
        if start is None:
            # Boxed in by the safety margin (pushed near a wall, or the map changed under it):
            # plan from the nearest known-free cell instead, so the robot can back out.
            start = nearest_traversable(layers.state == kernels.FREE, ri, rj, int(math.ceil(p.escape_radius_m / res)))
            if start is None:
                return Plan(None, np.zeros((0, 2)), False)
            layers.traversable[start] = True
        paths = GridPaths(layers.traversable, layers.cell_cost, start[0], start[1], self._search_arrays)
        self._search_arrays = paths.arrays
        reachable = paths.reachable
        self.waypoints.update(self.map, layers.sight, reachable)
        # Our own target left W: its information is now observed. Seen from within
        # target_seen_within_m (0: never), it is done with as if reached, and no waypoint is
        # made there again. Without that, a waypoint in front of a door of the Intel lab
        # (MinPos, seed 5) kept coming back with about 1100 bit after the robot had seen it
        # from 0.6 m, and the robot drove back to it eight times (likely a few cells there
        # turning unknown again, reopening a view).
        t = self.target
        if t is not None and not t.from_team and math.hypot(t.x_m - x_m, t.y_m - y_m) < p.target_seen_within_m \
                and not any((w.x_m, w.y_m) == (t.x_m, t.y_m) for w in self.waypoints.items):
            self.waypoints.ban(t.x_m, t.y_m)
            self.seen_on_way += 1
            self.target = None
        given_up = self._drop_waypoints_seen_by_others(layers.sight) if self.team.strategy.shares_topology else []

        # A target reached is done with: its surroundings are now observed (or unobservable).
        if self.target is not None and math.hypot(self.target.x_m - x_m, self.target.y_m - y_m) < p.waypoint_reached_m:
            self.waypoints.ban(self.target.x_m, self.target.y_m)
            self.reached += 1
            if self.target.from_team:
                self.team_places_emptied.append((self.target.x_m, self.target.y_m))
            self.target = None

        topo_src, topo_dist, topo_parent = self.topo.costs_from(x_m, y_m, frozenset(self.blocked_edges))
        to_src_m = 0.0
        if topo_src is not None:
            sx, sy = self.topo.positions()[topo_src]
            to_src_m = math.hypot(sx - x_m, sy - y_m)
        candidates = self._candidates(layers.sight)
        if self.p.shared_view_m > 0:
            self._remember_given_up(given_up, layers.sight)
        if not candidates and self._given_up and not any(r != self.team.robot_id for r in self.team.positions):
            revived = self._revive_shared_frontiers(layers.sight)
            self.waypoints.items.extend(revived)
            self.revived += len(revived)
            candidates = [_Candidate(w.x_m, w.y_m, w.e_bit, False) for w in revived]
        cells = [self.map.cell_of(c.x_m, c.y_m) for c in candidates]
        local = [self._in_window(wi, wj) and reachable[wi, wj] for wi, wj in cells]
        local_ij = np.array([ij for ij, ok in zip(cells, local) if ok], np.int64).reshape(-1, 2)
        paths.settle(local_ij[:, 0], local_ij[:, 1])
        graph_costs = self.topo.costs_to(topo_dist, [c.x_m for c in candidates], [c.y_m for c in candidates])
        for c, (wi, wj), ok, graph_cost in zip(candidates, cells, local, graph_costs):
            c.graph_cost_m = float(graph_cost) + to_src_m
            c.cost_m = float(paths.dist[wi, wj]) * res if ok else c.graph_cost_m
        if self.team.strategy.ranking == "minpos":
            self._minpos_ranks(candidates)
        # Strikes only count for targets that are still targets.
        keys = {(c.x_m, c.y_m) for c in candidates}
        self._strikes = {k: v for k, v in self._strikes.items() if k in keys}

        while candidates:
            c = self._choose(candidates)
            path = self._route(c, paths, topo_src, topo_dist, topo_parent, x_m, y_m)
            if path is not None:
                self._strikes.pop((c.x_m, c.y_m), None)
                self._track_progress(c, now_us)
                if self.target is None:
                    return Plan(None, np.zeros((0, 2)), False)
                return Plan(self.target, path, False)
            # No way there from here, not even along the topological map. A map glitch can
            # cause that for a moment, so it takes several cycles in a row to drop it for good,
            # and cycles count at most once per unreachable_strike_interval_s: a robot without
            # a route replans every 0.2 s, and three strikes took 0.35 s, too short for the
            # map to change (Intel lab, one robot, seed 3: every target dropped at once).
            key = (c.x_m, c.y_m)
            count, last_us = self._strikes.get(key, (0, None))
            if last_us is None or now_us - last_us >= self.p.unreachable_strike_interval_s * 1e6:
                count, last_us = count + 1, now_us
                self._strikes[key] = (count, last_us)
            if count >= self.p.unreachable_strikes:
                self.waypoints.ban(c.x_m, c.y_m)
                self.dropped_unreachable += 1
            candidates = [k for k in candidates if (k.x_m, k.y_m) != key and not self.waypoints.is_banned(k.x_m, k.y_m)]
            self.target = None
        self.target = None
        # Done only when no target is left at all; targets merely unreachable right now (still
        # collecting strikes) keep the robot planning.
        pending = any(count < self.p.unreachable_strikes for count, _ in self._strikes.values())
        return Plan(None, np.zeros((0, 2)), not pending)

    # --- targets (eq. 5) --------------------------------------------------------------
    def _candidates(self, sight: np.ndarray) -> list[_Candidate]:
        """W_t = W (own waypoints) united with W_inf (vertices of the shared map with
        obtainable information that this robot has not visited), minus banned places.

        A W_inf vertex inside the local map is checked against it: if this robot's own map
        shows less than e_min of unknown in view within 2 d_cam of it, the vertex's e_inf is
        stale for us (a lost information record, or we saw the place from elsewhere) and it
        is not a target. 2 d_cam, not d_cam: e_inf counts the sender's waypoints nearest to
        the vertex, which see d_cam around themselves and lie up to a sensor range away
        from it. Beyond the window the shared map is all we know, and the vertex stands."""
        out = [_Candidate(w.x_m, w.y_m, w.e_bit, False) for w in self.waypoints.items]
        if self.team.strategy.shares_topology and len(self.topo):
            xy = self.topo.positions()
            open_ = (self.topo.e_inf_codes() > 0) & ~self.topo.visited_by(self.team.robot_id)
            open_[open_] &= ~self.waypoints.banned_mask(xy[open_, 0], xy[open_, 1])
            ks = np.nonzero(open_)[0]
            if len(ks):
                ij, inside = self._cells_of(xy[ks])
                keep = np.ones(len(ks), bool)
                if inside.any():
                    cells = kernels.observable_unknown(sight, ij[inside, 0], ij[inside, 1], self.p.info_rays,
                                                       2.0 * self.p.d_cam_m / self.p.resolution_m)
                    keep[inside] = cells * self.p.entropy_per_cell_bit >= self.p.min_cluster_entropy_bit
                self.stale_team_targets += int((~keep).sum())
                self.team_places_emptied.extend((float(xy[k, 0]), float(xy[k, 1])) for k in ks[~keep])
                out.extend(_Candidate(float(xy[k, 0]), float(xy[k, 1]), 0.0, True) for k in ks[keep])
        return out

    def _drop_waypoints_seen_by_others(self, sight: np.ndarray) -> list[Waypoint]:
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
        Returns the waypoints it dropped."""
        if not len(self.topo) or not self.waypoints.items:
            return []
        items = self.waypoints.items
        held = []   # the current target's, exempt
        t = self.target
        if t is not None and not t.from_team and self.p.presence_holds_target:
            r2 = self.p.waypoint_cluster_radius_m ** 2
            near_target = [(w.x_m - t.x_m) ** 2 + (w.y_m - t.y_m) ** 2 < r2 for w in items]
            held = [w for w, near in zip(items, near_target) if near]
            items = [w for w, near in zip(items, near_target) if not near]
        keep, dropped = self._split_by_team_view(items, sight, self._places_of_others())
        self.waypoints.items = held + keep
        self.dropped_by_presence += len(dropped)
        return dropped

    def _remember_given_up(self, dropped: list[Waypoint], sight: np.ndarray) -> None:
        """Keep the waypoints the presence rule dropped (one per cluster radius, the latest)
        for _revive_shared_frontiers, which may need them long after the robot left: forget
        those that are banned, or that our own map now shows to hold too little."""
        r2 = self.p.waypoint_cluster_radius_m ** 2
        kept = [g for g in self._given_up if not self.waypoints.is_banned(g.x_m, g.y_m)
                and all((g.x_m - w.x_m) ** 2 + (g.y_m - w.y_m) ** 2 >= r2 for w in dropped)]
        self._given_up = kept + list(dropped)
        ij, inside = self._cells_of(np.array([(g.x_m, g.y_m) for g in self._given_up]).reshape(-1, 2))
        if inside.any():
            cells = kernels.observable_unknown(sight, ij[inside, 0], ij[inside, 1], self.p.info_rays,
                                               self.p.d_cam_m / self.p.resolution_m)
            for k, c in zip(np.nonzero(inside)[0], cells):
                self._given_up[k].e_bit = float(c) * self.p.entropy_per_cell_bit
            self._given_up = [g for g in self._given_up if g.e_bit >= self.p.min_cluster_entropy_bit]

    def _revive_shared_frontiers(self, sight: np.ndarray) -> list[Waypoint]:
        """The presence rule's deadlock breaker, for a robot left with no target at all and
        no teammate still exploring (every one it heard of reported done).

        Robots that pass close to each other (a staging area, a shared corridor) each drop
        a frontier there on account of the others' places, and when every one of them does,
        nobody explores what lies beyond: the cave:1:60x60 greedy mission of seed 4 ended at
        51 % coverage so. A teammate's place within shared_view_m of one of our own places
        saw about what we saw from there, and our map shows that this was not enough; so the
        waypoints given up (_remember_given_up) are judged again without those places. Only
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
        others = self._places_of_others(apart_m=self.p.shared_view_m)
        everyone_elses = self.topo.positions()[self._places_of_others()]
        clear2 = self.p.revive_clear_m ** 2
        big = [g for g in self._given_up if g.e_bit >= self.p.revive_min_bit
               and not (((everyone_elses - (g.x_m, g.y_m)) ** 2).sum(axis=1) < clear2).any()]
        revived, _ = self._split_by_team_view(big, sight, others)
        return revived

    def _places_of_others(self, apart_m: float = 0.0) -> np.ndarray:
        """Indices of the places teammates reported and this robot did not, leaving out those
        within apart_m of one of this robot's own places (0: none left out)."""
        mine = self.topo.visited_by(self.team.robot_id)
        others = np.nonzero(self.topo.visited_by_others(self.team.robot_id) & ~mine)[0]
        if apart_m > 0 and len(others) and mine.any():
            xy = self.topo.positions()
            d2 = ((xy[others, None, :] - xy[mine][None, :, :]) ** 2).sum(axis=2).min(axis=1)
            others = others[d2 > apart_m ** 2]
        return others

    def _split_by_team_view(self, items: list[Waypoint], sight: np.ndarray,
                            others: np.ndarray) -> tuple[list[Waypoint], list[Waypoint]]:
        """(kept, dropped): the presence rule of _drop_waypoints_seen_by_others for the
        waypoints `items`, with `others` the indices of the teammates' places it counts."""
        if len(others) == 0:
            return list(items), []
        xy = self.topo.positions()
        reported = []   # (waypoint, i, j): waypoints with a report that may cancel them
        keep = []
        dropped = []
        for w in items:
            d = np.hypot(xy[others, 0] - w.x_m, xy[others, 1] - w.y_m)
            near = others[d < self.p.d_cam_m]
            wi, wj = self.map.cell_of(w.x_m, w.y_m)
            if not self._in_window(wi, wj):
                # Nothing to check against: the report stands.
                (dropped if len(near) else keep).append(w)
                continue
            for v in near:
                vi, vj = self.map.cell_of(xy[v, 0], xy[v, 1])
                if not self._in_window(vi, vj) or line_of_sight(sight, wi, wj, vi, vj):
                    reported.append((w, wi, wj))
                    break
            else:
                keep.append(w)
        if reported:
            # A place more than 2 d_cam from every such waypoint sees nothing the waypoint
            # would (1 m spare for cell rounding), so it is left out: the same result, much
            # less ray casting.
            wxy = np.array([(w.x_m, w.y_m) for w, *_ in reported])
            reach2 = (2.0 * self.p.d_cam_m + 1.0) ** 2
            d2 = ((xy[others, None, :] - wxy[None, :, :]) ** 2).sum(axis=2).min(axis=1)
            places = others[d2 <= reach2]
            ij, inside = self._cells_of(xy[places])
            seen = np.zeros(sight.shape, bool)
            kernels.mark_visible(sight, ij[inside, 0], ij[inside, 1], self.p.team_view_rays,
                                 self.p.d_cam_m / self.p.resolution_m, seen)
            team_sight = sight.copy()
            team_sight[seen & (sight == kernels.UNKNOWN)] = kernels.SEEN_BY_TEAM
            wi = np.array([r[1] for r in reported], np.int64)
            wj = np.array([r[2] for r in reported], np.int64)
            unseen_bit = kernels.observable_unknown(team_sight, wi, wj, self.p.info_rays,
                                                    self.p.d_cam_m / self.p.resolution_m) * self.p.entropy_per_cell_bit
            for (w, *_), left in zip(reported, unseen_bit):
                (keep if left >= self.p.presence_keep_bit else dropped).append(w)
        return keep, dropped

    def _minpos_ranks(self, candidates: list[_Candidate]) -> None:
        """Eq. 6: a target's rank counts the other robots with a shorter topological path
        to it than this robot's."""
        for c in candidates:
            c.rank = 0
        for rid, (ox, oy) in sorted(self.team.positions.items()):
            if rid == self.team.robot_id:
                continue
            src, dist, _ = self.topo.costs_from(ox, oy, frozenset(self.blocked_edges))
            if src is None:
                continue
            sx, sy = self.topo.positions()[src]
            lead = math.hypot(sx - ox, sy - oy)
            others = self.topo.costs_to(dist, [c.x_m for c in candidates], [c.y_m for c in candidates])
            for c, other in zip(candidates, others):
                if float(other) + lead < c.graph_cost_m:
                    c.rank += 1

    def _choose(self, candidates: list[_Candidate]) -> _Candidate:
        """Lowest rank (MinPos; all ranks are 0 under Greedy), then the closest. The current
        target is kept unless another is clearly better, so the robot does not dither."""
        key = lambda c: (c.rank, c.cost_m, c.x_m, c.y_m)  # noqa: E731
        best = min(candidates, key=key)
        if self.target is not None:
            for c in candidates:
                if (c.x_m, c.y_m) == (self.target.x_m, self.target.y_m) and c.rank <= best.rank \
                        and best.cost_m >= 0.8 * c.cost_m:
                    return c
        return best

    def _track_progress(self, c: _Candidate, now_us: int) -> None:
        key = (c.x_m, c.y_m)
        # Time spent heading for each target accumulates across switches, so two targets
        # taking turns cannot keep a robot busy for ever.
        if self.target is not None:
            prev = (self.target.x_m, self.target.y_m)
            self._time_on_us[prev] = self._time_on_us.get(prev, 0) + now_us - self._last_track_us
        self._last_track_us = now_us
        same = self.target is not None and (self.target.x_m, self.target.y_m) == key
        if not same:
            self.target = Target(c.x_m, c.y_m, c.cost_m, c.from_team)
            self._best_progress_m = c.cost_m
            self._progress_stamp_us = now_us
            # A budget: the stall timeout plus the first cost at a crawl (0.25 m/s).
            self._budget_us.setdefault(key, int((self.p.stall_timeout_s + 4.0 * c.cost_m) * 1e6))
            return
        self.target.cost_m = c.cost_m
        if c.cost_m < self._best_progress_m - 0.3:
            self._best_progress_m = c.cost_m
            self._progress_stamp_us = now_us
        if now_us - self._progress_stamp_us > self.p.stall_timeout_s * 1e6 \
                or self._time_on_us.get(key, 0) > self._budget_us[key]:
            # Paths keep promising but the robot gets no closer: give up on this target.
            self.waypoints.ban(c.x_m, c.y_m)
            self.dropped_stalled += 1
            self.target = None

    # --- routes -----------------------------------------------------------------------
    def _route(self, c: _Candidate, paths: GridPaths, topo_src, topo_dist, topo_parent,
               x_m: float, y_m: float) -> np.ndarray | None:
        """A local path to the target, or to the farthest vertex on the topological route
        towards it that the local map can reach."""
        reachable = paths.reachable
        wi, wj = self.map.cell_of(c.x_m, c.y_m)
        if self._in_window(wi, wj) and reachable[wi, wj]:
            return self._path_xy(paths.path(wi, wj))
        if topo_src is None:
            return None
        _, goal_vertex = self.topo.cost_to(topo_dist, c.x_m, c.y_m)
        if goal_vertex is None:
            return None
        xy = self.topo.positions()
        route = self.topo.path(topo_parent, goal_vertex)
        best = None
        for k, v in enumerate(route):
            vi, vj = self.map.cell_of(xy[v, 0], xy[v, 1])
            if not self._in_window(vi, vj):
                continue
            hit = nearest_traversable(reachable, vi, vj, 3)
            if hit is not None:
                best = (v, hit)
            elif k > 0 and best is not None and best[0] == route[k - 1] and cell_known(self.map, vi, vj):
                # The graph steps from a place we can reach to a known place we cannot: in our
                # map that edge crosses a wall. Never route along it again.
                self.blocked_edges.add(self.topo.edge_key(route[k - 1], v))
                break
        if best is None or math.hypot(xy[best[0], 0] - x_m, xy[best[0], 1] - y_m) < self.p.waypoint_reached_m:
            return None  # the only reachable place on the way is where we stand: no progress
        return self._path_xy(paths.path(best[1][0], best[1][1]))


def cell_known(local_map: LocalMap, i: int, j: int) -> bool:
    """Is the cell observed (free or wall) in the local map, rather than unknown?"""
    p = local_map.p
    v = local_map.logodds[i, j]
    return bool(v > p.logodds_occupied or v < p.logodds_free)
