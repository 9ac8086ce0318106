"""WiSER-X as a scheme (firmware/schemes/wiserx/): the per-teammate track layer (relpos), the
coverage record (hgrid), the utility of eqs. (2)-(7), and the scheme on the robot: it needs
UWB and AoA, sends nothing over LoRa, and a small team stops by itself.
(../shared/schemes/wiserx.md sections 1.4-1.8, 6.1, 6.8.)"""
import math

import numpy as np
import pytest

from firmware import kernels
from firmware.agent import ExplorerAgent
from firmware.schemes import build, resolve
from firmware.schemes.wiserx import utility as U
from firmware.schemes.wiserx.hgrid import HGrid
from firmware.schemes.wiserx.params import EkfParams, WiserxParams
from firmware.schemes.wiserx.relpos import RelPos, circular_median, polar_fix
from firmware.services.deployment import Deployment
from hal.bundle import Hal
from hal.samples import AoaBearing, UwbRange
from host_tools.mission import MissionConfig, run_mission
from tests.doubles import ScriptedHal

S = 1_000_000


def _pose_at(xy=(0.0, 0.0), yaw=0.0):
    return lambda stamp_us: (xy[0], xy[1], yaw)


def _rng_samples(peer_xy, n, seed=0, own=(0.0, 0.0), yaw=0.0, period_s=1.0, range_std=0.1, bearing_std_deg=5.0):
    """n paired range and bearing samples of a teammate standing at peer_xy."""
    rng = np.random.default_rng(seed)
    d = math.hypot(peer_xy[0] - own[0], peer_xy[1] - own[1])
    b = math.atan2(peer_xy[1] - own[1], peer_xy[0] - own[0]) - yaw
    ranges, bearings = [], []
    for k in range(n):
        t = round((k + 1) * period_s * S)
        ranges.append(UwbRange(t, 1, d + range_std * rng.standard_normal()))
        bearings.append(AoaBearing(t, 1, b + math.radians(bearing_std_deg) * rng.standard_normal()))
    return ranges, bearings


# --- relpos -----------------------------------------------------------------------------------

def test_a_standing_teammate_is_located_from_paired_ranges_and_bearings():
    rp = RelPos(0)
    ranges, bearings = _rng_samples((12.0, 5.0), 20)
    rp.feed(ranges, bearings, _pose_at())
    (e,) = rp.estimates(20 * S, 5.0)
    err = np.array([e.x_m - 12.0, e.y_m - 5.0])
    # Within the filter's own 99.9 % ellipse, and close (one bearing of 5 deg at 13 m is 1.1 m).
    assert e.peer_id == 1 and err @ np.linalg.solve(e.cov, err) < 13.8 and np.hypot(*err) < 1.5
    assert rp.counts()["tracks_started"] == 1 and rp.counts()["ranges_accepted"] == 20


def test_bearings_are_taken_in_the_robots_own_frame_with_its_yaw_at_the_sample_time():
    """The robot faces +y (yaw 90 deg): a teammate straight ahead in its body frame (bearing
    0) stands at +y of its odometry frame."""
    rp = RelPos(0)
    ranges, bearings = _rng_samples((0.0, 10.0), 10, own=(0.0, 0.0), yaw=math.pi / 2, range_std=0.0,
                                    bearing_std_deg=0.0)
    rp.feed(ranges, bearings, _pose_at(yaw=math.pi / 2))
    (e,) = rp.estimates(10 * S, 5.0)
    assert e.x_m == pytest.approx(0.0, abs=1e-6) and e.y_m == pytest.approx(10.0, abs=1e-6)


def test_each_sample_is_paired_with_the_own_pose_of_its_time():
    asked = []

    def pose_at(stamp_us):
        asked.append(stamp_us)
        return (stamp_us / S, 0.0, 0.0)        # the robot drives along x at 1 m/s

    rp = RelPos(0)
    # The teammate stands at (10, 5); from the robot at x = t, it is at (10 - t, 5).
    ranges = [UwbRange(t * S, 1, math.hypot(10.0 - t, 5.0)) for t in (1, 2, 3)]
    bearings = [AoaBearing(t * S, 1, math.atan2(5.0, 10.0 - t)) for t in (1, 2, 3)]
    rp.feed(ranges, bearings, pose_at)
    assert asked == [S, 2 * S, 3 * S]
    (e,) = rp.estimates(3 * S, 5.0)
    assert math.hypot(e.x_m - 10.0, e.y_m - 5.0) < 1e-6


