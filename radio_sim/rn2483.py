"""The Microchip RN2483 / RN2903 (firmware 1.0.5) command set as a pure state machine.

No I/O and no clock: every call gets the current time in integer microseconds and
returns the lines the module would print (without the trailing CR LF). The serial
server (radio_sim.virtual_modem) moves the bytes; the shared Channel moves the frames.
Commands, answers, ranges and defaults come from hal.rn2483_protocol.

Behaviour copied from the real module (Microchip command references DS40001784 for the
RN2483 and DS40001811 for the RN2903, and the drivers that talk to them):
- every documented `radio` and `sys` command is answered: `radio set/get` of mod, freq, pwr,
  sf, afcbw, rxbw, bitrate, fdev, prlen, crc, iqi, cr, wdt, sync, bw, bt (and `get` of snr and
  rssi), `radio tx/rx/rxstop/cw`, `sys reset/factoryRESET/sleep/eraseFW`, `sys set
  nvm/pindig/pinmode`, `sys get ver/nvm/vdd/hweui/pindig/pinana`. Values are stored and
  read back as the module prints them;
- the power-on settings are the module's defaults (RN2483: 868.1 MHz, 1 dBm; RN2903:
  923.3 MHz, 2 dBm; both SF12, BW125, CR 4/5, CRC on, IQ not inverted, sync 34, preamble 8,
  watchdog 15000 ms), so a driver that configures nothing gets what a real module gives it;
- `radio tx` / `radio rx` answer `ok` and later `radio_tx_ok` / `radio_rx  <HEX>` (two
  spaces, upper-case hex) or `radio_err`; reception is one-shot; the watchdog (`radio set
  wdt`, 0 = off) ends a reception or a transmission that runs longer with `radio_err`;
- while the radio is transmitting, receiving or sending a carrier (`radio cw on`), `radio
  tx`, `radio rx` and `radio set` answer `busy`; `radio get`, `sys` and `mac` queries are
  answered at any time;
- `sys sleep N` answers `ok` when the N ms are over; meanwhile the module does not listen
  to the UART (lines sent to it are lost, as on the module without a wake-up break);
- `sys eraseFW` answers nothing and leaves the module in its bootloader, which ignores the
  command set from then on;
- NVM (user EEPROM 0x300-0x3FF) survives `sys reset`; `sys factoryRESET` erases it and
  restores every default;
- anything the module does not know, or a parameter out of range, answers `invalid_param`.

Air interface: every frame goes into the shared Channel with this modem's own settings
(hal.lora.AirInterface: frequency, LoRa SF/BW/CR/preamble/CRC/sync word/IQ polarity, or FSK
bit rate, sync word and receive bandwidth) and power (`radio set pwr` plus the board's
front-end gain, see `front_end_gain_db`); it is heard by the modems listening with equal
settings, so two modules left at power-on defaults hear each other, as do two on the
network's operating point.

Deliberate simplifications (documented, not hidden):
- `mac pause` is not required before radio commands (the LoRaWAN stack of a module that
  never joined is idle anyway); `mac` commands other than pause/resume/rxdelay1/2 are
  `invalid_param`.
- `radio cw on` keys a carrier that the Channel does not carry (no receiver decodes it; its
  interference is not modelled); `radio cw off` or `sys reset` ends it.
- Pins read back what was written (`sys get pindig` of an output), 0 for inputs, and
  `sys get pinana` reads 0: nothing is wired to the virtual module.
- A reception window (`radio rx N`, N > 0 symbols) closes after N symbol times; a frame
  counts only if it ends inside the window.
- With an ideal profile (Bayer & Faigl's link) the Channel hands every frame to every node,
  whatever it is doing, and a modem on the network's settings prints each one even outside
  `radio rx`.
- A transmission longer than the watchdog is not put on the air at all (a real module
  would have sent a truncated frame that no receiver decodes) and ends in `radio_err`.
- Without a Channel (`port=None`) the modem times its own frames and hears nothing.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, replace
from typing import Protocol

from hal import rn2483_protocol as P
from hal.lora import PRIVATE_SYNC_WORD, AirInterface, LoraModulation, RadioProfile
from hal.samples import RadioRxFrame, RadioTxDone

# Re-exported for callers that know the emulator only.
VERSION_LINE = P.RN2483.version_line
MAC_PAUSE_MS = P.MAC_PAUSE_MS
MAX_PAYLOAD_BYTES = P.MAX_LORA_PAYLOAD_BYTES
MAX_LINE_CHARS = 600               # longer than any valid command (radio tx of 255 B is 519)

_HEX = re.compile(r"[0-9A-Fa-f]*")
_UINT = re.compile(r"[0-9]+")
_INT = re.compile(r"-?[0-9]+")


@dataclass(frozen=True)
class RadioSettings:
    """What `radio set` changes. Defaults are the RN2483's power-on values (`for_model`
    gives another module's)."""

    mod: str = "lora"              # "lora" or "fsk"
    freq_hz: int = P.RN2483.default_freq_hz
    pwr_dbm: int = P.RN2483.default_pwr_dbm
    sf: int = 12
    bw_khz: int = 125
    cr: int = 1                    # coding rate 4/(4+cr)
    crc_on: bool = True
    iqi_on: bool = False           # IQ inversion
    sync_hex: str = "34"           # as the module prints it: upper case, whole bytes
    preamble_symbols: int = 8
    wdt_ms: int = 15_000           # 0 = watchdog off
    bitrate_bps: int = 50_000      # FSK
    fdev_hz: int = 25_000          # FSK
    afcbw_khz: str = "41.7"        # FSK
    rxbw_khz: str = "25"           # FSK
    bt: str = "0.5"                # FSK Gaussian filter

    @classmethod
    def for_model(cls, model: P.ModuleModel) -> RadioSettings:
        return cls(freq_hz=model.default_freq_hz, pwr_dbm=model.default_pwr_dbm)

    @property
    def sync_word(self) -> int:
        return int(self.sync_hex, 16)

    def modulation(self) -> LoraModulation:
        return LoraModulation(sf=self.sf, bw_hz=self.bw_khz * 1000, cr=self.cr,
                              preamble_symbols=self.preamble_symbols, crc_on=self.crc_on)

    def air_interface(self) -> AirInterface:
        """What this modem sends with and listens for."""
        if self.mod == "lora":
            return AirInterface(self.freq_hz, self.modulation(), self.sync_word, self.iqi_on)
        return AirInterface(self.freq_hz, LoraModulation(preamble_symbols=self.preamble_symbols, crc_on=self.crc_on),
                            self.sync_word, False, fsk_bitrate_bps=self.bitrate_bps,
                            fsk_rx_bw_hz=round(float(self.rxbw_khz) * 1000), fsk_sync_bytes=len(self.sync_hex) // 2)

    def airtime_us(self, payload_bytes: int) -> int:
        return self.air_interface().airtime_us(payload_bytes)

    def symbol_time_us(self) -> int:
        if self.mod == "lora":
            return -(-(2**self.sf) * 1000 // self.bw_khz)
        return -(-8 * 1_000_000 // self.bitrate_bps)        # one byte time for FSK

    def get(self, name: str) -> str | None:
        """The `radio get <name>` answer for a stored setting; None if `name` is not one."""
        values = {
            "mod": self.mod, "freq": str(self.freq_hz), "pwr": str(self.pwr_dbm), "sf": f"sf{self.sf}",
            "bw": str(self.bw_khz), "cr": f"4/{4 + self.cr}", "crc": "on" if self.crc_on else "off",
            "iqi": "on" if self.iqi_on else "off", "sync": self.sync_hex, "prlen": str(self.preamble_symbols),
            "wdt": str(self.wdt_ms), "bitrate": str(self.bitrate_bps), "fdev": str(self.fdev_hz),
            "afcbw": self.afcbw_khz, "rxbw": self.rxbw_khz, "bt": self.bt,
        }
        return values.get(name)


def on_air_settings(profile: RadioProfile, sync_word: int = PRIVATE_SYNC_WORD,
                    model: P.ModuleModel | None = None) -> RadioSettings:
    """The network's operating point for `profile`, as the settings of the module that tunes
    it (the RN2483 in Europe, the RN2903 in the US band) after the driver configured it."""
    model = model or P.model_for_freq(profile.freq_hz)
    m = profile.modulation
    if m.implicit_header or m.low_data_rate_optimize is not None or m.sf not in P.SF_VALUES:
        raise ValueError(f"profile {profile.name!r}: modulation {m} cannot be set on an RN2483 or RN2903")
    if model is None or not model.tunes(profile.freq_hz):
        raise ValueError(f"profile {profile.name!r}: {profile.freq_hz} Hz is outside the bands of the "
                         f"RN2483 ({P.RN2483.bands_text()}) and the RN2903 ({P.RN2903.bands_text()})")
    return replace(RadioSettings.for_model(model), mod="lora", freq_hz=profile.freq_hz,
                   pwr_dbm=P.network_pwr_dbm(profile, model), sf=m.sf, bw_khz=m.bw_hz // 1000, cr=m.cr,
                   crc_on=m.crc_on, iqi_on=False, sync_hex=f"{sync_word:02X}",
                   preamble_symbols=m.preamble_symbols, wdt_ms=0)


class AirPort(Protocol):
    """The modem's handle on the shared Channel, bound to its node id."""

    def transmit(self, payload: bytes, now_us: int, air: AirInterface, tx_power_dbm: float) -> int | None: ...

    def set_listening(self, listening: bool, now_us: int, air: AirInterface) -> None: ...


def hweui_for(node_id: int) -> str:
    return f"{P.MICROCHIP_OUI}FF{node_id & 0xFFFFFFFF:08X}"


IDLE, TX, RX, CW, SLEEP, BOOTLOADER = "idle", "tx", "rx", "cw", "sleep", "bootloader"


class Rn2483:
    """One module. `command` answers a line, `deliver` takes a Channel event addressed to
    this node, `expire` fires the module's own timers (watchdog, rx window, sleep, self-timed tx).

    `network` is the network's operating point (for the ideal link's fiction, see the module
    docstring); `front_end_gain_db` is what the board adds to `radio set pwr` on the way to
    the antenna (an amplifier, antenna gain), so that a module set to the network's power
    radiates the profile's power."""

    def __init__(self, node_id: int, port: AirPort | None = None, network: RadioSettings | None = None,
                 *, model: P.ModuleModel = P.RN2483, ideal_link: bool = False, front_end_gain_db: float = 0.0):
        self.node_id = node_id
        self.model = model
        # The ideal link (Bayer & Faigl) hands every frame to every node, even one that is
        # sending or not listening; the modem prints it all the same, so the serial path
        # shows the firmware exactly what the in-process modem shows. A fiction, like the link.
        self._ideal_link = ideal_link
        self._port = port
        self._network_air = network.air_interface() if network is not None else None
        self.front_end_gain_db = front_end_gain_db
        self.nvm = bytearray([P.NVM_ERASED]) * (P.NVM_ADDRESS_RANGE[1] - P.NVM_ADDRESS_RANGE[0] + 1)
        self._air_busy_until_us = 0          # an on-air frame of ours a reset could not recall
        self._power_on()

    def _power_on(self) -> None:
        self.settings = RadioSettings.for_model(self.model)
        self.state = IDLE
        self.mac_paused = False
        self.last_snr_db = -128
        self.last_rssi_dbm = -128
        self.pin_modes = {name: "digin" for name in P.PIN_NAMES}
        self.pin_levels = {name: 0 for name in P.PIN_NAMES}
        self._deadline_us: int | None = None     # watchdog / window / sleep / self-timed tx end
        self._tx_on_air = False
        self._tx_failed = False                  # a watchdog-refused frame ends in radio_err
        self._listen_air: AirInterface | None = None

    # -- queries for the server ------------------------------------------------------
    @property
    def on_air(self) -> bool:
        """Whether the modem is on the network's operating point."""
        return self._network_air is not None and self.settings.air_interface() == self._network_air

    def next_deadline_us(self) -> int | None:
        return self._deadline_us

    # -- commands --------------------------------------------------------------------
    def command(self, line: str, now_us: int) -> list[str]:
        if self.state == BOOTLOADER or self.state == SLEEP:
            return []                # not listening to the command set (see module docstring)
        if len(line) > MAX_LINE_CHARS or not line.isascii():
            return [P.INVALID_PARAM]
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
        return [P.INVALID_PARAM]

    def _sys(self, w: list[str], now_us: int) -> list[str]:
        if w == ["reset"]:
            self._abort(now_us)
            self._power_on()
            return [self.model.version_line]
        if w == ["factoryRESET"]:
            self._abort(now_us)
            self.nvm[:] = bytes([P.NVM_ERASED]) * len(self.nvm)
            self._power_on()
            return [self.model.version_line]
        if w == ["eraseFW"]:
            self._abort(now_us)
            self.state = BOOTLOADER
            return []
        if len(w) == 2 and w[0] == "sleep":
            ms = _uint(w[1], P.SLEEP_RANGE_MS[1])
            if ms < P.SLEEP_RANGE_MS[0]:
                raise _Invalid
            self._abort(now_us)
            self.state = SLEEP
            self._deadline_us = now_us + ms * 1000
            return []                                    # `ok` when it wakes (expire)
        if len(w) >= 2 and w[0] == "get":
            return [self._sys_get(w[1:])]
        if len(w) >= 2 and w[0] == "set":
            self._sys_set(w[1:])
            return [P.OK]
        raise _Invalid

    def _sys_get(self, w: list[str]) -> str:
        if w == ["ver"]:
            return self.model.version_line
        if w == ["hweui"]:
            return hweui_for(self.node_id)
        if w == ["vdd"]:
            return str(P.VDD_MV)
        if len(w) == 2 and w[0] == "nvm":
            return f"{self.nvm[_nvm_index(w[1])]:02X}"
        if len(w) == 2 and w[0] == "pindig" and w[1] in P.PIN_NAMES:
            return str(self.pin_levels[w[1]] if self.pin_modes[w[1]] == "digout" else 0)
        if len(w) == 2 and w[0] == "pinana" and w[1] in P.ANALOG_PIN_NAMES:
            return "0"
        raise _Invalid

    def _sys_set(self, w: list[str]) -> None:
        if len(w) == 3 and w[0] == "nvm":
            index = _nvm_index(w[1])
            if not (_HEX.fullmatch(w[2]) and 1 <= len(w[2]) <= 2):
                raise _Invalid
            self.nvm[index] = int(w[2], 16)
            return
        if len(w) == 3 and w[0] == "pindig" and w[1] in P.PIN_NAMES and w[2] in ("0", "1"):
            self.pin_levels[w[1]] = int(w[2])
            return
        if len(w) == 3 and w[0] == "pinmode" and w[1] in P.PIN_NAMES and w[2] in P.PIN_MODES:
            if w[2] == "ana" and w[1] not in P.ANALOG_PIN_NAMES:
                raise _Invalid
            self.pin_modes[w[1]] = w[2]
            return
        raise _Invalid

    def _mac(self, w: list[str]) -> list[str]:
        if w == ["pause"]:
            self.mac_paused = True
            return [str(P.MAC_PAUSE_MS)]
        if w == ["resume"]:
            self.mac_paused = False
            return [P.OK]
        if w == ["get", "rxdelay1"]:
            return [str(P.MAC_RXDELAY1_MS)]
        if w == ["get", "rxdelay2"]:
            return [str(P.MAC_RXDELAY2_MS)]
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
                return [P.BUSY]
            self.settings = new
            return [P.OK]
        if verb == "tx":
            return self._tx(args, now_us)
        if verb == "rx" and len(args) == 1:
            return self._rx(args[0], now_us)
        if verb == "rxstop" and not args:
            if self.state == RX:
                self._end_rx(now_us)
            return [P.OK]
        if verb == "cw" and len(args) == 1 and args[0] in P.ON_OFF:
            if args[0] == "on":
                if self.state not in (IDLE, CW):
                    return [P.BUSY]
                self.state = CW
            elif self.state == CW:
                self.state = IDLE
            return [P.OK]
        raise _Invalid

    def _get(self, name: str) -> str:
        if name == "snr":
            return str(self.last_snr_db)
        if name == "rssi":
            return str(self.last_rssi_dbm)
        value = self.settings.get(name)
        if value is None:
            raise _Invalid
        return value

    def _parse_set(self, name: str, value: str) -> RadioSettings:
        s = self.settings
        if name == "mod" and value in P.MOD_VALUES:
            # One stored sync word; LoRa uses its last byte (the module's own behaviour on
            # switching is not documented).
            sync = s.sync_hex[-2:] if value == "lora" else s.sync_hex
            return replace(s, mod=value, sync_hex=sync)
        if name == "freq":
            f = _uint(value, 4_294_967_295)
            if self.model.tunes(f):
                return replace(s, freq_hz=f)
        if name == "pwr" and _INT.fullmatch(value) and len(value) <= 4 and int(value) in self.model.pwr_values_dbm:
            return replace(s, pwr_dbm=int(value))
        if name == "sf" and value in {f"sf{n}" for n in P.SF_VALUES}:
            return replace(s, sf=int(value[2:]))
        if name == "bw" and value in {str(b) for b in P.BW_KHZ_VALUES}:
            return replace(s, bw_khz=int(value))
        if name == "cr" and value in {f"4/{4 + c}" for c in P.CR_VALUES}:
            return replace(s, cr=int(value[2]) - 4)
        if name == "crc" and value in P.ON_OFF:
            return replace(s, crc_on=value == "on")
        if name == "iqi" and value in P.ON_OFF:
            return replace(s, iqi_on=value == "on")
        if name == "sync" and _HEX.fullmatch(value) and value:
            # LoRa takes one byte; FSK up to eight (whole bytes are kept: `7` is `07`).
            limit = P.LORA_SYNC_HEX_DIGITS if s.mod == "lora" else P.FSK_SYNC_MAX_HEX_DIGITS
            if len(value) <= limit:
                return replace(s, sync_hex=value.upper().zfill(len(value) + len(value) % 2))
        if name == "prlen":
            return replace(s, preamble_symbols=_uint(value, P.PRLEN_RANGE[1]))
        if name == "wdt":
            return replace(s, wdt_ms=_uint(value, P.WDT_RANGE_MS[1]))
        if name == "bitrate":
            bps = _uint(value, P.BITRATE_RANGE_BPS[1])
            if bps >= P.BITRATE_RANGE_BPS[0]:
                return replace(s, bitrate_bps=bps)
        if name == "fdev":
            return replace(s, fdev_hz=_uint(value, P.FDEV_RANGE_HZ[1]))
        if name == "afcbw" and value in P.FSK_BW_KHZ_VALUES:
            return replace(s, afcbw_khz=value)
        if name == "rxbw" and value in P.FSK_BW_KHZ_VALUES:
            return replace(s, rxbw_khz=value)
        if name == "bt" and value in P.BT_VALUES:
            return replace(s, bt=value)
        raise _Invalid

    def _tx(self, args: list[str], now_us: int) -> list[str]:
        # `radio tx ` with an empty field sends an empty frame, as does a bare `radio tx`.
        if len(args) > 1:
            raise _Invalid
        data = args[0] if args else ""
        limit = P.MAX_LORA_PAYLOAD_BYTES if self.settings.mod == "lora" else P.MAX_FSK_PAYLOAD_BYTES
        if not _HEX.fullmatch(data) or len(data) % 2 or len(data) // 2 > limit:
            raise _Invalid
        if self.state != IDLE:
            return [P.BUSY]
        payload = bytes.fromhex(data)
        air = self.settings.air_interface()
        airtime_us = air.airtime_us(len(payload))
        wdt_us = self.settings.wdt_ms * 1000
        if wdt_us and airtime_us > wdt_us:
            self._tx_on_air = False
            self._deadline_us = now_us + wdt_us
            self._tx_failed = True
        elif self._port is not None:
            end_us = self._port.transmit(payload, now_us, air, self.settings.pwr_dbm + self.front_end_gain_db)
            if end_us is None:
                # The Channel refuses: either our frame recalled by `sys reset` is still on the
                # air, or the frame exceeds what the profile allows on this channel.
                return [P.BUSY] if now_us < self._air_busy_until_us else [P.INVALID_PARAM]
            self._tx_on_air = True
            self._air_busy_until_us = end_us
            self._deadline_us = None
            self._tx_failed = False
        else:
            self._tx_on_air = False
            self._deadline_us = now_us + airtime_us
            self._tx_failed = False
        self.state = TX
        return [P.OK]

    def _rx(self, arg: str, now_us: int) -> list[str]:
        window_symbols = _uint(arg, P.RX_WINDOW_RANGE_SYMBOLS[1])
        if self.state != IDLE:
            return [P.BUSY]
        deadlines = []
        if window_symbols:
            deadlines.append(now_us + window_symbols * self.settings.symbol_time_us())
        if self.settings.wdt_ms:
            deadlines.append(now_us + self.settings.wdt_ms * 1000)
        self._deadline_us = min(deadlines) if deadlines else None
        self.state = RX
        if self._port is not None:
            self._listen_air = self.settings.air_interface()
            self._port.set_listening(True, now_us, self._listen_air)
        return [P.OK]

    # -- events and timers -----------------------------------------------------------
    def deliver(self, event: RadioRxFrame | RadioTxDone, now_us: int) -> list[str]:
        """A Channel event for this node (oldest first). Events the module no longer waits
        for (after `sys reset` or `radio rxstop`) are dropped, as the module would."""
        if isinstance(event, RadioTxDone):
            if self.state == TX and self._tx_on_air:
                self._finish()
                return [P.RADIO_TX_OK if event.ok else P.RADIO_ERR]
            return []
        if self.state == RX or (self._ideal_link and self.on_air and self.state in (IDLE, TX)):
            if self.state == RX:
                self._finish()
            lo, hi = P.SNR_RANGE_DB
            self.last_snr_db = max(lo, min(hi, round(event.snr_db)))
            self.last_rssi_dbm = round(event.rssi_dbm)
            return [P.RADIO_RX_PREFIX + event.payload.hex().upper()]
        return []

    def expire(self, now_us: int) -> list[str]:
        if self._deadline_us is None or now_us < self._deadline_us:
            return []
        if self.state == TX:
            failed = self._tx_failed
            self._finish()
            return [P.RADIO_ERR if failed else P.RADIO_TX_OK]
        if self.state == RX:
            self._end_rx(now_us)
            return [P.RADIO_ERR]
        if self.state == SLEEP:
            self._finish()
            return [P.OK]
        self._deadline_us = None
        return []

    # -- helpers ---------------------------------------------------------------------
    def _finish(self) -> None:
        self.state = IDLE
        self._deadline_us = None
        self._tx_on_air = False

    def _end_rx(self, now_us: int) -> None:
        if self._port is not None:
            self._port.set_listening(False, now_us, self._listen_air or self.settings.air_interface())
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


def _nvm_index(text: str) -> int:
    lo, hi = P.NVM_ADDRESS_RANGE
    if not (_HEX.fullmatch(text) and 1 <= len(text) <= 3) or not lo <= int(text, 16) <= hi:
        raise _Invalid
    return int(text, 16) - lo
