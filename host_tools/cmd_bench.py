"""`lorascout bench`: firmware tick time (median, p99; overall and per task), simulation
speed and peak memory for a named scenario. Benchmarks, not timed tests: run them on a quiet
machine and compare medians and ratios."""
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
}


class WallClockProfiler:
    """Collects wall time per task call and per firmware tick (perf_counter, on the host)."""

    def __init__(self) -> None:
        self.samples_s: dict[str, list[float]] = defaultdict(list)
        self._open: dict[str, float] = {}

    def enter(self, task: str) -> None:
        self._open[task] = time.perf_counter()

    def leave(self, task: str) -> None:
        self.samples_s[task].append(time.perf_counter() - self._open.pop(task))


OPTIONS = (
    Opt("--scenario", "choice", "what to run", choices=lambda: sorted(SCENARIOS), default="cave-1robot"),
    Opt("--sim-s", "float", "simulated seconds (default: the scenario's)", unit="s", lo=1.0, hi=SIM_S_MAX,
        metavar="S"),
    Opt("--warmup-sim-s", "float", "simulated seconds run first and thrown away, so JIT compilation is not measured",
        unit="s", lo=0.0, hi=3600.0, default=20.0, metavar="S"),
    JSON, QUIET,
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_options(p, OPTIONS)


def _stats_ms(samples_s: list[float]) -> dict:
    a = np.asarray(samples_s) * 1e3
    return {"calls": int(a.size), "median_ms": round(float(np.median(a)), 4),
            "p99_ms": round(float(np.percentile(a, 99)), 4), "max_ms": round(float(a.max()), 4)}


def run_bench(name: str, sim_s: float | None, warmup_sim_s: float, quiet: bool) -> dict:
    base = SCENARIOS[name]
    cfg = MissionConfig(**{**base.__dict__, "max_sim_s": sim_s or base.max_sim_s})
    run_mission(MissionConfig(**{**cfg.__dict__, "max_sim_s": warmup_sim_s}))  # compile kernels
    profiler = WallClockProfiler()
    bar = progress_bar(cfg.max_sim_s, f"bench {name}", "sim s", quiet)
    last = [0.0]

    def progress(t: float, _coverage: float) -> None:
        bar.update(t - last[0])
        last[0] = t

    result = run_mission(cfg, progress, profiler=profiler)
    bar.close()
    peak_rss_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    agent = result.agents[0]
    tasks = {k: _stats_ms(v) for k, v in sorted(profiler.samples_s.items()) if k != "tick"}
    return {
        "scenario": name,
        "map": result.map_label,
        "robots": cfg.robots,
        "sim_s": result.sim_s,
        "wall_s": round(result.wall_s, 3),
        "sim_speedup": round(result.sim_speedup, 2),
        "tick": _stats_ms(profiler.samples_s["tick"]),
        "tasks": tasks,
        "peak_rss_mb": round(peak_rss_mb, 1),
        "local_map_bytes": int(agent.local_map.logodds.nbytes),
        "paged_out_bytes": int(agent.local_map.pager.nbytes),
        "coverage": round(result.coverage, 4),
    }


def main(args: argparse.Namespace) -> int:
    try:
        report = run_bench(args.scenario, args.sim_s, args.warmup_sim_s, args.quiet)
    except (ValueError, OSError) as exc:
        print(f"lorascout bench: --scenario {args.scenario}: {exc}", file=sys.stderr)
        return 2
    if args.json:
        print(strict_dumps(report, sort_keys=True))
        return 0
    print(f"scenario {report['scenario']}: {report['map']}, {report['robots']} robot(s), "
          f"{report['sim_s']:.0f} s simulated in {report['wall_s']:.1f} s wall")
    print(f"{'':<12}{'calls':>8}{'median ms':>12}{'p99 ms':>10}{'max ms':>10}")
    for name, s in [("tick", report["tick"])] + list(report["tasks"].items()):
        print(f"{name:<12}{s['calls']:>8}{s['median_ms']:>12.3f}{s['p99_ms']:>10.3f}{s['max_ms']:>10.3f}")
    print(f"simulation speed   {report['sim_speedup']:.1f}x real time")
    print(f"peak memory        {report['peak_rss_mb']:.0f} MB resident (whole process)")
    print(f"local map          {report['local_map_bytes'] / 1024:.0f} KiB window (fixed), "
          f"{report['paged_out_bytes'] / 1024:.0f} KiB paged out (grows with the area covered)")
    return 0

