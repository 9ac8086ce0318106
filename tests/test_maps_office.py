"""Generated office floors: determinism, exact narrow doors, a start room only the body's
clearance gets out of, every room reachable by the body, furniture gaps just wider than it,
and the `office:` map spec."""
from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from host_tools.map_report import drivable_centres
from world_sim import office
from world_sim.kinematics import ClearanceMap
from world_sim.map_spec import MapSpecError, check_map_spec, resolve_map, staging_poses
from world_sim.office import body_centres_in, body_reachable, build_office, generate_office
from world_sim.world import WorldParams

EIGHT = np.ones((3, 3), dtype=bool)
SEEDS = [0, 1, 2, 3]


@pytest.fixture(scope="module")
def floors():
    """The default 40 x 30 m floor of each seed in SEEDS, built once for the module."""
    return {seed: build_office(seed) for seed in SEEDS}


def clear_run_cells(free: np.ndarray, door: office.Door) -> int:
    """Free cells in a row along the door's wall, through the door, from jamb to jamb (the
    fewest over the wall's thickness)."""
    o = door.opening
    runs = []
    along_x = door.side in ("south", "north")
    for layer in (range(o.row0, o.row1) if along_x else range(o.col0, o.col1)):
        line = free[layer, :] if along_x else free[:, layer]
        lo, hi = (o.col0, o.col1) if along_x else (o.row0, o.row1)
        assert line[lo:hi].all()
        while lo > 0 and line[lo - 1]:
            lo -= 1
        while hi < line.size and line[hi]:
            hi += 1
        runs.append(hi - lo)
    return min(runs)


def room_of(floor, x_m: float, y_m: float) -> int:
    row, col = floor.occ.cell_of(x_m, y_m)
    inside = [i for i, r in enumerate(floor.rooms)
              if r.interior.row0 <= row < r.interior.row1 and r.interior.col0 <= col < r.interior.col1]
    assert len(inside) == 1
    return inside[0]


def test_the_body_is_the_simulated_robot():
    assert office.BODY_RADIUS_M == WorldParams().robot_radius_m
    assert office.NARROW_DOOR_M == pytest.approx(2 * office.BODY_RADIUS_M + 0.1)


def test_same_seed_same_map_bit_for_bit(floors):
    again, start = generate_office(1)
    assert np.packbits(again.free).tobytes() == np.packbits(floors[1].occ.free).tobytes()
    assert start == floors[1].start
    other, other_start = generate_office(2)
    assert not np.array_equal(other.free, again.free) and other_start != start


@pytest.mark.parametrize("seed", SEEDS)
def test_a_walled_floor_in_one_piece(floors, seed):
    floor = floors[seed]
    occ = floor.occ
    assert (occ.rows, occ.cols) == (300, 400) and occ.resolution_m == 0.1 and occ.name == f"office:{seed}"
    assert not occ.free[:2].any() and not occ.free[-2:].any()
    assert not occ.free[:, :2].any() and not occ.free[:, -2:].any()
    _, pieces = ndimage.label(occ.free, structure=EIGHT)
    assert pieces == 1
    assert len(floor.rooms) >= 10 and 0.6 <= occ.free.mean() <= 0.9
    side_cells = [min(r.interior.height_cells, r.interior.width_cells) for r in floor.rooms]
    assert min(side_cells) >= 30 and max(r.interior.height_cells for r in floor.rooms) <= 80
    corridor_widths = [min(c.height_cells, c.width_cells) for c in floor.corridors]
    assert all(12 <= w <= 20 for w in corridor_widths)


@pytest.mark.parametrize("seed", SEEDS)
def test_doors_are_0_6_to_1_0_m_clear_in_the_raster_and_the_narrowest_is_exactly_6_cells(floors, seed):
    floor = floors[seed]
    for door in floor.doors:
        assert 6 <= door.clear_cells <= 10
        assert clear_run_cells(floor.occ.free, door) == door.clear_cells
        # the wall is one or two cells thick there
        assert min(door.opening.height_cells, door.opening.width_cells) in (1, 2)
    assert min(d.clear_cells for d in floor.doors) == 6


@pytest.mark.parametrize("seed", SEEDS)
def test_the_start_room_has_one_door_and_it_is_the_narrowest(floors, seed):
    floor = floors[seed]
    occ, start = floor.occ, floor.start
    assert room_of(floor, start[0], start[1]) == floor.start_room
    (door,) = floor.doors_of(floor.start_room)
    assert door.other_room == -1 and door.clear_cells == 6
    assert clear_run_cells(occ.free, door) * occ.resolution_m == pytest.approx(0.6)
    # The simulated body fits through the middle of the door with 5 cm to spare each side...
    o = door.opening
    mid_x, mid_y = occ.center_of(o.row0, o.col0)
    if door.side in ("south", "north"):
        mid_x = o.col0 * occ.resolution_m + 0.3
    else:
        mid_y = o.row0 * occ.resolution_m + 0.3
    clearance = ClearanceMap.from_map(occ)
    assert clearance.disc_fits(mid_x, mid_y, WorldParams().robot_radius_m)
    assert clearance.clearance_m(mid_x, mid_y) == pytest.approx(0.3)
    # ...and reaches every corridor from the start. Where a planner may put the robot's centre
    # (drivable_centres: at least a clearance from every wall cell's centre, the firmware's rule
    # as `lorascout map` applies it) leads out of the start room with a clearance just under
    # half the door, 0.29 m, but not with the body's radius and 7 cm, 0.32 m.
    swept = body_reachable(occ, start[:2])
    assert all(swept[c.index].mean() > 0.95 for c in floor.corridors)
    room = np.zeros_like(occ.free)
    room[floor.rooms[floor.start_room].interior.index] = True
    assert (drivable_centres(occ, start[:2], 0.29) & ~room).sum() > 0.5 * occ.free.sum()
    trapped = drivable_centres(occ, start[:2], office.BODY_RADIUS_M + 0.07)
    assert trapped[room].any() and not (trapped & ~room).any()


