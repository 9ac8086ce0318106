"""Stream deframer: chunking does not matter, garbage is skipped, CRC failures resync."""
from hypothesis import given, settings, strategies as st

from firmware.comms.frame import Reason, encode_frame
from firmware.comms.schema import CORE, SENDER, Dialect, DialectSet, Field, RecordType
from firmware.comms.stream import Deframer
from firmware.schemes import all_dialects
from firmware.schemes.bayer_faigl.records import DIALECT as BF

RECORD_TYPES = CORE.records + BF.records


def values_for(rt):
    return st.fixed_dictionaries({f.name: st.integers(f.min_value, f.max_value) for f in rt.fields})


record = st.sampled_from(RECORD_TYPES).flatmap(lambda rt: st.tuples(st.just(rt.name), values_for(rt)))
frame = st.builds(lambda s, q, recs: encode_frame(s, q, recs), st.integers(0, 255), st.integers(0, 65535),
                  st.lists(record, min_size=1, max_size=4))


def run(stream: bytes, cuts: list[int]) -> list[bytes]:
    d, out, prev = Deframer(), [], 0
    for c in sorted(set(cuts)) + [len(stream)]:
        out += d.feed(stream[prev:c])
        prev = c
    out += d.flush()
    return [(r.reason, r.frame) for r in out]


@settings(max_examples=150, deadline=None)
@given(st.lists(frame, min_size=1, max_size=6), st.data())
def test_any_split_yields_the_same_frames(frames, data):
    stream = b"".join(frames)
    cuts = data.draw(st.lists(st.integers(0, len(stream)), max_size=12))
    got = run(stream, cuts)
    assert got == run(stream, [])
    assert [f.size_bytes for _, f in got] == [len(f) for f in frames]
    assert all(r is Reason.OK for r, _ in got)


def test_byte_at_a_time_equals_whole():
    frames = [encode_frame(i, i, [("topo", dict(sender_id=i, x_cm=i, y_cm=0, z_cm=0, presence=1, e_inf_code=9, info_version=0))])
              for i in range(5)]
    stream = b"".join(frames)
    assert run(stream, list(range(len(stream)))) == run(stream, [])


@settings(max_examples=150, deadline=None)
@given(st.binary(max_size=300), st.lists(frame, min_size=1, max_size=4), st.data())
def test_garbage_before_frames_is_skipped(garbage, frames, data):
    stream = garbage + b"".join(frames)
    cuts = data.draw(st.lists(st.integers(0, len(stream)), max_size=8))
    got = [f for r, f in run(stream, cuts) if r is Reason.OK]
    # Garbage may by chance contain a valid frame (CRC-16: ~1 in 65536 per candidate), so
    # compare the tail: every real frame comes out, in order, at the end.
    want = [len(f) for f in frames]
    assert [f.size_bytes for f in got[-len(frames):]] == want
    assert [f.seq for f in got[-len(frames):]] == [int.from_bytes(f[4:6], "big") for f in frames]


def test_corrupted_frame_between_good_ones_costs_only_itself():
    mk = lambda i: encode_frame(1, i, [("topo", dict(sender_id=1, x_cm=i, y_cm=0, z_cm=0, presence=0, e_inf_code=0, info_version=0))])
    bad = bytearray(mk(2))
    bad[9] ^= 0x10
    stream = mk(1) + bytes(bad) + mk(3)
    d = Deframer()
    got = d.feed(stream) + d.flush()
    assert [r.frame.seq for r in got] == [1, 3]
    assert d.stats["bytes_skipped"] == len(bad) and d.stats["crc_rejects"] >= 1
    assert d.stats["bytes_in"] == len(stream)


def test_truncated_tail_is_released_by_flush():
    f = encode_frame(1, 1, [("topo", dict(sender_id=1, x_cm=0, y_cm=0, z_cm=0, presence=0, e_inf_code=0, info_version=0))])
    d = Deframer()
    assert d.feed(f + f[:10]) and d.pending_bytes == 10
    assert d.flush() == [] and d.pending_bytes == 0


@settings(max_examples=200, deadline=None)
@given(st.lists(st.binary(max_size=80), max_size=10))
def test_arbitrary_chunks_never_raise_and_every_byte_is_accounted(chunks):
    d = Deframer()
    for c in chunks:
        d.feed(c)
        st = d.stats
        assert st["bytes_in"] == st["bytes_skipped"] + st["bytes_framed"] + d.pending_bytes
    d.flush()
    assert d.pending_bytes == 0 and d.stats["bytes_in"] == d.stats["bytes_skipped"] + d.stats["bytes_framed"]


def test_a_frame_of_an_unknown_dialect_is_stepped_over_like_garbage():
    """Its CRC cannot be checked, so it is no better than noise: the scan resyncs through
    it, and frames after it still come out."""
    other = Dialect(200, "other", (RecordType(1, "blip", 2, (SENDER, Field("level_id", 8))),))
    theirs = encode_frame(4, 9, [("blip", dict(sender_id=4, level_id=1))],
                          dialects=DialectSet([*all_dialects(), other]))
    ours = encode_frame(1, 1, [("topo", dict(sender_id=1, x_cm=0, y_cm=0, z_cm=0, presence=0, e_inf_code=0,
                                             info_version=0))])
    d = Deframer()
    got = d.feed(ours + theirs + ours) + d.flush()
    assert [(r.reason, r.frame.seq) for r in got] == [(Reason.OK, 1), (Reason.OK, 1)]
    assert d.stats["dialect_rejects"] >= 1 and d.stats["bytes_skipped"] == len(theirs)
