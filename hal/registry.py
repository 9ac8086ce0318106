"""Backend registry: peripheral kind -> backend name -> (module, class).

Only the chosen backend's module is imported, so a robot without pyserial or python-can
never imports them, and the simulator never imports real drivers (the python-can pattern).
"""
from __future__ import annotations

import importlib

BACKENDS: dict[str, dict[str, tuple[str, str]]] = {
    "clock": {"sim": ("hal.sim.clock", "SimClock")},
    "lidar": {
        "sim": ("hal.sim.lidar", "SimLidar"),
        "rplidar": ("hal.rplidar", "RplidarLidar"),
    },
    "odometry": {
        "sim": ("hal.sim.odometry", "SimOdometry"),
        "odrive-can": ("hal.odrive_can", "OdriveWheelOdometry"),
    },
    "drive": {
        "sim": ("hal.sim.drive", "SimDriveBase"),
        "odrive-can": ("hal.odrive_can", "OdriveDiffDrive"),
    },
    "uwb": {
        "sim": ("hal.sim.uwb", "SimUwbRanger"),
        "dwm1001": ("hal.dwm1001", "Dwm1001Ranger"),
    },
    "aoa": {"sim": ("hal.sim.aoa", "SimWifiAoa")},
    "radio": {
        "sim": ("hal.sim.radio", "SimRadioModem"),
        "rn2483": ("hal.rn2483", "Rn2483Modem"),
    },
}


class UnknownBackend(LookupError):
    pass


def backend_class(kind: str, name: str) -> type:
    """The class implementing peripheral `kind` for backend `name`, imported on demand."""
    try:
        module_name, class_name = BACKENDS[kind][name]
    except KeyError:
        known = ", ".join(f"{k}:{n}" for k, names in BACKENDS.items() for n in names)
        raise UnknownBackend(f"no backend {name!r} for {kind!r}; known: {known}") from None
    return getattr(importlib.import_module(module_name), class_name)
