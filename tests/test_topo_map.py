"""The topological map: Algorithm 1 against a plain reference, graph costs against
networkx, and the map as a pure function of the record SET (order, duplicates)."""
import math

import networkx as nx
import numpy as np
from hypothesis import given, settings, strategies as st

from firmware.services.topo_map import TopoMap, fold_records, merge_rows

SETTINGS = settings(max_examples=60, deadline=None)

records = st.lists(
    st.tuples(st.integers(0, 200), st.integers(-800, 800), st.integers(-800, 800), st.just(0),
              st.integers(0, 1), st.integers(0, 255), st.integers(0, 127)),
    min_size=1, max_size=60)
# Over the wire's whole 24-bit range, a few places (records often share one) far apart.
WIRE_CM = st.integers(-(1 << 23), (1 << 23) - 1)
far_records = st.lists(st.tuples(WIRE_CM, WIRE_CM), min_size=1, max_size=6).flatmap(
    lambda places: st.lists(st.tuples(st.integers(0, 255), st.sampled_from(places), st.integers(-150, 150),
                                      st.integers(-150, 150), st.integers(0, 1), st.integers(0, 255),
                                      st.integers(0, 127)).map(
        lambda r: (r[0], r[1][0] + r[2], r[1][1] + r[3], 0, r[4], r[5], r[6])), min_size=1, max_size=60))


def reference_fold(recs, d_build_cm, d_connect_cm):
    """Algorithm 1 as printed, with a brute-force closest vertex; e_inf per vertex is the
    smallest over senders of each sender's highest revision (ties: its lower code)."""
    verts = []  # [x, y, ids, {sender: (revision, -code)}]
    edges = set()
    for sender, x, y, _z, presence, e, revision in recs:
        h = None
        if verts:
            d = [math.hypot(v[0] - x, v[1] - y) for v in verts]
            h = min(range(len(verts)), key=lambda k: (d[k], k))
            if d[h] >= d_build_cm:
                h = None
        if h is None:
            h = len(verts)
            for u, v in enumerate(verts):
                if math.hypot(v[0] - x, v[1] - y) <= d_connect_cm:
                    edges.add((h, u))
            verts.append([x, y, set(), {}])
        if presence:
            verts[h][2].add(sender)
        words = verts[h][3]
        words[sender] = max(words.get(sender, (-1, 0)), (revision, -e))
    for v in verts:
        v.append(min(-code for _rev, code in v[3].values()))
    return verts, edges


@SETTINGS
@given(st.one_of(records, far_records))
def test_fold_matches_algorithm_1_reference(recs):
    rec = np.array(recs, np.int64)
    vx, vy, _vz, ids, e, edges, lengths, *_words = fold_records(rec, 100, 250)
    verts, ref_edges = reference_fold(recs, 100, 250)
    assert [(v[0], v[1], v[4]) for v in verts] == list(zip(vx.tolist(), vy.tolist(), e.tolist()))
    for k, v in enumerate(verts):
        got = {s for s in range(256) if (int(ids[k, s >> 6]) >> (s & 63)) & 1}
        assert got == v[2]
    assert {tuple(x) for x in edges.tolist()} == ref_edges


@SETTINGS
@given(records, st.randoms(use_true_random=False), st.data())
def test_map_is_a_function_of_the_record_set(recs, rnd, data):
    a = TopoMap(1.0, 2.5)
    for r in recs:
        a.add(r)
    shuffled = list(recs) + data.draw(st.lists(st.sampled_from(recs), max_size=20))  # duplicates
    rnd.shuffle(shuffled)
    b = TopoMap(1.0, 2.5)
    looks = set(data.draw(st.lists(st.integers(0, len(shuffled) - 1), max_size=6)))
    for i, r in enumerate(shuffled):
        b.add(r)
        if i in looks:
            b.positions()   # built in steps: what came since is merged into the records held
    assert np.array_equal(a.positions(), b.positions())
    assert np.array_equal(a.e_inf_codes(), b.e_inf_codes())
    assert np.array_equal(a.edges, b.edges)
    for robot in {r[0] for r in recs}:
        assert np.array_equal(a.visited_by(robot), b.visited_by(robot))
        assert all(np.array_equal(x, y) for x, y in zip(a.word_of(robot), b.word_of(robot)))
    x, y = data.draw(st.floats(-8, 8)), data.draw(st.floats(-8, 8))
    sa, da, _ = a.costs_from(x, y)
    sb, db, _ = b.costs_from(x, y)
    assert sa == sb and np.array_equal(da, db)


