"""Hardware in the loop (issue 26, item 6): the ODrive axis emulator between the real CAN
backends and the simulated world, `lorascout hil`'s checks of its options and of its bus, and
two `lorascout robot` processes exploring a 30 x 30 m cave in real time on emulated devices."""
import itertools
import json
import math
import os
import subprocess
import sys
import signal
import threading
from types import SimpleNamespace

import can
import pytest

from hal.odrive_can import (AXIS_STATE_CLOSED_LOOP_CONTROL, AXIS_STATE_IDLE, DiffDriveGeometry, OdriveDiffDrive,
                            OdriveWheelOdometry, set_axis_state)
from hal.lora import PROFILES
from hal.samples import DriveLimits
from host_tools.hil import HilError, HilSettings, HilWorld
from tests.doubles import REPO, StepClock, room
from world_sim.devices.odrive_emulator import OdriveAxes, WorldDiffDrive
from world_sim.world import World

GEOMETRY = DiffDriveGeometry(left_node=4, right_node=5, wheel_radius_m=0.08, track_width_m=0.4)
LIMITS = DriveLimits(max_v_mps=0.8, max_omega_radps=1.5, robot_radius_m=0.25)
_channels = itertools.count()


@pytest.fixture
def base():
    """Robot 0 of a world in an empty 10 x 10 m room, its wheels on two emulated axes, driven
    by the real drive and odometry backends over python-can's virtual bus."""
    channel = f"hil-test-{next(_channels)}"
    robot_bus, world_bus = can.Bus(channel, interface="virtual"), can.Bus(channel, interface="virtual")
    world = World(room(10.0, 10.0), [(5.0, 5.0, 0.0)], seed=1)
    axes = OdriveAxes(world_bus, (GEOMETRY.left_node, GEOMETRY.right_node))
    wheels = WorldDiffDrive(world, 0, axes, GEOMETRY)
    clock = StepClock()
    drive = OdriveDiffDrive(robot_bus, GEOMETRY, LIMITS)
    odometry = OdriveWheelOdometry(robot_bus, clock, GEOMETRY, start=(5.0, 5.0, 0.0))
    yield SimpleNamespace(world=world, axes=axes, wheels=wheels, drive=drive, odometry=odometry, clock=clock,
                          robot_bus=robot_bus)
    robot_bus.shutdown()
    world_bus.shutdown()


def drive_for(b: SimpleNamespace, seconds: float, step_us: int = 10_000) -> None:
    """What the HIL world does every 10 ms: commands in, a world step, the wheels turned, the
    encoder estimates out."""
    for _ in range(round(seconds * 1e6 / step_us)):
        b.axes.take_commands()
        b.wheels.apply_commands()
        b.world.step(step_us)
        b.wheels.after_step(step_us)
        b.axes.broadcast_estimates()
        b.clock.t_us = b.world.now_us


def test_the_emulated_axes_move_the_body_as_the_drive_commands_and_the_driver_odometry_follows_it(base):
    world, axes, drive, odometry = base.world, base.axes, base.drive, base.odometry
    axes.take_commands()
    assert {axes[n].state for n in (4, 5)} == {AXIS_STATE_IDLE}      # not armed yet: the body must not move
    drive.command(0.5, 0.0)
    drive_for(base, 0.5)
    assert world.command(0) == (0.0, 0.0) and world.path_length_m(0) == 0.0
    drive.arm()
    drive.command(0.4, 0.5)
    drive_for(base, 2.0)
    v, w = world.command(0)
    assert v == pytest.approx(0.4, abs=1e-6) and w == pytest.approx(0.5, abs=1e-6)
    assert {axes[n].state for n in (4, 5)} == {AXIS_STATE_CLOSED_LOOP_CONTROL}
    truth, estimate, world_odometry = world.true_pose(0), odometry.read(), world.odometry_sample(0)
    assert world.path_length_m(0) == pytest.approx(0.8, abs=0.02)
    # The driver integrates the encoder speeds the world measured: its pose is the world's
    # dead reckoning up to the position noise wheels cannot carry, and near the truth.
    assert math.hypot(estimate.x_m - world_odometry.x_m, estimate.y_m - world_odometry.y_m) < 0.02
    assert abs(math.remainder(estimate.yaw_rad - world_odometry.yaw_rad, 2 * math.pi)) < 0.02
    assert math.hypot(estimate.x_m - truth.x_m, estimate.y_m - truth.y_m) < 0.05
    assert estimate.v_mps == pytest.approx(0.4, rel=0.1) and estimate.omega_radps == pytest.approx(0.5, rel=0.1)
    drive.disarm()
    drive_for(base, 0.1)
    assert world.command(0) == (0.0, 0.0)


