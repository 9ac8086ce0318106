"""The firmware's hot loops, compiled with numba.

Each kernel has a plain-Python twin in tests/reference_kernels.py, and the tests prove
they agree on generated inputs. Grids are indexed [row, col] with row 0 at the lowest y.
The local window is anchored on a global integer cell lattice: window cell (i, j) is global
cell (row0 + i, col0 + j), whose centre is ((col0 + j + 0.5) * res, (row0 + i + 0.5) * res).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

UNKNOWN = np.uint8(0)
FREE = np.uint8(1)
OCCUPIED = np.uint8(2)
# Unknown to this robot but in view of a place a teammate reported being at: not counted as
# information, and transparent to rays like UNKNOWN (see schemes/bayer_faigl/presence.py).
SEEN_BY_TEAM = np.uint8(3)


@njit(cache=True)
def bearing_bin(dx, dy, bin0_rad, bin_rad, n):
    """Index of the bearing bin (width bin_rad, bin 0 centred on bin0_rad in [0, 2 pi))
    that the direction (dx, dy) falls in."""
    a = math.atan2(dy, dx) - bin0_rad
    while a < 0.0:
        a += 2.0 * math.pi
    b = int(a / bin_rad + 0.5)
    while b >= n:
        b -= n
    return b


# atan(z) ~ z * P(z^2) on [0, 1], a least-squares fit with an error below 3e-7 rad (the tests
# check 1e-6 densely): the bound below has a wide slack.
_ATAN_P = (0.9999956229973079, -0.3331600082890011, 0.19796881437698616, -0.1319586197724881,
           0.07899909561206236, -0.033104606824052196, 0.006658074915354038)
BEARING_APPROX_ERROR_RAD = 1e-5
# The approximate and the exact bearing from bin 0 differ by the bound above plus math.atan2's
# own error (an ulp or two) and the rounding of the few operations either way (below 1e-13
# rad): twice the bound covers all.
_MARGIN_RAD = 2.0 * BEARING_APPROX_ERROR_RAD
_BLOCK_CELLS = 12   # polar_fill's blocks, a side: the fastest of 8 to 32 on maze scans at 0.1 m


@njit(cache=True, inline='always')
def bearing_approx_rad(dx, dy):
    """math.atan2(dy, dx) within BEARING_APPROX_ERROR_RAD, with the same signs (that of dy;
    +-pi on the negative x axis), and NaN at the origin: a few multiplications instead of a
    libm call."""
    ax = abs(dx)
    ay = abs(dy)
    if not (ax > 0.0 or ay > 0.0):
        return math.nan
    steep = ay > ax
    z = ax / ay if steep else ay / ax
    s = z * z
    p0, p1, p2, p3, p4, p5, p6 = _ATAN_P
    s2 = s * s
    r = z * ((p0 + s * p1) + s2 * ((p2 + s * p3) + s2 * ((p4 + s * p5) + s2 * p6)))
    if steep:
        r = 0.5 * math.pi - r
    if dx < 0.0:
        r = math.pi - r
    return math.copysign(r, dy)


@njit(cache=True, inline='always')
def _bearing_from_bin0(dx, dy, bin0_rad):
    """bearing_bin's angle before it becomes a bin, approximately: the bearing from bin 0's
    centre, wrapped the same way into [0, 2 pi)."""
    a = bearing_approx_rad(dx, dy) - bin0_rad
    while a < 0.0:
        a += 2.0 * math.pi
    return a


@njit(cache=True, inline='always')
def _cell_free(dx, dy, d2, free_below_m2, bin0_rad, bin_rad, bins_per_rad, margin_bins, n):
    """d2 < free_below_m2[bearing_bin(dx, dy, bin0_rad, bin_rad, n)], exactly, with the atan2
    only when the approximate bearing cannot tell: at most two bins lie within margin_bins of
    its bin coordinate, and when they agree either is the answer. Bins either side of bin 0's
    wrap may be far apart in index, so a bearing near it goes to atan2 too."""
    a = _bearing_from_bin0(dx, dy, bin0_rad)
    if _MARGIN_RAD < a < 2.0 * math.pi - _MARGIN_RAD and margin_bins < 0.25:
        t = a * bins_per_rad + 0.5
        k_lo = int(t - margin_bins)
        k_hi = int(t + margin_bins)
        while k_hi >= n:
            k_lo -= n
            k_hi -= n
        if k_lo < 0:
            k_lo += n
        free = d2 < free_below_m2[k_lo]
        if k_lo == k_hi or free == (d2 < free_below_m2[k_hi]):
            return free
    return d2 < free_below_m2[bearing_bin(dx, dy, bin0_rad, bin_rad, n)]


@njit(cache=True)
def _abs_span(lo, hi):
    """The least and greatest |v| over v in [lo, hi] (the least is 0 when the span holds 0)."""
    if lo > 0.0:
        return lo, hi
    if hi < 0.0:
        return -hi, -lo
    return 0.0, max(-lo, hi)


@njit(cache=True)
def _sector_bounds(a0, a1, a2, a3, free_below_m2, bins_per_rad, margin_bins, n, beyond_m2):
    """The least and greatest free_below_m2 over the bins that cells inside the rectangle with
    corner bearings a0..a3 (approximate, from _bearing_from_bin0) can fall in; (-1, beyond_m2)
    when that is not bounded: the rectangle subtends more than a quarter turn (as it does
    when it holds the sensor), comes near bin 0's wrap, or the bins are too fine.

    A rectangle clear of the sensor that subtends less than half a turn has every point's
    bearing between its corners'. The corners' approximate bin coordinates are within
    margin_bins of their true ones, and the cells' exact coordinates within margin_bins of
    theirs, so the cells' bins lie within twice margin_bins of the corners' span; the edge
    keeps their true bearings clear of the wrap, so that the exact ones wrap the same way."""
    two_pi = 2.0 * math.pi
    edge = 2.0 * _MARGIN_RAD
    if not (edge < a0 < two_pi - edge and edge < a1 < two_pi - edge and edge < a2 < two_pi - edge
            and edge < a3 < two_pi - edge and 2.0 * margin_bins < 0.25):
        return -1.0, beyond_m2
    a_lo = min(min(a0, a1), min(a2, a3))
    a_hi = max(max(a0, a1), max(a2, a3))
    if a_hi - a_lo > 0.5 * math.pi:
        return -1.0, beyond_m2
    k_first = int(a_lo * bins_per_rad + 0.5 - 2.0 * margin_bins)
    k_last = int(a_hi * bins_per_rad + 0.5 + 2.0 * margin_bins)
    k = k_first % n
    lo = math.inf
    hi = -math.inf
    for _ in range(k_last - k_first + 1):
        f = free_below_m2[k]
        lo = min(lo, f)
        hi = max(hi, f)
        k += 1
        if k == n:
            k = 0
    return lo, hi


@njit(cache=True, parallel=True)
def polar_fill(logodds, row0, col0, res, px, py, bin0_rad, bin_rad, ranges_m, range_max_m,
               hit, miss, lmin, lmax, r_lo, r_hi, c_lo, c_hi):
    """Fold one scan, binned by bearing, into the log-odds window, inside rows [r_lo, r_hi)
    and cols [c_lo, c_hi) only.

    A cell is free when its centre is nearer than its bearing's range (by half a cell when
    that beam hit something), so the free region is the scan's whole visibility polygon with
    no gaps between beams; the cell just beyond each hit is occupied. Bins with a range <= 0
    or NaN carry no information.

    Cells go in square blocks, which bound the ranges of the bins their cells can fall in
    from the bearings of their corners: against those bounds most cells are told free or not
    by their distance alone, and only the rest need their own bearing.
    """
    n = ranges_m.shape[0]
    rows, cols = logodds.shape
    half = 0.5 * res
    two_pi = 2.0 * math.pi
    bin0 = bin0_rad % two_pi
    # Only as far as the longest beam: in tunnels that is far less than the sensor's range.
    longest = 0.0
    for b in range(n):
        r = ranges_m[b]
        if r > longest:
            longest = r
    longest = min(longest, range_max_m)
    reach = longest + res
    reach2 = longest * longest
    # A cell in bin b is free when its squared distance d2 < free_below_m2[b] (never when -1:
    # no information), beyond the reach included.
    free_below_m2 = np.empty(n)
    for b in range(n):
        r = ranges_m[b]
        limit = r if r >= range_max_m else r - half
        f = limit * limit if r > 0.0 and limit > 0.0 else -1.0
        free_below_m2[b] = reach2 if reach2 < f else f
    beyond_m2 = reach2 if reach2 == reach2 else math.inf
    if bin_rad > 0.0:
        bins_per_rad = 1.0 / bin_rad
        # + the rounding of a bin coordinate: approximate bearings are used only with
        # margin_bins < 0.25, i.e. fewer than 12500 bins a radian, so coordinates below 1e5.
        margin_bins = _MARGIN_RAD * bins_per_rad + 1e-6
    else:
        bins_per_rad = 0.0
        margin_bins = math.inf  # no approximate bearings: all from atan2
    i_lo = max(r_lo, int(math.floor((py - reach) / res)) - row0, 0)
    i_hi = min(r_hi, int(math.floor((py + reach) / res)) - row0 + 1, rows)
    j_lo = max(c_lo, int(math.floor((px - reach) / res)) - col0, 0)
    j_hi = min(c_hi, int(math.floor((px + reach) / res)) - col0 + 1, cols)
    side = _BLOCK_CELLS
    # Rows of blocks in parallel: each cell's update depends on that cell alone, so the
    # result is the same whatever the thread count.
    for block_row in prange(max(0, (i_hi - i_lo + side - 1) // side)):
        i_a = i_lo + block_row * side
        i_b = min(i_a + side, i_hi)
        # A block's cell centres lie in the rectangle from its first cell's centre to the
        # next block's first cell's (the offsets are monotonic in the index), whose corners
        # it shares with its neighbours.
        y_a = (row0 + i_a + 0.5) * res - py
        y_b = (row0 + i_b + 0.5) * res - py
        ay_lo, ay_hi = _abs_span(min(y_a, y_b), max(y_a, y_b))
        x_b = (col0 + j_lo + 0.5) * res - px
        a_ab = _bearing_from_bin0(x_b, y_a, bin0)
        a_bb = _bearing_from_bin0(x_b, y_b, bin0)
        for j_a in range(j_lo, j_hi, side):
            j_b = min(j_a + side, j_hi)
            x_a, a_aa, a_ba = x_b, a_ab, a_bb
            x_b = (col0 + j_b + 0.5) * res - px
            a_ab = _bearing_from_bin0(x_b, y_a, bin0)
            a_bb = _bearing_from_bin0(x_b, y_b, bin0)
            ax_lo, ax_hi = _abs_span(min(x_a, x_b), max(x_a, x_b))
            if ax_lo * ax_lo + ay_lo * ay_lo >= beyond_m2:
                continue  # beyond every beam's reach
            free_lo, free_hi = _sector_bounds(a_aa, a_ab, a_ba, a_bb, free_below_m2, bins_per_rad, margin_bins, n,
                                              beyond_m2)
            if ax_lo * ax_lo + ay_lo * ay_lo >= free_hi:
                continue
            for i in range(i_a, i_b):
                cy = (row0 + i + 0.5) * res - py
                for j in range(j_a, j_b):
                    if logodds[i, j] <= lmin:
                        continue  # already as free as it gets: a miss cannot change it (hits come below)
                    cx = (col0 + j + 0.5) * res - px
                    d2 = cx * cx + cy * cy
                    if d2 >= free_hi:
                        continue
                    if not d2 < free_lo and not _cell_free(cx, cy, d2, free_below_m2, bin0, bin_rad, bins_per_rad,
                                                           margin_bins, n):
                        continue
                    v = logodds[i, j] + miss
                    logodds[i, j] = v if v > lmin else lmin
    for b in range(n):
        r = ranges_m[b]
        if not r > 0.0 or r >= range_max_m:
            continue
        a = bin0 + b * bin_rad  # wrapped like the cells above: a scan and its keyframe hit the same cells
        hx = px + (r + half) * math.cos(a)
        hy = py + (r + half) * math.sin(a)
        i = int(math.floor(hy / res)) - row0
        j = int(math.floor(hx / res)) - col0
        if r_lo <= i < r_hi and c_lo <= j < c_hi and 0 <= i < rows and 0 <= j < cols:
            v = logodds[i, j] + hit
            logodds[i, j] = v if v < lmax else lmax


@njit(cache=True)
def classify(logodds, occupied_above, free_below):
    """Log-odds to UNKNOWN / FREE / OCCUPIED."""
    rows, cols = logodds.shape
    out = np.zeros((rows, cols), np.uint8)
    for i in range(rows):
        for j in range(cols):
            v = logodds[i, j]
            if v > occupied_above:
                out[i, j] = OCCUPIED
            elif v < free_below:
                out[i, j] = FREE
    return out


@njit(cache=True)
def _chamfer_passes(d):
    """Two raster passes of the 8-neighbour chamfer (steps 1 and sqrt 2), in place, over a
    field that holds 0 at the sources and +inf elsewhere, inside a border one cell wide of
    +inf: a border neighbour never lowers a value, so no cell needs a test for the edges."""
    rows, cols = d.shape
    s2 = np.float32(math.sqrt(2.0))
    one = np.float32(1.0)
    # In float32 throughout: rounding is monotone, so the least of the rounded sums is the
    # rounded least of the exact ones, as if summed wider and stored once.
    for i in range(1, rows - 1):
        # The row above first (no cell of the row waits for another), then along the row.
        for j in range(1, cols - 1):
            d[i, j] = min(min(d[i, j], d[i - 1, j] + one), min(d[i - 1, j - 1] + s2, d[i - 1, j + 1] + s2))
        for j in range(1, cols - 1):
            d[i, j] = min(d[i, j], d[i, j - 1] + one)
    for i in range(rows - 2, 0, -1):
        for j in range(cols - 2, 0, -1):
            d[i, j] = min(min(d[i, j], d[i + 1, j] + one), min(d[i + 1, j - 1] + s2, d[i + 1, j + 1] + s2))
        for j in range(cols - 2, 0, -1):
            d[i, j] = min(d[i, j], d[i, j + 1] + one)


@njit(cache=True)
def chamfer_distance(blocked):
    """Distance in cells from every cell to the nearest blocked cell (8-neighbour chamfer,
    steps 1 and sqrt 2: exact along axes and diagonals, at most 8 % long in between).
    With no blocked cell at all every distance is +inf."""
    rows, cols = blocked.shape
    d = np.full((rows + 2, cols + 2), np.inf, np.float32)
    for i in range(rows):
        for j in range(cols):
            if blocked[i, j]:
                d[i + 1, j + 1] = 0.0
    _chamfer_passes(d)
    return d[1:rows + 1, 1:cols + 1].copy()


@njit(cache=True, parallel=True)
def chamfer_distances(state):
    """(distance to the nearest OCCUPIED cell, distance to the nearest cell that is not
    FREE), in cells; each as chamfer_distance would give it."""
    rows, cols = state.shape
    d_occ = np.full((rows + 2, cols + 2), np.inf, np.float32)
    d_blk = np.full((rows + 2, cols + 2), np.inf, np.float32)
    for i in range(rows):
        for j in range(cols):
            v = state[i, j]
            if v == OCCUPIED:
                d_occ[i + 1, j + 1] = 0.0
            if v != FREE:
                d_blk[i + 1, j + 1] = 0.0
    for k in prange(2):        # the two fields are independent: one per thread
        _chamfer_passes(d_occ if k == 0 else d_blk)
    return d_occ[1:rows + 1, 1:cols + 1].copy(), d_blk[1:rows + 1, 1:cols + 1].copy()


@njit(cache=True)
def wall_jump_cells(ok, ai, aj, c2, cos_limit):
    """Cells of `ok` where the nearest wall jumps (a Voronoi diagram of the walls on a grid):
    of two neighbours p, q (4- or diagonal), both ok, whose nearest wall cells (ai, aj) lie
    at least acos(cos_limit) apart seen from p, the one with the larger squared distance c2
    to its wall (ties: p, the lower in cell order). The angle test squares, so no roots:
    cos(u, v) <= cos_limit."""
    rows, cols = ok.shape
    out = np.zeros((rows, cols), np.bool_)
    cc = cos_limit * cos_limit
    for i in range(rows):
        for j in range(cols):
            if not ok[i, j]:
                continue
            uy = np.int64(ai[i, j]) - i
            ux = np.int64(aj[i, j]) - j
            uu = float(ux * ux + uy * uy)
            for di, dj in ((0, 1), (1, 0), (1, 1), (1, -1)):     # each pair once
                qi, qj = i + di, j + dj
                if qi >= rows or qj < 0 or qj >= cols or not ok[qi, qj]:
                    continue
                vy = np.int64(ai[qi, qj]) - i
                vx = np.int64(aj[qi, qj]) - j
                dot = float(ux * vx + uy * vy)
                uv = uu * float(vx * vx + vy * vy)
                if cos_limit < 0:
                    pair = dot < 0 and dot * dot >= cc * uv
                else:
                    pair = dot <= 0 or dot * dot <= cc * uv
                if pair:
                    if c2[i, j] >= c2[qi, qj]:
                        out[i, j] = True
                    else:
                        out[qi, qj] = True
    return out


@njit(cache=True)
def square_dilation(mask, r):
    """Cells within r cells (Chebyshev) of a True cell of mask: any(mask) over the square of
    side 2 r + 1 around each cell, clipped to the grid. Two passes of running counts (rows,
    then columns), so the cost does not grow with r."""
    rows, cols = mask.shape
    across = np.zeros((rows, cols), np.int32)    # True cells within r along the row
    for i in range(rows):
        count = 0
        for j in range(min(r, cols)):
            count += mask[i, j]
        for j in range(cols):
            if j + r < cols:
                count += mask[i, j + r]
            if j - r - 1 >= 0:
                count -= mask[i, j - r - 1]
            across[i, j] = count
    out = np.zeros((rows, cols), np.bool_)
    count_col = np.zeros(cols, np.int32)
    for i in range(min(r, rows)):
        for j in range(cols):
            count_col[j] += across[i, j]
    for i in range(rows):
        for j in range(cols):
            if i + r < rows:
                count_col[j] += across[i + r, j]
            if i - r - 1 >= 0:
                count_col[j] -= across[i - r - 1, j]
            out[i, j] = count_col[j] > 0
    return out


@njit(cache=True)
def cells_near_changes(state, changed, r, i0, i1, j0, j1):
    """The cells of [i0, i1) x [j0, j1) within r cells (Chebyshev, square_dilation) of a
    changed cell, split into the FREE ones, listed in row-major order (free_i, free_j), and
    a mask of the others."""
    near = square_dilation(changed, r)
    others = np.zeros(state.shape, np.bool_)
    n_free = 0
    for i in range(i0, i1):
        for j in range(j0, j1):
            if near[i, j]:
                if state[i, j] == FREE:
                    n_free += 1
                else:
                    others[i, j] = True
    free_i = np.empty(n_free, np.int64)
    free_j = np.empty(n_free, np.int64)
    n_free = 0
    for i in range(i0, i1):
        for j in range(j0, j1):
            if near[i, j] and state[i, j] == FREE:
                free_i[n_free] = i
                free_j[n_free] = j
                n_free += 1
    return free_i, free_j, others


# Where in a cell the body may stand: its centre, the midpoints of its sides and its corners,
# in half cells. A door an even number of cells wide has its middle on a cell edge.
SUBCELL_OFFSETS = np.array([(0, 0), (-1, 0), (1, 0), (0, -1), (0, 1), (-1, -1), (-1, 1), (1, -1), (1, 1)],
                           np.int8)


@njit(cache=True)
def best_standing_points(occupied, cells_i, cells_j, half_side_cells, reach_cells):
    """For each listed cell, the point of it (SUBCELL_OFFSETS, first best on ties) farthest
    from every occupied cell, and that distance in cells. An occupied cell stands for a
    square of half_side_cells around its centre (0.5: the whole cell). Walls farther than
    reach_cells are not looked at, so a distance of reach_cells or more reads as reach_cells.
    Returns (distance_cells float32[n], offset index int8[n])."""
    rows, cols = occupied.shape
    n = cells_i.shape[0]
    best_d = np.empty(n, np.float32)
    best_k = np.zeros(n, np.int8)
    r = int(math.ceil(reach_cells))
    wi = np.empty((2 * r + 1) * (2 * r + 1), np.int64)
    wj = np.empty((2 * r + 1) * (2 * r + 1), np.int64)
    for c in range(n):
        ci = cells_i[c]
        cj = cells_j[c]
        m = 0
        for i in range(max(ci - r, 0), min(ci + r + 1, rows)):
            for j in range(max(cj - r, 0), min(cj + r + 1, cols)):
                if occupied[i, j]:
                    wi[m] = i
                    wj[m] = j
                    m += 1
        top = -1.0
        for k in range(SUBCELL_OFFSETS.shape[0]):
            pi = ci + 0.5 * SUBCELL_OFFSETS[k, 0]
            pj = cj + 0.5 * SUBCELL_OFFSETS[k, 1]
            d2 = reach_cells * reach_cells
            for w in range(m):
                ei = max(abs(wi[w] - pi) - half_side_cells, 0.0)
                ej = max(abs(wj[w] - pj) - half_side_cells, 0.0)
                e2 = ei * ei + ej * ej
                if e2 < d2:
                    d2 = e2
            d = math.sqrt(d2)
            if d > top:
                top = d
                best_k[c] = k
        best_d[c] = top
    return best_d, best_k


@njit(cache=True)
def _sift_up(keys, vals, pos, i):
    """Move heap entry i up to its place. The heap is ordered by (key, val), so ties between
    equal costs go to the lower flat index and the result is reproducible."""
    key = keys[i]
    val = vals[i]
    while i > 0:
        parent = (i - 1) >> 1
        if keys[parent] < key or (keys[parent] == key and vals[parent] <= val):
            break
        keys[i] = keys[parent]
        vals[i] = vals[parent]
        pos[vals[i]] = i
        i = parent
    keys[i] = key
    vals[i] = val
    pos[val] = i


@njit(cache=True)
def _pop_top(keys, vals, pos, size):
    """Remove the top entry (the caller read keys[0], vals[0] first); returns the new size."""
    pos[vals[0]] = -2          # settled: never enters the heap again
    size -= 1
    if size == 0:
        return 0
    key = keys[size]
    val = vals[size]
    i = 0
    while True:
        child = 2 * i + 1
        if child >= size:
            break
        right = child + 1
        if right < size and (keys[right] < keys[child] or (keys[right] == keys[child] and vals[right] < vals[child])):
            child = right
        if key < keys[child] or (key == keys[child] and val <= vals[child]):
            break
        keys[i] = keys[child]
        vals[i] = vals[child]
        pos[vals[i]] = i
        i = child
    keys[i] = key
    vals[i] = val
    pos[val] = i
    return size


@njit(cache=True)
def dijkstra_start(traversable, start_i, start_j, dist, parent, keys, vals, pos, size):
    """Set the arrays of a shortest-path search over the grid from one start cell to its
    state before any cell is settled: dist and parent (rows x cols), the heap's keys and
    values and each cell's heap slot (rows * cols each), the heap size (1 element).
    dijkstra_settle advances it. The caller owns the arrays, so a robot that plans every
    second reuses them instead of paging in fresh megabytes each time."""
    rows, cols = traversable.shape
    dist[:, :] = np.inf
    parent[:, :] = -1
    pos[:] = -1                                # heap slot of each cell; -1 never seen, -2 settled
    size[0] = 0
    if traversable[start_i, start_j]:
        keys[0] = 0.0
        vals[0] = start_i * cols + start_j
        pos[vals[0]] = 0
        size[0] = 1
        dist[start_i, start_j] = 0.0


def dijkstra_arrays(rows, cols):
    """Fresh arrays for dijkstra_start: (dist, parent, keys, vals, pos, size)."""
    return (np.empty((rows, cols), np.float64), np.empty((rows, cols), np.int64), np.empty(rows * cols, np.float64),
            np.empty(rows * cols, np.int64), np.empty(rows * cols, np.int64), np.empty(1, np.int64))


@njit(cache=True)
def _settle_top(traversable, cell_cost, dist, parent, keys, vals, pos, n):
    """Settle the heap's top cell and relax its neighbours; returns (its flat index, the
    new heap size). A step costs its length in cells times the mean of the two cells' cost
    factors, so a path through narrow places pays for hugging walls (Bayer & Faigl IV-A).
    Diagonal steps may not cut a blocked corner."""
    rows, cols = traversable.shape
    s2 = math.sqrt(2.0)
    dcur = keys[0]
    flat = vals[0]
    n = _pop_top(keys, vals, pos, n)
    i = flat // cols
    j = flat - i * cols
    for di in range(-1, 2):
        for dj in range(-1, 2):
            if di == 0 and dj == 0:
                continue
            ni = i + di
            nj = j + dj
            if ni < 0 or nj < 0 or ni >= rows or nj >= cols or not traversable[ni, nj]:
                continue
            diagonal = di != 0 and dj != 0
            if diagonal and not (traversable[i, nj] and traversable[ni, j]):
                continue
            step = s2 if diagonal else 1.0
            nd = dcur + step * 0.5 * (cell_cost[i, j] + cell_cost[ni, nj])
            if nd < dist[ni, nj]:
                dist[ni, nj] = nd
                parent[ni, nj] = flat
                nflat = ni * cols + nj
                slot = pos[nflat]
                if slot == -1:
                    slot = n
                    n += 1
                keys[slot] = nd
                vals[slot] = nflat
                _sift_up(keys, vals, pos, slot)
    return flat, n


@njit(cache=True)
def _mask_of(flat, n_cells):
    """A mask over n_cells, true at the flat indices given."""
    mask = np.zeros(n_cells, np.bool_)
    for f in flat:
        mask[f] = True
    return mask


@njit(cache=True)
def dijkstra_settle(traversable, cell_cost, dist, parent, keys, vals, pos, size, want_flat):
    """Run the search of dijkstra_start until every cell in want_flat is settled (its dist
    and parent final) or nothing is left to settle; an empty want_flat runs it to the end.

    The heap orders ties by flat index, so cells settle in the same order however the
    search is split into calls (this one, dijkstra_settle_first, dijkstra_settle_below): a
    settled cell's dist and parent are those of the full search. It holds each cell at
    most once (a better cost moves the cell up in place), which keeps it small on open maps.
    """
    waiting = 0
    for f in want_flat:
        if pos[f] != -2:
            waiting += 1
    if waiting == 0 and want_flat.shape[0] > 0:
        return
    wanted = _mask_of(want_flat, pos.shape[0])
    n = size[0]
    while n > 0:
        flat, n = _settle_top(traversable, cell_cost, dist, parent, keys, vals, pos, n)
        if wanted[flat]:
            waiting -= 1
            if waiting == 0:
                break
    size[0] = n


@njit(cache=True)
def dijkstra_settle_first(traversable, cell_cost, dist, parent, keys, vals, pos, size, want_flat):
    """Run the search until one of the cells in want_flat is settled (at once if one is
    already) or nothing is left: the nearest of them, in the full search's order. Nothing
    wanted, nothing settled."""
    if want_flat.shape[0] == 0:
        return
    for f in want_flat:
        if pos[f] == -2:
            return
    wanted = _mask_of(want_flat, pos.shape[0])
    n = size[0]
    while n > 0:
        flat, n = _settle_top(traversable, cell_cost, dist, parent, keys, vals, pos, n)
        if wanted[flat]:
            break
    size[0] = n


@njit(cache=True)
def dijkstra_settle_below(traversable, cell_cost, dist, parent, keys, vals, pos, size, bound):
    """Run the search while the next cell's cost is at most `bound` (in cells): afterwards
    every cell whose cost is at most `bound` is settled, and every other cell's exceeds it."""
    n = size[0]
    while n > 0 and keys[0] <= bound:
        _flat, n = _settle_top(traversable, cell_cost, dist, parent, keys, vals, pos, n)
    size[0] = n


