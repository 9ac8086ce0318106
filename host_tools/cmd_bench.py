"""`lorascout bench`: firmware tick time (median, p99; overall and per task, with each task's
budget: its period), simulation speed and peak memory for a named scenario. Benchmarks, not
timed tests: run them on a quiet machine and compare medians and ratios.

`--serial-radio` runs every robot's radio through the RN2483 driver and a virtual modem on a
pty, as `lorascout run --serial-radio` does: the radio task's time then includes the driver's
calls. The lockstep hand-over between ticks (the driver reading up to the simulation's time)
is the simulator's, outside every task, and is not counted."""
from __future__ import annotations

import argparse
import resource
import sys
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

from host_tools.mission import MissionConfig, run_mission
from host_tools.options import JSON, QUIET, SIM_S_MAX, Opt, add_options
from host_tools.progress import progress_bar
from host_tools.safe_io import strict_dumps

# The shared maps beside the repository, wherever the command is run from.
SHARED_MAPS = Path(__file__).resolve().parents[2] / "shared" / "maps"

SCENARIOS: dict[str, MissionConfig] = {
    "cave-1robot": MissionConfig(map_spec="cave:1", robots=1, seed=0, max_sim_s=600.0),
    "intel-1robot": MissionConfig(map_spec=str(SHARED_MAPS / "intel.yaml"), robots=1, seed=0, max_sim_s=600.0),
    "maze_a-5robots": MissionConfig(map_spec=str(SHARED_MAPS / "maze_a.yaml"), robots=5, seed=0, max_sim_s=600.0),
    # A team sharing a real LoRa band: radio traffic in every tick's radio task.
    "cave-3robots-eu868": MissionConfig(map_spec="cave:1:60x60", robots=3, seed=0, max_sim_s=600.0,
                                        radio="eu868-g3", strategy="minpos"),
    # Meier et al.'s polygon maps over the EU band: the tracker and the teammates' layer in
    # every robot's polygons task, on a cave and on the cluttered Intel lab.
    **{f"{name}-5robots-meier-eu868": MissionConfig(map_spec=spec, robots=5, seed=0, max_sim_s=300.0,
                                                     radio="eu868-g3", strategy="meier")
       for name, spec in (("cave60", "cave:1:60x60"), ("intel", str(SHARED_MAPS / "intel.yaml")))},
    # Scaling with the team (1, 5, 20 robots on one 100 m cave; 50 on a 200 m one) and with the
    # map (5 robots on 60, 100 and 200 m caves): MinPos on the ideal link, 400 s simulated.
    **{f"cave{size}-{n}robots": MissionConfig(map_spec=f"cave:1:{size}x{size}", robots=n, seed=0, max_sim_s=400.0,
                                              strategy="minpos")
       for size, n in ((100, 1), (100, 5), (100, 20), (200, 50), (60, 5), (200, 5))},
}
QUARTERS = 4


class WallClockProfiler:
    """Collects wall time per task call and per firmware tick (perf_counter, on the host),
    and each task's total per quarter of the run (`quarter`, set as the run goes)."""

    def __init__(self) -> None:
        self.samples_s: dict[str, list[float]] = defaultdict(list)
        self.quarter = 0
        self.quarter_s: dict[str, list[float]] = defaultdict(lambda: [0.0] * QUARTERS)
        self._open: dict[str, float] = {}

    def enter(self, task: str) -> None:
        self._open[task] = time.perf_counter()

    def leave(self, task: str) -> None:
        dt = time.perf_counter() - self._open.pop(task)
        self.samples_s[task].append(dt)
        self.quarter_s[task][self.quarter] += dt


