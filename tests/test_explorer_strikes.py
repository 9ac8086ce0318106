"""What the planner does when it finds no route: strikes against a target count once per
planning period however often it replans. Hand-built local map: the presence tests' closed
corridor, with a wall across it; and where a robot off the traversable cells plans from."""
import dataclasses

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import ndimage

from firmware.params import ExplorationParams
from firmware.services.grid_paths import escape_start, nearest_traversable
from firmware.services.waypoints import Waypoint
from tests.doubles import PlannerRig
from tests.test_explorer_presence import _explorer as corridor
from tests.doubles import paint_box as paint

P = ExplorationParams()
# Ordinary plans that never take a tight passage: only the retry after a recovery does.
P_NO_PASSAGES = dataclasses.replace(P, tight_passage_cost=0.0)
ROBOT_XY = (10.0, 20.0)
TARGET_XY = (30.0, 20.0)
SECOND_US = 1_000_000


def _explorer(wall_across_at_x_m: float, params: ExplorationParams = P) -> PlannerRig:
    """The closed corridor of the presence tests (y in [19, 21] m from x = 5 to 35 m, open
    and unexplored beyond x = 35 m) with a wall across it at the given x: the open end lies
    beyond what the robot can reach. The target: a waypoint near the open end."""
    ex = corridor(door=False, params=params)
    paint(ex.local_map, wall_across_at_x_m, wall_across_at_x_m + 0.1, 18.8, 21.2, P.logodds_max)
    ex.waypoints.items = [Waypoint(*TARGET_XY, 5000.0)]
    return ex


def _strike_counts(ex: PlannerRig) -> dict[tuple[float, float], int]:
    return ex.targets.strikes()


def _in_w(ex: PlannerRig) -> bool:
    return any((w.x_m, w.y_m) == TARGET_XY for w in ex.waypoints.items)


