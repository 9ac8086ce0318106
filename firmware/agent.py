"""The explorer firmware for one robot: setup() once, then tick() from the main loop.

It knows its robot only through the `Hal` it is given (ArduPilot's setup/loop shape, with
the HAL passed in rather than global). Every tick runs the tasks that are due:

    lidar    10 Hz  fold the newest scan into the local map (and move the window)
    control  20 Hz  drop topological vertices, follow the path, command the drive
    planning  1 Hz  waypoints, target choice, path planning, termination
"""
from __future__ import annotations

import math

import numpy as np

from firmware.controller import PathFollower
from firmware.explorer import Explorer
from firmware.local_map import KeyframeStore, LocalMap, bin_scan_by_bearing
from firmware.params import ExplorationParams, TaskRates
from firmware.scheduler import Scheduler, Task, TaskProfiler
from firmware.comms.schema import e_inf_bit_to_code
from firmware.topo_map import TopoMap
from hal.bundle import Hal
from hal.samples import LidarScan


class ExplorerAgent:
    MIN_REPLAN_US = 200_000  # event-triggered replanning is limited to 5 Hz
    def __init__(self, hal: Hal, params: ExplorationParams = ExplorationParams(),
                 rates: TaskRates = TaskRates()) -> None:
        self.hal = hal
        self.p = params
        self.rates = rates
        self.done = False
        self.status = "starting"
        self.ticks = 0
        self.scans = 0
        self._last_scan_binned: tuple[float, float, np.ndarray, float] | None = None
        self._last_vertex_xy: tuple[float, float] | None = None
        self._last_plan_us = -10**12
        self.scheduler = Scheduler([
            Task("lidar", rates.lidar_hz, self._task_lidar),
            Task("control", rates.control_hz, self._task_control),
            Task("planning", rates.planning_hz, self._task_planning),
        ])

    # --- lifecycle --------------------------------------------------------------------
    def setup(self) -> None:
        pose = self.hal.odometry.read()
        limits = self.hal.drive.limits()
        if limits.robot_radius_m > self.p.robot_radius_m:
            raise ValueError(
                f"robot radius {limits.robot_radius_m} m exceeds the planner's robot_radius_m "
                f"{self.p.robot_radius_m} m: paths would scrape walls")
        self.keyframes = KeyframeStore(self.p.keyframe_bins)
        self.local_map = LocalMap(self.p, pose.x_m, pose.y_m, self.keyframes)
        self.topo = TopoMap(self.p.d_build_m, self.p.d_connect_m)
        self.explorer = Explorer(self.p, self.local_map, self.topo)
        self.follower = PathFollower(self.p, limits.max_v_mps, limits.max_omega_radps)
        self.status = "exploring"

    def tick(self, profiler: TaskProfiler | None = None) -> None:
        self.ticks += 1
        if self.done:
            return
        self.scheduler.run_due(self.hal.clock.now_us(), profiler)

    # --- tasks ----------------------------------------------------------------------
    def _task_lidar(self, now_us: int) -> None:
        scan: LidarScan | None = self.hal.lidar.latest_scan()
        if scan is None:
            return
        pose = self.hal.odometry.read()
        self.local_map.follow(pose.x_m, pose.y_m)
        self.local_map.integrate_scan(pose.x_m, pose.y_m, pose.yaw_rad, scan.angle_min_rad,
                                      scan.angle_increment_rad, scan.ranges_m, scan.range_max_m)
        self._last_scan_binned = (
            pose.x_m, pose.y_m,
            bin_scan_by_bearing(pose.yaw_rad, scan.angle_min_rad, scan.angle_increment_rad,
                                scan.ranges_m, self.p.keyframe_bins),
            scan.range_max_m,
        )
        self.scans += 1

    def _task_control(self, now_us: int) -> None:
        pose = self.hal.odometry.read()
        self._maybe_add_vertex(pose.x_m, pose.y_m, now_us)
        if not self.follower.active and now_us - self._last_plan_us >= self.MIN_REPLAN_US:
            # The path ran out before the next planning slot: plan now instead of idling.
            self._task_planning(now_us)
            if self.done:
                return
        v, omega = self.follower.command(pose.x_m, pose.y_m, pose.yaw_rad)
        self.hal.drive.command(v, omega)

    def _task_planning(self, now_us: int) -> None:
        if self._last_scan_binned is None:
            return
        pose = self.hal.odometry.read()
        self._last_plan_us = now_us
        plan = self.explorer.plan(pose.x_m, pose.y_m, now_us)
        if plan.done:
            self.follower.clear()
            self.hal.drive.command(0.0, 0.0)
            self.done = True
            self.status = "complete"
            return
        self.follower.set_path(plan.path_xy)

    def _maybe_add_vertex(self, x_m: float, y_m: float, now_us: int) -> None:
        """A vertex (and its keyframe) every d_build of travel: the robot's own record of
        where it has been and what it saw there."""
        last = self._last_vertex_xy
        if last is not None and math.hypot(x_m - last[0], y_m - last[1]) < self.p.d_build_m:
            return
        if self._last_scan_binned is None:
            return
        kx, ky, ranges, range_max = self._last_scan_binned
        self.keyframes.add(kx, ky, ranges, range_max)
        e_inf = self.explorer.waypoints.total_entropy_near(x_m, y_m, self.p.local_map_size_m / 2)
        self.topo.add((self.hal.robot_id, round(x_m * 100), round(y_m * 100), 0, 1, e_inf_bit_to_code(e_inf)))
        self._last_vertex_xy = (x_m, y_m)
