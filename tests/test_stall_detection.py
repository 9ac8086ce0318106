"""Telling that the body does not move, from what a robot has: wheels that stop with it, and
wheels that slip while odometry runs on and the LiDAR shows the robot where it was."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from firmware.params import ExplorationParams
from firmware.services.motion import StallDetector
from hal.sim.drive import SimDriveBase
from hal.sim.lidar import SimLidar
from hal.sim.odometry import SimOdometry
from tests.doubles import room
from world_sim.occupancy_map import OccupancyMap
from world_sim.world import World, WorldParams

P = ExplorationParams()
TICK_US = 50_000
CONTROL_HZ = 20.0


def _drive(occ: OccupancyMap, start, v_mps: float, seconds: float, slip: float):
    """Drive straight at v_mps, feeding the detector as the agent does: the command every
    tick, each scan with the odometry pose of its time, and the pose corrected where it found
    a slip (a shift along x: the drive is straight along it). Returns the times (s) at which
    it said stuck, for each slip it found how far behind the corrected pose and how far from
    the true position it put the body (x, m), and the world."""
    world = World(occ, [start], seed=3, params=dataclasses.replace(WorldParams(), wheel_slip_frac=slip,
                                                                       lidar_phase_us=23_000))
    drive, lidar, odometry = SimDriveBase(world, 0), SimLidar(world, 0), SimOdometry(world, 0)
    detector = StallDetector(P, CONTROL_HZ)
    stuck_s, slipped = [], []
    shift_x_m = 0.0   # corrected pose = odometry's + this
    for _ in range(int(seconds * 1e6 / TICK_US)):
        world.step(TICK_US)
        scan = lidar.latest_scan()
        o = odometry.read()
        if scan is not None:
            # Straight driving: the pose at the scan's time, from the pose now and the speed.
            back_s = (o.stamp_us - scan.stamp_us) * 1e-6
            x_m = o.x_m - o.v_mps * back_s * np.cos(o.yaw_rad)
            y_m = o.y_m - o.v_mps * back_s * np.sin(o.yaw_rad)
            held_at = detector.on_scan(x_m, y_m, o.yaw_rad, scan.angle_min_rad, scan.angle_increment_rad,
                                       scan.ranges_m, scan.range_max_m)
            if held_at is not None:
                body_x_m = held_at[0] + shift_x_m
                slipped.append((x_m + shift_x_m - body_x_m, world.true_pose(0).x_m - body_x_m))
                shift_x_m = body_x_m - x_m
        if detector.stuck(o.v_mps):
            stuck_s.append(world.now_us / 1e6)
        drive.command(v_mps, 0.0)
        detector.commanded(v_mps)
    return stuck_s, slipped, world


@pytest.mark.parametrize("slip", [0.0, 0.5, 1.0])
def test_a_body_pushing_a_wall_is_told_within_two_seconds_whether_the_wheels_stop_or_slip(slip):
    # 3.65 m short of the east wall of a 20 x 8 m room at 0.5 m/s: the body reaches it after 7.3 s.
    stuck_s, slipped, world = _drive(room(20.0, 8.0), (16.0, 3.0, 0.0), 0.5, 14.0, slip)
    contact_s = (19.9 - 0.25 - 16.0) / 0.5
    assert stuck_s, "pushing a wall for 6 s was never noticed"
    assert contact_s - 0.2 < stuck_s[0] < contact_s + 2.0
    if slip > 0.0:
        # Where the scans put the body: behind where the corrected pose says, and near where it is.
        assert slipped and all(behind_m > 0.5 * P.slip_check_m and abs(off_m) < 0.05 for behind_m, off_m in slipped)


@pytest.mark.parametrize("width_m,height_m,start_y_m,seconds", [(20.0, 8.0, 4.0, 14.0), (40.0, 2.0, 1.0, 20.0)])
def test_driving_freely_is_never_called_stuck_even_along_a_featureless_corridor(width_m, height_m, start_y_m,
                                                                              seconds):
    # Along the middle of a 20 x 8 m room, and along a 2 m wide, 40 m long corridor whose far
    # end is beyond the LiDAR's 10 m for most of the way (every share of the travel fits its
    # walls alike); east from x = 2 m at 0.6 m/s.
    stuck_s, slipped, _ = _drive(room(width_m, height_m), (2.0, start_y_m, 0.0), 0.6, seconds, slip=1.0)
    far_end_x = width_m - 0.1 - 0.25
    assert not [t for t in stuck_s if 2.0 + 0.6 * t < far_end_x - 0.1]
    assert not slipped or stuck_s
