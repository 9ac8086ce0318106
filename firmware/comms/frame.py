"""Frames: what one LoRa transmission carries (frame format version 2).

    offset  size  field
    0       1     version (high nibble, = 2) | frame type (low nibble, 1 = data)
    1       1     dialect id of the frame (schema.Dialect.id): the sender's scheme dialect
                  when the frame holds any of its records, else 0 (core records only)
    2       1     payload length L in bytes (the group section below)
    3       1     sender id (the originator; a relay keeps it)
    4       2     sequence number, big-endian, RFC 1982 serial arithmetic (seq_newer)
    6       1     hops taken (high nibble) | hops left (low nibble); 0 left = do not relay
    7       L     groups: a tag byte, then `count` records of one type, each exactly its
                  schema size. Tag: bit 7 = 0 core dialect / 1 the frame's dialect,
                  bits 6..3 = record code in that dialect (1..15), bits 2..0 = count - 1
                  (1..8 records). A dialect-0 frame has no records with bit 7 set.
    7+L     2     CRC-16/MODBUS (see schema.CRC_NAME), big-endian, over the core dialect's
                  fingerprint (2 bytes, big-endian), then the frame dialect's fingerprint
                  (0x0000 for dialect 0), then bytes 0 .. 7+L-1. The fingerprints are folded
                  in, never sent (pymavlink's CRC_EXTRA, one per message set): a peer whose
                  copy of the core or of this frame's dialect differs rejects the frame, a peer
                  whose other dialects differ still reads it.

A frame whose dialect id the receiver does not know is rejected (UNKNOWN_DIALECT) before its
CRC can be checked, core records and all: without the dialect's fingerprint nothing in it can
be trusted. So a frame holding core records only goes as dialect 0, readable by any peer.

Overhead: 9 bytes per frame plus 1 per run of up to 8 records of one type. A frame with one
Table I vertex is 22 bytes; with 20 vertices 252 bytes (12 B per vertex, 3 tags).
"""
from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

from firmware.comms.codec import REASONS, Reason, decode, encode
from firmware.comms.schema import (CORE_DIALECT_ID, FRAME_CRC_BYTES, FRAME_HEADER_BYTES, FRAME_VERSION,
                                   GROUP_TAG_BYTES, MAX_FRAME_BYTES, NO_DIALECT_FINGERPRINT, Dialect,
                                   DialectSet, RecordType, crc16, default_dialects)

__all__ = [
    "Reason", "REASONS", "Frame", "DecodeResult", "encode_frame", "encode_frame_records",
    "decode_frame", "seq_newer", "frame_size_bytes", "seal", "with_hops", "frame_crc",
    "HEADER_BYTES", "CRC_BYTES", "MAX_FRAME_BYTES", "FRAME_TYPE_DATA", "MAX_RECORDS_PER_GROUP",
]

HEADER_BYTES = FRAME_HEADER_BYTES
CRC_BYTES = FRAME_CRC_BYTES
OVERHEAD_BYTES = HEADER_BYTES + CRC_BYTES
MAX_PAYLOAD_FIELD = 255
FRAME_TYPE_DATA = 1
FRAME_TYPES = {FRAME_TYPE_DATA: "data"}
MAX_HOPS = 15
SEQ_MODULUS = 1 << 16

# Header byte offsets.
DIALECT_BYTE = 1
LENGTH_BYTE = 2
SENDER_BYTE = 3
SEQ_BYTE = 4
HOPS_BYTE = 6

# Group tag layout.
TAG_DIALECT_BIT = 0x80          # set: the record is of the frame's dialect; clear: core
TAG_CODE_SHIFT = 3
TAG_CODE_MASK = 0x0F
TAG_COUNT_MASK = 0x07
MAX_RECORDS_PER_GROUP = TAG_COUNT_MASK + 1


@dataclass(frozen=True)
class Frame:
    version: int
    frame_type: int
    dialect_id: int
    sender_id: int
    seq: int
    hops_taken: int
    hops_left: int
    records: tuple[tuple[str, dict[str, int]], ...]   # (record type name, field values)
    size_bytes: int


