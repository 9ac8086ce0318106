"""One planning cycle, shared by every scheme: map layers, reachability, waypoints, the
scheme's stage (filter, then rank), target choice, and a path to the target through the
local map or, beyond it, along the topological graph of visited places (or, where neither
has one, through everything mapped).

    layers, start cell, grid search        services.grid_paths
    waypoints W re-scored and found        services.waypoints
    target seen on the way?                services.targets
    scheme.filter_waypoints                the scheme (e.g. Bayer & Faigl's presence rule)
    target reached?                        services.targets
    scheme.rank(own candidates)            the scheme (team targets, costs, Greedy / MinPos)
    choose, route, strikes, stall budget   services.targets and the routes below
    nothing left: a last look, a tight     services.waypoints, services.known_map
    retry, frontiers anywhere mapped
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from firmware import kernels
from firmware.params import ExplorationParams
from firmware.schemes.base import PlanningView, Scheme
from firmware.services.grid_paths import GridPaths, cell_known, escape_start, lines_of_sight, nearest_traversable
from firmware.services.known_map import Frontier, KnownMap, find_frontiers
from firmware.services.local_map import LocalMap
from firmware.services.targets import Candidate, Target, TargetKeeper
from firmware.services.topo_map import TopoMap
from firmware.services.waypoints import WaypointSet

PLACE_SNAP_CELLS = 3    # a topological place counts as reachable with a reachable cell this near
MAX_REACHED_KEPT = 4096  # bounded memory for where targets were reached (the latest kept)


@dataclass
class Plan:
    target: Target | None
    path_xy: np.ndarray            # world points to follow, robot first
    done: bool                     # nothing left to explore that this robot can reach
    clearance_m: np.ndarray = field(default_factory=lambda: np.zeros(0))   # room at each point
    recover: bool = False          # a target failed for the first time: recover, then retry it
    slow: bool = False             # a retry after a recovery: drive the path slowly


class Planner:
    def __init__(self, params: ExplorationParams, local_map: LocalMap, topo: TopoMap,
                 waypoints: WaypointSet, targets: TargetKeeper, scheme: Scheme) -> None:
        self.p = params
        self.map = local_map
        self.topo = topo
        self.waypoints = waypoints
        self.targets = targets
        self.scheme = scheme
        self._search_arrays: tuple | None = None   # GridPaths' arrays, reused plan after plan
        # Edges of the topological map that this robot's own map shows crossing a wall.
        self.blocked_edges: set[tuple[tuple[int, int], tuple[int, int]]] = set()
        # What was left when the robot had nothing more to explore (the last plan's).
        self.frontiers = FrontiersLeft()
        # Everything mapped, for routes the window and the graph cannot give and for what is
        # left anywhere before the robot stops; frontiers (global cells) it sent the robot to.
        self.known = KnownMap(params, local_map)
        self.known_unfelt = KnownMap(params, local_map, felt=False)   # for what is left at the end
        self._far_tried: dict[tuple[int, int], bool] = {}     # True: the scheme left it to a teammate
        # Until then plans are tight (faces at their cells' centres, passages at no extra cost)
        # and slow: the retry after a recovery (the agent sets it when one ends).
        self.tight_until_us = -1
        self._tried_tight: set[tuple[int, int]] = set()   # frontier cells (global) a tight retry was for
        self._reached_xy: list[tuple[float, float]] = []   # where targets were reached (the latest)
        # Driving back across a way the map has closed (_way_back): the trail point beyond
        # the closure being tried and until when; where earlier tries went; how many.
        self._way_back_try: tuple[tuple[float, float], int] | None = None
        self._ways_back_tried: list[tuple[float, float]] = []
        self.ways_back = 0
        self._beyond_closed_ways: tuple[Frontier, ...] = ()     # the last stop's (_behind_closed_ways)

    def _path(self, cells: list[tuple[int, int]], layers) -> tuple[np.ndarray, np.ndarray]:
        """World points through the cells, each at the cell's best point (its centre unless a
        wall is near: in a door an even number of cells wide that is the door's middle, on a
        cell edge), and the room there."""
        ij = np.array(cells, np.int64).reshape(-1, 2)
        half_cells = 0.5 * kernels.SUBCELL_OFFSETS[layers.standing[ij[:, 0], ij[:, 1]]]
        res = self.p.resolution_m
        x = (self.map.col0 + ij[:, 1] + 0.5) * res + half_cells[:, 1] * res
        y = (self.map.row0 + ij[:, 0] + 0.5) * res + half_cells[:, 0] * res
        return np.column_stack([x, y]), layers.clearance_m[ij[:, 0], ij[:, 1]].astype(np.float64)

    def _in_window(self, i: int, j: int) -> bool:
        return 0 <= i < self.map.n and 0 <= j < self.map.n

    def plan(self, x_m: float, y_m: float, now_us: int) -> Plan:
        p = self.p
        res = p.resolution_m
        tight = now_us < self.tight_until_us
        layers = self.map.layers(tight=tight)
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
        topo_src, topo_dist, topo_parent = self.topo.costs_from(x_m, y_m, frozenset(self.blocked_edges))
        to_src_m = 0.0
        if topo_src is not None:
            sx, sy = self.topo.positions()[topo_src]
            to_src_m = math.hypot(sx - x_m, sy - y_m)

        self._tell(self.targets.end_if_seen_on_way(x_m, y_m), "seen_on_way")
        view = self._view(x_m, y_m, now_us, layers.sight, topo_dist, to_src_m)
        view.reachable = reachable
        self.scheme.filter_waypoints(view)
        self._tell(self.targets.end_if_reached(x_m, y_m), "reached")
        view.target = self.targets.target
        held = None if self.targets.target is None else (self.targets.target.x_m, self.targets.target.y_m)
        own = [Candidate(w.x_m, w.y_m, w.e_bit, False) for w in self.waypoints.worth_heading_for(x_m, y_m, held)]
        candidates = self.scheme.rank(view, own)
        self.targets.forget_strikes_except(candidates)
        self._place_in_window(candidates, paths)

        # Candidates routed through the whole map, with their cells: costed by that way, they
        # take their turn again (the graph may have called them near across a wall).
        through_known: dict[tuple[float, float], list[tuple[int, int]] | None] = {}
        while candidates:
            settle_choice_costs(candidates, paths, self.targets.target, self.p.resolution_m)
            c = self.targets.choose(candidates)
            key = (c.x_m, c.y_m)
            cells, leap_m = self._route(c, paths, layers.state, topo_src, topo_dist, topo_parent, x_m, y_m)
            if cells is None or leap_m > p.d_cam_m:
                # No way in the window or along the graph, or the graph's way ends in a
                # straight line longer than a look reaches (across what the graph never
                # saw): the way through everything mapped is the truer one, if there is one.
                if key not in through_known:
                    graph_cost_m = c.cost_m
                    through_known[key] = self._route_through_known(c, paths, x_m, y_m, now_us)
                    if through_known[key] is not None and c.cost_m > graph_cost_m:
                        continue
                if through_known[key] is not None:
                    cells = through_known[key]
            if cells is not None:
                reaches_it = tuple(cells[-1]) == self.map.cell_of(c.x_m, c.y_m)
                ended = self.targets.head_for(c, now_us, reaches_it)
                self._tell(ended, "stalled")
                if self.targets.recovery_wanted and not tight:
                    self._spare_hopeless_recoveries(start)
                if self.targets.recovery_wanted:
                    return Plan(self.targets.target, np.zeros((0, 2)), False, recover=True)
                if self.targets.target is None:
                    return Plan(None, np.zeros((0, 2)), False)
                xy, room = self._path(cells, layers)
                return Plan(self.targets.target, xy, False, room, slow=tight)
            target = Target(c.x_m, c.y_m, c.cost_m, c.from_team)
            if self.targets.strike(c, now_us):
                self._tell(target, "unreachable")
            candidates = [k for k in candidates if (k.x_m, k.y_m) != key and not self.waypoints.is_banned(k.x_m, k.y_m)]
        self.targets.target = None
        if self.targets.recovery_wanted and not tight:
            self._spare_hopeless_recoveries(start)
        if self.targets.recovery_wanted:
            return Plan(None, np.zeros((0, 2)), False, recover=True)
        if self.targets.strikes_pending():
            return Plan(None, np.zeros((0, 2)), False)
        last_look = self.waypoints.look_again(self.map, layers.sight, reachable, x_m, y_m)
        if last_look is not None:
            # The scheme may still leave it to a teammate that reported having seen it.
            self.scheme.filter_waypoints(dataclasses.replace(view, closing=True))
            if last_look in self.waypoints.items:
                return Plan(None, np.zeros((0, 2)), False)  # the next cycle heads there
        near = [f.cell for f in find_frontiers(layers.sight, reachable, p, self.map.row0, self.map.col0).unreachable]
        if not tight and self._untried(near):
            # Frontiers the body cannot reach on the map's expected walls: recover and look
            # for a way on tight paths before saying so.
            self._tried_tight |= set(near)
            return Plan(None, np.zeros((0, 2)), False, recover=True)
        way_back = self._way_back_on(x_m, y_m, now_us)
        if way_back is not None:
            return way_back
        if self._head_for_far_frontier(view, x_m, y_m, now_us):
            return Plan(None, np.zeros((0, 2)), False)  # the next cycle heads there
        way_back = self._way_back(now_us)
        if way_back is not None:
            return way_back
        return Plan(None, np.zeros((0, 2)), True)

    def _spare_hopeless_recoveries(self, start: tuple[int, int]) -> None:
        """Targets in the window that ask for a recovery but that not even tight paths (the
        most room there can be) reach from here go without one. A recovery's worth is its
        tight retry: the LiDAR sees all round already, so turning on the spot shows little
        new, and the retry would crawl at min_speed_mps for recovery_retry_s towards a place
        the map walls in."""
        layers = self.map.layers(tight=True)
        traversable = layers.traversable
        traversable[start] = True
        reachable = kernels.reachable_cells(traversable, start[0], start[1])
        hopeless = set()
        for key in self.targets.waiting_for_recovery():
            wi, wj = self.map.cell_of(*key)
            if self._in_window(wi, wj) and not reachable[wi, wj]:
                hopeless.add(key)
        self.targets.no_recovery_for(hopeless)

    def _head_for_far_frontier(self, view: PlanningView, x_m: float, y_m: float, now_us: int) -> bool:
        """A robot about to stop: a frontier its body can reach anywhere in what it has
        mapped, not tried yet and not where it failed to get to before, becomes a waypoint
        (bans near it lifted), the nearest first. Each frontier gets one try; what is left
        after that is recorded in self.frontiers. True if the robot heads for one."""
        self.known.refresh(x_m, y_m, now_us, force=True)
        found = self.known.frontiers()
        fresh = [f for f in found.reachable if not self._near_tried(f) and not self.waypoints.failed_near(*f.stand_xy)]
        for f in sorted(fresh, key=lambda f: (math.hypot(f.stand_xy[0] - x_m, f.stand_xy[1] - y_m), f.cell)):
            w = self.waypoints.take_up(f.stand_xy[0], f.stand_xy[1], f.hidden_bit)
            # The scheme may leave it to a teammate that reported having seen it.
            self.scheme.filter_waypoints(dataclasses.replace(view, closing=True))
            self._far_tried[f.cell] = w not in self.waypoints.items
            if not self._far_tried[f.cell]:
                return True
        left = [f for f in found.reachable if not self._left_to_team(f)]
        # A frontier still there after the robot reached the place nearest it that its body
        # can get to is seen only through a gap narrower than the body (a pocket in clutter,
        # a crack in rock): no way on, as behind such a gap.
        looked_at = tuple(f for f in left if self._reached_near(f.stand_xy))
        given_up = tuple(f for f in left if f not in looked_at)
        self._beyond_closed_ways = self._behind_closed_ways(found.unreachable)
        suspect = self._beyond_closed_ways + self._behind_felt_obstacles(found.unreachable, x_m, y_m, now_us)
        suspect = tuple(f for k, f in enumerate(suspect) if f not in suspect[:k])
        self.frontiers = FrontiersLeft(given_up + suspect,
                                       tuple(f for f in found.unreachable if f not in suspect) + looked_at)
        return False

    def _reached_near(self, xy: tuple[float, float]) -> bool:
        """Did the robot reach a target within ban_radius_m of this point? (The place nearest
        a frontier shifts as the map around it fills in.)"""
        r = self.p.ban_radius_m
        return any(math.hypot(x - xy[0], y - xy[1]) <= r for x, y in self._reached_xy)

    def _behind_closed_ways(self, unreachable: tuple[Frontier, ...]) -> tuple[Frontier, ...]:
        """Of the frontiers the body cannot reach, those it could from places it has driven
        that the map no longer joins it to: the map has closed a way the body took, so no gap
        it shows there narrower than the body is known to be. Frontiers in parts of the map
        the robot never drove through stay behind their gaps."""
        if not unreachable:
            return ()
        trail = self.map.trail()
        cut = self.known.cut_off(trail, self.p.escape_radius_m)
        if not cut.any():
            return ()
        beyond = {f.cell for f in self.known.frontiers_from(trail[cut], self.p.escape_radius_m).reachable}
        return tuple(f for f in unreachable if f.cell in beyond)

    def _way_back(self, now_us: int) -> Plan | None:
        """A robot about to stop whose map has closed a way it drove, with frontiers beyond
        (_behind_closed_ways): before giving them up it drives back the way it came, from
        where it stands through what it reaches to the last trail point it still reaches
        before the closure, then along the trail across the closure to the first point cut
        off, on tight, slow plans. The body went through there, so it fits; the map drew the
        gap narrower later (a jamb seen from another side, a drifted pose, an obstacle felt).
        Each place beyond a closure gets one try, of at most the time the way takes at
        min_speed_mps plus recovery_retry_s, and a mission at most ways_back_max; None when
        none is left to try."""
        p = self.p
        if self.ways_back >= p.ways_back_max or not self._beyond_closed_ways:
            return None
        trail = self.map.trail()
        cut = self.known.cut_off(trail, p.escape_radius_m)
        spacing_m = 2.0 * p.escape_radius_m
        fresh = [k for k in np.nonzero(cut)[0].tolist()
                 if all(math.hypot(trail[k, 0] - tx, trail[k, 1] - ty) > spacing_m for tx, ty in self._ways_back_tried)]
        if not fresh:
            return None
        k = max(fresh)                  # the most recent place beyond a closure
        self._ways_back_tried.append((float(trail[k, 0]), float(trail[k, 1])))
        self.ways_back += 1
        return self._way_back_plan(trail, k, now_us, None)

    def _way_back_on(self, x_m: float, y_m: float, now_us: int) -> Plan | None:
        """The way back being tried (_way_back), from where the robot is now, while its time
        lasts and its end is still cut off; None once it is over."""
        if self._way_back_try is None:
            return None
        beyond_xy, until_us = self._way_back_try
        self.known.refresh(x_m, y_m, now_us)
        trail = self.map.trail()
        k = self._trail_index(trail, beyond_xy)
        if now_us < until_us and k is not None and self.known.cut_off(trail[k:k + 1], self.p.escape_radius_m)[0]:
            return self._way_back_plan(trail, k, now_us, until_us)
        self._way_back_try = None
        return None

    @staticmethod
    def _trail_index(trail: np.ndarray, xy: tuple[float, float]) -> int | None:
        """The index of this trail point (the latest if it is there more than once)."""
        hit = np.nonzero((trail[:, 0] == xy[0]) & (trail[:, 1] == xy[1]))[0]
        return int(hit[-1]) if len(hit) else None

    def _way_back_plan(self, trail: np.ndarray, k: int, now_us: int, until_us: int | None) -> Plan:
        """The way to trail[k] across the closure: the map's route to the first trail point
        after k that it reaches (from where the robot stands when none does), then the trail
        from there back to k, a point every cell."""
        p = self.p
        head_xy, head_room = np.zeros((0, 2)), np.zeros(0)
        j = k + 1
        while j < len(trail):
            found = self.known.route(float(trail[j, 0]), float(trail[j, 1]))
            if found is not None:
                head_xy = found[0]
                head_room = self.known.clearance_at(head_xy)
                break
            j += 1
        start = head_xy[-1] if len(head_xy) else self.known.built_xy()
        corners = np.vstack([start, trail[k:min(j, len(trail))][::-1]])
        tail = [start.reshape(1, 2)]
        for a, b in zip(corners[:-1], corners[1:]):
            steps = max(int(math.ceil(math.hypot(*(b - a)) / p.resolution_m)), 1)
            tail.append(a + (b - a) * (np.arange(1, steps + 1) / steps)[:, None])
        tail_xy = np.vstack(tail)[1:]
        path_xy = np.vstack([head_xy, tail_xy])
        room = np.concatenate([head_room, np.zeros(len(tail_xy))])   # the closure: as close as it gets
        if until_us is None:
            length_m = float(np.sum(np.hypot(*np.diff(path_xy, axis=0).T))) if len(path_xy) > 1 else 0.0
            until_us = now_us + int((length_m / p.min_speed_mps + p.recovery_retry_s) * 1e6)
            self._way_back_try = ((float(trail[k, 0]), float(trail[k, 1])), until_us)
        self.tight_until_us = max(self.tight_until_us, until_us)
        return Plan(None, path_xy, False, room, slow=True)

    def _behind_felt_obstacles(self, unreachable: tuple[Frontier, ...], x_m: float, y_m: float,
                               now_us: int) -> tuple[Frontier, ...]:
        """Of the frontiers the body cannot reach, those it could if the obstacles it only
        felt were not there. Such a gap is not known to be narrower than the body (the robot
        may have driven through it before, its pose since drifted): they count as given up,
        not as behind gaps the body does not fit."""
        if not unreachable or not self.map.bumps:
            return ()
        self.known_unfelt.refresh(x_m, y_m, now_us, force=True)
        open_cells = [f.cell for f in self.known_unfelt.frontiers().reachable]
        return tuple(f for f in unreachable if self._near(f.cell, open_cells))

    def _near(self, cell: tuple[int, int], cells) -> bool:
        """Is the frontier at this global cell one of those at `cells`, within ban_radius_m?
        (A frontier's middle shifts a little as the map fills in.)"""
        r2 = (self.p.ban_radius_m / self.p.resolution_m) ** 2
        return any((cell[0] - i) ** 2 + (cell[1] - j) ** 2 <= r2 for i, j in cells)

    def _near_tried(self, f: Frontier) -> bool:
        """Did an earlier try go to this frontier?"""
        return self._near(f.cell, self._far_tried)

    def _left_to_team(self, f: Frontier) -> bool:
        return self._near(f.cell, [cell for cell, team in self._far_tried.items() if team])

    def _untried(self, cells: list[tuple[int, int]]) -> bool:
        """Is any of these frontier cells (global) not one a tight retry was for?"""
        return any(not self._near(c, self._tried_tight) for c in cells)

    def _place_in_window(self, candidates: list[Candidate], paths: GridPaths) -> None:
        """Candidates a grid path in the local map reaches are costed by that path, the
        others by the scheme's cost beyond the window. Grid costs are filled in lazily by
        settle_choice_costs: until then they read inf."""
        for c in candidates:
            wi, wj = self.map.cell_of(c.x_m, c.y_m)
            local = self._in_window(wi, wj) and paths.reachable[wi, wj]
            c.local_cell = (wi, wj) if local else None
            c.cost_m = math.inf if local else c.graph_cost_m

    def _tell(self, target: Target | None, outcome: str) -> None:
        if target is not None and outcome == "reached":
            self._reached_xy.append((target.x_m, target.y_m))
            del self._reached_xy[:-MAX_REACHED_KEPT]
        if target is not None:
            self.scheme.on_target_outcome(target, outcome)

    def _view(self, x_m: float, y_m: float, now_us: int, sight: np.ndarray, topo_dist: np.ndarray,
              to_src_m: float) -> PlanningView:
        def graph_costs(candidates: list[Candidate]) -> np.ndarray:
            """Costs (m) along the topological graph, from the robot's position."""
            return self.topo.costs_to(topo_dist, [c.x_m for c in candidates], [c.y_m for c in candidates]) + to_src_m

        return PlanningView(x_m, y_m, now_us, sight, self.targets.target, frozenset(self.blocked_edges),
                            graph_costs)

    # --- routes -----------------------------------------------------------------------
    def _route(self, c: Candidate, paths: GridPaths, state: np.ndarray, topo_src, topo_dist, topo_parent,
               x_m: float, y_m: float) -> tuple[list[tuple[int, int]] | None, float]:
        """The cells of a local path to the target, or to the farthest vertex on the
        topological route towards it that the local map can reach; and the straight line (m)
        the graph's way ends with (0 on a path to the target itself)."""
        reachable = paths.reachable
        wi, wj = self.map.cell_of(c.x_m, c.y_m)
        in_window = self._in_window(wi, wj)
        if in_window and reachable[wi, wj]:
            return paths.path(wi, wj), 0.0
        if topo_src is None:
            return None, math.inf
        _, goal_vertex = self.topo.cost_to(topo_dist, c.x_m, c.y_m)
        if goal_vertex is None:
            return None, math.inf
        xy = self.topo.positions()
        leap_m = math.hypot(xy[goal_vertex, 0] - c.x_m, xy[goal_vertex, 1] - c.y_m)
        if in_window and self._walled_off(xy[goal_vertex], (wi, wj), reachable, state):
            # The graph ends at a place the robot can drive to, short of c, and finishes with
            # a straight line through a wall: following it leads to that place and no
            # further. Only a way out of the window and back can help (the caller's route
            # through everything mapped), or none does.
            return None, leap_m
        route = self.topo.path(topo_parent, goal_vertex)
        best = None
        for k, v in enumerate(route):
            vi, vj = self.map.cell_of(xy[v, 0], xy[v, 1])
            if not self._in_window(vi, vj):
                continue
            hit = nearest_traversable(reachable, vi, vj, PLACE_SNAP_CELLS)
            if hit is not None:
                best = (v, hit)
            elif k > 0 and best is not None and best[0] == route[k - 1] and cell_known(self.map, vi, vj):
                # The graph steps from a place we can reach to a known place we cannot: in our
                # map that edge crosses a wall. Never route along it again.
                self.blocked_edges.add(self.topo.edge_key(route[k - 1], v))
                break
        if best is None or math.hypot(xy[best[0], 0] - x_m, xy[best[0], 1] - y_m) < self.p.waypoint_reached_m:
            return None, leap_m  # the only reachable place on the way is where we stand: no progress
        return paths.path(best[1][0], best[1][1]), leap_m

    def _walled_off(self, place_xy_m: np.ndarray, goal: tuple[int, int], reachable: np.ndarray,
                    state: np.ndarray) -> bool:
        """Is the place in the window, with a grid-reachable cell near it, farther than a
        target is reached from the goal cell, and with a known wall on the straight line
        between them? (Unknown cells on the line are no reason: driving there may open it.)"""
        vi, vj = self.map.cell_of(float(place_xy_m[0]), float(place_xy_m[1]))
        if not self._in_window(vi, vj) or nearest_traversable(reachable, vi, vj, PLACE_SNAP_CELLS) is None:
            return False
        if math.hypot(vi - goal[0], vj - goal[1]) * self.p.resolution_m <= self.p.waypoint_reached_m:
            return False
        return not lines_of_sight(state, [vi], [vj], [goal[0]], [goal[1]])[0]

    def _route_through_known(self, c: Candidate, paths: GridPaths, x_m: float, y_m: float,
                             now_us: int) -> list[tuple[int, int]] | None:
        """When neither the window nor the graph has a way to c, or the graph's ends in a long
        straight line: the cells of a local path along the shortest way through everything
        mapped (services.known_map), as far as that way stays in the window on cells a grid
        path reaches; None if there is no such way, if it makes no progress, or if it never
        leaves the window's reach (then only c's own cell is cut off, and it is struck as
        before)."""
        self.known.refresh(x_m, y_m, now_us)
        found = self.known.route(c.x_m, c.y_m)
        if found is None:
            return None
        xy, cost_m = found
        ij, inside = self.map.cells_of(xy)
        ok = inside.copy()
        ok[inside] = paths.reachable[ij[inside, 0], ij[inside, 1]]
        if ok.all():
            return None
        stretch = int(np.argmin(ok))
        if stretch == 0:
            return None
        end = ij[stretch - 1]
        if math.hypot(xy[stretch - 1, 0] - x_m, xy[stretch - 1, 1] - y_m) < self.p.waypoint_reached_m:
            return None
        c.cost_m = cost_m
        return paths.path(int(end[0]), int(end[1]))


@dataclass(frozen=True)
class FrontiersLeft:
    """What a robot that stopped left behind, in all it had mapped: frontiers its body could
    get to but that it failed to (given_up: tried, and still there; or cut off only by
    obstacles it felt and did not see; or reached from places it has driven that its map no
    longer joins it to), and frontiers behind gaps narrower than its body as mapped
    or seen only through one (behind_gaps: still there after the robot reached the place
    nearest them its body can get to). Each hides at least report_unreachable_bit."""
    given_up: tuple[Frontier, ...] = ()
    behind_gaps: tuple[Frontier, ...] = ()

    @staticmethod
    def area_m2(frontiers: tuple[Frontier, ...]) -> float:
        return float(sum(f.area_m2 for f in frontiers))

    def middles_xy(self, resolution_m: float) -> np.ndarray:
        """Every frontier's middle cell's centre (n, 2, metres), given up first."""
        cells = np.array([f.cell for f in self.given_up + self.behind_gaps], np.float64).reshape(-1, 2)
        return (cells[:, ::-1] + 0.5) * resolution_m


def settle_choice_costs(candidates: list[Candidate], paths: GridPaths, target: Target | None,
                        resolution_m: float) -> None:
    """Exact costs for every candidate the choice could take, and no more search than that.
    The choice (TargetKeeper.choose) takes the lowest rank, then the lowest cost plus
    penalty, then keeps the current target unless it costs much more. So the search settles
    the nearest grid candidate of the lowest rank, then every cell up to the cheapest cost
    plus penalty of that rank less the smallest penalty, and the current target's cell; the
    grid candidates it leaves unsettled all come out dearer than the cheapest and keep
    reading inf. The search is Dijkstra's (cells settle in order of cost), so the choice is
    the one costing every candidate would give."""
    r0 = min(c.rank for c in candidates)
    group = [c for c in candidates if c.rank == r0]
    _read_costs(group, paths, resolution_m)     # settled on the way to an earlier choice
    if any(c.by_gain for c in group):
        # A choice by gain per metre needs every cost of the group.
        local = [c for c in group if c.local_cell is not None and not paths.settled(*c.local_cell)]
        if local:
            paths.settle([c.local_cell[0] for c in local], [c.local_cell[1] for c in local])
            _read_costs(local, paths, resolution_m)
        return
    waiting = [c for c in group if c.local_cell is not None and not paths.settled(*c.local_cell)]
    if waiting:
        paths.settle_first([c.local_cell[0] for c in waiting], [c.local_cell[1] for c in waiting])
        _read_costs(waiting, paths, resolution_m)
        bound_m = min(c.cost_m + c.penalty_m for c in group) - min(c.penalty_m for c in group)
        # A little above the bound, so that no cost equal to it after rounding is missed.
        paths.settle_below(bound_m / resolution_m * (1.0 + 1e-9) + 1e-9)
        _read_costs(waiting, paths, resolution_m)
    if target is not None:
        held = [c for c in group if (c.x_m, c.y_m) == (target.x_m, target.y_m) and c.local_cell is not None]
        if held:
            paths.settle([c.local_cell[0] for c in held], [c.local_cell[1] for c in held])
            _read_costs(held, paths, resolution_m)


def _read_costs(candidates: list[Candidate], paths: GridPaths, resolution_m: float) -> None:
    for c in candidates:
        if c.local_cell is not None and paths.settled(*c.local_cell):
            c.cost_m = float(paths.dist[c.local_cell]) * resolution_m
