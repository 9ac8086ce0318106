"""Simulated WiFi angle of arrival of the other robots, in this robot's frame, [-pi, pi)."""
from __future__ import annotations

from hal.samples import AoaBearing
from world_sim.world import World


class SimWifiAoa:
    def __init__(self, world: World, robot_index: int) -> None:
        world.command(robot_index)
        self._world = world
        self._index = robot_index

    def bearings(self) -> tuple[AoaBearing, ...]:
        return self._world.take_aoa_bearings(self._index)
