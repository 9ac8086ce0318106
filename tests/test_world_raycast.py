"""The numba ray caster against the cell-box reference, on random grids and poses."""
from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings, strategies as st

from world_sim.raycast import (
    cast_and_mark,
    cast_and_mark_all,
    cast_rays,
    cast_rays_reference,
    mark_observed,
    mark_observed_reference,
    pair_wall_lengths_m,
    wall_length_m,
    wall_length_m_reference,
)

# Angles that hit grid corners exactly or within an ulp: the tie rule has to agree there.
SPECIAL_ANGLES = [k * math.pi / 4 for k in range(-4, 4)] + [
    math.atan2(a, b) for a in (-2, -1, 1, 2, 3) for b in (-3, -1, 1, 2)
]
angle_st = st.one_of(st.floats(-math.pi, math.pi), st.sampled_from(SPECIAL_ANGLES))
# Offsets inside the start cell; 0.5 with a 45 degree beam makes exact corner ties.
offset_st = st.one_of(st.sampled_from([0.5, 0.25, 0.75]), st.floats(0.01, 0.99))


@st.composite
def scenes(draw):
    rows = draw(st.integers(1, 9))
    cols = draw(st.integers(1, 9))
    bits = draw(st.lists(st.booleans(), min_size=rows * cols, max_size=rows * cols))
    wall = np.array(bits, dtype=np.uint8).reshape(rows, cols)
    free_cells = np.argwhere(wall == 0)
    if len(free_cells) == 0:
        wall[rows // 2, cols // 2] = 0
        free_cells = np.argwhere(wall == 0)
    row, col = free_cells[draw(st.integers(0, len(free_cells) - 1))]
    res = draw(st.sampled_from([0.05, 0.1, 0.2, 0.3, 1.0]))
    ox = draw(st.sampled_from([0.0, -3.7, 12.25]))
    oy = draw(st.sampled_from([0.0, 5.1, -0.35]))
    x = ox + (col + draw(offset_st)) * res
    y = oy + (row + draw(offset_st)) * res
    angles = np.array(draw(st.lists(angle_st, min_size=1, max_size=12)), dtype=np.float64)
    max_range = draw(st.sampled_from([0.5, 2.0, 4.0, 100.0])) * res * 3
    return wall, ox, oy, res, x, y, angles, max_range


@settings(max_examples=400, deadline=None)
@given(scenes())
def test_cast_rays_matches_reference(scene):
    wall, ox, oy, res, x, y, angles, max_range = scene
    got = cast_rays(wall, ox, oy, res, x, y, angles, max_range)
    want = cast_rays_reference(wall, ox, oy, res, x, y, angles, max_range)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-9)
    assert np.all(got >= 0) and np.all(got <= max_range)


@settings(max_examples=300, deadline=None)
@given(scenes(), st.lists(st.floats(0.0, 1.2), min_size=12, max_size=12))
def test_mark_observed_matches_reference(scene, fractions):
    wall, ox, oy, res, x, y, angles, max_range = scene
    true_ranges = cast_rays(wall, ox, oy, res, x, y, angles, max_range)
    # Both the true ranges and shortened/lengthened (noisy) ones.
    for ranges in (true_ranges, true_ranges * np.array(fractions[: len(angles)])):
        got = np.zeros(wall.shape, dtype=bool)
        want = np.zeros(wall.shape, dtype=bool)
        mark_observed(got, wall, ox, oy, res, x, y, angles, ranges)
        mark_observed_reference(want, wall, ox, oy, res, x, y, angles, ranges)
        assert np.array_equal(got, want), (got.astype(int), want.astype(int))


@settings(max_examples=200, deadline=None)
@given(scenes())
def test_fused_cast_and_mark_equals_the_two_steps(scene):
    wall, ox, oy, res, x, y, angles, max_range = scene
    fused_obs = np.zeros(wall.shape, dtype=bool)
    fused = cast_and_mark(fused_obs, wall, ox, oy, res, x, y, angles, max_range)
    ranges = cast_rays(wall, ox, oy, res, x, y, angles, max_range)
    obs = np.zeros(wall.shape, dtype=bool)
    mark_observed(obs, wall, ox, oy, res, x, y, angles, ranges)
    assert np.array_equal(fused, ranges)
    assert np.array_equal(fused_obs, obs)


@settings(max_examples=300, deadline=None)
@given(scenes(), st.floats(-2.0, 2.0), st.floats(-2.0, 2.0))
def test_wall_length_matches_reference(scene, ex, ey):
    wall, ox, oy, res, x, y, _, _ = scene
    rows, cols = wall.shape
    x1 = x + ex * cols * res
    y1 = y + ey * rows * res
    got = wall_length_m(wall, ox, oy, res, x, y, x1, y1)
    want = wall_length_m_reference(wall, ox, oy, res, x, y, x1, y1)
    assert abs(got - want) <= 1e-8 * max(1.0, res * (rows + cols))
    assert -1e-12 <= got <= math.hypot(x1 - x, y1 - y) + 1e-9


