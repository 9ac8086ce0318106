"""Gates found in a robot's own map (pereira.md 5.2 a), the places it reports (5.2 b).

`detect_gates(state, row0, col0, res_m)` is a pure function of a local occupancy state grid
(firmware.kernels UNKNOWN / FREE / OCCUPIED, anchored at global cell (row0, col0)). The steps
are the spec's; where they differ from it, the step says so and why.

1. Unknown cells touching walls count as walls (close_wall_gaps). The nearest wall cell a of
   every cell comes from an exact Euclidean distance transform to OCCUPIED cells only
   (unknown is not an obstacle), with its feature indices; the clearance c is the distance
   to that cell's face (half a cell nearer than its centre: a door 9 cells wide has c 0.45 m).
2. The generalized Voronoi diagram (GVD): of two neighbours (4- or diagonal) p, q, both FREE
   with c >= r_min (0.32 m), whose nearest walls lie >= 120 degrees apart seen from p, the
   one with the larger clearance (ties: p, the lower in cell order) is on it. The 120
   degrees drop the branches into corners. The ridge is the same with 60 degrees: it keeps
   the corner diagonals (a square room's GVD is its centre alone).
3. A GVD cell p is a candidate when
   - 2 c(p) <= w_max (5.1 m), and the nearest frontier unknown cell (UNKNOWN, 8-adjacent to
     FREE) is >= c(p) + 0.5 m away;
   - no GVD cell within max(1 m, c(p)) in sight (no wall cell on the straight segment) is
     narrower by more than c_tie (0.25 m). The spec has no c_tie: without it a 0.1 m bump
     on a wall breaks the corridor beside it into pieces;
   - a ridge cell within max(3 m, 3 c(p)) has clearance >= (1 + kappa) c(p) (kappa 0.5),
     lies at least 45 degrees off the axis p -> a(p), and is in sight through cells the
     body fits in (c >= r_min). The spec asks for a GVD cell in sight; the ridge sees into
     square rooms, the axis test keeps the widening beyond the gate line, not beside it (a
     corridor passing a door would otherwise count the room behind the door), and a door
     the body does not fit leads nowhere;
   - both sides open (not in the spec): across the axis, the free space reaches
     c(p) + 0.5 m on each side and the body fits there. A doorway joins two spaces; 0.1 m
     bumps on walls would otherwise make "gates" into pockets (a bump and the wall next to
     a corner) and across the wedges of corners (a bump on each of its walls puts their
     nearest points 120 degrees apart on the corner's diagonal).
4. The mouth: the narrowest candidate left and the candidates joined to it through
   candidates as narrow (within c_tie; joined when at most 2 x 0.1 m + 1.5 cells apart, as
   a bump can knock a cell off the GVD) are one narrowing.
   From its end nearest a widening (then global cell order), the gate walks down the
   clearance through the narrowing's cells to where it stops falling: out of the fringe a
   door's jamb corners make, into the door; at a corridor's mouth, onto the corridor's
   level. It suppresses the whole narrowing and every candidate within max(1.5 m, 2c) of
   it in sight. (The spec takes candidates by c, then distance to the widening, and
   suppresses by radius alone: a uniform corridor within 3 m of a room then gets a gate
   every 1.5 m, and a 0.1 m bump anywhere in it draws the mouth's gate to itself.)
5. Jambs: a = nearest wall; b = the nearest wall cell within c + 0.3 m at least 120 degrees
   from a. The gate is centre p, direction a -> b modulo pi, half length half the free width
   between the jambs' faces. A gate without a second jamb is dropped.

Orders and ties use integer squared cell distances and global cell coordinates, so moving
the window's anchor does not move a gate.

`GateTracker` confirms a gate seen on K = 3 cycles in a row and says which to send (none
that the fold already holds). `place_clear_dm` is the certified free radius of a place.
"""
from __future__ import annotations

import math
from collections.abc import Iterable
from typing import NamedTuple

import numpy as np
import scipy.ndimage as ndimage
from scipy.spatial import cKDTree

