"""`lorascout hil`: hardware in the loop. The simulated world runs in real time and serves every
robot's devices as emulators (LiDAR, UWB and modem on pseudo-terminals, the drive's ODrive axes
on a CAN bus other processes reach), writes each robot's configuration file, runs a `lorascout
robot` process per robot on it, and reports the team's coverage of the true map and each
robot's overruns when they have all stopped (host_tools.hil).

With --serve-only it writes the configuration files, prints their paths and serves the world
until SIGINT or SIGTERM (or --max-s), for robot processes started by hand.

Exit status: 0 when every robot process ended with status 0 (whatever ended the run), 1 when
one did not, 2 for options that cannot run, 130 when interrupted.
"""
from __future__ import annotations

import argparse
import signal
import sys
import textwrap
import time
from pathlib import Path

from host_tools.cli import EXIT_INTERRUPTED
from host_tools.hil import (DEFAULT_CAN_CHANNEL, ROBOTS_MAX, HilError, HilSettings, HilWorld, RobotRun,
                            check_can_channel, run_hil)
from host_tools.options import (JSON, LIDAR_PHASE, MAP, RADIO, ROBOTS, SCHEME, SEED, SIM_S_MAX, WHEEL_SLIP, Opt,
                                add_options, with_default)
from host_tools.safe_io import OutputPathError, check_out_file, strict_dumps, write_text
from world_sim.world import WorldParams

DEFAULT_MAP = "cave:7:30x30"


