"""UwbRanger backend for a Qorvo (Decawave) DWM1001 module (or the emulated one) over its
UART generic API (TLV; see hal.dwm1001_protocol for why TLV rather than the shell).

Opens anything pyserial's serial_for_url opens: a device path, `loop://`, `socket://`.

No firmware call waits on the UART. A reader thread of its own (pyserial's
`serial.threaded.ReaderThread`) splits the answers out of the byte stream, and a poller
thread asks the module, `poll_hz` times a second, whether it has new location data
(dwm_status_get) and, when it has, for it (dwm_loc_get); `ranges` only takes what arrived.
The module ranges at its own update rate; asking only when the status says so hands each
measurement over once.

Each reported distance becomes a UwbRange to the robot whose module has that address: the
`peer_ids` table maps UWB short addresses to robot ids (an anchor reports 64-bit tag
addresses; their low 16 bits are the short address); by default the emulated team's plan
(hal.dwm1001_protocol.robot_address); a real team lists its modules' addresses. Distances
of 0 or with quality 0 are the module's "no measurement" and are dropped, as are addresses
the table does not know (counted). A range's stamp is the clock time its dwm_loc_get answer arrived.

Lockstep (`lockstep=True`, for world_sim.devices): no poller thread; the simulation runner
calls `sync()` between firmware ticks, which asks the same two questions and waits for the
answers, so the firmware sees the world's ranges at the tick they were measured.

Built from configuration (hal.config) as `[uwb] backend = "dwm1001"`: the port, the
constructor's settings (SETTINGS) and the teammates' modules as text
(`peer_addresses = "0:0x1A2B, 2:0x1A2D"`, see `parse_peer_addresses`), free-running on the
robot's clock.
"""
from __future__ import annotations

import threading
import time
from collections.abc import Mapping

import serial

from hal import dwm1001_protocol as P
from hal.config import BuildContext, ConfigError, Setting
from hal.interfaces import Clock
from hal.samples import UwbRange
from hal.serial_reader import start_reader

# Ranges nobody collected are dropped oldest first beyond this many (as the simulated world
# keeps its measurement queues bounded).
MAX_PENDING_RANGES = 1024
# Robot ids a peer address table may name (node ids on the radio are one byte).
MAX_ROBOT_ID = 255


def parse_peer_addresses(text: str) -> dict[int, int]:
    """UWB short address -> robot id, from "ROBOT:ADDRESS, ..." (robot ids in decimal,
    addresses 16-bit hexadecimal, with or without 0x: "0:0x1A2B, 2:1A2D"). ValueError naming
    the entry that is malformed, out of range or given twice."""
    peers: dict[int, int] = {}
    robots: set[int] = set()
    for entry in text.split(","):
        robot_text, sep, address_text = entry.strip().partition(":")
        try:
            if not sep:
                raise ValueError
            robot, address = int(robot_text.strip(), 10), int(address_text.strip(), 16)
        except ValueError:
            raise ValueError(f"{entry.strip()!r} is not ROBOT:ADDRESS (a robot id and its module's 16-bit short "
                             f"address in hexadecimal, e.g. 2:0x1A2D)") from None
        if not 0 <= robot <= MAX_ROBOT_ID:
            raise ValueError(f"{entry.strip()!r}: robot id {robot} is not in 0 .. {MAX_ROBOT_ID}")
        if not 0 <= address <= 0xFFFF:
            raise ValueError(f"{entry.strip()!r}: address 0x{address:X} is not a 16-bit short address")
        if robot in robots:
            raise ValueError(f"{entry.strip()!r}: robot {robot} is given twice")
        if address in peers:
            raise ValueError(f"{entry.strip()!r}: address 0x{address:04X} is robot {peers[address]}'s too")
        peers[address] = robot
        robots.add(robot)
    return peers


class Dwm1001Error(RuntimeError):
    """The module answered wrongly or not at all at start-up."""


