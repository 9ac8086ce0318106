"""`lorascout run`: one mission on the simulated HAL, summarised for people or as JSON."""
from __future__ import annotations

import argparse
import signal
import sys
import threading
import time

from host_tools.mission import MissionConfig, drawn_failures, run_mission
from host_tools.options import (FAIL, FLUSH_S, FRAMES, JSON, LIDAR_PHASE, MAP, MAX_SIM_S, QUIET, RADIO, RANGE_M, ROBOTS, SCHEME,
                                SEED, SET, SLOW, SPREAD, SPREAD_MAX, WHEEL_SLIP, Opt, add_options, check_spread)
from host_tools.overrides import (check_schemes_used, combine_overrides, describe, params_help, params_with,
                                  scheme_settings)
from host_tools.progress import ProgressLines, progress_bar
from host_tools.safe_io import OutputPathError, atomic_path, check_out_file, strict_dumps, write_text

EXIT_INTERRUPTED = 130      # 128 + SIGINT, as a shell reports a command Ctrl-C ended

OPTIONS = (
    MAP, ROBOTS, SEED, MAX_SIM_S, FLUSH_S, RADIO, RANGE_M, SCHEME, FRAMES,
    Opt("--serial-radio", "flag", "drive every robot's radio through a virtual RN2483 modem on a pseudo-terminal"),
    Opt("--serial-lidar", "flag", "read every robot's LiDAR through the RPLIDAR driver and an emulated scanner on a "
        "pseudo-terminal"),
    Opt("--serial-uwb", "flag", "read every robot's UWB ranges through the DWM1001 driver and an emulated module on a "
        "pseudo-terminal"),
    Opt("--capture", "out_file", "record every frame on the air (for lorascout inspect)", metavar="FILE"),
    Opt("--start", "pose", "start pose in metres (and degrees; default the map's yaw): once, the centre of the "
        "team's staging area (default: the map's start); once per robot, each robot's own start",
        repeat=True, metavar="X,Y[,YAW_DEG]"),
    SPREAD, SPREAD_MAX,
    WHEEL_SLIP, LIDAR_PHASE, FAIL, SLOW,
    SET, JSON,
    Opt("--out", "out_dir", "write mission.png and mission.json here (each replaced only by a complete new one)",
        metavar="DIR"),
    QUIET,
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_options(p, OPTIONS)
    p.formatter_class = argparse.RawDescriptionHelpFormatter
    p.epilog = params_help()


def main(args: argparse.Namespace) -> int:
    # Everything that can be refused is refused before the mission starts.
    try:
        overrides = combine_overrides(args.overrides)
        check_schemes_used(overrides, [args.strategy], "--scheme")
        if args.spread and args.start:
            raise ValueError("--spread places every robot: give it or --start, not both")
        check_spread(args.spread, args.spread_max)
        if len(args.start) not in (0, 1, args.robots):
            raise ValueError(f"--start given {len(args.start)} times: give it once (the staging area) or once per "
                             f"robot ({args.robots}, from --robots)")
        outputs = [] if args.out is None else [check_out_file(args.out / n) for n in ("mission.png", "mission.json")]
        cfg = MissionConfig(map_spec=args.map, robots=args.robots, seed=args.seed,
                            max_sim_s=args.max_sim_s, radio=args.radio, starts=tuple(args.start),
                            strategy=args.strategy, frames=args.frames, serial_radio=args.serial_radio,
                            serial_lidar=args.serial_lidar, serial_uwb=args.serial_uwb,
                            capture_path=None if args.capture is None else str(args.capture),
                            wheel_slip_frac=args.wheel_slip, lidar_phase_ms=args.lidar_phase_ms, range_m=args.range_m,
                            spread_m=args.spread, spread_max_m=args.spread_max,
                            failures=drawn_failures(tuple(args.failures), args.seed, args.robots),
                            speed_factors=tuple(args.speed_factors), flush_s=args.flush_s)
    except (ValueError, OutputPathError) as exc:
        print(f"lorascout run: {exc}", file=sys.stderr)
        return 2
    bar = progress_bar(cfg.max_sim_s, "mission", "sim s", args.quiet)
    lines = ProgressLines("lorascout run", args.quiet)
    state = {"last": 0.0, "stop": False}
    wall0 = time.monotonic()

    def progress(sim_s: float, coverage: float) -> None:
        bar.update(sim_s - state["last"])
        state["last"] = sim_s
        bar.set_postfix(coverage=f"{coverage:.3f}")
        lines(f"{sim_s:.0f} s simulated of at most {cfg.max_sim_s:g}, coverage {coverage:.3f}, "
              f"{sim_s / max(time.monotonic() - wall0, 1e-9):.2f}x real time")

    def on_sigint(signum, frame) -> None:
        # The first Ctrl-C ends the mission at the next tick, with a report; a second one
        # stops at once (KeyboardInterrupt).
        state["stop"] = True
        signal.signal(signal.SIGINT, signal.default_int_handler)

    in_main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGINT, on_sigint) if in_main_thread else None
    try:
        result = run_mission(cfg, progress, params=params_with(overrides), scheme_settings=scheme_settings(overrides),
                             should_stop=lambda: state["stop"])
    except (ValueError, KeyError, OSError) as exc:
        bar.close()
        print(f"lorascout run: {exc}", file=sys.stderr)
        return 2
    finally:
        if in_main_thread:
            signal.signal(signal.SIGINT, previous)
    bar.close()
    report = result.to_json()
    report["params_overrides"] = dict(overrides)
    interrupted = result.termination == "interrupted"
    # The report is printed before the files are written: if writing fails, it is not lost.
    if args.json:
        print(strict_dumps(report, sort_keys=True), flush=True)
    else:
        print(format_summary(report), flush=True)
    if args.out is not None:
        from host_tools.plots import plot_mission

        try:
            with atomic_path(outputs[0]) as tmp:
                plot_mission(result, tmp)
            write_text(outputs[1], strict_dumps(report, indent=2) + "\n")
        except OSError as exc:
            print(f"lorascout run: cannot write the report into {args.out}: {exc}", file=sys.stderr)
            return 1
        if not args.json:
            print(f"wrote {outputs[0]} and {outputs[1]}")
    if interrupted:
        print(f"lorascout run: interrupted after {report['t_total_s']:.1f} s simulated; the report is partial",
              file=sys.stderr)
        return EXIT_INTERRUPTED
    return 0


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


