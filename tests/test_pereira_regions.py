"""Pereira regions (firmware/schemes/pereira/gates.py, regions.py, store.py): gates found on
hand-built maps, the region graph as a pure function of the record SET, and no edge through
a wall (pereira.md 6.1 items 2, 7, 8, 9)."""
import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from firmware import kernels
from firmware.schemes.pereira.gates import GateTracker, detect_gates, place_clear_dm
from firmware.schemes.pereira.records import Claim, Gate, Place, dm
from firmware.schemes.pereira.regions import REAL, VIRTUAL, crosses, fold, region_signature, signature_of
from firmware.schemes.pereira.status import status_view
from firmware.schemes.pereira.store import Store

SETTINGS = settings(max_examples=40, deadline=None)
RES = 0.1
F, O, U = kernels.FREE, kernels.OCCUPIED, kernels.UNKNOWN


# ---- hand-built maps (10 cm cells, row 0 at y = 0) -------------------------------------------

def boxed(shape):
    return np.full(shape, U, np.uint8)


def carve(g, r0, r1, c0, c1):
    """Free [r0, r1) x [c0, c1) with a one-cell wall around what is not free yet."""
    g[max(r0 - 1, 0):r1 + 1, max(c0 - 1, 0):c1 + 1] = np.where(
        g[max(r0 - 1, 0):r1 + 1, max(c0 - 1, 0):c1 + 1] == F, F, O)
    g[r0:r1, c0:c1] = F


def two_rooms(door_cells=9, door_row=35, far_known=True):
    """Two 5 x 5 m rooms side by side, a wall 0.2 m thick (columns 60, 61) between them with
    a door door_cells high starting at door_row. Door centre: x 6.1 m, y (door_row + w/2) 0.1."""
    g = boxed((80, 130))
    carve(g, 10, 60, 10, 60)
    if far_known:
        carve(g, 10, 60, 62, 112)
    g[10:60, 60:62] = O
    g[door_row:door_row + door_cells, 60:62] = F
    return g


def room_off_corridor(door_cells=9):
    """A corridor 1.5 m wide along x (y 1.0 .. 2.5 m, x 1.0 .. 15.0 m), a room of 6 x 5 m
    above it (y 2.7 .. 7.7 m, x 4.0 .. 10.0 m) behind a wall 0.2 m thick, a door centred at
    x 7.05 m."""
    g = boxed((90, 170))
    carve(g, 10, 25, 10, 150)
    carve(g, 27, 77, 40, 100)
    g[25:27, 40:100] = O
    c0 = 70 - door_cells // 2
    g[25:27, c0:c0 + door_cells] = F
    return g


def corridor(width_cells=15, open_ends=False):
    g = boxed((40, 160))
    carve(g, 10, 10 + width_cells, 10, 150)
    if open_ends:
        g[10:10 + width_cells, 9] = U
        g[10:10 + width_cells, 150] = U
    return g


def corridor_into_room():
    """A corridor 1.5 m wide (y 3.0 .. 4.5 m) from x 1.0 to x 6.0 m, opening into a 6 x 6 m
    room (x 6.0 .. 12.0 m, y 0.75 .. 6.75 m). Mouth at x 6.0 m, y 3.75 m."""
    g = boxed((90, 140))
    carve(g, 30, 45, 10, 60)
    carve(g, 8, 68, 60, 120)
    return g


def plain_room():
    g = boxed((60, 80))
    carve(g, 10, 50, 10, 70)
    return g


def walk(points, step_m=1.0):
    """Positions every step_m of travel along a polyline (x, y) in metres, both ends included."""
    out = [points[0]]
    left = step_m
    for (x0, y0), (x1, y1) in zip(points, points[1:]):
        seg = math.hypot(x1 - x0, y1 - y0)
        t = 0.0
        while seg - t >= left - 1e-9:
            t += left
            out.append((x0 + (x1 - x0) * t / seg, y0 + (y1 - y0) * t / seg))
            left = step_m
        left -= seg - t
    if math.hypot(out[-1][0] - points[-1][0], out[-1][1] - points[-1][1]) > 1e-6:
        out.append(points[-1])
    return out


