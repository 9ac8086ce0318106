"""The region graph as a pure function of the place and gate records held (pereira.md 5.2 c).

Every robot contributes evidence as grow-only records: places where it drove, each with a
disc its map certified FREE, and gates (narrowings) it saw whole. `fold(places, gates)`
turns the SET of those records into regions, as TopoMap does for Bayer & Faigl: duplicates
collapse, records are sorted by their wire values, and every decision after that is made
in integers (decimetres, centimetres, a fixed integer cos/sin table), so two robots holding
the same records hold the identical graph, bit for bit (`RegionGraph.digest`).

1. Gates: in sorted order, a gate record within r_match (0.75 m) and 30 degrees of an
   accepted gate folds into it; otherwise it is accepted. Its key is its (x_dm, y_dm,
   dir_code); its half length the largest of the records folded into it. Its segment is the
   centre +- (half + 0.15 m) along its direction, pushed into the jambs so edges cannot slip
   past its ends.
2. Place edges: p-q if q is p's link_back predecessor (the sender drove it), or if
   |pq| <= min(d_connect, clear_p + clear_q): then the segment lies inside the union of
   the two certified discs, so it crosses no wall the senders saw (wall-safe by
   construction).
3. An edge whose segment crosses an accepted gate's segment is cut (exact orientation tests
   in cm; a point on the gate's line counts on its "+" side, the left of a -> b).
4. Regions are the connected pieces of the uncut graph. A region's id is its anchor, the
   smallest place key (x_dm, y_dm, sender, oseq) in it; its signature the CRC-16/MODBUS of
   the sorted keys of the gates that cut an edge at one of its places, followed by the
   sorted keys of its places (region_signature; the spec has the gates only: a claim then
   outlived its region's growth where no new gate marks it); its gate signature the CRC of
   the gates alone. Adjacency: the two regions at the ends of a cut edge, through that gate.
5. Virtual regions V(g, s): the side s of gate g with no place within side_radius of the
   gate, when the other side has one: the room behind a door seen, never entered. It is
   adjacent, through g, to the region of the nearest place on the other side; its
   signature is the CRC of g alone, and its anchor point lies 0.5 m beyond the gate.
6. Visited (eq. 2) = the region has places: places are a grow-only set, so a visited
   region stays visited.

`RegionGraph.label` places a point in a region for private decisions (nearest place with
no gate between, else the virtual region beyond the gate crossed) where the robot's label
grid (labels.py, 5.2 d) does not reach. The scheme measures ways along the place edges to
choose where to head (Pereira._transit); paths themselves stay on the robot's own map.
"""
from __future__ import annotations

import hashlib
import itertools
import math
import struct
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from firmware.comms.schema import crc16
from firmware.schemes.pereira.params import PARAMS, PereiraParams
from firmware.schemes.pereira.records import DIR_CODES, Gate, Place

# ---- integer geometry -------------------------------------------------------------------

TRIG_SHIFT = 14
# cos and sin of code * pi / 256 in units of 2^-14: computed, then checked against their
# CRC, so a machine whose libm rounds one entry differently fails here instead of folding a
# different graph (the nearest entry to a rounding tie is 5e-4 of a unit away).
COS_Q = np.array([round(math.cos(k * math.pi / DIR_CODES) * (1 << TRIG_SHIFT)) for k in range(DIR_CODES)], np.int64)
SIN_Q = np.array([round(math.sin(k * math.pi / DIR_CODES) * (1 << TRIG_SHIFT)) for k in range(DIR_CODES)], np.int64)
assert crc16(struct.pack(">256h", *COS_Q.tolist()) + struct.pack(">256h", *SIN_Q.tolist())) == 0x62B9, \
    "integer trig table differs from the one every robot uses"

# Columns of the sorted record arrays: the sort keys first.
PLACE_COLUMNS = ("x_dm", "y_dm", "sender_id", "oseq", "clear_dm", "link_back")
GATE_COLUMNS = ("x_dm", "y_dm", "dir_code", "half_2cm", "sender_id", "oseq")
VIRTUAL_ANCHOR_DM = 5        # a virtual region's anchor point: this far beyond its gate

REAL, VIRTUAL = 0, 1
SIDE_PLUS, SIDE_MINUS = 0, 1


