"""`lorascout run`: one mission on the simulated HAL, summarised for people or as JSON."""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from hal.lora import PROFILES
from hal.sim.odometry import FRAMES
from host_tools.mission import MissionConfig, run_mission
from host_tools.overrides import describe, parse_overrides, params_with
from host_tools.progress import progress_bar
from host_tools.scheme_option import add_scheme_option

DEFAULT_MAP = "cave:1"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--map", default=DEFAULT_MAP,
                   help="PATH.yaml (ROS map_server), cave:SEED[:WxH] or tunnel:SEED[:WxH] (default %(default)s)")
    p.add_argument("--robots", type=int, default=1, help="team size (default %(default)s)")
    p.add_argument("--seed", type=int, default=0, help="mission seed: same seed, same result (default %(default)s)")
    p.add_argument("--max-sim-s", type=float, default=14400.0, help="simulated time limit in seconds (default %(default)s)")
    p.add_argument("--radio", default="ideal-100Bps", choices=sorted(PROFILES), help="radio profile (default %(default)s)")
    add_scheme_option(p, default="greedy")
    p.add_argument("--frames", choices=FRAMES, default="shared",
                   help="odometry frames: one shared by the team (start poses measured at deployment), or each "
                        "robot's own, unknown to the others (default %(default)s)")
    p.add_argument("--serial-radio", action="store_true",
                   help="drive every robot's radio through a virtual RN2483 modem on a pseudo-terminal")
    p.add_argument("--capture", type=Path, default=None, metavar="FILE",
                   help="record every frame on the air (for lorascout inspect)")
    p.add_argument("--start", type=_pose, action="append", default=[], metavar="X,Y[,YAW_DEG]",
                   help="start pose in metres (and degrees; default the map's yaw): once, the centre of the team's "
                        "staging area (default: the map's start); once per robot, each robot's own start")
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE", dest="overrides",
                   help="change an explorer parameter (firmware/params.py); repeatable")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the summary")
    p.add_argument("--out", type=Path, default=None, metavar="DIR", help="write mission.png and mission.json here")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def _pose(text: str) -> tuple[float, float, float | None]:
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) not in (2, 3) or not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f"expected X,Y or X,Y,YAW_DEG as numbers, got {text!r}")
    return (values[0], values[1], math.radians(values[2]) if len(values) == 3 else None)


def main(args: argparse.Namespace) -> int:
    if args.robots < 1:
        print("lorascout run: --robots must be at least 1", file=sys.stderr)
        return 2
    cfg = MissionConfig(map_spec=args.map, robots=args.robots, seed=args.seed,
                        max_sim_s=args.max_sim_s, radio=args.radio, starts=tuple(args.start),
                        strategy=args.strategy, frames=args.frames, serial_radio=args.serial_radio,
                        capture_path=None if args.capture is None else str(args.capture))
    bar = progress_bar(cfg.max_sim_s, "mission", "sim s", args.quiet)
    state = {"last": 0.0}

    def progress(sim_s: float, coverage: float) -> None:
        bar.update(sim_s - state["last"])
        state["last"] = sim_s
        bar.set_postfix(coverage=f"{coverage:.3f}")

    try:
        overrides = parse_overrides(args.overrides)
        result = run_mission(cfg, progress, params=params_with(overrides))
    except (ValueError, KeyError, OSError) as exc:
        bar.close()
        print(f"lorascout run: {exc}", file=sys.stderr)
        return 2
    bar.close()
    report = result.to_json()
    report["params_overrides"] = dict(overrides)
    report["coverage_within_planner_clearance"] = _within_clearance(result)
    if args.out is not None:
        from host_tools.plots import plot_mission

        args.out.mkdir(parents=True, exist_ok=True)
        plot_mission(result, args.out / "mission.png")
        (args.out / "mission.json").write_text(json.dumps(report, indent=2) + "\n")
    if args.json:
        print(json.dumps(report, sort_keys=True))
    else:
        print(format_summary(report))
        if args.out is not None:
            print(f"wrote {args.out / 'mission.png'} and {args.out / 'mission.json'}")
    return 0