def test_an_axis_told_to_idle_lets_its_wheel_go(base):
    world, drive = base.world, base.drive
    drive.arm()
    drive.command(0.5, 0.0)
    base.robot_bus.send(set_axis_state(GEOMETRY.right_node, AXIS_STATE_IDLE))
    drive_for(base, 0.2)
    # Only the left wheel drives: the body turns right while creeping forward.
    v, w = world.command(0)
    assert v == pytest.approx(0.25, abs=1e-6) and w == pytest.approx(-0.5 / 0.4, abs=1e-6)


def test_options_that_cannot_run_are_refused_naming_the_option(cli, tmp_path):
    r = cli("hil", "--can-channel", "10.1.2.3", "--out", tmp_path)
    assert r.code == 2 and "--can-channel" in r.err and "no multicast address" in r.err, r
    r = cli("hil", "--can-channel", "not-an-address", "--out", tmp_path)
    assert r.code == 2 and "--can-channel" in r.err and "no IP address" in r.err, r
    r = cli("hil", "--robots", "33")
    assert r.code == 2 and "--robots" in r.err and "1 <= N <= 32" in r.err, r
    r = cli("hil", "--robots", "2", "--start", "3,3", "--start", "4,4", "--start", "5,5")
    assert r.code == 2 and "--start" in r.err and "once per robot" in r.err, r
    r = cli("hil", "--map", "cave:7:30x30", "--start", "0.05,0.05", "--out", tmp_path)
    assert r.code == 2 and "--start" in r.err and "not on a free cell" in r.err, r


def test_a_second_world_on_the_same_bus_is_refused():
    """On Linux every udp_multicast bus on one port hears every group on the host, so a world
    whose axes would answer to the same node ids as a running one's must not start."""
    settings = HilSettings(map_spec="cave:1:20x20", robots=1, seed=0, profile=PROFILES["eu868-g3"],
                           scheme="bayer-faigl:minpos")
    with HilWorld(settings) as first:
        stop = threading.Event()

        def keep_broadcasting():
            while not stop.wait(0.02):
                first.axes.broadcast_heartbeats()

        talker = threading.Thread(target=keep_broadcasting, daemon=True)
        talker.start()
        try:
            # Either axis of the running robot may be heard first.
            with pytest.raises(HilError, match=r"ODrive node [01] is already broadcasting"):
                HilWorld(settings)
        finally:
            stop.set()
            talker.join()