@njit(cache=True)
def dijkstra_grid(traversable, cell_cost, start_i, start_j):
    """Shortest paths over 8-connected traversable cells from one start cell, all of them
    (see dijkstra_settle for the step costs). Returns (cost in cells, inf where
    unreachable; parent as flat index, -1 for the start and unreached cells)."""
    rows, cols = traversable.shape
    dist = np.empty((rows, cols), np.float64)
    parent = np.empty((rows, cols), np.int64)
    keys = np.empty(rows * cols, np.float64)
    vals = np.empty(rows * cols, np.int64)
    pos = np.empty(rows * cols, np.int64)
    size = np.empty(1, np.int64)
    dijkstra_start(traversable, start_i, start_j, dist, parent, keys, vals, pos, size)
    dijkstra_settle(traversable, cell_cost, dist, parent, keys, vals, pos, size, np.empty(0, np.int64))
    return dist, parent


@njit(cache=True)
def reachable_cells(traversable, start_i, start_j):
    """The cells dijkstra_grid reaches, without the costs: diagonal steps may not cut a
    corner, so every diagonal step has a two-step detour through traversable cells and
    4-connectivity reaches the same set. A flood fill, several times cheaper."""
    rows, cols = traversable.shape
    out = np.zeros((rows, cols), np.bool_)
    if not traversable[start_i, start_j]:
        return out
    stack = np.empty(rows * cols, np.int64)
    stack[0] = start_i * cols + start_j
    out[start_i, start_j] = True
    top = 1
    while top > 0:
        top -= 1
        flat = stack[top]
        i = flat // cols
        j = flat - i * cols
        for k in range(4):
            ni = i + (1 if k == 0 else -1 if k == 1 else 0)
            nj = j + (1 if k == 2 else -1 if k == 3 else 0)
            if 0 <= ni < rows and 0 <= nj < cols and traversable[ni, nj] and not out[ni, nj]:
                out[ni, nj] = True
                stack[top] = ni * cols + nj
                top += 1
    return out


