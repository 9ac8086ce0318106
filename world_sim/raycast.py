"""Exact 2-D ray casting on the ground-truth wall grid (the simulated LiDAR and the
line-of-sight tests of the UWB model).

Grid conventions are those of `OccupancyMap`: `wall[row, col]` (uint8, 1 = wall), row 0 is
the lowest y, cell (row, col) covers [origin + col*res, origin + (col+1)*res) in x and
likewise in y. Everything outside the grid counts as wall.

Algorithm: Amanatides & Woo (1987) grid traversal in grid units (1 = one cell). The
boundary crossing times are recomputed from the start point for every step, never
accumulated, so each one is bit-identical to the slab time `(boundary - g) / d` that the
plain-Python reference computes independently from the cell boxes.

Tie rule (a beam meeting a grid corner): cells are CLOSED squares for blocking, so a beam
that passes through a corner, or within `TIE_EPS_CELLS` (in beam-length units) of it, is
stopped by a wall in any of the three cells meeting ahead of that corner: light never leaks
diagonally between two walls that touch at a corner. Free cells merely grazed at such a
corner are not counted as traversed (they are not marked observed). Beams that start
exactly on a grid line and run along it are outside this contract: the start cell is
`floor` of the start point and the traversal follows the cells the half-open convention
gives.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

# Two boundary crossings closer than this (in cells along the beam) are one corner crossing.
TIE_EPS_CELLS = 1e-9


@njit(cache=True, inline="always")
def _blocked(wall: np.ndarray, row: int, col: int) -> bool:
    if row < 0 or col < 0 or row >= wall.shape[0] or col >= wall.shape[1]:
        return True
    return wall[row, col] != 0


@njit(cache=True, inline="always")
def _mark(observed: np.ndarray, row: int, col: int) -> None:
    if 0 <= row < observed.shape[0] and 0 <= col < observed.shape[1]:
        observed[row, col] = True


@njit(cache=True)
def _traverse(wall, gx, gy, dx, dy, stop_g, observed, do_mark):
    """Walk the beam from grid point (gx, gy) along unit direction (dx, dy), visiting cells
    whose entry time is <= stop_g. Returns the entry time (grid units) of the first wall or
    off-map cell met, or +inf if none is met before stop_g. Marks visited cells when asked
    (free cells passed through, and the wall cells that stopped the beam)."""
    cx = int(math.floor(gx))
    cy = int(math.floor(gy))
    if do_mark:
        _mark(observed, cy, cx)
    if _blocked(wall, cy, cx):
        return 0.0
    sx = 1 if dx > 0.0 else (-1 if dx < 0.0 else 0)
    sy = 1 if dy > 0.0 else (-1 if dy < 0.0 else 0)
    inf = np.inf
    while True:
        if sx > 0:
            tx = (cx + 1 - gx) / dx
        elif sx < 0:
            tx = (cx - gx) / dx
        else:
            tx = inf
        if sy > 0:
            ty = (cy + 1 - gy) / dy
        elif sy < 0:
            ty = (cy - gy) / dy
        else:
            ty = inf
        if tx <= ty + TIE_EPS_CELLS and ty <= tx + TIE_EPS_CELLS:
            # Corner crossing: the two side cells and the diagonal one all touch the beam.
            t_min = min(tx, ty)
            t_diag = max(tx, ty)
            if t_min > stop_g:
                return inf
            hit = inf
            if tx <= stop_g and _blocked(wall, cy, cx + sx):
                hit = min(hit, tx)
                if do_mark:
                    _mark(observed, cy, cx + sx)
            if ty <= stop_g and _blocked(wall, cy + sy, cx):
                hit = min(hit, ty)
                if do_mark:
                    _mark(observed, cy + sy, cx)
            if t_diag <= stop_g and _blocked(wall, cy + sy, cx + sx):
                hit = min(hit, t_diag)
                if do_mark:
                    _mark(observed, cy + sy, cx + sx)
            if hit < inf:
                return hit
            if t_diag > stop_g:
                return inf
            cx += sx
            cy += sy
            t = t_diag
        elif tx < ty:
            if tx > stop_g:
                return inf
            cx += sx
            t = tx
        else:
            if ty > stop_g:
                return inf
            cy += sy
            t = ty
        if do_mark:
            _mark(observed, cy, cx)
        if _blocked(wall, cy, cx):
            return t


@njit(cache=True)
def cast_rays(wall_u8, origin_x_m, origin_y_m, resolution_m, x_m, y_m, angles_rad, max_range_m):
    """Range (m) along each world-frame angle from (x_m, y_m) to the first wall or off-map
    cell boundary, or max_range_m if there is none within it. 0 if the start is in a wall."""
    gx = (x_m - origin_x_m) / resolution_m
    gy = (y_m - origin_y_m) / resolution_m
    stop_g = max_range_m / resolution_m
    n = angles_rad.shape[0]
    out = np.empty(n, dtype=np.float64)
    dummy = np.zeros((1, 1), dtype=np.bool_)
    for k in range(n):
        hit = _traverse(wall_u8, gx, gy, math.cos(angles_rad[k]), math.sin(angles_rad[k]), stop_g, dummy, False)
        out[k] = hit * resolution_m if hit <= stop_g else max_range_m
    return out


@njit(cache=True)
def mark_observed(observed, wall_u8, origin_x_m, origin_y_m, resolution_m, x_m, y_m, angles_rad, ranges_m):
    """Set observed[row, col] for every cell beam k passed through within ranges_m[k], and
    for the wall cell(s) that stopped it (the LiDAR footprint, for coverage)."""
    gx = (x_m - origin_x_m) / resolution_m
    gy = (y_m - origin_y_m) / resolution_m
    for k in range(angles_rad.shape[0]):
        stop_g = ranges_m[k] / resolution_m + TIE_EPS_CELLS
        _traverse(wall_u8, gx, gy, math.cos(angles_rad[k]), math.sin(angles_rad[k]), stop_g, observed, True)


@njit(cache=True)
def cast_and_mark(observed, wall_u8, origin_x_m, origin_y_m, resolution_m, x_m, y_m, angles_rad, max_range_m):
    """`cast_rays` and then `mark_observed` with the ranges it found, in one pass per beam:
    the marking walk stops at the first wall anyway, so it only needs the range limit."""
    gx = (x_m - origin_x_m) / resolution_m
    gy = (y_m - origin_y_m) / resolution_m
    stop_g = max_range_m / resolution_m
    n = angles_rad.shape[0]
    out = np.empty(n, dtype=np.float64)
    for k in range(n):
        hit = _traverse(wall_u8, gx, gy, math.cos(angles_rad[k]), math.sin(angles_rad[k]),
                        stop_g + TIE_EPS_CELLS, observed, True)
        out[k] = hit * resolution_m if hit <= stop_g else max_range_m
    return out


@njit(cache=True)
def cast_and_mark_all(observed, wall_u8, origin_x_m, origin_y_m, resolution_m, poses, beam_angles_rad, max_range_m):
    """`cast_and_mark` for every robot in one call: robot i at poses[i] = (x, y, yaw) casts
    beam_angles_rad + yaw and marks observed[i]. Returns the ranges, (n, beams)."""
    out = np.empty((poses.shape[0], beam_angles_rad.shape[0]), np.float64)
    for i in range(poses.shape[0]):
        out[i] = cast_and_mark(observed[i], wall_u8, origin_x_m, origin_y_m, resolution_m,
                               poses[i, 0], poses[i, 1], beam_angles_rad + poses[i, 2], max_range_m)
    return out


@njit(cache=True)
def wall_length_m(wall_u8, origin_x_m, origin_y_m, resolution_m, x0_m, y0_m, x1_m, y1_m):
    """Length (m) of the segment (x0, y0) -> (x1, y1) that lies inside wall or off-map cells
    (how much material a radio path between two robots crosses)."""
    ex = x1_m - x0_m
    ey = y1_m - y0_m
    length_m = math.hypot(ex, ey)
    if length_m == 0.0:
        return 0.0
    dx = ex / length_m
    dy = ey / length_m
    gx = (x0_m - origin_x_m) / resolution_m
    gy = (y0_m - origin_y_m) / resolution_m
    end_g = length_m / resolution_m
    cx = int(math.floor(gx))
    cy = int(math.floor(gy))
    sx = 1 if dx > 0.0 else (-1 if dx < 0.0 else 0)
    sy = 1 if dy > 0.0 else (-1 if dy < 0.0 else 0)
    inside_g = 0.0
    t = 0.0
    while t < end_g:
        if sx > 0:
            tx = (cx + 1 - gx) / dx
        elif sx < 0:
            tx = (cx - gx) / dx
        else:
            tx = np.inf
        if sy > 0:
            ty = (cy + 1 - gy) / dy
        elif sy < 0:
            ty = (cy - gy) / dy
        else:
            ty = np.inf
        t_next = min(tx, ty, end_g)
        if _blocked(wall_u8, cy, cx):
            inside_g += t_next - t
        t = t_next
        # A corner crossing moves diagonally: the side cells are only grazed (zero length).
        if tx <= ty + TIE_EPS_CELLS and ty <= tx + TIE_EPS_CELLS:
            cx += sx
            cy += sy
            t = max(t, min(max(tx, ty), end_g))
        elif tx < ty:
            cx += sx
        else:
            cy += sy
    return inside_g * resolution_m


# ---------------------------------------------------------------------------------------
# Plain-Python references. They do not walk the grid: they intersect the beam with every
# cell's closed square (slab method) and take the nearest, so they share no control flow
# with the kernels above, only the definition of the crossing times.


@np.errstate(over="ignore")  # a near-parallel beam's crossing time is legitimately +-inf
def _slab(g: float, d: float, lo: float, hi: float) -> tuple[float, float]:
    """Interval of t with lo <= g + t*d <= hi."""
    if d > 0.0:
        return (lo - g) / d, (hi - g) / d
    if d < 0.0:
        return (hi - g) / d, (lo - g) / d
    if lo <= g <= hi:
        return -math.inf, math.inf
    return math.inf, -math.inf


def _cell_interval(gx, gy, dx, dy, row, col):
    tx0, tx1 = _slab(gx, dx, col, col + 1)
    ty0, ty1 = _slab(gy, dy, row, row + 1)
    return max(tx0, ty0), min(tx1, ty1)


def _first_hit_g_reference(wall, gx, gy, dx, dy) -> float:
    rows, cols = wall.shape
    c0, r0 = math.floor(gx), math.floor(gy)
    if not (0 <= r0 < rows and 0 <= c0 < cols) or wall[r0, c0]:
        return 0.0
    # Leaving the grid rectangle is the hit on the off-map wall.
    best = min(_slab(gx, dx, 0, cols)[1], _slab(gy, dy, 0, rows)[1])
    for row in range(rows):
        for col in range(cols):
            if not wall[row, col]:
                continue
            t_in, t_out = _cell_interval(gx, gy, dx, dy, row, col)
            if t_out >= 0.0 and t_in <= t_out + TIE_EPS_CELLS:
                best = min(best, max(t_in, 0.0))
    return best


def cast_rays_reference(wall_u8, origin_x_m, origin_y_m, resolution_m, x_m, y_m, angles_rad, max_range_m):
    gx = (x_m - origin_x_m) / resolution_m
    gy = (y_m - origin_y_m) / resolution_m
    stop_g = max_range_m / resolution_m
    out = np.empty(len(angles_rad))
    for k, angle in enumerate(angles_rad):
        hit = _first_hit_g_reference(wall_u8, gx, gy, math.cos(angle), math.sin(angle))
        out[k] = hit * resolution_m if hit <= stop_g else max_range_m
    return out


def mark_observed_reference(observed, wall_u8, origin_x_m, origin_y_m, resolution_m, x_m, y_m, angles_rad, ranges_m):
    rows, cols = wall_u8.shape
    gx = (x_m - origin_x_m) / resolution_m
    gy = (y_m - origin_y_m) / resolution_m
    c0, r0 = math.floor(gx), math.floor(gy)
    for k, angle in enumerate(angles_rad):
        dx, dy = math.cos(angle), math.sin(angle)
        if 0 <= r0 < rows and 0 <= c0 < cols:
            observed[r0, c0] = True
        hit = _first_hit_g_reference(wall_u8, gx, gy, dx, dy)
        stop_g = ranges_m[k] / resolution_m + TIE_EPS_CELLS
        for row in range(rows):
            for col in range(cols):
                if (row, col) == (r0, c0):
                    continue
                t_in, t_out = _cell_interval(gx, gy, dx, dy, row, col)
                if t_out < 0.0 or t_in > stop_g:
                    continue
                if wall_u8[row, col]:
                    touched = t_in <= t_out + TIE_EPS_CELLS
                    if touched and t_in <= hit + TIE_EPS_CELLS:
                        observed[row, col] = True
                else:
                    passed = t_out > t_in + TIE_EPS_CELLS
                    if passed and t_in < hit:
                        observed[row, col] = True


def wall_length_m_reference(wall_u8, origin_x_m, origin_y_m, resolution_m, x0_m, y0_m, x1_m, y1_m) -> float:
    rows, cols = wall_u8.shape
    length_m = math.hypot(x1_m - x0_m, y1_m - y0_m)
    if length_m == 0.0:
        return 0.0
    dx, dy = (x1_m - x0_m) / length_m, (y1_m - y0_m) / length_m
    gx = (x0_m - origin_x_m) / resolution_m
    gy = (y0_m - origin_y_m) / resolution_m
    end_g = length_m / resolution_m

    def overlap(t_in: float, t_out: float) -> float:
        return max(0.0, min(t_out, end_g) - max(t_in, 0.0))

    tx0, tx1 = _slab(gx, dx, 0, cols)
    ty0, ty1 = _slab(gy, dy, 0, rows)
    in_grid_g = overlap(max(tx0, ty0), min(tx1, ty1))
    total_g = end_g - in_grid_g
    for row in range(rows):
        for col in range(cols):
            if wall_u8[row, col]:
                total_g += overlap(*_cell_interval(gx, gy, dx, dy, row, col))
    return total_g * resolution_m


@njit(cache=True)
def pair_wall_lengths_m(wall_u8, origin_x_m, origin_y_m, resolution_m, poses, within_m):
    """wall_length_m from robot i to robot j for every ordered pair closer than within_m
    (NaN for the rest and on the diagonal): the UWB's NLOS bias for a whole team in one call."""
    n = poses.shape[0]
    out = np.full((n, n), np.nan)
    for i in range(n):
        for j in range(n):
            dx = poses[j, 0] - poses[i, 0]
            dy = poses[j, 1] - poses[i, 1]
            if i != j and dx * dx + dy * dy <= within_m * within_m:
                out[i, j] = wall_length_m(wall_u8, origin_x_m, origin_y_m, resolution_m,
                                          poses[i, 0], poses[i, 1], poses[j, 0], poses[j, 1])
    return out
