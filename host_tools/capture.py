"""Radio captures: every frame the channel carried, one JSON line each, greppable.

Format (JSON Lines, UTF-8, one object per line):

line 1, the header:
    {"format": "lorascout-capture", "version": 1, "profile": "eu868-g3",
     "fingerprints": {"core": "0xD3DA", "bayer_faigl": "0x915F"}, "crc": "modbus",
     "reception_fields": ["receiver_id", "rssi_dbm", "snr_db", "fate"], "meta": {...}}
every further line, one transmission (radio_sim.air_log.AirFrame):
    {"start_us": 1200000, "end_us": 1241216, "sender_id": 3, "freq_hz": 869525000,
     "sf": 7, "bw_hz": 125000, "payload": "1101...hex...",
     "rx": [[1, -87.25, 6.5, "received"], [2, -131.0, -12.0, "out_of_range"]]}

"fingerprints" are those of every record dialect the writer knew (name -> CRC-16, see
firmware.comms.schema.Dialect), so a reader can tell which dialects' frames it will fail to
check. A capture from before dialects has one "schema_fingerprint" instead (frame format 1).
`sender_id` is the node that transmitted (a relay, for a relayed frame); the frame header
inside `payload` names the originator. `rx` has one row per other node, in the order of
"reception_fields"; fates are radio_sim.air_log.FATES. RSSI and SNR are rounded to 0.01 dB.
Unknown keys are ignored, so later versions may add some.

    grep '"sender_id": 3,' run.capture.jsonl | grep -c collided
"""
from __future__ import annotations

import json
import os
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any, TextIO

from firmware.comms.schema import CRC_NAME, DialectSet, default_dialects
from radio_sim.air_log import FATES, AirFrame, Reception

FORMAT_NAME = "lorascout-capture"
FORMAT_VERSION = 1
RECEPTION_FIELDS = ("receiver_id", "rssi_dbm", "snr_db", "fate")


class CaptureError(ValueError):
    """A capture file that cannot be read; the message names file, line and field."""


@dataclass(frozen=True)
class CaptureHeader:
    profile: str
    fingerprints: dict[str, int] | None    # dialect name -> fingerprint; None: not recorded
    crc: str | None
    meta: dict[str, Any] = field(default_factory=dict)
    version: int = FORMAT_VERSION


class CaptureWriter:
    """Append AirFrames to a capture file. Output is byte-identical for identical input."""

    def __init__(self, path: str | os.PathLike, profile_name: str, meta: dict[str, Any] | None = None,
                 dialects: DialectSet | None = None) -> None:
        """dialects: whose fingerprints the header records (default: every known dialect)."""
        dialects = dialects if dialects is not None else default_dialects()
        self.path = os.fspath(path)
        self.frames_written = 0
        self._f: TextIO | None = open(self.path, "w", encoding="utf-8", newline="\n")
        header = {
            "format": FORMAT_NAME, "version": FORMAT_VERSION, "profile": profile_name,
            "fingerprints": {name: f"0x{fp:04X}" for name, fp in dialects.fingerprints().items()}, "crc": CRC_NAME,
            "reception_fields": list(RECEPTION_FIELDS), "meta": meta or {},
        }
        self._f.write(json.dumps(header, sort_keys=True) + "\n")

    def write(self, air_frame: AirFrame) -> None:
        if self._f is None:
            raise ValueError(f"{self.path}: capture already closed")
        a = air_frame
        row = {
            "start_us": a.start_us, "end_us": a.end_us, "sender_id": a.sender_id, "freq_hz": a.freq_hz,
            "sf": a.sf, "bw_hz": a.bw_hz, "payload": bytes(a.payload).hex(),
            "rx": [[r.receiver_id, round(r.rssi_dbm, 2), round(r.snr_db, 2), r.fate] for r in a.receptions],
        }
        self._f.write(json.dumps(row) + "\n")
        self.frames_written += 1

    def close(self) -> None:
        if self._f is not None:
            self._f.close()
            self._f = None

    def __enter__(self) -> CaptureWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _fail(path: str, line: int, fld: str, problem: str) -> CaptureError:
    where = f"{path}:{line}"
    return CaptureError(f"{where}: field {fld!r}: {problem}" if fld else f"{where}: {problem}")


def _int(path: str, line: int, row: dict, key: str, lo: int | None = None, hi: int | None = None) -> int:
    if key not in row:
        raise _fail(path, line, key, "missing")
    v = row[key]
    if not isinstance(v, int) or isinstance(v, bool):
        raise _fail(path, line, key, f"expected an integer, got {v!r}")
    if (lo is not None and v < lo) or (hi is not None and v > hi):
        raise _fail(path, line, key, f"{v} outside [{lo}, {hi}]")
    return v


def _num(path: str, line: int, fld: str, v: Any) -> float:
    if not isinstance(v, (int, float)) or isinstance(v, bool):
        raise _fail(path, line, fld, f"expected a number, got {v!r}")
    return float(v)


