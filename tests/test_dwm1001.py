"""The DWM1001 TLV codec and readers (pure), and the driver (hal.dwm1001) against the emulated
module (world_sim.devices) on a real pty, in lockstep with the simulated world."""
from __future__ import annotations

import os
import struct
import time

import pytest
import serial
from hypothesis import given, settings
from hypothesis import strategies as st

from hal import dwm1001_protocol as P
from hal.dwm1001 import Dwm1001Error, Dwm1001Ranger
from hal.interfaces import UwbRanger
from world_sim.devices.dwm1001_emulator import Dwm1001Emulator
from world_sim.map_spec import resolve_map, staging_poses
from world_sim.world import World
from tests.doubles import StepClock

TICK_US = 50_000
MM = 0.5e-3 + 1e-9          # half the module's millimetre


def _world(robots: int, seed: int = 2) -> World:
    occ, start, _ = resolve_map("cave:5:20x20")
    return World(occ, staging_poses(occ, start, robots), seed)


class _WorldClock:
    def __init__(self, world):
        self.world = world

    def now_us(self):
        return self.world.now_us


# -- codec -------------------------------------------------------------------------------------

def test_loc_get_answer_of_a_tag_is_the_published_layout():
    loc = P.Location(P.Position(1, -2, 3, 50), (P.Distance(0x1A2B, 1234, 100, P.Position(10, 20, 30, 0)),), False)
    data = P.return_value(P.RV_OK) + P.encode_location(loc)
    assert P.request(P.CMD_LOC_GET) == bytes.fromhex("0C00")
    assert data[:5] == bytes.fromhex("400100410D")
    assert data[5:18] == struct.pack("<iiiB", 1, -2, 3, 50)
    assert data[18:21] == bytes((0x49, 1 + 20, 1))
    assert data[21:28] == bytes.fromhex("2B1A") + struct.pack("<I", 1234) + bytes((100,))
    reader = P.ResponseReader()
    reader.expect(P.CMD_LOC_GET)
    [answer] = reader.feed(data)
    assert (answer.cmd, answer.rc) == (P.CMD_LOC_GET, P.RV_OK)
    assert P.decode_location(answer.tlvs) == loc


def test_loc_get_answer_of_an_anchor_carries_64_bit_tag_addresses():
    loc = P.Location(P.Position(), tuple(P.Distance(0xDECA000000001000 + k, 500 + k, 90) for k in range(15)), True)
    reader = P.ResponseReader()
    reader.expect(P.CMD_LOC_GET)
    [answer] = reader.feed(P.return_value(P.RV_OK) + P.encode_location(loc))
    assert answer.tlvs[P.TLV_RNG_AN_DIST][0] == 15 and len(answer.tlvs[P.TLV_RNG_AN_DIST]) == 1 + 15 * 13
    assert P.decode_location(answer.tlvs) == loc
    with pytest.raises(ValueError, match="at most 4 anchors"):
        P.encode_location(P.Location(P.Position(), (P.Distance(1, 1, 1),) * 5, False))


def test_reader_splits_answers_across_chunks_and_reports_error_codes():
    reader = P.ResponseReader()
    for cmd in (P.CMD_STATUS_GET, P.CMD_CFG_GET, P.CMD_LOC_GET):
        reader.expect(cmd)
    data = (P.return_value(P.RV_OK) + P.encode_status(P.STATUS_LOC_READY) + P.return_value(P.RV_OK)
            + P.encode_cfg(node_is_anchor=True) + P.return_value(P.RV_ERR_BUSY))
    answers = []
    for b in data:
        answers += reader.feed(bytes([b]))
    assert [(a.cmd, a.rc) for a in answers] == [(P.CMD_STATUS_GET, 0), (P.CMD_CFG_GET, 0), (P.CMD_LOC_GET, 4)]
    assert P.decode_status(answers[0].tlvs[P.TLV_STATUS]) == P.STATUS_LOC_READY
    assert P.cfg_is_anchor(answers[1].tlvs[P.TLV_CFG])
    assert reader.waiting == 0 and reader.bytes_skipped == 0


def test_reader_skips_noise_and_drops_an_answer_that_does_not_fit_its_request():
    reader = P.ResponseReader()
    reader.expect(P.CMD_STATUS_GET)
    # Noise, then a loc_get answer where a status answer is due (a late answer), then the status.
    late = P.return_value(P.RV_OK) + P.encode_location(P.Location(P.Position(), (), False))
    [answer] = reader.feed(b"\x13\x37\x00" + late + P.return_value(P.RV_OK) + P.encode_status(0))
    assert answer.cmd == P.CMD_STATUS_GET and answer.tlvs == {P.TLV_STATUS: b"\x00\x00"}
    assert reader.malformed == 1 and reader.bytes_skipped > 0
    assert reader.feed(b"unsolicited") == [] and reader.bytes_skipped >= 11 + 3


