"""ODrive motor controllers on a CAN bus (python-can): a differential-drive base and its
wheel odometry, the real-robot backends of `DriveBase` and `Odometry`.

Two ODrive axes, one per wheel, speak ODrive's CANSimple protocol: the 11-bit frame id is
`node_id << 5 | command`, payloads are little-endian, velocities are in wheel turns per
second and positions in turns. The drive arms both axes for velocity control and sends
each command as a wheel velocity; the odometry integrates the encoder estimates the axes
broadcast (configure them to send `Get_Encoder_Estimates` cyclically, e.g. every 10 ms).

Any python-can bus works: SocketCAN on a robot computer, a USB adapter, or the `virtual`
interface in tests. Both classes only send or poll without blocking, so the firmware's tick
never waits on the bus.

Built from configuration (hal.config), the drive and the odometry each take the bus and the
wheels' geometry (BUS_SETTINGS, GEOMETRY_SETTINGS); on one bus they share one python-can bus
object, and a robot's configuration must give both the same values (AGREES_WITH). The drive
is armed when it is built and disarmed when it is closed.
"""
from __future__ import annotations

import math
import struct
from dataclasses import dataclass

import can

from hal.config import BuildContext, ConfigError, Setting
from hal.interfaces import Clock
from hal.samples import DriveLimits, OdometrySample

# CANSimple command ids (the low 5 bits of the frame id).
HEARTBEAT = 0x01
ESTOP = 0x02
SET_AXIS_STATE = 0x07
GET_ENCODER_ESTIMATES = 0x09
SET_CONTROLLER_MODE = 0x0B
SET_INPUT_VEL = 0x0D
CLEAR_ERRORS = 0x18

AXIS_STATE_IDLE = 1
AXIS_STATE_CLOSED_LOOP_CONTROL = 8
CONTROL_MODE_VELOCITY = 2
INPUT_MODE_VEL_RAMP = 2        # the axis ramps to each new velocity at its configured acceleration

MAX_NODE_ID = 0x3F             # 6 bits: 11-bit id minus the 5-bit command

# Payload layouts (struct formats), shared with the axis emulator (world_sim.devices.odrive_emulator).
INPUT_VEL_FORMAT = "<ff"           # Set_Input_Vel: velocity turn/s, torque feed-forward Nm
AXIS_STATE_FORMAT = "<I"           # Set_Axis_State: requested state
CONTROLLER_MODE_FORMAT = "<II"     # Set_Controller_Mode: control mode, input mode
ENCODER_ESTIMATES_FORMAT = "<ff"   # Get_Encoder_Estimates: position turns, velocity turn/s
HEARTBEAT_FORMAT = "<IBBBB"        # Heartbeat: axis error, axis state, procedure result, trajectory done, reserved


def frame_id(node_id: int, command: int) -> int:
    if not 0 <= node_id <= MAX_NODE_ID or not 0 <= command <= 0x1F:
        raise ValueError(f"CANSimple node id must be 0..{MAX_NODE_ID} and command 0..31, got {node_id}, {command}")
    return node_id << 5 | command


def set_input_vel(node_id: int, turns_per_s: float, torque_ff_nm: float = 0.0) -> can.Message:
    return can.Message(arbitration_id=frame_id(node_id, SET_INPUT_VEL), is_extended_id=False,
                       data=struct.pack(INPUT_VEL_FORMAT, turns_per_s, torque_ff_nm))


def set_axis_state(node_id: int, state: int) -> can.Message:
    return can.Message(arbitration_id=frame_id(node_id, SET_AXIS_STATE), is_extended_id=False,
                       data=struct.pack(AXIS_STATE_FORMAT, state))


def set_controller_mode(node_id: int, control_mode: int, input_mode: int) -> can.Message:
    return can.Message(arbitration_id=frame_id(node_id, SET_CONTROLLER_MODE), is_extended_id=False,
                       data=struct.pack(CONTROLLER_MODE_FORMAT, control_mode, input_mode))


def encoder_estimates(node_id: int, position_turns: float, velocity_turns_per_s: float) -> can.Message:
    """What an axis broadcasts (the axis emulator, world_sim.devices.odrive_emulator, sends it)."""
    return can.Message(arbitration_id=frame_id(node_id, GET_ENCODER_ESTIMATES), is_extended_id=False,
                       data=struct.pack(ENCODER_ESTIMATES_FORMAT, position_turns, velocity_turns_per_s))


