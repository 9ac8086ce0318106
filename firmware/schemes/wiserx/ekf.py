"""Where a teammate is, from UWB ranges and WiFi AoA bearings: an extended Kalman filter per
teammate in the observing robot's own odometry frame (../shared/schemes/wiserx.md sections
1.2, 1.3, 2, 4 A1-A5, 5.3).

State x = [x_j, y_j, vx_j, vy_j]: the teammate's position (m) and velocity (m/s) in the
frame of this robot's odometry; P its 4 x 4 covariance. This robot's own pose at each
sample's time is taken as exact (it comes from its odometry; the filter never needs the
teammate's frame). A measurement is z = (rho, psi): the range and the bearing in this
robot's frame, psi = wrap(AoA bearing in the body frame + own yaw at the sample's time)
(A2, `map_bearing`).

- Motion: constant velocity with white-noise acceleration of density q (A1):
  F = [[I, dt I], [0, I]], Q = q [[dt^3/3 I, dt^2/2 I], [dt^2/2 I, dt I]].
- Measurement: h(x) = (|d|, atan2(d_y, d_x)), d = (x_j, y_j) - (x_i, y_i), Jacobian
  H = [[d_x/rho, d_y/rho, 0, 0], [-d_y/rho^2, d_x/rho^2, 0, 0]]; the bearing residual is
  wrapped to [-pi, pi).
- Update: gated on the normalised innovation squared (chi-square at 99 %: 1 dof for a range or
  a bearing alone, 2 for both of one stamp), covariance in Joseph form.
- A track starts from its first range and bearing: x = x_i + rho (cos psi, sin psi), v = 0,
  P = J diag(sigma_r^2, sigma_psi^2) J^T for the position (J the polar-to-Cartesian
  Jacobian), init_speed_std^2 I for the velocity.
- Sequential mode (A5, the default): each sample is its own update at its own time, a range
  and a bearing of one stamp together. Window mode (A3, A4): the samples of a window reduced
  to one range (mean of every second sample) and one stable bearing (the largest cluster) at
  the window's middle.

The functions work on one track (x shape (4,), P (4, 4)) or on a batch of them (leading
dimensions, as the NEES tests use). Pure: no clock, no randomness, no I/O.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from firmware.schemes.wiserx.params import EkfParams

RANGE, BEARING = 0, 1           # measurement rows
BOTH = (RANGE, BEARING)


def wrap_angle(a):
    """a wrapped to [-pi, pi) (arrays elementwise)."""
    r = np.remainder(np.asarray(a, dtype=np.float64) + math.pi, 2.0 * math.pi) - math.pi
    return np.where(r >= math.pi, r - 2.0 * math.pi, r)


def map_bearing(body_bearing_rad: float, own_yaw_rad: float) -> float:
    """An AoA bearing (this robot's body frame) in the frame of its odometry, with the yaw of
    its pose at the sample's time."""
    return float(wrap_angle(body_bearing_rad + own_yaw_rad))


def transition(dt_s) -> np.ndarray:
    """F for a step of dt_s seconds (a scalar, or an array: one F per element)."""
    dt = np.asarray(dt_s, dtype=np.float64)
    F = np.zeros(dt.shape + (4, 4))
    F[..., [0, 1, 2, 3], [0, 1, 2, 3]] = 1.0
    F[..., 0, 2] = F[..., 1, 3] = dt
    return F


def process_noise(dt_s, accel_psd_m2ps3: float) -> np.ndarray:
    """Q of the discrete white-noise-acceleration model over dt_s seconds."""
    dt = np.asarray(dt_s, dtype=np.float64)
    Q = np.zeros(dt.shape + (4, 4))
    for p, v in ((0, 2), (1, 3)):
        Q[..., p, p] = dt ** 3 / 3.0
        Q[..., p, v] = Q[..., v, p] = dt ** 2 / 2.0
        Q[..., v, v] = dt
    return accel_psd_m2ps3 * Q


def predict(x: np.ndarray, P: np.ndarray, dt_s, accel_psd_m2ps3: float) -> tuple[np.ndarray, np.ndarray]:
    """The state and covariance dt_s seconds later (dt_s >= 0)."""
    F = transition(dt_s)
    x = np.einsum("...ij,...j->...i", F, x)
    P = F @ P @ np.swapaxes(F, -1, -2) + process_noise(dt_s, accel_psd_m2ps3)
    return x, P


def measure(x: np.ndarray, own_xy: np.ndarray) -> np.ndarray:
    """h(x): (range, bearing) of the teammate from this robot's position, shape (..., 2)."""
    dx = x[..., 0] - own_xy[..., 0]
    dy = x[..., 1] - own_xy[..., 1]
    return np.stack([np.hypot(dx, dy), np.arctan2(dy, dx)], axis=-1)


def jacobian(x: np.ndarray, own_xy: np.ndarray, min_range_m: float = 0.0) -> np.ndarray:
    """H = dh/dx at x, shape (..., 2, 4); ranges below min_range_m are taken as min_range_m
    (the caller refuses those updates)."""
    dx = x[..., 0] - own_xy[..., 0]
    dy = x[..., 1] - own_xy[..., 1]
    rho = np.maximum(np.hypot(dx, dy), max(min_range_m, 1e-12))
    H = np.zeros(x.shape[:-1] + (2, 4))
    H[..., 0, 0] = dx / rho
    H[..., 0, 1] = dy / rho
    H[..., 1, 0] = -dy / rho ** 2
    H[..., 1, 1] = dx / rho ** 2
    return H


def hessians(x: np.ndarray, own_xy: np.ndarray, min_range_m: float = 0.0) -> np.ndarray:
    """The second derivatives of h with respect to the position, shape (..., 2, 2, 2): [row]
    then the 2 x 2 Hessian (the velocity does not enter h). Range: (I - u u^T) / rho with u
    the unit line of sight; bearing: [[2 u_x u_y, u_y^2 - u_x^2], [u_y^2 - u_x^2, -2 u_x u_y]] / rho^2."""
    dx = x[..., 0] - own_xy[..., 0]
    dy = x[..., 1] - own_xy[..., 1]
    rho = np.maximum(np.hypot(dx, dy), max(min_range_m, 1e-12))
    ux, uy = dx / rho, dy / rho
    Hh = np.zeros(x.shape[:-1] + (2, 2, 2))
    Hh[..., RANGE, 0, 0] = uy * uy / rho
    Hh[..., RANGE, 1, 1] = ux * ux / rho
    Hh[..., RANGE, 0, 1] = Hh[..., RANGE, 1, 0] = -ux * uy / rho
    Hh[..., BEARING, 0, 0] = 2.0 * ux * uy / rho ** 2
    Hh[..., BEARING, 1, 1] = -2.0 * ux * uy / rho ** 2
    Hh[..., BEARING, 0, 1] = Hh[..., BEARING, 1, 0] = (uy * uy - ux * ux) / rho ** 2
    return Hh


def polar_start(range_m, bearing_rad, own_xy: np.ndarray, params: EkfParams) -> tuple[np.ndarray, np.ndarray]:
    """(x0, P0) of a new track from one range and (frame) bearing."""
    rho = np.asarray(range_m, dtype=np.float64)
    psi = np.asarray(bearing_rad, dtype=np.float64)
    c, s = np.cos(psi), np.sin(psi)
    x = np.zeros(rho.shape + (4,))
    x[..., 0] = own_xy[..., 0] + rho * c
    x[..., 1] = own_xy[..., 1] + rho * s
    J = np.zeros(rho.shape + (2, 2))
    J[..., 0, 0], J[..., 0, 1] = c, -rho * s
    J[..., 1, 0], J[..., 1, 1] = s, rho * c
    R = np.diag([params.range_std_m ** 2, params.bearing_std_rad ** 2])
    P = np.zeros(rho.shape + (4, 4))
    P[..., :2, :2] = J @ R @ np.swapaxes(J, -1, -2)
    P[..., 2, 2] = P[..., 3, 3] = params.init_speed_std_mps ** 2
    return x, P


@dataclass(frozen=True)
class Update:
    """What one (batch of) update(s) did. x, P: after the update (unchanged where refused);
    accepted: passed the gate with a usable range; nis: the normalised innovation squared
    (before the gate; inf where the predicted range is below min_range_m); innovation: z - h(x)
    with the bearing wrapped."""

    x: np.ndarray
    P: np.ndarray
    accepted: np.ndarray
    nis: np.ndarray
    innovation: np.ndarray


def update(x: np.ndarray, P: np.ndarray, z: np.ndarray, own_xy: np.ndarray, rows: tuple[int, ...],
           variances: np.ndarray, gate: float, min_range_m: float = 0.0, second_order: bool = False) -> Update:
    """Measurement update with the measurement rows `rows` (RANGE, BEARING or BOTH), z of
    shape (..., len(rows)) and their noise variances (shape (len(rows),), or one row of them
    per track); refused where the innovation fails the gate or the predicted range is below
    min_range_m.

    second_order: the Gaussian second-order filter's terms (Bar-Shalom, Li, Kirubarajan,
    "Estimation with Applications to Tracking and Navigation", 10.3.3): the predicted
    measurement gains 1/2 tr(h_a'' P) and S gains 1/2 tr(h_a'' P h_b'' P). For the range
    these are P_lateral / (2 rho) and P_lateral^2 / (2 rho^2): the sagitta of the range
    circle across the position's lateral spread, which a first-order EKF ignores and which
    exceeds a 10 cm range noise beyond ~13 m at 5 degrees of bearing noise."""
    idx = list(rows)
    h = measure(x, own_xy)
    rho = h[..., RANGE]
    H = jacobian(x, own_xy, min_range_m)[..., idx, :]
    predicted = h[..., idx]
    m = len(idx)
    R = np.asarray(variances, dtype=np.float64)[..., :, None] * np.eye(m)
    if second_order:
        Hh = hessians(x, own_xy, min_range_m)[..., idx, :, :]          # (..., m, 2, 2)
        HP = Hh @ P[..., None, :2, :2]                                   # (..., m, 2, 2)
        predicted = predicted + 0.5 * np.trace(HP, axis1=-2, axis2=-1)
        R = R + 0.5 * np.einsum("...aij,...bji->...ab", HP, HP)
    nu = np.asarray(z, dtype=np.float64) - predicted
    if BEARING in rows:
        b = idx.index(BEARING)
        nu[..., b] = wrap_angle(nu[..., b])
    Ht = np.swapaxes(H, -1, -2)
    S = H @ P @ Ht + R
    S_inv_nu = np.linalg.solve(S, nu[..., None])[..., 0]
    nis = np.einsum("...i,...i->...", nu, S_inv_nu)
    usable = rho >= min_range_m
    nis = np.where(usable, nis, np.inf)
    accepted = usable & (nis <= gate)
    K = np.swapaxes(np.linalg.solve(S, H @ P), -1, -2)        # P H^T S^-1, with S and P symmetric
    x_new = x + np.einsum("...ij,...j->...i", K, nu)
    A = np.eye(4) - K @ H
    P_new = A @ P @ np.swapaxes(A, -1, -2) + K @ R @ np.swapaxes(K, -1, -2)
    P_new = 0.5 * (P_new + np.swapaxes(P_new, -1, -2))
    return Update(x=np.where(accepted[..., None], x_new, x), P=np.where(accepted[..., None, None], P_new, P),
                  accepted=accepted, nis=nis, innovation=nu)


# --- window mode (A3, A4) ---------------------------------------------------------------


def average_dist(ranges_m) -> float | None:
    """The paper's AverageDist: the mean of a uniform sub-sample (every second sample, from
    the first) of the window's ranges; None for none."""
    r = np.asarray(ranges_m, dtype=np.float64)[::2]
    return float(r.mean()) if r.size else None


def stable_bearing(bearings_rad, cluster_rad: float, min_share: float) -> tuple[float, int] | None:
    """The paper's StableBearingAngle (A3): for each bearing, the bearings within cluster_rad
    of it form its cluster; the largest cluster (ties: the smaller circular variance) gives
    its circular mean, if it holds at least min_share of the bearings. (mean, cluster size),
    or None (no bearing this window)."""
    b = np.asarray(bearings_rad, dtype=np.float64)
    if b.size == 0:
        return None
    near = np.abs(wrap_angle(b[:, None] - b[None, :])) <= cluster_rad
    counts = near.sum(axis=1)
    c, s = np.cos(b), np.sin(b)
    resultant = np.hypot(near @ c, near @ s) / counts            # 1 - circular variance
    best = max(range(b.size), key=lambda k: (counts[k], resultant[k]))
    if counts[best] < min_share * b.size:
        return None
    m = near[best]
    return float(math.atan2(s[m].sum(), c[m].sum())), int(counts[best])


# --- one teammate's track ------------------------------------------------------------------


@dataclass(frozen=True)
class Outcome:
    """What a sample did to a track. status: "started" (a new track), "accepted", "rejected"
    (the gate), "restarted" (rejected, and the track started again from it, or dropped until
    the next range and bearing), "waiting" (no track yet: a range or a bearing alone), "stale"
    (older than the track), "too_close" (predicted range below min_range_m), "nothing" (no
    usable sample). nis and dof: of the update (nan, 0 without one)."""

    status: str
    nis: float = math.nan
    dof: int = 0


class TeammateEkf:
    """One teammate's position and velocity in this robot's odometry frame."""

    def __init__(self, params: EkfParams = EkfParams()) -> None:
        self.params = params
        self.x: np.ndarray | None = None
        self.P: np.ndarray | None = None
        self.stamp_us: int | None = None
        self.rejections = 0                     # in a row
        self._last_range: tuple[int, float] | None = None
        self._last_bearing: tuple[int, float] | None = None

    @property
    def tracking(self) -> bool:
        return self.x is not None

    @property
    def position(self) -> tuple[float, float]:
        return float(self.x[0]), float(self.x[1])

    @property
    def position_cov(self) -> np.ndarray:
        """The 2 x 2 covariance of the position (m^2)."""
        return self.P[:2, :2].copy()

    def start(self, stamp_us: int, own_xy, range_m: float, bearing_rad: float) -> Outcome:
        self.x, self.P = polar_start(range_m, bearing_rad, np.asarray(own_xy, dtype=np.float64), self.params)
        self.stamp_us = int(stamp_us)
        self.rejections = 0
        return Outcome("started")

    def drop(self) -> None:
        self.x = self.P = self.stamp_us = None
        self.rejections = 0

    def predict_to(self, stamp_us: int) -> None:
        """Move the track to stamp_us (no earlier than its own stamp)."""
        dt_s = (int(stamp_us) - self.stamp_us) * 1e-6
        if dt_s > 0.0:
            self.x, self.P = predict(self.x, self.P, dt_s, self.params.accel_psd_m2ps3)
            self.stamp_us = int(stamp_us)

    def observe(self, stamp_us: int, own_xy, range_m: float | None = None,
                bearing_rad: float | None = None, walls: int = 0) -> Outcome:
        """Sequential mode: one range, one bearing (in this robot's odometry frame,
        map_bearing) or both of one stamp, with this robot's position at that stamp; walls:
        how many walls lie in between (EkfParams.noise)."""
        if range_m is None and bearing_rad is None:
            return Outcome("nothing")
        p = self.params
        stamp_us = int(stamp_us)
        if range_m is not None:
            self._last_range = (stamp_us, float(range_m))
        if bearing_rad is not None:
            self._last_bearing = (stamp_us, float(bearing_rad))
        if not self.tracking:
            gap_us = round(p.pair_max_gap_s * 1e6)
            r, b = self._last_range, self._last_bearing
            if r is not None and b is not None and abs(r[0] - b[0]) <= gap_us:
                return self.start(stamp_us, own_xy, r[1], b[1])
            return Outcome("waiting")
        if stamp_us < self.stamp_us:
            return Outcome("stale")
        if range_m is not None and bearing_rad is not None:
            rows, z = BOTH, (range_m, bearing_rad)
        elif range_m is not None:
            rows, z = (RANGE,), (range_m,)
        else:
            rows, z = (BEARING,), (bearing_rad,)
        return self._update(stamp_us, own_xy, rows, z, self._variances(rows, 1, 1, walls),
                            restart=(range_m, bearing_rad) if len(rows) == 2 else None)

    def observe_window(self, stamp_us: int, own_xy, ranges_m, bearings_rad) -> Outcome:
        """Window mode: the window's ranges and (frame) bearings as one update at stamp_us (its
        middle), with this robot's position then."""
        p = self.params
        rho = average_dist(ranges_m)
        stable = stable_bearing(bearings_rad, p.window_cluster_rad, p.window_min_share)
        psi = None if stable is None else stable[0]
        if not self.tracking:
            if rho is None or psi is None:
                return Outcome("waiting" if rho is not None or len(bearings_rad) else "nothing")
            return self.start(stamp_us, own_xy, rho, psi)
        if rho is None and psi is None:
            return Outcome("nothing")
        if int(stamp_us) < self.stamp_us:
            return Outcome("stale")
        n_r = (len(ranges_m) + 1) // 2
        n_b = 0 if stable is None else stable[1]
        rows = tuple(k for k, v in ((RANGE, rho), (BEARING, psi)) if v is not None)
        z = tuple(v for v in (rho, psi) if v is not None)
        return self._update(int(stamp_us), own_xy, rows, z, self._variances(rows, n_r, n_b),
                            restart=(rho, psi) if len(rows) == 2 else None)

    def _variances(self, rows: tuple[int, ...], n_ranges: int, n_bearings: int, walls: int = 0) -> np.ndarray:
        """R of a mean of n_ranges ranges and n_bearings bearings, with walls in between."""
        range_std, bearing_std = self.params.noise(walls)
        var = {RANGE: range_std ** 2 / max(n_ranges, 1), BEARING: bearing_std ** 2 / max(n_bearings, 1)}
        return np.array([var[k] for k in rows])

    def _update(self, stamp_us: int, own_xy, rows, z, variances, restart) -> Outcome:
        p = self.params
        self.predict_to(stamp_us)
        own = np.asarray(own_xy, dtype=np.float64)
        u = update(self.x, self.P, np.asarray(z, dtype=np.float64), own, rows, variances,
                   p.gate_2dof if len(rows) == 2 else p.gate_1dof, p.min_range_m, p.second_order)
        nis, dof = float(u.nis), len(rows)
        if not math.isfinite(nis):
            return Outcome("too_close", nis, dof)
        if bool(u.accepted):
            self.x, self.P = u.x, u.P
            self.rejections = 0
            return Outcome("accepted", nis, dof)
        self.rejections += 1
        if self.rejections < p.reinit_after_rejections:
            return Outcome("rejected", nis, dof)
        if restart is not None:
            self.start(stamp_us, own, *restart)
        else:
            self.drop()
        return Outcome("restarted", nis, dof)
