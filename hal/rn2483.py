"""RadioModem backend for a Microchip RN2483 or RN2903 (or the virtual one) over a serial line.

Opens anything pyserial's serial_for_url opens: a device path, `loop://`, `socket://`.

No firmware call waits on the UART. The port is served by two threads of its own:
- a reader (pyserial's `serial.threaded.ReaderThread` with a `LineReader`) that splits the
  byte stream into lines and sorts each one: the module's asynchronous lines (`radio_rx
  <HEX>`, `radio_tx_ok`, `radio_err`) and the answers to commands go, in the order they
  arrived, into an inbox;
- a writer that takes commands from a queue and sends them one at a time, each after the
  module answered the one before (the module has a small UART buffer and answers in
  order, so this is how every driver talks to it).
`transmit`, `busy` and `poll` only queue commands and apply what the inbox holds, so they
return in microseconds whatever the baud rate: a 255-byte `radio tx` takes about 90 ms on
the wire at 57600 baud, on the writer's time. `transmit` answers from what the driver
knows (a frame of its own still on the air, a payload too long); a refusal the module
gives later (`busy`, `invalid_param`) comes back as a failed RadioTxDone.

The rssi and snr of a received frame are asked for (`radio get rssi/snr`) by the reader as
soon as the `radio_rx` line arrives; the frame is handed to the firmware once both answers
are in, in its place among the other events.

Lockstep (`lockstep=True`, for radio_sim.virtual_modem): the inbox is applied only in
`sync()`, which the simulation runner calls between firmware ticks, never during one.
`sync()` sends a barrier (`sys get ver`) and returns once its answer and every answer
queued before or because of it are in: every line the modem wrote up to the simulation's
current time has then been read and applied, whatever the kernel's scheduling of pty
bytes, and nothing changes until the next tick's commands. So the firmware sees exactly
what the in-process modem shows it, tick by tick. On real hardware leave it off: every
call then applies whatever has arrived.

What the firmware sees differs from the in-process modem in two documented ways, both
because a real module reports no more: RSSI and SNR are whole dB (`radio get rssi/snr`),
and an event's stamp_us is the clock time its line was applied (in lockstep, the first
tick at or after the frame's end), not the frame's end.
"""
from __future__ import annotations

import collections
import queue
import threading
import time
from dataclasses import dataclass, field
from typing import Callable

import serial
import serial.threaded

from hal import rn2483_protocol as P
from hal.config import BuildContext, ConfigError, Setting
from hal.interfaces import Clock
from hal.lora import PRIVATE_SYNC_WORD, PROFILES, RadioProfile
from hal.samples import RadioEvent, RadioRxFrame, RadioTxDone


class Rn2483Error(RuntimeError):
    """The module answered a command wrongly or not at all."""


@dataclass(eq=False)
class _Command:
    text: str
    # Called with the answer (None: no answer in time) when the inbox is applied, in stream order.
    on_reply: Callable[[str | None], None] | None = None
    timeout_s: float | None = None         # None: the modem's reply timeout
    reply: str | None = None
    done: threading.Event = field(default_factory=threading.Event)


@dataclass(eq=False)
class _RxEntry:
    """A received frame waiting for its `radio get rssi` and `radio get snr` answers."""

    payload: bytes
    stamp_us: int | None = None
    rssi: str | None = None
    snr: str | None = None
    answers: int = 0


class _Lines(serial.threaded.LineReader):
    TERMINATOR = b"\r\n"
    ENCODING = "ascii"
    UNICODE_HANDLING = "replace"

    def __init__(self, modem: Rn2483Modem):
        super().__init__()
        self._modem = modem

    def handle_line(self, line: str) -> None:
        self._modem._on_line(line)

    def connection_lost(self, exc) -> None:
        self._modem._on_connection_lost(exc)


