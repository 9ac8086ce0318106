"""The mission runner: the simulator's main loop, in lockstep with the firmware.

Per tick of the firmware's task table: every robot's firmware runs once at the current
mission time, then the world advances by one tick (bodies, sensors) and the radio channel
resolves what ended on the air. Only this loop moves time, so a mission is a pure
function of its configuration and seed.
"""
from __future__ import annotations

import dataclasses
import hashlib
import math
import time
from dataclasses import dataclass, field
from typing import Callable, NamedTuple

import numpy as np

from firmware.agent import ExplorerAgent
from firmware.params import ExplorationParams, TaskRates
from firmware.scheduler import TaskProfiler
from firmware.services.deployment import Deployment
from firmware.services.planner import FrontiersLeft
from firmware.schemes import Settings, build as build_scheme
from hal.lora import profile as radio_profile
from hal.sim.clock import SimClock
from hal.sim.factory import build_sim_hal
from hal.sim.mesh import SimMeshBus
from hal.sim.radio import SimRadioModem
from host_tools import merge_metrics, polygon_metrics, region_oracle
from host_tools.capture import CaptureWriter
from host_tools.cmd_inspect import sender_stats
from radio_sim.air_log import AirFrame
from radio_sim.channel import Channel
from radio_sim.virtual_modem import open_serial_radios
from world_sim.devices.lockstep import open_serial_sensors
from world_sim.map_spec import Pose, resolve_map, spread_poses, staging_poses
from world_sim.ros_map import reachable_from_starts
from world_sim.seeding import stream
from world_sim.world import World, WorldParams

COVERAGE_SAMPLE_US = 1_000_000


class Failure(NamedTuple):
    """A robot that fails (world_sim World.power_off): at a mission time, or when the team
    has seen a share of the reachable area (checked once per simulated second)."""

    robot: int
    at_s: float | None = None
    at_coverage: float | None = None


# `--fail random` (../shared/schemes/wiserx.md A23): a robot drawn uniformly fails when the
# team first sees a share of the area drawn uniformly in this range, both from the mission seed.
DRAWN = Failure(-1)
DRAWN_COVERAGE = (0.5, 0.7)


def drawn_failures(failures: tuple[Failure, ...], seed: int, robots: int) -> tuple[Failure, ...]:
    """The failures with DRAWN replaced by the robot and moment the seed draws (its own
    stream, "failure": the same seed, the same failure, whatever the scheme)."""
    if DRAWN not in failures:
        return failures
    if len(failures) > 1:
        raise ValueError("failures (--fail): random draws the failing robot; give it alone")
    rng = stream(seed, "failure")
    robot = int(rng.integers(robots))
    return (Failure(robot, at_coverage=round(float(rng.uniform(*DRAWN_COVERAGE)), 4)),)