@njit(cache=True)
def ray_offsets(n_rays, steps):
    """Cell offsets (row, col) of the steps 0..steps along n_rays rays from a cell centre:
    step s of ray k lies at floor(0.5 + s sin(k dtheta)), floor(0.5 + s cos(k dtheta)).
    The same for every source cell, so the ray kernels compute it once per call and then
    march in integers; it also makes a ray's cells independent of where its source is."""
    out = np.empty((n_rays, steps + 1, 2), np.int32)
    dtheta = 2.0 * math.pi / n_rays
    for k in range(n_rays):
        a = k * dtheta
        si = math.sin(a)
        sj = math.cos(a)
        for s in range(steps + 1):
            out[k, s, 0] = int(math.floor(0.5 + s * si))
            out[k, s, 1] = int(math.floor(0.5 + s * sj))
    return out


@njit(cache=True, parallel=True)
def observable_unknown(state, cand_i, cand_j, n_rays, max_range_cells):
    """For each candidate cell, the number of UNKNOWN cells observable from it within
    max_range_cells (eq. 3's observable(nu, xi) by ray casting in the local map).

    Rays march in unit steps (ray_offsets) and stop at an OCCUPIED cell or the window edge
    (what lies outside the window is not known to be unknown). Each visited unknown cell
    counts for the area its ray stands for at that distance, r * dtheta, so the sum
    estimates the number of distinct cells without double counting near the candidate.
    """
    rows, cols = state.shape
    n = cand_i.shape[0]
    out = np.zeros(n, np.float64)
    dtheta = 2.0 * math.pi / n_rays
    steps = int(max_range_cells)
    off = ray_offsets(n_rays, steps)
    # Computed once per call: each step's offset as an index into the flattened window, and
    # the area s * dtheta an unknown cell at step s stands for.
    flat = state.ravel()
    flat_off = np.empty((n_rays, steps + 1), np.int64)
    for k in range(n_rays):
        for s in range(steps + 1):
            flat_off[k, s] = off[k, s, 0] * cols + off[k, s, 1]
    area = np.empty(steps + 1, np.float64)
    for s in range(steps + 1):
        area[s] = s * dtheta
    for c in prange(n):        # candidates in parallel: each sums its own rays in order
        total = 0.0
        ci = cand_i[c]
        cj = cand_j[c]
        base = ci * cols + cj
        for k in range(n_rays):
            # A ray's row and column offsets are each monotone in s, so its steps inside the
            # window form one run: up to the last one inside, if it starts inside.
            last = steps
            while last > 0 and not (0 <= ci + off[k, last, 0] < rows and 0 <= cj + off[k, last, 1] < cols):
                last -= 1
            if last > 0 and not (0 <= ci + off[k, 1, 0] < rows and 0 <= cj + off[k, 1, 1] < cols):
                last = 0
            for s in range(1, last + 1):
                v = flat[base + flat_off[k, s]]
                if v == OCCUPIED:
                    break
                if v == UNKNOWN:
                    total += area[s]
        out[c] = total
    return out


