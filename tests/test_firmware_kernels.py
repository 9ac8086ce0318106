"""The numba kernels equal their plain references on generated inputs."""
import math

import numba
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from numba import njit

from firmware import kernels
from tests import reference_kernels as ref

SETTINGS = settings(max_examples=40, deadline=None)


@st.composite
def scans(draw):
    n = draw(st.integers(8, 90))
    range_max = draw(st.floats(0.5, 3.0))
    ranges = np.array(draw(st.lists(st.one_of(st.floats(0.0, range_max), st.just(range_max)), min_size=n, max_size=n)))
    rows = draw(st.integers(5, 40))
    cols = draw(st.integers(5, 40))
    res = draw(st.sampled_from([0.05, 0.1, 0.2]))
    row0 = draw(st.integers(-50, 50))
    col0 = draw(st.integers(-50, 50))
    px = (col0 + draw(st.floats(-5, cols + 5))) * res
    py = (row0 + draw(st.floats(-5, rows + 5))) * res
    bin0 = draw(st.floats(-4, 4))
    logodds = np.array(draw(st.lists(st.floats(-4, 4, width=32), min_size=rows * cols, max_size=rows * cols)),
                       np.float32).reshape(rows, cols)
    r_lo = draw(st.integers(-2, rows))
    c_lo = draw(st.integers(-2, cols))
    region = (r_lo, draw(st.integers(r_lo, rows + 2)), c_lo, draw(st.integers(c_lo, cols + 2)))
    return logodds, row0, col0, res, px, py, bin0, 2 * math.pi / n, ranges, range_max, region


