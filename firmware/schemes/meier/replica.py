"""A teammate's polygon map as this robot holds it: a pure function of the records held.

The sender (polygons.PolygonMap) describes its rings one vertex at a time: each `poly`
record is the state of one vertex at the sender's record counter `stamp` (its neighbours in
its ring, its lattice position, the type of the edge to its successor, alive or removed),
and `poly_alive` records say which ids of a block of 64 are alive at a stamp
(meier.md 5.2-5.3). Records arrive in any order, some twice, some never, and a refresh
re-sends every live vertex. Kept per vertex id: only its newest record; per block: only the
newest `poly_alive`. From those alone:

1. a vertex is alive as its newest record says, unless a newer `poly_alive` statement of its
   block says otherwise;
2. every kept record claims links: pred -> vertex -> succ if alive, pred -> succ if removed
   (a removed vertex's neighbours are joined); the successor of u is the head of the newest
   claim whose tail is u;
3. the rings are the cycles of that successor function over alive vertices (vertices on a
   tail into a cycle are left out), and each chain that ends where a successor is missing
   or removed (a record lost) closed across that gap; each started at its smallest id, in
   order of that id.

Stamps are 16-bit counters compared as RFC 1982 serial numbers: a is newer than b when
0 < (a - b) mod 2^16 < 2^15. The sender re-sends every live vertex at least every 2^14
stamps, so every record held is within 2^15 of the newest and the order is total.
"""
from __future__ import annotations

import zlib
from dataclasses import dataclass

import numpy as np

STAMP_BITS = 16
STAMP_MOD = 1 << STAMP_BITS
ALIVE_BLOCK_IDS = 64
MAX_VERTEX_ID = 4095         # ids 1..4095; 0 names no vertex
# A block's summary is one digest per part of SUM_PART_IDS ids, of SUM_DIGEST_BITS each: a
# receiver asks only for the parts that differ (a few records, not 64). Two parts that
# differ have the same digest once in 2^SUM_DIGEST_BITS.
SUM_PART_IDS = 8
SUM_PARTS = ALIVE_BLOCK_IDS // SUM_PART_IDS
SUM_DIGEST_BITS = 12


def newer(a: int, b: int) -> bool:
    """Is stamp a newer than stamp b (RFC 1982 on STAMP_BITS bits)?"""
    d = (a - b) % STAMP_MOD
    return 0 < d < STAMP_MOD // 2


@dataclass(frozen=True)
class PolyRecord:
    """The state of one vertex of the sender's polygon map at `stamp`."""

    sender_id: int
    stamp: int
    vertex_id: int
    pred_id: int
    succ_id: int
    x_lat: int              # lattice position (meier.md: 0.2 m units in the shared frame)
    y_lat: int
    edge_type: int          # of the edge vertex -> succ: 0 unknown (frontier), 1 occupied
    alive: bool
    kind: int = 0           # why it was sent (refresh, ES, VP, B, EP, merge): accounting only


@dataclass(frozen=True)
class AliveRecord:
    """Which vertex ids of block `block` (ids 64 block .. 64 block + 63) are alive at `stamp`."""

    sender_id: int
    stamp: int
    block: int
    alive_bits: int


@dataclass(frozen=True)
class Vertex:
    vertex_id: int
    x_lat: int
    y_lat: int
    edge_type: int


