"""Scan-to-map matching (services.scan_match) and the pose correction it feeds
(services.pose): an offset odometry pose is pulled back onto the map where the walls
constrain it, and left alone along a corridor that does not."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from firmware.params import ExplorationParams
from firmware.services.local_map import LocalMap
from firmware.services.pose import PoseService
from firmware.services.scan_match import ScanMatcher
from hal.samples import OdometrySample
from host_tools.mission import MissionConfig, run_mission
from world_sim.raycast import cast_rays
from world_sim.world import WorldParams

P = ExplorationParams(scan_match=True)
BEAMS = 360
ANGLE_MIN = -math.pi
INC = 2 * math.pi / BEAMS
RANGE_MAX_M = 10.0
WORLD_RES_M = 0.02      # the world finer than the map, and off its lattice


def _world(free: list[tuple[float, float, float, float]], pillars: list[tuple[float, float]]) -> np.ndarray:
    """A wall grid (uint8, 1 = wall) over x, y in [-20, 20) m: free boxes (x0, x1, y0, y1)
    with square pillars 0.3 m a side at the given centres."""
    n = int(40 / WORLD_RES_M)
    c = (np.arange(n) + 0.5) * WORLD_RES_M - 20.0
    xx, yy = np.meshgrid(c, c)
    wall = np.ones((n, n), np.uint8)
    for x0, x1, y0, y1 in free:
        wall[(xx >= x0) & (xx < x1) & (yy >= y0) & (yy < y1)] = 0
    for px, py in pillars:
        wall[(abs(xx - px) < 0.15) & (abs(yy - py) < 0.15)] = 1
    return wall


def _scan(wall: np.ndarray, x: float, y: float, yaw: float) -> np.ndarray:
    angles = yaw + ANGLE_MIN + np.arange(BEAMS) * INC
    return cast_rays(wall, -20.0, -20.0, WORLD_RES_M, x, y, angles, RANGE_MAX_M).astype(np.float32)


def _mapped(wall: np.ndarray, poses: list[tuple[float, float, float]]) -> LocalMap:
    local_map = LocalMap(P, 0.0, 0.0)
    for x, y, yaw in poses:
        local_map.integrate_scan(x, y, yaw, ANGLE_MIN, INC, _scan(wall, x, y, yaw), RANGE_MAX_M)
    return local_map


ROOM = _world([(-4.0, 4.0, -3.0, 3.0)], [(1.5, 1.0), (-2.0, -1.2), (2.5, -2.0)])
CORRIDOR = _world([(-19.0, 19.0, -1.0, 1.0)], [])


@pytest.mark.parametrize("offset", [(0.06, -0.05, 0.0), (-0.04, 0.0, 0.012), (0.0, 0.07, -0.015)])
def test_a_scan_taken_off_the_odometry_pose_is_matched_back_onto_the_map(offset):
    truth = (0.3, -0.2, 0.4)
    local_map = _mapped(ROOM, [(0.0, 0.0, 0.0), (0.5, 0.3, 1.0), (-0.5, -0.4, 2.0)])
    matcher = ScanMatcher(P)
    predicted = tuple(t + o for t, o in zip(truth, offset))
    found = matcher.match(local_map, *predicted, ANGLE_MIN, INC, _scan(ROOM, *truth), RANGE_MAX_M)
    assert found is not None
    assert math.hypot(found[0] - truth[0], found[1] - truth[1]) <= 0.03, found
    assert abs(found[2] - truth[2]) <= 0.006, found


def test_a_correction_must_gain_at_least_scan_match_min_gain_over_odometry():
    """The same offset pose as above: a correction gains a clear score there, so a threshold
    below the gain corrects and one above it keeps odometry's pose."""
    truth, predicted = (0.3, -0.2, 0.4), (0.36, -0.25, 0.4)
    local_map = _mapped(ROOM, [(0.0, 0.0, 0.0), (0.5, 0.3, 1.0), (-0.5, -0.4, 2.0)])
    scan = _scan(ROOM, *truth)
    corrected = ScanMatcher(P).match(local_map, *predicted, ANGLE_MIN, INC, scan, RANGE_MAX_M)
    kept = ScanMatcher(dataclasses.replace(P, scan_match_min_gain=1.0)).match(
        local_map, *predicted, ANGLE_MIN, INC, scan, RANGE_MAX_M)
    assert corrected is not None and math.hypot(corrected[0] - truth[0], corrected[1] - truth[1]) <= 0.03
    assert kept == predicted


def test_along_a_featureless_corridor_odometry_is_kept_and_across_it_corrected():
    local_map = _mapped(CORRIDOR, [(x, 0.0, 0.0) for x in (-6.0, -3.0, 0.0, 3.0, 6.0)])
    truth = (0.0, 0.1, 0.0)
    found = ScanMatcher(P).match(local_map, 0.05, 0.15, 0.0, ANGLE_MIN, INC, _scan(CORRIDOR, *truth), RANGE_MAX_M)
    assert found is not None
    assert found[0] == pytest.approx(0.05)              # along: nothing to go by
    assert abs(found[1] - truth[1]) <= 0.02             # across: the walls
    assert abs(found[2]) <= 0.006


