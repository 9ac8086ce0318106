"""Everything a robot has mapped (services.known_map): the window over the paged-out tiles,
frontiers found in all of it, and a robot about to stop going back to a frontier its window
has left behind, along a way only the whole map shows."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from firmware import kernels
from firmware.params import ExplorationParams
from firmware.services.known_map import KnownMap, find_frontiers
from firmware.services.local_map import LocalMap
from host_tools.mission import MissionConfig, run_mission
from tests.doubles import PlannerRig

P = ExplorationParams()
FREE_LOGODDS, WALL_LOGODDS = -5.0, 5.0


def _paint(local_map: LocalMap, x0_m: float, x1_m: float, y0_m: float, y1_m: float, value: float) -> None:
    """Set the log-odds of the window cells whose centres lie in the box."""
    ij, inside = local_map.cells_of(np.array([[x0_m, y0_m], [x1_m, y1_m]]))
    (i0, j0), (i1, j1) = np.clip(ij, 0, local_map.n - 1)
    local_map.logodds[i0:i1 + 1, j0:j1 + 1] = value


def _corridor(local_map: LocalMap, x0_m: float, x1_m: float) -> None:
    """A corridor 2 m wide along y = 0 between x0_m and x1_m, walls 0.2 m thick."""
    _paint(local_map, x0_m, x1_m, -1.3, 1.3, WALL_LOGODDS)
    _paint(local_map, x0_m, x1_m, -1.0, 1.0, FREE_LOGODDS)


def corridor_with_a_door_left_behind() -> LocalMap:
    """A robot that mapped a corridor from x = 0 to 70 m, with a doorway 1 m wide in its
    north wall at x = 60 m opening onto unknown ground, and came back to x = 5 m: the doorway
    is paged out, 40 m behind the window's edge."""
    local_map = LocalMap(P, 50.0, 0.0)
    _corridor(local_map, 30.0, 70.0)
    _paint(local_map, 70.0, 70.2, -1.3, 1.3, WALL_LOGODDS)          # the far end
    _paint(local_map, 59.5, 60.5, 1.0, 1.3, FREE_LOGODDS)           # the doorway, unknown beyond
    assert local_map.follow(10.0, 0.0)
    _corridor(local_map, 0.0, 30.0)
    _paint(local_map, -0.2, 0.0, -1.3, 1.3, WALL_LOGODDS)           # the near end
    return local_map


def test_the_whole_map_holds_the_window_over_the_paged_out_tiles():
    local_map = corridor_with_a_door_left_behind()
    known = KnownMap(P, local_map)
    known.refresh(5.0, 0.0, 0)
    route, cost_m = known.route(60.0, 0.5)
    assert 55.0 < cost_m < 70.0
    assert route[0, 0] < 5.5 and route[-1, 0] > 59.0
    assert (np.abs(route[:, 1]) < 1.0).all()        # along the corridor, inside its walls
    left = known.frontiers()
    assert len(left.reachable) == 1 and not left.unreachable
    door = left.reachable[0]
    assert abs(door.stand_xy[0] - 60.0) < 1.0 and 0.0 < door.stand_xy[1] < 1.5     # in or before the doorway
    assert door.hidden_bit >= P.report_unreachable_bit


def _corridor_with_a_deep_slot(slot_cells: int, niche: bool, params: ExplorationParams = P) -> LocalMap:
    """The corridor, closed at both ends, with a slot `slot_cells` cells wide and 1.2 m deep
    through its thick north wall (too deep to see through from the corridor), unknown beyond
    it or, with a niche, a free niche 1.2 m wide beyond it opening on unknown ground."""
    local_map = LocalMap(params, 0.0, 0.0)
    _corridor(local_map, -5.0, 5.0)
    _paint(local_map, -5.2, -5.0, -1.3, 1.3, WALL_LOGODDS)
    _paint(local_map, 5.0, 5.2, -1.3, 1.3, WALL_LOGODDS)
    _paint(local_map, -1.0, 1.0, 1.0, 2.3, WALL_LOGODDS)
    _paint(local_map, 0.0, (slot_cells - 1) * P.resolution_m, 1.0, 2.3, FREE_LOGODDS)
    if niche:
        _paint(local_map, -0.7, 0.9, 2.3, 3.0, WALL_LOGODDS)
        _paint(local_map, -0.5, 0.7, 2.3, 3.0, FREE_LOGODDS)
    return local_map


