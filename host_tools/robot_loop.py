"""The real-time tick loop of `lorascout robot`: the firmware on the wall clock.

Every tick period (the fastest task's period, 50 ms) the loop sleeps until the tick is due,
moves what follows the wall clock (a simulated world run in real time) to now, and runs the
firmware's due tasks. Ticks fall on multiples of the tick period of the clock (the first one
on the first multiple not before the loop starts), so robots whose clocks share an epoch
([clock] epoch_ns) tick together and their TDMA slots, cut from the same clock, line up. Ticks
keep that grid: a tick that ends after the next one was due starts the next one at once, and
skips the slots that passed entirely (counted), as the scheduler skips a late task's missed
periods.

Every task run is timed on the wall clock and compared with the task's time budget
(firmware.scheduler.Task.time_budget_us: its period, unless the task table declares less);
a run over budget is an overrun. The whole tick is compared with the tick period the same
way. A log line every `log_interval_s` gives the counts (a warning when something overran
since the line before); the run's summary gives them per task.

The loop ends when the robot's mission is complete and no teammate it heard of is still
exploring (a finished robot stays on the air for them, relaying and answering, until they
finish or fall silent), when `max_s` has passed, or when `should_stop()` names a reason (a
signal). It never stops the drive itself: its caller does, whatever ended the loop.

A robot that ends complete signs off first: when the stopping rule first holds, the firmware
queues its status heartbeat (ExplorerAgent.sign_off), and the loop keeps ticking until that
and everything else queued has left the air (ExplorerAgent.radio_quiet), at most
SIGN_OFF_FRAMES TDMA frames (a radio that cannot send must not keep the robot), then ends
"complete". A teammate that finished in the same moment and never heard this robot's done
heartbeat hears it now, instead of waiting for this robot to age out of its roster (three
heartbeat periods, 30 s). If the rule stops holding meanwhile (a teammate explores again), the
sign-off is called off and the robot goes on.
"""
from __future__ import annotations

import logging
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Protocol

from firmware.agent import ExplorerAgent

log = logging.getLogger("lorascout.robot")

# How long a robot signing off waits for its heartbeat to leave the air, in TDMA frames (on a
# channel without slots: in the time the longest frame takes, rounded up to ticks).
SIGN_OFF_FRAMES = 3


class WallClock(Protocol):
    def now_us(self) -> int: ...

    def sleep_until_us(self, t_us: int) -> None: ...


@dataclass
class RunTimes:
    """How long the runs of one task (or whole ticks) took, against the budget."""
    budget_us: int
    runs: int = 0
    overruns: int = 0
    total_us: int = 0
    max_us: int = 0

    def add(self, took_us: int) -> bool:
        """Count one run; True if it overran the budget."""
        self.runs += 1
        self.total_us += took_us
        self.max_us = max(self.max_us, took_us)
        over = took_us > self.budget_us
        self.overruns += over
        return over

    def to_json(self) -> dict:
        return {"budget_ms": self.budget_us / 1e3, "runs": self.runs, "overruns": self.overruns,
                "mean_ms": round(self.total_us / self.runs / 1e3, 3) if self.runs else None,
                "max_ms": self.max_us / 1e3}


class OverrunProfiler:
    """firmware.scheduler.TaskProfiler on the wall clock: times each task run and counts
    the runs over the task's budget. Tasks run one at a time, never nested."""

    def __init__(self, clock: WallClock, budgets_us: Mapping[str, int]) -> None:
        self._clock = clock
        self.tasks = {name: RunTimes(budget) for name, budget in budgets_us.items()}
        self._started_us = 0

    def enter(self, task: str) -> None:
        self._started_us = self._clock.now_us()

    def leave(self, task: str) -> None:
        took_us = self._clock.now_us() - self._started_us
        times = self.tasks[task]
        if times.add(took_us):
            log.debug("task %s took %.1f ms, over its budget of %.1f ms", task, took_us / 1e3, times.budget_us / 1e3)


@dataclass
class LoopResult:
    termination: str = "running"   # "complete", "time_limit", or what should_stop() said ("SIGTERM")
    wall_s: float = 0.0
    started_s: float | None = None  # when the loop started and ended, on the robot's clock (the shared
    ended_s: float | None = None    # clock of a team whose clocks have one epoch)
    # How the sign-off went: None (not complete, or not yet), "sent" (the heartbeat left the
    # air), "timed_out" (it had not after SIGN_OFF_FRAMES), "no_radio".
    sign_off: str | None = None
    sign_off_s: float = 0.0        # from the sign-off to the end
    ticks: int = 0
    ticks_skipped: int = 0         # tick slots that passed while the loop was behind
    tick: RunTimes = field(default_factory=lambda: RunTimes(0))    # whole ticks against the tick period
    tasks: dict[str, RunTimes] = field(default_factory=dict)

    def overruns(self) -> int:
        return self.tick.overruns + sum(t.overruns for t in self.tasks.values())

    def to_json(self) -> dict:
        return {"termination": self.termination, "wall_s": round(self.wall_s, 3),
                "started_s": _rounded(self.started_s), "ended_s": _rounded(self.ended_s),
                "sign_off": self.sign_off, "sign_off_s": round(self.sign_off_s, 3), "ticks": self.ticks,
                "ticks_skipped": self.ticks_skipped, "tick": self.tick.to_json(),
                "tasks": {name: t.to_json() for name, t in self.tasks.items()}}


