"""The Microchip RN2483 (firmware 1.0.5) radio command set as a pure state machine.

No I/O and no clock: every call gets the current time in integer microseconds and
returns the lines the module would print (without the trailing CR LF). The serial
server (radio_sim.virtual_modem) moves the bytes; the shared Channel moves the frames.

Behaviour copied from the real module (Microchip RN2483 command reference, DS40001784,
and the drivers that talk to it):
- the power-on radio settings are the module's defaults (868.1 MHz, SF12, BW125, CR 4/5,
  1 dBm, CRC on, sync 34, preamble 8, watchdog 15000 ms), so a driver that configures
  nothing gets what a real module gives it;
- `radio tx` / `radio rx` answer `ok` and later `radio_tx_ok` / `radio_rx  <HEX>` (two
  spaces, upper-case hex) or `radio_err`; reception is one-shot; the watchdog (`radio set
  wdt`, 0 = off) ends a reception or a transmission that runs longer with `radio_err`;
- while the radio is transmitting or receiving, `radio tx`, `radio rx` and `radio set`
  answer `busy`; `radio get`, `sys` and `mac` queries are answered at any time;
- anything the module does not know, or a parameter out of range, answers `invalid_param`.

Deliberate simplifications (documented, not hidden):
- `mac pause` is not required before radio commands (the LoRaWAN stack of a module that
  never joined is idle anyway); `mac` commands other than pause/resume/rxdelay1/2 are
  `invalid_param`.
- The shared Channel models one operating point, the radio profile's (frequency, SF, BW,
  CR, preamble, CRC) with the project's private sync word 0x12. A modem whose settings
  equal that operating point is *on the air*: its frames go through the Channel (with the
  Channel's collisions, range, duty cycle) and it hears the Channel. A modem set to
  anything else (another frequency, SF, FSK, sync word...) is *off the air*: its
  transmissions take their own time on air and reach no one, and it hears nothing, which
  is what a real receiver on another channel hears from this network.
- `radio set pwr` is stored and reported; the Channel uses the profile's power.
- A reception window (`radio rx N`, N > 0 symbols) closes after N symbol times; a frame
  counts only if it ends inside the window.
- With an ideal profile (Bayer & Faigl's link) the Channel hands every frame to every node,
  whatever it is doing, and the modem prints each one even outside `radio rx`.
- A transmission longer than the watchdog is not put on the air at all (a real module
  would have sent a truncated frame that no receiver decodes) and ends in `radio_err`.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, replace
from typing import Protocol

from hal.lora import LoraModulation, RadioProfile, time_on_air_us
from hal.samples import RadioRxFrame, RadioTxDone

VERSION_LINE = "RN2483 1.0.5 Oct 31 2018 15:06:52"
MAC_PAUSE_MS = 4294967245          # what `mac pause` answers: the longest pause, in ms
MAX_PAYLOAD_BYTES = 255
MAX_LINE_CHARS = 600               # longer than any valid command (radio tx of 255 B is 519)
PRIVATE_SYNC_WORD = 0x12           # DESIGN.md: the network's private LoRa sync word
MICROCHIP_OUI = "0004A3"
FSK_BITRATE_BPS = 50_000           # module default; `radio set bitrate` is not emulated

OK = "ok"
INVALID = "invalid_param"
BUSY = "busy"
TX_OK = "radio_tx_ok"
RADIO_ERR = "radio_err"
RX_PREFIX = "radio_rx  "           # two spaces, as the module prints it

_HEX = re.compile(r"[0-9A-Fa-f]*")
_UINT = re.compile(r"[0-9]+")
_INT = re.compile(r"-?[0-9]+")


@dataclass(frozen=True)
class RadioSettings:
    """What `radio set` changes. Defaults are the module's power-on values."""

    mod: str = "lora"              # "lora" or "fsk"
    freq_hz: int = 868_100_000
    pwr_dbm: int = 1
    sf: int = 12
    bw_khz: int = 125
    cr: int = 1                    # coding rate 4/(4+cr)
    crc_on: bool = True
    sync_word: int = 0x34
    preamble_symbols: int = 8
    wdt_ms: int = 15_000           # 0 = watchdog off

    def on_air_key(self) -> tuple:
        """Everything that must match for two modems to hear each other and for the
        Channel's airtime to be this modem's airtime."""
        return (self.mod, self.freq_hz, self.sf, self.bw_khz, self.cr, self.crc_on,
                self.sync_word, self.preamble_symbols)

    def modulation(self) -> LoraModulation:
        return LoraModulation(sf=self.sf, bw_hz=self.bw_khz * 1000, cr=self.cr,
                              preamble_symbols=self.preamble_symbols, crc_on=self.crc_on)

    def airtime_us(self, payload_bytes: int) -> int:
        if self.mod == "lora":
            return time_on_air_us(payload_bytes, self.modulation())
        # FSK frame: preamble bytes, 3-byte sync, length byte, payload, CRC-16.
        frame_bytes = self.preamble_symbols + 3 + 1 + payload_bytes + (2 if self.crc_on else 0)
        return -(-frame_bytes * 8 * 1_000_000 // FSK_BITRATE_BPS)

    def symbol_time_us(self) -> int:
        if self.mod == "lora":
            return -(-(2**self.sf) * 1000 // self.bw_khz)
        return -(-8 * 1_000_000 // FSK_BITRATE_BPS)


def on_air_settings(profile: RadioProfile, sync_word: int = PRIVATE_SYNC_WORD) -> RadioSettings:
    """The one operating point the Channel carries for `profile`, as RN2483 settings."""
    m = profile.modulation
    if m.implicit_header or m.low_data_rate_optimize is not None or not 7 <= m.sf <= 12:
        raise ValueError(f"profile {profile.name!r}: modulation {m} cannot be set on an RN2483")
    if not (433_050_000 <= profile.freq_hz <= 434_790_000 or 863_000_000 <= profile.freq_hz <= 870_000_000):
        raise ValueError(f"profile {profile.name!r}: {profile.freq_hz} Hz is outside the RN2483's bands "
                         f"(433.05-434.79 MHz, 863-870 MHz)")
    return RadioSettings(mod="lora", freq_hz=profile.freq_hz, pwr_dbm=min(15, int(profile.tx_power_dbm)),
                         sf=m.sf, bw_khz=m.bw_hz // 1000, cr=m.cr, crc_on=m.crc_on,
                         sync_word=sync_word, preamble_symbols=m.preamble_symbols, wdt_ms=0)


class AirPort(Protocol):
    """The modem's handle on the shared Channel, bound to its node id."""

    def transmit(self, payload: bytes, now_us: int) -> int | None: ...

    def set_listening(self, listening: bool, now_us: int) -> None: ...


def hweui_for(node_id: int) -> str:
    return f"{MICROCHIP_OUI}FF{node_id & 0xFFFFFFFF:08X}"


IDLE, TX, RX = "idle", "tx", "rx"


class Rn2483:
    """One module. `command` answers a line, `deliver` takes a Channel event addressed to
    this node, `expire` fires the module's own timers (watchdog, rx window, off-air tx)."""

    def __init__(self, node_id: int, port: AirPort | None = None, on_air: RadioSettings | None = None,
                 *, ideal_link: bool = False):
        self.node_id = node_id
        # The ideal link (Bayer & Faigl) hands every frame to every node, even one that is
        # sending or not listening; the modem prints it all the same, so the serial path
        # shows the firmware exactly what the in-process modem shows. A fiction, like the link.
        self._ideal_link = ideal_link
        self._port = port
        self._on_air_key = on_air.on_air_key() if on_air is not None else None
        self.settings = RadioSettings()
        self.state = IDLE
        self.mac_paused = False
        self.last_snr_db = -128
        self.last_rssi_dbm = -128
        self._deadline_us: int | None = None     # watchdog / window / off-air end of the current operation
        self._tx_on_air = False
        self._tx_failed = False                  # a watchdog-refused frame ends in radio_err
        self._air_busy_until_us = 0              # an on-air frame of ours the reset could not recall

    # -- queries for the server ------------------------------------------------------
    @property
    def on_air(self) -> bool:
        return self._port is not None and self.settings.on_air_key() == self._on_air_key

    def next_deadline_us(self) -> int | None:
        return self._deadline_us

    # -- commands --------------------------------------------------------------------
    def command(self, line: str, now_us: int) -> list[str]:
        if len(line) > MAX_LINE_CHARS or not line.isascii():
            return [INVALID]
        words = line.split(" ")
        head = words[0]
        try:
            if head == "sys":
                return self._sys(words[1:], now_us)
            if head == "mac":
                return self._mac(words[1:])
            if head == "radio":
                return self._radio(words[1:], now_us)
        except _Invalid:
            pass
        return [INVALID]

    def _sys(self, w: list[str], now_us: int) -> list[str]:
        if w == ["get", "ver"]:
            return [VERSION_LINE]
        if w == ["reset"]:
            self._abort(now_us)
            self.settings = RadioSettings()
            self.mac_paused = False
            self.last_snr_db = self.last_rssi_dbm = -128
            return [VERSION_LINE]
        if w == ["get", "hweui"]:
            return [hweui_for(self.node_id)]
        if w == ["get", "vdd"]:
            return ["3300"]
        raise _Invalid

    def _mac(self, w: list[str]) -> list[str]:
        if w == ["pause"]:
            self.mac_paused = True
            return [str(MAC_PAUSE_MS)]
        if w == ["resume"]:
            self.mac_paused = False
            return [OK]
        if w == ["get", "rxdelay1"]:
            return ["1000"]
        if w == ["get", "rxdelay2"]:
            return ["2000"]
        raise _Invalid

    def _radio(self, w: list[str], now_us: int) -> list[str]:
        if not w:
            raise _Invalid
        verb, args = w[0], w[1:]
        if verb == "get" and len(args) == 1:
            return [self._get(args[0])]
        if verb == "set" and len(args) == 2:
            new = self._parse_set(args[0], args[1])   # validate first: bad values are invalid even when busy
            if self.state != IDLE:
                return [BUSY]
            self.settings = new
            return [OK]
        if verb == "tx":
            return self._tx(args, now_us)
        if verb == "rx" and len(args) == 1:
            return self._rx(args[0], now_us)
        if verb == "rxstop" and not args:
            if self.state == RX:
                self._end_rx(now_us)
            return [OK]
        raise _Invalid

    def _get(self, name: str) -> str:
        s = self.settings
        values = {
            "mod": s.mod, "freq": str(s.freq_hz), "pwr": str(s.pwr_dbm), "sf": f"sf{s.sf}",
            "bw": str(s.bw_khz), "cr": f"4/{4 + s.cr}", "crc": "on" if s.crc_on else "off",
            "sync": f"{s.sync_word:02X}", "prlen": str(s.preamble_symbols), "wdt": str(s.wdt_ms),
            "snr": str(self.last_snr_db), "rssi": str(self.last_rssi_dbm),
        }
        try:
            return values[name]
        except KeyError:
            raise _Invalid from None

    def _parse_set(self, name: str, value: str) -> RadioSettings:
        s = self.settings
        if name == "mod" and value in ("lora", "fsk"):
            return replace(s, mod=value)
        if name == "freq":
            f = _uint(value, 870_000_000)
            if 433_050_000 <= f <= 434_790_000 or 863_000_000 <= f <= 870_000_000:
                return replace(s, freq_hz=f)
        if name == "pwr" and _INT.fullmatch(value) and -3 <= int(value) <= 15:
            return replace(s, pwr_dbm=int(value))
        if name == "sf" and value in {f"sf{n}" for n in range(7, 13)}:
            return replace(s, sf=int(value[2:]))
        if name == "bw" and value in ("125", "250", "500"):
            return replace(s, bw_khz=int(value))
        if name == "cr" and value in ("4/5", "4/6", "4/7", "4/8"):
            return replace(s, cr=int(value[2]) - 4)
        if name == "crc" and value in ("on", "off"):
            return replace(s, crc_on=value == "on")
        if name == "sync" and _HEX.fullmatch(value) and value:
            # LoRa takes one byte; FSK up to eight.
            if len(value) <= (2 if s.mod == "lora" else 16):
                return replace(s, sync_word=int(value, 16))
        if name == "prlen":
            return replace(s, preamble_symbols=_uint(value, 65_535))
        if name == "wdt":
            return replace(s, wdt_ms=_uint(value, 4_294_967_295))
        raise _Invalid

    def _tx(self, args: list[str], now_us: int) -> list[str]:
        # `radio tx ` with an empty field sends an empty frame, as does a bare `radio tx`.
        if len(args) > 1:
            raise _Invalid
        data = args[0] if args else ""
        if not _HEX.fullmatch(data) or len(data) % 2 or len(data) // 2 > MAX_PAYLOAD_BYTES:
            raise _Invalid
        if self.state != IDLE:
            return [BUSY]
        payload = bytes.fromhex(data)
        airtime_us = self.settings.airtime_us(len(payload))
        wdt_us = self.settings.wdt_ms * 1000
        if wdt_us and airtime_us > wdt_us:
            self._tx_on_air = False
            self._deadline_us = now_us + wdt_us
            self._tx_failed = True
        elif self.on_air:
            end_us = self._port.transmit(payload, now_us)  # type: ignore[union-attr]
            if end_us is None:
                # The Channel refuses: either our frame recalled by `sys reset` is still on the
                # air, or the frame exceeds what the profile allows on this channel.
                return [BUSY] if now_us < self._air_busy_until_us else [INVALID]
            self._tx_on_air = True
            self._air_busy_until_us = end_us
            self._deadline_us = None
            self._tx_failed = False
        else:
            self._tx_on_air = False
            self._deadline_us = now_us + airtime_us
            self._tx_failed = False
        self.state = TX
        return [OK]

    def _rx(self, arg: str, now_us: int) -> list[str]:
        window_symbols = _uint(arg, 65_535)
        if self.state != IDLE:
            return [BUSY]
        deadlines = []
        if window_symbols:
            deadlines.append(now_us + window_symbols * self.settings.symbol_time_us())
        if self.settings.wdt_ms:
            deadlines.append(now_us + self.settings.wdt_ms * 1000)
        self._deadline_us = min(deadlines) if deadlines else None
        self.state = RX
        if self.on_air:
            self._port.set_listening(True, now_us)  # type: ignore[union-attr]
        return [OK]

    # -- events and timers -----------------------------------------------------------
    def deliver(self, event: RadioRxFrame | RadioTxDone, now_us: int) -> list[str]:
        """A Channel event for this node (oldest first). Events the module no longer waits
        for (after `sys reset` or `radio rxstop`) are dropped, as the module would."""
        if isinstance(event, RadioTxDone):
            if self.state == TX and self._tx_on_air:
                self._finish()
                return [TX_OK if event.ok else RADIO_ERR]
            return []
        if self.state == RX or (self._ideal_link and self.on_air):
            if self.state == RX:
                self._finish()
            self.last_snr_db = max(-128, min(127, round(event.snr_db)))
            self.last_rssi_dbm = round(event.rssi_dbm)
            return [RX_PREFIX + event.payload.hex().upper()]
        return []

    def expire(self, now_us: int) -> list[str]:
        if self._deadline_us is None or now_us < self._deadline_us:
            return []
        if self.state == TX:
            failed = self._tx_failed
            self._finish()
            return [RADIO_ERR if failed else TX_OK]
        if self.state == RX:
            self._end_rx(now_us)
            return [RADIO_ERR]
        self._deadline_us = None
        return []

    # -- helpers ---------------------------------------------------------------------
    def _finish(self) -> None:
        self.state = IDLE
        self._deadline_us = None
        self._tx_on_air = False

    def _end_rx(self, now_us: int) -> None:
        if self.on_air:
            self._port.set_listening(False, now_us)  # type: ignore[union-attr]
        self._finish()

    def _abort(self, now_us: int) -> None:
        if self.state == RX:
            self._end_rx(now_us)
        self._finish()


class _Invalid(Exception):
    pass


def _uint(text: str, maximum: int) -> int:
    if not _UINT.fullmatch(text) or len(text) > 10 or int(text) > maximum:
        raise _Invalid
    return int(text)