def drive(state, points, sender=1, oseq0=0):
    """The place records a robot driving along `points` would send (one every metre)."""
    places = []
    for k, (x, y) in enumerate(walk(points)):
        places.append(Place(sender, oseq0 + k, dm(x), dm(y), place_clear_dm(state, 0, 0, RES, x, y),
                            1 if k else 0))
    return places


def gate_records(state, sender=1, oseq0=1000):
    return [Gate(sender, oseq0 + k, *g.wire()) for k, g in enumerate(detect_gates(state, 0, 0, RES))]


def angle_off_deg(a, b):
    d = abs(a - b) % math.pi
    return math.degrees(min(d, math.pi - d))


def free_segment(state, ax, ay, bx, by):
    """Every cell the segment (metres) passes through is FREE: sampled every 1/20 cell."""
    n = max(2, int(math.ceil(math.hypot(bx - ax, by - ay) / RES * 20)))
    t = np.linspace(0.0, 1.0, n + 1)
    i = np.floor((ay + (by - ay) * t) / RES).astype(int)
    j = np.floor((ax + (bx - ax) * t) / RES).astype(int)
    return bool(np.all(state[i, j] == F))


# ---- gates on hand-built maps ------------------------------------------------------------------

@settings(max_examples=25, deadline=None)
@given(st.integers(8, 16), st.integers(15, 40))
def test_two_rooms_and_a_door_give_one_gate_in_the_door(door_cells, door_row):
    gates = detect_gates(two_rooms(door_cells, door_row), 0, 0, RES)
    assert len(gates) == 1, gates
    g = gates[0]
    assert math.hypot(g.x_m - 6.1, g.y_m - (door_row + door_cells / 2) * RES) <= 0.2
    assert angle_off_deg(g.dir_rad, math.pi / 2) <= 10.0
    assert abs(2 * g.half_m - door_cells * RES) <= 0.15      # the free width of the door


def test_a_room_with_a_door_off_a_corridor_gives_one_gate_at_the_door():
    gates = detect_gates(room_off_corridor(), 0, 0, RES)
    assert len(gates) == 1
    assert math.hypot(gates[0].x_m - 7.05, gates[0].y_m - 2.6) <= 0.2
    assert angle_off_deg(gates[0].dir_rad, 0.0) <= 10.0


def test_a_corridor_opening_into_a_room_gives_one_gate_at_the_mouth():
    gates = detect_gates(corridor_into_room(), 0, 0, RES)
    assert len(gates) == 1
    assert math.hypot(gates[0].x_m - 6.0, gates[0].y_m - 3.75) <= 0.5
    assert angle_off_deg(gates[0].dir_rad, math.pi / 2) <= 10.0


@pytest.mark.parametrize("grid", [corridor(), corridor(10), corridor(25), corridor(open_ends=True), plain_room()],
                         ids=["corridor", "narrow", "wide", "open-ends", "room"])
def test_a_uniform_corridor_or_a_plain_room_has_no_gate(grid):
    assert detect_gates(grid, 0, 0, RES) == []


def bumpy(g, rng, count, door=None):
    """Wall cells added on the free side of walls: bumps of 0.1 m; none in the door's own
    cells (rows, cols), which two bumps could make too narrow to pass."""
    g = g.copy()
    free = g == F
    if door is not None:
        free[door] = False
    wall_side = free & ((np.roll(g, 1, 0) == O) | (np.roll(g, -1, 0) == O) | (np.roll(g, 1, 1) == O)
                        | (np.roll(g, -1, 1) == O))
    cells = np.argwhere(wall_side)
    for i, j in cells[rng.choice(len(cells), min(count, len(cells)), replace=False)]:
        g[i, j] = O
    return g


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 2 ** 32 - 1), st.integers(5, 60))
def test_bumps_on_the_walls_change_nothing(seed, count):
    rng = np.random.default_rng(seed)
    for grid, door, x, y, n in ((two_rooms(10, 30), np.s_[30:40, 60:62], 6.1, 3.5, 1),
                                (room_off_corridor(), np.s_[25:27, 66:75], 7.05, 2.6, 1),
                                (corridor_into_room(), None, 6.0, 3.75, 1), (corridor(), None, None, None, 0),
                                (plain_room(), None, None, None, 0)):
        gates = detect_gates(bumpy(grid, rng, count, door), 0, 0, RES)
        assert len(gates) == n, (n, gates)
        if n:
            # the tolerances of the bump-free tests (0.2 m at a door, 0.5 m at a mouth) plus
            # the size of a bump: one next to a jamb makes the door that much deeper
            assert math.hypot(gates[0].x_m - x, gates[0].y_m - y) <= (0.6 if x == 6.0 else 0.3)


