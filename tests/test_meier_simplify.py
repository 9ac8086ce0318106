"""Douglas-Peucker by edge splits, worst edge first (firmware/schemes/meier/simplify.py;
meier.md 7.1, D1 and D3): run to the end it gives a plain recursive Douglas-Peucker's
vertices, one split at a time, and no corner of the contour is left farther than eps from
its edge."""
from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from firmware import kernels
from firmware.schemes.meier.contours import trace_contours
from firmware.schemes.meier.simplify import RingSimplifier, douglas_peucker, point_segment_distance


def _contours(seed: int):
    rng = np.random.default_rng(seed)
    rows, cols = (int(v) for v in rng.integers(2, 40, 2))
    state = np.full((rows, cols), kernels.UNKNOWN, np.uint8)
    # A few blobs of free space with some walls: contours with long arcs and type changes.
    yy, xx = np.mgrid[0:rows, 0:cols]
    for _ in range(int(rng.integers(1, 4))):
        cy, cx, r = rng.uniform(0, rows), rng.uniform(0, cols), rng.uniform(2, 12)
        state[(yy - cy) ** 2 + (xx - cx) ** 2 < r * r] = kernels.FREE
    state[rng.random((rows, cols)) < rng.uniform(0.0, 0.08)] = kernels.OCCUPIED
    return trace_contours(state), float(rng.choice([0.5, 1.0, 1.5, 2.5]))


def _usable(corners: np.ndarray) -> np.ndarray:
    """Corners the contour passes once (not pinches)."""
    return np.array([sum((c == corners).all(axis=1)) == 1 for c in corners])


def _edge_errors(corners: np.ndarray, vertices: list[int], usable: np.ndarray) -> list[float]:
    """Per edge of the ring, the largest distance of a usable corner of its arc (0 if none)."""
    n = len(corners)
    out = []
    for i, s in enumerate(vertices):
        e = vertices[(i + 1) % len(vertices)]
        arc = (s + np.arange(1, (e - s) % n or n)) % n
        arc = arc[usable[arc]]
        out.append(float(point_segment_distance(corners[arc], corners[s], corners[e]).max()) if len(arc) else 0.0)
    return out


@settings(max_examples=300, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_splitting_the_worst_edge_first_ends_where_recursive_douglas_peucker_does(seed):
    contours, eps = _contours(seed)
    for ring in contours:
        rs = RingSimplifier(ring.corners, ring.edge_types, eps)
        start = list(rs.vertices)
        splits = 0
        while rs.split() is not None:
            splits += 1
        expected = douglas_peucker(ring.corners, start, eps, _usable(ring.corners))
        assert rs.vertices == expected
        assert splits == len(expected) - len(start)
        assert rs.worst_error == 0.0 and rs.split() is None


@settings(max_examples=300, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_no_corner_is_farther_than_eps_from_its_edge_once_refined(seed):
    contours, eps = _contours(seed)
    for ring in contours:
        rs = RingSimplifier(ring.corners, ring.edge_types, eps)
        while rs.split() is not None:
            pass
        v = rs.vertices
        n = len(ring.corners)
        seen = {tuple(c) for c in ring.corners.tolist()}
        assert max(_edge_errors(ring.corners, v, _usable(ring.corners))) <= eps
        # Every edge carries one crack type: each type change is a vertex.
        changes = [k for k in range(n) if ring.edge_types[k] != ring.edge_types[k - 1]]
        assert all(k in v or sum((ring.corners[k] == ring.corners).all(axis=1)) > 1 for k in changes)
        assert len(seen) <= n


@settings(max_examples=100, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_each_split_takes_the_worst_edge_of_the_ring(seed):
    contours, eps = _contours(seed)
    for ring in contours:
        rs = RingSimplifier(ring.corners, ring.edge_types, eps)
        usable = _usable(ring.corners)
        while True:
            worst = max(_edge_errors(ring.corners, rs.vertices, usable))
            assert rs.worst_error == (worst if worst > eps else 0.0)
            if rs.split() is None:
                break
