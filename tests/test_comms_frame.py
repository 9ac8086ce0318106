"""Frames: round trip, every rejection reason, bit flips, arbitrary bytes, dialects, RFC 1982."""
import dataclasses

import crcmod.predefined
import pytest
from hypothesis import given, settings, strategies as st

from firmware.comms.codec import REASONS, Reason, encode
from firmware.comms.frame import (FRAME_TYPE_DATA, MAX_RECORDS_PER_GROUP, decode_frame, encode_frame,
                                  encode_frame_records, frame_size_bytes, seal, seq_newer, with_hops)
from firmware.comms.schema import CORE, SENDER, Dialect, DialectSet, Field, RecordType
from firmware.schemes import all_dialects
from firmware.schemes.bayer_faigl.records import DIALECT as BF

DIALECTS = all_dialects()
# A second scheme's dialect, for peers that know more (or other) dialects than we do.
BLIP = RecordType(1, "blip", 2, (SENDER, Field("level_id", 8)))
OTHER = Dialect(200, "other", (BLIP,))     # an id no scheme uses
WITH_OTHER = DialectSet([CORE, BF, OTHER])


def values_for(rt):
    return st.fixed_dictionaries({f.name: st.integers(f.min_value, f.max_value) for f in rt.fields})


def records_of(dialect):
    """Strategy: (name, values) of a core record or one of `dialect`'s."""
    return st.sampled_from(CORE.records + dialect.records).flatmap(
        lambda rt: st.tuples(st.just(rt.name), values_for(rt)))


record = records_of(BF)
frames = st.builds(
    lambda s, q, h, recs: encode_frame(s, q, recs, hops_left=h),
    st.integers(0, 255), st.integers(0, 65535), st.integers(0, 15), st.lists(record, min_size=1, max_size=18))

TOPO = dict(sender_id=7, x_cm=100, y_cm=-200, z_cm=3, presence=1, e_inf_code=42, info_version=0)
POSE = dict(sender_id=7, x_cm=1, y_cm=2, yaw_cdeg=3, speed_cmps=4, exploring=1, done=0, returning=0, vertex_count=5)


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 255), st.integers(0, 65535), st.integers(0, 15), st.integers(0, 15),
       st.sampled_from([(BF, DIALECTS), (OTHER, WITH_OTHER)]).flatmap(
           lambda dd: st.tuples(st.just(dd), st.lists(records_of(dd[0]), min_size=1, max_size=18))))
def test_frames_mixing_core_and_dialect_records_round_trip(sender, seq, hops_left, hops_taken, case):
    (dialect, dialects), recs = case
    data = encode_frame(sender, seq, recs, dialect=dialect, dialects=dialects, hops_left=hops_left,
                        hops_taken=hops_taken)
    assert len(data) <= frame_size_bytes({}, dialects) + sum(
        dialects.record(n).size_bytes + 1 for n, _ in recs)  # at most one tag per record
    res = decode_frame(data, dialects)
    assert res.reason is Reason.OK, res.detail
    f = res.frame
    assert (f.sender_id, f.seq, f.hops_left, f.hops_taken, f.frame_type) == (sender, seq, hops_left, hops_taken, FRAME_TYPE_DATA)
    assert list(f.records) == [(n, v) for n, v in recs] and f.size_bytes == len(data)
    own = any(dialects.dialect_of(n) is dialect for n, _ in recs)
    assert f.dialect_id == (dialect.id if own else 0)       # core records only: dialect 0


def test_sizes_quoted_in_the_docs():
    assert len(encode_frame(1, 0, [("topo", TOPO)])) == 22 == frame_size_bytes({"topo": 1})
    assert len(encode_frame(1, 0, [("topo", TOPO)] * 20)) == 252 == frame_size_bytes({"topo": 20})
    assert frame_size_bytes({"topo": MAX_RECORDS_PER_GROUP}) == 9 + 1 + 8 * 12
    assert frame_size_bytes({"topo": MAX_RECORDS_PER_GROUP + 1}) == 9 + 2 + 9 * 12
    with pytest.raises(ValueError, match="exceeds 255"):
        encode_frame(1, 0, [("topo", TOPO)] * 21)


