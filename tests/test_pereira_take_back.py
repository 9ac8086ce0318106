"""Pereira's planning stage (Pereira.filter_waypoints): waypoints in a region a teammate
claimed explored are left to it if a teammate's place came within d_cam_m of them (else
kept, ranked last); waypoints the teammates' places saw are dropped; a robot
with nothing else left heads for a region a teammate heads for (transit), and with
pereira_take_back (or, once no teammate explores, pereira_take_back_alone) takes back what
is still unseen from every teammate's place.

The map: a corridor y in [19, 21] m from x = 5 to 35 m, walls along both sides, unknown
beyond x = 35 m (the open end). Teammate 1 drove the corridor's west part and claims its
region explored; this robot (0) has a rich waypoint at the open end."""
import dataclasses
import math

import numpy as np

from firmware.params import ExplorationParams
from firmware.schemes.base import PlanningView
from firmware.schemes.pereira.records import DIR_CODES, INTENT_STATES, Claim, Gate, Intent, Place, values_of
from firmware.services.local_map import LocalMap
from firmware.services.targets import Candidate
from firmware.services.waypoints import Waypoint
from hal.samples import OdometrySample
from host_tools.mission import MissionConfig, run_mission
from tests.doubles import PlannerRig
from tests.doubles import paint_box as paint

P = ExplorationParams()
# The take-back's tests: a claim on the west region leaves even what no teammate came near.
CLAIMS_COVER_ALL = dataclasses.replace(P, pereira_claims_near_only=False)
ME, OTHER = 0, 1
NOW_US = 1_000_000
AT_THE_END = (34.0, 20.0)                 # a waypoint at the corridor's open end
FAR_AWAY = (20.0, 35.0)                   # a waypoint no place labels: in no region


def _rig(teammate_places_x_m: list[float], teammate_active: bool, gate_at_x_m: float | None = None,
         own_places_x_m: tuple[float, ...] = (), params: ExplorationParams = P,
         heading_for_x_m: float | None = None, claim: bool = True) -> PlannerRig:
    """Teammate 1's places along the corridor (y = 20 m), and (with claim) its claim on the
    region of the westmost one; with a gate across the corridor at gate_at_x_m, the places east of it are
    a second region, which no one claims. With heading_for_x_m, teammate 1's intent: it
    explores, its goal on the corridor there."""
    local_map = LocalMap(params, 20.0, 20.0)
    local_map.logodds[:] = 0.0
    paint(local_map, 5.0, 35.0, 19.0, 21.0, params.logodds_min)      # corridor floor, seen free
    paint(local_map, 5.0, 35.0, 18.8, 18.9, params.logodds_max)      # south wall
    paint(local_map, 5.0, 35.0, 21.1, 21.2, params.logodds_max)      # north wall
    rig = PlannerRig(local_map, "pereira", ME, params)
    for k, x in enumerate(teammate_places_x_m):
        rig.scheme.on_record("place", values_of(Place(OTHER, k + 1, round(x * 10), 200, 8, 1 if k else 0)), NOW_US)
    for k, x in enumerate(own_places_x_m):      # as if it had driven there (its records go to its store)
        rig.scheme.store.add(Place(ME, k + 1, round(x * 10), 200, 8, 1 if k else 0))
    oseq = len(teammate_places_x_m) + 1
    if gate_at_x_m is not None:
        across_the_corridor = DIR_CODES // 2
        gate = Gate(OTHER, oseq, round(gate_at_x_m * 10), 200, across_the_corridor, 50)
        rig.scheme.on_record("gate", values_of(gate), NOW_US)
        oseq += 1
    graph = rig.scheme.store.graph()
    assert len(graph.regions) == (1 if gate_at_x_m is None else 2)
    west = graph.regions[int(graph.region_of_place[0])]       # places sort by x: the first is the westmost
    if claim:
        rig.scheme.on_record("claim", values_of(Claim(OTHER, oseq, west.anchor_x_dm, west.anchor_y_dm,
                                                      west.signature, 1, 0)), NOW_US)
    if teammate_active:
        rig.roster.heard_at(OTHER, 10.0, 20.0, NOW_US)
    if heading_for_x_m is not None:
        exploring = INTENT_STATES.index("exploring")
        goal_dm = round(heading_for_x_m * 10)
        intent = Intent(OTHER, goal_dm - 10, 200, goal_dm, 200, 10, exploring, 0, 1)
        rig.scheme.on_record("intent", values_of(intent), NOW_US)
    return rig


