"""`--set NAME=VALUE` on `lorascout run` and `lorascout sweep`: explorer parameters
(`firmware.params.ExplorationParams`) changed for one run or a whole grid, so that a variant
of the firmware's rules is measured by a command, and recorded with its results. A robot's
configuration file (`lorascout robot`) changes them in its [params] table, checked the same way.
`--set SCHEME.NAME=VALUE` changes a scheme's own parameters (`wiserx.tau_enabled=false`:
the scheme's params_type, firmware.schemes.base.Scheme), in a [params.SCHEME] table of a
configuration file.

Types, units and valid ranges come from the parameters' declaration in firmware/params.py
and firmware/declared.py; so do the list in `--help` (`params_help`) and the README's table
(`params_markdown`)."""
from __future__ import annotations

import dataclasses
import sys
from collections.abc import Iterable

from firmware import declared
from firmware.params import ExplorationParams, ParamError, check_param, check_params, param_kind, param_range
from firmware.schemes import SCHEMES, params_of, resolve, scheme_class

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


def _a(kind: str) -> str:
    return "an" if kind == "int" else "a"


def scheme_fields(scheme: str) -> dict[str, dataclasses.Field]:
    """The parameters `--set SCHEME.NAME=VALUE` takes for a scheme (registry name), by name;
    ValueError for an unknown scheme or one without parameters of its own."""
    if scheme not in SCHEMES:
        raise ValueError(f"no scheme {scheme!r} (the schemes with parameters of their own: "
                         f"{', '.join(schemes_with_params())})")
    cls = scheme_class(scheme)
    if cls.params_type is None:
        raise ValueError(f"scheme {scheme!r} has no parameters of its own (the schemes that have: "
                         f"{', '.join(schemes_with_params())})")
    return {f.name: f for f in declared.declared_fields(cls.params_type)}


def schemes_with_params() -> list[str]:
    return [name for name in SCHEMES if scheme_class(name).params_type is not None]


def _parse_scheme_override(item: str, name: str, text: str) -> tuple[str, bool | int | float | str]:
    scheme, _, field_name = name.partition(".")
    try:
        fields = scheme_fields(scheme)
    except ValueError as exc:
        raise ValueError(f"{item!r}: {exc}") from None
    if field_name not in fields:
        raise ValueError(f"{item!r}: scheme {scheme!r} has no parameter {field_name!r} "
                         f"(it has: {', '.join(fields)})")
    f = fields[field_name]
    kind = declared.kind(f)
    try:
        value = text if kind == "choice" else _PARSERS[kind](text)
    except ValueError:
        raise ValueError(f"{item!r}: {name} takes {_a(kind)} {kind}, not {text!r} "
                         f"({declared.range_text(f, name)})") from None
    try:
        declared.check_value(f, value, scheme)
    except ValueError as exc:
        raise ValueError(f"{item!r}: {exc}") from None
    return name, value


def parse_override(item: str) -> tuple[str, bool | int | float | str]:
    """One NAME=VALUE (or SCHEME.NAME=VALUE) string as (name, typed value within the
    parameter's range). ValueError naming the item, the parameter, the value and the valid
    range (argparse puts the option's name in front)."""
    fields = {f.name for f in dataclasses.fields(ExplorationParams)}
    name, sep, text = item.partition("=")
    name, text = name.strip(), text.strip()
    if not sep or not name:
        raise ValueError(f"{item!r}: expected NAME=VALUE, e.g. target_seen_within_m=1.5")
    if "." in name:
        return _parse_scheme_override(item, name, text)
    if name not in fields:
        raise ValueError(f"{item!r}: the explorer has no parameter {name!r} "
                         f"(firmware/params.py lists them: {', '.join(sorted(fields))})")
    kind = param_kind(name)
    try:
        value = _PARSERS[kind](text)
    except ValueError:
        raise ValueError(f"{item!r}: {name} takes {_a(kind)} {kind}, not {text!r} ({param_range(name)})") from None
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
        check_together(overrides)
    except ValueError as exc:
        raise ValueError(f"--set {describe(overrides)}: {exc}") from None
    return overrides


def check_together(overrides: Overrides) -> None:
    """The explorer's parameters against their relations, and each scheme's settings in every
    variant of the scheme; ValueError (ParamError) naming what must hold."""
    check_params(params_with(overrides))
    for scheme in sorted({name.partition(".")[0] for name, _ in scheme_settings(overrides)}):
        for variant in scheme_class(scheme).variants:
            try:
                params_of(f"{scheme}:{variant}" if variant else scheme, overrides)
            except ValueError as exc:
                raise ValueError(f"{exc} (in {scheme}:{variant})" if variant else str(exc)) from None


def scheme_settings(overrides: Overrides) -> Overrides:
    """The SCHEME.NAME settings among the overrides (what firmware.schemes.build takes)."""
    return tuple((name, value) for name, value in overrides if "." in name)


def check_schemes_used(overrides: Overrides, specs: Iterable[str], option: str, given_as: str = "--set ") -> None:
    """ValueError if a SCHEME.NAME setting names a scheme none of `specs` runs (a setting
    that would change nothing is a mistake the user wants to hear about). option: where the
    schemes were given, given_as: how the setting was (both for the message)."""
    specs = list(specs)
    used = {resolve(spec)[0] for spec in specs}
    for name, value in scheme_settings(overrides):
        if name.partition(".")[0] not in used:
            raise ValueError(f"{given_as}{describe([(name, value)])}: no scheme of this run is "
                             f"{name.partition('.')[0]!r} ({option} {' '.join(specs)})")


