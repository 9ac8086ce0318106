"""The explorer firmware for one robot: setup() once, then tick() from the main loop.

It knows its robot only through the `Hal` it is given (ArduPilot's setup/loop shape, with
the HAL passed in rather than global), and its coordination only through the `Scheme` it
runs (firmware.schemes). This module is the task table and the wiring between the shared
services (firmware.services) and the scheme; every decision is made in one of those. Every
tick runs the tasks that are due:

    radio    20 Hz  link layer: hear records (the scheme's to the scheme, heartbeats to the
                    roster), send queued ones within the airtime budget
    heartbeat 0.1 Hz  queue this robot's heartbeat (pose, exploring or done), if it talks
    (the scheme's own tasks, if any)
    lidar    10 Hz  fold the newest scan into the local map (and move the window)
    control  20 Hz  tell the scheme of travel, follow the path (or drive a recovery), react
                    to stalls (back off, then plan again)
    planning  1 Hz  one planning cycle (services.planner), or finish
"""
from __future__ import annotations

import math

from firmware.comms.link import LinkLayer, TdmaSchedule
from firmware.params import ExplorationParams, TaskRates
from firmware.scheduler import Scheduler, Task, TaskProfiler
from firmware.schemes import all_dialects, build
from firmware.schemes.base import NEEDS, PRIORITY_STATUS, Scheme, Services
from firmware.services.deployment import Deployment
from firmware.services.local_map import BinnedScan, LocalMap, bin_scan, something_within
from firmware.services.motion import PathFollower, StallDetector
from firmware.services.planner import FrontiersLeft, Planner
from firmware.services.pose import SHARED_FRAME, PoseService
from firmware.services.recovery import BackOff, Recovery, Retrace, Track, clear_behind
from firmware.services.roster import Roster
from firmware.services.scan_match import ScanMatcher
from firmware.services.targets import TargetKeeper
from firmware.services.topo_map import TopoMap
from firmware.services.waypoints import WaypointSet
from hal.bundle import Hal
from hal.lora import RadioProfile
from hal.samples import LidarScan


# Stalls in a row at one spot, with the LiDAR showing the walls, after which the gap ahead is
# closed in the map (ExplorerAgent._on_stall).
STALLS_BEFORE_CLOSING_A_GAP = 3


