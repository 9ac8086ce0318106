"""The simulated world as the firmware sees it: HAL conformance, sensor models, determinism."""
from __future__ import annotations

import dataclasses
import hashlib
import math

import numpy as np
import pytest

from hal.bundle import Hal
from hal.interfaces import Clock, DriveBase, Lidar, Odometry, RadioModem, UwbRanger, WifiAoa
from hal.null import NullRadioModem
from hal.registry import backend_class
from hal.samples import LidarScan
from hal.sim.aoa import SimWifiAoa
from hal.sim.clock import SimClock
from hal.sim.drive import SimDriveBase
from hal.sim.factory import build_sim_hal
from hal.sim.lidar import SimLidar
from hal.sim.odometry import SimOdometry
from hal.sim.uwb import SimUwbRanger
from tests.doubles import room
from world_sim.occupancy_map import OccupancyMap
from world_sim.raycast import cast_rays, mark_observed
from world_sim.sensing import REALISTIC
from world_sim.world import World, WorldParams

# Cheap sensors for tests that only need motion or radios.
QUIET = WorldParams(lidar_beams=8, lidar_rate_hz=0.5)


def divided_room() -> OccupancyMap:
    """20 x 10 m room, a 0.4 m thick wall from x = 10.0 to 10.4 m across its full height."""
    occ = room(20.0, 10.0)
    free = occ.free.copy()
    free[:, 100:104] = False
    return dataclasses.replace(occ, free=free, name="divided")


def run(world: World, seconds: float, dt_us: int = 50_000) -> None:
    for _ in range(int(round(seconds * 1e6 / dt_us))):
        world.step(dt_us)


# --- contract ------------------------------------------------------------------------------


def test_backends_satisfy_the_hal_protocols_and_the_registry():
    world = World(room(5.0, 5.0), [(2.5, 2.5, 0.0)], seed=1, params=QUIET)
    expected = {
        "clock": (SimClock, Clock), "lidar": (SimLidar, Lidar), "odometry": (SimOdometry, Odometry),
        "drive": (SimDriveBase, DriveBase), "uwb": (SimUwbRanger, UwbRanger), "aoa": (SimWifiAoa, WifiAoa),
    }
    for kind, (cls, protocol) in expected.items():
        assert backend_class(kind, "sim") is cls
        obj = cls(world) if kind == "clock" else cls(world, 0)
        assert isinstance(obj, protocol)
    hal = build_sim_hal(world, 0, NullRadioModem())
    assert isinstance(hal, Hal) and hal.robot_id == 0 and isinstance(hal.radio, RadioModem)
    assert isinstance(hal.lidar, SimLidar) and isinstance(hal.aoa, SimWifiAoa)
    with pytest.raises(TypeError, match="RadioModem"):
        build_sim_hal(world, 0, object())
    with pytest.raises(IndexError, match="robot index 3"):
        build_sim_hal(world, 3, NullRadioModem())


def test_clock_follows_the_world():
    world = World(room(5.0, 5.0), [(2.5, 2.5, 0.0)], seed=1, params=QUIET)
    clock = SimClock(world)
    assert clock.now_us() == 0
    world.step(12_345)
    world.step(1)
    assert clock.now_us() == 12_346 and isinstance(clock.now_us(), int)
    with pytest.raises(ValueError, match="dt_us"):
        world.step(0)


def test_drive_limits_and_clipping():
    world = World(room(5.0, 5.0), [(2.5, 2.5, 0.0)], seed=1)
    drive = SimDriveBase(world, 0)
    lim = drive.limits()
    assert (lim.max_v_mps, lim.max_omega_radps, lim.robot_radius_m) == (0.8, 1.5, 0.25)
    drive.command(5.0, -9.0)
    assert world.command(0) == (0.8, -1.5)
    drive.command(-0.3, 0.2)
    assert world.command(0) == (-0.3, 0.2)
    with pytest.raises(ValueError, match="omega_radps"):
        drive.command(0.1, math.nan)


