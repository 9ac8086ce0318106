"""The explorer firmware for one robot: setup() once, then tick() from the main loop.

It knows its robot only through the `Hal` it is given (ArduPilot's setup/loop shape, with
the HAL passed in rather than global). Every tick runs the tasks that are due:

    radio    20 Hz  link layer: hear records, send queued ones within the airtime budget
    lidar    10 Hz  fold the newest scan into the local map (and move the window)
    control  20 Hz  drop topological vertices, follow the path, command the drive
    planning  1 Hz  waypoints, target choice, path planning, termination
"""
from __future__ import annotations

import math

import numpy as np

from firmware.comms.link import LinkLayer, TdmaSchedule
from firmware.comms.schema import e_inf_bit_to_code
from firmware.controller import PathFollower
from firmware.explorer import Explorer
from firmware.local_map import BinnedScan, LocalMap, bin_scan, decode_keyframe, encode_keyframe, something_within
from firmware.params import ExplorationParams, TaskRates
from firmware.scheduler import Scheduler, Task, TaskProfiler
from firmware.team import STRATEGIES, Strategy, TeamView
from firmware.topo_map import MAX_INFO_VERSION, TOPO_FIELDS, TopoMap
from hal.bundle import Hal
from hal.lora import RadioProfile
from hal.samples import LidarScan

# Link-layer priorities: where the robot is matters more than bookkeeping about old places.
PRIORITY_MOTION = 2
PRIORITY_STATUS = 3
PRIORITY_INFO = 1
# An information-change record is sent when a vertex's e_inf code moves this far from what
# this robot last said there (one code step is 4.4 %, so 8 steps is about a third), or falls
# to zero.
INFO_CODE_STEP = 8