def _open_gap(ex: PlannerRig, wall_x_m: float, cells: int) -> None:
    """A gap of `cells` free cells in the wall (two cells thick) across the corridor, about y = 20 m."""
    i, j = ex.local_map.cell_of(wall_x_m + 0.05, 20.05)
    ex.local_map.logodds[i - cells // 2:i - cells // 2 + cells, j:j + 2] = P.logodds_min


def test_fast_replans_strike_an_unreachable_target_once_per_planning_period():
    ex = _explorer(wall_across_at_x_m=25.0, params=P_NO_PASSAGES)
    _open_gap(ex, 25.0, 5)      # the body fits only with the walls at their cells' centres
    # A robot without a route replans every 0.2 s: five plans in one second are one strike.
    for t_us in range(0, SECOND_US, 200_000):
        plan = ex.plan(*ROBOT_XY, t_us)
        assert plan.target is None and not plan.done
    assert _in_w(ex) and _strike_counts(ex) == {TARGET_XY: 1}
    plan = ex.plan(*ROBOT_XY, SECOND_US)
    assert _in_w(ex) and not plan.done and _strike_counts(ex) == {TARGET_XY: 2}
    plan = ex.plan(*ROBOT_XY, 2 * SECOND_US)
    # The third strike asks for a recovery first (back off, turn, retry on tight paths, which
    # pass the gap); the target stays.
    assert plan.recover and not plan.done and _in_w(ex) and ex.stat("targets_unreachable") == 0
    ex.targets.recovery_started()
    plan = ex.plan(*ROBOT_XY, 3 * SECOND_US)
    assert not _in_w(ex) and ex.stat("targets_unreachable") == 1
    # Nothing left it can reach, but a frontier beyond the wall: one tight retry looks for a way.
    assert plan.recover and not plan.done
    plan = ex.plan(*ROBOT_XY, 4 * SECOND_US)
    assert plan.done, "a target unreachable for three planning periods and after a recovery is dropped for good"


def test_a_target_not_even_tight_paths_reach_is_dropped_without_a_recovery():
    ex = _explorer(wall_across_at_x_m=25.0)      # a solid wall: no way past it at all
    for t_us in (0, SECOND_US):
        ex.plan(*ROBOT_XY, t_us)
    plan = ex.plan(*ROBOT_XY, 2 * SECOND_US)
    assert not plan.recover and _in_w(ex) and _strike_counts(ex) == {TARGET_XY: 2}
    plan = ex.plan(*ROBOT_XY, 3 * SECOND_US)
    assert not _in_w(ex) and ex.stat("targets_unreachable") == 1
    # The frontier beyond the wall still gets its one tight look before the robot stops.
    assert plan.recover and not plan.done


# --- where a robot off the traversable cells plans from -------------------------------------

def test_a_robot_off_the_traversable_cells_plans_from_the_large_region_not_the_nearest_sliver():
    # The doorway of the Intel lab's one-robot mission (seed 3, 20 bit waypoints): the robot's cell is not
    # traversable, the nearest traversable cell is a sliver the safety margin cut off, and
    # the room it came from lies three cells farther.
    t = np.zeros((40, 40), bool)
    t[20, 21] = True                       # a one-cell sliver next to the robot
    t[10:30, 24:36] = True                 # the room
    assert nearest_traversable(t, 20, 20, 8) == (20, 21)
    assert escape_start(t, 20, 20, 8) == (20, 24)
    assert escape_start(t, 20, 20, 2) == (20, 21), "the room is out of reach: the sliver is all there is"
    assert escape_start(np.zeros((40, 40), bool), 20, 20, 8) is None


def _reference_escape_start(t: np.ndarray, i: int, j: int, r: int):
    """Plainly: label the 4-connected regions, take the cells of the square nearest first
    (lowest index on ties), return the first one whose region is as large as any there."""
    labels, _ = ndimage.label(t)
    sizes = np.bincount(labels.ravel())
    cells = [(a, b) for a in range(max(i - r, 0), min(i + r + 1, t.shape[0]))
             for b in range(max(j - r, 0), min(j + r + 1, t.shape[1])) if t[a, b]]
    if not cells:
        return None
    cells.sort(key=lambda c: ((c[0] - i) ** 2 + (c[1] - j) ** 2, c[0], c[1]))
    biggest = max(sizes[labels[c]] for c in cells)
    return next(c for c in cells if sizes[labels[c]] == biggest)


@settings(max_examples=150, deadline=None)
@given(st.integers(0, 2 ** 32 - 1), st.floats(0.2, 0.7), st.integers(0, 23), st.integers(0, 23), st.integers(1, 6))
def test_escape_start_equals_a_plain_reference_on_generated_grids(seed, density, i, j, r):
    t = np.random.default_rng(seed).random((24, 24)) < density
    assert escape_start(t, i, j, r) == _reference_escape_start(t, i, j, r)


# --- targets the topological graph cannot bring within reach ---------------------------------

def _own_place(ex: PlannerRig, x_m: float, y_m: float) -> None:
    ex.topo.add((0, round(x_m * 100), round(y_m * 100), 0, 1, 0, 0))


def test_targets_behind_a_wall_next_to_the_robots_own_places_are_dropped_not_taken_in_turns():
    # Two waypoints just beyond the wall, each nearest to a different place of the robot's own
    # on this side. The graph costs each as a place plus a straight line through the wall;
    # following it leads to that place and no further, so a robot taking the two in turn
    # drove between the two places for ever. Neither is a way on: both must be dropped.
    ex = _explorer(wall_across_at_x_m=25.0)
    a_xy, b_xy = (30.0, 19.5), (30.0, 20.5)
    ex.waypoints.items = [Waypoint(*a_xy, 5000.0), Waypoint(*b_xy, 5000.0)]
    for x_m in range(10, 24, 2):
        _own_place(ex, float(x_m), 20.0)
    _own_place(ex, 24.0, 19.3)                 # the nearest place to a
    _own_place(ex, 24.0, 20.7)                 # the nearest place to b
    x_m, y_m = 24.0, 19.3
    done = False
    for period in range(20):
        plan = ex.plan(x_m, y_m, period * SECOND_US)
        if plan.recover:
            ex.targets.recovery_started()
        elif len(plan.path_xy):
            x_m, y_m = plan.path_xy[-1]          # the robot drives the whole path in a period
        if plan.done:
            done = True
            break
    assert done, "the robot still heads for waypoints the grid says it cannot reach"
    assert ex.stat("targets_unreachable") >= 1   # dropping one bans the other, 1 m away
    assert not {a_xy, b_xy} & {(w.x_m, w.y_m) for w in ex.waypoints.items}

