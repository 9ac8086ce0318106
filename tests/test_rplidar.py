"""The RPLIDAR protocol codec and parser (pure), the revolution assembler, and the driver
(hal.rplidar) against the emulated scanner (world_sim.devices) on a real pty, in lockstep
with the simulated world."""
from __future__ import annotations

import os
import time

import numpy as np
import pytest
import serial
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hal import rplidar_protocol as P
from hal.interfaces import Lidar
from hal.rplidar import RevolutionAssembler, RplidarError, RplidarLidar
from world_sim.devices.rplidar_emulator import RESET_BANNER, RplidarEmulator, encode_scan
from world_sim.map_spec import resolve_map
from world_sim.world import World
from tests.doubles import StepClock

# Half a quantum of the node's distance (1/4 mm) and float32 rounding of a 10 m range.
RANGE_TOLERANCE_M = 0.125e-3 + 1e-6
TICK_US = 50_000


def _nodes(angles_deg, distances_mm, first_start=True):
    n = len(angles_deg)
    start = np.zeros(n, bool)
    start[0] = first_start
    return P.encode_nodes(start, np.full(n, 15), np.rint(np.asarray(angles_deg) * 64).astype(int),
                          np.rint(np.asarray(distances_mm) * 4).astype(int))


def _all_nodes(answers):
    nodes = [a for a in answers if isinstance(a, P.Nodes)]
    if not nodes:
        return np.zeros(0, int), np.zeros(0, int)
    return (np.concatenate([n.angle_q6 for n in nodes]), np.concatenate([n.distance_q2 for n in nodes]))


# -- codec: the published byte layouts -------------------------------------------------------

def test_requests_and_descriptors_are_the_published_bytes():
    assert P.request(P.CMD_SCAN) == bytes.fromhex("A520")
    assert P.request(P.CMD_GET_HEALTH) == bytes.fromhex("A552")
    # Express scan, legacy mode: A5 82 05 00 00 00 00 00 and the XOR checksum 0x22.
    assert P.request(P.CMD_EXPRESS_SCAN, bytes(5)) == bytes.fromhex("A58205000000000022")
    assert P.request(P.CMD_SET_MOTOR_PWM, P.motor_pwm_payload(660)) == bytes.fromhex("A5F0029402C1")
    with pytest.raises(ValueError):
        P.request(P.CMD_SCAN, b"\x00")
    assert P.descriptor(P.ANS_TYPE_MEASUREMENT) == bytes.fromhex("A55A0500004081")
    assert P.descriptor(P.ANS_TYPE_DEVINFO) == bytes.fromhex("A55A1400000004")
    assert P.descriptor(P.ANS_TYPE_DEVHEALTH) == bytes.fromhex("A55A0300000006")


def test_a_node_carries_start_bits_quality_angle_with_check_bit_and_distance():
    raw = P.encode_nodes(np.array([True]), np.array([15]), np.array([90 * 64 + 5]), np.array([1234]))
    assert raw[0] == (15 << 2) | 0b01                       # start set, not-start clear
    assert raw[1] & 1 == 1                                  # check bit
    assert ((raw[1] >> 1) | (raw[2] << 7)) == 90 * 64 + 5
    assert raw[3] | (raw[4] << 8) == 1234
    [nodes] = P.ResponseParser().feed(P.descriptor(P.ANS_TYPE_MEASUREMENT) + raw + raw + raw)[1:]
    assert nodes.start.tolist() == [True] * 3 and nodes.quality.tolist() == [15] * 3
    assert nodes.angle_q6.tolist() == [5765] * 3 and nodes.distance_q2.tolist() == [1234] * 3