@st.composite
def hard_scans(draw):
    """Scans aimed at the edges of polar_fill's shortcuts: cells exactly on, or a hair off,
    bin boundaries (the sensor on a cell's centre or corner, the boundaries through a chosen
    cell or along the axes and diagonals); bin 0's wrap, with bins that do not tile the turn;
    walls (runs of equal ranges, one across the wrap) that leave whole blocks of cells free
    or not, or a step at every boundary; few and many bins; NaN, zero, negative and infinite
    ranges and ranges at range_max; NaN cells and cells at the lower clamp; tiny and clipped
    windows. The bulk arrays come from a drawn seed, to keep the examples quick."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    n = draw(st.sampled_from([1, 2, 3, 4, 8, 16, 64, 360, 720, 1440, 4000]) | st.integers(1, 1000))
    binw = draw(st.sampled_from([2 * math.pi, 1.5 * math.pi, 2 * math.pi * (1 + 1e-9), 2 * math.pi * (1 - 1e-9)])) / n
    range_max = draw(st.floats(0.3, 4.0))

    def ranges_of(k):
        v = rng.uniform(0.0, 1.2 * range_max, k)
        special = rng.random(k) < 0.3
        v[special] = rng.choice([range_max, math.nan, 0.0, -1.0, math.inf], special.sum())
        return v

    layout = draw(st.sampled_from(["a step at every bin", "walls", "a wall across bin 0"]))
    if layout == "a step at every bin":
        ranges = ranges_of(n)
    else:
        edges = [0, *np.sort(rng.integers(0, n + 1, draw(st.integers(0, 6)))), n]
        ranges = np.repeat(ranges_of(len(edges) - 1), np.diff(edges))
        if layout == "a wall across bin 0":
            before, after = rng.integers(0, n // 12 + 1, 2)
            ranges[:after] = ranges[n - before:] = ranges_of(1)[0]
    rows = draw(st.integers(1, 60))
    cols = draw(st.integers(1, 60))
    res = draw(st.sampled_from([0.05, 0.1, 0.2, 0.25, 1 / 3]))
    row0 = draw(st.integers(-50, 50))
    col0 = draw(st.integers(-50, 50))
    si = draw(st.integers(0, rows - 1) | st.integers(-3, rows + 2))
    sj = draw(st.integers(0, cols - 1) | st.integers(-3, cols + 2))
    fy, fx = {"centre": (0.5, 0.5), "corner": (0.0, 0.0), "anywhere": rng.random(2)}[
        draw(st.sampled_from(["centre", "corner", "anywhere"]))]
    px = (col0 + sj + fx) * res
    py = (row0 + si + fy) * res
    nudge = draw(st.sampled_from([0.0, 1e-13, -1e-13, 1e-9, -1e-9, 1e-6, -1e-6, 1e-5, -1e-5, 3e-5, -3e-5]))
    aim = draw(st.sampled_from(["anywhere", "axes and diagonals", "a cell"]))
    if aim == "anywhere":
        bin0 = draw(st.floats(-10, 10))
    elif aim == "axes and diagonals":
        bin0 = int(rng.integers(-16, 17)) * math.pi / 4 + 0.5 * binw + nudge
    else:  # the boundary after bin k through the centre of a cell near the sensor
        di, dj = rng.integers(-12, 13, 2)
        bearing = math.atan2((row0 + si + di + 0.5) * res - py, (col0 + sj + dj + 0.5) * res - px)
        bin0 = bearing - (int(rng.integers(-n, n)) + 0.5) * binw + nudge
    logodds = rng.choice([-4.0, 0.0, math.nan, 1.0], size=(rows, cols), p=[0.4, 0.1, 0.05, 0.45])
    logodds[logodds == 1.0] = rng.uniform(-4.0, 4.0, (logodds == 1.0).sum())
    region = (0, rows, 0, cols)
    if draw(st.booleans()):
        r_lo = draw(st.integers(-2, rows))
        c_lo = draw(st.integers(-2, cols))
        region = (r_lo, draw(st.integers(r_lo, rows + 2)), c_lo, draw(st.integers(c_lo, cols + 2)))
    return logodds.astype(np.float32), row0, col0, res, px, py, bin0, binw, ranges, range_max, region


@settings(max_examples=300, deadline=None)
@given(scans() | hard_scans())
def test_polar_fill_matches_reference(case):
    """To the bit: the kernel's shortcuts (blocks of cells decided together, approximate
    bearings) must not change a single cell."""
    logodds, row0, col0, res, px, py, bin0, binw, ranges, range_max, region = case
    expected = ref.polar_fill(logodds, row0, col0, res, px, py, bin0, binw, ranges, range_max,
                              0.85, -0.4, -4.0, 4.0, *region)
    got = logodds.copy()
    kernels.polar_fill(got, row0, col0, res, px, py, bin0, binw, ranges, range_max, 0.85, -0.4, -4.0, 4.0, *region)
    np.testing.assert_array_equal(got.view(np.uint32), expected.view(np.uint32))


@njit
def _approx_bearings(dx, dy):
    out = np.empty(dx.shape[0])
    for k in range(dx.shape[0]):
        out[k] = kernels.bearing_approx_rad(dx[k], dy[k])
    return out


def test_the_approximate_bearing_is_within_its_bound_with_atan2s_signs():
    """polar_fill relies on BEARING_APPROX_ERROR_RAD; the fit is ten times better, checked
    every 1.6e-6 rad around the circle and at several lengths."""
    theta = np.linspace(-math.pi, math.pi, 4_000_001)
    for length in (1e-3, 1.0, 37.0):
        dx, dy = length * np.cos(theta), length * np.sin(theta)
        assert np.abs(_approx_bearings(dx, dy) - np.arctan2(dy, dx)).max() < kernels.BEARING_APPROX_ERROR_RAD / 10
    # On the axes exactly atan2's values, signed zeros and +-pi included.
    axes = np.array([[1.0, 0.0], [1.0, -0.0], [0.0, 1.0], [-0.0, 1.0], [-1.0, 0.0], [-1.0, -0.0], [0.0, -1.0],
                     [-0.0, -1.0], [1e-300, -1.0], [-1.0, 1e-300], [-1.0, -1e-300]])
    got = _approx_bearings(axes[:, 0], axes[:, 1])
    want = np.arctan2(axes[:, 1], axes[:, 0])
    np.testing.assert_array_equal(got.view(np.uint64), want.view(np.uint64))
    assert math.isnan(kernels.bearing_approx_rad(0.0, 0.0)) and math.isnan(kernels.bearing_approx_rad(-0.0, -0.0))


def test_polar_fill_marks_free_space_and_the_wall_behind_it():
    logodds = np.zeros((40, 40), np.float32)
    ranges = np.full(360, 1.0)  # a circular wall 1 m around the sensor at the window's centre
    kernels.polar_fill(logodds, 0, 0, 0.1, 2.0, 2.0, 0.0, 2 * math.pi / 360, ranges, 3.0,
                       0.85, -0.4, -4.0, 4.0, 0, 40, 0, 40)
    assert logodds[20, 20] < 0          # the sensor's own cell is free
    assert logodds[20, 30] > 0          # 1.05 m east: the wall
    assert logodds[20, 35] == 0         # behind the wall: still unknown


@st.composite
def grids(draw, values=(0, 1)):
    rows = draw(st.integers(3, 30))
    cols = draw(st.integers(3, 30))
    cells = draw(st.lists(st.sampled_from(values), min_size=rows * cols, max_size=rows * cols))
    return np.array(cells, np.uint8).reshape(rows, cols)


@st.composite
def sparse_masks(draw):
    """A few True cells, so that a dilation leaves much of the grid False."""
    rows = draw(st.integers(1, 40))
    cols = draw(st.integers(1, 40))
    mask = np.zeros((rows, cols), bool)
    for i, j in draw(st.lists(st.tuples(st.integers(0, rows - 1), st.integers(0, cols - 1)), max_size=6)):
        mask[i, j] = True
    return mask


@SETTINGS
@given(st.one_of(sparse_masks(), grids().map(lambda g: g.astype(bool))), st.integers(0, 45))
def test_square_dilation_matches_reference(mask, r):
    """Radii from none through beyond the grid's side."""
    np.testing.assert_array_equal(kernels.square_dilation(mask, r), ref.square_dilation(mask, r))


