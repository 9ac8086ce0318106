"""The `Hal` bundle: one robot's peripherals, handed to the firmware at start-up."""
from __future__ import annotations

from dataclasses import dataclass

from hal.interfaces import Clock, DriveBase, Lidar, MeshLink, Odometry, RadioModem, UwbRanger, WifiAoa


@dataclass(frozen=True)
class Hal:
    robot_id: int
    clock: Clock
    lidar: Lidar
    odometry: Odometry
    drive: DriveBase
    uwb: UwbRanger
    aoa: WifiAoa
    radio: RadioModem
    mesh: MeshLink | None = None   # only robots fitted with a mesh link (dense-map baselines)
