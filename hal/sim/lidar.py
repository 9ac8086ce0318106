"""Simulated 2-D LiDAR: the world's noisy scans of one robot, each handed out once."""
from __future__ import annotations

from hal.config import BuildContext
from hal.samples import LidarScan
from hal.sim.realtime_world import RESOURCE, ROBOT_INDEX, world_of
from world_sim.world import World


class SimLidar:
    # Built from configuration (hal.config): robot ROBOT_INDEX of the configuration's [world].
    SETTINGS = ()
    RESOURCES = (RESOURCE,)

    def __init__(self, world: World, robot_index: int) -> None:
        world.latest_scan(robot_index)  # validates the index now, not at the first read
        self._world = world
        self._index = robot_index
        self._last_stamp_us = -1

    @classmethod
    def from_config(cls, ctx: BuildContext) -> SimLidar:
        return cls(world_of(ctx), ROBOT_INDEX)

    def latest_scan(self) -> LidarScan | None:
        scan = self._world.latest_scan(self._index)
        if scan is None or scan.stamp_us <= self._last_stamp_us:
            return None
        self._last_stamp_us = scan.stamp_us
        return scan
