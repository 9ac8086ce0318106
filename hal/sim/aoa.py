"""Simulated WiFi angle of arrival of the other robots, in this robot's frame, [-pi, pi): noise,
multipath outliers, dropouts and rate as WorldParams.sensing gives them (world_sim.sensing).
One bearing per peer and sweep (rank 0, no profile variance)."""
from __future__ import annotations

from hal.config import BuildContext
from hal.samples import AoaBearing
from hal.sim.realtime_world import RESOURCE, ROBOT_INDEX, world_of
from world_sim.world import World


class SimWifiAoa:
    # Built from configuration (hal.config): robot ROBOT_INDEX of the configuration's [world].
    SETTINGS = ()
    RESOURCES = (RESOURCE,)

    def __init__(self, world: World, robot_index: int) -> None:
        world.command(robot_index)
        self._world = world
        self._index = robot_index

    @classmethod
    def from_config(cls, ctx: BuildContext) -> SimWifiAoa:
        return cls(world_of(ctx), ROBOT_INDEX)

    def bearings(self) -> tuple[AoaBearing, ...]:
        return self._world.take_aoa_bearings(self._index)