@dataclass(frozen=True)
class MissionConfig:
    map_spec: str = "cave:1"
    robots: int = 1
    seed: int = 0
    max_sim_s: float = 14400.0
    radio: str = "ideal-100Bps"
    strategy: str = "greedy"
    # Start poses (x_m, y_m, yaw_rad or None for the map's yaw): none, the map's start; one, a
    # staging area around it (the team's common start, as Bayer & Faigl's robots start); one
    # per robot, exactly those. The robots' odometry starts from these poses, so they share
    # one frame, as a team that measured its start poses at deployment does.
    starts: tuple[tuple[float, float, float | None], ...] = ()
    # The robots' odometry frame: "shared" (start poses measured at deployment) or each
    # robot's "own" (origin at its own start, unknown to the others; the host keeps the truth).
    frames: str = "shared"
    # Spread starts (issue 25 item 1), instead of `starts`: with spread_m > 0, every robot
    # starts at least this far (driving distance) from every other, with a random yaw, and
    # with spread_max_m > 0 at most that far from the nearest one placed before it
    # (world_sim.map_spec.spread_poses, from the mission seed). The start poses, and so the
    # relations of the robots' own frames, are known to the host only (MissionResult.start_poses).
    spread_m: float = 0.0
    spread_max_m: float = 0.0
    serial_radio: bool = False          # every robot's radio through a virtual RN2483 on a pty
    serial_lidar: bool = False          # every robot's LiDAR through an emulated RPLIDAR on a pty
    serial_uwb: bool = False            # every robot's UWB through an emulated DWM1001 on a pty
    capture_path: str | None = None     # record every frame on the air (JSON Lines capture)
    # The simulated world's wheels and LiDAR (WorldParams.with_slip_and_lidar_phase): the share
    # of commanded wheel travel the encoders report while a wall holds the body, and the
    # LiDAR's first scan this long after the start (then one a period, between the ticks).
    wheel_slip_frac: float = 0.0
    lidar_phase_ms: float = 0.0
    # A hard radio range in metres on top of the profile (radio_sim.channel.Channel's
    # max_range_m: the ideal link's disc model); None: the profile's own reach.
    range_m: float | None = None
    # Robots that fail: from then on the robot does nothing at all (world_sim World.power_off);
    # the others go on. Robots with a slower drive (robot index, share of the speed and
    # turn-rate limits in (0, 1]); their firmware is not told.
    failures: tuple[Failure, ...] = ()
    speed_factors: tuple[tuple[int, float], ...] = ()
    # Once every robot has settled, the radios go on this long before the mission ends (the
    # robots keep ticking, parked; one that wakes up carries the mission on): records still
    # on their way arrive, so every robot's view of the team's shared state can be compared
    # at the end. Not part of t_total_s nor of radio_stats' frames, bytes and rates
    # (MissionResult.flush has its own); the link layer's counters in radio_stats include it.
    flush_s: float = 0.0

    def __post_init__(self) -> None:
        for name, pairs in (("failures (--fail)", self.failures), ("speed_factors (--slow)", self.speed_factors)):
            robots = [pair[0] for pair in pairs]
            for r in robots:
                if not 0 <= r < self.robots:
                    raise ValueError(f"{name}: robot {r} is not in the team of {self.robots} (--robots; robots 0.."
                                     f"{self.robots - 1})")
            if len(set(robots)) != len(robots):
                raise ValueError(f"{name}: robot {sorted(r for r in robots if robots.count(r) > 1)[0]} given twice")
        for f in self.failures:
            if (f.at_s is None) == (f.at_coverage is None):
                raise ValueError(f"failures (--fail): robot {f.robot} needs a time or a coverage, not both or neither")
            if f.at_s is not None and not 0.0 <= f.at_s <= self.max_sim_s:
                raise ValueError(f"failures (--fail): robot {f.robot} at {f.at_s:g} s is after the mission's end "
                                 f"(--max-sim-s {self.max_sim_s:g})")
            if f.at_coverage is not None and not 0.0 < f.at_coverage <= 1.0:
                raise ValueError(f"failures (--fail): robot {f.robot} at coverage {f.at_coverage:g}: must be in (0, 1]")
        if not 0.0 <= self.flush_s <= self.max_sim_s:
            raise ValueError(f"flush_s (--flush-s) {self.flush_s:g} s: must be in [0, --max-sim-s {self.max_sim_s:g}]")