class ExplorerAgent:
    MIN_REPLAN_US = 200_000  # event-triggered replanning is limited to 5 Hz

    def __init__(self, hal: Hal, params: ExplorationParams = ExplorationParams(),
                 rates: TaskRates = TaskRates(), strategy: Strategy = STRATEGIES["greedy"],
                 radio_profile: RadioProfile | None = None, team_size: int = 1) -> None:
        """team_size: robots sharing the channel, with ids 0..team_size-1; it sizes the
        link layer's TDMA frame (one slot per robot) on profiles with a shared channel."""
        self.hal = hal
        self.p = params
        self.rates = rates
        self.strategy = strategy
        self.done = False
        self.status = "starting"
        self.ticks = 0
        self.scans = 0
        self._last_scan: tuple[float, float, float, LidarScan] | None = None   # x_m, y_m, yaw_rad, scan
        self._last_vertex_xy: tuple[float, float] | None = None
        self._last_plan_us = -10**12
        self._last_cmd_v = 0.0
        self._stuck_ticks = 0
        self.bumps = 0
        self.link = (LinkLayer(hal.robot_id, radio_profile,
                               tdma=TdmaSchedule.for_team(radio_profile, team_size, hal.robot_id,
                                                          round(1_000_000 / rates.radio_hz)))
                     if strategy.shares_topology and radio_profile is not None else None)
        if strategy.shares_dense_map and hal.mesh is None:
            raise ValueError(f"strategy {strategy.name} shares dense maps but the robot has no mesh link")
        self.team = TeamView(hal.robot_id, strategy)
        self.scheduler = Scheduler([
            Task("radio", rates.radio_hz, self._task_radio),
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
        self.local_map = LocalMap(self.p, pose.x_m, pose.y_m)
        self.topo = TopoMap(self.p.d_build_m, self.p.d_connect_m)
        self.explorer = Explorer(self.p, self.local_map, self.topo, self.team)
        self.follower = PathFollower(self.p, limits.max_v_mps, limits.max_omega_radps)
        self.status = "exploring"

    def tick(self, profiler: TaskProfiler | None = None) -> None:
        """Run the due tasks. A finished robot keeps its radio up: it still relays what it
        hears and sends what it has queued, like a real robot parked at its last goal."""
        self.ticks += 1
        self.scheduler.run_due(self.hal.clock.now_us(), profiler)

    # --- tasks ----------------------------------------------------------------------
    def _task_radio(self, now_us: int) -> None:
        if self.hal.mesh is not None and self.strategy.shares_dense_map:
            for message in self.hal.mesh.receive():
                self._on_keyframe(message)
        if self.link is None:
            return
        self.link.service(now_us, self.hal.radio)
        for _sender, rtype, v in self.link.received():
            if rtype == "topo":
                self.topo.add(tuple(v[f] for f in TOPO_FIELDS))
                if v["presence"]:
                    self.team.positions[v["sender_id"]] = (v["x_cm"] / 100.0, v["y_cm"] / 100.0)
            elif rtype == "pose":
                if v["done"]:
                    # A finished robot explores nothing more: MinPos must not count it.
                    self.team.positions.pop(v["sender_id"], None)
                else:
                    self.team.positions[v["sender_id"]] = (v["x_cm"] / 100.0, v["y_cm"] / 100.0)

    def _on_keyframe(self, message: bytes) -> None:
        kf = decode_keyframe(message)
        if kf is not None:
            self.local_map.integrate_keyframe(kf[1])

    def _task_lidar(self, now_us: int) -> None:
        scan: LidarScan | None = self.hal.lidar.latest_scan()
        if scan is None or self.done:
            return
        pose = self.hal.odometry.read()
        self.local_map.follow(pose.x_m, pose.y_m)
        self.local_map.integrate_scan(pose.x_m, pose.y_m, pose.yaw_rad, scan.angle_min_rad,
                                      scan.angle_increment_rad, scan.ranges_m, scan.range_max_m)
        self._last_scan = (pose.x_m, pose.y_m, pose.yaw_rad, scan)
        self.scans += 1

    def _binned_last_scan(self) -> BinnedScan:
        """The last scan in world-frame bins: binned only when asked (a stall, a dense
        baseline's keyframe), not at every scan."""
        x_m, y_m, yaw_rad, scan = self._last_scan
        return bin_scan(x_m, y_m, yaw_rad, scan.angle_min_rad, scan.angle_increment_rad, scan.ranges_m,
                        scan.range_max_m, self.p.keyframe_bins)

    def _task_control(self, now_us: int) -> None:
        if self.done:
            return
        pose = self.hal.odometry.read()
        self._maybe_add_vertex(pose.x_m, pose.y_m)
        if not self.follower.active and now_us - self._last_plan_us >= self.MIN_REPLAN_US:
            # The path ran out before the next planning slot: plan now instead of idling.
            self._task_planning(now_us)
            if self.done:
                return
        if self._stuck(pose):
            # Driving but not moving. If the LiDAR shows nothing touching ahead, something the
            # map let through (a gap narrower than it looks at 10 cm cells) is in the way: mark
            # it like a bumper would. If it does show something, the map has it already and
            # the path was cut too close past it: follow the next path closely instead. (A
            # bump there, 0.7 m wide, closed the only way out of a room of the Intel lab: one
            # robot, seed 3, ended at 48 % coverage.) Then replan.
            reach_m = self.p.robot_radius_m + self.p.resolution_m
            touching = something_within(self._binned_last_scan(), pose.yaw_rad, reach_m)
            if not touching:
                self.local_map.mark_obstacle_ahead(pose.x_m, pose.y_m, pose.yaw_rad, reach_m)
            self.bumps += 1
            self.follower.clear()
            if touching:
                self.follower.follow_closely(self.p.follow_closely_after_stall_m)
            self._task_planning(now_us)
            if self.done:
                return
        v, omega = self.follower.command(pose.x_m, pose.y_m, pose.yaw_rad)
        self._last_cmd_v = v
        self.hal.drive.command(v, omega)

    def _stuck(self, pose) -> bool:
        """Commanded forward for stuck_after_s but the wheels report no motion."""
        if self.p.stuck_after_s <= 0:
            return False
        if self._last_cmd_v > 0.1 and abs(pose.v_mps) < 0.02:
            self._stuck_ticks += 1
        else:
            self._stuck_ticks = 0
        if self._stuck_ticks >= self.p.stuck_after_s * self.rates.control_hz:
            self._stuck_ticks = 0
            return True
        return False

    def _task_planning(self, now_us: int) -> None:
        if self._last_scan is None or self.done:
            return
        pose = self.hal.odometry.read()
        self._last_plan_us = now_us
        plan = self.explorer.plan(pose.x_m, pose.y_m, now_us)
        self._report_information_changes()
        self._settle_team_places()
        if plan.done:
            self.follower.clear()
            self.hal.drive.command(0.0, 0.0)
            self.done = True
            self.status = "complete"
            if self.link is not None:
                self.link.enqueue("pose", {
                    "sender_id": self.hal.robot_id, "x_cm": round(pose.x_m * 100), "y_cm": round(pose.y_m * 100),
                    "yaw_cdeg": round(math.degrees((pose.yaw_rad + math.pi) % (2 * math.pi) - math.pi) * 100),
                    "speed_cmps": 0, "exploring": 0, "done": 1, "returning": 0,
                    "vertex_count": min(len(self.topo), 4095)}, PRIORITY_STATUS, key="pose")
            return
        self.follower.set_path(plan.path_xy)

    # --- the shared topological map ---------------------------------------------------
    def _vertex_information(self, extra_xy: tuple[float, float] | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(vertex indices, positions, e_inf in bits) of the places this robot visited, plus
        extra_xy (index -1): each waypoint's information counts at the closest one (eq. 4)."""
        idx = np.nonzero(self.topo.visited_by(self.hal.robot_id))[0] if len(self.topo) else np.zeros(0, np.int64)
        xy = self.topo.positions()[idx] if len(idx) else np.zeros((0, 2))
        if extra_xy is not None:
            idx = np.append(idx, -1)
            xy = np.vstack([xy, [extra_xy]])
        e = np.zeros(len(xy))
        items = self.explorer.waypoints.items
        if len(xy) and items:
            w = np.array([(it.x_m, it.y_m) for it in items])
            nearest = np.argmin((w[:, None, 0] - xy[None, :, 0]) ** 2 + (w[:, None, 1] - xy[None, :, 1]) ** 2, axis=1)
            np.add.at(e, nearest, [it.e_bit for it in items])
        return idx, xy, e

    def _publish(self, record: tuple[int, int, int, int, int, int, int], priority: int) -> None:
        """Own records go into the own map at once and onto the air if the team shares."""
        self.topo.add(record)
        if self.link is not None:
            self.link.enqueue("topo", dict(zip(TOPO_FIELDS, record)), priority)

    def _maybe_add_vertex(self, x_m: float, y_m: float) -> None:
        """A record (and a keyframe) every d_build of travel: where the robot has been, what
        it saw there, and the information it still expects around it (Table I)."""
        last = self._last_vertex_xy
        if last is not None and math.hypot(x_m - last[0], y_m - last[1]) < self.p.d_build_m:
            return
        if self._last_scan is None or self._last_plan_us < 0:
            return  # the record carries the information here, known only after a first plan
        if self.hal.mesh is not None and self.strategy.shares_dense_map:
            self.hal.mesh.broadcast(encode_keyframe(self.hal.robot_id, self._binned_last_scan()))
        _, _, e = self._vertex_information((x_m, y_m))
        # Passing a place again: this record speaks for the vertex it will join, so it has to
        # outrank what this robot said there before.
        version = 0
        near = self.topo.nearest(x_m, y_m)
        if near is not None and math.dist(self.topo.positions()[near], (x_m, y_m)) < self.p.d_build_m:
            version = min(MAX_INFO_VERSION, int(self.topo.word_of(self.hal.robot_id)[0][near]) + 1)
        self._publish((self.hal.robot_id, round(x_m * 100), round(y_m * 100), 0, 1, e_inf_bit_to_code(e[-1]), version),
                      PRIORITY_MOTION)
        self._last_vertex_xy = (x_m, y_m)

    def _report_information_changes(self) -> None:
        """A record when the information this robot holds at one of its vertices has moved
        clearly away from what it last said there: down (a waypoint there was covered or
        handed to a teammate) or up (it saw more from there). Each carries the next revision,
        so it replaces the robot's earlier word in every map, whatever the arrival order."""
        idx, xy, e = self._vertex_information()
        if not len(idx):
            return
        revision, said = self.topo.word_of(self.hal.robot_id)
        for k, (x, y), e_bit in zip(idx, xy, e):
            self._say_information(x, y, e_inf_bit_to_code(float(e_bit)), int(revision[k]), int(said[k]))

    def _settle_team_places(self) -> None:
        """A teammate's place that promised information (e_inf > 0) but where this robot's own
        map shows none, or that this robot reached, gets this robot's word: the information it
        holds there itself, usually none. A vertex takes the smallest of its senders' words,
        so one robot's "nothing here" spares the rest of the team the trip. Without it, a
        stale e_inf (its sender still holds a waypoint that teammates covered) draws every
        robot there in turn."""
        places = self.explorer.team_places_emptied
        self.explorer.team_places_emptied = []
        if not places:
            return
        xy = self.topo.positions()
        revision, said = self.topo.word_of(self.hal.robot_id)
        for x, y in places:
            k = self.topo.nearest(x, y)
            if k is None or math.dist(xy[k], (x, y)) > 0.01:
                continue
            code = e_inf_bit_to_code(float(self._vertex_information((x, y))[2][-1]))
            if self._say_information(x, y, code, int(revision[k]), int(said[k])):
                revision[k] += 1    # the same place may come twice in one batch
                said[k] = code

    def _say_information(self, x_m: float, y_m: float, code: int, revision: int, said: int) -> bool:
        """Send this robot's word `code` for the vertex at (x, y), with the next revision, if
        it is worth a record: the robot has no word there yet (revision -1), or the new one
        has moved clearly away from what it said (INFO_CODE_STEP, or down to zero). True if
        it was sent."""
        if revision >= MAX_INFO_VERSION:
            return False
        if revision >= 0 and (code == said or (code != 0 and abs(code - said) < INFO_CODE_STEP)):
            return False
        self._publish((self.hal.robot_id, round(x_m * 100), round(y_m * 100), 0, 0, code, revision + 1), PRIORITY_INFO)
        return True
