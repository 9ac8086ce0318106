"""Target keeping: which candidate the robot heads for, and how a target ends.

Every scheme ranks candidates its own way (firmware.schemes); choosing among them, keeping
the current one against small improvements, counting strikes against targets without a
route, budgeting time per target, and deciding that a target was reached or seen on the way
are the same for all of them, and live here.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from firmware.params import ExplorationParams
from firmware.services.waypoints import WaypointSet

# How a target ended (told to the scheme, counted in the mission's statistics).
REACHED = "reached"
SEEN_ON_WAY = "seen_on_way"
UNREACHABLE = "unreachable"
STALLED = "stalled"
OUTCOMES = (REACHED, SEEN_ON_WAY, UNREACHABLE, STALLED)


@dataclass
class Target:
    x_m: float
    y_m: float
    cost_m: float
    from_team: bool = False    # a candidate the scheme added on the team's behalf, not an own waypoint


@dataclass
class Candidate:
    """A place the robot might head for, as the scheme's planning stage hands it back."""

    x_m: float
    y_m: float
    e_bit: float
    from_team: bool
    cost_m: float = math.inf        # this robot's cost (local map where it can, else the graph)
    graph_cost_m: float = math.inf  # this robot's cost beyond the local window (the scheme's)
    rank: int = 0                   # lower is better; the scheme's ranking, before cost
    penalty_m: float = 0.0          # the scheme's utility discount, in metres of path added to the cost
    local_cell: tuple[int, int] | None = None   # its local map cell, if a grid path reaches it
    # A scheme that chooses by utility per metre (WiSER-X's eq. 2, gain / cost; Pereira's A9,
    # e_bit / (cost + 1 m)) sets the gain, and the metres added to the cost before dividing;
    # nan: the choice is by cost plus penalty.
    gain: float = math.nan
    gain_cost_offset_m: float = 0.0

    @property
    def by_gain(self) -> bool:
        return not math.isnan(self.gain)

    def gain_per_m(self, min_cost_m: float) -> float:
        return self.gain / max(self.cost_m + self.gain_cost_offset_m, min_cost_m)


