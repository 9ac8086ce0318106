"""The polygon map following a growing observed area (firmware/schemes/meier/tracker.py):
after every update each ring lies on one contour in its order, vertices never move, refined
to the end no corner is farther than eps from its edge, and a receiver of every record
holds the same rings."""
from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from firmware import kernels
from firmware.schemes.meier.contours import smooth_edge_types, trace_contours
from firmware.schemes.meier.replica import Replica
from firmware.schemes.meier.simplify import point_segment_distance
from firmware.schemes.meier.tracker import PolygonTracker


def _growing_maps(seed: int, steps: int):
    """A map observed bit by bit: discs of free space seen one after another, walls among
    them, some free ground later seen to be wall."""
    rng = np.random.default_rng(seed)
    rows, cols = (int(v) for v in rng.integers(8, 40, 2))
    state = np.full((rows, cols), kernels.UNKNOWN, np.uint8)
    yy, xx = np.mgrid[0:rows, 0:cols]
    for _ in range(steps):
        cy, cx, r = rng.uniform(0, rows), rng.uniform(0, cols), rng.uniform(1.5, 8)
        disc = (yy - cy) ** 2 + (xx - cx) ** 2 < r * r
        state[disc & (state == kernels.UNKNOWN)] = kernels.FREE
        state[rng.random((rows, cols)) < 0.01] = kernels.OCCUPIED
        yield state.copy()


def _rings_on_contours(tracker, state):
    """Check the tracker's rings against the contours of `state`, with the crack types the
    tracker smooths them to; the contours."""
    pm = tracker.map
    contours = trace_contours(state)
    where = {}
    for label, c in enumerate(contours):
        for k, p in enumerate(map(tuple, c.corners.tolist())):
            where.setdefault(p, []).append((label, k))
    for ring in pm.rings():
        places = [where.get(tuple(pm.vertex(v)[:2]), []) for v in ring]
        assert all(len(p) == 1 for p in places)                  # on the boundary, never a pinch
        labels = {p[0][0] for p in places}
        assert len(labels) == 1                                  # one contour per ring
        ks = [p[0][1] for p in places]
        k0 = ks.index(min(ks))
        assert ks[k0:] + ks[:k0] == sorted(ks)                   # in the contour's order
        types = smooth_edge_types(contours[labels.pop()].edge_types, tracker.type_min_run)
        n = len(contours[places[0][0][0]].corners)
        for v, k, k_next in zip(ring, ks, ks[1:] + ks[:1]):
            arc = [(k + j) % n for j in range((k_next - k) % n or n)]
            if tracker.junction_hold:                            # a wall only if every crack is one;
                assert pm.vertex(v)[2] <= types[arc].min()       # a held junction draws some wall as frontier
            else:
                assert pm.vertex(v)[2] == types[arc].min()
    return contours


@settings(max_examples=150, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from([1, 3, 1000]), st.sampled_from([1, 3]), st.sampled_from([0, 4]),
       st.sampled_from([0.0, 4.9]), st.sampled_from([0.0, 12.5]))
def test_the_rings_follow_the_boundary_and_a_receiver_of_every_record_holds_them(seed, splits, type_min_run, hold,
                                                                                  min_region, min_hole):
    tracker = PolygonTracker(sender_id=1, eps_cells=1.0, type_min_run=type_min_run, junction_hold=hold,
                             min_region_cells=min_region, min_hole_cells=min_hole)
    records, placed = [], {}
    for state in _growing_maps(seed, 6):
        sent = tracker.update(state, splits)
        assert sum(r.kind == 1 for r in sent if r.alive) <= 3 * splits   # a split marks at most three
        records += sent
        _rings_on_contours(tracker, state)
        for r in sent:                                           # a vertex never moves: it goes
            if not r.alive:
                placed.pop(r.vertex_id, None)
            else:
                assert placed.setdefault(r.vertex_id, (r.x_lat, r.y_lat)) == (r.x_lat, r.y_lat)
        rng = np.random.default_rng(seed)
        shuffled = list(records)
        rng.shuffle(shuffled)
        rep = Replica()
        for r in shuffled:
            rep.add(r)
        got = [[(x.vertex_id, x.x_lat, x.y_lat, x.edge_type) for x in ring] for ring in rep.rings()]
        assert got == [[(v, *tracker.map.vertex(v)) for v in ring] for ring in tracker.map.rings()]


