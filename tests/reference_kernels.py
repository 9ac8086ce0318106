"""Plain-Python twins of firmware/kernels.py, written for clarity, not speed.

The tests run both on generated inputs and require the same answers."""
from __future__ import annotations

import heapq
import math

import numpy as np


def bearing_bin(dx, dy, bin0, binw, n):
    """The bin of direction (dx, dy): bins binw wide, bin 0 centred on bin0 in [0, 2 pi)."""
    a = math.atan2(dy, dx) - bin0
    while a < 0:
        a += 2 * math.pi
    return int(a / binw + 0.5) % n


def polar_fill(logodds, row0, col0, res, px, py, bin0, binw, ranges, range_max, hit, miss, lmin, lmax,
               r_lo, r_hi, c_lo, c_hi):
    """Each cell on its own, with its own bearing, in the kernel's arithmetic (squared
    distances, float64 sums stored to the window's dtype) so that the two agree to the bit."""
    out = logodds.copy()
    rows, cols = out.shape
    n = len(ranges)
    bin0 = bin0 % (2 * math.pi)
    longest = min(max([0.0] + [float(r) for r in ranges if r > 0]), range_max)
    reach = longest + res
    for i in range(max(r_lo, math.floor((py - reach) / res) - row0, 0),
                   min(r_hi, math.floor((py + reach) / res) - row0 + 1, rows)):
        for j in range(max(c_lo, math.floor((px - reach) / res) - col0, 0),
                       min(c_hi, math.floor((px + reach) / res) - col0 + 1, cols)):
            cx = (col0 + j + 0.5) * res - px
            cy = (row0 + i + 0.5) * res - py
            d2 = cx * cx + cy * cy
            if float(out[i, j]) <= lmin or d2 >= longest * longest:
                continue
            r = float(ranges[bearing_bin(cx, cy, bin0, binw, n)])
            if not r > 0:
                continue
            limit = r if r >= range_max else r - res / 2
            if d2 < limit * limit and limit > 0:
                out[i, j] = max(lmin, float(out[i, j]) + miss)
    for b, r in enumerate(ranges):
        if not r > 0 or r >= range_max:
            continue
        a = bin0 + b * binw
        i = math.floor((py + (r + res / 2) * math.sin(a)) / res) - row0
        j = math.floor((px + (r + res / 2) * math.cos(a)) / res) - col0
        if r_lo <= i < r_hi and c_lo <= j < c_hi and 0 <= i < rows and 0 <= j < cols:
            out[i, j] = min(lmax, float(out[i, j]) + hit)
    return out


def chamfer_distance(blocked):
    """Multi-source shortest paths over the 8-neighbour grid with steps 1 and sqrt 2."""
    rows, cols = blocked.shape
    d = np.full((rows, cols), np.inf)
    heap = []
    for i, j in zip(*np.nonzero(blocked)):
        d[i, j] = 0.0
        heap.append((0.0, int(i), int(j)))
    heapq.heapify(heap)
    while heap:
        dc, i, j = heapq.heappop(heap)
        if dc > d[i, j]:
            continue
        for di in (-1, 0, 1):
            for dj in (-1, 0, 1):
                if di == dj == 0:
                    continue
                ni, nj = i + di, j + dj
                if 0 <= ni < rows and 0 <= nj < cols:
                    nd = dc + (math.sqrt(2) if di and dj else 1.0)
                    if nd < d[ni, nj]:
                        d[ni, nj] = nd
                        heapq.heappush(heap, (nd, ni, nj))
    return d


