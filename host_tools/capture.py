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
"reception_fields"; fates are radio_sim.air_log.FATES. RSSI and SNR are rounded to 0.01 dB;
null where the receiver gave no number (a live modem's garbled answer). Unknown keys are
ignored, so later versions may add some. The JSON is strict (no NaN or Infinity), and a line
is at most MAX_LINE_BYTES long.

    grep '"sender_id": 3,' run.capture.jsonl | grep -c collided
"""
from __future__ import annotations

import json
import math
import os
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any, TextIO

from firmware.comms.schema import CRC_NAME, DialectSet, default_dialects
from host_tools.safe_io import strict_loads
from radio_sim.air_log import FATES, AirFrame, Reception

FORMAT_NAME = "lorascout-capture"
FORMAT_VERSION = 1
RECEPTION_FIELDS = ("receiver_id", "rssi_dbm", "snr_db", "fate")
# Longest line the reader takes: a 255-byte frame heard by 255 receivers is about 12 KiB.
MAX_LINE_BYTES = 1 << 20


class CaptureError(ValueError):
    """A capture file that cannot be read; the message names file, line and field."""


@dataclass(frozen=True)
class CaptureHeader:
    profile: str
    fingerprints: dict[str, int] | None    # dialect name -> fingerprint; None: not recorded
    crc: str | None
    meta: dict[str, Any] = field(default_factory=dict)
    version: int = FORMAT_VERSION


def _finite_or_none(x: float) -> float | None:
    return round(x, 2) if math.isfinite(x) else None


class CaptureWriter:
    """Append AirFrames to a capture file. Output is byte-identical for identical input.

    The frames go to a temporary file beside `path`, which close() renames into place (and
    abort() removes): a file already at `path` is replaced only by a finished capture."""

    def __init__(self, path: str | os.PathLike, profile_name: str, meta: dict[str, Any] | None = None,
                 dialects: DialectSet | None = None) -> None:
        """dialects: whose fingerprints the header records (default: every known dialect)."""
        dialects = dialects if dialects is not None else default_dialects()
        self.path = os.fspath(path)
        self.frames_written = 0
        folder = os.path.dirname(os.path.abspath(self.path))
        os.makedirs(folder, exist_ok=True)
        fd, self._tmp = tempfile.mkstemp(dir=folder, prefix=f".{os.path.basename(self.path)}.", suffix=".tmp")
        self._f: TextIO | None = os.fdopen(fd, "w", encoding="utf-8", newline="\n")
        header = {
            "format": FORMAT_NAME, "version": FORMAT_VERSION, "profile": profile_name,
            "fingerprints": {name: f"0x{fp:04X}" for name, fp in dialects.fingerprints().items()}, "crc": CRC_NAME,
            "reception_fields": list(RECEPTION_FIELDS), "meta": meta or {},
        }
        self._f.write(json.dumps(header, sort_keys=True, allow_nan=False) + "\n")

    def write(self, air_frame: AirFrame) -> None:
        if self._f is None:
            raise ValueError(f"{self.path}: capture already closed")
        a = air_frame
        row = {
            "start_us": a.start_us, "end_us": a.end_us, "sender_id": a.sender_id, "freq_hz": a.freq_hz,
            "sf": a.sf, "bw_hz": a.bw_hz, "payload": bytes(a.payload).hex(),
            "rx": [[r.receiver_id, _finite_or_none(r.rssi_dbm), _finite_or_none(r.snr_db), r.fate]
                   for r in a.receptions],
        }
        self._f.write(json.dumps(row, allow_nan=False) + "\n")
        self.frames_written += 1

    def close(self) -> None:
        """Finish the capture: it replaces whatever was at `path`."""
        if self._f is not None:
            self._f.flush()
            os.fsync(self._f.fileno())
            self._f.close()
            self._f = None
            mode = (os.stat(self.path).st_mode & 0o7777) if os.path.exists(self.path) else 0o644
            os.chmod(self._tmp, mode)
            os.replace(self._tmp, self.path)

    def abort(self) -> None:
        """Drop the capture: `path` stays as it was."""
        if self._f is not None:
            self._f.close()
            self._f = None
            try:
                os.unlink(self._tmp)
            except OSError:
                pass

    def __enter__(self) -> CaptureWriter:
        return self

    def __exit__(self, exc_type: object, *exc: object) -> None:
        if exc_type is None or exc_type is KeyboardInterrupt:
            self.close()
        else:
            self.abort()


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
    """A measured value: a finite number, or null for 'no number given' (NaN inside)."""
    if v is None:
        return math.nan
    if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
        raise _fail(path, line, fld, f"expected a finite number or null, got {v!r}")
    return float(v)


def _json(path: str, line: int, text: str, what: str) -> Any:
    try:
        return strict_loads(text)
    except json.JSONDecodeError as e:
        raise _fail(path, line, "", f"{what}not JSON ({e.msg} at column {e.colno})") from None
    except ValueError as e:          # NaN, Infinity
        raise _fail(path, line, "", f"{what}not strict JSON ({e})") from None
    except RecursionError:
        raise _fail(path, line, "", f"{what}nested too deeply") from None


def _parse_header(path: str, text: str) -> CaptureHeader:
    if not text.strip():
        raise _fail(path, 1, "", "empty file; expected a lorascout-capture header line")
    h = _json(path, 1, text, "header is ")
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
    row = _json(path, line, text, "")
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


def _lines(path: str, f) -> Iterator[tuple[int, str]]:
    """(line number, text) of a binary file, each line read with a bound and decoded on its
    own, so that an error names the exact line."""
    lineno = 0
    while True:
        data = f.readline(MAX_LINE_BYTES + 1)
        if not data:
            return
        lineno += 1
        if len(data) > MAX_LINE_BYTES:
            raise _fail(path, lineno, "", f"line longer than {MAX_LINE_BYTES} bytes; is this a lorascout capture?")
        try:
            yield lineno, data.decode("utf-8")
        except UnicodeDecodeError as e:
            raise _fail(path, lineno, "", f"not UTF-8 text (byte {e.start + 1} of the line)") from None


def read_capture_lines(path: str | os.PathLike) -> tuple[CaptureHeader, Iterator[tuple[int, AirFrame]]]:
    """The header (read now) and an iterator over (line number, frame), read lazily; a bad
    line raises CaptureError naming file, exact line and field when the iterator reaches it."""
    path = os.fspath(path)
    try:
        if os.path.isdir(path):
            raise CaptureError(f"{path}: cannot open: it is a folder")
        f = open(path, "rb")
    except OSError as e:
        raise CaptureError(f"{path}: cannot open: {e.strerror}") from None
    lines = _lines(path, f)
    try:
        header = _parse_header(path, next(lines, (1, ""))[1])
    except BaseException:
        f.close()
        raise

    def frames() -> Iterator[tuple[int, AirFrame]]:
        with f:
            for lineno, text in lines:
                if text.strip():
                    yield lineno, parse_frame_line(path, lineno, text)

    return header, frames()


def read_capture(path: str | os.PathLike) -> tuple[CaptureHeader, Iterator[AirFrame]]:
    """The header (read now) and an iterator over the frames (read lazily; a bad line raises
    CaptureError naming file, line and field when the iterator reaches it)."""
    header, it = read_capture_lines(path)
    return header, (a for _, a in it)