def _parse_header(path: str, text: str) -> CaptureHeader:
    if not text.strip():
        raise _fail(path, 1, "", "empty file; expected a lorascout-capture header line")
    try:
        h = json.loads(text)
    except json.JSONDecodeError as e:
        raise _fail(path, 1, "", f"header is not JSON ({e.msg} at column {e.colno})") from None
    if not isinstance(h, dict) or h.get("format") != FORMAT_NAME:
        raise _fail(path, 1, "format", f"expected {FORMAT_NAME!r}; is this a lorascout capture?")
    if h.get("version") != FORMAT_VERSION:
        raise _fail(path, 1, "version", f"{h.get('version')!r}; this reader knows version {FORMAT_VERSION}")
    if not isinstance(h.get("profile"), str):
        raise _fail(path, 1, "profile", f"expected a profile name, got {h.get('profile')!r}")
    fingerprints = _fingerprints(path, h)
    if h.get("reception_fields", list(RECEPTION_FIELDS)) != list(RECEPTION_FIELDS):
        raise _fail(path, 1, "reception_fields", f"expected {list(RECEPTION_FIELDS)}")
    meta = h.get("meta", {})
    if not isinstance(meta, dict):
        raise _fail(path, 1, "meta", "expected an object")
    return CaptureHeader(h["profile"], fingerprints, h.get("crc"), meta)


# The name a frame-format-1 capture's single fingerprint is filed under: it names no dialect,
# so a reader sees that the capture's tables are not its own.
LEGACY_FINGERPRINT_NAME = "schema (frame format 1)"


def _hex16(path: str, fld: str, v: Any) -> int:
    try:
        out = int(v, 16)
    except (TypeError, ValueError):
        raise _fail(path, 1, fld, f"expected hex like '0x1A2B', got {v!r}") from None
    if not 0 <= out <= 0xFFFF:
        raise _fail(path, 1, fld, f"{v!r} is not a 16-bit value")
    return out


def _fingerprints(path: str, h: dict) -> dict[str, int] | None:
    if "fingerprints" in h:
        fps = h["fingerprints"]
        if not isinstance(fps, dict):
            raise _fail(path, 1, "fingerprints", "expected an object of dialect name -> hex fingerprint")
        return {str(name): _hex16(path, f"fingerprints.{name}", v) for name, v in fps.items()}
    if h.get("schema_fingerprint") is not None:
        return {LEGACY_FINGERPRINT_NAME: _hex16(path, "schema_fingerprint", h["schema_fingerprint"])}
    return None


def parse_frame_line(path: str, line: int, text: str) -> AirFrame:
    try:
        row = json.loads(text)
    except json.JSONDecodeError as e:
        raise _fail(path, line, "", f"not JSON ({e.msg} at column {e.colno})") from None
    if not isinstance(row, dict):
        raise _fail(path, line, "", f"expected an object, got {type(row).__name__}")
    start = _int(path, line, row, "start_us")
    end = _int(path, line, row, "end_us", lo=start)
    sender = _int(path, line, row, "sender_id", 0, 255)
    freq = _int(path, line, row, "freq_hz", 1)
    sf = _int(path, line, row, "sf", 6, 12)
    bw = _int(path, line, row, "bw_hz", 1)
    hexs = row.get("payload")
    if not isinstance(hexs, str):
        raise _fail(path, line, "payload", f"expected a hex string, got {hexs!r}")
    try:
        payload = bytes.fromhex(hexs)
    except ValueError:
        raise _fail(path, line, "payload", "not an even-length hex string") from None
    if len(payload) > 255:
        raise _fail(path, line, "payload", f"{len(payload)} bytes; LoRa carries at most 255")
    rx = row.get("rx", [])
    if not isinstance(rx, list):
        raise _fail(path, line, "rx", "expected a list of receptions")
    receptions = []
    for i, r in enumerate(rx):
        fld = f"rx[{i}]"
        if not isinstance(r, list) or len(r) != len(RECEPTION_FIELDS):
            raise _fail(path, line, fld, f"expected [{', '.join(RECEPTION_FIELDS)}], got {r!r}")
        rid, rssi, snr, fate = r
        if not isinstance(rid, int) or isinstance(rid, bool) or not 0 <= rid <= 255:
            raise _fail(path, line, f"{fld}.receiver_id", f"expected 0..255, got {rid!r}")
        if fate not in FATES:
            raise _fail(path, line, f"{fld}.fate", f"{fate!r} is not one of {', '.join(FATES)}")
        receptions.append(Reception(rid, _num(path, line, f"{fld}.rssi_dbm", rssi),
                                    _num(path, line, f"{fld}.snr_db", snr), fate))
    return AirFrame(start, end, sender, freq, sf, bw, payload, tuple(receptions))


def read_capture(path: str | os.PathLike) -> tuple[CaptureHeader, Iterator[AirFrame]]:
    """The header (read now) and an iterator over the frames (read lazily; a bad line raises
    CaptureError naming file, line and field when the iterator reaches it)."""
    path = os.fspath(path)
    try:
        f = open(path, encoding="utf-8")
    except OSError as e:
        raise CaptureError(f"{path}: cannot open: {e.strerror}") from None
    try:
        header = _parse_header(path, f.readline())
    except UnicodeDecodeError:
        f.close()
        raise _fail(path, 1, "", "not UTF-8 text; is this a lorascout capture?") from None
    except BaseException:
        f.close()
        raise

    def frames() -> Iterator[AirFrame]:
        lineno = 1
        with f:
            try:
                for lineno, text in enumerate(f, start=2):
                    if text.strip():
                        yield parse_frame_line(path, lineno, text)
            except UnicodeDecodeError:
                raise _fail(path, lineno + 1, "", "not UTF-8 text") from None

    return header, frames()
