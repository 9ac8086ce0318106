"""The private label grid (firmware/schemes/pereira/labels.py, pereira.md 5.2 d): cells are
placed in regions by walking the robot's FREE cells from the places, with gates drawn as
walls, so a point is not labelled through a wall no gate marks; the room behind a door seen
but never entered is its virtual region; the numba walk equals a plain-Python one."""
from __future__ import annotations

import numpy as np
from hypothesis import given, settings, strategies as st

from firmware import kernels
from firmware.schemes.pereira.labels import NONE, _walk, label_grid
from firmware.schemes.pereira.records import Gate, Place
from firmware.schemes.pereira.regions import fold

RES = 0.1
F, O, U = kernels.FREE, kernels.OCCUPIED, kernels.UNKNOWN
DOOR_GATE = Gate(1, 90, 61, 54, 128, 22)     # across the door at x 6.1 m, y 5.0-5.9 m


def two_rooms():
    """Rooms A (x 1-6 m) and B (x 6.2-11.2 m), y 1-6 m, a 0.2 m wall between with a door at
    y 5.0-5.9 m; global cells (row = y / 0.1, col = x / 0.1) from (0, 0)."""
    g = np.full((70, 130), O, np.uint8)
    g[10:60, 10:60] = F
    g[10:60, 62:112] = F
    g[50:59, 60:62] = F
    return g


def label_at(grid, x_m, y_m):
    return int(grid[int(y_m / RES), int(x_m / RES)])


def test_a_point_across_a_wall_is_not_labelled_by_the_nearest_place():
    # A robot drove along the wall in A, through the door and off into B, away from the wall.
    places = [Place(1, 1, 55, 20, 4, 0), Place(1, 2, 55, 35, 4, 1), Place(1, 3, 55, 54, 4, 1),
              Place(1, 4, 68, 54, 4, 1), Place(1, 5, 80, 45, 4, 1), Place(1, 6, 90, 35, 4, 1),
              Place(1, 7, 100, 30, 4, 1)]
    graph = fold(places, [DOOR_GATE])
    a, b = graph.label(55, 20, 100), graph.label(100, 30, 100)
    assert a != b and graph.label(68, 54, 100) == b          # the door's gate cut A from B
    # Across the wall from A's first place, in room B: the nearest place with no gate
    # between is A's (the wall is no gate), the walk through the door says B.
    assert graph.label(65, 20, 100) == a
    grid = label_grid(two_rooms(), 0, 0, RES, graph)
    assert label_at(grid, 6.5, 2.0) == b and label_at(grid, 2.0, 2.0) == a
    assert label_at(grid, 6.1, 3.0) == NONE                  # the wall
    # Every free cell of A is A's and of B is B's (the door's cells are the gate's or A's).
    assert (grid[10:60, 10:60] == a).all() and (grid[10:60, 62:112] == b).all()


def test_the_room_behind_a_door_seen_from_one_side_is_its_virtual_region():
    places = [Place(1, q, 55, 10 + 10 * q, 4, 1 if q > 1 else 0) for q in range(1, 5)]
    graph = fold(places, [DOOR_GATE])
    (v,) = [k for k, r in enumerate(graph.regions) if r.virtual]
    a = graph.label(55, 20, 100)
    grid = label_grid(two_rooms(), 0, 0, RES, graph)
    assert (grid[10:60, 62:112] == v).all() and (grid[10:60, 10:60] == a).all()


def test_unknown_cells_and_a_window_elsewhere_stay_unlabelled():
    places = [Place(1, 1, 30, 30, 10, 0)]
    graph = fold(places, [])
    g = two_rooms()
    g[10:60, 40:60] = U
    grid = label_grid(g, 0, 0, RES, graph)
    assert (grid[10:60, 10:40] == 0).all() and (grid[10:60, 40:60] == NONE).all()
    assert (grid[10:60, 62:112] == NONE).all()               # no way from the place there
    # The same map in a window anchored elsewhere: the place lies outside it, nothing is labelled.
    assert (label_grid(g, 500, 500, RES, graph) == NONE).all()


def reference_walk(free, label, seeds):
    """Level by level: a cell of step d takes the lowest label of its step d - 1 neighbours."""
    label = label.copy()
    level = {}
    for i, j, lab in seeds:
        if free[i, j] and (label[i, j] == NONE or (i, j) in level):
            level[(i, j)] = min(lab, level.get((i, j), lab))
    for (i, j), lab in level.items():
        label[i, j] = lab
    seen = set(level)
    while level:
        nxt = {}
        for (i, j), lab in level.items():
            for ni, nj in ((i + 1, j), (i - 1, j), (i, j + 1), (i, j - 1)):
                if 0 <= ni < free.shape[0] and 0 <= nj < free.shape[1] and free[ni, nj] \
                        and (ni, nj) not in seen and label[ni, nj] == NONE:
                    nxt[(ni, nj)] = min(lab, nxt.get((ni, nj), lab))
        for (i, j), lab in nxt.items():
            label[i, j] = lab
        seen |= set(nxt)
        level = nxt
    return label


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 6))
def test_the_walk_equals_a_plain_level_by_level_walk(seed, n_seeds):
    rng = np.random.default_rng(seed)
    free = rng.random((15, 17)) < 0.7
    label = np.full(free.shape, NONE, np.int32)
    label[rng.random(free.shape) < 0.05] = 9               # labelled by an earlier walk
    seeds = [(int(rng.integers(15)), int(rng.integers(17)), int(rng.integers(5))) for _ in range(n_seeds)]
    expected = reference_walk(free, label, seeds)
    si, sj, sl = (np.array(c, np.int32) for c in zip(*seeds))
    _walk(free, label, si, sj, sl)
    assert (label == expected).all()