def test_a_frontier_behind_a_gap_narrower_than_the_body_is_found_but_not_reached():
    # A slot of 4 free cells: 0.4 m between the expected wall faces, 0.5 m between the wall
    # cells' centres, narrower than the body (0.5 m) even so. The robot can neither pass it
    # nor look through it into the niche beyond.
    known = KnownMap(P, _corridor_with_a_deep_slot(slot_cells=4, niche=True))
    known.refresh(0.0, 0.0, 0)
    left = known.frontiers()
    assert not left.reachable and len(left.unreachable) == 1
    assert left.unreachable[0].stand_xy is None


@pytest.mark.parametrize("passage_cost, passes", [(10.0, True), (0.0, False)])
def test_a_slot_the_body_fits_only_between_the_wall_cells_centres_is_a_tight_passage(passage_cost, passes):
    # 5 free cells: 0.5 m between the expected faces (the body's width, no room for the
    # tolerance), 0.6 m between the wall cells' centres: a tight passage, unless turned off.
    params = dataclasses.replace(P, tight_passage_cost=passage_cost)
    local_map = _corridor_with_a_deep_slot(slot_cells=5, niche=False, params=params)
    known = KnownMap(params, local_map)
    known.refresh(0.0, 0.0, 0)
    left = known.frontiers()
    assert (len(left.reachable), len(left.unreachable)) == ((1, 0) if passes else (0, 1))
    layers = local_map.layers()
    i, j = local_map.cell_of(0.2, 1.6)                      # in the slot, on its middle line
    assert layers.traversable[i, j] == passes
    assert local_map.in_passage_at(0.25, 1.65) == passes
    assert not local_map.in_passage_at(0.0, 0.0)            # the corridor's middle is no passage
    if passes:
        assert layers.cell_cost[i, j] >= passage_cost       # taken only where nothing wider is near
        route, cost_m = known.route(0.25, 2.2)
        assert cost_m > 3.0 * math.hypot(0.25, 2.2)


@pytest.mark.parametrize("door", [False, True])
def test_free_cells_seen_through_a_chink_in_a_wall_are_no_frontier_to_stand_at(door):
    # A wall one cell thick along a corridor's north side; beyond it a fan of free cells
    # opening on unknown ground, as a beam through a chink draws it. The corridor's cells
    # lie within reach of the fan, but through the wall: nowhere to look into it from. With
    # a door in the wall there is.
    local_map = LocalMap(P, 0.0, 0.0)
    _paint(local_map, -3.2, 3.2, -1.3, 1.0, WALL_LOGODDS)
    _paint(local_map, -3.0, 3.0, -1.0, 0.9, FREE_LOGODDS)
    _paint(local_map, -0.5, 0.5, 1.1, 1.5, FREE_LOGODDS)
    if door:
        _paint(local_map, -0.4, 0.4, 1.0, 1.0, FREE_LOGODDS)
    known = KnownMap(P, local_map)
    known.refresh(-2.0, 0.0, 0)
    found = known.frontiers()
    assert (len(found.reachable), len(found.unreachable)) == ((1, 0) if door else (0, 1))
    if not door:
        assert found.unreachable[0].stand_xy is None


def test_the_window_alone_finds_no_frontier_once_the_door_is_paged_out():
    local_map = corridor_with_a_door_left_behind()
    layers = local_map.layers()
    i, j = local_map.cell_of(5.0, 0.0)
    reachable = kernels.reachable_cells(layers.traversable, i, j)
    found = find_frontiers(layers.sight, reachable, P, local_map.row0, local_map.col0)
    assert not found.reachable and not found.unreachable


def test_a_robot_about_to_stop_goes_back_to_a_frontier_its_window_left_behind():
    rig = PlannerRig(corridor_with_a_door_left_behind(), "independent")
    first = rig.plan(5.0, 0.0, 1_000_000)
    assert not first.done                        # the doorway at x = 60 m is still to be seen
    second = rig.plan(5.0, 0.0, 2_000_000)
    assert second.target is not None and abs(second.target.x_m - 60.0) < 1.0
    # No vertex of the topological map leads there: the whole map gives the way, as far as
    # the window reaches.
    assert len(second.path_xy) > 0 and second.path_xy[-1, 0] > 25.0
    assert (np.abs(second.path_xy[:, 1]) < 1.0).all()