def _within_clearance(result) -> dict | None:
    """Coverage of the area a robot keeping the planner's clearance (robot radius plus safety
    margin) can reach from robot 0's start, next to the body-reachable area the mission
    scores: rooms behind doors narrower than twice the clearance count only in the latter.
    None when that start is too close to a wall for the clearance."""
    from host_tools.map_report import PLANNER_CLEARANCE_M, coverage_within_clearance

    x, y = result.start_poses[0][:2]
    try:
        area_m2, coverage = coverage_within_clearance(result.world.occ, result.world.observed_union(), (x, y),
                                                      PLANNER_CLEARANCE_M)
    except ValueError:
        return None
    return {"clearance_m": PLANNER_CLEARANCE_M, "reachable_area_m2": round(area_m2, 2), "coverage": round(coverage, 6)}


def _receptions(fates: dict[str, int], frames_sent: int) -> str:
    """What became of each frame at each robot in range of hearing it: 'received 812,
    collided 3 (0.4 %)'; the losses with their share of all receptions."""
    total = sum(fates.values())
    if not total:
        return "none (no other robot on the air)" if frames_sent else "none (no frame was sent)"
    parts = [f"received {fates.get('received', 0)}"]
    parts += [f"{fate.replace('_', ' ')} {n} ({100 * n / total:.1f} %)"
              for fate, n in sorted(fates.items()) if fate != "received" and n]
    return ", ".join(parts)


def _clearance_note(c: dict | None, reachable_m2: float) -> str:
    if c is None or c["reachable_area_m2"] >= 0.99 * reachable_m2:
        return ""           # a few cells' difference along walls says nothing
    return (f" ({c['coverage'] * 100:.2f} % of the {c['reachable_area_m2']:.0f} m² a robot keeping the planner's "
            f"{c['clearance_m']} m from walls can reach)")


def format_summary(r: dict) -> str:
    t90 = "not reached" if r["t_90_s"] is None else f"{r['t_90_s']:.1f} s"
    paths = ", ".join(f"{p:.1f}" for p in r["path_length_m"])
    lines = [
        f"map            {r['map']}   (reachable free area {r['reachable_area_m2']:.0f} m²)",
        f"robots         {r['robots']}   seed {r['seed']}   strategy {r['strategy']}   radio {r['radio']}",
        f"coverage       {r['coverage'] * 100:.2f} % of the reachable free area"
        + _clearance_note(r.get("coverage_within_planner_clearance"), r["reachable_area_m2"]),
        f"path length    {paths} m   (longest {max(r['path_length_m']):.1f} m: this trial's p_max)",
        f"T_total        {r['t_total_s']:.1f} s simulated",
        f"T_90           {t90}",
        f"ended          {r['termination']}   (robots: {', '.join(r['robot_status'])})",
        f"overlap        {r['overlap']:.3f}",
        f"radio          {', '.join(f'{b:.1f}' for b in r['radio_stats']['bytes_per_s_mean'])} B/s per robot (mean), "
        f"airtime {', '.join(f'{a * 100:.2f}' for a in r['radio_stats']['airtime_fraction'])} %, "
        f"duty-cycle violations {r['radio_stats']['duty_cycle_violations']}",
        f"receptions     {_receptions(r['radio_stats']['receptions'], sum(r['radio_stats']['frames_sent']))}",
        f"in a wall      {r['robots_in_wall']} robot-ticks",
        f"speed          {r['sim_speedup']:.1f}x real time, {r['ticks_per_s']:.0f} ticks/s, {r['wall_s']:.1f} s wall",
    ]
    if r.get("params_overrides"):
        lines.insert(2, f"parameters     {describe(r['params_overrides'].items())} (changed with --set)")
    return "\n".join(lines)
