"""Map merging without a common frame: the properties of the consensus
(firmware/schemes/mr_topomap/merge.py; mrtopomap.md 5.3, A1-A3, test 6.1.4; issue 25 item 6):
the result depends on the set of records held only (order, duplicates, incremental
arrival), re-expressing the own records in another frame moves T with it, one or two
matches never merge, a wrong early cluster is corrected by later evidence (the paper's Fig.
4), true matches outvote random wrong ones, and the check against the own map refuses what
puts a teammate's vertices in the own walls.

Scans, maps and frames come from world_sim (tests/test_mrtopomap_world.py)."""
from __future__ import annotations

import json
import math
import random

import numpy as np
import pytest
from scipy.stats import poisson
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from firmware.kernels import FREE, OCCUPIED
from firmware.schemes.mr_topomap import descriptor as D
from firmware.schemes.mr_topomap import merge as M
from firmware.schemes.mr_topomap.params import DEFAULT
from firmware.schemes.mr_topomap.records import Vertex
from tests import test_mrtopomap_world as W

CAVE = "cave:1:60x60"


def _yaw_deg(a: float) -> float:
    return math.degrees(abs((a + math.pi) % (2 * math.pi) - math.pi))


# ---- the result is a function of the record set ---------------------------------------

FA = M.SE2(0.7, 1234.5, -321.0)
FB = M.SE2(-2.1, -456.7, 890.1)


@pytest.fixture(scope="module")
def half_scene():
    A, B, axy, bxy, own = W.pair_records(CAVE, 77, FA, FB, "half")
    grid = M.ProfileGrid.of_map(own.state, own.row0, own.col0, own.res_m, W.RANGE_MAX)
    return A, B, bxy, own, grid


def _same(r1: M.MergeResult, r2: M.MergeResult) -> None:
    assert r1.merged == r2.merged and r1.reason == r2.reason
    assert r1.T == r2.T                                    # bit for bit
    assert r1.inliers == r2.inliers and r1.support == r2.support and r1.second == r2.second


@settings(max_examples=25, deadline=None)
@given(st.randoms(use_true_random=False), st.integers(0, 40), st.integers(0, 40))
def test_order_and_duplicates_do_not_change_the_merge(half_scene, rnd, dup_a, dup_b):
    A, B, _, own, _ = half_scene
    ref = M.estimate(M.VertexSet(A), M.VertexSet(B), None, own)
    a = A + [rnd.choice(A) for _ in range(dup_a)]
    b = B + [rnd.choice(B) for _ in range(dup_b)]
    rnd.shuffle(a)
    rnd.shuffle(b)
    _same(ref, M.estimate(M.VertexSet(a), M.VertexSet(b), None, own))


def test_incremental_records_in_any_order_end_where_the_batch_does(half_scene):
    """With the profile grid and the own map: a teammate's records fed one by one, shuffled,
    with duplicates, updating after each, end at the batch result bit for bit."""
    A, B, bxy, own, grid = half_scene
    own_set = M.VertexSet(A)
    ref = M.estimate(own_set, M.VertexSet(B), grid, own)
    assert ref.merged and W.merge_error(ref.T, FA, FB, bxy)[0] <= 0.6
    for seed in (1, 2):
        rnd = random.Random(seed)
        feed = B + rnd.sample(B, 10)
        rnd.shuffle(feed)
        tm = M.TeammateMerge(2)
        for k, v in enumerate(feed):
            tm.add(v)
            if k % 15 == 0:
                tm.update(own_set, grid, own, own_map_token=0)
        _same(ref, tm.update(own_set, grid, own, own_map_token=0))


def test_conflicting_records_under_one_key_keep_the_same_one_in_any_order(same_scene):
    """Two different records under one (owner, id): the one with the smaller bytes, whatever
    came first."""
    _, B, _, _, _ = same_scene
    other = B[4]._replace(x_dm=B[4].x_dm + 7)
    s1 = M.VertexSet(B + [other])
    s2 = M.VertexSet([other] + B[::-1])
    assert s1.vertices == s2.vertices and s1.token == s2.token and len(s1) == len(B)


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 31), st.floats(-1000, 1000), st.floats(-1000, 1000))
def test_re_expressing_the_own_records_in_another_frame_moves_t_with_it(same_scene, k, gx, gy):
    """Apply G (a yaw of k bins) to every own position and roll the own descriptors by k:
    T' = G T, and the same teammate vertices are the inliers (spec 6.1.4). (No own map: a
    grid map does not turn by an arbitrary angle exactly.)"""
    A, B, _, bxy, _ = same_scene
    G = M.SE2(k * D.BIN_RAD, gx, gy)
    moved = []
    for v in A:
        p = G.apply(np.array([v.x_m, v.y_m]))
        moved.append(v._replace(x_dm=int(round(p[0] * 10)), y_dm=int(round(p[1] * 10)),
                                desc=v.desc._replace(codes=tuple(int(c) for c in np.roll(v.desc.codes, k)))))
    r = M.estimate(M.VertexSet(A), M.VertexSet(B))
    r2 = M.estimate(M.VertexSet(moved), M.VertexSet(B))
    assert r.merged and r2.merged
    assert sorted({b for _, b in r.inliers}) == sorted({b for _, b in r2.inliers})
    pb = FB.apply(bxy)
    d = G.compose(r.T).apply(pb) - r2.T.apply(pb)
    assert np.sqrt((d ** 2).sum(axis=1).mean()) <= 0.1
    assert _yaw_deg(G.psi + r.T.psi - r2.T.psi) <= 0.5