@SETTINGS
@given(grids(values=(0, 1, 2)), st.data())
def test_cells_near_changes_match_reference(state, data):
    rows, cols = state.shape
    changed = np.zeros((rows, cols), bool)
    if data.draw(st.booleans()):          # a few changed cells
        for i, j in data.draw(st.lists(st.tuples(st.integers(0, rows - 1), st.integers(0, cols - 1)), max_size=4)):
            changed[i, j] = True
    else:                                 # changes anywhere
        changed[...] = np.array(data.draw(st.lists(st.booleans(), min_size=rows * cols, max_size=rows * cols)),
                                bool).reshape(rows, cols)
    i0 = data.draw(st.integers(0, rows))
    j0 = data.draw(st.integers(0, cols))
    i1 = data.draw(st.integers(i0, rows))
    j1 = data.draw(st.integers(j0, cols))
    r = data.draw(st.integers(0, 8))
    got = kernels.cells_near_changes(state, changed, r, i0, i1, j0, j1)
    want = ref.cells_near_changes(state, changed, r, i0, i1, j0, j1, kernels.FREE)
    for g, w in zip(got, want):
        np.testing.assert_array_equal(g, w)


@SETTINGS
@given(grids(values=(0, 1, 2, 3)), st.integers(0, 50), st.data())
def test_unknown_box_counts_match_reference(state, half, data):
    """Squares inside the grid, across its edges and larger than it; none asked for too."""
    k = data.draw(st.integers(0, 8))
    rows = np.array(data.draw(st.lists(st.integers(0, state.shape[0] - 1), min_size=k, max_size=k)), np.int64)
    cols = np.array(data.draw(st.lists(st.integers(0, state.shape[1] - 1), min_size=k, max_size=k)), np.int64)
    np.testing.assert_array_equal(kernels.unknown_box_counts(state, half, rows, cols),
                                  ref.unknown_box_counts(state, half, rows, cols, kernels.UNKNOWN))


@SETTINGS
@given(st.one_of(grids(), sparse_masks().map(lambda m: m.astype(np.uint8))))
def test_chamfer_distance_equals_the_plain_raster_passes_to_the_bit(blocked):
    """Dense and sparse sources (long chains of sums), single rows and columns included."""
    got = kernels.chamfer_distance(blocked.astype(bool))
    want = ref.chamfer_raster(blocked.astype(bool))
    assert got.dtype == want.dtype == np.float32
    assert got.tobytes() == want.tobytes()


@SETTINGS
@given(grids())
def test_chamfer_distance_matches_reference(blocked):
    got = kernels.chamfer_distance(blocked.astype(bool))
    expected = ref.chamfer_distance(blocked.astype(bool))
    np.testing.assert_allclose(got, expected, rtol=1e-5)


@SETTINGS
@given(grids(), st.data())
def test_best_standing_points_match_reference(blocked, data):
    rows, cols = blocked.shape
    n = data.draw(st.integers(1, 12))
    ci = np.array(data.draw(st.lists(st.integers(0, rows - 1), min_size=n, max_size=n)), np.int64)
    cj = np.array(data.draw(st.lists(st.integers(0, cols - 1), min_size=n, max_size=n)), np.int64)
    face = data.draw(st.sampled_from([0.0, 0.5]))
    reach = data.draw(st.sampled_from([1.5, 3.3, 5.0]))
    got_d, got_k = kernels.best_standing_points(blocked.astype(bool), ci, cj, face, reach)
    want_d, want_k = ref.best_standing_points(blocked.astype(bool), ci, cj, face, reach)
    np.testing.assert_allclose(got_d, want_d, rtol=1e-5, atol=1e-5)
    np.testing.assert_array_equal(got_k, want_k)


