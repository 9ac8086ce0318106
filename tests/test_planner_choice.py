"""The planner settles its grid search only as far as the choice of a target needs
(services.planner.settle_choice_costs). The choice must be the one costing every candidate
gives: the same candidate, at the same cost, through a sequence of choices in which each
chosen candidate is taken away again (as when its route fails)."""
import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from firmware.params import ExplorationParams
from firmware.services.grid_paths import GridPaths
from firmware.services.planner import settle_choice_costs
from firmware.services.targets import Candidate, Target, TargetKeeper
from firmware.services.waypoints import WaypointSet

RES = 0.1


def _case(seed: int):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(8, 40))
    traversable = rng.random((n, n)) < rng.uniform(0.5, 0.9)
    si, sj = (int(v) for v in rng.integers(0, n, 2))
    traversable[si, sj] = True
    # Uniform costs half the time: equal path costs, and so ties the choice breaks by position.
    cell_cost = 1.0 + (rng.integers(0, 3, (n, n)) if rng.random() < 0.5 else np.zeros((n, n))).astype(np.float64)
    paths = GridPaths(traversable, cell_cost, si, sj)
    candidates = []
    for _ in range(int(rng.integers(1, 12))):
        i, j = (int(v) for v in rng.integers(0, n, 2))
        # Some candidates share a cost class on purpose: whole-metre graph costs tie often.
        graph = float(rng.integers(0, 8)) if rng.random() < 0.8 else math.inf
        # A scheme's penalty (a utility discount) on some: whole metres tie with costs too.
        penalty = float(rng.choice([0.0, float(rng.integers(1, 4)), float(rng.uniform(0.0, 3.0))]))
        c = Candidate(x_m=j + 0.5, y_m=i + 0.5, e_bit=100.0, from_team=False, graph_cost_m=graph,
                      rank=int(rng.integers(0, 3)), penalty_m=penalty)
        c.local_cell = (i, j) if paths.reachable[i, j] else None
        c.cost_m = math.inf if c.local_cell is not None else graph
        candidates.append(c)
    target = None
    if rng.random() < 0.5:
        t = candidates[int(rng.integers(0, len(candidates)))]
        target = Target(t.x_m, t.y_m, 1.0)
    return traversable, cell_cost, (si, sj), candidates, target


def _choices(candidates, target, settle):
    keeper = TargetKeeper(ExplorationParams(), WaypointSet(ExplorationParams()))
    keeper.target = target
    out = []
    while candidates:
        settle(candidates)
        c = keeper.choose(candidates)
        out.append((c.x_m, c.y_m, c.cost_m))
        candidates = [k for k in candidates if k is not c]
    return out


@settings(max_examples=300, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_the_bounded_search_chooses_as_the_full_search_does(seed):
    traversable, cell_cost, (si, sj), candidates, target = _case(seed)
    lazy_paths = GridPaths(traversable, cell_cost, si, sj)
    lazy = _choices([Candidate(**vars(c)) for c in candidates], target,
                    lambda cs: settle_choice_costs(cs, lazy_paths, target, RES))

    full_paths = GridPaths(traversable, cell_cost, si, sj)
    full_paths.settle(*np.nonzero(traversable))

    def cost_all(cs):
        for c in cs:
            if c.local_cell is not None:
                c.cost_m = float(full_paths.dist[c.local_cell]) * RES
    assert lazy == _choices([Candidate(**vars(c)) for c in candidates], target, cost_all)


def test_a_tie_in_cost_goes_to_the_lower_position_even_when_the_search_meets_the_other_first():
    """Two grid candidates at the same cost: the search settles the one of lower flat index
    (row-major) first, the choice breaks the tie by x then y. The bound must cover both."""
    traversable = np.ones((11, 11), bool)
    cell_cost = np.ones((11, 11))
    paths = GridPaths(traversable, cell_cost, 5, 5)
    first_met = Candidate(6.5, 4.5, 100.0, False, rank=0)      # row 4, column 6: settled first
    lower_x = Candidate(4.5, 6.5, 100.0, False, rank=0)        # row 6, column 4: the choice
    for c in (first_met, lower_x):
        c.local_cell = (int(c.y_m), int(c.x_m))
    settle_choice_costs([first_met, lower_x], paths, None, RES)
    assert first_met.cost_m == lower_x.cost_m == math.sqrt(2) * RES
    keeper = TargetKeeper(ExplorationParams(), WaypointSet(ExplorationParams()))
    assert keeper.choose([first_met, lower_x]) is lower_x
