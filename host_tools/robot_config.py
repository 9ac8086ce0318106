"""A robot's configuration file for `lorascout robot`: TOML, one table per peripheral.

    [robot]      id, team_size, scheme, radio_profile          (ROBOT_SETTINGS)
    [params]     explorer parameters, as `--set` takes them    (firmware/params.py)
    [params.S]   scheme S's own parameters (`--set S.NAME=VALUE`; firmware/declared.py)
    [world]      the simulated world, when a backend is "sim"  (hal.sim.realtime_world)
    [clock] [lidar] [odometry] [drive] [radio] [uwb] [aoa] [mesh]
                 backend = NAME (hal.registry), and that backend's settings (its SETTINGS)

`load_robot_config` reads and checks the whole file before anything is opened: an unknown
table or key, a missing one, a value of the wrong type or out of range, an unknown backend,
a scheme that needs a peripheral the robot lacks: each is a RobotConfigError naming the file,
the table and the key (and, for TOML syntax, the line and column). `open_robot` then builds
the HAL through the registry, in PERIPHERALS order, and the firmware on it; if anything
fails, what was opened is closed again.
"""
from __future__ import annotations

import textwrap
import tomllib
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from firmware.agent import ExplorerAgent
from firmware.params import TaskRates
from firmware.schemes import build as build_scheme, resolve as resolve_scheme
from firmware.schemes.base import NEEDS
from hal.bundle import Hal
from hal.config import BuildContext, ConfigError, Setting, check_settings
from hal.lora import PROFILES
from hal.registry import BACKENDS, backend_class, build_backend, check_backend
from host_tools.options import ROBOTS_MAX
from host_tools.overrides import Overrides, check_schemes_used, overrides_from_table, params_with, scheme_settings

# Built in this order: the clock first, because backends stamp samples with it.
PERIPHERALS = ("clock", "lidar", "odometry", "drive", "radio", "uwb", "aoa", "mesh")
REQUIRED_PERIPHERALS = ("lidar", "odometry", "drive")
# A table left out: the wall clock, and no optional peripheral (hal.null).
DEFAULT_BACKENDS = {"clock": "monotonic", "radio": "null", "uwb": "null", "aoa": "null", "mesh": "null"}
OTHER_TABLES = ("robot", "params", "world")
# Resources backends ask the BuildContext for, and the table that provides each.
RESOURCE_TABLES = {"sim-world": "world"}


def _check_scheme(spec: str) -> None:
    resolve_scheme(spec)


ROBOT_SETTINGS = (
    Setting("id", "int", "this robot's id: its node id on the radio, 0 .. team_size - 1", lo=0, hi=ROBOTS_MAX - 1),
    Setting("team_size", "int", "robots in the team (one TDMA slot each on a shared channel)", unit="robots",
            default=1, lo=1, hi=ROBOTS_MAX),
    Setting("scheme", "text", "coordination scheme, NAME[:VARIANT] as `lorascout run --scheme` takes it",
            check=_check_scheme),
    Setting("radio_profile", "text", "the team's radio profile (needed when a radio is fitted)", default=None,
            choices=tuple(sorted(PROFILES))),
)


class RobotConfigError(ValueError):
    """A configuration that cannot be run; the message names the file, table and key."""


@dataclass(frozen=True)
class Peripheral:
    kind: str                   # hal.registry kind: "drive", "radio", ...
    backend: str                # registry name: "odrive-can", "null", ...
    settings: dict[str, Any]    # checked (hal.registry.check_backend)


@dataclass(frozen=True)
class RobotConfig:
    path: str
    robot_id: int
    team_size: int
    scheme: str
    radio_profile: str | None
    overrides: Overrides
    world: dict[str, Any] | None          # checked [world] settings, if the table is there
    peripherals: tuple[Peripheral, ...]   # in PERIPHERALS order, every kind present

    def backend(self, kind: str) -> str:
        return next(p.backend for p in self.peripherals if p.kind == kind)

    def fitted(self, kind: str) -> bool:
        return self.backend(kind) != "null"

    def describe(self) -> dict:
        """What will be built, JSON-able (for --check and the run's summary)."""
        return {"config": self.path, "robot_id": self.robot_id, "team_size": self.team_size, "scheme": self.scheme,
                "radio_profile": self.radio_profile, "params_overrides": dict(self.overrides),
                "world": self.world, "peripherals": {p.kind: {"backend": p.backend, **p.settings}
                                                     for p in self.peripherals}}


