"""Generated caves and mine tunnels: determinism, size, connectivity, room for a robot."""
from __future__ import annotations

import math
import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import ndimage

from world_sim.map_spec import MapSpecError, clearance_field_m, resolve_map, staging_poses
from world_sim.procgen import generate_cave, generate_tunnel

GENERATORS = {"cave": generate_cave, "tunnel": generate_tunnel}
EIGHT = np.ones((3, 3), dtype=bool)
ROBOT_RADIUS_M = 0.3


def check_invariants(occ, start, min_clearance_m: float = 1.0) -> None:
    free = occ.free
    assert free.dtype == bool
    # solid rock all around
    assert not free[0].any() and not free[-1].any()
    assert not free[:, 0].any() and not free[:, -1].any()
    # start on a free cell with room around it
    row, col = occ.cell_of(start[0], start[1])
    assert free[row, col]
    assert clearance_field_m(free, occ.resolution_m)[row, col] >= min_clearance_m
    assert 0.0 <= start[2] < 2.0 * math.pi
    # one piece, and it is the start's
    labels, count = ndimage.label(free, structure=EIGHT)
    assert count == 1 and labels[row, col] == 1


@pytest.mark.parametrize("kind", ["cave", "tunnel"])
def test_same_seed_same_map_bit_for_bit(kind):
    a, start_a = GENERATORS[kind](11, width_m=60.0, height_m=45.0)
    b, start_b = GENERATORS[kind](11, width_m=60.0, height_m=45.0)
    assert np.packbits(a.free).tobytes() == np.packbits(b.free).tobytes()
    assert start_a == start_b
    c, start_c = GENERATORS[kind](12, width_m=60.0, height_m=45.0)
    assert not np.array_equal(a.free, c.free)
    assert start_a != start_c


@pytest.mark.parametrize("kind", ["cave", "tunnel"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_100m_maps_are_connected_roomy_and_a_good_share_free(kind, seed):
    occ, start = GENERATORS[kind](seed)
    assert (occ.rows, occ.cols) == (1000, 1000)
    assert occ.resolution_m == 0.1 and (occ.origin_x_m, occ.origin_y_m) == (0.0, 0.0)
    assert occ.name == f"{kind}:{seed}"
    check_invariants(occ, start)
    assert 0.18 <= occ.free.mean() <= 0.5
    # a robot of radius 0.3 m reaches (with its body) nearly all of the free space
    clearance = clearance_field_m(occ.free, occ.resolution_m)
    centres_ok = clearance >= ROBOT_RADIUS_M
    labels, _ = ndimage.label(centres_ok, structure=EIGHT)
    row, col = occ.cell_of(start[0], start[1])
    reachable_centres = labels == labels[row, col]
    swept = ndimage.distance_transform_edt(~reachable_centres) * occ.resolution_m <= ROBOT_RADIUS_M + 0.1
    assert (swept & occ.free).sum() >= 0.97 * occ.free.sum()
    # room for a team to line up at the start
    assert len(staging_poses(occ, start, 8, spacing_m=1.0, clearance_m=0.5)) == 8


def test_tunnels_are_corridors_2_to_4_m_wide():
    occ, _ = generate_tunnel(4)
    clearance = clearance_field_m(occ.free, occ.resolution_m)
    # on the ridge of the clearance field (the corridor centre lines) the clearance is the
    # half width; chambers are the only places wider than a 4 m drift
    ridge = occ.free & (clearance >= ndimage.maximum_filter(clearance, size=5) - 1e-9)
    half_widths = clearance[ridge & (clearance > 0.3)]
    assert 0.8 <= np.median(half_widths) <= 2.0
    assert np.quantile(half_widths, 0.9) <= 2.5
    # and it is not a cave: most free cells lie within 2 m of a wall
    assert (clearance[occ.free] <= 2.0).mean() >= 0.9


def test_caves_have_chambers_and_passages():
    occ, _ = generate_cave(4)
    clearance = clearance_field_m(occ.free, occ.resolution_m)
    assert clearance.max() >= 4.0  # a chamber
    narrow = occ.free & (clearance < 1.2)
    assert narrow.sum() >= 0.2 * occ.free.sum()  # and winding passages / chamber edges


@pytest.mark.parametrize("kind", ["cave", "tunnel"])
def test_smallest_and_odd_sizes(kind):
    occ, start = GENERATORS[kind](3, width_m=50.0, height_m=50.0)
    assert (occ.rows, occ.cols) == (500, 500)
    check_invariants(occ, start)
    occ, start = GENERATORS[kind](3, width_m=55.55, height_m=20.0, resolution_m=0.25)
    assert (occ.rows, occ.cols) == (80, 222)
    check_invariants(occ, start)


@pytest.mark.realtime
@pytest.mark.parametrize("kind", ["cave", "tunnel"])
def test_500m_map_is_quick(kind):
    t0 = time.perf_counter()
    occ, start = GENERATORS[kind](8, width_m=500.0, height_m=500.0)
    elapsed_s = time.perf_counter() - t0
    assert (occ.rows, occ.cols) == (5000, 5000)
    assert occ.free[occ.cell_of(start[0], start[1])]
    assert 0.15 <= occ.free.mean() <= 0.5
    assert elapsed_s < 30.0  # a few seconds alone; generous for 2 shared cores
    t0 = time.perf_counter()
    assert len(staging_poses(occ, start, 8)) == 8
    assert time.perf_counter() - t0 < 2.0  # searches a window, not the 25 M cells


@pytest.mark.parametrize(
    "kwargs,match",
    [
        ({"width_m": 10.0}, "width_m must be a number >= 20"),
        ({"height_m": float("nan")}, "height_m must be a number >= 20"),
        ({"resolution_m": 0.0}, "resolution_m must be in"),
        ({"resolution_m": 1.0}, "resolution_m must be in"),
    ],
)
@pytest.mark.parametrize("kind", ["cave", "tunnel"])
def test_bad_sizes_are_refused(kind, kwargs, match):
    with pytest.raises(ValueError, match=match):
        GENERATORS[kind](1, **kwargs)


@settings(max_examples=12, deadline=None)
@given(
    kind=st.sampled_from(["cave", "tunnel"]),
    seed=st.integers(0, 2**40),
    width_m=st.floats(20.0, 60.0),
    height_m=st.floats(20.0, 60.0),
    resolution_m=st.sampled_from([0.1, 0.2, 0.25]),
)
def test_invariants_hold_for_any_seed_and_size(kind, seed, width_m, height_m, resolution_m):
    occ, start = GENERATORS[kind](seed, width_m=width_m, height_m=height_m, resolution_m=resolution_m)
    assert occ.rows == round(height_m / resolution_m) and occ.cols == round(width_m / resolution_m)
    check_invariants(occ, start)


def test_map_specs_for_generated_worlds():
    occ, start, label = resolve_map("cave:3:60x40")
    assert label == "cave:3:60x40" and (occ.cols, occ.rows) == (600, 400)
    same, same_start = generate_cave(3, width_m=60.0, height_m=40.0)
    assert np.array_equal(occ.free, same.free) and start == same_start
    occ, start, label = resolve_map(" tunnel:2 ")
    assert label == "tunnel:2:100x100" and (occ.cols, occ.rows) == (1000, 1000)
    _, _, label = resolve_map("Cave:5:50.5X60")
    assert label == "cave:5:50.5x60"
    with pytest.raises(MapSpecError, match="accepted: a path to a ROS map .yaml"):
        resolve_map("cavern:3")
