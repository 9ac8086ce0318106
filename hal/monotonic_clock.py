"""The real robot's clock: wall time from the operating system's monotonic clock, in
integer microseconds since the clock's epoch. By default the epoch is the clock's creation
(so mission time starts near zero, as the simulator's does); `[clock] epoch_ns` sets it to
a reading of time.monotonic_ns() (CLOCK_MONOTONIC, one clock for every process on a
machine), so that processes given the same epoch read the same time and their TDMA slots
(keyed on this clock) line up, as `lorascout hil` gives its robots the world's. It never
jumps when the system time is set (NTP, a GPS fix), because time.monotonic_ns does not."""
from __future__ import annotations

import time

from hal.config import BuildContext, Setting

# The one wall clock of a robot process: the HAL's clock and the host's tick loop share it,
# so the world a simulated robot steps to the wall clock and the firmware agree on "now".
SHARED_KEY = "monotonic-clock"

# How far in the future an epoch may lie: none can on the machine whose clock it was read
# from; this much allows for nothing but rounding by whoever wrote it down.
EPOCH_AHEAD_TOLERANCE_NS = 100_000_000


def _epoch_not_ahead(epoch_ns: int) -> None:
    now_ns = time.monotonic_ns()
    if epoch_ns - now_ns > EPOCH_AHEAD_TOLERANCE_NS:
        raise ValueError(f"{epoch_ns} lies {(epoch_ns - now_ns) / 1e9:.3f} s in the future of this machine's "
                         f"monotonic clock (now {now_ns} ns): an epoch is a time.monotonic_ns() reading already "
                         "taken on this machine (the clock restarts when the machine boots)")


class MonotonicClock:
    SETTINGS = (
        Setting("epoch_ns", "int", "the clock's zero as a time.monotonic_ns() (CLOCK_MONOTONIC) reading of this "
                "machine: processes given the same epoch read the same time, so a team's TDMA slots line up "
                "(default: when the clock is created)", unit="ns", default=None, lo=0, check=_epoch_not_ahead),
    )
    RESOURCES = ()

    def __init__(self, epoch_ns: int | None = None) -> None:
        self.epoch_ns = time.monotonic_ns() if epoch_ns is None else epoch_ns

    @classmethod
    def from_config(cls, ctx: BuildContext, epoch_ns: int | None = None) -> MonotonicClock:
        return ctx.shared(SHARED_KEY, lambda: cls(epoch_ns))

    def now_us(self) -> int:
        return (time.monotonic_ns() - self.epoch_ns) // 1000

    def sleep_until_us(self, t_us: int) -> None:
        """Block until now_us() >= t_us (the host's tick loop; the firmware never waits)."""
        remaining_us = t_us - self.now_us()
        if remaining_us > 0:
            time.sleep(remaining_us / 1e6)
