"""Frames: what one LoRa transmission carries.

    offset  size  field
    0       1     version (high nibble, = 1) | frame type (low nibble, 1 = data)
    1       1     payload length in bytes (the group section below)
    2       1     sender id (the originator; a relay keeps it)
    3       2     sequence number, big-endian, RFC 1982 serial arithmetic (seq_newer)
    5       1     hops taken (high nibble) | hops left (low nibble); 0 left = do not relay
    6       L     groups: a tag byte (record type code << 4 | count - 1) then `count`
                  records of that type, each exactly its schema size
    6+L     2     CRC-16/MODBUS (see schema.CRC_NAME), big-endian, over the 2-byte schema fingerprint followed by
                  bytes 0 .. 6+L-1 (the fingerprint is folded in, never sent: pymavlink's
                  CRC_EXTRA idea, so a peer with a different table rejects our frames)

Overhead: 8 bytes per frame plus 1 per run of up to 16 records of one type. A frame with
one Table I vertex is 21 bytes; with 20 vertices 250 bytes (12 B per vertex).
"""
from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

from firmware.comms.codec import REASONS, Reason, decode, encode
from firmware.comms.schema import (BY_CODE, FRAME_VERSION, SCHEMA_FINGERPRINT, crc16,
                                   record_type)

__all__ = [
    "Reason", "REASONS", "Frame", "DecodeResult", "encode_frame", "encode_frame_records",
    "decode_frame", "seq_newer", "frame_size_bytes", "seal", "with_hops",
    "HEADER_BYTES", "CRC_BYTES", "MAX_FRAME_BYTES", "FRAME_TYPE_DATA", "MAX_RECORDS_PER_GROUP",
]

HEADER_BYTES = 6
CRC_BYTES = 2
OVERHEAD_BYTES = HEADER_BYTES + CRC_BYTES
MAX_FRAME_BYTES = 255          # LoRa PHY payload limit (and the RN2483's `radio tx`)
MAX_PAYLOAD_FIELD = 255
FRAME_TYPE_DATA = 1
FRAME_TYPES = {FRAME_TYPE_DATA: "data"}
MAX_RECORDS_PER_GROUP = 16
MAX_HOPS = 15
SEQ_MODULUS = 1 << 16

# CRC register state after the fingerprint, so each frame CRC costs one crcmod call.
_CRC_SEED = crc16(SCHEMA_FINGERPRINT.to_bytes(2, "big"))


@dataclass(frozen=True)
class Frame:
    version: int
    frame_type: int
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


def frame_crc(body: bytes) -> int:
    return crc16(body, _CRC_SEED)


def seal(body: bytes) -> bytes:
    """Append the CRC to a header + payload."""
    return bytes(body) + frame_crc(body).to_bytes(CRC_BYTES, "big")


def frame_size_bytes(type_counts: Mapping[str, int]) -> int:
    """Size of a frame holding `count` records of each type, grouped by type."""
    size = OVERHEAD_BYTES
    for name, count in type_counts.items():
        if count:
            size += count * record_type(name).size_bytes + math.ceil(count / MAX_RECORDS_PER_GROUP)
    return size


def _check_u(name: str, v: int, hi: int) -> None:
    if not isinstance(v, int) or not 0 <= v <= hi:
        raise ValueError(f"frame {name} = {v!r} outside [0, {hi}]")


def encode_frame_records(sender_id: int, seq: int, records: Sequence[tuple[str, bytes]], *,
                         hops_left: int = 0, hops_taken: int = 0) -> bytes:
    """Frame from already-encoded records [(type name, record bytes)]. Consecutive records
    of one type share a group tag, so callers that sort by type pay fewest tags."""
    _check_u("sender_id", sender_id, 255)
    _check_u("seq", seq, SEQ_MODULUS - 1)
    _check_u("hops_left", hops_left, MAX_HOPS)
    _check_u("hops_taken", hops_taken, MAX_HOPS)
    if not records:
        raise ValueError("a frame needs at least one record")
    payload = bytearray()
    i = 0
    while i < len(records):
        rt = record_type(records[i][0])
        j = i
        while j < len(records) and j - i < MAX_RECORDS_PER_GROUP and records[j][0] == rt.name:
            if len(records[j][1]) != rt.size_bytes:
                raise ValueError(f"record {j} ({rt.name}) is {len(records[j][1])} bytes, expected {rt.size_bytes}")
            j += 1
        payload.append((rt.code << 4) | (j - i - 1))
        for k in range(i, j):
            payload += records[k][1]
        i = j
    if len(payload) > MAX_PAYLOAD_FIELD or len(payload) + OVERHEAD_BYTES > MAX_FRAME_BYTES:
        raise ValueError(f"frame of {len(payload) + OVERHEAD_BYTES} bytes exceeds {MAX_FRAME_BYTES}")
    header = bytes((
        (FRAME_VERSION << 4) | FRAME_TYPE_DATA, len(payload), sender_id, seq >> 8, seq & 0xFF,
        (hops_taken << 4) | hops_left,
    ))
    return seal(header + payload)


