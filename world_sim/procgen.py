"""Seeded generated worlds: natural caves and mine tunnel networks.

Both generators build a smooth "room" field on a coarse structure grid (0.5 m cells), positive
where a robot may be, roughly in metres: caves from three octaves of smoothed noise whose
separate chambers are then joined by carved winding passages (a spanning tree over the rock
gaps, plus a few loops); mines from drifts grown as capsules that keep a pillar of rock to every
tunnel they do not join. At the coarse scale every passage narrower than MIN_PASSAGE_M is cut
away (a morphological opening by a disc, done with two distance transforms) and only the start's
component is kept. The field is then interpolated to the requested resolution in row strips,
so a 500 x 500 m map at 0.1 m (25 M cells) never holds more than a few float strips at full
resolution, and walls come out smooth, not blocky.

Every random number comes from world_sim.seeding.stream(seed, "procgen.<kind>"), so a seed
names one map bit for bit.
"""
from __future__ import annotations

import math

import numpy as np
from scipy import ndimage
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import minimum_spanning_tree

from world_sim.map_spec import open_heading_rad
from world_sim.occupancy_map import OccupancyMap
from world_sim.seeding import stream

Pose = tuple[float, float, float]

MIN_SIDE_M = 20.0
MIN_PASSAGE_M = 1.6  # a robot of radius 0.3 m passes with margin for the interpolation
STRUCTURE_CELL_M = 0.5
BORDER_M = 2.0  # solid rock around the map edge
STAGING_RADIUS_M = 4.0  # chamber at the start: room for a team to line up
CAVE_ROCK_SHARE = 0.58  # noise quantile below which a cave cell is rock
CAVE_MIN_CHAMBER_M2 = 12.0  # smaller pockets are left cut off (and dropped)
_STRIP_ROWS = 512
_EIGHT_CONNECTED = np.ones((3, 3), dtype=bool)


def generate_cave(
    seed: int, width_m: float = 100.0, height_m: float = 100.0, resolution_m: float = 0.1
) -> tuple[OccupancyMap, Pose]:
    """A natural cave: organic chambers of many sizes joined by winding passages."""
    _check_size(width_m, height_m, resolution_m)
    rng = stream(seed, "procgen.cave")
    shape = _structure_shape(width_m, height_m)
    cell = STRUCTURE_CELL_M
    # Three octaves of smoothed noise: the coarse one lays out where the cave system is dense,
    # the middle one makes chambers and galleries, the fine one roughens the walls.
    noise = (
        1.00 * _smooth_noise(rng, shape, cell, scale_m=7.0)
        + 0.55 * _smooth_noise(rng, shape, cell, scale_m=22.0)
        + 0.18 * _smooth_noise(rng, shape, cell, scale_m=2.0)
    )
    noise /= noise.std()
    # Mostly rock: the noise alone makes separate chambers and galleries; the passages that
    # join them into one system are carved below, so connectivity never hangs on the noise.
    threshold = float(np.quantile(noise, CAVE_ROCK_SHARE))
    field = ((noise - threshold) * 3.0).astype(np.float32)  # about metres at the gallery scale
    start_xy = _pick_start(rng, width_m, height_m)
    _carve_disc(field, start_xy, STAGING_RADIUS_M)
    # rough walls (the staging chamber too); before joining, so no passage gets pinched shut
    field += 0.35 * _smooth_noise(rng, shape, cell, scale_m=1.5) / 0.5
    _join_chambers(rng, field)
    return _finish(field, start_xy, width_m, height_m, resolution_m, f"cave:{seed}")


