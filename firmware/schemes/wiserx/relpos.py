"""Where each teammate is, from the UWB ranges and AoA bearings this robot measured: one
track per teammate (../shared/schemes/wiserx.md sections 1.2, 1.3, A2-A5, A18, A19, A26).

Every sample is paired with this robot's own pose at the sample's time (services.pose's
pose_at): a bearing is turned into this robot's odometry frame with the yaw of that time
(A2), and the EKF (ekf.TeammateEkf, sequential mode) updates with the position of that
time. Before the EKF's gate, two rules of the spec:

- bearings (A3, sequential mode): a bearing counts only when it lies within
  bearing_median_tol of the circular median of the last bearing_median_k bearings of that
  teammate. Each is kept as its residual against the track's prediction at its own time, so
  a teammate that drives past (its bearing sweeping by tens of degrees between two WiFi
  sweeps) is not mistaken for multipath; before a track exists and while fewer than
  bearing_median_min are kept, only the gate decides;
- ranges (A4): a range that jumps from the last accepted one by more than range_jump_m
  (plus range_jump_speed_mps per second between them: two robots can part at 1.6 m/s) is held
  back, unless range_jump_agree held-back ranges in a row agree within range_jump_m, which
  then restart from the newest.

Failure (A18): a teammate neither ranged nor seen for silence_fail_s is taken as failed
(tau = 0) and its track dropped; the next sample of it revives it (tau = 1). What the
hgrid records (A19): an estimate whose last accepted update is recent (the caller says how
recent). Pure: time comes with the samples and the caller's now_us.
"""
from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np

from firmware.schemes.wiserx.ekf import Outcome, TeammateEkf, map_bearing, predict, wrap_angle
from firmware.schemes.wiserx.params import EkfParams, WiserxParams
from hal.samples import AoaBearing, UwbRange

PoseAt = Callable[[int], "tuple[float, float, float] | None"]
WallsBetween = Callable[[tuple[float, float], tuple[float, float]], int]

# Counters every track keeps (RelPos.counts sums them; stable keys for the mission report).
COUNTERS = ("ranges", "ranges_accepted", "ranges_held_back", "bearings", "bearings_accepted",
            "bearings_off_median", "gate_rejections", "tracks_started", "failures", "revivals")


def circular_median(angles_rad: Iterable[float]) -> float:
    """The angle minimising the summed absolute wrapped distance to the given angles, taken
    among the angles themselves (ties: the earliest)."""
    a = np.asarray(list(angles_rad), dtype=np.float64)
    cost = np.abs(wrap_angle(a[:, None] - a[None, :])).sum(axis=0)
    return float(a[int(np.argmin(cost))])


@dataclass(frozen=True)
class Estimate:
    """A teammate's position (m) in this robot's odometry frame, its 2 x 2 covariance (m^2),
    and when its track last took a measurement."""

    peer_id: int
    x_m: float
    y_m: float
    cov: np.ndarray
    updated_us: int

    @property
    def trace_m2(self) -> float:
        return float(self.cov[0, 0] + self.cov[1, 1])


