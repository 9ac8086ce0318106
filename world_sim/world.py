"""The simulated physical world: robot bodies on a ground-truth map and what their sensors
measure. The simulated HAL backends (`hal.sim`) are thin views onto one `World`.

Time is integer microseconds and moves only in `World.step`. Sensors fire on fixed period
grids (a LiDAR at 10 Hz scans at 0, 100 000, 200 000 us, ...); a step is split at every due
measurement so each one sees the true poses of all robots at its own time stamp.

Randomness: robot i's LiDAR noise comes only from `stream(seed, "lidar", i)`, its
odometry drift from "odometry", its UWB ranges from "uwb", its AoA bearings from "aoa";
UWB and AoA take a fixed number of draws for every peer at every firing, whatever the
profile and the outcome (world_sim.sensing), so a rate of outliers or dropouts never shifts
a later number. What UWB and AoA measure is WorldParams.sensing, a named profile.
Robot ids on the HAL (UwbRange.peer_id, AoaBearing.peer_id) are the robot indices.

Coverage is ground truth: each scan marks the cells its beams crossed, computed from the
TRUE pose and the noise-free ranges. Robots do not collide with or occlude each other.
"""
from __future__ import annotations

import math
import operator
from dataclasses import dataclass, fields, replace

import numpy as np

from hal.samples import AoaBearing, LidarScan, OdometrySample, UwbRange
from world_sim.kinematics import BodyState, ClearanceMap, advance_all, wrap_angle
from world_sim.occupancy_map import OccupancyMap
from world_sim.raycast import cast_and_mark_all, pair_wall_lengths_m
from world_sim.seeding import stream
from world_sim.sensing import AOA_DRAWS, REALISTIC, UWB_DRAWS, SensingProfile, sensing_profile

# Measurements a robot has not collected are dropped oldest first beyond this many.
MAX_PENDING_MEASUREMENTS = 1024
# What the command line and a robot's [world] table say of the two settings they take.
WHEEL_SLIP_HELP = ("share of the commanded wheel travel the encoders report while a wall holds the body back "
                   "(0: the wheels stop with it; 1: they spin on, and odometry runs on as if the robot drove)")
LIDAR_PHASE_HELP = ("the LiDAR's first scan this long after the start, then one every 100 ms: scans arrive between "
                    "the firmware's 50 ms ticks")