@dataclass
class MissionResult:
    config: MissionConfig
    map_label: str
    coverage: float
    path_length_m: list[float]
    t_total_s: float                # the last robot still running stopped (for good) then
    t_90_s: float | None
    termination: str
    wall_s: float
    sim_s: float
    ticks: int
    robots_in_wall: int
    blocked_moves: list[int]
    longest_push_s: list[float]
    trajectory_sha256: str
    reachable_area_m2: float
    robot_status: list[str]
    overlap: float
    radio: dict
    air_log_sha256: str
    coverage_raw: float = math.nan   # against the raw 4-connected component, slivers included
    # Per robot: how far its own pose estimate was from the truth when last sampled, and at
    # worst (sampled once per simulated second).
    pose_error_m: list[float] = field(default_factory=list)
    pose_error_max_m: list[float] = field(default_factory=list)
    start_poses: list[Pose] = field(default_factory=list)      # (x_m, y_m, yaw_rad) per robot
    # For plots (not in the JSON).
    trajectories: list[np.ndarray] = field(repr=False, default_factory=list)
    world: object = field(repr=False, default=None)
    agents: list = field(repr=False, default_factory=list)
    reachable: np.ndarray | None = field(repr=False, default=None)
    air_frames: list[AirFrame] = field(repr=False, default_factory=list)   # every transmission
    polygon_maps: dict | None = None     # schemes with polygon maps: host_tools.polygon_metrics.report
    frame_merges: dict | None = None     # schemes that merge frames: host_tools.merge_metrics
    failed_at_s: dict[int, float] = field(default_factory=dict)   # robot -> when it failed (MissionConfig.failures)
    # Per robot: the share of the reachable area its own LiDAR observed (a slow robot's share
    # against the others', issue 24).
    observed_share: list[float] = field(default_factory=list)
    # With failures: the share of the reachable area the robots still running at the end saw
    # (a failed robot's map is lost with it), and per failed robot the share of the area only
    # it had seen when it failed, and how much of that the survivors saw by the end.
    coverage_survivors: float | None = None
    lost_at_failure: dict[int, float] = field(default_factory=dict)
    recovered: dict[int, float | None] = field(default_factory=dict)
    # With a flush phase (MissionConfig.flush_s): per robot, frames and bytes it sent in it.
    flush: dict | None = None
    # When, after t_total_s, no robot had anything left to tell the team (Scheme.has_news:
    # records waiting or on the air, a teammate's summary showing it lacking some): the
    # mission proper ends then, and the radio's figures cover it; the flush comes after.
    settled_s: float | None = None

    @property
    def sim_speedup(self) -> float:
        return self.sim_s / self.wall_s if self.wall_s > 0 else math.inf

    def explorer_stats(self) -> dict[str, list[int]]:
        """Per robot: how its targets ended (reached, seen from close by on the way, dropped
        as unreachable or stalled), waypoints cancelled by teammates' presence and shared-map
        targets found stale in its own map (both counted per planning cycle: a place counts
        again each cycle it is found again), and obstacles it bumped into."""
        per_robot = [a.stats() for a in self.agents]
        keys = sorted({k for s in per_robot for k in s})
        return {k: [s.get(k, 0) for s in per_robot] for k in keys}

    def scheme_digests(self) -> list[dict[str, str]]:
        """Per robot, its scheme's digests of the team's shared state (Scheme.digests)."""
        return [a.scheme.digests() for a in self.agents]

    def to_json(self) -> dict:
        digests = self.scheme_digests()
        running = [d for d, status in zip(digests, self.robot_status) if status != "failed"]
        return {
            "map": self.map_label,
            "seed": self.config.seed,
            "robots": self.config.robots,
            "radio": self.config.radio,
            "range_m": self.config.range_m,
            "strategy": self.config.strategy,
            "frames": self.config.frames,
            **({"failures": [{**{k: v for k, v in f._asdict().items() if v is not None},
                              "failed_at_s": self.failed_at_s.get(f.robot),
                              "lost_at_failure": _rounded(self.lost_at_failure.get(f.robot)),
                              "recovered": _rounded(self.recovered.get(f.robot))} for f in self.config.failures],
                "coverage_survivors": _rounded(self.coverage_survivors)}
               if self.config.failures else {}),
            **({"speed_factors": {str(r): f for r, f in self.config.speed_factors}}
               if self.config.speed_factors else {}),
            **({"spread_m": [self.config.spread_m, self.config.spread_max_m]} if self.config.spread_m > 0 else {}),
            "world": {"wheel_slip_frac": self.world.params.wheel_slip_frac,
                      "lidar_phase_us": self.world.params.lidar_phase_us},
            "coverage": round(self.coverage, 6),
            "coverage_raw_component": round(self.coverage_raw, 6),
            "overlap": round(self.overlap, 6),
            "observed_share": [round(s, 6) for s in self.observed_share],
            "path_length_m": [round(p, 3) for p in self.path_length_m],
            "start_poses": [[round(x, 3), round(y, 3), round(yaw, 4)] for x, y, yaw in self.start_poses],
            "t_total_s": round(self.t_total_s, 3),
            "settled_s": None if self.settled_s is None else round(self.settled_s, 3),
            "t_90_s": None if self.t_90_s is None else round(self.t_90_s, 3),
            "termination": self.termination,
            "robot_status": self.robot_status,
            "unreachable_frontiers": [len(a.frontiers_left().given_up) for a in self.agents],
            "unreachable_frontier_area_m2": [round(FrontiersLeft.area_m2(a.frontiers_left().given_up), 2)
                                             for a in self.agents],
            "narrow_gap_frontiers": [len(a.frontiers_left().behind_gaps) for a in self.agents],
            "narrow_gap_frontier_area_m2": [round(FrontiersLeft.area_m2(a.frontiers_left().behind_gaps), 2)
                                            for a in self.agents],
            "reachable_area_m2": round(self.reachable_area_m2, 2),
            "robots_in_wall": self.robots_in_wall,
            "pose_error_m": [round(e, 3) for e in self.pose_error_m],
            "pose_error_max_m": [round(e, 3) for e in self.pose_error_max_m],
            "blocked_moves": self.blocked_moves,
            "longest_push_s": self.longest_push_s,
            "ticks": self.ticks,
            "trajectory_sha256": self.trajectory_sha256,
            "air_log_sha256": self.air_log_sha256,
            "radio_stats": self.radio,
            "explorer_stats": self.explorer_stats(),
            **({"polygon_maps": self.polygon_maps} if self.polygon_maps is not None else {}),
            **({"frame_merges": self.frame_merges} if self.frame_merges is not None else {}),
            # Equal on two robots exactly when they hold the same shared state; "agree": every
            # robot still running holds the same.
            **({"scheme_digests": {"per_robot": digests, "agree": all(d == running[0] for d in running)}}
               if any(digests) else {}),
            **({"flush": self.flush} if self.flush is not None else {}),
            # Wall-clock figures: the only keys that differ between identical runs.
            "wall_s": round(self.wall_s, 3),
            "sim_speedup": round(self.sim_speedup, 2),
            "ticks_per_s": round(self.ticks / self.wall_s, 1) if self.wall_s > 0 else None,
        }


