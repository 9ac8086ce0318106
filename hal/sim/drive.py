"""Simulated differential-drive base: the world moves the body with the last command."""
from __future__ import annotations

from hal.config import BuildContext
from hal.samples import DriveLimits
from hal.sim.realtime_world import RESOURCE, ROBOT_INDEX, world_of
from world_sim.world import World


class SimDriveBase:
    # Built from configuration (hal.config): robot ROBOT_INDEX of the configuration's [world].
    SETTINGS = ()
    RESOURCES = (RESOURCE,)

    def __init__(self, world: World, robot_index: int) -> None:
        world.command(robot_index)
        self._world = world
        self._index = robot_index
        p = world.params
        self._limits = DriveLimits(max_v_mps=p.max_v_mps, max_omega_radps=p.max_omega_radps,
                                   robot_radius_m=p.robot_radius_m)

    @classmethod
    def from_config(cls, ctx: BuildContext) -> SimDriveBase:
        return cls(world_of(ctx), ROBOT_INDEX)

    def limits(self) -> DriveLimits:
        return self._limits

    def command(self, v_mps: float, omega_radps: float) -> None:
        v, w = self._limits.clip(v_mps, omega_radps, f"SimDriveBase.command (robot {self._index})")
        self._world.set_command(self._index, v, w)
