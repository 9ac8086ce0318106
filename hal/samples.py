"""Frozen sample types passed between HAL backends and the firmware.

Every sample carries the time it was taken (`stamp_us`, integer microseconds of the
mission clock) and every field carries its unit in its name.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True, eq=False)
class LidarScan:
    """One 360-degree planar scan. Beam i points at angle_min_rad + i * angle_increment_rad
    in the robot frame. A beam that hit nothing reads range_max_m."""

    stamp_us: int
    angle_min_rad: float
    angle_increment_rad: float
    range_max_m: float
    ranges_m: np.ndarray = field(repr=False)  # float32, one per beam


# The frame a team shares when it measured its robots' start poses at deployment (Bayer &
# Faigl's assumption 1). A robot that did not reports poses in a frame of its own (named
# after it), whose relation to the others' it does not know.
SHARED_FRAME = "shared"


@dataclass(frozen=True)
class OdometrySample:
    """Pose estimate as the robot's localisation reports it (it may drift from the truth),
    in the frame named by frame_id."""

    stamp_us: int
    x_m: float
    y_m: float
    yaw_rad: float
    v_mps: float
    omega_radps: float
    frame_id: str = SHARED_FRAME


@dataclass(frozen=True)
class DriveLimits:
    max_v_mps: float
    max_omega_radps: float
    robot_radius_m: float

    def clip(self, v_mps: float, omega_radps: float, who: str) -> tuple[float, float]:
        """A body velocity command within the limits, as every drive backend applies it.
        Raises ValueError naming `who` for a value that is not finite."""
        for name, value in (("v_mps", v_mps), ("omega_radps", omega_radps)):
            if not math.isfinite(value):
                raise ValueError(f"{who}: {name} must be finite, got {value!r}")
        return (min(max(float(v_mps), -self.max_v_mps), self.max_v_mps),
                min(max(float(omega_radps), -self.max_omega_radps), self.max_omega_radps))


@dataclass(frozen=True)
class UwbRange:
    """Two-way ranging result to another robot's UWB tag. `quality`: the module's quality
    factor of this range (a DWM1001 reports 0..100), None where the backend has none."""

    stamp_us: int
    peer_id: int
    range_m: float
    quality: int | None = None


@dataclass(frozen=True)
class AoaBearing:
    """Angle of arrival of another robot's WiFi packets, in this robot's frame.

    A sensor that reports several peaks of its angular profile for one packet (as the WSR
    toolbox's top-N) gives them as samples with one stamp, `rank` 0 the strongest;
    `profile_variance` is the sensor's spread of that profile (higher behind walls), None
    where it has none."""

    stamp_us: int
    peer_id: int
    bearing_rad: float
    profile_variance: float | None = None
    rank: int = 0


@dataclass(frozen=True)
class RadioRxFrame:
    """A frame the modem received with a good PHY CRC."""

    stamp_us: int
    payload: bytes
    rssi_dbm: float
    snr_db: float


@dataclass(frozen=True)
class RadioTxDone:
    """The modem finished (ok=True) or aborted (ok=False) the frame it was sending."""

    stamp_us: int
    ok: bool


RadioEvent = RadioRxFrame | RadioTxDone