def test_angle_convention_is_clockwise_device_against_counter_clockwise_robot():
    robot = np.radians([0.0, 90.0, -90.0, 179.0])
    q6 = P.device_angle_q6(robot)
    assert (q6 // 64).tolist() == [0, 270, 90, 181]
    assert np.allclose(P.robot_angle_rad(q6), robot)


# -- parser -----------------------------------------------------------------------------------

def test_parser_decodes_single_answers_and_a_stream():
    info = P.DeviceInfo(0x18, 1, 29, 7, bytes(range(16)))
    data = (P.descriptor(P.ANS_TYPE_DEVHEALTH) + P.Health(P.HEALTH_WARNING, 0x1234).encode()
            + P.descriptor(P.ANS_TYPE_DEVINFO) + info.encode()
            + P.descriptor(P.ANS_TYPE_SAMPLE_RATE) + P.SampleRate(508, 254).encode()
            + P.descriptor(P.ANS_TYPE_MEASUREMENT) + _nodes([0, 1, 2, 3], [100, 200, 300, 400]))
    parser = P.ResponseParser()
    answers = []
    for b in data:                                          # byte at a time: state survives splits
        answers += parser.feed(bytes([b]))
    assert answers[:4] == [P.Health(P.HEALTH_WARNING, 0x1234), info, P.SampleRate(508, 254),
                           P.StreamStarted(P.ANS_TYPE_MEASUREMENT)]
    angles, dists = _all_nodes(answers)
    assert angles.tolist() == [0, 64, 128, 192] and dists.tolist() == [400, 800, 1200, 1600]
    assert parser.bytes_skipped == 0
    assert info.serial_hex == bytes(range(16))[::-1].hex().upper()


def test_parser_resynchronises_after_garbage_in_a_node_stream():
    rng = np.random.default_rng(3)
    head = _nodes(np.arange(0, 100), np.full(100, 1000))
    tail = _nodes(np.arange(100, 200), np.arange(100, 200) * 10.0, first_start=False)
    garbage = rng.integers(0, 256, 37, dtype=np.uint8).tobytes()
    answers = P.ResponseParser().feed(P.descriptor(P.ANS_TYPE_MEASUREMENT) + head + garbage + tail)
    angles, dists = _all_nodes(answers)
    # Every node after the garbage is back, in order, at the end of what was decoded.
    assert angles[-95:].tolist() == (np.arange(105, 200) * 64).tolist()
    assert dists[-95:].tolist() == (np.arange(105, 200) * 40).tolist()


def test_a_descriptor_is_found_even_off_the_node_grid():
    stream = P.descriptor(P.ANS_TYPE_MEASUREMENT) + _nodes(np.arange(10), np.full(10, 500)) + b"\x01\x02"
    answers = P.ResponseParser().feed(stream + P.descriptor(P.ANS_TYPE_DEVHEALTH) + P.Health(0, 0).encode())
    assert answers[-1] == P.Health(0, 0)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.binary(max_size=64), max_size=20), st.booleans())
def test_parser_never_raises_on_random_bytes(chunks, in_stream):
    parser = P.ResponseParser()
    if in_stream:
        parser.feed(P.descriptor(P.ANS_TYPE_MEASUREMENT))
    for chunk in chunks:
        for answer in parser.feed(chunk):
            if isinstance(answer, P.Nodes):
                assert (answer.angle_q6 < P.FULL_TURN_Q6).all()
    assembler = RevolutionAssembler()
    parser = P.ResponseParser()
    for chunk in chunks:
        for answer in parser.feed(P.descriptor(P.ANS_TYPE_MEASUREMENT) + chunk):
            if isinstance(answer, P.Nodes):
                assembler.add(answer, 0)


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=40), st.integers(0, 400))
def test_a_stream_recovers_from_any_garbage(garbage, split):
    """Whatever noise lands in a node stream, the nodes that follow it are decoded again."""
    head = _nodes(np.arange(0, 50), np.full(50, 700))
    tail = _nodes(np.arange(50, 150), np.full(100, 900), first_start=False)
    answers = P.ResponseParser().feed(P.descriptor(P.ANS_TYPE_MEASUREMENT) + head[:split] + garbage + head[split:] + tail)
    angles, _ = _all_nodes(answers)
    assert angles[-80:].tolist() == (np.arange(70, 150) * 64).tolist()


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=200))
def test_request_parser_never_raises(data):
    P.RequestParser().feed(data)


# -- assembler ----------------------------------------------------------------------------------

def _batch(angles_deg, distances_mm, starts):
    return P.Nodes(start=np.asarray(starts, bool), quality=np.full(len(starts), 15, np.uint8),
                   angle_q6=np.rint(np.asarray(angles_deg) * 64).astype(np.int64),
                   distance_q2=np.rint(np.asarray(distances_mm) * 4).astype(np.int64))


def test_assembler_finishes_a_revolution_at_its_last_bin_with_its_first_nodes_stamp():
    a = RevolutionAssembler(beams=360, range_max_m=10.0)
    angles = np.arange(0, 360)
    starts = angles == 0
    assert a.add(_batch(angles[:200], np.full(200, 2000.0), starts[:200]), now_us=7) == []
    [scan] = a.add(_batch(angles[200:], np.full(160, 3000.0), starts[200:]), now_us=9)
    assert scan.stamp_us == 7 and scan.range_max_m == 10.0 and len(scan.ranges_m) == 360
    # Device angle theta is robot angle -theta: beam i (robot angle -180 + i deg) saw theta = 180 - i.
    assert scan.ranges_m[180] == pytest.approx(2.0)            # theta 0
    assert scan.ranges_m[179] == pytest.approx(2.0)            # theta 1
    assert scan.ranges_m[0] == pytest.approx(2.0)              # theta 180
    assert scan.ranges_m[181] == pytest.approx(3.0)            # theta 359
    # Nodes after the last bin, before the next start flag, are dropped.
    assert a.add(_batch([359.9], [100.0], [False]), now_us=10) == [] and a.nodes_dropped == 1


