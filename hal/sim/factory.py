"""Assemble one robot's simulated `Hal` from a world, through the backend registry."""
from __future__ import annotations

from hal.bundle import Hal
from hal.interfaces import RadioModem
from hal.registry import backend_class
from world_sim.world import World


def build_sim_hal(world: World, robot_index: int, radio: RadioModem, frame: str = "shared") -> Hal:
    """Robot `robot_index`'s peripherals, all simulated on `world`; `radio` is supplied by
    the caller (the radio world is built separately). The robot id is the index. frame:
    the odometry's frame, "shared" or the robot's "own" (hal.sim.odometry)."""
    if not isinstance(radio, RadioModem):
        raise TypeError(f"radio for robot {robot_index} must implement hal.interfaces.RadioModem, got {type(radio).__name__}")
    return Hal(
        robot_id=robot_index,
        clock=backend_class("clock", "sim")(world),
        lidar=backend_class("lidar", "sim")(world, robot_index),
        odometry=backend_class("odometry", "sim")(world, robot_index, frame=frame),
        drive=backend_class("drive", "sim")(world, robot_index),
        uwb=backend_class("uwb", "sim")(world, robot_index),
        aoa=backend_class("aoa", "sim")(world, robot_index),
        radio=radio,
    )
