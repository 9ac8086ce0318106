"""Algorithm 1 and the unexplored directions (firmware/schemes/mr_topomap/vertices.py and
directions.py; mrtopomap.md 1.2, A4, A5, A10, A12, A13, A18; tests 6.1.3 and 6.1.5)."""
from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from firmware.kernels import FREE, OCCUPIED, UNKNOWN
from firmware.schemes.mr_topomap import directions as U
from firmware.schemes.mr_topomap.params import DEFAULT
from firmware.schemes.mr_topomap.records import MAX_VERTEX_ID, NO_VERTEX, SECTORS, sector_class, sector_mask
from firmware.schemes.mr_topomap.vertices import NewVertex, Place, ReEntry, VertexBuilder
from tests import test_mrtopomap_world as W
from world_sim.occupancy_map import OccupancyMap

SETTINGS = settings(max_examples=25, deadline=None)
CAVE = "cave:1:60x60"


def _corridor() -> OccupancyMap:
    """A 30 x 3 m corridor with alcoves every 4 m (0.1 m cells)."""
    free = np.zeros((50, 320), dtype=bool)
    free[10:40, 10:310] = True
    for x in range(30, 300, 40):
        free[40:46, x:x + 12] = True
    return OccupancyMap(free, 0.1, 0.0, 0.0, "corridor")


def _drive(builder: VertexBuilder, occ_spec_or_map, poses, rng, others=()):
    """Feed poses (x, y, yaw) at 10 Hz with noisy scans; return every event."""
    events = []
    for k, (x, y, yaw) in enumerate(poses):
        if isinstance(occ_spec_or_map, str):
            r = W.scan(occ_spec_or_map, x, y, yaw, rng)
        else:
            from world_sim.raycast import cast_rays
            occ = occ_spec_or_map
            r = cast_rays(occ.wall_u8(), occ.origin_x_m, occ.origin_y_m, occ.resolution_m, x, y,
                          W.ANGLE_MIN + yaw + W.ANGLE_INC * np.arange(W.BEAMS), W.RANGE_MAX)
            r = np.where(r < W.RANGE_MAX, r + rng.normal(0, W.NOISE_M, W.BEAMS), W.RANGE_MAX)
        events += builder.observe(x, y, yaw, 100_000 * k, r, W.ANGLE_MIN, W.ANGLE_INC, W.RANGE_MAX, others=others)
    return events


def test_a_straight_20_m_drive_makes_8_vertices_2_5_m_apart():
    b = VertexBuilder(3)
    xs = np.arange(2.0, 22.0 + 1e-9, 0.08)                  # 0.8 m/s at 10 Hz
    events = _drive(b, _corridor(), [(x, 2.5, 0.0) for x in xs], np.random.default_rng(0))
    new = [e.vertex for e in events if isinstance(e, NewVertex)]
    assert len(new) == 8 and len(events) == 8
    assert [v.vid for v in new] == list(range(8))
    assert [v.prev_id for v in new] == [NO_VERTEX] + list(range(7))
    assert all(v.prev_owner == 3 and v.owner == 3 for v in new)
    gaps = np.diff([v.x_m for v in new])
    assert (gaps > DEFAULT.d_vertex_m).all() and (gaps <= DEFAULT.d_vertex_m + DEFAULT.eval_every_m + 0.1).all()


def test_driving_back_makes_re_entry_edges_not_vertices():
    b = VertexBuilder(1)
    rng = np.random.default_rng(1)
    out = [(x, 2.5, 0.0) for x in np.arange(2.0, 14.0, 0.08)]
    back = [(x, 2.5, math.pi) for x in np.arange(14.0, 2.0, -0.08)]
    first = _drive(b, _corridor(), out, rng)
    n = len(b.vertices)
    events = _drive(b, _corridor(), back, rng)
    assert len(b.vertices) == n and all(isinstance(e, ReEntry) for e in events)
    edges = [e.edge for e in events]
    assert len(edges) >= 2
    xy = {v.vid: (v.x_m, v.y_m) for v in b.vertices}
    for e in edges:
        assert e.n1 == e.n2 == 1 and e.id1 != e.id2
    assert edges[0].id1 == len(first) - 1                      # from the last vertex built
    assert all(a.id2 == c.id1 for a, c in zip(edges, edges[1:]))   # each one becomes the last vertex
    assert xy[edges[-1].id2][0] < xy[edges[0].id2][0]           # walking back along the chain