OPTIONS = (
    Opt("--scenario", "choice", "what to run", choices=lambda: sorted(SCENARIOS), default="cave-1robot"),
    Opt("--sim-s", "float", "simulated seconds (default: the scenario's)", unit="s", lo=1.0, hi=SIM_S_MAX,
        metavar="S"),
    Opt("--warmup-sim-s", "float", "simulated seconds run first and thrown away, so JIT compilation is not measured",
        unit="s", lo=0.0, hi=3600.0, default=20.0, metavar="S"),
    Opt("--serial-radio", "flag", "every robot's radio through the RN2483 driver and a virtual modem on a pty"),
    JSON, QUIET,
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_options(p, OPTIONS)


def _stats_ms(samples_s: list[float]) -> dict:
    a = np.asarray(samples_s) * 1e3
    return {"calls": int(a.size), "median_ms": round(float(np.median(a)), 4),
            "p99_ms": round(float(np.percentile(a, 99)), 4), "max_ms": round(float(a.max()), 4)}


def task_budgets_ms(agent) -> dict[str, float]:
    """Each task's time budget, as the agent's task table declares it (firmware.scheduler:
    its period unless the table says less), the same `lorascout robot` counts overruns by."""
    return {task.name: task.time_budget_us / 1000.0 for task in agent.scheduler.tasks}


def run_bench(name: str, sim_s: float | None, warmup_sim_s: float, quiet: bool,
              serial_radio: bool = False) -> dict:
    base = SCENARIOS[name]
    cfg = MissionConfig(**{**base.__dict__, "max_sim_s": sim_s or base.max_sim_s,
                           "serial_radio": serial_radio or base.serial_radio})
    run_mission(MissionConfig(**{**cfg.__dict__, "max_sim_s": warmup_sim_s}))  # compile kernels
    profiler = WallClockProfiler()
    bar = progress_bar(cfg.max_sim_s, f"bench {name}", "sim s", quiet)
    last = [0.0]

    marks = []    # (simulated s, wall s) where each quarter of the scheduled time began, and the end

    def progress(t: float, _coverage: float) -> None:
        bar.update(t - last[0])
        last[0] = t
        quarter = min(QUARTERS - 1, int(QUARTERS * t / cfg.max_sim_s))
        if not marks or quarter != profiler.quarter:     # the first call comes before the first tick
            marks.append((t, time.perf_counter()))
        profiler.quarter = quarter

    result = run_mission(cfg, progress, profiler=profiler)
    marks.append((result.sim_s, time.perf_counter()))
    bar.close()
    peak_rss_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    agent = result.agents[0]
    budgets = task_budgets_ms(agent)
    tasks = {k: {**_stats_ms(v), "budget_ms": budgets.get(k)}
             for k, v in sorted(profiler.samples_s.items()) if k != "tick"}
    return {
        "scenario": name,
        "map": result.map_label,
        "robots": cfg.robots,
        "radio": cfg.radio,
        "serial_radio": cfg.serial_radio,
        "sim_s": result.sim_s,
        "wall_s": round(result.wall_s, 3),
        "sim_speedup": round(result.sim_speedup, 2),
        "tick": _stats_ms(profiler.samples_s["tick"]),
        "tasks": tasks,
        **scaling(cfg.robots, result.sim_s, result.wall_s, profiler, marks),
        "peak_rss_mb": round(peak_rss_mb, 1),
        **agent.memory_bytes(),
        "coverage": round(result.coverage, 4),
    }


def scaling(robots: int, sim_s: float, wall_s: float, profiler: WallClockProfiler,
            marks: list[tuple[float, float]]) -> dict:
    """How the cost grows with the team and with the mission: robot-seconds simulated per
    wall second, each task's wall time per robot-second (ms), and both per quarter of the
    scheduled time, with the last quarter's over the first's. A mission that ends early has
    fewer quarters (None for the others); its last one is partial."""
    robot_s = [robots * (b[0] - a[0]) for a, b in zip(marks, marks[1:])]
    wall = [b[1] - a[1] for a, b in zip(marks, marks[1:])]
    pad = [None] * (QUARTERS - len(robot_s))
    per_task = {task: [round(1e3 * q / rs, 4) if rs > 0 else None for q, rs in zip(quarters, robot_s)] + pad
                for task, quarters in sorted(profiler.quarter_s.items()) if task != "tick"}
    reached = [q for q in range(len(robot_s)) if robot_s[q] > 0]
    first, last = (reached[0], reached[-1]) if reached else (None, None)
    return {
        "robot_s_per_wall_s": round(robots * sim_s / wall_s, 2) if wall_s > 0 else None,
        "robot_s_per_wall_s_by_quarter": [round(rs / w, 2) if rs > 0 and w > 0 else None
                                          for rs, w in zip(robot_s, wall)] + pad,
        "task_ms_per_robot_s_by_quarter": per_task,
        "last_over_first_quarter": {task: round(q[last] / q[first], 2) if reached and q[first] else None
                                    for task, q in per_task.items()},
    }


def main(args: argparse.Namespace) -> int:
    try:
        report = run_bench(args.scenario, args.sim_s, args.warmup_sim_s, args.quiet, args.serial_radio)
    except (ValueError, OSError) as exc:
        print(f"lorascout bench: --scenario {args.scenario}: {exc}", file=sys.stderr)
        return 2
    if args.json:
        print(strict_dumps(report, sort_keys=True))
        return 0
    radio = report["radio"] + (" through virtual RN2483 modems (serial driver)" if report["serial_radio"] else "")
    print(f"scenario {report['scenario']}: {report['map']}, {report['robots']} robot(s), radio {radio}, "
          f"{report['sim_s']:.0f} s simulated in {report['wall_s']:.1f} s wall")
    print(f"{'':<12}{'calls':>8}{'median ms':>12}{'p99 ms':>10}{'max ms':>10}{'budget ms':>11}")
    for name, s in [("tick", report["tick"])] + list(report["tasks"].items()):
        budget = s.get("budget_ms")
        budget_text = f"{budget:>11.1f}" if budget is not None else f"{'':>11}"
        over = "  p99 over budget" if budget is not None and s["p99_ms"] > budget else ""
        print(f"{name:<12}{s['calls']:>8}{s['median_ms']:>12.3f}{s['p99_ms']:>10.3f}{s['max_ms']:>10.3f}"
              f"{budget_text}{over}")
    print(f"simulation speed   {report['sim_speedup']:.1f}x real time, {report['robot_s_per_wall_s']:.1f} "
          f"robot-seconds per wall second (by quarter of the run: "
          f"{', '.join(str(q) for q in report['robot_s_per_wall_s_by_quarter'])})")
    print("ms per robot-second, by quarter of the run (last / first):")
    for task, quarters in report["task_ms_per_robot_s_by_quarter"].items():
        print(f"  {task:<10}{'  '.join(f'{q:8.3f}' if q is not None else f'{chr(8211):>8}' for q in quarters)}   "
              f"({report['last_over_first_quarter'][task]})")
    print(f"peak memory        {report['peak_rss_mb']:.0f} MB resident (whole process)")
    print(f"local map          {report['local_map_bytes'] / 1024:.0f} KiB window (fixed), "
          f"{report['paged_out_bytes'] / 1024:.0f} KiB paged out (grows with the area covered)")
    return 0