def test_no_gate_until_the_far_side_is_observed():
    assert detect_gates(two_rooms(10, 30, far_known=False), 0, 0, RES) == []
    g = two_rooms(10, 30, far_known=False)
    carve(g, 25, 45, 62, 75)             # the far room seen near the door only: 1.3 m deep
    assert len(detect_gates(g, 0, 0, RES)) == 1


@pytest.mark.parametrize("pad", [(0, 0), (3, 7), (16, 1), (41, 29)])
def test_moving_the_window_anchor_does_not_move_a_gate(pad):
    base = [g.wire() for g in detect_gates(room_off_corridor(), 0, 0, RES)]
    grid = room_off_corridor()
    big = np.full((grid.shape[0] + pad[0] + 5, grid.shape[1] + pad[1] + 5), U, np.uint8)
    big[pad[0]:pad[0] + grid.shape[0], pad[1]:pad[1] + grid.shape[1]] = grid
    # the same world, the window anchored elsewhere
    assert [g.wire() for g in detect_gates(big, -pad[0], -pad[1], RES)] == base
    # the same window anchored elsewhere in the world: every gate moves by the shift
    moved = detect_gates(big, 100, -200, RES)
    assert [(g.cell[0] - 100 - pad[0], g.cell[1] + 200 - pad[1]) for g in moved] == \
        [g.cell for g in detect_gates(grid, 0, 0, RES)]


def test_a_gate_is_confirmed_after_three_cycles_and_not_sent_if_held():
    seen = detect_gates(room_off_corridor(), 0, 0, RES)
    t = GateTracker()
    assert t.update(seen) == [] and t.update(seen) == []
    assert t.update(seen) == seen
    assert t.update(seen) == []                          # once
    t = GateTracker()
    t.update(seen), t.update([]), t.update(seen), t.update(seen)
    assert t.update(seen) == seen                       # three in a row, after a gap
    held = GateTracker()
    x, y, d, _h = seen[0].wire()
    for _ in range(3):
        out = held.update(seen, folded=[(x + 3, y - 2, d + 5)])
    assert out == []


def test_a_place_certifies_only_free_cells():
    g = room_off_corridor()
    assert place_clear_dm(g, 0, 0, RES, 3.0, 1.75) == 6     # corridor half width 0.75 m, less a cell and rounding
    assert place_clear_dm(g, 0, 0, RES, 7.05, 5.2) >= 20
    assert place_clear_dm(g, 0, 0, RES, 0.5, 0.5) == 0      # unknown
    assert place_clear_dm(g, 0, 0, RES, 5.0, 2.6) == 0      # wall


# ---- regions from the records of a robot that drove there -------------------------------------

CORRIDOR_Y = 1.75


def test_room_off_a_corridor_gives_two_regions_and_one_gate_between():
    g = room_off_corridor()
    places = drive(g, [(1.5, CORRIDOR_Y), (14.5, CORRIDOR_Y), (7.05, CORRIDOR_Y), (7.05, 6.5), (5.0, 6.5)])
    graph = fold(places, gate_records(g))
    real = [r for r in graph.regions if not r.virtual]
    assert len(real) == 2 and len(graph.regions) == 2
    assert len(graph.gates) == 1
    assert graph.adjacency == ((0, 1, 0),)
    corridor_region = graph.region_of_place[[k for k, p in enumerate(graph.places) if p[1] < 25]]
    room_region = graph.region_of_place[[k for k, p in enumerate(graph.places) if p[1] > 28]]
    assert len(set(corridor_region.tolist())) == 1 and len(set(room_region.tolist())) == 1
    assert set(corridor_region.tolist()) != set(room_region.tolist())
    key = graph.gate_key(0)
    assert all(r.gate_signature == signature_of([key]) for r in real)
    assert all(r.signature == region_signature([key], [tuple(int(v) for v in graph.places[i, :4]) for i in r.places])
               for r in real)