def _filter(rig: PlannerRig, *waypoints: tuple[float, ...]) -> list[tuple[float, float]]:
    """The waypoints (x, y[, e_bit]; rich if no e_bit) the scheme keeps, the robot at (20, 20)."""
    rig.waypoints.items = [Waypoint(w[0], w[1], w[2] if len(w) > 2 else 2.0 * P.pereira_revive_min_bit)
                           for w in waypoints]
    view = PlanningView(20.0, 20.0, NOW_US, rig.local_map.layers().sight, None, frozenset(),
                        lambda cands: np.full(len(cands), math.inf))
    rig.scheme.filter_waypoints(view)
    return [(w.x_m, w.y_m) for w in rig.waypoints.items]


TAKING_BACK = dataclasses.replace(CLAIMS_COVER_ALL, pereira_take_back=True)


def test_a_robot_with_nothing_else_takes_back_what_no_teammate_could_have_seen():
    rig = _rig([6.0, 7.0, 8.0, 9.0, 10.0], teammate_active=True, params=TAKING_BACK)
    assert _filter(rig, AT_THE_END) == [AT_THE_END]
    assert rig.stat("waypoints_taken_back") == 1


def test_no_take_back_by_default():
    rig = _rig([6.0, 7.0, 8.0, 9.0, 10.0], teammate_active=True, params=CLAIMS_COVER_ALL)
    assert _filter(rig, AT_THE_END) == []
    assert rig.stat("waypoints_taken_back") == 0 and rig.stat("waypoints_left_to_team") == 1


def test_with_pereira_take_back_alone_the_last_robot_exploring_takes_back_what_no_teammate_saw():
    """No teammate explores any more: whatever this robot leaves to a claim stays unseen."""
    rig = _rig([6.0, 7.0, 8.0, 9.0, 10.0], teammate_active=False,
               params=dataclasses.replace(CLAIMS_COVER_ALL, pereira_take_back_alone=True))
    assert _filter(rig, AT_THE_END) == [AT_THE_END]
    assert rig.stat("waypoints_taken_back") == 1
    rig = _rig([6.0, 7.0, 8.0, 9.0, 10.0], teammate_active=False, params=CLAIMS_COVER_ALL)
    assert _filter(rig, AT_THE_END) == []
    assert rig.stat("waypoints_left_to_team") == 1


def test_beyond_the_window_the_last_robot_takes_back_only_what_no_teammate_stood_within_half_its_reach_of():
    """Beyond the window there is no map to cast the teammates' view in: a place within
    d_cam_m / 2 of the waypoint counts as having seen it; one farther off does not."""
    params = dataclasses.replace(CLAIMS_COVER_ALL, pereira_take_back_alone=True)
    beyond = (60.0, 20.0)                       # the window spans 0 to 40 m
    for place_x_m, kept in ((60.0 - P.d_cam_m / 2 + 0.5, []), (60.0 - P.d_cam_m / 2 - 0.5, [beyond])):
        rig = _rig([6.0, 7.0, 8.0, 9.0, 10.0, place_x_m], teammate_active=False, params=params)
        assert _filter(rig, beyond) == kept
        assert rig.stat("waypoints_taken_back") == len(kept) and rig.stat("waypoints_left_to_team") == 1 - len(kept)