def encode_frame(sender_id: int, seq: int, records: Iterable[tuple[str, Mapping[str, Any] | Any]], *,
                 hops_left: int = 0, hops_taken: int = 0) -> bytes:
    """Frame from [(record type name, values dict or record dataclass)]. Raises ValueError
    for values out of range or a frame over 255 bytes."""
    encoded = [(record_type(t).name, encode(t, v)) for t, v in records]
    return encode_frame_records(sender_id, seq, encoded, hops_left=hops_left, hops_taken=hops_taken)


def with_hops(frame: bytes, hops_left: int, hops_taken: int) -> bytes:
    """The same frame with a new hop byte and CRC: what a relay transmits."""
    _check_u("hops_left", hops_left, MAX_HOPS)
    _check_u("hops_taken", hops_taken, MAX_HOPS)
    body = bytearray(frame[:-CRC_BYTES])
    body[5] = (hops_taken << 4) | hops_left
    return seal(bytes(body))


def expected_size(header: bytes) -> int | None:
    """Total frame size announced by a header prefix (>= 2 bytes), else None."""
    if len(header) < 2:
        return None
    return OVERHEAD_BYTES + header[1]


def decode_frame(data: bytes) -> DecodeResult:
    """One frame from exactly its bytes. Never raises, whatever `data` is."""
    if not isinstance(data, (bytes, bytearray, memoryview)):
        return DecodeResult(None, Reason.TRUNCATED, f"input is {type(data).__name__}, not bytes")
    data = bytes(data)
    n = len(data)
    if n < HEADER_BYTES:
        return DecodeResult(None, Reason.TRUNCATED, f"{n} bytes, a header needs {HEADER_BYTES}")
    version = data[0] >> 4
    if version != FRAME_VERSION:
        return DecodeResult(None, Reason.UNKNOWN_VERSION, f"version {version}, expected {FRAME_VERSION}")
    want = OVERHEAD_BYTES + data[1]
    if n < want:
        return DecodeResult(None, Reason.TRUNCATED, f"{n} bytes, header announces {want}")
    if n > want:
        return DecodeResult(None, Reason.BAD_LENGTH, f"{n} bytes, header announces {want}")
    body = data[:-CRC_BYTES]
    got = int.from_bytes(data[-CRC_BYTES:], "big")
    calc = frame_crc(body)
    if got != calc:
        return DecodeResult(None, Reason.BAD_CRC, f"crc 0x{got:04X}, computed 0x{calc:04X}")
    frame_type = data[0] & 0x0F
    if frame_type not in FRAME_TYPES:
        return DecodeResult(None, Reason.UNKNOWN_TYPE, f"frame type {frame_type}")
    pos, end = HEADER_BYTES, HEADER_BYTES + data[1]
    if pos == end:
        return DecodeResult(None, Reason.BAD_LENGTH, "no records")
    records: list[tuple[str, dict[str, int]]] = []
    while pos < end:
        tag = data[pos]
        rt = BY_CODE.get(tag >> 4)
        if rt is None:
            return DecodeResult(None, Reason.UNKNOWN_TYPE, f"record type code {tag >> 4} at byte {pos}")
        count = (tag & 0x0F) + 1
        pos += 1
        if pos + count * rt.size_bytes > end:
            return DecodeResult(None, Reason.BAD_LENGTH,
                                f"group of {count} {rt.name} at byte {pos - 1} overruns the payload")
        for _ in range(count):
            rec = decode(rt, data[pos:pos + rt.size_bytes])
            if rec.values is None:
                return DecodeResult(None, rec.reason, f"record {len(records)}: {rec.detail}")
            records.append((rt.name, rec.values))
            pos += rt.size_bytes
    frame = Frame(version, frame_type, data[2], (data[3] << 8) | data[4], data[5] >> 4, data[5] & 0x0F,
                  tuple(records), n)
    return DecodeResult(frame, Reason.OK)
