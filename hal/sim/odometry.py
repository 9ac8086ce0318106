"""Simulated odometry: the world's drifting dead-reckoning estimate of one robot."""
from __future__ import annotations

from hal.samples import OdometrySample
from world_sim.world import World


class SimOdometry:
    def __init__(self, world: World, robot_index: int) -> None:
        world.odometry_sample(robot_index)
        self._world = world
        self._index = robot_index

    def read(self) -> OdometrySample:
        return self._world.odometry_sample(self._index)
