"""Bayer & Faigl's topological map (IV-B), as a pure function of the records a robot holds.

A vertex is a visited position with the set of robots seen there and the information still
obtainable from it (e_inf); edges join vertices closer than d_connect; long-distance costs
come from Dijkstra over the graph.

Robots hear records in different orders, lose some and hear others twice, yet two robots
that hold the same records must plan on the same map. So the map is rebuilt from the SET
of records: duplicates collapse, and Algorithm 1 folds the records in one canonical order
(sorted by their wire values). Algorithm 1's "h.e_inf <- t.e_inf" keeps the latest record,
which depends on arrival order; here each record carries the sender's revision count for
that vertex instead, so per vertex and sender the highest revision counts (ties: the lower
e_inf), and the vertex's e_inf is the smallest of its senders' current values: a robot
that finds nothing left at a place settles it for the team, as the latest record would in
the paper, while each robot can still raise its own word when it sees more from a place
than it first reported, which a plain minimum over all records could never express. (The
largest of the senders' values was tried: stale words kept whole teams travelling.)

Positions are kept in the wire's units (integer cm) so a robot's own records and the copies
its peers decode are the same values, bit for bit.
"""
from __future__ import annotations

import heapq
import math

import numpy as np
from numba import njit

# One record of the map: the columns fold_records reads, in this order. Bayer & Faigl's
# `topo` record (firmware/schemes/bayer_faigl/records.py) carries exactly these fields in
# this order, checked where it is defined, so a decoded record is a row as it is. The map is
# a shared service (schemes without a radio keep one of their own places too), so it does
# not import a scheme's dialect.
TOPO_FIELDS = ("sender_id", "x_cm", "y_cm", "z_cm", "presence", "e_inf_code", "info_version")
TopoRecord = tuple[int, int, int, int, int, int, int]

@njit(cache=True)
def _grid_slot(cell_x, cell_y, slot_x, slot_y, slot_head, mask):
    """The slot of cell (x, y) in the open-addressing table, or the empty slot where it goes."""
    h = (cell_x * 73856093) ^ (cell_y * 19349663)
    h = (h ^ (h >> 17)) & mask
    while slot_head[h] >= 0 and (slot_x[h] != cell_x or slot_y[h] != cell_y):
        h = (h + 1) & mask
    return h