# ---- reading and checking ------------------------------------------------------------------

def load_robot_config(path: str | Path) -> RobotConfig:
    """The checked configuration in `path`; RobotConfigError naming file, table and key."""
    doc = _read_toml(path)
    where = str(path)
    _check_tables(where, doc)
    robot_table, params_table = _table(where, doc, "robot", required=True), _table(where, doc, "params")
    robot = _in_table(where, "robot", lambda: _robot_settings(robot_table))
    overrides = _in_table(where, "params", lambda: overrides_from_table(params_table))
    world = None
    if "world" in doc:
        from hal.sim.realtime_world import checked_world_settings

        world = _in_table(where, "world", lambda: checked_world_settings(doc["world"]))
    peripherals = tuple(_peripheral(where, doc, kind) for kind in PERIPHERALS)
    cfg = RobotConfig(path=where, robot_id=robot["id"], team_size=robot["team_size"], scheme=robot["scheme"],
                      radio_profile=robot.get("radio_profile"), overrides=overrides, world=world,
                      peripherals=peripherals)
    _in_table(where, "params", lambda: check_schemes_used(overrides, [cfg.scheme], "[robot] scheme =", given_as=""))
    _check_resources(cfg)
    _check_agreements(cfg)
    _check_scheme_needs(cfg)
    return cfg


def _read_toml(path: str | Path) -> dict:
    try:
        raw = Path(path).read_bytes()
    except OSError as exc:
        raise RobotConfigError(f"{path}: cannot read it: {exc.strerror or exc}") from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        raise RobotConfigError(f"{path}: not UTF-8 text (line {line}, byte {exc.start}): TOML files are UTF-8") \
            from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise RobotConfigError(f"{path}: TOML syntax: {exc}") from None   # the message gives line and column


def _check_tables(where: str, doc: Mapping[str, Any]) -> None:
    known = OTHER_TABLES + PERIPHERALS
    for name, value in doc.items():
        if not isinstance(value, dict):
            raise RobotConfigError(f"{where}: {name}: a key outside every table; settings belong in a table "
                                   f"({', '.join(f'[{t}]' for t in known)})")
        if name not in known:
            raise RobotConfigError(f"{where}: [{name}]: unknown table; known: {', '.join(known)}")


def _table(where: str, doc: Mapping[str, Any], name: str, required: bool = False) -> dict:
    if name not in doc:
        if required:
            raise RobotConfigError(f"{where}: [{name}]: missing table")
        return {}
    return doc[name]


def _in_table(where: str, table: str, check):
    """check(), with a ConfigError or ValueError it raises put in the file and table."""
    try:
        return check()
    except ValueError as exc:            # hal.config.ConfigError among them
        raise RobotConfigError(f"{where}: [{table}] {exc}") from None


def _robot_settings(table: Mapping[str, Any]) -> dict:
    robot = check_settings(ROBOT_SETTINGS, table)
    if robot["id"] >= robot["team_size"]:
        raise ConfigError("id", f"{robot['id']} is not below team_size = {robot['team_size']} (ids are "
                          f"0 .. team_size - 1)")
    return robot


def _peripheral(where: str, doc: Mapping[str, Any], kind: str) -> Peripheral:
    if kind not in doc:
        if kind in REQUIRED_PERIPHERALS:
            raise RobotConfigError(f"{where}: [{kind}]: missing table: every robot has a {kind} "
                                   f"(backend = one of {_names(kind)})")
        return Peripheral(kind, DEFAULT_BACKENDS[kind], {})
    table = dict(doc[kind])
    if "backend" not in table:
        raise RobotConfigError(f"{where}: [{kind}] backend: missing: which {kind} this is, one of {_names(kind)}")
    name = table.pop("backend")
    if not isinstance(name, str) or name not in BACKENDS[kind]:
        raise RobotConfigError(f"{where}: [{kind}] backend: {name!r} is no {kind} backend; known: {_names(kind)}")
    settings = _in_table(where, kind, lambda: check_backend(kind, name, table))
    return Peripheral(kind, name, settings)


