"""Motion: a waypoint-following controller (pure pursuit on the planned path, turning in
place when the next point is far off the heading; the paper steers with forward and angular
velocity) that slows down and steers closely where the path leaves little room beside the
body, and stall detection."""
from __future__ import annotations

import math

import numpy as np

from firmware.params import ExplorationParams


class PathFollower:
    def __init__(self, params: ExplorationParams, max_v_mps: float, max_omega_radps: float) -> None:
        self.p = params
        self.max_v_mps = max_v_mps
        self.max_omega_radps = max_omega_radps
        self.path_xy = np.zeros((0, 2))
        self.room_m = np.zeros(0)                       # room from each path point to the walls
        self._slow = False
        self._next = 0
        self._closely_for_m = 0.0                       # travel left in follow_closely
        self._last_xy: tuple[float, float] | None = None

    def follow_closely(self, distance_m: float) -> None:
        """For the next distance_m of travel, steer for the next point of the path (one map
        cell ahead) instead of one look-ahead ahead: the shortcut pure pursuit takes through
        a path's bends can press the body against the very post the path bends around."""
        self._closely_for_m = distance_m

    def set_path(self, path_xy: np.ndarray, room_m: np.ndarray | None = None, slow: bool = False) -> None:
        """room_m: the room from each point to the walls (the planner's clearance); without
        it the path counts as roomy. slow: drive it at min_speed_mps (a retry after a
        recovery)."""
        self._slow = slow
        self.path_xy = path_xy
        self.room_m = np.full(len(path_xy), np.inf) if room_m is None else np.asarray(room_m, np.float64)
        self._next = 0

    def _roominess(self) -> float:
        """0 where the path ahead (the next metre) leaves no room beside the body, 1 where it
        leaves slow_clearance_m or more."""
        if self.p.slow_clearance_m <= 0.0:
            return 1.0
        ahead = self.room_m[max(self._next - 1, 0):self._next + int(1.0 / self.p.resolution_m) + 1]
        if not len(ahead):
            return 1.0
        spare_m = float(ahead.min()) - self.p.robot_radius_m
        return min(max(spare_m / self.p.slow_clearance_m, 0.0), 1.0)

    def clear(self) -> None:
        self.set_path(np.zeros((0, 2)))

    @property
    def following_closely(self) -> bool:
        return self._closely_for_m > 0.0

    @property
    def active(self) -> bool:
        return self._next < len(self.path_xy)

    def command(self, x_m: float, y_m: float, yaw_rad: float) -> tuple[float, float]:
        """(v, omega) towards the look-ahead point; (0, 0) at the end of the path."""
        pts = self.path_xy
        if self._last_xy is not None and self._closely_for_m > 0.0:
            self._closely_for_m -= math.hypot(x_m - self._last_xy[0], y_m - self._last_xy[1])
        self._last_xy = (x_m, y_m)
        roomy = self._roominess()
        lookahead_m = self.p.resolution_m if self._closely_for_m > 0.0 else \
            max(self.p.resolution_m, self.p.lookahead_m * roomy)
        # Points already within the look-ahead distance are passed.
        while self._next < len(pts) - 1 and math.hypot(pts[self._next, 0] - x_m, pts[self._next, 1] - y_m) < lookahead_m:
            self._next += 1
        if self._next >= len(pts):
            return 0.0, 0.0
        gx, gy = pts[self._next]
        dist = math.hypot(gx - x_m, gy - y_m)
        if self._next == len(pts) - 1 and dist < self.p.waypoint_reached_m * 0.5:
            self._next = len(pts)
            return 0.0, 0.0
        err = (math.atan2(gy - y_m, gx - x_m) - yaw_rad + math.pi) % (2 * math.pi) - math.pi
        omega = max(-self.max_omega_radps, min(self.max_omega_radps, self.p.heading_gain * err))
        # In a tight spot the body must face the path before it moves: an arc would sweep
        # its side into the door post.
        turn_on_spot_rad = self.p.rotate_in_place_rad * (0.4 + 0.6 * roomy)
        if abs(err) > turn_on_spot_rad:
            return 0.0, omega
        top_v = self.p.min_speed_mps + (0.0 if self._slow else (self.max_v_mps - self.p.min_speed_mps) * roomy)
        v = min(self.max_v_mps, top_v) * (1.0 - abs(err) / turn_on_spot_rad)
        # Slow down for the last point so the robot does not overshoot it.
        if self._next == len(pts) - 1:
            v = min(v, max(0.1, dist))
        return v, omega

    def remaining(self) -> np.ndarray:
        return self.path_xy[self._next:]


class StallDetector:
    """Commanded forward for stuck_after_s while the wheels report no motion: something
    the map does not show is in the way."""

    def __init__(self, params: ExplorationParams, control_hz: float) -> None:
        self.p = params
        self.control_hz = control_hz
        self._stuck_ticks = 0
        self._last_cmd_v = 0.0

    def commanded(self, v_mps: float) -> None:
        self._last_cmd_v = v_mps

    def stuck(self, measured_v_mps: float) -> bool:
        """Called once per control tick; True once per stall."""
        if self.p.stuck_after_s <= 0:
            return False
        if self._last_cmd_v > 0.05 and abs(measured_v_mps) < 0.02:
            self._stuck_ticks += 1
        else:
            self._stuck_ticks = 0
        if self._stuck_ticks >= self.p.stuck_after_s * self.control_hz:
            self._stuck_ticks = 0
            return True
        return False
