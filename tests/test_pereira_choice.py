"""Pereira goal choice and gossip (firmware/schemes/pereira/choice.py, gossip.py): labels,
the current region's margin, the four categories, eq. (3), and records crossing a chain
of robots by summaries (pereira.md 6.1 items 6, 10, 11)."""
import dataclasses
import math

import numpy as np

from firmware.params import ExplorationParams
from firmware.schemes.base import PlanningView
from firmware.schemes.pereira.choice import CURRENT, FS, FU, OTHER, Whereabouts, categorise, conflicts
from firmware.schemes.pereira.gossip import Holdings
from firmware.schemes.pereira.records import Claim, Gate, Place
from firmware.schemes.pereira.regions import fold
from firmware.services.local_map import LocalMap
from firmware.services.targets import Candidate
from tests.doubles import PlannerRig


def corridor_graph():
    """Places every metre along y = 0 from x = 0 to 10 m, one gate across at x = 5 m (regions
    L and R) and one at x = -1.5 m (a virtual region V beyond it, never entered)."""
    places = [Place(1, k + 1, k * 10, 0, 10, 1 if k else 0) for k in range(11)]
    gates = [Gate(1, 20, 50, 0, 128, 50), Gate(1, 21, -15, 0, 128, 50)]
    g = fold(places, gates)
    left, right = g.label(20, 0, 100), g.label(80, 0, 100)
    virtual = g.label(-30, 0, 100)
    return g, left, right, virtual


def test_points_are_labelled_by_the_nearest_place_with_no_gate_between():
    g, left, right, virtual = corridor_graph()
    assert len({left, right, virtual}) == 3 and g.regions[virtual].virtual
    assert g.label(45, 0, 100) == left and g.label(55, 0, 100) == right
    assert g.label(45, 500, 100) is None                  # no place within reach


def test_categories_follow_the_papers_order_and_the_margin():
    g, left, right, virtual = corridor_graph()
    pts = [(2.0, 0.0), (8.0, 0.0), (5.5, 0.3), (-3.0, 0.0)]
    labels = [g.label(round(x * 10), round(y * 10), 100) for x, y in pts]
    # In L at the start: R (entered by someone, not explored) is semi-explored, V unexplored;
    # a frontier 0.5 m beyond the gate to R is still the current region's (margin 1 m).
    assert categorise(g, labels, pts, left, None, set(), 1.0) == [CURRENT, FS, CURRENT, FU]
    # Coming back from R: R is the previous region, no longer "following".
    assert categorise(g, labels, pts, left, right, set(), 1.0) == [CURRENT, OTHER, CURRENT, FU]
    # R explored (by this robot's judgement): not semi-explored any more.
    assert categorise(g, labels, pts, left, None, {right}, 0.0) == [CURRENT, OTHER, OTHER, FU]
    assert categorise(g, labels, pts, None, None, set(), 1.0) == [OTHER] * 4


def test_the_current_region_changes_only_after_the_margin():
    g, left, right, _ = corridor_graph()
    w = Whereabouts(1.0)
    w.update(g, left, 4.6, 0.0)
    assert w.indices(g) == (left, None)
    for x in (5.4, 4.6, 5.4, 5.8, 4.9):          # wobbling across the gate line, never 1 m in R
        w.update(g, g.label(round(x * 10), 0, 100), x, 0.0)
    assert w.indices(g) == (left, None)
    for x in (5.2, 5.8, 6.3):
        w.update(g, g.label(round(x * 10), 0, 100), x, 0.0)
    assert w.indices(g) == (right, left)


def test_eq3_a_robot_takes_a_frontier_where_another_heads_only_if_closer():
    heading = [(6.0, 2)]                          # robot 2, 6 m from its goal in that region
    assert not conflicts(5.0, 1, heading) and conflicts(7.0, 1, heading)
    assert not conflicts(6.0, 1, heading) and conflicts(6.0, 3, heading)    # ties: the lower id
    assert conflicts(5.0, 1, [(6.0, 2), (4.0, 3)])                           # must beat every one
    # Symmetric: two robots heading into one region, each at the other's distance: one yields.
    assert conflicts(6.0, 2, [(6.0, 1)]) != conflicts(6.0, 1, [(6.0, 2)])