def test_a_range_jumping_more_than_3_m_is_held_back_unless_three_in_a_row_agree():
    p = WiserxParams()
    rp = RelPos(0, p)
    ranges, bearings = _rng_samples((10.0, 0.0), 5, range_std=0.0, bearing_std_deg=0.0, period_s=0.1)
    rp.feed(ranges, bearings, _pose_at())
    track = rp.tracks[1]
    before = track.counts["ranges_accepted"]
    # One late-path outlier, 0.1 s later: refused.
    rp.feed([UwbRange(600_000, 1, 14.0)], [], _pose_at())
    assert track.counts["ranges_held_back"] == 1 and track.counts["ranges_accepted"] == before
    # Three agreeing jumps in a row are taken (the teammate really is there).
    rp.feed([UwbRange(700_000, 1, 14.1), UwbRange(800_000, 1, 14.05)], [], _pose_at())
    assert track.counts["ranges_held_back"] == 2
    assert track.counts["ranges_accepted"] >= before + 1 or track.counts["gate_rejections"] >= 1


def test_the_jump_allowed_grows_with_the_time_since_the_last_accepted_range():
    rp = RelPos(0)
    ranges, bearings = _rng_samples((10.0, 0.0), 3, range_std=0.0, bearing_std_deg=0.0)
    rp.feed(ranges, bearings, _pose_at())
    # 10 s later 14 m is within 3 m + 2 m/s x 10 s of 10 m: not held back.
    rp.feed([UwbRange(13 * S, 1, 14.0)], [], _pose_at())
    assert rp.tracks[1].counts["ranges_held_back"] == 0


def test_an_outlying_bearing_off_the_recent_median_is_refused_once_the_track_is_good():
    rp = RelPos(0)
    ranges, bearings = _rng_samples((10.0, 0.0), 30, bearing_std_deg=2.0)
    rp.feed(ranges, bearings, _pose_at())
    t = rp.tracks[1]
    n = t.counts["bearings_off_median"]
    rp.feed([], [AoaBearing(31 * S, 1, math.radians(60.0))], _pose_at())
    assert t.counts["bearings_off_median"] == n + 1
    (e,) = rp.estimates(31 * S, 5.0)
    assert math.hypot(e.x_m - 10.0, e.y_m) < 0.5


def test_silence_makes_a_teammate_failed_and_its_next_sample_revives_it():
    p = WiserxParams(silence_fail_s=30.0)
    rp = RelPos(0, p)
    ranges, bearings = _rng_samples((10.0, 0.0), 5)
    rp.feed(ranges, bearings, _pose_at())
    assert rp.check_silence(34 * S) == [] and rp.alive(1)
    assert rp.check_silence(36 * S) == [1] and not rp.alive(1)
    assert rp.estimates(36 * S, 1e6) == []            # its track is dropped
    rp.feed([UwbRange(40 * S, 1, 10.0)], [], _pose_at())
    assert rp.alive(1) and rp.counts()["revivals"] == 1 and rp.counts()["failures"] == 1


def test_own_samples_and_unusable_values_are_ignored():
    rp = RelPos(3)
    rp.feed([UwbRange(S, 3, 5.0), UwbRange(S, 1, float("nan")), UwbRange(S, 1, 0.0)],
            [AoaBearing(S, 3, 0.1), AoaBearing(S, 1, 0.1, rank=1)], _pose_at())
    assert rp.tracks == {}


def test_circular_median_across_pi():
    assert circular_median([math.radians(179), math.radians(-179), math.radians(178)]) == pytest.approx(
        math.radians(179))


def test_polar_fix_covariance_is_the_first_order_propagation():
    z, R = polar_fix(10.0, math.pi / 2, (1.0, 2.0), EkfParams(range_std_m=0.1, bearing_std_rad=0.05))
    assert z == pytest.approx([1.0, 12.0])
    assert R[0, 0] == pytest.approx((10 * 0.05) ** 2) and R[1, 1] == pytest.approx(0.01)


# --- hgrid -----------------------------------------------------------------------------------