from firmware import kernels
from firmware.schemes.pereira.params import PARAMS, PereiraParams
from firmware.schemes.pereira.records import DIR_CODES, dir_code_of, dm, half_2cm_of
from firmware.services.dilation import dilate_square
from firmware.services.grid_paths import lines_of_sight
from firmware.services.local_map import close_wall_gaps

_SIGHT_BATCH = 16      # sight tests per candidate and round, nearest first


class GateObservation(NamedTuple):
    """A gate in one robot's map, in the shared frame."""

    x_m: float
    y_m: float
    dir_rad: float       # jamb a -> b, in [0, pi)
    half_m: float        # half the free width between the jambs
    clearance_m: float   # at the centre
    cell: tuple[int, int]   # global cell (row, col) of the centre

    def wire(self) -> tuple[int, int, int, int]:
        """x_dm, y_dm, dir_code, half_2cm as a gate record carries them."""
        return dm(self.x_m), dm(self.y_m), dir_code_of(self.dir_rad), half_2cm_of(self.half_m)


def _angle_at_least(ux, uy, vx, vy, cos_limit: float):
    """angle(u, v) >= acos(cos_limit) for integer vectors (cos <= cos_limit, squared to
    avoid roots)."""
    dot = (ux * vx + uy * vy).astype(np.float64)
    uv = (ux * ux + uy * uy).astype(np.float64) * (vx * vx + vy * vy).astype(np.float64)
    if cos_limit < 0:        # dot <= cos_limit |u||v| < 0
        return (dot < 0) & (dot * dot >= cos_limit * cos_limit * uv)
    return (dot <= 0) | (dot * dot <= cos_limit * cos_limit * uv)


