"""Scheduler, topological map, local map and path follower behaviour."""
import math

import numpy as np
import pytest

from firmware.services.motion import PathFollower
from firmware.services.local_map import BinnedScan, LocalMap, bin_scan, something_within
from firmware.params import ExplorationParams, TaskRates
from firmware.scheduler import Scheduler, Task
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


def test_bin_scan_keeps_each_beam_on_its_own_bearing_in_the_world_frame():
    ranges = np.full(360, 5.0)
    ranges[0] = 1.0  # beam 0
    scan = bin_scan(2.0, 3.0, math.pi / 2 + 0.3, -math.pi, 2 * math.pi / 360, ranges, 10.0, 360)
    # angle_min = -pi, so beam 0 points backwards: world bearing pi/2 + 0.3 - pi, wrapped
    assert scan.bearing0_rad == pytest.approx(1.5 * math.pi + 0.3)
    assert scan.ranges_m[0] == 1.0 and np.all(scan.ranges_m[1:] == 5.0)
    assert (scan.x_m, scan.y_m, scan.range_max_m) == (2.0, 3.0, 10.0)
    half = bin_scan(0.0, 0.0, 0.0, -math.pi, 2 * math.pi / 360, ranges, 10.0, 180)
    assert half.ranges_m[0] == 1.0 and np.all(half.ranges_m[1:] == 5.0)   # shortest of beams 0, 1 (and 359)


def test_something_within_reach_counts_only_the_half_plane_ahead():
    ranges = np.full(360, 5.0)
    ranges[135] = 0.3                       # bearing 10 + 135 deg, 0.3 m away
    scan = BinnedScan(0.0, 0.0, math.radians(10), ranges, 10.0)
    assert something_within(scan, math.radians(100), 0.35)      # 45 deg off the heading
    assert not something_within(scan, math.radians(-80), 0.35)  # behind
    assert not something_within(scan, math.radians(100), 0.25)   # out of reach
    ranges[135] = 0.0                       # no beam in that bin
    assert not something_within(scan, math.radians(100), 0.35)


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


def test_local_map_window_is_fixed_and_places_that_left_it_come_back():
    p = ExplorationParams()
    m = LocalMap(p, 0.0, 0.0)
    size = m.logodds.nbytes
    ranges = np.full(360, 3.0)  # a round room of radius 3 m around (0, 0)
    m.integrate_scan(0.0, 0.0, 0.0, -math.pi, 2 * math.pi / 360, ranges, 10.0)
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
    # Only tiles holding something are paged out: the room's, 6.4 m a side at 0.1 m.
    assert 0 < m.pager.nbytes <= 4 * 64 * 64 * 4
