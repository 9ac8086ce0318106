"""Unexplored directions of a vertex (the paper's list L, III-A/B, Fig. 3) and their update
when explored (III-E; mrtopomap.md A10, A12, A13, 5.5).

Detection, at a new own vertex (Algorithm 1 lines 15-16): in a 12 x 12 m crop of the own
map around the vertex, frontier cells are FREE cells 4-adjacent to an unknown one and
reachable (4-connected free space) from the vertex; 8-connected clusters of >= 10 cells
(1 m at 0.1 m) each give a direction: the sector of their centroid's bearing (16 sectors of
22.5 deg, sector k centred on k * 22.5 deg of the own frame) and a distance class (1: <= 3 m,
2: 3-6 m, 3: > 6 m) of the nearest cluster in that sector.

Update: a sector is explored when the robot came within 1.5 m of its direction point f_i
(vertex + class midpoint 1.5 / 4.5 / 7.5 m along the sector centre), or, for the robot's
own vertices whose clusters it remembers, when no reachable frontier cell is left within
1.5 m of the cluster's centroid. Explored sectors travel as an `mrud` clear mask; a
receiver's view of a vertex's open sectors is the vertex record's sectors AND-NOT the OR of
every clear mask it holds for it (`DirectionBook`): idempotent and commutative, a pure
function of the records held, in any order.
"""
from __future__ import annotations

import math
from collections.abc import Iterable
from typing import NamedTuple

import numpy as np
import scipy.ndimage as ndimage

from firmware.kernels import FREE, OCCUPIED
from firmware.schemes.mr_topomap.params import DEFAULT, MrTopoParams
from firmware.schemes.mr_topomap.records import SECTOR_RAD, SECTORS, clear_sectors, pack_sectors, sector_class

_FOUR = ndimage.generate_binary_structure(2, 1)
_EIGHT = np.ones((3, 3), dtype=bool)


class Cluster(NamedTuple):
    """One frontier cluster seen from a vertex: centroid (m, own frame), sector, class, size."""

    x_m: float
    y_m: float
    sector: int
    cls: int
    cells: int


class Directions(NamedTuple):
    ud_sectors: int                  # the mrvtx word: sector k's class in bits 2k..2k+1
    clusters: tuple[Cluster, ...]    # the nearest cluster of every set sector, by sector


def _crop(state: np.ndarray, r0: int, r1: int, c0: int, c1: int) -> np.ndarray:
    """state[r0:r1, c0:c1] with everything off the grid UNKNOWN (0)."""
    out = np.zeros((r1 - r0, c1 - c0), dtype=np.uint8)
    rs, re = max(r0, 0), min(r1, state.shape[0])
    cs, ce = max(c0, 0), min(c1, state.shape[1])
    if rs < re and cs < ce:
        out[rs - r0:re - r0, cs - c0:ce - c0] = state[rs:re, cs:ce]
    return out


def reachable_frontier(state: np.ndarray, i: int, j: int, reach_cells: int = 5) -> np.ndarray:
    """Frontier cells (FREE, 4-adjacent to a cell neither FREE nor OCCUPIED) in the free space
    4-connected to cell (i, j) of `state` (or to the nearest FREE cell within reach_cells of
    it); all False if there is none. Cells off the grid count as unknown."""
    free = state == FREE
    unknown = (state != FREE) & (state != OCCUPIED)
    padded = np.pad(unknown, 1, constant_values=True)
    near_unknown = padded[:-2, 1:-1] | padded[2:, 1:-1] | padded[1:-1, :-2] | padded[1:-1, 2:]
    frontier = free & near_unknown
    if not free.any():
        return np.zeros_like(free)
    labels, _ = ndimage.label(free, structure=_FOUR)
    si, sj = i, j
    if not (0 <= i < state.shape[0] and 0 <= j < state.shape[1] and free[i, j]):
        lo_i, lo_j = max(i - reach_cells, 0), max(j - reach_cells, 0)
        win = free[lo_i:max(i + reach_cells + 1, 0), lo_j:max(j + reach_cells + 1, 0)]
        cand = np.argwhere(win)
        if cand.size == 0:
            return np.zeros_like(free)
        d2 = (cand[:, 0] + lo_i - i) ** 2 + (cand[:, 1] + lo_j - j) ** 2
        k = int(np.argmin(d2))                       # first of the nearest, row-major: deterministic
        if d2[k] > reach_cells * reach_cells:
            return np.zeros_like(free)
        si, sj = int(cand[k, 0] + lo_i), int(cand[k, 1] + lo_j)
    return frontier & (labels == labels[si, sj])


def sector_of(dx: float, dy: float) -> int:
    return int(math.floor(math.atan2(dy, dx) / SECTOR_RAD + 0.5)) % SECTORS


def distance_class(d_m: float, params: MrTopoParams = DEFAULT) -> int:
    near, mid = params.ud_class_edges_m
    return 1 if d_m <= near else (2 if d_m <= mid else 3)


