"""Record codec: round trip at the declared size, range errors on encode, reasons on decode."""
import pytest
from hypothesis import given, settings, strategies as st

from firmware.comms.codec import Reason, decode, encode
from firmware.schemes import all_dialects

RECORD_TYPES = tuple(r for d in all_dialects() for r in d.records)


def values_for(rt):
    return st.fixed_dictionaries({f.name: st.integers(f.min_value, f.max_value) for f in rt.fields})


any_record = st.sampled_from(RECORD_TYPES).flatmap(lambda rt: st.tuples(st.just(rt), values_for(rt)))


@settings(max_examples=400, deadline=None)
@given(any_record)
def test_round_trip_at_declared_size(rec):
    rt, values = rec
    data = encode(rt.name, values)
    assert len(data) == rt.size_bytes
    got = decode(rt.name, data)
    assert got.reason is Reason.OK and got.values == values
    assert encode(rt.name, rt.values_class(**values)) == data


@settings(max_examples=300, deadline=None)
@given(st.sampled_from(RECORD_TYPES).flatmap(lambda rt: st.tuples(st.just(rt), st.binary(min_size=0, max_size=16))))
def test_decode_never_raises(case):
    rt, data = case
    got = decode(rt, data)
    if len(data) != rt.size_bytes:
        assert got.reason in (Reason.TRUNCATED, Reason.BAD_LENGTH) and got.values is None
    elif got.reason is Reason.OK:
        assert encode(rt, got.values) == data      # the only bytes that decode to these values
    else:
        assert got.reason is Reason.OUT_OF_RANGE and got.values is None


def test_field_order_is_msb_first():
    values = dict(sender_id=0xAB, x_cm=-1, y_cm=0, z_cm=1, presence=1, e_inf_code=0xFF, info_version=0)
    assert encode("topo", values).hex() == "ab" "ffffff" "000000" "000001" "ff" "80"


def test_range_errors_name_field_and_range():
    v = dict(sender_id=1, x_cm=0, y_cm=0, yaw_cdeg=18001, speed_cmps=0, exploring=0, done=0,
             returning=0, vertex_count=0)
    with pytest.raises(ValueError, match=r"pose\.yaw_cdeg = 18001 outside valid range \[-18000, 18000\]"):
        encode("pose", v)
    with pytest.raises(ValueError, match=r"topo\.x_cm = 8388608 outside valid range \[-8388608, 8388607\]"):
        encode("topo", dict(sender_id=1, x_cm=1 << 23, y_cm=0, z_cm=0, presence=0, e_inf_code=0, info_version=0))
    with pytest.raises(ValueError, match=r"missing fields \['e_inf_code', 'info_version'\]"):
        encode("topo", dict(sender_id=1, x_cm=0, y_cm=0, z_cm=0, presence=0))
    with pytest.raises(ValueError, match="expected an integer"):
        encode("topo", dict(sender_id=1, x_cm=0.5, y_cm=0, z_cm=0, presence=0, e_inf_code=0, info_version=0))
    with pytest.raises(ValueError, match="unknown record type 'nope'"):
        encode("nope", {})


def test_decode_reports_out_of_range_and_padding():
    pose = all_dialects().record("pose")
    assert pose.padding_bits == 1
    good = encode(pose, dict(sender_id=1, x_cm=0, y_cm=0, yaw_cdeg=0, speed_cmps=0, exploring=0,
                             done=0, returning=0, vertex_count=0))
    word = int.from_bytes(good, "big")
    yaw_shift = 96 - (8 + 24 + 24) - 16
    bad = (word | (0x7FFF << yaw_shift)).to_bytes(12, "big")
    got = decode(pose, bad)
    assert got.reason is Reason.OUT_OF_RANGE and "yaw_cdeg = 32767" in got.detail
    padded = bytearray(good)
    padded[-1] |= 1
    got = decode(pose, bytes(padded))
    assert got.reason is Reason.OUT_OF_RANGE and "padding" in got.detail


def test_saturate_clamps_and_rounds_into_range():
    from firmware.comms.codec import saturate
    v = saturate("pose", dict(sender_id=3, x_cm=12.6, y_cm=-1e12, yaw_cdeg=40000, speed_cmps=999.0,
                              exploring=True, done=0, returning=float("nan"), vertex_count=5000))
    assert v == dict(sender_id=3, x_cm=13, y_cm=-(1 << 23), yaw_cdeg=18000, speed_cmps=255, exploring=1,
                     done=0, returning=0, vertex_count=4095)
    assert decode("pose", encode("pose", v)).values == v
    assert saturate("topo", dict(sender_id=1, x_cm=float("inf"), y_cm=float("-inf"), z_cm=7e9, presence=1,
                                 e_inf_code=-4, info_version=300)) == dict(
        sender_id=1, x_cm=(1 << 23) - 1, y_cm=-(1 << 23), z_cm=(1 << 23) - 1, presence=1, e_inf_code=0,
        info_version=127)
