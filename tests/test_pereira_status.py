"""Pereira statuses (firmware/schemes/pereira/status.py, store.py): eq. 1 and 2, the
same-robot override and the loop rule as claims merged by set union: the join laws, the
paper's rules as properties, no clock, and convergence after partitions (pereira.md 6.1
items 4 and 5)."""
from hypothesis import given, settings, strategies as st

from firmware.schemes.pereira.records import Claim, Gate, Place
from firmware.schemes.pereira.regions import fold, signature_of
from firmware.schemes.pereira.status import ClaimSet, serial_latest, status_view
from firmware.schemes.pereira.records import serial_newer
from firmware.schemes.pereira.store import Store

SETTINGS = settings(max_examples=80, deadline=None)

# Two rooms joined through a door (gate g1 at x = 0), and a door (g2 at x = 4 m) into a room
# no one entered: regions L, R and V(g2, far side). Robot 1 drove from L into R.
PLACES = [Place(1, k, x, 0, 6, 1 if k else 0) for k, x in enumerate((-30, -20, -10, 10, 20, 30))]
GATES = [Gate(1, 10, 0, 0, 128, 25), Gate(2, 4, 40, 0, 128, 25)]
GRAPH = fold(PLACES, GATES)
G1, G2 = (0, 0, 128), (40, 0, 128)
L, R, V = range(3)
assert [r.virtual for r in GRAPH.regions] == [False, False, True]
assert GRAPH.regions[L].gate_signature == GRAPH.regions[R].gate_signature == signature_of([G1])
assert GRAPH.regions[L].signature != GRAPH.regions[R].signature      # their places differ
assert GRAPH.regions[V].signature == GRAPH.regions[V].gate_signature == signature_of([G2])
ANCHORS = [(r.anchor_x_dm, r.anchor_y_dm) for r in GRAPH.regions]
# Points that resolve to a region by the nearest place, and one that resolves to none.
PROBES = ANCHORS + [(-25, 3), (22, -4), (47, 2), (200, 200)]


def sig_at(x, y, virtual=0):
    r = GRAPH.resolve(x, y)
    return (GRAPH.regions[r].gate_signature if virtual else GRAPH.regions[r].signature) if r is not None else 0


claim_st = st.builds(
    lambda origin, oseq, at, right_sig, sig, explored, virtual: Claim(
        origin, oseq, at[0], at[1], sig_at(*at, virtual) if right_sig else sig, explored, virtual),
    st.integers(0, 4), st.integers(0, 40), st.sampled_from(PROBES), st.booleans(), st.integers(0, 65535),
    st.integers(0, 1), st.integers(0, 1))
claim_sets = st.lists(claim_st, max_size=25)
observers = st.integers(0, 5)


def view(claims, observer):
    return status_view(GRAPH, ClaimSet(claims), observer)


# ---- the join ---------------------------------------------------------------------------------

@SETTINGS
@given(claim_sets, claim_sets, claim_sets, observers)
def test_the_merge_is_a_join(a, b, c, observer):
    A, B, C = ClaimSet(a), ClaimSet(b), ClaimSet(c)
    assert A | B == B | A
    assert (A | B) | C == A | (B | C)
    assert A | A == A and A <= A | B
    v = lambda s: status_view(GRAPH, s, observer)     # noqa: E731
    assert v(A | B) == v(B | A)
    assert v((A | B) | C) == v(A | (B | C))
    assert v(A | A) == v(A)


@SETTINGS
@given(claim_sets, observers, st.randoms(use_true_random=False), st.data())
def test_loss_and_duplicates_then_redelivery_give_the_lossless_view(claims, observer, rnd, data):
    got = ClaimSet()
    arrivals = list(claims) + data.draw(st.lists(st.sampled_from(claims), max_size=10)) if claims else []
    rnd.shuffle(arrivals)
    for c in arrivals:
        if rnd.random() < 0.5:
            got = got.add(c)                           # the others are lost
    for c in reversed(claims):
        got = got.add(c)                               # redelivered, in another order
    assert status_view(GRAPH, got, observer) == view(claims, observer)


# ---- the paper's rules as properties ---------------------------------------------------------

