"""Every command-line option, declared once: its type, unit, valid range, default and help.

A command lists its options (`OPTIONS` in each cmd_*.py, most taken from the shared ones
below) and `add_options` turns them into argparse arguments whose `type` checks the value as
argparse reads it, before anything runs: a bad value ends the command with exit status 2 and
"argument --max-sim-s: 'nan' is not a number; valid: 1 <= S <= 86400 s". The help text shows
the same unit and range, and the tests generate their hostile values from the same table.
Adding an option to `run` and `sweep` (say `--scheme NAME[:VARIANT]`) is one `Opt` here and
its name in both commands' lists."""
from __future__ import annotations

import argparse
import dataclasses
import math
import re
import socket
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any

from host_tools.safe_io import OutputPathError, check_in_file, check_out_dir, check_out_file
from world_sim.world import LIDAR_PHASE_HELP, WHEEL_SLIP_HELP

SEED_MAX = 2**32 - 1           # seeds are what numpy's SeedSequence takes, bounded for the wire and the reader
ROBOTS_MAX = 64                # a 64-slot TDMA frame is 29 s at SF7/125 kHz; node ids are 0..255 on the wire
SIM_S_MAX = 86_400.0           # one simulated day: a trajectory point per robot and tick is kept in memory
RAY_CONNECT_TIMEOUT_S = 5.0

KINDS = ("flag", "int", "float", "text", "choice", "out_dir", "out_file", "in_file", "map", "pose", "override",
         "address", "scheme", "robot_at", "robot_share")


@dataclass(frozen=True)
class Opt:
    """One option. `flag` is '--name' (or a positional's bare name); `kind` one of KINDS;
    numbers are valid in lo..hi (inclusive; `lo_open` excludes lo)."""
    flag: str
    kind: str
    help: str
    unit: str = ""
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    default: Any = None
    choices: tuple[str, ...] | Callable[[], Iterable[str]] = ()
    nargs: str | None = None
    repeat: bool = False
    metavar: str | None = None
    dest: str | None = None
    required: bool = False
    aliases: tuple[str, ...] = ()    # older spellings of the flag, still accepted

    def __post_init__(self) -> None:
        assert self.kind in KINDS, self.kind

    @property
    def positional(self) -> bool:
        return not self.flag.startswith("-")

    def choice_list(self) -> list[str]:
        return list(self.choices() if callable(self.choices) else self.choices)

    def range_text(self) -> str:
        """'1 <= S <= 86400 s', 'N >= 1', ... ('' where there is no range)."""
        if self.kind not in ("int", "float"):
            return ""
        sym = self.metavar or ("N" if self.kind == "int" else "X")
        unit = f" {self.unit}" if self.unit else ""

        def num(v: float) -> str:
            return str(int(v)) if self.kind == "int" else f"{v:g}"

        if self.lo is not None and self.hi is not None:
            return f"{num(self.lo)} {'<' if self.lo_open else '<='} {sym} <= {num(self.hi)}{unit}"
        if self.lo is not None:
            return f"{sym} {'>' if self.lo_open else '>='} {num(self.lo)}{unit}"
        return f"{sym} <= {num(self.hi)}{unit}" if self.hi is not None else ""

    def parse(self, text: str) -> Any:
        """The typed value of `text`, or argparse.ArgumentTypeError saying what was given and
        what is valid (argparse puts the option's name in front)."""
        try:
            return _PARSERS[self.kind](self, text)
        except (ValueError, OutputPathError) as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None


def _number(opt: Opt, text: str) -> int | float:
    valid = f"valid: {opt.range_text()}"
    if opt.kind == "int":
        try:
            value: int | float = int(text.strip(), 10)
        except ValueError:
            raise ValueError(f"{text!r} is not a whole number; {valid}") from None
    else:
        try:
            value = float(text)
        except ValueError:
            raise ValueError(f"{text!r} is not a number; {valid}") from None
        if not math.isfinite(value):
            raise ValueError(f"{text!r} is not a finite number; {valid}")
    below = opt.lo is not None and (value <= opt.lo if opt.lo_open else value < opt.lo)
    above = opt.hi is not None and value > opt.hi
    if below or above:
        raise ValueError(f"{text!r} is out of range; {valid}")
    return value


