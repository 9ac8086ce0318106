"""This robot's polygon map as it tells it: rings of vertices edited by the paper's update
cases (meier.md 1.3: a new ring for a new contour, an edge split, a vertex that vanished,
rings broken in two or joined), and the records that tell a receiver about them (replica.py).

A change marks the vertices it touched; flush() sends as few records as make a receiver of
every record hold exactly these rings: the state of each vertex that is new, moved, retyped
or removed (tombstones first), then, for every live vertex whose successor a receiver would
still get wrong, its record again. It knows what a receiver would get by keeping one itself
(a replica of its own records), so an edge split costs one record (the new vertex claims both
its links) and a vertex that vanished one (its tombstone joins its neighbours). A removed
vertex's id is reused once its tombstone went out, the smallest first: the replica check
re-sends whatever link the old tombstone was the only record of. refresh() re-sends every live vertex and which ids
are alive, for receivers that lost some.
"""
from __future__ import annotations

import heapq
from dataclasses import dataclass

from firmware.schemes.meier.replica import ALIVE_BLOCK_IDS, MAX_VERTEX_ID, STAMP_MOD, AliveRecord, PolyRecord, Replica

# Why a vertex's record was sent (PolyRecord.kind; accounting and the inspector only).
REFRESH, EDGE_SPLIT, VANISHED, BROKEN, EMERGED = 0, 1, 2, 3, 4


@dataclass
class _State:
    pred: int
    succ: int
    x_lat: int
    y_lat: int
    edge_type: int
    alive: bool = True


