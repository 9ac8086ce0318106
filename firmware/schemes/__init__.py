"""The coordination schemes, found by name (python-can's backend registry pattern): a name
maps to (module, class), and only the scheme asked for is imported.

Adding a scheme: write its package under firmware/schemes/ (a firmware.schemes.base.Scheme
subclass, with its records' dialect in records.py if it sends any) and add one line to
SCHEMES. Its dialect then is in all_dialects(): every node decodes it. Its own parameters,
if it declares a params_type, are set with `--set NAME.FIELD=VALUE` (build's settings).

A scheme is asked for as NAME or NAME:VARIANT (`bayer-faigl:minpos`); the strategy names of
the first version (`minpos`, `greedy-full`, ...) stay valid as aliases.
"""
from __future__ import annotations

import dataclasses
import functools
import importlib
from collections.abc import Iterable
from typing import Any

from firmware.comms.schema import CORE, DialectSet
from firmware.schemes.base import Scheme

SCHEMES: dict[str, tuple[str, str]] = {
    "bayer-faigl": ("firmware.schemes.bayer_faigl", "BayerFaigl"),
    "dense": ("firmware.schemes.dense_baseline", "DenseBaseline"),
    "independent": ("firmware.schemes.independent", "Independent"),
    "meier": ("firmware.schemes.meier.scheme", "Meier"),
    "pereira": ("firmware.schemes.pereira.scheme", "Pereira"),
    "wiserx": ("firmware.schemes.wiserx.scheme", "Wiserx"),
    "mrtopomap": ("firmware.schemes.mr_topomap.scheme", "MrTopoMap"),
    "divide": ("firmware.schemes.divide.scheme", "Divide"),
}

ALIASES: dict[str, str] = {
    "greedy": "bayer-faigl:greedy",
    "minpos": "bayer-faigl:minpos",
    "greedy-full": "dense:greedy",
    "minpos-full": "dense:minpos",
    "meier-full": "dense:meier",
    "pereira-oracle": "pereira:oracle",
    "pereira-nogossip": "pereira:nogossip",
    "wiserx-blind": "wiserx:blind",
    "wiserx-lora": "wiserx:lora",
    "mrtopomap-literal": "mrtopomap:literal",
}


def scheme_class(name: str) -> type[Scheme]:
    try:
        module, cls = SCHEMES[name]
    except KeyError:
        raise ValueError(f"unknown scheme {name!r}; known: {', '.join(SCHEMES)} "
                         f"(or one of {', '.join(ALIASES)})") from None
    return getattr(importlib.import_module(module), cls)


def resolve(spec: str) -> tuple[str, str]:
    """(scheme name, variant) of NAME, NAME:VARIANT or an alias; ValueError naming what is
    unknown. An empty variant means the scheme's default."""
    name, _, variant = ALIASES.get(spec, spec).partition(":")
    return name, scheme_class(name).checked_variant(variant)


Settings = Iterable[tuple[str, Any]]    # ("SCHEME.FIELD", value), as `--set` gives them


def params_of(spec: str, settings: Settings = ()) -> Any | None:
    """The parameters the scheme of `spec` runs with: its variant's defaults, changed by the
    settings that name this scheme (the others are not its business). None for a scheme
    without parameters of its own. ValueError naming a setting the scheme has no field for,
    or a value its parameters refuse."""
    name, variant = resolve(spec)
    cls = scheme_class(name)
    changes = {key.partition(".")[2]: value for key, value in settings if key.partition(".")[0] == name}
    if cls.params_type is None:
        if changes:
            raise ValueError(f"scheme {name!r} has no parameters of its own to set ({', '.join(changes)})")
        return None
    fields = {f.name for f in dataclasses.fields(cls.params_type)}
    for field_name in changes:
        if field_name not in fields:
            raise ValueError(f"scheme {name!r} has no parameter {field_name!r}")
    return dataclasses.replace(cls.default_params(variant), **changes)


def build(spec: str, settings: Settings = ()) -> Scheme:
    """The scheme of `spec`, with its parameters changed by the settings that name it."""
    name, variant = resolve(spec)
    settings = tuple(settings)
    if not any(key.partition(".")[0] == name for key, _ in settings):
        return scheme_class(name)(variant)
    return scheme_class(name)(variant, params=params_of(spec, settings))


def specs() -> list[str]:
    """NAME:VARIANT (or NAME) of every registered scheme and variant."""
    return [f"{name}:{variant}" if variant else name for name in SCHEMES for variant in scheme_class(name).variants]


def catalogue() -> list[tuple[str, str]]:
    """(spec, what it does) for every scheme and variant, and every alias, for --help."""
    out = []
    for spec in specs():
        name, variant = resolve(spec)
        out.append((spec, scheme_class(name).variants[variant]))
    out.extend((alias, f"= {spec}") for alias, spec in ALIASES.items())
    return out


@functools.cache
def all_dialects() -> DialectSet:
    """The core dialect plus every registered scheme's dialect: what every node decodes.
    A scheme class without a dialect of its own (none, or one taken from a scheme it
    composes at run time) adds nothing; that scheme's dialect comes with its own line."""
    return DialectSet([CORE] + [d for name in SCHEMES if (d := scheme_class(name).dialect) is not None])