@njit(cache=True)
def fold_records(rec, d_build_cm, d_connect_cm):
    """Algorithm 1 over records in the given order. rec: int64 (n, 7) as TopoRecord.

    Returns vertex positions (cm), id bitmasks (4 x 64 bits per vertex), e_inf codes, the
    edges (u, v, length in cm) with u > v, and each sender's latest word per vertex as
    parallel arrays (vertex, sender, revision, e_inf code), in the order of their first
    records. A uniform grid of d_build cells finds the closest vertex: any vertex closer
    than d_build lies in the 3 x 3 cells around a record. The grid's cells are a hash table
    (a cell holds its vertices as a linked list, newest first) because records may lie
    anywhere in the wire's range.
    """
    n = rec.shape[0]
    vx = np.empty(n, np.int64)
    vy = np.empty(n, np.int64)
    vz = np.empty(n, np.int64)
    vertex_of = np.empty(n, np.int64)
    nxt = np.full(n, -1, np.int64)
    # At most one cell per vertex, so the table stays at most half full.
    size = 2
    while size < 2 * n:
        size *= 2
    mask = size - 1
    slot_x = np.zeros(size, np.int64)
    slot_y = np.zeros(size, np.int64)
    slot_head = np.full(size, -1, np.int64)
    eu = []
    ev = []
    ew = []
    count = 0
    cell = d_build_cm
    reach = int(math.ceil(d_connect_cm / cell))
    for r in range(n):
        x = rec[r, 1]
        y = rec[r, 2]
        if r > 0 and x == rec[r - 1, 1] and y == rec[r - 1, 2]:
            # Where the record before lies, and the vertices are as it left them: the same
            # search would find the vertex it joined, or the one it made right here.
            vertex_of[r] = vertex_of[r - 1]
            continue
        cx = x // cell
        cy = y // cell
        best = -1
        best_d2 = 0.0
        for gx in range(cx - 1, cx + 2):
            for gy in range(cy - 1, cy + 2):
                v = slot_head[_grid_slot(gx, gy, slot_x, slot_y, slot_head, mask)]
                while v >= 0:
                    dx = float(vx[v] - x)
                    dy = float(vy[v] - y)
                    d2 = dx * dx + dy * dy
                    if best < 0 or d2 < best_d2 or (d2 == best_d2 and v < best):
                        best = v
                        best_d2 = d2
                    v = nxt[v]
        if best >= 0 and math.sqrt(best_d2) < d_build_cm:
            vertex_of[r] = best
            continue
        k = count
        count += 1
        vertex_of[r] = k
        vx[k] = x
        vy[k] = y
        vz[k] = rec[r, 3]
        for gx in range(cx - reach, cx + reach + 1):
            for gy in range(cy - reach, cy + reach + 1):
                v = slot_head[_grid_slot(gx, gy, slot_x, slot_y, slot_head, mask)]
                while v >= 0:
                    dx = float(vx[v] - x)
                    dy = float(vy[v] - y)
                    d = math.sqrt(dx * dx + dy * dy)
                    if d <= d_connect_cm:
                        eu.append(k)
                        ev.append(v)
                        ew.append(d)
                    v = nxt[v]
        h = _grid_slot(cx, cy, slot_x, slot_y, slot_head, mask)
        slot_x[h] = cx
        slot_y[h] = cy
        nxt[k] = slot_head[h]
        slot_head[h] = k
    # Presence bits and each sender's highest revision per vertex (ties: the lower code);
    # a vertex keeps its words as a linked list, as few senders speak for one place.
    ids = np.zeros((count, 4), np.uint64)
    e = np.full(count, 255, np.int64)
    w_vertex = np.empty(n, np.int64)
    w_sender = np.empty(n, np.int64)
    w_version = np.empty(n, np.int64)
    w_code = np.empty(n, np.int64)
    w_next = np.empty(n, np.int64)
    w_head = np.full(count, -1, np.int64)
    words = 0
    for r in range(n):
        k = vertex_of[r]
        sender = rec[r, 0]
        if rec[r, 4] != 0:
            ids[k, sender >> 6] |= np.uint64(1) << np.uint64(sender & 63)
        version = rec[r, 6]
        code = rec[r, 5]
        w = w_head[k]
        while w >= 0 and w_sender[w] != sender:
            w = w_next[w]
        if w < 0:
            w = words
            words += 1
            w_vertex[w] = k
            w_sender[w] = sender
            w_version[w] = version
            w_code[w] = code
            w_next[w] = w_head[k]
            w_head[k] = w
        elif version > w_version[w] or (version == w_version[w] and code < w_code[w]):
            w_version[w] = version
            w_code[w] = code
    for w in range(words):
        if w_code[w] < e[w_vertex[w]]:
            e[w_vertex[w]] = w_code[w]
    m = len(eu)
    edges = np.empty((m, 2), np.int64)
    lengths = np.empty(m, np.float64)
    for i in range(m):
        edges[i, 0] = eu[i]
        edges[i, 1] = ev[i]
        lengths[i] = ew[i]
    return (vx[:count].copy(), vy[:count].copy(), vz[:count].copy(), ids, e, edges, lengths,
            w_vertex[:words].copy(), w_sender[:words].copy(), w_version[:words].copy(), w_code[:words].copy())


@njit(cache=True)
def merge_rows(a, b):
    """The rows of a and b, each sorted lexicographically and none in both, in one
    lexicographic order (as sorting their tuples would order them)."""
    out = np.empty((a.shape[0] + b.shape[0], a.shape[1]), a.dtype)
    i = 0
    j = 0
    for r in range(out.shape[0]):
        take_a = j == b.shape[0]
        if not take_a and i < a.shape[0]:
            for c in range(a.shape[1]):
                if a[i, c] != b[j, c]:
                    take_a = a[i, c] < b[j, c]
                    break
        if take_a:
            out[r] = a[i]
            i += 1
        else:
            out[r] = b[j]
            j += 1
    return out


@njit(cache=True)
def dijkstra_csr(indptr, indices, weights, src):
    """Single-source shortest paths on an undirected graph in CSR form (ties by vertex index)."""
    n = indptr.shape[0] - 1
    dist = np.full(n, np.inf)
    parent = np.full(n, -1, np.int64)
    dist[src] = 0.0
    heap = [(0.0, src)]
    while len(heap) > 0:
        d, u = heapq.heappop(heap)
        if d > dist[u]:
            continue
        for k in range(indptr[u], indptr[u + 1]):
            v = indices[k]
            nd = d + weights[k]
            if nd < dist[v]:
                dist[v] = nd
                parent[v] = u
                heapq.heappush(heap, (nd, v))
    return dist, parent