def _join_chambers(rng: np.random.Generator, field: np.ndarray) -> None:
    """Carve winding passages so every chamber of useful size joins one system.

    The chambers are joined along a minimum spanning tree of their "nearest rock gap" graph
    (from one feature transform: where the zones of two chambers meet, the sum of the two
    distances is the length of rock between them), plus a few short extra links for loops."""
    cell = STRUCTURE_CELL_M
    free = _opened(field > 0.0)
    labels, count = ndimage.label(free)
    if count < 2:
        return
    sizes = np.bincount(labels.ravel())
    big = sizes * cell * cell >= CAVE_MIN_CHAMBER_M2
    big[0] = False
    if big.sum() < 2:
        return
    chamber = np.where(big[labels], labels, 0)
    dist, (near_r, near_c) = ndimage.distance_transform_edt(chamber == 0, return_indices=True)
    owner = chamber[near_r, near_c]
    pairs = []
    for axis in (0, 1):
        a = owner[:-1, :] if axis == 0 else owner[:, :-1]
        b = owner[1:, :] if axis == 0 else owner[:, 1:]
        da = dist[:-1, :] if axis == 0 else dist[:, :-1]
        db = dist[1:, :] if axis == 0 else dist[:, 1:]
        rr, cc = np.nonzero(a != b)
        if rr.size == 0:
            continue
        r2, c2 = (rr + 1, cc) if axis == 0 else (rr, cc + 1)
        pairs.append(np.stack([
            np.minimum(a[rr, cc], b[rr, cc]).astype(np.float64),
            np.maximum(a[rr, cc], b[rr, cc]).astype(np.float64),
            da[rr, cc] + db[rr, cc],
            rr, cc, r2, c2,
        ], axis=1))
    if not pairs:
        return
    table = np.concatenate(pairs)
    order = np.lexsort((table[:, 4], table[:, 3], table[:, 2], table[:, 1], table[:, 0]))
    table = table[order]
    _, first = np.unique(table[:, :2], axis=0, return_index=True)
    edges = table[np.sort(first)]  # cheapest meeting point per pair of chambers
    ids = np.unique(edges[:, :2]).astype(np.int64)
    index = {int(v): i for i, v in enumerate(ids)}
    u = np.array([index[int(v)] for v in edges[:, 0]])
    v = np.array([index[int(w)] for w in edges[:, 1]])
    graph = csr_matrix((edges[:, 2] + 1.0, (u, v)), shape=(len(ids), len(ids)))
    tree = minimum_spanning_tree(graph).tocoo()
    in_tree = set(zip(tree.row.tolist(), tree.col.tolist()))
    for k in range(len(edges)):
        key = (int(u[k]), int(v[k]))
        extra = (key not in in_tree and (key[1], key[0]) not in in_tree
                 and edges[k, 2] * cell < 12.0 and rng.random() < 0.15)
        if key not in in_tree and (key[1], key[0]) not in in_tree and not extra:
            continue
        r1, c1, r2, c2 = (int(x) for x in edges[k, 3:7])
        a = (near_c[r1, c1], near_r[r1, c1])  # chamber cell nearest to the meeting point
        b = (near_c[r2, c2], near_r[r2, c2])
        mid = ((c1 + c2) / 2.0, (r1 + r2) / 2.0)
        half_w = float(rng.uniform(1.0, 1.6))
        for p, q in ((a, mid), (mid, b)):
            _carve_winding(rng, field, _cell_xy(p), _cell_xy(q), half_w)


def _cell_xy(col_row) -> tuple[float, float]:
    return ((float(col_row[0]) + 0.5) * STRUCTURE_CELL_M, (float(col_row[1]) + 0.5) * STRUCTURE_CELL_M)


