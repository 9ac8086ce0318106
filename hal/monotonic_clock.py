"""The real robot's clock: wall time from the operating system's monotonic clock, in
integer microseconds since the clock was created (so mission time starts near zero, as the
simulator's does). It never jumps when the system time is set (NTP, a GPS fix), because
time.monotonic_ns does not."""
from __future__ import annotations

import time

from hal.config import BuildContext

# The one wall clock of a robot process: the HAL's clock and the host's tick loop share it,
# so the world a simulated robot steps to the wall clock and the firmware agree on "now".
SHARED_KEY = "monotonic-clock"


class MonotonicClock:
    SETTINGS = ()
    RESOURCES = ()

    def __init__(self) -> None:
        self._t0_ns = time.monotonic_ns()

    @classmethod
    def from_config(cls, ctx: BuildContext) -> MonotonicClock:
        return ctx.shared(SHARED_KEY, cls)

    def now_us(self) -> int:
        return (time.monotonic_ns() - self._t0_ns) // 1000

    def sleep_until_us(self, t_us: int) -> None:
        """Block until now_us() >= t_us (the host's tick loop; the firmware never waits)."""
        remaining_us = t_us - self.now_us()
        if remaining_us > 0:
            time.sleep(remaining_us / 1e6)
