"""Emulated ODrive axes on a python-can bus, and a robot's differential drive built from two of
them in the simulated world, so the real backends (hal.odrive_can) drive the world unchanged.

The wire format (CANSimple frame ids, command ids, payload layouts) is hal.odrive_can's: the
emulator decodes what the driver encodes with the same constants, and encodes what the driver
decodes with the same builders.

`OdriveAxis` is one axis's state as CANSimple changes it: Set_Axis_State (idle or closed-loop
control), Set_Controller_Mode, Set_Input_Vel, Estop (the axis stops and reports an error until
Clear_Errors). It drives its wheel only in closed-loop velocity control; a velocity sent to an
idle axis is stored and used once it is armed, as the ODrive does. Each new velocity is taken at
once: the simulated body has no acceleration limit, and neither have these axes (a real axis in
INPUT_MODE_VEL_RAMP ramps at its configured rate).

`OdriveAxes` is a set of axes on one bus: `take_commands()` drains the frames waiting on the bus
and hands each to the axis its node id names (frames for other nodes, and the axes' own
broadcasts, are ignored, as other devices on a real bus ignore them), `broadcast_estimates()`
sends every axis's Get_Encoder_Estimates and `broadcast_heartbeats()` every axis's Heartbeat,
as an ODrive configured to send them cyclically does. How far a wheel turned is its owner's
business: a bench double turns it at the commanded speed (tests/doubles.FakeAxes), the world's
drive below by what the world's wheels did.

`WorldDiffDrive` binds two axes to robot `robot_index` of a world_sim World: `apply_commands()`
turns the axes' commanded wheel speeds into the body command the world moves the robot with
(zero unless both axes are in closed-loop control), and `after_step(dt_us)` turns each wheel by
what the world's wheel odometry measured over the step (the encoder speeds the world reports,
with their noise, and with wheel slip the travel of wheels that spin against a wall), so the
driver's odometry integrates the same encoder model the simulated odometry does. Time: nothing
here reads a clock; the caller steps the world and calls these in order.
"""
from __future__ import annotations

import math
import struct
from collections.abc import Iterable

import can

from hal.odrive_can import (AXIS_STATE_CLOSED_LOOP_CONTROL, AXIS_STATE_FORMAT, AXIS_STATE_IDLE, CLEAR_ERRORS,
                            CONTROL_MODE_VELOCITY, CONTROLLER_MODE_FORMAT, ESTOP, INPUT_VEL_FORMAT, MAX_NODE_ID,
                            SET_AXIS_STATE, SET_CONTROLLER_MODE, SET_INPUT_VEL, DiffDriveGeometry, encoder_estimates,
                            heartbeat)
from world_sim.world import World

AXIS_ERROR_ESTOP_REQUESTED = 0x4000      # ODrive's AxisError.ESTOP_REQUESTED

_PAYLOADS = {SET_INPUT_VEL: INPUT_VEL_FORMAT, SET_AXIS_STATE: AXIS_STATE_FORMAT,
             SET_CONTROLLER_MODE: CONTROLLER_MODE_FORMAT}


class OdriveAxis:
    """One ODrive axis: what CANSimple commands set, and where its encoder stands."""

    def __init__(self, node_id: int) -> None:
        if not 0 <= node_id <= MAX_NODE_ID:
            raise ValueError(f"ODrive node id must be 0..{MAX_NODE_ID}, got {node_id!r}")
        self.node_id = node_id
        self.state = AXIS_STATE_IDLE
        self.control_mode: int | None = None
        self.input_mode: int | None = None
        self.input_vel = 0.0                 # the last Set_Input_Vel, turn/s
        self.error = 0
        self.turns = 0.0                     # encoder position
        self.velocity = 0.0                  # encoder velocity, turn/s
        self.frames_taken = 0
        self.frames_malformed = 0            # a command whose payload is too short for it

    @property
    def closed_loop(self) -> bool:
        return self.state == AXIS_STATE_CLOSED_LOOP_CONTROL

    def commanded_turns_per_s(self) -> float:
        """The speed the axis drives its wheel at: the input velocity in closed-loop velocity
        control, else zero (an idle axis lets its wheel go)."""
        return self.input_vel if self.closed_loop and self.control_mode == CONTROL_MODE_VELOCITY else 0.0

    def take(self, command: int, data: bytes) -> None:
        """Apply one CANSimple command addressed to this axis (unknown commands are ignored,
        as the ODrive ignores the ones it does not implement)."""
        fmt = _PAYLOADS.get(command)
        if fmt is not None and len(data) < struct.calcsize(fmt):
            self.frames_malformed += 1
            return
        self.frames_taken += 1
        if command == SET_INPUT_VEL:
            vel = struct.unpack_from(fmt, data)[0]
            if math.isfinite(vel):
                self.input_vel = vel
        elif command == SET_AXIS_STATE:
            requested = struct.unpack_from(fmt, data)[0]
            # An axis with an error stays idle until the error is cleared.
            self.state = AXIS_STATE_IDLE if self.error else requested
        elif command == SET_CONTROLLER_MODE:
            self.control_mode, self.input_mode = struct.unpack_from(fmt, data)
        elif command == ESTOP:
            self.error |= AXIS_ERROR_ESTOP_REQUESTED
            self.state = AXIS_STATE_IDLE
        elif command == CLEAR_ERRORS:
            self.error = 0

    def turn(self, delta_turns: float, dt_s: float) -> None:
        """The wheel turned by `delta_turns` in `dt_s`: the encoder follows."""
        self.turns += delta_turns
        self.velocity = delta_turns / dt_s if dt_s > 0 else 0.0


