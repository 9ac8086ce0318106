"""Waypoints beyond the local window are re-scored on everything mapped
(WaypointSet.rescore_beyond_window): a place a dense teammate's scan explored is dropped,
one nobody saw is kept, and those inside the window are left to the planning cycle."""
import numpy as np

from firmware.params import ExplorationParams
from firmware.services.local_map import BinnedScan, LocalMap
from firmware.services.waypoints import Waypoint, WaypointSet

P = ExplorationParams()


def test_a_waypoint_beyond_the_window_is_dropped_once_a_teammates_scan_shows_it_explored():
    local_map = LocalMap(P, 0.0, 0.0)
    waypoints = WaypointSet(P)
    near = Waypoint(5.0, 0.0, 500.0)
    seen = Waypoint(3 * P.d_local_m, 0.0, 500.0)          # beyond the window
    unseen = Waypoint(0.0, 3 * P.d_local_m, 500.0)
    waypoints.items = [near, seen, unseen]
    assert waypoints.rescore_beyond_window(local_map) == 0
    assert seen.e_bit >= P.min_cluster_entropy_bit      # all unknown around it
    # A teammate's keyframes from there: a round room of 8 m radius, walls all around.
    for step_m in (0.0, 0.15):
        local_map.integrate_keyframe(BinnedScan(seen.x_m + step_m, seen.y_m + step_m, 0.0, np.full(1440, 8.0), 12.0))
    assert waypoints.rescore_beyond_window(local_map) == 1
    assert waypoints.items == [near, unseen] and near.e_bit == 500.0