@dataclass(frozen=True)
class WorldParams:
    robot_radius_m: float = 0.25
    max_v_mps: float = 0.8
    max_omega_radps: float = 1.5
    lidar_beams: int = 360
    lidar_range_m: float = 10.0
    lidar_noise_std_m: float = 0.01      # Gaussian, on beams that hit something
    lidar_rate_hz: float = 10.0
    # The first scan this long after the start, then one every period: with a phase or a rate
    # that is no multiple of the firmware's tick, scans arrive between ticks.
    lidar_phase_us: int = 0
    # Odometry drift is a random walk whose variance grows linearly with the motion:
    # position error std = odom_trans_noise_per_m * sqrt(metres travelled) per axis,
    # yaw error std = sqrt(odom_yaw_noise_per_rad^2 * |rad turned| + odom_yaw_drift_per_m^2 * metres).
    # The yaw error then bends the integrated track, so position drift grows faster than that.
    odom_trans_noise_per_m: float = 0.002
    odom_yaw_noise_per_rad: float = 0.001
    odom_yaw_drift_per_m: float = 0.0002
    odom_speed_noise_frac: float = 0.01  # relative std of the reported v and omega (encoder scale)
    wheel_slip_frac: float = 0.0         # WHEEL_SLIP_HELP
    # What the UWB ranger and the WiFi AoA sensor measure: a named profile of world_sim.sensing
    # (SENSING_PROFILE_HELP; sensing_profile() gives one by name).
    sensing: SensingProfile = REALISTIC
    collision_spacing_m: float = 0.01    # arc sampling for the swept-disc collision check

    def __post_init__(self) -> None:
        if not isinstance(self.sensing, SensingProfile):
            raise ValueError(f"WorldParams.sensing must be a world_sim.sensing.SensingProfile, got {self.sensing!r}")
        for f in fields(self):
            if f.name == "sensing":
                continue
            value = getattr(self, f.name)
            if not isinstance(value, (int, float)) or isinstance(value, bool) or not math.isfinite(value):
                raise ValueError(f"WorldParams.{f.name} must be a finite number, got {value!r}")
            if value < 0:
                raise ValueError(f"WorldParams.{f.name} must be >= 0, got {value!r}")
        for name in ("robot_radius_m", "lidar_range_m", "lidar_rate_hz", "collision_spacing_m"):
            if getattr(self, name) <= 0:
                raise ValueError(f"WorldParams.{name} must be > 0, got {getattr(self, name)!r}")
        if not isinstance(self.lidar_beams, int) or self.lidar_beams < 1:
            raise ValueError(f"WorldParams.lidar_beams must be a positive integer, got {self.lidar_beams!r}")
        if self.wheel_slip_frac > 1:
            raise ValueError(f"WorldParams.wheel_slip_frac must be in [0, 1], got {self.wheel_slip_frac!r}")
        if not isinstance(self.lidar_phase_us, int) or self.lidar_phase_us >= round(1e6 / self.lidar_rate_hz):
            raise ValueError(f"WorldParams.lidar_phase_us must be a whole number of microseconds below the LiDAR's "
                             f"period ({round(1e6 / self.lidar_rate_hz)} us), got {self.lidar_phase_us!r}")
        for name, rate_hz in (("lidar_rate_hz", self.lidar_rate_hz), ("sensing.uwb.rate_hz", self.sensing.uwb.rate_hz),
                              ("sensing.aoa.rate_hz", self.sensing.aoa.rate_hz)):
            if round(1e6 / rate_hz) < 1:
                raise ValueError(f"WorldParams.{name} = {rate_hz!r} is faster than 1 MHz")

    def with_slip_and_lidar_phase(self, wheel_slip_frac: float, lidar_phase_ms: float) -> WorldParams:
        """These parameters with wheel_slip_frac and a LiDAR phase given in milliseconds (as
        the command line and a robot's [world] table give it)."""
        return replace(self, wheel_slip_frac=wheel_slip_frac, lidar_phase_us=round(lidar_phase_ms * 1000))

    @property
    def lidar_period_us(self) -> int:
        return round(1e6 / self.lidar_rate_hz)

    def with_sensing_profile(self, name: str) -> WorldParams:
        """These parameters with the sensing profile of that name (world_sim.sensing.SENSING_PROFILES)."""
        return replace(self, sensing=sensing_profile(name))

    @property
    def uwb_period_us(self) -> int:
        return round(1e6 / self.sensing.uwb.rate_hz)

    @property
    def aoa_period_us(self) -> int:
        return round(1e6 / self.sensing.aoa.rate_hz)

    @property
    def lidar_angle_min_rad(self) -> float:
        return -math.pi

    @property
    def lidar_angle_increment_rad(self) -> float:
        return 2.0 * math.pi / self.lidar_beams


