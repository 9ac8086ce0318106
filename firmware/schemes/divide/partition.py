"""A floor plan split into k regions that every robot computes alike: a k-means of the plan's
navigable cells in the plan's own metric (path length between cell centres, so a region
never reaches across a wall into a place it cannot get to without another region), with
centres started from farthest points chosen without randomness. Each cell belongs to the
centre nearest along the plan (ties: the lower index), so every region is connected (cells
touching at a corner count as joined).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import cKDTree

LLOYD_ITERATIONS_MAX = 50


class Partition:
    def __init__(self, navigable_m2: np.ndarray, plan_cell_m: float, x0_m: float, y0_m: float,
                 min_area_m2: float, k: int) -> None:
        """navigable_m2: navigable area per plan cell (row 0 at y0_m); cells holding at least
        min_area_m2 are divided among k regions. ValueError for a plan without such cells."""
        rows, cols = np.nonzero(navigable_m2 >= min_area_m2)
        if len(rows) == 0:
            raise ValueError("a floor plan without navigable area cannot be divided")
        self.xy = np.column_stack([x0_m + (cols + 0.5) * plan_cell_m, y0_m + (rows + 0.5) * plan_cell_m])
        self._weight = navigable_m2[rows, cols].astype(np.float64)
        self._graph = _grid_graph(rows, cols, navigable_m2.shape, plan_cell_m)
        self._tree = cKDTree(self.xy)
        self.centres = self._lloyd(self._farthest_points(k))    # cell indices, one per region
        self.labels = self._nearest_centre(self.centres)

    def _farthest_points(self, k: int) -> np.ndarray:
        """The cell nearest the weighted centroid, then each next the cell farthest along the
        plan from those chosen (cells no path joins count as nearest; ties: lower index)."""
        centroid = (self.xy * self._weight[:, None]).sum(axis=0) / self._weight.sum()
        chosen = [int(self._tree.query(centroid)[1])]
        nearest = dijkstra(self._graph, indices=chosen[0])
        while len(chosen) < k:
            far = int(np.argmax(np.where(np.isfinite(nearest), nearest, -1.0)))
            chosen.append(far)
            nearest = np.minimum(nearest, dijkstra(self._graph, indices=far))
        return np.array(chosen, dtype=np.int64)

    def _nearest_centre(self, centres: np.ndarray) -> np.ndarray:
        """Each cell's region: its nearest centre along the plan (ties and cells no path joins
        to any centre: the lower index, resp. region 0)."""
        dist = dijkstra(self._graph, indices=np.unique(centres))
        by_centre = {int(c): row for c, row in zip(np.unique(centres), dist)}
        best = np.full(len(self.xy), np.inf)
        labels = np.zeros(len(self.xy), dtype=np.int64)
        for r, c in enumerate(centres):
            closer = by_centre[int(c)] < best
            best[closer] = by_centre[int(c)][closer]
            labels[closer] = r
        return labels

    def _lloyd(self, centres: np.ndarray) -> np.ndarray:
        """Lloyd's iterations: each centre moves to its region's cell nearest the region's
        weighted mean, until no cell changes region."""
        labels = None
        for _ in range(LLOYD_ITERATIONS_MAX):
            new = self._nearest_centre(centres)
            if labels is not None and np.array_equal(new, labels):
                break
            labels = new
            centres = centres.copy()
            for r in range(len(centres)):
                mine = np.flatnonzero(labels == r)
                if len(mine):
                    mean = (self.xy[mine] * self._weight[mine, None]).sum(axis=0) / self._weight[mine].sum()
                    centres[r] = mine[np.argmin(((self.xy[mine] - mean) ** 2).sum(axis=1))]
        return centres

    def region_of(self, x_m, y_m) -> np.ndarray:
        """The region of each point of the plan's frame: that of the nearest navigable cell."""
        points = np.column_stack([np.ravel(np.asarray(x_m, dtype=np.float64)),
                                  np.ravel(np.asarray(y_m, dtype=np.float64))])
        return self.labels[self._tree.query(points)[1]]

    def cells_of(self, region: int) -> np.ndarray:
        """The centres (N x 2, m) of a region's cells."""
        return self.xy[self.labels == region]


def _grid_graph(rows: np.ndarray, cols: np.ndarray, shape: tuple[int, int], cell_m: float):
    """The 8-connected graph of the given cells, edges weighted by their length in metres (a
    diagonal step between cells that touch at a corner only is kept: the floor the plan
    counts in them may meet there, as a passage running diagonally does)."""
    index = np.full(shape, -1, dtype=np.int64)
    index[rows, cols] = np.arange(len(rows))
    src, dst, length = [], [], []
    for dr, dc in ((0, 1), (1, 0), (1, 1), (1, -1)):
        r2, c2 = rows + dr, cols + dc
        inside = (r2 >= 0) & (r2 < shape[0]) & (c2 >= 0) & (c2 < shape[1])
        a = np.flatnonzero(inside)
        b = index[r2[a], c2[a]]
        ok = b >= 0
        src.append(a[ok])
        dst.append(b[ok])
        length.append(np.full(int(ok.sum()), cell_m * (math.sqrt(2.0) if dr and dc else 1.0)))
    src, dst, length = np.concatenate(src), np.concatenate(dst), np.concatenate(length)
    n = len(rows)
    return coo_matrix((np.concatenate([length, length]), (np.concatenate([src, dst]), np.concatenate([dst, src]))),
                      shape=(n, n)).tocsr()
