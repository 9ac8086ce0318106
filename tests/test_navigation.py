"""Navigation through gaps the body just fits: a room behind a door 0.1 m wider than the
robot, explored from inside and from outside, on a raster aligned with the robot's map and
on one shifted against it by a fraction of a cell."""
from __future__ import annotations

import numpy as np
import pytest

from host_tools.mission import MissionConfig, run_mission
from tests.test_maps_ros import write_map

FREE, WALL = 254, 0
CELL_M = 0.1


def room_behind_a_door(folder, door_cells: int = 6, origin_m: float = 0.0) -> str:
    """A 4 x 4 m room (x 0.2..4.2 m) whose only door, door_cells wide, opens into a 6 x 4 m
    hall (x 4.4..10.4 m); walls 0.2 m thick. Baffle walls 1 m from the door on both sides
    hide most of each space from the other: the robot must pass the door to see them. The
    robot is 0.5 m wide: 6 cells is 0.1 m more."""
    rows, cols = 44, 106
    px = np.full((rows, cols), WALL, np.uint8)
    px[2:42, 2:42] = FREE                    # the room
    px[2:42, 44:104] = FREE                  # the hall
    top = 22 - door_cells // 2
    px[top:top + door_cells, 42:44] = FREE   # the door through the 0.2 m wall
    px[13:31, 31:33] = WALL                  # the room's baffle, 1 m inside the door
    px[13:31, 53:55] = WALL                  # the hall's baffle
    return str(write_map(folder, px, origin=f"[{origin_m}, {origin_m}, 0.0]"))


def _explore(map_path, start_xy, seed=0):
    return run_mission(MissionConfig(map_spec=map_path, seed=seed, max_sim_s=900.0,
                                     starts=((start_xy[0], start_xy[1], 0.0),)))


@pytest.mark.parametrize("origin_m", [0.0, 0.03, 0.05])
@pytest.mark.parametrize("inside", [True, False])
def test_a_robot_explores_a_room_behind_a_door_a_tenth_wider_than_its_body(tmp_path, inside, origin_m):
    m = room_behind_a_door(tmp_path, origin_m=origin_m)
    start = (1.5 + origin_m, 1.0 + origin_m) if inside else (9.0 + origin_m, 3.5 + origin_m)
    r = _explore(m, start)
    assert r.coverage >= 0.99, (r.coverage, r.termination)
    assert r.termination == "complete"
    assert r.robots_in_wall == 0


def test_behind_a_door_narrower_than_the_body_the_robot_reports_frontiers_it_cannot_reach(tmp_path):
    m = room_behind_a_door(tmp_path, door_cells=4)          # 0.4 m: the 0.5 m body does not fit
    r = _explore(m, (9.0, 3.5))
    traj = r.trajectories[0]
    assert (traj[:, 0] > 4.3).all()                         # never inside the wall or the room
    # The room is not part of the area the body can reach: the mission is complete, and the
    # robot says which frontiers lie behind a gap narrower than its body.
    assert r.coverage >= 0.99 and r.termination == "complete"
    report = r.to_json()
    assert report["narrow_gap_frontiers"][0] >= 1 and report["narrow_gap_frontier_area_m2"][0] > 0
    assert report["unreachable_frontiers"] == [0]


@pytest.mark.parametrize("seed", [1, 2, 3, 4])
@pytest.mark.parametrize("door_cells", [4, 6])
def test_other_seeds_end_complete_with_the_hall_seen_and_the_room_only_through_a_door_the_body_fits(tmp_path, seed,
                                                                                                 door_cells):
    r = _explore(room_behind_a_door(tmp_path, door_cells=door_cells), (9.0, 3.5), seed=seed)
    assert r.termination == "complete" and r.coverage >= 0.99, (r.termination, r.coverage)
    entered = (r.trajectories[0][:, 0] < 4.2).any()
    assert entered == (door_cells == 6)