def _text(opt: Opt, text: str) -> str:
    if not text.strip():
        raise ValueError("an empty value")
    if "\0" in text:
        raise ValueError(f"{text!r} holds a NUL character")
    return text


def _map(opt: Opt, text: str) -> str:
    from world_sim.map_spec import check_map_spec

    check_map_spec(text)
    return text


def _pose(opt: Opt, text: str) -> tuple[float, float, float | None]:
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) not in (2, 3) or not all(math.isfinite(v) and abs(v) <= 1e6 for v in values):
        raise ValueError(f"{text!r}: expected X,Y or X,Y,YAW_DEG as finite numbers (metres and degrees, "
                         "each within +-1e6)")
    return (values[0], values[1], math.radians(values[2]) if len(values) == 3 else None)


def _robot_and(text: str, sep: str, form: str) -> tuple[int, float]:
    """(robot index, number) of 'R<sep>X', or ValueError saying what form was expected."""
    robot, found, number = text.partition(sep)
    try:
        r, x = int(robot.strip(), 10), float(number)
    except ValueError:
        r, x = -1, math.nan
    if not found or not 0 <= r < ROBOTS_MAX or not math.isfinite(x):
        raise ValueError(f"{text!r}: expected {form}, R a robot index 0..{ROBOTS_MAX - 1}")
    return r, x


def _robot_at(opt: Opt, text: str):
    """R@S, R@P% or random: a host_tools.mission.Failure (DRAWN for random)."""
    from host_tools.mission import DRAWN, Failure

    if text == "random":
        return DRAWN
    form = "R@S, R@P% or random (robot R, S seconds into the mission or when the team has seen P % of the area)"
    if text.endswith("%"):
        r, share = _robot_and(text[:-1], "@", form)
        if not 0.0 < share <= 100.0:
            raise ValueError(f"{text!r}: P must be in (0, 100]")
        return Failure(r, at_coverage=share / 100.0)
    r, at_s = _robot_and(text, "@", form)
    if not 0.0 <= at_s <= SIM_S_MAX:
        raise ValueError(f"{text!r}: S must be 0..{SIM_S_MAX:g} s")
    return Failure(r, at_s=at_s)


def _robot_share(opt: Opt, text: str) -> tuple[int, float]:
    r, share = _robot_and(text, "=", "R=F (robot R, a share F of the limits)")
    if not 0.0 < share <= 1.0:
        raise ValueError(f"{text!r}: F must be in (0, 1]")
    return r, share


def _scheme(opt: Opt, text: str) -> str:
    """A scheme spec (NAME[:VARIANT]) or alias, as given: aliases stay the names in reports."""
    from firmware.schemes import resolve

    resolve(text)
    return text


def _override(opt: Opt, text: str) -> tuple[str, Any]:
    from host_tools.overrides import parse_override

    return parse_override(text)


def _address(opt: Opt, text: str) -> str:
    """'local', 'auto', HOST:PORT or ray://HOST:PORT; a HOST:PORT must accept a TCP connection
    within RAY_CONNECT_TIMEOUT_S, so an address where nothing listens fails now, not never."""
    if text in ("local", "auto"):
        return text
    m = re.fullmatch(r"(ray://)?(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9.-]+):(\d{1,5})", text)
    if m is None or not 1 <= int(m.group(3)) <= 65535:
        raise ValueError(f"{text!r}: expected 'local', 'auto', HOST:PORT or ray://HOST:PORT (port 1..65535)")
    host, port = m.group(2).strip("[]"), int(m.group(3))
    try:
        with socket.create_connection((host, port), timeout=RAY_CONNECT_TIMEOUT_S):
            pass
    except socket.timeout:
        raise ValueError(f"{text!r}: nothing answered at {host}:{port} within {RAY_CONNECT_TIMEOUT_S:g} s "
                         "(is the Ray head running there?)") from None
    except OSError as exc:
        raise ValueError(f"{text!r}: cannot connect to {host}:{port} ({exc.strerror or exc}; "
                         "is the Ray head running there?)") from None
    return text


