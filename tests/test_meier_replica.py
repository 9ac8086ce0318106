"""Meier et al.'s polygon records (firmware/schemes/meier): a receiver's copy of a
teammate's rings is a pure function of the records it holds, whatever their order,
duplicates and losses, once a refresh has come (meier.md 5.3, tests R1-R6)."""
from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from firmware.comms.codec import decode, encode
from firmware.schemes.meier.polygons import PolygonMap
from firmware.schemes.meier.records import alive_record, alive_values, poly_record, poly_values
from firmware.schemes.meier.replica import SUM_PARTS, AliveRecord, Replica

SETTINGS = settings(max_examples=400, deadline=None)


def _edit(pm: PolygonMap, rng: np.random.Generator) -> None:
    """One random change of the kinds the paper names: a new ring, an edge split, a vertex
    vanishing, a ring broken in two (or two rings joined: the same relink)."""
    rings = pm.rings()
    op = rng.integers(0, 4) if rings else 0
    if op == 0 or len(rings) == 0:
        n = int(rng.integers(2, 5))
        pm.new_ring([(int(rng.integers(-500, 500)), int(rng.integers(-500, 500)), int(rng.integers(0, 2)))
                     for _ in range(n)])
        return
    ring = rings[int(rng.integers(0, len(rings)))]
    if op == 1:
        pm.split_edge(ring[int(rng.integers(0, len(ring)))], int(rng.integers(-500, 500)), int(rng.integers(-500, 500)))
    elif op == 2:
        for v in (ring if len(ring) == 2 else [ring[int(rng.integers(0, len(ring)))]]):
            pm.vanish(v)                            # a ring of two goes whole
    else:
        every = [v for r in rings for v in r]
        u, w = (every[int(k)] for k in rng.integers(0, len(every), 2))
        relinked = _with_edge(rings, u, w)
        if all(len(r) >= 2 for r in relinked):      # else it would leave a ring of one vertex
            pm.relink(relinked)


def _with_edge(rings: list[list[int]], u: int, w: int) -> list[list[int]]:
    """The rings with u -> w an edge and pred(w) -> the old succ(u): one ring broken in two,
    or two joined."""
    succ = {r[k]: r[(k + 1) % len(r)] for r in rings for k in range(len(r))}
    pred = {b: a for a, b in succ.items()}
    succ[u], succ[pred[w]] = w, succ[u]
    out, seen = [], set()
    for v in sorted(succ):
        if v not in seen:
            ring = [v]
            while succ[ring[-1]] != v:
                ring.append(succ[ring[-1]])
            seen.update(ring)
            out.append(ring)
    return out


def _history(seed: int, first_stamp: int = 0):
    """A sender edited at random, flushing now and then: (its map, every record sent)."""
    rng = np.random.default_rng(seed)
    pm = PolygonMap(sender_id=3, first_stamp=first_stamp)
    records = []
    for _ in range(int(rng.integers(1, 60))):
        _edit(pm, rng)
        if rng.random() < 0.4:
            records += pm.flush()
    records += pm.flush()
    return pm, records, rng


def _sender_rings(pm: PolygonMap):
    return [[(v, *pm.vertex(v)) for v in ring] for ring in pm.rings()]


def _over_the_air(r):
    """The record as a receiver gets it: encoded in its record type and decoded."""
    if isinstance(r, AliveRecord):
        return alive_record(decode("poly_alive", encode("poly_alive", alive_values(r))).values)
    rtype, values = poly_values(r)
    return poly_record(rtype, decode(rtype, encode(rtype, values)).values)


def _replica_rings(records) -> list:
    rep = Replica()
    for r in records:
        rep.add(_over_the_air(r))
    return [[(v.vertex_id, v.x_lat, v.y_lat, v.edge_type) for v in ring] for ring in rep.rings()]


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.sampled_from([0, 65500]))
def test_every_record_in_any_order_and_twice_gives_the_senders_rings(seed, first_stamp):
    pm, records, rng = _history(seed, first_stamp)
    doubled = records + [records[int(k)] for k in rng.integers(0, len(records), len(records) // 2)] if records else []
    rng.shuffle(doubled)
    assert _replica_rings(doubled) == _sender_rings(pm)


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.floats(0.2, 0.9), st.sampled_from([0, 65500]))
def test_any_loss_then_one_refresh_gives_the_senders_rings(seed, loss, first_stamp):
    pm, records, rng = _history(seed, first_stamp)
    kept = [r for r in records if rng.random() >= loss]
    held = kept + pm.refresh() + [records[int(k)] for k in rng.integers(0, len(records), 5)] if records else pm.refresh()
    rng.shuffle(held)
    assert _replica_rings(held) == _sender_rings(pm)


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.floats(0.0, 0.9))
def test_the_same_records_in_another_order_give_the_same_rings_and_never_raise(seed, loss):
    _, records, rng = _history(seed)
    held = [r for r in records if rng.random() >= loss]
    other = list(held)
    rng.shuffle(other)
    rings = _replica_rings(held)
    assert rings == _replica_rings(other)
    for ring in rings:                               # simple cycles over distinct ids
        assert len({v[0] for v in ring}) == len(ring)


