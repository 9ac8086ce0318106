"""Backend registry: peripheral kind -> backend name -> (module, class).

Only the chosen backend's module is imported, so a robot without pyserial or python-can
never imports them, and the simulator never imports real drivers (the python-can pattern).

Every backend is also built from configuration the same way (hal.config): `check_backend`
checks a configuration table against the class's declared SETTINGS without opening anything,
and `build_backend` builds it with `from_config`, registering its `close()` (if it has one)
with the robot's BuildContext. A class may add `check_config(settings)` for what its
settings' ranges cannot say (two wheels on one CAN node).
"""
from __future__ import annotations

import importlib
from collections.abc import Mapping
from typing import Any

from hal.config import BuildContext, check_settings

BACKENDS: dict[str, dict[str, tuple[str, str]]] = {
    "clock": {
        "sim": ("hal.sim.clock", "SimClock"),
        "monotonic": ("hal.monotonic_clock", "MonotonicClock"),
    },
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
        "null": ("hal.null", "NullUwbRanger"),
    },
    "aoa": {
        "sim": ("hal.sim.aoa", "SimWifiAoa"),
        "null": ("hal.null", "NullWifiAoa"),
    },
    "radio": {
        "sim": ("hal.sim.radio", "SimRadioModem"),
        "rn2483": ("hal.rn2483", "Rn2483Modem"),
        "null": ("hal.null", "NullRadioModem"),
    },
    "mesh": {"null": ("hal.null", "NullMeshLink")},
}


class UnknownBackend(LookupError):
    pass


def backend_class(kind: str, name: str) -> type:
    """The class implementing peripheral `kind` for backend `name`, imported on demand."""
    if kind not in BACKENDS:
        raise UnknownBackend(f"no peripheral kind {kind!r}; known: {', '.join(BACKENDS)}")
    try:
        module_name, class_name = BACKENDS[kind][name]
    except KeyError:
        raise UnknownBackend(f"no backend {name!r} for {kind!r}; known: {', '.join(BACKENDS[kind])}") from None
    return getattr(importlib.import_module(module_name), class_name)


def check_backend(kind: str, name: str, table: Mapping[str, Any]) -> dict[str, Any]:
    """The checked settings for building backend `name` of peripheral `kind` from `table`
    (its configuration without the backend's name). UnknownBackend, or hal.config.ConfigError
    naming the key; nothing is opened."""
    cls = backend_class(kind, name)
    settings = check_settings(cls.SETTINGS, table, owner=f"backend {name!r}")
    check_config = getattr(cls, "check_config", None)
    if check_config is not None:
        check_config(settings)
    return settings


def build_backend(kind: str, name: str, settings: Mapping[str, Any], ctx: BuildContext) -> Any:
    """The backend, built from settings `check_backend` returned; closed by `ctx.close()`."""
    backend = backend_class(kind, name).from_config(ctx, **settings)
    close = getattr(backend, "close", None)
    if callable(close):
        ctx.on_close(f"{kind} ({name})", close)
    return backend