def test_start_poses_are_validated():
    occ = divided_room()
    with pytest.raises(ValueError, match=r"robot 1 at \(x=10\.200 m"):
        World(occ, [(2.0, 2.0, 0.0), (10.2, 5.0, 0.0)], seed=0)
    with pytest.raises(ValueError, match="robot 0 .*clearance 0.200"):
        World(occ, [(0.3, 5.0, 0.0)], seed=0)  # disc would overlap the border wall
    with pytest.raises(ValueError, match="robot 0 must be"):
        World(occ, [(1.0, 2.0)], seed=0)
    with pytest.raises(ValueError, match="at least one"):
        World(occ, [], seed=0)
    with pytest.raises(ValueError, match="lidar_noise_std_m"):
        WorldParams(lidar_noise_std_m=-1.0)


# --- lidar ---------------------------------------------------------------------------------


def test_lidar_scan_is_in_the_robot_frame_and_handed_out_once():
    params = WorldParams(lidar_noise_std_m=0.0, lidar_beams=360)
    occ = room(10.0, 6.0)
    world = World(occ, [(3.0, 2.0, math.pi / 2)], seed=3, params=params)
    lidar = SimLidar(world, 0)
    scan = lidar.latest_scan()
    assert isinstance(scan, LidarScan) and scan.stamp_us == 0
    assert lidar.latest_scan() is None
    assert scan.ranges_m.dtype == np.float32 and scan.ranges_m.shape == (360,)
    assert scan.angle_min_rad == -math.pi and scan.angle_increment_rad == pytest.approx(2 * math.pi / 360)
    # Robot faces +y: its forward beam (robot angle 0, index 180) hits the north wall at
    # y = 5.9 m; its left beam (+90 deg, index 270) the west wall at x = 0.1 m.
    assert scan.ranges_m[180] == pytest.approx(5.9 - 2.0, abs=1e-5)
    assert scan.ranges_m[270] == pytest.approx(3.0 - 0.1, abs=1e-5)
    assert scan.ranges_m[0] == pytest.approx(2.0 - 0.1, abs=1e-5)  # backwards: south wall
    world.step(60_000)
    assert lidar.latest_scan() is None  # next scan is due at 100 ms
    world.step(60_000)
    scan2 = lidar.latest_scan()
    assert scan2.stamp_us == 100_000 and lidar.latest_scan() is None
    # Skipped scans are dropped: only the newest is returned.
    world.step(250_000)
    assert lidar.latest_scan().stamp_us == 300_000


def test_lidar_noise_and_clipping():
    params = WorldParams(lidar_noise_std_m=0.05, lidar_range_m=4.0)
    occ = room(12.0, 3.0)
    world = World(occ, [(1.5, 1.5, 0.0)], seed=5, params=params)
    angles = params.lidar_angle_min_rad + np.arange(params.lidar_beams) * params.lidar_angle_increment_rad
    true = cast_rays(occ.wall_u8(), 0.0, 0.0, 0.1, 1.5, 1.5, angles, 4.0)
    errors = []
    for _ in range(20):
        scan = world.latest_scan(0)
        r = scan.ranges_m.astype(np.float64)
        assert np.all((r >= 0.0) & (r <= 4.0))
        no_hit = true >= 4.0
        assert no_hit.any() and np.all(r[no_hit] == 4.0)  # nothing hit: exactly range_max
        errors.append(r[~no_hit] - true[~no_hit])
        world.step(100_000)
    err = np.concatenate(errors)
    assert abs(err.mean()) < 0.01 and 0.04 < err.std() < 0.06