_PARSERS: dict[str, Callable[[Opt, str], Any]] = {
    "int": _number, "float": _number, "text": _text, "choice": _text,
    "out_dir": lambda o, t: check_out_dir(t), "out_file": lambda o, t: check_out_file(t),
    "in_file": lambda o, t: check_in_file(t), "map": _map, "pose": _pose, "override": _override,
    "address": _address, "scheme": _scheme, "robot_at": _robot_at, "robot_share": _robot_share,
}


def help_text(opt: Opt) -> str:
    parts = [opt.help]
    rng = opt.range_text()
    if rng:
        parts.append(f"[{rng}]")
    elif opt.unit:
        parts.append(f"[{opt.unit}]")
    if opt.default not in (None, False, [], ()) and opt.kind != "flag":
        parts.append(f"(default {' '.join(map(str, opt.default)) if isinstance(opt.default, list) else opt.default})")
    return " ".join(parts).replace("%", "%%")


def add_options(parser: argparse.ArgumentParser, options: Sequence[Opt]) -> None:
    """The declared options as argparse arguments, each checked by its declaration."""
    for opt in options:
        kw: dict[str, Any] = {"help": help_text(opt)}
        if opt.kind == "flag":
            kw["action"] = "store_true"
        else:
            if opt.kind == "choice":
                kw["choices"] = opt.choice_list()
            kw["type"] = opt.parse
            if opt.repeat:
                kw["action"] = "append"
            if opt.nargs:
                kw["nargs"] = opt.nargs
            if opt.metavar:
                kw["metavar"] = opt.metavar
            # A string default is parsed (and so checked) by argparse only when the option is
            # not given; numbers are declared already typed.
            default = opt.default
            if isinstance(default, (list, tuple)):
                default = list(default)
            elif opt.repeat and default is None:
                default = []
            kw["default"] = default
        if opt.positional:
            if opt.nargs is None and not opt.required:
                kw["nargs"] = "?"
            parser.add_argument(opt.flag, **kw)
        else:
            if opt.dest:
                kw["dest"] = opt.dest
            if opt.required:
                kw["required"] = True
            parser.add_argument(opt.flag, *opt.aliases, **kw)


def with_default(opt: Opt, default: Any, help: str | None = None) -> Opt:
    return dataclasses.replace(opt, default=default, help=help or opt.help)


# ---- options more than one command takes --------------------------------------------------

def _radios() -> list[str]:
    from hal.lora import PROFILES
    return sorted(PROFILES)


# The five strategies of the first version (aliases of schemes), in the order the sweep's
# tables show them.
LEGACY_STRATEGIES = ("greedy", "minpos", "greedy-full", "minpos-full", "independent")


def _scheme_catalogue() -> str:
    from firmware.schemes import catalogue
    return "; ".join(f"{spec} {doc}" if doc.startswith("=") else f"{spec} ({doc})" for spec, doc in catalogue())


MAP = Opt("--map", "map", "PATH.yaml (ROS map_server), cave:SEED[:WxH], tunnel:SEED[:WxH] or office:SEED[:WxH]", default="cave:1")
ROBOTS = Opt("--robots", "int", "team size", unit="robots", lo=1, hi=ROBOTS_MAX, default=1)
SEED = Opt("--seed", "int", "mission seed: same seed, same result", lo=0, hi=SEED_MAX, default=0)
MAX_SIM_S = Opt("--max-sim-s", "float", "simulated time limit", unit="s", lo=1.0, hi=SIM_S_MAX, default=14400.0,
                metavar="S")
