"""`lorascout robot --config robot.toml`: one robot's firmware on the wall clock, on the
peripherals its configuration names (host_tools.robot_config), simulated or real.

It checks the whole configuration before opening any device (`--check` stops there), opens
the peripherals through the backend registry, sets the firmware up and runs its tick loop
in real time (host_tools.robot_loop), counting every task's overruns against its budget.
It ends when the mission is complete (once its sign-off heartbeat has left the air), after
`--max-s`, or on SIGINT or SIGTERM; whatever ends it, the drive is commanded to zero and every
device closed, and a summary printed.

Exit status: 0 for a run that ended as asked (complete, time limit, a signal), 1 when a
device failed (at start-up or while running), 2 for a configuration that cannot run.
"""
from __future__ import annotations

import argparse
import contextlib
import logging
import signal
import sys
import textwrap

from firmware.warm_up import warm_up
from hal.monotonic_clock import SHARED_KEY, MonotonicClock
from host_tools.options import JSON, SIM_S_MAX, Opt, add_options
from host_tools.overrides import params_with
from host_tools.robot_config import (DeviceError, Robot, RobotConfig, RobotConfigError, config_help,
                                     load_robot_config, open_robot)
from host_tools.robot_loop import LoopResult, RobotLoop
from host_tools.safe_io import strict_dumps

log = logging.getLogger("lorascout.robot")

