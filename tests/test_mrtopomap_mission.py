"""MR-TopoMap as a registered scheme (firmware/schemes/mr_topomap/scheme.py): missions with
each robot's odometry in its own frame and spread starts, merges checked against the truth
only the host knows; the literal ablation's merge; the spread starts themselves."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.sparse.csgraph import dijkstra

from firmware.comms.frame import decode_frame
from firmware.schemes import build, resolve
from firmware.schemes.mr_topomap.literal import LiteralMerge, smmr_mean
from firmware.schemes.mr_topomap.merge import SE2, VertexSet
from firmware.schemes.mr_topomap.records import DIALECT, Vertex
from host_tools.merge_metrics import pair_error, true_relations
from host_tools.mission import MissionConfig, run_mission
from world_sim.map_spec import clearance_field_m, resolve_map, spread_poses


def test_the_scheme_is_registered_and_needs_no_shared_frame():
    s = build("mrtopomap")
    assert s.dialect is DIALECT and "shared_frame" not in s.needs_of() and "radio" in s.needs_of()
    assert resolve("mrtopomap-literal") == ("mrtopomap", "literal")


@pytest.fixture(scope="module")
def two_robots():
    """Two robots on a 30 x 30 m cave, own frames, starts 10-20 m of driving apart with random
    yaws, over the EU 10 % band (about 45 s of wall time)."""
    return run_mission(MissionConfig(map_spec="cave:3:30x30", robots=2, seed=1, max_sim_s=1800, radio="eu868-g3",
                                     strategy="mrtopomap", frames="own", spread_m=10.0, spread_max_m=20.0))


def test_two_robots_in_their_own_frames_merge_right(two_robots):
    r = two_robots
    yaws = [p[2] for p in r.start_poses]
    assert abs(math.remainder(yaws[0] - yaws[1], 2 * math.pi)) > math.radians(20), "the frames differ in yaw"
    fm = r.frame_merges
    assert fm["merged_at_end"] == 2 and fm["right_at_end"] == 2 and fm["ever_wrong"] == 0
    assert fm["rms_m_max"] <= 0.6 and fm["yaw_deg_max"] <= 3.0
    # Each robot's view of the pair agrees: T_01 composed with T_10 is close to identity.
    a, b = (ag.scheme.frame_merges() for ag in r.agents)
    loop = a[1].compose(b[0])
    assert math.hypot(loop.tx, loop.ty) <= 0.5 and abs(math.degrees(loop.psi)) <= 2.0


def test_two_robots_stop_by_themselves_and_cover_the_cave(two_robots):
    r = two_robots
    assert r.termination in ("complete", "complete_with_unreachable_frontiers")
    assert all(a.done for a in r.agents) and r.coverage >= 0.97 and r.robots_in_wall == 0
    assert r.radio["duty_cycle_violations"] == 0
    sent = {name for air in r.air_frames for name, _ in decode_frame(air.payload).frame.records}
    assert {"mrvtx", "mrud", "mrlink"} <= sent <= {"mrvtx", "mredge", "mrud", "mrlink", "pose"}
    stats = r.to_json()["explorer_stats"]
    assert min(stats["vertices_built"]) >= 5 and min(stats["teammates_merged"]) == 1
    # Each robot told its merge and heard the other's; two robots' links only confirm.
    assert min(stats["links_sent"]) >= 1 and min(stats["links_heard"]) >= 1
    assert max(stats["merges_outvoted"]) == 0 and max(stats["merges_transitive"]) == 0


def test_merged_teammates_count_in_planning(two_robots):
    """Once merged, a teammate's vertices are in the own frame where the truth puts them,
    and the drawn map holds them."""
    r = two_robots
    truth = true_relations(r.start_poses, "own")
    for n, ag in enumerate(r.agents):
        j = 1 - n
        T = ag.scheme.frame_merges()[j]
        q = ag.scheme.teammate_vertex_xy(j)
        moved = T.apply(q)
        h = np.column_stack([q, np.ones(len(q))])
        assert np.sqrt((((h @ truth[n][j].T)[:, :2] - moved) ** 2).sum(axis=1)).max() <= 1.0
        assert pair_error(T, truth[n][j], q)[0] <= 0.6
        assert len(ag.scheme.drawables()["points"]) == len(ag.scheme.own_vertex_xy()) + len(q)


def _vertex(owner: int, vid: int, x: float, y: float, codes) -> Vertex:
    from firmware.schemes.mr_topomap.descriptor import Descriptor
    return Vertex(owner, vid, round(x * 10), round(y * 10), owner, vid - 1 if vid else 4095, 0,
                  Descriptor(tuple(int(c) for c in codes), 16, 4))


def test_the_literal_merge_is_a_translation_from_the_first_match():
    rng = np.random.default_rng(3)
    codes = [rng.integers(0, 16, 32) for _ in range(4)]
    own = VertexSet([_vertex(0, k, 2.0 * k, 1.0, codes[k]) for k in range(4)])
    m = LiteralMerge(1)
    # Teammate 1 saw places 2 and 0 (in that order) from a frame shifted by (-5, 3) and turned
    # by 90 degrees: the literal merge takes no rotation, and the first match decides.
    for vid, k in enumerate((2, 0)):
        x, y = 2.0 * k + 5.0, 1.0 - 3.0
        m.add(_vertex(1, vid, -y, x, codes[k]))       # the same place in a frame turned by 90 degrees
    r = m.update(own)
    assert r.merged and r.T.psi == 0.0
    assert (r.T.tx, r.T.ty) == pytest.approx((4.0 - 2.0, 1.0 - 9.0))     # place 2: (4, 1) - (-(-2), 9)
    assert m.merges == 1


def test_smmr_drops_the_samples_off_the_mean():
    assert smmr_mean(np.array([[1.0, 1.0], [9.0, 9.0]])).tolist() == [1.0, 1.0]   # below three: the first
    s = np.array([[0.0, 0.0], [0.2, 0.1], [-0.1, 0.1], [10.0, -8.0]])
    assert np.allclose(smmr_mean(s), s[:3].mean(axis=0))


@pytest.mark.parametrize("spec", ["cave:1:60x60", "office:2"])
def test_spread_starts_are_far_apart_by_driving_and_repeatable(spec):
    occ, start, _ = resolve_map(spec)
    poses = spread_poses(occ, start, 4, 10.0, 25.0, seed=7)
    assert poses == spread_poses(occ, start, 4, 10.0, 25.0, seed=7)
    assert poses != spread_poses(occ, start, 4, 10.0, 25.0, seed=8)
    clearance = clearance_field_m(occ.free, occ.resolution_m)
    cells = [occ.cell_of(x, y) for x, y, _ in poses]
    assert all(clearance[c] >= 0.5 for c in cells)
    # Driving distances for the body (0.25 m) on the map's own lattice, 8-connected: >= 10 m
    # apart, each within 25 m of one placed before (5 % slack for the coarse lattice spread_poses uses).
    roomy = clearance >= 0.25
    from scipy.sparse import coo_matrix
    idx = -np.ones(roomy.shape, np.int64)
    pts = np.argwhere(roomy)
    idx[pts[:, 0], pts[:, 1]] = np.arange(len(pts))
    src, dst, w = [], [], []
    for dr, dc in ((0, 1), (1, 0), (1, 1), (1, -1)):
        b = pts + (dr, dc)
        ok = (b >= 0).all(axis=1) & (b[:, 0] < roomy.shape[0]) & (b[:, 1] < roomy.shape[1])
        a, b = pts[ok], b[ok]
        ok = roomy[b[:, 0], b[:, 1]]
        src.append(idx[a[ok, 0], a[ok, 1]])
        dst.append(idx[b[ok, 0], b[ok, 1]])
        w.append(np.full(int(ok.sum()), math.hypot(dr, dc) * occ.resolution_m))
    g = coo_matrix((np.concatenate(w), (np.concatenate(src), np.concatenate(dst))), shape=(len(pts),) * 2)
    d = dijkstra(g.tocsr(), directed=False, indices=[idx[c] for c in cells])
    between = d[:, [idx[c] for c in cells]]
    off = ~np.eye(len(poses), dtype=bool)
    assert between[off].min() >= 10.0 * 0.95
    for k in range(1, len(poses)):
        assert between[k, :k].min() <= 25.0 * 1.05
    assert len({round(p[2], 3) for p in poses}) == len(poses)


def test_spread_starts_refuse_what_does_not_fit():
    occ, start, _ = resolve_map("cave:5:20x20")
    with pytest.raises(ValueError, match="start poses fit"):
        spread_poses(occ, start, 6, 40.0, seed=0)
    with pytest.raises(ValueError, match="spread starts"):
        run_mission(MissionConfig(map_spec="cave:5:20x20", robots=2, starts=((5.0, 5.0, None), (6.0, 5.0, None)),
                                  spread_m=5.0))


def test_se2_helpers_agree_with_the_host_truth():
    """merge.SE2 and host_tools.merge_metrics describe the same transforms."""
    poses = [(3.0, -2.0, 0.4), (-7.0, 5.0, -2.1)]
    T = true_relations(poses, "own")[0][1]
    est = SE2(math.atan2(T[1, 0], T[0, 0]), T[0, 2], T[1, 2])
    q = np.array([[1.0, 2.0], [-4.0, 0.5]])
    assert pair_error(est, T, q) == pytest.approx((0.0, 0.0), abs=1e-9)
    assert true_relations(poses, "shared")[0][1] == pytest.approx(np.eye(3))
