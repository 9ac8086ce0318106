"""The coarse lattice the polygons live on (meier.md A9, 5.3 step 4), both ways.

Own map -> lattice: the robot's classified fine cells pooled into coarse cells of k x k
(k = lattice / resolution, 2 for 0.2 m over 0.1 m), aligned on the global cell lattice: a
coarse cell is FREE if at least half its fine cells are free and none is occupied, OCCUPIED
if any is, else UNKNOWN. The raster is monotone: a coarse cell once known never returns to
UNKNOWN (free and occupied may swap), so log-odds flicker at grazing angles does not make
vertices come and go.

Rings -> lattice: a sender's rings, even-odd filled (cell centres never lie on a lattice
line), are FREE; each wall edge is then drawn, on top, as the cells just outside it (its
right-hand side: rings have the free side on their left), sampled densely enough that the
band is 4-connected and the free inside never touches the unknown outside across a wall.
"""
from __future__ import annotations

import numpy as np

from firmware import kernels
from firmware.schemes.meier.contours import rotated

# Coarse cells the own raster grows by at a time, so it is not reallocated every update.
GROW_CELLS = 32
# Samples per coarse cell along a wall edge's band.
WALL_SAMPLES_PER_CELL = 4


def pool(fine: np.ndarray, fine_row0: int, fine_col0: int, k: int) -> tuple[np.ndarray, int, int]:
    """Coarse states of the k x k blocks of the global fine lattice that the grid (anchored at
    global fine cell (fine_row0, fine_col0)) touches; fine cells outside it count as
    unknown. Returns (coarse, coarse_row0, coarse_col0)."""
    r0, c0 = fine_row0 // k, fine_col0 // k
    top, left = fine_row0 - r0 * k, fine_col0 - c0 * k
    rows, cols = fine.shape
    n_r, n_c = -(-(top + rows) // k), -(-(left + cols) // k)
    padded = np.full((n_r * k, n_c * k), kernels.UNKNOWN, np.uint8)
    padded[top:top + rows, left:left + cols] = fine
    blocks = padded.reshape(n_r, k, n_c, k)
    free = (blocks == kernels.FREE).sum(axis=(1, 3))
    occupied = (blocks == kernels.OCCUPIED).any(axis=(1, 3))
    coarse = np.full((n_r, n_c), kernels.UNKNOWN, np.uint8)
    coarse[(2 * free >= k * k) & ~occupied] = kernels.FREE
    coarse[occupied] = kernels.OCCUPIED
    return coarse, r0, c0


class CoarseRaster:
    """The robot's own observed area on the coarse lattice, monotone (see the module)."""

    def __init__(self, k: int) -> None:
        self.k = k
        self.cells = np.zeros((0, 0), np.uint8)
        self.row0 = self.col0 = 0

    def merge(self, fine: np.ndarray, fine_row0: int, fine_col0: int) -> bool:
        """Pool the fine grid (anchored at global fine cell (fine_row0, fine_col0)) in; did
        any coarse cell change?"""
        coarse, r0, c0 = pool(fine, fine_row0, fine_col0, self.k)
        self._cover(r0, c0, r0 + coarse.shape[0], c0 + coarse.shape[1])
        view = self.cells[r0 - self.row0:r0 - self.row0 + coarse.shape[0],
                          c0 - self.col0:c0 - self.col0 + coarse.shape[1]]
        known = coarse != kernels.UNKNOWN
        changed = bool((view[known] != coarse[known]).any())
        view[known] = coarse[known]
        return changed

    def _cover(self, r_lo: int, c_lo: int, r_hi: int, c_hi: int) -> None:
        """Grow the raster (by whole GROW_CELLS steps) to hold rows [r_lo, r_hi), cols [c_lo, c_hi)."""
        if self.cells.size == 0:
            self.row0, self.col0 = r_lo - GROW_CELLS, c_lo - GROW_CELLS
            self.cells = np.zeros((r_hi - r_lo + 2 * GROW_CELLS, c_hi - c_lo + 2 * GROW_CELLS), np.uint8)
            return
        rows, cols = self.cells.shape
        new_r0 = min(self.row0, r_lo - GROW_CELLS) if r_lo < self.row0 else self.row0
        new_c0 = min(self.col0, c_lo - GROW_CELLS) if c_lo < self.col0 else self.col0
        new_r1 = max(self.row0 + rows, r_hi + GROW_CELLS) if r_hi > self.row0 + rows else self.row0 + rows
        new_c1 = max(self.col0 + cols, c_hi + GROW_CELLS) if c_hi > self.col0 + cols else self.col0 + cols
        if (new_r0, new_c0, new_r1, new_c1) == (self.row0, self.col0, self.row0 + rows, self.col0 + cols):
            return
        grown = np.zeros((new_r1 - new_r0, new_c1 - new_c0), np.uint8)
        grown[self.row0 - new_r0:self.row0 - new_r0 + rows, self.col0 - new_c0:self.col0 - new_c0 + cols] = self.cells
        self.cells, self.row0, self.col0 = grown, new_r0, new_c0


def rasterise_rings(rings: list[np.ndarray], wall: list[np.ndarray], shape: tuple[int, int],
                    row0: int, col0: int) -> np.ndarray:
    """The coarse states of the grid of `shape` anchored at global coarse cell (row0, col0)
    that one sender's rings say: each ring an (n, 2) int array of lattice (x, y) corners in
    order, wall[i][k] true if the edge from corner k to k + 1 is a wall."""
    rows, cols = shape
    out = np.full(shape, kernels.UNKNOWN, np.uint8)
    if not rings:
        return out
    a = np.concatenate(rings).astype(np.float64)
    b = np.concatenate([rotated(r, 1) for r in rings]).astype(np.float64)
    is_wall = np.concatenate(wall).astype(bool)
    # Even-odd fill: each non-horizontal edge flips the cells of the rows it crosses (within
    # the grid) whose centres lie right of the crossing.
    steep = a[:, 1] != b[:, 1]
    ea, eb = a[steep], b[steep]
    y_lo = np.maximum(np.minimum(ea[:, 1], eb[:, 1]), row0).astype(np.int64)
    y_hi = np.minimum(np.maximum(ea[:, 1], eb[:, 1]), row0 + rows).astype(np.int64)
    counts = np.maximum(y_hi - y_lo, 0)
    edge = np.repeat(np.arange(len(ea)), counts)
    first = np.cumsum(counts) - counts
    row = y_lo[edge] + np.arange(counts.sum()) - first[edge]
    yc = row + 0.5
    x_cross = ea[edge, 0] + (yc - ea[edge, 1]) * (eb[edge, 0] - ea[edge, 0]) / (eb[edge, 1] - ea[edge, 1])
    col = np.floor(x_cross + 0.5).astype(np.int64)      # the first cell whose centre lies right of it
    flat = (row - row0) * (cols + 1) + np.clip(col - col0, 0, cols)
    flips = (np.bincount(flat, minlength=rows * (cols + 1)) % 2).astype(np.uint8).reshape(rows, cols + 1)
    free = np.bitwise_xor.accumulate(flips, axis=1)[:, :cols] == 1
    out[free] = kernels.FREE
    # Walls (of every ring): the band of cells just right of each wall edge, sampled where
    # the band can fall in the grid.
    is_wall &= (a != b).any(axis=1)        # a ring of one vertex has an edge of no length
    wa, wb = a[is_wall], b[is_wall]
    if len(wa):
        d = wb - wa
        length = np.hypot(d[:, 0], d[:, 1])
        normal = np.column_stack([d[:, 1], -d[:, 0]]) / length[:, None]      # right of the edge
        t_lo, t_hi = _clip(wa + 0.5 * normal, d, (col0 - 1, row0 - 1), (col0 + cols + 1, row0 + rows + 1))
        n = np.ceil((t_hi - t_lo) * length * WALL_SAMPLES_PER_CELL).astype(np.int64)
        n = np.where(t_hi > t_lo, np.maximum(n, 1), 0)
        # Inside the edge only: an end point's sample would land on the next edge's side.
        edge = np.repeat(np.arange(len(wa)), n)
        first = np.cumsum(n) - n
        t = t_lo[edge] + (np.arange(n.sum()) - first[edge] + 0.5) / n[edge] * (t_hi - t_lo)[edge]
        pts = wa[edge] + t[:, None] * d[edge] + 0.5 * normal[edge]
        wr = np.floor(pts[:, 1]).astype(np.int64) - row0
        wc = np.floor(pts[:, 0]).astype(np.int64) - col0
        ok = (wr >= 0) & (wr < rows) & (wc >= 0) & (wc < cols)
        out[wr[ok], wc[ok]] = kernels.OCCUPIED
    return out


def _clip(start: np.ndarray, d: np.ndarray, lo: tuple[int, int], hi: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Per segment start + t d, t in [0, 1]: the range of t inside the box lo..hi (x, y);
    empty where t_hi <= t_lo."""
    t_lo, t_hi = np.zeros(len(d)), np.ones(len(d))
    for axis in (0, 1):
        moving = d[:, axis] != 0
        with np.errstate(divide="ignore", invalid="ignore"):
            t1 = (lo[axis] - start[:, axis]) / d[:, axis]
            t2 = (hi[axis] - start[:, axis]) / d[:, axis]
        t_lo = np.where(moving, np.maximum(t_lo, np.minimum(t1, t2)), t_lo)
        t_hi = np.where(moving, np.minimum(t_hi, np.maximum(t1, t2)), t_hi)
        outside = ~moving & ((start[:, axis] < lo[axis]) | (start[:, axis] > hi[axis]))
        t_hi = np.where(outside, -1.0, t_hi)
    return t_lo, t_hi
