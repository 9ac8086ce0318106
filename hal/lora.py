"""LoRa physical-layer facts shared by the firmware (duty-cycle budget), the radio world
(channel timing) and the modem emulator: modulation settings, time on air, and the named
regional profiles. One source of truth for each number.

Time on air follows the Semtech SX127x datasheet (4.1.1.6) and AN1200.13.
"""
from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from math import ceil

# DESIGN.md: the network uses a private LoRa sync word, not LoRaWAN's public 0x34, so robots
# do not decode (or get woken by) LoRaWAN traffic on the same channel.
PRIVATE_SYNC_WORD = 0x12


@dataclass(frozen=True)
class LoraModulation:
    sf: int = 7                  # spreading factor 7..12
    bw_hz: int = 125_000         # 125 000, 250 000 or 500 000
    cr: int = 1                  # coding rate 4/(4+cr), cr = 1..4
    preamble_symbols: int = 8
    crc_on: bool = True
    implicit_header: bool = False
    # Low data rate optimisation: None means "as the modem does": on when T_sym >= 16 ms.
    low_data_rate_optimize: bool | None = None

    def __post_init__(self) -> None:
        if not 6 <= self.sf <= 12:
            raise ValueError(f"sf must be 6..12, got {self.sf}")
        if self.bw_hz not in (125_000, 250_000, 500_000):
            raise ValueError(f"bw_hz must be 125000, 250000 or 500000, got {self.bw_hz}")
        if not 1 <= self.cr <= 4:
            raise ValueError(f"cr must be 1..4 (4/5..4/8), got {self.cr}")

    @property
    def symbol_time_us(self) -> Fraction:
        return Fraction(2**self.sf * 1_000_000, self.bw_hz)

    @property
    def ldro(self) -> bool:
        if self.low_data_rate_optimize is not None:
            return self.low_data_rate_optimize
        return self.symbol_time_us >= 16_000


def payload_symbols(payload_bytes: int, mod: LoraModulation) -> int:
    de = 1 if mod.ldro else 0
    numerator = 8 * payload_bytes - 4 * mod.sf + 28 + 16 * int(mod.crc_on) - 20 * int(mod.implicit_header)
    blocks = max(ceil(Fraction(numerator, 4 * (mod.sf - 2 * de))), 0)
    return 8 + blocks * (mod.cr + 4)


def time_on_air_us(payload_bytes: int, mod: LoraModulation) -> int:
    """Exact LoRa time on air of one frame, rounded to the nearest microsecond."""
    if payload_bytes < 0:
        raise ValueError("payload_bytes must be >= 0")
    preamble = (mod.preamble_symbols + Fraction(17, 4)) * mod.symbol_time_us
    payload = payload_symbols(payload_bytes, mod) * mod.symbol_time_us
    return round(preamble + payload)