def test_a_claim_leaves_to_the_team_only_what_a_teammates_place_came_within_d_cam_of():
    """Teammate 1 claimed the west region from places at x 6-10 m. This robot's map carries
    the region on to the open end (no gate between): the waypoint there, 24 m from every
    teammate's place, is kept; one 2 m from them is left to the claim."""
    near_the_places = (12.0, 20.0)
    rig = _rig([6.0, 7.0, 8.0, 9.0, 10.0], teammate_active=True)
    assert _filter(rig, AT_THE_END, near_the_places) == [AT_THE_END]
    assert rig.stat("claimed_waypoints_kept") == 1 and rig.stat("waypoints_left_to_team") == 1
    just_within = (10.0 + P.d_cam_m - 0.2, 20.0)
    just_beyond = (10.0 + P.d_cam_m + 0.2, 20.0)
    assert _filter(_rig([6.0, 7.0, 8.0, 9.0, 10.0], teammate_active=True), just_within, just_beyond) == [just_beyond]
    rig = _rig([6.0, 7.0, 8.0, 9.0, 10.0], teammate_active=True, params=CLAIMS_COVER_ALL)
    assert _filter(rig, AT_THE_END, near_the_places) == []
    assert rig.stat("claimed_waypoints_kept") == 0 and rig.stat("waypoints_left_to_team") == 2


def test_claimed_waypoints_no_teammate_came_near_are_ranked_after_every_other():
    """Kept against the claim, the waypoint at the open end comes last: the robot goes there
    once nothing else is left (by when a teammate may have come near it)."""
    for last in (True, False):
        rig = _rig([6.0, 7.0, 8.0, 9.0, 10.0], teammate_active=True,
                   params=dataclasses.replace(P, pereira_unseen_claimed_last=last))
        _filter(rig, AT_THE_END, FAR_AWAY)
        view = PlanningView(20.0, 20.0, NOW_US, rig.local_map.layers().sight, None, frozenset(),
                            lambda cands: np.full(len(cands), math.inf))
        ranked = rig.scheme.rank(view, [Candidate(x, y, 2.0 * P.pereira_revive_min_bit, False)
                                        for x, y in (AT_THE_END, FAR_AWAY)])
        at_the_end, far_away = (c.rank for c in ranked)
        assert (at_the_end > far_away) == last


def test_while_it_has_its_own_waypoints_it_leaves_the_claimed_region_to_the_team():
    rig = _rig([6.0, 7.0, 8.0, 9.0, 10.0], teammate_active=True, params=TAKING_BACK)
    assert _filter(rig, AT_THE_END, FAR_AWAY) == [FAR_AWAY]
    assert rig.stat("waypoints_left_to_team") == 1 and rig.stat("waypoints_taken_back") == 0


def test_what_a_teammates_place_had_in_view_stays_left_to_it():
    """A place 4 m on, out in what this robot has not seen (beyond revive_clear_m of the
    waypoint): its LiDAR saw nearly all the waypoint promises."""
    rig = _rig([6.0, 7.0, 8.0, 9.0, 10.0, 38.0], teammate_active=True, params=TAKING_BACK)
    assert _filter(rig, AT_THE_END) == []
    rig = _rig([6.0, 7.0, 8.0, 9.0, 10.0, 38.0], teammate_active=False, params=TAKING_BACK)
    assert _filter(rig, AT_THE_END) == []


ALONG_THE_CORRIDOR = [float(x) for x in range(6, 45)]    # teammate 1 drove on past the open end
GATE_X_M = 35.5
EAST_GOAL_X_M = 44.0                                     # where teammate 1 is heading: east of the gate


def test_waypoints_teammates_places_saw_are_dropped_claimed_or_not():
    """No claim at all: teammate 1 drove the whole corridor, so what the waypoint at its end
    promises was seen from its places; the waypoint no place is near stays."""
    for team_view, kept in ((True, [FAR_AWAY]), (False, [AT_THE_END, FAR_AWAY])):
        rig = _rig(ALONG_THE_CORRIDOR, teammate_active=True, claim=False,
                   params=dataclasses.replace(P, pereira_team_view=team_view))
        assert _filter(rig, AT_THE_END, FAR_AWAY) == kept
        assert rig.stat("waypoints_seen_by_team") == (1 if team_view else 0)


DROVE_TO_34_M = [float(x) for x in range(6, 35)]