@njit(cache=True)
def unknown_box_counts(state, half_cells, rows, cols):
    """UNKNOWN cells within the square of half-side half_cells around each (row, col),
    clipped to the window: an upper bound of what a candidate there can observe, to skip
    hopeless candidates cheaply. From one summed-area table of the window's unknown cells."""
    n_r, n_c = state.shape
    sat = np.zeros((n_r + 1, n_c + 1), np.int64)   # unknown cells in [0, i) x [0, j)
    for i in range(n_r):
        run = 0
        for j in range(n_c):
            if state[i, j] == UNKNOWN:
                run += 1
            sat[i + 1, j + 1] = sat[i, j + 1] + run
    out = np.empty(rows.shape[0], np.int64)
    for k in range(rows.shape[0]):
        i0 = min(max(rows[k] - half_cells, 0), n_r)
        i1 = min(max(rows[k] + half_cells + 1, 0), n_r)
        j0 = min(max(cols[k] - half_cells, 0), n_c)
        j1 = min(max(cols[k] + half_cells + 1, 0), n_c)
        out[k] = sat[i1, j1] - sat[i0, j1] - sat[i1, j0] + sat[i0, j0]
    return out


_BLOCK_SHIFT = 3     # mark_visible counts the wanted cells left per block of 8 x 8 cells
_CHECK_STEPS = 16    # and checks a ray's way ahead every this many steps


