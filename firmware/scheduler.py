"""A fixed task table run from the tick loop: each task has a rate and runs when due.

Time comes from the caller (the HAL clock); the scheduler never reads a clock itself. An
optional profiler object (the host's benchmark and `lorascout robot` pass one) is told when
each task starts and ends, so the firmware stays free of any timing code.

Every task has a time budget: the longest one run of it may take. It is the task's period
unless the table declares a smaller one: a task that runs longer than its period delays its
own next run and every task after it. The profilers count the runs over budget (overruns).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Protocol


class TaskProfiler(Protocol):
    def enter(self, task: str) -> None: ...

    def leave(self, task: str) -> None: ...


@dataclass
class Task:
    name: str
    rate_hz: float
    run: Callable[[int], None]     # called with the tick's time, in microseconds
    next_due_us: int = 0
    budget_us: int | None = None   # None: the task's period

    @property
    def period_us(self) -> int:
        return int(round(1_000_000 / self.rate_hz))

    @property
    def time_budget_us(self) -> int:
        return self.period_us if self.budget_us is None else self.budget_us


class Scheduler:
    def __init__(self, tasks: list[Task]) -> None:
        self.tasks = tasks

    def run_due(self, now_us: int, profiler: TaskProfiler | None = None) -> None:
        """Run, in table order, every task whose time has come. A late task runs once and
        then keeps its own period grid: missed periods are skipped, not replayed."""
        for task in self.tasks:
            if now_us < task.next_due_us:
                continue
            if profiler is not None:
                profiler.enter(task.name)
            task.run(now_us)
            if profiler is not None:
                profiler.leave(task.name)
            period = task.period_us
            missed = (now_us - task.next_due_us) // period
            task.next_due_us += (missed + 1) * period
