"""pcap files with LINKTYPE_LORATAP (270) and LoRaTap version-0 headers, for Wireshark.

LoRaTap v0 header, 15 bytes, big-endian:
    version u8 (0), padding u8, length u16 (15), frequency u32 Hz, bandwidth u8 (125 kHz
    steps), sf u8, packet rssi u8 (dBm = value - 139), max rssi u8, current rssi u8,
    snr u8 (two's complement, quarter dB), sync word u8.
We write the packet RSSI into both "packet" and "max", and "current" as the same value (we do
not model the RSSI sampled outside the packet). Out-of-range RSSI/SNR saturate.

Wireshark's LoRaTap dissector passes the payload to the `loratap.syncword` table; our Lua
dissector (host_tools/dissector/lorascout.lua) registers there for sync word 0x12.

Two ways to turn the air log into packets (`write_pcap(mode=...)`):
- "per-frame" (default): one packet per transmission, what a sniffer next to every robot
  would log, with the best RSSI/SNR over the receivers (any fate); -139 dBm if nobody was
  in range.
- "per-receiver": one packet per (transmission, receiver that got it: fate "received"), with
  that receiver's RSSI/SNR, in time order then receiver id. LoRaTap v0 has no receiver field,
  so Wireshark cannot tell which robot heard it; use the JSON inspector for that.
Timestamps are mission time (start of the transmission) from the Unix epoch.
"""
from __future__ import annotations

import math
import os
import struct
from collections.abc import Iterable
from typing import BinaryIO

from radio_sim.air_log import RECEIVED, AirFrame

LINKTYPE_LORATAP = 270
PCAP_MAGIC_US = 0xA1B2C3D4
LORATAP_HEADER_BYTES = 15
SYNC_WORD = 0x12
RSSI_OFFSET_DB = 139
MODES = ("per-frame", "per-receiver")

_GLOBAL = struct.Struct("<IHHiIII")
_RECORD = struct.Struct("<IIII")
_LORATAP = struct.Struct(">BBHIBBBBBBB")
assert _LORATAP.size == LORATAP_HEADER_BYTES


MAX_TIMESTAMP_US = (1 << 32) * 1_000_000 - 1     # pcap seconds are 32 bits


def _rssi_code(rssi_dbm: float) -> int:
    """Saturating; an RSSI the receiver did not give (NaN) is written as the floor, -139 dBm."""
    return max(0, min(255, round(rssi_dbm + RSSI_OFFSET_DB))) if math.isfinite(rssi_dbm) else 0


def _snr_code(snr_db: float) -> int:
    return (max(-128, min(127, round(snr_db * 4))) & 0xFF) if math.isfinite(snr_db) else 0


def check_frame(start_us: int, freq_hz: int, bw_hz: int, sf: int) -> None:
    """ValueError naming the field unless a frame fits a pcap record and a LoRaTap v0 header."""
    if not 0 <= start_us <= MAX_TIMESTAMP_US:
        raise ValueError(f"field 'start_us': {start_us} us is outside what pcap holds (0..{MAX_TIMESTAMP_US})")
    if not 0 <= freq_hz <= 0xFFFFFFFF:
        raise ValueError(f"field 'freq_hz': {freq_hz} Hz does not fit LoRaTap's 32 bits")
    if bw_hz % 125_000 or not 0 < bw_hz // 125_000 <= 255:
        raise ValueError(f"field 'bw_hz': bandwidth {bw_hz} Hz is not a multiple of 125 kHz (LoRaTap v0)")
    if not 0 <= sf <= 255:
        raise ValueError(f"field 'sf': {sf} does not fit a byte")


def loratap_header(freq_hz: int, bw_hz: int, sf: int, rssi_dbm: float, snr_db: float,
                   sync_word: int = SYNC_WORD) -> bytes:
    if bw_hz % 125_000 or not 0 < bw_hz // 125_000 <= 255:
        raise ValueError(f"bandwidth {bw_hz} Hz is not a multiple of 125 kHz")
    rssi = _rssi_code(rssi_dbm)
    return _LORATAP.pack(0, 0, LORATAP_HEADER_BYTES, freq_hz, bw_hz // 125_000, sf, rssi, rssi, rssi,
                         _snr_code(snr_db), sync_word)


def parse_loratap_header(data: bytes) -> dict[str, float | int]:
    """Inverse of loratap_header (to the codes' resolution), for tests and tools."""
    if len(data) < LORATAP_HEADER_BYTES:
        raise ValueError(f"LoRaTap header needs {LORATAP_HEADER_BYTES} bytes, got {len(data)}")
    v, _pad, length, freq, bw, sf, rssi, max_rssi, cur_rssi, snr, sync = _LORATAP.unpack_from(data)
    if v != 0 or length != LORATAP_HEADER_BYTES:
        raise ValueError(f"not a LoRaTap v0 header (version {v}, length {length})")
    return {"freq_hz": freq, "bw_hz": bw * 125_000, "sf": sf, "rssi_dbm": rssi - RSSI_OFFSET_DB,
            "max_rssi_dbm": max_rssi - RSSI_OFFSET_DB, "current_rssi_dbm": cur_rssi - RSSI_OFFSET_DB,
            "snr_db": (snr - 256 if snr > 127 else snr) / 4, "sync_word": sync}


