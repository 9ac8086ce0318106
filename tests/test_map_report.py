"""`lorascout map`: the coverage ceiling of a map for a planner that keeps a clearance from
walls. A room behind a door narrower than twice the clearance is seen only through the
door; the drivable cells match a brute-force reading of the firmware's rule."""
import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host_tools.cli import main
from host_tools.map_report import drivable_centres, observable_share
from world_sim.occupancy_map import OccupancyMap

RES = 0.05


def corridor_and_room(door_cells: int) -> OccupancyMap:
    """A 2 m x 6 m corridor (x 0.5..6.5, y 0.5..2.5) and a 3 m x 3 m room above it (x 2..5,
    y 2.6..5.6), joined by a door door_cells wide in the 0.1 m wall between them."""
    free = np.zeros((120, 140), dtype=bool)
    free[10:50, 10:130] = True          # corridor
    free[52:112, 40:100] = True         # room
    mid = 70
    free[50:52, mid - door_cells // 2: mid - door_cells // 2 + door_cells] = True
    return OccupancyMap(free=free, resolution_m=RES, origin_x_m=0.0, origin_y_m=0.0, name="door")


def share(occ, clearance_m, **kw):
    args = dict(body_radius_m=0.2, lidar_beams=360, lidar_range_m=10.0, stride_m=0.1)
    args.update(kw)
    return observable_share(occ, (1.0, 1.5), clearance_m, **args)


def test_a_room_behind_a_door_the_planner_cannot_pass_is_seen_only_through_the_door():
    occ = corridor_and_room(door_cells=10)                    # 0.5 m: the 0.2 m body passes
    wide, unseen_wide = share(occ, 0.2)
    assert wide.observable_share == 1.0 and not unseen_wide.any()
    assert 20.8 < wide.reachable_m2 <= 2 * 6 + 3 * 3 + 0.5 * 0.1     # square corners the body cannot sweep
    narrow, unseen = share(occ, 0.32)
    assert narrow.reachable_m2 == wide.reachable_m2 and narrow.drivable_m2 < wide.drivable_m2
    assert 0.9 < narrow.observable_share < 1.0
    assert narrow.unobservable_m2 == pytest.approx(unseen.sum() * RES ** 2)
    rows, cols = np.nonzero(unseen)
    assert rows.min() >= 52                                   # all of it in the room...
    assert not unseen[52:, 65:75].any()                       # ...none of it straight through the door
    # The rim beside the door, inside the room, is what nobody outside can see.
    assert unseen[52:60, 40:60].any() and unseen[52:60, 80:100].any()


def test_a_door_wider_than_twice_the_clearance_lets_the_planner_in():
    occ = corridor_and_room(door_cells=16)                    # 0.8 m
    s, unseen = share(occ, 0.32)
    assert s.observable_share == 1.0 and not unseen.any()


def test_a_coarser_stride_stands_the_lidar_on_fewer_cells_and_sees_no_more():
    occ = corridor_and_room(door_cells=10)
    fine, _ = share(occ, 0.32)
    coarse, _ = share(occ, 0.32, stride_m=0.4)
    assert coarse.stations < fine.stations / 10 and coarse.stride_m == pytest.approx(0.4)
    assert coarse.observable_share <= fine.observable_share


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2 ** 32 - 1), st.floats(0.05, 0.4))
def test_drivable_cells_keep_the_clearance_from_every_wall_cell_and_the_map_edge(seed, clearance_m):
    rng = np.random.default_rng(seed)
    free = rng.random((14, 17)) > 0.12
    occ = OccupancyMap(free=free, resolution_m=0.1, origin_x_m=0.0, origin_y_m=0.0)
    walls = [(r, c) for r in range(-1, 15) for c in range(-1, 18)
             if not (0 <= r < 14 and 0 <= c < 17) or not free[r, c]]
    keeps = np.array([[min(np.hypot(r - wr, c - wc) for wr, wc in walls) * 0.1 >= clearance_m
                       for c in range(17)] for r in range(14)])
    if not keeps.any():
        with pytest.raises(ValueError, match="no cell keeps"):
            drivable_centres(occ, (0.75, 0.75), clearance_m)
        return
    got = drivable_centres(occ, (0.75, 0.75), clearance_m)
    assert not (got & ~keeps).any()                           # only cells that keep it...
    # ...forming one 8-connected piece: no kept cell outside it touches it.
    from scipy import ndimage
    grown = ndimage.binary_dilation(got, structure=np.ones((3, 3), dtype=bool))
    assert not (grown & keeps & ~got).any()


def test_the_command_prints_a_table_json_and_a_figure(tmp_path, capsys):
    png = tmp_path / "cave.png"
    assert main(["map", "--map", "cave:4:40x40", "--clearance-m", "0.32", "0.5", "--stride-m", "0.3",
                 "--png", str(png), "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "| 0.32 |" in out and "| 0.50 |" in out and png.read_bytes()[:4] == b"\x89PNG"
    assert main(["map", "--map", "cave:4:40x40", "--stride-m", "0.3", "--json", "--quiet"]) == 0
    report = json.loads(capsys.readouterr().out)
    (c,) = report["clearances"]
    assert c["clearance_m"] == 0.27 and 0.9 < c["observable_share"] <= 1.0 and c["stations"] > 100
    assert report["body_radius_m"] == 0.25 and report["lidar_range_m"] == 10.0


def test_bad_input_is_refused_with_the_reason(tmp_path, cli):
    r = cli("map", "--map", tmp_path / "none.yaml", "--quiet")
    assert r.code == 2 and "argument --map" in r.err and "none.yaml: map YAML file not found" in r.err
    r = cli("map", "--map", "cave:4:40x40", "--clearance-m", "0", "--quiet")
    assert r.code == 2 and "argument --clearance-m: '0' is out of range; valid: 0 < M <= 10 m" in r.err
    r = cli("map", "--map", "cave:4:40x40", "--clearance-m", "9", "--quiet")
    assert r.code == 2 and "no cell keeps 9.0 m" in r.err