@pytest.mark.realtime
def test_two_robot_processes_explore_a_30_m_cave_in_real_time_on_emulated_devices(tmp_path):
    """The acceptance of issue 26's hardware in the loop: two unchanged `lorascout robot`
    processes, with the real serial and CAN drivers, explore cave:7:30x30 on the wall clock to
    at least 0.99 coverage of the true map, stop by themselves, and no task (nor the tick as a
    whole) overruns its budget in more than 5 % of the ticks. (The lockstep simulator, same
    map and scheme: coverage 1.0, complete after 91 s simulated.) Each signs off before it
    stops, so neither waits 30 s for the other to fall silent. Both robots' clocks have the
    world's epoch, so their TDMA slots line up and few receptions are lost: on clocks of their
    own, 9 to 78 of 159 to 210 were (one transmitting while the other did, or was not
    listening), with the shared epoch 2 to 4 of 145 to 170 (while a robot was starting or had
    stopped, or at a slot's turnaround)."""
    # As a user runs it: numba on one thread per process (host_tools/__init__.py), not the two
    # that conftest.py sets for the kernels' thread-count tests; two robots with two threads
    # each and the world would share two cores.
    env = {**os.environ, "NUMBA_NUM_THREADS": "1"}
    proc = subprocess.run([sys.executable, "-m", "host_tools.cli", "hil", "--map", "cave:7:30x30", "--robots", "2",
                           "--out", str(tmp_path), "--max-s", "300", "--json"],
                          cwd=REPO, capture_output=True, text=True, timeout=420, env=env)
    assert proc.returncode == 0, proc.stderr[-3000:]
    report = json.loads(proc.stdout)
    logs = {r["robot_id"]: (tmp_path / f"robot{r['robot_id']}.log").read_text()[-1500:] for r in report["robots"]}
    assert report["ended"] == "robots_ended" and report["termination"] == "complete", (report, logs)
    assert report["coverage"] >= 0.99, report
    for r in report["robots"]:
        assert r["exit_status"] == 0 and r["termination"] == "complete", (r, logs[r["robot_id"]])
        assert r["ticks"] > 500, r
        assert r["worst_overrun_share"] <= 0.05, (r, logs[r["robot_id"]])
        assert r["sign_off"] == "sent", (r, logs[r["robot_id"]])
    # Without the sign-off one robot outlived the other by about 30 s (three heartbeat periods).
    assert report["robots_exited_within_s"] < 10, (report, logs)
    # Every robot's tick loop on the world's clock: it started after the world, and ended before
    # the world saw its process end.
    for r in report["robots"]:
        assert 0 < r["started_s"] < r["ended_s"] <= r["exited_s"] <= report["sim_s"], r
    # Aligned TDMA slots: a few receptions lost while a robot starts or has stopped, allowed
    # for, and at most 5 % of the rest.
    air = report["air"]
    receptions = air["received"] + report["lost_receptions"]
    assert receptions > 50 and report["lost_receptions"] <= 4 + 0.05 * receptions, air
    assert report["loop"]["loops"] > 0 and report["sim_s"] >= max(r["wall_s"] for r in report["robots"])


def test_serve_only_writes_configurations_a_robot_accepts_and_stops_on_a_signal(tmp_path):
    """`lorascout hil --serve-only` prints each robot's configuration file and serves the
    world for robots started by hand, until a signal."""
    world = subprocess.Popen([sys.executable, "-m", "host_tools.cli", "hil", "--serve-only", "--robots", "2",
                              "--map", "cave:1:20x20", "--out", str(tmp_path), "--max-s", "60"],
                             cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        paths = [world.stdout.readline().strip() for _ in range(2)]
        assert paths == [str(tmp_path / "robot0.toml"), str(tmp_path / "robot1.toml")], world.stderr.read()
        check = subprocess.run([sys.executable, "-m", "host_tools.cli", "robot", "--config", paths[1], "--check",
                                "--json"], cwd=REPO, capture_output=True, text=True, timeout=60)
        assert check.returncode == 0, check.stderr
        described = json.loads(check.stdout)
        assert described["robot_id"] == 1 and described["team_size"] == 2
        p = described["peripherals"]
        assert {k: p[k]["backend"] for k in ("lidar", "odometry", "drive", "radio", "uwb")} == {
            "lidar": "rplidar", "odometry": "odrive-can", "drive": "odrive-can", "radio": "rn2483", "uwb": "dwm1001"}
        assert (p["drive"]["interface"], p["drive"]["left_node"], p["drive"]["right_node"]) == ("udp_multicast", 2, 3)
        assert p["lidar"]["port"].startswith("/dev/pts/") and p["radio"]["port"] != p["lidar"]["port"]
        world.send_signal(signal.SIGINT)
        assert world.wait(timeout=10) == 130
    finally:
        if world.poll() is None:
            world.kill()
            world.wait()