def heartbeat(node_id: int, axis_error: int, axis_state: int) -> can.Message:
    return can.Message(arbitration_id=frame_id(node_id, HEARTBEAT), is_extended_id=False,
                       data=struct.pack(HEARTBEAT_FORMAT, axis_error, axis_state, 0, 0, 0))


@dataclass(frozen=True)
class DiffDriveGeometry:
    """Where the wheels are and which way their motors turn."""
    left_node: int
    right_node: int
    wheel_radius_m: float
    track_width_m: float          # distance between the wheels' contact points
    # +1 when a positive axis velocity drives that wheel forward. Mirrored motors usually
    # leave one side at -1.
    left_direction: int = 1
    right_direction: int = -1

    def __post_init__(self) -> None:
        for name in ("left_node", "right_node"):
            value = getattr(self, name)
            if not 0 <= value <= MAX_NODE_ID:
                raise ValueError(f"DiffDriveGeometry.{name} must be 0..{MAX_NODE_ID}, got {value!r}")
        if self.left_node == self.right_node:
            raise ValueError(f"DiffDriveGeometry: both wheels on node {self.left_node}")
        for name in ("wheel_radius_m", "track_width_m"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"DiffDriveGeometry.{name} must be a positive number of metres, got {value!r}")
        for name in ("left_direction", "right_direction"):
            if getattr(self, name) not in (1, -1):
                raise ValueError(f"DiffDriveGeometry.{name} must be 1 or -1, got {getattr(self, name)!r}")

    def wheel_turns_per_s(self, v_mps: float, omega_radps: float) -> tuple[float, float]:
        """Axis velocities (left, right) for a body velocity."""
        circumference_m = 2.0 * math.pi * self.wheel_radius_m
        left = (v_mps - omega_radps * self.track_width_m / 2.0) / circumference_m
        right = (v_mps + omega_radps * self.track_width_m / 2.0) / circumference_m
        return left * self.left_direction, right * self.right_direction

    def wheel_travel_m(self, left_turns: float, right_turns: float) -> tuple[float, float]:
        """Forward travel of each wheel for axis turns (the inverse of the directions above)."""
        circumference_m = 2.0 * math.pi * self.wheel_radius_m
        return left_turns * self.left_direction * circumference_m, right_turns * self.right_direction * circumference_m


def _check_interface(name: str) -> None:
    if name not in can.interfaces.VALID_INTERFACES:
        known = ", ".join(sorted(can.interfaces.VALID_INTERFACES))
        raise ValueError(f"{name!r} is no python-can interface; known: {known}")


BUS_SETTINGS = (
    Setting("interface", "text", "the python-can interface", default="socketcan", check=_check_interface),
    Setting("channel", "text", "the bus: can0 for SocketCAN, an adapter's port, a virtual bus's name"),
    Setting("bitrate", "int", "the bus's bit rate, for interfaces that set it (SocketCAN takes it from `ip link`)",
            unit="bit/s", default=None, lo=10_000, hi=1_000_000),
)
GEOMETRY_SETTINGS = (
    Setting("left_node", "int", "CANSimple node id of the left wheel's axis", lo=0, hi=MAX_NODE_ID),
    Setting("right_node", "int", "CANSimple node id of the right wheel's axis", lo=0, hi=MAX_NODE_ID),
    Setting("wheel_radius_m", "float", "wheel radius", unit="m", lo=0.0, lo_open=True, hi=5.0),
    Setting("track_width_m", "float", "distance between the wheels' contact points", unit="m", lo=0.0,
            lo_open=True, hi=20.0),
    Setting("left_direction", "int", "1 when a positive axis velocity drives the left wheel forward",
            default=1, choices=(1, -1)),
    Setting("right_direction", "int", "1 when a positive axis velocity drives the right wheel forward "
            "(mirrored motors: -1)", default=-1, choices=(1, -1)),
)


def open_bus(ctx: BuildContext, interface: str, channel: str, bitrate: int | None) -> can.BusABC:
    """The python-can bus for these settings, opened once per robot and shut down with it."""
    extra = {} if bitrate is None else {"bitrate": bitrate}
    return ctx.shared(("can-bus", interface, channel, bitrate),
                      lambda: can.Bus(channel=channel, interface=interface, **extra), lambda bus: bus.shutdown())


