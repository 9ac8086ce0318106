"""The firmware against a scripted HAL: it terminates in a closed room, and a robot whose
wheels do not move backs off, marks what blocks it (unless its LiDAR shows it), drops its
targets for good, and still terminates."""
import dataclasses
import math

import numpy as np
import pytest

from firmware.agent import STALLS_BEFORE_CLOSING_A_GAP, ExplorerAgent
from firmware.params import ExplorationParams
from firmware.services.local_map import LocalMap
from firmware.services.recovery import step_time_us
from firmware.services.waypoints import Waypoint
from hal.bundle import Hal
from hal.lora import profile
from hal.samples import OdometrySample
from tests.doubles import ScriptedHal, StepClock

P = ExplorationParams()


def run(fake: ScriptedHal, seconds: float, scheme: str = "independent") -> ExplorerAgent:
    agent = ExplorerAgent(fake.hal(), scheme=scheme)
    agent.setup()
    return fake.run(agent, seconds)


def bayer_faigl_robot(fake: ScriptedHal) -> ExplorerAgent:
    """A Bayer & Faigl robot whose radio sends nothing and hears nothing."""
    agent = ExplorerAgent(fake.hal(), scheme="bayer-faigl:greedy", radio_profile=profile("ideal-100Bps"))
    agent.setup()
    return agent


def test_a_closed_room_seen_whole_is_done_at_once():
    agent = run(ScriptedHal(np.full(360, 3.0)), 30)
    assert agent.done and agent.status == "complete"
    assert agent.waypoints.items == []
    assert agent.hal.drive.commands[-1] == (0.0, 0.0)


def test_a_robot_that_cannot_move_marks_the_obstacle_drops_targets_and_stops():
    ranges = np.full(360, 3.0)
    ranges[150:210] = 10.0          # an opening straight ahead: a corridor leading away
    agent = run(ScriptedHal(ranges), 3000)
    assert agent.bumps >= 1
    stats = agent.stats()
    given_up = stats["targets_stalled"] + stats["targets_unreachable"]
    assert given_up >= 1
    # Each target got its recovery (back off, turn, retry) before it was given up; a body that
    # cannot move finishes neither step, and each ends at its deadline.
    assert stats["recoveries"] == stats["recovery_rotates"] >= given_up
    assert agent.done, "targets that cannot be reached must be dropped for good, not retried forever"


def test_a_stall_against_something_the_lidar_shows_marks_no_bump_and_follows_closely():
    ranges = np.full(360, 3.0)
    ranges[150:210] = 10.0          # the corridor leading away, straight ahead (beam 180)
    ranges[255:265] = 0.3           # and a post touching the body on its left, a little ahead
    fake = ScriptedHal(ranges)
    agent = ExplorerAgent(fake.hal(), scheme="independent")
    agent.setup()
    for second in range(1, 600):            # until the first stall (ScriptedHal.run takes mission time)
        fake.run(agent, second)
        if agent.bumps:
            break
    assert agent.local_map.bumps == [], "the map has the post already: no bump closes the corridor"
    assert agent.follower.following_closely
    while not agent.local_map.bumps and fake.t_us < 3000e6:
        fake.run(agent, fake.t_us / 1e6 + 1.0)
    # Stalled at the same spot again and again: the gap ahead is narrower than the map shows.
    assert agent.bumps >= STALLS_BEFORE_CLOSING_A_GAP and agent.local_map.bumps and not agent.done
    fake.run(agent, 3000)
    assert agent.done, "a robot that really cannot move still drops its targets for good and stops"
    # Before it stopped it forgot the gap its bumps closed, once: a drifting pose can wedge
    # the body in a door it fits through (its targets here were dropped already).
    assert agent.local_map.bumps == []


@pytest.mark.parametrize("wall_behind", [False, True])
def test_after_a_stall_the_robot_backs_off_before_driving_on_where_the_lidar_shows_room_behind(wall_behind):
    ranges = np.full(360, 3.0)
    ranges[150:210] = 10.0          # the corridor leading away, straight ahead (beam 180)
    if wall_behind:
        ranges[:15] = ranges[-15:] = 0.3    # beam 0 looks straight back
    fake = ScriptedHal(ranges)
    agent = ExplorerAgent(fake.hal(), scheme="independent")
    agent.setup()
    while not agent.bumps and fake.t_us < 600e6:
        fake.run(agent, fake.t_us / 1e6 + 0.05)        # a tick at a time, up to the first stall
    first = len(fake.commands) - 1                     # the command of the stall's tick
    fake.run(agent, fake.t_us / 1e6 + 5.0)
    v_mps = [v for v, _ in fake.commands]
    reversing = next((k for k, v in enumerate(v_mps[first:]) if v >= 0.0), len(v_mps) - first)
    if wall_behind:
        assert agent.stats()["stall_back_offs"] == 0 and reversing == 0
    else:
        # These wheels never turn, so the back-off runs to its deadline, then the robot goes on.
        assert agent.stats()["stall_back_offs"] == 1
        assert reversing * 50_000 == pytest.approx(step_time_us(P.stall_back_off_m, P.min_speed_mps), abs=50_000)
        assert all(v == -P.min_speed_mps for v in v_mps[first:first + reversing])
        assert fake.commands[first + reversing] != (0.0, 0.0)


