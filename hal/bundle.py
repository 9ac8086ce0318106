"""The `Hal` bundle: one robot's peripherals, handed to the firmware at start-up.

A clock, a LiDAR, odometry and a drive base every robot has. The radio, UWB, WiFi AoA and
mesh link are optional: a robot without one gets its null backend (hal.null), and
`has(name)` says which are fitted."""
from __future__ import annotations

from dataclasses import dataclass, field

from hal.interfaces import Clock, DriveBase, Lidar, MeshLink, Odometry, RadioModem, UwbRanger, WifiAoa
from hal.null import NullMeshLink, NullPeripheral, NullRadioModem, NullUwbRanger, NullWifiAoa

OPTIONAL = ("radio", "uwb", "aoa", "mesh")


@dataclass(frozen=True, kw_only=True)
class Hal:
    robot_id: int
    clock: Clock
    lidar: Lidar
    odometry: Odometry
    drive: DriveBase
    radio: RadioModem = field(default_factory=NullRadioModem)
    uwb: UwbRanger = field(default_factory=NullUwbRanger)
    aoa: WifiAoa = field(default_factory=NullWifiAoa)
    mesh: MeshLink = field(default_factory=NullMeshLink)   # a mesh link: the dense-map baselines

    def has(self, peripheral: str) -> bool:
        """Is the optional peripheral (radio, uwb, aoa, mesh) fitted?"""
        if peripheral not in OPTIONAL:
            raise ValueError(f"unknown optional peripheral {peripheral!r}; known: {', '.join(OPTIONAL)}")
        return not isinstance(getattr(self, peripheral), NullPeripheral)