def _q_mul(length: np.ndarray | int, table_value: np.ndarray | int):
    """round(length * table / 2^14), the same integers everywhere."""
    return (length * table_value + (1 << (TRIG_SHIFT - 1))) >> TRIG_SHIFT


def orient(ax, ay, bx, by, cx, cy):
    """Twice the signed area of (a, b, c): > 0 when c is left of a -> b. Integer inputs."""
    return (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)


def crosses(px, py, qx, qy, ax, ay, bx, by):
    """Does segment p-q cross gate segment a-b? p and q must lie on different sides of the
    gate's line (a point on the line counts as "+"), and a and b on the closed segment's
    two sides. Integer arrays or ints (cm), broadcast."""
    sp = orient(ax, ay, bx, by, px, py) >= 0
    sq = orient(ax, ay, bx, by, qx, qy) >= 0
    oa = orient(px, py, qx, qy, ax, ay)
    ob = orient(px, py, qx, qy, bx, by)
    return (sp != sq) & (((oa <= 0) & (ob >= 0)) | ((oa >= 0) & (ob <= 0)))


def near_segment(px, py, ax, ay, bx, by, r):
    """Is point p within r of segment a-b? Exact in integers (arrays broadcast); the
    coordinates' differences must stay below about 2^20 (the callers pass neighbours)."""
    dx, dy = bx - ax, by - ay
    ux, uy = px - ax, py - ay
    t = ux * dx + uy * dy
    ll = dx * dx + dy * dy
    wx, wy = px - bx, py - by
    cross = ux * dy - uy * dx
    before = t <= 0
    after = t >= ll
    return np.where(before, ux * ux + uy * uy <= r * r,
                    np.where(after, wx * wx + wy * wy <= r * r, cross * cross <= r * r * ll))


# The keys as a signature covers them: gate (x_dm, y_dm, dir_code) and place (x_dm, y_dm,
# sender, oseq), big-endian as on the wire.
GATE_KEY_BYTES = np.dtype([("x", ">i2"), ("y", ">i2"), ("dir", "u1")])
PLACE_KEY_BYTES = np.dtype([("x", ">i2"), ("y", ">i2"), ("sender", "u1"), ("oseq", ">u2")])


def _key_rows(keys: np.ndarray, layout: np.dtype) -> np.ndarray:
    """Rows of integer keys (the first len(layout.names) columns) as packed records."""
    out = np.empty(len(keys), layout)
    for c, name in enumerate(layout.names):
        out[name] = keys[:, c]
    return out


def gate_key_bytes(keys: Iterable[tuple[int, int, int]]) -> bytes:
    return _key_rows(np.array(list(keys), np.int64).reshape(-1, 3), GATE_KEY_BYTES).tobytes()


def signature_of(keys: Iterable[tuple[int, int, int]]) -> int:
    """CRC-16/MODBUS over gate keys in sorted order: a region's gate signature."""
    return crc16(gate_key_bytes(sorted(keys)))


def region_signature(gate_keys: Iterable[tuple[int, int, int]], place_keys: Iterable[tuple[int, int, int, int]]) -> int:
    """CRC-16/MODBUS over the sorted gate keys, then the sorted place keys (x_dm, y_dm,
    sender, oseq) of a real region: what a claim of it names. With the places in it, a claim
    covers the region as its claimant knew it: once anyone adds a place (the region grew
    beyond what the claimant saw, with no new gate: the rule when every doorway is known from
    the start, as pereira:oracle's are), the claim no longer applies until its claimant
    judges the grown region again."""
    places = _key_rows(np.array(sorted(place_keys), np.int64).reshape(-1, 4), PLACE_KEY_BYTES)
    return crc16(gate_key_bytes(sorted(gate_keys)) + places.tobytes())


# ---- the graph --------------------------------------------------------------------------

@dataclass(frozen=True)
class Region:
    id: tuple[int, ...]          # (REAL, x_dm, y_dm, sender, oseq) of its anchor, or (VIRTUAL, gx, gy, gdir, side)
    anchor_x_dm: int             # the anchor place, or the point 0.5 m beyond the gate
    anchor_y_dm: int
    signature: int               # real: region_signature (gates and places); virtual: signature_of({g})
    virtual: bool
    places: tuple[int, ...]      # indices into RegionGraph.places (empty for a virtual region)
    gate_signature: int = 0      # signature_of(its gates): what a claim of the virtual region it was names

    @property
    def visited(self) -> bool:
        """Eq. 2: some robot has been there (the region has places)."""
        return not self.virtual