def test_header_and_tag_layout():
    data = encode_frame(9, 0x1234, [("pose", POSE), ("topo", TOPO), ("topo", TOPO)], hops_left=2, hops_taken=1)
    assert data[:7] == bytes([0x21, BF.id, 1 + 12 + 1 + 24, 9, 0x12, 0x34, 0x12])
    assert data[7] == (0 << 7) | (1 << 3) | 0           # core, code 1 (pose), 1 record
    assert data[7 + 13] == (1 << 7) | (1 << 3) | 1      # frame's dialect, code 1 (topo), 2 records
    crc = crcmod.predefined.mkPredefinedCrcFun("modbus")
    fps = CORE.fingerprint.to_bytes(2, "big") + BF.fingerprint.to_bytes(2, "big")
    assert int.from_bytes(data[-2:], "big") == crc(fps + data[:-2])
    core_only = encode_frame(9, 1, [("pose", POSE)], dialect=BF)
    assert core_only[1] == 0 and int.from_bytes(core_only[-2:], "big") == crc(
        CORE.fingerprint.to_bytes(2, "big") + b"\x00\x00" + core_only[:-2])


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
    for dialects in (DIALECTS, WITH_OTHER):
        res = decode_frame(data, dialects)
        assert res.reason in REASONS
        assert (res.frame is None) == (res.reason is not Reason.OK)


def test_non_bytes_input_is_a_reason_not_an_exception():
    for junk in (None, 5, "hello", [1, 2]):
        assert decode_frame(junk).reason is Reason.TRUNCATED


def _body(sender=1, seq=0, payload=b"", version=2, ftype=1, dialect=1, length=None):
    length = len(payload) if length is None else length
    return bytes(((version << 4) | ftype, dialect, length, sender, seq >> 8, seq & 0xFF, 0)) + payload


def test_each_reason_from_a_crafted_frame():
    good = encode_frame(1, 5, [("topo", TOPO)])
    rec = good[7:-2]
    assert decode_frame(good[:3]).reason is Reason.TRUNCATED
    assert decode_frame(good[:-1]).reason is Reason.TRUNCATED
    assert decode_frame(good + b"\x00").reason is Reason.BAD_LENGTH
    assert decode_frame(bytes([0x11]) + good[1:]).reason is Reason.UNKNOWN_VERSION
    assert decode_frame(good[:-1] + bytes([good[-1] ^ 1])).reason is Reason.BAD_CRC
    assert decode_frame(seal(_body(payload=rec, ftype=2))).reason is Reason.UNKNOWN_TYPE
    assert decode_frame(seal(_body(payload=bytes([0xF8]) + rec[1:]))).reason is Reason.UNKNOWN_TYPE   # code 15
    assert decode_frame(seal(_body(payload=bytes([0x00]) + rec[1:]))).reason is Reason.UNKNOWN_TYPE   # code 0
    # A core-only frame (dialect 0) has no "frame's dialect" records.
    assert decode_frame(seal(_body(payload=rec, dialect=0))).reason is Reason.UNKNOWN_TYPE
    assert decode_frame(seal(_body(payload=rec[:-1]))).reason is Reason.BAD_LENGTH
    assert decode_frame(seal(_body(payload=b""))).reason is Reason.BAD_LENGTH
    bad_yaw = bytearray(encode("pose", POSE))
    bad_yaw[7] = 0x7F   # yaw_cdeg high byte -> 32767
    res = decode_frame(seal(_body(payload=bytes([0x08]) + bytes(bad_yaw), dialect=0)))
    assert res.reason is Reason.OUT_OF_RANGE and "yaw_cdeg" in res.detail
    unknown = _body(payload=bytes([0x88, 1, 2]), dialect=200)
    res = decode_frame(seal(unknown, WITH_OTHER))
    assert res.reason is Reason.UNKNOWN_DIALECT and "dialect id 200" in res.detail
    with pytest.raises(ValueError, match="unknown dialect id 200"):
        seal(unknown)


def test_unknown_dialect_ids_are_rejected_whatever_the_crc():
    for dialect_id in range(256):
        body = _body(payload=bytes([0x88, 1, 2]), dialect=dialect_id)
        for crc in (b"\x00\x00", b"\xff\xff"):
            reason = decode_frame(body + crc).reason
            assert (reason is Reason.UNKNOWN_DIALECT) == (dialect_id not in DIALECTS.by_id), dialect_id