@st.composite
def _walks(draw):
    """A bouncing random walk through the cave: (x, y, yaw) every 0.08 m."""
    seed = draw(st.integers(0, 10**6))
    rng = np.random.default_rng(seed)
    start = W.poisson_points(CAVE, rng, 3.0, max_points=40)
    x, y = start[rng.integers(len(start))]
    yaw = rng.uniform(-math.pi, math.pi)
    poses = []
    for _ in range(draw(st.integers(100, 500))):
        for _ in range(20):
            nx, ny = x + 0.08 * math.cos(yaw), y + 0.08 * math.sin(yaw)
            if W.standing(CAVE, np.array([[nx, ny]]))[0]:
                break
            yaw = rng.uniform(-math.pi, math.pi)
        else:
            continue
        x, y = nx, ny
        yaw += rng.normal(0, 0.05)
        poses.append((x, y, yaw))
    return seed, poses


@SETTINGS
@given(_walks())
def test_algorithm_1_invariants_on_random_walks(walk):
    seed, poses = walk
    b = VertexBuilder(2)
    last = None
    for k, (x, y, yaw) in enumerate(poses):
        r = W.scan(CAVE, x, y, yaw, np.random.default_rng(seed + k))
        for e in b.observe(x, y, yaw, 100_000 * k, r, W.ANGLE_MIN, W.ANGLE_INC, W.RANGE_MAX):
            if isinstance(e, NewVertex):
                v = e.vertex
                assert (v.prev_owner, v.prev_id) == (last if last is not None else (2, NO_VERTEX))
                last = v.key
            else:
                ed = e.edge
                assert (ed.n1, ed.id1) == last and (ed.n2, ed.id2) != last
                there = next(v for v in b.vertices if v.vid == ed.id2)
                assert math.hypot(there.x_m - x, there.y_m - y) <= DEFAULT.r_reentry_m + 0.05
                last = (ed.n2, ed.id2)
    ids = [v.vid for v in b.vertices]
    assert ids == list(range(len(ids)))
    xy = np.array([[v.x_m, v.y_m] for v in b.vertices])
    if len(xy) > 1:
        d = np.hypot(*(xy[:, None] - xy[None]).transpose(2, 0, 1))
        assert d[~np.eye(len(xy), dtype=bool)].min() > DEFAULT.d_vertex_m


def test_algorithm_1_runs_every_quarter_metre_or_second():
    b = VertexBuilder(1)
    r = np.full(360, 3.0)
    assert b.observe(0.0, 0.0, 0.0, 0, r, W.ANGLE_MIN, W.ANGLE_INC, 10.0)        # vertex 0
    assert not b.due(0.1, 0.0, 500_000)
    assert b.due(0.25, 0.0, 500_000) and b.due(0.1, 0.0, 1_000_000)
    assert b.observe(0.2, 0.0, 0.0, 500_000, r, W.ANGLE_MIN, W.ANGLE_INC, 10.0) == []
    assert b.due(0.3, 0.0, 600_000)                # a skipped observation moved nothing
    for k, x in enumerate(np.arange(0.3, 2.6, 0.3)):
        assert b.observe(x, 0.0, 0.0, 600_000 + k, r, W.ANGLE_MIN, W.ANGLE_INC, 10.0) == []
    assert len(b.observe(2.7, 0.0, 0.0, 700_000, r, W.ANGLE_MIN, W.ANGLE_INC, 10.0)) == 1