def hairpin_with_a_door_far_round() -> LocalMap:
    """Two corridors along y = 0 and y = 25 m from x = 0 to 70 m, closed at x = 0 and joined
    at the far end by a corridor along x = 68 m, with a doorway onto unknown ground in the
    upper corridor's north wall at x = 2 m. The window is back round the lower corridor's
    west end: the doorway lies 26 m north of it, 150 m round by the corridors."""
    local_map = LocalMap(P, 50.0, 15.0)
    for y_m in (0.0, 25.0):
        _paint(local_map, 30.0, 70.0, y_m - 1.3, y_m + 1.3, WALL_LOGODDS)
        _paint(local_map, 30.0, 69.0, y_m - 1.0, y_m + 1.0, FREE_LOGODDS)
    _paint(local_map, 66.7, 69.3, 0.0, 25.0, WALL_LOGODDS)
    _paint(local_map, 67.0, 69.0, -1.0, 26.0, FREE_LOGODDS)
    assert local_map.follow(10.0, 15.0)
    for y_m in (0.0, 25.0):
        _paint(local_map, -0.2, 30.0, y_m - 1.3, y_m + 1.3, WALL_LOGODDS)
        _paint(local_map, 0.0, 30.0, y_m - 1.0, y_m + 1.0, FREE_LOGODDS)
    _paint(local_map, 1.5, 2.5, 26.0, 26.3, FREE_LOGODDS)           # the doorway, unknown beyond
    assert local_map.follow(10.0, -5.0)
    return local_map


def test_a_way_round_everything_mapped_beats_the_graphs_straight_line_across_the_unknown():
    """A robot that shares no topological map has its own places along the lower corridor
    only. The place nearest the doorway is the corridor's west end, 26 m short of it in a
    straight line the robot's map shows walled: the graph's way leads there and no further.
    The way round the corridors, through everything mapped, is the one to take."""
    rig = PlannerRig(hairpin_with_a_door_far_round(), "independent")
    for x_m in range(1, 10):
        rig.topo.add((0, x_m * 100, 0, 0, 1, 0, 0))
    assert not rig.plan(9.0, 0.0, 1_000_000).done
    heading = rig.plan(9.0, 0.0, 2_000_000)
    assert heading.target is not None and math.dist((heading.target.x_m, heading.target.y_m), (2.0, 26.0)) < 1.0
    assert heading.target.cost_m > 140.0                        # costed round the corridors
    assert len(heading.path_xy) > 0 and heading.path_xy[-1, 0] > 25.0     # east, not to the west end
    assert (np.abs(heading.path_xy[:, 1]) < 1.0).all()


def test_a_robot_says_complete_only_when_nothing_it_mapped_is_left_that_its_body_can_reach():
    # No communication: no frontier is left to a teammate (a scheme may do that).
    r = run_mission(MissionConfig(map_spec="cave:2:30x30", robots=2, seed=1, max_sim_s=1200.0,
                                  strategy="independent"))
    assert r.termination in ("complete", "complete_with_unreachable_frontiers")
    report = r.to_json()
    for k, agent in enumerate(r.agents):
        known = KnownMap(agent.p, agent.local_map)
        x_m, y_m = r.trajectories[k][-1, :2]
        known.refresh(float(x_m), float(y_m), 0)
        left = known.frontiers()
        if report["robot_status"][k] == "complete":
            assert not left.reachable, (k, left.reachable)
        assert report["narrow_gap_frontiers"][k] == len(left.unreachable)


def test_a_frontier_the_scheme_leaves_to_a_teammate_does_not_stop_the_robot_short_of_the_next():
    from firmware.schemes.independent import Independent

    class LeavesTheNearDoorToATeammate(Independent):
        """As if a teammate had reported seeing the doorway at x = 40 m."""

        def filter_waypoints(self, view):
            if view.closing:
                wps = self.s.waypoints
                wps.items = [w for w in wps.items if w.x_m > 50.0]

    local_map = corridor_with_a_door_left_behind()
    local_map.follow(50.0, 0.0)
    _paint(local_map, 39.5, 40.5, 1.0, 1.3, FREE_LOGODDS)           # a second doorway, nearer
    local_map.follow(10.0, 0.0)
    rig = PlannerRig(local_map, "independent")
    scheme = LeavesTheNearDoorToATeammate()
    scheme.attach(rig.scheme.s)
    rig.planner.scheme = scheme
    assert not rig.plan(5.0, 0.0, 1_000_000).done
    heading = rig.plan(5.0, 0.0, 2_000_000)
    assert heading.target is not None and abs(heading.target.x_m - 60.0) < 1.0


