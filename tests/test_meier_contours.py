"""The boundary of the observed area as crack contours (firmware/schemes/meier/contours.py;
meier.md 7.1, T1 and T3)."""
from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from scipy import ndimage

from firmware import kernels
from firmware.schemes.meier.contours import (FRONTIER_EDGE, WALL_EDGE, hold_junctions, signed_area, smooth_edge_types,
                                             trace_contours)


def _state(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    rows, cols = (int(v) for v in rng.integers(1, 30, 2))
    p = rng.dirichlet([1.0, 1.0, 1.0])
    return rng.choice(np.array([kernels.UNKNOWN, kernels.FREE, kernels.OCCUPIED], np.uint8), size=(rows, cols), p=p)


def _cell(state, x, y):
    r, c = y, x
    if 0 <= r < state.shape[0] and 0 <= c < state.shape[1]:
        return state[r, c]
    return kernels.UNKNOWN


@settings(max_examples=500, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_every_crack_has_free_on_its_left_and_the_areas_add_up(seed):
    state = _state(seed)
    contours = trace_contours(state)
    total = 0.0
    cracks = 0
    for ring in contours:
        n = len(ring.corners)
        assert n >= 4
        for k in range(n):
            (x0, y0), (x1, y1) = ring.corners[k], ring.corners[(k + 1) % n]
            dx, dy = x1 - x0, y1 - y0
            assert abs(dx) + abs(dy) == 1
            # The cell on the left of the step and the one on its right.
            lx, ly = (x0 - 1, y0) if dy == 1 else (x0, y0 - 1) if dy == -1 else (x0, y0) if dx == 1 else (x1, y1 - 1)
            rx, ry = (x0, y0) if dy == 1 else (x0 - 1, y0 - 1) if dy == -1 else (x0, y0 - 1) if dx == 1 else (x1, y1)
            assert _cell(state, lx, ly) == kernels.FREE
            assert _cell(state, rx, ry) != kernels.FREE
            expected = WALL_EDGE if _cell(state, rx, ry) == kernels.OCCUPIED else FRONTIER_EDGE
            assert ring.edge_types[k] == expected
        cracks += n
        total += signed_area(ring.corners)
    free = state == kernels.FREE
    assert total == free.sum()
    # Every crack between a free cell and another is on exactly one contour.
    padded = np.pad(free, 1)
    assert cracks == int((padded[1:, :] != padded[:-1, :]).sum() + (padded[:, 1:] != padded[:, :-1]).sum())
    # One outer ring per 4-connected free region.
    _, regions = ndimage.label(free)
    assert sum(signed_area(r.corners) > 0 for r in contours) == regions


@settings(max_examples=300, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_filling_the_rings_even_odd_gives_back_the_free_cells(seed):
    state = _state(seed)
    rows, cols = state.shape
    yc, xc = np.mgrid[0:rows, 0:cols] + 0.5
    inside = np.zeros(state.shape, bool)
    for ring in trace_contours(state):
        x, y = ring.corners[:, 0].astype(float), ring.corners[:, 1].astype(float)
        y2 = np.roll(y, -1)
        for k in range(len(x)):
            if y[k] == y2[k]:
                continue                                  # horizontal cracks cross no centre row
            crosses = (np.minimum(y[k], y2[k]) < yc) & (yc < np.maximum(y[k], y2[k])) & (xc < x[k])
            inside ^= crosses
    assert np.array_equal(inside, state == kernels.FREE)


def test_two_free_cells_touching_at_a_corner_are_two_contours():
    s = np.full((2, 2), kernels.OCCUPIED, np.uint8)
    s[0, 0] = s[1, 1] = kernels.FREE
    rings = trace_contours(s)
    assert len(rings) == 2 and all(len(r.corners) == 4 for r in rings)
    assert all((r.edge_types == WALL_EDGE).sum() == 2 for r in rings)


def _runs(types: np.ndarray) -> list[tuple[int, int, int]]:
    """(start, length, type) of each run of a closed contour's types; [] for one type."""
    change = np.nonzero(types != np.roll(types, 1))[0]
    if not len(change):
        return []
    lengths = np.diff(np.append(change, change[0] + len(types)))
    return [(int(a), int(n), int(types[a])) for a, n in zip(change, lengths)]


@settings(max_examples=300, deadline=None)
@given(st.lists(st.sampled_from([FRONTIER_EDGE, WALL_EDGE]), min_size=1, max_size=60), st.integers(1, 5))
def test_smoothed_types_have_no_run_shorter_than_the_minimum_and_change_only_short_runs(types, min_run):
    types = np.array(types, np.int8)
    out = smooth_edge_types(types, min_run)
    assert all(n >= min_run for _, n, _ in _runs(out))
    assert np.array_equal(smooth_edge_types(out, min_run), out)         # smoothing it again changes nothing
    short = np.zeros(len(types), bool)
    for a, n, _ in _runs(types):
        if n < min_run:
            short[(a + np.arange(n)) % len(types)] = True
    changed = out != types
    # A crack changes only if it lay in a short run, or the whole contour became one type.
    assert not (changed & ~short).any() or len(set(out.tolist())) == 1
    if min_run == 1:
        assert np.array_equal(out, types)


def test_a_gap_of_a_crack_in_a_wall_becomes_wall_and_a_speck_of_wall_in_a_frontier_frontier():
    w, f = WALL_EDGE, FRONTIER_EDGE
    types = np.array([w, w, w, f, w, w, w, w, f, f, f, f, w, f, f, f, f], np.int8)
    assert smooth_edge_types(types, 3).tolist() == [w] * 8 + [f] * 9


@settings(max_examples=500, deadline=None)
@given(st.lists(st.sampled_from([FRONTIER_EDGE, WALL_EDGE]), min_size=1, max_size=60),
       st.lists(st.integers(0, 59), max_size=8), st.integers(0, 6))
def test_a_held_junction_moves_back_along_its_wall_onto_a_kept_vertex_and_never_makes_a_wall(types, kept, hold):
    types = np.array(types, np.int8)
    n = len(types)
    kept = sorted({k % n for k in kept})
    out = hold_junctions(types, kept, hold)
    assert not (out > types).any()                                   # no frontier crack becomes a wall
    junctions = set(np.nonzero(out != np.roll(out, 1))[0].tolist())
    before = set(np.nonzero(types != np.roll(types, 1))[0].tolist())
    assert junctions <= before | set(kept)                           # a new junction sits on a kept vertex
    spans = []                         # wall cracks between a junction and a kept vertex within reach
    for k in before:
        for d in range(1, hold + 1):
            back = types[k] == FRONTIER_EDGE
            cracks = (k - np.arange(1, d + 1)) % n if back else (k + np.arange(d)) % n
            if (types[cracks] == WALL_EDGE).all() and ((k - d) % n if back else (k + d) % n) in kept:
                spans.append(set(cracks.tolist()))
    for c in np.nonzero(out != types)[0].tolist():
        assert any(c in span for span in spans)
    if hold == 0 or not kept:
        assert np.array_equal(out, types)


def test_a_junction_stays_on_the_nearest_kept_vertex_within_reach_and_only_along_a_wall():
    w, f = WALL_EDGE, FRONTIER_EDGE
    types = np.array([w] * 6 + [f] * 4 + [w] * 6, np.int8)           # junctions at corners 6 and 10
    assert hold_junctions(types, [3, 5], 3).tolist() == [w] * 5 + [f] * 5 + [w] * 6
    assert hold_junctions(types, [2], 3).tolist() == types.tolist()  # 4 cracks back: too far
    assert hold_junctions(types, [13], 3).tolist() == [w] * 6 + [f] * 7 + [w] * 3
    assert hold_junctions(types, [8], 3).tolist() == types.tolist()  # a vertex in the frontier holds nothing
    assert hold_junctions(types, [4, 6], 3).tolist() == types.tolist()  # a junction on a vertex stays
