"""MR-TopoMap's records (firmware/schemes/mr_topomap/records.py; mrtopomap.md 5.1, test 6.1.1):
fixed sizes, exact round trips, out-of-range values refused when encoding, and bytes from
the air never raising when decoding."""
from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from firmware.comms.codec import Reason
from firmware.comms.schema import CORE, DialectSet
from firmware.schemes import all_dialects
from firmware.schemes.mr_topomap import records as R
from firmware.schemes.mr_topomap.descriptor import Descriptor

SETTINGS = settings(max_examples=300, deadline=None)

u8 = st.integers(0, 255)
vid = st.integers(0, R.MAX_VERTEX_ID)
dm = st.integers(-(1 << 15), (1 << 15) - 1)
descriptors = st.builds(Descriptor, st.tuples(*[st.integers(0, 15)] * 32), st.integers(0, 31), st.integers(0, 7))
vertices = st.builds(R.Vertex, u8, vid, dm, dm, u8, st.integers(0, R.NO_VERTEX), st.integers(0, (1 << 32) - 1),
                     descriptors)
edges = st.builds(R.Edge, u8, u8, vid, u8, vid)
uds = st.builds(R.UdClear, u8, u8, vid, st.integers(0, 0xFFFF))
links = st.builds(R.Link, u8, u8, dm, dm, st.integers(0, R.DYAW_CODES - 1), st.integers(0, R.MAX_SUPPORT))

ENCODE = {"mrvtx": R.encode_vertex, "mredge": R.encode_edge, "mrud": R.encode_ud, "mrlink": R.encode_link}
TYPES = {"mrvtx": R.MRVTX, "mredge": R.MREDGE, "mrud": R.MRUD, "mrlink": R.MRLINK}


def test_sizes_are_the_specs():
    assert {r.name: r.size_bytes for r in R.DIALECT.records} == {"mrvtx": 30, "mredge": 6, "mrud": 6, "mrlink": 9}
    assert R.MRVTX.size_bytes <= 32


def test_the_dialect_is_registered_and_clashes_with_none():
    """Every node decodes it (firmware.schemes.all_dialects, through the mrtopomap scheme);
    its id and record names clash with no other dialect's."""
    registered = list(all_dialects())
    assert R.DIALECT in registered
    assert [d.id for d in registered].count(R.DIALECT.id) == 1
    DialectSet([CORE, R.DIALECT])


@SETTINGS
@given(vertices)
def test_vertex_round_trip(v):
    data = R.encode_vertex(v)
    assert len(data) == 30
    d = R.decode_vertex(data)
    assert d.reason is Reason.OK and d.value == v


@SETTINGS
@given(st.one_of(edges.map(lambda e: ("mredge", e)), uds.map(lambda u: ("mrud", u)),
                 links.map(lambda lk: ("mrlink", lk))))
def test_edge_ud_link_round_trip(item):
    name, value = item
    data = ENCODE[name](value)
    assert len(data) == TYPES[name].size_bytes
    d = R.DECODERS[name](data)
    assert d.reason is Reason.OK and d.value == value


@SETTINGS
@given(st.sampled_from(sorted(TYPES)), st.binary(min_size=0, max_size=40))
def test_random_bytes_never_raise(name, data):
    d = R.DECODERS[name](data)
    if len(data) != TYPES[name].size_bytes:
        assert d.value is None and d.reason in (Reason.TRUNCATED, Reason.BAD_LENGTH)
    if d.value is None:
        assert d.reason is not Reason.OK and d.detail
    else:
        assert d.reason is Reason.OK
        assert ENCODE[name](d.value) == data          # what decodes re-encodes to the same bytes


@SETTINGS
@given(st.sampled_from(sorted(TYPES)), st.data())
def test_non_zero_padding_is_refused(name, data):
    rt = TYPES[name]
    if rt.padding_bits == 0:
        return
    raw = bytearray(data.draw(st.binary(min_size=rt.size_bytes, max_size=rt.size_bytes)))
    raw[-1] |= 1 << data.draw(st.integers(0, rt.padding_bits - 1))
    d = R.DECODERS[name](bytes(raw))
    assert d.value is None and d.reason is Reason.OUT_OF_RANGE


def test_vertex_id_4095_is_refused_but_no_edge_is_not():
    v = R.Vertex(1, 0, 0, 0, 1, R.NO_VERTEX, 0, Descriptor((0,) * 32, 0, 0))
    assert R.decode_vertex(R.encode_vertex(v)).value == v
    with pytest.raises(ValueError, match="vertex_id"):
        R.encode_vertex(v._replace(vid=R.NO_VERTEX))
    raw = bytearray(R.encode_vertex(v))
    raw[1] |= 0xFF                                  # vertex_id's top 8 bits: id 4080 + ...
    raw[2] |= 0xF0                                  # ... its low 4 bits: 4095
    d = R.decode_vertex(bytes(raw))
    assert d.value is None and d.reason is Reason.OUT_OF_RANGE and "vertex_id" in d.detail


def test_out_of_range_values_are_refused_when_encoding():
    v = R.Vertex(1, 0, 0, 0, 1, R.NO_VERTEX, 0, Descriptor((0,) * 32, 0, 0))
    for bad, field in ((v._replace(x_dm=1 << 15), "x_dm"), (v._replace(owner=256), "sender_id"),
                       (v._replace(desc=Descriptor((0,) * 32, 32, 0)), "desc_mean"),
                       (v._replace(desc=Descriptor((0,) * 32, 0, 8)), "desc_std"),
                       (v._replace(ud_sectors=1 << 32), "ud_sectors")):
        with pytest.raises(ValueError, match=field):
            R.encode_vertex(bad)
    with pytest.raises(AssertionError):
        R.encode_vertex(v._replace(desc=Descriptor((16,) + (0,) * 31, 0, 0)))
    with pytest.raises(ValueError, match="clear_mask"):
        R.encode_ud(R.UdClear(1, 1, 0, 1 << 16))


def test_non_bytes_are_refused_not_raised():
    for decode in R.DECODERS.values():
        for junk in (None, 30, "x" * 30, [0] * 30):
            d = decode(junk)
            assert d.value is None and d.reason is Reason.BAD_LENGTH


def test_bit_order_of_packed_fields():
    codes = tuple(range(16)) * 2
    v = R.Vertex(7, 5, -1, 1, 7, 4, R.pack_sectors([3] + [0] * 14 + [1]), Descriptor(codes, 31, 7))
    vals = R.vertex_values(v)
    assert vals["desc_0"] == 0x01234567 and vals["desc_1"] == 0x89ABCDEF
    assert vals["ud_sectors"] == 3 | (1 << 30)
    assert R.sector_mask(vals["ud_sectors"]) == 1 | (1 << 15)
    assert R.clear_sectors(vals["ud_sectors"], 1) == 1 << 30
    assert R.sector_class(vals["ud_sectors"], 15) == 1


@SETTINGS
@given(st.integers(0, (1 << 32) - 1), st.integers(0, 0xFFFF), st.integers(0, 0xFFFF))
def test_clearing_sectors_is_and_not(ud, m1, m2):
    once = R.clear_sectors(R.clear_sectors(ud, m1), m2)
    assert once == R.clear_sectors(R.clear_sectors(ud, m2), m1) == R.clear_sectors(ud, m1 | m2)
    assert R.clear_sectors(once, m1) == once
    assert R.sector_mask(once) == R.sector_mask(ud) & ~(m1 | m2) & 0xFFFF
