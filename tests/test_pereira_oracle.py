"""`pereira-oracle` (issue 23 item 6): regions cut at the doorways of the ground truth, which
the host finds once and hands to every robot as a region map; the firmware never sees the
simulator's map (host_tools/region_oracle.py, Pereira.load_region_map)."""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from firmware.params import ExplorationParams
from firmware.schemes import build
from firmware.schemes.pereira.records import ORACLE_ORIGIN, dir_code_of
from host_tools.mission import MissionConfig, run_mission
from host_tools.region_oracle import doorways, truth_state
from world_sim.map_spec import resolve_map
from world_sim.occupancy_map import OccupancyMap


def two_rooms_truth(res_m: float = 0.05) -> OccupancyMap:
    """Two 5 x 5 m rooms side by side, a 0.2 m wall at x = 6.0..6.2 m between them with a
    door 0.9 m wide at y = 3.5..4.4 m; origin (0.5, 0.5) m, so the truth's cells are not
    the robots' cells."""
    free = np.zeros((int(7 / res_m), int(12 / res_m)), bool)

    def carve(x0, x1, y0, y1):
        free[int(round((y0 - 0.5) / res_m)):int(round((y1 - 0.5) / res_m)),
             int(round((x0 - 0.5) / res_m)):int(round((x1 - 0.5) / res_m))] = True
    carve(1.0, 6.0, 1.0, 6.0)
    carve(6.2, 11.2, 1.0, 6.0)
    carve(6.0, 6.2, 3.5, 4.4)
    return OccupancyMap(free, res_m, 0.5, 0.5, "two rooms")


def test_the_truth_becomes_the_robots_grid_in_the_shared_frame():
    occ = two_rooms_truth()
    state, row0, col0 = truth_state(occ, 0.1)
    # The corner cell is (floor(y / 0.1), floor(x / 0.1)) of the map's origin, less the border.
    assert (row0, col0) == (4, 4)
    from firmware import kernels
    # A cell in the left room and one in the wall, looked up by their global cells.
    assert state[int(3.0 / 0.1) - row0, int(3.0 / 0.1) - col0] == kernels.FREE
    assert state[int(3.0 / 0.1) - row0, int(6.1 / 0.1) - col0] == kernels.OCCUPIED
    assert (state[0] == kernels.OCCUPIED).all() and (state[:, -1] == kernels.OCCUPIED).all()


def test_the_doorway_of_two_rooms_is_the_door():
    (d,) = doorways(two_rooms_truth())
    x_dm, y_dm, code, half_2cm = d
    assert math.hypot(x_dm / 10 - 6.1, y_dm / 10 - 3.95) <= 0.2
    assert min((code - dir_code_of(math.pi / 2)) % 256, (dir_code_of(math.pi / 2) - code) % 256) <= 8
    assert abs(half_2cm * 0.02 * 2 - 0.9) <= 0.2


def test_maze_a_has_its_corridor_mouths_as_doorways(shared_maps):
    occ, _, _ = resolve_map(str(shared_maps / "maze_a.yaml"))
    found = doorways(occ)
    assert 10 <= len(found) <= 30
    # Every doorway lies on free ground in the truth, between walls about 5 m apart (the maze's corridors).
    for x_dm, y_dm, _code, half_2cm in found:
        assert occ.is_free_point(x_dm / 10, y_dm / 10)
        assert 4.5 <= 2 * half_2cm * 0.02 <= 5.2


def test_a_region_map_is_the_oracle_variants_alone_and_checked():
    with pytest.raises(ValueError, match="only pereira:oracle"):
        build("pereira").load_region_map([(0, 0, 0, 10)])
    oracle = build("pereira-oracle")
    assert "region_map" in oracle.needs_of() and "region_map" not in build("pereira").needs_of()
    with pytest.raises(ValueError, match="doorway 2"):
        oracle.load_region_map([(0, 0, 0, 10), (0, 0, 256, 10)])     # dir_code is 8 bits
    with pytest.raises(ValueError, match="needs the team's region map"):
        build("pereira-oracle").attach(SimpleNamespace(params=ExplorationParams()))


def test_an_oracle_team_cuts_its_regions_at_the_maps_doorways_and_sends_none():
    r = run_mission(MissionConfig(map_spec="cave:5:20x20", robots=3, seed=1, strategy="pereira-oracle",
                                  max_sim_s=900, radio="eu868-g3"))
    assert r.termination == "complete" and r.coverage >= 0.99
    occ, _, _ = resolve_map("cave:5:20x20")
    expected = doorways(occ)
    stats = r.to_json()["explorer_stats"]
    assert stats["map_doorways"] == [len(expected)] * 3 and len(expected) >= 1
    assert stats["gates_sent"] == [0, 0, 0] and sum(stats["claims_sent"]) > 0
    graphs = [a.scheme.store.graph() for a in r.agents]
    assert len({g.digest() for g in graphs}) == 1
    # The graph's gates are the map's doorways, no more (none folded away: they are apart).
    assert sorted(tuple(int(v) for v in row) for row in graphs[0].gates) == sorted(d[:4] for d in expected)
    assert all(int(o) == ORACLE_ORIGIN for o in graphs[0].gate_records[:, 4])
    # The region map is held, never gossiped: no robot summarises or pushes the oracle's records.
    assert all(ORACLE_ORIGIN not in a.scheme.holdings.origins() for a in r.agents)