def test_a_hole_no_beam_reached_in_a_room_seen_all_round_is_no_frontier():
    """A speck of floor no beam reached (two cells in the middle of a room), in sight of a
    chink in the wall beyond which lies unknown ground: the rays from the speck count the
    unknown through the chink, but what lies behind the speck is the speck. It is no
    frontier; the doorway into the unknown beyond the other wall is."""
    local_map = LocalMap(P, 0.0, 0.0)
    _paint(local_map, -3.2, 3.2, -3.2, 3.2, WALL_LOGODDS)
    _paint(local_map, -3.0, 3.0, -3.0, 3.0, FREE_LOGODDS)
    _paint(local_map, -0.1, 0.1, 3.0, 3.2, FREE_LOGODDS)          # a chink 0.2 m wide in the north wall
    _paint(local_map, -0.05, 0.05, 2.3, 2.45, 0.0)                 # the speck, 0.7 m from the chink
    _paint(local_map, -0.5, 0.5, -3.2, -3.0, FREE_LOGODDS)        # a doorway in the south wall
    known = KnownMap(P, local_map)
    known.refresh(0.0, 0.0, 0)
    left = known.frontiers()
    assert len(left.reachable) == 1
    assert left.reachable[0].stand_xy[1] < -2.0


def _corridor_with_a_doorway(door_half_m: float) -> LocalMap:
    """A corridor 10 m long, closed at both ends, with a doorway in its north wall at x = 5 m
    opening on unknown ground."""
    local_map = LocalMap(P, 5.0, 0.0)
    _corridor(local_map, 0.0, 10.0)
    _paint(local_map, -0.2, 0.0, -1.3, 1.3, WALL_LOGODDS)
    _paint(local_map, 10.0, 10.2, -1.3, 1.3, WALL_LOGODDS)
    _paint(local_map, 5.0 - door_half_m, 5.0 + door_half_m, 1.0, 1.3, FREE_LOGODDS)
    return local_map


def _stop(rig: PlannerRig, x_m: float, y_m: float):
    """Plan once a second until the planner says there is nothing left: the robot gets to
    the end of each path by the next plan (the map does not change: it has seen all it can
    from there), and retries on tight paths whenever the planner asks for a recovery (as
    the agent does once one ends)."""
    for period in range(1, 60):
        now_us = period * 1_000_000
        plan = rig.plan(x_m, y_m, now_us)
        if plan.done:
            return rig.planner.frontiers
        if plan.recover:
            rig.targets.recovery_started()
            rig.planner.tight_until_us = now_us + int(P.recovery_retry_s * 1e6)
        elif len(plan.path_xy):
            x_m, y_m = plan.path_xy[-1]
    raise AssertionError("the planner never stopped")


def test_a_doorway_closed_only_by_obstacles_the_robot_felt_is_given_up_not_behind_a_gap():
    local_map = _corridor_with_a_doorway(0.4)
    for x_m in (4.7, 5.0, 5.3):                          # stalls in the doorway, heading north
        local_map.mark_obstacle_ahead(x_m, 0.8, math.pi / 2, 0.35)
    left = _stop(PlannerRig(local_map, scheme="independent"), 2.0, 0.0)
    assert len(left.given_up) == 1 and not left.behind_gaps
    assert abs(left.given_up[0].cell[1] * P.resolution_m - 5.0) < 0.6


def test_the_map_without_felt_obstacles_opens_what_only_they_closed():
    bumped = _corridor_with_a_doorway(0.4)
    for x_m in (4.7, 5.0, 5.3):
        bumped.mark_obstacle_ahead(x_m, 0.8, math.pi / 2, 0.35)
    narrow = _corridor_with_a_doorway(0.15)                # 0.3 m, and a niche beyond it
    _paint(narrow, 4.3, 5.7, 1.3, 2.0, WALL_LOGODDS)
    _paint(narrow, 4.5, 5.5, 1.3, 2.0, FREE_LOGODDS)
    narrow.mark_obstacle_ahead(8.0, 0.0, 0.0, 0.35)
    for local_map, open_unfelt in ((bumped, True), (narrow, False)):
        for felt in (True, False):
            known = KnownMap(P, local_map, felt=felt)
            known.refresh(2.0, 0.0, 0)
            found = known.frontiers()
            reached = bool(found.reachable) and not found.unreachable
            assert len(found.reachable) + len(found.unreachable) == 1
            assert reached == (open_unfelt and not felt), (open_unfelt, felt)




