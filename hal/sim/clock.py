"""Simulated clock: mission time is whatever the world's lockstep clock says."""
from __future__ import annotations

from world_sim.world import World


class SimClock:
    def __init__(self, world: World) -> None:
        self._world = world

    def now_us(self) -> int:
        return self._world.now_us
