"""One planning cycle, shared by every scheme: map layers, reachability, waypoints, the
scheme's stage (filter, then rank), target choice, and a path to the target through the
local map or, beyond it, along the topological graph of visited places.

    layers, start cell, grid search        services.grid_paths
    waypoints W re-scored and found        services.waypoints
    target seen on the way?                services.targets
    scheme.filter_waypoints                the scheme (e.g. Bayer & Faigl's presence rule)
    target reached?                        services.targets
    scheme.rank(own candidates)            the scheme (team targets, costs, Greedy / MinPos)
    choose, route, strikes, stall budget   services.targets and the routes below
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from firmware import kernels
from firmware.params import ExplorationParams
from firmware.schemes.base import PlanningView, Scheme
from firmware.services.grid_paths import GridPaths, cell_known, escape_start, nearest_traversable
from firmware.services.local_map import LocalMap
from firmware.services.targets import Candidate, Target, TargetKeeper
from firmware.services.topo_map import TopoMap
from firmware.services.waypoints import WaypointSet


@dataclass
class Plan:
    target: Target | None
    path_xy: np.ndarray            # world points to follow, robot first
    done: bool                     # nothing left to explore that this robot can reach


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

    def _path_xy(self, cells: list[tuple[int, int]]) -> np.ndarray:
        return np.array([self.map.center_of(i, j) for i, j in cells], np.float64).reshape(-1, 2)

    def _in_window(self, i: int, j: int) -> bool:
        return 0 <= i < self.map.n and 0 <= j < self.map.n

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
        self._tell(self.targets.end_if_seen_on_way(x_m, y_m), "seen_on_way")
        graph: list = []    # (source vertex, distances, parents, metres to the source), once known
        view = self._view(x_m, y_m, now_us, layers.sight, paths, graph)
        self.scheme.filter_waypoints(view)
        self._tell(self.targets.end_if_reached(x_m, y_m), "reached")

        topo_src, topo_dist, topo_parent = self.topo.costs_from(x_m, y_m, frozenset(self.blocked_edges))
        to_src_m = 0.0
        if topo_src is not None:
            sx, sy = self.topo.positions()[topo_src]
            to_src_m = math.hypot(sx - x_m, sy - y_m)
        graph.extend((topo_dist, to_src_m))
        view.target = self.targets.target
        own = [Candidate(w.x_m, w.y_m, w.e_bit, False) for w in self.waypoints.items]
        candidates = self.scheme.rank(view, own)
        self.targets.forget_strikes_except(candidates)

        while candidates:
            c = self.targets.choose(candidates)
            path = self._route(c, paths, topo_src, topo_dist, topo_parent, x_m, y_m)
            if path is not None:
                ended = self.targets.head_for(c, now_us)
                self._tell(ended, "stalled")
                if self.targets.target is None:
                    return Plan(None, np.zeros((0, 2)), False)
                return Plan(self.targets.target, path, False)
            target = Target(c.x_m, c.y_m, c.cost_m, c.from_team)
            if self.targets.strike(c, now_us):
                self._tell(target, "unreachable")
            key = (c.x_m, c.y_m)
            candidates = [k for k in candidates if (k.x_m, k.y_m) != key and not self.waypoints.is_banned(k.x_m, k.y_m)]
        self.targets.target = None
        return Plan(None, np.zeros((0, 2)), not self.targets.strikes_pending())

    def _tell(self, target: Target | None, outcome: str) -> None:
        if target is not None:
            self.scheme.on_target_outcome(target, outcome)

    def _view(self, x_m: float, y_m: float, now_us: int, sight: np.ndarray, paths: GridPaths,
              graph: list) -> PlanningView:
        res = self.p.resolution_m

        def local_costs(candidates: list[Candidate]) -> tuple[np.ndarray, np.ndarray]:
            """Grid path lengths (m) in the local map, and which candidates it reaches."""
            cells = [self.map.cell_of(c.x_m, c.y_m) for c in candidates]
            local = [self._in_window(wi, wj) and paths.reachable[wi, wj] for wi, wj in cells]
            local_ij = np.array([ij for ij, ok in zip(cells, local) if ok], np.int64).reshape(-1, 2)
            paths.settle(local_ij[:, 0], local_ij[:, 1])
            cost = np.array([float(paths.dist[wi, wj]) * res if ok else math.inf
                             for (wi, wj), ok in zip(cells, local)], np.float64)
            return cost, np.array(local, bool)

        def graph_costs(candidates: list[Candidate]) -> np.ndarray:
            """Costs (m) along the topological graph, from the robot's position."""
            topo_dist, to_src_m = graph
            return self.topo.costs_to(topo_dist, [c.x_m for c in candidates], [c.y_m for c in candidates]) + to_src_m

        return PlanningView(x_m, y_m, now_us, sight, self.targets.target, frozenset(self.blocked_edges),
                            local_costs, graph_costs)

    # --- routes -----------------------------------------------------------------------
    def _route(self, c: Candidate, paths: GridPaths, topo_src, topo_dist, topo_parent,
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

