"""Backends built from configuration, as python-can builds a bus from `can.Bus(**config)`.

Every registered backend class (hal.registry) declares what it takes and builds itself:

    SETTINGS: tuple[Setting, ...]      the keys of its configuration table: kind, unit,
                                       valid range, default, meaning
    RESOURCES: tuple[str, ...]         what it needs the configuration to provide besides its
                                       own keys (the simulated world of the sim backends)
    from_config(ctx, **settings)       a classmethod: the backend, from checked settings and
                                       what the robot's BuildContext shares

Checking is apart from building: `check_settings` refuses an unknown key, a missing one, a
value of the wrong type or outside its range, naming the key, and opens nothing; a robot's
configuration is checked whole before its first device is opened.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Hashable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from hal.interfaces import Clock
from hal.lora import RadioProfile


class _Required:
    def __repr__(self) -> str:
        return "REQUIRED"


REQUIRED: Any = _Required()     # a Setting's default when the key must be given
KINDS = ("bool", "int", "float", "text")

# TOML's types as a user reads them in an error message.
_TYPE_NAMES = {bool: "a boolean", int: "an integer", float: "a number", str: "a string", list: "an array",
               dict: "a table"}


class ConfigError(ValueError):
    """A configuration value that cannot be used; `key` names the setting (None: the
    table as a whole). The configuration file's reader puts the file and table in front."""

    def __init__(self, key: str | None, message: str) -> None:
        super().__init__(f"{key}: {message}" if key else message)
        self.key = key
        self.message = message


def _number_text(value: float) -> str:
    """Whole numbers in full (4294967295, 1000000), others as %g."""
    return str(int(value)) if float(value).is_integer() and abs(value) < 1e16 else f"{value:g}"


def _type_name(value: Any) -> str:
    return _TYPE_NAMES.get(type(value), type(value).__name__)


@dataclass(frozen=True)
class Setting:
    """One key of a backend's configuration table. Numbers are valid in lo..hi (inclusive;
    `lo_open` excludes lo); `choices` lists the only valid values; `check` (raising
    ValueError) adds what a range cannot say, such as "a map spec that names a map".
    default: REQUIRED (the key must be given), None (optional: left out when not given) or
    the value used when it is not given."""

    name: str
    kind: str
    doc: str
    unit: str = ""
    default: Any = REQUIRED
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    choices: tuple = ()
    check: Callable[[Any], None] | None = None

    def __post_init__(self) -> None:
        assert self.kind in KINDS, self.kind

    def valid_text(self) -> str:
        """'0 < X <= 2 m', 'one of 1, -1', 'a string' ...: what this key accepts."""
        if self.choices:
            return "one of " + ", ".join(repr(c) if isinstance(c, str) else str(c) for c in self.choices)
        if self.kind in ("bool", "text"):
            return {"bool": "true or false", "text": "a string"}[self.kind]
        unit = f" {self.unit}" if self.unit else ""
        low = "" if self.lo is None else f"{_number_text(self.lo)} {'<' if self.lo_open else '<='} "
        high = "" if self.hi is None else f" <= {_number_text(self.hi)}"
        noun = "an integer" if self.kind == "int" else "a number"
        return f"{noun}, {low}X{high}{unit}" if low or high else f"{noun}{unit}"

    def help_line(self) -> str:
        """One line for --help: the key, what it accepts, its default, its meaning."""
        if self.default is REQUIRED:
            default = "required"
        elif self.default is None:
            default = "optional"
        elif isinstance(self.default, bool):
            default = f"default {str(self.default).lower()}"
        else:
            default = f"default {self.default!r}"
        return f"{self.name} ({self.valid_text()}; {default}): {self.doc}"

    def checked(self, value: Any) -> Any:
        """`value` as this setting's type, or ConfigError naming the key, the value and
        what is valid."""
        typed = self._typed(value)
        if self.choices and typed not in self.choices:
            raise ConfigError(self.name, f"{value!r} is not {self.valid_text()}")
        if self.kind in ("int", "float") and not self._in_range(typed):
            raise ConfigError(self.name, f"{value!r} is out of range; valid: {self.valid_text()}")
        if self.check is not None:
            try:
                self.check(typed)
            except ValueError as exc:
                raise ConfigError(self.name, str(exc)) from None
        return typed

    def _typed(self, value: Any) -> Any:
        expected = {"bool": (bool,), "int": (int,), "float": (int, float), "text": (str,)}[self.kind]
        if not isinstance(value, expected) or (self.kind != "bool" and isinstance(value, bool)):
            raise ConfigError(self.name, f"expected {self.valid_text()}, got {value!r} ({_type_name(value)})")
        if self.kind == "float":
            if not math.isfinite(value):
                raise ConfigError(self.name, f"{value!r} is not a finite number; valid: {self.valid_text()}")
            return float(value)
        if self.kind == "text" and not value.strip():
            raise ConfigError(self.name, f"an empty string; expected {self.doc}")
        return value

    def _in_range(self, value: float) -> bool:
        below = self.lo is not None and (value <= self.lo if self.lo_open else value < self.lo)
        above = self.hi is not None and value > self.hi
        return not (below or above)