def detect(state: np.ndarray, row0: int, col0: int, res_m: float, x_m: float, y_m: float,
           params: MrTopoParams = DEFAULT) -> Directions:
    """The unexplored directions of a vertex at (x_m, y_m) from the own map `state`
    (UNKNOWN / FREE / OCCUPIED on the global lattice, window origin (row0, col0))."""
    half = int(round(params.ud_crop_m / 2.0 / res_m))
    ci = int(math.floor(y_m / res_m)) - row0
    cj = int(math.floor(x_m / res_m)) - col0
    # one cell more on each side so that the crop's border cells see their real neighbours
    crop = _crop(state, ci - half - 1, ci + half + 1, cj - half - 1, cj + half + 1)
    front = reachable_frontier(crop, half + 1, half + 1, reach_cells=max(1, int(round(0.5 / res_m))))
    front[[0, -1], :] = False
    front[:, [0, -1]] = False
    labels, n = ndimage.label(front, structure=_EIGHT)
    if n == 0:
        return Directions(0, ())
    idx = np.arange(1, n + 1)
    sizes = ndimage.sum_labels(front, labels, idx)
    cents = np.asarray(ndimage.center_of_mass(front, labels, idx), dtype=np.float64).reshape(-1, 2)
    best: dict[int, tuple[float, Cluster]] = {}
    for k in range(n):
        if sizes[k] < params.ud_min_cells:
            continue
        cy = (row0 + ci - half - 1 + cents[k, 0] + 0.5) * res_m
        cx = (col0 + cj - half - 1 + cents[k, 1] + 0.5) * res_m
        d = math.hypot(cx - x_m, cy - y_m)
        s = sector_of(cx - x_m, cy - y_m)
        c = Cluster(float(cx), float(cy), s, distance_class(d, params), int(sizes[k]))
        if s not in best or d < best[s][0]:
            best[s] = (d, c)
    classes = [best[s][1].cls if s in best else 0 for s in range(SECTORS)]
    return Directions(pack_sectors(classes), tuple(best[s][1] for s in sorted(best)))


def direction_points(x_m: float, y_m: float, ud_sectors: int,
                     params: MrTopoParams = DEFAULT) -> tuple[np.ndarray, np.ndarray]:
    """(sectors (k,), points f_i (k, 2)) of the open sectors of a vertex, in its owner's frame:
    vertex + class midpoint along the sector centre (A10)."""
    ks = [k for k in range(SECTORS) if sector_class(ud_sectors, k)]
    if not ks:
        return np.zeros(0, np.int64), np.zeros((0, 2))
    mid = np.asarray(params.ud_class_mid_m)[[sector_class(ud_sectors, k) - 1 for k in ks]]
    ang = np.asarray(ks) * SECTOR_RAD
    return np.asarray(ks), np.stack([x_m + mid * np.cos(ang), y_m + mid * np.sin(ang)], axis=1)


def explored_near(x_m: float, y_m: float, ud_sectors: int, robot_x_m: float, robot_y_m: float,
                  params: MrTopoParams = DEFAULT) -> int:
    """The clear mask of the open sectors of a vertex (all in one frame) whose direction point
    lies within explored_radius_m of the robot."""
    ks, pts = direction_points(x_m, y_m, ud_sectors, params)
    near = np.hypot(pts[:, 0] - robot_x_m, pts[:, 1] - robot_y_m) <= params.explored_radius_m
    return int(sum(1 << int(k) for k in ks[near]))


def vanished(clusters: Iterable[Cluster], state: np.ndarray, row0: int, col0: int, res_m: float,
             robot_x_m: float, robot_y_m: float, params: MrTopoParams = DEFAULT) -> int:
    """The clear mask of the sectors whose cluster has no frontier cell reachable from the
    robot left within explored_radius_m of its centroid (A12)."""
    clusters = list(clusters)
    if not clusters:
        return 0
    front = reachable_frontier(state, int(math.floor(robot_y_m / res_m)) - row0,
                               int(math.floor(robot_x_m / res_m)) - col0,
                               reach_cells=max(1, int(round(0.5 / res_m))))
    pts = np.argwhere(front)
    mask = 0
    for c in clusters:
        if pts.size:
            gy = c.y_m / res_m - row0 - 0.5
            gx = c.x_m / res_m - col0 - 0.5
            d = np.sqrt(((pts[:, 0] - gy) ** 2 + (pts[:, 1] - gx) ** 2).min()) * res_m
            if d <= params.explored_radius_m:
                continue
        mask |= 1 << c.sector
    return mask


class DirectionBook:
    """Open sectors of every vertex a robot holds: each vertex record's ud_sectors with the
    sectors of every clear mask received for it removed. A pure function of the set of
    records held: masks combine by OR (idempotent, commutative), and a mask that comes before
    its vertex is kept until the vertex does."""

    def __init__(self) -> None:
        self._ud: dict[tuple[int, int], int] = {}
        self._cleared: dict[tuple[int, int], int] = {}

    def add_vertex(self, key: tuple[int, int], ud_sectors: int) -> None:
        """A vertex record; a second, different record for the same key keeps the smaller word
        (the choice must not depend on arrival order)."""
        old = self._ud.get(key)
        self._ud[key] = ud_sectors if old is None else min(old, ud_sectors)

    def clear(self, key: tuple[int, int], clear_mask: int) -> None:
        """An mrud record (or the robot's own decision): these sectors are explored."""
        self._cleared[key] = self._cleared.get(key, 0) | (clear_mask & 0xFFFF)

    def remaining(self, key: tuple[int, int]) -> int:
        """The vertex's ud_sectors word with the cleared sectors set to none (0: unknown vertex)."""
        return clear_sectors(self._ud.get(key, 0), self._cleared.get(key, 0))

    def open_keys(self) -> list[tuple[int, int]]:
        """Vertices with at least one open sector, sorted."""
        return sorted(k for k in self._ud if self.remaining(k))

    def any_open(self) -> bool:
        """The paper's termination test (III-E) reads: exploration ends when this is False."""
        return any(self.remaining(k) for k in self._ud)