def reference(claims, observer):
    """e^o per region, straight from the paper's rules with per-origin registers: each origin
    o != observer speaks through its newest claim among those naming the region (here every
    counter lies in 0..40, so newest is the largest; a tie goes to the retraction); the
    region is explored by others if any such claim is explored and carries the region's
    signature (a claim with the virtual bit: its gate signature)."""
    out = []
    for r, reg in enumerate(GRAPH.regions):
        by = set()
        for o in {c.sender_id for c in claims} - {observer}:
            mine = [c for c in claims if c.sender_id == o and GRAPH.resolve(c.anchor_x_dm, c.anchor_y_dm) == r]
            if mine:
                top = max(c.oseq for c in mine)
                latest = min((c for c in mine if c.oseq == top), key=lambda c: (c.explored, c))
                if latest.explored and latest.sig == (reg.gate_signature if latest.virtual else reg.signature):
                    by.add(o)
        out.append((bool(by), min(by) if by else None))
    return out


@SETTINGS
@given(claim_sets, observers)
def test_eq1_is_the_or_over_each_origins_latest_claim(claims, observer):
    v = view(claims, observer)
    assert [(s.explored_by_others, s.explorer) for s in v.regions] == reference(set(claims), observer)
    assert {c for c in v.pending} == {c for c in claims if c.sender_id != observer
                                      and GRAPH.resolve(c.anchor_x_dm, c.anchor_y_dm) is None}


@SETTINGS
@given(st.integers(0, 2), st.integers(1, 500), st.permutations(range(3)), st.booleans())
def test_a_newer_claim_of_the_same_origin_overrides_even_downwards(region, gap, order, other):
    x, y = ANCHORS[region]
    sig = GRAPH.regions[region].signature
    said = [Claim(3, 7, x, y, sig, 1, 0), Claim(3, 7 + gap, x, y, sig, 0, 0)]     # explored, then retracted
    if other:
        said.append(Claim(4, 2, x, y, sig, 1, 0))                                    # another robot's
    arrivals = ClaimSet()
    for k in order:
        if k < len(said):
            arrivals = arrivals.add(said[k])
    s = status_view(GRAPH, arrivals, observer=1).regions[region]
    assert s.explored_by_others == other and s.explorer == (4 if other else None)


def test_the_single_slot_of_the_paper_is_order_dependent_and_the_registers_are_not():
    """A3: A holds (explored, by C), hears B: explored; then C retracts. With one slot
    (e^o, r^o) per region, A drops to unexplored although B explored the region; had B's
    message come after C's retraction, A would say explored. The registers say explored
    either way."""
    def single_slot(messages):
        e, r, t = 0, None, {}
        for sender, stamp, explored in messages:
            if sender == r and stamp > t.get(sender, -1):
                e = explored                                  # same robot, newer: may decrease
            elif explored > e:
                e, r = explored, sender                       # eq. 1: the maximum
            t[sender] = max(stamp, t.get(sender, -1))
        return e

    c_claims, b_says, c_retracts = ("C", 1, 1), ("B", 1, 1), ("C", 2, 0)
    assert single_slot([c_claims, b_says, c_retracts]) == 0
    assert single_slot([c_claims, c_retracts, b_says]) == 1
    x, y = ANCHORS[R]
    sig = GRAPH.regions[R].signature
    claims = [Claim(3, 1, x, y, sig, 1, 0), Claim(2, 1, x, y, sig, 1, 0), Claim(3, 2, x, y, sig, 0, 0)]
    for order in ([0, 1, 2], [0, 2, 1], [2, 1, 0]):
        s = view([claims[k] for k in order], observer=1).regions[R]
        assert s.explored_by_others and s.explorer == 2


@SETTINGS
@given(claim_sets, claim_sets, observers)
def test_claims_of_the_observers_own_never_change_its_view(claims, own, observer):
    mine = [c._replace(sender_id=observer) for c in own]
    assert view(claims + mine, observer) == view(claims, observer)


@SETTINGS
@given(st.lists(st.builds(Place, st.integers(0, 3), st.integers(0, 30), st.integers(-60, 60),
                          st.integers(-60, 60), st.integers(0, 30), st.integers(0, 3)), max_size=25),
       st.lists(st.builds(Gate, st.integers(0, 3), st.integers(31, 40), st.integers(-60, 60), st.integers(-60, 60),
                          st.integers(0, 255), st.integers(0, 120)), max_size=5),
       st.lists(st.builds(Place, st.integers(0, 3), st.integers(41, 60), st.integers(-60, 60),
                          st.integers(-60, 60), st.integers(0, 30), st.integers(0, 3)), max_size=10),
       st.lists(st.builds(Gate, st.integers(0, 3), st.integers(61, 70), st.integers(-60, 60), st.integers(-60, 60),
                          st.integers(0, 255), st.integers(0, 120)), max_size=3))
