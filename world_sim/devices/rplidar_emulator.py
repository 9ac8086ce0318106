"""An emulated Slamtec RPLIDAR A1 on a pseudo-terminal, scanning one robot of the simulated world.

It answers the protocol (hal.rplidar_protocol) as an A1M8 does:
- GET_INFO: model 0x18, firmware 1.29, hardware 7, a serial number made from the robot index;
- GET_HEALTH: good; GET_SAMPLERATE: 508 us per standard sample, 254 us per express one;
- SCAN and FORCE_SCAN: the measurement descriptor, then every new scan the world takes of
  this robot, as 5-byte nodes in the device's clockwise order from its 0 degrees (the first
  node carries the start flag); beams that hit nothing are sent as no return (distance 0,
  quality 0), as are ranges beyond the node's 16.383 m;
- STOP: streaming ends; RESET: streaming ends and the core prints its text banner;
- SET_MOTOR_PWM: stored, no answer (as the A2's accessory board does).
Requests it does not implement get no answer (EXPRESS_SCAN and GET_LIDAR_CONF among them),
as a scanner whose firmware lacks a command behaves; payload requests with a bad checksum
are ignored.

Time: the emulator never reads a clock. Requests are answered at once by the port's service
thread; scans are sent in `advance_to(now_us)`, which the simulation runner calls after each
world step (world_sim.devices.lockstep), so each scan goes out whole at the tick it was taken.
A real scanner spreads a revolution over its period; the simulated world takes each scan at
one instant, and sending it whole keeps the serial path's scans those of the in-process one.
"""
from __future__ import annotations

import threading

import numpy as np

from hal import rplidar_protocol as P
from world_sim.devices.pty_port import PtyPort
from world_sim.world import World

A1M8_MODEL = 0x18
A1M8_FIRMWARE = (1, 29)
A1M8_HARDWARE = 7
A1M8_SAMPLE_RATE = P.SampleRate(standard_us=508, express_us=254)
HIT_QUALITY = 15                     # what an A1 typically reports for a solid return
RESET_BANNER = b"RP LIDAR System.\r\nFirmware Ver 1.29 - rtm, HW Ver 7\r\nModel: 18\r\n"


def encode_scan(robot_angles_rad: np.ndarray, ranges_m: np.ndarray, range_max_m: float) -> bytes:
    """One revolution of nodes for beams at these robot-frame angles, in device order."""
    angle_q6 = P.device_angle_q6(robot_angles_rad)
    order = np.argsort(angle_q6, kind="stable")
    ranges = np.asarray(ranges_m, dtype=np.float64)[order]
    distance_q2 = np.rint(ranges * 1000.0 * P.DISTANCE_Q2_PER_MM).astype(np.int64)
    valid = (ranges < range_max_m) & (distance_q2 > 0) & (distance_q2 <= P.MAX_DISTANCE_Q2)
    distance_q2 = np.where(valid, distance_q2, 0)
    quality = np.where(valid, HIT_QUALITY, 0)
    start = np.zeros(len(order), dtype=bool)
    start[:1] = True
    return P.encode_nodes(start, quality, angle_q6[order], distance_q2)


class RplidarEmulator:
    """Robot `robot_index`'s LiDAR, as an RPLIDAR A1 on the pty at `path`."""

    def __init__(self, world: World, robot_index: int, *, baudrate: int = P.BAUDRATE):
        world.latest_scan(robot_index)      # validates the index now
        self._world = world
        self._index = robot_index
        p = world.params
        self._beam_angles_rad = p.lidar_angle_min_rad + np.arange(p.lidar_beams) * p.lidar_angle_increment_rad
        self.info = P.DeviceInfo(model=A1M8_MODEL, firmware_major=A1M8_FIRMWARE[0],
                                 firmware_minor=A1M8_FIRMWARE[1], hardware=A1M8_HARDWARE,
                                 serial_number=bytes(range(12)) + robot_index.to_bytes(4, "little"))
        self.health = P.Health(P.HEALTH_GOOD, 0)
        self.motor_pwm = 0
        self.scanning = False
        self._last_sent_stamp_us = -1
        self._requests = P.RequestParser()
        self._lock = threading.Lock()
        self.requests_served = 0
        self._port = PtyPort(self._on_input, baudrate, f"rplidar-emulator {robot_index}")

    @property
    def path(self) -> str:
        return self._port.path

    @property
    def bytes_queued(self) -> int:
        """Every byte written to the client so far (a lockstep driver waits for them)."""
        return self._port.bytes_queued

    def advance_to(self, now_us: int) -> None:
        """Send the world's newest scan of this robot if it is new and the scanner is scanning."""
        if self._port.error is not None:
            raise RuntimeError(f"RPLIDAR emulator {self._index}: service thread failed: "
                               f"{self._port.error!r}") from self._port.error
        with self._lock:
            if not self.scanning:
                return
            scan = self._world.latest_scan(self._index)
            if scan is None or scan.stamp_us <= self._last_sent_stamp_us or scan.stamp_us > now_us:
                return
            self._last_sent_stamp_us = scan.stamp_us
            self._port.write(encode_scan(self._beam_angles_rad, scan.ranges_m, scan.range_max_m))

    def close(self) -> None:
        self._port.close()

    def __enter__(self) -> RplidarEmulator:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- service thread -----------------------------------------------------------------
    def _on_input(self, data: bytes) -> None:
        with self._lock:
            for req in self._requests.feed(data):
                self.requests_served += 1
                self._answer(req)

    def _answer(self, req: P.Request) -> None:
        if req.cmd == P.CMD_STOP:
            self.scanning = False
        elif req.cmd == P.CMD_RESET:
            self.scanning = False
            self.motor_pwm = 0
            self._port.write(RESET_BANNER)
        elif req.cmd in (P.CMD_SCAN, P.CMD_FORCE_SCAN):
            self.scanning = True           # before the answer: a driver that has it sees a scanning device
            self._port.write(P.descriptor(P.ANS_TYPE_MEASUREMENT))
        elif req.cmd == P.CMD_GET_INFO:
            self._port.write(P.descriptor(P.ANS_TYPE_DEVINFO) + self.info.encode())
        elif req.cmd == P.CMD_GET_HEALTH:
            self._port.write(P.descriptor(P.ANS_TYPE_DEVHEALTH) + self.health.encode())
        elif req.cmd == P.CMD_GET_SAMPLERATE:
            self._port.write(P.descriptor(P.ANS_TYPE_SAMPLE_RATE) + A1M8_SAMPLE_RATE.encode())
        elif req.cmd == P.CMD_SET_MOTOR_PWM and len(req.payload) == 2:
            self.motor_pwm = int.from_bytes(req.payload, "little")