@pytest.mark.parametrize("seed", SEEDS)
def test_every_room_is_reachable_by_the_body_from_the_start(floors, seed):
    floor = floors[seed]
    occ = floor.occ
    swept = body_reachable(occ, floor.start[:2])
    for index, room in enumerate(floor.rooms):
        assert any(d.clear_cells >= 6 for d in floor.doors_of(index))
        window = room.interior.index
        # every place in the room where the body can stand is reached from the start...
        assert swept[window][body_centres_in(occ.free[window], occ.resolution_m)].all()
        # ...and the furniture leaves little of the floor out of its reach
        assert swept[window].sum() >= 0.85 * occ.free[window].sum()
    assert swept.sum() >= 0.95 * occ.free.sum()


@pytest.mark.parametrize("seed", SEEDS)
def test_some_rooms_have_two_doors_and_some_are_entered_only_through_another(floors, seed):
    floor = floors[seed]
    doors = [floor.doors_of(i) for i in range(len(floor.rooms))]
    assert any(len(d) >= 2 for d in doors)
    inner = [i for i, d in enumerate(doors) if all(door.other_room >= 0 for door in d)]
    assert inner
    for i in inner:
        neighbours = {door.room if door.other_room == i else door.other_room for door in doors[i]}
        assert floor.start_room not in neighbours
        assert any(any(door.other_room == -1 for door in doors[j]) for j in neighbours)


@pytest.mark.parametrize("seed", SEEDS)
def test_furniture_leaves_gaps_just_wider_than_the_body(floors, seed):
    floor = floors[seed]
    free = floor.occ.free
    centres = body_centres_in(free, floor.occ.resolution_m)
    assert len(floor.squeezes) >= 10
    assert {s.gap_cells for s in floor.squeezes} <= {6, 7} and 6 in {s.gap_cells for s in floor.squeezes}
    for squeeze in floor.squeezes:
        g = squeeze.gap
        assert free[g.index].all()
        if squeeze.faces_apart_in_y:   # furniture below and above, all along
            assert g.height_cells == squeeze.gap_cells
            assert not free[g.row0 - 1, g.col0:g.col1].any() and not free[g.row1, g.col0:g.col1].any()
        else:
            assert g.width_cells == squeeze.gap_cells
            assert not free[g.row0:g.row1, g.col0 - 1].any() and not free[g.row0:g.row1, g.col1].any()
        assert centres[g.index].any()  # the body stands in the gap (and every such place is reached, above)


def test_a_small_team_lines_up_in_the_start_room(floors):
    for floor in floors.values():
        poses = staging_poses(floor.occ, floor.start, 6)
        assert all(room_of(floor, x, y) == floor.start_room for x, y, _ in poses)


@pytest.mark.parametrize("width_m,height_m,resolution_m", [(20.0, 20.0, 0.1), (55.55, 20.0, 0.25),
                                                           (40.0, 30.0, 0.05), (40.0, 30.0, 0.2),
                                                           (30.0, 20.0, 0.15)])
def test_other_sizes_and_resolutions(width_m, height_m, resolution_m):
    floor = build_office(3, width_m, height_m, resolution_m)  # checks every room is reachable itself
    occ = floor.occ
    assert (occ.rows, occ.cols) == (round(height_m / resolution_m), round(width_m / resolution_m))
    narrowest = min(d.clear_cells for d in floor.doors) * resolution_m
    assert 0.6 - 1e-9 <= narrowest < 0.6 + resolution_m
    (door,) = floor.doors_of(floor.start_room)
    assert door.clear_cells * resolution_m == pytest.approx(narrowest)
    swept = body_reachable(occ, floor.start[:2])
    assert all(swept[r.interior.index].any() for r in floor.rooms)


@pytest.mark.parametrize(
    "kwargs,match",
    [
        ({"width_m": 10.0}, "width_m must be a number >= 20"),
        ({"height_m": 250.0}, "height_m of an office floor must be at most 200"),
        ({"resolution_m": 1.0}, "resolution_m must be in"),
    ],
)
def test_bad_sizes_are_refused(kwargs, match):
    with pytest.raises(ValueError, match=match):
        generate_office(1, **kwargs)


def test_office_map_specs():
    occ, start, label = resolve_map("office:3:30x25")
    assert label == "office:3:30x25" and (occ.cols, occ.rows) == (300, 250)
    same, same_start = generate_office(3, width_m=30.0, height_m=25.0)
    assert np.array_equal(occ.free, same.free) and start == same_start
    _, _, label = resolve_map(" Office:2 ")
    assert label == "office:2:40x30"


@pytest.mark.parametrize(
    "spec,expect",
    [
        ("office:x", "seed 'x' is not a non-negative integer"),
        ("office:", "seed '' is not a non-negative integer"),
        ("office:1:30", "size '30' is not WxH in metres"),
        ("office:1:10x30", "width 10 m is outside 20..200 m"),
        ("office:1:40x201", "height 201 m is outside 20..200 m"),
        ("office:1:2:3:4", "separators"),
        ("offices:1", "unrecognised map spec"),
    ],
)
def test_bad_office_specs_say_what_is_wrong(spec, expect):
    with pytest.raises(MapSpecError) as info:
        check_map_spec(spec)  # parsed only: a refused spec never costs a generation
    assert expect in str(info.value)
    assert "office:SEED" in str(info.value) or "outside" in str(info.value)