class DecodeResult(NamedTuple):
    frame: Frame | None
    reason: Reason
    detail: str = ""

    @property
    def ok(self) -> bool:
        return self.reason is Reason.OK


def seq_newer(a: int, b: int) -> bool:
    """RFC 1982 (SERIAL_BITS = 16): is sequence number `a` newer than `b`? The undefined
    case (exactly half the space apart) is treated as not newer in either direction."""
    d = (a - b) % SEQ_MODULUS
    return 0 < d < SEQ_MODULUS // 2


# CRC register state after the two fingerprints, per (core, dialect) fingerprint pair, so
# each frame CRC costs one crcmod call.
_CRC_SEEDS: dict[tuple[int, int], int] = {}


def _crc_seed(dialects: DialectSet, dialect_id: int) -> int | None:
    """None if `dialect_id` is not in `dialects`."""
    if dialect_id == CORE_DIALECT_ID:
        dialect_fp = NO_DIALECT_FINGERPRINT
    else:
        d = dialects.get(dialect_id)
        if d is None:
            return None
        dialect_fp = d.fingerprint
    key = (dialects.core.fingerprint, dialect_fp)
    seed = _CRC_SEEDS.get(key)
    if seed is None:
        seed = _CRC_SEEDS[key] = crc16(key[0].to_bytes(2, "big") + key[1].to_bytes(2, "big"))
    return seed


def frame_crc(body: bytes, dialects: DialectSet | None = None) -> int:
    """The CRC of a header + payload, under the fingerprints of the dialect its header names
    (ValueError if `dialects` does not know it)."""
    dialects = dialects if dialects is not None else default_dialects()
    if len(body) <= DIALECT_BYTE:
        raise ValueError(f"{len(body)} bytes hold no dialect id")
    seed = _crc_seed(dialects, body[DIALECT_BYTE])
    if seed is None:
        raise ValueError(f"unknown dialect id {body[DIALECT_BYTE]}")
    return crc16(bytes(body), seed)


def seal(body: bytes, dialects: DialectSet | None = None) -> bytes:
    """Append the CRC to a header + payload."""
    return bytes(body) + frame_crc(body, dialects).to_bytes(CRC_BYTES, "big")


def frame_size_bytes(type_counts: Mapping[str, int], dialects: DialectSet | None = None) -> int:
    """Size of a frame holding `count` records of each type, grouped by type."""
    dialects = dialects if dialects is not None else default_dialects()
    size = OVERHEAD_BYTES
    for name, count in type_counts.items():
        if count:
            size += count * dialects.record(name).size_bytes + GROUP_TAG_BYTES * math.ceil(count / MAX_RECORDS_PER_GROUP)
    return size


def _check_u(name: str, v: int, hi: int) -> None:
    if not isinstance(v, int) or not 0 <= v <= hi:
        raise ValueError(f"frame {name} = {v!r} outside [0, {hi}]")


def _sending_dialect(types: Sequence[RecordType], dialect: Dialect | None, dialects: DialectSet) -> Dialect:
    """The dialect whose records may go beside the core's: `dialect`, or with None the one
    non-core dialect the records belong to (the core if there is none)."""
    core = dialects.core
    if dialect is not None:
        if dialect.id != CORE_DIALECT_ID and dialects.get(dialect.id) != dialect:
            raise ValueError(f"dialect {dialect.name!r} (id {dialect.id}) is not in the dialect set")
        allowed = {core.id, dialect.id}
        for rt in types:
            owner = dialects.dialect_of(rt)
            if owner.id not in allowed:
                raise ValueError(f"record {rt.name!r} is of dialect {owner.name!r}; a frame of dialect "
                                 f"{dialect.name!r} carries core and {dialect.name!r} records only")
        return dialect
    others = {dialects.dialect_of(rt).id for rt in types} - {core.id}
    if len(others) > 1:
        raise ValueError(f"records of dialects {sorted(others)} cannot share one frame")
    return dialects.get(others.pop()) if others else core