class HeldAheadHal(ScriptedHal):
    """ScriptedHal whose wheels drive the commanded (v, omega) (a unicycle), until the body
    reaches x = held_at_x_m: from there on nothing moves it forward."""

    def __init__(self, ranges_m: np.ndarray, held_at_x_m: float):
        super().__init__(ranges_m)
        self.held_at_x_m = held_at_x_m
        self.x = self.y = self.yaw = self.v = 0.0

    def read(self):
        return OdometrySample(self.t_us, self.x, self.y, self.yaw, self.v, 0.0)

    def command(self, v_mps, omega_radps):
        super().command(v_mps, omega_radps)
        x = self.x + v_mps * 0.05 * math.cos(self.yaw)
        self.v = v_mps if x < self.held_at_x_m or x < self.x else 0.0
        self.x, self.y = self.x + self.v * 0.05 * math.cos(self.yaw), self.y + self.v * 0.05 * math.sin(self.yaw)
        self.yaw += omega_radps * 0.05


def test_after_a_stall_with_no_room_behind_the_robot_drives_back_the_way_it_came():
    ranges = np.full(360, 3.0)
    ranges[150:210] = 10.0          # the corridor leading away, straight ahead (beam 180)
    ranges[:15] = ranges[-15:] = 0.3    # no room straight behind
    fake = HeldAheadHal(ranges, held_at_x_m=1.0)
    # The scripted LiDAR sees the same ranges wherever the body is: no slip check.
    agent = ExplorerAgent(fake.hal(), dataclasses.replace(P, slip_check_m=0.0), scheme="independent")
    agent.setup()
    while not agent.bumps and fake.t_us < 600e6:
        fake.run(agent, fake.t_us / 1e6 + 0.05)
    assert fake.x == pytest.approx(1.0, abs=0.05) and agent.stats()["stall_back_offs"] == 0
    held_x, xs = fake.x, []
    while fake.t_us < 600e6 and (len(xs) < 2 or xs[-1] <= xs[-2] + 1e-9):     # until it heads on again
        fake.run(agent, fake.t_us / 1e6 + 0.05)
        xs.append(fake.x)
    assert agent.stats()["stall_retraces"] == 1
    assert held_x - min(xs) == pytest.approx(P.stall_retrace_m, abs=0.06)


def test_information_at_a_vertex_falls_and_rises_again_with_a_new_revision_each_time():
    """A robot's word about one of its vertices is replaced, not min-ed: the shared map
    follows it down when a waypoint there is covered and up when a new one appears."""
    fake = ScriptedHal(np.full(360, 3.0))
    agent = bayer_faigl_robot(fake)
    agent.topo.add((0, 0, 0, 0, 1, 200, 0))           # the robot's own vertex at the origin
    agent.topo.add((0, 500, 0, 0, 1, 0, 0))           # and one 5 m away, with nothing left
    waypoints = agent.waypoints
    # (waypoints held, vertex code after reporting, robot's revision there). The third step
    # moves the information by 6 %, below the step that is worth a record: no new revision.
    steps = [([], 0, 1), ([Waypoint(0.5, 0.0, 5000.0)], 197, 2), ([Waypoint(0.5, 0.0, 5300.0)], 197, 2), ([], 0, 3)]
    for items, code, revision in steps:
        waypoints.items = items
        agent.scheme.after_plan(fake.read(), fake.t_us)
        assert agent.topo.e_inf_codes().tolist() == [code, 0]
        assert [a.tolist() for a in agent.topo.word_of(0)] == [[revision, 0], [code, 0]]


