"""The ODrive CAN backends on python-can's virtual bus: frames as ODrive's CANSimple defines
them, a stand-in pair of axes that integrates the commanded wheel speeds, the drive's
clipping and arming, the odometry's arcs, and bytes off the bus that never raise."""
import itertools
import math

import can
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hal.odrive_can import (AXIS_STATE_CLOSED_LOOP_CONTROL, AXIS_STATE_IDLE, CONTROL_MODE_VELOCITY,
                            GET_ENCODER_ESTIMATES, DiffDriveGeometry, OdriveDiffDrive, OdriveWheelOdometry,
                            encoder_estimates, frame_id, heartbeat, set_input_vel)
from hal.registry import backend_class
from hal.samples import DriveLimits
from tests.doubles import FakeAxes, StepClock

GEOMETRY = DiffDriveGeometry(left_node=3, right_node=4, wheel_radius_m=0.08, track_width_m=0.4)
LIMITS = DriveLimits(max_v_mps=0.8, max_omega_radps=1.5, robot_radius_m=0.25)
_channels = itertools.count()


@pytest.fixture
def rig():
    channel = f"odrive-test-{next(_channels)}"
    robot_bus = can.Bus(channel, interface="virtual")
    axes = FakeAxes(channel, GEOMETRY)
    clock = StepClock()
    drive = OdriveDiffDrive(robot_bus, GEOMETRY, LIMITS)
    odom = OdriveWheelOdometry(robot_bus, clock, GEOMETRY, start=(1.0, 2.0, 0.0))
    yield drive, odom, axes, clock
    robot_bus.shutdown()
    axes.bus.shutdown()


def test_frames_are_cansimple():
    # Node 1, Set_Input_Vel -2.5 turn/s with 0.25 Nm feed-forward: id 0x02d, little-endian
    # floats (the frame ODrive's own documentation and other CANSimple codecs give).
    msg = set_input_vel(1, -2.5, 0.25)
    assert msg.arbitration_id == 0x02D and not msg.is_extended_id
    assert bytes(msg.data) == bytes([0x00, 0x00, 0x20, 0xC0, 0x00, 0x00, 0x80, 0x3E])
    assert frame_id(3, GET_ENCODER_ESTIMATES) == 0x69 and frame_id(63, 0x1F) == 0x7FF
    with pytest.raises(ValueError, match="node id"):
        frame_id(64, 1)
    assert bytes(heartbeat(2, 0x80000001, 8).data)[:5] == bytes([0x01, 0x00, 0x00, 0x80, 0x08])


def test_the_registry_names_the_backends():
    assert backend_class("drive", "odrive-can") is OdriveDiffDrive
    assert backend_class("odometry", "odrive-can") is OdriveWheelOdometry


def test_arming_puts_both_axes_in_closed_loop_velocity_control_and_disarming_idles_them(rig):
    drive, _, axes, _ = rig
    drive.arm()
    axes.take_commands()
    assert axes.state == {3: AXIS_STATE_CLOSED_LOOP_CONTROL, 4: AXIS_STATE_CLOSED_LOOP_CONTROL}
    assert axes.control_mode == {3: CONTROL_MODE_VELOCITY, 4: CONTROL_MODE_VELOCITY}
    drive.command(0.5, 0.0)
    drive.disarm()
    axes.take_commands()
    assert axes.state == {3: AXIS_STATE_IDLE, 4: AXIS_STATE_IDLE} and axes.velocity == {3: 0.0, 4: 0.0}


def test_commands_become_wheel_speeds_and_are_clipped_to_the_limits(rig):
    drive, _, axes, _ = rig
    circumference = 2 * math.pi * GEOMETRY.wheel_radius_m
    drive.command(0.5, 0.0)
    axes.take_commands()
    assert axes.velocity[3] == pytest.approx(0.5 / circumference, rel=1e-6)
    assert axes.velocity[4] == pytest.approx(-0.5 / circumference, rel=1e-6)       # mirrored motor
    drive.command(0.0, 1.0)                      # turning left in place: right wheel forward
    axes.take_commands()
    assert axes.velocity[3] == pytest.approx(-0.2 / circumference, rel=1e-6)
    assert axes.velocity[4] == pytest.approx(-0.2 / circumference, rel=1e-6)
    drive.command(5.0, -9.0)                     # beyond both limits: 0.8 m/s, -1.5 rad/s
    axes.take_commands()
    assert axes.velocity[3] == pytest.approx((0.8 + 1.5 * 0.2) / circumference, rel=1e-6)
    assert axes.velocity[4] == pytest.approx(-(0.8 - 1.5 * 0.2) / circumference, rel=1e-6)
    with pytest.raises(ValueError, match="v_mps must be finite"):
        drive.command(math.nan, 0.0)
    assert drive.limits() == LIMITS


