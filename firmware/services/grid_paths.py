"""Grid paths in the local map: where to plan from, shortest paths settled only as far as a
plan needs, and the cell tests routing uses. Every scheme plans on these."""
from __future__ import annotations

import numpy as np

from firmware import kernels
from firmware.services.local_map import LocalMap


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

    def _flat(self, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        """Flat indices of the reachable cells among (i, j)."""
        i = np.asarray(i, np.int64)
        j = np.asarray(j, np.int64)
        ok = self.reachable[i, j]
        return i[ok] * self.dist.shape[1] + j[ok]

    def settle(self, i: np.ndarray, j: np.ndarray) -> None:
        """Make dist and parent final at the cells (i, j) that are reachable."""
        flat = self._flat(i, j)
        if len(flat):
            kernels.dijkstra_settle(self._traversable, self._cell_cost, self.dist, self.parent, *self._heap, flat)

    def settle_first(self, i: np.ndarray, j: np.ndarray) -> None:
        """Settle the search until the nearest reachable cell among (i, j) is final."""
        flat = self._flat(i, j)
        if len(flat):
            kernels.dijkstra_settle_first(self._traversable, self._cell_cost, self.dist, self.parent, *self._heap,
                                          flat)

    def settle_below(self, bound_cells: float) -> None:
        """Make final every cell whose cost is at most bound_cells (in cells)."""
        kernels.dijkstra_settle_below(self._traversable, self._cell_cost, self.dist, self.parent, *self._heap,
                                      float(bound_cells))

    def settled(self, i: int, j: int) -> bool:
        """Are the cell's dist and parent final?"""
        return bool(self._heap[2][i * self.dist.shape[1] + j] == -2)

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


def lines_of_sight(state: np.ndarray, i0: np.ndarray, j0: np.ndarray, i1: np.ndarray,
                   j1: np.ndarray) -> np.ndarray:
    """Per pair of cells of the local map (arrays of their rows and columns): no OCCUPIED
    cell on the straight segment between them. A segment of n steps checks the cells at
    round(start + (end - start) t) for t = 0, 1/n, ..., 1, as np.linspace spaces them."""
    i0, j0, i1, j1 = (np.asarray(a, np.int64) for a in (i0, j0, i1, j1))
    steps = np.maximum(np.abs(i1 - i0), np.abs(j1 - j0))
    pair = np.repeat(np.arange(len(steps)), steps + 1)
    first = np.cumsum(steps + 1) - (steps + 1)
    s = np.arange(len(pair)) - first[pair]
    n = steps[pair]
    t = np.where(s == n, 1.0, s * (1.0 / np.maximum(n, 1)))
    ii = np.round(i0[pair] + (i1 - i0)[pair] * t).astype(np.int64)
    jj = np.round(j0[pair] + (j1 - j0)[pair] * t).astype(np.int64)
    walls = np.bincount(pair, weights=state[ii, jj] == kernels.OCCUPIED, minlength=len(steps))
    return (walls == 0) | (steps == 0)


def walls_crossed(state: np.ndarray, i0: int, j0: int, i1: int, j1: int) -> int:
    """How many walls (runs of OCCUPIED cells) the straight segment between two cells of a
    state grid crosses, counted up to where it leaves the grid (cells sampled as
    lines_of_sight samples them)."""
    steps = max(abs(i1 - i0), abs(j1 - j0))
    t = np.arange(steps + 1) * (1.0 / max(steps, 1))
    ii = np.round(i0 + (i1 - i0) * t).astype(np.int64)
    jj = np.round(j0 + (j1 - j0) * t).astype(np.int64)
    inside = (ii >= 0) & (ii < state.shape[0]) & (jj >= 0) & (jj < state.shape[1])
    if not inside.all():
        stop = int(np.argmin(inside)) if inside[0] else 0
        ii, jj = ii[:stop], jj[:stop]
    wall = state[ii, jj] == kernels.OCCUPIED
    return int(np.count_nonzero(wall[1:] & ~wall[:-1]) + (1 if len(wall) and wall[0] else 0))


def cell_known(local_map: LocalMap, i: int, j: int) -> bool:
    """Is the cell observed (free or wall) in the local map, rather than unknown?"""
    p = local_map.p
    v = local_map.logodds[i, j]
    return bool(v > p.logodds_occupied or v < p.logodds_free)