def test_a_split_costs_one_record_and_a_vanished_vertex_one():
    pm = PolygonMap(sender_id=1)
    a, b, c = pm.new_ring([(0, 0, 0), (10, 0, 0), (10, 10, 1)])
    records = pm.flush()
    d = pm.split_edge(a, 5, -1)
    split = pm.flush()
    assert [r.vertex_id for r in split] == [d]                  # it claims a -> d -> b itself
    pm.vanish(c)
    gone = pm.flush()
    assert [(r.vertex_id, r.alive) for r in gone] == [(c, False)]   # its tombstone joins b -> a
    assert _replica_rings(records + split + gone) == _sender_rings(pm)


def test_a_removed_id_is_reused_after_its_tombstone_and_every_receiver_stays_exact():
    pm = PolygonMap(sender_id=1)
    a, b, c, d = pm.new_ring([(0, 0, 0), (10, 0, 0), (10, 10, 1), (0, 10, 0)])
    records = pm.flush()
    pm.vanish(b)                                     # a -> c now
    assert b not in pm.new_ring([(50, 50, 0), (60, 50, 0)])     # its tombstone has not gone out
    records += pm.flush()
    assert b in pm.new_ring([(70, 70, 0), (80, 70, 0)])         # now it has: the smallest removed id
    sent = pm.flush()
    # b's new state replaces its old one at every receiver, so a's link to c is sent again.
    assert a in {r.vertex_id for r in sent}
    rng = np.random.default_rng(0)
    for _ in range(20):
        held = records + sent
        rng.shuffle(held)
        assert _replica_rings(held) == _sender_rings(pm)


def test_a_ring_whose_tombstones_were_all_lost_is_gone_after_a_refresh():
    pm = PolygonMap(sender_id=2)
    keep = pm.new_ring([(0, 0, 0), (10, 0, 1), (10, 10, 0)])
    gone = pm.new_ring([(50, 50, 0), (60, 50, 1)])
    first = pm.flush()
    for v in gone:                                    # a ring of two goes whole
        pm.vanish(v)
    lost = pm.flush()
    assert {r.vertex_id for r in lost} == set(gone) and not any(r.alive for r in lost)
    held = first + pm.refresh()                       # every tombstone lost
    assert [[v.vertex_id for v in ring] for ring in _replica_rings_of(held)] == [keep]


def test_a_ring_cut_open_by_lost_records_is_closed_across_the_gap():
    pm = PolygonMap(sender_id=4)
    ids = pm.new_ring([(0, 0, 1), (10, 0, 1), (20, 0, 1), (20, 10, 0), (10, 10, 1), (0, 10, 1)])
    records = pm.flush()
    lost = {ids[2], ids[3]}                           # two neighbours: one gap
    held = [r for r in records if r.vertex_id not in lost]
    assert [[v.vertex_id for v in ring] for ring in _replica_rings_of(held)] == [
        [v for v in ids if v not in lost]]
    two_gaps = [r for r in records if r.vertex_id not in {ids[1], ids[4]}]   # two pieces, each closed
    assert [[v.vertex_id for v in ring] for ring in _replica_rings_of(two_gaps)] == [
        [ids[0], ids[5]], [ids[2], ids[3]]]


def _replica_rings_of(records):
    rep = Replica()
    for r in records:
        rep.add(_over_the_air(r))
    return rep.rings()


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.floats(0.05, 0.9))
def test_block_summaries_find_the_parts_a_receiver_lacks_and_sending_those_again_makes_it_exact(seed, loss):
    pm, records, rng = _history(seed, 65500)
    complete, lossy = Replica(), Replica()
    for r in records:
        complete.add(_over_the_air(r))
    for r in records:
        if rng.random() >= loss:
            lossy.add(_over_the_air(r))
    collided = False
    for block in range(pm.blocks()):
        sent = pm.block_digests(block)
        assert complete.block_digests(block) == sent                  # a receiver of every record agrees
        assert not complete.holds_since(block, pm.next_stamp)         # and holds nothing newer than that
        held = lossy.block_digests(block)
        parts = sum(1 << k for k in range(SUM_PARTS) if held[k] != sent[k])
        for k in range(SUM_PARTS):
            lacks = any(lossy.held(v) != complete.held(v) for v in complete.block_ids(block, 1 << k))
            assert lacks or not parts >> k & 1                         # a part that differs lacks something
            collided |= lacks and not parts >> k & 1                   # once in 2^12, a part that lacks does not
        for r in pm.block_records(block, parts):
            lossy.add(_over_the_air(r))
        assert lossy.block_digests(block) == sent
    got = [[(v.vertex_id, v.x_lat, v.y_lat, v.edge_type) for v in ring] for ring in lossy.rings()]
    assert collided or got == _sender_rings(pm)