def _carve_winding(rng, field, a_xy, b_xy, half_w: float) -> None:
    """A passage from a to b that meanders sideways by about a fifth of its length."""
    length = math.hypot(b_xy[0] - a_xy[0], b_xy[1] - a_xy[1])
    if length < 1e-6:
        _carve_disc(field, a_xy, half_w)
        return
    nx, ny = -(b_xy[1] - a_xy[1]) / length, (b_xy[0] - a_xy[0]) / length
    bends = max(1, int(length // 6.0))
    t = np.linspace(0.0, 1.0, bends + 2)
    offset = rng.normal(0.0, 0.12 * length / math.sqrt(bends), size=bends + 2)
    offset[0] = offset[-1] = 0.0
    xs = a_xy[0] + t * (b_xy[0] - a_xy[0]) + offset * nx
    ys = a_xy[1] + t * (b_xy[1] - a_xy[1]) + offset * ny
    for i in range(bends + 1):
        _carve_capsule(field, (xs[i], ys[i]), (xs[i + 1], ys[i + 1]), half_w)


def _opened(free: np.ndarray) -> np.ndarray:
    """free minus everything a disc of diameter MIN_PASSAGE_M cannot reach."""
    radius_cells = 0.5 * MIN_PASSAGE_M / STRUCTURE_CELL_M
    core = ndimage.distance_transform_edt(free) > radius_cells
    return free & (ndimage.distance_transform_edt(~core) <= radius_cells + 1e-6)


def generate_tunnel(
    seed: int, width_m: float = 100.0, height_m: float = 100.0, resolution_m: float = 0.1
) -> tuple[OccupancyMap, Pose]:
    """A mine: straight-ish drifts 2-4 m wide from a shaft station, with cross-cuts, T and
    X junctions, dead ends, a few loops and the odd wider chamber."""
    _check_size(width_m, height_m, resolution_m)
    rng = stream(seed, "procgen.tunnel")
    shape = _structure_shape(width_m, height_m)
    start_xy = _pick_start(rng, width_m, height_m)
    network = _TunnelNetwork(rng, width_m, height_m)
    network.grow(start_xy)
    field = np.full(shape, -10.0, dtype=np.float32)
    for x0, y0, x1, y1, half_w in network.segments:
        _carve_capsule(field, (x0, y0), (x1, y1), half_w)
    # rough rock walls: +-0.2 m of smooth noise on the wall position
    field += 0.2 * _smooth_noise(rng, shape, STRUCTURE_CELL_M, scale_m=1.5) / 0.5
    return _finish(field, start_xy, width_m, height_m, resolution_m, f"tunnel:{seed}")


# ----------------------------------------------------------------------------- tunnels


class _TunnelNetwork:
    """Grows drifts as capsules (segment + half width) that keep a pillar of rock to every
    tunnel they do not join. Segments are bucketed on a coarse grid for the clearance test."""

    PILLAR_M = 5.0  # least rock between two tunnels that do not meet
    SAMPLE_M = 0.5
    BUCKET_M = 16.0
    TARGET_SHARE = 0.26  # stop when tunnels cover this share of the box
    MIN_JUNCTION_DEG = 40.0
    BRANCH_TRIES = 4  # failed cross-cuts before a drift counts as boxed in
    LOOP_P = 0.45  # when a drift runs into another tunnel: join it (loop) or stop short

    def __init__(self, rng: np.random.Generator, width_m: float, height_m: float):
        self.rng = rng
        self.width_m, self.height_m = width_m, height_m
        self.margin_m = BORDER_M + 4.0
        self.segments: list[tuple[float, float, float, float, float]] = []
        self.buckets: dict[tuple[int, int], list[int]] = {}
        self.area_m2 = 0.0
        self.target_m2 = self.TARGET_SHARE * width_m * height_m

    def grow(self, start_xy: tuple[float, float]) -> None:
        rng = self.rng
        tips: list[tuple[float, float, float, float]] = []  # x, y, heading, half width
        self._add_chamber(start_xy[0], start_xy[1], STAGING_RADIUS_M)
        n_first = int(rng.integers(3, 5))
        base = rng.uniform(0.0, 2.0 * math.pi)
        for k in range(n_first):
            heading = base + 2.0 * math.pi * k / n_first + rng.normal(0.0, 0.15)
            tips.append((start_xy[0], start_xy[1], heading, rng.uniform(1.5, 2.0)))
        # Tries that fail count against the drift they branch from; a drift that keeps failing
        # is boxed in and is no longer tried, so the effort goes where there is still rock.
        branch_fails: list[int] = []
        budget = 20 * int(self.target_m2 / 50.0) + 400  # a hard stop, rarely reached
        while self.area_m2 < self.target_m2 and budget > 0:
            budget -= 1
            source = -1
            if tips:
                x, y, heading, half_w = tips.pop(int(rng.integers(len(tips))))
            else:
                branch_fails.extend([0] * (len(self.segments) - len(branch_fails)))
                open_ids = np.flatnonzero(np.asarray(branch_fails) < self.BRANCH_TRIES)
                if open_ids.size == 0:
                    break
                source = int(open_ids[int(rng.integers(open_ids.size))])
                x, y, heading, half_w = self._branch_from(source)
            outcome, end = self._extend(x, y, heading, half_w)
            if outcome == "blocked":
                if source >= 0:
                    branch_fails[source] += 1
                continue
            if outcome != "open":
                continue  # joined another tunnel (a loop) or stopped short (a dead end)
            ex, ey = end
            children = 0
            if rng.random() < 0.80:
                tips.append((ex, ey, heading + rng.normal(0.0, 0.20), half_w))
                children += 1
            for side in (-1.0, 1.0):
                if rng.random() < 0.30:
                    turn = side * rng.uniform(math.radians(60), math.radians(100))
                    tips.append((ex, ey, heading + turn, rng.uniform(1.0, 1.5)))
                    children += 1
            if children >= 2 and rng.random() < 0.25:
                self._add_chamber(ex, ey, rng.uniform(3.0, 5.0))

    def _branch_from(self, i: int):
        """A cross-cut leaving drift i at a random point, to either side."""
        rng = self.rng
        x0, y0, x1, y1, _ = self.segments[i]
        t = rng.uniform(0.2, 0.8)
        if (x0, y0) == (x1, y1):  # a chamber: leave it in any direction
            heading = rng.uniform(0.0, 2.0 * math.pi)
        else:
            heading = math.atan2(y1 - y0, x1 - x0) + (1 if rng.random() < 0.5 else -1) * (
                math.pi / 2 + rng.normal(0.0, 0.25)
            )
        return (x0 + t * (x1 - x0), y0 + t * (y1 - y0), heading, rng.uniform(1.0, 1.5))

    def _extend(self, x: float, y: float, heading: float, half_w: float):
        rng = self.rng
        length = rng.uniform(10.0, 35.0)
        reach = length + half_w + self.PILLAR_M + 2.5  # look far enough to find a tunnel to join
        s = np.arange(self.SAMPLE_M, reach + 1e-9, self.SAMPLE_M)
        dx, dy = math.cos(heading), math.sin(heading)
        px, py = x + s * dx, y + s * dy
        lo_x, hi_x = self.margin_m, self.width_m - self.margin_m
        lo_y, hi_y = self.margin_m, self.height_m - self.margin_m
        inside = (px >= lo_x) & (px <= hi_x) & (py >= lo_y) & (py <= hi_y)
        # the drift must stay in the box; where it would leave, it ends (a dead end at the edge)
        n_inside = len(s) if inside.all() else int(np.argmin(inside))
        first_bad, joined_at = self._first_conflict(x, y, px, py, half_w)
        if first_bad is None or first_bad * self.SAMPLE_M > length:
            stop = min(n_inside, int(length / self.SAMPLE_M))
            outcome = "open" if stop == int(length / self.SAMPLE_M) else "dead_end"
        elif joined_at is not None and joined_at < n_inside and rng.random() < self.LOOP_P:
            stop, outcome = joined_at + 1, "joined"
        else:
            stop = min(first_bad - int(math.ceil(1.0 / self.SAMPLE_M)), n_inside)
            outcome = "dead_end"
        if stop * self.SAMPLE_M < 6.0:
            return "blocked", None
        ex, ey = float(px[stop - 1]), float(py[stop - 1])
        self._add_segment(x, y, ex, ey, half_w)
        return outcome, (ex, ey)

    def _first_conflict(self, x, y, px, py, half_w):
        """First sample index too close to a tunnel this drift does not start from, and the
        first index after it that lies inside that tunnel (where a loop would close)."""
        ids = self._nearby(min(x, px.min()), min(y, py.min()), max(x, px.max()), max(y, py.max()))
        if not ids:
            return None, None
        seg = np.asarray([self.segments[i] for i in ids], dtype=np.float64)
        d = _point_segment_distance(px[:, None], py[:, None], seg[None, :, 0], seg[None, :, 1],
                                    seg[None, :, 2], seg[None, :, 3])  # (samples, segments)
        clear = seg[None, :, 4] + half_w + self.PILLAR_M
        bad = d < clear
        start_d = _point_segment_distance(x, y, seg[:, 0], seg[:, 1], seg[:, 2], seg[:, 3])
        # Tunnels already within pillar distance of the junction (the one it leaves, and the
        # drifts meeting there) may only be moved away from, never approached again.
        at_start = start_d < seg[:, 4] + half_w + self.PILLAR_M
        # leaving a junction, keep a real angle to every tunnel already there (no thin slivers)
        hx, hy = px[0] - x, py[0] - y
        hn = math.hypot(hx, hy)
        for ex_col, ey_col in ((0, 1), (2, 3)):
            vx, vy = seg[:, ex_col] - x, seg[:, ey_col] - y
            vn = np.hypot(vx, vy)
            cos = (vx * hx + vy * hy) / np.maximum(vn * hn, 1e-12)
            if np.any(at_start & (vn > 0.5) & (cos > math.cos(math.radians(self.MIN_JUNCTION_DEG)))):
                return 0, None
        left = np.maximum.accumulate(~bad[:, at_start], axis=0)
        bad[:, at_start] &= left
        if at_start.any() and not left[-1].all():
            return 0, None  # never gets clear of its own junction: runs along its parent
        rows = np.nonzero(bad.any(axis=1))[0]
        if rows.size == 0:
            return None, None
        first = int(rows[0])
        hit = int(np.nonzero(bad[first])[0][0])
        inside = np.nonzero(d[first:, hit] < seg[hit, 4] * 0.5)[0]
        if inside.size == 0:
            return first, None
        joined = first + int(inside[0])
        # join only across the other tunnel, not by merging into it at a grazing angle
        hx, hy = px[-1] - x, py[-1] - y
        sx, sy = seg[hit, 2] - seg[hit, 0], seg[hit, 3] - seg[hit, 1]
        sine = abs(hx * sy - hy * sx) / max(math.hypot(hx, hy) * math.hypot(sx, sy), 1e-12)
        if sine < math.sin(math.radians(45.0)):
            return first, None
        # a loop may not cut through a third tunnel on its way in
        others = np.ones(len(ids), dtype=bool)
        others[hit] = False
        if bad[:joined + 1][:, others].any():
            return first, None
        return first, joined

    def _nearby(self, x0, y0, x1, y1) -> list[int]:
        pad = 5.0 + 2.0 + self.PILLAR_M + 0.5  # widest chamber + widest drift + pillar
        b = self.BUCKET_M
        found: set[int] = set()
        for bx in range(int((x0 - pad) // b), int((x1 + pad) // b) + 1):
            for by in range(int((y0 - pad) // b), int((y1 + pad) // b) + 1):
                found.update(self.buckets.get((bx, by), ()))
        return sorted(found)

    def _add_chamber(self, x, y, radius_m) -> None:
        self._add_segment(x, y, x, y, radius_m)
        self.area_m2 += math.pi * radius_m ** 2

    def _add_segment(self, x0, y0, x1, y1, half_w) -> None:
        index = len(self.segments)
        self.segments.append((x0, y0, x1, y1, half_w))
        self.area_m2 += 2.0 * half_w * math.hypot(x1 - x0, y1 - y0)
        b = self.BUCKET_M
        for bx in range(int((min(x0, x1) - half_w) // b), int((max(x0, x1) + half_w) // b) + 1):
            for by in range(int((min(y0, y1) - half_w) // b), int((max(y0, y1) + half_w) // b) + 1):
                self.buckets.setdefault((bx, by), []).append(index)


def _point_segment_distance(px, py, ax, ay, bx, by):
    abx, aby = bx - ax, by - ay
    length2 = np.maximum(abx * abx + aby * aby, 1e-12)
    t = np.clip(((px - ax) * abx + (py - ay) * aby) / length2, 0.0, 1.0)
    return np.hypot(px - (ax + t * abx), py - (ay + t * aby))


# ----------------------------------------------------------------------------- shared steps


def _check_size(width_m: float, height_m: float, resolution_m: float) -> None:
    for name, value in (("width_m", width_m), ("height_m", height_m)):
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= MIN_SIDE_M):
            raise ValueError(f"{name} must be a number >= {MIN_SIDE_M:g} m, got {value!r}")
    if not (isinstance(resolution_m, (int, float)) and 0.01 <= resolution_m <= STRUCTURE_CELL_M):
        raise ValueError(
            f"resolution_m must be in 0.01..{STRUCTURE_CELL_M:g} m, got {resolution_m!r}"
        )


def _structure_shape(width_m: float, height_m: float) -> tuple[int, int]:
    return (int(math.ceil(height_m / STRUCTURE_CELL_M)), int(math.ceil(width_m / STRUCTURE_CELL_M)))


def _pick_start(rng: np.random.Generator, width_m: float, height_m: float) -> tuple[float, float]:
    """Somewhere in the middle half of the box, so the world extends on every side."""
    return (
        float(width_m * rng.uniform(0.25, 0.75)),
        float(height_m * rng.uniform(0.25, 0.75)),
    )


def _smooth_noise(rng: np.random.Generator, shape, cell_m: float, scale_m: float) -> np.ndarray:
    """Gaussian-smoothed white noise with features about scale_m across, std about 0.5.

    Drawn on a grid of scale_m/3 cells and interpolated, so the cost does not grow with scale."""
    coarse_cell = max(cell_m, scale_m / 3.0)
    coarse_shape = (
        int(math.ceil(shape[0] * cell_m / coarse_cell)) + 2,
        int(math.ceil(shape[1] * cell_m / coarse_cell)) + 2,
    )
    white = rng.standard_normal(coarse_shape)
    smooth = ndimage.gaussian_filter(white, sigma=scale_m / (3.0 * coarse_cell), mode="wrap")
    smooth /= max(float(smooth.std()), 1e-12) * 2.0
    return _resample(smooth.astype(np.float32), coarse_cell, shape, cell_m)


def _resample(src: np.ndarray, src_cell_m: float, out_shape, out_cell_m: float,
              row_range: tuple[int, int] | None = None) -> np.ndarray:
    """Bilinear interpolation of a cell-centred grid onto another cell-centred grid with the
    same origin (rows row_range of the output only, to work in strips)."""
    r_lo, r_hi = row_range if row_range is not None else (0, out_shape[0])
    r_idx0, r_idx1, r_w = _axis_weights(np.arange(r_lo, r_hi), src.shape[0], src_cell_m, out_cell_m)
    c_idx0, c_idx1, c_w = _axis_weights(np.arange(out_shape[1]), src.shape[1], src_cell_m, out_cell_m)
    rows = src[r_idx0] * (1.0 - r_w)[:, None] + src[r_idx1] * r_w[:, None]
    return rows[:, c_idx0] * (1.0 - c_w)[None, :] + rows[:, c_idx1] * c_w[None, :]


def _axis_weights(out_index: np.ndarray, n_src: int, src_cell_m: float, out_cell_m: float):
    u = (out_index + 0.5) * (out_cell_m / src_cell_m) - 0.5
    u = np.clip(u, 0.0, n_src - 1.0)
    i0 = np.floor(u).astype(np.int64)
    i1 = np.minimum(i0 + 1, n_src - 1)
    return i0, i1, (u - i0).astype(np.float32)


def _carve_disc(field: np.ndarray, centre_xy, radius_m: float) -> None:
    _carve_capsule(field, centre_xy, centre_xy, radius_m)


def _carve_capsule(field: np.ndarray, a_xy, b_xy, half_w_m: float) -> None:
    """field = max(field, half_w - distance to segment ab), within the capsule's box."""
    cell = STRUCTURE_CELL_M
    reach = half_w_m + 2.0 * cell
    c_lo = max(int((min(a_xy[0], b_xy[0]) - reach) / cell), 0)
    c_hi = min(int((max(a_xy[0], b_xy[0]) + reach) / cell) + 1, field.shape[1])
    r_lo = max(int((min(a_xy[1], b_xy[1]) - reach) / cell), 0)
    r_hi = min(int((max(a_xy[1], b_xy[1]) + reach) / cell) + 1, field.shape[0])
    if c_lo >= c_hi or r_lo >= r_hi:
        return
    xs = (np.arange(c_lo, c_hi) + 0.5) * cell
    ys = (np.arange(r_lo, r_hi) + 0.5) * cell
    d = _point_segment_distance(xs[None, :], ys[:, None], a_xy[0], a_xy[1], b_xy[0], b_xy[1])
    window = field[r_lo:r_hi, c_lo:c_hi]
    np.maximum(window, (half_w_m - d).astype(field.dtype), out=window)


def _finish(field: np.ndarray, start_xy, width_m: float, height_m: float, resolution_m: float,
            name: str) -> tuple[OccupancyMap, Pose]:
    cell = STRUCTURE_CELL_M
    field = field.astype(np.float32, copy=False)
    border = int(math.ceil(BORDER_M / cell))
    field[:border, :] = np.minimum(field[:border, :], -cell)
    field[-border:, :] = np.minimum(field[-border:, :], -cell)
    field[:, :border] = np.minimum(field[:, :border], -cell)
    field[:, -border:] = np.minimum(field[:, -border:], -cell)
    free = field > 0.0

    opened = _opened(free)
    # 4-connected: discs of the opening that only touch corner to corner do not make a passage
    labels, _ = ndimage.label(opened)
    start_rc = (int(start_xy[1] / cell), int(start_xy[0] / cell))
    keep = labels == labels[start_rc]
    if not keep[start_rc]:
        raise RuntimeError(f"{name}: start is not in open space (generator bug)")
    # Inside the kept system the field is at least a fraction of the depth into it, so a
    # passage whose noise hovers just above zero still interpolates to a positive band; outside
    # it is clamped to a small negative range, so interpolation never revives what was cut.
    depth = ndimage.distance_transform_edt(keep)
    inside = np.maximum(field, (0.25 * cell) * np.minimum(depth, 4.0))
    outside = np.clip(field, -cell, -0.1 * cell)
    field = np.where(keep, inside, outside).astype(np.float32)

    rows = int(round(height_m / resolution_m))
    cols = int(round(width_m / resolution_m))
    fine = np.empty((rows, cols), dtype=bool)
    for r0 in range(0, rows, _STRIP_ROWS):
        r1 = min(rows, r0 + _STRIP_ROWS)
        fine[r0:r1] = _resample(field, cell, (rows, cols), resolution_m, (r0, r1)) > 0.0
    fine[0, :] = fine[-1, :] = False
    fine[:, 0] = fine[:, -1] = False

    occ = OccupancyMap(free=fine, resolution_m=float(resolution_m), origin_x_m=0.0,
                       origin_y_m=0.0, name=name)
    row, col = occ.cell_of(start_xy[0], start_xy[1])
    # The field above makes the fine grid one piece already; this pass makes it a promise.
    fine_labels, count = ndimage.label(fine, structure=_EIGHT_CONNECTED)
    if count > 1:
        np.equal(fine_labels, fine_labels[row, col], out=fine)
    del fine_labels
    yaw = open_heading_rad(fine, row, col, resolution_m)
    x_m, y_m = occ.center_of(row, col)
    return occ, (x_m, y_m, yaw)
