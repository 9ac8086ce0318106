"""Simulated clock: mission time is whatever the world's lockstep clock says."""
from __future__ import annotations

from hal.config import BuildContext
from hal.sim.realtime_world import RESOURCE, world_of
from world_sim.world import World


class SimClock:
    # Built from configuration (hal.config): the time of the configuration's [world].
    SETTINGS = ()
    RESOURCES = (RESOURCE,)

    def __init__(self, world: World) -> None:
        self._world = world

    @classmethod
    def from_config(cls, ctx: BuildContext) -> SimClock:
        return cls(world_of(ctx))

    def now_us(self) -> int:
        return self._world.now_us
