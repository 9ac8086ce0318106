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
from typing import Callable

import numpy as np

from firmware.agent import ExplorerAgent
from firmware.params import ExplorationParams, TaskRates
from firmware.scheduler import TaskProfiler
from firmware.team import strategy as strategy_named
from hal.lora import profile as radio_profile
from hal.sim.clock import SimClock
from hal.sim.factory import build_sim_hal
from hal.sim.mesh import SimMeshBus
from hal.sim.radio import SimRadioModem
from radio_sim.channel import Channel
from world_sim.map_spec import resolve_map, staging_poses
from world_sim.ros_map import reachable_free
from world_sim.world import World, WorldParams

COVERAGE_SAMPLE_US = 1_000_000


@dataclass(frozen=True)
class MissionConfig:
    map_spec: str = "cave:1"
    robots: int = 1
    seed: int = 0
    max_sim_s: float = 7200.0
    radio: str = "ideal-100Bps"
    strategy: str = "greedy"
    start_xy: tuple[float, float] | None = None


@dataclass
class MissionResult:
    config: MissionConfig
    map_label: str
    coverage: float
    path_length_m: list[float]
    t_total_s: float
    t_90_s: float | None
    termination: str
    wall_s: float
    sim_s: float
    ticks: int
    robots_in_wall: int
    blocked_moves: list[int]
    trajectory_sha256: str
    reachable_area_m2: float
    robot_status: list[str]
    # For plots (not in the JSON).
    trajectories: list[np.ndarray] = field(repr=False, default_factory=list)
    world: object = field(repr=False, default=None)
    agents: list = field(repr=False, default_factory=list)
    reachable: np.ndarray | None = field(repr=False, default=None)

    @property
    def sim_speedup(self) -> float:
        return self.sim_s / self.wall_s if self.wall_s > 0 else math.inf

    def to_json(self) -> dict:
        return {
            "map": self.map_label,
            "seed": self.config.seed,
            "robots": self.config.robots,
            "radio": self.config.radio,
            "strategy": self.config.strategy,
            "coverage": round(self.coverage, 6),
            "path_length_m": [round(p, 3) for p in self.path_length_m],
            "t_total_s": round(self.t_total_s, 3),
            "t_90_s": None if self.t_90_s is None else round(self.t_90_s, 3),
            "termination": self.termination,
            "robot_status": self.robot_status,
            "reachable_area_m2": round(self.reachable_area_m2, 2),
            "robots_in_wall": self.robots_in_wall,
            "blocked_moves": self.blocked_moves,
            "ticks": self.ticks,
            "trajectory_sha256": self.trajectory_sha256,
            # Wall-clock figures: the only keys that differ between identical runs.
            "wall_s": round(self.wall_s, 3),
            "sim_speedup": round(self.sim_speedup, 2),
            "ticks_per_s": round(self.ticks / self.wall_s, 1) if self.wall_s > 0 else None,
        }


WALL_TIME_KEYS = ("wall_s", "sim_speedup", "ticks_per_s")


def run_mission(cfg: MissionConfig, progress: Callable[[float, float], None] | None = None,
                profiler: TaskProfiler | None = None,
                params: ExplorationParams = ExplorationParams(),
                rates: TaskRates = TaskRates(),
                world_params: WorldParams = WorldParams()) -> MissionResult:
    occ, start, label = resolve_map(cfg.map_spec)
    if cfg.start_xy is not None:
        start = (cfg.start_xy[0], cfg.start_xy[1], start[2])
    poses = staging_poses(occ, start, cfg.robots) if cfg.robots > 1 else [start]
    world = World(occ, poses, cfg.seed, world_params)
    reachable = reachable_free(occ, (poses[0][0], poses[0][1]))
    reachable_cells = int(reachable.sum())
    profile = radio_profile(cfg.radio)
    strategy = strategy_named(cfg.strategy)
    channel = Channel(profile, cfg.seed, occupancy=occ)
    mesh = SimMeshBus()
    clock = SimClock(world)
    agents = []
    for i in range(cfg.robots):
        channel.attach(i, lambda i=i: world.true_pose(i)[:2])
        hal = build_sim_hal(world, i, radio=SimRadioModem(channel, i, clock))
        if strategy.shares_dense_map:
            hal = dataclasses.replace(hal, mesh=mesh.endpoint(i))
        agent = ExplorerAgent(hal, params, rates, strategy, profile)
        agent.setup()
        agents.append(agent)

    tick_us = rates.tick_period_us
    max_us = int(cfg.max_sim_s * 1e6)
    traj = [[] for _ in range(cfg.robots)]
    in_wall = 0
    t_90_us = None
    coverage = 0.0
    next_sample_us = 0
    ticks = 0
    wall0 = time.perf_counter()
    while True:
        now = world.now_us
        if now >= next_sample_us:
            coverage = float((world.observed_union() & reachable).sum()) / reachable_cells
            if t_90_us is None and coverage >= 0.9:
                t_90_us = now
            if progress is not None:
                progress(now / 1e6, coverage)
            next_sample_us += COVERAGE_SAMPLE_US
        if all(a.done for a in agents) or now >= max_us:
            break
        for agent in agents:
            if profiler is not None:
                profiler.enter("tick")
                agent.tick(profiler)
                profiler.leave("tick")
            else:
                agent.tick()
        world.step(tick_us)
        channel.advance_to(world.now_us)
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
    return MissionResult(
        config=cfg,
        map_label=label,
        coverage=coverage,
        path_length_m=[float(world.path_length_m(i)) for i in range(cfg.robots)],
        t_total_s=world.now_us / 1e6,
        t_90_s=None if t_90_us is None else t_90_us / 1e6,
        termination="complete" if all(a.done for a in agents) else "time_limit",
        wall_s=wall_s,
        sim_s=world.now_us / 1e6,
        ticks=ticks,
        robots_in_wall=in_wall,
        blocked_moves=[int(world.blocked_moves(i)) for i in range(cfg.robots)],
        trajectory_sha256=digest.hexdigest(),
        reachable_area_m2=reachable_cells * occ.resolution_m ** 2,
        robot_status=[a.status for a in agents],
        trajectories=trajectories,
        world=world,
        agents=agents,
        reachable=reachable,
    )
