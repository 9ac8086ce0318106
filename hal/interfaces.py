"""The HAL contract. The firmware is written against these and nothing else.

Every call is non-blocking in simulated time: a backend answers from what it has,
and the mission clock only moves between firmware ticks (lockstep, as in ArduPilot SITL).
"""
from __future__ import annotations

from typing import Protocol, runtime_checkable

from hal.samples import AoaBearing, DriveLimits, LidarScan, OdometrySample, RadioEvent, UwbRange


@runtime_checkable
class Clock(Protocol):
    def now_us(self) -> int:
        """Mission time in integer microseconds; monotonic."""


@runtime_checkable
class Lidar(Protocol):
    def latest_scan(self) -> LidarScan | None:
        """The newest scan not yet returned, or None if none arrived since the last call."""


@runtime_checkable
class Odometry(Protocol):
    def read(self) -> OdometrySample: ...


@runtime_checkable
class DriveBase(Protocol):
    def limits(self) -> DriveLimits: ...

    def command(self, v_mps: float, omega_radps: float) -> None:
        """Set the body velocity until the next command; values beyond the limits are clipped."""


@runtime_checkable
class UwbRanger(Protocol):
    def ranges(self) -> tuple[UwbRange, ...]:
        """Ranges measured since the last call."""


@runtime_checkable
class WifiAoa(Protocol):
    def bearings(self) -> tuple[AoaBearing, ...]:
        """Bearings measured since the last call."""


@runtime_checkable
class RadioModem(Protocol):
    """A half-duplex LoRa transceiver. While idle it listens; it transmits one frame at a time."""

    def transmit(self, payload: bytes) -> bool:
        """Start sending `payload` now. False (and nothing sent) if the radio is still
        sending the previous frame or the payload does not fit."""

    def busy(self) -> bool:
        """True while a transmission is in progress."""

    def poll(self) -> tuple[RadioEvent, ...]:
        """Frames received and transmissions finished since the last call, oldest first."""


@runtime_checkable
class MeshLink(Protocol):
    """A high-bandwidth broadcast link (WiFi mesh) for the dense-map baselines that the
    LoRa schemes are compared against. Messages are whole byte strings."""

    def broadcast(self, message: bytes) -> None: ...

    def receive(self) -> tuple[bytes, ...]:
        """Messages from other robots since the last call, oldest first."""
