"""Synthetic worlds for the MR-TopoMap tests (firmware/schemes/mr_topomap), and tests that
they are what the other test files take them for.

Everything here is test-side: the ground truth comes from world_sim (map generators, ROS
maps, the exact ray caster), which firmware never imports. A robot's frame is an SE(2)
transform T_frame<-world; a vertex is built at a world pose with a noisy 360-beam scan cast
there, its position and descriptor expressed in its robot's frame, as the firmware would
see them with drift-free odometry.
"""
from __future__ import annotations

import functools
import math

import numpy as np
import pytest
from scipy import ndimage

from firmware.kernels import FREE, OCCUPIED, UNKNOWN
from firmware.schemes.mr_topomap import descriptor as desc
from firmware.schemes.mr_topomap.merge import SE2, OwnMap
from firmware.schemes.mr_topomap.records import NO_VERTEX, Vertex
from tests.conftest import SHARED_MAPS
from world_sim.map_spec import resolve_map
from world_sim.occupancy_map import OccupancyMap
from world_sim.raycast import cast_and_mark, cast_rays

BEAMS = 360
ANGLE_MIN = -math.pi
ANGLE_INC = 2.0 * math.pi / BEAMS
RANGE_MAX = 10.0
NOISE_M = 0.01
CLEARANCE_M = 0.35          # vertices stand this far from walls at least (robot radius 0.25 m + margin)
MAP_RES = 0.1               # the own maps' lattice (LocalMap's)


@functools.lru_cache(maxsize=None)
def scene(spec: str | OccupancyMap) -> OccupancyMap:
    """A ground truth by map spec; a shared ROS map by file name (skipped when absent); a
    hand-built OccupancyMap as it is (every helper here takes any of the three)."""
    if isinstance(spec, OccupancyMap):
        return spec
    if spec.endswith(".yaml"):
        path = SHARED_MAPS / spec
        if not path.exists():
            pytest.skip(f"shared map {path} is absent")
        spec = str(path)
    occ, _, _ = resolve_map(spec)
    return occ


@functools.lru_cache(maxsize=None)
def _clear_cells(spec: str) -> np.ndarray:
    occ = scene(spec)
    return ndimage.distance_transform_edt(occ.free) * occ.resolution_m >= CLEARANCE_M


def _biggest_component(mask: np.ndarray) -> np.ndarray:
    labels, n = ndimage.label(mask)
    if n == 0:
        return mask
    sizes = ndimage.sum_labels(mask, labels, np.arange(1, n + 1))
    return labels == 1 + int(np.argmax(sizes))


@functools.lru_cache(maxsize=None)
def _roomy(spec: str) -> np.ndarray:
    """Cells a robot can stand in, in the map's largest connected free region."""
    return _biggest_component(_clear_cells(spec))