def test_visited_never_falls_as_records_arrive(places, gates, more_places, more_gates):
    """Eq. 2: a region someone has been in stays visited; places only accumulate."""
    before = fold(places, gates)
    after = fold(places + more_places, gates + more_gates)
    keys = {tuple(row[:4]) for row in after.places.tolist()}
    for row in before.places.tolist():
        assert tuple(row[:4]) in keys
        k = [tuple(r[:4]) for r in after.places.tolist()].index(tuple(row[:4]))
        assert after.regions[after.region_of_place[k]].visited
    assert all(r.visited == (not r.virtual) == bool(r.places) for r in after.regions)


@SETTINGS
@given(claim_sets, observers, st.data())
def test_no_clock_only_each_origins_own_order_counts(claims, observer, data):
    """Replace each origin's counter values by any increasing relabelling (in RFC 1982
    order, anywhere on the 16-bit circle, wrapping included): the view does not change."""
    relabel = {}
    for o in sorted({c.sender_id for c in claims}):
        values = sorted({c.oseq for c in claims if c.sender_id == o})
        start = data.draw(st.integers(0, 65535))
        steps = data.draw(st.lists(st.integers(1, 700), min_size=len(values), max_size=len(values)))  # span < 2^15
        at = start
        for v, step in zip(values, steps):
            relabel[(o, v)] = at % 65536
            at += step
    moved = [c._replace(oseq=relabel[(c.sender_id, c.oseq)]) for c in claims]
    strip = lambda v: [(s.region, s.visited, s.explored_by_others, s.explorer) for s in v.regions]  # noqa: E731
    assert strip(view(moved, observer)) == strip(view(claims, observer))


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 65535), st.lists(st.integers(0, 32766), min_size=1, max_size=12))
def test_serial_latest_is_rfc_1982_newest_within_half_the_space(base, offsets):
    values = [(base + d) % 65536 for d in offsets]
    newest = serial_latest(values)
    assert all(v == newest or serial_newer(newest, v) for v in values)


# ---- a claim waits for the gates its origin knew -------------------------------------------------

def test_a_claim_is_pending_or_ineffective_until_the_receiver_knows_the_claimants_gates():
    x, y = ANCHORS[R]
    claim = Claim(2, 1, x, y, fold(PLACES, GATES[:1]).regions[R].signature, 1, 0)
    no_gates = fold(PLACES, [])            # the receiver lacks the door: one region, another signature
    s = status_view(no_gates, [claim], observer=1).regions
    assert len(s) == 1 and not s[0].explored_by_others and s[0].latest == ((claim, False),)
    s = status_view(fold(PLACES, GATES[:1]), [claim], observer=1).regions
    assert s[R].explored_by_others and not s[L].explored_by_others
    far = Claim(2, 2, 500, 500, 0, 1, 0)
    assert status_view(GRAPH, [far], observer=1).pending == (far,)


def test_a_claim_does_not_cover_places_its_origin_did_not_know():
    """A region that grew after the claim, with no new gate (every doorway known from the
    start, as pereira:oracle's): the claim no longer applies, until its origin claims the
    grown region."""
    x, y = ANCHORS[R]
    claim = Claim(2, 1, x, y, GRAPH.regions[R].signature, 1, 0)
    assert status_view(GRAPH, [claim], observer=1).regions[R].explored_by_others
    grown = fold(PLACES + [Place(3, 1, 35, 5, 6, 0)], GATES)
    r = grown.resolve(x, y)
    assert grown.regions[r].gate_signature == GRAPH.regions[R].gate_signature
    assert not status_view(grown, [claim], observer=1).regions[r].explored_by_others
    again = Claim(2, 2, x, y, grown.regions[r].signature, 1, 0)
    assert status_view(grown, [claim, again], observer=1).regions[r].explored_by_others


# ---- partitions ---------------------------------------------------------------------------------

@settings(max_examples=40, deadline=None)
@given(st.lists(st.lists(st.one_of(claim_st, st.sampled_from(PLACES + GATES)), max_size=8), min_size=3, max_size=5),
       st.lists(st.tuples(st.integers(0, 4), st.integers(0, 4)), max_size=20))
def test_after_partitions_and_a_rejoin_every_robot_holds_the_same_statuses(own, talks):
    """Each robot starts with records of its own; robots talk in pairs, in any order, some
    never (partitions); then the team rejoins and everyone hears everyone."""
    robots = [Store(records) for records in own]
    n = len(robots)
    for a, b in talks:
        if a < n and b < n:
            robots[b].merge(robots[a])
    for a in range(n):
        for b in range(n):
            robots[b].merge(robots[a])
    assert len({r.digest() for r in robots}) == 1
    assert len({r.graph().digest() for r in robots}) == 1
    for observer in range(6):
        assert len({repr(r.view(observer)) for r in robots}) == 1