def _corridor_rig(params: ExplorationParams, walls: list[tuple[float, float, float, float]]) -> PlannerRig:
    """The corridor's floor and south wall, the given walls (x0, x1, y0, y1 in m), and
    teammate 1's places along it to x = 34 m; teammate 1 active."""
    local_map = LocalMap(params, 20.0, 20.0)
    local_map.logodds[:] = 0.0
    paint(local_map, 5.0, 35.0, 19.0, 21.0, params.logodds_min)
    paint(local_map, 5.0, 35.0, 18.8, 18.9, params.logodds_max)
    for x0, x1, y0, y1 in walls:
        paint(local_map, x0, x1, y0, y1, params.logodds_max)
    rig = PlannerRig(local_map, "pereira", ME, params)
    for k, x in enumerate(DROVE_TO_34_M):
        rig.scheme.on_record("place", values_of(Place(OTHER, k + 1, round(x * 10), 200, 8, 1 if k else 0)), NOW_US)
    rig.roster.heard_at(OTHER, 30.0, 20.0, NOW_US)
    return rig


def test_a_teammates_places_do_not_see_past_a_gate():
    """A room north of the corridor (x 14 to 18 m, unknown to this robot), its door at x 15.5
    to 16.5 m with a gate across it. Teammate 1 drove the corridor. The waypoint at the door
    promises the room (12.7 kbit): the teammate's view stops at the gate, so it is kept;
    without that, rays from the corridor pass through the unknown room, 3.6 kbit are left and
    it is dropped (up to 5 kbit counts as seen here: a one-metre door shows little of a
    room to a corridor)."""
    at_the_door = (16.0, 20.6)
    for gates_block, kept in ((True, [at_the_door]), (False, [])):
        params = dataclasses.replace(P, pereira_team_view=True, pereira_gates_block_view=gates_block,
                                     pereira_revive_left_bit=5000.0)
        north_wall_with_a_door = [(5.0, 15.5, 21.1, 21.2), (16.5, 35.0, 21.1, 21.2)]
        rig = _corridor_rig(params, north_wall_with_a_door)
        along_x = 0
        rig.scheme.on_record("gate", values_of(Gate(OTHER, len(DROVE_TO_34_M) + 1, 160, 212, along_x, 25)), NOW_US)
        assert _filter(rig, at_the_door) == kept
        assert rig.stat("waypoints_seen_by_team") == 1 - len(kept)


def test_a_robot_with_nothing_else_left_heads_for_a_region_a_teammate_still_explores():
    """Everything this robot holds lies in the claimed west region, where the teammate stood
    near enough to have seen it all (nothing to take back). East of the gate, past the open
    end, lies a region no one claims: of its waypoints the robot keeps the one on the way
    there, and maps its way in instead of stopping."""
    rig = _rig(ALONG_THE_CORRIDOR, teammate_active=True, gate_at_x_m=GATE_X_M, heading_for_x_m=EAST_GOAL_X_M)
    assert _filter(rig, (7.0, 20.0), AT_THE_END) == [AT_THE_END]
    assert rig.stat("transit_choices") == 1 and rig.stat("waypoints_taken_back") == 0


def test_a_pocket_too_far_to_head_for_is_not_something_else_left():
    rig = _rig(ALONG_THE_CORRIDOR, teammate_active=True, gate_at_x_m=GATE_X_M, heading_for_x_m=EAST_GOAL_X_M)
    pocket_far_away = (*FAR_AWAY, P.report_unreachable_bit / 2)
    assert _filter(rig, (7.0, 20.0), AT_THE_END, pocket_far_away) == [AT_THE_END, FAR_AWAY]
    assert rig.stat("transit_choices") == 1


def test_no_transit_where_no_teammate_heads_where_the_robot_has_been_when_alone_or_switched_off():
    heading = dict(gate_at_x_m=GATE_X_M, heading_for_x_m=EAST_GOAL_X_M)
    no_one_heads_east = _rig(ALONG_THE_CORRIDOR, teammate_active=True, gate_at_x_m=GATE_X_M)
    heads_west = _rig(ALONG_THE_CORRIDOR, teammate_active=True, gate_at_x_m=GATE_X_M, heading_for_x_m=8.0)
    near_my_places = _rig(ALONG_THE_CORRIDOR, teammate_active=True, own_places_x_m=(37.0, 39.0, 41.0, 43.0),
                          **heading)
    alone = _rig(ALONG_THE_CORRIDOR, teammate_active=False, gate_at_x_m=GATE_X_M)   # (an intent is news of it)
    off = _rig(ALONG_THE_CORRIDOR, teammate_active=True, params=dataclasses.replace(P, pereira_transit=False),
               **heading)
    all_claimed = _rig(ALONG_THE_CORRIDOR, teammate_active=True, heading_for_x_m=EAST_GOAL_X_M)
    for rig in (no_one_heads_east, heads_west, near_my_places, alone, off, all_claimed):
        assert _filter(rig, (7.0, 20.0), AT_THE_END) == []
        assert rig.stat("transit_choices") == 0


