"""RadioModem backend for a Microchip RN2483 (or the virtual one) over a serial line.

Opens anything pyserial's serial_for_url opens: a device path, `loop://`, `socket://`.
The firmware calls transmit/busy/poll from its tick, so nothing here waits for the air:
a call waits at most for the module's immediate answer to a command (`ok`, a value),
bounded by `reply_timeout_s`.

Line handling: the module prints asynchronous lines (`radio_rx  <HEX>`, `radio_tx_ok`,
`radio_err`) between the answers to commands. Every line read, while waiting for an
answer or while polling, goes through one classifier; asynchronous ones are queued as
events in the order they arrived, so an answer is never mistaken for an event or the
other way round.

`sync_poll=True` is for the lockstep simulator (radio_sim.virtual_modem.ModemBank):
poll() and busy() end with a `sys get ver` barrier and read up to its answer, so every
line the modem wrote before (all events up to the simulation time) has been read, no
matter when the kernel hands pty bytes over. On real hardware leave it off: poll() then
only takes what has already arrived.

What the firmware sees differs from the in-process modem in two documented ways, both
because a real module reports no more: RSSI and SNR are whole dB (`radio get rssi/snr`,
asked right after each `radio_rx`), and an event's stamp_us is the clock time the line was
read (in lockstep, the first tick at or after the frame's end), not the frame's end.
"""
from __future__ import annotations

import time

import serial

from hal.interfaces import Clock
from hal.lora import PROFILES, RadioProfile
from hal.samples import RadioEvent, RadioRxFrame, RadioTxDone

MODULE_MAX_PAYLOAD_BYTES = 255
MODULE_MAX_PWR_DBM = 15          # the RN2483's highest `radio set pwr`
PRIVATE_SYNC_WORD = 0x12

_TX_OK = "radio_tx_ok"
_RADIO_ERR = "radio_err"
_RX_PREFIX = "radio_rx"


class Rn2483Error(RuntimeError):
    """The module answered a command wrongly or not at all."""