def _changed_topo_dialect():
    topo = BF.by_name["topo"]
    z = tuple(dataclasses.replace(f, lo=-100, hi=100) if f.name == "z_cm" else f for f in topo.fields)
    return Dialect(BF.id, BF.name, (dataclasses.replace(topo, fields=z),))


def test_a_peer_whose_copy_of_the_frames_dialect_differs_rejects_it():
    """The frame dialect's fingerprint is folded into the CRC (pymavlink's CRC_EXTRA)."""
    ours = encode_frame(1, 5, [("pose", POSE), ("topo", TOPO)])
    theirs = DialectSet([CORE, _changed_topo_dialect()])
    assert decode_frame(ours).reason is Reason.OK
    assert decode_frame(ours, theirs).reason is Reason.BAD_CRC
    # The core fingerprint is in every frame's CRC: a changed core breaks every frame.
    core2 = Dialect(0, "core", (dataclasses.replace(CORE.records[0], doc="same"),
                                RecordType(2, "extra", 1, (SENDER,))))
    assert decode_frame(encode_frame(1, 5, [("pose", POSE)]), DialectSet([core2, BF])).reason is Reason.BAD_CRC


def test_a_peer_whose_other_dialects_differ_still_reads_the_frame():
    """Changing one scheme's table breaks only that scheme's frames."""
    ours = encode_frame(1, 5, [("pose", POSE), ("topo", TOPO)])
    peer = DialectSet([CORE, BF, OTHER])                                    # knows one dialect more
    peer_changed = DialectSet([CORE, BF, Dialect(200, "other", (dataclasses.replace(BLIP, size_bytes=3,
                                                             fields=BLIP.fields + (Field("more_id", 8),)),))])
    for dialects in (peer, peer_changed):
        res = decode_frame(ours, dialects)
        assert res.reason is Reason.OK and [n for n, _ in res.frame.records] == ["pose", "topo"]
    # ... and their core-only frames reach us, whatever dialects either side knows.
    blips = encode_frame(3, 1, [("pose", POSE)], dialect=OTHER, dialects=peer)
    assert decode_frame(blips).reason is Reason.OK
    assert decode_frame(encode_frame(3, 2, [("blip", dict(sender_id=3, level_id=4))], dialects=peer)
                        ).reason is Reason.UNKNOWN_DIALECT


def test_with_hops_reseals():
    data = encode_frame(9, 77, [("topo", TOPO)], hops_left=3)
    relayed = with_hops(data, 2, 1)
    f = decode_frame(relayed).frame
    assert (f.sender_id, f.seq, f.hops_left, f.hops_taken, f.dialect_id) == (9, 77, 2, 1, BF.id)


def test_encode_rejects_bad_header_values_and_foreign_records():
    for kwargs in (dict(sender_id=256, seq=0), dict(sender_id=0, seq=65536), dict(sender_id=-1, seq=0)):
        with pytest.raises(ValueError, match="outside"):
            encode_frame(kwargs["sender_id"], kwargs["seq"], [("topo", TOPO)])
    with pytest.raises(ValueError, match="at least one record"):
        encode_frame_records(1, 0, [])
    with pytest.raises(ValueError, match="expected 12"):
        encode_frame_records(1, 0, [("topo", b"\x00" * 11)])
    with pytest.raises(ValueError, match="carries core and 'other' records only"):
        encode_frame(1, 0, [("topo", TOPO)], dialect=OTHER, dialects=WITH_OTHER)
    with pytest.raises(ValueError, match="cannot share one frame"):
        encode_frame(1, 0, [("topo", TOPO), ("blip", dict(sender_id=1, level_id=0))], dialects=WITH_OTHER)
    with pytest.raises(ValueError, match="not in the dialect set"):
        encode_frame(1, 0, [("pose", POSE)], dialect=OTHER)
    with pytest.raises(ValueError, match="unknown record type 'blip'"):
        encode_frame(1, 0, [("blip", dict(sender_id=1, level_id=0))])


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