def test_a_profile_grid_re_expressed_with_the_records_moves_t_with_it(half_scene):
    """The same with the profile grid (its points moved and its codes rolled) for one G."""
    A, B, bxy, _, grid = half_scene
    k, G = 5, M.SE2(5 * D.BIN_RAD, -321.0, 77.0)
    moved = [v._replace(x_dm=int(round(G.apply(np.array([v.x_m, v.y_m]))[0] * 10)),
                        y_dm=int(round(G.apply(np.array([v.x_m, v.y_m]))[1] * 10)),
                        desc=v.desc._replace(codes=tuple(int(c) for c in np.roll(v.desc.codes, k)))) for v in A]
    r = M.estimate(M.VertexSet(A), M.VertexSet(B), grid)
    r2 = M.estimate(M.VertexSet(moved), M.VertexSet(B), M.ProfileGrid(G.apply(grid.xy), np.roll(grid.codes, k, axis=1)))
    assert r.merged and r2.merged
    pb = FB.apply(bxy)
    d = G.compose(r.T).apply(pb) - r2.T.apply(pb)
    assert np.sqrt((d ** 2).sum(axis=1).mean()) <= 0.1


# ---- outliers, mismatches and their correction (the paper's Fig. 4) --------------------

@pytest.fixture(scope="module")
def same_scene():
    A, B, axy, bxy, own = W.pair_records(CAVE, 11, FA, FB, "same", n=30)
    return A, B, axy, bxy, own


def _lookalikes(A, idx, G: M.SE2, first_id: int, owner: int = 2) -> list[Vertex]:
    """Fake teammate vertices that G maps exactly onto own vertices idx, with their views
    (rolled by G's yaw, a whole number of bins): a cluster as consistent as a true one."""
    k = int(round(G.psi / D.BIN_RAD))
    inv = G.inverse()
    out = []
    for n, i in enumerate(idx):
        q = inv.apply(np.array([A[i].x_m, A[i].y_m]))
        out.append(Vertex(owner, first_id + n, int(round(q[0] * 10)), int(round(q[1] * 10)), owner, 4095, 0,
                          A[i].desc._replace(codes=tuple(int(c) for c in np.roll(A[i].desc.codes, -k)))))
    return out


def test_a_single_match_never_merges_nor_fewer_than_k_min(same_scene):
    A, B, _, _, own = same_scene
    one = M.estimate(M.VertexSet(A), M.VertexSet(B[:1]), None, own)
    assert not one.merged
    for n in range(2, DEFAULT.k_min):
        r = M.estimate(M.VertexSet(A), M.VertexSet(B[:n]), None, own)
        assert not r.merged and r.reason in ("support below k_min", "no hypotheses", "all refused")
        r = M.estimate(M.VertexSet(A), M.VertexSet(B[:n]))        # no own map: consensus alone
        assert not r.merged and r.support < DEFAULT.k_min


def test_a_wrong_cluster_is_corrected_by_later_evidence(same_scene):
    """k_min look-alikes under a wrong transform merge first (nothing contradicts them yet);
    with the true vertices later the true cluster wins (>= 2 x k_min): one correction."""
    A, B, axy, bxy, own = same_scene
    wrong = M.SE2(8 * D.BIN_RAD, 35.0, -20.0)
    fakes = _lookalikes(A, list(range(3, 3 + DEFAULT.k_min)), wrong, first_id=100)
    tm = M.TeammateMerge(2)
    for v in fakes:
        tm.add(v)
    r = tm.update(M.VertexSet(A))
    assert r.merged and r.support == DEFAULT.k_min and abs(r.T.tx - wrong.tx) < 0.2 and abs(r.T.ty - wrong.ty) < 0.2
    true_ids = []
    for v in B:
        tm.add(v)
        true_ids.append(v.vid)
        r = tm.update(M.VertexSet(A))
    assert r.merged and W.merge_error(r.T, FA, FB, bxy)[0] <= 0.3
    assert tm.corrections == 1 and tm.merges - tm.unmerges == 1