def test_the_whole_map_tells_which_places_the_body_is_cut_off_from():
    local_map = _corridor_with_a_deep_slot(slot_cells=3, niche=True)
    known = KnownMap(P, local_map)
    known.refresh(-3.0, 0.0, 0)
    points = [[2.0, 0.0], [0.1, 2.7], [0.1, 1.3], [3.0, 2.2], [500.0, 0.0]]
    # The corridor, the niche (behind the slot), the slot's mouth, a point inside the rock
    # beyond the corridor's wall (nowhere to stand near it), off the map.
    assert known.cut_off(np.array(points), 0.8).tolist() == [False, True, False, False, False]


@pytest.mark.parametrize("trail, given_up", [
    ([], False),
    ([(0.1, 2.7), (0.1, 1.7), (0.1, 0.7)], True),     # from the niche, through the slot
    ([(3.0, 2.2)], False),                            # a point the drifted map drew inside rock
])
def test_a_frontier_behind_a_narrow_gap_the_robot_has_driven_through_is_given_up(trail, given_up):
    # The robot's map shows the slot narrower than its body; alone, the niche's frontier is
    # behind a gap the body does not fit. Had the robot driven from the niche (its map since
    # drifted), that gap is not known to be narrow: it gave the frontier up. A trail point
    # with nowhere to stand near it is no such sign.
    local_map = _corridor_with_a_deep_slot(slot_cells=3, niche=True)
    for x_m, y_m in trail:
        local_map.mark_trail(x_m, y_m)
    local_map.mark_trail(-3.0, 0.0)
    left = _stop(PlannerRig(local_map, scheme="independent"), -3.0, 0.0)
    assert len(left.given_up) == (1 if given_up else 0)
    assert len(left.behind_gaps) == (0 if given_up else 1)


def test_a_way_closed_elsewhere_leaves_a_frontier_never_driven_to_behind_its_gap():
    # The robot drove into a closed pocket south of the corridor through a slot its map now
    # shows narrower than the body: its map has closed a way it took. The niche north of
    # the corridor is in no part of the map the robot drove: its frontier stays behind the
    # gap, not given up.
    local_map = _corridor_with_a_deep_slot(slot_cells=3, niche=True)
    _paint(local_map, -3.8, -2.2, -2.9, -1.0, WALL_LOGODDS)
    _paint(local_map, -3.6, -2.4, -2.7, -1.3, FREE_LOGODDS)
    _paint(local_map, -3.0, -2.8, -1.3, -1.0, FREE_LOGODDS)
    for x_m, y_m in ((-3.0, -2.0), (-3.0, 0.0)):
        local_map.mark_trail(x_m, y_m)
    known = KnownMap(P, local_map)
    known.refresh(-3.0, 0.0, 0)
    assert known.cut_off(local_map.trail(), P.escape_radius_m).tolist() == [True, False]
    left = _stop(PlannerRig(local_map, scheme="independent"), -3.0, 0.0)
    assert not left.given_up and len(left.behind_gaps) == 1


def test_a_robot_whose_map_closed_the_way_it_came_drives_back_across_it_before_stopping():
    # The robot came from the niche through the slot, which its map now shows narrower than
    # the body. Before it gives the niche's frontier up it drives back the way it came, on
    # a slow plan: to the last trail point it still reaches, then along the trail to the
    # first one cut off. One try per closure, for a bounded time; then it stops.
    local_map = _corridor_with_a_deep_slot(slot_cells=3, niche=True)
    for x_m, y_m in ((0.1, 2.7), (0.1, 1.7), (0.1, 0.7), (-3.0, 0.0)):
        local_map.mark_trail(x_m, y_m)
    rig = PlannerRig(local_map, scheme="independent")
    x_m, y_m = -3.0, 0.0
    for period in range(1, 60):                        # as _stop does, until a way back
        plan = rig.plan(x_m, y_m, period * 1_000_000)
        assert not plan.done
        if plan.recover:
            rig.targets.recovery_started()
            rig.planner.tight_until_us = period * 1_000_000 + int(P.recovery_retry_s * 1e6)
        elif plan.target is None and len(plan.path_xy):
            break
        elif len(plan.path_xy):
            x_m, y_m = plan.path_xy[-1]
    assert plan.slow and rig.planner.ways_back == 1
    assert np.allclose(plan.path_xy[-1], (0.1, 1.7))
    assert np.hypot(plan.path_xy[0, 0] - x_m, plan.path_xy[0, 1] - y_m) < 0.2
    assert np.max(np.hypot(*np.diff(plan.path_xy, axis=0).T)) <= P.resolution_m * 1.5
    late = rig.plan(x_m, y_m, 3_600_000_000)            # the try's time is up: it stops
    assert late.done and len(rig.planner.frontiers.given_up) == 1 and rig.planner.ways_back == 1