def encode_frame_records(sender_id: int, seq: int, records: Sequence[tuple[str, bytes]], *,
                         dialect: Dialect | None = None, dialects: DialectSet | None = None,
                         hops_left: int = 0, hops_taken: int = 0) -> bytes:
    """Frame from already-encoded records [(type name, record bytes)]. `dialect` is the
    sender's (None: the one the records belong to); the records must be core records or of
    that dialect. The header names that dialect if any of its records is in the frame, else
    dialect 0. Consecutive records of one type share a group tag, so callers that sort by
    type pay fewest tags."""
    dialects = dialects if dialects is not None else default_dialects()
    _check_u("sender_id", sender_id, 255)
    _check_u("seq", seq, SEQ_MODULUS - 1)
    _check_u("hops_left", hops_left, MAX_HOPS)
    _check_u("hops_taken", hops_taken, MAX_HOPS)
    if not records:
        raise ValueError("a frame needs at least one record")
    types = [dialects.record(name) for name, _ in records]
    sending = _sending_dialect(types, dialect, dialects)
    frame_dialect_id = (sending.id if any(dialects.dialect_of(rt).id == sending.id for rt in types)
                        else CORE_DIALECT_ID)
    payload = bytearray()
    i = 0
    while i < len(records):
        rt = types[i]
        j = i
        while j < len(records) and j - i < MAX_RECORDS_PER_GROUP and types[j] == rt:
            if len(records[j][1]) != rt.size_bytes:
                raise ValueError(f"record {j} ({rt.name}) is {len(records[j][1])} bytes, expected {rt.size_bytes}")
            j += 1
        dialect_bit = 0 if dialects.dialect_of(rt).id == CORE_DIALECT_ID else TAG_DIALECT_BIT
        payload.append(dialect_bit | (rt.code << TAG_CODE_SHIFT) | (j - i - 1))
        for k in range(i, j):
            payload += records[k][1]
        i = j
    if len(payload) > MAX_PAYLOAD_FIELD or len(payload) + OVERHEAD_BYTES > MAX_FRAME_BYTES:
        raise ValueError(f"frame of {len(payload) + OVERHEAD_BYTES} bytes exceeds {MAX_FRAME_BYTES}")
    header = bytes((
        (FRAME_VERSION << 4) | FRAME_TYPE_DATA, frame_dialect_id, len(payload), sender_id, seq >> 8, seq & 0xFF,
        (hops_taken << 4) | hops_left,
    ))
    assert len(header) == HEADER_BYTES
    return seal(header + payload, dialects)


def encode_frame(sender_id: int, seq: int, records: Iterable[tuple[str, Mapping[str, Any] | Any]], *,
                 dialect: Dialect | None = None, dialects: DialectSet | None = None,
                 hops_left: int = 0, hops_taken: int = 0) -> bytes:
    """Frame from [(record type name, values dict or record dataclass)] (see
    encode_frame_records for `dialect`). Raises ValueError for values out of range, records
    of a dialect the frame cannot carry or a frame over 255 bytes."""
    dialects = dialects if dialects is not None else default_dialects()
    encoded = [(dialects.record(t).name, encode(dialects.record(t), v)) for t, v in records]
    return encode_frame_records(sender_id, seq, encoded, dialect=dialect, dialects=dialects,
                                hops_left=hops_left, hops_taken=hops_taken)


def with_hops(frame: bytes, hops_left: int, hops_taken: int, dialects: DialectSet | None = None) -> bytes:
    """The same frame with a new hop byte and CRC: what a relay transmits."""
    _check_u("hops_left", hops_left, MAX_HOPS)
    _check_u("hops_taken", hops_taken, MAX_HOPS)
    body = bytearray(frame[:-CRC_BYTES])
    body[HOPS_BYTE] = (hops_taken << 4) | hops_left
    return seal(bytes(body), dialects)


