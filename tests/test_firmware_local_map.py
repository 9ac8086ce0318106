"""The local map keeps what it learnt: places that leave the window come back as they were
left, and a teammate's keyframe folds in the scan that was taken there, wherever it lands."""
import math

import numpy as np
from hypothesis import given, settings, strategies as st

from firmware.schemes.dense_baseline.keyframes import decode_keyframe, encode_keyframe, keyframe_bytes
from firmware.services.local_map import BinnedScan, LocalMap, bin_scan
from firmware.params import ExplorationParams

P = ExplorationParams()
BEAMS = 360
INCREMENT_RAD = 2.0 * math.pi / BEAMS


def _room_scan(rng: np.random.Generator) -> np.ndarray:
    """Ranges in whole centimetres (what a keyframe carries), some beams at range_max."""
    ranges = rng.integers(30, 900, BEAMS) / 100.0
    ranges[rng.random(BEAMS) < 0.1] = 10.0
    return ranges


@settings(max_examples=100, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), yaw_rad=st.floats(-math.pi, math.pi), x_m=st.floats(-3.0, 3.0),
       y_m=st.floats(-3.0, 3.0))
def test_a_keyframe_folds_in_exactly_the_scan_taken_there(seed, yaw_rad, x_m, y_m):
    ranges = _room_scan(np.random.default_rng(seed))
    live = LocalMap(P, 0.0, 0.0)
    live.integrate_scan(x_m, y_m, yaw_rad, -math.pi, INCREMENT_RAD, ranges, 10.0)
    sent = encode_keyframe(3, bin_scan(x_m, y_m, yaw_rad, -math.pi, INCREMENT_RAD, ranges, 10.0, BEAMS))
    _, received = decode_keyframe(sent)
    # The wire rounds the position to 1 cm and the bearing to 1/65536 turn: compare against
    # the scan at the position and bearing the teammate received.
    live = LocalMap(P, 0.0, 0.0)
    live.integrate_scan(received.x_m, received.y_m, received.bearing0_rad, 0.0, INCREMENT_RAD, ranges, 10.0)
    folded = LocalMap(P, 0.0, 0.0)
    folded.integrate_keyframe(received)
    assert np.array_equal(live.logodds, folded.logodds)


def test_keyframes_on_fixed_world_bearings_would_not_fold_in_the_scan():
    """The check above can fail: bins on fixed world bearings (what keyframes were before)
    move a grazing wall's beams and so clear or miss many cells."""
    ranges = _room_scan(np.random.default_rng(7))
    live = LocalMap(P, 0.0, 0.0)
    live.integrate_scan(0.0, 0.0, 0.4, -math.pi, INCREMENT_RAD, ranges, 10.0)
    moved = bin_scan(0.0, 0.0, 0.4, -math.pi, INCREMENT_RAD, ranges, 10.0, BEAMS)
    fixed = moved._replace(bearing0_rad=round(moved.bearing0_rad / INCREMENT_RAD) * INCREMENT_RAD)
    folded = LocalMap(P, 0.0, 0.0)
    folded.integrate_keyframe(fixed)
    assert np.count_nonzero(live.logodds != folded.logodds) > 100


def _drive(m: LocalMap, path_xy) -> None:
    for x, y in path_xy:
        m.follow(x, y)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), away_x_m=st.floats(-80.0, 80.0), away_y_m=st.floats(-80.0, 80.0))
def test_a_place_that_left_the_window_comes_back_as_it_was_left(seed, away_x_m, away_y_m):
    rng = np.random.default_rng(seed)
    m = LocalMap(P, 0.0, 0.0)
    for k in range(6):   # scans along a short track, the window following
        x, y = 1.5 * k, 0.5 * k
        m.follow(x, y)
        m.integrate_scan(x, y, rng.uniform(-math.pi, math.pi), -math.pi, INCREMENT_RAD, _room_scan(rng), 10.0)
    m.follow(8.0, 0.0)
    anchor, before = (m.row0, m.col0), m.logodds.copy()
    there = [(8.0 + (away_x_m - 8.0) * t, away_y_m * t) for t in np.linspace(0.0, 1.0, 60)]
    _drive(m, there + there[::-1])
    # The window need not sit where it sat (it moves only 2 m off centre): compare the cells
    # both windows cover, in global cell coordinates.
    (r0, c0), n = anchor, m.n
    dr, dc = m.row0 - r0, m.col0 - c0
    assert abs(dr) < n // 4 and abs(dc) < n // 4
    now = m.logodds[max(-dr, 0):n - max(dr, 0), max(-dc, 0):n - max(dc, 0)]
    then = before[max(dr, 0):n - max(-dr, 0), max(dc, 0):n - max(-dc, 0)]
    assert np.count_nonzero(then) > 1000
    assert np.array_equal(now, then)


