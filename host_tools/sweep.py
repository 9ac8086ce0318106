"""Trial grids: every (map, strategy, seed) mission, run on local cores or a Ray cluster,
reduced to the tables of Bayer & Faigl (Table III: p_max per map and strategy; Table IV:
packet size, bandwidth and robots per scheme) and their path figures (Figs. 8 and 9)."""
from __future__ import annotations

import csv
import json
import statistics
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Callable, Iterable

import numpy as np

from firmware.comms.frame import frame_size_bytes
from firmware.comms.schema import record_type
from firmware.team import strategy as strategy_named
from host_tools.mission import MissionConfig, run_mission

PATH_DECIMATION = 10   # keep every 10th tick of a path for the figures (0.5 s at 20 Hz)


@dataclass(frozen=True)
class SweepSpec:
    maps: tuple[str, ...]
    strategies: tuple[str, ...]
    robots: int
    seeds: int
    radio: str
    max_sim_s: float
    first_seed: int = 0

    def trials(self) -> list[MissionConfig]:
        return [MissionConfig(map_spec=m, robots=self.robots, seed=self.first_seed + k, max_sim_s=self.max_sim_s,
                              radio=self.radio, strategy=s)
                for m in self.maps for s in self.strategies for k in range(self.seeds)]


def run_trial(cfg: MissionConfig) -> dict:
    """One mission, reduced to what the tables and figures need (picklable for workers)."""
    r = run_mission(cfg)
    report = r.to_json()
    report["map_spec"] = cfg.map_spec
    report["paths_xy"] = [t[::PATH_DECIMATION, :2].round(2).tolist() for t in r.trajectories]
    return report


def run_local(trials: list[MissionConfig], jobs: int, on_done: Callable[[dict], None]) -> list[dict]:
    results: list[dict | None] = [None] * len(trials)
    if jobs <= 1:
        for k, cfg in enumerate(trials):
            results[k] = run_trial(cfg)
            on_done(results[k])
        return results  # type: ignore[return-value]
    with ProcessPoolExecutor(max_workers=jobs) as pool:
        futures = {pool.submit(run_trial, cfg): k for k, cfg in enumerate(trials)}
        for f in as_completed(futures):
            results[futures[f]] = f.result()
            on_done(results[futures[f]])
    return results  # type: ignore[return-value]


def run_ray(trials: list[MissionConfig], address: str, on_done: Callable[[dict], None]) -> list[dict]:
    try:
        import ray
    except ImportError:
        raise RuntimeError("--ray needs the ray package: pip install 'lorascout[ray]'") from None
    ray.init(address=address, ignore_reinit_error=True, log_to_driver=False)
    remote = ray.remote(run_trial)
    refs = [remote.remote(cfg) for cfg in trials]
    index = {ref: k for k, ref in enumerate(refs)}
    results: list[dict | None] = [None] * len(trials)
    pending = list(refs)
    while pending:
        done, pending = ray.wait(pending, num_returns=1)
        for ref in done:
            results[index[ref]] = ray.get(ref)
            on_done(results[index[ref]])
    return results  # type: ignore[return-value]


def p_max(trials: Iterable[dict]) -> float:
    """Bayer & Faigl eq. (1): the median over trials of the longest path of any robot."""
    return float(statistics.median(max(t["path_length_m"]) for t in trials))


def packet_bytes(strategy: str) -> int:
    """Bytes of one map update as the scheme sends it: a 12-byte topological record, or, for
    the dense baselines, one keyframe scan on the mesh link (13 + 2 * 360 bytes)."""
    if strategy_named(strategy).shares_dense_map:
        return 13 + 2 * 360
    if strategy_named(strategy).shares_topology:
        return record_type("topo").size_bytes
    return 0