def _names(kind: str) -> str:
    return ", ".join(repr(n) for n in BACKENDS[kind])


def _check_resources(cfg: RobotConfig) -> None:
    """Every resource a backend needs is provided by its table, and every such table used."""
    used = set()
    for p in cfg.peripherals:
        for resource in backend_class(p.kind, p.backend).RESOURCES:
            table = RESOURCE_TABLES[resource]
            used.add(table)
            if table == "world" and cfg.world is None:
                raise RobotConfigError(f"{cfg.path}: [{p.kind}] backend: {p.backend!r} needs a [world] table "
                                       "(the simulated world it is part of: map = ..., seed = ...)")
    if cfg.world is not None and "world" not in used:
        raise RobotConfigError(f"{cfg.path}: [world]: no peripheral is simulated (none has backend = 'sim'); "
                               "remove the table or simulate one")


def _check_agreements(cfg: RobotConfig) -> None:
    """Two tables on one device (the ODrive drive and odometry) describe it the same way."""
    by_kind = {p.kind: p for p in cfg.peripherals}
    for p in cfg.peripherals:
        for other_kind, keys in getattr(backend_class(p.kind, p.backend), "AGREES_WITH", {}).items():
            other = by_kind[other_kind]
            if other.backend != p.backend:
                continue
            for key in keys:
                if p.settings.get(key) != other.settings.get(key):
                    raise RobotConfigError(
                        f"{cfg.path}: [{p.kind}] {key}: {p.settings.get(key)!r}, but [{other_kind}] {key} is "
                        f"{other.settings.get(key)!r}: both tables describe one {p.backend} device")


def _check_scheme_needs(cfg: RobotConfig) -> None:
    """The peripherals the scheme needs are fitted (the agent checks again when it starts;
    here it is found before any device is opened)."""
    radio_fitted = cfg.fitted("radio")
    if radio_fitted and cfg.radio_profile is None:
        raise RobotConfigError(f"{cfg.path}: [robot] radio_profile: missing: the [radio] "
                               f"({cfg.backend('radio')}) needs the team's radio profile, one of "
                               f"{', '.join(sorted(PROFILES))}")
    for need in sorted(build_scheme(cfg.scheme, scheme_settings(cfg.overrides)).needs_of()):
        if need in SIMULATOR_ONLY_NEEDS:
            raise RobotConfigError(f"{cfg.path}: [robot] scheme: {cfg.scheme} needs {need} ({NEEDS[need]}), which "
                                   "only the simulator's missions give (lorascout run)")
        kind = "radio" if need == "relay" else need
        if kind in PERIPHERALS and not cfg.fitted(kind):
            raise RobotConfigError(f"{cfg.path}: [robot] scheme: {cfg.scheme} needs {need} ({NEEDS[need]}), but "
                                   f"this robot has no [{kind}] (backend 'null')")


# What a scheme may need that a robot's configuration cannot give: the simulator's missions
# hand it over from the ground truth (host_tools.mission).
SIMULATOR_ONLY_NEEDS = ("floor_plan", "region_map")


# ---- building ----------------------------------------------------------------------------------

class DeviceError(RuntimeError):
    """A peripheral that could not be opened or started; the message names its table."""


@dataclass
class Robot:
    """A robot built from its configuration: the HAL, the firmware (set up), and the
    context that closes every device."""
    config: RobotConfig
    hal: Hal
    agent: ExplorerAgent
    ctx: BuildContext


