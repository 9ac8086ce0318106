"""Recovery behaviours: what a robot tries before it gives a target up (nav2's recovery
tree, in the order it uses): back off a little if the LiDAR shows room behind, turn once on
the spot so the LiDAR sees all around again (a door half-seen from an angle, a stale
obstacle), then retry the target once on a tighter, slower path. Only a target that fails
again after that is struck or dropped (services.targets). And for a body held where it
has no room straight behind: the way back along its own track (Track, Retrace).

The behaviour drives from odometry alone: distances and angles are measured from the pose
where each step began.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from firmware.params import ExplorationParams
from firmware.services.local_map import BinnedScan
from firmware.services.motion import wrap_rad

BACK_OFF = "back_off"
ROTATE = "rotate"
STEPS = (BACK_OFF, ROTATE)


def clear_behind(scan: BinnedScan, yaw_rad: float, distance_m: float, half_width_m: float) -> bool:
    """No return of the scan inside the strip the body would sweep backing up distance_m:
    behind the scan's origin, up to distance_m + half_width_m back, half_width_m to each side."""
    bins = len(scan.ranges_m)
    bearing = scan.bearing0_rad + np.arange(bins) * (2 * math.pi / bins) - (yaw_rad + math.pi)
    r = np.asarray(scan.ranges_m, np.float64)
    back = r * np.cos(bearing)
    side = r * np.sin(bearing)
    inside = (r > 0.0) & (back > 0.0) & (back <= distance_m + half_width_m) & (np.abs(side) < half_width_m)
    return not bool(inside.any())


def step_time_us(amount: float, rate_per_s: float) -> int:
    """How long a step of `amount` (metres backed off, radians turned) at `rate_per_s` may
    take: twice its nominal time and a second more (held or slipping, it ends there)."""
    return int((2.0 * amount / rate_per_s + 1.0) * 1e6)


class BackOff:
    """Reverse straight back at a fixed speed until distance_m from where it began (by
    odometry) or until step_time_us has passed."""

    def __init__(self, speed_mps: float) -> None:
        self.speed_mps = speed_mps
        self._from_xy: tuple[float, float] | None = None
        self._distance_m = 0.0
        self._deadline_us = 0

    @property
    def active(self) -> bool:
        return self._from_xy is not None

    def start(self, x_m: float, y_m: float, distance_m: float, now_us: int) -> None:
        self._from_xy = (x_m, y_m)
        self._distance_m = distance_m
        self._deadline_us = now_us + step_time_us(distance_m, self.speed_mps)

    def command(self, x_m: float, y_m: float, now_us: int) -> tuple[float, float] | None:
        """(v, omega) for this control tick, or None once it is over."""
        if self._from_xy is None:
            return None
        if now_us < self._deadline_us and \
                math.hypot(x_m - self._from_xy[0], y_m - self._from_xy[1]) < self._distance_m:
            return -self.speed_mps, 0.0
        self._from_xy = None
        return None


# Points of the track the robot keeps of its own travel (Track), this far apart.
TRACK_SPACING_M = 0.05
# Retrace turns on the spot while the next point lies more than this off its heading: in a
# gap as wide as the body, an arc would sweep its side into what it touches.
RETRACE_TURN_ON_SPOT_RAD = 0.1
RETRACE_HEADING_GAIN = 2.0      # turn rate per radian of heading error while driving


class Track:
    """The last stretch of the robot's own travel by odometry (uncorrected: the wheels' path,
    without the jumps localisation adds), a point every TRACK_SPACING_M, newest last: the way
    back out of a place the body got into. Over half a metre odometry drifts by millimetres."""

    def __init__(self, keep_m: float) -> None:
        self._keep = int(math.ceil(keep_m / TRACK_SPACING_M)) + 1
        self._points: list[tuple[float, float]] = []

    def add(self, x_m: float, y_m: float) -> None:
        pts = self._points
        # Back where it was a point ago (a back-off): the track is the way here, not every move.
        while len(pts) >= 2 and math.hypot(x_m - pts[-2][0], y_m - pts[-2][1]) < 0.5 * TRACK_SPACING_M:
            pts.pop()
        if not pts or math.hypot(x_m - pts[-1][0], y_m - pts[-1][1]) >= TRACK_SPACING_M:
            pts.append((x_m, y_m))
            if len(pts) > self._keep:
                del pts[0]

    def take_way_back(self, distance_m: float) -> np.ndarray:
        """The points back along the track from the newest, up to distance_m of it, nearest
        first, as (n, 2); they leave the track, which ends where the way back does (driving
        it does not make a new way back into the place just left)."""
        pts = self._points
        way: list[tuple[float, float]] = []
        length_m = 0.0
        while len(pts) >= 2 and length_m < distance_m:
            (x1, y1), (x0, y0) = pts[-1], pts[-2]
            length_m += math.hypot(x1 - x0, y1 - y0)
            pts.pop()
            way.append((x0, y0))
        return np.array(way, np.float64).reshape(-1, 2)