def test_a_keyframe_received_far_away_is_there_when_the_window_arrives():
    rng = np.random.default_rng(11)
    scan = bin_scan(50.0, 40.0, 0.3, -math.pi, INCREMENT_RAD, _room_scan(rng), 10.0, BEAMS)
    far = LocalMap(P, 0.0, 0.0)
    far.integrate_keyframe(scan)             # 64 m away: outside the 40 m window
    _drive(far, [(50.0 * t, 40.0 * t) for t in np.linspace(0.0, 1.0, 80)])
    near = LocalMap(P, 0.0, 0.0)
    _drive(near, [(50.0 * t, 40.0 * t) for t in np.linspace(0.0, 1.0, 80)])
    assert (near.row0, near.col0) == (far.row0, far.col0)
    near.integrate_keyframe(scan)            # the same keyframe, folded with the window there
    assert np.count_nonzero(near.logodds) > 1000
    assert np.array_equal(far.logodds, near.logodds)


@settings(max_examples=200, deadline=None)
@given(sender=st.integers(0, 255), x_m=st.floats(-20000.0, 20000.0), y_m=st.floats(-20000.0, 20000.0),
       bearing0_rad=st.floats(-10.0, 10.0), bins=st.integers(1, 720), seed=st.integers(0, 2**32 - 1))
def test_keyframe_wire_round_trip(sender, x_m, y_m, bearing0_rad, bins, seed):
    ranges = np.random.default_rng(seed).integers(0, 65535, bins) / 100.0
    scan = BinnedScan(x_m, y_m, bearing0_rad, ranges, 12.0)
    data = encode_keyframe(sender, scan)
    assert len(data) == keyframe_bytes(bins)
    got_sender, got = decode_keyframe(data)
    assert got_sender == sender
    # Positions travel in centimetres: off by at most half of one (and a rounding of the float).
    assert abs(got.x_m - x_m) <= 0.005 + 1e-12 and abs(got.y_m - y_m) <= 0.005 + 1e-12 and got.range_max_m == 12.0
    turn = 2 * math.pi
    wrapped = abs((got.bearing0_rad - bearing0_rad + math.pi) % turn - math.pi)
    assert wrapped <= turn / 65536
    assert np.array_equal(got.ranges_m, ranges)


def test_a_keyframe_at_360_bins_is_735_bytes():
    assert keyframe_bytes(P.keyframe_bins) == 735


@settings(max_examples=2000, deadline=None)
@given(data=st.binary(max_size=800))
def test_random_bytes_into_decode_keyframe_never_raise(data):
    out = decode_keyframe(data)
    if out is not None:
        assert len(data) == keyframe_bytes(len(out[1].ranges_m))


