"""Simulated UWB two-way ranging to the other robots (noise and NLOS bias: see WorldParams)."""
from __future__ import annotations

from hal.samples import UwbRange
from world_sim.world import World


class SimUwbRanger:
    def __init__(self, world: World, robot_index: int) -> None:
        world.command(robot_index)
        self._world = world
        self._index = robot_index

    def ranges(self) -> tuple[UwbRange, ...]:
        return self._world.take_uwb_ranges(self._index)