@njit(cache=True)
def mark_visible(state, src_i, src_j, n_rays, max_range_cells, wanted, out):
    """Set out[i, j] for every wanted cell that a ray from one of the source cells reaches
    within max_range_cells: what a sensor there would see of them, as far as this map can
    tell. Rays march like observable_unknown's and stop at an OCCUPIED cell (not marked) or
    the window edge; UNKNOWN cells are see-through, since nothing is known to block them.

    Only the wanted cells not marked yet need a ray, and most rays of a source cross what
    earlier sources saw: a ray is cut short at a check every _CHECK_STEPS steps when no
    block of 8 x 8 cells in the box from its current cell to its last one still holds such
    a cell (a ray's row and column each move one way, so the box holds the rest of it).
    The blocks' counts are summed once per source, so within a source they are too high,
    never too low: the cut never loses a cell. The window gets a border of OCCUPIED cells
    (a ray moves at most one cell per step along each axis, so it meets the border before
    it leaves) and rays step by flat index."""
    rows, cols = state.shape
    steps = int(max_range_cells)
    off = ray_offsets(n_rays, steps)
    sh = _BLOCK_SHIFT
    pc = cols + 2
    blocked = np.ones((rows + 2) * pc, np.bool_)
    left = np.zeros((rows + 2) * pc, np.bool_)     # wanted and not marked yet
    block_rows = ((rows - 1) >> sh) + 1
    block_cols = ((cols - 1) >> sh) + 1
    left_in_block = np.zeros((block_rows, block_cols), np.int64)
    for i in range(rows):
        row = (i + 1) * pc + 1
        for j in range(cols):
            blocked[row + j] = state[i, j] == OCCUPIED
            left[row + j] = wanted[i, j] and not out[i, j]
        for j in range(cols):
            left_in_block[i >> sh, j >> sh] += left[row + j]
    step_flat = np.empty((n_rays, steps + 1), np.int64)
    for k in range(n_rays):
        for s in range(steps + 1):
            step_flat[k, s] = off[k, s, 0] * pc + off[k, s, 1]
    table = np.zeros((block_rows + 1, block_cols + 1), np.int64)   # summed area of left_in_block
    for c in range(src_i.shape[0]):
        for bi in range(block_rows):
            run = 0
            for bj in range(block_cols):
                run += left_in_block[bi, bj]
                table[bi + 1, bj + 1] = table[bi, bj + 1] + run
        if table[block_rows, block_cols] == 0:
            break
        ci = src_i[c]
        cj = src_j[c]
        if ci < 0 or cj < 0 or ci >= rows or cj >= cols:
            continue
        start = (ci + 1) * pc + cj + 1
        for k in range(n_rays):
            end_i = ci + off[k, steps, 0]
            end_j = cj + off[k, steps, 1]
            check = 0
            for s in range(0, steps + 1):
                if s == check:
                    check += _CHECK_STEPS
                    i = ci + off[k, s, 0]
                    j = cj + off[k, s, 1]
                    a0 = max(min(i, end_i), 0) >> sh
                    a1 = (min(max(i, end_i), rows - 1) >> sh) + 1
                    b0 = max(min(j, end_j), 0) >> sh
                    b1 = (min(max(j, end_j), cols - 1) >> sh) + 1
                    if a0 >= a1 or b0 >= b1 or table[a1, b1] - table[a0, b1] - table[a1, b0] + table[a0, b0] == 0:
                        break
                x = start + step_flat[k, s]
                if blocked[x]:
                    break
                if left[x]:
                    left[x] = False
                    i = x // pc - 1
                    j = x % pc - 1
                    left_in_block[i >> sh, j >> sh] -= 1
                    out[i, j] = True