WALL_TIME_KEYS = ("wall_s", "sim_speedup", "ticks_per_s")


def _rounded(x: float | None) -> float | None:
    return None if x is None else round(x, 6)


def _seen_by(world: World, robots: list[int], reachable: np.ndarray) -> np.ndarray:
    """The reachable cells any of `robots` has observed."""
    seen = np.zeros_like(reachable)
    for j in robots:
        seen |= world.observed(j)
    return seen & reachable


def air_log_digest(air_frames: list[AirFrame]) -> str:
    """SHA-256 over every transmission: when, who, what (the transmit log of DESIGN.md)."""
    h = hashlib.sha256()
    for a in air_frames:
        h.update(f"{a.start_us},{a.end_us},{a.sender_id},{len(a.payload)};".encode())
        h.update(a.payload)
    return h.hexdigest()


def radio_metrics(air_frames: list[AirFrame], channel: Channel, agents: list, mesh: SimMeshBus, now_us: int) -> dict:
    """What the team put on the air and what became of it, per robot where it is per robot."""
    n = len(agents)
    profile = channel.profile
    stats = sender_stats(air_frames, profile, duration_us=max(now_us, 1))
    per = [stats.get(i) for i in range(n)]
    fates: dict[str, int] = {}
    for a in air_frames:
        for r in a.receptions:
            fates[r.fate] = fates.get(r.fate, 0) + 1
    violations = 0
    duty = []
    for st in per:
        worst = 0.0
        if st is not None:
            for sb, use in st.duty_cycle_max_by_sub_band.items():
                limit = st.duty_cycle_limit_by_sub_band.get(sb)
                worst = max(worst, use)
                if limit is not None and use > limit + 1e-12:
                    violations += 1
        duty.append(round(worst, 6))
    counters = [a.link.counters if a.link is not None else {} for a in agents]
    return {
        "profile": profile.name,
        "frames_sent": [st.frames if st else 0 for st in per],
        "bytes_sent": [st.bytes if st else 0 for st in per],
        "bytes_per_s_mean": [round(st.bytes_per_s, 3) if st else 0.0 for st in per],
        "bytes_per_s_peak_10s": [round(st.peak_bytes_per_s_10s, 3) if st else 0.0 for st in per],
        "airtime_fraction": [round(st.airtime_us / max(now_us, 1), 6) if st else 0.0 for st in per],
        "duty_cycle_worst_hour": duty,
        "duty_cycle_violations": violations,
        "records_sent": [c.get("sent.records", 0) for c in counters],
        "deferred_duty_cycle": [c.get("deferred.duty_cycle", 0) for c in counters],
        "deferred_rate_cap": [c.get("deferred.rate_cap", 0) for c in counters],
        "deferred_slot": [c.get("deferred.slot", 0) for c in counters],
        "dropped_queue_full": [c.get("dropped.queue_full", 0) for c in counters],
        "receptions": dict(sorted(fates.items())),
        "mesh_bytes_sent": [mesh.bytes_sent.get(i, 0) for i in range(n)],
    }