def test_the_best_standing_point_of_a_door_two_cells_wide_is_its_middle():
    # Walls along columns 0 and 3: the door's middle is the edge between columns 1 and 2.
    occupied = np.zeros((5, 4), bool)
    occupied[:, [0, 3]] = True
    d, k = kernels.best_standing_points(occupied, np.array([2]), np.array([1]), 0.5, 4.0)
    assert kernels.SUBCELL_OFFSETS[k[0]].tolist() == [0, 1] and d[0] == pytest.approx(1.0)


def _search_case(free, data):
    """A shortest-path problem on a drawn grid: (traversable, cell cost factors, start)."""
    rows, cols = free.shape
    cost = np.array(data.draw(st.lists(st.floats(1.0, 3.0), min_size=rows * cols, max_size=rows * cols))).reshape(rows, cols)
    return free.astype(bool), cost, data.draw(st.integers(0, rows - 1)), data.draw(st.integers(0, cols - 1))


@SETTINGS
@given(grids(), st.data())
def test_dijkstra_matches_reference(free, data):
    rows, cols = free.shape
    trav, cost, si, sj = _search_case(free, data)
    dist, parent = kernels.dijkstra_grid(trav, cost, si, sj)
    ref_dist, ref_parent = ref.dijkstra_grid(trav, cost, si, sj)
    # Exactly equal: the same cells settle in the same order, so ties pick the same parents.
    np.testing.assert_array_equal(dist, ref_dist)
    np.testing.assert_array_equal(parent, ref_parent)
    # Every reached cell's parent chain leads back to the start.
    for i, j in zip(*np.nonzero(np.isfinite(dist))):
        steps = 0
        while parent[i, j] >= 0:
            i, j = divmod(int(parent[i, j]), cols)
            steps += 1
            assert steps <= rows * cols
        assert (i, j) == (si, sj)


def test_dijkstra_breaks_ties_like_the_reference():
    """Uniform costs make many equal path costs; the parents show the tie order."""
    rng = np.random.default_rng(7)
    trav = rng.random((60, 70)) > 0.25
    trav[30, 35] = True
    cost = np.ones(trav.shape)
    dist, parent = kernels.dijkstra_grid(trav, cost, 30, 35)
    ref_dist, ref_parent = ref.dijkstra_grid(trav, cost, 30, 35)
    np.testing.assert_array_equal(dist, ref_dist)
    np.testing.assert_array_equal(parent, ref_parent)


@SETTINGS
@given(grids(), st.data())
def test_dijkstra_settled_in_parts_equals_the_full_search(free, data):
    """Settling cells a few at a time (what a plan does) gives every settled cell the
    full search's cost and parent, and the flood fill finds the cells the search reaches."""
    rows, cols = free.shape
    trav, cost, si, sj = _search_case(free, data)
    full_dist, full_parent = kernels.dijkstra_grid(trav, cost, si, sj)
    reach = kernels.reachable_cells(trav, si, sj)
    np.testing.assert_array_equal(reach, np.isfinite(full_dist))
    arrays = kernels.dijkstra_arrays(rows, cols)
    arrays[0][:] = 7.0   # left over from an earlier search: dijkstra_start must reset it
    kernels.dijkstra_start(trav, si, sj, *arrays)
    dist, parent, *heap = arrays
    settled = np.zeros((rows, cols), bool)
    for _ in range(data.draw(st.integers(1, 4))):
        k = data.draw(st.integers(0, 5))
        wi = np.array(data.draw(st.lists(st.integers(0, rows - 1), min_size=k, max_size=k)), np.int64)
        wj = np.array(data.draw(st.lists(st.integers(0, cols - 1), min_size=k, max_size=k)), np.int64)
        ok = reach[wi, wj]
        kernels.dijkstra_settle(trav, cost, dist, parent, *heap, wi[ok] * cols + wj[ok])
        settled[wi[ok], wj[ok]] = True
        # Exactly equal, not close: the cells settle in the full search's order.
        np.testing.assert_array_equal(dist[settled], full_dist[settled])
        np.testing.assert_array_equal(parent[settled], full_parent[settled])