class Rn2483Modem:
    """hal.interfaces.RadioModem over the RN2483 / RN2903 radio command set."""

    # Built from configuration (hal.config), on the robot's radio profile and clock.
    SETTINGS = (
        Setting("port", "text", "the module's serial device or a pyserial URL (/dev/ttyUSB0, socket://HOST:PORT)"),
        Setting("baudrate", "int", "the UART's speed", unit="bit/s", default=P.BAUDRATE, lo=1200, hi=1_000_000),
        Setting("reply_timeout_s", "float", "how long to wait for the module's answer to a command", unit="s",
                default=2.0, lo=0.05, hi=60.0),
        Setting("reset_timeout_s", "float", "how long to wait for the module to restart after `sys reset`",
                unit="s", default=3.0, lo=0.1, hi=60.0),
        Setting("configure", "bool", "reset the module and configure it for the radio profile at start-up "
                "(false: use it as it is configured)", default=True),
    )
    RESOURCES = ()

    @classmethod
    def from_config(cls, ctx: BuildContext, port: str, **settings) -> Rn2483Modem:
        if ctx.radio_profile is None:
            raise ConfigError(None, "an RN2483 needs the robot's radio profile to configure the module")
        return cls(port, ctx.radio_profile, ctx.clock, **settings)

    def __init__(self, url_or_path: str, profile: RadioProfile = PROFILES["eu868-g3"],
                 clock: Clock | None = None, *, baudrate: int = P.BAUDRATE,
                 reply_timeout_s: float = 2.0, reset_timeout_s: float = 3.0,
                 sync_word: int = PRIVATE_SYNC_WORD, configure: bool = True, lockstep: bool = False):
        m = profile.modulation
        # (An ideal profile is configured by its nominal modulation; the simulated Channel
        # then times frames by the profile's byte-rate cap.)
        if m.implicit_header or m.sf not in P.SF_VALUES:
            raise ValueError(f"profile {profile.name!r} cannot be configured on an RN2483 or RN2903 "
                             f"(sf={m.sf}, implicit_header={m.implicit_header})")
        self.profile = profile
        self.port_name = url_or_path
        self._clock = clock
        self._t0_ns = time.monotonic_ns()
        self._reply_timeout_s = reply_timeout_s
        self._lockstep = lockstep
        self._max_payload = min(P.MAX_LORA_PAYLOAD_BYTES, profile.max_payload_bytes)
        # Firmware-side state; touched only by the calling thread (transmit/busy/poll/sync).
        self._transmitting = False
        self._receiving = False
        self._events: collections.deque = collections.deque()   # RadioEvent or _RxEntry, in order
        self._pending_rx: collections.deque = collections.deque()  # _RxEntry per radio_rx line in the inbox
        # Shared with the I/O threads.
        self._lock = threading.Lock()
        self._changed = threading.Condition(self._lock)
        self._inbox: collections.deque = collections.deque()    # ("line", str) / ("reply", cmd, reply)
        self._commands: queue.Queue[_Command | None] = queue.Queue()
        self._in_flight: _Command | None = None
        self._outstanding = 0              # commands queued and not yet answered (or timed out)
        self._closed = False
        self._io_error: BaseException | None = None
        self.lines_ignored = 0             # unexpected or malformed lines, for diagnostics
        self.command_errors: list[str] = []    # commands the module refused after start-up
        self.version = ""
        self.model: P.ModuleModel | None = None
        try:
            self._ser = serial.serial_for_url(url_or_path, baudrate=baudrate, bytesize=8, parity="N",
                                              stopbits=1, timeout=None, write_timeout=reply_timeout_s)
        except (serial.SerialException, ValueError) as e:
            raise Rn2483Error(f"{url_or_path}: cannot open: {e}") from e
        # Whatever the module said before we opened the port is nobody's answer.
        self._ser.reset_input_buffer()
        self._reader = serial.threaded.ReaderThread(self._ser, lambda: _Lines(self))
        self._reader.start()
        self._writer = threading.Thread(target=self._write_loop, name=f"rn2483-writer {url_or_path}", daemon=True)
        self._writer.start()
        try:
            self._start(profile, sync_word, reset_timeout_s, configure)
        except BaseException:
            self.close()
            raise

    # -- start-up (blocking: before the firmware runs) ------------------------------------
    def _start(self, profile: RadioProfile, sync_word: int, reset_timeout_s: float, configure: bool) -> None:
        if configure:
            self._expect(P.SYS_RESET, lambda r: P.model_of_version(r) is not None,
                         "a version line 'RN2483 ...' or 'RN2903 ...'", timeout_s=reset_timeout_s)
        self.version = self._expect(P.SYS_GET_VER, lambda r: P.model_of_version(r) is not None,
                                    "a version line 'RN2483 ...' or 'RN2903 ...'")
        self.model = P.model_of_version(self.version)
        self._expect(P.MAC_PAUSE, str.isdigit, "the pause length in ms")
        if configure:
            try:
                commands = P.network_config_commands(profile, self.model, sync_word)
            except ValueError as e:
                raise Rn2483Error(f"{self.port_name}: {e}") from None
            for cmd in commands:
                self._expect(cmd, lambda r: r == P.OK, f"'{P.OK}'")
        self._arm_rx()
        # Listening when the constructor returns, as a caller expects of a radio it just opened.
        if self._lockstep:
            self.sync()
        else:
            self.settle()

    # -- RadioModem -----------------------------------------------------------------
    def transmit(self, payload: bytes) -> bool:
        self._apply_if_free_running()
        if self._transmitting or len(payload) > self._max_payload:
            return False
        if self._receiving:
            self._send(P.RADIO_RXSTOP, self._rx_stopped)
            self._receiving = False
        self._send(P.radio_tx(payload), self._tx_answered)
        self._transmitting = True
        return True

    def busy(self) -> bool:
        self._apply_if_free_running()
        return self._transmitting

    def poll(self) -> tuple[RadioEvent, ...]:
        self._apply_if_free_running()
        events: list[RadioEvent] = []
        while self._events:
            head = self._events[0]
            if isinstance(head, _RxEntry):
                if head.answers < 2:
                    break                  # its rssi/snr are on their way; keep the order
                events.append(RadioRxFrame(stamp_us=head.stamp_us, payload=head.payload,
                                           rssi_dbm=_number(head.rssi), snr_db=_number(head.snr)))
            else:
                events.append(head)
            self._events.popleft()
        # Reception is one-shot on the module: listen again right away, as the in-process
        # backend does after each poll.
        if not self._transmitting and not self._receiving:
            self._arm_rx()
        return tuple(events)

    def close(self) -> None:
        with self._lock:
            if self._closed:
                return
            if self._receiving and self._io_error is None:
                # Leave the module idle (best effort: nobody waits for the answer).
                self._queue_locked(_Command(P.RADIO_RXSTOP))
            self._closed = True
        self._commands.put(None)
        self._writer.join(timeout=self._reply_timeout_s + 1.0)
        self._reader.close()

    # -- host-side helpers (not part of the HAL contract) ---------------------------
    def sync(self, timeout_s: float | None = None) -> None:
        """Lockstep barrier: see the module docstring. Raises Rn2483Error if the module does
        not answer within `timeout_s` (default: the reply timeout)."""
        timeout_s = self._reply_timeout_s if timeout_s is None else timeout_s
        self._send(P.SYS_GET_VER, self._expect_version)
        self.settle(timeout_s)

    def settle(self, timeout_s: float | None = None) -> None:
        """Wait until every command queued so far is answered, then apply what arrived."""
        timeout_s = self._reply_timeout_s if timeout_s is None else timeout_s
        deadline = time.monotonic() + timeout_s
        with self._changed:
            while self._outstanding and self._io_error is None:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise Rn2483Error(f"{self.port_name}: {self._outstanding} command(s) unanswered "
                                      f"after {timeout_s:g} s")
                self._changed.wait(remaining)
        self._raise_io_error()
        self._apply()

    def wait(self, timeout_s: float) -> bool:
        """Block until something arrived from the module or `timeout_s` passed (for host
        tools that have nothing else to do, such as the live inspector). True if something
        arrived."""
        with self._changed:
            if not self._inbox:
                self._changed.wait(timeout_s)
            return bool(self._inbox)

    # -- firmware-side state --------------------------------------------------------
    def _apply_if_free_running(self) -> None:
        if not self._lockstep:
            self._raise_io_error()
            self._apply()

    def _apply(self) -> None:
        """Apply what the reader put in the inbox, in stream order."""
        with self._lock:
            items = list(self._inbox)
            self._inbox.clear()
        for kind, *rest in items:
            if kind == "reply":
                cmd, reply = rest
                if cmd.on_reply is not None:
                    cmd.on_reply(reply)
            else:
                self._async_line(rest[0])

    def _async_line(self, line: str) -> None:
        if line.startswith(P.RADIO_RX_PREFIX.rstrip() + " "):
            self._receiving = False
            if P.parse_rx_line(line) is None:
                with self._lock:
                    self.lines_ignored += 1    # the reader made no entry for it either
                return
            entry = self._pending_rx.popleft()
            entry.stamp_us = self._now_us()
            self._events.append(entry)
            return
        stamp = self._now_us()
        if self._transmitting:
            self._transmitting = False
            self._events.append(RadioTxDone(stamp_us=stamp, ok=line == P.RADIO_TX_OK))
        elif self._receiving:
            self._receiving = False        # the watchdog or the window ended the reception
        else:
            with self._lock:
                self.lines_ignored += 1

    def _tx_answered(self, reply: str | None) -> None:
        if reply == P.OK:
            return
        # Refused (busy, invalid_param) or unanswered: the frame never went out.
        self._note_error("radio tx", reply)
        if self._transmitting:
            self._transmitting = False
            self._events.append(RadioTxDone(stamp_us=self._now_us(), ok=False))

    def _rx_armed(self, reply: str | None) -> None:
        if reply != P.OK:
            self._receiving = False        # tried again at the next poll
            if reply != P.BUSY:
                self._note_error(P.RADIO_RX_CONTINUOUS, reply)

    def _rx_stopped(self, reply: str | None) -> None:
        if reply != P.OK:
            self._note_error(P.RADIO_RXSTOP, reply)

    def _expect_version(self, reply: str | None) -> None:
        if reply is None or P.model_of_version(reply) is None:
            self._note_error(P.SYS_GET_VER, reply)

    def _note_error(self, what: str, reply: str | None) -> None:
        self.command_errors.append(f"{what}: {'no answer' if reply is None else repr(reply)}")

    def _arm_rx(self) -> None:
        self._send(P.RADIO_RX_CONTINUOUS, self._rx_armed)
        self._receiving = True

    def _now_us(self) -> int:
        if self._clock is not None:
            return self._clock.now_us()
        return (time.monotonic_ns() - self._t0_ns) // 1000

    def _raise_io_error(self) -> None:
        if self._io_error is not None:
            raise Rn2483Error(f"{self.port_name}: serial line lost: {self._io_error!r}") from self._io_error

    # -- commands -------------------------------------------------------------------
    def _send(self, text: str, on_reply: Callable[[str | None], None] | None = None,
              timeout_s: float | None = None) -> _Command:
        cmd = _Command(text, on_reply, timeout_s=timeout_s)
        with self._lock:
            if self._closed:
                raise Rn2483Error(f"{self.port_name}: closed")
            self._queue_locked(cmd)
        return cmd

    def _queue_locked(self, cmd: _Command) -> None:
        self._outstanding += 1
        self._commands.put(cmd)

    def _expect(self, text: str, good, what: str, timeout_s: float | None = None) -> str:
        """Send one command and wait for its answer (start-up only)."""
        timeout_s = self._reply_timeout_s if timeout_s is None else timeout_s
        cmd = self._send(text, timeout_s=timeout_s)
        if not cmd.done.wait(timeout_s + 1.0):
            raise Rn2483Error(f"{self.port_name}: command {text!r}: no answer within {timeout_s:g} s")
        self._raise_io_error()
        if cmd.reply is None:
            raise Rn2483Error(f"{self.port_name}: command {text!r}: no answer within {timeout_s:g} s")
        if not good(cmd.reply):
            raise Rn2483Error(f"{self.port_name}: command {text!r} answered {cmd.reply!r}, expected {what}")
        return cmd.reply

    # -- I/O threads ----------------------------------------------------------------
    def _write_loop(self) -> None:
        while True:
            cmd = self._commands.get()
            if cmd is None:
                return
            timeout_s = self._reply_timeout_s if cmd.timeout_s is None else cmd.timeout_s
            with self._lock:
                self._in_flight = cmd
            try:
                if self._io_error is None:
                    self._reader.write((cmd.text + P.EOL).encode("ascii"))
            except (serial.SerialException, OSError) as e:
                with self._lock:
                    self._io_error = self._io_error or e
            answered = cmd.done.wait(timeout_s) if self._io_error is None else False
            if not answered:
                with self._lock:
                    if self._in_flight is cmd:       # no answer: give up on it, go on
                        self._in_flight = None
                        self._finish_locked(cmd, None)

    def _finish_locked(self, cmd: _Command, reply: str | None) -> None:
        cmd.reply = reply
        self._inbox.append(("reply", cmd, reply))
        self._outstanding -= 1
        cmd.done.set()
        self._changed.notify_all()

    def _on_line(self, line: str) -> None:
        """Reader thread: sort one line; nothing here waits."""
        with self._lock:
            if P.is_async_line(line):
                self._inbox.append(("line", line))
                if P.parse_rx_line(line) is not None:
                    # Ask for this frame's rssi and snr now, so the answers are usually in
                    # by the next poll; the entry is completed in stream order.
                    entry = _RxEntry(P.parse_rx_line(line))
                    self._pending_rx.append(entry)
                    for text in (P.RADIO_GET_RSSI, P.RADIO_GET_SNR):
                        if not self._closed:
                            self._queue_locked(_Command(text, self._rx_answer(entry, text)))
                self._changed.notify_all()
                return
            cmd = self._in_flight
            if cmd is None:
                self.lines_ignored += 1    # an answer nobody waits for (e.g. a late one)
                return
            self._in_flight = None
            self._finish_locked(cmd, line)

    def _rx_answer(self, entry: _RxEntry, text: str) -> Callable[[str | None], None]:
        def store(reply: str | None) -> None:
            if text == P.RADIO_GET_RSSI:
                entry.rssi = reply
            else:
                entry.snr = reply
            entry.answers += 1
        return store

    def _on_connection_lost(self, exc) -> None:
        with self._lock:
            if exc is not None and not self._closed:
                self._io_error = exc
            cmd, self._in_flight = self._in_flight, None
            if cmd is not None and not cmd.done.is_set():
                self._finish_locked(cmd, None)
            self._changed.notify_all()


def _number(text: str | None) -> float:
    try:
        return float(int(text))             # the module prints whole dB / dBm
    except (TypeError, ValueError):
        return float("nan")