def run_mission(cfg: MissionConfig, progress: Callable[[float, float], None] | None = None,
                profiler: TaskProfiler | None = None,
                params: ExplorationParams = ExplorationParams(),
                scheme_settings: Settings = (),
                rates: TaskRates = TaskRates(),
                world_params: WorldParams = WorldParams(),
                should_stop: Callable[[], bool] | None = None,
                loss_rule: Callable[[int, int, bytes], bool] | None = None,
                observer: Callable[[int, list[ExplorerAgent]], None] | None = None) -> MissionResult:
    """One mission to completion, the time limit, or until `should_stop()` (asked once per
    tick) says so: then it ends there, with termination "interrupted", and the result holds
    everything up to that tick. scheme_settings: the scheme's own parameters changed
    (`--set SCHEME.NAME=VALUE`, firmware.schemes.build). world_params: the simulated world's
    physics, with the wheels' slip and the LiDAR's phase taken from cfg. loss_rule
    (radio_sim.channel.Channel) loses chosen receptions; observer is called with the mission
    time and the agents once per simulated second (tests)."""
    occ, start, label = resolve_map(cfg.map_spec)
    if cfg.spread_m > 0 and cfg.starts:
        raise ValueError("give start poses or spread starts, not both")
    poses = (spread_poses(occ, start, cfg.robots, cfg.spread_m, cfg.spread_max_m, cfg.seed,
                          body_m=world_params.robot_radius_m) if cfg.spread_m > 0
             else start_poses(occ, start, cfg.starts, cfg.robots))
    world = World(occ, poses, cfg.seed, world_params.with_slip_and_lidar_phase(cfg.wheel_slip_frac, cfg.lidar_phase_ms))
    for i, factor in cfg.speed_factors:
        world.set_speed_factor(i, factor)
    # Scored against the free area a robot body can reach from the starts (see reachable_free);
    # the figure against the raw 4-connected free component is reported too.
    reachable = reachable_from_starts(occ, poses, robot_radius_m=world_params.robot_radius_m)
    reachable_raw = reachable_from_starts(occ, poses)
    profile = radio_profile(cfg.radio)
    channel = Channel(profile, cfg.seed, occupancy=occ, loss_rule=loss_rule, max_range_m=cfg.range_m)
    air_frames: list[AirFrame] = []
    channel.add_sink(air_frames.append)
    capture = None
    if cfg.capture_path is not None:
        capture = CaptureWriter(cfg.capture_path, profile.name,
                                meta={"map": label, "seed": cfg.seed, "robots": cfg.robots, "strategy": cfg.strategy})
        channel.add_sink(capture.write)
    mesh = SimMeshBus()
    clock = SimClock(world)
    for i in range(cfg.robots):
        channel.attach(i, lambda i=i: world.true_pose(i)[:2])
    bank = sensors = None
    completed = False
    try:
        if cfg.serial_radio:
            bank, radios = open_serial_radios(channel, profile, clock, list(range(cfg.robots)))
        else:
            radios = [SimRadioModem(channel, i, clock) for i in range(cfg.robots)]
        if cfg.serial_lidar or cfg.serial_uwb:
            sensors, lidars, rangers = open_serial_sensors(world, clock, lidar=cfg.serial_lidar, uwb=cfg.serial_uwb)
        agents = []
        doorways = None         # the ground truth's, for schemes that load a region map
        for i in range(cfg.robots):
            scheme = build_scheme(cfg.strategy, scheme_settings)
            if "region_map" in scheme.needs_of():
                if doorways is None:
                    doorways = region_oracle.doorways(occ, params)
                scheme.load_region_map(doorways)
            hal = build_sim_hal(world, i, radio=radios[i], frame=cfg.frames)
            if cfg.serial_lidar:
                hal = dataclasses.replace(hal, lidar=lidars[i])
            if cfg.serial_uwb:
                hal = dataclasses.replace(hal, uwb=rangers[i])
            if "mesh" in scheme.needs_of():
                hal = dataclasses.replace(hal, mesh=mesh.endpoint(i))
            agent = ExplorerAgent(hal, params, rates, scheme, profile, team_size=cfg.robots,
                                  deployment=deployment(occ, reachable, poses[i], cfg.frames, cfg.robots))
            agent.setup()
            agents.append(agent)
        sampler = polygon_metrics.ErrorSampler() if polygon_metrics.has_polygons(agents) else None
        if sampler is not None:
            observer = _observers(sampler, observer)
        merges = merge_metrics.MergeSampler(poses, cfg.frames) if merge_metrics.has_frame_merges(agents) else None
        if merges is not None:
            observer = _observers(merges, observer)
        result = _loop(cfg, label, occ, world, channel, bank, sensors, agents, reachable, air_frames, mesh,
                       progress, profiler, rates, should_stop, observer)
        if sampler is not None:
            result.polygon_maps = polygon_metrics.report(agents, sampler, result.sim_s)
        if merges is not None:
            merges(world.now_us, agents)
            result.frame_merges = merges.report()
        result.coverage_raw = float((world.observed_union() & reachable_raw).sum()) / int(reachable_raw.sum())
        result.start_poses = poses
        completed = True
        return result
    finally:
        if bank is not None:
            bank.close()                    # closes the radios too
        if sensors is not None:
            sensors.close()                 # closes the LiDAR and UWB drivers too
        if capture is not None:
            # A mission that ended (an interrupted one too) puts its capture in place; one that
            # failed leaves the file that was there before.
            if completed:
                capture.close()
            else:
                capture.abort()