def _split(settings: dict) -> tuple[dict, dict, dict]:
    """(bus settings, geometry settings, the rest) of a checked configuration table."""
    bus = {s.name: settings.get(s.name) for s in BUS_SETTINGS}
    geometry = {s.name: settings[s.name] for s in GEOMETRY_SETTINGS}
    rest = {k: v for k, v in settings.items() if k not in bus and k not in geometry}
    return bus, geometry, rest


def _check_geometry(settings: dict) -> None:
    """What the settings' own ranges cannot say (DiffDriveGeometry checks the rest again)."""
    if settings["left_node"] == settings["right_node"]:
        raise ConfigError("right_node", f"{settings['right_node']} is left_node's too: each wheel needs an axis "
                          "of its own")


class OdriveDiffDrive:
    """`DriveBase` on two ODrive axes. `arm()` puts both into closed-loop velocity control;
    `disarm()` stops them and lets them go idle. Commands beyond the limits are clipped, as
    the simulated base clips them."""

    SETTINGS = BUS_SETTINGS + GEOMETRY_SETTINGS + (
        Setting("max_v_mps", "float", "top forward speed the firmware may command", unit="m/s", lo=0.0,
                lo_open=True, hi=20.0),
        Setting("max_omega_radps", "float", "top turn rate the firmware may command", unit="rad/s", lo=0.0,
                lo_open=True, hi=50.0),
        Setting("robot_radius_m", "float", "radius of the circle the robot's body fits in", unit="m", lo=0.0,
                lo_open=True, hi=5.0),
    )
    RESOURCES = ()

    def __init__(self, bus: can.BusABC, geometry: DiffDriveGeometry, limits: DriveLimits) -> None:
        self._bus = bus
        self.geometry = geometry
        self._limits = limits

    @classmethod
    def check_config(cls, settings: dict) -> None:
        _check_geometry(settings)

    @classmethod
    def from_config(cls, ctx: BuildContext, **settings) -> OdriveDiffDrive:
        bus, geometry, limits = _split(settings)
        drive = cls(open_bus(ctx, **bus), DiffDriveGeometry(**geometry), DriveLimits(**limits))
        drive.arm()
        return drive

    def close(self) -> None:
        """Stop both wheels and leave the axes idle; the bus stays open (it may be shared)."""
        self.disarm()

    def limits(self) -> DriveLimits:
        return self._limits

    def arm(self) -> None:
        for node in (self.geometry.left_node, self.geometry.right_node):
            self._bus.send(set_controller_mode(node, CONTROL_MODE_VELOCITY, INPUT_MODE_VEL_RAMP))
            self._bus.send(set_input_vel(node, 0.0))
            self._bus.send(set_axis_state(node, AXIS_STATE_CLOSED_LOOP_CONTROL))

    def disarm(self) -> None:
        for node in (self.geometry.left_node, self.geometry.right_node):
            self._bus.send(set_input_vel(node, 0.0))
            self._bus.send(set_axis_state(node, AXIS_STATE_IDLE))

    def command(self, v_mps: float, omega_radps: float) -> None:
        v, w = self._limits.clip(v_mps, omega_radps, "OdriveDiffDrive.command")
        left, right = self.geometry.wheel_turns_per_s(v, w)
        self._bus.send(set_input_vel(self.geometry.left_node, left))
        self._bus.send(set_input_vel(self.geometry.right_node, right))


@dataclass
class BusCounters:
    """What the odometry made of the frames it read."""
    estimates: int = 0            # encoder estimates used
    heartbeats: int = 0
    malformed: int = 0            # frames of a wheel's node with a payload too short for their command
    other: int = 0                # other nodes, other commands, extended ids, remote frames