def test_a_plain_corridor_gives_one_region():
    g = corridor()
    places = drive(g, [(1.5, CORRIDOR_Y), (14.5, CORRIDOR_Y), (3.0, 1.3)])
    graph = fold(places, gate_records(g))
    assert len(graph.gates) == 0 and len(graph.regions) == 1 and graph.adjacency == ()
    assert graph.regions[0].gate_signature == signature_of([])


def test_a_door_seen_from_the_corridor_makes_a_virtual_region_behind_it():
    g = room_off_corridor()
    corridor_places = drive(g, [(1.5, CORRIDOR_Y), (14.5, CORRIDOR_Y)])
    gates = gate_records(g)
    graph = fold(corridor_places, gates)
    assert [r.virtual for r in graph.regions] == [False, True]
    v = graph.regions[1]
    assert v.id[0] == VIRTUAL and not v.visited and v.anchor_y_dm > 26     # the room's side
    assert graph.adjacency == ((0, 1, 0),)
    # a robot that saw the whole room from the door claims it; a teammate that entered it
    # resolves the claim (virtual bit set) to the real room, with the same gate signature (one door)
    claim = Claim(2, 5, v.anchor_x_dm, v.anchor_y_dm, v.signature, 1, 1)
    assert graph.resolve(v.anchor_x_dm, v.anchor_y_dm) == 1
    inside = drive(g, [(7.05, CORRIDOR_Y), (7.05, 6.5)], oseq0=100)
    entered = fold(corridor_places + inside, gates)
    room = entered.resolve(v.anchor_x_dm, v.anchor_y_dm)
    assert room is not None and not entered.regions[room].virtual
    view = status_view(entered, [claim], observer=1)
    assert view.regions[room].explored_by_others and view.regions[room].explorer == 2


def test_rooms_behind_a_wall_without_a_door_are_not_joined():
    g = two_rooms(far_known=True)
    g[10:60, 60:62] = O                                   # no door
    left = drive(g, [(1.5, 3.5), (5.8, 3.5)])
    right = drive(g, [(6.4, 3.5), (11.0, 3.5)], sender=2)
    graph = fold(left + right, gate_records(g))
    assert len(graph.regions) == 2 and graph.adjacency == ()
    for u, v in graph.edges.tolist():
        assert (graph.places[u, 0] < 61) == (graph.places[v, 0] < 61)


def test_cut_only_by_the_gate_and_a_matching_gate_folds_into_it():
    g = two_rooms(10, 30)
    places = drive(g, [(2.0, 3.5), (10.5, 3.5)])
    gates = gate_records(g)
    assert len(fold(places, []).regions) == 1
    graph = fold(places, gates)
    assert len(graph.regions) == 2 and len(graph.adjacency) == 1
    x, y, d, h = gates[0][2:]
    other = Gate(7, 3, x + 4, y - 5, (d + 14) % 256, h + 3)   # 0.64 m and 19.7 degrees away
    both = fold(places, gates + [other])
    assert len(both.gates) == 1 and both.gate_key(0) == graph.gate_key(0)
    assert both.partition() == graph.partition()
    assert both.gates[0, 3] == h + 3                        # the longest half length of the gate's records


# ---- no edge through a wall: procgen maps, places on random traversable cells ----------------

_MAPS = {}


def ground_truth(spec):
    if spec not in _MAPS:
        from world_sim.map_spec import resolve_map
        occ, _pose, _ = resolve_map(spec)
        assert occ.resolution_m == RES and occ.origin_x_m == 0 and occ.origin_y_m == 0
        _MAPS[spec] = np.where(occ.free, F, O).astype(np.uint8)
    return _MAPS[spec]


@settings(max_examples=20, deadline=None)
@given(st.sampled_from(["cave:1:30x30", "cave:4:30x30", "tunnel:2:30x30", "office:3:30x30"]),
       st.integers(0, 2 ** 32 - 1), st.integers(100, 400))