def test_the_trail_keeps_a_point_a_metre():
    local_map = LocalMap(P, 0.0, 0.0)
    for x_m in np.arange(0.0, 3.05, 0.1):
        local_map.mark_trail(float(x_m), 0.0)
    assert np.allclose(local_map.trail(), [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0]])


@pytest.mark.parametrize("passage_cost", [10.0, 0.0])
def test_an_ordinary_plan_takes_a_tight_passage_where_no_wider_way_goes(passage_cost):
    """Beyond a slot of 5 free cells lies a niche opening on unknown ground. With tight
    passages, once the robot stands at the slot's mouth, a waypoint in the niche is its
    next target and the plan drives through the slot, slowly where it is narrow; without,
    no ordinary plan leads there."""
    params = dataclasses.replace(P, tight_passage_cost=passage_cost)
    rig = PlannerRig(_corridor_with_a_deep_slot(slot_cells=5, niche=True, params=params), "independent",
                     params=params)
    first = rig.plan(0.0, 0.0, 1_000_000)
    assert first.target is not None and first.target.y_m < 1.0        # the slot's mouth, to look up it
    for now_us in (2_000_000, 3_000_000):
        plan = rig.plan(first.target.x_m, first.target.y_m, now_us)
    if passage_cost == 0.0:
        assert plan.target is None or plan.target.y_m < 1.0
        return
    assert not plan.recover and plan.target is not None and plan.target.y_m > 2.3
    assert plan.path_xy[-1, 1] > 2.3
    in_slot = (plan.path_xy[:, 1] > 1.1) & (plan.path_xy[:, 1] < 2.2)
    room_beside_body_m = plan.clearance_m[in_slot] - params.robot_radius_m
    assert in_slot.any() and (room_beside_body_m < 0.05).all()      # the follower slows down there



def corridor_past_a_sealed_room() -> LocalMap:
    """A robot that mapped a corridor from x = 0 to 70 m along y = 0 and, north of it at
    x = 60-64 m, a room it saw whole through a window but with no door (walls all round),
    and came back to x = 10 m: the room is paged out, 30 m beyond the window's edge."""
    local_map = LocalMap(P, 50.0, 0.0)
    _corridor(local_map, 30.0, 70.0)
    _paint(local_map, 70.0, 70.2, -1.3, 1.3, WALL_LOGODDS)          # the far end
    _paint(local_map, 59.7, 64.3, 2.7, 7.3, WALL_LOGODDS)           # the room's walls ...
    _paint(local_map, 60.0, 64.0, 3.0, 7.0, FREE_LOGODDS)           # ... round its floor
    assert local_map.follow(10.0, 0.0)
    _corridor(local_map, 0.0, 30.0)
    _paint(local_map, -0.2, 0.0, -1.3, 1.3, WALL_LOGODDS)           # the near end
    return local_map


def test_a_target_the_graph_leads_towards_but_not_to_keeps_its_strikes_between_tries():
    # The topological map's places run along the corridor to x = 60 m, past the window's
    # edge at 30 m. Beside the last of them the window reaches (x = 29.3 m) the graph leads
    # no further and nothing mapped reaches the room: the target is struck; 14 m back the
    # graph leads towards it again. Coming and going, the strikes add up and the target is
    # dropped, instead of being counted afresh at each return.
    rig = PlannerRig(corridor_past_a_sealed_room(), "independent")
    for x_m in range(5, 61):
        rig.topo.add((0, x_m * 100, 0, 0, 1, 0, 0))
    rig.waypoints.take_up(62.0, 5.0, 1.0)
    now_us = 0
    for x_m in [15.0, 29.3] * (2 * P.unreachable_strikes):
        now_us += 2_000_000
        plan = rig.plan(x_m, 0.0, now_us)
        if plan.recover:
            rig.targets.recovery_started()          # as the agent does, then backs off and turns
    assert rig.stat("targets_unreachable") == 1
