"""Coordination strategies (Bayer & Faigl IV-C and their baselines) and what a robot knows
of its team."""
from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class Strategy:
    name: str
    ranking: str              # "greedy" (eq. 5, closest target) or "minpos" (eq. 6)
    shares_topology: bool     # 12-byte topological records over the LoRa link
    shares_dense_map: bool    # keyframe scans over an unconstrained link (the baselines)
    doc: str


STRATEGIES: dict[str, Strategy] = {s.name: s for s in (
    Strategy("greedy", "greedy", True, False, "closest target on the shared topological map"),
    Strategy("minpos", "minpos", True, False, "lowest MinPos rank on the shared topological map, ties by Greedy"),
    Strategy("greedy-full", "greedy", True, True, "Greedy with dense maps shared over an unconstrained link"),
    Strategy("minpos-full", "minpos", True, True, "MinPos with dense maps shared over an unconstrained link"),
    Strategy("independent", "greedy", False, False, "no communication at all"),
)}


def strategy(name: str) -> Strategy:
    try:
        return STRATEGIES[name]
    except KeyError:
        raise KeyError(f"unknown strategy {name!r}; known: {', '.join(STRATEGIES)}") from None


@dataclass
class TeamView:
    """The rest of the team as this robot last heard of it."""

    robot_id: int
    strategy: Strategy
    positions: dict[int, tuple[float, float]] = field(default_factory=dict)  # latest, by robot id