@dataclass(frozen=True, eq=False)
class RegionGraph:
    """What `fold` derives. Arrays are canonical: equal inputs give equal arrays."""

    places: np.ndarray           # int64 (n, 6) in PLACE_COLUMNS, sorted, unique
    gate_records: np.ndarray     # int64 (m, 6) in GATE_COLUMNS, sorted, unique
    gate_of_record: np.ndarray   # int64 (m,): the accepted gate each gate record folded into
    gates: np.ndarray            # int64 (k, 4): x_dm, y_dm, dir_code, half_2cm of the accepted gates (key order)
    segments_cm: np.ndarray      # int64 (k, 4): ax, ay, bx, by of each gate's segment
    edges: np.ndarray            # int64 (e, 2): place index pairs u < v, sorted
    edge_kind: np.ndarray        # uint8 (e,): 1 trajectory, 2 certified, 3 both
    cuts: np.ndarray             # int64 (c, 2): (edge, gate) for every gate crossing an edge, sorted
    region_of_place: np.ndarray  # int64 (n,): index into regions
    regions: tuple[Region, ...]  # real regions by anchor, then virtual ones by (gate, side)
    adjacency: tuple[tuple[int, int, int], ...]   # (region a, region b, gate), a < b, sorted, unique
    params: PereiraParams = PARAMS

    # ---- lookups ----
    def gate_key(self, g: int) -> tuple[int, int, int]:
        return int(self.gates[g, 0]), int(self.gates[g, 1]), int(self.gates[g, 2])

    def region_index(self, region_id: tuple[int, ...]) -> int | None:
        return self._index_of_id.get(region_id)

    @property
    def _index_of_id(self) -> dict[tuple[int, ...], int]:
        cached = self.__dict__.get("_ids")
        if cached is None:
            cached = {r.id: k for k, r in enumerate(self.regions)}
            object.__setattr__(self, "_ids", cached)
        return cached

    def neighbours(self, r: int) -> tuple[int, ...]:
        return tuple(sorted({b if a == r else a for a, b, _g in self.adjacency if r in (a, b)}))

    def is_cut(self) -> np.ndarray:
        cut = np.zeros(len(self.edges), bool)
        cut[self.cuts[:, 0]] = True
        return cut

    def partition(self) -> tuple[tuple[tuple[int, ...], tuple[tuple[int, ...], ...]], ...]:
        """Each region's id with the keys of its places: what every robot must agree on."""
        keys = [tuple(int(v) for v in row[:4]) for row in self.places]
        return tuple((r.id, tuple(keys[i] for i in r.places)) for r in self.regions)

    def digest(self) -> str:
        """SHA-256 over everything derived, in canonical order."""
        h = hashlib.sha256()
        for a in (self.places, self.gate_records, self.gate_of_record, self.gates, self.segments_cm, self.edges,
                  self.edge_kind, self.cuts, self.region_of_place):
            h.update(str(a.shape).encode())
            h.update(np.ascontiguousarray(a).astype(np.int64).tobytes())
        h.update(repr(self.regions).encode())
        h.update(repr(self.adjacency).encode())
        return h.hexdigest()

    # ---- claim resolution (5.3) ----
    def resolve(self, x_dm: int, y_dm: int) -> int | None:
        """The region a claim's anchor names in this graph, or None (pending): the place with
        exactly that position; else the nearest place within resolve_radius whose segment to
        the anchor crosses no gate (ties: lowest key); else the virtual region V(g, s) whose
        gate lies within virtual_resolve of the anchor, the anchor on side s (nearest gate
        centre, then lowest key)."""
        p = self.params
        x_dm, y_dm = int(x_dm), int(y_dm)
        pl = self.places
        if len(pl):
            lo = np.searchsorted(self._xy_keys, x_dm * (1 << 17) + y_dm, "left")
            if lo < len(pl) and pl[lo, 0] == x_dm and pl[lo, 1] == y_dm:
                return int(self.region_of_place[lo])
            r = p.resolve_radius_dm
            near = self._place_tree.query_ball_point((x_dm, y_dm), r + 0.5)
            if near:
                near = np.array(sorted(near), np.int64)
                d2 = (pl[near, 0] - x_dm) ** 2 + (pl[near, 1] - y_dm) ** 2
                near, d2 = near[d2 <= r * r], d2[d2 <= r * r]
                for k in near[np.lexsort((near, d2))]:
                    if not self._segment_cut(int(pl[k, 0]) * 10, int(pl[k, 1]) * 10, x_dm * 10, y_dm * 10):
                        return int(self.region_of_place[k])
        best = None
        for k, reg in enumerate(self.regions):
            if not reg.virtual:
                continue
            g, side = self._virtual_gate[k]
            ax, ay, bx, by = (int(v) for v in self.segments_cm[g])
            on_plus = orient(ax, ay, bx, by, x_dm * 10, y_dm * 10) >= 0
            if on_plus != (side == SIDE_PLUS):
                continue
            if not near_segment(x_dm * 10, y_dm * 10, ax, ay, bx, by, p.virtual_resolve_cm):
                continue
            d2 = (int(self.gates[g, 0]) - x_dm) ** 2 + (int(self.gates[g, 1]) - y_dm) ** 2
            if best is None or (d2, reg.id) < best[0]:
                best = ((d2, reg.id), k)
        return None if best is None else best[1]

    def label(self, x_dm: int, y_dm: int, reach_dm: int, nearest: int = 8) -> int | None:
        """The region a point (a waypoint, the robot) lies in, for private decisions (5.2 d.3):
        the region of the nearest of the `nearest` places within reach_dm whose segment to
        the point crosses no gate; else, seen from the nearest place, the virtual region
        beyond the gate crossed nearest the point (None if that side has no virtual region,
        or no place is near)."""
        return self.labels(np.array([[x_dm, y_dm]], np.int64), reach_dm, nearest)[0]

    def labels(self, xy_dm: np.ndarray, reach_dm: int, nearest: int = 8) -> list[int | None]:
        """`label` of every row (x_dm, y_dm, integers) of xy_dm."""
        pl = self.places
        xy_dm = np.asarray(xy_dm, np.int64).reshape(-1, 2)
        if not len(pl) or not len(xy_dm):
            return [None] * len(xy_dm)
        k = min(nearest, len(pl))
        d, idx = self._place_tree.query(xy_dm.astype(np.float64), k=k, distance_upper_bound=reach_dm + 0.5)
        d, idx = d.reshape(len(xy_dm), k), idx.reshape(len(xy_dm), k)
        found = np.isfinite(d)              # a prefix of each row: nearest first
        idx = np.where(found, idx, 0)
        s = self.segments_cm
        if not len(s):
            return [int(self.region_of_place[i[0]]) if f[0] else None for i, f in zip(idx, found)]
        x_cm, y_cm = xy_dm[:, 0, None, None] * 10, xy_dm[:, 1, None, None] * 10
        hit = crosses(pl[idx, 0, None] * 10, pl[idx, 1, None] * 10, x_cm, y_cm,
                      s[None, None, :, 0], s[None, None, :, 1], s[None, None, :, 2], s[None, None, :, 3])
        clear = found & ~hit.any(axis=2)
        first_clear = np.argmax(clear, axis=1)
        out: list[int | None] = []
        for q in range(len(xy_dm)):
            if not found[q, 0]:
                out.append(None)
            elif clear[q, first_clear[q]]:
                out.append(int(self.region_of_place[idx[q, first_clear[q]]]))
            else:
                out.append(self._beyond_gate(int(xy_dm[q, 0]), int(xy_dm[q, 1]), np.flatnonzero(hit[q, 0])))
        return out

    def _beyond_gate(self, x_dm: int, y_dm: int, gs: np.ndarray) -> int | None:
        """The virtual region beyond the gate nearest the point among gs (ties: lowest
        index), on the point's side; None if that side has none."""
        d2 = (self.gates[gs, 0] - x_dm) ** 2 + (self.gates[gs, 1] - y_dm) ** 2
        g = int(gs[np.lexsort((gs, d2))[0]])
        ax, ay, bx, by = (int(v) for v in self.segments_cm[g])
        side = SIDE_PLUS if orient(ax, ay, bx, by, x_dm * 10, y_dm * 10) >= 0 else SIDE_MINUS
        return self.region_index((VIRTUAL, *self.gate_key(g), side))

    def places_within(self, x_dm: float, y_dm: float, r_dm: float) -> np.ndarray:
        """Indices of the places within r_dm of the point, ascending."""
        if not len(self.places):
            return np.zeros(0, np.int64)
        return np.array(sorted(self._place_tree.query_ball_point((x_dm, y_dm), r_dm)), np.int64)

    def gates_between(self, a: int, b: int) -> tuple[int, ...]:
        """The gates through which regions a and b are adjacent."""
        lo, hi = min(a, b), max(a, b)
        return tuple(g for x, y, g in self.adjacency if (x, y) == (lo, hi))

    @property
    def _xy_keys(self) -> np.ndarray:
        cached = self.__dict__.get("_xy")
        if cached is None:
            cached = self.places[:, 0] * (1 << 17) + self.places[:, 1]
            object.__setattr__(self, "_xy", cached)
        return cached

    @property
    def _place_tree(self) -> cKDTree:
        cached = self.__dict__.get("_tree")
        if cached is None:
            cached = cKDTree(self.places[:, :2].astype(np.float64))
            object.__setattr__(self, "_tree", cached)
        return cached

    def virtual_gate(self, k: int) -> tuple[int, int]:
        """(gate index, side) of virtual region k."""
        return self._virtual_gate[k]

    @property
    def _virtual_gate(self) -> dict[int, tuple[int, int]]:
        cached = self.__dict__.get("_vg")
        if cached is None:
            by_key = {self.gate_key(g): g for g in range(len(self.gates))}
            cached = {k: (by_key[r.id[1:4]], r.id[4]) for k, r in enumerate(self.regions) if r.virtual}
            object.__setattr__(self, "_vg", cached)
        return cached

    def _segment_cut(self, px: int, py: int, qx: int, qy: int) -> bool:
        if not len(self.segments_cm):
            return False
        s = self.segments_cm
        return bool(np.any(crosses(px, py, qx, qy, s[:, 0], s[:, 1], s[:, 2], s[:, 3])))


