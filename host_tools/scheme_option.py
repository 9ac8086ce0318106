"""The `--scheme NAME[:VARIANT]` option (and its older spelling, `--strategy`) for every
command that runs missions: checked against the scheme registry, listed in --help."""
from __future__ import annotations

import argparse

from firmware.schemes import ALIASES, catalogue, resolve

# The five strategies of the first version, in the order the sweep's tables show them.
LEGACY_STRATEGIES = ("greedy", "minpos", "greedy-full", "minpos-full", "independent")


def scheme_spec(text: str) -> str:
    """argparse type: a scheme spec or alias, as given (aliases stay the names in reports)."""
    try:
        resolve(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None
    return text


def catalogue_help() -> str:
    return "; ".join(f"{spec} ({doc})" if not doc.startswith("=") else f"{spec} {doc}" for spec, doc in catalogue())


def add_scheme_option(p: argparse.ArgumentParser, default: str) -> None:
    p.add_argument("--scheme", "--strategy", dest="strategy", type=scheme_spec, default=default,
                   metavar="NAME[:VARIANT]",
                   help=f"coordination scheme (default %(default)s): {catalogue_help()}")


def add_schemes_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--schemes", "--strategies", dest="strategies", nargs="+", type=scheme_spec,
                   default=list(LEGACY_STRATEGIES), metavar="NAME[:VARIANT]",
                   help=f"coordination schemes (default: {' '.join(LEGACY_STRATEGIES)}): {catalogue_help()}")


assert set(LEGACY_STRATEGIES) <= set(ALIASES) | {"independent"}