def check_settings(declared: Sequence[Setting], given: Mapping[str, Any], owner: str = "this table") -> dict[str, Any]:
    """The settings from a configuration table `given`: every value typed and checked,
    defaults filled in, optional keys not given left out. ConfigError naming the first key
    that is unknown (and what `owner`, the table or backend, takes instead), missing or
    invalid."""
    known = {s.name: s for s in declared}
    for key in given:
        if key not in known:
            takes = ", ".join(known) if known else "no settings"
            raise ConfigError(key, f"unknown setting; {owner} takes {takes}")
    settings: dict[str, Any] = {}
    for s in declared:
        if s.name in given:
            settings[s.name] = s.checked(given[s.name])
        elif s.default is REQUIRED:
            raise ConfigError(s.name, f"missing: {s.doc} ({s.valid_text()})")
        elif s.default is not None:
            settings[s.name] = s.default
    return settings


class BuildContext:
    """What the backends of one robot share while they are built and run: the robot's id,
    its radio profile, its clock (set once the clock is built, for the backends that stamp
    samples), resources opened once and shared (a CAN bus that the ODrive drive and odometry
    both use; the simulated world), and everything to close at the end.

    providers: resource name -> function that opens it (the configuration's [world] table
    provides "sim-world"); a backend asks with `resource(name)`."""

    def __init__(self, robot_id: int, radio_profile: RadioProfile | None = None,
                 providers: Mapping[str, Callable[[BuildContext], Any]] | None = None) -> None:
        self.robot_id = robot_id
        self.radio_profile = radio_profile
        self.clock: Clock | None = None
        self._providers = dict(providers or {})
        self._shared: dict[Hashable, Any] = {}
        self._closers: list[tuple[str, Callable[[], None]]] = []
        # Called with the wall clock's time before every tick: what must keep up with real
        # time without being a device (a simulated world run in real time).
        self.wall_clock_followers: list[Callable[[int], None]] = []
        # name -> function giving a JSON-able dict for the run's summary.
        self.reports: dict[str, Callable[[], dict]] = {}

    def shared(self, key: Hashable, open_fn: Callable[[], Any],
               close_fn: Callable[[Any], None] | None = None) -> Any:
        """The object under `key`, opened by `open_fn()` the first time it is asked for;
        `close_fn(obj)` is then called by close()."""
        if key not in self._shared:
            obj = open_fn()
            self._shared[key] = obj
            if close_fn is not None:
                self.on_close(str(key), lambda: close_fn(obj))
        return self._shared[key]

    def resource(self, name: str) -> Any:
        """A resource the configuration provides, opened once."""
        if name not in self._providers:
            raise ConfigError(None, f"needs the resource {name!r}, which this configuration does not provide")
        return self.shared(("resource", name), lambda: self._providers[name](self))

    def on_close(self, what: str, fn: Callable[[], None]) -> None:
        self._closers.append((what, fn))

    def close(self) -> list[str]:
        """Close everything opened, the last opened first. Never raises: a device that fails
        to close must not keep the others open. Returns what failed, one line each."""
        failures = []
        while self._closers:
            what, fn = self._closers.pop()
            try:
                fn()
            except Exception as exc:       # noqa: BLE001 - reported, and the rest still closed
                failures.append(f"{what}: {type(exc).__name__}: {exc}")
        return failures
