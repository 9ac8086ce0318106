"""Map merging without a common frame: Algorithm 2 (III-C) made real (mrtopomap.md 5.3, A1-A3, A6).

The paper estimates a translation from the first descriptor match (Algorithm 2 line 11) and
corrects mismatches later by dropping the transformation "deviated from the mean" once three
or more are known. Here, per receiving robot n and teammate j:

1. Hypotheses. Every pair (own-built vertex v_i, j's vertex v_alpha) scoring th_merge or
   more gives h = (psi, t = p_i - R(psi) p_alpha), psi the descriptor's best circular shift
   (5.2): a full SE(2) transform T_n<-j, never used alone. Optionally (the spec's
   recommendation, 5.3 2b) cells of a profile grid of the own map scoring th_merge - 0.04 or
   more give more: per received vertex the best cell of each distinct place (cells >=
   cluster_sep apart, greedy by score, at most grid_top places). The spec takes each
   vertex's 3 best cells; those are neighbours of one place, and where several places look
   alike (a row of equal rooms) they hide it: every vertex's best 3 fall in whichever copy
   the lattice happens to sample best, and a wrong copy wins alone. Only own-built vertices
   anchor hypotheses (A6).
2. Consensus (deterministic, RANSAC-like by enumeration: every hypothesis is tried as the
   seed, no sampling). Inliers of h: the hypotheses whose pair h maps within inlier_m (1.5 m)
   and whose yaw is within inlier_deg (6 deg) of h's; support = min(distinct own anchors,
   distinct alphas) among them (one vertex matching many places counts once). Seeds are
   walked by support (ties: canonical order); a seed within cluster_sep (3 m, 10 deg) of a
   kept or refused cluster is skipped; otherwise its inliers are fitted (below), the inliers
   re-collected around the fit and fitted again. The walk stops when no seed left can merge
   (support below k_min and nothing kept) or change the ratio test (support * ratio <= c1).
3. Check against the receiver's own map. j's vertices within occ_radius (15 m, in j's frame)
   of the cluster's inliers are mapped by the fit. Why 15 m: a place that repeats (a stretch
   of cave tunnel that looks like another turned by 110 deg) can explain every view within
   10 m of its look-alike pairs; a little farther out the two places differ. At 10 m one
   disjoint cave draw in 100 merged wrongly with a consensus of 6 that chance does not
   explain (below); at 15 m none did, and 2 more of 100 Intel half-overlaps merged (right).
   Farther out, odometry drift between j's vertices (A9) would start to contradict true
   merges.
   a. Occupancy check (the spec's): those landing in the own known area count as tested; a
      vertex is bad if it lands deeper than occ_depth (0.3 m) inside the own walls (OCCUPIED
      cells, and unknown pockets enclosed by the own map: the inside of a wall seen from both
      sides) or in own free space not connected to where the own robot has been. A robot
      stood at every vertex, so it must be free. More than max(occ_tolerated, occ_share *
      tested) bad: the cluster is refused.
   b. View check (not in the spec; why: on a LocalMap walls are a thin shell with unknown
      behind, so (a) rarely finds a vertex deep in a wall, and a wrong transform that puts
      j's vertices in own free space, as a symmetric hall or a repeated corridor does, passes
      it): for those landing on own FREE cells where the own map knows the view (view_known
      of the virtual scan's rays crossed only FREE cells), the vertex's descriptor is scored
      against that virtual view at the fit's shift (+-1 bin); below view_score (0.4) it
      contradicts, at view_good (0.8) or more it confirms. Refused: more than
      max(view_tolerated, view_share (12 %) * such vertices) contradicting, fewer than
      view_confirm (65 %) confirming, or fewer than view_min_seen (10) such vertices at all
      (a cluster the own map cannot check yet waits for more records). Thresholds calibrated
      on static tests (196 clusters of support >= 3 on four maps: no true cluster refused, 64
      of 65 wrong ones, the one left 2.5 m off; true clusters had >= 13 such vertices).
4. Merge iff the best kept cluster's support c1 >= k_min and c1 >= ratio (2) * c2, c2 the
   best other kept cluster's (the ratio test: corridors that look alike give several
   clusters of like support, and no merge). k_min is 4, not the spec's 3 (the paper's "three
   or more"): in static tests on the cave, three look-alike pairs consistent by chance passed
   the ratio test and both checks in about 1 trial of 12 (disjoint or half-overlapping
   areas, no competing cluster); every such wrong cluster had support 3, and k_min 4 cost
   no true merge there.
   Significance (a-contrario, as in Moisan & Stival's ORSA; not in the spec): a consensus of
   c1 is also what chance gives where the descriptors find look-alikes everywhere. With H
   hypotheses scattered uniformly over the own free area A and all yaws, a seed collects
   another by chance with probability p = (pi inlier_m^2 / A) (2 inlier_deg / 360 deg) each,
   so the expected number of clusters of support c1 or more is NFA = H P(Poisson(H p) >=
   c1 - 1). Merge only if NFA <= nfa_max (0.01). Why: in a cave every blob of tunnel looks
   like others, and four look-alike pairs in disjoint areas passed k_min, the ratio test and
   both checks in about 1 draw of 60 (H ~ 600, NFA 0.4); in the Intel lab, where hypotheses
   are few (H ~ 40), a true consensus of 4 has NFA <= 3e-4. In static tests (320 draws of
   half-overlapping and disjoint areas on the cave, the Intel lab and the depot) no true
   cluster had NFA above 3e-4 and no wrong kept one below 0.4. In a cave it asks for a
   consensus of 6 instead of 4. Without an own map (no area) the test is not made.
5. Fit: psi = the circular mean of the inliers' descriptor yaws blended with the 2-D
   Procrustes yaw of the pairs by their expected variances (sigma_psi^2 / n against
   sigma_pos^2 / sum |q - q_mean|^2: many far-apart pairs trust the geometry, a few close
   ones the descriptor); t = mean(p - R(psi) q).

Revisable merges: `estimate` is a pure function of (the own vertex set, the profile grid,
the own map, the set of j's vertex records): no state is carried from one call to the next.
A later cluster that wins re-merges (the paper's mismatch correction, Fig. 4) and one that
makes the ratio test fail un-merges; `TeammateMerge` only caches and counts such changes.
Record order and duplicates cannot change the result, bit for bit: vertex sets are sorted by
key (a conflicting duplicate key keeps the record with the smaller bytes), hypotheses are
sorted canonically, descriptor scores are exact integers over exact norms (descriptor.py),
and every sum runs over arrays in that order.

What the result does not account for: odometry drift between j's vertices (A9; the 1.5 m
inlier tolerance and the 15 m occupancy radius absorb some); places that repeat beyond what
both robots have seen (in maze_b whole blocks recur, and a teammate that saw only one copy
merges onto the other: no local evidence can tell them apart); transitive merges (mrlink,
A8), left to the caller. Cost: scoring a profile grid of 4 000 cells against 100 teammate
vertices takes ~0.3 s here; `TeammateMerge` keeps the scores (`PairScores`) and scores only
lattice points whose profile changed and vertices it did not hold before. The rest of
`estimate` is recomputed each call, so a caller should re-run it when records arrive in
batches.
"""
from __future__ import annotations

