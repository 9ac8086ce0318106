"""Divide and conquer (`--scheme divide`, ../shared/schemes/wiserx.md B3): the floor plan
split into one connected region per robot, alike on every robot, each robot exploring only
its own; issue 24's baseline for a team with a slow robot."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import ndimage

from firmware.agent import ExplorerAgent
from firmware.schemes.divide.partition import Partition
from host_tools.mission import MissionConfig, deployment, run_mission
from tests.doubles import ScriptedHal
from world_sim.map_spec import resolve_map
from world_sim.ros_map import reachable_from_starts


def _plan(map_spec: str):
    occ, start, _ = resolve_map(map_spec)
    reachable = reachable_from_starts(occ, [start], robot_radius_m=0.25)
    return deployment(occ, reachable, start, "shared", 1)


def _connected(p: Partition, region: int, plan_shape, x0, y0, cell_m) -> bool:
    image = np.zeros(plan_shape, dtype=bool)
    xy = p.cells_of(region)
    image[((xy[:, 1] - y0) / cell_m).astype(int), ((xy[:, 0] - x0) / cell_m).astype(int)] = True
    return ndimage.label(image, structure=np.ones((3, 3)))[1] == 1


@pytest.mark.parametrize("map_spec, k", [("cave:1:60x60", 3), ("cave:1:60x60", 5), ("../shared/maps/intel.yaml", 3),
                                         ("../shared/maps/maze_a.yaml", 5)])
def test_every_cell_is_in_one_region_and_every_region_is_connected(map_spec, k, shared_maps):
    d = _plan(map_spec.replace("../shared/maps", str(shared_maps)))
    x0, y0 = d.boundary_m[:2]
    p = Partition(d.navigable_m2, d.plan_cell_m, x0, y0, 0.25, k)
    assert len(p.labels) == int((d.navigable_m2 >= 0.25).sum()) and set(p.labels) == set(range(k))
    for r in range(k):
        assert _connected(p, r, d.navigable_m2.shape, x0, y0, d.plan_cell_m), f"region {r} is in pieces"
    again = Partition(d.navigable_m2, d.plan_cell_m, x0, y0, 0.25, k)
    assert np.array_equal(again.labels, p.labels)          # every robot divides alike
    assert np.array_equal(p.region_of(p.xy[:, 0], p.xy[:, 1]), p.labels)


def test_a_region_follows_the_walls_not_the_crow():
    """Two arms of a U, 1 m apart across a wall and 40 m apart along the floor: halved, each
    arm is one region, although the arms' ends lie nearer each other than their own bottoms."""
    plan = np.zeros((22, 9))
    plan[0:2, :] = 1.0                          # the bottom of the U
    plan[:, 0:4] = 1.0                          # the left arm
    plan[:, 5:9] = 1.0                          # the right arm, one cell of wall between
    p = Partition(plan, 1.0, 0.0, 0.0, 0.25, 2)
    left = p.region_of([1.5, 1.5, 2.5], [21.5, 12.5, 16.5])
    right = p.region_of([6.5, 6.5, 7.5], [21.5, 12.5, 16.5])
    assert len(set(left)) == 1 and len(set(right)) == 1 and left[0] != right[0]


@settings(max_examples=40, deadline=None)
@given(st.integers(2, 6), st.integers(1, 4), st.randoms(use_true_random=False))
def test_random_plans_divide_into_connected_regions(side, k, rnd):
    plan = np.array([[1.0 if rnd.random() < 0.7 else 0.0 for _ in range(side * 3)] for _ in range(side * 3)])
    labels, n = ndimage.label(plan > 0, structure=np.ones((3, 3)))
    if n == 0:
        return
    plan[labels != 1 + int(np.argmax(np.bincount(labels.ravel())[1:]))] = 0.0   # one piece of floor
    p = Partition(plan, 1.0, 0.0, 0.0, 0.25, k)
    for r in set(p.labels):
        assert _connected(p, int(r), plan.shape, 0.0, 0.0, 1.0)


def test_a_team_divides_the_cave_and_covers_it_with_less_overlap_than_robots_alone():
    runs = {s: run_mission(MissionConfig(map_spec="cave:4:40x40", robots=3, seed=0, max_sim_s=1800, strategy=s))
            for s in ("divide", "independent")}
    divided = runs["divide"]
    assert divided.termination == "complete" and divided.coverage >= 0.99 and divided.air_frames == []
    assert divided.overlap < 0.5 * runs["independent"].overlap
    assert divided.t_total_s < runs["independent"].t_total_s
    assert all(n > 0 for n in divided.explorer_stats()["divide_waypoints_outside"])


def test_without_a_floor_plan_it_refuses_to_start():
    with pytest.raises(ValueError, match="scheme divide needs floor_plan"):
        ExplorerAgent(ScriptedHal(np.full(360, 3.0)).hal(), scheme="divide")