@SETTINGS
@given(grids(), st.data())
def test_dijkstra_settled_to_the_first_wanted_or_below_a_bound_equals_the_full_search(free, data):
    """settle_first stops at the nearest wanted cell (in the full search's order);
    settle_below leaves settled exactly the cells whose full-search cost is within the
    bound; both agree with the full search at every settled cell."""
    rows, cols = free.shape
    trav, cost, si, sj = _search_case(free, data)
    full_dist, full_parent = kernels.dijkstra_grid(trav, cost, si, sj)
    arrays = kernels.dijkstra_arrays(rows, cols)
    kernels.dijkstra_start(trav, si, sj, *arrays)
    dist, parent, *heap = arrays
    pos = heap[2].reshape(rows, cols)
    reach = np.isfinite(full_dist)
    k = data.draw(st.integers(1, 6))
    wi = np.array(data.draw(st.lists(st.integers(0, rows - 1), min_size=k, max_size=k)), np.int64)
    wj = np.array(data.draw(st.lists(st.integers(0, cols - 1), min_size=k, max_size=k)), np.int64)
    ok = reach[wi, wj]
    kernels.dijkstra_settle_first(trav, cost, dist, parent, *heap, wi[ok] * cols + wj[ok])
    if ok.any():
        nearest = full_dist[wi[ok], wj[ok]].min()
        assert (pos[wi[ok], wj[ok]] == -2).any()
        # everything strictly nearer than the nearest wanted cell is settled, nothing farther
        assert (pos[full_dist < nearest] == -2).all() and not (pos[full_dist > nearest] == -2).any()
    bound = data.draw(st.floats(0.0, 2.0 * max(rows, cols)))
    kernels.dijkstra_settle_below(trav, cost, dist, parent, *heap, bound)
    settled = pos == -2
    assert settled[full_dist <= bound].all()
    assert not settled[reach & (full_dist > bound)].any() or ok.any()
    np.testing.assert_array_equal(dist[settled], full_dist[settled])
    np.testing.assert_array_equal(parent[settled], full_parent[settled])


def _draw_cells(data, shape, k):
    """k cells of a grid of this shape, as (rows, cols) index arrays."""
    rows, cols = shape
    ci = np.array(data.draw(st.lists(st.integers(0, rows - 1), min_size=k, max_size=k)), np.int64)
    cj = np.array(data.draw(st.lists(st.integers(0, cols - 1), min_size=k, max_size=k)), np.int64)
    return ci, cj


@SETTINGS
@given(grids(values=(0, 1, 2)), st.data())
def test_observable_unknown_matches_reference(state, data):
    ci, cj = _draw_cells(data, state.shape, data.draw(st.integers(1, 5)))
    rays = data.draw(st.integers(4, 64))
    reach = data.draw(st.floats(1.0, 40.0))
    np.testing.assert_allclose(kernels.observable_unknown(state, ci, cj, rays, reach),
                               ref.observable_unknown(state, ci, cj, rays, reach), rtol=1e-12)


@SETTINGS
@given(grids(values=(0, 1, 2)), st.data())
def test_mark_visible_matches_reference(state, data):
    si, sj = _draw_cells(data, state.shape, data.draw(st.integers(0, 8)))
    rays = data.draw(st.integers(4, 400))
    reach = data.draw(st.floats(0.0, 40.0))
    every = np.ones(state.shape, bool)
    wanted = data.draw(st.sampled_from([every, _draw_mask(data, state.shape)]))
    marked_before = data.draw(st.sampled_from([~every, _draw_mask(data, state.shape)]))
    out = marked_before.copy()
    kernels.mark_visible(state, si, sj, rays, reach, wanted, out)
    np.testing.assert_array_equal(out, marked_before | ref.mark_visible(state, si, sj, rays, reach, wanted))


def _draw_mask(data, shape):
    cells = data.draw(st.lists(st.booleans(), min_size=shape[0] * shape[1], max_size=shape[0] * shape[1]))
    return np.array(cells, bool).reshape(shape)


def test_mark_visible_matches_reference_on_a_large_window_with_many_sources():
    """Rays are cut short by counts per block of cells, checked every few steps: on small
    grids few checks happen, so a window of many blocks, scattered walls and sparse wanted
    cells, and sources that see much of the same."""
    rng = np.random.default_rng(7)
    state = rng.choice(np.array([0, 1, 2], np.uint8), size=(90, 110), p=[0.3, 0.68, 0.02])
    state[30:33, 10:80] = kernels.OCCUPIED
    wanted = (rng.random(state.shape) < 0.1) & (state == kernels.UNKNOWN)
    si = rng.integers(0, 90, 12)
    sj = rng.integers(0, 110, 12)
    out = np.zeros(state.shape, bool)
    kernels.mark_visible(state, si, sj, 300, 45.0, wanted, out)
    expected = ref.mark_visible(state, si, sj, 300, 45.0, wanted)
    assert expected.sum() > 200
    np.testing.assert_array_equal(out, expected)