import hashlib
import math
from collections.abc import Iterable
from typing import NamedTuple

import numpy as np
import scipy.ndimage as ndimage
from scipy.spatial import cKDTree

from firmware.kernels import FREE, OCCUPIED
from firmware.schemes.mr_topomap import descriptor as desc
from firmware.schemes.mr_topomap.params import DEFAULT, MrTopoParams
from firmware.schemes.mr_topomap.records import Vertex, encode_vertex

_CHUNK_SCORES = 1 << 21      # shift scores held at once when scoring (16 MB of float64)
_EIGHT = np.ones((3, 3), dtype=bool)


def wrap(a):
    """Angles to [-pi, pi)."""
    return np.mod(np.asarray(a) + math.pi, 2.0 * math.pi) - math.pi


class SE2(NamedTuple):
    """x_to = R(psi) x_from + (tx, ty)."""

    psi: float
    tx: float
    ty: float

    def apply(self, xy) -> np.ndarray:
        xy = np.asarray(xy, dtype=np.float64)
        c, s = math.cos(self.psi), math.sin(self.psi)
        return np.stack([c * xy[..., 0] - s * xy[..., 1] + self.tx, s * xy[..., 0] + c * xy[..., 1] + self.ty], axis=-1)

    def compose(self, other: SE2) -> SE2:
        """self after other."""
        t = self.apply([other.tx, other.ty])
        return SE2(float(wrap(self.psi + other.psi)), float(t[0]), float(t[1]))

    def inverse(self) -> SE2:
        c, s = math.cos(self.psi), math.sin(self.psi)
        return SE2(float(wrap(-self.psi)), -(c * self.tx + s * self.ty), -(-s * self.tx + c * self.ty))


def within(a: SE2, b: SE2, at_xy, distance_m: float, angle_rad: float) -> bool:
    """a and b map the point at_xy (in the frame they map from) within distance_m of each
    other, and their yaws differ by at most angle_rad."""
    d = a.apply(at_xy) - b.apply(at_xy)
    return math.hypot(float(d[0]), float(d[1])) <= distance_m and abs(float(wrap(a.psi - b.psi))) <= angle_rad


def canonical(vertices: Iterable[Vertex]) -> tuple[Vertex, ...]:
    """One vertex per key, sorted by key; of two different records under one key, the one
    with the smaller bytes (a choice that does not depend on order)."""
    best: dict[tuple[int, int], tuple[bytes, Vertex]] = {}
    for v in vertices:
        b = encode_vertex(v)
        old = best.get(v.key)
        if old is None or b < old[0]:
            best[v.key] = (b, v)
    return tuple(best[k][1] for k in sorted(best))


class VertexSet:
    """An immutable, canonical set of vertices of one robot, as arrays."""

    def __init__(self, vertices: Iterable[Vertex]) -> None:
        self.vertices = canonical(vertices)
        n = len(self.vertices)
        self.keys = [v.key for v in self.vertices]
        self.xy = np.array([[v.x_m, v.y_m] for v in self.vertices], dtype=np.float64).reshape(n, 2)
        self.codes = np.array([v.desc.codes for v in self.vertices], dtype=np.int64).reshape(n, desc.BINS)
        self.centred = desc.centred(self.codes)
        self.token = hashlib.blake2b(b"".join(encode_vertex(v) for v in self.vertices), digest_size=16).hexdigest()

    def __len__(self) -> int:
        return len(self.vertices)