@settings(max_examples=150, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_refined_to_the_end_no_corner_is_farther_than_eps_from_its_edge(seed):
    tracker = PolygonTracker(sender_id=1, eps_cells=1.0)
    for state in _growing_maps(seed, 5):
        tracker.update(state, 10_000)
    contours = _rings_on_contours(tracker, state)
    pm = tracker.map
    index = {}
    passes = {}
    for c in contours:
        for p in map(tuple, c.corners.tolist()):
            passes[p] = passes.get(p, 0) + 1
    for label, c in enumerate(contours):
        for k, p in enumerate(map(tuple, c.corners.tolist())):
            index[p] = (label, k)
    rings_by_label = {}
    for ring in pm.rings():
        label = index[tuple(pm.vertex(ring[0])[:2])][0]
        rings_by_label[label] = sorted(index[tuple(pm.vertex(v)[:2])][1] for v in ring)
    for label, c in enumerate(contours):
        usable = [passes[p] == 1 for p in map(tuple, c.corners.tolist())]
        if sum(usable) < 2:
            continue
        ks = rings_by_label[label]                               # every contour has its ring
        n = len(c.corners)
        for i, s in enumerate(ks):
            e = ks[(i + 1) % len(ks)]
            arc = [(s + j) % n for j in range(1, (e - s) % n or n)]
            arc = [k for k in arc if usable[k]]
            if arc:
                assert point_segment_distance(c.corners[arc], c.corners[s], c.corners[e]).max() <= 1.0


def test_a_frontier_advancing_along_a_corridor_leaves_a_vertex_on_its_walls_only_every_hold_cracks():
    def corridor(length):                       # 3 free cells wide between walls, open at the far end
        state = np.full((5, 40), kernels.UNKNOWN, np.uint8)
        state[0, :length + 1] = state[4, :length + 1] = kernels.OCCUPIED
        state[1:4, :length] = kernels.FREE
        state[1:4, 0] = kernels.OCCUPIED
        return state

    live = {}
    for hold in (0, 5):
        tracker = PolygonTracker(sender_id=1, eps_cells=1.0, type_min_run=1, junction_hold=hold)
        for length in range(3, 33):
            tracker.update(corridor(length), 0)
            _rings_on_contours(tracker, corridor(length))
        live[hold] = len(tracker.map.live_vertices())
    assert live[0] >= 2 * 30                     # both junctions left a vertex at every step
    assert live[5] <= 2 * 30 // 5 + 4


def test_free_regions_too_small_for_the_body_and_holes_too_small_to_matter_get_no_ring():
    state = np.full((20, 20), kernels.UNKNOWN, np.uint8)
    state[2:12, 2:12] = kernels.FREE                 # a room of 100 cells
    state[8:10, 4:6] = kernels.OCCUPIED              # a 4-cell obstacle inside it: a hole
    state[3:6, 8:11] = kernels.OCCUPIED              # a 9-cell one
    state[15, 15] = kernels.FREE                     # a free speck of one cell, walled in
    state[14, 14:17] = state[16, 14:17] = state[15, 14] = state[15, 16] = kernels.OCCUPIED
    state[15:17, 2:4] = kernels.FREE                 # a free patch of 4 cells
    kept = PolygonTracker(sender_id=1, eps_cells=1.0, min_region_cells=4.9, min_hole_cells=6.0)
    kept.update(state, 10_000)
    every = PolygonTracker(sender_id=1, eps_cells=1.0)
    every.update(state, 10_000)
    assert len(every.map.rings()) == 5
    rings = kept.map.rings()
    assert len(rings) == 2                          # the room and its larger hole
    corners = {tuple(kept.map.vertex(v)[:2]) for ring in rings for v in ring}
    assert all(2 <= x <= 12 and 2 <= y <= 12 for x, y in corners)
    # The speck grows into a region the body fits in: it gets its ring.
    state[15:18, 15:18] = kernels.FREE
    state[14, 14:19] = state[18, 14:19] = kernels.OCCUPIED
    state[14:19, 14] = state[14:19, 18] = kernels.OCCUPIED
    kept.update(state, 10_000)
    assert len(kept.map.rings()) == 3
    # The small obstacle is seen to be larger: its hole gets its ring.
    state[8:10, 4:7] = kernels.OCCUPIED
    kept.update(state, 10_000)
    assert len(kept.map.rings()) == 4