@njit(cache=True)
def scan_match_scores(field, row0, col0, res, x_m, y_m, yaw_rad, beam_x_m, beam_y_m, dxs_m, dys_m, dyaws_rad):
    """How well a scan fits a map at poses around (x_m, y_m, yaw_rad): for each pose
    (x_m + dxs_m[a], y_m + dys_m[b], yaw_rad + dyaws_rad[k]), the mean of field (a grid
    anchored at global cell (row0, col0), read bilinearly between cell centres, 0 outside
    it) at the scan's endpoints, given in the robot frame (beam_x_m, beam_y_m).
    Returns scores[k, a, b]."""
    n_r, n_c = field.shape
    n = len(beam_x_m)
    out = np.zeros((len(dyaws_rad), len(dxs_m), len(dys_m)))
    if n == 0:
        return out
    for k in range(len(dyaws_rad)):
        c = math.cos(yaw_rad + dyaws_rad[k])
        s = math.sin(yaw_rad + dyaws_rad[k])
        for m in range(n):
            wx = c * beam_x_m[m] - s * beam_y_m[m] + x_m
            wy = s * beam_x_m[m] + c * beam_y_m[m] + y_m
            for a in range(len(dxs_m)):
                fx = (wx + dxs_m[a]) / res - col0 - 0.5
                j0 = int(math.floor(fx))
                tx = fx - j0
                if j0 < 0 or j0 + 1 >= n_c:
                    continue
                for b in range(len(dys_m)):
                    fy = (wy + dys_m[b]) / res - row0 - 0.5
                    i0 = int(math.floor(fy))
                    ty = fy - i0
                    if i0 < 0 or i0 + 1 >= n_r:
                        continue
                    out[k, a, b] += (1.0 - ty) * ((1.0 - tx) * field[i0, j0] + tx * field[i0, j0 + 1]) \
                        + ty * ((1.0 - tx) * field[i0 + 1, j0] + tx * field[i0 + 1, j0 + 1])
    return out / n


