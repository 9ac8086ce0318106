"""The team roster: who this robot has heard of, when, where, and whether it said it was done.

Schemes read it (MinPos counts the teammates still exploring) and feed it from their own
records (a Bayer & Faigl vertex with presence says where its sender was); the core
heartbeat feeds it for every scheme. A teammate not heard of for `max_age_us` counts as
gone: a robot whose last "done" was lost, or that died, stops being counted as exploring.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass
class Member:
    x_m: float
    y_m: float
    heard_us: int          # when this robot last heard of it (its own clock)
    done: bool = False


class Roster:
    def __init__(self, robot_id: int, max_age_us: int | None = None) -> None:
        """max_age_us: a teammate not heard of for longer is left out of `active`
        (None: never aged out)."""
        self.robot_id = robot_id
        self.max_age_us = max_age_us
        self._members: dict[int, Member] = {}

    def heard_at(self, robot_id: int, x_m: float, y_m: float, now_us: int) -> None:
        """A record placed the teammate at (x, y) (whether it is done, it did not say)."""
        if robot_id == self.robot_id:
            return
        m = self._members.get(robot_id)
        self._members[robot_id] = Member(x_m, y_m, now_us, done=m is not None and m.done)

    def heard_status(self, robot_id: int, x_m: float, y_m: float, done: bool, now_us: int) -> None:
        """A heartbeat: where the teammate is and whether it has finished (for good: a
        finished robot explores nothing more)."""
        if robot_id == self.robot_id:
            return
        m = self._members.get(robot_id)
        self._members[robot_id] = Member(x_m, y_m, now_us, done=bool(done) or (m is not None and m.done))

    def _alive(self, m: Member, now_us: int) -> bool:
        return self.max_age_us is None or now_us - m.heard_us <= self.max_age_us

    def active(self, now_us: int) -> dict[int, tuple[float, float]]:
        """Teammates still exploring, as last heard, by id in ascending order: not done
        and, with aging, heard of within max_age_us of now_us."""
        return {rid: (m.x_m, m.y_m) for rid, m in sorted(self._members.items())
                if not m.done and self._alive(m, now_us)}

    def any_active(self, now_us: int) -> bool:
        return bool(self.active(now_us))

    def members(self) -> dict[int, Member]:
        """Every teammate ever heard of, by id (copies)."""
        return {rid: Member(m.x_m, m.y_m, m.heard_us, m.done) for rid, m in sorted(self._members.items())}