class World:
    def __init__(
        self,
        occ: OccupancyMap,
        start_poses: list[tuple[float, float, float]],
        seed: int,
        params: WorldParams = WorldParams(),
    ) -> None:
        self.occ = occ
        self.params = params
        self.seed = int(seed)
        self.clearance = ClearanceMap.from_map(occ)
        self._wall = self.clearance.wall_u8
        n = len(start_poses)
        if n == 0:
            raise ValueError("World needs at least one start pose")
        poses = np.empty((n, 3), dtype=np.float64)
        for i, pose in enumerate(start_poses):
            try:
                x, y, yaw = (float(v) for v in pose)
            except (TypeError, ValueError):
                raise ValueError(f"start pose of robot {i} must be (x_m, y_m, yaw_rad), got {pose!r}") from None
            if not all(math.isfinite(v) for v in (x, y, yaw)):
                raise ValueError(f"start pose of robot {i} has a non-finite value: {pose!r}")
            clearance_m = self.clearance.clearance_m(x, y, params.robot_radius_m + 1.0)
            if not clearance_m > params.robot_radius_m:
                raise ValueError(
                    f"start pose of robot {i} at (x={x:.3f} m, y={y:.3f} m, yaw={yaw:.3f} rad) on map "
                    f"{occ.name!r}: the robot disc (radius {params.robot_radius_m} m) touches a wall cell "
                    f"or the map edge (clearance {clearance_m:.3f} m)"
                )
            poses[i] = (x, y, wrap_angle(yaw))
        self.n_robots = n
        self.now_us = 0
        self._pose = poses
        self._cmd = np.zeros((n, 2), dtype=np.float64)
        self._speed_factor = np.ones(n, dtype=np.float64)     # of the drive limits (a slow robot)
        self._powered = np.ones(n, dtype=bool)                # False: the robot failed
        self._path_m = np.zeros(n, dtype=np.float64)
        self._blocked = np.zeros(n, dtype=np.int64)
        self._push_us = np.zeros(n, dtype=np.int64)          # the current run of blocked steps
        self._longest_push_us = np.zeros(n, dtype=np.int64)
        self._observed = np.zeros((n, occ.rows, occ.cols), dtype=bool)
        self._odom = poses.copy()
        self._odom_vel = np.zeros((n, 2), dtype=np.float64)
        self._odom_stamp_us = 0
        self._scans: list[LidarScan | None] = [None] * n
        self._uwb: list[list[UwbRange]] = [[] for _ in range(n)]
        self._aoa: list[list[AoaBearing]] = [[] for _ in range(n)]
        self._rng_lidar = [stream(seed, "lidar", i) for i in range(n)]
        self._rng_odom = [stream(seed, "odometry", i) for i in range(n)]
        self._rng_uwb = [stream(seed, "uwb", i) for i in range(n)]
        self._rng_aoa = [stream(seed, "aoa", i) for i in range(n)]
        self._walls = np.zeros((n, n))
        self._walls_us = -1
        p = params
        self._beam_angles = p.lidar_angle_min_rad + np.arange(p.lidar_beams) * p.lidar_angle_increment_rad
        self._periods = (p.lidar_period_us, p.uwb_period_us, p.aoa_period_us)
        if p.lidar_phase_us == 0:
            self._fire_lidar()
        self._fire_uwb()
        self._fire_aoa()
        self._next_us = list(self._periods)
        if p.lidar_phase_us:
            self._next_us[0] = p.lidar_phase_us

    # --- control ------------------------------------------------------------------------

    def _check_index(self, i: int) -> int:
        i = operator.index(i)
        if not 0 <= i < self.n_robots:
            raise IndexError(f"robot index {i} out of range (world has {self.n_robots} robots)")
        return i

    def set_command(self, i: int, v_mps: float, omega_radps: float) -> None:
        """Robot i drives with this body velocity (clipped to the limits) until the next command."""
        i = self._check_index(i)
        for name, value in (("v_mps", v_mps), ("omega_radps", omega_radps)):
            if not math.isfinite(value):
                raise ValueError(f"drive command for robot {i}: {name} must be finite, got {value!r}")
        if not self._powered[i]:
            return                                   # a robot without power does not move
        p = self.params
        max_v, max_omega = p.max_v_mps * self._speed_factor[i], p.max_omega_radps * self._speed_factor[i]
        self._cmd[i, 0] = min(max(float(v_mps), -max_v), max_v)
        self._cmd[i, 1] = min(max(float(omega_radps), -max_omega), max_omega)

    def set_speed_factor(self, i: int, factor: float) -> None:
        """Robot i's drive reaches only this share (0 < factor <= 1) of the speed and turn
        rate limits: a slower robot in a team (its firmware is not told)."""
        i = self._check_index(i)
        if not (math.isfinite(factor) and 0.0 < factor <= 1.0):
            raise ValueError(f"speed factor of robot {i} must be in (0, 1], got {factor!r}")
        self._speed_factor[i] = float(factor)
        self.set_command(i, *self._cmd[i])

    def power_off(self, i: int) -> None:
        """Robot i fails: it stops where it is and for good, and its UWB and WiFi neither
        measure nor answer. Its LiDAR's scans go on but nobody reads them; they mark what is
        seen from where it stopped, little if anything beyond its last scan before."""
        i = self._check_index(i)
        self._cmd[i] = 0.0
        self._powered[i] = False

    def powered(self, i: int) -> bool:
        return bool(self._powered[self._check_index(i)])

    def command(self, i: int) -> tuple[float, float]:
        i = self._check_index(i)
        return float(self._cmd[i, 0]), float(self._cmd[i, 1])

    def step(self, dt_us: int) -> None:
        """Advance the world by dt_us microseconds, taking every measurement that falls due."""
        dt_us = operator.index(dt_us)
        if dt_us <= 0:
            raise ValueError(f"dt_us must be a positive integer, got {dt_us}")
        t_end = self.now_us + dt_us
        n = self.n_robots
        travelled_signed = np.zeros(n)
        turned = np.zeros(n)
        blocked = np.zeros(n, dtype=bool)
        t = self.now_us
        while True:
            t_next = min(self._next_us[0], self._next_us[1], self._next_us[2], t_end)
            if t_next > t:
                self._move_all((t_next - t) * 1e-6, travelled_signed, turned, blocked)
                t = t_next
            self.now_us = t
            if self._next_us[0] == t:
                self._fire_lidar()
                self._next_us[0] += self._periods[0]
            if self._next_us[1] == t:
                self._fire_uwb()
                self._next_us[1] += self._periods[1]
            if self._next_us[2] == t:
                self._fire_aoa()
                self._next_us[2] += self._periods[2]
            if t == t_end:
                break
        self._blocked += blocked
        self._push_us = np.where(blocked, self._push_us + dt_us, 0)
        np.maximum(self._longest_push_us, self._push_us, out=self._longest_push_us)
        dt_s = dt_us * 1e-6
        frac = self.params.odom_speed_noise_frac
        for i in range(n):
            v = travelled_signed[i] / dt_s
            w = turned[i] / dt_s
            if v != 0.0 or w != 0.0:
                z = self._rng_odom[i].standard_normal(2)
                v *= 1.0 + frac * z[0]
                w *= 1.0 + frac * z[1]
            self._odom_vel[i] = (v, w)
        self._odom_stamp_us = t_end

    def _move_all(self, dt_s: float, travelled_signed: np.ndarray, turned: np.ndarray, blocked_any: np.ndarray) -> None:
        p = self.params
        c = self.clearance
        start = self._pose.copy()
        travelled_m = np.empty(self.n_robots)
        blocked = np.empty(self.n_robots, dtype=bool)
        advance_all(c.wall_u8, c.cell_clearance_lb_m, c.origin_x_m, c.origin_y_m, c.resolution_m,
                    p.robot_radius_m, p.collision_spacing_m, self._pose, self._cmd, dt_s, travelled_m, blocked)
        self._path_m += travelled_m
        blocked_any |= blocked
        for i in range(self.n_robots):
            x0, y0, th0 = start[i]
            x1, y1, _ = self._pose[i]
            ds = travelled_m[i]
            v, w = self._cmd[i]
            dth = w * dt_s
            # Dead reckoning: the true body-frame displacement, integrated on the drifting
            # estimate, plus a random walk driven by how far and how much the robot moved;
            # held back by a wall, slipping wheels add travel the body did not make.
            slip_m = p.wheel_slip_frac * max(abs(v) * dt_s - ds, 0.0) if blocked[i] else 0.0
            travelled_signed[i] += math.copysign(ds + slip_m, v)
            turned[i] += dth
            if ds == 0.0 and dth == 0.0 and slip_m == 0.0:
                continue
            ca, sa = math.cos(th0), math.sin(th0)
            bx = ca * (x1 - x0) + sa * (y1 - y0) + math.copysign(slip_m, v)
            by = -sa * (x1 - x0) + ca * (y1 - y0)
            ds += slip_m
            z = self._rng_odom[i].standard_normal(3)
            pos_std = p.odom_trans_noise_per_m * math.sqrt(ds)
            yaw_std = math.sqrt(p.odom_yaw_noise_per_rad ** 2 * abs(dth) + p.odom_yaw_drift_per_m ** 2 * ds)
            ex, ey, eth = self._odom[i]
            ce, se = math.cos(eth), math.sin(eth)
            self._odom[i] = (
                ex + ce * bx - se * by + pos_std * z[0],
                ey + se * bx + ce * by + pos_std * z[1],
                wrap_angle(eth + dth + yaw_std * z[2]),
            )

    # --- sensors -------------------------------------------------------------------------

    def _fire_lidar(self) -> None:
        p = self.params
        occ = self.occ
        all_ranges = cast_and_mark_all(self._observed, self._wall, occ.origin_x_m, occ.origin_y_m, occ.resolution_m,
                                       self._pose, self._beam_angles, p.lidar_range_m)
        noise = np.stack([rng.standard_normal(p.lidar_beams) for rng in self._rng_lidar]) * p.lidar_noise_std_m
        hit = all_ranges < p.lidar_range_m
        measured = np.where(hit, np.clip(all_ranges + noise, 0.0, p.lidar_range_m), p.lidar_range_m).astype(np.float32)
        measured.flags.writeable = False  # every reader gets the same sample object
        for i in range(self.n_robots):
            self._scans[i] = LidarScan(
                stamp_us=self.now_us,
                angle_min_rad=p.lidar_angle_min_rad,
                angle_increment_rad=p.lidar_angle_increment_rad,
                range_max_m=p.lidar_range_m,
                ranges_m=measured[i],
            )

    def _pair_walls(self) -> np.ndarray:
        """Metres of wall on the straight line between every ordered pair of robots now
        (0 on the diagonal and for pairs beyond both sensors' reach). UWB and AoA firing at
        the same time share one computation."""
        if self._walls_us != self.now_us:
            s = self.params.sensing
            occ = self.occ
            # One metre beyond the reach, so that the sensors' exact test decides who is in range.
            within_m = max(s.uwb.range_max_m, s.aoa.range_max_m) + 1.0
            walls = pair_wall_lengths_m(self._wall, occ.origin_x_m, occ.origin_y_m, occ.resolution_m,
                                        self._pose, within_m)
            self._walls = np.nan_to_num(walls, nan=0.0)
            self._walls_us = self.now_us
        return self._walls

    def _peer_geometry(self, i: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Robot i's peers (every other robot, in index order), their true distances and the
        metres of wall between."""
        peers = np.array([j for j in range(self.n_robots) if j != i], dtype=np.int64)
        dx = self._pose[peers, 0] - self._pose[i, 0]
        dy = self._pose[peers, 1] - self._pose[i, 1]
        return peers, np.hypot(dx, dy), self._pair_walls()[i, peers]

    def _fire_uwb(self) -> None:
        model = self.params.sensing.uwb
        k = self.n_robots - 1
        for i in range(self.n_robots):
            peers, d, wall_m = self._peer_geometry(i)
            # The same draws for every peer at every firing, measured or not (world_sim.sensing).
            rng = self._rng_uwb[i]
            u = rng.random((k, UWB_DRAWS))
            z = rng.standard_normal(k)
            ranges, measured = model.measure(d, wall_m, u, z)
            out = self._uwb[i]
            for j, r, ok in zip(peers.tolist(), ranges.tolist(), measured.tolist()):
                if ok and self._powered[i] and self._powered[j]:
                    out.append(UwbRange(stamp_us=self.now_us, peer_id=j, range_m=r))
            del out[:-MAX_PENDING_MEASUREMENTS]

    def _fire_aoa(self) -> None:
        model = self.params.sensing.aoa
        k = self.n_robots - 1
        for i in range(self.n_robots):
            peers, d, wall_m = self._peer_geometry(i)
            xi, yi, yaw_i = self._pose[i]
            truth = np.arctan2(self._pose[peers, 1] - yi, self._pose[peers, 0] - xi) - yaw_i
            rng = self._rng_aoa[i]
            u = rng.random((k, AOA_DRAWS))
            z = rng.standard_normal(k)
            bearings, measured = model.measure(truth, d, wall_m, u, z)
            out = self._aoa[i]
            for j, b, ok in zip(peers.tolist(), bearings.tolist(), measured.tolist()):
                if ok and self._powered[i] and self._powered[j]:
                    out.append(AoaBearing(stamp_us=self.now_us, peer_id=j, bearing_rad=b))
            del out[:-MAX_PENDING_MEASUREMENTS]

    # --- what the HAL backends read --------------------------------------------------------

    def latest_scan(self, i: int) -> LidarScan | None:
        """Robot i's newest scan (robot frame, noisy); the same object until the next is due."""
        return self._scans[self._check_index(i)]

    def odometry_sample(self, i: int) -> OdometrySample:
        i = self._check_index(i)
        x, y, yaw = self._odom[i]
        v, w = self._odom_vel[i]
        return OdometrySample(stamp_us=self._odom_stamp_us, x_m=float(x), y_m=float(y), yaw_rad=float(yaw),
                              v_mps=float(v), omega_radps=float(w))

    def take_uwb_ranges(self, i: int) -> tuple[UwbRange, ...]:
        """Robot i's UWB ranges since the last call, oldest first."""
        q = self._uwb[self._check_index(i)]
        out = tuple(q)
        q.clear()
        return out

    def take_aoa_bearings(self, i: int) -> tuple[AoaBearing, ...]:
        q = self._aoa[self._check_index(i)]
        out = tuple(q)
        q.clear()
        return out

    # --- ground truth for metrics -----------------------------------------------------------

    def true_pose(self, i: int) -> BodyState:
        x, y, yaw = self._pose[self._check_index(i)]
        return BodyState(float(x), float(y), float(yaw))

    def true_poses(self) -> np.ndarray:
        """All true poses, shape (n_robots, 3): x_m, y_m, yaw_rad (a copy)."""
        return self._pose.copy()

    def path_length_m(self, i: int) -> float:
        return float(self._path_m[self._check_index(i)])

    def blocked_moves(self, i: int) -> int:
        """Steps in which a wall cut robot i's commanded translation short."""
        return int(self._blocked[self._check_index(i)])

    def longest_push_s(self, i: int) -> float:
        """The longest run of steps in which a wall cut robot i's commanded translation short:
        how long it kept pushing a wall."""
        return int(self._longest_push_us[self._check_index(i)]) * 1e-6

    def observed(self, i: int) -> np.ndarray:
        """Read-only view of the cells robot i's LiDAR has covered (bool, map shape)."""
        view = self._observed[self._check_index(i)].view()
        view.flags.writeable = False
        return view

    def observed_union(self) -> np.ndarray:
        return np.any(self._observed, axis=0)
