"""Pockets (waypoints holding less than report_unreachable_bit) are not chased across the map."""
from types import SimpleNamespace

import numpy as np

from firmware import kernels
from firmware.params import ExplorationParams
from firmware.services.waypoints import Waypoint, WaypointSet

P = ExplorationParams()


def test_a_pocket_is_worth_heading_for_only_near_or_while_it_is_the_target():
    small = P.report_unreachable_bit / 2
    waypoints = WaypointSet(P)
    near_pocket = Waypoint(P.pocket_reach_m - 0.5, 0.0, small)
    far_pocket = Waypoint(0.0, P.pocket_reach_m + 0.5, small)
    held_pocket = Waypoint(-20.0, 0.0, small)
    far_room = Waypoint(30.0, 30.0, P.report_unreachable_bit)
    waypoints.items = [near_pocket, far_pocket, held_pocket, far_room]
    assert waypoints.worth_heading_for(0.0, 0.0) == [near_pocket, far_room]
    assert waypoints.worth_heading_for(0.0, 0.0, held=(-20.0, 0.0)) == [near_pocket, held_pocket, far_room]
    assert waypoints.worth_heading_for(0.0, 8.0) == [far_pocket, far_room]
    # A frontier's one try before stopping goes wherever it is and whatever it holds now.
    last_try = waypoints.take_up(-40.0, 0.0, P.report_unreachable_bit)
    last_try.e_bit = small
    assert last_try in waypoints.worth_heading_for(0.0, 0.0)


def _free_hall_with_a_pocket(pocket_row: int, pocket_col: int) -> np.ndarray:
    """A 250 x 250 cell hall, all seen but for an unknown patch of 6 x 6 cells: more than
    e_min, less than report_unreachable_bit."""
    state = np.full((250, 250), kernels.FREE, np.uint8)
    state[pocket_row:pocket_row + 6, pocket_col:pocket_col + 6] = kernels.UNKNOWN
    return state


def test_a_last_look_takes_a_pocket_near_the_robot_and_not_one_across_the_map():
    window = SimpleNamespace(row0=0, col0=0)
    res = P.resolution_m
    for pocket_at, robot_at, expect_a_look in (((230, 230), (10, 10), False), ((230, 230), (225, 225), True)):
        state = _free_hall_with_a_pocket(*pocket_at)
        reachable = state == kernels.FREE
        x_m, y_m = (robot_at[1] + 0.5) * res, (robot_at[0] + 0.5) * res
        look = WaypointSet(P).look_again(window, state, reachable, x_m, y_m)
        if expect_a_look:
            assert look is not None and P.min_cluster_entropy_bit <= look.e_bit < P.report_unreachable_bit
            assert np.hypot(look.x_m - x_m, look.y_m - y_m) <= P.pocket_reach_m
        else:
            assert look is None