def test_merged_teammates_vertices_count_as_known_places():
    """A5: where a merged teammate has a vertex, no new one is built; a re-entry edge may go to it."""
    occ = _corridor()
    rng = np.random.default_rng(4)
    b0 = VertexBuilder(1)
    mate = [e.vertex for e in _drive(b0, occ, [(x, 2.5, 0.0) for x in np.arange(2.0, 12.0, 0.08)], rng)]
    others = [Place(7, v.vid, v.x_m, v.y_m, v.desc) for v in mate]        # as if merged, same frame
    b = VertexBuilder(2)
    events = _drive(b, occ, [(x, 2.5, 0.0) for x in np.arange(3.0, 12.0, 0.08)], rng, others=others)
    assert b.vertices == [] and b.last is not None and b.last[0] == 7
    assert all(isinstance(e, ReEntry) and e.edge.n1 == e.edge.n2 == 7 for e in events)
    more = _drive(b, occ, [(x, 2.5, 0.0) for x in np.arange(12.0, 16.0, 0.08)], rng, others=others)
    first = next(e.vertex for e in more if isinstance(e, NewVertex))
    assert first.vid == 0 and first.prev_owner == 7       # its line-17 edge to the teammate's vertex


def test_the_literal_rule_builds_by_descriptor_only():
    occ = _corridor()
    rng = np.random.default_rng(5)
    b = VertexBuilder(1, novelty="descriptor")
    _drive(b, occ, [(6.0, 2.5, 0.0)] * 3 + [(6.0, 2.5, 1.0)] * 3, rng)
    assert len(b.vertices) == 1                             # the same place, any heading: known
    b2 = VertexBuilder(1, novelty="descriptor")
    _drive(b2, occ, [(x, 2.5, 0.0) for x in np.arange(2.0, 4.0, 0.08)], rng)
    assert len(b2.vertices) >= 1


def test_ids_stop_at_4094():
    b = VertexBuilder(1, first_id=MAX_VERTEX_ID)
    r = np.full(360, 3.0)
    assert len(b.observe(0.0, 0.0, 0.0, 0, r, W.ANGLE_MIN, W.ANGLE_INC, 10.0)) == 1
    assert b.observe(10.0, 0.0, 0.0, 10**7, r, W.ANGLE_MIN, W.ANGLE_INC, 10.0) == [] and b.exhausted == 1


# ---- unexplored directions ---------------------------------------------------------------

def _room_state(half_m: float, doors: dict[int, float], res: float = 0.1, pocket: bool = False):
    """A known square room (free inside, walls 0.2 m) centred on (0, 0) in a sea of unknown,
    with 1.2 m doors in the walls at the given sides (0 east, 4 north, 8 west, 12 south:
    sectors) and offsets along them; row0 = col0 = -n."""
    n = int(round((half_m + 3.0) / res))
    state = np.zeros((2 * n, 2 * n), dtype=np.uint8)
    h = int(round(half_m / res))
    c = n
    state[c - h - 2:c + h + 2, c - h - 2:c + h + 2] = OCCUPIED
    state[c - h:c + h, c - h:c + h] = FREE
    for side, off in doors.items():
        o = int(round(off / res))
        w = 6
        if side == 0:
            state[c + o - w:c + o + w, c + h:c + h + 2] = FREE
        elif side == 4:
            state[c + h:c + h + 2, c + o - w:c + o + w] = FREE
        elif side == 8:
            state[c + o - w:c + o + w, c - h - 2:c - h] = FREE
        else:
            state[c - h - 2:c - h, c + o - w:c + o + w] = FREE
    if pocket:                                              # free cells by unknown, behind a wall
        state[c - 2:c + 2, c + h + 4:c + h + 8] = FREE
    return state, -n, -n


@settings(max_examples=60, deadline=None)
@given(st.floats(2.0, 5.5), st.sets(st.sampled_from([0, 4, 8, 12]), min_size=0, max_size=4),
       st.floats(-1.0, 1.0))
def test_doors_give_their_sectors_and_distance_classes(half, sides, frac):
    off = frac * half * math.tan(math.radians(8.0))        # the door's centre within its sector
    state, row0, col0 = _room_state(half, {s: off for s in sides})
    found = U.detect(state, row0, col0, 0.1, 0.05, 0.05, DEFAULT)
    assert sector_mask(found.ud_sectors) == sum(1 << s for s in sides)
    for c in found.clusters:
        d = math.hypot(c.x_m - 0.05, c.y_m - 0.05)          # from the vertex
        assert c.cls == U.distance_class(d) and sector_class(found.ud_sectors, c.sector) == c.cls
        assert abs(d - (half + 0.2)) < 0.3