OPTIONS = (
    Opt("--config", "in_file", "the robot's configuration file (TOML; its tables are listed below)",
        metavar="FILE", required=True),
    Opt("--check", "flag", "check the configuration, print what it would build, and exit without opening a device"),
    Opt("--max-s", "float", "stop after this much wall time (default: when the mission is complete)", unit="s",
        lo=0.0, lo_open=True, hi=SIM_S_MAX, metavar="S"),
    Opt("--log-interval-s", "float", "a log line with tick and overrun counts this often", unit="s", lo=0.1,
        hi=3600.0, default=10.0, metavar="S"),
    Opt("--log-level", "choice", "least severe log messages shown (on stderr)",
        choices=("debug", "info", "warning", "error"), default="info"),
    JSON,
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_options(p, OPTIONS)
    p.formatter_class = argparse.RawDescriptionHelpFormatter
    p.description = f"{p.description}\n\n" + textwrap.fill(
        "Every task's time budget is its period (radio and control 50 ms, lidar 100 ms, planning 1 s); a run over "
        "it is an overrun, and so is a tick longer than the tick period (50 ms). SIGINT or SIGTERM stops the robot "
        "after the tick that is running (a second one at once); the drive is commanded to zero and every device "
        "closed.", width=88)
    p.epilog = config_help()


class StopNow(BaseException):
    """A stop signal that cannot wait for the end of a tick: one during start-up (which may
    wait on a device), or a second one. A BaseException, so that no `except Exception`
    on the way takes it for a device error."""

    def __init__(self, signal_name: str) -> None:
        super().__init__(signal_name)
        self.signal_name = signal_name


class StopSignals:
    """SIGINT and SIGTERM: while the tick loop runs, the first asks it to stop after the
    current tick (`reason()`); before it runs, or a second time, they stop at once
    (StopNow). While the robot shuts down they are only noted: the drive is stopped and the
    devices closed whatever arrives."""

    def __init__(self) -> None:
        self.received: str | None = None
        self.phase = "starting"        # "starting", "running", "stopping"

    def reason(self) -> str | None:
        return self.received

    def ready(self) -> None:
        """The robot is built: from now on a first signal waits for the end of a tick."""
        self.phase = "running"

    def _handle(self, signum: int, frame) -> None:
        name = signal.Signals(signum).name
        first = self.received is None
        self.received = self.received or name
        if self.phase == "stopping":
            return
        if self.phase == "starting" or not first:
            raise StopNow(name)

    @contextlib.contextmanager
    def installed(self):
        previous = {sig: signal.signal(sig, self._handle) for sig in (signal.SIGINT, signal.SIGTERM)}
        try:
            yield self
        finally:
            for sig, handler in previous.items():
                signal.signal(sig, handler)


def main(args: argparse.Namespace) -> int:
    _configure_logging(args.log_level)
    try:
        cfg = load_robot_config(args.config)
    except RobotConfigError as exc:
        print(f"lorascout robot: {exc}", file=sys.stderr)
        return 2
    if args.check:
        print(strict_dumps(cfg.describe(), sort_keys=True) if args.json else format_config(cfg))
        return 0
    with StopSignals().installed() as signals:
        return _run(cfg, args, signals)


def _configure_logging(level_name: str) -> None:
    logging.basicConfig(stream=sys.stderr, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    logging.getLogger("lorascout").setLevel(level_name.upper())


def _run(cfg: RobotConfig, args: argparse.Namespace, signals: StopSignals) -> int:
    try:
        log.info("compiling the firmware's kernels")
        warm_up(params_with(cfg.overrides))
        robot = open_robot(cfg, on_ready=signals.ready)
    except StopNow as stop:
        _print_report({**_identity(cfg), "termination": stop.signal_name, "started": False}, args.json)
        return 0
    except DeviceError as exc:
        print(f"lorascout robot: {cfg.path}: {exc}", file=sys.stderr)
        return 1
    except RobotConfigError as exc:    # the simulated world cannot hold the robot where it starts
        print(f"lorascout robot: {exc}", file=sys.stderr)
        return 2
    except ValueError as exc:          # the firmware refused the robot it was given (agent.setup)
        print(f"lorascout robot: {cfg.path}: {exc}", file=sys.stderr)
        return 2
    result = LoopResult()
    failure = None
    try:
        log.info("robot %d of %d started (%s): %s", cfg.robot_id, cfg.team_size, cfg.scheme,
                 ", ".join(f"{p.kind} {p.backend}" for p in cfg.peripherals))
        loop = RobotLoop(robot.agent, robot.ctx.shared(SHARED_KEY, MonotonicClock),
                         robot.ctx.wall_clock_followers, args.log_interval_s)
        result = loop.result
        loop.run(signals.reason, args.max_s)
    except StopNow as stop:
        result.termination = stop.signal_name
    except Exception as exc:           # noqa: BLE001 - a device or the firmware failed: stop safely, report
        log.exception("the tick loop failed")
        result.termination = "error"
        failure = f"{type(exc).__name__}: {exc}"
    finally:
        signals.phase = "stopping"
        report = _shut_down(robot, result)
    report["error"] = failure
    _print_report(report, args.json)
    return 1 if failure is not None else 0


def _shut_down(robot: Robot, result: LoopResult) -> dict:
    """Command the drive to zero, take the run's figures, close every device: the report.
    The devices are closed even if taking the figures fails."""
    drive_stopped = _stop_drive(robot)
    agent = robot.agent
    try:
        report = {**_identity(robot.config), **result.to_json(), "started": True, "drive_stopped": drive_stopped,
                  "status": agent.status, "scans": agent.scans, "explorer_stats": agent.stats(),
                  **{name: fn() for name, fn in robot.ctx.reports.items()}}
    finally:
        close_failures = robot.ctx.close()
        for failure in close_failures:
            log.error("closing %s", failure)
    report["close_failures"] = close_failures
    return report


def _stop_drive(robot: Robot) -> bool:
    """Command the drive to zero; False (logged) if the drive refused."""
    try:
        robot.hal.drive.command(0.0, 0.0)
    except Exception:                  # noqa: BLE001 - closing the devices must still happen
        log.exception("could not command the drive to zero")
        return False
    return True


def _identity(cfg: RobotConfig) -> dict:
    return {"config": cfg.path, "robot_id": cfg.robot_id, "team_size": cfg.team_size, "scheme": cfg.scheme,
            "radio_profile": cfg.radio_profile, "params_overrides": dict(cfg.overrides),
            "backends": {p.kind: p.backend for p in cfg.peripherals}}


def _print_report(report: dict, as_json: bool) -> None:
    print(strict_dumps(report, sort_keys=True) if as_json else format_report(report), flush=True)


def format_config(cfg: RobotConfig) -> str:
    """What --check prints: the configuration is valid, and what it would build."""
    lines = [f"{cfg.path}: valid (nothing opened)",
             f"robot          {cfg.robot_id} of {cfg.team_size}   scheme {cfg.scheme}   "
             f"radio profile {cfg.radio_profile or '(none)'}"]
    if cfg.overrides:
        lines.append("parameters     " + ", ".join(f"{k}={v}" for k, v in cfg.overrides))
    if cfg.world is not None:
        lines.append("world          " + ", ".join(f"{k}={v!r}" for k, v in cfg.world.items()))
    for p in cfg.peripherals:
        settings = ", ".join(f"{k}={v!r}" for k, v in p.settings.items())
        lines.append(f"{p.kind:<15}{p.backend}" + (f"   {settings}" if settings else ""))
    return "\n".join(lines)


def format_report(r: dict) -> str:
    if not r["started"]:
        return f"robot {r['robot_id']}: stopped by {r['termination']} while starting; no tick ran"
    lines = [f"robot          {r['robot_id']} of {r['team_size']}   scheme {r['scheme']}   "
             f"radio profile {r['radio_profile'] or '(none)'}   config {r['config']}",
             f"ended          {r['termination']} after {r['wall_s']:.1f} s wall (status {r['status']}); drive "
             + ("commanded to zero" if r["drive_stopped"] else "NOT confirmed stopped"),
             *([f"signed off     {r['sign_off'].replace('_', ' ')} after {r['sign_off_s']:.1f} s"]
               if r.get("sign_off") else []),
             f"ticks          {r['ticks']}: {r['tick']['overruns']} over {r['tick']['budget_ms']:.0f} ms, "
             f"{r['ticks_skipped']} skipped",
             f"{'task':<15}{'runs':>7}{'overruns':>10}{'mean ms':>10}{'max ms':>10}{'budget ms':>11}"]
    for name, t in r["tasks"].items():
        mean = f"{t['mean_ms']:>10.3f}" if t["mean_ms"] is not None else f"{'-':>10}"
        lines.append(f"  {name:<13}{t['runs']:>7}{t['overruns']:>10}{mean}{t['max_ms']:>10.3f}"
                     f"{t['budget_ms']:>11.1f}")
    if "world" in r:
        w = r["world"]
        lines.append(f"world          {w['map']}: coverage {w['coverage'] * 100:.1f} %, "
                     f"path {w['path_length_m']:.1f} m, "
                     f"drive command {w['drive_command']['v_mps']:.3f} m/s, "
                     f"{w['drive_command']['omega_radps']:.3f} rad/s")
    if r.get("error"):
        lines.append(f"error          {r['error']}")
    for failure in r.get("close_failures", ()):
        lines.append(f"not closed     {failure}")
    return "\n".join(lines)
