"""Lidar backend for a Slamtec RPLIDAR A-series scanner (or the emulated one) over a serial line.

Opens anything pyserial's serial_for_url opens: a device path, `loop://`, `socket://`.

Why not a driver library: the Python RPLIDAR drivers on PyPI (rplidar-roboticia, pyrplidar,
adafruit-circuitpython-rplidar) read the port in a blocking generator on the caller's
thread and raise on the first malformed node (check bit, start flags), so a burst of noise
ends the scan; the Adafruit one also needs Blinka. This backend parses the published
protocol (hal.rplidar_protocol) instead; tests/test_rplidar_third_party.py checks that two
of those libraries, unchanged, read the emulated scanner as they read a real one.

No firmware call waits on the UART: a reader thread of its own (pyserial's
`serial.threaded.ReaderThread`) parses the byte stream as it arrives, resynchronising after
noise, and assembles revolutions; `latest_scan` only takes the newest finished one.

Revolutions: nodes are binned by angle onto the same grid the simulated LiDAR uses (`beams`
beams from -pi, counter-clockwise, in the robot frame; see hal.rplidar_protocol for the
mounting convention). A revolution is finished when a node lands in its last angular bin
(the bin before the device's 0 degrees) or when the next revolution's start flag arrives,
whichever comes first; nodes of it that come later are dropped. A bin that got no valid
return reads `range_max_m`; a bin that got several keeps the nearest. Revolutions with fewer
than `min_nodes_per_revolution` nodes are dropped (a scan start, or noise that looked like
a start flag). A revolution's stamp is the clock time its first node arrived; on real
hardware that is within one UART chunk of the measurement.

Lockstep (`lockstep=True`, for world_sim.devices): nodes are parsed on the reader thread but
assembled only in `sync(until_bytes_received)`, which the simulation runner calls between
firmware ticks with the number of bytes the emulator has written so far; it returns once
they are all in, and stamps the revolutions they start with the clock's time then. So the
firmware sees exactly the scans the world had taken up to that tick.

Motor: an A1's motor runs while the adapter holds DTR low; the backend sets it low at start
and high at close, and skips it on ports without modem lines (pseudo-terminals). A2/A3
scanners take `motor_pwm` over the protocol instead.

Built from configuration (hal.config) as `[lidar] backend = "rplidar"`: the port and the
constructor's settings (SETTINGS), free-running on the robot's clock.
"""
from __future__ import annotations

import math
import queue
import threading
import time

import numpy as np
import serial

from hal import rplidar_protocol as P
from hal.config import BuildContext, ConfigError, Setting
from hal.interfaces import Clock
from hal.samples import LidarScan
from hal.serial_reader import start_reader

A1_RANGE_MAX_M = 12.0


class RplidarError(RuntimeError):
    """The scanner answered wrongly, not at all, or reported a hardware error."""


