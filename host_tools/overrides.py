"""`--set NAME=VALUE` on `lorascout run` and `lorascout sweep`: explorer parameters
(`firmware.params.ExplorationParams`) changed for one run or a whole grid, so that a variant
of the firmware's rules is measured by a command, and recorded with its results."""
from __future__ import annotations

import dataclasses
import math

from firmware.params import ExplorationParams

Overrides = tuple[tuple[str, bool | int | float], ...]   # sorted by name


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


def parse_overrides(items: list[str] | tuple[str, ...]) -> Overrides:
    """NAME=VALUE strings as typed values, sorted by name; the last of repeated names counts.
    ValueError with the offending item for a missing '=', an unknown name or a bad value."""
    fields = {f.name: f.type for f in dataclasses.fields(ExplorationParams)}
    out: dict[str, bool | int | float] = {}
    for item in items:
        name, sep, text = item.partition("=")
        name, text = name.strip(), text.strip()
        if not sep or not name:
            raise ValueError(f"--set {item!r}: expected NAME=VALUE, e.g. target_seen_within_m=1.5")
        if name not in fields:
            raise ValueError(f"--set {item!r}: the explorer has no parameter {name!r} "
                             f"(firmware/params.py lists them: {', '.join(sorted(fields))})")
        kind = fields[name]   # the annotation as text (postponed annotations)
        try:
            value = _PARSERS[kind](text)
        except ValueError:
            raise ValueError(f"--set {item!r}: {name} takes a {kind}, not {text!r}") from None
        if isinstance(value, float) and not math.isfinite(value):
            raise ValueError(f"--set {item!r}: {name} must be a finite number")
        out[name] = value
    return tuple(sorted(out.items()))


def params_with(overrides: Overrides) -> ExplorationParams:
    """The default parameters with the overrides applied."""
    return dataclasses.replace(ExplorationParams(), **dict(overrides))


def describe(overrides) -> str:
    """'a=1, b=true' (pairs as tuples, or as lists after a JSON round trip); '' for none."""
    return ", ".join(f"{k}={str(v).lower() if isinstance(v, bool) else v}" for k, v in overrides)