def test_mark_visible_stops_at_walls():
    state = np.zeros((60, 60), np.uint8)
    state[:, 40] = kernels.OCCUPIED
    out = np.zeros(state.shape, bool)
    kernels.mark_visible(state, np.array([30]), np.array([30]), 600, 25.0, np.ones(state.shape, bool), out)
    assert out[30, 39] and out[30, 5] and out[5, 30]
    assert not out[:, 40:].any()          # the wall and everything behind it
    assert not out[30, 30 - 27]           # beyond the range


def test_observable_unknown_counts_about_the_disc_area():
    state = np.zeros((101, 101), np.uint8)
    count = kernels.observable_unknown(state, np.array([50]), np.array([50]), 256, 30.0)[0]
    assert abs(count - math.pi * 30 * 31) / (math.pi * 30 * 31) < 1e-9
    walled = state.copy()
    walled[:, 55] = kernels.OCCUPIED  # a wall 5 cells east hides everything beyond it
    assert kernels.observable_unknown(walled, np.array([50]), np.array([50]), 256, 30.0)[0] < 0.7 * count


@SETTINGS
@given(st.one_of(grids(values=(0, 1)), sparse_masks().map(lambda m: m.astype(np.uint8))),
       st.sampled_from([-0.5, -0.9, 0.0, 0.5, math.cos(math.radians(120)), math.cos(math.radians(60))]))
def test_wall_jump_cells_match_reference(walls, cos_limit):
    """The gate finder's Voronoi cells: the nearest walls from an exact distance transform,
    as detect_gates takes them (ties in the transform's indices included)."""
    import scipy.ndimage as ndimage

    wall = walls.astype(bool)
    if not wall.any():
        wall[0, 0] = True
    _d, (ai, aj) = ndimage.distance_transform_edt(~wall, return_indices=True)
    ii, jj = np.indices(wall.shape)
    c2 = (ai - ii) ** 2 + (aj - jj) ** 2
    ok = ~wall & (c2 >= 2)
    assert np.array_equal(kernels.wall_jump_cells(ok, ai, aj, c2, cos_limit),
                          ref.wall_jump_cells(ok, ai, aj, c2, cos_limit))


@SETTINGS
@given(grids(values=(0, 1, 2)))
def test_paired_chamfer_distances_equal_the_single_ones(state):
    d_occ, d_blk = kernels.chamfer_distances(state)
    np.testing.assert_array_equal(d_occ, kernels.chamfer_distance(state == kernels.OCCUPIED))
    np.testing.assert_array_equal(d_blk, kernels.chamfer_distance(state != kernels.FREE))


def _with_threads(n, fn):
    previous = numba.get_num_threads()
    numba.set_num_threads(n)
    try:
        return fn()
    finally:
        numba.set_num_threads(previous)


@settings(max_examples=15, deadline=None)
@given(scans() | hard_scans(), grids(values=(0, 1, 2)), st.data())
def test_parallel_kernels_give_the_same_bits_on_one_thread_and_on_all(scan, state, data):
    """polar_fill, chamfer_distances and observable_unknown run their
    iterations in parallel; a robot computer with another core count must still drive the
    same mission, so one thread and all threads must agree exactly."""
    logodds, row0, col0, res, px, py, bin0, binw, ranges, range_max, region = scan
    ci, cj = _draw_cells(data, state.shape, data.draw(st.integers(0, 6)))
    rays = data.draw(st.integers(4, 200))
    reach = data.draw(st.floats(0.0, 40.0))

    def run():
        filled = logodds.copy()
        kernels.polar_fill(filled, row0, col0, res, px, py, bin0, binw, ranges, range_max,
                           0.85, -0.4, -4.0, 4.0, *region)
        return (filled, *kernels.chamfer_distances(state), kernels.observable_unknown(state, ci, cj, rays, reach))

    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("NUMBA_NUM_THREADS is 1: nothing to compare (tests/conftest.py asks for two unless it is set)")
    for one, every in zip(_with_threads(1, run), _with_threads(numba.config.NUMBA_NUM_THREADS, run)):
        np.testing.assert_array_equal(one, every)


