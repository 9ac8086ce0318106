"""Frames: round trip, every rejection reason, bit flips, arbitrary bytes, RFC 1982."""
import crcmod.predefined
from hypothesis import given, settings, strategies as st

from firmware.comms.codec import REASONS, Reason, encode
from firmware.comms.frame import (FRAME_TYPE_DATA, decode_frame, encode_frame, encode_frame_records,
                                  frame_size_bytes, seal, seq_newer, with_hops)
from firmware.comms.schema import BY_NAME, RECORD_TYPES, SCHEMA_FINGERPRINT

import pytest


def values_for(rt):
    return st.fixed_dictionaries({f.name: st.integers(f.min_value, f.max_value) for f in rt.fields})


record = st.sampled_from(RECORD_TYPES).flatmap(lambda rt: st.tuples(st.just(rt.name), values_for(rt)))
frames = st.builds(
    lambda s, q, h, recs: encode_frame(s, q, recs, hops_left=h),
    st.integers(0, 255), st.integers(0, 65535), st.integers(0, 15), st.lists(record, min_size=1, max_size=18))

TOPO = dict(sender_id=7, x_cm=100, y_cm=-200, z_cm=3, presence=1, e_inf_code=42, info_version=0)


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 255), st.integers(0, 65535), st.integers(0, 15), st.integers(0, 15),
       st.lists(record, min_size=1, max_size=18))
def test_frame_round_trip(sender, seq, hops_left, hops_taken, recs):
    data = encode_frame(sender, seq, recs, hops_left=hops_left, hops_taken=hops_taken)
    counts = {}
    for name, _ in recs:
        counts[name] = counts.get(name, 0) + 1
    assert len(data) <= frame_size_bytes({n: 1 for n, _ in recs}) + sum(
        BY_NAME[n].size_bytes + 1 for n, _ in recs)  # at most one tag per record
    res = decode_frame(data)
    assert res.reason is Reason.OK, res.detail
    f = res.frame
    assert (f.sender_id, f.seq, f.hops_left, f.hops_taken, f.frame_type) == (sender, seq, hops_left, hops_taken, FRAME_TYPE_DATA)
    assert list(f.records) == [(n, v) for n, v in recs] and f.size_bytes == len(data)


def test_sizes_quoted_in_the_docs():
    assert len(encode_frame(1, 0, [("topo", TOPO)])) == 21 == frame_size_bytes({"topo": 1})
    assert len(encode_frame(1, 0, [("topo", TOPO)] * 20)) == 250 == frame_size_bytes({"topo": 20})
    with pytest.raises(ValueError, match="exceeds 255"):
        encode_frame(1, 0, [("topo", TOPO)] * 21)


@settings(max_examples=60, deadline=None)
@given(frames)
def test_every_single_bit_flip_is_rejected(data):
    for i in range(len(data) * 8):
        bad = bytearray(data)
        bad[i // 8] ^= 0x80 >> (i % 8)
        assert decode_frame(bytes(bad)).reason is not Reason.OK


@settings(max_examples=500, deadline=None)
@given(st.binary(max_size=300))
def test_arbitrary_bytes_never_raise(data):
    res = decode_frame(data)
    assert res.reason in REASONS
    assert (res.frame is None) == (res.reason is not Reason.OK)


def test_non_bytes_input_is_a_reason_not_an_exception():
    for junk in (None, 5, "hello", [1, 2]):
        assert decode_frame(junk).reason is Reason.TRUNCATED


def _body(sender=1, seq=0, payload=b"", version=1, ftype=1, length=None):
    length = len(payload) if length is None else length
    return bytes(((version << 4) | ftype, length, sender, seq >> 8, seq & 0xFF, 0)) + payload


def test_each_reason_from_a_crafted_frame():
    good = encode_frame(1, 5, [("topo", TOPO)])
    rec = good[6:-2]
    assert decode_frame(good[:3]).reason is Reason.TRUNCATED
    assert decode_frame(good[:-1]).reason is Reason.TRUNCATED
    assert decode_frame(good + b"\x00").reason is Reason.BAD_LENGTH
    assert decode_frame(bytes([0x21]) + good[1:]).reason is Reason.UNKNOWN_VERSION
    assert decode_frame(good[:-1] + bytes([good[-1] ^ 1])).reason is Reason.BAD_CRC
    assert decode_frame(seal(_body(payload=rec, ftype=2))).reason is Reason.UNKNOWN_TYPE
    assert decode_frame(seal(_body(payload=bytes([0xF0]) + rec[1:]))).reason is Reason.UNKNOWN_TYPE
    assert decode_frame(seal(_body(payload=rec[:-1]))).reason is Reason.BAD_LENGTH
    assert decode_frame(seal(_body(payload=b""))).reason is Reason.BAD_LENGTH
    bad_yaw = bytearray(encode("pose", dict(sender_id=1, x_cm=0, y_cm=0, yaw_cdeg=0, speed_cmps=0,
                                            exploring=0, done=0, returning=0, vertex_count=0)))
    bad_yaw[7] = 0x7F   # yaw_cdeg high byte -> 32767
    res = decode_frame(seal(_body(payload=bytes([0x20]) + bytes(bad_yaw))))
    assert res.reason is Reason.OUT_OF_RANGE and "yaw_cdeg" in res.detail


def test_peer_with_another_schema_is_rejected():
    """A frame sealed under a different fingerprint fails the CRC (CRC_EXTRA idea)."""
    crc = crcmod.predefined.mkPredefinedCrcFun("modbus")
    body = encode_frame(1, 5, [("topo", TOPO)])[:-2]
    ours = crc(SCHEMA_FINGERPRINT.to_bytes(2, "big") + body)
    assert decode_frame(body + ours.to_bytes(2, "big")).reason is Reason.OK
    theirs = crc(((SCHEMA_FINGERPRINT + 1) & 0xFFFF).to_bytes(2, "big") + body)
    assert decode_frame(body + theirs.to_bytes(2, "big")).reason is Reason.BAD_CRC


def test_with_hops_reseals():
    data = encode_frame(9, 77, [("topo", TOPO)], hops_left=3)
    relayed = with_hops(data, 2, 1)
    f = decode_frame(relayed).frame
    assert (f.sender_id, f.seq, f.hops_left, f.hops_taken) == (9, 77, 2, 1)


def test_encode_rejects_bad_header_values():
    for kwargs in (dict(sender_id=256, seq=0), dict(sender_id=0, seq=65536), dict(sender_id=-1, seq=0)):
        with pytest.raises(ValueError, match="outside"):
            encode_frame(kwargs["sender_id"], kwargs["seq"], [("topo", TOPO)])
    with pytest.raises(ValueError, match="at least one record"):
        encode_frame_records(1, 0, [])
    with pytest.raises(ValueError, match="expected 12"):
        encode_frame_records(1, 0, [("topo", b"\x00" * 11)])


@given(st.integers(0, 65535), st.integers(0, 65535))
def test_seq_newer_is_rfc1982(a, b):
    d = (a - b) % 65536
    assert seq_newer(a, b) == (0 < d < 32768)
    assert not (seq_newer(a, b) and seq_newer(b, a))
    if a != b and d != 32768:
        assert seq_newer(a, b) != seq_newer(b, a)


def test_seq_newer_wraps():
    assert seq_newer(0, 65535) and seq_newer(5, 65530) and not seq_newer(65535, 0)
    assert not seq_newer(32768, 0) and not seq_newer(0, 32768)   # undefined case: neither
    assert not seq_newer(3, 3)
