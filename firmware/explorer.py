"""One planning cycle of the explorer: map layers, reachability, waypoints, target choice,
and a path to the target through the local map or, beyond it, the topological graph."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from firmware import kernels
from firmware.local_map import LocalMap
from firmware.params import ExplorationParams
from firmware.topo_map import TopoMap
from firmware.waypoints import Waypoint, WaypointSet


@dataclass
class Target:
    x_m: float
    y_m: float
    cost_m: float


@dataclass
class Plan:
    target: Target | None
    path_xy: np.ndarray            # world points to follow, robot first
    reachable_entropy_bit: float   # information of the waypoints reachable in the local map
    done: bool                     # nothing left to explore that this robot can reach


def nearest_traversable(traversable: np.ndarray, i: int, j: int, radius_cells: int) -> tuple[int, int] | None:
    """The traversable cell closest to (i, j) within a square of radius_cells (lowest index on ties)."""
    n_r, n_c = traversable.shape
    i0, i1 = max(i - radius_cells, 0), min(i + radius_cells + 1, n_r)
    j0, j1 = max(j - radius_cells, 0), min(j + radius_cells + 1, n_c)
    cells = np.argwhere(traversable[i0:i1, j0:j1])
    if len(cells) == 0:
        return None
    d2 = (cells[:, 0] + i0 - i) ** 2 + (cells[:, 1] + j0 - j) ** 2
    k = int(np.argmin(d2))
    return int(cells[k, 0] + i0), int(cells[k, 1] + j0)


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


class Explorer:
    """Greedy exploration over the local map and the robot's topological map."""

    def __init__(self, params: ExplorationParams, local_map: LocalMap, topo: TopoMap) -> None:
        self.p = params
        self.map = local_map
        self.topo = topo
        self.waypoints = WaypointSet(params)
        self.target: Target | None = None
        self._best_progress_m = math.inf
        self._progress_stamp_us = 0
        self.dropped_unreachable = 0
        self.dropped_stalled = 0
        self.reached = 0

    def _path_xy(self, cells: list[tuple[int, int]]) -> np.ndarray:
        return np.array([self.map.center_of(i, j) for i, j in cells], np.float64).reshape(-1, 2)

    def plan(self, x_m: float, y_m: float, now_us: int) -> Plan:
        p = self.p
        res = p.resolution_m
        layers = self.map.layers()
        ri, rj = self.map.cell_of(x_m, y_m)
        start = nearest_traversable(layers.traversable, ri, rj, int(math.ceil(0.8 / res)))
        if start is None:
            # Boxed in by the safety margin (e.g. after being pushed near a wall): plan from
            # the nearest known-free cell instead, so the robot can back out.
            start = nearest_traversable(layers.state == kernels.FREE, ri, rj, int(math.ceil(0.8 / res)))
            if start is None:
                return Plan(None, np.zeros((0, 2)), 0.0, False)
            layers.traversable[start] = True
        dist, parent = kernels.dijkstra_grid(layers.traversable, layers.cell_cost, start[0], start[1])
        reachable = np.isfinite(dist)
        self.waypoints.update(self.map, layers.state, reachable)

        # A target reached is done with: its surroundings are now observed (or unobservable).
        if self.target is not None and math.hypot(self.target.x_m - x_m, self.target.y_m - y_m) < p.waypoint_reached_m:
            self.waypoints.ban(self.target.x_m, self.target.y_m)
            self.reached += 1
            self.target = None

        topo_src, topo_dist, topo_parent = self.topo.costs_from(x_m, y_m)
        reachable_entropy = 0.0
        candidates: list[tuple[float, int, Waypoint]] = []
        for k, w in enumerate(self.waypoints.items):
            wi, wj = self.map.cell_of(w.x_m, w.y_m)
            if 0 <= wi < self.map.n and 0 <= wj < self.map.n and reachable[wi, wj]:
                cost = float(dist[wi, wj]) * res
                reachable_entropy += w.e_bit
            else:
                cost, _ = self.topo.cost_to(topo_dist, w.x_m, w.y_m)
                if topo_src is not None:
                    src_x, src_y = self.topo.positions()[topo_src]
                    cost += math.hypot(src_x - x_m, src_y - y_m)
            candidates.append((cost, k, w))

        while candidates:
            choice = self._choose(candidates)
            w = choice[2]
            path = self._route(w, dist, parent, reachable, topo_src, topo_dist, topo_parent, x_m, y_m)
            if path is not None:
                self._track_progress(w, choice[0], now_us)
                if self.target is None:
                    return Plan(None, np.zeros((0, 2)), reachable_entropy, False)
                return Plan(self.target, path, reachable_entropy, False)
            # No way there from here, not even through the topological map: drop it for good.
            self.waypoints.ban(w.x_m, w.y_m)
            self.dropped_unreachable += 1
            candidates = [c for c in candidates if c[2] in self.waypoints.items]
            self.target = None
        self.target = None
        return Plan(None, np.zeros((0, 2)), 0.0, True)

    def _choose(self, candidates: list[tuple[float, int, Waypoint]]) -> tuple[float, int, Waypoint]:
        """Greedy: the closest target. The current target is kept unless another is clearly
        closer, so the robot does not dither between two nearly equal choices."""
        best = min(candidates, key=lambda c: (c[0], c[1]))
        if self.target is not None:
            for c in candidates:
                if c[2].x_m == self.target.x_m and c[2].y_m == self.target.y_m and best[0] >= 0.8 * c[0]:
                    return c
        return best

    def _track_progress(self, w: Waypoint, cost_m: float, now_us: int) -> None:
        same = self.target is not None and (self.target.x_m, self.target.y_m) == (w.x_m, w.y_m)
        if not same:
            self.target = Target(w.x_m, w.y_m, cost_m)
            self._best_progress_m = cost_m
            self._progress_stamp_us = now_us
            return
        self.target.cost_m = cost_m
        if cost_m < self._best_progress_m - 0.3:
            self._best_progress_m = cost_m
            self._progress_stamp_us = now_us
        elif now_us - self._progress_stamp_us > self.p.stall_timeout_s * 1e6:
            # Planned paths keep promising but the robot gets no closer: give up on it.
            self.waypoints.ban(w.x_m, w.y_m)
            self.dropped_stalled += 1
            self.target = None

    def _route(self, w: Waypoint, dist, parent, reachable, topo_src, topo_dist, topo_parent, x_m: float, y_m: float) -> np.ndarray | None:
        """A local path to the waypoint, or to the farthest vertex on the topological route
        towards it that the local map can reach."""
        n = self.map.n
        wi, wj = self.map.cell_of(w.x_m, w.y_m)
        if 0 <= wi < n and 0 <= wj < n and reachable[wi, wj]:
            return self._path_xy(extract_path(parent, wi, wj))
        if topo_src is None:
            return None
        _, goal_vertex = self.topo.cost_to(topo_dist, w.x_m, w.y_m)
        if goal_vertex is None:
            return None
        route = self.topo.path(topo_parent, goal_vertex)
        xy = self.topo.positions()
        for v in reversed(route):
            vi, vj = self.map.cell_of(xy[v, 0], xy[v, 1])
            if not (0 <= vi < n and 0 <= vj < n):
                continue
            hit = nearest_traversable(reachable, vi, vj, 3)
            if hit is None:
                continue
            if math.hypot(xy[v, 0] - x_m, xy[v, 1] - y_m) < self.p.waypoint_reached_m:
                break  # the only reachable vertex on the way is where we stand: no progress
            return self._path_xy(extract_path(parent, hit[0], hit[1]))
        return None
