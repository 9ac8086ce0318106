"""Record dialects: sizes, CRC catalogue check, fingerprints per dialect, dialect sets,
generated docs and classes."""
import dataclasses
import math

import crcmod.predefined
import pytest
from hypothesis import given, settings, strategies as st

from firmware.comms import schema
from firmware.comms.schema import (CORE, CRC_NAME, MAX_RECORD_BYTES, Dialect, DialectSet, Field, RecordType,
                                   check_table, markdown_table)
from firmware.schemes import all_dialects
from firmware.schemes.bayer_faigl.records import DIALECT as BF, TOPO


@pytest.mark.parametrize("name, check", [("modbus", 0x4B37), ("crc-16-dnp", 0xEA82),
                                         ("crc-16-mcrf4xx", 0x6F91), ("crc-ccitt-false", 0x29B1)])
def test_crc_catalogue_check_values(name, check):
    assert crcmod.predefined.mkPredefinedCrcFun(name)(b"123456789") == check


def test_frame_crc_is_modbus():
    assert CRC_NAME == "modbus"
    assert schema.crc16(b"123456789") == 0x4B37 == schema.CRC_CHECK


def _syndromes(crc_name: str, frame_bytes: int) -> list[int]:
    """CRC change caused by flipping each single bit of a frame (data bits, then CRC bits).
    The CRC is affine in the data, so an error pattern goes undetected exactly when the
    XOR of its bits' syndromes is zero."""
    crc = crcmod.predefined.mkPredefinedCrcFun(crc_name)
    data = bytes((7 * i + 3) & 0xFF for i in range(frame_bytes - 2))
    ref = crc(data)
    out = []
    for i in range(len(data) * 8):
        b = bytearray(data)
        b[i // 8] ^= 0x80 >> (i % 8)
        out.append(crc(bytes(b)) ^ ref)
    return out + [1 << k for k in range(16)]


def test_every_1_and_2_bit_error_in_a_max_size_frame_is_detected():
    s = _syndromes(CRC_NAME, 255)
    assert 0 not in s                      # every single-bit error
    assert len(set(s)) == len(s)           # every pair of distinct bits: s_i ^ s_j != 0


def test_why_not_dnp_some_2_bit_errors_pass_it():
    assert len(set(_syndromes("crc-16-dnp", 17))) == 17 * 8          # fine up to 151 bits
    s = _syndromes("crc-16-dnp", 64)
    assert len(set(s)) < len(s)


def test_topo_is_bayer_faigl_table_1_plus_a_revision_in_the_padding():
    widths = {f.name: f.bits for f in TOPO.fields}
    assert widths == {"sender_id": 8, "x_cm": 24, "y_cm": 24, "z_cm": 24, "presence": 1, "e_inf_code": 8,
                      "info_version": 7}
    assert TOPO.bits_used == 96 and TOPO.size_bytes == 12 and TOPO.padding_bits == 0
    assert (BF.id, BF.name, BF.records) == (1, "bayer_faigl", (TOPO,))


def test_the_core_dialect_holds_the_heartbeat():
    assert (CORE.id, CORE.name, [r.name for r in CORE.records]) == (0, "core", ["pose"])
    assert CORE.by_name["pose"].size_bytes == 12


def test_every_type_is_tightly_packed_and_fits_a_frame():
    for d in all_dialects():
        for r in d.records:
            assert r.size_bytes == math.ceil(r.bits_used / 8)
            assert r.size_bytes <= MAX_RECORD_BYTES == 255 - 7 - 1 - 2
            assert 1 <= r.code <= 15


def test_bad_rows_are_caught_by_the_dialect_check():
    with pytest.raises(AssertionError, match="declared 11 B"):
        check_table((dataclasses.replace(TOPO, size_bytes=11),))
    with pytest.raises(AssertionError, match="duplicate record type code"):
        Dialect(5, "x", (TOPO, dataclasses.replace(TOPO, name="topo2")))
    with pytest.raises(AssertionError, match="does not fit"):
        Dialect(5, "x", (RecordType(4, "x", 1, (Field("v_cm", 8, lo=0, hi=300),)),))
    with pytest.raises(AssertionError, match="code 16 outside 1..15"):
        Dialect(5, "x", (dataclasses.replace(TOPO, code=16),))
    with pytest.raises(AssertionError, match="code 0 outside"):
        Dialect(5, "x", (dataclasses.replace(TOPO, code=0),))
    wide = RecordType(1, "wide", 246, tuple(Field(f"v{i}_id", 8) for i in range(246)))
    with pytest.raises(AssertionError, match="at most 245 B"):
        Dialect(5, "x", (wide,))
    Dialect(5, "x", (RecordType(1, "widest", 245, tuple(Field(f"v{i}_id", 8) for i in range(245))),))
    with pytest.raises(AssertionError, match="id 256 outside"):
        Dialect(256, "x", ())


def test_dialect_sets_check_ids_and_names_across_dialects():
    other = Dialect(2, "other", (dataclasses.replace(TOPO, name="vertex"),))
    ds = DialectSet([CORE, BF, other])
    assert [d.id for d in ds] == [0, 1, 2] and ds.core is CORE
    assert ds.lookup(1, 1) is TOPO and ds.lookup(2, 1).name == "vertex" and ds.lookup(0, 1).name == "pose"
    assert ds.lookup(1, 2) is None and ds.lookup(3, 1) is None
    assert ds.record("topo") is TOPO and ds.dialect_of("vertex") is other and ds.dialect_of("pose") is CORE
    assert ds.fingerprints() == {"core": CORE.fingerprint, "bayer_faigl": BF.fingerprint, "other": other.fingerprint}
    with pytest.raises(ValueError, match="unknown record type 'nope'"):
        ds.record("nope")
    with pytest.raises(AssertionError, match="record name 'topo' in dialects 'bayer_faigl' and 'clash'"):
        DialectSet([CORE, BF, Dialect(3, "clash", (TOPO,))])
    with pytest.raises(AssertionError, match="dialect id 1 used by 'bayer_faigl' and 'other'"):
        DialectSet([CORE, BF, dataclasses.replace(other, id=1)])
    with pytest.raises(AssertionError, match="two dialects named 'bayer_faigl'"):
        DialectSet([CORE, BF, dataclasses.replace(other, name="bayer_faigl")])
    with pytest.raises(AssertionError, match="needs the core dialect"):
        DialectSet([BF])
    assert len(DialectSet([CORE, BF, BF])) == 2          # two schemes sharing one dialect


def test_fingerprint_tracks_wire_relevant_changes_only():
    widened = dataclasses.replace(TOPO, fields=tuple(
        dataclasses.replace(f, lo=-100, hi=100) if f.name == "z_cm" else f for f in TOPO.fields))
    assert Dialect(1, "bayer_faigl", (widened,)).fingerprint != BF.fingerprint
    assert Dialect(2, "bayer_faigl", (TOPO,)).fingerprint != BF.fingerprint          # id
    assert Dialect(1, "bayer_faigl_2", (TOPO,)).fingerprint != BF.fingerprint        # name
    assert schema.fingerprint(1, "bayer_faigl", (TOPO,), version=3) != BF.fingerprint
    reworded = Dialect(1, "bayer_faigl", tuple(dataclasses.replace(r, doc="different words") for r in BF.records))
    assert reworded.fingerprint == BF.fingerprint
    assert CORE.fingerprint != BF.fingerprint


def _mutations(rt: RecordType):
    """Strategy: a wire-relevant change to one field of `rt` (the record stays valid)."""
    def mutate(args):
        i, kind = args
        f = rt.fields[i]
        if kind == "name":
            g = dataclasses.replace(f, name=f.name + "_x")
        elif kind == "unit":
            g = dataclasses.replace(f, unit=f.unit + "!")
        elif kind == "range":
            g = dataclasses.replace(f, hi=f.max_value - 1, lo=min(f.min_value, f.max_value - 1))
        else:   # swap with the next field: same bits, another layout
            j = (i + 1) % len(rt.fields)
            if rt.fields[j] == f:
                return None
            fields = list(rt.fields)
            fields[i], fields[j] = fields[j], fields[i]
            return dataclasses.replace(rt, fields=tuple(fields))
        return dataclasses.replace(rt, fields=tuple(g if k == i else x for k, x in enumerate(rt.fields)))
    return st.tuples(st.integers(0, len(rt.fields) - 1),
                     st.sampled_from(["name", "unit", "range", "order"])).map(mutate).filter(lambda r: r is not None)


@settings(max_examples=100, deadline=None)
@given(st.sampled_from(sorted(all_dialects().record_names())).flatmap(
    lambda name: st.tuples(st.just(name), _mutations(all_dialects().record(name)))))
def test_changing_one_dialects_table_changes_its_fingerprint_only(case):
    name, changed = case
    ds = all_dialects()
    owner = ds.dialect_of(name)
    mine = Dialect(owner.id, owner.name, tuple(changed if r.name == name else r for r in owner.records))
    assert mine.fingerprint != owner.fingerprint
    rebuilt = DialectSet([mine if d.id == owner.id else d for d in ds])
    for d in rebuilt:
        assert (d.fingerprint == ds.get(d.id).fingerprint) == (d.id != owner.id), d.name


def test_markdown_lists_every_dialect_and_field_with_unit_and_range():
    md = markdown_table()
    for d in all_dialects():
        assert f"## Dialect {d.id} `{d.name}` (fingerprint 0x{d.fingerprint:04X})" in md
        for r in d.records:
            assert f"### `{r.name}` (dialect {d.id}, code {r.code}, {r.size_bytes} bytes" in md
            for f in r.fields:
                assert f"| `{f.name}` | {f.bits} |" in md
                assert f"{f.min_value} .. {f.max_value}" in md
    assert "0.01 deg" in md


def test_generated_dataclasses_are_frozen_and_complete():
    for d in all_dialects():
        for r in d.records:
            cls = r.values_class
            assert cls.__name__ == "".join(p.capitalize() for p in r.name.split("_")) + "Record"
            assert [f.name for f in dataclasses.fields(cls)] == [f.name for f in r.fields]
            inst = cls(**{f.name: f.min_value for f in r.fields})
            with pytest.raises(dataclasses.FrozenInstanceError):
                inst.sender_id = 1