class RobotLoop:
    """Ticks a set-up agent on `clock`; `followers` are called with the time before every
    tick. `result` holds the counts so far, also when `run` ends by an exception."""

    def __init__(self, agent: ExplorerAgent, clock: WallClock, followers: Sequence[Callable[[int], None]] = (),
                 log_interval_s: float = 10.0) -> None:
        self.agent = agent
        self.clock = clock
        self.followers = tuple(followers)
        self.tick_us = agent.rates.tick_period_us
        self.log_every_us = round(log_interval_s * 1e6)
        self.profiler = OverrunProfiler(clock, {t.name: t.time_budget_us for t in agent.scheduler.tasks})
        self.result = LoopResult(tick=RunTimes(self.tick_us), tasks=self.profiler.tasks)
        self._start_us = 0
        self._overruns_logged = 0
        link = agent.link
        if link is not None and link.tdma is not None:
            frame_us = link.tdma.slot_us * link.tdma.slots
        elif link is not None:
            longest_us = link.profile.airtime_us(link.max_frame_bytes)
            frame_us = -(-longest_us // self.tick_us) * self.tick_us + self.tick_us
        else:
            frame_us = 0
        self.sign_off_timeout_us = SIGN_OFF_FRAMES * frame_us
        self._signing_off_since_us: int | None = None

    def run(self, should_stop: Callable[[], str | None], max_s: float | None = None) -> LoopResult:
        """Tick until the mission is complete, max_s has passed or should_stop() gives a
        reason; the result's termination says which."""
        clock, result = self.clock, self.result
        self._start_us = clock.now_us()
        result.started_s = self._start_us / 1e6
        next_tick_us = -(-self._start_us // self.tick_us) * self.tick_us    # the first multiple from now on
        next_log_us = self._start_us + self.log_every_us
        try:
            while not (reason := self._reason_to_stop(should_stop, max_s)):
                clock.sleep_until_us(next_tick_us)
                if reason := should_stop():          # asked while the loop slept
                    break
                self._tick()
                next_tick_us, skipped = next_tick(next_tick_us, clock.now_us(), self.tick_us)
                result.ticks_skipped += skipped
                if clock.now_us() >= next_log_us:
                    self._log_progress()
                    next_log_us += ((clock.now_us() - next_log_us) // self.log_every_us + 1) * self.log_every_us
            result.termination = reason
        finally:
            ended_us = clock.now_us()
            result.ended_s = ended_us / 1e6
            result.wall_s = (ended_us - self._start_us) / 1e6
        return result

    def _tick(self) -> None:
        started_us = self.clock.now_us()
        for follow in self.followers:
            follow(started_us)
        self.agent.tick(self.profiler)
        self.result.ticks += 1
        self.result.tick.add(self.clock.now_us() - started_us)

    def _reason_to_stop(self, should_stop: Callable[[], str | None], max_s: float | None) -> str | None:
        agent = self.agent
        if reason := should_stop():
            return reason
        now_us = agent.hal.clock.now_us()
        if agent.done and not agent.roster.any_active(now_us):
            if reason := self._sign_off(now_us):
                return reason
        elif self._signing_off_since_us is not None:
            log.info("a teammate explores again (or this robot does): sign-off called off")
            self._signing_off_since_us = None
        if max_s is not None and self.clock.now_us() - self._start_us >= max_s * 1e6:
            return "time_limit"
        return None

    def _sign_off(self, now_us: int) -> str | None:
        """The stopping rule holds: sign off, or wait for the sign-off to leave the air;
        "complete" once it has (or the wait timed out)."""
        agent, result = self.agent, self.result
        since_us = self._signing_off_since_us
        if since_us is None:
            if not agent.sign_off(now_us):
                result.sign_off = "no_radio"
                return "complete"
            log.info("mission complete and no teammate exploring: signing off")
            self._signing_off_since_us = now_us
            return None
        if agent.radio_quiet(now_us):
            result.sign_off = "sent"
        elif now_us - since_us >= self.sign_off_timeout_us:
            log.warning("the sign-off heartbeat has not left the air after %.1f s; stopping all the same",
                        (now_us - since_us) / 1e6)
            result.sign_off = "timed_out"
        else:
            return None
        result.sign_off_s = (now_us - since_us) / 1e6
        return "complete"

    def _log_progress(self) -> None:
        """One line of counts; a warning if something overran since the line before."""
        result = self.result
        overruns = result.overruns()
        per_task = ", ".join(f"{name} {t.overruns}/{t.runs}" for name, t in result.tasks.items())
        level = logging.WARNING if overruns > self._overruns_logged else logging.INFO
        log.log(level, "%.1f s, %s: %d ticks (%d over %.0f ms, %d skipped); task overruns %s; %d scans",
                (self.clock.now_us() - self._start_us) / 1e6, self.agent.status, result.ticks, result.tick.overruns,
                self.tick_us / 1e3, result.ticks_skipped, per_task, self.agent.scans)
        self._overruns_logged = overruns


def next_tick(due_us: int, now_us: int, tick_us: int) -> tuple[int, int]:
    """(when the next tick is due, tick slots skipped) after the tick due at `due_us` ended
    at `now_us`: the slot after it or, if the loop is later than that, the latest slot that
    has begun (the slots before it are skipped)."""
    next_us = due_us + tick_us
    skipped = max(0, (now_us - next_us) // tick_us)
    return next_us + skipped * tick_us, skipped


def _rounded(seconds: float | None) -> float | None:
    return None if seconds is None else round(seconds, 3)