class Retrace:
    """Drive through a list of points in order (a Track's way back), forwards or backwards,
    whichever faces the first point with less turning: turn on the spot to face each point,
    then drive to it straight, at speed_mps. Over when the last point is reached or at a
    deadline (a body held where it is ends there)."""

    def __init__(self, speed_mps: float, max_omega_radps: float) -> None:
        self.speed_mps = speed_mps
        self.max_omega_radps = max_omega_radps
        self._points = np.zeros((0, 2))
        self._next = 0
        self._sign = 1.0
        self._deadline_us = 0

    @property
    def active(self) -> bool:
        return self._next < len(self._points)

    def start(self, points: np.ndarray, x_m: float, y_m: float, yaw_rad: float, now_us: int) -> None:
        self._points = np.asarray(points, np.float64).reshape(-1, 2)
        self._next = 0
        if not len(self._points):
            return
        ahead = math.atan2(self._points[0, 1] - y_m, self._points[0, 0] - x_m)
        self._sign = 1.0 if abs(wrap_rad(ahead - yaw_rad)) <= math.pi / 2 else -1.0
        length_m = float(np.hypot(*np.diff(np.vstack(([x_m, y_m], self._points)), axis=0).T).sum())
        self._deadline_us = now_us + step_time_us(length_m, self.speed_mps) + \
            step_time_us(math.pi, self.max_omega_radps)

    def command(self, x_m: float, y_m: float, yaw_rad: float, now_us: int) -> tuple[float, float] | None:
        """(v, omega) for this control tick, or None once it is over."""
        while self.active and now_us < self._deadline_us:
            gx, gy = self._points[self._next]
            if math.hypot(gx - x_m, gy - y_m) < 0.5 * TRACK_SPACING_M:
                self._next += 1
                continue
            facing = yaw_rad if self._sign > 0 else yaw_rad + math.pi
            err = wrap_rad(math.atan2(gy - y_m, gx - x_m) - facing)
            omega = max(-self.max_omega_radps, min(self.max_omega_radps, RETRACE_HEADING_GAIN * err))
            if abs(err) > RETRACE_TURN_ON_SPOT_RAD:
                return 0.0, omega
            return self._sign * self.speed_mps, omega
        self._points = np.zeros((0, 2))
        self._next = 0
        return None


@dataclass
class _Turn:
    turned_rad: float
    last_yaw_rad: float
    deadline_us: int           # a turn that cannot finish ends here


class Recovery:
    """One recovery at a time: start() it, then ask command() every control tick until it
    returns None; counts holds how many of each step ran."""

    def __init__(self, params: ExplorationParams, max_v_mps: float, max_omega_radps: float) -> None:
        self.p = params
        self.turn_rate_radps = min(params.recovery_turn_radps, max_omega_radps)
        self._back_off = BackOff(min(params.min_speed_mps, max_v_mps))
        self._steps: list[str] = []
        self._turn: _Turn | None = None
        self.counts: dict[str, int] = {"recoveries": 0, **{f"recovery_{s}s": 0 for s in STEPS}}

    @property
    def active(self) -> bool:
        return self._back_off.active or self._turn is not None or bool(self._steps)

    def start(self, room_behind: bool) -> None:
        """Begin a recovery; back off only if room_behind (clear_behind on the last scan)."""
        self._steps = ([BACK_OFF] if room_behind and self.p.recovery_back_off_m > 0 else []) + [ROTATE]
        self._turn = None
        self.counts["recoveries"] += 1

    def command(self, x_m: float, y_m: float, yaw_rad: float, now_us: int) -> tuple[float, float] | None:
        """(v, omega) for this control tick, or None once the recovery is over."""
        while True:
            if not self._back_off.active and self._turn is None:
                if not self._steps:
                    return None
                name = self._steps.pop(0)
                if name == BACK_OFF:
                    self._back_off.start(x_m, y_m, self.p.recovery_back_off_m, now_us)
                else:
                    self._turn = _Turn(0.0, yaw_rad, now_us + step_time_us(2 * math.pi, self.turn_rate_radps))
                self.counts[f"recovery_{name}s"] += 1
            if self._back_off.active:
                cmd = self._back_off.command(x_m, y_m, now_us)
                if cmd is not None:
                    return cmd
                continue
            t = self._turn
            if now_us < t.deadline_us:
                t.turned_rad += abs((yaw_rad - t.last_yaw_rad + math.pi) % (2 * math.pi) - math.pi)
                t.last_yaw_rad = yaw_rad
                if t.turned_rad < 2 * math.pi:
                    return 0.0, self.turn_rate_radps
            self._turn = None