@dataclass(frozen=True)
class AirInterface:
    """What one transmitter sends with, or one receiver listens for: the settings that decide
    who hears whom on a shared channel.

    A receiver decodes a frame when their `reception_key`s are equal: same modulation, centre
    frequency, and for LoRa the same SF, bandwidth, sync word and IQ polarity. Coding rate and
    CRC presence are not in the key: with the explicit header (the only mode the RN2483
    offers) they travel in the frame's header and a receiver follows them, as real modules
    do. Frames whose `interference_key`s are equal overlap in frequency and chirp rate and so
    can collide, whatever their sync words (spreading factors are taken as orthogonal, as in
    LoRaSim). FSK (`fsk_bitrate_bps` set) keys on frequency, bit rate and sync word.
    """

    freq_hz: int
    modulation: LoraModulation = LoraModulation()
    sync_word: int = PRIVATE_SYNC_WORD
    iq_inverted: bool = False
    fsk_bitrate_bps: int | None = None     # None: LoRa
    fsk_rx_bw_hz: int = 25_000             # FSK receiver bandwidth (noise bandwidth)
    fsk_sync_bytes: int = 1                # FSK sync word length on the air

    @property
    def is_lora(self) -> bool:
        return self.fsk_bitrate_bps is None

    def reception_key(self) -> tuple:
        if self.is_lora:
            m = self.modulation
            return ("lora", self.freq_hz, m.sf, m.bw_hz, self.sync_word, self.iq_inverted)
        return ("fsk", self.freq_hz, self.fsk_bitrate_bps, self.sync_word, self.fsk_sync_bytes)

    def interference_key(self) -> tuple:
        if self.is_lora:
            return ("lora", self.freq_hz, self.modulation.sf, self.modulation.bw_hz)
        return ("fsk", self.freq_hz)

    @property
    def noise_bw_hz(self) -> int:
        return self.modulation.bw_hz if self.is_lora else self.fsk_rx_bw_hz

    def airtime_us(self, payload_bytes: int) -> int:
        if self.is_lora:
            return time_on_air_us(payload_bytes, self.modulation)
        # FSK packet (SX127x packet mode, variable length): preamble bytes, sync word, length
        # byte, payload, CRC-16 when on.
        m = self.modulation
        frame_bytes = m.preamble_symbols + self.fsk_sync_bytes + 1 + payload_bytes + (2 if m.crc_on else 0)
        return -(-frame_bytes * 8 * 1_000_000 // self.fsk_bitrate_bps)

    def preamble_grace_us(self, symbols_needed: int) -> Fraction:
        """How much of the start of a frame an earlier frame may overlap and the frame still
        be caught: LoRa receivers lock on the last `symbols_needed` preamble symbols."""
        if not self.is_lora:
            return Fraction(0)
        return max(self.modulation.preamble_symbols - symbols_needed, 0) * self.modulation.symbol_time_us


@dataclass(frozen=True)
class RadioProfile:
    """A named operating point: where on the band, how fast, and what the law allows."""

    name: str
    freq_hz: int
    sub_band: str
    duty_cycle: float | None       # fraction of any one hour a node may transmit; None = no limit
    modulation: LoraModulation
    max_payload_bytes: int
    tx_power_dbm: float
    byte_rate_cap_Bps: float | None = None   # optional link-layer cap (Bayer & Faigl's 100 B/s)
    # Ideal link (Bayer & Faigl's model): every frame reaches every robot, no loss, no
    # collisions, unlimited range; a frame occupies the sender for bytes / byte_rate_cap_Bps.
    ideal: bool = False
    duty_cycle_window_us: int = 3_600_000_000  # ETSI: transmit time over one hour

    def airtime_us(self, payload_bytes: int) -> int:
        if self.ideal:
            assert self.byte_rate_cap_Bps is not None
            return round(payload_bytes * 1_000_000 / self.byte_rate_cap_Bps)
        return time_on_air_us(payload_bytes, self.modulation)

    def air_interface(self, sync_word: int = PRIVATE_SYNC_WORD) -> AirInterface:
        """The network's operating point on this profile."""
        return AirInterface(self.freq_hz, self.modulation, sync_word, False)


PROFILES: dict[str, RadioProfile] = {
    p.name: p
    for p in (
        RadioProfile("eu868-g1", 868_100_000, "g1", 0.01, LoraModulation(7, 125_000), 255, 14.0),
        RadioProfile("eu868-g3", 869_525_000, "g3", 0.10, LoraModulation(7, 125_000), 255, 27.0),
        RadioProfile("eu868-g3-bw250", 869_525_000, "g3", 0.10, LoraModulation(7, 250_000), 255, 27.0),
        # 242 B keeps SF7/BW125 frames under the FCC 400 ms dwell time.
        RadioProfile("us915", 915_000_000, "us915", None, LoraModulation(7, 125_000), 242, 20.0),
        RadioProfile(
            "ideal-100Bps", 869_525_000, "ideal", None, LoraModulation(7, 125_000), 255, 14.0,
            byte_rate_cap_Bps=100.0, ideal=True,
        ),
    )
}


def profile(name: str) -> RadioProfile:
    try:
        return PROFILES[name]
    except KeyError:
        raise KeyError(f"unknown radio profile {name!r}; known: {', '.join(PROFILES)}") from None