class Rn2483Modem:
    """hal.interfaces.RadioModem over the RN2483 radio command set."""

    def __init__(self, url_or_path: str, profile: RadioProfile = PROFILES["eu868-g3"],
                 clock: Clock | None = None, *, baudrate: int = 57600,
                 reply_timeout_s: float = 2.0, reset_timeout_s: float = 3.0,
                 sync_word: int = PRIVATE_SYNC_WORD, sync_poll: bool = False):
        m = profile.modulation
        # (An ideal profile is configured by its nominal modulation; the simulated Channel
        # then times frames by the profile's byte-rate cap.)
        if m.implicit_header or not 7 <= m.sf <= 12:
            raise ValueError(f"profile {profile.name!r} cannot be configured on an RN2483 "
                             f"(sf={m.sf}, implicit_header={m.implicit_header})")
        self.profile = profile
        self.port_name = url_or_path
        self._clock = clock
        self._t0_ns = time.monotonic_ns()
        self._reply_timeout_s = reply_timeout_s
        self._sync_poll = sync_poll
        self._max_payload = min(MODULE_MAX_PAYLOAD_BYTES, profile.max_payload_bytes)
        self._rx_buf = bytearray()
        self._pending: list[tuple] = []        # ("rx", hex, stamp) / ("tx", ok, stamp); stamp = clock time the line was read
        self._transmitting = False
        self._receiving = False
        self.lines_ignored = 0                 # unexpected or malformed lines, for diagnostics
        try:
            self._ser = serial.serial_for_url(url_or_path, baudrate=baudrate, bytesize=8,
                                              parity="N", stopbits=1,
                                              timeout=reply_timeout_s, write_timeout=reply_timeout_s)
        except (serial.SerialException, ValueError) as e:
            raise Rn2483Error(f"{url_or_path}: cannot open: {e}") from e
        try:
            self._start(m, profile, sync_word, reset_timeout_s)
        except BaseException:
            self._ser.close()
            raise

    # -- start-up -------------------------------------------------------------------
    def _start(self, m, profile: RadioProfile, sync_word: int, reset_timeout_s: float) -> None:
        self._ser.reset_input_buffer()
        self._expect("sys reset", lambda r: r.startswith("RN2483"), "a version line 'RN2483 ...'",
                     timeout_s=reset_timeout_s)
        self.version = self._expect("sys get ver", lambda r: r.startswith("RN2483"), "a version line 'RN2483 ...'")
        self._expect("mac pause", str.isdigit, "the pause length in ms")
        pwr = max(-3, min(MODULE_MAX_PWR_DBM, round(profile.tx_power_dbm)))
        for cmd in ("radio set mod lora",
                    f"radio set freq {profile.freq_hz}",
                    f"radio set sf sf{m.sf}",
                    f"radio set bw {m.bw_hz // 1000}",
                    f"radio set cr 4/{4 + m.cr}",
                    f"radio set pwr {pwr}",
                    f"radio set crc {'on' if m.crc_on else 'off'}",
                    f"radio set sync {sync_word:02X}",
                    f"radio set prlen {m.preamble_symbols}",
                    "radio set wdt 0"):
            self._expect(cmd, lambda r: r == "ok", "'ok'")
        self._arm_rx()

    # -- RadioModem -----------------------------------------------------------------
    def transmit(self, payload: bytes) -> bool:
        if self._sync_poll and self._transmitting:
            self._barrier()   # the radio_tx_ok of a frame that ended by now must be seen
        else:
            self._drain()
        if self._transmitting or len(payload) > self._max_payload:
            return False
        if self._receiving:
            reply = self._command("radio rxstop")
            if reply != "ok":
                raise Rn2483Error(f"{self.port_name}: command 'radio rxstop' answered {reply!r}, expected 'ok'")
            self._receiving = False
        reply = self._command("radio tx " + payload.hex().upper())
        if reply == "ok":
            self._transmitting = True
            return True
        if reply in ("busy", "invalid_param"):
            return False
        raise Rn2483Error(f"{self.port_name}: command 'radio tx' answered {reply!r}, expected 'ok', 'busy' or 'invalid_param'")

    def busy(self) -> bool:
        if self._sync_poll:
            self._barrier()
        else:
            self._drain()
        return self._transmitting

    def poll(self) -> tuple[RadioEvent, ...]:
        if self._sync_poll:
            self._barrier()
        else:
            self._drain()
        events: list[RadioEvent] = []
        while self._pending:
            item = self._pending.pop(0)
            if item[0] == "tx":
                events.append(RadioTxDone(stamp_us=item[2], ok=item[1]))
            elif item[0] == "rx":
                frame = self._rx_frame(item[1], item[2])
                if frame is not None:
                    events.append(frame)
        # Reception is one-shot on the module: listen again right away, as the in-process
        # backend does after each poll.
        if not self._transmitting and not self._receiving:
            self._arm_rx()
        return tuple(events)

    def close(self) -> None:
        self._ser.close()

    # -- internals ------------------------------------------------------------------
    def _now_us(self) -> int:
        if self._clock is not None:
            return self._clock.now_us()
        return (time.monotonic_ns() - self._t0_ns) // 1000

    def _arm_rx(self) -> None:
        reply = self._command("radio rx 0")
        if reply == "ok":
            self._receiving = True
        elif reply != "busy":
            raise Rn2483Error(f"{self.port_name}: command 'radio rx 0' answered {reply!r}, expected 'ok'")

    def _rx_frame(self, hex_text: str, stamp_us: int) -> RadioRxFrame | None:
        try:
            payload = bytes.fromhex(hex_text)
        except ValueError:
            self.lines_ignored += 1
            return None
        rssi = self._query_int("radio get rssi")
        snr = self._query_int("radio get snr")
        return RadioRxFrame(stamp_us=stamp_us, payload=payload, rssi_dbm=float(rssi), snr_db=float(snr))

    def _query_int(self, cmd: str) -> int:
        reply = self._command(cmd)
        try:
            return int(reply)
        except ValueError:
            raise Rn2483Error(f"{self.port_name}: command {cmd!r} answered {reply!r}, expected an integer") from None

    def _barrier(self) -> None:
        reply = self._command("sys get ver")
        if not reply.startswith("RN2483"):
            raise Rn2483Error(f"{self.port_name}: command 'sys get ver' answered {reply!r}, expected 'RN2483 ...'")

    def _expect(self, cmd: str, good, what: str, timeout_s: float | None = None) -> str:
        reply = self._command(cmd, timeout_s)
        if not good(reply):
            raise Rn2483Error(f"{self.port_name}: command {cmd!r} answered {reply!r}, expected {what}")
        return reply

    def _command(self, cmd: str, timeout_s: float | None = None) -> str:
        """Send one command and return its answer; asynchronous lines read meanwhile are queued."""
        self._ser.write(cmd.encode("ascii") + b"\r\n")
        self._ser.flush()
        deadline = time.monotonic() + (self._reply_timeout_s if timeout_s is None else timeout_s)
        while True:
            line = self._next_line(deadline)
            if line is None:
                raise Rn2483Error(f"{self.port_name}: command {cmd!r}: no answer within "
                                  f"{self._reply_timeout_s if timeout_s is None else timeout_s:g} s")
            if not self._take_async(line):
                return line

    def _next_line(self, deadline: float) -> str | None:
        while True:
            nl = self._rx_buf.find(b"\n")
            if nl >= 0:
                raw = bytes(self._rx_buf[:nl]).rstrip(b"\r")
                del self._rx_buf[: nl + 1]
                return raw.decode("ascii", errors="replace")
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return None
            # Blocks until one byte arrives or the port timeout (reply_timeout_s) passes.
            self._rx_buf += self._ser.read(max(1, self._ser.in_waiting))

    def _drain(self) -> None:
        """Take what has arrived, without waiting."""
        waiting = self._ser.in_waiting
        if waiting:
            self._rx_buf += self._ser.read(waiting)
        while True:
            nl = self._rx_buf.find(b"\n")
            if nl < 0:
                return
            raw = bytes(self._rx_buf[:nl]).rstrip(b"\r")
            del self._rx_buf[: nl + 1]
            line = raw.decode("ascii", errors="replace")
            if not self._take_async(line):
                self.lines_ignored += 1   # an answer nobody asked for (e.g. a late one)

    def _take_async(self, line: str) -> bool:
        """Queue `line` if it is an asynchronous module line; False if it is an answer."""
        if line.startswith(_RX_PREFIX + " "):
            self._receiving = False
            self._pending.append(("rx", line[len(_RX_PREFIX):].strip(), self._now_us()))
            return True
        if line == _TX_OK or line == _RADIO_ERR:
            stamp = self._now_us()
            if self._transmitting:
                self._transmitting = False
                self._pending.append(("tx", line == _TX_OK, stamp))
            elif self._receiving:
                self._receiving = False        # watchdog or window ended the reception
            else:
                self.lines_ignored += 1
            return True
        return False