# ---- the fold ---------------------------------------------------------------------------

def _sorted_unique(rows: Iterable[tuple[int, ...]], columns: tuple[int, ...]) -> np.ndarray:
    """The records as int64 rows with their fields in `columns` order, sorted
    lexicographically, duplicates dropped."""
    rows = list(rows)
    a = np.fromiter(itertools.chain.from_iterable(rows), np.int64, 6 * len(rows)).reshape(-1, 6)[:, list(columns)]
    if len(a) < 2:
        return a
    a = a[np.lexsort(a.T[::-1])]
    keep = np.ones(len(a), bool)
    keep[1:] = np.any(a[1:] != a[:-1], axis=1)
    return a[keep]


def _fold_gates(gr: np.ndarray, p: PereiraParams) -> tuple[np.ndarray, np.ndarray]:
    """Accepted gates (x, y, dir, half) and the accepted gate of every record."""
    accepted: list[list[int]] = []
    of_record = np.empty(len(gr), np.int64)
    r2 = p.r_match_dm ** 2
    max_codes = p.r_match_codes
    for i in range(len(gr)):
        x, y, d, half = (int(v) for v in gr[i, :4])
        hit = -1
        for k, (ax, ay, ad, _h) in enumerate(accepted):
            dd = abs(d - ad) % DIR_CODES
            if (x - ax) ** 2 + (y - ay) ** 2 <= r2 and min(dd, DIR_CODES - dd) <= max_codes:
                hit = k
                break
        if hit < 0:
            hit = len(accepted)
            accepted.append([x, y, d, half])
        else:
            accepted[hit][3] = max(accepted[hit][3], half)
        of_record[i] = hit
    return np.array(accepted, np.int64).reshape(-1, 4), of_record