def test_assembler_keeps_the_nearest_fills_empty_bins_with_range_max_and_drops_short_revolutions():
    a = RevolutionAssembler(beams=4, range_max_m=5.0, min_nodes_per_revolution=3)
    scans = a.add(_batch([0, 0.1, 80, 0, 1], [4000, 1000, 0, 2000, 2000], [1, 0, 0, 1, 0]), now_us=1)
    [scan] = scans
    assert scans[0].stamp_us == 1
    # Robot beams at -180, -90, 0, 90 degrees; theta 0 is robot 0 (beam 2), theta 80 is ~ -90 (beam 1).
    assert scan.ranges_m.tolist() == [5.0, 5.0, 1.0, 5.0]      # no return at 80 deg: range max
    assert a.add(_batch([0], [1000], [1]), now_us=2) == []      # the 2-node revolution is dropped
    assert a.revolutions_dropped == 1


# -- the driver against the emulator, on a pty, in lockstep -------------------------------------

@pytest.fixture
def world():
    occ, start, _ = resolve_map("cave:5:20x20")
    return World(occ, [start], seed=3)


class _Rig:
    """A world, its clock, the emulated scanner and the driver, advanced together."""

    def __init__(self, world):
        self.world = world
        self.clock = _WorldClock(world)
        self.emulator = RplidarEmulator(world, 0)
        self.lidar = RplidarLidar(self.emulator.path, self.clock, range_max_m=world.params.lidar_range_m,
                                  lockstep=True)

    def tick(self, v_mps=0.4, omega_radps=0.6):
        self.world.set_command(0, v_mps, omega_radps)
        self.world.step(TICK_US)
        self.advance()

    def advance(self):
        self.emulator.advance_to(self.world.now_us)
        self.lidar.sync(self.emulator.bytes_queued)

    def close(self):
        self.lidar.close()
        self.emulator.close()


class _WorldClock:
    def __init__(self, world):
        self.world = world

    def now_us(self):
        return self.world.now_us


@pytest.fixture
def rig(world):
    r = _Rig(world)
    yield r
    r.close()


def test_world_scans_round_trip_through_the_pty_within_the_quantisation(rig):
    assert isinstance(rig.lidar, Lidar)
    assert rig.lidar.latest_scan() is None                  # nothing before the runner hands time over
    rig.advance()
    compared = 0
    for _ in range(40):
        got, want = rig.lidar.latest_scan(), rig.world.latest_scan(0)
        if got is not None:
            assert got.stamp_us == want.stamp_us
            assert (got.angle_min_rad, got.angle_increment_rad, got.range_max_m) == \
                (want.angle_min_rad, want.angle_increment_rad, want.range_max_m)
            assert got.ranges_m.dtype == np.float32
            assert np.abs(got.ranges_m - want.ranges_m).max() <= RANGE_TOLERANCE_M
            assert (got.ranges_m == want.range_max_m).tolist() == (want.ranges_m == want.range_max_m).tolist()
            compared += 1
        rig.tick()
    assert compared == 20                                   # 10 Hz scans, 20 Hz ticks, one each
    assert rig.lidar.latest_scan() is not None and rig.lidar.latest_scan() is None   # each handed out once
    assert rig.lidar.counters() == {"bytes_skipped": 0, "nodes_dropped": 0, "revolutions_dropped": 0,
                                    "scans_skipped": 0}


def test_driver_reads_health_and_info_and_starts_the_motor(rig):
    assert rig.lidar.health == P.Health(P.HEALTH_GOOD, 0)
    assert rig.lidar.info == rig.emulator.info
    assert (rig.lidar.info.model, rig.lidar.info.firmware_major, rig.lidar.info.firmware_minor) == (0x18, 1, 29)
    assert rig.emulator.scanning


def test_driver_resynchronises_after_garbage_on_the_line(rig):
    rng = np.random.default_rng(11)
    rig.advance()
    rig.lidar.latest_scan()
    for k in range(10):
        # Noise between and inside revolutions: a loose connector, a motor spike.
        rig.emulator._port.write(rng.integers(0, 256, int(rng.integers(1, 60)), dtype=np.uint8).tobytes())
        rig.tick()
        rig.tick()
    got, want = rig.lidar.latest_scan(), rig.world.latest_scan(0)
    assert got is not None and got.stamp_us == want.stamp_us
    assert np.abs(got.ranges_m - want.ranges_m).max() <= RANGE_TOLERANCE_M
    assert rig.lidar.counters()["bytes_skipped"] > 0