def test_cells_are_ceil_L_over_r_a_side_and_edges_belong_to_cells():
    g = HGrid(0, (0.0, 0.0, 45.0, 25.0), params=WiserxParams(sensor_range_m=10.0))
    assert (g.nx, g.ny) == (5, 3) and g.sx == pytest.approx(9.0) and g.sy == pytest.approx(25 / 3)
    assert g.cell_of(0.0, 0.0) == (0, 0) and g.cell_of(45.0, 25.0) == (2, 4) and g.cell_of(9.0, 0.0) == (0, 1)
    assert g.cell_of(-0.01, 3.0) is None and g.cell_of(3.0, 25.01) is None


def test_pts2_fills_a_cell_with_two_points_of_live_robots():
    g = HGrid(0, (0.0, 0.0, 20.0, 20.0), params=WiserxParams.paper(sensor_range_m=10.0))
    g.insert(0, 5.0, 5.0, 1.0, 0)
    assert g.fill() == 0.0
    g.insert(1, 6.0, 5.0, 0.3, 0)
    assert g.filled()[0, 0] and g.fill() == pytest.approx(0.25)
    g.set_alive(1, False)                 # eq. (7): the failed robot's point stops counting
    assert g.fill() == 0.0
    g.set_alive(1, True)
    assert g.fill() == pytest.approx(0.25)


def test_disc_fills_a_cell_half_within_r_of_a_point():
    p = WiserxParams(sensor_range_m=10.0, fill_lattice_m=1.0, fill_disc_share=0.5)
    g = HGrid(0, (0.0, 0.0, 20.0, 10.0), params=p)
    # A point on the cells' common edge: every test point of both cells within 10 m of it.
    g.insert(0, 10.0, 5.0, 1.0, 0)
    assert g.filled().all()
    g2 = HGrid(0, (0.0, 0.0, 40.0, 10.0), params=p)
    # A point at x = 0: within r of columns 0-9 (all of cell 0, none of cell 1 whose test
    # points start at x = 10.5).
    g2.insert(0, 0.0, 5.0, 1.0, 0)
    assert g2.filled().tolist() == [[True, False, False, False]]


def test_the_footprint_counts_only_cells_with_enough_navigable_area():
    nav = np.zeros((20, 20))
    nav[:10, :10] = 1.0                 # 100 m2 in cell (0, 0)
    nav[15, 15] = 1.0                   # 1 m2 in cell (1, 1)
    g = HGrid(0, (0.0, 0.0, 20.0, 20.0), params=WiserxParams(footprint_min_area_m2=25.0), navigable_m2=nav)
    assert g.footprint.tolist() == [[True, False], [False, False]]
    g.insert(0, 5.0, 5.0, 1.0, 0)
    assert g.fill() == 1.0


def test_points_are_placed_in_the_boundary_frame_through_the_start_transform():
    """A robot whose odometry origin is at (30, 10) of the boundary, facing +y: its own
    (0, 5) is the boundary's (25, 10)."""
    g = HGrid(0, (0.0, 0.0, 40.0, 20.0), to_boundary=(30.0, 10.0, math.pi / 2),
              params=WiserxParams.paper(sensor_range_m=10.0))
    bx, by = g.to_boundary(0.0, 5.0)
    assert (float(bx), float(by)) == pytest.approx((25.0, 10.0))
    g.insert(0, 0.0, 5.0, 1.0, 0)
    g.insert(0, 0.0, 6.0, 1.0, 0)
    assert np.argwhere(g.filled()).tolist() == [[1, 2]]
    # Own (0, -11) is the boundary's (41, 10): 1 m beyond its right edge.
    assert g.inside(0.0, 0.0) and not g.inside(0.0, -11.0) and g.inside(0.0, -11.0, margin_m=2.0)


def test_teammate_points_leave_out_own_points_and_failed_robots():
    g = HGrid(0, (0.0, 0.0, 20.0, 20.0))
    g.insert(0, 1.0, 1.0, 1.0, 0)
    g.insert(1, 2.0, 2.0, 0.5, 0)
    g.insert(2, 3.0, 3.0, 1.0, 0)
    g.set_alive(2, False)
    x, y, w = g.teammate_points()
    assert x.tolist() == [2.0] and w.tolist() == [0.5]
    g_off = HGrid(0, (0.0, 0.0, 20.0, 20.0), params=WiserxParams(tau_enabled=False))
    g_off.insert(2, 3.0, 3.0, 1.0, 0)
    g_off.set_alive(2, False)
    assert g_off.teammate_points()[0].tolist() == [3.0]      # eq. (6): tau ignored