def test_odometry_follows_a_straight_run_a_turn_in_place_and_an_arc(rig):
    drive, odom, axes, clock = rig
    drive.arm()
    drive.command(0.5, 0.0)
    axes.run(2.0)
    clock.t_us = 2_000_000
    s = odom.read()
    # The first pair of estimates only sets where the wheels stand: 10 ms of travel less.
    assert (s.x_m, s.y_m, s.yaw_rad) == pytest.approx((1.0 + 0.5 * 1.99, 2.0, 0.0), abs=1e-5)
    assert s.stamp_us == 2_000_000 and s.v_mps == pytest.approx(0.5, rel=1e-6) and s.omega_radps == pytest.approx(0)
    drive.command(0.0, math.pi / 4)
    axes.run(2.0)
    s = odom.read()
    assert s.yaw_rad == pytest.approx(math.pi / 2, abs=1e-5) and s.x_m == pytest.approx(1.995, abs=1e-5)
    assert s.omega_radps == pytest.approx(math.pi / 4, rel=1e-6)
    # An arc of radius 1 m to the left from heading +y, about the centre (0.995, 2): 3.14 s
    # at 0.5 rad/s, just short of a quarter circle.
    drive.command(0.5, 0.5)
    axes.run(3.14)
    s = odom.read()
    turned = 0.5 * 3.14
    assert (s.x_m, s.y_m) == pytest.approx((0.995 + math.cos(turned), 2.0 + math.sin(turned)), abs=1e-5)
    assert s.yaw_rad == pytest.approx(math.pi / 2 + turned, abs=1e-5)
    assert odom.counters.estimates == 2 * (200 + 200 + 314) and odom.counters.malformed == 0


def test_frames_it_cannot_use_are_counted_and_heartbeats_kept(rig):
    _, odom, axes, _ = rig
    bus = axes.bus
    bus.send(can.Message(arbitration_id=frame_id(3, GET_ENCODER_ESTIMATES), is_extended_id=False, data=b"\x00" * 4))
    bus.send(can.Message(arbitration_id=frame_id(9, GET_ENCODER_ESTIMATES), is_extended_id=False, data=b"\x00" * 8))
    bus.send(can.Message(arbitration_id=frame_id(3, GET_ENCODER_ESTIMATES), is_extended_id=True, data=b"\x00" * 8))
    bus.send(encoder_estimates(4, math.nan, 0.0))
    bus.send(heartbeat(4, 0x100, AXIS_STATE_CLOSED_LOOP_CONTROL))
    s = odom.read()
    assert (s.x_m, s.y_m) == (1.0, 2.0)
    assert (odom.counters.malformed, odom.counters.other, odom.counters.heartbeats) == (2, 2, 1)
    assert odom.axis_state[4] == AXIS_STATE_CLOSED_LOOP_CONTROL and odom.axis_error[4] == 0x100
    assert odom.axis_state[3] is None


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 0x7FF), st.booleans(), st.binary(max_size=8)), max_size=30))
def test_any_frames_on_the_bus_never_raise(frames):
    channel = f"odrive-fuzz-{next(_channels)}"
    with can.Bus(channel, interface="virtual") as robot_bus, can.Bus(channel, interface="virtual") as other:
        odom = OdriveWheelOdometry(robot_bus, StepClock(), GEOMETRY)
        for arbitration_id, remote, data in frames:
            other.send(can.Message(arbitration_id=arbitration_id, is_extended_id=False, is_remote_frame=remote,
                                   data=None if remote else data, dlc=len(data)))
        s = odom.read()
        c = odom.counters
        assert c.estimates + c.heartbeats + c.malformed + c.other == len(frames)
        assert all(math.isfinite(v) for v in (s.x_m, s.y_m, s.yaw_rad, s.v_mps, s.omega_radps))


def test_geometry_is_checked():
    with pytest.raises(ValueError, match="wheel_radius_m must be a positive number of metres"):
        DiffDriveGeometry(left_node=1, right_node=2, wheel_radius_m=0.0, track_width_m=0.4)
    with pytest.raises(ValueError, match="both wheels on node 1"):
        DiffDriveGeometry(left_node=1, right_node=1, wheel_radius_m=0.1, track_width_m=0.4)
    with pytest.raises(ValueError, match="right_direction must be 1 or -1"):
        DiffDriveGeometry(left_node=1, right_node=2, wheel_radius_m=0.1, track_width_m=0.4, right_direction=0)
    with pytest.raises(ValueError, match="left_node must be 0..63"):
        DiffDriveGeometry(left_node=70, right_node=2, wheel_radius_m=0.1, track_width_m=0.4)
