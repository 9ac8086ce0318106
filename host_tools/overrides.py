"""`--set NAME=VALUE` on `lorascout run` and `lorascout sweep`: explorer parameters
(`firmware.params.ExplorationParams`) changed for one run or a whole grid, so that a variant
of the firmware's rules is measured by a command, and recorded with its results. A robot's
configuration file (`lorascout robot`) changes them in its [params] table, checked the same way.

Types, units and valid ranges come from the parameters' declaration in firmware/params.py;
so do the list in `--help` (`params_help`) and the README's table (`params_markdown`)."""
from __future__ import annotations

import dataclasses
import sys

from firmware.params import ExplorationParams, ParamError, check_param, check_params, param_kind, param_range

Overrides = tuple[tuple[str, bool | int | float], ...]   # sorted by name

README_BLOCK = "explorer-params"     # the README block params_markdown() fills


def _parse_bool(text: str) -> bool:
    lowered = text.lower()
    if lowered in ("1", "true", "yes", "on"):
        return True
    if lowered in ("0", "false", "no", "off"):
        return False
    raise ValueError(text)


def _parse_int(text: str) -> int:
    return int(text, 10)


_PARSERS = {"bool": _parse_bool, "int": _parse_int, "float": float}


def parse_override(item: str) -> tuple[str, bool | int | float]:
    """One NAME=VALUE string as (name, typed value within the parameter's range). ValueError
    naming the item, the parameter, the value and the valid range (argparse puts the option's
    name in front)."""
    fields = {f.name for f in dataclasses.fields(ExplorationParams)}
    name, sep, text = item.partition("=")
    name, text = name.strip(), text.strip()
    if not sep or not name:
        raise ValueError(f"{item!r}: expected NAME=VALUE, e.g. target_seen_within_m=1.5")
    if name not in fields:
        raise ValueError(f"{item!r}: the explorer has no parameter {name!r} "
                         f"(firmware/params.py lists them: {', '.join(sorted(fields))})")
    kind = param_kind(name)
    try:
        value = _PARSERS[kind](text)
    except ValueError:
        raise ValueError(f"{item!r}: {name} takes a {kind}, not {text!r} ({param_range(name)})") from None
    try:
        check_param(name, value)
    except ParamError as exc:
        raise ValueError(f"{item!r}: {exc}") from None
    return name, value


def parse_overrides(items: list[str] | tuple[str, ...]) -> Overrides:
    """NAME=VALUE strings as typed values, sorted by name; the last of repeated names counts.
    ValueError with the offending item for a missing '=', an unknown name, a bad value, or a
    combination the parameters' relations forbid (e.g. logodds_min above logodds_max)."""
    pairs = []
    for item in items:
        try:
            pairs.append(parse_override(item))
        except ValueError as exc:
            raise ValueError(f"--set {exc}") from None
    return combine_overrides(pairs)


def combine_overrides(pairs: list[tuple[str, bool | int | float]]) -> Overrides:
    """Parsed (name, value) pairs as Overrides (the last of a name counts), checked together
    against the parameters' relations; ValueError naming them otherwise."""
    overrides = tuple(sorted(dict(pairs).items()))
    try:
        check_params(params_with(overrides))
    except ParamError as exc:
        raise ValueError(f"--set {describe(overrides)}: {exc}") from None
    return overrides


def overrides_from_table(table: dict) -> Overrides:
    """Typed values (a configuration file's [params] table) as Overrides: the same checks as
    `--set`, without the text: ValueError naming the parameter, the value and the valid
    range for an unknown name, a value of the wrong type (a string, a float for an int) or
    out of range, or a combination the parameters' relations forbid."""
    fields = {f.name for f in dataclasses.fields(ExplorationParams)}
    pairs = []
    for name, value in table.items():
        if name not in fields:
            raise ValueError(f"{name}: the explorer has no parameter {name!r} "
                             f"(firmware/params.py lists them: {', '.join(sorted(fields))})")
        try:
            check_param(name, value)
        except ParamError as exc:
            raise ValueError(f"{name}: {exc}") from None
        pairs.append((name, float(value) if param_kind(name) == "float" else value))
    overrides = tuple(sorted(pairs))
    try:
        check_params(params_with(overrides))
    except ParamError as exc:
        raise ValueError(str(exc)) from None
    return overrides


def params_with(overrides: Overrides) -> ExplorationParams:
    """The default parameters with the overrides applied."""
    return dataclasses.replace(ExplorationParams(), **dict(overrides))


def describe(overrides) -> str:
    """'a=1, b=true' (pairs as tuples, or as lists after a JSON round trip); '' for none."""
    return ", ".join(f"{k}={str(v).lower() if isinstance(v, bool) else v}" for k, v in overrides)


def _default(f: dataclasses.Field) -> str:
    return str(f.default).lower() if isinstance(f.default, bool) else f"{f.default:g}"


def params_help() -> str:
    """The parameters `--set` takes, one a line, for the commands' --help."""
    lines = ["explorer parameters for --set NAME=VALUE (firmware/params.py; valid range, default):"]
    for f in dataclasses.fields(ExplorationParams):
        lines.append(f"  {param_range(f.name)}, default {_default(f)}: {f.metadata['doc']}")
    return "\n".join(lines)


def params_markdown() -> str:
    """The README's table of the parameters `--set` takes."""
    lines = ["| parameter | type | unit | valid range | default | meaning |", "|---|---|---|---|---:|---|"]
    for f in dataclasses.fields(ExplorationParams):
        m = f.metadata
        if f.type == "bool":
            valid = "true, false"
        else:
            valid = (f"{m['lo']:g} {'<' if m['lo_open'] else '<='} x {'<' if m['hi_open'] else '<='} {m['hi']:g}")
        lines.append(f"| `{f.name}` | {f.type} | {m['unit'] if m['unit'] not in ('', '1', 'bool') else ''} | "
                     f"{valid} | {_default(f)} | {m['doc']} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str]) -> int:
    """`python -m host_tools.overrides README.md`: put params_markdown() into the README's
    explorer-params block."""
    from pathlib import Path

    from host_tools.readme_sync import splice
    from host_tools.safe_io import write_text

    if len(argv) != 1:
        print("usage: python -m host_tools.overrides README.md", file=sys.stderr)
        return 2
    path = Path(argv[0])
    try:
        write_text(path, splice(path.read_text(), params_markdown(), str(path), README_BLOCK))
    except (OSError, ValueError) as exc:
        print(f"host_tools.overrides: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