class ProfileGrid:
    """Virtual 4-bit profiles of the own map at lattice points (5.3 step 2b)."""

    def __init__(self, xy: np.ndarray, codes: np.ndarray) -> None:
        self.xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        self.codes = np.asarray(codes, dtype=np.int64).reshape(-1, desc.BINS)
        self.centred = desc.centred(self.codes)
        self.token = hashlib.blake2b(self.xy.tobytes() + self.codes.tobytes(), digest_size=16).hexdigest()

    def __len__(self) -> int:
        return self.xy.shape[0]

    @classmethod
    def of_map(cls, state: np.ndarray, row0: int, col0: int, res_m: float, range_max_m: float,
               params: MrTopoParams = DEFAULT) -> ProfileGrid:
        """Every point of the grid_spacing lattice (multiples of it in the own frame) whose cell
        is FREE at least grid_clearance from any cell that is not."""
        clear_m = ndimage.distance_transform_edt(state == FREE) * res_m
        step = params.grid_spacing_m
        rows, cols = state.shape
        x0, y0 = col0 * res_m, row0 * res_m
        gx = np.arange(math.ceil(x0 / step), math.floor((x0 + cols * res_m) / step) + 1) * step
        gy = np.arange(math.ceil(y0 / step), math.floor((y0 + rows * res_m) / step) + 1) * step
        X, Y = np.meshgrid(gx, gy)
        j = np.floor(X / res_m).astype(np.int64) - col0
        i = np.floor(Y / res_m).astype(np.int64) - row0
        ok = (i >= 0) & (i < rows) & (j >= 0) & (j < cols)
        ok[ok] = clear_m[i[ok], j[ok]] >= params.grid_clearance_m
        xy = np.stack([X[ok], Y[ok]], axis=1)
        profiles = desc.virtual_profiles(state, row0, col0, res_m, xy, range_max_m, params.grid_rays, params.r_min_m)
        return cls(xy, desc.quantise_many(profiles, params))


class OwnMap:
    """The receiver's own map for the occupancy check: state (UNKNOWN / FREE / OCCUPIED) on
    the global lattice with window origin (row0, col0), and where the own robot has been."""

    def __init__(self, state: np.ndarray, row0: int, col0: int, res_m: float, visited_xy: np.ndarray,
                 range_max_m: float = 10.0) -> None:
        self.range_max_m = float(range_max_m)
        self.state = np.asarray(state, dtype=np.uint8)
        self.row0, self.col0, self.res_m = int(row0), int(col0), float(res_m)
        free = self.state == FREE
        known = free | (self.state == OCCUPIED)
        solid = ndimage.binary_fill_holes(known) & ~free       # walls and the pockets they enclose
        self.known = known | solid
        self.free_area_m2 = float(free.sum()) * self.res_m ** 2
        self.depth_m = ndimage.distance_transform_edt(solid) * self.res_m
        labels, _ = ndimage.label(free, structure=_EIGHT)
        i, j = self.cells(np.asarray(visited_xy, dtype=np.float64).reshape(-1, 2))
        inside = (i >= 0) & (i < self.state.shape[0]) & (j >= 0) & (j < self.state.shape[1])
        seeds = np.unique(labels[i[inside], j[inside]])
        self.reachable = np.isin(labels, seeds[seeds > 0])

    def cells(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return (np.floor(xy[:, 1] / self.res_m).astype(np.int64) - self.row0,
                np.floor(xy[:, 0] / self.res_m).astype(np.int64) - self.col0)

    def check(self, xy: np.ndarray, params: MrTopoParams = DEFAULT) -> tuple[int, int]:
        """(tested, bad) for places where a robot stood, in the own frame."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        i, j = self.cells(xy)
        inside = (i >= 0) & (i < self.state.shape[0]) & (j >= 0) & (j < self.state.shape[1])
        i, j = i[inside], j[inside]
        tested = self.known[i, j]
        in_wall = self.depth_m[i, j] > params.occ_depth_m
        stray = (self.state[i, j] == FREE) & ~self.reachable[i, j]
        return int(tested.sum()), int((tested & (in_wall | stray)).sum())

    def check_views(self, xy: np.ndarray, their_centred: np.ndarray, psi: float,
                    params: MrTopoParams = DEFAULT) -> tuple[int, int, int]:
        """(tested, contradicting, confirming) for the view check: a teammate's vertices mapped
        to xy (own frame) by a transform of rotation psi, with their descriptors (`centred`).
        Tested: the own map's virtual view there is known (a view_known share of its rays
        crossed only FREE cells); contradicting / confirming: the descriptor scores below
        view_score / at least view_good against that view at the transform's shift (+-1 bin)."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        i, j = self.cells(xy)
        inside = (i >= 0) & (i < self.state.shape[0]) & (j >= 0) & (j < self.state.shape[1])
        on_free = np.zeros(len(xy), dtype=bool)
        on_free[inside] = self.state[i[inside], j[inside]] == FREE
        if not on_free.any():
            return 0, 0, 0
        profiles, known = desc.virtual_scans(self.state, self.row0, self.col0, self.res_m, xy[on_free],
                                             self.range_max_m, params.grid_rays, params.r_min_m)
        use = known >= params.view_known
        if not use.any():
            return 0, 0, 0
        mine = desc.centred(desc.quantise_many(profiles[use], params))
        theirs = np.asarray(their_centred, dtype=np.float64).reshape(-1, desc.BINS)[on_free][use]
        k0 = int(round(psi / desc.BIN_RAD)) % desc.BINS
        shifts = [(k0 - 1) % desc.BINS, k0, (k0 + 1) % desc.BINS]
        scores = np.stack([desc.shift_scores(mine[n], theirs[n])[0, 0, shifts] for n in range(mine.shape[0])])
        best = scores.max(axis=1)
        return int(use.sum()), int((best < params.view_score).sum()), int((best >= params.view_good).sum())