def test_emulator_answers_sample_rate_stop_and_reset_as_an_a1(world):
    with RplidarEmulator(world, 0) as emu:
        port = serial.Serial(emu.path, P.BAUDRATE, timeout=2)
        try:
            port.write(P.request(P.CMD_GET_SAMPLERATE))
            assert port.read(11) == P.descriptor(P.ANS_TYPE_SAMPLE_RATE) + P.SampleRate(508, 254).encode()
            port.write(P.request(P.CMD_SET_MOTOR_PWM, P.motor_pwm_payload(660)))
            port.write(P.request(P.CMD_SCAN))
            assert port.read(7) == P.descriptor(P.ANS_TYPE_MEASUREMENT)
            emu.advance_to(world.now_us)
            assert len(port.read(5 * world.params.lidar_beams)) == 5 * world.params.lidar_beams
            assert emu.motor_pwm == 660
            port.write(P.request(P.CMD_STOP))
            port.write(P.request(P.CMD_GET_HEALTH))
            assert port.read(10) == P.descriptor(P.ANS_TYPE_DEVHEALTH) + bytes(3)
            world.step(100_000)
            emu.advance_to(world.now_us)                    # stopped: nothing more
            port.write(P.request(P.CMD_RESET))
            assert port.read(len(RESET_BANNER)) == RESET_BANNER
            port.write(P.request(P.CMD_EXPRESS_SCAN, bytes(5)))   # not implemented: no answer
            port.timeout = 0.2
            assert port.read(1) == b""
        finally:
            port.close()


def test_encode_scan_sends_no_return_for_beams_that_hit_nothing():
    angles = np.radians([-180.0, -90.0, 0.0, 90.0])
    answers = P.ResponseParser().feed(P.descriptor(P.ANS_TYPE_MEASUREMENT)
                                      + encode_scan(angles, np.array([1.0, 10.0, 20.0, 2.5]), 10.0))
    [nodes] = [a for a in answers if isinstance(a, P.Nodes)]
    assert nodes.start.tolist() == [True, False, False, False]
    assert (nodes.angle_q6 // 64).tolist() == [0, 90, 180, 270]         # device order
    # Device 0, 90, 180, 270 are robot 0 (20 m), -90 (10 m = range max), -180 (1 m), 90 (2.5 m).
    assert nodes.distance_q2.tolist() == [0, 0, 4000, 10000]
    assert nodes.quality.tolist() == [0, 0, 15, 15]


def test_driver_reports_an_unopenable_port_and_a_silent_device():
    with pytest.raises(RplidarError, match="/dev/does-not-exist: cannot open"):
        RplidarLidar("/dev/does-not-exist")
    master, slave = os.openpty()
    try:
        with pytest.raises(RplidarError, match=r"request 0x52: no answer within 0.2 s"):
            RplidarLidar(os.ttyname(slave), reply_timeout_s=0.2)
    finally:
        os.close(master)
        os.close(slave)


def test_free_running_driver_stamps_revolutions_with_the_clock_on_arrival(world):
    clock = StepClock()
    clock.t_us = 123_000
    with RplidarEmulator(world, 0) as emu:
        lidar = RplidarLidar(emu.path, clock, range_max_m=world.params.lidar_range_m)
        try:
            emu.advance_to(world.now_us)
            deadline = time.monotonic() + 2.0
            scan = lidar.latest_scan()
            while scan is None and time.monotonic() < deadline:
                time.sleep(0.005)
                scan = lidar.latest_scan()
            assert scan is not None and scan.stamp_us == 123_000
        finally:
            lidar.close()


def test_registry_builds_the_rplidar_backend_by_name():
    from hal.registry import backend_class
    assert backend_class("lidar", "rplidar") is RplidarLidar


def test_a_configured_rplidar_is_built_on_the_robots_clock_and_closed_with_the_robot(world):
    from hal.config import BuildContext, ConfigError
    from hal.registry import build_backend, check_backend
    clock = StepClock()
    clock.t_us = 77_000
    with RplidarEmulator(world, 0) as emu:
        settings = check_backend("lidar", "rplidar", {"port": emu.path, "range_max_m": world.params.lidar_range_m})
        with pytest.raises(ConfigError, match="needs the robot's clock"):
            build_backend("lidar", "rplidar", settings, BuildContext(0))
        ctx = BuildContext(0)
        ctx.clock = clock
        lidar = build_backend("lidar", "rplidar", settings, ctx)
        try:
            assert isinstance(lidar, RplidarLidar) and lidar.info is not None
            emu.advance_to(world.now_us)
            deadline = time.monotonic() + 2.0
            scan = lidar.latest_scan()
            while scan is None and time.monotonic() < deadline:
                time.sleep(0.005)
                scan = lidar.latest_scan()
            assert scan is not None and scan.stamp_us == 77_000 and scan.range_max_m == world.params.lidar_range_m
        finally:
            assert ctx.close() == []
        assert lidar._closed
