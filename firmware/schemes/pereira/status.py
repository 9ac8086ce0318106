"""Region statuses without clocks (pereira.md 1.3, 4 A3/A4/A16/A17, 5.3): claims as a lattice.

The paper keeps one slot (e^o, r^o) per region and merges a received graph by eq. 1
(explored is the maximum), lets a newer message from the same robot lower the status
(same-robot override), never takes its own statuses back from others (loop rule) and
compares timestamps only within one robot. Its slot is order dependent (A3: A holds (1, C),
hears B: 1, then C retracts, and A drops to 0 although B explored the region), so here:

- A status is a claim record (origin, oseq, anchor, signature, explored, virtual), kept in
  a grow-only set: the merge is set union, commutative, associative and idempotent, and a
  relay forwards the origin's record unchanged, with the origin's counter (A4).
- A receiver resolves a claim's anchor to a region of its own region graph
  (RegionGraph.resolve); the claim is effective only if its signature equals that region's
  (its gates and places; a claim with the virtual bit, of a room seen through a door, its
  gates alone), so a claim never reaches beyond the region its origin knew, and one whose
  gates or places the receiver lacks waits (pending).
- e^o_A(R) = OR over origins o != A of [o's latest claim among those resolving to R is
  effective and explored] (eq. 1 as an OR over per-origin registers). "Latest" is the
  origin's own counter in RFC 1982 order, the only order compared (no clock); so a newer
  claim of the same origin overrides an older one, downwards too (same-robot override).
  r^o(R) = the lowest such origin.
- Claims of A's own are ignored (loop rule): A's e^r is its live judgement, outside this
  view (A16). Claims never expire (A17).
- v(R) = R has places (eq. 2): places only accumulate, so v never falls.

`status_view(graph, claims, observer)` is a deterministic function of the claim SET and
the region graph; e^o itself is not monotone (retractions), the record set is.
"""
from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass

from firmware.schemes.pereira.records import OSEQ_BITS, Claim
from firmware.schemes.pereira.regions import RegionGraph


class ClaimSet:
    """A grow-only set of claims (G-Set). `a | b` is the join."""

    __slots__ = ("_claims", "_in_order")

    def __init__(self, claims: Iterable[Claim] = ()) -> None:
        self._claims = frozenset(Claim(*(int(v) for v in c)) for c in claims)
        self._in_order: tuple[Claim, ...] | None = None

    def join(self, other: ClaimSet) -> ClaimSet:
        out = ClaimSet()
        out._claims = self._claims | other._claims
        return out

    __or__ = join

    def add(self, claim: Claim) -> ClaimSet:
        return self.join(ClaimSet([claim]))

    def __le__(self, other: ClaimSet) -> bool:
        return self._claims <= other._claims

    def __eq__(self, other: object) -> bool:
        return isinstance(other, ClaimSet) and self._claims == other._claims

    def __hash__(self) -> int:
        return hash(self._claims)

    def __iter__(self) -> Iterator[Claim]:
        if self._in_order is None:
            self._in_order = tuple(sorted(self._claims))
        return iter(self._in_order)

    def __len__(self) -> int:
        return len(self._claims)

    def __contains__(self, claim: object) -> bool:
        return claim in self._claims

    def __repr__(self) -> str:
        return f"ClaimSet({sorted(self._claims)!r})"


def serial_latest(values: Iterable[int], bits: int = OSEQ_BITS) -> int:
    """The newest of one origin's counter values in RFC 1982 order, as a function of the
    set: the value just before the largest gap around the circle (the first such gap in
    increasing order if two tie). Whenever the values span less than half the counter's
    space, which RFC 1982 needs to order them at all, this is the value every other one is
    older than."""
    v = sorted({int(x) % (1 << bits) for x in values})
    if not v:
        raise ValueError("no values")
    gaps = [(b - a, a) for a, b in zip(v, v[1:])] + [((v[0] - v[-1]) % (1 << bits) or (1 << bits), v[-1])]
    widest = max(g for g, _a in gaps)
    return next(a for g, a in gaps if g == widest)


@dataclass(frozen=True)
class RegionStatus:
    region: tuple[int, ...]          # the region's id (RegionGraph.regions[k].id)
    visited: bool                    # v (eq. 2)
    explored_by_others: bool         # e^o (eq. 1 with the override and the loop rule)
    explorer: int | None             # r^o: the lowest origin whose latest claim makes e^o true
    latest: tuple[tuple[Claim, bool], ...]   # each other origin's latest claim resolving here, effective?


@dataclass(frozen=True)
class StatusView:
    observer: int
    regions: tuple[RegionStatus, ...]    # in RegionGraph.regions order
    pending: tuple[Claim, ...]           # claims of others whose anchors resolve to no region yet

    def of(self, region_id: tuple[int, ...]) -> RegionStatus | None:
        return next((r for r in self.regions if r.region == region_id), None)


def _latest(claims: list[Claim]) -> Claim:
    """One origin's latest claim among `claims` (same origin). A counter value used twice
    (a robot that rebooted without listening first) resolves to the retraction, then the
    smallest record: unexplored is the safe side."""
    newest = serial_latest(c.oseq for c in claims)
    return min((c for c in claims if c.oseq == newest), key=lambda c: (c.explored, c))


def status_view(graph: RegionGraph, claims: Iterable[Claim] | ClaimSet, observer: int) -> StatusView:
    """Every region's status as robot `observer` sees it, holding `claims` and `graph`."""
    claims = claims if isinstance(claims, ClaimSet) else ClaimSet(claims)
    groups: dict[tuple[int, int], list[Claim]] = {}
    pending: list[Claim] = []
    resolved: dict[tuple[int, int], int | None] = {}
    for c in claims:
        if c.sender_id == observer:
            continue                                   # the loop rule
        at = (c.anchor_x_dm, c.anchor_y_dm)
        if at not in resolved:
            resolved[at] = graph.resolve(*at)
        r = resolved[at]
        if r is None:
            pending.append(c)
        else:
            groups.setdefault((r, c.sender_id), []).append(c)
    latest: dict[int, list[tuple[Claim, bool]]] = {}
    for (r, _origin), cs in sorted(groups.items()):
        c = _latest(cs)
        reg = graph.regions[r]
        latest.setdefault(r, []).append((c, c.sig == (reg.gate_signature if c.virtual else reg.signature)))
    out = []
    for k, reg in enumerate(graph.regions):
        mine = tuple(latest.get(k, ()))
        by = [c.sender_id for c, effective in mine if effective and c.explored]
        out.append(RegionStatus(reg.id, reg.visited, bool(by), min(by) if by else None, mine))
    return StatusView(observer, tuple(out), tuple(pending))