class Replica:
    """One sender's polygon map, rebuilt from the records of it this robot holds."""

    def __init__(self) -> None:
        self._vertices: dict[int, PolyRecord] = {}
        self._blocks: dict[int, AliveRecord] = {}
        self.version = 0        # counts the records that changed what is held
        self._rings: tuple[int, list[list[Vertex]]] | None = None    # (version, rings)

    def add(self, record: PolyRecord | AliveRecord) -> None:
        """Hold a record (older states of the same vertex or block are dropped)."""
        if isinstance(record, AliveRecord):
            held = self._blocks.get(record.block)
            if held is None or newer(record.stamp, held.stamp):
                self._blocks[record.block] = record
                self.version += 1
            return
        held = self._vertices.get(record.vertex_id)
        if held is None or newer(record.stamp, held.stamp):
            self._vertices[record.vertex_id] = record
            self.version += 1

    def held(self, vertex_id: int) -> PolyRecord | None:
        """The newest record of a vertex held (None if none)."""
        return self._vertices.get(vertex_id)

    def block_ids(self, block: int, parts: int = (1 << SUM_PARTS) - 1) -> list[int]:
        """The ids of a block of ALIVE_BLOCK_IDS this replica holds a record of, in the parts
        of SUM_PART_IDS whose bits are set in `parts`."""
        lo = block * ALIVE_BLOCK_IDS
        return [v for v in range(lo, lo + ALIVE_BLOCK_IDS)
                if parts >> ((v - lo) // SUM_PART_IDS) & 1 and v in self._vertices]

    def holds_since(self, block: int, stamp: int) -> bool:
        """Does it hold a record of the block made at `stamp` or later?"""
        return any(self._vertices[v].stamp == stamp or newer(self._vertices[v].stamp, stamp)
                   for v in self.block_ids(block))

    def block_digests(self, block: int) -> list[int]:
        """A summary of what is held of a block, one SUM_DIGEST_BITS digest per part: of the
        id and stamp of the newest record of each vertex in it. Two replicas of one sender
        with the same digest of a part hold the same newest records there (but with odds of
        2^-SUM_DIGEST_BITS), and then agree on those vertices whatever poly_alive records
        either holds: a vertex's newest record was true at every later stamp."""
        return [zlib.crc32(np.array([(v, self._vertices[v].stamp) for v in self.block_ids(block, 1 << part)],
                                    "<u4").reshape(-1, 2).tobytes()) & ((1 << SUM_DIGEST_BITS) - 1)
                for part in range(SUM_PARTS)]

    def _alive(self, r: PolyRecord) -> bool:
        block = self._blocks.get(r.vertex_id // ALIVE_BLOCK_IDS)
        if block is not None and newer(block.stamp, r.stamp):
            return bool(block.alive_bits >> (r.vertex_id % ALIVE_BLOCK_IDS) & 1)
        return r.alive

    def successors(self) -> dict[int, int]:
        """The successor of every alive vertex that has one (rules 1 and 2)."""
        alive = {v for v, r in self._vertices.items() if self._alive(r)}
        return {v: head for v, head in self._claims(alive).items() if v in alive}

    def _claims(self, alive) -> dict[int, int]:
        """tail -> head of the newest claim with that tail."""
        succ: dict[int, tuple[int, int]] = {}        # tail -> (head, stamp of the claim)

        def claim(tail: int, head: int, stamp: int) -> None:
            held = succ.get(tail)
            if held is None or newer(stamp, held[1]):
                succ[tail] = (head, stamp)

        for r in self._vertices.values():
            if r.vertex_id in alive:
                claim(r.pred_id, r.vertex_id, r.stamp)
                claim(r.vertex_id, r.succ_id, r.stamp)
            else:
                claim(r.pred_id, r.succ_id, r.stamp)
        return {tail: head for tail, (head, _) in succ.items()}

    def rings(self) -> list[list[Vertex]]:
        """The sender's rings as this robot knows them (see the module's rules); the same
        list until a record changes what is held (do not change it)."""
        if self._rings is None or self._rings[0] != self.version:
            self._rings = (self.version, self._derive_rings())
        return self._rings[1]

    def _derive_rings(self) -> list[list[Vertex]]:
        alive = {v: r for v, r in self._vertices.items() if self._alive(r)}
        succ = self._claims(alive)
        led_to = {succ[v] for v in alive if v in succ}
        done: set[int] = set()
        rings = []
        # From each head (no alive vertex leads to it) first: a chain that ends where a
        # successor is missing or removed is a ring a lost record cut open, closed across
        # the gap, so that the record costs the area by the vertices it missed, not the
        # whole ring; a chain into a cycle is a tail, left out. Then the cycles left.
        for start in sorted(v for v in alive if v not in led_to) + sorted(alive):
            path, cycle_at = self._walk(start, alive, succ, done)
            if cycle_at is not None:
                path = path[cycle_at:]
            elif len(path) < 2 or succ.get(path[-1]) in alive:
                continue
            k = path.index(min(path))
            rings.append(path[k:] + path[:k])
        rings.sort(key=lambda ring: ring[0])
        return [[Vertex(v, alive[v].x_lat, alive[v].y_lat, alive[v].edge_type) for v in ring] for ring in rings]

    @staticmethod
    def _walk(start: int, alive, succ: dict[int, int], done: set[int]) -> tuple[list[int], int | None]:
        """Follow successors from `start` over alive vertices not yet done, marking them
        done: the path, and where on it the cycle it closed begins (None if it closed none:
        it ran into a missing vertex, a removed one or one done before)."""
        path: list[int] = []
        on_path: dict[int, int] = {}
        v = start
        while v in alive and v not in done and v not in on_path:
            on_path[v] = len(path)
            path.append(v)
            v = succ.get(v, 0)
        done.update(path)
        return path, on_path.get(v)
