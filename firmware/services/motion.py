"""Motion: a waypoint-following controller (pure pursuit on the planned path, turning in
place when the next point is far off the heading; the paper steers with forward and angular
velocity) that slows down and steers closely where the path leaves little room beside the
body, and stall detection."""
from __future__ import annotations

import math

import numpy as np
from firmware import kernels
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


# The slip check lays each scan over an earlier one, with the robot moved by a share of the
# travel odometry counted in between (0, 0.1, ..., 1), and takes the share that fits best:
# far below all of it, and fitting clearly better than all of it, the wheels slipped. Each
# beam's misfit is its distance to the surface through the nearest point of the earlier scan
# (point to line, as point-to-plane ICP: point to point, the beams' own spacing along a wall
# favours no motion), at most SLIP_MISFIT_CAP_M (a beam that sees what the other scan could
# not see counts no more than that); hits with no surface through them (beams grazing a wall
# far apart, edges) do not count.
SLIP_SHARES = np.linspace(0.0, 1.0, 11)
SLIP_MAX_TURN_RAD = 0.5          # scans farther apart in heading start the check over
SLIP_MIN_BEAMS = 30
SLIP_MISFIT_CAP_M = 0.2
SLIP_SURFACE_GAP_M = 0.3         # neighbouring hits farther apart are no surface
SLIP_SEEN_SHARE = 0.5            # slipping: the best share is at most this ...
SLIP_CLEAR_FIT = 0.7             # ... and its mean misfit at most this much of the full travel's
SLIP_NEAREST_CELL_M = 0.2        # the nearest-point search's cells: a few hits each at a few metres


class StallDetector:
    """Driving but not moving: something the map does not show is in the way. Told two ways,
    from what a robot has: commanded forward for stuck_after_s while the wheels report no
    motion (they stopped with the body), or odometry counting slip_check_m of forward travel
    that the LiDAR does not see (the wheels spin while the body is held)."""

    def __init__(self, params: ExplorationParams, control_hz: float) -> None:
        self.p = params
        self.control_hz = control_hz
        self._stuck_ticks = 0
        self._last_cmd_v = 0.0
        self._reference: tuple[float, float, float, np.ndarray] | None = None   # x, y, yaw, scan points
        self._slipped = False

    def commanded(self, v_mps: float) -> None:
        self._last_cmd_v = v_mps

    def stuck(self, measured_v_mps: float) -> bool:
        """Called once per control tick; True once per stall."""
        if self._slipped:
            self._slipped = False
            self._stuck_ticks = 0
            return True
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

    def on_scan(self, x_m: float, y_m: float, yaw_rad: float, angle_min_rad: float, angle_increment_rad: float,
                ranges_m: np.ndarray, range_max_m: float) -> tuple[float, float] | None:
        """Called with each scan and odometry's own pose for its time (uncorrected by
        localisation: the travel between two scans is the wheels'). When the wheels slipped
        (odometry counted travel since an earlier scan that the scans do not show): where the
        scans put the robot, (x_m, y_m) in odometry's frame, and the next stuck() says so;
        else None."""
        # Any forward command counts, a crawl too: a body held while it turns slowly towards
        # its path, commanded a few cm/s, presses on what holds it all the same.
        if self.p.slip_check_m <= 0 or self._last_cmd_v <= 0.0:
            self._reference = None
            return None
        ref = self._reference
        restart = ref is None or abs(wrap_rad(yaw_rad - ref[2])) > SLIP_MAX_TURN_RAD
        if not restart and math.hypot(x_m - ref[0], y_m - ref[1]) < self.p.slip_check_m:
            return None
        points = scan_points(angle_min_rad, angle_increment_rad, ranges_m, range_max_m)
        self._reference = (x_m, y_m, yaw_rad, points)
        if restart:
            return None
        if len(points) < SLIP_MIN_BEAMS or len(ref[3]) < SLIP_MIN_BEAMS:
            return None
        share = travel_share_seen(ref[3], points, x_m - ref[0], y_m - ref[1], ref[2], yaw_rad)
        if share is None or share > SLIP_SEEN_SHARE:
            return None
        self._slipped = True
        return ref[0] + share * (x_m - ref[0]), ref[1] + share * (y_m - ref[1])


def scan_points(angle_min_rad: float, angle_increment_rad: float, ranges_m: np.ndarray,
                range_max_m: float) -> np.ndarray:
    """The scan's hits as (n, 2) points in the robot's frame."""
    ranges_m = np.asarray(ranges_m, np.float64)
    angles = angle_min_rad + np.arange(len(ranges_m)) * angle_increment_rad
    hit = np.isfinite(ranges_m) & (ranges_m > 0.0) & (ranges_m < range_max_m)
    return np.column_stack((ranges_m[hit] * np.cos(angles[hit]), ranges_m[hit] * np.sin(angles[hit])))


def travel_share_seen(ref_points: np.ndarray, points: np.ndarray, dx_m: float, dy_m: float,
                      ref_yaw_rad: float, yaw_rad: float) -> float | None:
    """The share of odometry's travel (dx, dy in the world frame, between the scans) that
    best lays `points` over `ref_points` (each in its robot's frame); None unless that share
    fits clearly better than the whole travel (SLIP_CLEAR_FIT), e.g. in a corridor without
    features, where every share fits alike."""
    c, s = math.cos(ref_yaw_rad), math.sin(ref_yaw_rad)
    turn = wrap_rad(yaw_rad - ref_yaw_rad)
    ct, st = math.cos(turn), math.sin(turn)
    turned = points @ np.array([[ct, st], [-st, ct]])                    # rotated into the earlier frame
    misfit, counted = kernels.slip_misfits(
        np.ascontiguousarray(ref_points[:, 0]), np.ascontiguousarray(ref_points[:, 1]),
        np.ascontiguousarray(turned[:, 0]), np.ascontiguousarray(turned[:, 1]),
        c * dx_m + s * dy_m, -s * dx_m + c * dy_m, SLIP_SHARES,
        SLIP_SURFACE_GAP_M, SLIP_MISFIT_CAP_M, SLIP_NEAREST_CELL_M)
    if (counted < SLIP_MIN_BEAMS).any():
        return None
    best = int(np.argmin(misfit))
    if misfit[best] > SLIP_CLEAR_FIT * misfit[-1]:
        return None
    return float(SLIP_SHARES[best])


def wrap_rad(a_rad):
    """Angles (a float or an array) into [-pi, pi)."""
    return (a_rad + math.pi) % (2 * math.pi) - math.pi
