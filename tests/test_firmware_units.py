"""Scheduler, topological map, local map and path follower behaviour."""
import math

import numpy as np

from firmware.controller import PathFollower
from firmware.local_map import KeyframeStore, LocalMap, bin_scan_by_bearing, something_within
from firmware.params import ExplorationParams, TaskRates
from firmware.scheduler import Scheduler, Task
from firmware.topo_map import TopoMap
from firmware import kernels


def test_scheduler_runs_each_task_at_its_rate():
    runs = {"fast": [], "slow": []}
    s = Scheduler([Task("fast", 20, runs["fast"].append), Task("slow", 1, runs["slow"].append)])
    for k in range(41):
        s.run_due(k * 50_000)
    assert len(runs["fast"]) == 41
    assert runs["slow"] == [0, 1_000_000, 2_000_000]


def test_scheduler_skips_missed_periods_instead_of_replaying_them():
    runs = []
    s = Scheduler([Task("t", 10, runs.append)])
    s.run_due(0)
    s.run_due(1_050_000)  # ten periods late
    s.run_due(1_100_000)
    assert runs == [0, 1_050_000, 1_100_000]


def test_tick_period_is_the_fastest_rate():
    assert TaskRates().tick_period_us == 50_000


def test_bin_scan_by_bearing_rotates_into_the_world_frame():
    ranges = np.full(360, 5.0)
    ranges[0] = 1.0  # the beam straight ahead
    binned = bin_scan_by_bearing(math.pi / 2, -math.pi, 2 * math.pi / 360, ranges, 360)
    # angle_min = -pi, so beam 0 points backwards: world bearing pi/2 - pi = -pi/2 -> bin 270
    assert binned[270] == 1.0 and binned[90] == 5.0


def test_something_within_reach_counts_only_the_half_plane_ahead():
    binned = np.full(360, 5.0)
    binned[135] = 0.3                       # world bearing 135 deg, 0.3 m away
    assert something_within(binned, math.radians(90), 0.35)      # 45 deg off the heading
    assert not something_within(binned, math.radians(-90), 0.35)  # behind
    assert not something_within(binned, math.radians(90), 0.25)   # out of reach
    binned[135] = 0.0                       # no beam in that bin
    assert not something_within(binned, math.radians(90), 0.35)


def test_following_closely_steers_for_the_next_point_until_the_distance_is_driven():
    p = ExplorationParams()

    def east_then_north(x, y):
        """A path that leaves (x, y) eastwards for one cell, then turns north."""
        return np.array([(x + 0.1, y)] + [(x + 0.1, y + 0.1 * k) for k in range(1, 6)] + [(x + 0.1, y + 1.5)])

    normal = PathFollower(p, 0.8, 1.5)
    normal.set_path(east_then_north(0.0, 0.0))
    _, omega = normal.command(0.0, 0.0, math.pi / 2)        # facing north
    assert abs(omega) < 0.5, "pure pursuit looks 0.35 m ahead and cuts the corner northwards"
    close = PathFollower(p, 0.8, 1.5)
    close.follow_closely(0.5)
    close.set_path(east_then_north(0.0, 0.0))                # a new path keeps the order
    v, omega = close.command(0.0, 0.0, math.pi / 2)
    assert v == 0.0 and omega < -1.0, "turns right, towards the point east of it, first"
    # Having driven the distance (0.6 m north), it cuts corners again.
    close.command(0.0, 0.6, math.pi / 2)
    close.set_path(east_then_north(0.0, 0.6))
    _, omega = close.command(0.0, 0.6, math.pi / 2)
    assert abs(omega) < 0.5


def test_local_map_memory_is_fixed_and_keyframes_restore_what_left_the_window():
    p = ExplorationParams()
    kf = KeyframeStore(p.keyframe_bins)
    m = LocalMap(p, 0.0, 0.0, kf)
    size = m.logodds.nbytes
    ranges = np.full(360, 3.0)  # a round room of radius 3 m around (0, 0)
    m.integrate_scan(0.0, 0.0, 0.0, -math.pi, 2 * math.pi / 360, ranges, 10.0)
    kf.add(0.0, 0.0, bin_scan_by_bearing(0.0, -math.pi, 2 * math.pi / 360, ranges, 360), 10.0)
    before = kernels.classify(m.logodds, p.logodds_occupied, p.logodds_free)
    i, j = m.cell_of(1.0, 1.0)
    assert before[i, j] == kernels.FREE
    for x in np.arange(2.0, 60.0, 2.0):      # drive far away: the room leaves the window
        m.follow(x, 0.0)
    assert not m.contains(0.0, 0.0)
    for x in np.arange(60.0, -1.0, -2.0):    # and come back
        m.follow(x, 0.0)
    assert m.logodds.nbytes == size
    after = kernels.classify(m.logodds, p.logodds_occupied, p.logodds_free)
    i, j = m.cell_of(1.0, 1.0)
    assert after[i, j] == kernels.FREE
    i, j = m.cell_of(3.05, 0.0)
    assert after[i, j] == kernels.OCCUPIED
