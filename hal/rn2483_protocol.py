"""The Microchip RN2483 / RN2903 serial command set, in one place: commands, replies, value
ranges and power-on defaults. The driver (hal.rn2483), the emulator (radio_sim.rn2483) and
the packet inspector (host_tools.cmd_inspect, through the driver) all take them from here.

Source: Microchip "RN2483 LoRa Technology Module Command Reference User's Guide"
(DS40001784) and its RN2903 twin (DS40001811), firmware 1.0.5. The two modules speak the same
language; they differ in their version line, the frequencies they tune and the transmit
powers they offer. Lines are ASCII ending in CR LF, 57600 8N1.

Every command gets exactly one immediate answer line (`ok`, `invalid_param`, `busy`, or a
value), except `sys sleep` (its `ok` comes when the module wakes) and `sys eraseFW` (no
answer: the module drops into its bootloader). `radio tx` and `radio rx` print a second,
asynchronous line later (`radio_tx_ok`, `radio_rx  <HEX>`, `radio_err`).
"""
from __future__ import annotations

from dataclasses import dataclass

from hal.lora import PRIVATE_SYNC_WORD, RadioProfile

BAUDRATE = 57600
EOL = "\r\n"

# -- answers ----------------------------------------------------------------------------
OK = "ok"
INVALID_PARAM = "invalid_param"
BUSY = "busy"
RADIO_TX_OK = "radio_tx_ok"
RADIO_ERR = "radio_err"
RADIO_RX_PREFIX = "radio_rx  "          # two spaces, upper-case hex after it

# -- commands the project sends -----------------------------------------------------------
SYS_RESET = "sys reset"
SYS_GET_VER = "sys get ver"
SYS_GET_HWEUI = "sys get hweui"
MAC_PAUSE = "mac pause"
MAC_RESUME = "mac resume"
RADIO_RX_CONTINUOUS = "radio rx 0"
RADIO_RXSTOP = "radio rxstop"
RADIO_GET_RSSI = "radio get rssi"
RADIO_GET_SNR = "radio get snr"

MAC_PAUSE_MS = 4294967245               # what `mac pause` answers: the longest pause
MAC_RXDELAY1_MS = 1000                  # LoRaWAN defaults the stack reports
MAC_RXDELAY2_MS = 2000
MICROCHIP_OUI = "0004A3"                # first three bytes of every module's hweui
VDD_MV = 3300

# -- values `radio set` takes --------------------------------------------------------------
MAX_LORA_PAYLOAD_BYTES = 255
MAX_FSK_PAYLOAD_BYTES = 64
SF_VALUES = tuple(range(7, 13))                       # `sf7` .. `sf12`
BW_KHZ_VALUES = (125, 250, 500)
CR_VALUES = (1, 2, 3, 4)                              # `4/5` .. `4/8`
MOD_VALUES = ("lora", "fsk")
ON_OFF = ("on", "off")
BT_VALUES = ("none", "1.0", "0.5", "0.3")             # FSK Gaussian filter BT
# FSK receive and AFC bandwidths in kHz, spelt exactly as the module accepts and prints them.
FSK_BW_KHZ_VALUES = ("250", "125", "62.5", "31.3", "15.6", "7.8", "3.9", "200", "100", "50", "25",
                     "12.5", "6.3", "3.1", "166.7", "83.3", "41.7", "20.8", "10.4", "5.2", "2.6")
BITRATE_RANGE_BPS = (1, 300_000)
FDEV_RANGE_HZ = (0, 200_000)
PRLEN_RANGE = (0, 65_535)
WDT_RANGE_MS = (0, 4_294_967_295)                     # 0 = watchdog off
RX_WINDOW_RANGE_SYMBOLS = (0, 65_535)                 # `radio rx 0` = continuous
LORA_SYNC_HEX_DIGITS = 2                              # one byte
FSK_SYNC_MAX_HEX_DIGITS = 16                          # up to eight bytes
SNR_RANGE_DB = (-128, 127)

# -- values `sys` takes --------------------------------------------------------------------
SLEEP_RANGE_MS = (100, 4_294_967_296)
NVM_ADDRESS_RANGE = (0x300, 0x3FF)                    # user EEPROM
NVM_ERASED = 0xFF
PIN_NAMES = tuple(f"GPIO{i}" for i in range(14)) + ("UART_CTS", "UART_RTS", "TEST0", "TEST1")
ANALOG_PIN_NAMES = tuple(f"GPIO{i}" for i in (0, 1, 2, 3, 5, 6, 7, 8, 9, 10, 11, 12, 13))
PIN_MODES = ("digout", "digin", "ana")
ADC_MAX = 1023