def overrides_from_table(table: dict) -> Overrides:
    """Typed values (a configuration file's [params] table) as Overrides: the same checks as
    `--set`, without the text: ValueError naming the parameter, the value and the valid
    range for an unknown name, a value of the wrong type (a string, a float for an int) or
    out of range, or a combination the parameters' relations forbid."""
    fields = {f.name for f in dataclasses.fields(ExplorationParams)}
    pairs = []
    for name, value in table.items():
        if isinstance(value, dict) and "." not in name:
            pairs.extend(_scheme_table(name, value))
            continue
        if name not in fields:
            raise ValueError(f"{name}: the explorer has no parameter {name!r} "
                             f"(firmware/params.py lists them: {', '.join(sorted(fields))})")
        try:
            check_param(name, value)
        except ParamError as exc:
            raise ValueError(f"{name}: {exc}") from None
        pairs.append((name, float(value) if param_kind(name) == "float" else value))
    overrides = tuple(sorted(pairs))
    check_together(overrides)
    return overrides


def _scheme_table(scheme: str, table: dict) -> list[tuple[str, bool | int | float | str]]:
    """A [params.SCHEME] table's values as (SCHEME.NAME, value), checked."""
    try:
        fields = scheme_fields(scheme)
    except ValueError as exc:
        raise ValueError(f"{scheme}: {exc}") from None
    pairs = []
    for name, value in table.items():
        if name not in fields:
            raise ValueError(f"{scheme}.{name}: scheme {scheme!r} has no parameter {name!r} "
                             f"(it has: {', '.join(fields)})")
        f = fields[name]
        declared.check_value(f, value, scheme)
        pairs.append((f"{scheme}.{name}", float(value) if declared.kind(f) == "float" else value))
    return pairs


def params_with(overrides: Overrides) -> ExplorationParams:
    """The default explorer parameters with the overrides that name them applied."""
    return dataclasses.replace(ExplorationParams(), **{name: value for name, value in overrides if "." not in name})


def describe(overrides) -> str:
    """'a=1, b=true' (pairs as tuples, or as lists after a JSON round trip); '' for none."""
    return ", ".join(f"{k}={str(v).lower() if isinstance(v, bool) else v}" for k, v in overrides)


def _default(f: dataclasses.Field) -> str:
    return str(f.default).lower() if isinstance(f.default, bool) else f"{f.default:g}"


def _scheme_default(f: dataclasses.Field) -> str:
    return f.default if declared.kind(f) == "choice" else _default(f)


def _params_module(scheme: str) -> str:
    return scheme_class(scheme).params_type.__module__.replace(".", "/") + ".py"


def params_help() -> str:
    """The parameters `--set` takes, one a line, for the commands' --help."""
    lines = ["explorer parameters for --set NAME=VALUE (firmware/params.py; valid range, default):"]
    for f in dataclasses.fields(ExplorationParams):
        lines.append(f"  {param_range(f.name)}, default {_default(f)}: {f.metadata['doc']}")
    for scheme in schemes_with_params():
        lines.append(f"scheme {scheme}'s parameters for --set {scheme}.NAME=VALUE ({_params_module(scheme)}; "
                     f"valid values, default of its default variant):")
        for f in scheme_fields(scheme).values():
            lines.append(f"  {declared.range_text(f, f'{scheme}.{f.name}')}, default {_scheme_default(f)}: "
                         f"{f.metadata['doc']}")
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
    for scheme in schemes_with_params():
        cls = scheme_class(scheme)
        lines += ["", f"Scheme `{scheme}`'s own parameters, `--set {scheme}.NAME=VALUE` ({_params_module(scheme)}; "
                  f"defaults of its default variant{_variant_note(cls)}):", "",
                  "| parameter | type | unit | valid values | default | meaning |", "|---|---|---|---|---:|---|"]
        for f in scheme_fields(scheme).values():
            kind, m = declared.kind(f), f.metadata
            valid = {"bool": "true, false", "choice": ", ".join(m.get("choices", ()))}.get(
                kind, f"{m.get('lo', 0):g} <= x <= {m.get('hi', 0):g}")
            unit = m["unit"] if m["unit"] not in ("", "1", "bool") else ""
            lines.append(f"| `{scheme}.{f.name}` | {kind} | {unit} | {valid} | {_scheme_default(f)} | {m['doc']} |")
    return "\n".join(lines) + "\n"


def _variant_note(cls) -> str:
    """Where another variant starts from other defaults: which fields, and their values."""
    base = cls.default_params(cls.default_variant)
    notes = []
    for variant in cls.variants:
        other = cls.default_params(variant)
        changed = [f"{f.name}={_text(getattr(other, f.name))}" for f in declared.declared_fields(cls.params_type)
                   if getattr(other, f.name) != getattr(base, f.name)]
        if changed:
            notes.append(f"`{cls.name}:{variant}` starts from {', '.join(changed)}")
    return "; " + "; ".join(notes) if notes else ""


def _text(value) -> str:
    return str(value).lower() if isinstance(value, bool) else f"{value:g}" if isinstance(value, float) else str(value)


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