# --- utility ---------------------------------------------------------------------------------

def _sight(n=60, unknown_from_col=30):
    s = np.full((n, n), kernels.FREE, np.uint8)
    s[:, unknown_from_col:] = kernels.UNKNOWN
    return s


def _brute(sight, res, vx, vy, px, py, omega, r, k1, k2):
    """Eqs. (4)-(6) cell by cell, as written (blocks of one cell)."""
    info = info0 = 0.0
    for i, j in np.argwhere(sight == kernels.UNKNOWN):
        cx, cy = (j + 0.5) * res, (i + 0.5) * res
        d = math.hypot(cx - vx, cy - vy)
        if d > r:
            continue
        s = 1.0 / (1.0 + math.exp((d - k1) / k2))
        e = sum(w / (1.0 + math.exp((math.hypot(cx - x, cy - y) - k1) / k2)) for x, y, w in zip(px, py, omega))
        info += max(0.0, s - e)
        info0 += s
    return info, info0


@pytest.mark.parametrize("k2", [0.1, 1.0])
def test_information_and_loss_equal_a_brute_force_of_eqs_4_to_6(k2):
    res = 0.5
    sight = _sight(40, 20)
    px, py, omega = np.array([12.0, 14.0]), np.array([8.0, 11.0]), np.array([1.0, 0.25])
    blocks = U.UnknownBlocks.from_sight(sight, 0, 0, res, res)
    loss = U.block_loss(blocks, px, py, omega, 5.0, k2)
    vx, vy = np.array([9.0, 12.0]), np.array([10.0, 4.0])
    info, info0 = U.information(blocks, loss, vx, vy, 10.0, 5.0, k2)
    for k in range(2):
        bi, bi0 = _brute(sight, res, vx[k], vy[k], px, py, omega, 10.0, 5.0, k2)
        assert info[k] == pytest.approx(bi, rel=1e-9, abs=1e-9) and info0[k] == pytest.approx(bi0, rel=1e-9)


def test_blocks_count_unknown_cells_at_their_centres():
    sight = _sight(10, 5)
    b = U.UnknownBlocks.from_sight(sight, row0=100, col0=200, resolution_m=0.1, block_m=0.5)
    assert sorted(zip(b.x_m.round(6), b.y_m.round(6), b.count)) == [(20.75, 10.25, 25.0), (20.75, 10.75, 25.0)]


def test_a_failed_teammate_is_as_if_its_points_were_never_recorded():
    """Eq. (7) with tau_j = 0 equals eq. (6) without j's points."""
    sight = _sight(40, 20)
    blocks = U.UnknownBlocks.from_sight(sight, 0, 0, 0.5, 0.5)
    g = HGrid(0, (0.0, 0.0, 20.0, 20.0))
    g.insert(1, 12.0, 8.0, 1.0, 0)
    g.insert(2, 14.0, 11.0, 1.0, 0)
    g.set_alive(2, False)
    x, y, w = g.teammate_points()
    with_tau = U.information(blocks, U.block_loss(blocks, x, y, w, 5.0, 0.1), [9.0], [10.0], 10.0, 5.0, 0.1)
    only_1 = U.information(blocks, U.block_loss(blocks, np.array([12.0]), np.array([8.0]), np.array([1.0]), 5.0,
                                                0.1), [9.0], [10.0], 10.0, 5.0, 0.1)
    assert with_tau == only_1


def test_information_never_grows_when_a_point_is_added():
    sight = _sight(40, 20)
    blocks = U.UnknownBlocks.from_sight(sight, 0, 0, 0.5, 0.5)
    rng = np.random.default_rng(3)
    px, py, w = np.zeros(0), np.zeros(0), np.zeros(0)
    last = U.information(blocks, U.block_loss(blocks, px, py, w, 5.0, 0.1), [9.0], [10.0], 10.0, 5.0, 0.1)[0][0]
    for _ in range(10):
        px, py, w = np.append(px, rng.uniform(0, 20)), np.append(py, rng.uniform(0, 20)), np.append(w, rng.uniform())
        now = U.information(blocks, U.block_loss(blocks, px, py, w, 5.0, 0.1), [9.0], [10.0], 10.0, 5.0, 0.1)[0][0]
        assert now <= last + 1e-12
        last = now