@settings(max_examples=25, deadline=None)
@given(st.integers(4, 24), st.data())
def test_c_true_matches_outvote_c_over_2_wrong_ones(same_scene, c, data):
    """With c true matches and <= c/2 random wrong ones (look-alikes of random own vertices
    at random places and yaws), T is the true one."""
    A, B, _, bxy, own = same_scene
    rng = np.random.default_rng(data.draw(st.integers(0, 10**6)))
    picked = sorted(rng.choice(len(B), size=min(c, len(B)), replace=False))
    wrong = []
    for n in range(data.draw(st.integers(0, c // 2))):
        G = M.SE2(int(rng.integers(32)) * D.BIN_RAD, float(rng.uniform(-500, 500)), float(rng.uniform(-500, 500)))
        wrong += _lookalikes(A, [int(rng.integers(len(A)))], G, first_id=200 + n)
    r = M.estimate(M.VertexSet(A), M.VertexSet([B[i] for i in picked] + wrong), None, None)
    if r.merged:
        assert W.merge_error(r.T, FA, FB, bxy[picked])[0] <= 0.5
    else:                                       # too few of the c true ones matched at th_merge
        assert r.reason in ("support below k_min", "ratio test")
        assert r.best is None or W.merge_error(r.best.T, FA, FB, bxy[picked])[0] <= 0.5 or r.support < 3


def test_the_occupancy_check_refuses_what_puts_vertices_in_the_own_walls():
    """Teammate vertices that the true transform puts deep inside walls the own robot saw
    from both sides: two are refused (more than max(1, 2 %)), one is tolerated."""
    rng = np.random.default_rng(21)
    axy = W.poisson_points(CAVE, rng, 2.0, max_points=400)
    A = W.vertices(CAVE, 1, axy, FA, rng)
    own = W.own_map(CAVE, axy, FA)
    deep = np.argwhere(own.depth_m > 0.6)
    assert len(deep) > 100
    bxy = W.jitter(CAVE, axy[:40], rng, 0.3)
    B = W.vertices(CAVE, 2, bxy, FB, rng)
    ok = M.estimate(M.VertexSet(A), M.VertexSet(B), None, own)
    assert ok.merged
    inl_world = bxy[[k[1] for _, k in ok.inliers]]
    # the two wall cells nearest to the inliers, A's frame -> world -> B's frame
    pts = np.stack([(own.col0 + deep[:, 1] + 0.5) * own.res_m, (own.row0 + deep[:, 0] + 0.5) * own.res_m], axis=1)
    world = FA.inverse().apply(pts)
    d = np.sqrt(((world[:, None, :] - inl_world[None, :, :]) ** 2).sum(axis=2)).min(axis=1)
    nearest = np.argsort(d, kind="stable")
    world = world[nearest[[0, 40]]]                      # two cells some way apart
    assert d[nearest[40]] < DEFAULT.occ_radius_m - 1.0
    blank = W.descriptor_at(CAVE, *inl_world[0], 0.0, FB.psi, rng)._replace(codes=(8,) * 32)
    in_walls = [Vertex(2, 300 + n, *[int(round(c * 10)) for c in FB.apply(w)], 2, 4095, 0, blank)
                for n, w in enumerate(world)]
    one = M.estimate(M.VertexSet(A), M.VertexSet(B + in_walls[:1]), None, own)
    assert one.merged and one.best.bad >= 1
    two = M.estimate(M.VertexSet(A), M.VertexSet(B + in_walls), None, own)
    assert not two.merged and two.refused and two.refused[0].bad >= 2
    for cl in two.clusters:
        assert cl.bad <= max(DEFAULT.occ_tolerated, DEFAULT.occ_share * cl.tested)


def test_own_map_checks():
    """OwnMap: free where the robot was is fine; deep in an enclosed wall is bad; unknown
    open space is not tested; a free pocket not connected to where the robot was is bad."""
    state = np.zeros((100, 100), dtype=np.uint8)
    state[10:90, 10:90] = OCCUPIED
    state[20:40, 20:80] = FREE                 # room 1
    state[60:80, 20:80] = FREE                 # room 2, a 2 m wall between
    state[45:47, 45:47] = FREE                 # a pocket inside the wall
    state[40:60, 50:53] = FREE                 # a door from room 1 to room 2
    m = M.OwnMap(state, 0, 0, 0.1, np.array([[3.0, 3.0]]))
    pts = np.array([[5.0, 3.0], [3.0, 5.0], [0.5, 0.5], [9.5, 9.5], [4.6, 4.6], [3.0, 5.0]])
    tested, bad = m.check(pts)
    assert tested == 4 and bad == 3           # room 1 fine; the wall interior twice and the pocket bad;
    #                                           (0.5, 0.5) and (9.5, 9.5) are open unknown
    assert m.check(np.array([[4.6, 4.6]])) == (1, 1)                # the pocket: free but unreachable
    assert m.check(np.array([[3.0, 7.0]])) == (1, 0)                # room 2, through the door


@settings(max_examples=50, deadline=None)
@given(st.integers(1, 5000), st.integers(1, 40), st.floats(1.0, 1e5))
def test_chance_clusters_is_the_poisson_tail_of_uniform_hypotheses(n_hyp, support, area_m2):
    """NFA = H P(Poisson(H p) >= support - 1), p = (pi inlier_m^2 / area) (2 inlier_deg / 360 deg):
    more support is rarer, more hypotheses or less area make it commoner."""
    p = min(1.0, math.pi * DEFAULT.inlier_m ** 2 / area_m2 * 2 * DEFAULT.inlier_deg / 360.0)
    nfa = M.chance_clusters(n_hyp, support, area_m2)
    want = n_hyp * (poisson.sf(support - 2, n_hyp * p) if support > 1 else 1.0)
    assert nfa == pytest.approx(want, rel=1e-9, abs=1e-300)
    assert M.chance_clusters(n_hyp, support + 1, area_m2) <= nfa
    assert M.chance_clusters(n_hyp + 1, support, area_m2) >= nfa
    assert M.chance_clusters(n_hyp, support, area_m2 * 2) <= nfa



@settings(max_examples=5, deadline=None)
@given(st.integers(0, 10**6))
def test_grid_scores_kept_between_calls_give_the_same_hypotheses(seed):
    """While the own map grows (the profile grid rendered again from more of it, most
    lattice points keeping their profile; at the end every profile held twice) and a
    teammate's vertices come and go in any subset, the hypotheses with the grid's scores
    kept from call to call are those scored afresh, bit for bit."""
    rng = np.random.default_rng(seed)
    A, B, axy, _, _ = W.pair_records(CAVE, seed, FA, FB, "half")
    kept = M.PairScores()
    scored = 0
    for share in (0.4, 0.4, 0.7, 1.0, 1.0):
        n_own = max(1, int(round(len(axy) * share)))
        own = W.own_map(CAVE, axy[:n_own], FA)
        grid = M.ProfileGrid.of_map(own.state, own.row0, own.col0, own.res_m, W.RANGE_MAX)
        if share == 1.0:         # every profile twice, at two places
            grid = M.ProfileGrid(np.vstack([grid.xy, grid.xy + 0.25]), np.vstack([grid.codes, grid.codes]))
        theirs = M.VertexSet([B[i] for i in rng.permutation(len(B))[:int(rng.integers(1, len(B) + 1))]])
        own_set = M.VertexSet(A[:n_own])
        fresh = M.hypotheses(own_set, theirs, grid)
        again = M.hypotheses(own_set, theirs, grid, grid_scores=kept)
        scored += len(fresh) > 0       # a subset of one or two vertices may give none
        for name in fresh._fields:
            assert np.array_equal(getattr(again, name), getattr(fresh, name)), name
    assume(scored > 0)                 # an example where nothing was scored shows nothing


def test_the_merge_rates_tool_tabulates_its_draws(tmp_path, capsys):
    """tests/mrtopomap_merge_rates.py, the README's static draws: a row per draw, a table by
    map and areas, a clear refusal of an unknown parameter."""
    from tests import mrtopomap_merge_rates as rates

    out_file = tmp_path / "draws.jsonl"
    assert rates.main(["--draws", "2", "--json", str(out_file)]) == 0
    rows = [json.loads(line) for line in out_file.read_text().splitlines()]
    assert [r["map"] for r in rows] == ["cave:1:60x60", "intel.yaml"] and all(r["mode"] == "half" for r in rows)
    table = capsys.readouterr().out
    merged_right = sum(1 for r in rows[:1] if r["merged"] and r["right"])
    assert f"| cave:1:60x60 | half | 1 | {merged_right} |" in table
    with pytest.raises(SystemExit, match="no_such_field"):
        rates.main(["--draws", "1", "--set", "no_such_field=1"])
