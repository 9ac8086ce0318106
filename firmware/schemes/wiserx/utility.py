"""WiSER-X's frontier utility with the overlap loss, eqs. (2)-(7) (../shared/schemes/wiserx.md
sections 1.5, 1.7, A10-A16).

For a viewpoint x_v (here: one of the robot's waypoints, a reachable place with unknown in
LiDAR view), over the unknown cells c within r of it:

    S(D)  = 1 / (1 + exp((D - kappa1) / kappa2))                                   (5)
    E_c   = sum over recorded teammate points p (tau_p = 1) of omega_p S(|x_p - x_c|)  (6, 7)
    I     = sum_c max(0, S(|x_v - x_c|) - E_c)                                     (4)
    I_0   = sum_c S(|x_v - x_c|)                            (4 with E = 0: no overlap)
    beta  = log10(max(d_min, beta_min_distance))  (d_min: nearest fresh teammate estimate;
            1 with none, a common factor)                                          (3)
    U     = beta I / C   (C: the path length; the shared planner supplies it)      (2)
    ratio = 1 - I / I_0  (the share of the information lost to overlap, A16); after
            the soft threshold a viewpoint with ratio > invalid_ratio is invalid.

Unknown cells are counted in square blocks of info_cell_m (a block's cells all at its
centre): S is nearly a step at kappa1 = 5 m, so 0.5 m blocks change I by a boundary sliver,
and a plan costs viewpoints x blocks instead of viewpoints x cells. Pure numpy.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from firmware import kernels

POINT_CHUNK = 256      # points per step of the loss sum (bounds the temporary arrays)


def sigmoid(distance_m, kappa1_m: float, kappa2_m: float) -> np.ndarray:
    """S(D) of eq. (5), elementwise."""
    z = (np.asarray(distance_m, dtype=np.float64) - kappa1_m) / kappa2_m
    return 1.0 / (1.0 + np.exp(np.clip(z, -700.0, 700.0)))


def loss_reach_m(kappa1_m: float, kappa2_m: float) -> float:
    """Beyond this distance a point's S is below 2e-9: farther points need not be summed."""
    return kappa1_m + 20.0 * kappa2_m


@dataclass(frozen=True)
class UnknownBlocks:
    """The unknown cells of a window, in blocks: the centre (odometry frame, m) of every
    block holding any, and how many it holds."""

    x_m: np.ndarray
    y_m: np.ndarray
    count: np.ndarray

    @classmethod
    def from_sight(cls, sight: np.ndarray, row0: int, col0: int, resolution_m: float,
                   block_m: float) -> UnknownBlocks:
        """sight: a window of firmware.kernels cell states whose cell (0, 0) is global cell
        (row0, col0)."""
        b = max(1, int(round(block_m / resolution_m)))
        n_r, n_c = sight.shape
        pad_r, pad_c = -n_r % b, -n_c % b
        unknown = np.pad(sight == kernels.UNKNOWN, ((0, pad_r), (0, pad_c)))
        counts = unknown.reshape((n_r + pad_r) // b, b, (n_c + pad_c) // b, b).sum(axis=(1, 3))
        bi, bj = np.nonzero(counts)
        # A block's centre: the middle of its b x b cells, cell centres at (index + 0.5) res.
        x = (col0 + bj * b + 0.5 * b) * resolution_m
        y = (row0 + bi * b + 0.5 * b) * resolution_m
        return cls(x, y, counts[bi, bj].astype(np.float64))


def block_loss(blocks: UnknownBlocks, px: np.ndarray, py: np.ndarray, omega: np.ndarray,
               kappa1_m: float, kappa2_m: float) -> np.ndarray:
    """E_c of eqs. (6)/(7) per block: the weighted sum of S over the given points (the
    caller passes the live teammates' points, those beyond loss_reach_m of the window may be
    left out)."""
    e = np.zeros(len(blocks.x_m))
    for k in range(0, len(px), POINT_CHUNK):
        sl = slice(k, k + POINT_CHUNK)
        d = np.hypot(blocks.x_m[None, :] - px[sl, None], blocks.y_m[None, :] - py[sl, None])
        e += (omega[sl, None] * sigmoid(d, kappa1_m, kappa2_m)).sum(axis=0)
    return e


def information(blocks: UnknownBlocks, loss: np.ndarray, vx: np.ndarray, vy: np.ndarray, radius_m: float,
                kappa1_m: float, kappa2_m: float) -> tuple[np.ndarray, np.ndarray]:
    """(I, I_0) of eq. (4) per viewpoint, over the unknown cells within radius_m (r) of it."""
    vx = np.asarray(vx, dtype=np.float64)
    vy = np.asarray(vy, dtype=np.float64)
    if not len(vx) or not len(blocks.x_m):
        return np.zeros(len(vx)), np.zeros(len(vx))
    d = np.hypot(blocks.x_m[None, :] - vx[:, None], blocks.y_m[None, :] - vy[:, None])
    s = np.where(d <= radius_m, sigmoid(d, kappa1_m, kappa2_m), 0.0)
    n = blocks.count[None, :]
    return (n * np.maximum(0.0, s - loss[None, :])).sum(axis=1), (n * s).sum(axis=1)


def loss_ratio(info: np.ndarray, info0: np.ndarray) -> np.ndarray:
    """1 - I / I_0 (0 where I_0 is 0: nothing to lose)."""
    info0 = np.asarray(info0, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(info0 > 0.0, 1.0 - np.asarray(info) / info0, 0.0)


def proximity(vx: np.ndarray, vy: np.ndarray, tx: np.ndarray, ty: np.ndarray, min_distance_m: float) -> np.ndarray:
    """beta of eq. (3) per viewpoint: log10 of the distance to the nearest teammate estimate
    (at least min_distance_m), 1 with no estimate."""
    vx = np.asarray(vx, dtype=np.float64)
    if not len(tx):
        return np.ones(len(vx))
    d = np.hypot(np.asarray(vx)[:, None] - np.asarray(tx)[None, :], np.asarray(vy)[:, None] - np.asarray(ty)[None, :])
    return np.log10(np.maximum(d.min(axis=1), min_distance_m))


def weight(cov_trace_m2: float) -> float:
    """omega = min(1, 1 / Tr Sigma) of an estimate, frozen when it is recorded (eq. 6)."""
    return 1.0 if cov_trace_m2 <= 1.0 else 1.0 / cov_trace_m2


def utility(beta: np.ndarray, info: np.ndarray, cost_m: np.ndarray, min_cost_m: float) -> np.ndarray:
    """U = beta I / C of eq. (2), with C at least min_cost_m."""
    return np.asarray(beta) * np.asarray(info) / np.maximum(np.asarray(cost_m, dtype=np.float64), min_cost_m)