class RevolutionAssembler:
    """Nodes in, LidarScans out (see the module docstring). Pure: the caller gives the time."""

    def __init__(self, beams: int = 360, range_max_m: float = A1_RANGE_MAX_M, min_nodes_per_revolution: int = 36):
        if beams < 1:
            raise ValueError(f"beams must be >= 1, got {beams}")
        if not (math.isfinite(range_max_m) and range_max_m > 0):
            raise ValueError(f"range_max_m must be a positive number, got {range_max_m!r}")
        self.beams = beams
        self.range_max_m = float(range_max_m)
        self.min_nodes_per_revolution = min_nodes_per_revolution
        self.angle_min_rad = -math.pi
        self.angle_increment_rad = 2.0 * math.pi / beams
        self._ranges: np.ndarray | None = None    # the revolution being filled
        self._stamp_us = 0
        self._nodes = 0
        self._finished = True                    # nothing open until a start flag
        self.nodes_dropped = 0
        self.revolutions_dropped = 0

    def add(self, nodes: P.Nodes, now_us: int) -> list[LidarScan]:
        """Take a batch of nodes that arrived at `now_us`; the revolutions they finish."""
        out: list[LidarScan] = []
        starts = np.flatnonzero(nodes.start)
        bounds = [0, *[int(s) for s in starts if s > 0], len(nodes)]
        for lo, hi in zip(bounds[:-1], bounds[1:]):
            if hi == lo:
                continue
            if nodes.start[lo]:
                self._close(out)
                self._open(now_us)
            self._fill(nodes, lo, hi, out)
        return out

    def _open(self, now_us: int) -> None:
        self._ranges = np.full(self.beams, np.inf, dtype=np.float64)
        self._stamp_us = now_us
        self._nodes = 0
        self._finished = False

    def _fill(self, nodes: P.Nodes, lo: int, hi: int, out: list[LidarScan]) -> None:
        if self._finished:
            self.nodes_dropped += hi - lo
            return
        angle_q6 = nodes.angle_q6[lo:hi]
        # Device bin k is centred on k full bins clockwise from the device's 0 degrees.
        device_bin = np.rint(angle_q6 * self.beams / P.FULL_TURN_Q6).astype(np.int64) % self.beams
        last = np.flatnonzero(device_bin == self.beams - 1)
        end = int(last[0]) + 1 if len(last) else hi - lo
        beam = np.rint((P.robot_angle_rad(angle_q6[:end]) - self.angle_min_rad) / self.angle_increment_rad)
        beam = beam.astype(np.int64) % self.beams
        distance_q2 = nodes.distance_q2[lo:lo + end]
        valid = distance_q2 > 0
        range_m = distance_q2[valid] / (P.DISTANCE_Q2_PER_MM * 1000.0)
        np.minimum.at(self._ranges, beam[valid], range_m)
        self._nodes += end
        if len(last):
            self.nodes_dropped += (hi - lo) - end
            self._close(out)

    def _close(self, out: list[LidarScan]) -> None:
        if self._finished:
            return
        self._finished = True
        if self._nodes < self.min_nodes_per_revolution:
            self.revolutions_dropped += 1
            return
        ranges = np.minimum(self._ranges, self.range_max_m).astype(np.float32)
        ranges.flags.writeable = False
        out.append(LidarScan(stamp_us=self._stamp_us, angle_min_rad=self.angle_min_rad,
                             angle_increment_rad=self.angle_increment_rad, range_max_m=self.range_max_m,
                             ranges_m=ranges))