def _frontiers_left(r: dict) -> str:
    """'; 3 frontiers the robots could not reach (0.8 m² of frontier cells); 2 behind gaps
    narrower than the body (0.5 m²)', or the parts of it that are not zero."""
    out = ""
    count = sum(r.get("unreachable_frontiers", []))
    if count:
        out += (f"; {count} frontier{'s' if count > 1 else ''} the robots could not reach "
                f"({sum(r['unreachable_frontier_area_m2']):.1f} m² of frontier cells)")
    narrow = sum(r.get("narrow_gap_frontiers", []))
    if narrow:
        out += (f"; {narrow} frontier{'s' if narrow > 1 else ''} behind gaps narrower than the body "
                f"({sum(r['narrow_gap_frontier_area_m2']):.1f} m²)")
    return out


def _flush_and_digests(r: dict) -> list[str]:
    """The flush phase's lines and whether the robots hold the same shared state, if any."""
    lines = []
    if "flush" in r:
        f = r["flush"]
        lines.append(f"flush          {f['ran_s']:.1f} s after every robot stopped (of {f['flush_s']:g} s asked), "
                     f"{sum(f['frames_sent'])} frames, {sum(f['bytes_sent'])} bytes")
    if "scheme_digests" in r:
        d = r["scheme_digests"]
        kinds = ", ".join(sorted({k for per in d["per_robot"] for k in per}))
        lines.append(f"shared state   {'the same on every robot still running' if d['agree'] else 'differs between robots'}"
                     f" ({kinds})")
    return lines


def format_summary(r: dict) -> str:
    t90 = "not reached" if r["t_90_s"] is None else f"{r['t_90_s']:.1f} s"
    paths = ", ".join(f"{p:.1f}" for p in r["path_length_m"])
    lines = [
        f"map            {r['map']}   (reachable free area {r['reachable_area_m2']:.0f} m²)",
        f"robots         {r['robots']}   seed {r['seed']}   strategy {r['strategy']}   radio {r['radio']}"
        + ("" if r.get("range_m") is None else f" within {r['range_m']:g} m"),
        f"coverage       {r['coverage'] * 100:.2f} % of the reachable free area",
        f"path length    {paths} m   (longest {max(r['path_length_m']):.1f} m: this trial's p_max)",
        f"T_total        {r['t_total_s']:.1f} s simulated",
        f"T_90           {t90}" + ("" if r["t_90_s"] is None or r["t_90_s"] <= 0 else
                                      f"   (T_total / T_90 = {r['t_total_s'] / r['t_90_s']:.2f}: the last 10 %'s tail)"),
        f"ended          {r['termination']}   (robots: {', '.join(r['robot_status'])})" + _frontiers_left(r),
        f"overlap        {r['overlap']:.3f}",
        f"radio          {', '.join(f'{b:.1f}' for b in r['radio_stats']['bytes_per_s_mean'])} B/s per robot (mean), "
        f"airtime {', '.join(f'{a * 100:.2f}' for a in r['radio_stats']['airtime_fraction'])} %, "
        f"duty-cycle violations {r['radio_stats']['duty_cycle_violations']}",
        f"receptions     {_receptions(r['radio_stats']['receptions'], sum(r['radio_stats']['frames_sent']))}",
        f"in a wall      {r['robots_in_wall']} robot-ticks",
        *_flush_and_digests(r),
        f"speed          {r['sim_speedup']:.1f}x real time, {r['ticks_per_s']:.0f} ticks/s, {r['wall_s']:.1f} s wall",
    ]
    if r.get("params_overrides"):
        lines.insert(2, f"parameters     {describe(r['params_overrides'].items())} (changed with --set)")
    return "\n".join(lines)