def test_nothing_mapped_nothing_matched():
    local_map = LocalMap(P, 0.0, 0.0)
    assert ScanMatcher(P).match(local_map, 0.0, 0.0, 0.0, ANGLE_MIN, INC, _scan(ROOM, 0.0, 0.0, 0.0),
                                RANGE_MAX_M) is None


def test_matching_is_due_after_travel_or_turning_and_never_when_off():
    matcher = ScanMatcher(P)
    local_map = _mapped(ROOM, [(0.0, 0.0, 0.0)])
    assert matcher.due(0.0, 0.0, 0.0)
    matcher.match(local_map, 0.0, 0.0, 0.0, ANGLE_MIN, INC, _scan(ROOM, 0.0, 0.0, 0.0), RANGE_MAX_M)
    assert not matcher.due(0.1, 0.0, 0.05)
    assert matcher.due(P.scan_match_every_m, 0.0, 0.0)
    assert matcher.due(0.0, 0.0, P.scan_match_every_rad)
    assert not ScanMatcher(ExplorationParams()).due(0.0, 0.0, 0.0)      # off by default


class _Odometry:
    def __init__(self) -> None:
        self.sample = OdometrySample(0, 0.0, 0.0, 0.0, 0.0, 0.0)

    def read(self) -> OdometrySample:
        return self.sample


def test_a_correction_carries_on_rigidly_to_the_odometry_that_follows():
    odo = _Odometry()
    pose = PoseService(odo)
    odo.sample = OdometrySample(1_000, 2.0, 1.0, 0.5, 0.5, 0.0)
    pose.read()
    pose.correct_at(1_000, 2.1, 0.9, 0.52)
    assert pose.pose_at(1_000) == pytest.approx((2.1, 0.9, 0.52))
    # One metre straight ahead by odometry is one metre ahead of the corrected pose.
    odo.sample = OdometrySample(2_000, 2.0 + math.cos(0.5), 1.0 + math.sin(0.5), 0.5, 0.5, 0.0)
    now = pose.read()
    assert (now.x_m, now.y_m, now.yaw_rad) == pytest.approx((2.1 + math.cos(0.52), 0.9 + math.sin(0.52), 0.52))
    assert now.v_mps == 0.5


@pytest.mark.parametrize("frames,scheme", [("shared", "greedy"), ("own", "independent")])
def test_a_mission_reports_how_far_each_robot_believes_itself_from_where_it_is(frames, scheme):
    exact = dataclasses.replace(WorldParams(), odom_trans_noise_per_m=0.0, odom_yaw_noise_per_rad=0.0,
                                odom_yaw_drift_per_m=0.0, odom_speed_noise_frac=0.0)
    cfg = MissionConfig(map_spec="cave:3:30x30", robots=2, seed=4, max_sim_s=120.0, strategy=scheme, frames=frames)
    odometry_alone = ExplorationParams(scan_match=False)   # what the firmware believes is odometry's, exactly
    r = run_mission(cfg, world_params=exact, params=odometry_alone)
    assert r.pose_error_max_m == pytest.approx([0.0, 0.0], abs=1e-6)
    drifting = run_mission(cfg, params=odometry_alone)
    assert all(e > 0.0 for e in drifting.pose_error_max_m)
    assert drifting.to_json()["pose_error_m"] == [round(e, 3) for e in drifting.pose_error_m]


def test_matching_scans_adds_no_error_where_odometry_has_none():
    exact = dataclasses.replace(WorldParams(), odom_trans_noise_per_m=0.0, odom_yaw_noise_per_rad=0.0,
                                odom_yaw_drift_per_m=0.0, odom_speed_noise_frac=0.0)
    r = run_mission(MissionConfig(map_spec="cave:3:30x30", seed=4, max_sim_s=300.0), params=P, world_params=exact)
    assert r.explorer_stats()["scan_matches"][0] > 100
    assert r.pose_error_max_m[0] < 0.05


def test_a_correction_between_two_scans_is_no_wheel_slip():
    # Odometry ten times as drifty as the default, wheels that never slip: scan matching
    # corrects the pose hundreds of times along the tunnel, and the slip check, which weighs
    # the wheels' travel against the scans', must not take a correction's jump for travel
    # the LiDAR did not see (it stopped the robot as if held, and marked a wall ahead).
    drifty = dataclasses.replace(WorldParams(), odom_trans_noise_per_m=0.02, odom_yaw_drift_per_m=0.002)
    r = run_mission(MissionConfig(map_spec="tunnel:3:40x40", seed=1, max_sim_s=150.0, strategy="independent"),
                    params=P, world_params=drifty)
    stats = r.explorer_stats()
    assert stats["scan_corrections"][0] > 100
    assert stats["bumps"][0] == 0 and stats["stall_back_offs"][0] == 0
