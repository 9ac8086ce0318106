"""Meier et al.'s records on the air (firmware/schemes/meier/records.py): fixed sizes, and
every vertex state and alive block the sender can make survives the codec."""
import dataclasses

from hypothesis import given, settings
from hypothesis import strategies as st

from firmware.comms.codec import decode, encode
from firmware.comms.frame import frame_size_bytes
from firmware.comms.schema import MAX_FRAME_BYTES, record_type
from firmware.schemes.meier.records import alive_record, alive_values, nack_seqs, nack_values, poly_record, poly_values
from firmware.schemes.meier.replica import MAX_VERTEX_ID, AliveRecord, PolyRecord


def test_records_are_small_and_twenty_vertices_fit_a_frame():
    assert [record_type(n).size_bytes for n in ("poly", "poly_gone", "poly_alive", "target")] == [12, 8, 12, 8]
    assert frame_size_bytes({"poly": 20}) <= MAX_FRAME_BYTES


ids = st.integers(1, MAX_VERTEX_ID)
lattice = st.integers(-(1 << 14), (1 << 14) - 1)


@settings(max_examples=300, deadline=None)
@given(st.builds(PolyRecord, st.integers(0, 255), st.integers(0, 65535), ids, ids, ids, lattice, lattice,
                 st.integers(0, 1), st.booleans(), st.integers(0, 4)))
def test_a_vertex_state_survives_the_codec_and_a_removed_one_goes_short_without_its_place(r):
    rtype, values = poly_values(r)
    assert rtype == ("poly" if r.alive else "poly_gone")
    got = poly_record(rtype, decode(rtype, encode(rtype, values)).values)
    assert got == (r if r.alive else dataclasses.replace(r, x_lat=0, y_lat=0, edge_type=0))


@settings(max_examples=300, deadline=None)
@given(st.builds(AliveRecord, st.integers(0, 255), st.integers(0, 65535), st.integers(0, 63),
                 st.integers(0, (1 << 64) - 1)))
def test_an_alive_block_survives_the_codec(r):
    got = decode("poly_alive", encode("poly_alive", alive_values(r)))
    assert alive_record(got.values) == r


@settings(max_examples=300, deadline=None)
@given(st.integers(0, 65535), st.lists(st.integers(1, 40), max_size=30))
def test_lost_frames_named_in_nack_records_are_exactly_those_lost(first, steps):
    seqs = [first]
    for d in steps:
        seqs.append((seqs[-1] + d) % 65536)
    records = nack_values(3, 1, seqs)
    assert len(records) <= len(seqs)
    named = [seq for v in records for seq in nack_seqs(decode("poly_nack", encode("poly_nack", v)).values)]
    assert named == seqs
