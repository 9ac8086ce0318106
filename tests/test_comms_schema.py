"""The record table: sizes, CRC catalogue check, fingerprint, generated docs and classes."""
import dataclasses
import math

import crcmod.predefined
import pytest

from firmware.comms import schema
from firmware.comms.schema import (BY_NAME, CRC_NAME, RECORD_CLASSES, RECORD_TYPES, Field,
                                   RecordType, check_table, e_inf_bit_to_code, e_inf_code_to_bit,
                                   fingerprint, markdown_table)


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
    topo = BY_NAME["topo"]
    widths = {f.name: f.bits for f in topo.fields}
    assert widths == {"sender_id": 8, "x_cm": 24, "y_cm": 24, "z_cm": 24, "presence": 1, "e_inf_code": 8,
                      "info_version": 7}
    assert topo.bits_used == 96 and topo.size_bytes == 12 and topo.padding_bits == 0


def test_every_type_is_tightly_packed_and_within_12_bytes():
    for r in RECORD_TYPES:
        assert r.size_bytes == math.ceil(r.bits_used / 8)
        assert r.size_bytes <= 12
        assert 1 <= r.code <= 15


def test_bad_rows_are_caught_by_the_import_check():
    good = BY_NAME["topo"]
    with pytest.raises(AssertionError, match="declared 11 B"):
        check_table((dataclasses.replace(good, size_bytes=11),))
    with pytest.raises(AssertionError, match="duplicate record type code"):
        check_table((good, dataclasses.replace(good, name="topo2")))
    with pytest.raises(AssertionError, match="does not fit"):
        check_table((RecordType(4, "x", 1, (Field("v_cm", 8, lo=0, hi=300),)),))


def test_fingerprint_tracks_wire_relevant_changes_only():
    base = fingerprint()
    topo = BY_NAME["topo"]
    widened = dataclasses.replace(topo, fields=tuple(
        dataclasses.replace(f, lo=-100, hi=100) if f.name == "z_cm" else f for f in topo.fields))
    other = tuple(widened if r.name == "topo" else r for r in RECORD_TYPES)
    assert fingerprint(other) != base
    assert fingerprint(version=2) != base
    reworded = tuple(dataclasses.replace(r, doc="different words") for r in RECORD_TYPES)
    assert fingerprint(reworded) == base


def test_markdown_lists_every_field_with_unit_and_range():
    md = markdown_table()
    for r in RECORD_TYPES:
        assert f"### `{r.name}` (type {r.code}, {r.size_bytes} bytes" in md
        for f in r.fields:
            assert f"| `{f.name}` | {f.bits} |" in md
            assert f"{f.min_value} .. {f.max_value}" in md
    assert "0.01 deg" in md


def test_generated_dataclasses_are_frozen_and_complete():
    for r in RECORD_TYPES:
        cls = RECORD_CLASSES[r.name]
        assert [f.name for f in dataclasses.fields(cls)] == [f.name for f in r.fields]
        inst = cls(**{f.name: f.min_value for f in r.fields})
        with pytest.raises(dataclasses.FrozenInstanceError):
            inst.sender_id = 1


def test_e_inf_scale_is_monotone_and_saturating():
    codes = [e_inf_bit_to_code(e) for e in (0.0, 0.5, 1.0, 10.0, 100.0, 1e4, 1e5, 1e9)]
    assert codes == sorted(codes) and codes[0] == 0 and codes[-1] == 255
    assert e_inf_bit_to_code(float("nan")) == 0 and e_inf_bit_to_code(-3.0) == 0
    for code in range(256):
        assert e_inf_bit_to_code(e_inf_code_to_bit(code)) == code
    # 16 codes per octave: relative step about 4.4 %
    assert e_inf_code_to_bit(200) / e_inf_code_to_bit(199) == pytest.approx(2 ** (1 / 16), rel=1e-3)
