"""What the planner does when it finds no route: strikes against a target count once per
planning period however often it replans. Hand-built local map: the presence tests' closed
corridor, with a wall across it."""
from firmware.explorer import Explorer
from firmware.params import ExplorationParams
from firmware.waypoints import Waypoint
from tests.test_explorer_presence import _explorer as corridor
from tests.test_explorer_presence import paint

P = ExplorationParams()
ROBOT_XY = (10.0, 20.0)
TARGET_XY = (30.0, 20.0)
SECOND_US = 1_000_000


def _explorer(wall_across_at_x_m: float) -> Explorer:
    """The closed corridor of the presence tests (y in [19, 21] m from x = 5 to 35 m, open
    and unexplored beyond x = 35 m) with a wall across it at the given x: the open end lies
    beyond what the robot can reach. The target: a waypoint near the open end."""
    ex = corridor(door=False)
    paint(ex.map, wall_across_at_x_m, wall_across_at_x_m + 0.1, 18.8, 21.2, P.logodds_max)
    ex.waypoints.items = [Waypoint(*TARGET_XY, 5000.0)]
    return ex


def _strike_counts(ex: Explorer) -> dict[tuple[float, float], int]:
    return {key: count for key, (count, _) in ex._strikes.items()}


def _in_w(ex: Explorer) -> bool:
    return any((w.x_m, w.y_m) == TARGET_XY for w in ex.waypoints.items)


def test_fast_replans_strike_an_unreachable_target_once_per_planning_period():
    ex = _explorer(wall_across_at_x_m=25.0)
    # A robot without a route replans every 0.2 s: five plans in one second are one strike.
    for t_us in range(0, SECOND_US, 200_000):
        plan = ex.plan(*ROBOT_XY, t_us)
        assert plan.target is None and not plan.done
    assert _in_w(ex) and _strike_counts(ex) == {TARGET_XY: 1}
    plan = ex.plan(*ROBOT_XY, SECOND_US)
    assert _in_w(ex) and not plan.done and _strike_counts(ex) == {TARGET_XY: 2}
    plan = ex.plan(*ROBOT_XY, 2 * SECOND_US)
    assert not _in_w(ex) and ex.dropped_unreachable == 1
    assert plan.done, "a target unreachable for three planning periods is dropped for good"