def expected_size(header: bytes) -> int | None:
    """Total frame size announced by a header prefix (>= LENGTH_BYTE + 1 bytes), else None."""
    if len(header) <= LENGTH_BYTE:
        return None
    return OVERHEAD_BYTES + header[LENGTH_BYTE]


def decode_frame(data: bytes, dialects: DialectSet | None = None) -> DecodeResult:
    """One frame from exactly its bytes, read with `dialects` (default: every dialect this
    firmware knows). Never raises, whatever `data` is."""
    if not isinstance(data, (bytes, bytearray, memoryview)):
        return DecodeResult(None, Reason.TRUNCATED, f"input is {type(data).__name__}, not bytes")
    dialects = dialects if dialects is not None else default_dialects()
    data = bytes(data)
    n = len(data)
    if n < HEADER_BYTES:
        return DecodeResult(None, Reason.TRUNCATED, f"{n} bytes, a header needs {HEADER_BYTES}")
    version = data[0] >> 4
    if version != FRAME_VERSION:
        return DecodeResult(None, Reason.UNKNOWN_VERSION, f"version {version}, expected {FRAME_VERSION}")
    want = OVERHEAD_BYTES + data[LENGTH_BYTE]
    if n < want:
        return DecodeResult(None, Reason.TRUNCATED, f"{n} bytes, header announces {want}")
    if n > want:
        return DecodeResult(None, Reason.BAD_LENGTH, f"{n} bytes, header announces {want}")
    dialect_id = data[DIALECT_BYTE]
    seed = _crc_seed(dialects, dialect_id)
    if seed is None:
        return DecodeResult(None, Reason.UNKNOWN_DIALECT, f"dialect id {dialect_id}")
    body = data[:-CRC_BYTES]
    got = int.from_bytes(data[-CRC_BYTES:], "big")
    calc = crc16(body, seed)
    if got != calc:
        return DecodeResult(None, Reason.BAD_CRC, f"crc 0x{got:04X}, computed 0x{calc:04X}")
    frame_type = data[0] & 0x0F
    if frame_type not in FRAME_TYPES:
        return DecodeResult(None, Reason.UNKNOWN_TYPE, f"frame type {frame_type}")
    pos, end = HEADER_BYTES, HEADER_BYTES + data[LENGTH_BYTE]
    if pos == end:
        return DecodeResult(None, Reason.BAD_LENGTH, "no records")
    records: list[tuple[str, dict[str, int]]] = []
    while pos < end:
        tag = data[pos]
        in_dialect = bool(tag & TAG_DIALECT_BIT)
        code = (tag >> TAG_CODE_SHIFT) & TAG_CODE_MASK
        # A dialect-0 frame has no "frame's dialect" records: bit 7 there is an unknown type.
        rt = (dialects.lookup(dialect_id, code) if in_dialect and dialect_id != CORE_DIALECT_ID
              else None if in_dialect else dialects.core.by_code.get(code))
        if rt is None:
            return DecodeResult(None, Reason.UNKNOWN_TYPE,
                                f"record code {code} of dialect {dialect_id if in_dialect else 0} at byte {pos}")
        count = (tag & TAG_COUNT_MASK) + 1
        pos += GROUP_TAG_BYTES
        if pos + count * rt.size_bytes > end:
            return DecodeResult(None, Reason.BAD_LENGTH,
                                f"group of {count} {rt.name} at byte {pos - 1} overruns the payload")
        for _ in range(count):
            rec = decode(rt, data[pos:pos + rt.size_bytes])
            if rec.values is None:
                return DecodeResult(None, rec.reason, f"record {len(records)}: {rec.detail}")
            records.append((rt.name, rec.values))
            pos += rt.size_bytes
    frame = Frame(version, frame_type, dialect_id, data[SENDER_BYTE], (data[SEQ_BYTE] << 8) | data[SEQ_BYTE + 1],
                  data[HOPS_BYTE] >> 4, data[HOPS_BYTE] & 0x0F, tuple(records), n)
    return DecodeResult(frame, Reason.OK)
