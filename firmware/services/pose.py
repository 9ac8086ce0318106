"""This robot's pose: the latest odometry sample and a short history of them, so a sample
taken at another time (a LiDAR scan, a range) can be paired with the pose of its own time;
and the correction localisation (services.scan_match) found for the odometry's drift, which
every pose handed out carries.

Poses are in the odometry's frame, named by `frame_id`: the shared mission frame when the
team measured its start poses at deployment, or the robot's own start frame when it did not
(schemes that need a common frame declare it, see firmware.schemes.base).
"""
from __future__ import annotations

import bisect
import dataclasses
import math

from hal.interfaces import Odometry
from hal.samples import SHARED_FRAME, OdometrySample

__all__ = ["SHARED_FRAME", "PoseService", "TravelMilestones"]


class PoseService:
    def __init__(self, odometry: Odometry, history: int = 64) -> None:
        """history: samples kept for pose_at (64 control ticks: 3.2 s at 20 Hz)."""
        self._odometry = odometry
        self._history = history
        self._stamps: list[int] = []
        self._samples: list[OdometrySample] = []
        # Map pose = this rigid transform (rotate by yaw about the origin, then shift) of the
        # odometry's pose: the identity until localisation corrects it.
        self._shift_x_m = self._shift_y_m = self._turn_rad = 0.0

    @property
    def frame_id(self) -> str | None:
        """The frame of the poses (hal.samples.OdometrySample.frame_id); None before any."""
        return self._samples[-1].frame_id if self._samples else None

    def read(self) -> OdometrySample:
        """The newest sample (read from the odometry now, remembered for pose_at), corrected."""
        s = self._odometry.read()
        if not self._stamps or s.stamp_us > self._stamps[-1]:
            self._stamps.append(s.stamp_us)
            self._samples.append(s)
            if len(self._stamps) > self._history:
                del self._stamps[0], self._samples[0]
        if self._uncorrected:
            return s
        x_m, y_m, yaw_rad = self.corrected(s.x_m, s.y_m, s.yaw_rad)
        return dataclasses.replace(s, x_m=x_m, y_m=y_m, yaw_rad=yaw_rad)

    def latest(self) -> tuple[float, float, float] | None:
        """The newest pose read (corrected), without reading the odometry; None before any."""
        return self.pose_at(self._stamps[-1]) if self._stamps else None

    def pose_at(self, stamp_us: int) -> tuple[float, float, float] | None:
        """(x_m, y_m, yaw_rad) at stamp_us, corrected, interpolated between the samples
        around it (yaw the short way round); the oldest or newest sample outside the
        history's span; None before any sample."""
        raw = self.odometry_at(stamp_us)
        return None if raw is None else self.corrected(*raw)

    def correct_at(self, stamp_us: int, x_m: float, y_m: float, yaw_rad: float) -> None:
        """Localisation found the robot at (x_m, y_m, yaw_rad) at stamp_us: correct this and
        every later pose by the rigid transform that takes the odometry's pose then there."""
        raw = self.odometry_at(stamp_us)
        if raw is None:
            return
        ox, oy, oyaw = raw
        turn = (yaw_rad - oyaw + math.pi) % (2 * math.pi) - math.pi
        c, s = math.cos(turn), math.sin(turn)
        self._turn_rad = turn
        self._shift_x_m = x_m - (c * ox - s * oy)
        self._shift_y_m = y_m - (s * ox + c * oy)

    @property
    def _uncorrected(self) -> bool:
        return not self._turn_rad and not self._shift_x_m and not self._shift_y_m

    def corrected(self, x_m: float, y_m: float, yaw_rad: float) -> tuple[float, float, float]:
        """An odometry pose in the map: carried by the correction localisation found."""
        if self._uncorrected:
            return x_m, y_m, yaw_rad
        c, s = math.cos(self._turn_rad), math.sin(self._turn_rad)
        yaw = (yaw_rad + self._turn_rad + math.pi) % (2 * math.pi) - math.pi
        return c * x_m - s * y_m + self._shift_x_m, s * x_m + c * y_m + self._shift_y_m, yaw

    def odometry_at(self, stamp_us: int) -> tuple[float, float, float] | None:
        """The odometry's own pose at stamp_us (pose_at without the correction): the
        wheels' travel between two stamps, with no jump where localisation corrected."""
        if not self._stamps:
            return None
        k = bisect.bisect_left(self._stamps, stamp_us)
        if k == 0:
            s = self._samples[0]
            return s.x_m, s.y_m, s.yaw_rad
        if k == len(self._stamps):
            s = self._samples[-1]
            return s.x_m, s.y_m, s.yaw_rad
        a, b = self._samples[k - 1], self._samples[k]
        if b.stamp_us == stamp_us:
            return b.x_m, b.y_m, b.yaw_rad
        f = (stamp_us - a.stamp_us) / (b.stamp_us - a.stamp_us)
        dyaw = (b.yaw_rad - a.yaw_rad + math.pi) % (2 * math.pi) - math.pi
        yaw = (a.yaw_rad + f * dyaw + math.pi) % (2 * math.pi) - math.pi
        return a.x_m + f * (b.x_m - a.x_m), a.y_m + f * (b.y_m - a.y_m), yaw


class TravelMilestones:
    """Every `every_m` of travel (straight-line distance from the last milestone): where
    schemes drop a place into their map."""

    def __init__(self, every_m: float) -> None:
        self.every_m = every_m
        self._last_xy: tuple[float, float] | None = None

    def due(self, x_m: float, y_m: float) -> bool:
        last = self._last_xy
        return last is None or math.hypot(x_m - last[0], y_m - last[1]) >= self.every_m

    def mark(self, x_m: float, y_m: float) -> None:
        self._last_xy = (x_m, y_m)