# Deployment knowledge (services.deployment) comes as navigable area per square of this side.
PLAN_CELL_M = 1.0


def _observers(first: Callable[[int, list[ExplorerAgent]], None],
               then: Callable[[int, list[ExplorerAgent]], None] | None) -> Callable[[int, list[ExplorerAgent]], None]:
    """One mission observer that calls first, then (if any) then."""
    def observer(now_us: int, agents: list[ExplorerAgent]) -> None:
        first(now_us, agents)
        if then is not None:
            then(now_us, agents)
    return observer


def deployment(occ, reachable: np.ndarray, start: Pose, frames: str, robots: int) -> Deployment:
    """What a robot is told before it starts (services.deployment): the map's bounding box,
    the area its body can reach per PLAN_CELL_M square (a coarse floor plan), and where its
    odometry frame lies in the map's: the identity with frames "shared", its start pose with
    frames "own"."""
    res = occ.resolution_m
    n_r = math.ceil(occ.height_m / PLAN_CELL_M - 1e-9)
    n_c = math.ceil(occ.width_m / PLAN_CELL_M - 1e-9)
    rows, cols = np.nonzero(reachable)
    area = np.zeros((n_r, n_c))
    np.add.at(area, (np.minimum(((rows + 0.5) * res / PLAN_CELL_M).astype(np.int64), n_r - 1),
                     np.minimum(((cols + 0.5) * res / PLAN_CELL_M).astype(np.int64), n_c - 1)), res * res)
    x0, y0 = occ.origin_x_m, occ.origin_y_m
    origin = (float(start[0]), float(start[1]), float(start[2])) if frames == "own" else (0.0, 0.0, 0.0)
    return Deployment((x0, y0, x0 + occ.width_m, y0 + occ.height_m), origin, robots, area, PLAN_CELL_M)


def _pose_errors(world: World, agents: list[ExplorerAgent], own_origins: list[Pose] | None) -> list[float]:
    """Per robot: the distance (m) from where it believes it is to where it is (0 before its
    first pose reading), in the frame its odometry reports in: with frames "own" the truth
    is taken into the robot's own frame (origin and heading at its start, own_origins)."""
    out = []
    for i, agent in enumerate(agents):
        est = agent.pose_estimate()
        x, y, _ = world.true_pose(i)
        if own_origins is not None:
            ox, oy, oyaw = own_origins[i]
            c, s = math.cos(oyaw), math.sin(oyaw)
            x, y = c * (x - ox) + s * (y - oy), -s * (x - ox) + c * (y - oy)
        out.append(0.0 if est is None else math.hypot(est[0] - x, est[1] - y))
    return out


def _on(running: list[bool]) -> list[int]:
    return [i for i, on in enumerate(running) if on]


