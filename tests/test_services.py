"""Shared services on their own: the pose history's pose_at, and the roster's aging."""
import math

import pytest

from firmware.services.pose import PoseService, TravelMilestones
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