class OdriveWheelOdometry:
    """`Odometry` from the encoder estimates of two ODrive axes: each `read()` drains the
    frames waiting on the bus, advances the pose by every new pair of wheel positions
    (differential-drive arc), and reports it with the clock's time. The pose starts at
    `start` in the mission frame. Frames it cannot use are counted, never raised."""

    SETTINGS = BUS_SETTINGS + GEOMETRY_SETTINGS + (
        Setting("start_x_m", "float", "the robot's start position in the mission frame", unit="m", default=0.0,
                lo=-1e6, hi=1e6),
        Setting("start_y_m", "float", "the robot's start position in the mission frame", unit="m", default=0.0,
                lo=-1e6, hi=1e6),
        Setting("start_yaw_deg", "float", "the robot's start heading in the mission frame", unit="deg",
                default=0.0, lo=-360.0, hi=360.0),
    )
    RESOURCES = ()
    # The drive on the same backend drives these wheels on this bus: both tables must agree.
    AGREES_WITH = {"drive": tuple(s.name for s in BUS_SETTINGS + GEOMETRY_SETTINGS)}

    def __init__(self, bus: can.BusABC, clock: Clock, geometry: DiffDriveGeometry,
                 start: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> None:
        self._bus = bus
        self._clock = clock
        self.geometry = geometry
        self._x, self._y, self._yaw = (float(v) for v in start)
        self._last_turns: dict[int, float | None] = {geometry.left_node: None, geometry.right_node: None}
        self._new_turns: dict[int, float] = {}
        self._velocity: dict[int, float] = {geometry.left_node: 0.0, geometry.right_node: 0.0}
        self.axis_state: dict[int, int | None] = {geometry.left_node: None, geometry.right_node: None}
        self.axis_error: dict[int, int] = {geometry.left_node: 0, geometry.right_node: 0}
        self.counters = BusCounters()

    @classmethod
    def check_config(cls, settings: dict) -> None:
        _check_geometry(settings)

    @classmethod
    def from_config(cls, ctx: BuildContext, start_x_m: float, start_y_m: float, start_yaw_deg: float,
                    **settings) -> OdriveWheelOdometry:
        if ctx.clock is None:
            raise ConfigError(None, "the odometry needs the robot's clock to stamp its samples")
        bus, geometry, _ = _split(settings)
        return cls(open_bus(ctx, **bus), ctx.clock, DiffDriveGeometry(**geometry),
                   start=(start_x_m, start_y_m, math.radians(start_yaw_deg)))

    def read(self) -> OdometrySample:
        while (msg := self._bus.recv(timeout=0.0)) is not None:
            self._take(msg)
        g = self.geometry
        v_left, v_right = g.wheel_travel_m(self._velocity[g.left_node], self._velocity[g.right_node])
        return OdometrySample(stamp_us=self._clock.now_us(), x_m=self._x, y_m=self._y, yaw_rad=self._yaw,
                              v_mps=(v_left + v_right) / 2.0, omega_radps=(v_right - v_left) / g.track_width_m)

    def _take(self, msg: can.Message) -> None:
        node, command = msg.arbitration_id >> 5, msg.arbitration_id & 0x1F
        if msg.is_extended_id or msg.is_remote_frame or node not in self._last_turns:
            self.counters.other += 1
            return
        data = bytes(msg.data)
        if command == GET_ENCODER_ESTIMATES:
            if len(data) < 8:
                self.counters.malformed += 1
                return
            turns, velocity = struct.unpack_from(ENCODER_ESTIMATES_FORMAT, data)
            if not (math.isfinite(turns) and math.isfinite(velocity)):
                self.counters.malformed += 1
                return
            self.counters.estimates += 1
            self._velocity[node] = velocity
            self._new_turns[node] = turns
            if len(self._new_turns) == 2:
                self._advance()
        elif command == HEARTBEAT:
            if len(data) < 5:
                self.counters.malformed += 1
                return
            self.counters.heartbeats += 1
            self.axis_error[node], self.axis_state[node] = struct.unpack_from("<IB", data)
        else:
            self.counters.other += 1

    def _advance(self) -> None:
        """Move the pose by what both wheels travelled since their previous pair of estimates.
        (Positions come as float32 turns, so their resolution falls with distance: 1.2e-4 turn,
        0.06 mm on 8 cm wheels, after 1 km. Differences of consecutive estimates keep it.)"""
        g = self.geometry
        new, self._new_turns = self._new_turns, {}
        last_left, last_right = self._last_turns[g.left_node], self._last_turns[g.right_node]
        self._last_turns = dict(new)
        if last_left is None or last_right is None:
            return                    # the first pair only sets where the wheels stand
        d_left, d_right = g.wheel_travel_m(new[g.left_node] - last_left, new[g.right_node] - last_right)
        ds = (d_left + d_right) / 2.0
        dyaw = (d_right - d_left) / g.track_width_m
        # Along the arc's chord, at the mean heading: exact for constant wheel speeds.
        chord = ds if abs(dyaw) < 1e-9 else 2.0 * ds / dyaw * math.sin(dyaw / 2.0)
        heading = self._yaw + dyaw / 2.0
        self._x += chord * math.cos(heading)
        self._y += chord * math.sin(heading)
        self._yaw = math.remainder(self._yaw + dyaw, 2.0 * math.pi)