def chamfer_raster(blocked):
    """The chamfer's two raster passes cell by cell with edge tests, each cell's least
    candidate taken in float64 (steps of 1 exact, of sqrt 2 as float32 sums) and stored as
    float32: what the kernel must give to the bit, however it orders its work."""
    rows, cols = blocked.shape
    d = np.where(blocked, np.float32(0.0), np.float32(np.inf)).astype(np.float32)
    s2 = np.float32(math.sqrt(2.0))
    for i in range(rows):
        for j in range(cols):
            v = float(d[i, j])
            if i > 0:
                v = min(v, float(d[i - 1, j]) + 1.0)
                if j > 0:
                    v = min(v, float(d[i - 1, j - 1] + s2))
                if j < cols - 1:
                    v = min(v, float(d[i - 1, j + 1] + s2))
            if j > 0:
                v = min(v, float(d[i, j - 1]) + 1.0)
            d[i, j] = np.float32(v)
    for i in range(rows - 1, -1, -1):
        for j in range(cols - 1, -1, -1):
            v = float(d[i, j])
            if i < rows - 1:
                v = min(v, float(d[i + 1, j]) + 1.0)
                if j > 0:
                    v = min(v, float(d[i + 1, j - 1] + s2))
                if j < cols - 1:
                    v = min(v, float(d[i + 1, j + 1] + s2))
            if j < cols - 1:
                v = min(v, float(d[i, j + 1]) + 1.0)
            d[i, j] = np.float32(v)
    return d


def dijkstra_grid(traversable, cost, si, sj):
    """(cost, parent as flat index): heapq pops equal costs by (row, col), the kernel's order."""
    rows, cols = traversable.shape
    d = np.full((rows, cols), np.inf)
    parent = np.full((rows, cols), -1, np.int64)
    if not traversable[si, sj]:
        return d, parent
    d[si, sj] = 0.0
    heap = [(0.0, si, sj)]
    while heap:
        dc, i, j = heapq.heappop(heap)
        if dc > d[i, j]:
            continue
        for di in (-1, 0, 1):
            for dj in (-1, 0, 1):
                if di == dj == 0:
                    continue
                ni, nj = i + di, j + dj
                if not (0 <= ni < rows and 0 <= nj < cols and traversable[ni, nj]):
                    continue
                if di and dj and not (traversable[i, nj] and traversable[ni, j]):
                    continue
                nd = dc + (math.sqrt(2) if di and dj else 1.0) * 0.5 * (cost[i, j] + cost[ni, nj])
                if nd < d[ni, nj]:
                    d[ni, nj] = nd
                    parent[ni, nj] = i * cols + j
                    heapq.heappush(heap, (nd, ni, nj))
    return d, parent


def observable_unknown(state, cand_i, cand_j, n_rays, max_range_cells, unknown=0, occupied=2):
    rows, cols = state.shape
    out = []
    dtheta = 2 * math.pi / n_rays
    for ci, cj in zip(cand_i, cand_j):
        total = 0.0
        for k in range(n_rays):
            a = k * dtheta
            for s in range(1, int(max_range_cells) + 1):
                i = ci + math.floor(0.5 + s * math.sin(a))
                j = cj + math.floor(0.5 + s * math.cos(a))
                if not (0 <= i < rows and 0 <= j < cols) or state[i, j] == occupied:
                    break
                if state[i, j] == unknown:
                    total += s * dtheta
        out.append(total)
    return np.array(out)


def unknown_box_counts(state, half_cells, rows, cols, unknown=0):
    """Count the unknown cells of each clipped square one by one."""
    return np.array([int((state[max(0, i - half_cells):max(0, i + half_cells + 1),
                                max(0, j - half_cells):max(0, j + half_cells + 1)] == unknown).sum())
                     for i, j in zip(rows, cols)], np.int64)


def mark_visible(state, src_i, src_j, n_rays, max_range_cells, wanted, occupied=2):
    rows, cols = state.shape
    out = np.zeros((rows, cols), bool)
    dtheta = 2 * math.pi / n_rays
    for ci, cj in zip(src_i, src_j):
        for k in range(n_rays):
            a = k * dtheta
            for s in range(0, int(max_range_cells) + 1):
                i = ci + math.floor(0.5 + s * math.sin(a))
                j = cj + math.floor(0.5 + s * math.cos(a))
                if not (0 <= i < rows and 0 <= j < cols) or state[i, j] == occupied:
                    break
                out[i, j] = wanted[i, j]
    return out


SUBCELL_OFFSETS = [(0, 0), (-1, 0), (1, 0), (0, -1), (0, 1), (-1, -1), (-1, 1), (1, -1), (1, 1)]


