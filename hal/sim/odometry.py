"""Simulated odometry: the world's drifting dead-reckoning estimate of one robot, in the
team's shared frame or in a frame of the robot's own (origin and heading at its start)."""
from __future__ import annotations

import dataclasses
import math

from hal.config import BuildContext, Setting
from hal.samples import SHARED_FRAME, OdometrySample
from hal.sim.realtime_world import RESOURCE, ROBOT_INDEX, world_of
from world_sim.world import World

FRAMES = ("shared", "own")


class SimOdometry:
    # Built from configuration (hal.config): robot ROBOT_INDEX of the configuration's [world].
    SETTINGS = (Setting("frame", "text", "the odometry's frame: the team's shared one, or the robot's own "
                        "(origin at its start, facing +x)", default="shared", choices=FRAMES),)
    RESOURCES = (RESOURCE,)

    def __init__(self, world: World, robot_index: int, frame: str = "shared") -> None:
        """frame: "shared" (the mission frame every robot's start pose was measured in) or
        "own" (the robot knows only that it started at its own origin, facing +x)."""
        if frame not in FRAMES:
            raise ValueError(f"odometry frame must be one of {', '.join(FRAMES)}, got {frame!r}")
        start = world.odometry_sample(robot_index)
        self._world = world
        self._index = robot_index
        self._origin = (start.x_m, start.y_m, start.yaw_rad) if frame == "own" else None
        self.frame_id = SHARED_FRAME if frame == "shared" else f"robot{robot_index}"

    @classmethod
    def from_config(cls, ctx: BuildContext, frame: str) -> SimOdometry:
        return cls(world_of(ctx), ROBOT_INDEX, frame=frame)

    def read(self) -> OdometrySample:
        s = self._world.odometry_sample(self._index)
        if self._origin is None:
            return s
        x0, y0, yaw0 = self._origin
        c, sn = math.cos(yaw0), math.sin(yaw0)
        dx, dy = s.x_m - x0, s.y_m - y0
        return dataclasses.replace(s, x_m=c * dx + sn * dy, y_m=-sn * dx + c * dy,
                                   yaw_rad=(s.yaw_rad - yaw0 + math.pi) % (2 * math.pi) - math.pi,
                                   frame_id=self.frame_id)