def test_frontiers_behind_walls_and_small_clusters_give_no_direction():
    state, row0, col0 = _room_state(3.0, {}, pocket=True)
    assert U.detect(state, row0, col0, 0.1, 0.05, 0.05).ud_sectors == 0
    state, row0, col0 = _room_state(3.0, {0: 0.0})
    c = -row0
    state[c - 12:c + 12, c + 30:c + 32] = OCCUPIED          # the door nearly shut: 4 cells open
    state[c - 2:c + 2, c + 30:c + 32] = FREE
    assert U.detect(state, row0, col0, 0.1, 0.05, 0.05).ud_sectors == 0


def test_crop_is_12_m():
    state, row0, col0 = _room_state(7.0, {0: 0.0})         # the door 7 m east: outside a 12 m crop
    assert U.detect(state, row0, col0, 0.1, 0.05, 0.05).ud_sectors == 0
    assert U.detect(state, row0, col0, 0.1, 2.05, 0.05).ud_sectors != 0


def test_explored_when_close_to_the_direction_point_or_the_cluster_is_gone():
    state, row0, col0 = _room_state(4.0, {0: 0.0, 4: 0.0})
    found = U.detect(state, row0, col0, 0.1, 0.05, 0.05)
    ks, pts = U.direction_points(0.05, 0.05, found.ud_sectors)
    assert list(ks) == [0, 4]
    assert U.explored_near(0.05, 0.05, found.ud_sectors, *pts[1]) == 1 << 4
    assert U.explored_near(0.05, 0.05, found.ud_sectors, 0.0, 0.0) == 0
    assert U.vanished(found.clusters, state, row0, col0, 0.1, 0.05, 0.05) == 0
    c = -row0
    seen = state.copy()
    seen[c - 30:c + 30, c + 42:c + 60] = FREE               # beyond the east door: explored, walled
    seen[c - 30:c + 30, c + 60:c + 62] = OCCUPIED
    seen[[c - 31, c + 30], c + 40:c + 62] = OCCUPIED
    assert U.vanished(found.clusters, seen, row0, col0, 0.1, 0.05, 0.05) == 1 << 0


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.sampled_from(["v", "c"]), st.integers(0, 3), st.integers(0, (1 << 32) - 1)),
                max_size=30), st.randoms(use_true_random=False))
def test_the_direction_book_is_a_pure_function_of_the_records(ops, rnd):
    """mrud masks AND-NOT in any order, with duplicates, before or after their vertex."""
    ops = [(kind, (1, k), word if kind == "v" else word & 0xFFFF) for kind, k, word in ops]
    shuffled = ops + ops[: len(ops) // 2]
    rnd.shuffle(shuffled)
    books = []
    for seq in (ops, shuffled):
        book = U.DirectionBook()
        for kind, key, word in seq:
            book.add_vertex(key, word) if kind == "v" else book.clear(key, word)
        books.append(book)
    for k in range(4):
        assert books[0].remaining((1, k)) == books[1].remaining((1, k))
        ud = [w for kind, key, w in ops if kind == "v" and key == (1, k)]
        cleared = 0
        for kind, key, w in ops:
            if kind == "c" and key == (1, k):
                cleared |= w
        expect = 0 if not ud else min(ud)
        for s in range(SECTORS):
            if (cleared >> s) & 1:
                expect &= ~(3 << (2 * s))
        assert books[0].remaining((1, k)) == expect
    assert books[0].any_open() == bool(books[0].open_keys())


def test_unknown_cells_off_the_grid_count_as_unknown():
    state = np.full((40, 40), FREE, dtype=np.uint8)        # free up to the grid's edge
    found = U.detect(state, 0, 0, 0.1, 2.0, 2.0)
    assert sector_mask(found.ud_sectors) != 0
    assert (state == UNKNOWN).sum() == 0
