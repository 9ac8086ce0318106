"""Meier et al.'s coordination (eq. (1), Algorithm 1; meier.md A11-A14): teammates' targets
as their records say, the utility discount, and the choice it makes on a hand-built map."""
import numpy as np
import pytest

from firmware import kernels
from firmware.params import ExplorationParams
from firmware.schemes.meier.coordination import TeamTargets, coverage_probability, discount
from firmware.services.local_map import LocalMap
from firmware.services.targets import Candidate
from tests.doubles import PlannerRig, paint_box

P = ExplorationParams()
S = 1_000_000


def test_eq_1_is_the_chance_the_sensor_covers_a_cell_at_that_distance():
    assert coverage_probability([0.0, 5.0, 10.0, 12.0], 10.0).tolist() == [1.0, 0.5, 0.0, 0.0]


def test_a_teammates_newest_target_counts_until_released_or_expired():
    t = TeamTargets(expiry_s=90.0)
    t.heard(2, 1.0, 1.0, True, seq=5, now_us=0)
    t.heard(2, 9.0, 9.0, True, seq=4, now_us=1 * S)        # older, relayed late: ignored
    assert t.active(2 * S) == {2: (1.0, 1.0)}
    t.heard(2, 3.0, 3.0, True, seq=6, now_us=3 * S)
    assert t.active(4 * S) == {2: (3.0, 3.0)}
    t.heard(2, 3.0, 3.0, True, seq=6, now_us=80 * S)        # keep-alive
    assert t.active(160 * S) == {2: (3.0, 3.0)}
    assert t.active(171 * S) == {}                           # 90 s after the last word
    t.heard(2, 3.0, 3.0, False, seq=7, now_us=172 * S)      # released
    t.heard(2, 3.0, 3.0, True, seq=6, now_us=173 * S)       # the old claim again: stays released
    assert t.active(174 * S) == {}
    t.heard(2, 5.0, 5.0, True, seq=(7 + 100) % 128, now_us=175 * S)   # 100 ahead is behind (RFC 1982)
    assert t.active(176 * S) == {}
    t.heard(2, 5.0, 5.0, True, seq=(7 + 3) % 128, now_us=177 * S)
    assert t.active(178 * S) == {2: (5.0, 5.0)}


def _hall() -> LocalMap:
    """A hall x in [0, 20] m, y in [7, 13] m, seen free and walled, with two openings in its
    north wall onto unknown ground: x in [1.5, 3] m and x in [14.5, 16] m."""
    lm = LocalMap(P, 10.0, 10.0)
    lm.logodds[:] = 0.0
    paint_box(lm, 0.0, 20.0, 7.0, 13.0, P.logodds_min)
    paint_box(lm, -0.2, 20.2, 6.8, 6.9, P.logodds_max)
    paint_box(lm, -0.2, -0.1, 6.8, 13.2, P.logodds_max)
    paint_box(lm, 20.1, 20.2, 6.8, 13.2, P.logodds_max)
    for x0, x1 in ((-0.2, 1.4), (3.1, 14.4), (16.1, 20.2)):
        paint_box(lm, x0, x1, 13.1, 13.2, P.logodds_max)
    return lm


def test_a_wall_between_a_target_and_a_goal_spares_the_goal():
    lm = _hall()
    paint_box(lm, 9.9, 10.0, 7.0, 13.0, P.logodds_max)      # a wall across the hall at x = 10 m
    near, behind = Candidate(8.0, 10.0, 100.0, False), Candidate(12.0, 10.0, 100.0, False)
    discount([near, behind], [(7.0, 10.0)], lm, lm.layers().sight, 10.0, 0.1)
    assert near.penalty_m == pytest.approx((1.0 - 1.0 / 10.0) / 0.1)
    assert behind.penalty_m == 0.0


@pytest.mark.parametrize("me", [0, 1])
def test_a_robot_leaves_the_goal_a_teammate_of_lower_id_heads_for(me):
    """Alone, the robot takes goal A. When the other robot claims A, robot 1 takes another
    goal, away from A; robot 0 does not yield to robot 1's claim (priority by id, A11)."""
    alone = PlannerRig(_hall(), "meier", robot_id=me).plan(6.0, 10.0, now_us=S).target
    rig = PlannerRig(_hall(), "meier", robot_id=me)
    rig.scheme.on_record("target", {"sender_id": 1 - me, "x_cm": round(alone.x_m * 100),
                                    "y_cm": round(alone.y_m * 100), "claimed": 1, "target_seq": 1}, 0)
    claimed = rig.plan(6.0, 10.0, now_us=S).target
    if me == 0:
        assert (claimed.x_m, claimed.y_m) == (alone.x_m, alone.y_m)
    else:
        assert np.hypot(claimed.x_m - alone.x_m, claimed.y_m - alone.y_m) > 3.0


def _closed_room_with_a_door() -> LocalMap:
    """A room x, y in [5, 15] m, seen free and walled, with a door in its east wall at
    y in [9.2, 10.8] m; beyond the door this robot saw nothing."""
    lm = LocalMap(P, 10.0, 10.0)
    lm.logodds[:] = 0.0
    paint_box(lm, 5.0, 15.0, 5.0, 15.0, P.logodds_min)
    paint_box(lm, 4.8, 15.2, 4.8, 4.9, P.logodds_max)
    paint_box(lm, 4.8, 15.2, 15.1, 15.2, P.logodds_max)
    paint_box(lm, 4.8, 4.9, 4.8, 15.2, P.logodds_max)
    paint_box(lm, 15.1, 15.2, 4.8, 9.1, P.logodds_max)
    paint_box(lm, 15.1, 15.2, 10.9, 15.2, P.logodds_max)
    return lm


def test_a_frontier_only_a_teammates_polygons_show_beyond_the_window_is_in_the_whole_map():
    """A teammate mapped a corridor from the door to x = 70 m, open at its far end (40 m
    beyond this robot's window): the whole map a robot looks over before it stops holds it,
    and the frontier at its end is one the robot can reach."""
    from firmware.schemes.meier.polygons import PolygonMap
    from firmware.schemes.meier.records import poly_values
    from firmware.services.known_map import KnownMap

    rig = PlannerRig(_closed_room_with_a_door(), "meier", robot_id=1)
    paint_box(rig.local_map, 15.1, 15.2, 9.2, 10.8, P.logodds_min)     # the door, seen free
    corridor = PolygonMap(sender_id=0)
    # Lattice of 0.2 m: x 15.2 .. 70 m, y 9 .. 11 m; walls along both sides, open at the far end.
    corridor.new_ring([(76, 45, 1), (350, 45, 0), (350, 55, 1), (76, 55, 0)])
    for r in corridor.flush():
        rig.scheme.on_record(*poly_values(r), 0)
    state, row0, col0 = rig.local_map.whole_state()
    assert state[100 - row0, 500 - col0] == kernels.FREE                 # (50, 10) m: the teammate saw it
    known = KnownMap(P, rig.local_map)
    known.refresh(10.0, 10.0, 0, force=True)
    assert any(f.stand_xy[0] > 65.0 for f in known.frontiers().reachable)
