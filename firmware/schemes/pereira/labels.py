"""The private label grid (pereira.md 5.2 d): which region each FREE cell of the robot's
window lies in, so a waypoint is placed in a region by the way the robot could walk to it
instead of by the nearest place (a nearest place may lie behind a wall no gate marks).

1. The folded gates are drawn into the window as walls, 4-connected lines, so a walk
   between 4-neighbours cannot slip through one diagonally.
2. A breadth-first walk over FREE cells (4-neighbours) from the cell of every place in the
   window, each seeded with its region; a cell takes the region that reaches it first, and
   of those reaching it at the same step the lowest region index (regions are numbered by
   their anchors, so: the smallest (distance, anchor)).
3. A second walk from the cells next to a gate on the side of one of its virtual regions
   V(g, s), over what the first left unlabelled: the room behind a door seen, not entered.

Cells no walk reached (unknown, walls, pockets with no place) keep NONE: such points are
labelled by RegionGraph.label as before. The grid is this robot's own: robots with other
windows may label a cell otherwise, which is harmless (labels feed private decisions only).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from firmware import kernels
from firmware.schemes.pereira.regions import SIDE_PLUS, RegionGraph, orient

NONE = -1
SEED_BAND_CELLS = 1.5        # a virtual region's seeds: cells whose centre lies this close to its gate


@njit(cache=True)
def _walk(free: np.ndarray, label: np.ndarray, seed_i: np.ndarray, seed_j: np.ndarray,
          seed_label: np.ndarray) -> None:
    """Multi-source BFS over free & unlabelled cells (4-neighbours), in place. A cell found
    at step d by several cells of step d - 1 keeps the lowest label: every cell of step
    d - 1 leaves the queue before any of step d, so a label is final when its cell leaves."""
    n_r, n_c = free.shape
    dist = np.full((n_r, n_c), -1, np.int32)
    qi = np.empty(n_r * n_c, np.int32)
    qj = np.empty(n_r * n_c, np.int32)
    head = tail = 0
    for k in range(len(seed_i)):
        i, j = seed_i[k], seed_j[k]
        if not free[i, j] or (label[i, j] != NONE and dist[i, j] < 0):
            continue            # a wall, or labelled by an earlier walk
        if dist[i, j] < 0:
            dist[i, j] = 0
            label[i, j] = seed_label[k]
            qi[tail] = i
            qj[tail] = j
            tail += 1
        elif seed_label[k] < label[i, j]:
            label[i, j] = seed_label[k]
    while head < tail:
        i, j = qi[head], qj[head]
        head += 1
        d = dist[i, j] + 1
        lab = label[i, j]
        for step in range(4):
            ni = i + (1 if step == 0 else -1 if step == 1 else 0)
            nj = j + (1 if step == 2 else -1 if step == 3 else 0)
            if ni < 0 or nj < 0 or ni >= n_r or nj >= n_c or not free[ni, nj]:
                continue
            if dist[ni, nj] < 0:
                if label[ni, nj] != NONE:
                    continue    # labelled by an earlier walk
                dist[ni, nj] = d
                label[ni, nj] = lab
                qi[tail] = ni
                qj[tail] = nj
                tail += 1
            elif dist[ni, nj] == d and lab < label[ni, nj]:
                label[ni, nj] = lab


def _draw_segments(blocked: np.ndarray, segments_cm: np.ndarray, row0: int, col0: int, res_m: float) -> None:
    """Each segment (ax, ay, bx, by in cm, shared frame) as a 4-connected line of blocked
    cells, where it crosses the window anchored at global cell (row0, col0)."""
    n_r, n_c = blocked.shape
    res_cm = res_m * 100.0
    for ax, ay, bx, by in segments_cm.tolist():
        steps = max(1, int(math.ceil(math.hypot(bx - ax, by - ay) / (res_cm / 4))))
        t = np.linspace(0.0, 1.0, steps + 1)
        ii = np.floor((ay + t * (by - ay)) / res_cm).astype(np.int64) - row0
        jj = np.floor((ax + t * (bx - ax)) / res_cm).astype(np.int64) - col0
        # A diagonal step between samples: block one of the two cells it cuts the corner of.
        diag = (ii[1:] != ii[:-1]) & (jj[1:] != jj[:-1])
        ii = np.concatenate([ii, ii[1:][diag]])
        jj = np.concatenate([jj, jj[:-1][diag]])
        ok = (ii >= 0) & (ii < n_r) & (jj >= 0) & (jj < n_c)
        blocked[ii[ok], jj[ok]] = True


def gate_cells(shape: tuple[int, int], row0: int, col0: int, res_m: float, graph: RegionGraph) -> np.ndarray:
    """The cells of a window (anchored at global cell (row0, col0)) that the graph's gate
    segments cross, as 4-connected lines."""
    n_r, n_c = shape
    blocked = np.zeros((n_r, n_c), bool)
    seg = graph.segments_cm
    if len(seg):
        # Only gates that can reach the window.
        lo_x, lo_y = col0 * res_m * 100, row0 * res_m * 100
        hi_x, hi_y = (col0 + n_c) * res_m * 100, (row0 + n_r) * res_m * 100
        near = (np.maximum(seg[:, 0], seg[:, 2]) >= lo_x) & (np.minimum(seg[:, 0], seg[:, 2]) <= hi_x) & \
               (np.maximum(seg[:, 1], seg[:, 3]) >= lo_y) & (np.minimum(seg[:, 1], seg[:, 3]) <= hi_y)
        _draw_segments(blocked, seg[near], row0, col0, res_m)
    return blocked


def label_grid(sight: np.ndarray, row0: int, col0: int, res_m: float, graph: RegionGraph) -> np.ndarray:
    """The region index (of graph.regions) of every cell of the window, NONE where none."""
    n_r, n_c = sight.shape
    label = np.full((n_r, n_c), NONE, np.int32)
    if not len(graph.places):
        return label
    res_dm = res_m * 10.0
    seg = graph.segments_cm
    free = (sight == kernels.FREE) & ~gate_cells(sight.shape, row0, col0, res_m, graph)
    pl = graph.places
    pi = np.floor(pl[:, 1] / res_dm).astype(np.int64) - row0
    pj = np.floor(pl[:, 0] / res_dm).astype(np.int64) - col0
    inside = (pi >= 0) & (pi < n_r) & (pj >= 0) & (pj < n_c)
    _walk(free, label, pi[inside].astype(np.int32), pj[inside].astype(np.int32),
          graph.region_of_place[inside].astype(np.int32))
    virtual = [k for k, r in enumerate(graph.regions) if r.virtual]
    if not virtual:
        return label
    si, sj, sl = [], [], []
    band = SEED_BAND_CELLS
    for k in virtual:
        g, side = graph.virtual_gate(k)
        ax, ay, bx, by = (int(v) for v in seg[g])
        # Cells around the gate's segment, on side s, within band cells of it.
        c_lo = int(math.floor(min(ax, bx) / (res_m * 100) - band)) - col0
        c_hi = int(math.ceil(max(ax, bx) / (res_m * 100) + band)) - col0
        r_lo = int(math.floor(min(ay, by) / (res_m * 100) - band)) - row0
        r_hi = int(math.ceil(max(ay, by) / (res_m * 100) + band)) - row0
        r_lo, r_hi, c_lo, c_hi = max(r_lo, 0), min(r_hi + 1, n_r), max(c_lo, 0), min(c_hi + 1, n_c)
        if r_lo >= r_hi or c_lo >= c_hi:
            continue
        ii, jj = np.mgrid[r_lo:r_hi, c_lo:c_hi]
        cx = np.round((jj + col0 + 0.5) * res_m * 100).astype(np.int64)
        cy = np.round((ii + row0 + 0.5) * res_m * 100).astype(np.int64)
        on_side = (orient(ax, ay, bx, by, cx, cy) >= 0) == (side == SIDE_PLUS)
        length = math.hypot(bx - ax, by - ay) or 1.0
        dist_cm = np.abs(orient(ax, ay, bx, by, cx, cy)) / length
        pick = on_side & (dist_cm <= band * res_m * 100) & free[ii, jj] & (label[ii, jj] == NONE)
        si.append(ii[pick])
        sj.append(jj[pick])
        sl.append(np.full(int(pick.sum()), k, np.int64))
    if si:
        _walk(free, label, np.concatenate(si).astype(np.int32), np.concatenate(sj).astype(np.int32),
              np.concatenate(sl).astype(np.int32))
    return label