class ExplorerAgent:
    MIN_REPLAN_US = 200_000  # event-triggered replanning is limited to 5 Hz

    def __init__(self, hal: Hal, params: ExplorationParams = ExplorationParams(),
                 rates: TaskRates = TaskRates(), scheme: Scheme | str = "bayer-faigl:greedy",
                 radio_profile: RadioProfile | None = None, team_size: int = 1,
                 deployment: Deployment | None = None) -> None:
        """scheme: a Scheme, or its registry spec (firmware.schemes). team_size: robots
        sharing the channel, with ids 0..team_size-1; it sizes the link layer's TDMA frame
        (one slot per robot) on profiles with a shared channel. deployment: what the team
        knew of the area before it started (services.deployment), for schemes that use it."""
        self.hal = hal
        self.p = params
        self.rates = rates
        self.scheme = build(scheme) if isinstance(scheme, str) else scheme
        self.deployment = deployment
        needs = self.scheme.needs_of()
        missing = [n for n in sorted(needs) if not self._has(n, radio_profile)]
        if missing:
            raise ValueError(f"scheme {self.scheme.spec} needs " + "; ".join(f"{n} ({NEEDS[n]})" for n in missing)
                             + f", which robot {hal.robot_id} does not have")
        self.done = False
        self.status = "starting"
        self.ticks = 0
        self.scans = 0
        self._last_scan: tuple[float, float, float, LidarScan] | None = None   # x_m, y_m, yaw_rad, scan
        self._last_plan_us = -10**12
        self.bumps = 0
        self._last_stall_xy: tuple[float, float] | None = None
        self._stalls_here = 0          # stalls in a row at the same spot
        self._bumps_forgotten = False  # the bumps were forgotten once, before the robot stopped
        self.link = (LinkLayer(hal.robot_id, radio_profile,
                               tdma=TdmaSchedule.for_team(radio_profile, team_size, hal.robot_id,
                                                          round(1_000_000 / rates.radio_hz)),
                               relay_hop_limit=self.scheme.relay_hops if "relay" in needs else 0,
                               dialect=self.scheme.dialect, dialects=all_dialects())
                     if "radio" in needs else None)
        self.scheduler = Scheduler([
            Task("radio", rates.radio_hz, self._task_radio),
            Task("lidar", rates.lidar_hz, self._task_lidar),
            Task("control", rates.control_hz, self._task_control),
            Task("planning", rates.planning_hz, self._task_planning),
        ])

    def _has(self, need: str, radio_profile: RadioProfile | None) -> bool:
        """Is `need` (schemes.base.NEEDS) met? A shared frame shows only in the odometry's
        samples, so setup() checks that one; a region map is the scheme's own, checked when it
        is attached."""
        hal = self.hal
        if need in ("radio", "relay"):
            return hal.has("radio") and radio_profile is not None
        if need == "floor_plan":
            return self.deployment is not None and self.deployment.navigable_m2 is not None
        return need in ("shared_frame", "region_map") or hal.has(need)

    # --- lifecycle --------------------------------------------------------------------
    def setup(self) -> None:
        self.pose = PoseService(self.hal.odometry)
        pose = self.pose.read()
        if "shared_frame" in self.scheme.needs_of() and pose.frame_id != SHARED_FRAME:
            raise ValueError(f"scheme {self.scheme.spec} needs shared_frame ({NEEDS['shared_frame']}), but robot "
                             f"{self.hal.robot_id}'s odometry reports frame {pose.frame_id!r}")
        limits = self.hal.drive.limits()
        if limits.robot_radius_m > self.p.robot_radius_m:
            raise ValueError(
                f"robot radius {limits.robot_radius_m} m exceeds the planner's robot_radius_m "
                f"{self.p.robot_radius_m} m: paths would scrape walls")
        self.local_map = LocalMap(self.p, pose.x_m, pose.y_m)
        self.localiser = ScanMatcher(self.p)
        self.topo = TopoMap(self.p.d_build_m, self.p.d_connect_m)
        self.waypoints = WaypointSet(self.p)
        self.roster = Roster(self.hal.robot_id, self.rates.roster_max_age_us)
        self.targets = TargetKeeper(self.p, self.waypoints)
        self.scheme.attach(Services(
            robot_id=self.hal.robot_id, params=self.p, rates=self.rates, local_map=self.local_map,
            waypoints=self.waypoints, topo=self.topo, roster=self.roster,
            send=self._send if self.link is not None else None, mesh=self.hal.mesh if self.hal.has("mesh") else None,
            last_scan_binned=self._binned_last_scan, has_planned=lambda: self._last_plan_us >= 0,
            queued=self.link.queued if self.link is not None else (lambda rtype: 0),
            withdraw=self.link.withdraw if self.link is not None else (lambda key: False),
            on_air_until_us=self.link.on_air_until_us if self.link is not None else (lambda: 0),
            radio_Bps=self.link.sustained_Bps() if self.link is not None else None,
            bytes_sent=self.link.bytes_sent if self.link is not None else (lambda: 0),
            missed_from=self.link.missed_from if self.link is not None else (lambda sender: []),
            keys_sent_in=self.link.keys_sent_in if self.link is not None else (lambda seq: ()),
            current_target=lambda: self.targets.target, pose_at=self.pose.pose_at,
            uwb=self.hal.uwb if self.hal.has("uwb") else None, aoa=self.hal.aoa if self.hal.has("aoa") else None,
            deployment=self.deployment, last_scan=lambda: self._last_scan))
        own_tasks = self.scheme.tasks()
        if self.link is not None:
            own_tasks.insert(0, Task("heartbeat", self.rates.heartbeat_hz, self._task_heartbeat))
        self.scheduler.tasks[1:1] = own_tasks   # after the radio task
        self.planner = Planner(self.p, self.local_map, self.topo, self.waypoints, self.targets, self.scheme)
        self.follower = PathFollower(self.p, limits.max_v_mps, limits.max_omega_radps)
        self.stall = StallDetector(self.p, self.rates.control_hz)
        self.recovery = Recovery(self.p, limits.max_v_mps, limits.max_omega_radps)
        self.stall_back_off = BackOff(min(self.p.min_speed_mps, limits.max_v_mps))
        self.stall_back_offs = 0
        self.track = Track(self.p.stall_retrace_m)
        self.retrace = Retrace(min(self.p.min_speed_mps, limits.max_v_mps), limits.max_omega_radps)
        self.stall_retraces = 0
        self.status = "exploring"

    def tick(self, profiler: TaskProfiler | None = None) -> None:
        """Run the due tasks. A finished robot keeps its radio up: it still relays what it
        hears and sends what it has queued, like a real robot parked at its last goal."""
        self.ticks += 1
        self.scheduler.run_due(self.hal.clock.now_us(), profiler)

    def sign_off(self, now_us: int) -> bool:
        """The robot is about to leave the team (its host ends the mission): queue its status
        heartbeat now, so that teammates hear it is done instead of waiting for it to fall
        silent. It goes out in the robot's next slot, with ticks as usual. False, and nothing
        queued, for a robot without a radio."""
        if self.link is None:
            return False
        self._send_heartbeat(self.pose.read())
        return True

    def radio_quiet(self, now_us: int) -> bool:
        """Nothing of this robot's waits to be sent and none of its frames is on the air at
        `now_us` (always, without a radio): what it queued, a sign-off among it, has gone."""
        return self.link is None or (self.link.queue_len == 0 and self.link.on_air_until_us() <= now_us)

    @property
    def settled(self) -> bool:
        """Finished, and nothing left that its scheme has to tell the team."""
        return self.done and not self.scheme.has_news()

    def stats(self) -> dict[str, int]:
        """How this robot's targets ended, the frontiers it stopped short of (0 while it
        explores: those it gave up on, and those behind gaps narrower than its body), its
        bumps, its drives back across ways its map closed, and the scheme's own counters."""
        c = self.targets.counts
        return {"targets_reached": c["reached"], "targets_seen_on_way": c["seen_on_way"],
                "targets_unreachable": c["unreachable"], "targets_stalled": c["stalled"],
                "unreachable_frontiers": len(self.planner.frontiers.given_up),
                "narrow_gap_frontiers": len(self.planner.frontiers.behind_gaps),
                **self.recovery.counts, **self.scheme.stats(), "bumps": self.bumps,
                "stall_back_offs": self.stall_back_offs, "stall_retraces": self.stall_retraces,
                "ways_back": self.planner.ways_back,
                "scan_matches": self.localiser.matches, "scan_corrections": self.localiser.corrections}

    def pose_estimate(self) -> tuple[float, float, float] | None:
        """Where this robot believes it is (x_m, y_m, yaw_rad), as of its last pose reading."""
        pose = getattr(self, "pose", None)
        return None if pose is None else pose.latest()

    def frontiers_left(self) -> FrontiersLeft:
        """What this robot left behind when it stopped (empty while it explores)."""
        return self.planner.frontiers

    def memory_bytes(self) -> dict[str, int]:
        return {"local_map_bytes": int(self.local_map.logodds.nbytes),
                "paged_out_bytes": int(self.local_map.pager.nbytes)}

    # --- tasks ----------------------------------------------------------------------
    def _send(self, rtype: str, values, priority: int, key=None) -> bool:
        return self.link.enqueue(rtype, values, priority, key=key)

    def _task_radio(self, now_us: int) -> None:
        if self.link is None:
            return
        self.link.service(now_us, self.hal.radio)
        for _sender, rtype, v in self.link.received():
            if rtype in self.scheme.records:
                self.scheme.on_record(rtype, v, now_us)
            elif rtype == "pose":
                self.roster.heard_status(v["sender_id"], v["x_cm"] / 100.0, v["y_cm"] / 100.0, v["done"], now_us)

    def _task_heartbeat(self, now_us: int) -> None:
        self._send_heartbeat(self.pose.read())

    def _send_heartbeat(self, pose) -> None:
        """This robot's pose and status; a newer one replaces one still queued."""
        self.link.enqueue("pose", {
            "sender_id": self.hal.robot_id, "x_cm": round(pose.x_m * 100), "y_cm": round(pose.y_m * 100),
            "yaw_cdeg": round(math.degrees((pose.yaw_rad + math.pi) % (2 * math.pi) - math.pi) * 100),
            "speed_cmps": min(255, round(abs(pose.v_mps) * 100)) if not self.done else 0,
            "exploring": int(self.targets.target is not None and not self.done), "done": int(self.done),
            "returning": 0, "vertex_count": min(len(self.topo), 4095)}, PRIORITY_STATUS, key="pose")

    def _task_lidar(self, now_us: int) -> None:
        scan: LidarScan | None = self.hal.lidar.latest_scan()
        if scan is None or self.done:
            return
        pose = self.pose.read()
        # The pose when the scan was taken, not now: a LiDAR's scans arrive on its own clock.
        # The slip check weighs the wheels' own travel against the scans': a correction
        # localisation made between two scans is no travel the wheels counted.
        odometry_x_m, odometry_y_m, odometry_yaw_rad = self.pose.odometry_at(scan.stamp_us)
        held_at = self.stall.on_scan(odometry_x_m, odometry_y_m, odometry_yaw_rad, scan.angle_min_rad,
                                     scan.angle_increment_rad, scan.ranges_m, scan.range_max_m)
        x_m, y_m, yaw_rad = self.pose.corrected(odometry_x_m, odometry_y_m, odometry_yaw_rad)
        if held_at is not None:
            # The wheels slipped: the body is behind where odometry puts it.
            x_m, y_m, yaw_rad = self.pose.corrected(*held_at, odometry_yaw_rad)
            self.pose.correct_at(scan.stamp_us, x_m, y_m, yaw_rad)
            pose = self.pose.read()
        self.local_map.follow(pose.x_m, pose.y_m)
        if self.localiser.due(x_m, y_m, yaw_rad):
            found = self.localiser.match(self.local_map, x_m, y_m, yaw_rad, scan.angle_min_rad,
                                         scan.angle_increment_rad, scan.ranges_m, scan.range_max_m)
            if found is not None:
                self.pose.correct_at(scan.stamp_us, *found)
                x_m, y_m, yaw_rad = found
        self.local_map.integrate_scan(x_m, y_m, yaw_rad, scan.angle_min_rad,
                                      scan.angle_increment_rad, scan.ranges_m, scan.range_max_m)
        self._last_scan = (x_m, y_m, yaw_rad, scan)
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
        pose = self.pose.read()
        wheels = self.pose.odometry_at(pose.stamp_us)      # the way back is the wheels' own
        if not self.retrace.active:
            self.track.add(wheels[0], wheels[1])
        self.scheme.on_travel(pose, now_us)
        self.local_map.mark_trail(pose.x_m, pose.y_m)
        if self.recovery.active:
            cmd = self.recovery.command(pose.x_m, pose.y_m, pose.yaw_rad, now_us)
            if cmd is not None:
                self.hal.drive.command(*cmd)
                return
            # Recovered: retry on tight, slow paths, starting now.
            self.planner.tight_until_us = now_us + int(self.p.recovery_retry_s * 1e6)
            self._task_planning(now_us)
            if self.done:
                return
        if now_us < self.planner.tight_until_us or self.local_map.in_passage_at(pose.x_m, pose.y_m):
            self.local_map.mark_passed(pose.x_m, pose.y_m)
        if not self.follower.active and now_us - self._last_plan_us >= self.MIN_REPLAN_US:
            # The path ran out before the next planning slot: plan now instead of idling.
            self._task_planning(now_us)
            if self.done:
                return
        if self.stall.stuck(pose.v_mps):
            self._on_stall(pose, wheels, now_us)
            self._task_planning(now_us)
            if self.done:
                return
        cmd = self.stall_back_off.command(pose.x_m, pose.y_m, now_us)
        if cmd is None and self.retrace.active:
            cmd = self.retrace.command(*wheels, now_us)
            if cmd is None:
                # Out of where it was held: plan from here, not from there.
                self._task_planning(now_us)
                if self.done:
                    return
        v, omega = cmd if cmd is not None else self.follower.command(pose.x_m, pose.y_m, pose.yaw_rad)
        self.stall.commanded(v)
        self.hal.drive.command(v, omega)

    def _on_stall(self, pose, wheels: tuple[float, float, float], now_us: int) -> None:
        """Driving but not moving. First back off stall_back_off_m where the last scan shows
        room behind: pressing on stops (a real drive strains, its wheels dig in or slip), and
        the next try starts clear of what held it. Without room straight behind (wedged, held
        on both sides) it drives stall_retrace_m back the way it came, then plans from there:
        a path the planner draws out of a gap as wide as the body, on a pose a few centimetres
        off, presses the body into a side of it. If the LiDAR shows nothing touching
        ahead, something the map let through (a gap narrower than it looks at 10 cm cells)
        is in the way: mark it like a bumper would. If it does show something, the map has
        it already and the path was cut too close past it: follow the next path closely
        instead. (A bump there, 0.7 m wide, closed the only way out of a room of the Intel
        lab: one robot, seed 3, ended at 48 % coverage.) Stalled there
        STALLS_BEFORE_CLOSING_A_GAP times in a row, it marks the bump all the same: the gap
        is narrower than the map shows. wheels: odometry's own pose now (the track's frame)."""
        reach_m = self.p.robot_radius_m + self.p.resolution_m
        touching = something_within(self._binned_last_scan(), pose.yaw_rad, reach_m)
        again = self._last_stall_xy is not None and \
            math.hypot(pose.x_m - self._last_stall_xy[0], pose.y_m - self._last_stall_xy[1]) < self.p.resolution_m
        self._stalls_here = self._stalls_here + 1 if again else 1
        self._last_stall_xy = (pose.x_m, pose.y_m)
        # Following closely did not get the body past: the gap ahead is narrower than the map
        # shows (the planner lets a path through where the body fits only if the walls lie at
        # the far side of their cells); close it like a bumper would.
        wedged = self._stalls_here >= STALLS_BEFORE_CLOSING_A_GAP
        if not touching or wedged:
            self.local_map.mark_obstacle_ahead(pose.x_m, pose.y_m, pose.yaw_rad, reach_m)
        self.bumps += 1
        self.follower.clear()
        if self.p.stall_back_off_m > 0 and self._room_behind(pose, self.p.stall_back_off_m):
            self.stall_back_off.start(pose.x_m, pose.y_m, self.p.stall_back_off_m, now_us)
            self.stall_back_offs += 1
        elif self.p.stall_retrace_m > 0:
            way = self.track.take_way_back(self.p.stall_retrace_m)
            if len(way):
                self.retrace.start(way, *wheels, now_us)
                self.stall_retraces += 1
        if touching and not wedged:
            self.follower.follow_closely(self.p.follow_closely_after_stall_m)

    def _task_planning(self, now_us: int) -> None:
        if self._last_scan is None or self.recovery.active:
            return
        if self.done:
            if not self.scheme.wake_up(now_us):
                return
            self.done, self.status = False, "exploring"
        pose = self.pose.read()
        self._last_plan_us = now_us
        plan = self.planner.plan(pose.x_m, pose.y_m, now_us)
        self.scheme.after_plan(pose, now_us)
        if plan.done and self.local_map.bumps and not self._bumps_forgotten:
            # Gaps closed by bumps may have held the body back only because the path met
            # them askew (a drifting pose, a jamb cut close): before it stops, the robot forgets
            # them once and tries what lies behind them again. A gap the body really does not
            # fit closes again after its stalls there.
            self._bumps_forgotten = True
            self.local_map.forget_bumps()
            self._last_stall_xy, self._stalls_here = None, 0
            return
        if plan.done:
            self.follower.clear()
            self.hal.drive.command(0.0, 0.0)
            self.done = True
            self.scheme.on_finished(self.planner.frontiers.middles_xy(self.p.resolution_m))
            # Nothing left that this robot can get to; say so if it gave up on frontiers its
            # body could reach (frontiers behind gaps narrower than the body are no way on).
            self.status = "complete_with_unreachable_frontiers" if self.planner.frontiers.given_up else "complete"
            if self.link is not None:
                self._send_heartbeat(pose)
            return
        if plan.recover:
            self._start_recovery(pose)
            return
        self.follower.set_path(plan.path_xy, plan.clearance_m, slow=plan.slow)

    def _start_recovery(self, pose) -> None:
        """A target failed for the first time: back off if the last scan shows room behind,
        turn once on the spot, then plan again (services.recovery)."""
        self.targets.recovery_started()
        self.follower.clear()
        self.recovery.start(self._room_behind(pose, self.p.recovery_back_off_m))

    def _room_behind(self, pose, distance_m: float) -> bool:
        """The last scan shows nothing in the strip the body sweeps backing up distance_m."""
        half_width_m = self.p.robot_radius_m + self.p.lethal_tolerance_m
        return clear_behind(self._binned_last_scan(), pose.yaw_rad, distance_m, half_width_m)