class Hypotheses(NamedTuple):
    """Candidate transforms T_own<-theirs, one per (own anchor, their vertex) pair, in
    canonical order (by their vertex, then anchor: own vertices first, then grid points)."""

    psi: np.ndarray          # (H,) rad
    t: np.ndarray            # (H, 2) m
    p: np.ndarray            # (H, 2) the own anchor, own frame
    q: np.ndarray            # (H, 2) their vertex, their frame
    anchor: np.ndarray       # (H,) own vertex index, or len(own) + grid index
    alpha: np.ndarray        # (H,) index into their vertex set
    score: np.ndarray        # (H,)

    def __len__(self) -> int:
        return self.psi.shape[0]


def _empty() -> Hypotheses:
    z = np.zeros(0)
    return Hypotheses(z, np.zeros((0, 2)), np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0, np.int64),
                      np.zeros(0, np.int64), z)


def _scored(anchor_c: np.ndarray, their_c: np.ndarray, th: float) -> tuple[np.ndarray, ...]:
    """(anchor index, their index, score, shift) of every pair scoring >= th, in no set order."""
    out_a, out_b, out_s, out_k = [], [], [], []
    chunk = max(1, _CHUNK_SCORES // max(1, anchor_c.shape[0] * desc.BINS))
    for b0 in range(0, their_c.shape[0], chunk):
        best, shift = desc.peaks(desc.shift_scores(anchor_c, their_c[b0:b0 + chunk]))     # (n, chunk)
        a, b = np.nonzero(best >= th)
        out_a.append(a)
        out_b.append(b + b0)
        out_s.append(best[a, b])
        out_k.append(shift[a, b])
    cat = (lambda xs, dt: np.concatenate(xs).astype(dt) if xs else np.zeros(0, dt))
    return cat(out_a, np.int64), cat(out_b, np.int64), cat(out_s, np.float64), cat(out_k, np.float64)


def _distinct_places(a: np.ndarray, b: np.ndarray, s: np.ndarray, k: np.ndarray, top: int,
                     anchor_xy: np.ndarray, sep_m: float) -> tuple[np.ndarray, ...]:
    """Of pairs sorted by (their index, anchor index): per received vertex only its `top`
    best anchors that lie at least sep_m apart (greedy by score, ties: the lower index)."""
    keep = np.zeros(len(a), dtype=bool)
    starts = np.flatnonzero(np.r_[True, b[1:] != b[:-1]]) if len(b) else np.zeros(0, np.int64)
    ends = np.r_[starts[1:], len(b)]
    sep2 = sep_m * sep_m
    for lo, hi in zip(starts, ends):
        by_score = lo + np.argsort(-s[lo:hi], kind="stable")
        chosen: list[int] = []
        for c in by_score:
            xy = anchor_xy[a[c]]
            if all((xy[0] - anchor_xy[a[n], 0]) ** 2 + (xy[1] - anchor_xy[a[n], 1]) ** 2 >= sep2 for n in chosen):
                chosen.append(int(c))
                if len(chosen) == top:
                    break
        keep[chosen] = True
    return a[keep], b[keep], s[keep], k[keep]


def _pairs(anchor_c: np.ndarray, their_c: np.ndarray, th: float, top: int | None = None,
           anchor_xy: np.ndarray | None = None, sep_m: float = 0.0,
           cache: PairScores | None = None, anchor_codes: np.ndarray | None = None,
           their_codes: np.ndarray | None = None) -> tuple[np.ndarray, ...]:
    """(anchor index, their index, score, shift) of every pair scoring >= th, sorted by
    (their index, anchor index). With `top`: per received vertex only its `top` best anchors
    that lie at least sep_m apart: the best anchor of up to `top` distinct places. Without
    that separation the top anchors are neighbours of one place, and a place that looks like
    others would hide that it does. With a cache (and the codes behind anchor_c and their_c)
    only pairs it has not scored before are scored."""
    if cache is None:
        a, b, s, k = _scored(anchor_c, their_c, th)
    else:
        a, b, s, k = cache.scored(anchor_codes, their_codes, th)
    order = np.lexsort((a, b))
    a, b, s, k = a[order], b[order], s[order], k[order]
    if top is not None:
        a, b, s, k = _distinct_places(a, b, s, k, top, anchor_xy, sep_m)
    return a, b, s, k


class PairScores:
    """Scores >= a threshold between two sets of descriptors, kept from one call to the
    next: only rows of codes not seen in the last call are scored again. A score depends on
    nothing but the two rows of codes and is exact (descriptor.py), so the pairs are the
    same, bit for bit, as scoring everything. Used for the profile grid against one
    teammate's vertices: between two renders of the grid most lattice points keep their
    profile, and between two merges most vertices were held before."""

    def __init__(self) -> None:
        self._th: float | None = None
        self._forget()

    def _forget(self) -> None:
        self._anchors = np.zeros((0, desc.BINS), dtype=np.int64)      # unique code rows, sorted
        self._theirs = np.zeros((0, desc.BINS), dtype=np.int64)
        self._pairs = (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0), np.zeros(0))   # unique indices

    def scored(self, anchor_codes: np.ndarray, their_codes: np.ndarray, th: float) -> tuple[np.ndarray, ...]:
        """`_scored` of the centred codes, row indices into anchor_codes and their_codes."""
        ua, inv_a = _unique_rows(anchor_codes)
        ut, inv_t = _unique_rows(their_codes)
        if th != self._th:                               # scores held are for another threshold
            self._forget()
        old_a = _row_lookup(self._anchors, ua)           # per new unique row: the old one, or -1
        old_t = _row_lookup(self._theirs, ut)
        # pairs between rows both held before: from the last call
        new_of_old_a = np.full(len(self._anchors), -1, np.int64)
        new_of_old_a[old_a[old_a >= 0]] = np.flatnonzero(old_a >= 0)
        new_of_old_t = np.full(len(self._theirs), -1, np.int64)
        new_of_old_t[old_t[old_t >= 0]] = np.flatnonzero(old_t >= 0)
        pa, pt, ps, pk = self._pairs
        pa, pt = new_of_old_a[pa], new_of_old_t[pt]
        kept = (pa >= 0) & (pt >= 0)
        parts = [(pa[kept], pt[kept], ps[kept], pk[kept])]
        # new anchors against every vertex; anchors held before against new vertices
        fresh_a, fresh_t = np.flatnonzero(old_a < 0), np.flatnonzero(old_t < 0)
        held_a = np.flatnonzero(old_a >= 0)
        if len(fresh_a) and len(ut):
            a, t, sc, k = _scored(desc.centred(ua[fresh_a]), desc.centred(ut), th)
            parts.append((fresh_a[a], t, sc, k))
        if len(held_a) and len(fresh_t):
            a, t, sc, k = _scored(desc.centred(ua[held_a]), desc.centred(ut[fresh_t]), th)
            parts.append((held_a[a], fresh_t[t], sc, k))
        pairs = tuple(np.concatenate([p[n] for p in parts]) for n in range(4))
        self._anchors, self._theirs, self._th, self._pairs = ua, ut, th, pairs
        return _expand(pairs, inv_a, inv_t)