def square_dilation(mask, r):
    """Each cell: is any cell of the (clipped) square of side 2 r + 1 around it True?"""
    rows, cols = mask.shape
    out = np.zeros((rows, cols), bool)
    for i in range(rows):
        for j in range(cols):
            out[i, j] = bool(mask[max(i - r, 0):i + r + 1, max(j - r, 0):j + r + 1].any())
    return out


def cells_near_changes(state, changed, r, i0, i1, j0, j1, free=1):
    """The near cells of the sub-rectangle: np.nonzero of the FREE ones, a mask of the others."""
    near = np.zeros(state.shape, bool)
    near[i0:i1, j0:j1] = square_dilation(changed, r)[i0:i1, j0:j1]
    return (*np.nonzero(near & (state == free)), near & (state != free))


def best_standing_points(occupied, cells_i, cells_j, half_side_cells, reach_cells):
    """Every sub-cell point against every occupied cell's square in the kernel's window."""
    walls = np.argwhere(occupied)
    best_d, best_k = [], []
    for ci, cj in zip(cells_i, cells_j):
        scores = []
        for di, dj in SUBCELL_OFFSETS:
            pi, pj = ci + 0.5 * di, cj + 0.5 * dj
            near = [math.hypot(max(abs(i - pi) - half_side_cells, 0.0), max(abs(j - pj) - half_side_cells, 0.0))
                    for i, j in walls if max(abs(i - ci), abs(j - cj)) <= math.ceil(reach_cells)]
            d = min(near, default=math.inf)
            scores.append(min(d, reach_cells))
        k = int(np.argmax(scores))      # the first of the best
        best_d.append(scores[k])
        best_k.append(k)
    return np.array(best_d, np.float32), np.array(best_k, np.int8)


def scan_match_scores(field, row0, col0, res, x, y, yaw, beam_x, beam_y, dxs, dys, dyaws):
    """For each pose offset, the mean over the endpoints of the field interpolated
    bilinearly between cell centres; an endpoint whose four cells are not all inside reads 0."""
    n_r, n_c = field.shape
    out = np.zeros((len(dyaws), len(dxs), len(dys)))
    for k, dyaw in enumerate(dyaws):
        c, s = math.cos(yaw + dyaw), math.sin(yaw + dyaw)
        for a, dx in enumerate(dxs):
            for b, dy in enumerate(dys):
                total = 0.0
                for bxm, bym in zip(beam_x, beam_y):
                    fx = (c * bxm - s * bym + x + dx) / res - col0 - 0.5
                    fy = (s * bxm + c * bym + y + dy) / res - row0 - 0.5
                    j0, i0 = math.floor(fx), math.floor(fy)
                    if 0 <= i0 < n_r - 1 and 0 <= j0 < n_c - 1:
                        tx, ty = fx - j0, fy - i0
                        total += ((1 - ty) * (1 - tx) * field[i0, j0] + (1 - ty) * tx * field[i0, j0 + 1]
                                  + ty * (1 - tx) * field[i0 + 1, j0] + ty * tx * field[i0 + 1, j0 + 1])
                out[k, a, b] = total / len(beam_x) if len(beam_x) else 0.0
    return out


def crack_contours(free, occupied):
    """Contours along cell borders with dicts of outgoing cracks per corner: each free cell
    adds its border cracks; each contour is walked from its start, left turns first."""
    rows, cols = free.shape
    out: dict[tuple[int, int], dict[int, int]] = {}

    def add(x, y, d, r, c):
        wall = 0 <= r < rows and 0 <= c < cols and bool(occupied[r, c])
        out.setdefault((x, y), {})[d] = 1 if wall else 0

    def is_free(r, c):
        return 0 <= r < rows and 0 <= c < cols and bool(free[r, c])

    for r in range(rows):
        for c in range(cols):
            if not free[r, c]:
                continue
            if not is_free(r - 1, c):
                add(c, r, 0, r - 1, c)
            if not is_free(r, c + 1):
                add(c + 1, r, 1, r, c + 1)
            if not is_free(r + 1, c):
                add(c + 1, r + 1, 2, r + 1, c)
            if not is_free(r, c - 1):
                add(c, r + 1, 3, r, c - 1)
    steps = ((1, 0), (0, 1), (-1, 0), (0, -1))
    corners, types, starts = [], [], [0]
    for start in sorted(out, key=lambda p: (p[1], p[0])):
        while out.get(start):
            here = start
            first = d = min(out[start])
            while True:
                t = out[here].pop(d)
                corners.append(here)
                types.append(t)
                here = (here[0] + steps[d][0], here[1] + steps[d][1])
                options = out.get(here, {})
                d = next(k for k in ((d + 1) % 4, d, (d + 3) % 4)
                         if k in options or (here == start and k == first))
                if here == start and d == first:
                    break
            starts.append(len(corners))
    return (np.array(corners, np.int64).reshape(-1, 2), np.array(types, np.int8), np.array(starts, np.int64))