class Dwm1001Ranger:
    """hal.interfaces.UwbRanger over the DWM1001 TLV API."""

    # Built from configuration (hal.config): the constructor's settings, on the robot's clock.
    SETTINGS = (
        Setting("port", "text", "the module's serial device or a pyserial URL (/dev/ttyACM0, socket://HOST:PORT)"),
        Setting("baudrate", "int", "the UART's speed", unit="bit/s", default=P.BAUDRATE, lo=9600, hi=1_000_000),
        Setting("poll_hz", "float", "how often the module is asked for new location data (it ranges at its own "
                "update rate, at most 10 Hz)", unit="Hz", default=10.0, lo=0.0, lo_open=True, hi=100.0),
        Setting("reply_timeout_s", "float", "how long to wait for the module's answer to a request", unit="s",
                default=1.0, lo=0.05, hi=60.0),
        Setting("peer_addresses", "text", "the teammates' modules, ROBOT:ADDRESS, comma-separated (\"0:0x1A2B, "
                "2:0x1A2D\"; addresses 16-bit hexadecimal); left out: the emulated team's plan (robot r is "
                f"0x{P.ADDRESS_BASE:04X} + r), under which a real module's ranges are dropped as unknown",
                default=None, check=parse_peer_addresses),
    )
    RESOURCES = ()

    @classmethod
    def from_config(cls, ctx: BuildContext, port: str, peer_addresses: str | None = None,
                    **settings) -> Dwm1001Ranger:
        if ctx.clock is None:
            raise ConfigError(None, "the DWM1001 needs the robot's clock to stamp its ranges")
        peer_ids = None if peer_addresses is None else parse_peer_addresses(peer_addresses)
        return cls(port, ctx.clock, peer_ids=peer_ids, **settings)

    def __init__(self, url_or_path: str, clock: Clock | None = None, *, peer_ids: Mapping[int, int] | None = None,
                 poll_hz: float = 10.0, baudrate: int = P.BAUDRATE, reply_timeout_s: float = 1.0,
                 lockstep: bool = False):
        if not poll_hz > 0:
            raise ValueError(f"poll_hz must be > 0, got {poll_hz!r}")
        self.port_name = url_or_path
        self._clock = clock
        self._t0_ns = time.monotonic_ns()
        self._peer_ids = dict(P.default_peer_ids() if peer_ids is None else peer_ids)
        self._poll_period_s = 1.0 / poll_hz
        self._reply_timeout_s = reply_timeout_s
        self._lockstep = lockstep
        self._reader_state = P.ResponseReader()
        self._lock = threading.Lock()
        self._changed = threading.Condition(self._lock)
        self._answers: list[tuple[int, P.Response]] = []     # (arrival stamp_us, answer)
        self._ranges: list[UwbRange] = []
        self._io_error: BaseException | None = None
        self._closed = False
        self._stop = threading.Event()
        self.node_is_anchor: bool | None = None
        self.versions: tuple[int, int, int] | None = None   # firmware, configuration, hardware
        self.timeouts = 0
        self.errors: list[str] = []                          # requests the module refused while polling
        self.unknown_addresses = 0
        self.ranges_dropped = 0
        try:
            self._ser = serial.serial_for_url(url_or_path, baudrate=baudrate, bytesize=8, parity="N",
                                              stopbits=1, timeout=None, write_timeout=reply_timeout_s)
        except (serial.SerialException, ValueError) as e:
            raise Dwm1001Error(f"{url_or_path}: cannot open: {e}") from e
        self._ser.reset_input_buffer()
        self._reader = start_reader(self._ser, self._on_bytes, self._on_connection_lost)
        self._poller: threading.Thread | None = None
        try:
            self._start()
        except BaseException:
            self.close()
            raise

    # -- start-up (blocking: before the firmware runs) ------------------------------------
    def _start(self) -> None:
        cfg = self._ask(P.CMD_CFG_GET)
        self.node_is_anchor = P.cfg_is_anchor(cfg.tlvs[P.TLV_CFG])
        ver = self._ask(P.CMD_VER_GET)
        self.versions = tuple(int.from_bytes(ver.tlvs[t], "little") for t in (P.TLV_FW_VER, P.TLV_CFG_VER, P.TLV_HW_VER))
        if not self._lockstep:
            self._poller = threading.Thread(target=self._poll_loop, name=f"dwm1001-poller {self.port_name}",
                                            daemon=True)
            self._poller.start()

    def _ask(self, cmd: int) -> P.Response:
        got = self._transact(cmd)
        if got is None:
            raise Dwm1001Error(f"{self.port_name}: request 0x{cmd:02X}: no answer within {self._reply_timeout_s:g} s")
        answer = got[1]
        if answer.rc != P.RV_OK:
            raise Dwm1001Error(f"{self.port_name}: request 0x{cmd:02X} answered {answer.rc} "
                               f"({P.RETURN_CODES.get(answer.rc, 'unknown code')})")
        return answer

    # -- UwbRanger ------------------------------------------------------------------
    def ranges(self) -> tuple[UwbRange, ...]:
        with self._lock:
            out, self._ranges = tuple(self._ranges), []
        return out

    # -- host-side helpers (not part of the HAL contract) ---------------------------
    def sync(self) -> None:
        """Lockstep: ask for new location data now and wait for it (see the module docstring)."""
        self._raise_io_error()
        self._poll_once()

    def close(self) -> None:
        with self._lock:
            if self._closed:
                return
            self._closed = True
            self._changed.notify_all()
        self._stop.set()
        if self._poller is not None:
            self._poller.join(timeout=self._reply_timeout_s + 1.0)
        self._reader.close()

    # -- polling --------------------------------------------------------------------
    def _poll_loop(self) -> None:
        while not self._stop.wait(self._poll_period_s):
            if self._io_error is not None:
                return
            self._poll_once()

    def _poll_once(self) -> None:
        status = self._transact(P.CMD_STATUS_GET)
        if not self._accepted(status) or not P.decode_status(status[1].tlvs[P.TLV_STATUS]) & P.STATUS_LOC_READY:
            return
        loc = self._transact(P.CMD_LOC_GET)
        if not self._accepted(loc):
            return
        stamp_us, answer = loc
        location = P.decode_location(answer.tlvs)
        fresh = [r for r in (self._range(d, stamp_us) for d in location.distances) if r is not None]
        with self._lock:
            self._ranges.extend(fresh)
            overflow = len(self._ranges) - MAX_PENDING_RANGES
            if overflow > 0:
                del self._ranges[:overflow]
                self.ranges_dropped += overflow

    def _accepted(self, got: tuple[int, P.Response] | None) -> bool:
        if got is None or self._closed:
            return False
        answer = got[1]
        if answer.rc != P.RV_OK:
            self.errors.append(f"request 0x{answer.cmd:02X}: {P.RETURN_CODES.get(answer.rc, answer.rc)}")
            return False
        return True

    def _range(self, d: P.Distance, stamp_us: int) -> UwbRange | None:
        if d.distance_mm == 0 or d.quality == 0:
            return None
        peer = self._peer_ids.get(d.address & 0xFFFF)
        if peer is None:
            self.unknown_addresses += 1
            return None
        return UwbRange(stamp_us=stamp_us, peer_id=peer, range_m=d.distance_mm / 1000.0)

    # -- request / answer -------------------------------------------------------------
    def _transact(self, cmd: int) -> tuple[int, P.Response] | None:
        """Send one request and wait for its answer: (the clock time it arrived, the
        answer), or None (and the reader resynchronised) if none came in time."""
        deadline = time.monotonic() + self._reply_timeout_s
        with self._changed:
            if self._closed or self._io_error is not None:
                return None
            self._reader_state.expect(cmd)
        try:
            self._reader.write(P.request(cmd))
        except (serial.SerialException, OSError) as e:
            with self._lock:
                self._io_error = self._io_error or e
            return None
        with self._changed:
            while not self._answers and not self._closed and self._io_error is None:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    self._reader_state.forget()
                    self.timeouts += 1
                    return None
                self._changed.wait(remaining)
            if not self._answers:
                return None
            return self._answers.pop(0)

    # -- reader thread --------------------------------------------------------------
    def _on_bytes(self, data: bytes) -> None:
        now_us = self._now_us()
        with self._lock:
            for answer in self._reader_state.feed(data):
                self._answers.append((now_us, answer))
            self._changed.notify_all()

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
            raise Dwm1001Error(f"{self.port_name}: serial line lost: {self._io_error!r}") from self._io_error

    @property
    def counters(self) -> dict[str, int]:
        with self._lock:
            return {"timeouts": self.timeouts, "bytes_skipped": self._reader_state.bytes_skipped,
                    "malformed": self._reader_state.malformed, "unknown_addresses": self.unknown_addresses,
                    "ranges_dropped": self.ranges_dropped}