def test_ratio_beta_weight_and_utility():
    assert U.loss_ratio(np.array([10.0, 0.0, 0.0]), np.array([100.0, 50.0, 0.0])).tolist() == [0.9, 1.0, 0.0]
    beta = U.proximity(np.array([0.0, 0.0]), np.array([0.0, 0.0]), np.array([100.0, 0.5]), np.array([0.0, 0.0]), 1.12)
    assert beta[0] == pytest.approx(math.log10(1.12)) and beta[0] > 0.049
    assert U.proximity(np.array([0.0]), np.array([0.0]), np.array([]), np.array([]), 1.12).tolist() == [1.0]
    assert U.weight(0.5) == 1.0 and U.weight(4.0) == 0.25
    assert U.utility(np.array([2.0]), np.array([30.0]), np.array([0.0]), 0.1).tolist() == [600.0]
    assert U.sigmoid(5.0, 5.0, 0.1) == pytest.approx(0.5) and U.sigmoid(1e6, 5.0, 0.1) < 1e-300


def test_utility_is_unchanged_when_everything_moves_by_one_rigid_transform():
    """Frame equivariance (spec 6.8), for what does not depend on the map's grid: beta,
    the loss per point and the fill."""
    rng = np.random.default_rng(5)
    pts = rng.uniform(0, 30, (20, 2))
    th, t = 0.7, np.array([3.0, -4.0])
    Rm = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
    moved = pts @ Rm.T + t
    v = rng.uniform(0, 30, (5, 2))
    vm = v @ Rm.T + t
    b0 = U.proximity(v[:, 0], v[:, 1], pts[:, 0], pts[:, 1], 1.12)
    b1 = U.proximity(vm[:, 0], vm[:, 1], moved[:, 0], moved[:, 1], 1.12)
    assert np.allclose(b0, b1, atol=1e-9)
    # The same positions recorded by a robot whose odometry origin sits elsewhere in the
    # boundary: identical fill.
    g0 = HGrid(0, (0.0, 0.0, 40.0, 40.0), (0.0, 0.0, 0.0))
    inv = (pts - t) @ Rm                  # the points in a frame that T takes to the boundary's
    g1 = HGrid(0, (0.0, 0.0, 40.0, 40.0), (t[0], t[1], th))
    for (x, y), (xi, yi) in zip(pts, inv):
        g0.insert(0, x, y, 1.0, 0)
        g1.insert(0, xi, yi, 1.0, 0)
    assert g0.filled().tolist() == g1.filled().tolist()


# --- the scheme on a robot --------------------------------------------------------------------

def test_registered_with_its_variants_and_alias():
    assert resolve("wiserx") == ("wiserx", "complete")
    assert resolve("wiserx:paper") == ("wiserx", "paper")
    assert resolve("wiserx-blind") == ("wiserx", "blind")
    assert build("wiserx").needs_of() == {"uwb", "aoa"} and build("wiserx-blind").needs_of() == frozenset()
    assert resolve("wiserx-lora") == ("wiserx", "lora")
    assert build("wiserx-lora").needs_of() == {"uwb", "aoa", "radio"} and build("wiserx").dialect.name == "wiserx"
    assert build("wiserx:paper").params.fill_rule == "pts2" and build("wiserx:paper").params.hard_enabled
    assert build("wiserx").params.fill_rule == "disc" and not build("wiserx").params.hard_enabled


@pytest.mark.parametrize("missing", [("uwb",), ("aoa",), ("uwb", "aoa")])
def test_it_refuses_to_start_without_uwb_or_aoa(missing):
    fake = ScriptedHal(np.full(360, 3.0))
    hal = fake.hal()
    kept = {k: getattr(hal, k) for k in ("uwb", "aoa") if k not in missing}
    hal = Hal(robot_id=0, clock=fake, lidar=fake, odometry=fake, drive=fake, radio=fake, **kept)
    with pytest.raises(ValueError) as err:
        ExplorerAgent(hal, scheme="wiserx")
    for name in missing:
        assert f"{name} (" in str(err.value)
    assert "does not have" in str(err.value)
    ExplorerAgent(hal, scheme="wiserx-blind")      # the blind variant needs neither