def poisson_points(spec: str, rng: np.random.Generator, spacing_m: float, x_lo: float = 0.0, x_hi: float = 1.0,
                   max_points: int = 400) -> np.ndarray:
    """World points (n, 2) in the roomy free space with x in [x_lo, x_hi] of the map's width,
    at least spacing_m apart (greedy over a random order of the cells: a Poisson-disc set)."""
    occ = scene(spec)
    stride = max(1, int(spacing_m / 4.0 / occ.resolution_m))     # candidates on a lattice finer than spacing / 4
    roomy = _roomy(spec)
    cells = np.argwhere(roomy[::stride, ::stride]) * stride
    cells = cells + rng.integers(0, stride, cells.shape)            # jittered within their lattice cell
    cells = cells[roomy[np.minimum(cells[:, 0], occ.rows - 1), np.minimum(cells[:, 1], occ.cols - 1)]]
    xy = np.stack([occ.origin_x_m + (cells[:, 1] + 0.5) * occ.resolution_m,
                   occ.origin_y_m + (cells[:, 0] + 0.5) * occ.resolution_m], axis=1)
    fx = (xy[:, 0] - occ.origin_x_m) / occ.width_m
    xy = xy[(fx >= x_lo) & (fx <= x_hi)]
    xy = xy[rng.permutation(len(xy))]
    chosen: list[np.ndarray] = []
    cell = spacing_m / math.sqrt(2.0)
    grid: dict[tuple[int, int], int] = {}
    for p in xy:
        gi, gj = int(p[0] // cell), int(p[1] // cell)
        ok = True
        for di in (-2, -1, 0, 1, 2):
            for dj in (-2, -1, 0, 1, 2):
                k = grid.get((gi + di, gj + dj))
                if k is not None and np.hypot(*(chosen[k] - p)) < spacing_m:
                    ok = False
                    break
            if not ok:
                break
        if ok:
            grid[(gi, gj)] = len(chosen)
            chosen.append(p)
            if len(chosen) >= max_points:
                break
    return np.array(chosen).reshape(-1, 2)


def standing(spec: str, xy: np.ndarray) -> np.ndarray:
    """Which world points a robot could stand at."""
    occ = scene(spec)
    r = np.floor((xy[:, 1] - occ.origin_y_m) / occ.resolution_m).astype(int)
    c = np.floor((xy[:, 0] - occ.origin_x_m) / occ.resolution_m).astype(int)
    ok = (r >= 0) & (r < occ.rows) & (c >= 0) & (c < occ.cols)
    out = np.zeros(len(xy), dtype=bool)
    out[ok] = _clear_cells(spec)[r[ok], c[ok]]
    return out


def jitter(spec: str, xy: np.ndarray, rng: np.random.Generator, radius_m: float) -> np.ndarray:
    """Each point moved by up to radius_m to a place a robot can stand (kept if none is found)."""
    out = xy.copy()
    for k in range(len(xy)):
        for _ in range(30):
            r, a = radius_m * math.sqrt(rng.random()), rng.uniform(-math.pi, math.pi)
            cand = xy[k] + r * np.array([math.cos(a), math.sin(a)])
            if standing(spec, cand[None])[0]:
                out[k] = cand
                break
    return out


def scan(spec: str, x: float, y: float, heading: float, rng: np.random.Generator | None) -> np.ndarray:
    """A 360-beam scan at a world pose, as world_sim's LiDAR gives it (1 cm noise on hits)."""
    occ = scene(spec)
    r = cast_rays(occ.wall_u8(), occ.origin_x_m, occ.origin_y_m, occ.resolution_m, float(x), float(y),
                  ANGLE_MIN + heading + ANGLE_INC * np.arange(BEAMS), RANGE_MAX)
    if rng is not None:
        hit = r < RANGE_MAX
        r = np.where(hit, np.clip(r + rng.normal(0.0, NOISE_M, BEAMS), 0.0, RANGE_MAX), RANGE_MAX)
    return r


def descriptor_at(spec: str, x: float, y: float, heading: float, frame_psi: float,
                  rng: np.random.Generator | None) -> desc.Descriptor:
    """The descriptor a robot with heading `heading` (world) makes there, its odometry frame
    turned by frame_psi from the world's (its odometry yaw = heading + frame_psi)."""
    return desc.describe(scan(spec, x, y, heading, rng), ANGLE_MIN, ANGLE_INC, heading + frame_psi, RANGE_MAX)


def vertices(spec: str, owner: int, world_xy: np.ndarray, frame: SE2, rng: np.random.Generator) -> list[Vertex]:
    """The vertex records robot `owner` (frame T_frame<-world) makes at the world points."""
    out = []
    pos = frame.apply(world_xy) if len(world_xy) else np.zeros((0, 2))
    for k, (w, p) in enumerate(zip(world_xy, pos)):
        d = descriptor_at(spec, w[0], w[1], rng.uniform(-math.pi, math.pi), frame.psi, rng)
        out.append(Vertex(owner, k, int(round(p[0] * 10)), int(round(p[1] * 10)), owner,
                          k - 1 if k else NO_VERTEX, 0, d))
    return out


def observed_state(spec: str, world_xy: np.ndarray) -> np.ndarray:
    """What a robot that scanned at the world points knows, on the ground truth's grid:
    UNKNOWN / FREE / OCCUPIED."""
    occ = scene(spec)
    wall = occ.wall_u8()
    seen = np.zeros(occ.free.shape, dtype=bool)
    angles = ANGLE_MIN + ANGLE_INC * np.arange(BEAMS)
    for x, y in world_xy:
        cast_and_mark(seen, wall, occ.origin_x_m, occ.origin_y_m, occ.resolution_m, float(x), float(y), angles,
                      RANGE_MAX)
    state = np.full(occ.free.shape, UNKNOWN, dtype=np.uint8)
    state[seen & occ.free] = FREE
    state[seen & ~occ.free] = OCCUPIED
    return state


def state_in_frame(spec: str, world_state: np.ndarray, frame: SE2, res_m: float = MAP_RES):
    """A world-grid state resampled onto the lattice of a robot's frame: (state, row0, col0)
    for firmware's global-lattice convention. Nearest cell; a cell is OCCUPIED if any of its
    3 x 3 sub-samples is (walls survive the resampling)."""
    occ = scene(spec)
    corners = np.array([[occ.origin_x_m, occ.origin_y_m], [occ.origin_x_m + occ.width_m, occ.origin_y_m],
                        [occ.origin_x_m, occ.origin_y_m + occ.height_m],
                        [occ.origin_x_m + occ.width_m, occ.origin_y_m + occ.height_m]])
    fc = frame.apply(corners)
    col0, row0 = int(math.floor(fc[:, 0].min() / res_m)) - 1, int(math.floor(fc[:, 1].min() / res_m)) - 1
    col1, row1 = int(math.ceil(fc[:, 0].max() / res_m)) + 1, int(math.ceil(fc[:, 1].max() / res_m)) + 1
    inv = frame.inverse()
    out = np.zeros((row1 - row0, col1 - col0), dtype=np.uint8)
    jj, ii = np.meshgrid(np.arange(col1 - col0), np.arange(row1 - row0))
    for si in (-1 / 3, 0.0, 1 / 3):
        for sj in (-1 / 3, 0.0, 1 / 3):
            pts = np.stack([(col0 + jj + 0.5 + sj) * res_m, (row0 + ii + 0.5 + si) * res_m], axis=-1)
            w = inv.apply(pts)
            r = np.floor((w[..., 1] - occ.origin_y_m) / occ.resolution_m).astype(int)
            c = np.floor((w[..., 0] - occ.origin_x_m) / occ.resolution_m).astype(int)
            ok = (r >= 0) & (r < occ.rows) & (c >= 0) & (c < occ.cols)
            v = np.zeros(out.shape, dtype=np.uint8)
            v[ok] = world_state[r[ok], c[ok]]
            occupied = v == OCCUPIED
            out = np.where(occupied, OCCUPIED, np.where((out == UNKNOWN) & (v == FREE), FREE, out))
    return out, row0, col0


def own_map(spec: str, world_xy: np.ndarray, frame: SE2) -> OwnMap:
    """The occupancy check's map of a robot (frame T_frame<-world) that scanned at the points."""
    state, row0, col0 = state_in_frame(spec, observed_state(spec, world_xy), frame)
    return OwnMap(state, row0, col0, MAP_RES, frame.apply(world_xy))


def random_frame(rng: np.random.Generator, reach_m: float = 1000.0) -> SE2:
    return SE2(float(rng.uniform(-math.pi, math.pi)), float(rng.uniform(-reach_m, reach_m)),
               float(rng.uniform(-reach_m, reach_m)))


def merge_error(T_est: SE2, frame_a: SE2, frame_b: SE2, b_world_xy: np.ndarray) -> tuple[float, float]:
    """(RMS position error in m over B's vertices, |yaw error| in deg) of an estimate of
    T_A<-B against the truth frame_a o frame_b^-1 (5.4's measure)."""
    truth = frame_a.compose(frame_b.inverse())
    pb = frame_b.apply(b_world_xy)
    d = T_est.apply(pb) - truth.apply(pb)
    yaw = abs((T_est.psi - truth.psi + math.pi) % (2 * math.pi) - math.pi)
    return float(np.sqrt((d ** 2).sum(axis=1).mean())), math.degrees(yaw)


def pair_records(spec, seed: int, fa: SE2, fb: SE2, mode: str, n: int = 40):
    """Robot A (id 1, frame fa) and B (id 2, frame fb) in one map: (A's records, B's records,
    A's world points, B's world points, A's own map). mode "same": B's vertices at A's places +
    <= 0.3 m (spec 6.1.4); "half": A the left 60 % of the map, B the right 60 %; "disjoint": A
    the left 40 %, B the right 40 %."""
    rng = np.random.default_rng(seed)
    if mode == "same":                    # B's vertices at A's places + <= 0.3 m (spec 6.1.4)
        axy = poisson_points(spec, rng, 2.5, max_points=n)
        bxy = jitter(spec, axy, rng, 0.3)
    elif mode == "half":                  # A the left 60 %, B the right 60 %
        axy = poisson_points(spec, rng, 2.5, 0.0, 0.6)
        bxy = poisson_points(spec, rng, 2.5, 0.4, 1.0)
    else:                                 # disjoint: A the left 40 %, B the right 40 %
        axy = poisson_points(spec, rng, 2.5, 0.0, 0.4)
        bxy = poisson_points(spec, rng, 2.5, 0.6, 1.0)
    return (vertices(spec, 1, axy, fa, rng), vertices(spec, 2, bxy, fb, rng), axy, bxy,
            own_map(spec, axy, fa))


# ---- the helpers are what the tests take them for ------------------------------------

def test_frames_compose_and_invert():
    rng = np.random.default_rng(1)
    for _ in range(20):
        a, b = random_frame(rng), random_frame(rng)
        pts = rng.uniform(-50, 50, (5, 2))
        assert np.allclose(a.compose(b).apply(pts), a.apply(b.apply(pts)))
        assert np.allclose(a.inverse().apply(a.apply(pts)), pts, atol=1e-9)


def test_poisson_points_are_spaced_and_standable():
    rng = np.random.default_rng(2)
    xy = poisson_points("cave:1:60x60", rng, 2.5)
    assert len(xy) > 50
    d = np.hypot(*(xy[:, None, :] - xy[None, :, :]).transpose(2, 0, 1))
    assert d[~np.eye(len(xy), dtype=bool)].min() >= 2.5
    assert standing("cave:1:60x60", xy).all()


def test_the_resampled_own_map_keeps_the_walls_where_they_are():
    """A frame's own map, pulled back to the world, has its walls on the ground truth's."""
    rng = np.random.default_rng(3)
    xy = poisson_points("cave:1:60x60", rng, 2.5, max_points=20)
    frame = random_frame(rng, 300.0)
    m = own_map("cave:1:60x60", xy, frame)
    occ = scene("cave:1:60x60")
    i, j = np.nonzero(m.state == OCCUPIED)
    w = frame.inverse().apply(np.stack([(m.col0 + j + 0.5) * MAP_RES, (m.row0 + i + 0.5) * MAP_RES], axis=1))
    dist_to_wall = ndimage.distance_transform_edt(occ.free) * occ.resolution_m
    r = np.floor((w[:, 1] - occ.origin_y_m) / occ.resolution_m).astype(int)
    c = np.floor((w[:, 0] - occ.origin_x_m) / occ.resolution_m).astype(int)
    assert len(i) > 1000
    assert np.median(dist_to_wall[r, c]) <= 0.1
    assert (m.state == FREE).sum() > 10000