@SETTINGS
@given(records, st.data())
def test_merge_rows_orders_two_sorted_sets_as_sorting_their_union(recs, data):
    union = sorted(set(recs))
    split = data.draw(st.lists(st.booleans(), min_size=len(union), max_size=len(union)))
    a = np.array([r for r, left in zip(union, split) if left], np.int64).reshape(-1, 7)
    b = np.array([r for r, left in zip(union, split) if not left], np.int64).reshape(-1, 7)
    assert merge_rows(a, b).tolist() == [list(r) for r in union]


def map_of(recs) -> TopoMap:
    t = TopoMap(1.0, 2.5)
    for r in recs:
        t.add(r)
    return t


@SETTINGS
@given(records, st.data())
def test_graph_costs_match_networkx(recs, data):
    t = map_of(recs)
    xy = t.positions()
    g = nx.Graph()
    g.add_nodes_from(range(len(xy)))
    for u, v in t.edges.tolist():
        g.add_edge(u, v, weight=math.hypot(*(xy[u] - xy[v])))
    src = data.draw(st.integers(0, len(xy) - 1))
    src_found, dist, parent = t.costs_from(*xy[src])
    expected = nx.single_source_dijkstra_path_length(g, src_found, weight="weight")
    for v in range(len(xy)):
        if v in expected:
            assert math.isclose(dist[v], expected[v], rel_tol=1e-9, abs_tol=1e-9)
            assert t.path(parent, v)[0] == src_found
        else:
            assert math.isinf(dist[v])


@SETTINGS
@given(records, st.data())
def test_costs_to_many_points_are_cost_to_each_bit_for_bit(recs, data):
    t = map_of(recs)
    xy = t.positions()
    src = data.draw(st.integers(0, len(xy) - 1))
    _, dist, _ = t.costs_from(*xy[src])
    points = data.draw(st.lists(st.tuples(st.floats(-10, 10), st.floats(-10, 10)), max_size=12))
    xs, ys = [p[0] for p in points], [p[1] for p in points]
    assert t.costs_to(dist, xs, ys).tolist() == [t.cost_to(dist, x, y)[0] for x, y in points]
    nowhere = np.full(len(xy), np.inf)
    assert t.costs_to(nowhere, xs, ys).tolist() == [math.inf] * len(points)
    # The same points again, from a teammate that reaches fewer vertices, then on a grown map.
    fewer = np.where(np.arange(len(xy)) % 2 == 0, dist, np.inf)
    assert t.costs_to(fewer, xs, ys).tolist() == [t.cost_to(fewer, x, y)[0] for x, y in points]
    t.add(data.draw(records)[0])
    _, dist, _ = t.costs_from(*xy[src])
    assert t.costs_to(dist, xs, ys).tolist() == [t.cost_to(dist, x, y)[0] for x, y in points]


def test_algorithm_1_merges_close_records_and_falls_back_when_disconnected():
    t = TopoMap(d_build_m=1.0, d_connect_m=2.5)
    t.add((1, 0, 0, 0, 1, 10, 0))
    t.add((1, 200, 0, 0, 1, 5, 0))
    t.add((2, 50, 0, 0, 1, 0, 0))   # within d_build of (0, 0): merged; robot 2 saw nothing left there
    t.add((1, 1000, 0, 0, 1, 0, 0))  # beyond d_connect of everything: an island
    assert len(t) == 3
    assert t.visited_by(2).tolist() == [True, False, False]
    assert t.e_inf_codes().tolist() == [0, 5, 0]
    assert [a.tolist() for a in t.word_of(2)] == [[0, -1, -1], [0, 0, 0]]
    src, dist, _ = t.costs_from(0.1, 0.0)
    assert src == 0 and dist[1] == 2.0 and math.isinf(dist[2])
    cost, via = t.cost_to(dist, 10.0, 0.0)
    assert via == 1 and cost == 2.0 + 8.0


def test_a_later_revision_replaces_the_senders_word_whether_it_falls_or_rises():
    t = TopoMap(d_build_m=1.0, d_connect_m=2.5)
    t.add((1, 0, 0, 0, 1, 200, 0))
    t.add((1, 0, 0, 0, 0, 0, 1))     # covered: falls to 0
    assert t.e_inf_codes().tolist() == [0]
    t.add((1, 30, 0, 0, 1, 150, 2))  # came back and saw more from there: rises again
    assert t.e_inf_codes().tolist() == [150]
    t.add((1, 0, 0, 0, 0, 90, 2))    # the same revision twice (a protocol slip): the lower code
    assert t.e_inf_codes().tolist() == [90]
    assert [a.tolist() for a in t.word_of(1)] == [[2], [90]]
    t.add((3, 20, 0, 0, 0, 0, 7))    # another robot finds nothing left: it does not replace robot 1's word,
    assert t.e_inf_codes().tolist() == [0]   # but the vertex takes the smaller of the two
    assert [a.tolist() for a in t.word_of(1)] == [[2], [90]]