class TopoMap:
    def __init__(self, d_build_m: float, d_connect_m: float) -> None:
        self.d_build_cm = int(round(d_build_m * 100))
        self.d_connect_cm = int(round(d_connect_m * 100))
        self._records: set[TopoRecord] = set()
        # The records in canonical order as one array, and those not in it yet: a rebuild
        # appends the new ones and sorts in numpy instead of sorting Python tuples.
        self._sorted = np.zeros((0, len(TOPO_FIELDS)), np.int64)
        self._new: list[TopoRecord] = []
        self._empty()

    def _empty(self) -> None:
        self._xy_m = np.zeros((0, 2))
        self._ids = np.zeros((0, 4), np.uint64)
        self._e_code = np.zeros(0, np.int64)
        self._words = [np.zeros(0, np.int64)] * 4
        self.edges = np.zeros((0, 2), np.int64)
        self._csr = (np.zeros(1, np.int64), np.zeros(0, np.int64), np.zeros(0))
        self._lines_key: tuple[bytes, bytes] | None = None
        self._lines_m = np.zeros((0, 0))

    # --- records --------------------------------------------------------------------
    def add(self, record: TopoRecord) -> bool:
        """Hold one more record; True if it was new."""
        record = tuple(int(v) for v in record)
        if record in self._records:
            return False
        self._records.add(record)
        self._new.append(record)
        return True

    @property
    def record_count(self) -> int:
        return len(self._records)

    def records(self) -> frozenset[TopoRecord]:
        return frozenset(self._records)

    def _ensure_built(self) -> None:
        if not self._new:
            return
        new = np.array(self._new, np.int64).reshape(-1, len(TOPO_FIELDS))
        self._new = []
        # Lexicographic over the fields, as sorting the tuples would order them; the records
        # held are in that order already, so only the new ones are sorted.
        rec = merge_rows(self._sorted, new[np.lexsort(new.T[::-1])])
        self._sorted = rec
        vx, vy, _vz, ids, e, edges, lengths, *words = fold_records(rec, self.d_build_cm, self.d_connect_cm)
        self._words = words
        self._xy_m = np.column_stack([vx, vy]).astype(np.float64) / 100.0
        self._ids = ids
        self._e_code = e
        self.edges = edges
        n = len(vx)
        # Symmetric CSR, neighbours in ascending order so Dijkstra's ties are reproducible.
        # An edge is listed once, so (src, dst) pairs are distinct and one key orders them.
        src = np.concatenate([edges[:, 0], edges[:, 1]])
        dst = np.concatenate([edges[:, 1], edges[:, 0]])
        w = np.concatenate([lengths, lengths]) / 100.0
        order = np.argsort(src * n + dst, kind="stable")
        indptr = np.zeros(n + 1, np.int64)
        np.cumsum(np.bincount(src, minlength=n), out=indptr[1:])
        self._csr = (indptr, dst[order], w[order])
        self._lines_key = None

    # --- the map --------------------------------------------------------------------
    def __len__(self) -> int:
        self._ensure_built()
        return len(self._xy_m)

    def positions(self) -> np.ndarray:
        """Vertex positions in metres, (n, 2)."""
        self._ensure_built()
        return self._xy_m

    def e_inf_codes(self) -> np.ndarray:
        self._ensure_built()
        return self._e_code

    def visited_by(self, robot_id: int) -> np.ndarray:
        """Per vertex: did robot_id report its presence there?"""
        self._ensure_built()
        word = self._ids[:, robot_id >> 6]
        return (word >> np.uint64(robot_id & 63)) & np.uint64(1) == np.uint64(1)

    def word_of(self, robot_id: int) -> tuple[np.ndarray, np.ndarray]:
        """Per vertex: robot_id's latest revision there (-1: it never sent one) and the
        e_inf code of that revision (0 where none)."""
        self._ensure_built()
        vertex, sender, version, code = self._words
        revision = np.full(len(self._xy_m), -1, np.int64)
        value = np.zeros(len(self._xy_m), np.int64)
        mine = sender == robot_id
        revision[vertex[mine]] = version[mine]
        value[vertex[mine]] = code[mine]
        return revision, value

    def visited_by_others(self, robot_id: int) -> np.ndarray:
        """Per vertex: did any robot but robot_id report its presence there?"""
        self._ensure_built()
        ids = self._ids.copy()
        ids[:, robot_id >> 6] &= ~(np.uint64(1) << np.uint64(robot_id & 63))
        return (ids != 0).any(axis=1)

    def nearest(self, x_m: float, y_m: float) -> int | None:
        xy = self.positions()
        if len(xy) == 0:
            return None
        return int(np.argmin((xy[:, 0] - x_m) ** 2 + (xy[:, 1] - y_m) ** 2))

    def costs_from(self, x_m: float, y_m: float, blocked: frozenset[tuple[tuple[int, int], tuple[int, int]]] = frozenset()
                   ) -> tuple[int | None, np.ndarray, np.ndarray]:
        """(source vertex, graph distance in m to every vertex (inf if unreached), parents)
        from the vertex nearest to (x, y). `blocked` edges (pairs of vertex positions in cm,
        see edge_key) are left out: a robot's own finding that an edge crosses a wall."""
        src = self.nearest(x_m, y_m)
        if src is None:
            return None, np.zeros(0), np.zeros(0, np.int64)
        indptr, indices, weights = self._csr
        if blocked:
            weights = weights.copy()
            index = self._index_by_position()
            for a, b in blocked:
                u, v = index.get(a), index.get(b)
                if u is None or v is None:
                    continue
                for x, y in ((u, v), (v, u)):
                    row = indices[indptr[x]:indptr[x + 1]]
                    weights[indptr[x] + np.nonzero(row == y)[0]] = np.inf
        dist, parent = dijkstra_csr(indptr, indices, weights, src)
        return src, dist, parent

    def edge_key(self, u: int, v: int) -> tuple[tuple[int, int], tuple[int, int]]:
        """A name for the edge between vertices u and v that survives rebuilding the map."""
        xy = np.round(self.positions() * 100).astype(np.int64)
        a, b = (int(xy[u, 0]), int(xy[u, 1])), (int(xy[v, 0]), int(xy[v, 1]))
        return (a, b) if a <= b else (b, a)

    def _index_by_position(self) -> dict[tuple[int, int], int]:
        xy = np.round(self.positions() * 100).astype(np.int64)
        return {(int(x), int(y)): k for k, (x, y) in enumerate(xy)}

    def cost_to(self, dist: np.ndarray, x_m: float, y_m: float) -> tuple[float, int | None]:
        """Cost to a point off the graph: graph distance to the reached vertex closest to the
        point, plus the straight line from there. When the graph is disconnected this falls
        back to the closest vertex the robot can reach."""
        reached = np.isfinite(dist)
        if not reached.any():
            return math.inf, None
        xy = self.positions()
        line = np.hypot(xy[:, 0] - x_m, xy[:, 1] - y_m)
        line[~reached] = np.inf
        k = int(np.argmin(line))
        return float(dist[k] + line[k]), k

    def costs_to(self, dist: np.ndarray, xs_m: np.ndarray, ys_m: np.ndarray) -> np.ndarray:
        """cost_to for many points at once (the same numbers, bit for bit): inf for every
        point when no vertex is reached."""
        xs_m = np.asarray(xs_m, np.float64)
        ys_m = np.asarray(ys_m, np.float64)
        reached = np.isfinite(dist)
        if not reached.any() or len(xs_m) == 0:
            return np.full(len(xs_m), math.inf)
        line = self._lines_to(xs_m, ys_m)
        if not reached.all():
            line = line.copy()
            line[:, ~reached] = np.inf
        k = np.argmin(line, axis=1)
        return dist[k] + line[np.arange(len(xs_m)), k]

    def _lines_to(self, xs_m: np.ndarray, ys_m: np.ndarray) -> np.ndarray:
        """Straight lines (m) from each point to every vertex, (points, vertices). The last
        answer is kept until the map changes: a plan asks it for the same candidates once
        for itself and once per teammate."""
        self._ensure_built()
        key = (xs_m.tobytes(), ys_m.tobytes())
        if key != self._lines_key:
            xy = self._xy_m
            self._lines_m = np.hypot(xy[None, :, 0] - xs_m[:, None], xy[None, :, 1] - ys_m[:, None])
            self._lines_key = key
        return self._lines_m

    @staticmethod
    def path(parent: np.ndarray, dst: int) -> list[int]:
        out = [dst]
        while parent[out[-1]] >= 0:
            out.append(int(parent[out[-1]]))
        out.reverse()
        return out