@njit(cache=True)
def crack_contours(free, occupied):
    """The contours of the True cells of `free` (4-connected) along cell borders (cracks),
    free on the left (outer boundaries counter-clockwise, holes clockwise), each crack typed
    1 if the cell across it is `occupied`, else 0 (unknown, or outside the grid). Lattice
    corner (x, y) = (column, row); a contour starts at its lowest (y, x) corner with its
    lowest free direction (+x, +y, -x, -y), turns left before going straight before turning
    right (so free cells touching at a corner stay apart), and contours come in order of
    their start corner. Returns the corners (n, 2) of all contours one after another, the
    types of the cracks leaving them, and the offsets where each contour starts (and the end)."""
    rows, cols = free.shape
    has = np.zeros((rows + 1, cols + 1, 4), np.bool_)       # [y, x, direction]: a crack not yet followed
    typ = np.zeros((rows + 1, cols + 1, 4), np.int8)
    total = 0
    for r in range(rows):
        for c in range(cols):
            if not free[r, c]:
                continue
            if r == 0 or not free[r - 1, c]:                  # below: +x along y = r
                has[r, c, 0] = True
                typ[r, c, 0] = 1 if r > 0 and occupied[r - 1, c] else 0
                total += 1
            if c == cols - 1 or not free[r, c + 1]:           # right: +y along x = c + 1
                has[r, c + 1, 1] = True
                typ[r, c + 1, 1] = 1 if c + 1 < cols and occupied[r, c + 1] else 0
                total += 1
            if r == rows - 1 or not free[r + 1, c]:           # above: -x along y = r + 1
                has[r + 1, c + 1, 2] = True
                typ[r + 1, c + 1, 2] = 1 if r + 1 < rows and occupied[r + 1, c] else 0
                total += 1
            if c == 0 or not free[r, c - 1]:                  # left: -y along x = c
                has[r + 1, c, 3] = True
                typ[r + 1, c, 3] = 1 if c > 0 and occupied[r, c - 1] else 0
                total += 1
    corners = np.empty((total, 2), np.int64)
    types = np.empty(total, np.int8)
    starts = np.zeros(total + 1, np.int64)
    step_x = (1, 0, -1, 0)
    step_y = (0, 1, 0, -1)
    n = 0
    k = 0
    for y in range(rows + 1):
        for x in range(cols + 1):
            while True:
                first = -1
                for d in range(4):
                    if has[y, x, d]:
                        first = d
                        break
                if first < 0:
                    break
                hx, hy, d = x, y, first
                while True:
                    has[hy, hx, d] = False
                    corners[n, 0] = hx
                    corners[n, 1] = hy
                    types[n] = typ[hy, hx, d]
                    n += 1
                    hx += step_x[d]
                    hy += step_y[d]
                    home = hx == x and hy == y
                    nd = -1
                    for turn in ((d + 1) % 4, d, (d + 3) % 4):
                        if has[hy, hx, turn] or (home and turn == first):
                            nd = turn
                            break
                    if nd < 0 or (home and nd == first):
                        break
                    d = nd
                k += 1
                starts[k] = n
    return corners, types, starts[:k + 1]


@njit(cache=True)
def point_cells(ref_x, ref_y, cell_m):
    """The reference points sorted into square cells cell_m wide, for nearest_in_cells:
    (x0, y0, nx, ny, start, order), the points of cell cy * nx + cx being
    order[start[c]:start[c + 1]] in increasing index. Built once, it serves every query
    against the same points (the slip check asks for eleven shares of travel)."""
    n = ref_x.shape[0]
    x0 = ref_x.min()
    y0 = ref_y.min()
    nx = int((ref_x.max() - x0) / cell_m) + 1
    ny = int((ref_y.max() - y0) / cell_m) + 1
    # Counting sort of the reference points by cell.
    key = np.empty(n, np.int64)
    start = np.zeros(nx * ny + 1, np.int64)
    for k in range(n):
        cx = min(int((ref_x[k] - x0) / cell_m), nx - 1)
        cy = min(int((ref_y[k] - y0) / cell_m), ny - 1)
        key[k] = cy * nx + cx
        start[key[k] + 1] += 1
    for c in range(nx * ny):
        start[c + 1] += start[c]
    order = np.empty(n, np.int64)
    fill = start[:-1].copy()
    for k in range(n):
        order[fill[key[k]]] = k
        fill[key[k]] += 1
    return x0, y0, nx, ny, start, order


@njit(cache=True)
def nearest_in_cells(ref_x, ref_y, x0, y0, nx, ny, start, order, query_x, query_y, cell_m, out):
    """nearest_points's answer for each query, into out, with the cells point_cells built
    from ref_x, ref_y and cell_m."""
    for q in range(query_x.shape[0]):
        qx = query_x[q]
        qy = query_y[q]
        qcx = int(math.floor((qx - x0) / cell_m))
        qcy = int(math.floor((qy - y0) / cell_m))
        # Beyond this ring every cell of the grid has been visited.
        last_ring = max(max(qcx, nx - 1 - qcx), max(qcy, ny - 1 - qcy))
        best_d2 = math.inf
        best = -1
        r = 0
        while True:
            for cy in range(max(qcy - r, 0), min(qcy + r, ny - 1) + 1):
                on_edge_row = cy == qcy - r or cy == qcy + r
                step = 1 if on_edge_row else 2 * r
                for cx in range(qcx - r, qcx + r + 1, step):
                    if 0 <= cx < nx:
                        c = cy * nx + cx
                        for s in range(start[c], start[c + 1]):
                            k = order[s]
                            dx = ref_x[k] - qx
                            dy = ref_y[k] - qy
                            d2 = dx * dx + dy * dy
                            if d2 < best_d2 or (d2 == best_d2 and k < best):
                                best_d2 = d2
                                best = k
            gap = r * cell_m
            if (best >= 0 and best_d2 < gap * gap) or r >= last_ring:
                break
            r += 1
        out[q] = best