RADIO = Opt("--radio", "choice", "radio profile", choices=_radios, default="ideal-100Bps")
SCHEME = Opt("--scheme", "scheme", f"coordination scheme: {_scheme_catalogue()}", default="greedy",
             aliases=("--strategy",), dest="strategy", metavar="NAME[:VARIANT]")
SCHEMES = Opt("--schemes", "scheme", f"coordination schemes to run (default: {' '.join(LEGACY_STRATEGIES)})",
              nargs="+", default=list(LEGACY_STRATEGIES), aliases=("--strategies",), dest="strategies",
              metavar="NAME[:VARIANT]")
RANGE_M = Opt("--range-m", "float", "a hard radio range: robots farther apart than this hear nothing from each "
              "other, on any profile (the ideal link's disc model, as Pereira et al.'s 5 m); default: the profile's "
              "own reach", unit="m", lo=0.0, lo_open=True, hi=1e6, metavar="M")
FLUSH_S = Opt("--flush-s", "float", "once every robot has stopped, keep the radios going this long before the "
              "mission ends (robots parked; one that wakes up goes on), so records on their way arrive; not counted "
              "in T_total or the radio's rates; the report compares what each robot holds (scheme_digests)",
              unit="s", lo=0.0, hi=SIM_S_MAX, default=0.0, metavar="S")
FRAMES = Opt("--frames", "choice", "odometry frames: one shared by the team (start poses measured at deployment), or "
             "each robot's own, unknown to the others", choices=("shared", "own"), default="shared")
SPREAD = Opt("--spread", "float", "spread starts instead: every robot at least this much driving distance from every "
             "other, with a random yaw (from the seed); the host alone knows the poses", unit="m", lo=0.0, hi=1e4,
             default=0.0, metavar="M")
SPREAD_MAX = Opt("--spread-max", "float", "with --spread: each robot at most this much driving distance from the "
                 "nearest placed before it (0: no bound)", unit="m", lo=0.0, hi=1e4, default=0.0, metavar="M")


def check_spread(spread_m: float, spread_max_m: float) -> None:
    """Refuse a --spread-max below --spread (ValueError naming both)."""
    if spread_max_m and spread_max_m < spread_m:
        raise ValueError(f"--spread-max {spread_max_m:g} is below --spread {spread_m:g}")


FAIL = Opt("--fail", "robot_at", "robot R fails S seconds into the mission (R@S) or once the team has seen P % of the "
           "reachable area (R@P%): from then on it does nothing (no driving, radio, UWB or WiFi) and the others go "
           "on; repeatable. random: a robot drawn from the seed fails once the team has seen a share drawn from "
           "the seed in [50 %, 70 %]", repeat=True, metavar="R@S|R@P%|random", dest="failures")
SLOW = Opt("--slow", "robot_share", "robot R's drive reaches only the share F (0 < F <= 1) of the speed and turn-rate "
           "limits; its firmware is not told; repeatable", repeat=True, metavar="R=F", dest="speed_factors")
WHEEL_SLIP = Opt("--wheel-slip", "float", WHEEL_SLIP_HELP, lo=0.0, hi=1.0, default=0.0,
                 metavar="FRAC")
LIDAR_PHASE = Opt("--lidar-phase-ms", "float", LIDAR_PHASE_HELP, unit="ms", lo=0.0, hi=99.999,
                  default=0.0, metavar="MS")
SET = Opt("--set", "override", "change an explorer parameter (firmware/params.py; the list is below); repeatable",
          repeat=True, metavar="NAME=VALUE", dest="overrides")
JSON = Opt("--json", "flag", "print one JSON object instead of the summary")
QUIET = Opt("--quiet", "flag", "no progress bar")


def options_of(module: Any) -> Sequence[Opt]:
    """A command module's declared options."""
    return module.OPTIONS