class RplidarLidar:
    """hal.interfaces.Lidar over the RPLIDAR serial protocol (standard SCAN)."""

    # Built from configuration (hal.config): the constructor's settings, on the robot's clock.
    SETTINGS = (
        Setting("port", "text", "the scanner's serial device or a pyserial URL (/dev/ttyUSB1, socket://HOST:PORT)"),
        Setting("baudrate", "int", "the UART's speed (A1 and A2M8: 115200; A2M12 and A3: 256000)", unit="bit/s",
                default=P.BAUDRATE, lo=9600, hi=1_000_000),
        Setting("beams", "int", "angular bins a revolution is assembled into, from -pi counter-clockwise (nodes "
                "in one bin keep the nearest)", unit="beams", default=360, lo=8, hi=3600),
        Setting("range_max_m", "float", "the scans' maximum range: a bin without a valid return reads it (the "
                "standard scan's 16-bit distances end at the upper bound)", unit="m", default=A1_RANGE_MAX_M, lo=0.0,
                lo_open=True, hi=P.MAX_DISTANCE_Q2 / (P.DISTANCE_Q2_PER_MM * 1000.0)),
        Setting("reply_timeout_s", "float", "how long to wait for the scanner's answer at start-up", unit="s",
                default=1.0, lo=0.05, hi=60.0),
        Setting("motor_pwm", "int", "motor speed set over the protocol at start-up, for A2/A3 scanners (an A1's "
                "motor runs off the adapter's DTR line: leave it out)", default=None, lo=0, hi=P.MAX_MOTOR_PWM),
        Setting("min_nodes_per_revolution", "int", "revolutions with fewer nodes are dropped (a scan's start, "
                "noise that looked like a start flag)", unit="nodes", default=36, lo=1, hi=100_000),
    )
    RESOURCES = ()

    @classmethod
    def from_config(cls, ctx: BuildContext, port: str, **settings) -> RplidarLidar:
        if ctx.clock is None:
            raise ConfigError(None, "the RPLIDAR needs the robot's clock to stamp its scans")
        return cls(port, ctx.clock, **settings)

    def __init__(self, url_or_path: str, clock: Clock | None = None, *, beams: int = 360,
                 range_max_m: float = A1_RANGE_MAX_M, baudrate: int = P.BAUDRATE, reply_timeout_s: float = 1.0,
                 motor_pwm: int | None = None, min_nodes_per_revolution: int = 36, lockstep: bool = False):
        self.port_name = url_or_path
        self._clock = clock
        self._t0_ns = time.monotonic_ns()
        self._reply_timeout_s = reply_timeout_s
        self._lockstep = lockstep
        self._parser = P.ResponseParser()
        self._assembler = RevolutionAssembler(beams, range_max_m, min_nodes_per_revolution)
        self._lock = threading.Lock()
        self._changed = threading.Condition(self._lock)
        self._answers: queue.Queue = queue.Queue()        # everything but nodes, for start-up
        self._pending_nodes: list[P.Nodes] = []           # lockstep: parsed, not yet assembled
        self._newest: LidarScan | None = None             # finished and not yet read
        self._bytes_received = 0
        self._io_error: BaseException | None = None
        self._closed = False
        self.scans_skipped = 0            # finished revolutions a newer one replaced before anyone read them
        self.info: P.DeviceInfo | None = None
        self.health: P.Health | None = None
        try:
            self._ser = serial.serial_for_url(url_or_path, baudrate=baudrate, bytesize=8, parity="N",
                                              stopbits=1, timeout=None, write_timeout=reply_timeout_s)
        except (serial.SerialException, ValueError) as e:
            raise RplidarError(f"{url_or_path}: cannot open: {e}") from e
        self._ser.reset_input_buffer()
        self._reader = start_reader(self._ser, self._on_bytes, self._on_connection_lost)
        try:
            self._start(motor_pwm)
        except BaseException:
            self.close()
            raise

    # -- start-up (blocking: before the firmware runs) ------------------------------------
    def _start(self, motor_pwm: int | None) -> None:
        self._write(P.request(P.CMD_STOP))    # in case a previous session left it scanning
        self.health = self._ask(P.CMD_GET_HEALTH, P.Health)
        if self.health.status == P.HEALTH_ERROR:
            raise RplidarError(f"{self.port_name}: the scanner reports a hardware error "
                               f"(code 0x{self.health.error_code:04X}); power-cycle or reset it")
        self.info = self._ask(P.CMD_GET_INFO, P.DeviceInfo)
        self._set_motor(running=True)
        if motor_pwm is not None:
            self._write(P.request(P.CMD_SET_MOTOR_PWM, P.motor_pwm_payload(motor_pwm)))
        started = self._ask(P.CMD_SCAN, P.StreamStarted)
        if started.answer_type != P.ANS_TYPE_MEASUREMENT:
            raise RplidarError(f"{self.port_name}: SCAN started a stream of type 0x{started.answer_type:02X}, "
                               f"expected 0x{P.ANS_TYPE_MEASUREMENT:02X}")

    def _ask(self, cmd: int, answer_class: type):
        """Send a request and wait for its answer (start-up only); other answers are dropped."""
        self._write(P.request(cmd))
        deadline = time.monotonic() + self._reply_timeout_s
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise RplidarError(f"{self.port_name}: request 0x{cmd:02X}: no answer within "
                                   f"{self._reply_timeout_s:g} s")
            try:
                answer = self._answers.get(timeout=remaining)
            except queue.Empty:
                continue
            self._raise_io_error()
            if isinstance(answer, answer_class):
                return answer

    def _set_motor(self, running: bool) -> None:
        try:
            self._ser.dtr = not running
        except (OSError, serial.SerialException):
            pass                           # no modem lines (a pseudo-terminal): nothing to switch

    def _write(self, data: bytes) -> None:
        self._raise_io_error()
        try:
            self._reader.write(data)
        except (serial.SerialException, OSError) as e:
            raise RplidarError(f"{self.port_name}: write failed: {e}") from e

    # -- Lidar ------------------------------------------------------------------------
    def latest_scan(self) -> LidarScan | None:
        with self._lock:
            scan, self._newest = self._newest, None
            return scan

    # -- host-side helpers (not part of the HAL contract) ---------------------------
    def sync(self, until_bytes_received: int, timeout_s: float | None = None) -> None:
        """Lockstep barrier: wait until `until_bytes_received` bytes have arrived since the
        port was opened, then assemble the nodes they carried, at the clock's time now."""
        timeout_s = self._reply_timeout_s if timeout_s is None else timeout_s
        deadline = time.monotonic() + timeout_s
        with self._changed:
            while self._bytes_received < until_bytes_received and self._io_error is None:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise RplidarError(f"{self.port_name}: {self._bytes_received} of {until_bytes_received} "
                                       f"bytes after {timeout_s:g} s")
                self._changed.wait(remaining)
            pending, self._pending_nodes = self._pending_nodes, []
        self._raise_io_error()
        now_us = self._now_us()
        finished = [scan for nodes in pending for scan in self._assembler.add(nodes, now_us)]
        with self._lock:
            self._publish(finished)

    @property
    def bytes_received(self) -> int:
        with self._lock:
            return self._bytes_received

    def counters(self) -> dict[str, int]:
        """What noise and timing cost: bytes skipped to resynchronise, nodes and revolutions
        dropped, finished scans nobody read."""
        with self._lock:
            return {"bytes_skipped": self._parser.bytes_skipped, "nodes_dropped": self._assembler.nodes_dropped,
                    "revolutions_dropped": self._assembler.revolutions_dropped, "scans_skipped": self.scans_skipped}

    def close(self) -> None:
        with self._lock:
            if self._closed:
                return
            self._closed = True
        if self._io_error is None:
            try:
                self._reader.write(P.request(P.CMD_STOP))
            except (serial.SerialException, OSError):
                pass                       # best effort: the line is going away anyway
            self._set_motor(running=False)
        self._reader.close()

    # -- reader thread --------------------------------------------------------------
    def _on_bytes(self, data: bytes) -> None:
        # The parser (and, free-running, the assembler) belong to this thread alone, so the
        # work happens outside the lock: a firmware call never waits for a chunk's parsing.
        # The arrival time is read once per chunk.
        now_us = None if self._lockstep else self._now_us()
        nodes: list[P.Nodes] = []
        finished: list[LidarScan] = []
        for answer in self._parser.feed(data):
            if not isinstance(answer, P.Nodes):
                self._answers.put(answer)
            elif self._lockstep:
                nodes.append(answer)
            else:
                finished += self._assembler.add(answer, now_us)
        with self._lock:
            self._pending_nodes += nodes
            self._publish(finished)
            self._bytes_received += len(data)
            self._changed.notify_all()

    def _publish(self, finished: list[LidarScan]) -> None:
        """Keep the newest finished scan (lock held)."""
        for scan in finished:
            if self._newest is not None:
                self.scans_skipped += 1
            self._newest = scan

    def _on_connection_lost(self, exc) -> None:
        with self._lock:
            if exc is not None and not self._closed:
                self._io_error = exc
            self._changed.notify_all()

    def _now_us(self) -> int:
        if self._clock is not None:
            return self._clock.now_us()
        return (time.monotonic_ns() - self._t0_ns) // 1000

    def _raise_io_error(self) -> None:
        if self._io_error is not None:
            raise RplidarError(f"{self.port_name}: serial line lost: {self._io_error!r}") from self._io_error