def test_no_edge_crosses_a_wall(spec, seed, count):
    """Places on random free cells with their certified radius in the ground truth: every
    edge between them (gates do not make edges, they only cut them) runs through free cells."""
    g = ground_truth(spec)
    rng = np.random.default_rng(seed)
    cells = np.argwhere(g == F)
    places = []
    for k, (i, j) in enumerate(cells[rng.choice(len(cells), count, replace=False)]):
        x, y = (j + rng.random()) * RES, (i + rng.random()) * RES
        places.append(Place(k % 3, k, dm(x), dm(y), place_clear_dm(g, 0, 0, RES, x, y), 0))
    graph = fold(places, [])
    assert len(graph.edges)
    for (u, v), kind in zip(graph.edges.tolist(), graph.edge_kind.tolist()):
        assert kind == 2
        pu, pv = graph.places[u], graph.places[v]
        if pu[0] == pv[0] and pu[1] == pv[1]:
            continue            # two places on one point (on the wire's dm): nothing between them
        assert free_segment(g, pu[0] / 10, pu[1] / 10, pv[0] / 10, pv[1] / 10), (pu, pv)


# ---- a pure function of the record set ----------------------------------------------------------

coord = st.integers(-60, 60)
places_st = st.lists(st.builds(Place, st.integers(0, 3), st.integers(0, 24), coord, coord, st.integers(0, 30),
                               st.integers(0, 3)), min_size=0, max_size=40)
gates_st = st.lists(st.builds(Gate, st.integers(0, 3), st.integers(25, 40), coord, coord, st.integers(0, 255),
                              st.integers(0, 120)), max_size=8)


def everything(graph):
    return (graph.digest(), graph.partition(), graph.regions, graph.adjacency, graph.cuts.tolist(),
            graph.edges.tolist(), graph.gates.tolist())


@SETTINGS
@given(places_st, gates_st, st.randoms(use_true_random=False), st.data())
def test_graph_is_a_function_of_the_record_set(places, gates, rnd, data):
    a = fold(places, gates)
    dup_p = places + (data.draw(st.lists(st.sampled_from(places), max_size=10)) if places else [])
    dup_g = gates + (data.draw(st.lists(st.sampled_from(gates), max_size=5)) if gates else [])
    rnd.shuffle(dup_p)
    rnd.shuffle(dup_g)
    b = fold(dup_p, dup_g)
    assert everything(a) == everything(b)
    probes = data.draw(st.lists(st.tuples(coord, coord), max_size=6))
    assert [a.resolve(x, y) for x, y in probes] == [b.resolve(x, y) for x, y in probes]


@SETTINGS
@given(places_st, gates_st, st.randoms(use_true_random=False), st.data())
def test_incremental_ingestion_equals_batch(places, gates, rnd, data):
    records = places + gates
    batch = Store(records)
    shuffled = records + (data.draw(st.lists(st.sampled_from(records), max_size=10)) if records else [])
    rnd.shuffle(shuffled)
    s = Store()
    looks = set(data.draw(st.lists(st.integers(0, max(len(shuffled) - 1, 0)), max_size=5)))
    for k, r in enumerate(shuffled):
        s.add(r)
        if k in looks:
            s.graph()                                    # folded in between
    assert s.digest() == batch.digest()
    assert everything(s.graph()) == everything(batch.graph())


@SETTINGS
@given(places_st, gates_st)
def test_regions_are_the_uncut_pieces_and_anchored_at_their_smallest_place(places, gates):
    graph = fold(places, gates)
    cut = graph.is_cut()
    for (u, v), c in zip(graph.edges.tolist(), cut.tolist()):
        pu, pv = graph.places[u] * 10, graph.places[v] * 10
        s = graph.segments_cm
        hit = bool(len(s)) and bool(np.any(crosses(pu[0], pu[1], pv[0], pv[1], s[:, 0], s[:, 1], s[:, 2], s[:, 3])))
        assert hit == c
        if not c:
            assert graph.region_of_place[u] == graph.region_of_place[v]
    for k, r in enumerate(graph.regions):
        if r.virtual:
            continue
        assert r.id[0] == REAL and list(r.places) == sorted(r.places)
        assert r.id[1:] == tuple(graph.places[r.places[0], :4].tolist())
        assert all(graph.region_of_place[i] == k for i in r.places)
    ids = [r.id for r in graph.regions]
    assert len(set(ids)) == len(ids)
    for a, b, g in graph.adjacency:
        assert a < b and 0 <= g < len(graph.gates)