WARM_UP_CHECK = """
import importlib, pathlib, firmware
from numba.core.registry import CPUDispatcher
# Every module file, namespace packages included (pkgutil.walk_packages skips those).
root = pathlib.Path(firmware.__path__[0])
modules = [importlib.import_module('.'.join(('firmware',) + f.relative_to(root).with_suffix('').parts))
           for f in sorted(root.rglob('*.py')) if f.name != '__init__.py']
def compiled():
    return {f'{m.__name__}.{k}': len(v.signatures) for m in modules for k, v in vars(m).items()
            if isinstance(v, CPUDispatcher)}
from firmware.params import ExplorationParams
from firmware.warm_up import warm_up
warm_up(ExplorationParams())
before = compiled()
from host_tools.mission import MissionConfig, run_mission
run_mission(MissionConfig(map_spec='cave:1:30x30', max_sim_s=60, strategy='minpos', robots=2))
print({k: (before.get(k), n) for k, n in compiled().items() if before.get(k) != n})
"""


def test_warm_up_compiles_every_kernel_a_mission_calls():
    """A robot's tick loop must not stall on a first call that compiles (lorascout robot)."""
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-c", WARM_UP_CHECK], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "{}", f"compiled only after warm_up: {out.stdout}"


@SETTINGS
@given(st.integers(0, 2**32 - 1))
def test_scan_match_scores_matches_reference(seed):
    rng = np.random.default_rng(seed)
    rows, cols = (int(v) for v in rng.integers(2, 25, 2))
    field = rng.random((rows, cols))
    row0, col0 = (int(v) for v in rng.integers(-50, 50, 2))
    res = float(rng.choice([0.05, 0.1, 0.2]))
    x = (col0 + rng.uniform(0, cols)) * res
    y = (row0 + rng.uniform(0, rows)) * res
    yaw = float(rng.uniform(-math.pi, math.pi))
    n = int(rng.integers(0, 30))
    r = rng.uniform(0.0, 0.6 * max(rows, cols) * res, n)
    a = rng.uniform(-math.pi, math.pi, n)
    bx, by = r * np.cos(a), r * np.sin(a)
    dxs = rng.uniform(-0.2, 0.2, int(rng.integers(1, 4)))
    dys = rng.uniform(-0.2, 0.2, int(rng.integers(1, 4)))
    dyaws = rng.uniform(-0.05, 0.05, int(rng.integers(1, 4)))
    got = kernels.scan_match_scores(field, row0, col0, res, x, y, yaw, bx, by, dxs, dys, dyaws)
    expected = ref.scan_match_scores(field, row0, col0, res, x, y, yaw, bx, by, dxs, dys, dyaws)
    np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-12)


@SETTINGS
@given(grids(values=(0, 1, 2)))
def test_crack_contours_matches_reference(state):
    free, occupied = state == 1, state == 2
    got = kernels.crack_contours(free, occupied)
    expected = ref.crack_contours(free, occupied)
    for g, e in zip(got, expected):
        np.testing.assert_array_equal(g, e)


@pytest.mark.parametrize("seed", range(5))
def test_nearest_points_matches_a_brute_force_search(seed):
    """The slip check's nearest-point search against every distance computed (lowest index
    on a tie), queries inside and far outside the reference points' cells included."""
    rng = np.random.default_rng(seed)
    for _ in range(20):
        ref = rng.normal(0.0, rng.uniform(0.1, 8.0), (int(rng.integers(1, 300)), 2))
        query = rng.normal(0.0, rng.uniform(0.1, 15.0), (int(rng.integers(1, 300)), 2))
        got = kernels.nearest_points(ref[:, 0].copy(), ref[:, 1].copy(), query[:, 0].copy(), query[:, 1].copy(),
                                     float(rng.uniform(0.05, 1.0)))
        d2 = ((query[:, None, :] - ref[None, :, :]) ** 2).sum(axis=2)
        assert np.array_equal(got, np.argmin(d2, axis=1))


