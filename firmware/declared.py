"""Parameter classes that declare each field's unit, valid range and meaning: the schemes'
own parameters (WiserxParams, MrTopoParams, EkfParams).

A class is a frozen dataclass whose fields are made with `number`, `flag` or `choice`, and
whose __post_init__ calls `check_declared(self)`. A field made with a plain default (a tuple,
say) is the scheme's to keep: it is not checked and `--set` does not offer it.

`--set SCHEME.NAME=VALUE` parses, checks, lists and documents these from the declaration
(host_tools/overrides.py), as it does the explorer's own parameters (firmware/params.py).
Ranges are inclusive.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import Field, field
from typing import Any


def number(default: float | int, unit: str, lo: float, hi: float, doc: str) -> Any:
    """A float (or, with an int default, an int) within [lo, hi], in `unit`."""
    return field(default=default, metadata={"unit": unit, "lo": lo, "hi": hi, "doc": doc})


def flag(default: bool, doc: str) -> Any:
    return field(default=default, metadata={"unit": "bool", "doc": doc})


def choice(default: str, choices: tuple[str, ...], doc: str) -> Any:
    return field(default=default, metadata={"unit": "", "choices": choices, "doc": doc})


def kind(f: Field) -> str | None:
    """'bool', 'int', 'float' or 'choice'; None for a field that is not declared."""
    m = f.metadata
    if "choices" in m:
        return "choice"
    if "doc" not in m:
        return None
    if isinstance(f.default, bool):
        return "bool"
    return "int" if isinstance(f.default, int) else "float"


def declared_fields(cls: type) -> list[Field]:
    """The declared fields of a parameter class, in declaration order."""
    return [f for f in dataclasses.fields(cls) if kind(f) is not None]


def range_text(f: Field, name: str | None = None) -> str:
    """The valid values as text, e.g. '0 <= kappa1_m <= 1000 m' or 'fill_rule is disc or pts2'."""
    name = name or f.name
    k, m = kind(f), f.metadata
    if k == "bool":
        return f"{name} is true or false"
    if k == "choice":
        return f"{name} is {' or '.join(m['choices'])}"
    unit = "" if m["unit"] in ("", "1") else f" {m['unit']}"
    return f"{m['lo']:g} <= {name} <= {m['hi']:g}{unit}"


def check_value(f: Field, value: Any, owner: str) -> None:
    """ValueError naming owner.field, the value and the valid values, unless value is one."""
    k = kind(f)
    where = f"{owner}.{f.name} = {value!r}"
    if k == "bool":
        if not isinstance(value, bool):
            raise ValueError(f"{where}: takes true or false")
        return
    if k == "choice":
        if value not in f.metadata["choices"]:
            raise ValueError(f"{where}: {range_text(f)}")
        return
    ok_type = isinstance(value, int) if k == "int" else isinstance(value, (int, float))
    if isinstance(value, bool) or not ok_type:
        raise ValueError(f"{where}: takes {'an integer' if k == 'int' else 'a number'} ({range_text(f)})")
    if not math.isfinite(value) or not f.metadata["lo"] <= value <= f.metadata["hi"]:
        raise ValueError(f"{where} is outside the valid range {range_text(f)}")


def check_declared(obj: Any) -> None:
    """Every declared field of a parameter object within its declaration; ValueError naming
    the first that is not."""
    for f in declared_fields(type(obj)):
        check_value(f, getattr(obj, f.name), type(obj).__name__)