def slip_misfits(ref_x, ref_y, turned_x, turned_y, travel_x, travel_y, shares, gap_m, cap_m, cell_m):
    """The slip check's fit in numpy, as the firmware first wrote it: neighbours' normals,
    every share's moved points at once, the nearest reference point by brute force (lowest
    index on a tie), capped distances, numpy means."""
    points = np.column_stack((ref_x, ref_y))
    normals = np.full(points.shape, np.nan)
    if len(points) >= 3:
        before, after = points[:-2], points[2:]
        near = (np.hypot(*(points[1:-1] - before).T) < gap_m) & (np.hypot(*(after - points[1:-1]).T) < gap_m)
        tangent = after - before
        length = np.hypot(tangent[:, 0], tangent[:, 1])
        ok = near & (length > 0.0)
        normals[1:-1][ok] = np.column_stack((-tangent[ok, 1], tangent[ok, 0])) / length[ok, None]
    turned = np.column_stack((turned_x, turned_y))
    moved = turned[None, :, :] + shares[:, None, None] * np.array([travel_x, travel_y])
    misfit = np.full(len(shares), np.nan)
    counted = np.zeros(len(shares), np.int64)
    for s in range(len(shares)):
        d2 = ((moved[s][:, None, :] - points[None, :, :]) ** 2).sum(axis=2)
        nearest = np.argmin(d2, axis=1)
        along = np.abs(((moved[s] - points[nearest]) * normals[nearest]).sum(axis=1))
        on_surface = ~np.isnan(along)
        counted[s] = np.count_nonzero(on_surface)
        if counted[s]:
            misfit[s] = np.minimum(along, cap_m)[on_surface].mean()
    return misfit, counted


def wall_jump_cells(ok, ai, aj, c2, cos_limit):
    """Every pair of neighbours (4- or diagonal) in whole-array numpy, as the gate finder
    first did it: for each offset, the pairs both ok whose nearest walls lie at least
    acos(cos_limit) apart seen from the first; the one farther from its wall is marked."""
    rows, cols = ok.shape
    ii, jj = np.indices(ok.shape)
    out = np.zeros(ok.shape, bool)
    for di, dj in ((0, 1), (1, 0), (1, 1), (1, -1)):
        pj0, pj1 = max(0, -dj), cols - max(0, dj)
        sp = (slice(0, rows - di), slice(pj0, pj1))
        sq = (slice(di, rows), slice(pj0 + dj, pj1 + dj))
        uy, ux = ai[sp] - ii[sp], aj[sp] - jj[sp]
        vy, vx = ai[sq] - ii[sp], aj[sq] - jj[sp]
        dot = (ux * vx + uy * vy).astype(np.float64)
        uv = (ux * ux + uy * uy).astype(np.float64) * (vx * vx + vy * vy).astype(np.float64)
        if cos_limit < 0:
            apart = (dot < 0) & (dot * dot >= cos_limit * cos_limit * uv)
        else:
            apart = (dot <= 0) | (dot * dot <= cos_limit * cos_limit * uv)
        pair = ok[sp] & ok[sq] & apart
        p_wins = c2[sp] >= c2[sq]
        out[sp] |= pair & p_wins
        out[sq] |= pair & ~p_wins
    return out