def _failure_due(f: Failure, now_us: int, coverage: float) -> bool:
    return now_us >= int(round(f.at_s * 1e6)) if f.at_s is not None else coverage >= f.at_coverage


def _termination(agents: list[ExplorerAgent], interrupted: bool, powered: list[bool]) -> str:
    """"complete" when every robot that did not fail stopped with no frontier left that its
    body could reach in all it had mapped; "complete_with_unreachable_frontiers" when every
    such robot stopped but some gave up on such frontiers (its map showed a way, it failed
    to get there); "all_failed" when no robot is left; else why the mission was cut short.
    Frontiers behind gaps narrower than the body are counted (narrow_gap_frontiers) but are
    no way on. A failed robot's own frontiers do not count: the team may not know them."""
    left = [a for a, on in zip(agents, powered) if on]
    if not left:
        return "all_failed"
    if all(a.done for a in left):
        return "complete" if all(a.status == "complete" for a in left) else "complete_with_unreachable_frontiers"
    return "interrupted" if interrupted else "time_limit"


def start_poses(occ, map_start: Pose, starts: tuple[tuple[float, float, float | None], ...],
                robots: int) -> list[Pose]:
    """Every robot's start pose from a mission's `starts` (see MissionConfig). Raises
    ValueError naming the start when there are neither one nor `robots` of them, or one is
    not on a free cell of the map (the world then checks that each body fits there)."""
    if len(starts) not in (0, 1, robots):
        raise ValueError(f"give one start pose (a staging area) or one per robot ({robots}), got {len(starts)}")
    for k, (x, y, _) in enumerate(starts):
        if not occ.is_free_point(x, y):
            raise ValueError(f"start {k + 1} ({x:.3f}, {y:.3f}) m is not on a free cell of map '{occ.name}'")
    poses = [(float(x), float(y), map_start[2] if yaw is None else float(yaw)) for x, y, yaw in starts]
    if len(poses) == robots and robots > 1:
        return poses
    centre = poses[0] if poses else map_start
    return staging_poses(occ, centre, robots) if robots > 1 else [centre]