def open_robot(cfg: RobotConfig, rates: TaskRates = TaskRates(),
               on_ready: Callable[[], None] | None = None) -> Robot:
    """Open the simulated world, if any, then every peripheral (through hal.registry), and set
    the firmware up on them. RobotConfigError for a world the robot cannot start in;
    DeviceError naming the table of a device that failed; everything opened before it is
    closed again (so is everything if the firmware's setup fails, or anything interrupts it
    before `on_ready()`, called last, returns)."""
    ctx = _context(cfg)
    try:
        if cfg.world is not None:
            _open_world(cfg, ctx)
        devices = {}
        for p in cfg.peripherals:
            devices[p.kind] = _open(p, ctx)
            if p.kind == "clock":
                ctx.clock = devices["clock"]
        hal = Hal(robot_id=cfg.robot_id, **devices)
        profile = PROFILES[cfg.radio_profile] if cfg.radio_profile is not None else None
        scheme = build_scheme(cfg.scheme, scheme_settings(cfg.overrides))
        agent = ExplorerAgent(hal, params_with(cfg.overrides), rates, scheme, profile, team_size=cfg.team_size)
        agent.setup()
        if on_ready is not None:
            on_ready()
    except BaseException:
        ctx.close()
        raise
    return Robot(cfg, hal, agent, ctx)


def _context(cfg: RobotConfig) -> BuildContext:
    providers = {}
    if cfg.world is not None:
        from hal.sim.realtime_world import RealTimeWorld

        providers["sim-world"] = lambda ctx: RealTimeWorld.open(ctx, cfg.world)
    profile = PROFILES[cfg.radio_profile] if cfg.radio_profile is not None else None
    return BuildContext(cfg.robot_id, profile, providers)


def _open_world(cfg: RobotConfig, ctx: BuildContext) -> None:
    """The simulated world, before any device: a start where the body does not fit is the
    configuration's mistake (RobotConfigError), found before anything else is opened."""
    try:
        ctx.resource("sim-world")
    except ValueError as exc:
        raise RobotConfigError(f"{cfg.path}: [world] {exc}") from None


def _open(p: Peripheral, ctx: BuildContext):
    try:
        return build_backend(p.kind, p.backend, p.settings, ctx)
    except Exception as exc:        # noqa: BLE001 - any failure to open a device ends start-up, named
        raise DeviceError(f"[{p.kind}] backend = {p.backend!r}: cannot start: {type(exc).__name__}: {exc}") from exc



# ---- documentation -------------------------------------------------------------------------

def config_help() -> str:
    """The configuration file's tables, backends and keys, for `lorascout robot --help`:
    generated from the declarations the checks use."""
    from hal.sim.realtime_world import WORLD_SETTINGS

    lines = ["configuration file (TOML; examples/robot-sim.toml, examples/robot-real.toml):", "  [robot]",
             *(_indented(s.help_line(), 4) for s in ROBOT_SETTINGS),
             "  [params]", _indented("explorer parameters, NAME = VALUE, as --set takes them (lorascout run --help "
                                     "lists them)", 4),
             "  [params.SCHEME]", _indented("the scheme's own parameters, NAME = VALUE, as --set SCHEME.NAME=VALUE "
                                            "takes them", 4),
             "  [world]  the simulated world the 'sim' backends are part of, stepped to the wall clock",
             *(_indented(s.help_line(), 4) for s in WORLD_SETTINGS)]
    for kind in PERIPHERALS:
        absent = ("required" if kind in REQUIRED_PERIPHERALS
                  else f"without the table: backend {DEFAULT_BACKENDS[kind]!r}")
        lines.append(f"  [{kind}]  backend = {' | '.join(repr(n) for n in BACKENDS[kind])}  ({absent})")
        for name in BACKENDS[kind]:
            cls = backend_class(kind, name)
            if cls.SETTINGS:
                lines.append(f"    backend {name!r}:")
                lines.extend(_indented(s.help_line(), 6) for s in cls.SETTINGS)
    return "\n".join(lines)


def _indented(text: str, indent: int) -> str:
    """`text` wrapped to 100 columns, indented, its continuation lines a little more."""
    return textwrap.fill(text, width=100, initial_indent=" " * indent, subsequent_indent=" " * (indent + 4))