class TargetKeeper:
    def __init__(self, params: ExplorationParams, waypoints: WaypointSet) -> None:
        self.p = params
        self.waypoints = waypoints
        self.target: Target | None = None
        self._best_progress_m = math.inf
        self._progress_stamp_us = 0
        self._time_on_us: dict[tuple[float, float], int] = {}
        self._budget_us: dict[tuple[float, float], int] = {}
        self._last_track_us = 0
        # Per target without a route: (strikes, when the last one counted).
        self._strikes: dict[tuple[float, float], tuple[int, int]] = {}
        self.counts: dict[str, int] = dict.fromkeys(OUTCOMES, 0)
        # Recovery (services.recovery) before a target is given up: targets waiting for one,
        # and those that had theirs (given up for good the next time they fail).
        self._wanting_recovery: set[tuple[float, float]] = set()
        self._recovered: set[tuple[float, float]] = set()

    # --- recovery ---------------------------------------------------------------------
    @property
    def recovery_wanted(self) -> bool:
        """A target failed for the first time: recover (and retry) before giving it up."""
        return bool(self._wanting_recovery)

    def waiting_for_recovery(self) -> frozenset[tuple[float, float]]:
        """The targets (positions) whose first failure asks for a recovery."""
        return frozenset(self._wanting_recovery)

    def no_recovery_for(self, keys: set[tuple[float, float]]) -> None:
        """These targets go without a recovery: their next failure gives them up."""
        self._recovered |= self._wanting_recovery & keys
        self._wanting_recovery -= keys

    def recovery_started(self) -> None:
        """The targets waiting for a recovery have it now: the next failure gives them up."""
        self._recovered |= self._wanting_recovery
        self._wanting_recovery = set()

    def _first_failure(self, key: tuple[float, float]) -> bool:
        """Is this the target's first failure (so a recovery comes before giving it up)?"""
        if key in self._recovered:
            return False
        self._wanting_recovery.add(key)
        return True

    # --- outcomes found at the start of a planning cycle ------------------------------
    def end_if_seen_on_way(self, x_m: float, y_m: float) -> Target | None:
        """Our own target left W: its information is now observed. Seen from within
        target_seen_within_m (0: never), it is done with as if reached, and no waypoint is
        made there again. Without that, a waypoint in front of a door of the Intel lab
        (MinPos, seed 5) kept coming back with about 1100 bit after the robot had seen it
        from 0.6 m, and the robot drove back to it eight times (likely a few cells there
        turning unknown again, reopening a view). Returns the target so ended."""
        t = self.target
        if t is not None and not t.from_team and math.hypot(t.x_m - x_m, t.y_m - y_m) < self.p.target_seen_within_m \
                and not any((w.x_m, w.y_m) == (t.x_m, t.y_m) for w in self.waypoints.items):
            return self._end(SEEN_ON_WAY)
        return None

    def end_if_reached(self, x_m: float, y_m: float) -> Target | None:
        """A target reached is done with: its surroundings are now observed (or
        unobservable). Returns the target so ended."""
        t = self.target
        if t is not None and math.hypot(t.x_m - x_m, t.y_m - y_m) < self.p.waypoint_reached_m:
            return self._end(REACHED)
        return None

    def _end(self, outcome: str) -> Target:
        t = self.target
        self.waypoints.ban(t.x_m, t.y_m, failed=outcome == STALLED)
        self.counts[outcome] += 1
        self.target = None
        return t

    # --- choosing ---------------------------------------------------------------------
    def forget_strikes_except(self, candidates: list[Candidate]) -> None:
        """Strikes only count for targets that are still targets."""
        keys = {(c.x_m, c.y_m) for c in candidates}
        self._strikes = {k: v for k, v in self._strikes.items() if k in keys}
        self._wanting_recovery &= keys

    def choose(self, candidates: list[Candidate]) -> Candidate:
        """Lowest rank, then the closest (cost plus the scheme's penalty). The current target
        is kept unless another is clearly better, so the robot does not dither."""
        if any(c.by_gain for c in candidates):
            return self._choose_by_gain(candidates)
        key = lambda c: (c.rank, c.cost_m + c.penalty_m, c.x_m, c.y_m)  # noqa: E731
        best = min(candidates, key=key)
        if self.target is not None:
            for c in candidates:
                if (c.x_m, c.y_m) == (self.target.x_m, self.target.y_m) and c.rank <= best.rank \
                        and best.cost_m + best.penalty_m >= 0.8 * (c.cost_m + c.penalty_m):
                    return c
        return best

    def _choose_by_gain(self, candidates: list[Candidate]) -> Candidate:
        """Lowest rank, then the highest gain per metre of cost (a candidate without a gain
        has none); the current target is kept unless another's is clearly higher."""
        floor = self.p.resolution_m
        value = lambda c: c.gain_per_m(floor) if c.by_gain else 0.0  # noqa: E731
        best = min(candidates, key=lambda c: (c.rank, -value(c), c.x_m, c.y_m))
        if self.target is not None:
            for c in candidates:
                if (c.x_m, c.y_m) == (self.target.x_m, self.target.y_m) and c.rank <= best.rank \
                        and 0.8 * value(best) <= value(c):
                    return c
        return best

    def head_for(self, c: Candidate, now_us: int, reaches_it: bool = True) -> Target | None:
        """The robot has a route to c and heads there. Time spent heading for each target
        accumulates across switches, so two targets taking turns cannot keep a robot busy
        for ever; a target the robot gets no closer to within its budget is given up
        (returned, with the outcome STALLED counted). A route that reaches c clears its
        strikes; one that ends at a place on the way (reaches_it False: where the
        topological map or the window ends) leaves them standing, for c may prove out of
        reach from there again, and a robot that left there for another target and came
        back would otherwise start counting afresh each time."""
        key = (c.x_m, c.y_m)
        if reaches_it:
            self._strikes.pop(key, None)
        if self.target is not None:
            prev = (self.target.x_m, self.target.y_m)
            self._time_on_us[prev] = self._time_on_us.get(prev, 0) + now_us - self._last_track_us
        self._last_track_us = now_us
        same = self.target is not None and (self.target.x_m, self.target.y_m) == key
        if not same:
            self.target = Target(c.x_m, c.y_m, c.cost_m, c.from_team)
            self._best_progress_m = c.cost_m
            self._progress_stamp_us = now_us
            # A budget: the stall timeout plus the first cost at a crawl (0.25 m/s).
            self._budget_us.setdefault(key, int((self.p.stall_timeout_s + 4.0 * c.cost_m) * 1e6))
            return None
        self.target.cost_m = c.cost_m
        if c.cost_m < self._best_progress_m - 0.3:
            self._best_progress_m = c.cost_m
            self._progress_stamp_us = now_us
        if now_us - self._progress_stamp_us > self.p.stall_timeout_s * 1e6 \
                or self._time_on_us.get(key, 0) > self._budget_us[key]:
            # Paths keep promising but the robot gets no closer: recover and retry once, then
            # give up on this target.
            if self._first_failure(key):
                self._progress_stamp_us = now_us
                self._budget_us[key] = self._time_on_us.get(key, 0) + int(self.p.stall_timeout_s * 1e6)
                return None
            return self._end(STALLED)
        return None

    def strike(self, c: Candidate, now_us: int) -> bool:
        """No way to c from here, not even along the topological map. A map glitch can
        cause that for a moment, so it takes several cycles in a row to drop it for good,
        and cycles count at most once per unreachable_strike_interval_s: a robot without a
        route replans every 0.2 s, and three strikes took 0.35 s, too short for the map to
        change (Intel lab, one robot, seed 3: every target dropped at once). The first time
        the strikes run out, a recovery comes first (recovery_wanted) and one more strike
        after it drops c. True when c is dropped for good (banned, outcome UNREACHABLE
        counted)."""
        key = (c.x_m, c.y_m)
        count, last_us = self._strikes.get(key, (0, None))
        if last_us is None or now_us - last_us >= self.p.unreachable_strike_interval_s * 1e6:
            count, last_us = count + 1, now_us
            self._strikes[key] = (count, last_us)
        self.target = None
        if count >= self.p.unreachable_strikes and self._first_failure(key):
            # One more strike after the recovery drops it.
            self._strikes[key] = (self.p.unreachable_strikes - 1, last_us)
            return False
        if count >= self.p.unreachable_strikes:
            self.waypoints.ban(c.x_m, c.y_m)
            self.counts[UNREACHABLE] += 1
            return True
        return False

    def strikes(self) -> dict[tuple[float, float], int]:
        """Strikes held against targets without a route, by target position."""
        return {key: count for key, (count, _) in self._strikes.items()}

    def strikes_pending(self) -> bool:
        """Targets merely unreachable right now (still collecting strikes, or waiting for
        their recovery) keep the robot planning: it is done only when no target is left."""
        return any(count < self.p.unreachable_strikes for count, _ in self._strikes.values()) \
            or self.recovery_wanted
