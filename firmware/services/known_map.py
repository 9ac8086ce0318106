"""Everything the robot has mapped, planned on as one grid: the window and every paged-out
tile. Planning works on the window (services.planner), and beyond it along the topological
graph of visited places. Two questions need more than that:

- a place the window shows but cannot route to, and the graph cannot either (the vertex
  nearest it lies across a wall, or the way round leaves the window): is there a way
  through what the robot has mapped? Without one the place was struck as unreachable and
  banned for good, although the robot had driven to it before (Willow Garage, one robot:
  108 targets struck, 0.97 coverage, rooms left unseen beside the corridors it used);
- a robot about to stop: is a frontier its body can reach left anywhere it has mapped,
  not just in the window around it? Only then may it say it is complete.

The whole map is derived from scratch when asked, at most once per known_map_refresh_s
while the robot stays within recenter_distance_m of where it was derived: both questions
come up seldom, and a place a few seconds out of date still shows the way.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.ndimage as ndimage

from firmware import kernels
from firmware.params import ExplorationParams
from firmware.services.body_fit import PlanningFits
from firmware.services.dilation import dilate_disc, dilate_square
from firmware.services.grid_paths import extract_path, lines_of_sight, nearest_traversable, traversable_near
from firmware.services.local_map import LocalMap, close_wall_gaps

# A group of fewer frontier cells is narrower than the body (0.5 m at 0.1 m cells): a speck
# of noise at a wall's foot, or a crack, not a way on.
MIN_FRONTIER_CELLS = 5
# How far from where a robot's centre can go it still stands at a frontier: its radius
# (0.25 m) and a cell, at 0.1 m cells.
REACH_CELLS = 4


@dataclass(frozen=True)
class Frontier:
    """A group of frontier cells (free cells bordering unknown ones, 8-connected): its
    middle cell (global row, col), its area, the information in view from the middle, and
    where the body can stand to look into it (world metres; None if nowhere it reaches)."""

    cell: tuple[int, int]
    area_m2: float
    hidden_bit: float
    stand_xy: tuple[float, float] | None


@dataclass(frozen=True)
class Frontiers:
    """The frontiers of a map that hide at least report_unreachable_bit: those the body can
    get to and those it cannot (behind a gap narrower than the body, as mapped)."""

    reachable: tuple[Frontier, ...] = ()
    unreachable: tuple[Frontier, ...] = ()


def find_frontiers(sight: np.ndarray, reachable: np.ndarray, params: ExplorationParams,
                   row0: int = 0, col0: int = 0) -> Frontiers:
    """The frontiers of a map that hide something: at least report_unreachable_bit of
    unknown in view from the frontier's middle, so a pocket too small to matter (under a
    desk, a fan of free cells drawn through a chink in a wall) is left alone. They are read
    from the sight layer (MapLayers.sight), where unknown cells touching a wall count as
    wall: the unknown sliver at a wall's foot that no beam grazed is no way on. The body gets
    to a frontier when one of its cells lies within REACH_CELLS of a reachable cell (the
    body's edge, where it can look into the unknown) with no wall between; it stands at the
    reachable cell nearest the middle (_stand_near). (row0, col0): the map's global cell, to
    name the frontiers' cells."""
    free = sight == kernels.FREE
    unknown = sight == kernels.UNKNOWN
    frontier = free & dilate_square(unknown, 1)
    labels, n = ndimage.label(frontier, structure=np.ones((3, 3), bool))
    if n == 0:
        return Frontiers()
    sizes = np.bincount(labels.ravel(), minlength=n + 1)
    groups = np.nonzero(sizes >= MIN_FRONTIER_CELLS)[0]
    groups = groups[groups > 0]
    if not len(groups):
        return Frontiers()
    middles = np.array([_middle_cell(labels, k) for k in groups], np.int64).reshape(-1, 2)
    unseen_cells = kernels.observable_unknown(sight, middles[:, 0], middles[:, 1], params.info_rays,
                                              params.d_cam_m / params.resolution_m)
    behind = unknown_behind(labels, unknown)[groups]
    hidden_bit = np.minimum(unseen_cells, behind) * params.entropy_per_cell_bit
    res = params.resolution_m
    reach, unreach = [], []
    near_reach = dilate_disc(reachable, REACH_CELLS)
    touched = np.bincount(labels.ravel(), weights=near_reach.ravel(), minlength=n + 1) > 0
    # The cells a reachable cell lies within REACH_CELLS of along both axes (_stand_near's square).
    near_square = dilate_square(reachable, REACH_CELLS)
    for k, (mi, mj), bits in zip(groups.tolist(), middles.tolist(), hidden_bit.tolist()):
        if bits < params.report_unreachable_bit:
            continue
        cell = (row0 + mi, col0 + mj)
        area = float(sizes[k]) * res * res
        if not touched[k]:
            unreach.append(Frontier(cell, area, bits, None))
            continue
        stand = _stand_near(labels == k, near_square, reachable, sight, mi, mj)
        xy = None if stand is None else ((col0 + stand[1] + 0.5) * res, (row0 + stand[0] + 0.5) * res)
        (reach if xy is not None else unreach).append(Frontier(cell, area, bits, xy))
    return Frontiers(tuple(reach), tuple(unreach))


def unknown_behind(labels: np.ndarray, unknown: np.ndarray) -> np.ndarray:
    """Per frontier group (labels: 1..n, 0 elsewhere), how many unknown cells lie behind it:
    the cells of the unknown regions (8-connected) its cells border; inf for a region that
    reaches the map's edge (it goes on beyond). What the rays from a frontier's middle count
    includes unknown seen through other gaps; a hole of a cell or two that no beam reached,
    walled in by what the robot has seen, hides no more than itself."""
    regions, n_regions = ndimage.label(unknown, structure=np.ones((3, 3), bool))
    size = np.bincount(regions.ravel(), minlength=n_regions + 1).astype(np.float64)
    edge = np.concatenate([regions[0], regions[-1], regions[:, 0], regions[:, -1]])
    size[edge] = np.inf
    # (group, region) for every frontier cell and unknown neighbour of it.
    padded_groups = np.pad(labels, 1)
    padded_regions = np.pad(regions, 1)
    rows, cols = labels.shape
    pairs = []
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            g = padded_groups[1:rows + 1, 1:cols + 1]
            r = padded_regions[1 + di:rows + 1 + di, 1 + dj:cols + 1 + dj]
            both = (g > 0) & (r > 0)
            pairs.append(np.column_stack((g[both], r[both])))
    pairs = np.unique(np.concatenate(pairs), axis=0)
    behind = np.zeros(int(labels.max()) + 1)
    np.add.at(behind, pairs[:, 0], size[pairs[:, 1]])
    return behind


def _middle_cell(labels: np.ndarray, k: int) -> tuple[int, int]:
    """The cell of group k nearest the group's centroid (lowest index on ties)."""
    cells = np.argwhere(labels == k)
    d2 = ((cells - cells.mean(axis=0)) ** 2).sum(axis=1)
    i, j = cells[int(np.argmin(d2))]
    return int(i), int(j)


def _stand_near(group: np.ndarray, near_square: np.ndarray, reachable: np.ndarray, sight: np.ndarray,
                mi: int, mj: int) -> tuple[int, int] | None:
    """Where the body stands to look into the group: for the group's cell nearest its middle
    (mi, mj) that has any, the nearest reachable cell within REACH_CELLS of it (a square;
    near_square marks the cells that have one) with no wall between the two. A fan of free
    cells drawn through a chink in a wall lies within that reach of the wall's near side,
    but shows nothing from there."""
    cells = np.argwhere(group & near_square)
    order = np.argsort(((cells - (mi, mj)) ** 2).sum(axis=1), kind="stable")
    for i, j in cells[order].tolist():
        near = traversable_near(reachable, i, j, REACH_CELLS)
        seen = lines_of_sight(sight, near[:, 0], near[:, 1], np.full(len(near), i), np.full(len(near), j))
        if seen.any():
            k = int(np.argmax(seen))
            return int(near[k, 0]), int(near[k, 1])
    return None


class KnownMap:
    """The robot's whole dense map with the body's layers and a full grid search from where
    the robot stood when it was derived; with the obstacles the robot felt but never saw
    (LocalMap.mark_obstacle_ahead) as walls, or, unless felt, without them."""

    def __init__(self, params: ExplorationParams, local_map: LocalMap, felt: bool = True) -> None:
        self.p = params
        self.local_map = local_map
        self.felt = felt
        self._built_us: int | None = None
        self._built_xy = (math.nan, math.nan)
        self.row0 = self.col0 = 0
        self.sight = np.zeros((0, 0), np.uint8)
        self.traversable = np.zeros((0, 0), bool)
        self.reachable = np.zeros((0, 0), bool)
        self._clearance_m = np.zeros((0, 0), np.float32)
        self._dist = np.zeros((0, 0))
        self._parent = np.zeros((0, 0), np.int64)

    def refresh(self, x_m: float, y_m: float, now_us: int, force: bool = False) -> None:
        """Derive the whole map again unless the last derivation is recent and near."""
        p = self.p
        if not force and self._built_us is not None \
                and now_us - self._built_us < p.known_map_refresh_s * 1e6 \
                and math.hypot(x_m - self._built_xy[0], y_m - self._built_xy[1]) < p.recenter_distance_m:
            return
        state, self.row0, self.col0 = self.local_map.whole_state(felt=self.felt)
        fit, _narrow = PlanningFits(p).ordinary(state, self.row0, self.col0)
        traversable = fit.traversable
        self.local_map.open_passed(traversable, state, self.row0, self.col0)
        self.sight = close_wall_gaps(state)
        i, j = self.cell_of(x_m, y_m)
        start = (i, j) if self._inside(i, j) and traversable[i, j] else \
            nearest_traversable(traversable, i, j, int(math.ceil(p.escape_radius_m / p.resolution_m)))
        if start is None:
            self._dist = np.full(state.shape, np.inf)
            self._parent = np.full(state.shape, -1, np.int64)
        else:
            self._dist, self._parent = kernels.dijkstra_grid(traversable, fit.cell_cost, start[0], start[1])
        self.reachable = np.isfinite(self._dist)
        self.traversable = traversable
        self._clearance_m = fit.clearance_m
        self._built_us, self._built_xy = now_us, (x_m, y_m)

    def _cells_of(self, xy_m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The map's (rows, cols) of points (n, 2, metres), and which lie on the map."""
        res = self.p.resolution_m
        rows = np.floor(xy_m[:, 1] / res).astype(np.int64) - self.row0
        cols = np.floor(xy_m[:, 0] / res).astype(np.int64) - self.col0
        n_rows, n_cols = self.traversable.shape
        return rows, cols, (rows >= 0) & (rows < n_rows) & (cols >= 0) & (cols < n_cols)

    def built_xy(self) -> np.ndarray:
        """Where the robot stood when the map was last derived (metres)."""
        return np.array(self._built_xy, np.float64)

    def clearance_at(self, xy_m: np.ndarray) -> np.ndarray:
        """The room from each point (n, 2, metres) to the walls, as the map was last derived
        (0 off the map)."""
        rows, cols, inside = self._cells_of(xy_m)
        out = np.zeros(len(xy_m))
        out[inside] = self._clearance_m[rows[inside], cols[inside]]
        return out

    def cut_off(self, xy_m: np.ndarray, radius_m: float) -> np.ndarray:
        """Per point (n, 2, metres), as the map was last derived: the body could stand within
        radius_m of it (a traversable cell there) but cannot get to any cell within radius_m
        of it: the map has closed the way between. A point with nothing traversable near (a
        wall drawn over it as the pose drifted) or off the map says nothing either way: False."""
        res = self.p.resolution_m
        rows, cols, inside = self._cells_of(xy_m)
        out = np.zeros(len(xy_m), bool)
        if not inside.any() or not self.traversable.any():
            return out
        r, c = rows[inside], cols[inside]
        near_traversable = ndimage.distance_transform_edt(~self.traversable)[r, c] * res <= radius_m
        near_reachable = np.zeros(len(r), bool)
        if self.reachable.any():
            near_reachable = ndimage.distance_transform_edt(~self.reachable)[r, c] * res <= radius_m
        out[inside] = near_traversable & ~near_reachable
        return out

    def cell_of(self, x_m: float, y_m: float) -> tuple[int, int]:
        res = self.p.resolution_m
        return int(math.floor(y_m / res)) - self.row0, int(math.floor(x_m / res)) - self.col0

    def _inside(self, i: int, j: int) -> bool:
        return 0 <= i < self.reachable.shape[0] and 0 <= j < self.reachable.shape[1]

    def route(self, x_m: float, y_m: float) -> tuple[np.ndarray, float] | None:
        """World points (cell centres) of the shortest path from where the map was derived
        to the point, and its cost (m, with the inflation's extra); None if the body cannot
        get there through what is mapped."""
        i, j = self.cell_of(x_m, y_m)
        if not self._inside(i, j):
            return None
        goal = (i, j) if self.reachable[i, j] else nearest_traversable(self.reachable, i, j, REACH_CELLS)
        if goal is None:
            return None
        cells = np.array(extract_path(self._parent, goal[0], goal[1]), np.int64)
        res = self.p.resolution_m
        xy = np.column_stack([(self.col0 + cells[:, 1] + 0.5) * res, (self.row0 + cells[:, 0] + 0.5) * res])
        return xy, float(self._dist[goal]) * res

    def frontiers(self) -> Frontiers:
        """The frontiers of the whole map (find_frontiers)."""
        if not self.reachable.size:
            return Frontiers()
        return find_frontiers(self.sight, self.reachable, self.p, self.row0, self.col0)

    def frontiers_from(self, xy_m: np.ndarray, radius_m: float) -> Frontiers:
        """The frontiers of the whole map as if the robot stood at any of these points (n, 2,
        metres): reachable are those the body could get to from a traversable cell within
        radius_m of one. Grid paths never cut a corner, so the cells a path reaches from a
        cell are its 4-connected traversable component."""
        if not self.traversable.any() or not len(xy_m):
            return Frontiers()
        components, _n = ndimage.label(self.traversable)
        res = self.p.resolution_m
        rows, cols, inside = self._cells_of(xy_m)
        _d, (near_i, near_j) = ndimage.distance_transform_edt(components == 0, return_indices=True)
        r, c = near_i[rows[inside], cols[inside]], near_j[rows[inside], cols[inside]]
        close = np.hypot(r - rows[inside], c - cols[inside]) * res <= radius_m
        held = np.unique(components[r[close], c[close]])
        reachable = np.isin(components, held[held > 0])
        return find_frontiers(self.sight, reachable, self.p, self.row0, self.col0)