class OdriveAxes:
    """ODrive axes on one python-can bus (the caller owns the bus and shuts it down)."""

    def __init__(self, bus: can.BusABC, node_ids: Iterable[int]) -> None:
        self.bus = bus
        self.axes = {n: OdriveAxis(n) for n in node_ids}
        if not self.axes:
            raise ValueError("OdriveAxes needs at least one node id")
        self.frames_ignored = 0

    def __getitem__(self, node_id: int) -> OdriveAxis:
        return self.axes[node_id]

    def take_commands(self) -> int:
        """Apply every frame waiting on the bus to the axis it addresses; returns how many
        frames were read. Never blocks."""
        read = 0
        while (msg := self.bus.recv(timeout=0.0)) is not None:
            read += 1
            self.take(msg)
        return read

    def take(self, msg: can.Message) -> None:
        node, command = msg.arbitration_id >> 5, msg.arbitration_id & 0x1F
        axis = self.axes.get(node)
        if axis is None or msg.is_extended_id or msg.is_remote_frame or command not in _COMMANDS:
            self.frames_ignored += 1      # other devices' traffic, our own broadcasts, requests we do not serve
            return
        axis.take(command, bytes(msg.data))

    def broadcast_estimates(self) -> None:
        for axis in self.axes.values():
            self.bus.send(encoder_estimates(axis.node_id, axis.turns, axis.velocity))

    def broadcast_heartbeats(self) -> None:
        for axis in self.axes.values():
            self.bus.send(heartbeat(axis.node_id, axis.error, axis.state))


_COMMANDS = frozenset((SET_INPUT_VEL, SET_AXIS_STATE, SET_CONTROLLER_MODE, ESTOP, CLEAR_ERRORS))


class WorldDiffDrive:
    """Robot `robot_index`'s differential drive: the axes `geometry` names, in `axes`."""

    def __init__(self, world: World, robot_index: int, axes: OdriveAxes, geometry: DiffDriveGeometry) -> None:
        world.command(robot_index)          # validates the index now
        for node in (geometry.left_node, geometry.right_node):
            if node not in axes.axes:
                raise ValueError(f"robot {robot_index}'s wheel axis {node} is not among the emulated axes "
                                 f"{sorted(axes.axes)}")
        self._world = world
        self._index = robot_index
        self.geometry = geometry
        self.left = axes[geometry.left_node]
        self.right = axes[geometry.right_node]

    def body_command(self) -> tuple[float, float]:
        """(v_mps, omega_radps) the wheels' commanded speeds give the body."""
        g = self.geometry
        left_m, right_m = g.wheel_travel_m(self.left.commanded_turns_per_s(), self.right.commanded_turns_per_s())
        return (left_m + right_m) / 2.0, (right_m - left_m) / g.track_width_m

    def apply_commands(self) -> None:
        """The world moves the body with what the wheels are told (the world clips it to the
        body's limits, as the simulated base does)."""
        self._world.set_command(self._index, *self.body_command())

    def after_step(self, dt_us: int) -> None:
        """Turn both wheels by what the world's wheel odometry measured over the step just taken."""
        s = self._world.odometry_sample(self._index)
        dt_s = dt_us * 1e-6
        left_turns, right_turns = self.geometry.wheel_turns_per_s(s.v_mps, s.omega_radps)
        self.left.turn(left_turns * dt_s, dt_s)
        self.right.turn(right_turns * dt_s, dt_s)
