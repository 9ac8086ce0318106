"""Anti-entropy for the record set (pereira.md 5.5): the paper's multi-hop, done by the
application instead of the network.

Places, gates and claims share their origin's one record counter (oseq, from 1), so what a
robot holds of an origin is mostly a run 1..upto with perhaps a few records beyond a gap.
A summary says, for up to five origins, the highest `upto` held; a robot hearing one whose
entry for origin o lags its own `upto` of o answers with the next few records of o from
where the entry stops. The sender of the summary is never pushed its own records. Over a
chain a record crosses one hop per summary period; in full range nobody lags and nothing
is pushed.
"""
from __future__ import annotations

from firmware.schemes.pereira.records import OSEQ_BITS, SUMMARY_SLOTS, Claim, Gate, Place

HeldRecord = tuple[str, Place | Gate | Claim]


class Holdings:
    """The place, gate and claim records held, by origin and oseq."""

    def __init__(self) -> None:
        self._by_origin: dict[int, dict[int, HeldRecord]] = {}
        self._upto: dict[int, int] = {}

    def add(self, name: str, record: Place | Gate | Claim) -> bool:
        """Hold one record; True if its (origin, oseq) was new. A second record under the
        same (origin, oseq) is not held here (the store keeps it: only a rebooted robot that
        did not listen first sends one)."""
        o, q = int(record.sender_id), int(record.oseq)
        held = self._by_origin.setdefault(o, {})
        if q in held:
            return False
        held[q] = (name, record)
        u = self._upto.get(o, 0)
        while u + 1 < (1 << OSEQ_BITS) and u + 1 in held:
            u += 1
        self._upto[o] = u
        return True

    def upto(self, origin: int) -> int:
        """The highest oseq n such that 1..n of this origin are all held (0: none)."""
        return self._upto.get(origin, 0)

    def origins(self) -> list[int]:
        return sorted(self._by_origin)

    def holds(self, origin: int, oseq: int) -> bool:
        return oseq in self._by_origin.get(origin, {})

    def __len__(self) -> int:
        return sum(len(v) for v in self._by_origin.values())

    def summary_entries(self, turn: int) -> tuple[tuple[int, int], ...]:
        """(origin, upto) of up to five origins: all of them if they fit, else the turn-th
        group of five in a round robin."""
        origins = self.origins()
        if len(origins) > SUMMARY_SLOTS:
            start = (turn * SUMMARY_SLOTS) % len(origins)
            origins = sorted((origins + origins)[start:start + SUMMARY_SLOTS])
        return tuple((o, self.upto(o)) for o in origins)

    def snapshot(self) -> dict[int, int]:
        """upto of every origin now (to_push's `held_since`)."""
        return dict(self._upto)

    def to_push(self, sender: int, entries: tuple[tuple[int, int], ...], at_most: int,
                held_since: dict[int, int] | None = None) -> list[HeldRecord]:
        """What to answer a summary of `sender` with: for every origin it lags on, the next
        `at_most` records held after its entry. An origin missing from a summary with free
        slots is one the sender holds nothing of; from a full one, unknown.

        held_since: an earlier snapshot(); only records held then are pushed (the scheme
        passes the one taken when the same sender's previous summary came: records heard
        since may still be on their way to it, or in a summary composed before it heard them)."""
        theirs = dict(entries)
        full = len(entries) >= SUMMARY_SLOTS
        out: list[HeldRecord] = []
        for o in self.origins():
            if o == sender:
                continue
            lag = theirs.get(o, None if full else 0)
            upto = self.upto(o) if held_since is None else min(self.upto(o), held_since.get(o, 0))
            if lag is None or upto <= lag:
                continue
            held = self._by_origin[o]
            out.extend(held[q] for q in range(lag + 1, min(lag + at_most, upto) + 1))
        return out
