"""Pack and unpack single records by their schema table row.

A record type is given as its RecordType or by name (looked up in every known dialect,
schema.record_type).

Encoding is for our own data, so a value out of range is a programming error: ValueError
naming the record, field and range. Decoding is for bytes from the air, so it never raises:
it returns a reason the link layer counts.
"""
from __future__ import annotations

import dataclasses
import enum
from collections.abc import Mapping
from typing import Any, NamedTuple

from firmware.comms.schema import RecordType, record_type


class Reason(enum.StrEnum):
    """Why a frame was accepted or rejected; the complete, fixed set."""

    OK = "ok"
    TRUNCATED = "truncated"              # fewer bytes than the header says
    BAD_CRC = "bad_crc"                  # CRC mismatch (corruption, or a peer with another schema)
    UNKNOWN_VERSION = "unknown_version"  # version nibble is not ours
    UNKNOWN_DIALECT = "unknown_dialect"  # the header's dialect id is in no dialect we know
    UNKNOWN_TYPE = "unknown_type"        # frame type, or record code not in its dialect
    BAD_LENGTH = "bad_length"            # trailing bytes, or groups that do not fill the payload
    OUT_OF_RANGE = "out_of_range"        # a field outside its valid range, or non-zero padding


REASONS: tuple[Reason, ...] = tuple(Reason)


class RecordDecode(NamedTuple):
    values: dict[str, int] | None
    reason: Reason
    detail: str = ""


# Per type: (field, shift from the record's least significant bit, mask, valid min, max).
# Keyed by the RecordType object (kept in the entry so its id is never reused), not its name:
# two dialect sets may hold different tables under one name (an older peer's, in tests).
_LAYOUT: dict[int, tuple[RecordType, tuple[tuple[str, int, int, bool, int, int], ...]]] = {}


def _layout(rt: RecordType) -> tuple[tuple[str, int, int, bool, int, int], ...]:
    cached = _LAYOUT.get(id(rt))
    if cached is None or cached[0] is not rt:
        total = 8 * rt.size_bytes
        cached = _LAYOUT[id(rt)] = (rt, tuple(
            (f.name, total - off - f.bits, (1 << f.bits) - 1, f.signed, f.min_value, f.max_value)
            for f, off in rt.field_offsets()
        ))
    return cached[1]


def as_values(rt: RecordType, values: Mapping[str, Any] | Any) -> Mapping[str, Any]:
    if dataclasses.is_dataclass(values) and not isinstance(values, type):
        values = {f.name: getattr(values, f.name) for f in dataclasses.fields(values)}
    if not isinstance(values, Mapping):
        raise TypeError(f"{rt.name}: values must be a mapping or a {rt.name} record dataclass, "
                        f"got {type(values).__name__}")
    expected = [f.name for f in rt.fields]
    missing = [n for n in expected if n not in values]
    extra = [n for n in values if n not in expected]
    if missing or extra:
        raise ValueError(f"{rt.name}: missing fields {missing}, unknown fields {extra}")
    return values


def encode(rtype: str | RecordType, values: Mapping[str, Any] | Any) -> bytes:
    """Values (dict or the generated dataclass) -> exactly rt.size_bytes bytes."""
    rt = record_type(rtype)
    values = as_values(rt, values)
    word = 0
    for name, shift, mask, _signed, lo, hi in _layout(rt):
        v = values[name]
        if isinstance(v, bool):
            v = int(v)
        if not isinstance(v, int):
            raise ValueError(f"{rt.name}.{name}: expected an integer, got {v!r}")
        if not lo <= v <= hi:
            raise ValueError(f"{rt.name}.{name} = {v} outside valid range [{lo}, {hi}]")
        word |= (v & mask) << shift
    return word.to_bytes(rt.size_bytes, "big")


def decode(rtype: str | RecordType, data: bytes) -> RecordDecode:
    """Bytes -> field values, or a reason. Never raises for any bytes."""
    rt = record_type(rtype)
    if len(data) != rt.size_bytes:
        reason = Reason.TRUNCATED if len(data) < rt.size_bytes else Reason.BAD_LENGTH
        return RecordDecode(None, reason, f"{rt.name}: {len(data)} bytes, expected {rt.size_bytes}")
    word = int.from_bytes(data, "big")
    if rt.padding_bits and word & ((1 << rt.padding_bits) - 1):
        return RecordDecode(None, Reason.OUT_OF_RANGE, f"{rt.name}: non-zero padding bits")
    out: dict[str, int] = {}
    for name, shift, mask, signed, lo, hi in _layout(rt):
        v = (word >> shift) & mask
        if signed and v > (mask >> 1):
            v -= mask + 1
        if not lo <= v <= hi:
            return RecordDecode(None, Reason.OUT_OF_RANGE, f"{rt.name}.{name} = {v} outside [{lo}, {hi}]")
        out[name] = v
    return RecordDecode(out, Reason.OK)


def saturate(rtype: str | RecordType, values: Mapping[str, Any]) -> dict[str, int]:
    """Round each value to an integer and clamp it into its field's valid range: for fields
    the table documents as saturating (speed_cmps, vertex_count, path_cost_dm) and for
    callers converting from physical units. NaN becomes the range's lower bound, +-inf its ends."""
    rt = record_type(rtype)
    values = as_values(rt, values)
    out = {}
    for f in rt.fields:
        v = values[f.name]
        if v != v:                                   # NaN != NaN
            v = f.min_value
        elif v in (float("inf"), float("-inf")):
            v = f.max_value if v > 0 else f.min_value
        out[f.name] = min(f.max_value, max(f.min_value, round(v)))
    return out
