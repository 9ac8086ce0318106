"""Simulated 2-D LiDAR: the world's noisy scans of one robot, each handed out once."""
from __future__ import annotations

from hal.samples import LidarScan
from world_sim.world import World


class SimLidar:
    def __init__(self, world: World, robot_index: int) -> None:
        world.latest_scan(robot_index)  # validates the index now, not at the first read
        self._world = world
        self._index = robot_index
        self._last_stamp_us = -1

    def latest_scan(self) -> LidarScan | None:
        scan = self._world.latest_scan(self._index)
        if scan is None or scan.stamp_us <= self._last_stamp_us:
            return None
        self._last_stamp_us = scan.stamp_us
        return scan