def tables(spec: SweepSpec, results: list[dict]) -> dict:
    by = {}
    for r in results:
        by.setdefault((r["map_spec"], r["strategy"]), []).append(r)
    table3 = []
    for m in spec.maps:
        row = {"map": next((r["map"] for r in results if r["map_spec"] == m), m)}
        for s in spec.strategies:
            trials = by.get((m, s), [])
            row[s] = {
                "p_max_m": round(p_max(trials), 1) if trials else None,
                "coverage_min": round(min(t["coverage"] for t in trials), 4) if trials else None,
                "complete": sum(t["termination"] == "complete" for t in trials),
                "trials": len(trials),
                "t_total_median_s": round(statistics.median(t["t_total_s"] for t in trials), 1) if trials else None,
                "overlap_median": round(statistics.median(t["overlap"] for t in trials), 3) if trials else None,
            }
        table3.append(row)
    table4 = []
    for s in spec.strategies:
        rs = [r for r in results if r["strategy"] == s]
        radio_bps = [b for r in rs for b in r["radio_stats"]["bytes_per_s_mean"]]
        radio_peak = [b for r in rs for b in r["radio_stats"]["bytes_per_s_peak_10s"]]
        mesh_bps = [b / max(r["t_total_s"], 1e-9) for r in rs for b in r["radio_stats"]["mesh_bytes_sent"]]
        table4.append({
            "strategy": s,
            "packet_bytes": packet_bytes(s),
            "frame_bytes_one_record": frame_size_bytes({"topo": 1}) if strategy_named(s).shares_topology else 0,
            "radio_Bps_per_robot_mean": round(float(np.mean(radio_bps)), 2) if radio_bps else 0.0,
            "radio_Bps_per_robot_peak_10s": round(float(np.max(radio_peak)), 2) if radio_peak else 0.0,
            "mesh_Bps_per_robot_mean": round(float(np.mean(mesh_bps)), 1) if mesh_bps else 0.0,
            "duty_cycle_violations": sum(r["radio_stats"]["duty_cycle_violations"] for r in rs),
            "robots": spec.robots,
        })
    return {"spec": asdict(spec), "table3_p_max": table3, "table4_communication": table4}


def markdown(t: dict) -> str:
    spec = t["spec"]
    lines = [f"p_max [m] (median over {spec['seeds']} seeds of the longest robot path; {spec['robots']} robots, "
             f"radio {spec['radio']}); in brackets: lowest coverage, missions complete",
             "", "| map | " + " | ".join(spec["strategies"]) + " |", "|---|" + "---|" * len(spec["strategies"])]
    for row in t["table3_p_max"]:
        cells = []
        for s in spec["strategies"]:
            c = row[s]
            cells.append("n/a" if c["p_max_m"] is None else
                         f"{c['p_max_m']:.1f} ({c['coverage_min']:.3f}, {c['complete']}/{c['trials']})")
        lines.append(f"| {row['map']} | " + " | ".join(cells) + " |")
    lines += ["", "| scheme | packet [B] | LoRa B/s per robot (mean / peak 10 s) | mesh B/s per robot | "
              "duty-cycle violations | robots |", "|---|---|---|---|---|---|"]
    for r in t["table4_communication"]:
        lines.append(f"| {r['strategy']} | {r['packet_bytes']} | {r['radio_Bps_per_robot_mean']:.1f} / "
                     f"{r['radio_Bps_per_robot_peak_10s']:.1f} | {r['mesh_Bps_per_robot_mean']:.0f} | "
                     f"{r['duty_cycle_violations']} | {r['robots']} |")
    return "\n".join(lines) + "\n"


def save(out: Path, spec: SweepSpec, results: list[dict]) -> dict:
    out.mkdir(parents=True, exist_ok=True)
    t = tables(spec, results)
    (out / "tables.json").write_text(json.dumps(t, indent=2) + "\n")
    (out / "tables.md").write_text(markdown(t))
    with open(out / "trials.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["map", "strategy", "seed", "robots", "radio", "coverage", "termination", "t_total_s", "t_90_s",
                    "longest_path_m", "overlap", "radio_Bps_mean", "duty_cycle_violations"])
        for r in sorted(results, key=lambda r: (r["map_spec"], r["strategy"], r["seed"])):
            w.writerow([r["map"], r["strategy"], r["seed"], r["robots"], r["radio"], r["coverage"], r["termination"],
                        r["t_total_s"], r["t_90_s"], max(r["path_length_m"]), r["overlap"],
                        round(float(np.mean(r["radio_stats"]["bytes_per_s_mean"])), 3),
                        r["radio_stats"]["duty_cycle_violations"]])
    with open(out / "trials.jsonl", "w") as f:
        for r in sorted(results, key=lambda r: (r["map_spec"], r["strategy"], r["seed"])):
            f.write(json.dumps({k: v for k, v in r.items() if k != "paths_xy"}, sort_keys=True) + "\n")
    from host_tools.plots import plot_sweep_paths

    for m in spec.maps:
        for s in spec.strategies:
            first = min((r for r in results if r["map_spec"] == m and r["strategy"] == s), key=lambda r: r["seed"])
            plot_sweep_paths(m, first, out / f"paths_{Path(first['map']).stem.replace(':', '_')}_{s}.png")
    return t
