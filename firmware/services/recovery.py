"""Recovery behaviours: what a robot tries before it gives a target up (nav2's recovery
tree, in the order it uses): back off a little if the LiDAR shows room behind, turn once on
the spot so the LiDAR sees all around again (a door half-seen from an angle, a stale
obstacle), then retry the target once on a tighter, slower path. Only a target that fails
again after that is struck or dropped (services.targets).

The behaviour drives from odometry alone: distances and angles are measured from the pose
where each step began.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from firmware.params import ExplorationParams
from firmware.services.local_map import BinnedScan

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


@dataclass
class _Step:
    name: str
    x_m: float
    y_m: float
    turned_rad: float
    last_yaw_rad: float
    deadline_us: int           # a step that cannot finish (blocked, slipping) ends here


class Recovery:
    """One recovery at a time: start() it, then ask command() every control tick until it
    returns None; counts holds how many of each step ran."""

    def __init__(self, params: ExplorationParams, max_v_mps: float, max_omega_radps: float) -> None:
        self.p = params
        self.back_speed_mps = min(params.min_speed_mps, max_v_mps)
        self.turn_rate_radps = min(params.recovery_turn_radps, max_omega_radps)
        self._steps: list[str] = []
        self._step: _Step | None = None
        self.counts: dict[str, int] = {"recoveries": 0, **{f"recovery_{s}s": 0 for s in STEPS}}

    @property
    def active(self) -> bool:
        return self._step is not None or bool(self._steps)

    def start(self, room_behind: bool) -> None:
        """Begin a recovery; back off only if room_behind (clear_behind on the last scan)."""
        self._steps = ([BACK_OFF] if room_behind and self.p.recovery_back_off_m > 0 else []) + [ROTATE]
        self._step = None
        self.counts["recoveries"] += 1

    def _duration_us(self, name: str) -> int:
        """Twice the time a step takes at its speed, and a second more."""
        nominal_s = self.p.recovery_back_off_m / self.back_speed_mps if name == BACK_OFF \
            else 2 * math.pi / self.turn_rate_radps
        return int((2.0 * nominal_s + 1.0) * 1e6)

    def command(self, x_m: float, y_m: float, yaw_rad: float, now_us: int) -> tuple[float, float] | None:
        """(v, omega) for this control tick, or None once the recovery is over."""
        while True:
            if self._step is None:
                if not self._steps:
                    return None
                name = self._steps.pop(0)
                self._step = _Step(name, x_m, y_m, 0.0, yaw_rad, now_us + self._duration_us(name))
                self.counts[f"recovery_{name}s"] += 1
            s = self._step
            if now_us < s.deadline_us:
                if s.name == BACK_OFF and math.hypot(x_m - s.x_m, y_m - s.y_m) < self.p.recovery_back_off_m:
                    return -self.back_speed_mps, 0.0
                if s.name == ROTATE:
                    s.turned_rad += abs((yaw_rad - s.last_yaw_rad + math.pi) % (2 * math.pi) - math.pi)
                    s.last_yaw_rad = yaw_rad
                    if s.turned_rad < 2 * math.pi:
                        return 0.0, self.turn_rate_radps
            self._step = None