@njit(cache=True)
def nearest_points(ref_x, ref_y, query_x, query_y, cell_m):
    """For each query point, the index of its nearest reference point (Euclidean; the lowest
    index on an exact tie). The reference points are sorted into square cells cell_m wide;
    a query visits the rings of cells around its own, nearest first, and stops once every
    point of the rings beyond is at least as far as the nearest found: rings past ring r lie
    r whole cells away. A scan's hits against the scan before it (the slip check): both are
    a few hundred points a few centimetres apart, where a k-d tree spends most of its time
    descending to them."""
    out = np.full(query_x.shape[0], -1, np.int64)
    if ref_x.shape[0] == 0:
        return out
    x0, y0, nx, ny, start, order = point_cells(ref_x, ref_y, cell_m)
    nearest_in_cells(ref_x, ref_y, x0, y0, nx, ny, start, order, query_x, query_y, cell_m, out)
    return out


@njit(cache=True)
def _surface_distances(ref_x, ref_y, normal_x, normal_y, query_x, query_y, nearest, out):
    """For each query point, its distance to the surface through its nearest reference point
    nearest[q] (point to line: along that point's unit normal; NaN where the point has none),
    into out."""
    for q in range(query_x.shape[0]):
        k = nearest[q]
        if k < 0:
            out[q] = np.nan
        else:
            out[q] = abs((query_x[q] - ref_x[k]) * normal_x[k] + (query_y[q] - ref_y[k]) * normal_y[k])


@njit(cache=True)
def _block_sum(a, lo, n):
    """numpy's sum of at most 128 values: below eight in order, else in eight partial sums."""
    if n < 8:
        s = 0.0
        for i in range(lo, lo + n):
            s += a[i]
        return s
    r = a[lo:lo + 8].copy()
    i = 8
    while i < n - n % 8:
        for k in range(8):
            r[k] += a[lo + i + k]
        i += 8
    s = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
    while i < n:
        s += a[lo + i]
        i += 1
    return s


@njit(cache=True)
def pairwise_sum(a, lo, n):
    """a[lo:lo + n] summed in numpy's order (its pairwise summation: blocks of at most 128,
    halved at multiples of eight), so that a mean taken here equals numpy's to the bit.
    numpy recurses; this walks the same tree with a stack (numba's cache cannot hold a
    recursive function)."""
    if n <= 128:
        return _block_sum(a, lo, n)
    depth = 64                                  # a halving per level: far beyond any array
    node_lo = np.empty(depth, np.int64)
    node_n = np.empty(depth, np.int64)
    node_stage = np.empty(depth, np.int64)      # 0: left half next, 1: right half next, 2: add
    sums = np.empty(depth, np.float64)
    nodes = 1
    done = 0
    node_lo[0] = lo
    node_n[0] = n
    node_stage[0] = 0
    while nodes > 0:
        top = nodes - 1
        size = node_n[top]
        if size <= 128:
            sums[done] = _block_sum(a, node_lo[top], size)
            done += 1
            nodes -= 1
            continue
        half = size // 2
        half -= half % 8
        stage = node_stage[top]
        node_stage[top] = stage + 1
        if stage == 2:
            sums[done - 2] = sums[done - 2] + sums[done - 1]
            done -= 1
            nodes -= 1
            continue
        node_lo[nodes] = node_lo[top] + (0 if stage == 0 else half)
        node_n[nodes] = half if stage == 0 else size - half
        node_stage[nodes] = 0
        nodes += 1
    return sums[0]


@njit(cache=True)
def surface_normals(px, py, gap_m):
    """Unit normals of the surface through each point of a scan, from its two neighbours in
    the scan; NaN at the ends, where a neighbour is gap_m or farther, or where they coincide."""
    n = px.shape[0]
    nx = np.full(n, np.nan)
    ny = np.full(n, np.nan)
    for k in range(1, n - 1):
        if math.hypot(px[k] - px[k - 1], py[k] - py[k - 1]) < gap_m and \
                math.hypot(px[k + 1] - px[k], py[k + 1] - py[k]) < gap_m:
            tx = px[k + 1] - px[k - 1]
            ty = py[k + 1] - py[k - 1]
            length = math.hypot(tx, ty)
            if length > 0.0:
                nx[k] = -ty / length
                ny[k] = tx / length
    return nx, ny


@njit(cache=True)
def slip_misfits(ref_x, ref_y, turned_x, turned_y, travel_x, travel_y, shares, gap_m, cap_m, cell_m):
    """The slip check's fit of a scan over an earlier one, for each share of the travel: the
    scan's points (turned into the earlier robot frame) moved by share * travel, each point's
    distance to the earlier scan's surface through its nearest point (point to line, capped
    at cap_m; points whose nearest point has no surface do not count). Returns each share's
    mean misfit (NaN where no point counts) and how many points counted."""
    normal_x, normal_y = surface_normals(ref_x, ref_y, gap_m)
    n = turned_x.shape[0]
    misfit = np.empty(shares.shape[0], np.float64)
    counted = np.zeros(shares.shape[0], np.int64)
    moved_x = np.empty(n, np.float64)
    moved_y = np.empty(n, np.float64)
    on_surface = np.empty(n, np.float64)
    if ref_x.shape[0] == 0:                    # no nearest point: no point counts
        misfit[:] = np.nan
        return misfit, counted
    nearest = np.empty(n, np.int64)
    distance = np.empty(n, np.float64)
    # One sort of the reference points into cells serves every share.
    x0, y0, nx, ny, start, order = point_cells(ref_x, ref_y, cell_m)
    for s in range(shares.shape[0]):
        dx = shares[s] * travel_x
        dy = shares[s] * travel_y
        for q in range(n):
            moved_x[q] = turned_x[q] + dx
            moved_y[q] = turned_y[q] + dy
        nearest_in_cells(ref_x, ref_y, x0, y0, nx, ny, start, order, moved_x, moved_y, cell_m, nearest)
        _surface_distances(ref_x, ref_y, normal_x, normal_y, moved_x, moved_y, nearest, distance)
        m = 0
        for q in range(n):
            if not math.isnan(distance[q]):
                on_surface[m] = min(distance[q], cap_m)
                m += 1
        counted[s] = m
        misfit[s] = pairwise_sum(on_surface, 0, m) / m if m > 0 else np.nan
    return misfit, counted