@pytest.mark.parametrize("seed", range(5))
def test_cells_built_once_answer_every_query_set_as_a_brute_force_search(seed):
    """point_cells built once and nearest_in_cells asked again and again (as the slip check
    asks for each share of travel): every answer the brute-force nearest, the lowest index
    on a tie. Duplicated reference points make exact ties; the query sets move from on the
    points to far beyond their cells."""
    rng = np.random.default_rng(seed)
    for _ in range(10):
        ref = rng.normal(0.0, rng.uniform(0.1, 8.0), (int(rng.integers(1, 200)), 2))
        ref = np.concatenate([ref, ref[rng.integers(0, len(ref), len(ref) // 3)]])
        rx, ry = ref[:, 0].copy(), ref[:, 1].copy()
        cell_m = float(rng.uniform(0.05, 1.0))
        x0, y0, nx, ny, start, order = kernels.point_cells(rx, ry, cell_m)
        query = ref[rng.integers(0, len(ref), int(rng.integers(1, 200)))] + rng.normal(0.0, 0.05, (1, 2))
        travel = rng.normal(0.0, 10.0, 2)
        out = np.full(len(query), -7, np.int64)
        for share in np.linspace(0.0, 1.0, 11):
            moved = query + share * travel
            kernels.nearest_in_cells(rx, ry, x0, y0, nx, ny, start, order, moved[:, 0].copy(), moved[:, 1].copy(),
                                     cell_m, out)
            d2 = ((moved[:, None, :] - ref[None, :, :]) ** 2).sum(axis=2)
            assert np.array_equal(out, np.argmin(d2, axis=1))


@pytest.mark.parametrize("n", [0, 1, 7, 8, 9, 15, 16, 17, 127, 128, 129, 255, 256, 257, 1000, 3001])
def test_pairwise_sum_equals_numpys_sum_to_the_bit(n):
    a = np.random.default_rng(n).lognormal(0.0, 3.0, n)
    assert kernels.pairwise_sum(a, 0, n) == np.add.reduce(a)
    if n > 3:
        assert kernels.pairwise_sum(a, 2, n - 3) == np.add.reduce(a[2:n - 1].copy())


def _scan(rng, n):
    """A LiDAR-like scan: walls at a few distances, with gaps and edges."""
    angles = np.sort(rng.uniform(-np.pi, np.pi, n))
    ranges = np.where(rng.random(n) < 0.8, rng.uniform(0.5, 6.0) + 0.3 * np.sin(3 * angles), rng.uniform(0.3, 9.0, n))
    return ranges * np.cos(angles), ranges * np.sin(angles)


@pytest.mark.parametrize("seed", range(8))
def test_slip_misfits_equal_the_numpy_reference_to_the_bit(seed):
    """The slip check's fit, every share's mean misfit and count, equal to the bit to the
    plain numpy version (brute-force nearest points, numpy means): the firmware decides on
    these numbers, so a trajectory must not depend on which one ran."""
    rng = np.random.default_rng(seed)
    shares = np.linspace(0.0, 1.0, 11)
    for _ in range(10):
        rx, ry = _scan(rng, int(rng.integers(2, 400)))
        tx, ty = rx + rng.normal(0.0, 0.02, rx.shape), ry + rng.normal(0.0, 0.02, ry.shape)
        keep = rng.random(rx.shape) < 0.9
        tx, ty = tx[keep].copy(), ty[keep].copy()
        travel = rng.normal(0.0, 0.05, 2)
        args = (rx, ry, tx, ty, float(travel[0]), float(travel[1]), shares, 0.3, 0.2)
        got_misfit, got_counted = kernels.slip_misfits(*args, 0.2)
        want_misfit, want_counted = ref.slip_misfits(*args, 0.2)
        assert np.array_equal(got_counted, want_counted)
        assert np.array_equal(got_misfit, want_misfit, equal_nan=True)


@pytest.mark.parametrize("seed", range(4))
def test_slip_misfits_over_long_travel_equal_the_numpy_reference_to_the_bit(seed):
    """As above with travel of metres, so that the shares carry the points across many of
    the search's cells and far outside the earlier scan's."""
    rng = np.random.default_rng(100 + seed)
    shares = np.linspace(0.0, 1.0, 11)
    for _ in range(6):
        rx, ry = _scan(rng, int(rng.integers(30, 400)))
        keep = rng.random(rx.shape) < 0.9
        tx, ty = rx[keep] + rng.normal(0.0, 0.02, keep.sum()), ry[keep] + rng.normal(0.0, 0.02, keep.sum())
        travel = rng.normal(0.0, 2.0, 2)
        args = (rx, ry, tx, ty, float(travel[0]), float(travel[1]), shares, 0.3, 0.2, 0.2)
        got_misfit, got_counted = kernels.slip_misfits(*args)
        want_misfit, want_counted = ref.slip_misfits(*args)
        assert np.array_equal(got_counted, want_counted)
        assert np.array_equal(got_misfit, want_misfit, equal_nan=True)


def test_slip_misfits_with_no_earlier_points_count_none():
    """No earlier point, no nearest point: no share counts any point and none has a misfit."""
    tx, ty = _scan(np.random.default_rng(0), 50)
    misfit, counted = kernels.slip_misfits(np.zeros(0), np.zeros(0), tx, ty, 0.3, 0.0, np.linspace(0.0, 1.0, 11),
                                           0.3, 0.2, 0.2)
    assert np.all(np.isnan(misfit)) and misfit.shape == (11,)
    assert np.array_equal(counted, np.zeros(11, np.int64))
