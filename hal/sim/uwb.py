"""Simulated UWB two-way ranging to the other robots: noise, NLOS bias and spread, outliers,
dropouts, resolution and rate as WorldParams.sensing gives them (world_sim.sensing: the
`paper` and `realistic` profiles)."""
from __future__ import annotations

from hal.config import BuildContext
from hal.samples import UwbRange
from hal.sim.realtime_world import RESOURCE, ROBOT_INDEX, world_of
from world_sim.world import World


class SimUwbRanger:
    # Built from configuration (hal.config): robot ROBOT_INDEX of the configuration's [world].
    SETTINGS = ()
    RESOURCES = (RESOURCE,)

    def __init__(self, world: World, robot_index: int) -> None:
        world.command(robot_index)
        self._world = world
        self._index = robot_index

    @classmethod
    def from_config(cls, ctx: BuildContext) -> SimUwbRanger:
        return cls(world_of(ctx), ROBOT_INDEX)

    def ranges(self) -> tuple[UwbRange, ...]:
        return self._world.take_uwb_ranges(self._index)