def test_a_gap_the_body_drove_through_stays_open_to_later_plans():
    """Wall cells whose centres lie 0.5 m apart read too narrow for the 0.5 m body even with
    the faces at the centres (a tight passage needs the tolerance too); the cells the body's
    centre went through (mark_passed, diagonal steps filled in) are traversable from then
    on, while free."""
    p = ExplorationParams()
    local_map, (i0, j0) = _walls_along_y(p, -3, 2)                 # two walls along y, 5 cells apart
    for tight in (False, True):
        assert not local_map.layers(tight).traversable[i0 - 5:i0 + 6, j0 - 2:j0 + 2].any()
    for k in range(-5, 6):                                         # a slightly slanted drive through
        local_map.mark_passed(-0.15 + 0.1 * ((k + 5) // 4), 0.05 + 0.1 * k)
    layers = local_map.layers()
    rows = range(i0 - 5, i0 + 6)
    assert all(layers.traversable[i, j0 - 2:j0 + 2].any() for i in rows)
    assert kernel_path_exists(layers.traversable, local_map.cell_of(-0.15, -0.45), local_map.cell_of(0.05, 0.55))


def test_a_door_the_body_drove_through_stays_open_when_later_scans_draw_it_narrower():
    """A door 0.8 m between the wall cells' centres fits the body with room to spare, but
    less than slow_clearance_m beside it: a passage, so the cells driven through it are
    remembered. When later scans draw the door 0.5 m wide, too narrow even for a tight
    passage, plans still go through where the body went."""
    p = ExplorationParams()
    local_map, (i0, j0) = _walls_along_y(p, -4, 4)                 # two walls along y, 7 cells apart
    assert local_map.layers().traversable[i0 - 5:i0 + 6, j0].all()
    assert local_map.in_passage_at(0.05, 0.05)
    for k in range(-9, 10):                                        # down the door's middle
        x, y = 0.05, 0.05 + 0.1 * k
        if local_map.in_passage_at(x, y):
            local_map.mark_passed(x, y)
    local_map.logodds[i0 - 10:i0 + 11, j0 - 3] = p.logodds_max     # the door as scans draw it later
    local_map.logodds[i0 - 10:i0 + 11, j0 + 2] = p.logodds_max
    for tight in (False, True):
        assert not _the_same_map_never_driven(p, local_map).layers(tight).traversable[i0 - 5:i0 + 6, j0].any()
    assert kernel_path_exists(local_map.layers().traversable, (i0 - 8, j0), (i0 + 8, j0))


def _walls_along_y(p: ExplorationParams, west_col: int, east_col: int) -> tuple[LocalMap, tuple[int, int]]:
    """A free square 2.1 m a side round (0, 0) with a wall along y in the columns this many
    cells from the origin's; and the origin's cell."""
    local_map = LocalMap(p, 0.0, 0.0)
    i0, j0 = local_map.cell_of(0.0, 0.0)
    local_map.logodds[i0 - 10:i0 + 11, j0 - 10:j0 + 11] = p.logodds_min
    local_map.logodds[i0 - 10:i0 + 11, j0 + west_col] = p.logodds_max
    local_map.logodds[i0 - 10:i0 + 11, j0 + east_col] = p.logodds_max
    return local_map, (i0, j0)


def _the_same_map_never_driven(p: ExplorationParams, local_map: LocalMap) -> LocalMap:
    """A map with the same log-odds and no cells driven through."""
    other = LocalMap(p, 0.0, 0.0)
    other.logodds[:] = local_map.logodds
    return other


def kernel_path_exists(traversable, a, b) -> bool:
    from firmware import kernels
    return bool(kernels.reachable_cells(traversable, a[0], a[1])[b])


def test_an_obstacle_felt_where_the_body_just_was_is_not_marked():
    """A robot came west along y = 0 to x = 2 m, turned round to the south-east and stalled
    there: the arc marked ahead reaches back over the way it came. Only the arc's points
    farther from that way than the body's radius less half a cell are kept, so the way back
    stays open; the same stall with no path behind it marks the whole arc."""
    p = ExplorationParams()
    local_map = LocalMap(p, 0.0, 0.0)
    for k in range(41):
        local_map.mark_trail(4.0 - 0.05 * k, 0.0)
    yaw_rad, reach_m = -0.55, p.robot_radius_m + p.resolution_m
    local_map.mark_obstacle_ahead(2.0, 0.0, yaw_rad, reach_m)
    fresh = LocalMap(p, 0.0, 0.0)
    fresh.mark_obstacle_ahead(2.0, 0.0, yaw_rad, reach_m)
    arc = np.array(fresh.bumps)
    assert len(arc) == 7
    # Distance of each arc point from the way driven (the segment x in [2, 4], y = 0).
    dx = np.clip(arc[:, 0], 2.0, 4.0) - arc[:, 0]
    covered = np.hypot(dx, arc[:, 1]) <= p.robot_radius_m - 0.5 * p.resolution_m
    assert covered.any() and not covered.all()
    np.testing.assert_allclose(np.array(local_map.bumps).reshape(-1, 2), arc[~covered])


def test_the_body_covers_only_its_recent_path():
    p = ExplorationParams()
    local_map = LocalMap(p, 0.0, 0.0)
    for k in range(400):                    # 20 m east
        local_map.mark_trail(0.05 * k, 0.0)
    reach_m = p.robot_radius_m - 0.5 * p.resolution_m
    probe = np.array([[19.0, 0.9 * reach_m], [19.0, 1.1 * reach_m], [1.0, 0.0], [21.0, 0.0]])
    np.testing.assert_array_equal(local_map.body_covers(probe), [True, False, False, False])