class PolygonMap:
    def __init__(self, sender_id: int, first_stamp: int = 0) -> None:
        self.sender_id = sender_id
        self._stamp = first_stamp % STAMP_MOD
        self._v: dict[int, _State] = {}
        self._dirty: dict[int, int] = {}            # vertex id -> kind of the change
        self._said: dict[int, tuple[int, int, int, bool]] = {}   # id -> (x, y, type, alive) last sent
        self._mirror = Replica()                    # what a receiver of every record sent holds
        self._free: list[int] = []                  # removed ids (a heap; some may live again)
        self._next_id = 1
        self._refreshed_up_to = 0                   # refresh_next's place in its round

    # --- what the map holds ---------------------------------------------------------------
    def rings(self) -> list[list[int]]:
        """The live rings, each from its smallest id, in order of that id."""
        seen: set[int] = set()
        out = []
        for v in sorted(i for i, s in self._v.items() if s.alive):
            if v in seen:
                continue
            ring = [v]
            seen.add(v)
            u = self._v[v].succ
            while u != v:
                ring.append(u)
                seen.add(u)
                u = self._v[u].succ
            k = ring.index(min(ring))
            out.append(ring[k:] + ring[:k])
        return sorted(out)

    def vertex(self, v: int) -> tuple[int, int, int]:
        """(x_lat, y_lat, edge_type) of a live vertex."""
        s = self._v[v]
        return s.x_lat, s.y_lat, s.edge_type

    def alive(self, v: int) -> bool:
        return v in self._v and self._v[v].alive

    # --- the update cases -----------------------------------------------------------------
    def new_ring(self, points: list[tuple[int, int, int]]) -> list[int]:
        """A new contour (emerged points): a ring of at least two (x_lat, y_lat, edge_type)."""
        if len(points) < 2:
            raise ValueError(f"a ring needs at least 2 vertices, got {len(points)}")
        ids = [self._new_id() for _ in points]
        for k, (v, (x, y, t)) in enumerate(zip(ids, points)):
            self._v[v] = _State(ids[k - 1], ids[(k + 1) % len(ids)], x, y, t)
            self._mark(v, EMERGED)
        return ids

    def add_vertex(self, x_lat: int, y_lat: int, edge_type: int) -> int:
        """A vertex on its own, for relink() to place in a ring before the next flush."""
        v = self._new_id()
        self._v[v] = _State(v, v, x_lat, y_lat, edge_type)
        self._mark(v, EMERGED)
        return v

    def split_edge(self, u: int, x_lat: int, y_lat: int) -> int:
        """A vertex at (x_lat, y_lat) into the edge u -> succ(u); both halves keep its type."""
        w = self._v[u].succ
        v = self._new_id()
        self._v[v] = _State(u, w, x_lat, y_lat, self._v[u].edge_type)
        self._v[u].succ = v
        self._v[w].pred = v
        for k in (u, v, w):
            self._mark(k, EDGE_SPLIT)
        return v

    def vanish(self, v: int) -> None:
        """A vertex no longer on the boundary: it goes and its neighbours are joined, whatever
        is left of its ring (an update relinks the rings before the next flush)."""
        s = self._v[v]
        self._kill(v, s.pred, s.succ)
        if s.pred != v:
            self._v[s.pred].succ = s.succ
            self._v[s.succ].pred = s.pred
            self._mark(s.pred, VANISHED)
            self._mark(s.succ, VANISHED)

    def live_vertices(self) -> list[int]:
        """Every live vertex, by id (some may be between rings during an update)."""
        return sorted(v for v, s in self._v.items() if s.alive)

    def relink(self, rings: list[list[int]]) -> None:
        """Make these the rings of the live vertices they name (each at least two, in order):
        boundaries broken, joined or reordered at once. Vertices whose neighbours changed
        are sent again."""
        for ring in rings:
            if len(ring) < 2:
                raise ValueError(f"a ring needs at least 2 vertices, got {ring}")
            for k, v in enumerate(ring):
                s = self._v[v]
                pred, succ = ring[k - 1], ring[(k + 1) % len(ring)]
                if (s.pred, s.succ) != (pred, succ):
                    s.pred, s.succ = pred, succ
                    self._mark(v, BROKEN)

    def set_edge_type(self, v: int, edge_type: int) -> None:
        """The edge v -> succ(v) now borders another kind of cell (a frontier became a wall)."""
        if self._v[v].edge_type != edge_type:
            self._v[v].edge_type = edge_type
            self._mark(v, BROKEN)

    # --- records --------------------------------------------------------------------------
    def flush(self) -> list[PolyRecord]:
        """The records that bring a receiver of every record up to date (see the module's
        note): changed vertices (tombstones first), then links the receiver would get wrong."""
        out = []
        for v in sorted(self._dirty, key=lambda v: (self._v[v].alive, v)):
            st = self._v[v]
            said = self._said.get(v)
            if said is None and not st.alive:
                continue                            # made and removed between two flushes
            if said != (st.x_lat, st.y_lat, st.edge_type, st.alive):
                out.append(self._record(v, self._dirty[v]))
        kinds = self._dirty
        while True:
            succ = self._mirror.successors()
            wrong = [v for v, st in sorted(self._v.items()) if st.alive and succ.get(v) != st.succ]
            if not wrong:
                break
            out += [self._record(v, kinds.get(v, BROKEN)) for v in wrong]
        self._dirty = {}
        return out

    def refresh(self) -> list[PolyRecord | AliveRecord]:
        """Every live vertex again, then which ids are alive, block by block (every block
        that ever held an id)."""
        out: list[PolyRecord | AliveRecord] = self.flush()
        out += [self._record(v, REFRESH) for v in self.live_vertices()]
        return out + self._alive_blocks()

    def refresh_next(self, count: int) -> list[PolyRecord | AliveRecord]:
        """A refresh a few records at a time: the next `count` live vertices by id, round
        robin; after the last of a round, which ids are alive. Over a round a receiver that
        lost records gets what refresh() would give it."""
        out: list[PolyRecord | AliveRecord] = []
        live = [v for v in self.live_vertices() if v > self._refreshed_up_to]
        for v in live[:count]:
            out.append(self._record(v, REFRESH))
            self._refreshed_up_to = v
        if len(live) <= count:
            out += self._alive_blocks()
            self._refreshed_up_to = 0
        return out

    def last_record(self, v: int) -> PolyRecord | None:
        """The newest record made of vertex v (None if none was): sent again as it is, it
        tells a receiver that lost it what it would have held."""
        return self._mirror.held(v)

    @property
    def next_stamp(self) -> int:
        """The stamp the next record will carry: every record made so far is older."""
        return self._stamp

    def blocks(self) -> int:
        """How many blocks of ALIVE_BLOCK_IDS ids have ever held a vertex."""
        return (self._next_id - 1) // ALIVE_BLOCK_IDS + 1 if self._next_id > 1 else 0

    def block_digests(self, block: int) -> list[int]:
        """The summary (Replica.block_digests) a receiver of every record sent holds of a block."""
        return self._mirror.block_digests(block)

    def block_records(self, block: int, parts: int) -> list[PolyRecord]:
        """The newest record made of each vertex of these parts of a block: sent again as
        they are, they give a receiver whose digests of those parts differ what it would
        have held."""
        return [self._mirror.held(v) for v in self._mirror.block_ids(block, parts)]

    def alive_block(self, block: int) -> AliveRecord:
        """Which ids of a block are alive now."""
        bits = 0
        for v in range(block * ALIVE_BLOCK_IDS, (block + 1) * ALIVE_BLOCK_IDS):
            if self.alive(v):
                bits |= 1 << (v % ALIVE_BLOCK_IDS)
        return AliveRecord(self.sender_id, self._next_stamp(), block, bits)

    def _alive_blocks(self) -> list[AliveRecord]:
        return [self.alive_block(block) for block in range(max(1, self.blocks()))]

    # --- inside -----------------------------------------------------------------------------
    def _next_stamp(self) -> int:
        s = self._stamp
        self._stamp = (s + 1) % STAMP_MOD
        return s

    def _record(self, v: int, kind: int) -> PolyRecord:
        s = self._v[v]
        r = PolyRecord(self.sender_id, self._next_stamp(), v, s.pred, s.succ, s.x_lat, s.y_lat, s.edge_type,
                       s.alive, kind)
        self._said[v] = (s.x_lat, s.y_lat, s.edge_type, s.alive)
        self._mirror.add(r)
        return r

    def _mark(self, v: int, kind: int) -> None:
        self._dirty.setdefault(v, kind)

    def _kill(self, v: int, pred: int, succ: int) -> None:
        s = self._v[v]
        s.alive, s.pred, s.succ = False, pred, succ
        self._mark(v, VANISHED)
        heapq.heappush(self._free, v)

    def _new_id(self) -> int:
        """The smallest id removed before the last flush (its tombstone went out: a vertex
        never moves on the air, it goes and an id comes back), else a new one."""
        held_back = []
        found = None
        while self._free:
            v = heapq.heappop(self._free)
            if self._v[v].alive:
                continue                            # reused already
            if v in self._dirty:
                held_back.append(v)                 # removed since the last flush
                continue
            found = v
            break
        for v in held_back:
            heapq.heappush(self._free, v)
        if found is not None:
            return found
        if self._next_id > MAX_VERTEX_ID:
            raise RuntimeError(f"more than {MAX_VERTEX_ID} vertices alive or waiting to be reused")
        self._next_id += 1
        return self._next_id - 1
