"""Shared services on their own: the pose history's pose_at, and the roster's aging."""
import math

import pytest

import numpy as np

from firmware.params import ExplorationParams
from firmware.services.local_map import BinnedScan
from firmware.services.pose import PoseService, TravelMilestones
from firmware.services.recovery import Recovery, Retrace, Track, clear_behind
from firmware.services.roster import Roster
from hal.samples import SHARED_FRAME, OdometrySample


class ScriptedOdometry:
    """Returns the samples it is given, one per read."""

    def __init__(self, samples):
        self.samples = list(samples)

    def read(self):
        return self.samples.pop(0)


def _sample(t_us, x, y, yaw, frame=SHARED_FRAME):
    return OdometrySample(t_us, x, y, yaw, 0.0, 0.0, frame)


def test_pose_at_interpolates_between_samples_and_turns_the_short_way():
    pose = PoseService(ScriptedOdometry([_sample(0, 0.0, 0.0, math.radians(170)),
                                         _sample(100_000, 1.0, 2.0, math.radians(-170))]))
    assert pose.frame_id is None and pose.pose_at(0) is None
    pose.read()
    pose.read()
    x, y, yaw = pose.pose_at(50_000)
    assert (x, y) == pytest.approx((0.5, 1.0))
    assert math.degrees(yaw) == pytest.approx(180.0) or math.degrees(yaw) == pytest.approx(-180.0)
    assert pose.pose_at(-5) == (0.0, 0.0, math.radians(170))           # before the history: its oldest
    assert pose.pose_at(10**9) == (1.0, 2.0, math.radians(-170))       # after it: the newest
    assert pose.frame_id == SHARED_FRAME


def test_the_pose_history_is_bounded_and_keeps_the_newest():
    pose = PoseService(ScriptedOdometry([_sample(t, float(t), 0.0, 0.0, "robot3") for t in range(10)]), history=4)
    for _ in range(10):
        pose.read()
    assert pose.pose_at(0)[0] == 6.0 and pose.pose_at(9)[0] == 9.0 and pose.frame_id == "robot3"


def test_travel_milestones_come_every_so_many_metres():
    m = TravelMilestones(1.0)
    assert m.due(0.0, 0.0)
    m.mark(0.0, 0.0)
    assert not m.due(0.6, 0.6) and m.due(0.8, 0.8)


def test_the_roster_ages_silent_teammates_out_and_a_done_stays_done():
    roster = Roster(robot_id=0, max_age_us=30_000_000)
    roster.heard_at(0, 1.0, 1.0, 0)                       # itself: never on its own roster
    roster.heard_at(1, 2.0, 0.0, 0)
    roster.heard_status(2, 5.0, 0.0, done=False, now_us=10_000_000)
    assert roster.active(20_000_000) == {1: (2.0, 0.0), 2: (5.0, 0.0)}
    assert roster.active(35_000_000) == {2: (5.0, 0.0)}, "robot 1 silent for longer than 30 s"
    roster.heard_status(2, 5.0, 0.0, done=True, now_us=36_000_000)
    roster.heard_at(2, 6.0, 0.0, 37_000_000)             # a late record of its travel: still done
    assert not roster.any_active(37_000_000)
    assert roster.members()[2].done and set(roster.members()) == {1, 2}


# --- recovery ---------------------------------------------------------------------------

def _drive(recovery: Recovery, pose, dt_s: float = 0.05, limit_s: float = 60.0):
    """Integrate the recovery's commands on a free body; (commands, final pose, time)."""
    x, y, yaw = pose
    t_us, commands = 0, []
    while t_us < limit_s * 1e6:
        cmd = recovery.command(x, y, yaw, t_us)
        if cmd is None:
            return commands, (x, y, yaw), t_us
        commands.append(cmd)
        v, w = cmd
        x, y, yaw = x + v * dt_s * math.cos(yaw), y + v * dt_s * math.sin(yaw), yaw + w * dt_s
        t_us += int(dt_s * 1e6)
    raise AssertionError("the recovery never ended")


def test_a_recovery_backs_off_its_distance_then_turns_once_around():
    p = ExplorationParams()
    r = Recovery(p, max_v_mps=0.5, max_omega_radps=1.0)
    r.start(room_behind=True)
    commands, (x, y, yaw), _ = _drive(r, (1.0, 2.0, 0.0))
    assert x == pytest.approx(1.0 - p.recovery_back_off_m, abs=p.min_speed_mps * 0.05 + 1e-9) and y == 2.0
    assert all(v <= 0 for v, _ in commands) and yaw == pytest.approx(2 * math.pi, abs=p.recovery_turn_radps * 0.05)
    assert r.counts == {"recoveries": 1, "recovery_back_offs": 1, "recovery_rotates": 1} and not r.active