def test_a_robot_records_its_own_position_every_insert_period_and_uses_the_deployment():
    fake = ScriptedHal(np.full(360, 3.0))
    nav = np.ones((40, 40))
    d = Deployment((-20.0, -20.0, 20.0, 20.0), (0.0, 0.0, 0.0), 1, nav, 1.0)
    agent = ExplorerAgent(fake.hal(), scheme="wiserx", deployment=d)
    agent.setup()
    while fake.t_us < 12 * S:           # a finished robot keeps recording where it stands
        agent.tick()
        fake.t_us += 50_000
    st = agent.stats()
    assert st["hgrid_points_own"] == 3          # at 0, 5 and 10 s
    assert st["hgrid_cells_footprint"] == 16


def test_three_robots_stop_by_themselves_without_a_lora_byte():
    r = run_mission(MissionConfig(map_spec="cave:5:30x30", robots=3, seed=2, max_sim_s=1500, radio="eu868-g3",
                                  strategy="wiserx", frames="own"))
    js = r.to_json()
    assert all(a.done for a in r.agents) and r.termination.startswith("complete")
    assert r.air_frames == [] and sum(js["radio_stats"]["bytes_sent"]) == 0
    assert r.coverage >= 0.9 and r.robots_in_wall == 0
    es = js["explorer_stats"]
    assert all(n > 0 for n in es["hgrid_points_teammates"]), "every robot recorded its teammates"
    assert all(n > 0 for n in es["uwb_aoa_tracks_started"])


# --- the planning stage: soft and hard termination, on a hand-built map ------------------------

def _rig(spec: str):
    """A robot at (10, 20) in a seen-free room x in [5, 35], y in [15, 25], unknown all round;
    its hgrid over a 40 m square, every cell filled by its own positions (fill 1.0)."""
    from firmware.params import ExplorationParams
    from firmware.services.local_map import LocalMap
    from tests.doubles import PlannerRig, paint_box
    P = ExplorationParams()
    lm = LocalMap(P, 20.0, 20.0)
    lm.logodds[:] = 0.0
    paint_box(lm, 5.0, 35.0, 15.0, 25.0, P.logodds_min)
    rig = PlannerRig(lm, spec, robot_id=0)
    sch = rig.scheme
    sch.hgrid = HGrid(0, (0.0, 0.0, 40.0, 40.0), params=sch.params)
    for x in range(5, 40, 10):
        for y in range(5, 40, 10):
            sch.hgrid.insert(0, x, y, 1.0, 0)
            sch.hgrid.insert(0, x + 0.5, y, 1.0, 0)
    return rig


def _plan_until_done(rig, cycles=12):
    for k in range(cycles):
        plan = rig.plan(10.0, 20.0, (k + 1) * 3_000_000)
        if plan.done:
            return True
    return False


def _teammate_all_round(rig, robot=1, alive=True):
    """A teammate that stood every 2 m along the room's edge and beyond it."""
    for x in range(0, 41, 2):
        for y in (9, 13, 17, 23, 27, 31):
            rig.scheme.hgrid.insert(robot, x, y, 1.0, 0)
    for y in range(9, 32, 2):
        for x in (1, 3, 37, 39):
            rig.scheme.hgrid.insert(robot, x, y, 1.0, 0)
    rig.scheme.hgrid.set_alive(robot, alive)


def test_after_soft_a_robot_stops_where_teammates_have_been_all_round():
    rig = _rig("wiserx")
    _teammate_all_round(rig)
    assert _plan_until_done(rig)
    assert rig.stat("waypoints_invalid") > 0 and rig.scheme.soft


def test_without_teammates_positions_or_with_the_teammate_failed_it_goes_on():
    assert not _plan_until_done(_rig("wiserx"))
    rig = _rig("wiserx")
    _teammate_all_round(rig, alive=False)       # eq. (7): a failed robot's area is open again
    assert not _plan_until_done(rig)
    assert rig.stat("waypoints_invalid") == 0


def test_the_blind_variant_never_counts_a_loss():
    rig = _rig("wiserx-blind")
    _teammate_all_round(rig)
    assert not _plan_until_done(rig)


def test_hard_stops_at_once_in_paper_mode_and_never_in_complete_mode():
    rig = _rig("wiserx:paper")                     # fill 1.0 >= hard 0.95
    assert rig.plan(10.0, 20.0).done and rig.scheme.hard
    assert rig.stat("waypoints_dropped_hard") > 0
    assert not _rig("wiserx").scheme.params.hard_enabled