def gate_segments_cm(gates: np.ndarray, extension_cm: int) -> np.ndarray:
    """ax, ay, bx, by (cm) of gates given as rows x_dm, y_dm, dir_code, half_2cm."""
    cx, cy = gates[:, 0] * 10, gates[:, 1] * 10
    ext = gates[:, 3] * 2 + extension_cm
    ox, oy = _q_mul(ext, COS_Q[gates[:, 2]]), _q_mul(ext, SIN_Q[gates[:, 2]])
    return np.stack([cx - ox, cy - oy, cx + ox, cy + oy], axis=1).astype(np.int64).reshape(-1, 4)


def _edges(pl: np.ndarray, tree: cKDTree | None, p: PereiraParams) -> tuple[np.ndarray, np.ndarray]:
    """Place edges (u < v, sorted) and their kinds (bit 0 trajectory, bit 1 certified).
    `tree`: the places' positions (dm), None if there are none."""
    n = len(pl)
    us, vs, ks = [], [], []
    # Trajectory: the sender's previous place, link_back records before.
    seq = pl[:, 2] * (1 << 16) + pl[:, 3]
    order = np.argsort(seq, kind="stable")
    back = np.flatnonzero(pl[:, 5] > 0)
    want = pl[back, 2] * (1 << 16) + (pl[back, 3] - pl[back, 5]) % (1 << 16)
    lo = np.searchsorted(seq[order], want, "left")
    hi = np.searchsorted(seq[order], want, "right")
    count = hi - lo
    if count.sum():
        src = np.repeat(back, count)
        starts = np.repeat(lo, count) + (np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count))
        dst = order[starts]
        us.append(src)
        vs.append(dst)
        ks.append(np.ones(len(src), np.uint8))
    # Certified: inside the union of the two certified discs.
    if n > 1:
        r = p.d_connect_dm
        pairs = tree.query_pairs(r + 0.5, output_type="ndarray").astype(np.int64)
        if len(pairs):
            u, v = pairs[:, 0], pairs[:, 1]
            d2 = (pl[u, 0] - pl[v, 0]) ** 2 + (pl[u, 1] - pl[v, 1]) ** 2
            reach = np.minimum(r, pl[u, 4] + pl[v, 4])
            ok = d2 <= reach * reach
            us.append(u[ok])
            vs.append(v[ok])
            ks.append(np.full(int(ok.sum()), 2, np.uint8))
    if not us:
        return np.zeros((0, 2), np.int64), np.zeros(0, np.uint8)
    u, v, k = np.concatenate(us), np.concatenate(vs), np.concatenate(ks)
    a, b = np.minimum(u, v), np.maximum(u, v)
    code = a * n + b
    order = np.argsort(code, kind="stable")
    code, k = code[order], k[order]
    if not len(code):
        return np.zeros((0, 2), np.int64), np.zeros(0, np.uint8)
    first = np.ones(len(code), bool)
    first[1:] = code[1:] != code[:-1]
    starts = np.flatnonzero(first)
    kinds = np.bitwise_or.reduceat(k, starts).astype(np.uint8)
    code = code[starts]
    return np.stack([code // n, code % n], axis=1), kinds


def _cuts(pl: np.ndarray, edges: np.ndarray, seg: np.ndarray) -> np.ndarray:
    """(edge, gate) pairs whose segments cross, sorted."""
    if not len(edges) or not len(seg):
        return np.zeros((0, 2), np.int64)
    px, py = pl[edges[:, 0], 0] * 10, pl[edges[:, 0], 1] * 10
    qx, qy = pl[edges[:, 1], 0] * 10, pl[edges[:, 1], 1] * 10
    half_len = np.hypot((qx - px).astype(np.float64), (qy - py).astype(np.float64)) / 2
    gate_half = np.hypot((seg[:, 2] - seg[:, 0]).astype(np.float64), (seg[:, 3] - seg[:, 1]).astype(np.float64)) / 2
    # Candidate pairs: the two segments' midpoints no farther apart than their half lengths
    # (plus a margin); edges far longer than usual are checked against every gate.
    long_edge = half_len > 200.0
    short = np.flatnonzero(~long_edge)
    pe, pg = [], []
    if len(short):
        mids = np.stack([(px + qx)[short] / 2, (py + qy)[short] / 2], axis=1)
        tree = cKDTree(mids)
        centres = np.stack([(seg[:, 0] + seg[:, 2]) / 2, (seg[:, 1] + seg[:, 3]) / 2], axis=1)
        hits = tree.query_ball_point(centres, gate_half + float(half_len[short].max()) + 2.0)
        counts = np.fromiter((len(hs) for hs in hits), np.int64, len(hits))
        pe.append(short[np.fromiter(itertools.chain.from_iterable(hits), np.int64, int(counts.sum()))])
        pg.append(np.repeat(np.arange(len(hits), dtype=np.int64), counts))
    for e in np.flatnonzero(long_edge):
        pe.append(np.full(len(seg), e, np.int64))
        pg.append(np.arange(len(seg), dtype=np.int64))
    if not pe:
        return np.zeros((0, 2), np.int64)
    e, g = np.concatenate(pe), np.concatenate(pg)
    hit = crosses(px[e], py[e], qx[e], qy[e], seg[g, 0], seg[g, 1], seg[g, 2], seg[g, 3])
    out = np.stack([e[hit], g[hit]], axis=1)
    return out[np.lexsort((out[:, 1], out[:, 0]))] if len(out) else out.reshape(0, 2)


def _one_sided_gates(pl: np.ndarray, tree: cKDTree | None, acc: np.ndarray, seg: np.ndarray,
                     r_cm: int) -> list[tuple[int, int, int]]:
    """(gate, side, place) for every side of a gate with no place within r_cm of the gate's
    segment while the other side has one: `place` is that side's nearest place to the gate's
    centre (ties: lowest index). A point on the gate's line counts on its "+" side. `tree`:
    the places' positions (dm); its float distances only gather candidates, with 2 cm to
    spare, for the integer test."""
    if not len(pl) or not len(acc):
        return []
    cx, cy = acc[:, 0] * 10, acc[:, 1] * 10
    reach = np.hypot((seg[:, 2] - seg[:, 0]).astype(np.float64), (seg[:, 3] - seg[:, 1]).astype(np.float64)) / 2 \
        + r_cm + 2.0
    hits = tree.query_ball_point(acc[:, :2].astype(np.float64), reach / 10)
    counts = np.fromiter((len(h) for h in hits), np.int64, len(hits))
    g = np.repeat(np.arange(len(acc), dtype=np.int64), counts)
    i = np.fromiter(itertools.chain.from_iterable(hits), np.int64, int(counts.sum()))
    px, py = pl[i, 0] * 10, pl[i, 1] * 10
    ax, ay, bx, by = seg[g, 0], seg[g, 1], seg[g, 2], seg[g, 3]
    ok = near_segment(px - cx[g], py - cy[g], ax - cx[g], ay - cy[g], bx - cx[g], by - cy[g], r_cm)
    side = np.where(orient(ax, ay, bx, by, px, py) >= 0, SIDE_PLUS, SIDE_MINUS)
    d2 = (px - cx[g]) ** 2 + (py - cy[g]) ** 2
    g, side, i, d2 = g[ok], side[ok], i[ok], d2[ok]
    order = np.lexsort((i, d2, side, g))
    g, side, i = g[order], side[order], i[order]
    first = np.ones(len(g), bool)
    first[1:] = (g[1:] != g[:-1]) | (side[1:] != side[:-1])
    nearest = {(int(a), int(s)): int(k) for a, s, k in zip(g[first].tolist(), side[first].tolist(), i[first].tolist())}
    out = []
    for gate in range(len(acc)):
        for s in (SIDE_PLUS, SIDE_MINUS):
            other = nearest.get((gate, 1 - s))
            if (gate, s) not in nearest and other is not None:
                out.append((gate, s, other))
    return out


def fold(places: Iterable[Place | tuple[int, ...]], gates: Iterable[Gate | tuple[int, ...]],
         params: PereiraParams = PARAMS) -> RegionGraph:
    """The region graph of a set of place and gate records (any order, duplicates allowed)."""
    p = params
    pl = _sorted_unique(places, (2, 3, 0, 1, 4, 5))      # PLACE_COLUMNS
    gr = _sorted_unique(gates, (2, 3, 4, 5, 0, 1))       # GATE_COLUMNS
    acc, gate_of_record = _fold_gates(gr, p)
    # Accepted gates in key order (x, y, dir), so gate indices do not depend on fold order.
    order = np.lexsort((acc[:, 2], acc[:, 1], acc[:, 0])) if len(acc) else np.zeros(0, np.int64)
    rank = np.empty(len(order), np.int64)
    rank[order] = np.arange(len(order))
    acc = acc[order]
    gate_of_record = rank[gate_of_record] if len(gate_of_record) else gate_of_record
    seg = gate_segments_cm(acc, p.gate_extension_cm)
    tree = cKDTree(pl[:, :2].astype(np.float64)) if len(pl) else None
    edges, kind = _edges(pl, tree, p)
    cuts = _cuts(pl, edges, seg)
    n = len(pl)

    # Regions: connected pieces of the uncut graph, numbered by their smallest place.
    cut = np.zeros(len(edges), bool)
    if len(cuts):
        cut[cuts[:, 0]] = True
    keep = edges[~cut]
    if n:
        graph = coo_matrix((np.ones(len(keep)), (keep[:, 0], keep[:, 1])), shape=(n, n))
        _count, label = connected_components(graph, directed=False)
        first = np.full(label.max() + 1, n, np.int64)
        np.minimum.at(first, label, np.arange(n))
        order_r = np.argsort(first, kind="stable")
        new = np.empty(len(order_r), np.int64)
        new[order_r] = np.arange(len(order_r))
        region_of_place = new[label]
    else:
        region_of_place = np.zeros(0, np.int64)
    n_real = int(region_of_place.max()) + 1 if n else 0
    # Each region's places, ascending (so in key order: the places are sorted by key).
    by_region = np.argsort(region_of_place, kind="stable")
    ends = np.cumsum(np.bincount(region_of_place, minlength=n_real))
    members = np.split(by_region, ends[:-1]) if n_real else []
    # Each gate that cuts an edge at one of a region's places; adjacency through cut edges.
    k_gates = len(acc)
    ra = region_of_place[edges[cuts[:, 0], 0]]
    rb = region_of_place[edges[cuts[:, 0], 1]]
    g_cut = cuts[:, 1]
    region_gate = np.unique(np.concatenate([ra * k_gates + g_cut, rb * k_gates + g_cut]))
    gate_ends = np.cumsum(np.bincount(region_gate // max(k_gates, 1), minlength=n_real))
    gates_of = np.split(region_gate % max(k_gates, 1), gate_ends[:-1]) if n_real else []
    two = ra != rb
    pair_gate = np.unique((np.minimum(ra, rb)[two] * n_real + np.maximum(ra, rb)[two]) * k_gates + g_cut[two])
    adjacency = {(a // n_real, a % n_real, g) for a, g in zip((pair_gate // k_gates).tolist(),
                                                             (pair_gate % k_gates).tolist())} if len(pair_gate) else set()
    gate_bytes = _key_rows(acc, GATE_KEY_BYTES)
    place_bytes = _key_rows(pl, PLACE_KEY_BYTES)
    regions = []
    for r in range(n_real):
        a = int(members[r][0])
        gk = gate_bytes[gates_of[r]].tobytes()     # gate indices ascend with their keys
        regions.append(Region((REAL, int(pl[a, 0]), int(pl[a, 1]), int(pl[a, 2]), int(pl[a, 3])),
                              int(pl[a, 0]), int(pl[a, 1]), crc16(gk + place_bytes[members[r]].tobytes()), False,
                              tuple(members[r].tolist()), crc16(gk)))

    # Virtual regions behind gates with places on one side only.
    keys = [tuple(a) for a in acc[:, :3].tolist()]
    virtual: list[tuple[tuple[int, ...], int, int, int]] = []   # (id, anchor x, anchor y, adjacent real region)
    for g, side, other in _one_sided_gates(pl, tree, acc, seg, p.side_radius_cm):
        d = int(acc[g, 2])
        nx = -_q_mul(VIRTUAL_ANCHOR_DM, int(SIN_Q[d]))
        ny = _q_mul(VIRTUAL_ANCHOR_DM, int(COS_Q[d]))
        sgn = 1 if side == SIDE_PLUS else -1
        virtual.append(((VIRTUAL, *keys[g], side), int(acc[g, 0]) + sgn * nx, int(acc[g, 1]) + sgn * ny,
                        int(region_of_place[other])))
    virtual.sort()
    gate_index = {k: g for g, k in enumerate(keys)}
    for vid, x, y, real in virtual:
        g = gate_index[vid[1:4]]
        k = len(regions)
        sig = signature_of([keys[g]])
        regions.append(Region(vid, x, y, sig, True, (), sig))
        adjacency.add((real, k, g))
    out = RegionGraph(places=pl, gate_records=gr, gate_of_record=gate_of_record, gates=acc, segments_cm=seg,
                      edges=edges, edge_kind=kind, cuts=cuts, region_of_place=region_of_place,
                      regions=tuple(regions), adjacency=tuple(sorted(adjacency)), params=p)
    if tree is not None:
        object.__setattr__(out, "_tree", tree)
    return out