def test_holdings_count_contiguous_records_and_answer_what_a_summary_lacks():
    h = Holdings()
    for q in (1, 2, 3, 5):
        h.add("place", Place(7, q, q, 0, 5, 0))
    h.add("claim", Claim(9, 1, 0, 0, 0, 1, 0))
    assert h.upto(7) == 3 and h.upto(9) == 1 and h.upto(4) == 0
    assert not h.add("place", Place(7, 2, 2, 0, 5, 0))
    h.add("gate", Gate(7, 4, 0, 0, 0, 10))
    assert h.upto(7) == 5 and h.summary_entries(0) == ((7, 5), (9, 1))
    pushed = h.to_push(3, ((7, 2),), at_most=2)          # lags on 7, holds nothing of 9
    assert [(r.sender_id, r.oseq) for _, r in pushed] == [(7, 3), (7, 4), (9, 1)]
    assert h.to_push(7, ((9, 1),), at_most=6) == []      # its own records are never pushed back
    full = tuple((o, 0) for o in (1, 2, 3, 4, 5))
    assert h.to_push(3, full, at_most=6) == []           # a full summary says nothing of 7 and 9


def test_records_cross_a_chain_by_summaries():
    """A - B - C in a line (A and C out of range): C's records reach A through B, one hop
    per summary round."""
    held = {n: Holdings() for n in "ABC"}
    ids = {"A": 1, "B": 2, "C": 3}
    for q in range(1, 9):
        held["C"].add("place", Place(3, q, q, 0, 5, 0))
    links = {"A": "B", "B": "AC", "C": "B"}
    for _round in range(4):
        for speaker in "ABC":
            entries = held[speaker].summary_entries(0)
            for listener in links[speaker]:
                for name, r in held[listener].to_push(ids[speaker], entries, at_most=6):
                    # the push is heard by every neighbour of its sender
                    for hearer in links[listener]:
                        held[hearer].add(name, r)
    assert held["A"].upto(3) == 8 and held["B"].upto(3) == 8


def _ranked(params, near_cost_m, far_cost_m):
    """Pereira's rank of two waypoints in the same category (no regions yet: both OTHER),
    a poor one near and a rich one far, costed as the planner would have costed them."""
    rig = PlannerRig(LocalMap(params, 0.0, 0.0), "pereira", params=params)
    view = PlanningView(0.0, 0.0, 1_000_000, rig.local_map.layers().sight, None, frozenset(),
                        lambda cands: np.full(len(cands), math.inf))
    near, far = Candidate(1.0, 0.0, 300.0, False), Candidate(6.0, 0.0, 2000.0, False)
    ranked = rig.scheme.rank(view, [near, far])
    near.cost_m, far.cost_m = near_cost_m, far_cost_m
    assert near.rank == far.rank
    return rig.targets.choose(ranked), near, far


def test_within_a_category_the_choice_is_by_information_over_cost_plus_a_metre():
    """The spec's A9: U = e_bit / (cost_m + 1 m); pereira_by_cost: the cheapest."""
    p = ExplorationParams()
    chosen, near, far = _ranked(p, 1.0, 6.0)
    assert (near.gain, near.gain_cost_offset_m) == (300.0, p.pereira_cost_offset_m)
    assert chosen is far                                  # 2000 / 7 > 300 / 2
    chosen, near, far = _ranked(p, 1.0, 15.0)
    assert chosen is near                                 # 2000 / 16 < 300 / 2
    chosen, near, far = _ranked(dataclasses.replace(p, pereira_by_cost=True), 1.0, 6.0)
    assert chosen is near and not near.by_gain