@settings(max_examples=300, deadline=None)
@given(st.lists(st.sampled_from(sorted(P.REQUEST_LENGTHS)), max_size=4), st.lists(st.binary(max_size=80), max_size=8))
def test_readers_never_raise_on_random_bytes(expected, chunks):
    reader = P.ResponseReader()
    for cmd in expected:
        reader.expect(cmd)
    for chunk in chunks:
        for answer in reader.feed(chunk):
            if answer.cmd == P.CMD_LOC_GET and answer.rc == P.RV_OK:
                P.decode_location(answer.tlvs)
            if answer.cmd == P.CMD_STATUS_GET and answer.rc == P.RV_OK:
                P.decode_status(answer.tlvs[P.TLV_STATUS])
        P.RequestReader().feed(chunk)


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=60).filter(lambda b: 0x40 not in b))
def test_an_answer_after_any_noise_is_found(noise):
    reader = P.ResponseReader()
    reader.expect(P.CMD_STATUS_GET)
    [answer] = reader.feed(noise + P.return_value(P.RV_OK) + P.encode_status(3))
    assert P.decode_status(answer.tlvs[P.TLV_STATUS]) == 3


# -- the driver against the emulator, on a pty, in lockstep -------------------------------------

class _Rig:
    def __init__(self, world, robot=0, **emulator_kwargs):
        self.world = world
        self.emulator = Dwm1001Emulator(world, robot, **emulator_kwargs)
        self.ranger = Dwm1001Ranger(self.emulator.path, _WorldClock(world), lockstep=True)

    def tick(self):
        self.world.step(TICK_US)
        self.advance()

    def advance(self):
        self.emulator.advance_to(self.world.now_us)
        self.ranger.sync()

    def close(self):
        self.ranger.close()
        self.emulator.close()


def _reference_and_serial(world_seed: int, robots: int, ticks: int, **emulator_kwargs):
    """Robot 0's ranges from the in-process world and through the emulated module, tick by tick."""
    ref_world, ser_world = _world(robots, world_seed), _world(robots, world_seed)
    rig = _Rig(ser_world, **emulator_kwargs)
    ref, ser = [], []
    try:
        assert isinstance(rig.ranger, UwbRanger)
        rig.advance()
        for _ in range(ticks):
            ref.append(sorted((r.stamp_us, r.peer_id, r.range_m) for r in ref_world.take_uwb_ranges(0)))
            ser.append(sorted((r.stamp_us, r.peer_id, r.range_m) for r in rig.ranger.ranges()))
            for w in (ref_world, ser_world):
                for i in range(robots):
                    w.set_command(i, 0.3, 0.2 * (i + 1))
            ref_world.step(TICK_US)
            rig.tick()
        return ref, ser, rig.ranger.counters
    finally:
        rig.close()


def test_world_ranges_round_trip_through_the_pty_to_the_millimetre():
    ref, ser, counters = _reference_and_serial(world_seed=4, robots=3, ticks=30)
    assert sum(len(t) for t in ref) == 2 * 3                # 2 Hz, two peers, 1.5 s
    for want, got in zip(ref, ser):
        assert [(s, p) for s, p, _ in got] == [(s, p) for s, p, _ in want]
        assert all(abs(g - w) <= MM for (_, _, g), (_, _, w) in zip(got, want))
    assert counters == {"timeouts": 0, "bytes_skipped": 0, "malformed": 0, "unknown_addresses": 0, "ranges_dropped": 0}


def test_a_tag_reports_its_four_nearest_peers_and_an_anchor_all_of_them():
    ref, ser, _ = _reference_and_serial(world_seed=5, robots=7, ticks=1)
    want = sorted(ref[0], key=lambda r: r[2])[:4]
    assert [p for _, p, _ in ser[0]] == sorted(p for _, p, _ in want)
    ref, ser, _ = _reference_and_serial(world_seed=5, robots=7, ticks=1, node_is_anchor=True)
    assert [p for _, p, _ in ser[0]] == [1, 2, 3, 4, 5, 6]


def test_driver_reads_the_configuration_and_versions():
    rig = _Rig(_world(2))
    try:
        assert rig.ranger.node_is_anchor is False
        assert rig.ranger.versions == (0x01030000, 0x00070100, 0xDECA0302)
    finally:
        rig.close()
    rig = _Rig(_world(2), node_is_anchor=True)
    try:
        assert rig.ranger.node_is_anchor is True
    finally:
        rig.close()


