"""The records a robot holds (places, gates, claims) and what it derives from them.

A grow-only set: `add` ingests one record (a duplicate changes nothing), `merge` takes in
another store's records (set union: the join). The region graph is folded again only when
places or gates arrived since the last look, the claim set built again only when claims
did; the status view depends on the graph and the claims. Both are functions of the set
alone, so any interleaving of ingestion gives what batch ingestion gives.
"""
from __future__ import annotations

import hashlib
from collections.abc import Iterable

from firmware.schemes.pereira.params import PARAMS, PereiraParams
from firmware.schemes.pereira.records import Claim, Gate, Place, encode
from firmware.schemes.pereira.regions import RegionGraph, fold
from firmware.schemes.pereira.status import ClaimSet, StatusView, status_view


class Store:
    def __init__(self, records: Iterable[Place | Gate | Claim] = (), params: PereiraParams = PARAMS) -> None:
        self.params = params
        self._places: set[Place] = set()
        self._gates: set[Gate] = set()
        self._claims: set[Claim] = set()
        self._graph: RegionGraph | None = None
        self._claim_set: ClaimSet | None = None
        for r in records:
            self.add(r)

    def add(self, record: Place | Gate | Claim) -> bool:
        """Ingest one record; True if it was new."""
        if isinstance(record, Place):
            held = self._places
        elif isinstance(record, Gate):
            held = self._gates
        elif isinstance(record, Claim):
            held = self._claims
        else:
            raise TypeError(f"not a place, gate or claim: {type(record).__name__}")
        if record in held:
            return False
        held.add(record)
        if held is self._claims:
            self._claim_set = None
        else:
            self._graph = None
        return True

    def merge(self, other: Store) -> None:
        """Take in every record of `other` (the join)."""
        for r in other.records():
            self.add(r)

    def records(self) -> list[Place | Gate | Claim]:
        """Everything held, in a canonical order (places, gates, claims; each sorted)."""
        return [*sorted(self._places), *sorted(self._gates), *sorted(self._claims)]

    def __len__(self) -> int:
        return len(self._places) + len(self._gates) + len(self._claims)

    def graph(self) -> RegionGraph:
        if self._graph is None:
            self._graph = fold(self._places, self._gates, self.params)
        return self._graph

    def claims(self) -> ClaimSet:
        if self._claim_set is None:
            self._claim_set = ClaimSet(self._claims)
        return self._claim_set

    def view(self, observer: int) -> StatusView:
        return status_view(self.graph(), self.claims(), observer)

    def digest(self) -> str:
        """SHA-256 of the record set: equal on two robots exactly when they hold the same records."""
        h = hashlib.sha256()
        for r in self.records():
            h.update(type(r).__name__.encode())
            h.update(encode(r))
        return h.hexdigest()