def test_coverage_is_the_true_footprint():
    occ = divided_room()
    params = WorldParams(lidar_range_m=6.0)
    world = World(occ, [(5.0, 5.0, 0.3), (15.0, 2.0, -1.0)], seed=9, params=params)
    angles = params.lidar_angle_min_rad + np.arange(params.lidar_beams) * params.lidar_angle_increment_rad
    for i, (x, y, yaw) in enumerate([(5.0, 5.0, 0.3), (15.0, 2.0, -1.0)]):
        want = np.zeros(occ.free.shape, dtype=bool)
        ranges = cast_rays(occ.wall_u8(), 0.0, 0.0, 0.1, x, y, angles + yaw, 6.0)
        mark_observed(want, occ.wall_u8(), 0.0, 0.0, 0.1, x, y, angles + yaw, ranges)
        assert np.array_equal(world.observed(i), want)
    # The dividing wall hides each half from the other robot.
    assert not world.observed(0)[:, 105:].any() and not world.observed(1)[:, :99].any()
    assert np.array_equal(world.observed_union(), world.observed(0) | world.observed(1))
    with pytest.raises(ValueError):
        world.observed(0)[0, 0] = True  # read-only view


# --- motion and odometry --------------------------------------------------------------------


def test_path_length_and_blocked_moves():
    world = World(room(10.0, 4.0), [(2.0, 2.0, 0.0)], seed=2, params=QUIET)
    drive = SimDriveBase(world, 0)
    drive.command(0.5, 0.0)
    run(world, 4.0)
    assert world.path_length_m(0) == pytest.approx(2.0)
    assert world.true_pose(0).x_m == pytest.approx(4.0)
    assert world.blocked_moves(0) == 0
    drive.command(0.8, 0.0)
    run(world, 10.0)  # the east wall inner face is at 9.9 m: stops before 9.65 m
    x = world.true_pose(0).x_m
    assert 9.6 < x < 9.65 and world.blocked_moves(0) > 0
    assert world.path_length_m(0) == pytest.approx(2.0 + x - 4.0)
    odo = SimOdometry(world, 0).read()
    assert odo.v_mps == 0.0 and odo.stamp_us == world.now_us  # pushing a wall: no motion


@pytest.mark.parametrize("slip", [0.0, 0.5, 1.0])
def test_slipping_wheels_count_travel_the_body_does_not_make(slip):
    world = World(room(10.0, 4.0), [(8.0, 2.0, 0.0)], seed=2, params=dataclasses.replace(QUIET, wheel_slip_frac=slip))
    SimDriveBase(world, 0).command(0.8, 0.0)
    run(world, 5.0)                     # at the east wall after about 2 s, then 3 s pushing it
    true_x, odo = world.true_pose(0).x_m, SimOdometry(world, 0).read()
    assert 9.6 < true_x < 9.65
    assert odo.x_m - true_x == pytest.approx(slip * 0.8 * (5.0 - (true_x - 8.0) / 0.8), abs=0.1)
    assert odo.v_mps == pytest.approx(slip * 0.8, rel=0.05, abs=1e-9)
    assert world.path_length_m(0) == pytest.approx(true_x - 8.0)


def test_the_lidar_runs_on_its_own_clock_with_a_phase():
    params = dataclasses.replace(QUIET, lidar_rate_hz=10.0, lidar_phase_us=37_000)
    world = World(room(10.0, 4.0), [(2.0, 2.0, 0.0)], seed=2, params=params)
    lidar = SimLidar(world, 0)
    assert lidar.latest_scan() is None
    stamps = []
    for _ in range(10):
        world.step(50_000)
        scan = lidar.latest_scan()
        if scan is not None:
            stamps.append(scan.stamp_us)
    assert stamps == [37_000 + 100_000 * k for k in range(5)]
    for bad in (100_000, -1, 1.5):
        with pytest.raises(ValueError, match="lidar_phase_us"):
            dataclasses.replace(params, lidar_phase_us=bad)
    with pytest.raises(ValueError, match="wheel_slip_frac"):
        dataclasses.replace(params, wheel_slip_frac=1.5)