def _pairs_within(qi, qj, ti, tj, radii) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(query k, target m, squared distance) for every target within radii[k] of query k,
    sorted by (k, distance, m)."""
    if not len(qi) or not len(ti):
        z = np.zeros(0, np.int64)
        return z, z, z
    q = cKDTree(np.stack([qi, qj], axis=1).astype(np.float64))
    t = cKDTree(np.stack([ti, tj], axis=1).astype(np.float64))
    m = q.sparse_distance_matrix(t, float(np.max(radii)), output_type="ndarray")
    k, j = m["i"].astype(np.int64), m["j"].astype(np.int64)
    d2 = (qi[k] - ti[j]) ** 2 + (qj[k] - tj[j]) ** 2
    keep = d2 <= radii[k] ** 2
    k, j, d2 = k[keep], j[keep], d2[keep]
    order = np.lexsort((j, d2, k))
    return k[order], j[order], d2[order]


def _first_in_sight(grid, k, si, sj, ti, tj, n_queries) -> np.ndarray:
    """Per query, the index into the pairs (k sorted, nearest first) of its nearest pair in
    sight (from (si, sj)[k] to (ti, tj)), or -1. Tested in rounds of the next few pairs of
    each query still open: most queries settle in the first round."""
    first = np.full(n_queries, -1, np.int64)
    if not len(k):
        return first
    start = np.searchsorted(k, np.arange(n_queries), "left")
    end = np.searchsorted(k, np.arange(n_queries), "right")
    pos = start.copy()
    while True:
        open_q = np.flatnonzero((first < 0) & (pos < end))
        if not len(open_q):
            return first
        take = np.minimum(end[open_q] - pos[open_q], _SIGHT_BATCH)
        rows = np.repeat(pos[open_q], take) + (np.arange(take.sum()) - np.repeat(np.cumsum(take) - take, take))
        seen = lines_of_sight(grid, si[k[rows]], sj[k[rows]], ti[rows], tj[rows])
        hit = rows[seen]
        # the first hit of each query (rows ascend within a query)
        qs, at = np.unique(k[hit], return_index=True)
        first[qs] = hit[at]
        pos[open_q] += take


def detect_gates(state: np.ndarray, row0: int, col0: int, res_m: float,
                 params: PereiraParams = PARAMS) -> list[GateObservation]:
    """The gates of one state grid, in global cell order of their centres."""
    p = params
    st = close_wall_gaps(np.asarray(state, np.uint8))
    occ = st == kernels.OCCUPIED
    free = st == kernels.FREE
    if not occ.any() or not free.any():
        return []
    rows, cols = st.shape
    _d, (ai, aj) = ndimage.distance_transform_edt(~occ, return_indices=True)
    ii, jj = np.indices(st.shape)
    c2 = (ai - ii) ** 2 + (aj - jj) ** 2                 # squared distance to the nearest wall cell, exact
    cf = np.sqrt(c2.astype(np.float64)) - 0.5          # clearance c in cells, to the wall's face
    r_min = p.r_min_m / res_m
    ok = free & (cf >= r_min)
    cos_gvd = math.cos(math.radians(p.gvd_angle_deg))
    gi, gj = np.nonzero(kernels.wall_jump_cells(ok, ai, aj, c2, cos_gvd))
    if not len(gi):
        return []
    gc2, gc = c2[gi, gj], cf[gi, gj]
    tie = p.c_tie_m / res_m

    # Narrow enough, and observed around.
    frontier = (st == kernels.UNKNOWN) & dilate_square(free, 1)
    # (A k-d tree of the frontier cells gives the distance transform's values, sqrt of the
    # same integers, at the few GVD cells read, for a fraction of its cost.)
    fi, fj = np.nonzero(frontier)
    d_front = cKDTree(np.stack([fi, fj], axis=1).astype(np.float64)).query(
        np.stack([gi, gj], axis=1).astype(np.float64))[0] if len(fi) else np.full(len(gi), np.inf)
    idx = np.flatnonzero((2 * gc * res_m <= p.w_max_m + 1e-9) & (d_front >= gc + p.observed_margin_m / res_m))

    # The narrowest of the GVD around, within c_tie.
    k, m, _d2 = _pairs_within(gi[idx], gj[idx], gi, gj, np.maximum(p.local_min_radius_m / res_m, gc[idx]) + 1e-6)
    lower = gc[m] < gc[idx[k]] - tie
    k, m = k[lower], m[lower]
    beaten = _first_in_sight(st, k, gi[idx], gj[idx], gi[m], gj[m], len(idx)) >= 0
    idx = idx[~beaten]

    # A widening beyond the gate line, in sight for the body; the nearest for the mouth rule.
    ri, rj = np.nonzero(kernels.wall_jump_cells(ok, ai, aj, c2, math.cos(math.radians(p.ridge_angle_deg))))
    r_wide = np.maximum(p.widening_radius_m / res_m, p.widening_radius_c * gc[idx]) + 1e-6
    k, m, d2 = _pairs_within(gi[idx], gj[idx], ri, rj, r_wide)
    pi_, pj_ = gi[idx[k]], gj[idx[k]]
    wy, wx = ri[m] - pi_, rj[m] - pj_
    uy, ux = ai[pi_, pj_] - pi_, aj[pi_, pj_] - pj_
    dot = (wx * ux + wy * uy).astype(np.float64)
    cos_off = math.cos(math.radians(90.0 - p.widening_off_axis_deg))
    good = (cf[ri[m], rj[m]] >= (1.0 + p.widening_kappa) * gc[idx[k]]) & (
        dot * dot <= cos_off * cos_off * (wx * wx + wy * wy).astype(np.float64) * (ux * ux + uy * uy))
    k, m, d2 = k[good], m[good], d2[good]
    roomy = np.where(ok, kernels.FREE, kernels.OCCUPIED).astype(np.uint8)
    first = _first_in_sight(roomy, k, gi[idx], gj[idx], ri[m], rj[m], len(idx))
    keep = first >= 0
    idx, nearest_wide = idx[keep], d2[first[keep]]

    # Both sides open, across the axis to the nearest wall.
    if len(idx):
        uy = (ai[gi[idx], gj[idx]] - gi[idx]).astype(np.float64)
        ux = (aj[gi[idx], gj[idx]] - gj[idx]).astype(np.float64)
        norm = np.hypot(uy, ux)
        ny, nx = ux / norm, -uy / norm                 # unit normal to the axis
        reach = gc[idx] + p.side_depth_m / res_m
        steps = np.arange(1, int(math.ceil(2 * reach.max())) + 1) * 0.5
        t = np.minimum(steps[None, :], reach[:, None])         # half-cell steps, the last at the reach
        opened = np.ones(len(idx), bool)
        for sgn in (1.0, -1.0):
            si = np.floor(gi[idx, None] + 0.5 + sgn * t * ny[:, None]).astype(np.int64)
            sj = np.floor(gj[idx, None] + 0.5 + sgn * t * nx[:, None]).astype(np.int64)
            inside = (si >= 0) & (si < rows) & (sj >= 0) & (sj < cols)
            si, sj = np.clip(si, 0, rows - 1), np.clip(sj, 0, cols - 1)
            opened &= np.all(inside & free[si, sj], axis=1) & (cf[si[:, -1], sj[:, -1]] >= r_min)
        idx, nearest_wide = idx[opened], nearest_wide[opened]
    if not len(idx):
        return []

    # The mouth, and suppression.
    wide_of = dict(zip(idx.tolist(), nearest_wide.tolist()))
    bridge = max(1, int(round(0.1 / res_m)))
    near_k, near_m, _ = _pairs_within(gi[idx], gj[idx], gi[idx], gj[idx], np.full(len(idx), 2.0 * bridge + 1.5))
    neighbours: dict[int, list[int]] = {}
    for a, b in zip(idx[near_k].tolist(), idx[near_m].tolist()):
        neighbours.setdefault(a, []).append(b)
    order = idx[np.lexsort((gj[idx] + col0, gi[idx] + row0, gc2[idx]))].tolist()
    alive = set(order)
    accepted: list[int] = []
    for k0 in order:
        if k0 not in alive:
            continue
        limit = gc[k0] + tie
        stretch, todo = {k0}, [k0]
        while todo:
            for b in neighbours.get(todo.pop(), ()):
                if b in alive and b not in stretch and gc[b] <= limit:
                    stretch.add(b)
                    todo.append(b)
        stretch_a = np.array(sorted(stretch), np.int64)
        wides = np.array([wide_of[x] for x in stretch_a], np.int64)
        # From the end nearest a widening, down the clearance to where it stops falling.
        pick = int(stretch_a[np.lexsort((gj[stretch_a] + col0, gi[stretch_a] + row0, wides))[0]])
        while True:
            lower = [b for b in neighbours.get(pick, ()) if b in stretch and gc2[b] < gc2[pick]]
            if not lower:
                break
            pick = min(lower, key=lambda b: (gc2[b], wide_of[b], gi[b] + row0, gj[b] + col0))
        accepted.append(pick)
        left = np.array(sorted(alive), np.int64)
        r = np.maximum(p.nms_radius_m / res_m, p.nms_radius_c * np.maximum(gc[pick], gc[left]))
        within = left[(gi[left] - gi[pick]) ** 2 + (gj[left] - gj[pick]) ** 2 <= r * r]
        seen = within[lines_of_sight(st, np.full(len(within), gi[pick]), np.full(len(within), gj[pick]),
                                     gi[within], gj[within])]
        alive -= stretch | set(seen.tolist()) | {pick}

    # Jambs.
    occ_i, occ_j = np.nonzero(occ)
    out = []
    for k in accepted:
        pi0, pj0 = int(gi[k]), int(gj[k])
        a_i, a_j = int(ai[pi0, pj0]), int(aj[pi0, pj0])
        r = int(math.ceil(gc[k] + 0.5 + p.jamb_search_m / res_m))
        box = (np.abs(occ_i - pi0) <= r) & (np.abs(occ_j - pj0) <= r)
        bi, bj = occ_i[box], occ_j[box]
        d2 = (bi - pi0) ** 2 + (bj - pj0) ** 2
        good = (d2 <= (gc[k] + 0.5 + p.jamb_search_m / res_m) ** 2) & _angle_at_least(
            np.full(len(bi), a_j - pj0), np.full(len(bi), a_i - pi0), bj - pj0, bi - pi0, cos_gvd)
        if not good.any():
            continue
        bi, bj, d2 = bi[good], bj[good], d2[good]
        b = np.lexsort((bj + col0, bi + row0, d2))[0]
        b_i, b_j = int(bi[b]), int(bj[b])
        out.append(GateObservation(
            x_m=(col0 + pj0 + 0.5) * res_m, y_m=(row0 + pi0 + 0.5) * res_m,
            dir_rad=math.atan2(b_i - a_i, b_j - a_j) % math.pi,
            half_m=0.5 * (math.hypot(b_i - a_i, b_j - a_j) - 1.0) * res_m, clearance_m=float(gc[k]) * res_m,
            cell=(row0 + pi0, col0 + pj0)))
    out.sort(key=lambda g: g.cell)
    return out


def _same_gate(ax: float, ay: float, ad: float, bx: float, by: float, bd: float, dist_m: float,
               angle_rad: float) -> bool:
    dd = abs(ad - bd) % math.pi
    return math.hypot(ax - bx, ay - by) <= dist_m and min(dd, math.pi - dd) <= angle_rad


class GateTracker:
    """Confirmation (5.2 a.6): a gate seen on k_confirm planning cycles in a row (each
    within confirm_dist and confirm_angle of the last sighting) is confirmed once; it is to
    be sent unless a gate the fold already holds lies within r_match and r_match_deg."""

    def __init__(self, params: PereiraParams = PARAMS) -> None:
        self.p = params
        self._tracks: list[tuple[GateObservation, int, bool]] = []   # last sighting, cycles in a row, confirmed

    def update(self, seen: Iterable[GateObservation],
               folded: Iterable[tuple[int, int, int]] = ()) -> list[GateObservation]:
        """One cycle's detections; `folded`: (x_dm, y_dm, dir_code) of the gates the robot's
        region graph holds. Returns the gates newly confirmed and not yet held."""
        p = self.p
        dist, ang = p.confirm_dist_m, math.radians(p.confirm_angle_deg)
        folded = [(x / 10.0, y / 10.0, d * math.pi / DIR_CODES) for x, y, d in folded]
        tracks, out = [], []
        free = list(self._tracks)
        for g in sorted(seen, key=lambda g: g.cell):
            hit = next((k for k, (t, _n, _c) in enumerate(free)
                        if _same_gate(g.x_m, g.y_m, g.dir_rad, t.x_m, t.y_m, t.dir_rad, dist, ang)), None)
            count, confirmed = 1, False
            if hit is not None:
                _t, count, confirmed = free.pop(hit)
                count += 1
            if not confirmed and count >= p.k_confirm:
                confirmed = True
                if not any(_same_gate(g.x_m, g.y_m, g.dir_rad, x, y, d, p.r_match_m, math.radians(p.r_match_deg))
                           for x, y, d in folded):
                    out.append(g)
            tracks.append((g, count, confirmed))
        self._tracks = tracks
        return out


def place_clear_dm(state: np.ndarray, row0: int, col0: int, res_m: float, x_m: float, y_m: float,
                   params: PereiraParams = PARAMS) -> int:
    """clear_dm of a place at (x_m, y_m): the radius of a disc around the place's wire
    position (dm) that is FREE in this map, floored to dm, 0 if its cell is not FREE.

    It is the distance from the place's cell centre to the nearest cell that is not FREE
    (OCCUPIED or UNKNOWN, the window's edge counting as not FREE), less one cell, less how
    far the wire position lies from that cell centre; computed up to clear_cap_m."""
    i = int(math.floor(y_m / res_m)) - row0
    j = int(math.floor(x_m / res_m)) - col0
    rows, cols = state.shape
    if not (0 <= i < rows and 0 <= j < cols) or state[i, j] != kernels.FREE:
        return 0
    r = int(math.ceil(params.clear_cap_m / res_m)) + 2
    i0, i1, j0, j1 = max(0, i - r), min(rows, i + r + 1), max(0, j - r), min(cols, j + r + 1)
    crop = np.zeros((i1 - i0 + 2, j1 - j0 + 2), bool)        # a blocked border
    crop[1:-1, 1:-1] = state[i0:i1, j0:j1] == kernels.FREE
    d_blk = float(ndimage.distance_transform_edt(crop)[i - i0 + 1, j - j0 + 1])
    cx, cy = (col0 + j + 0.5) * res_m, (row0 + i + 0.5) * res_m
    off = math.hypot(dm(x_m) / 10.0 - cx, dm(y_m) / 10.0 - cy)
    clear = min((d_blk - 1.0) * res_m - off, params.clear_cap_m)
    return max(0, min(255, int(math.floor(clear * 10.0))))