def _loop(cfg, label, occ, world, channel, bank, sensors, agents, reachable, air_frames, mesh, progress, profiler,
          rates, should_stop=None, observer=None):
    reachable_cells = int(reachable.sum())

    tick_us = rates.tick_period_us
    max_us = int(cfg.max_sim_s * 1e6)
    traj = [[] for _ in range(cfg.robots)]
    in_wall = 0
    t_90_us = None
    coverage = 0.0
    next_sample_us = 0
    ticks = 0
    pose_error = pose_error_max = [0.0] * cfg.robots
    sample_pose_errors = False
    own_origins = [world.true_pose(i) for i in range(cfg.robots)] if cfg.frames == "own" else None
    interrupted = False
    pending = {f.robot: f for f in cfg.failures}          # failures still to come
    running = [True] * cfg.robots                          # False: the robot failed
    failed_at_s: dict[int, float] = {}
    lost: dict[int, np.ndarray] = {}                       # failed robot -> cells only it had seen then
    flush_us = int(round(cfg.flush_s * 1e6))
    # Since when every robot still running has stopped, and since when none has news left for
    # the team either (Scheme.has_news): the mission ends flush_us after the second.
    stopped_us = settled_us = None
    wall0 = time.perf_counter()
    while True:
        now = world.now_us
        if now >= next_sample_us:
            coverage = float((world.observed_union() & reachable).sum()) / reachable_cells
            if t_90_us is None and coverage >= 0.9:
                t_90_us = now
            if progress is not None:
                progress(now / 1e6, coverage)
            if observer is not None:
                observer(now, agents)
            next_sample_us += COVERAGE_SAMPLE_US
            sample_pose_errors = True
        for i in [i for i, f in pending.items() if _failure_due(f, now, coverage)]:
            world.power_off(i)
            running[i] = False
            failed_at_s[i] = now / 1e6
            del pending[i]
            lost[i] = world.observed(i) & reachable & ~_seen_by(world, _on(running), reachable)
        if all(a.done or not on for a, on in zip(agents, running)):
            stopped_us = now if stopped_us is None else stopped_us
            if settled_us is None and all(a.settled or not on for a, on in zip(agents, running)):
                settled_us = now
        else:
            stopped_us = settled_us = None      # a robot woke up (news, or in the flush): it goes on
        if (settled_us is not None and now - settled_us >= flush_us) or now >= max_us:
            break
        if should_stop is not None and should_stop():
            interrupted = True
            break
        for agent, on in zip(agents, running):
            if not on:
                continue
            if profiler is not None:
                profiler.enter("tick")
                agent.tick(profiler)
                profiler.leave("tick")
            else:
                agent.tick()
        if sample_pose_errors:
            # After the robots read their odometry this tick and before the world moves on.
            pose_error = _pose_errors(world, agents, own_origins)
            pose_error_max = [max(m, e) for m, e in zip(pose_error_max, pose_error)]
            sample_pose_errors = False
        world.step(tick_us)
        if bank is not None:
            bank.advance_to(world.now_us)   # the bank moves the channel, the drivers read up to it
        else:
            channel.advance_to(world.now_us)
        if sensors is not None:
            sensors.advance_to(world.now_us)   # the emulators send what the world measured, the drivers read it
        ticks += 1
        for i in range(cfg.robots):
            x, y, yaw = world.true_pose(i)
            traj[i].append((x, y, yaw))
            if not occ.is_free_point(x, y):
                in_wall += 1
    wall_s = time.perf_counter() - wall0
    coverage = float((world.observed_union() & reachable).sum()) / reachable_cells
    if t_90_us is None and coverage >= 0.9:
        t_90_us = world.now_us
    trajectories = [np.array(t, np.float64).reshape(-1, 3) for t in traj]
    digest = hashlib.sha256()
    for t in trajectories:
        digest.update(t.tobytes())
    own_shares = [float((world.observed(i) & reachable).sum()) / reachable_cells for i in range(cfg.robots)]
    survivors_seen = _seen_by(world, _on(running), reachable) if cfg.failures else None
    end_us = world.now_us if settled_us is None else settled_us
    stopped_us = world.now_us if stopped_us is None else stopped_us
    flushed = [a for a in air_frames if a.start_us >= end_us] if cfg.flush_s > 0 else []
    mission_frames = [a for a in air_frames if a.start_us < end_us] if flushed else air_frames
    return MissionResult(
        pose_error_m=pose_error,
        pose_error_max_m=pose_error_max,
        overlap=sum(own_shares) - coverage,
        observed_share=own_shares,
        radio=radio_metrics(mission_frames, channel, agents, mesh, end_us),
        air_log_sha256=air_log_digest(air_frames),
        config=cfg,
        map_label=label,
        coverage=coverage,
        path_length_m=[float(world.path_length_m(i)) for i in range(cfg.robots)],
        t_total_s=stopped_us / 1e6,
        settled_s=None if settled_us is None else settled_us / 1e6,
        t_90_s=None if t_90_us is None else t_90_us / 1e6,
        termination=_termination(agents, interrupted, running),
        wall_s=wall_s,
        sim_s=world.now_us / 1e6,
        ticks=ticks,
        robots_in_wall=in_wall,
        blocked_moves=[int(world.blocked_moves(i)) for i in range(cfg.robots)],
        longest_push_s=[round(world.longest_push_s(i), 3) for i in range(cfg.robots)],
        trajectory_sha256=digest.hexdigest(),
        reachable_area_m2=reachable_cells * occ.resolution_m ** 2,
        robot_status=[a.status if on else "failed" for a, on in zip(agents, running)],
        failed_at_s=failed_at_s,
        coverage_survivors=None if survivors_seen is None else float(survivors_seen.sum()) / reachable_cells,
        lost_at_failure={i: float(cells.sum()) / reachable_cells for i, cells in lost.items()},
        recovered={i: float((cells & survivors_seen).sum()) / cells.sum() if cells.any() else None
                   for i, cells in lost.items()},
        flush=None if cfg.flush_s <= 0 else {
            "flush_s": cfg.flush_s, "ran_s": (world.now_us - end_us) / 1e6,
            "frames_sent": [sum(a.sender_id == i for a in flushed) for i in range(cfg.robots)],
            "bytes_sent": [sum(len(a.payload) for a in flushed if a.sender_id == i) for i in range(cfg.robots)]},
        trajectories=trajectories,
        world=world,
        agents=agents,
        reachable=reachable,
        air_frames=air_frames,
    )