def test_odometry_starts_true_and_reports_speed():
    world = World(room(30.0, 30.0), [(5.0, 5.0, 0.5)], seed=4, params=QUIET)
    odo = SimOdometry(world, 0)
    s = odo.read()
    assert (s.x_m, s.y_m, s.yaw_rad, s.v_mps, s.omega_radps, s.stamp_us) == (5.0, 5.0, 0.5, 0.0, 0.0, 0)
    run(world, 5.0)  # standing still never drifts
    s = odo.read()
    assert (s.x_m, s.y_m, s.yaw_rad) == (5.0, 5.0, 0.5)
    SimDriveBase(world, 0).command(0.6, 0.3)
    run(world, 2.0)
    s = odo.read()
    assert s.v_mps == pytest.approx(0.6, rel=0.05) and s.omega_radps == pytest.approx(0.3, rel=0.05)
    true = world.true_pose(0)
    assert math.hypot(s.x_m - true.x_m, s.y_m - true.y_m) < 0.05


def _odometry_errors(distance_m: float, seeds: range) -> np.ndarray:
    occ = room(60.0, 10.0, res=0.2)
    errs = []
    for seed in seeds:
        world = World(occ, [(2.0, 5.0, 0.0)], seed=seed, params=QUIET)
        world.set_command(0, 0.8, 0.0)
        run(world, distance_m / 0.8, dt_us=250_000)
        s, t = world.odometry_sample(0), world.true_pose(0)
        errs.append((s.x_m - t.x_m, s.y_m - t.y_m))
    return np.array(errs)


def test_odometry_drift_grows_with_distance_and_is_unbiased():
    short = _odometry_errors(5.0, range(40))
    long = _odometry_errors(45.0, range(40))
    rms_short = np.sqrt((short ** 2).sum(axis=1).mean())
    rms_long = np.sqrt((long ** 2).sum(axis=1).mean())
    # Random walk alone: sqrt(2) * 0.002 * sqrt(d); the yaw walk adds a d^1.5 term.
    assert 0.002 < rms_short < 0.012
    assert rms_long > 2.5 * rms_short
    # Zero mean: the mean error is within 3 standard errors of 0 on each axis.
    for errs in (short, long):
        assert np.all(np.abs(errs.mean(axis=0)) < 3 * errs.std(axis=0) / math.sqrt(len(errs)) + 1e-4)


# --- UWB and AoA ----------------------------------------------------------------------------


def test_uwb_ranges_los_nlos_and_limit():
    occ = divided_room()
    # The realistic profile's LOS noise and NLOS bias, without its outliers, spread and dropouts
    # (tests/test_sim_sensing.py tests those).
    model = dataclasses.replace(REALISTIC.uwb, rate_hz=20.0, range_max_m=12.0, outlier_prob_los=0.0,
                              outlier_prob_nlos=0.0, nlos_extra_std_m=0.0, nlos_extra_std_per_wall_m=0.0,
                              detection_decay_per_wall_m=0.0)
    params = dataclasses.replace(QUIET, sensing=dataclasses.replace(REALISTIC, uwb=model))
    # 0 and 1 see each other; 2 is behind the 0.4 m wall from 0; 3 is out of range of 0.
    poses = [(6.0, 5.05, 0.0), (2.0, 8.05, 1.0), (14.0, 5.05, 0.0), (19.0, 1.0, 0.0)]
    world = World(occ, poses, seed=11, params=params)
    uwb = SimUwbRanger(world, 0)
    run(world, 20.0, dt_us=500_000)
    ranges = uwb.ranges()
    assert uwb.ranges() == ()
    assert all(r.stamp_us % 50_000 == 0 for r in ranges)
    by_peer = {j: np.array([r.range_m for r in ranges if r.peer_id == j]) for j in range(4)}
    assert len(by_peer[0]) == 0 and len(by_peer[3]) == 0
    assert len(by_peer[1]) == len(by_peer[2]) == 401  # t = 0 .. 20 s at 20 Hz
    los_err = by_peer[1] - 5.0
    nlos_err = by_peer[2] - 8.0
    assert abs(los_err.mean()) < 0.01 and 0.04 < los_err.std() < 0.06
    expected_bias = model.nlos_bias_m + model.nlos_bias_per_wall_m * 0.4
    assert nlos_err.mean() == pytest.approx(expected_bias, abs=0.01)
    assert nlos_err.mean() > 0.3


