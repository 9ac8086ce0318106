"""Differential-drive robot bodies on the ground-truth grid: exact unicycle motion and
collision against walls.

The body is a disc of radius `radius_m`. A position is allowed when its clearance (the
exact Euclidean distance from the centre to the nearest wall cell square or to the map
edge) is strictly greater than the radius, so the closed disc never touches a wall cell.

Swept-path guarantee. A move is checked at positions spaced at most `spacing_m` apart
along its arc. Clearance is 1-Lipschitz, so on the arc between two checked positions a
and b (arc length h, hence every point p has |p-a| + |p-b| <= h) the clearance is at least
(c_a + c_b - h) / 2. A new position b is accepted only if c_b > R and c_a + c_b > 2R + h,
which bounds the clearance of every point the centre passes by R: the robot never enters
a wall, between samples included. Clearances are computed exactly near walls and
replaced by a lower bound far from them, which keeps the guarantee.

A move also stops where the clearance would fall to the radius plus half a sample spacing
(a skin of 5 mm with the default spacing): from there, a move along or away from a straight
wall always passes the check above, so a body that touched a wall can always leave it.
A blocked move keeps the last accepted position (refined by bisection) and still applies
the full commanded rotation: spinning in place never changes the disc, so it is always
allowed; this is what a skid-steer base pushing against a wall does.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from numba import njit
from scipy.ndimage import distance_transform_edt

from world_sim.occupancy_map import OccupancyMap

DEFAULT_SPACING_M = 0.01
_BISECTION_STEPS = 10


class BodyState(NamedTuple):
    x_m: float
    y_m: float
    yaw_rad: float


class MoveResult(NamedTuple):
    state: BodyState
    travelled_m: float   # arc length actually driven (>= 0)
    blocked: bool        # the commanded translation was cut short by a wall


@dataclass(frozen=True, eq=False)
class ClearanceMap:
    """Per-map collision data: the wall grid and, per cell, a lower bound (m) on the
    clearance of any point inside it, so free space far from walls is accepted in O(1)."""

    wall_u8: np.ndarray = field(repr=False)
    cell_clearance_lb_m: np.ndarray = field(repr=False)
    origin_x_m: float
    origin_y_m: float
    resolution_m: float

    @classmethod
    def from_map(cls, occ: OccupancyMap) -> ClearanceMap:
        wall = occ.wall_u8()
        # One ring of wall around the grid stands for the off-map region.
        padded = np.zeros((occ.rows + 2, occ.cols + 2), dtype=bool)
        padded[1:-1, 1:-1] = occ.free
        centre_dist_cells = distance_transform_edt(padded)[1:-1, 1:-1]
        # Any point of a cell is within sqrt(2)/2 cells of its centre, and any point of the
        # nearest wall cell within sqrt(2)/2 of that one's: subtract both.
        lb = (centre_dist_cells - math.sqrt(2.0)) * occ.resolution_m
        lb[~occ.free] = 0.0
        return cls(
            wall_u8=np.ascontiguousarray(wall),
            cell_clearance_lb_m=np.ascontiguousarray(np.maximum(lb, 0.0)),
            origin_x_m=float(occ.origin_x_m),
            origin_y_m=float(occ.origin_y_m),
            resolution_m=float(occ.resolution_m),
        )

    def clearance_m(self, x_m: float, y_m: float, cap_m: float = 1.0) -> float:
        """Exact distance from the point to the nearest wall cell or the map edge, or cap_m
        if that is larger. 0 inside a wall or off the map."""
        return float(_capped_clearance(
            self.wall_u8, self.cell_clearance_lb_m, self.origin_x_m, self.origin_y_m,
            self.resolution_m, float(x_m), float(y_m), float(cap_m),
        ))

    def disc_fits(self, x_m: float, y_m: float, radius_m: float) -> bool:
        """True if a closed disc of radius_m centred here touches no wall cell nor the map edge."""
        return self.clearance_m(x_m, y_m, radius_m + 1.0) > radius_m


@njit(cache=True)
def _capped_clearance(wall, clear_lb, ox, oy, res, x, y, cap):
    rows, cols = wall.shape
    edge = min(x - ox, ox + cols * res - x, y - oy, oy + rows * res - y)
    if not edge > 0.0:  # also catches NaN
        return 0.0
    col = int(math.floor((x - ox) / res))
    row = int(math.floor((y - oy) / res))
    if row < 0 or col < 0 or row >= rows or col >= cols or wall[row, col] != 0:
        return 0.0
    if clear_lb[row, col] >= cap:
        return cap
    best = min(edge, cap)
    c0 = max(int(math.floor((x - best - ox) / res)), 0)
    c1 = min(int(math.floor((x + best - ox) / res)), cols - 1)
    r0 = max(int(math.floor((y - best - oy) / res)), 0)
    r1 = min(int(math.floor((y + best - oy) / res)), rows - 1)
    for r in range(r0, r1 + 1):
        ylo = oy + r * res
        yhi = ylo + res
        ddy = max(ylo - y, 0.0, y - yhi)
        if ddy >= best:
            continue
        for c in range(c0, c1 + 1):
            if wall[r, c] == 0:
                continue
            xlo = ox + c * res
            xhi = xlo + res
            ddx = max(xlo - x, 0.0, x - xhi)
            d = math.sqrt(ddx * ddx + ddy * ddy)
            if d < best:
                best = d
    return best


@njit(cache=True, inline="always")
def _arc_point(x, y, yaw, v, omega, s_t):
    """Pose after driving (v, omega) for s_t seconds from (x, y, yaw): the exact unicycle arc."""
    if abs(omega) < 1e-12:
        return x + v * s_t * math.cos(yaw), y + v * s_t * math.sin(yaw)
    yaw1 = yaw + omega * s_t
    k = v / omega
    return x + k * (math.sin(yaw1) - math.sin(yaw)), y - k * (math.cos(yaw1) - math.cos(yaw))


@njit(cache=True)
def wrap_angle(a):
    """Angle wrapped to [-pi, pi)."""
    w = (a + math.pi) % (2.0 * math.pi) - math.pi
    if w >= math.pi:
        w -= 2.0 * math.pi
    return w


@njit(cache=True)
def advance(wall, clear_lb, ox, oy, res, radius_m, spacing_m, x, y, yaw, v, omega, dt_s):
    """One move of the body. Returns (x, y, yaw, travelled_m, blocked). The start position is
    taken as allowed (the caller keeps it so)."""
    yaw_end = wrap_angle(yaw + omega * dt_s)
    arc_m = abs(v) * dt_s
    if arc_m == 0.0:
        return x, y, yaw_end, 0.0, False
    cap = radius_m + 2.0 * spacing_m
    # New positions keep half a sample spacing more than the radius from every wall. Closer,
    # the swept-path bound (it needs (c_a - R) + (c_b - R) > h) can prove no next sample safe
    # unless the move points almost straight away from the wall: a body that had stopped
    # 5 um from a wall of the Intel lab could neither slide along it nor leave at an angle,
    # and stayed there for 600 s. With the skin, a move along or away from a straight wall
    # always passes.
    stop_clearance_m = radius_m + 0.5 * spacing_m
    n = int(math.ceil(arc_m / spacing_m))
    h_s = dt_s / n
    h_m = arc_m / n
    c_prev = _capped_clearance(wall, clear_lb, ox, oy, res, x, y, cap)
    px, py = x, y
    for k in range(1, n + 1):
        qx, qy = _arc_point(x, y, yaw, v, omega, k * h_s)
        c = _capped_clearance(wall, clear_lb, ox, oy, res, qx, qy, cap)
        if c > stop_clearance_m and c_prev + c > 2.0 * radius_m + h_m:
            px, py, c_prev = qx, qy, c
            continue
        # Blocked between sample k-1 (accepted) and k: bisect for the last safe point.
        lo = (k - 1) * h_s
        hi = k * h_s
        c_lo = c_prev
        for _ in range(_BISECTION_STEPS):
            mid = 0.5 * (lo + hi)
            mx, my = _arc_point(x, y, yaw, v, omega, mid)
            cm = _capped_clearance(wall, clear_lb, ox, oy, res, mx, my, cap)
            if cm > stop_clearance_m and c_lo + cm > 2.0 * radius_m + abs(v) * (mid - lo):
                lo, c_lo, px, py = mid, cm, mx, my
            else:
                hi = mid
        return px, py, yaw_end, abs(v) * lo, True
    return px, py, yaw_end, arc_m, False


@njit(cache=True)
def advance_all(wall, clear_lb, ox, oy, res, radius_m, spacing_m, poses, cmds, dt_s, travelled_m, blocked):
    """`advance` for every robot in one call: poses (n, 3) in place from cmds (n, 2) of
    (v, omega); each robot's distance driven into travelled_m and whether a wall stopped
    it into blocked."""
    for i in range(poses.shape[0]):
        x, y, yaw, ds, hit = advance(wall, clear_lb, ox, oy, res, radius_m, spacing_m,
                                     poses[i, 0], poses[i, 1], poses[i, 2], cmds[i, 0], cmds[i, 1], dt_s)
        poses[i, 0] = x
        poses[i, 1] = y
        poses[i, 2] = yaw
        travelled_m[i] = ds
        blocked[i] = hit


def step(
    state: BodyState,
    v_mps: float,
    omega_radps: float,
    dt_s: float,
    clearance: ClearanceMap,
    radius_m: float,
    spacing_m: float = DEFAULT_SPACING_M,
) -> MoveResult:
    """Drive the body with constant (v, omega) for dt_s seconds; stop short of walls."""
    if not dt_s >= 0.0:
        raise ValueError(f"dt_s must be >= 0, got {dt_s}")
    for name, value in (("v_mps", v_mps), ("omega_radps", omega_radps)):
        if not math.isfinite(value):
            raise ValueError(f"{name} must be finite, got {value}")
    x, y, yaw, travelled, blocked = advance(
        clearance.wall_u8, clearance.cell_clearance_lb_m, clearance.origin_x_m, clearance.origin_y_m,
        clearance.resolution_m, float(radius_m), float(spacing_m),
        float(state.x_m), float(state.y_m), float(state.yaw_rad), float(v_mps), float(omega_radps), float(dt_s),
    )
    return MoveResult(BodyState(x, y, yaw), travelled, blocked)