def test_each_measurement_is_handed_over_once_and_noise_is_skipped():
    rig = _Rig(_world(2))
    try:
        rig.advance()
        assert [r.peer_id for r in rig.ranger.ranges()] == [1]
        rig.advance()                                       # no new ranging round: nothing new
        assert rig.ranger.ranges() == ()
        rig.emulator._port.write(b"\x11\x22\x33 line noise \x99")
        for _ in range(10):
            rig.tick()
        assert [r.stamp_us for r in rig.ranger.ranges()] == [500_000]
        assert rig.ranger.counters["bytes_skipped"] > 0 and rig.ranger.counters["timeouts"] == 0
    finally:
        rig.close()


def test_emulator_answers_requests_as_the_module_does():
    world = _world(2)
    with Dwm1001Emulator(world, 1) as emu:
        port = serial.Serial(emu.path, P.BAUDRATE, timeout=2)
        try:
            emu.advance_to(0)
            port.write(P.request(P.CMD_STATUS_GET))
            assert port.read(7) == P.return_value(0) + P.encode_status(P.STATUS_LOC_READY | P.STATUS_UWBMAC_JOINED)
            port.write(P.request(P.CMD_LOC_GET))
            head = port.read(3 + 15 + 3)
            assert head[:5] == bytes.fromhex("400100410D") and head[18:21] == bytes((0x49, 21, 1))
            entry = port.read(20)
            assert struct.unpack_from("<HIB", entry)[0] == P.robot_address(0)
            port.write(P.request(P.CMD_STATUS_GET))
            assert port.read(7) == P.return_value(0) + P.encode_status(P.STATUS_UWBMAC_JOINED)
            port.write(P.request(P.CMD_UR_SET, struct.pack("<HH", 5, 50)))
            assert port.read(3) == P.return_value(0)
            port.write(P.request(P.CMD_UR_GET))
            assert port.read(9) == P.return_value(0) + P.tlv(P.TLV_UR, struct.pack("<HH", 5, 50))
            port.write(bytes.fromhex("7700"))                # not a request the API knows
            assert port.read(3) == P.return_value(P.RV_ERR_TLV)
            port.write(P.request(P.CMD_LOC_GET, b"\x01"))    # a known one with a wrong length
            assert port.read(3) == P.return_value(P.RV_ERR_TLV)
        finally:
            port.close()


def test_driver_reports_an_unopenable_port_and_a_silent_module():
    with pytest.raises(Dwm1001Error, match="/dev/does-not-exist: cannot open"):
        Dwm1001Ranger("/dev/does-not-exist")
    master, slave = os.openpty()
    try:
        with pytest.raises(Dwm1001Error, match=r"request 0x08: no answer within 0.2 s"):
            Dwm1001Ranger(os.ttyname(slave), reply_timeout_s=0.2)
    finally:
        os.close(master)
        os.close(slave)


def test_free_running_driver_polls_on_its_own_thread():
    world = _world(2)
    clock = StepClock()
    clock.t_us = 42_000
    with Dwm1001Emulator(world, 0) as emu:
        ranger = Dwm1001Ranger(emu.path, clock, poll_hz=100.0)
        try:
            emu.advance_to(0)
            deadline = time.monotonic() + 2.0
            got = ranger.ranges()
            while not got and time.monotonic() < deadline:
                time.sleep(0.005)
                got = ranger.ranges()
            assert [(r.stamp_us, r.peer_id) for r in got] == [(42_000, 1)]
        finally:
            ranger.close()


def test_registry_builds_the_dwm1001_backend_by_name():
    from hal.registry import backend_class
    assert backend_class("uwb", "dwm1001") is Dwm1001Ranger


def test_a_configured_dwm1001_maps_the_listed_addresses_on_the_robots_clock():
    from hal.config import BuildContext
    from hal.dwm1001 import parse_peer_addresses
    from hal.registry import build_backend, check_backend
    assert parse_peer_addresses(" 0:0x1A2B,2:1a2d ") == {0x1A2B: 0, 0x1A2D: 2}
    world = _world(2)
    clock = StepClock()
    clock.t_us = 42_000
    with Dwm1001Emulator(world, 0) as emu:
        # The emulated robot 1's module, listed as robot 7's: its ranges come as robot 7's.
        table = {"port": emu.path, "poll_hz": 100.0, "peer_addresses": f"7:0x{P.robot_address(1):04X}"}
        ctx = BuildContext(0)
        ctx.clock = clock
        ranger = build_backend("uwb", "dwm1001", check_backend("uwb", "dwm1001", table), ctx)
        try:
            emu.advance_to(0)
            deadline = time.monotonic() + 2.0
            got = ranger.ranges()
            while not got and time.monotonic() < deadline:
                time.sleep(0.005)
                got = ranger.ranges()
            assert [(r.stamp_us, r.peer_id) for r in got] == [(42_000, 7)]
        finally:
            assert ctx.close() == []