def test_aoa_bearings_and_outlier_rate():
    model = dataclasses.replace(REALISTIC.aoa, rate_hz=100.0)
    params = dataclasses.replace(QUIET, sensing=dataclasses.replace(REALISTIC, aoa=model))
    occ = room(20.0, 20.0)
    # Robot 0 faces +x; robot 1 is to its left (+90 deg), robot 2 behind it (-180 deg).
    world = World(occ, [(10.0, 10.0, 0.0), (10.0, 15.0, 0.0), (4.0, 10.0, 0.0)], seed=21, params=params)
    aoa = SimWifiAoa(world, 0)
    bearings = []
    for _ in range(40):
        world.step(1_000_000)
        bearings.extend(aoa.bearings())
    assert len(bearings) == 2 * 4001  # t = 0 .. 40 s at 100 Hz, two peers
    truth = {1: math.pi / 2, 2: -math.pi}
    b = np.array([x.bearing_rad for x in bearings])
    assert np.all((b >= -math.pi) & (b < math.pi))
    err = np.array([math.remainder(x.bearing_rad - truth[x.peer_id], 2 * math.pi) for x in bearings])
    far = np.abs(err) > 5 * model.los_noise_std_rad
    # An outlier lands within 5 sigma of the truth with probability 10 sigma / (2 pi).
    expected = model.los_outlier_prob * (1 - 10 * model.los_noise_std_rad / (2 * math.pi))
    sigma = math.sqrt(expected * (1 - expected) / len(err))
    assert abs(far.mean() - expected) < 4 * sigma
    assert np.std(err[~far]) == pytest.approx(model.los_noise_std_rad, rel=0.1)


# --- determinism ----------------------------------------------------------------------------


def _digest(seed: int) -> tuple[str, list[np.ndarray]]:
    occ = divided_room()
    world = World(occ, [(3.0, 3.0, 0.0), (6.0, 7.0, 2.0), (15.0, 5.0, -1.0)], seed=seed)
    hals = [build_sim_hal(world, i, NullRadioModem()) for i in range(3)]
    h = hashlib.sha256()
    noise = []
    for k in range(60):
        for i, hal in enumerate(hals):
            hal.drive.command(0.7 * math.cos(0.1 * k + i), 1.2 * math.sin(0.07 * k * (i + 1)))
            scan = hal.lidar.latest_scan()
            if scan is not None:
                h.update(scan.ranges_m.tobytes())
                h.update(scan.stamp_us.to_bytes(8, "little"))
            o = hal.odometry.read()
            h.update(np.array([o.x_m, o.y_m, o.yaw_rad, o.v_mps, o.omega_radps]).tobytes())
            h.update(np.array([x.range_m for x in hal.uwb.ranges()]).tobytes())
            h.update(np.array([x.bearing_rad for x in hal.aoa.bearings()]).tobytes())
            h.update(np.array(world.true_pose(i)).tobytes())
        world.step(50_000)
    for i in range(3):
        scan = world.latest_scan(i)
        x, y, yaw = world.true_pose(i)
        p = world.params
        angles = p.lidar_angle_min_rad + np.arange(p.lidar_beams) * p.lidar_angle_increment_rad + yaw
        # Noise the robot saw on its last scan; the pose is unchanged since that scan at 3.0 s.
        true = cast_rays(occ.wall_u8(), 0.0, 0.0, 0.1, x, y, angles, p.lidar_range_m)
        noise.append(scan.ranges_m.astype(np.float64) - true)
    return h.hexdigest(), noise


def test_same_seed_same_bytes_and_independent_streams():
    d1, noise1 = _digest(7)
    d2, noise2 = _digest(7)
    d3, noise3 = _digest(8)
    assert d1 == d2 and d1 != d3
    assert all(np.array_equal(a, b) for a, b in zip(noise1, noise2))
    # Each robot draws its own noise, and another seed gives other noise.
    assert np.std(noise1[0] - noise1[1]) > 0.005 and np.std(noise1[0] - noise3[0]) > 0.005