def test_a_teammate_place_this_robot_sees_empty_is_settled_for_the_team():
    """A teammate's vertex that still promises information, inside a room this robot has seen
    whole, gets this robot's word "nothing here": the vertex's e_inf falls to zero for every
    map that hears it, so nobody else drives there for nothing."""
    fake = ScriptedHal(np.full(360, 3.0))
    agent = bayer_faigl_robot(fake)
    agent.topo.add((1, 100, 0, 0, 1, 200, 0))           # teammate 1 was 1 m away, expecting a lot
    agent.topo.add((2, 5000, 0, 0, 1, 180, 0))          # teammate 2, 50 m away: beyond our map
    fake.run(agent, 30)
    assert (0, 100, 0, 0, 0, 0, 0) in agent.topo.records()
    code_at = {tuple(np.round(xy, 2)): int(c) for xy, c in zip(agent.topo.positions(), agent.topo.e_inf_codes())}
    assert code_at[(1.0, 0.0)] == 0
    assert code_at[(50.0, 0.0)] == 180, "a place our map does not hold keeps its sender's word"
    assert not any(r[0] == 0 and r[1] == 5000 for r in agent.topo.records())


def test_a_scheme_refuses_to_start_without_what_it_needs():
    with pytest.raises(ValueError, match="needs radio"):
        ExplorerAgent(ScriptedHal(np.full(360, 3.0)).hal(), scheme="bayer-faigl:minpos")
    with pytest.raises(ValueError, match="needs mesh"):
        ExplorerAgent(ScriptedHal(np.full(360, 3.0)).hal(), scheme="dense:minpos", radio_profile=profile("ideal-100Bps"))


def test_optional_peripherals_default_to_null_backends():
    hal = Hal(robot_id=3, clock=StepClock(), lidar=None, odometry=None, drive=None)
    assert not any(hal.has(p) for p in ("radio", "uwb", "aoa", "mesh"))
    assert hal.uwb.ranges() == () and hal.aoa.bearings() == () and hal.radio.poll() == ()
    assert not hal.radio.transmit(b"x") and hal.mesh.receive() == ()
    with pytest.raises(ValueError, match="unknown optional peripheral"):
        hal.has("lidar")


def test_a_scheme_that_needs_a_shared_frame_refuses_odometry_in_a_frame_of_its_own():
    class OwnFrame(ScriptedHal):
        def read(self):
            return dataclasses.replace(super().read(), frame_id="robot0")

    fake = OwnFrame(np.full(360, 3.0))
    with pytest.raises(ValueError, match="needs shared_frame"):
        ExplorerAgent(fake.hal(), scheme="bayer-faigl:minpos", radio_profile=profile("ideal-100Bps")).setup()
    agent = ExplorerAgent(fake.hal(), scheme="independent")
    agent.setup()
    assert fake.run(agent, 30).done, "a robot alone does not care which frame it maps in"


def test_a_scheme_that_needs_relaying_gets_a_link_that_floods():
    from firmware.schemes.base import Scheme

    class Gossip(Scheme):
        name, doc = "gossip", "a test scheme that needs multi-hop"
        needs = frozenset({"radio", "relay"})
        relay_hops = 4

        def rank(self, view, own):
            return own

    fake = ScriptedHal(np.full(360, 3.0))
    relaying = ExplorerAgent(fake.hal(), scheme=Gossip(), radio_profile=profile("eu868-g3"))
    plain = ExplorerAgent(fake.hal(), scheme="bayer-faigl:minpos", radio_profile=profile("eu868-g3"))
    assert relaying.link.relay_hop_limit == 4 and plain.link.relay_hop_limit == 0


class LateLidarOnRails(ScriptedHal):
    """A robot whose odometry runs along x at 1 m/s and whose LiDAR hands over each scan
    60 ms after it was taken (a real LiDAR's own clock and a USB hop)."""

    LATE_US = 60_000

    def latest_scan(self):
        scan = super().latest_scan()
        return None if scan is None or self.t_us < self.LATE_US else \
            dataclasses.replace(scan, stamp_us=self.t_us - self.LATE_US)

    def read(self):
        return OdometrySample(self.t_us, self.t_us * 1e-6, 0.0, 0.0, 1.0, 0.0)


def test_a_scan_is_folded_at_the_pose_of_its_own_time():
    fake = LateLidarOnRails(np.full(360, 2.0))
    agent = ExplorerAgent(fake.hal(), scheme="independent")
    agent.setup()
    while agent.scans == 0:
        agent.tick()
        fake.t_us += 50_000
    scan_time_us = fake.t_us - 50_000 - LateLidarOnRails.LATE_US
    expected = LocalMap(agent.p, 0.0, 0.0)
    expected.integrate_scan(scan_time_us * 1e-6, 0.0, 0.0, -np.pi, 2 * np.pi / 360, fake.ranges_m, 10.0)
    assert np.array_equal(agent.local_map.logodds, expected.logodds)
