"""MR-TopoMap's merges told on the air (links.py): the mrlink record's values, and how a robot
weighs its own merges against its teammates' links."""
import math

import numpy as np
from hypothesis import given, settings, strategies as st

from firmware.schemes.mr_topomap import links
from firmware.schemes.mr_topomap.merge import SE2, wrap
from firmware.schemes.mr_topomap.params import DEFAULT
from firmware.schemes.mr_topomap.records import decode_link, encode_link

poses = st.builds(SE2, st.floats(-math.pi, math.pi), st.floats(-200.0, 200.0), st.floats(-200.0, 200.0))
CENTRE = np.array([3.0, -2.0])


def _close(a: SE2, b: SE2, m: float = 0.08, rad: float = math.radians(0.2)) -> bool:
    d = a.apply(CENTRE) - b.apply(CENTRE)
    return math.hypot(*d) <= m and abs(float(wrap(a.psi - b.psi))) <= rad


@given(poses, st.integers(0, 200))
def test_a_link_carries_its_transform_within_the_records_quantisation(T, support):
    lk = links.link_of(2, 5, T, support)
    back, reason, _ = decode_link(encode_link(lk))
    assert back == lk and back.support == min(support, 63)
    assert _close(links.transform_of(back), T)


def _truth(n: int, rng) -> list[SE2]:
    """Each robot's frame in a world frame."""
    return [SE2(float(rng.uniform(-math.pi, math.pi)), *rng.uniform(-50, 50, 2)) for _ in range(n)]


def _rel(truth, a: int, b: int) -> SE2:
    """T_a<-b from the truth."""
    return truth[a].inverse().compose(truth[b])


@given(st.integers(0, 2**32 - 1))
def test_agreeing_links_keep_the_direct_merges_and_merge_the_rest_by_composition(seed):
    rng = np.random.default_rng(seed)
    truth = _truth(4, rng)
    me = 0
    direct = {1: _rel(truth, 0, 1)}                               # robot 0 merged robot 1 only
    heard = {(1, 2): _rel(truth, 1, 2), (2, 0): _rel(truth, 2, 0),   # 1 merged 2, 2 merged 0
             (3, 2): _rel(truth, 3, 2), (3, 0): _rel(truth, 3, 0)}   # 3 merged 2 and 0
    centres = {1: CENTRE, 2: CENTRE, 3: CENTRE}
    out = links.resolve(me, direct, heard, centres, DEFAULT)
    assert out[1].source == "direct" and out[1].T == direct[1]
    assert out[2].source == "transitive" and _close(out[2].T, _rel(truth, 0, 2), 1e-6, 1e-9)
    assert out[2].agreeing == 2
    # 3's one tie to robot 0 is its own merge of 0: one robot's word, not taken up.
    assert 3 not in out
    # Nor is 2's, without the composition through 1 that confirms it.
    assert 2 not in links.resolve(me, direct, {(2, 0): _rel(truth, 2, 0)}, centres, DEFAULT)


@given(st.integers(0, 2**32 - 1), st.floats(math.radians(30), math.radians(180)))
def test_a_turned_direct_merge_is_outvoted_by_the_inverse_and_a_composition_that_agree(seed, turn):
    rng = np.random.default_rng(seed)
    truth = _truth(3, rng)
    right = _rel(truth, 1, 0)
    wrong = SE2(float(wrap(right.psi + turn)), right.tx + 1.0, right.ty)       # robot 1's own merge of 0
    direct = {0: wrong, 2: _rel(truth, 1, 2)}
    heard = {(0, 1): _rel(truth, 0, 1), (2, 0): _rel(truth, 2, 0)}
    out = links.resolve(1, direct, heard, {0: CENTRE, 2: CENTRE}, DEFAULT)
    assert out[0].source == "outvoted" and _close(out[0].T, right, 1e-6, 1e-9) and out[0].agreeing == 2
    # One dissenting estimate does not outvote a direct merge: without the composition it stands.
    out = links.resolve(1, {0: wrong}, {(0, 1): _rel(truth, 0, 1)}, {0: CENTRE}, DEFAULT)
    assert out[0].source == "direct" and out[0].T == wrong


@given(st.integers(0, 2**32 - 1), st.floats(math.radians(30), math.radians(180)))
def test_a_pair_fooled_alike_stands_against_one_composition_and_falls_to_two(seed, turn):
    """Robots 0 and 1 merged each other turned by the same look-alike places: the direct
    merge and the inverse agree, and count as one piece of evidence."""
    rng = np.random.default_rng(seed)
    truth = _truth(4, rng)
    bad = SE2(turn, 1.0, 0.0)                         # how the fooled pair is off, in robot 1's frame
    wrong_10 = bad.compose(_rel(truth, 1, 0))
    direct = {0: wrong_10, 2: _rel(truth, 1, 2), 3: _rel(truth, 1, 3)}
    heard = {(0, 1): wrong_10.inverse(), (2, 0): _rel(truth, 2, 0)}
    out = links.resolve(1, direct, heard, {0: CENTRE, 2: CENTRE, 3: CENTRE}, DEFAULT)
    assert out[0].source == "direct" and out[0].T == wrong_10
    heard[(0, 3)] = _rel(truth, 0, 3)                 # a second third robot: 3 merged with 0 too
    out = links.resolve(1, direct, heard, {0: CENTRE, 2: CENTRE, 3: CENTRE}, DEFAULT)
    assert out[0].source == "outvoted" and _close(out[0].T, _rel(truth, 1, 0), 1e-6, 1e-9) and out[0].agreeing == 2


@settings(max_examples=50)
@given(st.integers(0, 2**32 - 1), st.randoms(use_true_random=False))
def test_the_outcome_is_a_function_of_the_estimates_held_not_of_the_order_heard(seed, shuffler):
    rng = np.random.default_rng(seed)
    truth = _truth(5, rng)
    direct = {j: _rel(truth, 0, j) for j in (1, 2)}
    pairs = [(a, b) for a in range(5) for b in range(5) if a != b and rng.random() < 0.5]
    heard = [((a, b), _rel(truth, a, b) if rng.random() < 0.8 else SE2(1.0, 9.0, 9.0)) for a, b in pairs]
    centres = {j: CENTRE for j in range(1, 5)}
    first = links.resolve(0, direct, dict(heard), centres, DEFAULT)
    shuffler.shuffle(heard)
    assert links.resolve(0, direct, dict(heard), centres, DEFAULT) == first


def test_ties_merge_nothing_new():
    a, b = SE2(0.0, 0.0, 0.0), SE2(math.pi, 20.0, 0.0)
    direct = {1: SE2(0.0, 0.0, 0.0), 2: SE2(0.0, 0.0, 0.0)}
    out = links.resolve(0, direct, {(1, 3): a, (2, 3): b}, {3: CENTRE}, DEFAULT)
    assert 3 not in out
