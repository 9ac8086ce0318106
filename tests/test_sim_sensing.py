"""The simulated UWB and WiFi AoA sensing profiles (world_sim.sensing; ../shared/schemes/wiserx.md
section 5.4): each profile's numbers, its statistics on many seeded samples (means, spreads,
outlier and dropout rates within four standard errors), and the world's use of them (rates,
walls, fixed draws per sample, same seed same samples)."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from hal.samples import AoaBearing, UwbRange
from tests.doubles import room
from world_sim.sensing import (AOA_DRAWS, PAPER, PAPER_NOISE_LEVELS, REALISTIC, SENSING_PROFILES, UWB_DRAWS, AoaModel,
                               UwbModel, paper_noise, sensing_profile)
from world_sim.world import World, WorldParams

N = 200_000
DEG = math.pi / 180.0
QUIET = WorldParams(lidar_beams=8, lidar_rate_hz=0.5)


def _uwb(model: UwbModel, d_m: float, wall_m: float, seed: int, n: int = N):
    rng = np.random.default_rng(seed)
    u, z = rng.random((n, UWB_DRAWS)), rng.standard_normal(n)
    r, ok = model.measure(np.full(n, d_m), np.full(n, wall_m), u, z)
    return r - d_m, ok


def _aoa(model: AoaModel, truth_rad: float, wall_m: float, seed: int, n: int = N):
    rng = np.random.default_rng(seed)
    u, z = rng.random((n, AOA_DRAWS)), rng.standard_normal(n)
    b, ok = model.measure(np.full(n, truth_rad), np.full(n, 10.0), np.full(n, wall_m), u, z)
    return b, np.remainder(b - truth_rad + math.pi, 2 * math.pi) - math.pi, ok


def _near(value: float, expected: float, std_error: float) -> bool:
    return abs(value - expected) <= 4.0 * std_error


def _share_near(flags: np.ndarray, p: float) -> bool:
    return _near(flags.mean(), p, math.sqrt(p * (1 - p) / flags.size))


def _normal_tail(k: float) -> float:
    """P(|N(0, 1)| > k)."""
    return math.erfc(k / math.sqrt(2.0))


# --- the numbers of section 5.4 -------------------------------------------------------------


def test_the_profiles_hold_the_numbers_of_the_spec():
    assert set(SENSING_PROFILES) == {"paper", "realistic"}
    assert sensing_profile("paper") is PAPER and sensing_profile("realistic") is REALISTIC
    u, a = PAPER.uwb, PAPER.aoa
    assert (u.los_noise_std_m, u.nlos_bias_m, u.nlos_bias_per_wall_m, u.nlos_extra_std_m) == (0.10, 0, 0, 0)
    assert (u.outlier_prob_los, u.outlier_prob_nlos, u.detection_decay_per_wall_m, u.resolution_m) == (0, 0, 0, 0)
    assert (u.rate_hz, a.rate_hz) == (0.2, 0.2)                 # one range and one bearing per 5 s
    assert a.los_noise_std_rad == a.nlos_noise_std_rad == pytest.approx(5 * DEG)
    assert (a.los_outlier_prob, a.nlos_outlier_prob, a.detection_decay_per_wall_m) == (0, 0, 0)
    u, a = REALISTIC.uwb, REALISTIC.aoa
    assert (u.los_noise_std_m, u.nlos_bias_m, u.nlos_bias_per_wall_m) == (0.05, 0.3, 1.2)
    assert (u.nlos_extra_std_m, u.nlos_extra_std_per_wall_m) == (0.15, 0.3)
    assert (u.outlier_prob_los, u.outlier_prob_nlos, u.outlier_min_m, u.outlier_max_m) == (0.02, 0.10, 0.5, 3.0)
    assert (u.detection_decay_per_wall_m, u.range_max_m, u.resolution_m, u.rate_hz) == (1.0, 50.0, 0.001, 2.0)
    assert a.los_noise_std_rad == pytest.approx(5 * DEG) and a.nlos_noise_std_rad == pytest.approx(10 * DEG)
    assert (a.los_outlier_prob, a.nlos_outlier_prob, a.nlos_spurious_share) == (0.05, 0.25, 0.5)
    assert (a.spurious_min_rad, a.spurious_max_rad) == pytest.approx((20 * DEG, 90 * DEG))
    assert (a.detection_decay_per_wall_m, a.range_max_m, a.rate_hz) == (0.5, 50.0, 0.2)
    assert WorldParams().sensing is REALISTIC
    assert WorldParams().with_sensing_profile("paper").sensing is PAPER


def test_the_paper_noise_levels():
    assert PAPER_NOISE_LEVELS == ((2.0, 0.01), (5.0, 0.10), (10.0, 0.20), (30.0, 1.0))
    p = paper_noise(30.0, 1.0)
    assert p.uwb.los_noise_std_m == 1.0 and p.aoa.los_noise_std_rad == p.aoa.nlos_noise_std_rad == 30 * DEG
    assert dataclasses.replace(p.uwb, los_noise_std_m=0.10) == PAPER.uwb
    assert paper_noise(5.0, 0.10).aoa == PAPER.aoa


@pytest.mark.parametrize("bad", [
    lambda: dataclasses.replace(REALISTIC.uwb, outlier_prob_los=1.5),
    lambda: dataclasses.replace(REALISTIC.uwb, los_noise_std_m=-0.1),
    lambda: dataclasses.replace(REALISTIC.uwb, rate_hz=0.0),
    lambda: dataclasses.replace(REALISTIC.uwb, outlier_min_m=4.0),
    lambda: dataclasses.replace(REALISTIC.uwb, resolution_m=float("nan")),
    lambda: dataclasses.replace(REALISTIC.aoa, nlos_outlier_prob=-0.01),
    lambda: dataclasses.replace(REALISTIC.aoa, spurious_min_rad=2.0, spurious_max_rad=1.0),
    lambda: WorldParams(sensing="realistic"),
    lambda: WorldParams().with_sensing_profile("ideal"),
    lambda: dataclasses.replace(REALISTIC, aoa=REALISTIC.uwb),
])
def test_a_value_out_of_range_is_refused_by_name(bad):
    with pytest.raises(ValueError, match=r"rate_hz|outlier|noise_std|resolution|spurious|sensing|ideal|UwbModel"):
        bad()


# --- UWB statistics -------------------------------------------------------------------------


def test_uwb_realistic_line_of_sight():
    err, ok = _uwb(REALISTIC.uwb, 12.0, 0.0, seed=1)
    assert ok.all()                                             # no dropouts in line of sight
    late = err > 0.25                                           # outliers add >= 0.5 m, 5 sigma above
    assert _share_near(late, 0.02)
    inl = err[~late]
    assert _near(inl.mean(), 0.0, 0.05 / math.sqrt(inl.size))
    assert inl.std() == pytest.approx(0.05, rel=0.02)
    assert _near(err[late].mean(), 1.75, 2.5 / math.sqrt(12 * late.sum()))   # U(0.5, 3) m late
    assert err[late].min() > 0.5 - 0.25 and err[late].max() < 3.0 + 0.25
    mm = (err + 12.0) * 1000.0
    assert np.allclose(mm, np.round(mm), atol=1e-6)            # whole millimetres


@pytest.mark.parametrize("wall_m", [0.2, 0.4, 1.0])
def test_uwb_realistic_behind_walls(wall_m):
    model = REALISTIC.uwb
    err, ok = _uwb(model, 15.0, wall_m, seed=2)
    assert _share_near(ok, math.exp(-wall_m / 1.0))            # p_det = exp(-w / 1 m)
    e = err[ok]
    bias = 0.3 + 1.2 * wall_m
    var_noise = 0.05 ** 2 + (0.15 + 0.3 * wall_m) ** 2
    p, lo, hi = 0.10, 0.5, 3.0
    mean_late = p * (lo + hi) / 2
    var_late = p * (hi ** 3 - lo ** 3) / (3 * (hi - lo)) - mean_late ** 2
    var = var_noise + var_late
    assert _near(e.mean(), bias + mean_late, math.sqrt(var / e.size))
    assert e.var() == pytest.approx(var, rel=0.03)
    # The median sits a little above the bias: the noise is symmetric, the late paths only add.
    assert bias < np.median(e) < bias + 0.1


def test_uwb_out_of_range_is_never_measured():
    model = REALISTIC.uwb
    rng = np.random.default_rng(3)
    d = np.array([49.9, 50.0, 50.01, 80.0])
    _, ok = model.measure(d, np.zeros(4), np.zeros((4, UWB_DRAWS)), rng.standard_normal(4))
    assert ok.tolist() == [True, True, False, False]


@pytest.mark.parametrize("wall_m", [0.0, 0.6])
def test_uwb_paper_is_gaussian_everywhere(wall_m):
    err, ok = _uwb(PAPER.uwb, 9.0, wall_m, seed=4)
    assert ok.all()                                             # no dropouts, no bias behind walls
    assert _near(err.mean(), 0.0, 0.10 / math.sqrt(N))
    assert err.std() == pytest.approx(0.10, rel=0.02)
    assert np.abs(err).max() < 6 * 0.10                         # no outliers
    assert _share_near(np.abs(err) > 0.20, _normal_tail(2.0))
    mm = (err + 9.0) * 1000.0
    assert not np.allclose(mm, np.round(mm), atol=1e-6)         # metres, not rounded


# --- AoA statistics -------------------------------------------------------------------------


@pytest.mark.parametrize("truth_deg", [0.0, 179.0, -179.0, 90.0])
def test_aoa_realistic_line_of_sight(truth_deg):
    sigma = 5 * DEG
    b, err, ok = _aoa(REALISTIC.aoa, truth_deg * DEG, 0.0, seed=5)
    assert ok.all()
    assert np.all((b >= -math.pi) & (b < math.pi))
    far = np.abs(err) > 5 * sigma
    # 5 % uniform on the circle, of which a share 10 sigma / 2 pi lands within 5 sigma.
    assert _share_near(far, 0.05 * (1 - 10 * sigma / (2 * math.pi)))
    inl = err[~far]
    assert _near(inl.mean(), 0.0, sigma / math.sqrt(inl.size))
    # The direct path N(0, sigma), and the outliers that fell within 5 sigma, uniform there.
    p_stray = 0.05 * 10 * sigma / (2 * math.pi)
    var = (0.95 * sigma ** 2 + p_stray * (5 * sigma) ** 2 / 3) / (0.95 + p_stray)
    assert inl.std() == pytest.approx(math.sqrt(var), rel=0.02)
    # The outliers are uniform: as many on either side, spread over the whole circle.
    out = err[far]
    assert _near(np.mean(out > 0), 0.5, 0.5 / math.sqrt(out.size))
    assert _near(np.mean(np.abs(out)), (math.pi + 5 * sigma) / 2, math.pi / math.sqrt(12 * out.size))


@pytest.mark.parametrize("wall_m", [0.3, 2.0])
def test_aoa_realistic_behind_walls(wall_m):
    sigma = 10 * DEG
    _, err, ok = _aoa(REALISTIC.aoa, 1.0, wall_m, seed=6)
    assert _share_near(ok, math.exp(-wall_m / 2.0))            # p_det = exp(-w / 2 m)
    a = np.abs(err[ok])
    # Bands: the direct path N(0, 10 deg) (75 %), a spurious peak 20..90 deg off (12.5 %),
    # uniform on the circle (12.5 %).
    lo, hi = 20 * DEG, 90 * DEG
    p_gauss_band = _normal_tail(2.0) - _normal_tail(9.0)
    assert _share_near((a > lo) & (a < hi), 0.75 * p_gauss_band + 0.125 + 0.125 * (hi - lo) / math.pi)
    assert _share_near(a > hi, 0.125 * (math.pi - hi) / math.pi)
    assert _share_near(a < 2 * sigma, 0.75 * (1 - _normal_tail(2.0)) + 0.125 * 2 * sigma / math.pi)
    band = err[ok][(a > 3 * sigma) & (a < hi)]
    assert _near(np.mean(band > 0), 0.5, 0.5 / math.sqrt(band.size))   # spurious peaks on either side
    inl = err[ok][a < 2 * sigma]
    assert inl.std() == pytest.approx(sigma * 0.8796, rel=0.03)         # N(0, s) within 2 s: std 0.8796 s


@pytest.mark.parametrize("wall_m", [0.0, 1.5])
def test_aoa_paper_is_gaussian_everywhere(wall_m):
    sigma = 5 * DEG
    _, err, ok = _aoa(PAPER.aoa, -2.0, wall_m, seed=7)
    assert ok.all()
    assert _near(err.mean(), 0.0, sigma / math.sqrt(N))
    assert err.std() == pytest.approx(sigma, rel=0.02)
    assert np.abs(err).max() < 6 * sigma


# --- in the world -------------------------------------------------------------------------


def _divided_room():
    """20 x 10 m, a 0.4 m wall from x = 10.0 to 10.4 m across its full height."""
    occ = room(20.0, 10.0)
    free = occ.free.copy()
    free[:, 100:104] = False
    return dataclasses.replace(occ, free=free, name="divided")


# Robot 0 sees robot 1 (5 m) and is behind the wall from robot 2 (8 m, 0.4 m of wall).
POSES = [(6.0, 5.05, 0.0), (2.0, 8.05, 1.0), (14.0, 5.05, 0.0)]


def _samples(params: WorldParams, seconds: float, seed: int = 11, poses=POSES):
    world = World(_divided_room(), poses, seed=seed, params=params)
    ranges, bearings = [], []
    for _ in range(round(seconds)):
        world.step(1_000_000)
        ranges.extend(world.take_uwb_ranges(0))
        bearings.extend(world.take_aoa_bearings(0))
    return ranges, bearings


def _fast(profile, uwb_hz=50.0, aoa_hz=50.0, **changes):
    return dataclasses.replace(QUIET, sensing=dataclasses.replace(
        profile, uwb=dataclasses.replace(profile.uwb, rate_hz=uwb_hz, **changes.get("uwb", {})),
        aoa=dataclasses.replace(profile.aoa, rate_hz=aoa_hz, **changes.get("aoa", {}))))


@pytest.mark.parametrize("profile, uwb_period_us, aoa_period_us", [(REALISTIC, 500_000, 5_000_000),
                                                                  (PAPER, 5_000_000, 5_000_000)])
def test_the_world_measures_at_the_profiles_rates(profile, uwb_period_us, aoa_period_us):
    params = dataclasses.replace(QUIET, sensing=profile)
    ranges, bearings = _samples(params, 60.0, poses=[(3.0, 3.0, 0.0), (6.0, 7.0, 2.0), (8.0, 2.0, -1.0)])
    for samples, period in ((ranges, uwb_period_us), (bearings, aoa_period_us)):
        assert [s.stamp_us for s in samples] == [t for t in range(0, 60_000_001, period) for _ in (1, 2)]
        assert [s.peer_id for s in samples] == [1, 2] * (60_000_000 // period + 1)
    assert all(r.quality is None for r in ranges)
    assert all(b.rank == 0 and b.profile_variance is None for b in bearings)


def test_the_world_applies_the_wall_between_two_robots():
    ranges, bearings = _samples(_fast(REALISTIC), 40.0)
    truth_bearing = {1: math.atan2(3.0, -4.0), 2: 0.0}
    n_firings = 40 * 50 + 1
    los = np.array([r.range_m for r in ranges if r.peer_id == 1]) - 5.0
    nlos = np.array([r.range_m for r in ranges if r.peer_id == 2]) - 8.0
    assert los.size == n_firings                               # no dropouts in line of sight
    assert _near(nlos.size / n_firings, math.exp(-0.4), math.sqrt(0.25 / n_firings))
    assert np.median(los) == pytest.approx(0.0, abs=0.01)
    assert np.median(nlos) == pytest.approx(0.3 + 1.2 * 0.4, abs=0.05)
    err = {j: np.array([math.remainder(b.bearing_rad - truth_bearing[j], 2 * math.pi)
                        for b in bearings if b.peer_id == j]) for j in (1, 2)}
    assert err[1].size == n_firings
    assert _near(err[2].size / n_firings, math.exp(-0.2), math.sqrt(0.25 / n_firings))
    # Within 3 sigma of the direct path: LOS 95 % x 99.7 %, NLOS 75 % x 99.7 % (plus stray outliers).
    assert np.mean(np.abs(err[1]) < 15 * DEG) == pytest.approx(0.95, abs=0.02)
    assert np.mean(np.abs(err[2]) < 30 * DEG) == pytest.approx(0.78, abs=0.04)


def test_same_seed_same_samples_and_each_sensor_its_own_stream():
    a = _samples(_fast(REALISTIC), 10.0)
    assert a == _samples(_fast(REALISTIC), 10.0)
    other = _samples(_fast(REALISTIC), 10.0, seed=12)
    assert [r.range_m for r in a[0]][:50] != [r.range_m for r in other[0]][:50]
    # Another AoA model leaves every range as it was, and the other way round.
    aoa_changed = _samples(_fast(REALISTIC, aoa={"los_outlier_prob": 0.5}), 10.0)
    uwb_changed = _samples(_fast(REALISTIC, uwb={"los_noise_std_m": 0.2}), 10.0)
    assert aoa_changed[0] == a[0] and aoa_changed[1] != a[1]
    assert uwb_changed[1] == a[1] and uwb_changed[0] != a[0]


def test_an_outlier_or_dropout_rate_changes_its_own_samples_only():
    base = _samples(_fast(REALISTIC), 20.0)
    more = _samples(_fast(REALISTIC, uwb={"outlier_prob_los": 0.5, "outlier_prob_nlos": 0.5},
                          aoa={"los_outlier_prob": 0.5, "nlos_outlier_prob": 0.6}), 20.0)
    # Outliers: the same samples (stamps and peers); each one either as it was or an outlier now.
    for b, m in zip(base, more):
        assert [(s.stamp_us, s.peer_id) for s in b] == [(s.stamp_us, s.peer_id) for s in m]
    same_r = [x.range_m == y.range_m for x, y in zip(base[0], more[0])]
    assert 0.3 < np.mean(same_r) < 0.7
    assert all(y.range_m > x.range_m for x, y, s in zip(base[0], more[0], same_r) if not s)   # only late paths
    same_b = [x.bearing_rad == y.bearing_rad for x, y in zip(base[1], more[1])]
    assert 0.3 < np.mean(same_b) < 0.7
    # Dropouts: fewer samples, and those left are the very same ones.
    fewer = _samples(_fast(REALISTIC, uwb={"detection_decay_per_wall_m": 3.0},
                           aoa={"detection_decay_per_wall_m": 3.0}), 20.0)
    for b, f in zip(base, fewer):
        assert len(f) < len(b) and set(f) <= set(b)
        assert [s for s in b if s.peer_id == 1] == [s for s in f if s.peer_id == 1]   # LOS: none lost


# --- HAL samples ---------------------------------------------------------------------------


def test_the_hal_samples_keep_their_old_form():
    r = UwbRange(5, 1, 2.5)
    assert (r.stamp_us, r.peer_id, r.range_m, r.quality) == (5, 1, 2.5, None)
    assert UwbRange(5, 1, 2.5) == UwbRange(stamp_us=5, peer_id=1, range_m=2.5)
    assert UwbRange(5, 1, 2.5, quality=80).quality == 80
    b = AoaBearing(5, 2, -1.0)
    assert (b.profile_variance, b.rank) == (None, 0)
    assert AoaBearing(5, 2, -1.0, profile_variance=0.3, rank=2).rank == 2
