"""Pereira records (firmware/schemes/pereira/records.py): fixed sizes (pereira.md 5.4), every
record survives the codec, and any bytes decode to a record or a reason, never an exception."""
import math

import pytest
from hypothesis import given, settings, strategies as st

from firmware.comms.codec import Reason
from firmware.comms.schema import CORE
from firmware.schemes import all_dialects
from firmware.schemes.pereira.records import (
    CLAIM, DIALECT, EMPTY_ORIGIN, GATE, INTENT, PLACE, SUMMARY, SUMMARY_SLOTS, Claim, Gate, Intent, Place,
    Summary, decode, dir_code_of, dm, encode, half_2cm_of, record_name, serial_newer)

u8, u16 = st.integers(0, 255), st.integers(0, 65535)
s16 = st.integers(-(1 << 15), (1 << 15) - 1)
places = st.builds(Place, u8, u16, s16, s16, u8, st.integers(0, 15))
gates = st.builds(Gate, u8, u16, s16, s16, u8, u8)
claims = st.builds(Claim, u8, u16, s16, s16, u16, st.integers(0, 1), st.integers(0, 1))
intents = st.builds(Intent, u8, s16, s16, s16, s16, st.integers(0, 4095), st.integers(0, 3), st.integers(0, 3), u8)
summaries = st.builds(Summary, u8, st.lists(st.tuples(st.integers(0, 254), u16), max_size=SUMMARY_SLOTS).map(tuple))
records = st.one_of(places, gates, claims, intents, summaries)
NAMES = ("place", "gate", "claim", "intent", "summary")


def test_sizes_are_the_specs():
    assert [r.size_bytes for r in (PLACE, GATE, CLAIM, INTENT, SUMMARY)] == [9, 9, 10, 12, 16]
    assert [r.bits_used for r in (PLACE, GATE, CLAIM, INTENT, SUMMARY)] == [68, 72, 74, 96, 128]
    assert DIALECT.id == 3 and [r.code for r in DIALECT.records] == [1, 2, 3, 4, 5]


def test_the_dialect_is_registered_beside_the_others():
    """Every node decodes it (the scheme is registered), and its id, record names and
    fingerprint clash with no other dialect (checked by DialectSet)."""
    ds = all_dialects()
    assert DIALECT in ds and CORE in ds
    assert len({d.fingerprint for d in ds}) == len(ds)


@settings(max_examples=400, deadline=None)
@given(records)
def test_every_record_survives_the_codec(r):
    data = encode(r)
    name = record_name(r)
    assert len(data) == {"place": 9, "gate": 9, "claim": 10, "intent": 12, "summary": 16}[name]
    got = decode(name, data)
    assert got.reason == Reason.OK and got.record == r


@settings(max_examples=400, deadline=None)
@given(st.sampled_from(NAMES), st.binary(max_size=24))
def test_any_bytes_decode_to_a_record_or_a_reason(name, data):
    got = decode(name, data)
    if got.record is None:
        assert got.reason != Reason.OK and got.detail
    else:
        assert got.reason == Reason.OK
        assert encode(got.record) == data              # one encoding per record


@settings(max_examples=200, deadline=None)
@given(st.sampled_from(NAMES), st.data())
def test_random_bytes_of_the_right_size(name, data):
    size = {"place": 9, "gate": 9, "claim": 10, "intent": 12, "summary": 16}[name]
    raw = data.draw(st.binary(min_size=size, max_size=size))
    got = decode(name, raw)
    assert (got.record is None) == (got.reason != Reason.OK)
    if got.record is not None:
        assert encode(got.record) == raw


def test_rejections_say_why():
    assert decode("place", b"\x00" * 8).reason == Reason.TRUNCATED
    assert decode("place", b"\x00" * 10).reason == Reason.BAD_LENGTH
    assert decode("place", b"\x00" * 8 + b"\x01").reason == Reason.OUT_OF_RANGE      # padding bits set
    empty_with_count = bytearray(encode(Summary(1, ())))
    empty_with_count[-1] = 7                       # the last slot's counter, its origin 255
    got = decode("summary", bytes(empty_with_count))
    assert got.record is None and got.reason == Reason.OUT_OF_RANGE and "empty slot" in got.detail
    with pytest.raises(ValueError):
        decode("nothing", b"")
    with pytest.raises(ValueError):
        encode(Place(1, 70000, 0, 0, 0, 0))
    with pytest.raises(ValueError):
        encode(Summary(1, ((2, 3),) * 6))
    with pytest.raises(ValueError):
        encode(Summary(1, ((EMPTY_ORIGIN, 3),)))


def test_wire_units():
    assert dm(1.04) == 10 and dm(-0.05) == 0 and dm(1e9) == 32767 and dm(-1e9) == -32768
    assert dir_code_of(0.0) == 0 and dir_code_of(math.pi / 2) == 128 and dir_code_of(math.pi - 1e-6) == 0
    assert dir_code_of(-math.pi / 4) == 192
    assert half_2cm_of(0.46) == 23 and half_2cm_of(0.5) == 25
    assert half_2cm_of(9.0) == 255 and half_2cm_of(-1.0) == 0


def test_serial_order():
    assert serial_newer(1, 0) and not serial_newer(0, 1)
    assert serial_newer(0, 65535) and serial_newer(100, 65000)
    assert not serial_newer(5, 5) and not serial_newer(32768, 0) and not serial_newer(0, 32768)
