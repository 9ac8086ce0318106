"""Third-party RPLIDAR drivers from PyPI, used unchanged, against the emulated scanner on a
real pty: pyrplidar 0.1.2 reads info, health, sample rate and a standard scan whose nodes
are the world's scan; rplidar-roboticia 0.9.5 reads info and health and starts a scan.

Neither can start an A1's motor on a pseudo-terminal (they switch it with the adapter's DTR
line, which a pty does not have), so the tests leave the motor alone, as a bench test of a
scanner powered from a lab supply would; roboticia's measurement iterator always switches
the motor first, so only its request/answer calls are exercised."""
from __future__ import annotations

import threading

import numpy as np
import pytest

from hal import rplidar_protocol as P
from world_sim.devices.rplidar_emulator import RplidarEmulator
from world_sim.map_spec import resolve_map
from world_sim.world import World

TICK_US = 50_000


@pytest.fixture
def world():
    occ, start, _ = resolve_map("cave:5:20x20")
    return World(occ, [start], seed=3)


class _WorldRunner(threading.Thread):
    """Steps the world and hands each scan to the emulator, as the mission runner does,
    while a library blocks in its reads on the test thread."""

    def __init__(self, world, emulator, ticks):
        super().__init__(daemon=True)
        self.world, self.emulator, self.ticks = world, emulator, ticks
        self.stop = threading.Event()

    def run(self):
        for _ in range(self.ticks):
            if self.stop.wait(0.002):
                return
            self.world.step(TICK_US)
            self.emulator.advance_to(self.world.now_us)


def test_pyrplidar_reads_the_emulated_scanner(world):
    pyrplidar = pytest.importorskip("pyrplidar")             # test extra: pyrplidar==0.1.2
    with RplidarEmulator(world, 0) as emu:
        lidar = pyrplidar.PyRPlidar()
        lidar.connect(port=emu.path, baudrate=P.BAUDRATE, timeout=3)
        runner = _WorldRunner(world, emu, ticks=40)
        try:
            info = lidar.get_info()
            assert (info.model, info.firmware_major, info.firmware_minor, info.hardware) == (0x18, 1, 29, 7)
            assert lidar.get_health().status == 0
            rate = lidar.get_samplerate()
            assert (rate.t_standard, rate.t_express) == (508, 254)

            want = world.latest_scan(0)                       # the scan the first revolution carries
            scan = lidar.start_scan()
            runner.start()
            measurements = []
            for m in scan():
                if m.start_flag and len(measurements) >= world.params.lidar_beams:
                    break
                measurements.append(m)
            lidar.stop()
        finally:
            runner.stop.set()
            runner.join(timeout=5)
            lidar.disconnect()
    first = measurements[:world.params.lidar_beams]
    assert first[0].start_flag and not any(m.start_flag for m in first[1:])
    angles_deg = np.array([m.angle for m in first])
    assert np.all(np.diff(angles_deg) > 0)                    # clockwise from the device's 0 degrees
    # Device angle theta is robot angle -theta: the library's node at theta is the world's beam there.
    beam = np.rint((180.0 - angles_deg) % 360.0).astype(int) % world.params.lidar_beams
    got_m = np.array([m.distance for m in first]) / 1000.0
    hit = got_m > 0
    assert hit.sum() > 100
    assert np.abs(got_m[hit] - want.ranges_m[beam[hit]]).max() <= 0.125e-3 + 1e-6
    assert np.all(want.ranges_m[beam[~hit]] == want.range_max_m)
    assert all(m.quality == (15 if h else 0) for m, h in zip(first, hit))


def test_rplidar_roboticia_reads_info_and_health_and_starts_a_scan(world):
    rplidar = pytest.importorskip("rplidar")                 # test extra: rplidar-roboticia==0.9.5
    with RplidarEmulator(world, 0) as emu:
        lidar = rplidar.RPLidar(emu.path, baudrate=P.BAUDRATE, timeout=3)
        try:
            info = lidar.get_info()
            assert (info["model"], info["firmware"], info["hardware"]) == (0x18, (1, 29), 7)
            assert info["serialnumber"] == emu.info.serial_number.hex().upper()
            assert lidar.get_health() == ("Good", 0)
            lidar.start("normal")                            # checks the descriptor's length, mode and type
            assert lidar.scanning[0] and emu.scanning
            lidar.stop()
            assert not emu.scanning
        finally:
            lidar.disconnect()