class PcapWriter:
    """Classic pcap (microsecond timestamps, little-endian), LINKTYPE_LORATAP."""

    def __init__(self, out: str | os.PathLike | BinaryIO, snaplen: int = 65535) -> None:
        self._own = not hasattr(out, "write")
        self._f: BinaryIO = open(os.fspath(out), "wb") if self._own else out  # type: ignore[arg-type]
        self._f.write(_GLOBAL.pack(PCAP_MAGIC_US, 2, 4, 0, 0, snaplen, LINKTYPE_LORATAP))
        self.packets = 0

    def write(self, ts_us: int, packet: bytes) -> None:
        if ts_us < 0:
            raise ValueError(f"pcap timestamps cannot be negative: {ts_us} us")
        sec, usec = divmod(ts_us, 1_000_000)
        self._f.write(_RECORD.pack(sec, usec, len(packet), len(packet)) + packet)
        self.packets += 1

    def close(self) -> None:
        if self._own:
            self._f.close()

    def __enter__(self) -> PcapWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def air_frame_packets(frames: Iterable[AirFrame], mode: str = "per-frame") -> Iterable[tuple[int, bytes]]:
    """(timestamp us, LoRaTap header + payload) for each packet `mode` makes of the frames."""
    if mode not in MODES:
        raise ValueError(f"pcap mode {mode!r}; choose one of {', '.join(MODES)}")
    return _packets(frames, mode)


def _packets(frames: Iterable[AirFrame], mode: str) -> Iterable[tuple[int, bytes]]:
    for a in frames:
        if mode == "per-frame":
            best = max(a.receptions, key=lambda r: (r.rssi_dbm if math.isfinite(r.rssi_dbm) else -math.inf,
                                                    -r.receiver_id), default=None)
            rssi, snr = (best.rssi_dbm, best.snr_db) if best else (-float(RSSI_OFFSET_DB), 0.0)
            yield a.start_us, loratap_header(a.freq_hz, a.bw_hz, a.sf, rssi, snr) + a.payload
        else:
            for r in sorted(a.receptions, key=lambda r: r.receiver_id):
                if r.fate == RECEIVED:
                    yield a.start_us, loratap_header(a.freq_hz, a.bw_hz, a.sf, r.rssi_dbm, r.snr_db) + a.payload


def write_pcap(out: str | os.PathLike | BinaryIO, frames: Iterable[AirFrame], mode: str = "per-frame") -> int:
    """Write the frames as a LoRaTap pcap; returns the number of packets. Every packet is
    made before the file is touched, and a path is written atomically: a frame pcap cannot
    carry leaves a file already there as it was."""
    packets = list(air_frame_packets(frames, mode))
    for ts, _ in packets:
        if not 0 <= ts <= MAX_TIMESTAMP_US:
            raise ValueError(f"pcap timestamps must lie in 0..{MAX_TIMESTAMP_US} us, got {ts}")
    if hasattr(out, "write"):
        return _write_packets(out, packets)   # type: ignore[arg-type]
    from host_tools.safe_io import atomic_open

    with atomic_open(out, "wb") as f:
        return _write_packets(f, packets)


def _write_packets(f: BinaryIO, packets: list[tuple[int, bytes]]) -> int:
    with PcapWriter(f) as w:
        for ts, pkt in packets:
            w.write(ts, pkt)
        return w.packets


def read_pcap(path: str | os.PathLike) -> tuple[int, list[tuple[int, bytes]]]:
    """(link type, [(timestamp us, packet bytes)]) of a classic microsecond pcap."""
    path = os.fspath(path)
    with open(path, "rb") as f:
        data = f.read()
    if len(data) < _GLOBAL.size:
        raise ValueError(f"{path}: {len(data)} bytes, too short for a pcap header")
    magic, _vmaj, _vmin, _tz, _sig, _snap, linktype = _GLOBAL.unpack_from(data)
    if magic != PCAP_MAGIC_US:
        raise ValueError(f"{path}: magic 0x{magic:08X}; expected a little-endian microsecond pcap")
    pos, out = _GLOBAL.size, []
    while pos < len(data):
        if pos + _RECORD.size > len(data):
            raise ValueError(f"{path}: truncated record header at byte {pos}")
        sec, usec, incl, _orig = _RECORD.unpack_from(data, pos)
        pos += _RECORD.size
        if pos + incl > len(data):
            raise ValueError(f"{path}: truncated packet at byte {pos}")
        out.append((sec * 1_000_000 + usec, data[pos:pos + incl]))
        pos += incl
    return linktype, out