OPTIONS = (
    with_default(MAP, DEFAULT_MAP),
    Opt("--robots", "int", ROBOTS.help, unit="robots", lo=1, hi=ROBOTS_MAX, default=2),
    with_default(SEED, 0, "world seed: sensor noise and the radio channel (the robots run on the wall clock, so "
                 "runs differ)"),
    with_default(RADIO, "eu868-g3", "the team's radio profile (the modems' settings and the channel)"),
    with_default(SCHEME, "bayer-faigl:minpos"),
    Opt("--start", "pose", "start pose in metres (and degrees): once, the centre of the team's staging area "
        "(default: the map's start); once per robot, each robot's own start", repeat=True, metavar="X,Y[,YAW_DEG]"),
    WHEEL_SLIP, LIDAR_PHASE,
    Opt("--can-channel", "text", "the udp_multicast CAN bus's multicast group (the default is interface-local: "
        "frames never leave this host)", default=DEFAULT_CAN_CHANNEL, metavar="GROUP"),
    Opt("--out", "out_dir", "write each robot's configuration (robotN.toml), log (robotN.log) and summary "
        "(robotN.json), and the run's summary (hil.json) here", default="out/hil", metavar="DIR"),
    Opt("--max-s", "float", "stop the robots (SIGTERM) after this much wall time", unit="s", lo=0.0, lo_open=True,
        hi=SIM_S_MAX, default=1800.0, metavar="S"),
    Opt("--serve-only", "flag", "write the configuration files, print their paths and serve the world until "
        "SIGINT or SIGTERM (or --max-s); start `lorascout robot --config FILE` yourself"),
    JSON,
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_options(p, OPTIONS)
    p.formatter_class = argparse.RawDescriptionHelpFormatter
    p.description = f"{p.description}\n\n" + textwrap.fill(
        "Per robot: an RPLIDAR A1, a DWM1001 and an RN2483 (RN2903 for us915) on pseudo-terminals, and the two ODrive "
        "axes of its differential drive on python-can's udp_multicast bus (robot r's axes are nodes 2r and 2r + 1). "
        "The world is the lockstep simulator's, stepped to the wall clock. Each robot is an unchanged `lorascout "
        "robot --config robotN.toml` process with the real drivers; the run ends when every robot has stopped by "
        "itself (or --max-s, or Ctrl-C, which stops them with SIGTERM).", width=88)


def main(args: argparse.Namespace) -> int:
    from hal.lora import profile as radio_profile
    from radio_sim.rn2483 import on_air_settings

    prof = radio_profile(args.radio)
    try:
        try:
            on_air_settings(prof)      # the modems must be able to carry the profile
        except ValueError as exc:
            raise ValueError(f"--radio {args.radio}: {exc}") from None
        try:
            check_can_channel(args.can_channel)
        except ValueError as exc:
            raise ValueError(f"--can-channel: {exc}") from None
        if len(args.start) not in (0, 1, args.robots):
            raise ValueError(f"--start given {len(args.start)} times: give it once (the staging area) or once per "
                             f"robot ({args.robots}, from --robots)")
        _check_starts(args)
        out_dir = Path(args.out)
        out_dir.mkdir(parents=True, exist_ok=True)
        summary_path = check_out_file(out_dir / "hil.json")
    except (ValueError, OutputPathError, OSError) as exc:
        print(f"lorascout hil: {exc}", file=sys.stderr)
        return 2
    settings = HilSettings(map_spec=args.map, robots=args.robots, seed=args.seed, profile=prof,
                           scheme=args.strategy, starts=tuple(args.start), can_channel=args.can_channel,
                           world_params=WorldParams().with_slip_and_lidar_phase(args.wheel_slip, args.lidar_phase_ms))
    stop = {"signal": None}

    def on_signal(signum, frame) -> None:
        if stop["signal"] is not None:
            raise KeyboardInterrupt     # a second signal: stop at once (the robots are killed on the way out)
        stop["signal"] = signal.Signals(signum).name

    previous = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        _warm_up(settings)
        try:
            hil = HilWorld(settings)
        except ValueError as exc:      # a start where a body does not fit, a map that cannot be read
            print(f"lorascout hil: {exc}", file=sys.stderr)
            return 2
        except (HilError, OSError) as exc:
            print(f"lorascout hil: {exc}", file=sys.stderr)
            return 1
        with hil:
            configs = hil.write_configs(out_dir)
            if args.serve_only:
                return _serve_only(hil, configs, args.max_s, stop)
            runs = [RobotRun(i, configs[i], out_dir / f"robot{i}.log", out_dir / f"robot{i}.json")
                    for i in range(args.robots)]
            t0 = time.monotonic()
            try:
                why = run_hil(hil, runs, args.max_s, lambda: stop["signal"] is not None)
            except Exception as exc:   # noqa: BLE001 - an emulator failed: the robots were stopped on the way out
                print(f"lorascout hil: the world failed, the robots were stopped: {type(exc).__name__}: {exc}",
                      file=sys.stderr)
                return 1
            wall_s = time.monotonic() - t0
            report = {**_identity(settings, args), "ended": why, "wall_s": round(wall_s, 3), **hil.report()}
            report["robots"] = [{**run.to_json(), **truth} for run, truth in zip(runs, report["robots"])]
            report["robots_exited_within_s"] = _exited_within_s(report["robots"])
            report["lost_receptions"] = _lost(report["air"])
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    report["termination"] = _termination(report)
    print(strict_dumps(report, sort_keys=True) if args.json else format_report(report), flush=True)
    try:
        write_text(summary_path, strict_dumps(report, indent=2, sort_keys=True) + "\n")
    except OSError as exc:
        print(f"lorascout hil: cannot write {summary_path}: {exc}", file=sys.stderr)
        return 1
    if why == "interrupted":
        return EXIT_INTERRUPTED
    return 0 if all(r["exit_status"] == 0 for r in report["robots"]) else 1


def _check_starts(args: argparse.Namespace) -> None:
    """Each --start on a free cell of the map (the world then checks that each body fits)."""
    from host_tools.mission import start_poses
    from world_sim.map_spec import resolve_map

    occ, start, _ = resolve_map(args.map)
    try:
        start_poses(occ, start, tuple(args.start), args.robots)
    except ValueError as exc:
        raise ValueError(f"--start: {exc}") from None


def _warm_up(settings: HilSettings) -> None:
    """Compile the world's kernels (motion, collision, LiDAR) before the wall clock runs: a
    throwaway world of one robot takes a step."""
    from world_sim.map_spec import resolve_map
    from world_sim.world import World

    occ, start, _ = resolve_map(settings.map_spec)
    World(occ, [start], settings.seed, settings.world_params).step(200_000)


def _serve_only(hil: HilWorld, configs: list[Path], max_s: float, stop: dict) -> int:
    for path in configs:
        print(path)
    sys.stdout.flush()
    hil.serve(lambda now_us: stop["signal"] is not None or now_us >= max_s * 1e6)
    return EXIT_INTERRUPTED if stop["signal"] is not None else 0


def _identity(settings: HilSettings, args: argparse.Namespace) -> dict:
    return {"map_spec": settings.map_spec, "team_size": settings.robots, "seed": settings.seed,
            "scheme": settings.scheme, "radio": settings.profile.name, "can_channel": settings.can_channel,
            "world_params": {"wheel_slip_frac": settings.world_params.wheel_slip_frac,
                             "lidar_phase_us": settings.world_params.lidar_phase_us},
            "out": str(args.out)}


def _exited_within_s(robots: list[dict]) -> float | None:
    """From the first robot process's exit to the last's, on the world's clock."""
    ends = [r["exited_s"] for r in robots if r["exited_s"] is not None]
    return round(max(ends) - min(ends), 3) if len(ends) == len(robots) else None


def _lost(air: dict) -> int:
    """Receptions that did not arrive, whatever the reason (radio_sim.air_log.FATES)."""
    return sum(v for k, v in air.items() if k not in ("frames", "received", "duplicates_delivered"))


def _termination(report: dict) -> str:
    """"complete" when every robot stopped by itself with its mission complete; else what
    ended the first robot that did not."""
    for r in report["robots"]:
        if r["exit_status"] != 0:
            return f"robot {r['robot_id']} failed (exit status {r['exit_status']})"
        if r["termination"] != "complete":
            return f"robot {r['robot_id']} ended {r['termination']}"
    return "complete"


def format_report(r: dict) -> str:
    cov = ", ".join(f"robot {x['robot_id']} {x['coverage'] * 100:.1f} %" for x in r["robots"])
    lines = [f"hil            {r['map']}, {r['team_size']} robots, {r['scheme']} on {r['radio']}, seed {r['seed']}: "
             f"{r['termination']} ({r['ended'].replace('_', ' ')}) after {r['wall_s']:.1f} s wall",
             f"coverage       {r['coverage'] * 100:.1f} % of {r['reachable_area_m2']:.1f} m² ({cov})"]
    for x in r["robots"]:
        ticks = x["ticks"] or 0
        share = f"{x['worst_overrun_share'] * 100:.2f} %" if x["worst_overrun_share"] is not None else "-"
        overruns = ", ".join(f"{name} {n}" for name, n in x["task_overruns"].items() if n) or "none"
        ended = (f", ticked from {x['started_s']:.1f} s to {x['ended_s']:.1f} s on the shared clock"
                 if x.get("started_s") is not None and x.get("ended_s") is not None else "")
        ended += f", exited at {x['exited_s']:.1f} s" if x.get("exited_s") is not None else ""
        signed = f", signed off: {x['sign_off']} in {x['sign_off_s']:.1f} s" if x.get("sign_off") else ""
        lines.append(f"robot {x['robot_id']:<9}{x['termination']} after {x['wall_s'] or 0:.1f} s{ended}{signed} "
                     f"(exit {x['exit_status']}): {ticks} ticks, {x['tick_overruns']} over 50 ms; task overruns "
                     f"{overruns}; worst {share} of ticks; path {x['path_length_m']:.1f} m")
        if x.get("error"):
            lines.append(f"{'':15}error: {x['error']}")
    loop = r["loop"]
    lines.append(f"world          {r['sim_s']:.1f} s served in {loop['loops']} loops ({loop['late_loops']} began "
                 f">= 50 ms late, the latest {loop['max_lag_ms']:.0f} ms)")
    air = r["air"]
    fates = ", ".join(f"{k.replace('_', ' ')} {v}" for k, v in sorted(air.items()) if v and k != "frames")
    lines.append(f"air            {air.get('frames', 0)} frames; receptions: {fates or 'none'} ({_lost(air)} lost)")
    if r.get("robots_exited_within_s") is not None:
        lines.append(f"ends           the robot processes exited within {r['robots_exited_within_s']:.1f} s of "
                     "each other")
    lines.append(f"files          {r['out']}/robotN.toml, robotN.log, robotN.json, hil.json")
    return "\n".join(lines)