def test_known_geometry():
    # A 5 x 5 room of 1 m cells with a wall column at col 3; robot in cell (2, 0) centre.
    wall = np.zeros((5, 5), dtype=np.uint8)
    wall[:, 3] = 1
    angles = np.array([0.0, math.pi, math.pi / 2, -math.pi / 2, math.pi / 4])
    r = cast_rays(wall, 0.0, 0.0, 1.0, 0.5, 2.5, angles, 100.0)
    # east: wall starts at x = 3; west: map edge at x = 0; north/south: edges at y = 5 and 0;
    # north-east 45 deg from (0.5, 2.5) meets x = 3 at y = 5.0: exactly the corner of the map
    # and of the wall column, so the closed-corner rule stops it there.
    np.testing.assert_allclose(r, [2.5, 0.5, 2.5, 2.5, 2.5 * math.sqrt(2)], atol=1e-12)
    assert cast_rays(wall, 0.0, 0.0, 1.0, 0.5, 2.5, angles, 1.0).tolist() == [1.0, 0.5, 1.0, 1.0, 1.0]
    # Start inside a wall reads zero.
    assert cast_rays(wall, 0.0, 0.0, 1.0, 3.5, 2.5, angles, 10.0).tolist() == [0.0] * 5
    # Through-wall length of a horizontal radio path across the column.
    assert wall_length_m(wall, 0.0, 0.0, 1.0, 0.5, 2.5, 4.5, 2.5) == 1.0


def test_no_diagonal_leak_between_touching_walls():
    # Two walls touching at a corner; a 45 degree beam through that corner must stop.
    wall = np.zeros((4, 4), dtype=np.uint8)
    wall[1, 2] = 1
    wall[2, 1] = 1
    r = cast_rays(wall, 0.0, 0.0, 1.0, 1.5, 1.5, np.array([math.pi / 4]), 10.0)
    assert abs(r[0] - 0.5 * math.sqrt(2)) < 1e-12
    obs = np.zeros(wall.shape, dtype=bool)
    mark_observed(obs, wall, 0.0, 0.0, 1.0, 1.5, 1.5, np.array([math.pi / 4]), r)
    assert obs[1, 1] and obs[1, 2] and obs[2, 1] and not obs[2, 2]


def test_real_map_crop_matches_reference():
    from pathlib import Path

    from PIL import Image

    pixels = np.asarray(Image.open(Path("/work/shared/maps/intel.png")).convert("L"))
    free = np.flipud((255.0 - pixels) / 255.0 < 0.1)[400:440, 300:340]  # a 2 x 2 m corner of the lab
    wall = (~free).astype(np.uint8)
    rng = np.random.default_rng(5)
    free_cells = np.argwhere(free)
    assert len(free_cells) > 100 and wall.sum() > 50
    for r, c in free_cells[rng.choice(len(free_cells), 8, replace=False)]:
        x = 15.0 + (c + rng.uniform(0.02, 0.98)) * 0.05
        y = 20.0 + (r + rng.uniform(0.02, 0.98)) * 0.05
        angles = rng.uniform(-math.pi, math.pi, 24)
        got = cast_rays(wall, 15.0, 20.0, 0.05, x, y, angles, 1.5)
        want = cast_rays_reference(wall, 15.0, 20.0, 0.05, x, y, angles, 1.5)
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-9)
        obs_got = np.zeros(wall.shape, dtype=bool)
        obs_want = np.zeros(wall.shape, dtype=bool)
        mark_observed(obs_got, wall, 15.0, 20.0, 0.05, x, y, angles, got)
        mark_observed_reference(obs_want, wall, 15.0, 20.0, 0.05, x, y, angles, got)
        assert np.array_equal(obs_got, obs_want)


@settings(max_examples=150, deadline=None)
@given(scenes(), st.lists(st.tuples(st.floats(0.01, 0.99), st.floats(0.01, 0.99), angle_st), min_size=1, max_size=5),
       st.floats(0.0, 8.0))
def test_the_team_calls_equal_one_call_per_robot(scene, robots, within_cells):
    """cast_and_mark_all and pair_wall_lengths_m (the world's one call per step for the whole
    team) give exactly what the per-robot kernels give."""
    wall, ox, oy, res, _, _, angles, max_range = scene
    rows, cols = wall.shape
    poses = np.array([(ox + fx * cols * res, oy + fy * rows * res, yaw) for fx, fy, yaw in robots])
    observed = np.zeros((len(poses),) + wall.shape, dtype=bool)
    ranges = cast_and_mark_all(observed, wall, ox, oy, res, poses, angles, max_range)
    within_m = within_cells * res
    lengths = pair_wall_lengths_m(wall, ox, oy, res, poses, within_m)
    for i, (x, y, yaw) in enumerate(poses):
        want_observed = np.zeros(wall.shape, dtype=bool)
        want = cast_and_mark(want_observed, wall, ox, oy, res, x, y, angles + yaw, max_range)
        assert np.array_equal(ranges[i], want) and np.array_equal(observed[i], want_observed)
        for j, (xj, yj, _) in enumerate(poses):
            if i != j and (xj - x) ** 2 + (yj - y) ** 2 <= within_m ** 2:
                assert lengths[i, j] == wall_length_m(wall, ox, oy, res, x, y, xj, yj)
            else:
                assert math.isnan(lengths[i, j])