def test_a_recovery_without_room_behind_only_turns_and_a_body_that_cannot_move_ends_at_the_deadlines():
    p = ExplorationParams()
    r = Recovery(p, max_v_mps=0.5, max_omega_radps=1.0)
    r.start(room_behind=False)
    commands, _, _ = _drive(r, (0.0, 0.0, 0.0))
    assert all(v == 0.0 and w > 0 for v, w in commands) and r.counts["recovery_back_offs"] == 0
    r.start(room_behind=True)
    t_us, ended = 0, None
    while ended is None:                      # the pose never changes: stuck wheels
        ended = t_us if r.command(0.0, 0.0, 0.0, t_us) is None else None
        t_us += 50_000
    back_s, turn_s = p.recovery_back_off_m / p.min_speed_mps, 2 * math.pi / p.recovery_turn_radps
    assert ended / 1e6 == pytest.approx(2 * back_s + 1 + 2 * turn_s + 1, abs=0.1)


def test_room_behind_is_read_from_the_scan_strip_the_body_would_sweep():
    ranges = np.full(360, 5.0)
    scan = BinnedScan(0.0, 0.0, 0.0, ranges, 10.0)          # bin k looks at k degrees
    assert clear_behind(scan, 0.0, 0.3, 0.27)
    ranges[180] = 0.4                                        # something right behind
    assert not clear_behind(BinnedScan(0.0, 0.0, 0.0, ranges, 10.0), 0.0, 0.3, 0.27)
    assert clear_behind(BinnedScan(0.0, 0.0, 0.0, ranges, 10.0), math.pi, 0.3, 0.27)   # ahead when facing back
    ranges[180], ranges[90] = 5.0, 0.4                       # a wall beside the body, not behind it
    assert clear_behind(BinnedScan(0.0, 0.0, 0.0, ranges, 10.0), 0.0, 0.3, 0.27)


def test_a_track_keeps_its_last_stretch_and_hands_the_way_back_over_nearest_first():
    track = Track(keep_m=0.3)
    for k in range(21):                               # 1.2 m along x, a point every 6 cm
        track.add(0.06 * k, 0.0)
    track.add(1.14, 0.0)                              # backed off to the point before: no new point
    track.add(1.16, 0.0)                              # less than a spacing on: none either
    way = track.take_way_back(0.2)
    assert way[:, 0] == pytest.approx([1.08, 1.02, 0.96, 0.90]) and not way[:, 1].any()
    rest = track.take_way_back(1.0)                   # the track ends where the way back did
    assert rest[:, 0] == pytest.approx([0.84]) and not len(track.take_way_back(1.0))


def _in_a_wedge():
    """A 3 x 3 m floor at 1 cm cells with a slot that narrows from 0.56 to 0.505 m between
    x = 1.5 and 2.1 m, and a disc body of 0.25 m driven along it from x = 1 until a wall
    holds it: the world's ClearanceMap, the body's track and where it was held."""
    from world_sim.kinematics import ClearanceMap, advance
    from world_sim.occupancy_map import OccupancyMap
    res, n = 0.01, 300
    free = np.ones((n, n), dtype=bool)
    free[0, :] = free[-1, :] = free[:, 0] = free[:, -1] = False
    xs = (np.arange(n) + 0.5) * res
    for c in range(150, 210):
        half = 0.28 - (0.28 - 0.2525) * (xs[c] - 1.5) / 0.6
        free[(np.abs(xs - 1.5) > half), c] = False    # the slot is centred on y = 1.5
    world = ClearanceMap.from_map(OccupancyMap(free=free, resolution_m=res, origin_x_m=0.0, origin_y_m=0.0, name="wedge"))
    args = (world.wall_u8, world.cell_clearance_lb_m, 0.0, 0.0, res, 0.25, 0.01)
    track = Track(keep_m=0.5)
    x, y, yaw = 1.0, 1.5, 0.005                      # a little askew, as a drifted pose drives
    for _ in range(400):
        track.add(x, y)
        x, y, yaw, _, held = advance(*args, x, y, yaw, 0.3, 0.0, 0.05)
        if held:
            return args, track, (x, y, yaw)
    raise AssertionError("the body never got held")


def test_a_body_wedged_in_a_slot_backs_out_along_its_track_where_straight_back_is_blocked():
    from world_sim.kinematics import advance
    args, track, (x, y, yaw) = _in_a_wedge()
    assert x > 1.7
    yaw += 1.2                                       # a recovery turned it on the spot
    _, _, _, _, held = advance(*args, x, y, yaw, -0.1, 0.0, 0.5)
    assert held                                      # reversing straight back on its new heading rubs a side
    retrace = Retrace(speed_mps=0.1, max_omega_radps=1.0)
    retrace.start(track.take_way_back(0.5), x, y, yaw, 0)
    t_us, x0 = 0, x
    while (cmd := retrace.command(x, y, yaw, t_us)) is not None:
        x, y, yaw, _, held = advance(*args, x, y, yaw, cmd[0], cmd[1], 0.05)
        assert not held
        t_us += 50_000
    assert x0 - x >= 0.45 and abs(y - 1.5) < 0.05 and t_us < 20e6