def _claims_after_two_cycles(east_end_walled: bool) -> PlannerRig:
    """Teammate 1 drove the corridor to x = 34 m and claimed nothing; this robot plans twice
    at (20, 20) (a region is explored for it after pereira_explored_cycles clean cycles).
    Every waypoint near a teammate's place counts as seen by the team here (what the view
    leaves unseen is another test's): this one is about the claim that follows."""
    params = dataclasses.replace(P, pereira_team_view=True, pereira_revive_left_bit=1e9)
    walls = [(5.0, 35.0, 21.1, 21.2), (4.8, 4.9, 18.8, 21.2)] + ([(35.1, 35.2, 18.8, 21.2)] if east_end_walled else [])
    rig = _corridor_rig(params, walls)
    for cycle in range(P.pereira_explored_cycles):
        now_us = NOW_US + cycle * 1_000_000
        rig.plan(20.0, 20.0, now_us)
        rig.scheme.after_plan(OdometrySample(now_us, 20.0, 20.0, 0.0, 0.0, 0.0), now_us)
    return rig


def test_a_robot_claims_no_region_where_it_dropped_waypoints_on_the_teammates_view():
    """The open east end's waypoints are dropped: the teammate's places saw what they promise,
    by the model (its rays pass through the unknown this robot's map shows there). That is
    not this robot's judgement, so no claim; with the end walled off there is nothing to
    drop and the corridor is claimed."""
    open_end = _claims_after_two_cycles(east_end_walled=False)
    assert open_end.stat("waypoints_seen_by_team") > 0 and open_end.stat("claims_sent") == 0
    walled = _claims_after_two_cycles(east_end_walled=True)
    assert walled.stat("waypoints_seen_by_team") == 0 and walled.stat("claims_sent") == 1


def _claims_on_stopping(places_x_m: list[float], frontiers_left_xy: list[tuple[float, float]]) -> int:
    """Teammate 1 drove the corridor and claimed nothing; this robot stops."""
    local_map = LocalMap(P, 20.0, 20.0)
    local_map.logodds[:] = 0.0
    paint(local_map, 5.0, 35.0, 19.0, 21.0, P.logodds_min)
    rig = PlannerRig(local_map, "pereira", ME, P)
    for k, x in enumerate(places_x_m):
        rig.scheme.on_record("place", values_of(Place(OTHER, k + 1, round(x * 10), 200, 8, 1 if k else 0)), NOW_US)
    rig.scheme.on_finished(np.array(frontiers_left_xy, np.float64).reshape(-1, 2))
    return rig.stat("claims_on_stopping")


def test_a_robot_that_stops_claims_every_region_it_has_mapped_whole():
    assert _claims_on_stopping([6.0, 7.0, 8.0, 9.0, 10.0], []) == 1
    # A place in what this robot never mapped: the region may go on where it did not look.
    assert _claims_on_stopping([6.0, 7.0, 8.0, 9.0, 10.0, 38.0], []) == 0
    # A frontier it leaves there (given up, or behind a gap): not explored for it.
    assert _claims_on_stopping([6.0, 7.0, 8.0, 9.0, 10.0], [(14.0, 20.0)]) == 0


def test_two_robots_cover_the_eight_region_map_and_stop():
    """The paper's eight-region map, two robots, seed 2, where the end-game rules meet: one
    robot can run out of waypoints early, its regions claimed by the other (so it was on
    d42aaba), and judging take-backs by the frontier a teammate had in view left both
    robots stopped at 0.70 coverage. The team must cover the map and stop by itself."""
    r = run_mission(MissionConfig(map_spec="tests/data/pereira8.yaml", robots=2, seed=2, strategy="pereira",
                                  max_sim_s=600))
    assert r.coverage >= 0.99 and r.termination.startswith("complete")
