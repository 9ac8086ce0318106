"""The place descriptor from a 2-D LiDAR scan (mrtopomap.md 5.2): it replaces the paper's
CalFeature (a 2048-float CNN image vector, III-A) with 32 bins of log range, 4 bits each.

    log profile   for each beam, bearing phi = yaw + angle_min + i * increment in the robot's
                  own odometry frame; value ln(clip(r, 0.2 m, range_max)) (a beam with no
                  return, non-finite or <= 0, counts as range_max); bin b = floor(phi / 11.25
                  deg) mod 32 holds the mean of its beams (an empty bin: interpolated around
                  the circle from its neighbours).
    wire          m = mean, s = std of the 32 values; q_b = round((clip((v_b - m) / s, -2.5,
                  2.5) + 2.5) / 5 * 15) in 0..15; desc_mean (5 bits) and desc_std (3 bits)
                  ride along (5.1).
    score         Score(a, b) = max over circular shifts k of sum_m z_a[(m + k) mod 32] z_b[m],
                  z the dequantised codes made zero-mean and unit-norm (InnerProduct's role,
                  in [-1, 1]). The best shift, refined by a parabola through its neighbours,
                  is the yaw of the frame a was taken in relative to b's: psi_a<-b = (k +
                  delta) * 11.25 deg (the paper's descriptor gives no yaw, A1).

Rotation handling (5.2): the bins sit on fixed bearings of the robot's own odometry frame,
so the robot's heading does not matter (the panorama's purpose, the paper's Fig. 2), and a
rotation psi between two robots' frames rolls the profile by psi / 11.25 deg bins: Score is
rotation-invariant and its argmax says by how much. A rotation by k * 11.25 deg rolls the
bins by exactly k.

Scores are exact: a 4-bit profile made zero-mean is proportional to c = 32 q - sum(q), an
integer vector (|c_b| <= 480), so every shifted inner product is an integer held exactly in
float64 whatever order BLAS sums it in. Scores, shifts and everything built on them are the
same bit for bit however a batch is cut (the merge's order independence rests on this).

The profile grid (5.3 step 2b) and the merge's view check render virtual scans of the own
map: `virtual_profiles`, `virtual_scans` (which also say how much of each view the map knows).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from firmware.kernels import FREE, OCCUPIED
from firmware.schemes.mr_topomap.params import DEFAULT, MrTopoParams

BINS = 32
BIN_RAD = 2.0 * math.pi / BINS
LEVELS = 16                 # 4-bit codes
Z_CLIP = 2.5                # z-scores clipped to +-this before quantising
Z_STEP = 2.0 * Z_CLIP / (LEVELS - 1)     # one code in sigma units (1/3)
MEAN_CODES = 32             # desc_mean: 5 bits
STD_CODES = 8               # desc_std: 3 bits
_SNAP = 1e-9                # bearings this close below a bin edge count as on it (rotations by whole bins stay exact)

# _SHIFT[k, j] = (j - k) mod 32: row k of b[_SHIFT] is b rolled by k, so that
# (a @ b[_SHIFT].T)[k] = sum_m a[(m + k) mod 32] b[m].
_SHIFT = (np.arange(BINS)[None, :] - np.arange(BINS)[:, None]) % BINS


class Descriptor(NamedTuple):
    """A place descriptor as it travels: 32 codes 0..15 (bin b = bearings [b, b+1) * 11.25
    deg of the sender's frame), the mean log range's code 0..31 and the spread's code 0..7."""

    codes: tuple[int, ...]
    mean_code: int
    std_code: int


def log_profile(ranges_m: np.ndarray, angle_min_rad: float, angle_increment_rad: float, yaw_rad: float,
                range_max_m: float, r_min_m: float = DEFAULT.r_min_m) -> np.ndarray:
    """The 32-bin log-range profile of one scan in the robot's own frame (float64, ln m)."""
    r = np.asarray(ranges_m, dtype=np.float64)
    r = np.where(np.isfinite(r) & (r > 0.0), r, range_max_m)
    v = np.log(np.clip(r, r_min_m, max(range_max_m, r_min_m)))
    u = (float(yaw_rad) + float(angle_min_rad) + float(angle_increment_rad) * np.arange(r.size)) / BIN_RAD
    b = np.mod(np.floor(u + _SNAP).astype(np.int64), BINS)
    sums = np.bincount(b, weights=v, minlength=BINS)
    counts = np.bincount(b, minlength=BINS)
    out = np.divide(sums, counts, out=np.zeros(BINS), where=counts > 0)
    if not counts.all():
        have = np.flatnonzero(counts)
        if have.size == 0:
            return np.full(BINS, math.log(max(range_max_m, r_min_m)))
        out = np.interp(np.arange(BINS), have, out[have], period=BINS)
    return out


def quantise(profile: np.ndarray, params: MrTopoParams = DEFAULT) -> Descriptor:
    """The wire form of a log profile (5.2). A flat profile (s = 0) gives all codes 8: its
    zero-mean form is zero, and it scores 0 against everything."""
    v = np.asarray(profile, dtype=np.float64).reshape(1, BINS)
    codes = quantise_many(v)[0]
    m, s = float(v.mean(axis=1)[0]), float(v.std(axis=1)[0])
    lo, hi = math.log(params.log_r_lo_m), math.log(params.log_r_hi_m)
    mean_code = int(np.clip(np.rint((m - lo) / (hi - lo) * (MEAN_CODES - 1)), 0, MEAN_CODES - 1))
    spread = min(max(s, 0.0), params.std_hi) / params.std_hi
    std_code = int(np.clip(np.rint(spread * (STD_CODES - 1)), 0, STD_CODES - 1))
    return Descriptor(tuple(int(c) for c in codes), mean_code, std_code)


def describe(ranges_m: np.ndarray, angle_min_rad: float, angle_increment_rad: float, yaw_rad: float,
             range_max_m: float, params: MrTopoParams = DEFAULT) -> Descriptor:
    """A scan's descriptor: quantise(log_profile(...))."""
    return quantise(log_profile(ranges_m, angle_min_rad, angle_increment_rad, yaw_rad, range_max_m,
                                params.r_min_m), params)


def dequantise(codes) -> np.ndarray:
    """The clipped z-scores the codes stand for (before the receiver's re-normalisation):
    within half a step (Z_STEP / 2 = 0.167 sigma) of clip(z, -2.5, 2.5)."""
    return np.asarray(codes, dtype=np.float64) * Z_STEP - Z_CLIP


def normalised(codes) -> np.ndarray:
    """The receiver's form: dequantised, zero mean, unit L2 norm (zeros for a flat profile)."""
    z = dequantise(codes)
    z = z - z.mean(axis=-1, keepdims=True)
    n = np.linalg.norm(z, axis=-1, keepdims=True)
    return np.divide(z, n, out=np.zeros_like(z), where=n > 0)


def centred(codes) -> np.ndarray:
    """32 q - sum(q): integer-valued float64, proportional to the zero-mean profile; (n, 32)
    for (n, 32) codes."""
    q = np.asarray(codes, dtype=np.float64)
    return BINS * q - q.sum(axis=-1, keepdims=True)


def shift_scores(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Scores at every circular shift, (n, m, 32), of n descriptors a against m descriptors b,
    both given as `centred` (or any real-valued) vectors: [i, j, k] = sum_m a_i[(m + k) mod
    32] b_j[m] / (|a_i| |b_j|); 0 where either is zero."""
    a = np.atleast_2d(np.asarray(a, dtype=np.float64))
    b = np.atleast_2d(np.asarray(b, dtype=np.float64))
    rolled = b[:, _SHIFT]                                   # (m, 32 shifts, 32)
    num = (a @ rolled.reshape(-1, BINS).T).reshape(a.shape[0], b.shape[0], BINS)
    den = np.sqrt(np.einsum("ij,ij->i", a, a)[:, None] * np.einsum("ij,ij->i", b, b)[None, :])
    return np.divide(num, den[:, :, None], out=np.zeros_like(num), where=den[:, :, None] > 0)


def peaks(scores: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(best score, best shift in bins) along the last axis of shift scores; the shift refined
    by a parabola through the best and its two circular neighbours (within +-0.5 bin), in
    [-16, 16)."""
    s = np.asarray(scores, dtype=np.float64)
    k = np.argmax(s, axis=-1)
    best = np.take_along_axis(s, k[..., None], axis=-1)[..., 0]
    lo = np.take_along_axis(s, ((k - 1) % BINS)[..., None], axis=-1)[..., 0]
    hi = np.take_along_axis(s, ((k + 1) % BINS)[..., None], axis=-1)[..., 0]
    curv = lo - 2.0 * best + hi
    delta = np.divide(0.5 * (lo - hi), curv, out=np.zeros_like(best), where=curv < 0.0)
    shift = k + np.clip(delta, -0.5, 0.5)
    return best, np.mod(shift + BINS / 2, BINS) - BINS / 2


def match(a: Descriptor | tuple, b: Descriptor | tuple) -> tuple[float, float]:
    """(Score(a, b), psi_a<-b in radians, in [-pi, pi)): b's frame turned by psi is a's."""
    ca = centred(np.asarray(a.codes if isinstance(a, Descriptor) else a))
    cb = centred(np.asarray(b.codes if isinstance(b, Descriptor) else b))
    best, shift = peaks(shift_scores(ca, cb)[0, 0])
    return float(best), float(shift) * BIN_RAD


def match_profiles(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """`match` for float profiles (log ranges, unquantised): the float baseline of 5.2."""
    za = np.asarray(a, dtype=np.float64) - np.mean(a)
    zb = np.asarray(b, dtype=np.float64) - np.mean(b)
    best, shift = peaks(shift_scores(za, zb)[0, 0])
    return float(best), float(shift) * BIN_RAD


# ---- the profile grid: virtual scans of the own map (5.3 step 2b) ----------------------

@njit(cache=True)
def _march(state, gx, gy, dx, dy, max_g):
    """(grid units from (gx, gy) along the unit direction (dx, dy) to the first OCCUPIED
    cell, or max_g; whether every cell before it was FREE). UNKNOWN and FREE let the ray
    through, and so does everything off the grid (which counts as not FREE)."""
    rows, cols = state.shape
    cx = int(math.floor(gx))
    cy = int(math.floor(gy))
    if cx < 0 or cy < 0 or cx >= cols or cy >= rows:
        return max_g, False
    if state[cy, cx] == OCCUPIED:
        return 0.0, True
    clean = state[cy, cx] == FREE
    inf = np.inf
    if dx > 0.0:
        sx, tdx, tx = 1, 1.0 / dx, (cx + 1 - gx) / dx
    elif dx < 0.0:
        sx, tdx, tx = -1, -1.0 / dx, (cx - gx) / dx
    else:
        sx, tdx, tx = 0, inf, inf
    if dy > 0.0:
        sy, tdy, ty = 1, 1.0 / dy, (cy + 1 - gy) / dy
    elif dy < 0.0:
        sy, tdy, ty = -1, -1.0 / dy, (cy - gy) / dy
    else:
        sy, tdy, ty = 0, inf, inf
    while True:
        if tx < ty:
            t = tx
            cx += sx
            tx += tdx
        else:
            t = ty
            cy += sy
            ty += tdy
        if t >= max_g:
            return max_g, clean
        if cx < 0 or cy < 0 or cx >= cols or cy >= rows:
            return max_g, False
        v = state[cy, cx]
        if v == OCCUPIED:
            return t, clean
        if v != FREE:
            clean = False


@njit(cache=True)
def _virtual_log_ranges(state, row0, col0, res, xs, ys, n_rays, r_max, r_min):
    out = np.empty((xs.shape[0], n_rays), np.float64)
    clean = np.empty((xs.shape[0], n_rays), np.bool_)
    max_g = r_max / res
    for j in range(n_rays):
        a = (j + 0.5) * 2.0 * math.pi / n_rays
        dx, dy = math.cos(a), math.sin(a)
        for p in range(xs.shape[0]):
            g, c = _march(state, xs[p] / res - col0, ys[p] / res - row0, dx, dy, max_g)
            out[p, j] = math.log(min(max(g * res, r_min), r_max))
            clean[p, j] = c
    return out, clean


def virtual_scans(state: np.ndarray, row0: int, col0: int, res_m: float, xy_m: np.ndarray,
                  range_max_m: float, n_rays: int = DEFAULT.grid_rays,
                  r_min_m: float = DEFAULT.r_min_m) -> tuple[np.ndarray, np.ndarray]:
    """(log profiles (n, 32), known share (n,)) of virtual scans of an own map at the points
    xy_m (n, 2); see virtual_profiles. The known share is the fraction of rays that crossed
    FREE cells only before their wall (or their range): how much of the view the map knows."""
    assert n_rays % BINS == 0, "n_rays must be a multiple of 32"
    xy = np.ascontiguousarray(np.asarray(xy_m, dtype=np.float64).reshape(-1, 2))
    logs, clean = _virtual_log_ranges(np.ascontiguousarray(state, dtype=np.uint8), int(row0), int(col0),
                                      float(res_m), np.ascontiguousarray(xy[:, 0]), np.ascontiguousarray(xy[:, 1]),
                                      int(n_rays), float(range_max_m), float(r_min_m))
    return logs.reshape(xy.shape[0], BINS, n_rays // BINS).mean(axis=2), clean.mean(axis=1)


def virtual_profiles(state: np.ndarray, row0: int, col0: int, res_m: float, xy_m: np.ndarray,
                     range_max_m: float, n_rays: int = DEFAULT.grid_rays,
                     r_min_m: float = DEFAULT.r_min_m) -> np.ndarray:
    """Log profiles (n, 32) of virtual scans of an own map at the points xy_m (n, 2): n_rays
    rays (a multiple of 32, n_rays / 32 per bin, at the centres of equal sub-bins) stop at
    OCCUPIED cells; UNKNOWN counts as free (5.3). The state grid is on the global lattice:
    cell (i, j) covers x in [(col0 + j) res, (col0 + j + 1) res), y likewise with row0."""
    return virtual_scans(state, row0, col0, res_m, xy_m, range_max_m, n_rays, r_min_m)[0]


def quantise_many(profiles: np.ndarray, params: MrTopoParams = DEFAULT) -> np.ndarray:
    """The codes (n, 32, int64) of n log profiles: `quantise` row by row, vectorised."""
    v = np.atleast_2d(np.asarray(profiles, dtype=np.float64))
    m = v.mean(axis=1, keepdims=True)
    s = v.std(axis=1, keepdims=True)
    z = np.divide(v - m, s, out=np.zeros_like(v), where=s > 0)
    return np.rint((np.clip(z, -Z_CLIP, Z_CLIP) + Z_CLIP) / Z_STEP).astype(np.int64)