def _unique_rows(codes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(the distinct rows, sorted; for each row its index among them)."""
    codes = np.asarray(codes, dtype=np.int64).reshape(-1, desc.BINS)
    if not len(codes):
        return codes, np.zeros(0, np.int64)
    u, inv = np.unique(codes, axis=0, return_inverse=True)
    return u, inv.reshape(-1).astype(np.int64)


def _row_lookup(table: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """For each row, its index in table (distinct rows), or -1."""
    index = {r.tobytes(): n for n, r in enumerate(table)}
    return np.array([index.get(r.tobytes(), -1) for r in rows], dtype=np.int64)


def _expand(pairs: tuple[np.ndarray, ...], inv_a: np.ndarray, inv_t: np.ndarray) -> tuple[np.ndarray, ...]:
    """Pairs of distinct rows to pairs of every row holding them (in no set order)."""
    ua, ut, s, k = pairs
    order_a, count_a, start_a = _rows_of(inv_a)
    order_t, count_t, start_t = _rows_of(inv_t)
    per_pair = count_a[ua] * count_t[ut]
    n = np.repeat(np.arange(len(ua)), per_pair)
    local = np.arange(int(per_pair.sum())) - np.repeat(np.cumsum(per_pair) - per_pair, per_pair)
    across = count_t[ut[n]]
    return (order_a[start_a[ua[n]] + local // across], order_t[start_t[ut[n]] + local % across], s[n], k[n])


def _rows_of(inv: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rows grouped by the distinct row they hold: (row indices in groups, each group's size,
    each group's start in the first)."""
    order = np.argsort(inv, kind="stable")
    count = np.bincount(inv, minlength=int(inv.max()) + 1 if len(inv) else 0)
    return order, count, np.cumsum(count) - count


def hypotheses(own: VertexSet, theirs: VertexSet, grid: ProfileGrid | None = None,
               params: MrTopoParams = DEFAULT, grid_scores: PairScores | None = None) -> Hypotheses:
    """Step 1: every hypothesis the descriptors give. grid_scores: the grid's scores against
    these vertices kept from earlier calls (the same hypotheses, less scoring)."""
    if len(theirs) == 0 or (len(own) == 0 and (grid is None or len(grid) == 0)):
        return _empty()
    parts = []
    if len(own):
        a, b, s, k = _pairs(own.centred, theirs.centred, params.th_merge, None)
        parts.append((a, own.xy[a], b, s, k))
    if grid is not None and len(grid):
        a, b, s, k = _pairs(grid.centred, theirs.centred, params.th_grid, params.grid_top, grid.xy,
                            params.cluster_sep_m, grid_scores, grid.codes, theirs.codes)
        parts.append((a + len(own), grid.xy[a], b, s, k))
    anchor = np.concatenate([x[0] for x in parts])
    p = np.concatenate([x[1] for x in parts]).reshape(-1, 2)
    alpha = np.concatenate([x[2] for x in parts])
    score = np.concatenate([x[3] for x in parts])
    psi = wrap(np.concatenate([x[4] for x in parts]) * desc.BIN_RAD)
    order = np.lexsort((anchor, alpha))
    anchor, p, alpha, score, psi = anchor[order], p[order], alpha[order], score[order], psi[order]
    q = theirs.xy[alpha]
    c, s_ = np.cos(psi), np.sin(psi)
    t = p - np.stack([c * q[:, 0] - s_ * q[:, 1], s_ * q[:, 0] + c * q[:, 1]], axis=1)
    return Hypotheses(psi, t, p, q, anchor, alpha, score)


def _consistent(h: Hypotheses, psi: float, t: np.ndarray, params: MrTopoParams, idx=slice(None)) -> np.ndarray:
    """Which hypotheses (of idx) agree with the transform (psi, t)."""
    c, s = math.cos(psi), math.sin(psi)
    q, p = h.q[idx], h.p[idx]
    rx = c * q[:, 0] - s * q[:, 1] + t[0] - p[:, 0]
    ry = s * q[:, 0] + c * q[:, 1] + t[1] - p[:, 1]
    return (rx * rx + ry * ry <= params.inlier_m ** 2) & (np.abs(wrap(h.psi[idx] - psi)) <= params.inlier_rad)


def _support(h: Hypotheses, members: np.ndarray) -> int:
    """min(distinct own anchors, distinct alphas) among the member hypotheses (indices)."""
    if members.size == 0:
        return 0
    return int(min(np.unique(h.anchor[members]).size, np.unique(h.alpha[members]).size))


def fit(h: Hypotheses, members: np.ndarray, params: MrTopoParams = DEFAULT) -> SE2:
    """Step 5: one transform from the member hypotheses (boolean mask or indices)."""
    psi_i, p, q = h.psi[members], h.p[members], h.q[members]
    n = psi_i.shape[0]
    psi_d = math.atan2(float(np.sin(psi_i).sum()), float(np.cos(psi_i).sum()))
    pc, qc = p - p.mean(axis=0), q - q.mean(axis=0)
    spread = float((qc * qc).sum())
    num = float((qc[:, 0] * pc[:, 1] - qc[:, 1] * pc[:, 0]).sum())
    den = float((qc[:, 0] * pc[:, 0] + qc[:, 1] * pc[:, 1]).sum())
    psi = psi_d
    if spread > 0.0 and (num != 0.0 or den != 0.0):
        w_d = n / math.radians(params.sigma_psi_deg) ** 2
        w_p = spread / params.sigma_pos_m ** 2
        psi = float(wrap(psi_d + w_p / (w_d + w_p) * float(wrap(math.atan2(num, den) - psi_d))))
    c, s = math.cos(psi), math.sin(psi)
    t = (p - np.stack([c * q[:, 0] - s * q[:, 1], s * q[:, 0] + c * q[:, 1]], axis=1)).mean(axis=0)
    return SE2(psi, float(t[0]), float(t[1]))


class Cluster(NamedTuple):
    T: SE2
    support: int
    members: np.ndarray      # indices into the hypotheses, ascending
    tested: int              # occupancy check: j's vertices landing in the own known area
    bad: int                 # ... of which in the own walls or off the reachable free space
    seen: int                # view check: j's vertices landing where the own map knows the view
    contra: int              # ... of which whose descriptor contradicts that view
    confirm: int             # ... of which whose descriptor confirms it
    nfa: float               # clusters this strong that chance would give (nan: no own map)


class MergeResult(NamedTuple):
    merged: bool
    T: SE2 | None            # T_own<-theirs when merged
    support: int             # c1 (0: no cluster)
    second: int              # c2
    reason: str              # merged, no hypotheses, support below k_min, chance consensus, ratio test, all refused
    clusters: tuple[Cluster, ...]    # kept, best first
    refused: tuple[Cluster, ...]     # refused by the occupancy check, in walk order
    n_hypotheses: int
    inliers: tuple[tuple[tuple, tuple[int, int]], ...]   # ((own anchor key), their key) of the winner

    @property
    def best(self) -> Cluster | None:
        return self.clusters[0] if self.clusters else None


def _anchor_key(own: VertexSet, grid: ProfileGrid | None, a: int) -> tuple:
    if a < len(own):
        return ("v",) + own.keys[a]
    g = grid.xy[a - len(own)]
    return ("g", float(g[0]), float(g[1]))


def consensus(h: Hypotheses, theirs: VertexSet, own_map: OwnMap | None = None,
              params: MrTopoParams = DEFAULT) -> tuple[tuple[Cluster, ...], tuple[Cluster, ...]]:
    """Steps 2-3: (kept clusters best first, refused clusters)."""
    H = len(h)
    if H == 0:
        return (), ()
    rows, cols = _consistent_pairs(h, params)
    support = _supports(h, rows, cols)
    order = np.lexsort((np.arange(H), -support))
    kept: list[Cluster] = []
    refused: list[Cluster] = []
    for seed in order:
        c1 = kept[0].support if kept else 0
        if kept and support[seed] * params.ratio <= c1:
            break                                  # nothing left can fail the ratio test
        if not kept and support[seed] < params.k_min:
            break                                  # nothing left can merge (seeds by support)
        if any(_near(h, seed, cl.T, params) for cl in kept + refused):
            continue
        members = np.flatnonzero(_consistent(h, float(h.psi[seed]), h.t[seed], params))
        T = fit(h, members, params)
        members = np.flatnonzero(_consistent(h, T.psi, np.array([T.tx, T.ty]), params))
        if members.size == 0:
            members = np.array([seed])
        T = fit(h, members, params)
        tested = bad = seen = contra = confirm = 0
        if own_map is not None:
            near = _near_members(theirs, h.q[members], params.occ_radius_m)
            mapped = T.apply(theirs.xy[near])
            tested, bad = own_map.check(mapped, params)
            if bad <= max(params.occ_tolerated, params.occ_share * tested):
                seen, contra, confirm = own_map.check_views(mapped, theirs.centred[near], T.psi, params)
        support_ = _support(h, members)
        nfa = chance_clusters(H, support_, own_map.free_area_m2, params) if own_map is not None else math.nan
        cl = Cluster(T, support_, members, tested, bad, seen, contra, confirm, nfa)
        if (bad > max(params.occ_tolerated, params.occ_share * tested)
                or contra > max(params.view_tolerated, params.view_share * seen)
                or (own_map is not None
                    and (seen < params.view_min_seen or confirm < params.view_confirm * seen))):
            refused.append(cl)
            continue
        kept.append(cl)
        kept.sort(key=lambda k: -k.support)        # stable: ties keep walk order
    return tuple(kept), tuple(refused)


def chance_clusters(n_hypotheses: int, support: int, free_area_m2: float, params: MrTopoParams = DEFAULT) -> float:
    """NFA (step 4): how many clusters of at least this support n_hypotheses hypotheses
    scattered uniformly over free_area_m2 and all yaws would form by chance."""
    if support <= 1 or free_area_m2 <= 0.0:
        return float(n_hypotheses)
    p_agree = math.pi * params.inlier_m ** 2 / free_area_m2 * (2.0 * params.inlier_rad / (2.0 * math.pi))
    return n_hypotheses * poisson_tail(support - 1, min(1.0, p_agree) * n_hypotheses)


def poisson_tail(k: int, mean: float) -> float:
    """P(X >= k) for X ~ Poisson(mean). Above the mean the tail is summed from the k-th term
    up (precise where it is tiny, which is where it matters here); at or below the mean it
    is one minus the terms below k (then it is at least about a half)."""
    if k <= 0:
        return 1.0
    if mean <= 0.0:
        return 0.0

    def term(i: int) -> float:
        return math.exp(i * math.log(mean) - mean - math.lgamma(i + 1))

    if k <= mean:
        return max(0.0, 1.0 - math.fsum(term(i) for i in range(k)))
    t, total, i = term(k), 0.0, k
    while t > 1e-17 * total:
        total += t
        i += 1
        t *= mean / i
    return min(1.0, total)


def _consistent_pairs(h: Hypotheses, params: MrTopoParams) -> tuple[np.ndarray, np.ndarray]:
    """Every (seed, member) pair of hypotheses where the member agrees with the seed's
    transform, sorted. Exhaustive, without comparing all H^2 pairs: if h' agrees with h,
    the images of their vertices' centroid c under the two transforms lie within
    inlier_m + 2 sin(inlier_deg / 2) * max|q - c| of each other, so a k-d tree on those
    images finds every candidate pair, and the exact test decides."""
    H = len(h)
    c = h.q.mean(axis=0)
    cs, sn = np.cos(h.psi), np.sin(h.psi)
    img = np.stack([cs * c[0] - sn * c[1] + h.t[:, 0], sn * c[0] + cs * c[1] + h.t[:, 1]], axis=1)
    reach = float(np.sqrt(((h.q - c) ** 2).sum(axis=1)).max())
    radius = params.inlier_m + 2.0 * math.sin(params.inlier_rad / 2.0) * reach + 1e-6
    pairs = cKDTree(img).query_pairs(radius, output_type="ndarray").reshape(-1, 2)
    i = np.concatenate([np.arange(H), pairs[:, 0], pairs[:, 1]])
    j = np.concatenate([np.arange(H), pairs[:, 1], pairs[:, 0]])
    qx, qy = h.q[j, 0], h.q[j, 1]
    rx = cs[i] * qx - sn[i] * qy + h.t[i, 0] - h.p[j, 0]
    ry = sn[i] * qx + cs[i] * qy + h.t[i, 1] - h.p[j, 1]
    ok = (rx * rx + ry * ry <= params.inlier_m ** 2) & (np.abs(wrap(h.psi[j] - h.psi[i])) <= params.inlier_rad)
    ok[:H] = True                                   # a hypothesis always agrees with itself
    i, j = i[ok], j[ok]
    order = np.lexsort((j, i))
    return i[order], j[order]


def _distinct_per_row(rows: np.ndarray, values: np.ndarray, H: int) -> np.ndarray:
    """For each row r, how many distinct values[k] there are over the pairs k of row r."""
    pairs = np.unique(np.stack([rows, values], axis=1), axis=0)
    return np.bincount(pairs[:, 0], minlength=H)


def _supports(h: Hypotheses, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """support of every hypothesis as a seed: min(distinct anchors, distinct alphas) of its members."""
    H = len(h)
    return np.minimum(_distinct_per_row(rows, h.anchor[cols], H), _distinct_per_row(rows, h.alpha[cols], H))


def _near(h: Hypotheses, seed: int, T: SE2, params: MrTopoParams) -> bool:
    d = T.apply(h.q[seed]) - h.p[seed]
    return (float(d[0] * d[0] + d[1] * d[1]) <= params.cluster_sep_m ** 2
            and abs(float(wrap(h.psi[seed] - T.psi))) <= params.cluster_sep_rad)


def _near_members(theirs: VertexSet, q: np.ndarray, radius_m: float) -> np.ndarray:
    """Indices of their vertices within radius_m of any of the points q (their frame)."""
    d2 = ((theirs.xy[:, None, :] - q[None, :, :]) ** 2).sum(axis=2).min(axis=1)
    return np.flatnonzero(d2 <= radius_m * radius_m)


def decide(h: Hypotheses, kept: tuple[Cluster, ...], refused: tuple[Cluster, ...], own: VertexSet,
           theirs: VertexSet, grid: ProfileGrid | None, params: MrTopoParams = DEFAULT) -> MergeResult:
    """Step 4."""
    c1 = kept[0].support if kept else 0
    c2 = kept[1].support if len(kept) > 1 else 0
    if len(h) == 0:
        reason = "no hypotheses"
    elif not kept:
        reason = "all refused" if refused else "support below k_min"
    elif c1 < params.k_min:
        reason = "support below k_min"
    elif kept[0].nfa > params.nfa_max:
        reason = "chance consensus"
    elif c1 < params.ratio * c2:
        reason = "ratio test"
    else:
        reason = "merged"
    merged = reason == "merged"
    inl = ()
    if merged:
        m = kept[0].members
        inl = tuple((_anchor_key(own, grid, int(h.anchor[i])), theirs.keys[int(h.alpha[i])]) for i in m)
    return MergeResult(merged, kept[0].T if merged else None, c1, c2, reason, kept, refused, len(h), inl)


def estimate(own: VertexSet, theirs: VertexSet, grid: ProfileGrid | None = None, own_map: OwnMap | None = None,
             params: MrTopoParams = DEFAULT, grid_scores: PairScores | None = None) -> MergeResult:
    """T_own<-theirs from the vertex records held: a pure function of its arguments
    (grid_scores only saves work: see `hypotheses`)."""
    h = hypotheses(own, theirs, grid, params, grid_scores)
    kept, refused = consensus(h, theirs, own_map, params)
    return decide(h, kept, refused, own, theirs, grid, params)


class TeammateVertices:
    """One teammate's vertices as received: per vertex the newest state (duplicates
    collapse; any order)."""

    def __init__(self, owner: int) -> None:
        self.owner = owner
        self._records: dict[tuple[int, int], Vertex] = {}
        self._set: VertexSet | None = None

    def add(self, v: Vertex) -> bool:
        """A received vertex of this teammate; False if it was held already (the same bytes)."""
        assert v.owner == self.owner, "a vertex of another robot"
        old = self._records.get(v.key)
        if old is not None and encode_vertex(old) <= encode_vertex(v):
            return False
        self._records[v.key] = v
        self._set = None
        return True

    @property
    def vertices(self) -> VertexSet:
        if self._set is None:
            self._set = VertexSet(self._records.values())
        return self._set


class TeammateMerge(TeammateVertices):
    """One teammate's vertices and the merge of its frame into the own one: `estimate`
    re-run when asked, with the counts of changes. Holds no state that changes the
    transform: only caches and counters."""

    def __init__(self, owner: int, params: MrTopoParams = DEFAULT) -> None:
        super().__init__(owner)
        self.p = params
        self._last: MergeResult | None = None
        self._last_key: tuple | None = None
        self._last_merged: SE2 | None = None
        self._grid_scores = PairScores()
        self.merges = 0          # not merged -> merged
        self.unmerges = 0        # merged -> not merged (later evidence made it ambiguous)
        self.corrections = 0     # merged again elsewhere than the last merge, maybe after an unmerged
        #                          spell (the paper's mismatch correction)

    def update(self, own: VertexSet, grid: ProfileGrid | None = None, own_map: OwnMap | None = None,
               own_map_token: object = None) -> MergeResult:
        """The merge for what is held now. The own map has no content token of its own: pass
        one (e.g. the map's revision) to reuse the last result while nothing changed."""
        key = (own.token, self.vertices.token, grid.token if grid is not None else None,
               own_map_token if own_map is not None else None)
        if self._last is not None and key == self._last_key and (own_map is None or own_map_token is not None):
            return self._last
        r = estimate(own, self.vertices, grid, own_map, self.p, self._grid_scores)
        prev = self._last
        if prev is not None and prev.merged and not r.merged:
            self.unmerges += 1
        elif r.merged and (prev is None or not prev.merged):
            self.merges += 1
        if r.merged:
            was = self._last_merged
            if was is not None:
                if not within(was, r.T, self.vertices.xy.mean(axis=0), self.p.cluster_sep_m, self.p.cluster_sep_rad):
                    self.corrections += 1
            self._last_merged = r.T
        self._last, self._last_key = r, key
        return r