# Power-on `radio get` answers shared by both modules (freq and pwr differ, see ModuleModel).
RADIO_DEFAULTS = {
    "mod": "lora", "sf": "sf12", "bw": "125", "cr": "4/5", "crc": "on", "iqi": "off", "sync": "34",
    "prlen": "8", "wdt": "15000", "bitrate": "50000", "fdev": "25000", "afcbw": "41.7", "rxbw": "25",
    "bt": "0.5",
}


@dataclass(frozen=True)
class ModuleModel:
    """What tells the RN2483 and the RN2903 apart."""

    name: str
    version_line: str                                  # `sys get ver`, `sys reset`
    freq_bands_hz: tuple[tuple[int, int], ...]         # `radio set freq` ranges, inclusive
    default_freq_hz: int
    pwr_values_dbm: tuple[int, ...]                    # what `radio set pwr` accepts
    default_pwr_dbm: int

    def tunes(self, freq_hz: int) -> bool:
        return any(lo <= freq_hz <= hi for lo, hi in self.freq_bands_hz)

    def bands_text(self) -> str:
        return ", ".join(f"{lo / 1e6:g}-{hi / 1e6:g} MHz" for lo, hi in self.freq_bands_hz)


RN2483 = ModuleModel("RN2483", "RN2483 1.0.5 Oct 31 2018 15:06:52",
                     ((433_050_000, 434_790_000), (863_000_000, 870_000_000)), 868_100_000,
                     tuple(range(-3, 16)), 1)
# RN2903: US 902-928 MHz; its PA offers these steps only (13, 18 and 19 dBm are refused).
RN2903 = ModuleModel("RN2903", "RN2903 1.0.5 Nov 06 2018 10:45:27",
                     ((902_000_000, 928_000_000),), 923_300_000,
                     (2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 14, 15, 16, 17, 20), 2)
MODELS = {m.name: m for m in (RN2483, RN2903)}


def model_for_freq(freq_hz: int) -> ModuleModel | None:
    """The module that tunes `freq_hz`, or None."""
    for m in MODELS.values():
        if m.tunes(freq_hz):
            return m
    return None


def model_of_version(line: str) -> ModuleModel | None:
    """The module a version line names (`RN2483 1.0.5 ...`), or None."""
    for m in MODELS.values():
        if line.startswith(m.name + " "):
            return m
    return None


def network_pwr_dbm(profile: RadioProfile, model: ModuleModel) -> int:
    """The `radio set pwr` value for a profile: the highest the module offers that does not
    exceed the profile's power (a board may add an amplifier or antenna gain on top)."""
    allowed = [p for p in model.pwr_values_dbm if p <= profile.tx_power_dbm]
    return max(allowed) if allowed else min(model.pwr_values_dbm)


def network_config_commands(profile: RadioProfile, model: ModuleModel,
                            sync_word: int = PRIVATE_SYNC_WORD) -> list[str]:
    """The `radio set` lines that put a module on the network's operating point."""
    m = profile.modulation
    if m.implicit_header or not m.sf in SF_VALUES:
        raise ValueError(f"profile {profile.name!r} cannot be configured on an {model.name} "
                         f"(sf={m.sf}, implicit_header={m.implicit_header})")
    if not model.tunes(profile.freq_hz):
        raise ValueError(f"profile {profile.name!r}: {profile.freq_hz} Hz is outside the {model.name}'s "
                         f"bands ({model.bands_text()})")
    return [
        "radio set mod lora",
        f"radio set freq {profile.freq_hz}",
        f"radio set sf sf{m.sf}",
        f"radio set bw {m.bw_hz // 1000}",
        f"radio set cr 4/{4 + m.cr}",
        f"radio set pwr {network_pwr_dbm(profile, model)}",
        f"radio set crc {'on' if m.crc_on else 'off'}",
        "radio set iqi off",
        f"radio set sync {sync_word:02X}",
        f"radio set prlen {m.preamble_symbols}",
        "radio set wdt 0",
    ]


def radio_tx(payload: bytes) -> str:
    return "radio tx " + payload.hex().upper()


def is_async_line(line: str) -> bool:
    """True for the lines the module prints on its own (not as an answer to a command)."""
    return line.startswith(RADIO_RX_PREFIX.rstrip() + " ") or line in (RADIO_TX_OK, RADIO_ERR)


def parse_rx_line(line: str) -> bytes | None:
    """The payload of a `radio_rx  <HEX>` line; None if the line is not a well-formed one.
    Never raises."""
    head = RADIO_RX_PREFIX.rstrip()
    if not line.startswith(head + " "):
        return None
    text = line[len(head):].strip()
    if len(text) % 2 or not all(c in "0123456789abcdefABCDEF" for c in text):
        return None
    return bytes.fromhex(text)
