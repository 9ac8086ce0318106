"""One robot's simulated world run in real time, for `lorascout robot` on the sim backends.

The lockstep simulator (host_tools.mission) moves time itself, tick by tick. A robot process
runs on the wall clock instead, so here the world follows it: before every tick the host's
loop calls `advance_to(now_us)` and the world steps to that time in steps no longer than the
simulator's tick, so bodies, sensors and odometry move as they do in lockstep. When the
firmware is late, the world is not: the robot keeps driving on its last command, as a real
one does.

The sim backends (hal.sim) built from configuration view this world as robot index 0; the
configuration's [world] table gives its settings (WORLD_SETTINGS). Its radio channel carries
only this robot's frames: the team's other robots are other processes.
"""
from __future__ import annotations

import math
from typing import Any, Mapping

from hal.config import BuildContext, ConfigError, Setting, check_settings
from hal.lora import RadioProfile
from radio_sim.channel import Channel
from world_sim.map_spec import check_map_spec, resolve_map
from world_sim.ros_map import reachable_free
from world_sim.world import LIDAR_PHASE_HELP, WHEEL_SLIP_HELP, World, WorldParams

RESOURCE = "sim-world"            # the BuildContext resource name the sim backends ask for
ROBOT_INDEX = 0                   # the one robot of this world
MAX_STEP_US = 50_000              # the lockstep simulator's tick
WARM_UP_STEP_US = 200_000         # long enough for every simulated sensor to fire once


def _check_map(spec: str) -> None:
    check_map_spec(spec)          # MapSpecError / MapFormatError are ValueErrors naming what is wrong


WORLD_SETTINGS = (
    Setting("map", "text", "the ground truth: a ROS map_server .yaml, cave:SEED[:WxH] or tunnel:SEED[:WxH]",
            check=_check_map),
    Setting("seed", "int", "seed of the sensor noise and of the radio channel", default=0, lo=0, hi=2**32 - 1),
    Setting("start_x_m", "float", "start position (with start_y_m; default: the map's start)", unit="m",
            default=None, lo=-1e6, hi=1e6),
    Setting("start_y_m", "float", "start position (with start_x_m)", unit="m", default=None, lo=-1e6, hi=1e6),
    Setting("start_yaw_deg", "float", "start heading (default: the map's)", unit="deg", default=None,
            lo=-360.0, hi=360.0),
    Setting("wheel_slip_frac", "float", WHEEL_SLIP_HELP, default=0.0, lo=0.0, hi=1.0),
    Setting("lidar_phase_ms", "float", LIDAR_PHASE_HELP, unit="ms", default=0.0, lo=0.0, hi=99.999),
)


def checked_world_settings(table: Mapping[str, Any]) -> dict[str, Any]:
    """The [world] table's settings, checked without generating or loading the map's cells
    beyond what check_map_spec reads; ConfigError naming the key otherwise."""
    settings = check_settings(WORLD_SETTINGS, table)
    if ("start_x_m" in settings) != ("start_y_m" in settings):
        given, missing = ("start_x_m", "start_y_m") if "start_x_m" in settings else ("start_y_m", "start_x_m")
        raise ConfigError(missing, f"missing: {given} is given, so the start position needs {missing} too")
    if "start_x_m" in settings:
        _check_start(settings["map"], settings["start_x_m"], settings["start_y_m"])
    return settings


def _check_start(map_spec: str, x_m: float, y_m: float) -> None:
    """The start on a free cell (the map is generated or loaded for it; the World checks
    the body's clearance when it is built)."""
    occ, _, label = resolve_map(map_spec)
    if not occ.is_free_point(x_m, y_m):
        raise ConfigError("start_x_m", f"({x_m:g}, {y_m:g}) m is not on a free cell of map {label!r}")


def warm_up_world(settings: Mapping[str, Any]) -> None:
    """Compile the world's kernels (motion, collision, LiDAR) before the wall clock runs:
    a throwaway copy of the world takes a step, so the robot's first ticks do not stall on
    the compiler."""
    RealTimeWorld(**settings).world.step(WARM_UP_STEP_US)


class RealTimeWorld:
    """A World of one robot, built from the [world] settings (the keys are its arguments),
    that follows the wall clock and owns the radio channel around the robot."""

    def __init__(self, map: str, seed: int = 0, start_x_m: float | None = None, start_y_m: float | None = None,
                 start_yaw_deg: float | None = None, wheel_slip_frac: float = 0.0, lidar_phase_ms: float = 0.0,
                 params: WorldParams = WorldParams()) -> None:
        params = params.with_slip_and_lidar_phase(wheel_slip_frac, lidar_phase_ms)
        occ, map_start, self.map_label = resolve_map(map)
        x, y, yaw = map_start
        if start_x_m is not None:
            x, y = start_x_m, start_y_m
        if start_yaw_deg is not None:
            yaw = math.radians(start_yaw_deg)
        self.world = World(occ, [(x, y, yaw)], seed, params)
        self._reachable = reachable_free(occ, (x, y), connectivity=4, robot_radius_m=params.robot_radius_m)
        self._channel: Channel | None = None

    @classmethod
    def open(cls, ctx: BuildContext, settings: Mapping[str, Any]) -> RealTimeWorld:
        """The "sim-world" resource of a robot's BuildContext, from its checked [world]
        settings (checked_world_settings): it follows the wall clock and reports coverage in
        the run's summary. ValueError if the robot's body does not fit at its start."""
        sim = cls(**settings)
        warm_up_world(settings)
        ctx.wall_clock_followers.append(sim.advance_to)
        ctx.reports["world"] = sim.report
        return sim

    def advance_to(self, now_us: int) -> None:
        while self.world.now_us < now_us:
            self.world.step(min(MAX_STEP_US, now_us - self.world.now_us))
        if self._channel is not None and self._channel.now_us < self.world.now_us:
            self._channel.advance_to(self.world.now_us)

    def channel(self, profile: RadioProfile, node_id: int) -> Channel:
        """The radio channel around this robot, with the robot attached as `node_id` (once)."""
        if self._channel is None:
            self._channel = Channel(profile, self.world.seed, occupancy=self.world.occ)
            self._channel.attach(node_id, lambda: self.world.true_pose(ROBOT_INDEX)[:2])
        return self._channel

    def report(self) -> dict:
        """Ground truth for the run's summary: coverage of the free area the robot's body can
        reach from its start (the lockstep simulator's definition), the path driven, and the
        drive command the body last received (zero once the robot has stopped)."""
        covered = self.world.observed(ROBOT_INDEX) & self._reachable
        v_mps, omega_radps = self.world.command(ROBOT_INDEX)
        return {
            "map": self.map_label,
            "sim_s": self.world.now_us / 1e6,
            "coverage": round(float(covered.sum()) / int(self._reachable.sum()), 6),
            "path_length_m": round(self.world.path_length_m(ROBOT_INDEX), 3),
            "drive_command": {"v_mps": v_mps, "omega_radps": omega_radps},
        }


def world_of(ctx: BuildContext) -> World:
    """The world a sim backend built from configuration views (as robot ROBOT_INDEX)."""
    return ctx.resource(RESOURCE).world