def polar_fix(range_m: float, psi_rad: float, own_xy: tuple[float, float],
              params: EkfParams, walls: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The position a range and a (frame) bearing put a teammate at, and its 2 x 2
    covariance from the range and bearing noise (first order; EkfParams.noise with walls in
    between)."""
    c, s = math.cos(psi_rad), math.sin(psi_rad)
    z = np.array([own_xy[0] + range_m * c, own_xy[1] + range_m * s])
    J = np.array([[c, -range_m * s], [s, range_m * c]])
    range_std, bearing_std = params.noise(walls)
    return z, J @ np.diag([range_std ** 2, bearing_std ** 2]) @ J.T


class PeerTrack:
    """One teammate: its EKF and the rules in front of it."""

    def __init__(self, peer_id: int, params: WiserxParams, ekf_params: EkfParams) -> None:
        self.peer_id = peer_id
        self.p = params
        self.ekf = TeammateEkf(ekf_params)
        self.alive = True
        self.heard_us: int | None = None            # the newest sample of it, accepted or not
        self.updated_us: int | None = None          # the newest accepted update
        self._residuals: deque[float] = deque(maxlen=params.bearing_median_k)
        self._last_range: tuple[int, float] | None = None     # (stamp, m): the last accepted range
        self._held: list[float] = []                # ranges held back in a row
        self.counts = dict.fromkeys(COUNTERS, 0)

    # --- samples ----------------------------------------------------------------------
    def heard(self, stamp_us: int) -> None:
        """A sample of this teammate arrived: it is alive (revived if it was taken as failed)."""
        if not self.alive:
            self.alive = True
            self.counts["revivals"] += 1
        self.heard_us = stamp_us if self.heard_us is None else max(self.heard_us, stamp_us)

    def observe(self, stamp_us: int, own_pose: tuple[float, float, float], range_m: float | None,
                body_bearing_rad: float | None, walls: int = 0) -> str:
        """One range, one bearing (this robot's body frame) or both of one stamp, with this
        robot's pose at that stamp and the walls in between (EkfParams.noise). Returns what
        became of it: the EKF's outcome status, or "held_back" / "off_median" when a rule
        refused everything."""
        x, y, yaw = own_pose
        psi = None
        if range_m is not None:
            self.counts["ranges"] += 1
            if not self._range_ok(stamp_us, range_m):
                range_m = None
        if body_bearing_rad is not None:
            self.counts["bearings"] += 1
            psi = map_bearing(body_bearing_rad, yaw)
            if not self._bearing_ok(stamp_us, (x, y), psi):
                psi = None
        if range_m is None and psi is None:
            return "held_back" if body_bearing_rad is None else "off_median"
        was_tracking = self.ekf.tracking
        if was_tracking and range_m is not None and psi is not None and stamp_us >= self.ekf.stamp_us:
            out = self._converted_update(stamp_us, (x, y), range_m, psi, walls)
        else:
            out = self.ekf.observe(stamp_us, (x, y), range_m, psi, walls)
        if out.status in ("started", "accepted") or (out.status == "restarted" and self.ekf.tracking):
            self.updated_us = stamp_us
            if range_m is not None:
                self._last_range = (stamp_us, range_m)
                self._held = []
                self.counts["ranges_accepted"] += 1
            if psi is not None:
                self.counts["bearings_accepted"] += 1
            if out.status != "accepted":
                self.counts["tracks_started"] += 1
                self._residuals.clear()
        elif out.status in ("rejected", "restarted"):
            self.counts["gate_rejections"] += 1
        if not was_tracking and self.ekf.tracking:
            self._residuals.clear()
        return out.status

    def _converted_update(self, stamp_us: int, own_xy: tuple[float, float], range_m: float, psi: float,
                          walls: int = 0) -> Outcome:
        """A range and a bearing of one stamp as one position measurement (the converted
        measurement filter): z = own + rho (cos psi, sin psi), R = J diag(sigma_r^2,
        sigma_psi^2) J^T, a linear update of the position, gated at chi-square 2 dof. The
        bearing's non-linearity then never meets the track's linearisation: with a bearing
        only every 5 s and teammates turning in between, the track's position spread grows
        to metres, and the plain EKF update, linearised there, went astray by 10 m and more
        while every range and bearing was within 10 cm and 5 degrees (Intel lab, paper
        profile). Three rejections in a row restart the track from the measurement."""
        e, ep = self.ekf, self.ekf.params
        e.predict_to(stamp_us)
        z, R = polar_fix(range_m, psi, own_xy, ep, walls)
        P = e.P
        nu = z - e.x[:2]
        S = P[:2, :2] + R
        nis = float(nu @ np.linalg.solve(S, nu))
        if nis > ep.gate_2dof:
            e.rejections += 1
            if e.rejections < ep.reinit_after_rejections:
                return Outcome("rejected", nis, 2)
            e.start(stamp_us, own_xy, range_m, psi)
            return Outcome("restarted", nis, 2)
        K = np.linalg.solve(S, P[:2, :]).T                 # P H^T S^-1 with H = [I 0]
        A = np.eye(4)
        A[:, :2] -= K
        e.x = e.x + K @ nu
        Pn = A @ P @ A.T + K @ R @ K.T
        e.P = 0.5 * (Pn + Pn.T)
        e.rejections = 0
        return Outcome("accepted", nis, 2)

    def _range_ok(self, stamp_us: int, range_m: float) -> bool:
        p = self.p
        if self._last_range is None:
            return True
        t0, r0 = self._last_range
        allowed = p.range_jump_m + p.range_jump_speed_mps * max(stamp_us - t0, 0) * 1e-6
        if abs(range_m - r0) <= allowed:
            self._held = []
            return True
        self._held.append(range_m)
        if len(self._held) >= p.range_jump_agree and max(self._held[-p.range_jump_agree:]) - \
                min(self._held[-p.range_jump_agree:]) <= p.range_jump_m:
            self._held = []
            return True
        self.counts["ranges_held_back"] += 1
        return False

    def _bearing_ok(self, stamp_us: int, own_xy: tuple[float, float], psi: float) -> bool:
        """The median check of A3, on the bearing's residual against the track's prediction,
        where the track predicts bearings better than the tolerance (its position spread
        seen from here under bearing_median_tol); elsewhere residuals say more about the
        track than about multipath, and the gate alone decides (a check against a stray
        track refused good bearings and kept it astray: 64 of 105 bearings refused, tracks
        10 m off, Intel lab, realistic profile)."""
        p = self.p
        if not self.ekf.tracking or stamp_us < self.ekf.stamp_us:
            return True
        xj, P = self.ekf.x, self.ekf.P
        dt = (stamp_us - self.ekf.stamp_us) * 1e-6
        dx, dy = xj[0] + xj[2] * dt - own_xy[0], xj[1] + xj[3] * dt - own_xy[1]
        spread_m = math.sqrt(max(P[0, 0] + P[1, 1] + dt * dt * (P[2, 2] + P[3, 3]), 0.0))
        if spread_m > math.hypot(dx, dy) * math.tan(min(p.bearing_median_tol_rad, 1.5)):
            self._residuals.clear()
            return True
        residual = float(wrap_angle(psi - math.atan2(dy, dx)))
        ok = True
        if len(self._residuals) >= p.bearing_median_min:
            ok = abs(float(wrap_angle(residual - circular_median(self._residuals)))) <= p.bearing_median_tol_rad
        self._residuals.append(residual)
        if not ok:
            self.counts["bearings_off_median"] += 1
        return ok

    # --- liveness and output ------------------------------------------------------------
    def check_silence(self, now_us: int) -> bool:
        """Take the teammate as failed after silence_fail_s without a sample; True when it
        just failed."""
        if not self.alive or self.heard_us is None:
            return False
        if now_us - self.heard_us > self.p.silence_fail_s * 1e6:
            self.alive = False
            self.ekf.drop()
            self._residuals.clear()
            self._last_range, self._held = None, []
            self.counts["failures"] += 1
            return True
        return False

    def estimate(self, now_us: int, max_age_s: float) -> Estimate | None:
        """The track's position and covariance if the teammate is alive and its last
        accepted update is at most max_age_s old, predicted to now_us (never backwards)."""
        if not self.alive or not self.ekf.tracking or self.updated_us is None:
            return None
        if now_us - self.updated_us > max_age_s * 1e6:
            return None
        # Predicted without moving the track: a sample stamped before now_us may still come.
        x, P = predict(self.ekf.x, self.ekf.P, max(now_us - self.ekf.stamp_us, 0) * 1e-6,
                       self.ekf.params.accel_psd_m2ps3)
        return Estimate(self.peer_id, float(x[0]), float(x[1]), P[:2, :2].copy(), self.updated_us)


class RelPos:
    """Every teammate's track. feed() takes what the UWB ranger and the AoA sensor gave
    since the last call."""

    def __init__(self, own_id: int, params: WiserxParams = WiserxParams(), ekf_params: EkfParams = EkfParams()) -> None:
        self.own_id = own_id
        self.p = params
        self.ekf_params = ekf_params
        self.tracks: dict[int, PeerTrack] = {}
        self.no_pose = 0           # samples dropped for want of an own pose at their time

    def track(self, peer_id: int) -> PeerTrack:
        t = self.tracks.get(peer_id)
        if t is None:
            t = self.tracks[peer_id] = PeerTrack(peer_id, self.p, self.ekf_params)
        return t

    def feed(self, ranges: Iterable[UwbRange], bearings: Iterable[AoaBearing], pose_at: PoseAt,
             walls_between: WallsBetween | None = None) -> list[tuple[int, str]]:
        """The samples in time order, a range and a bearing of one teammate with one stamp
        as one update; only the strongest AoA peak (rank 0) is used. walls_between(own_xy,
        teammate_xy): the walls the own map shows between the robot and where the track
        predicts the teammate at the sample's time (None: taken as none). Returns (peer,
        status) per update."""
        by_key: dict[tuple[int, int], list] = {}
        for r in ranges:
            if r.peer_id != self.own_id and math.isfinite(r.range_m) and r.range_m > 0.0:
                by_key.setdefault((r.stamp_us, r.peer_id), [None, None])[0] = r.range_m
        for b in bearings:
            if b.peer_id != self.own_id and b.rank == 0 and math.isfinite(b.bearing_rad):
                by_key.setdefault((b.stamp_us, b.peer_id), [None, None])[1] = b.bearing_rad
        out = []
        for (stamp_us, peer), (rho, phi) in sorted(by_key.items()):
            pose = pose_at(stamp_us)
            if pose is None:
                self.no_pose += 1
                continue
            t = self.track(peer)
            t.heard(stamp_us)
            walls = 0
            if walls_between is not None and t.ekf.tracking and stamp_us >= t.ekf.stamp_us:
                dt = (stamp_us - t.ekf.stamp_us) * 1e-6
                xj = t.ekf.x
                walls = walls_between((pose[0], pose[1]), (xj[0] + xj[2] * dt, xj[1] + xj[3] * dt))
            out.append((peer, t.observe(stamp_us, pose, rho, phi, walls)))
        return out

    def check_silence(self, now_us: int) -> list[int]:
        """Teammates that just fell silent for silence_fail_s (taken as failed)."""
        return [peer for peer, t in sorted(self.tracks.items()) if t.check_silence(now_us)]

    def alive(self, peer_id: int) -> bool:
        t = self.tracks.get(peer_id)
        return t is None or t.alive

    def estimates(self, now_us: int, max_age_s: float) -> list[Estimate]:
        """The live teammates' estimates updated within max_age_s, by peer id."""
        out = []
        for _peer, t in sorted(self.tracks.items()):
            e = t.estimate(now_us, max_age_s)
            if e is not None:
                out.append(e)
        return out

    def counts(self) -> dict[str, int]:
        total = dict.fromkeys(COUNTERS, 0)
        for t in self.tracks.values():
            for k, v in t.counts.items():
                total[k] += v
        return total
