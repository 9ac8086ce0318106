"""Hardware in the loop: the simulated world in real time, with every device of every robot
emulated where a robot computer would find the real one, for `lorascout robot` processes.

Per robot the world serves
- an RPLIDAR A1 on a pseudo-terminal (world_sim.devices.rplidar_emulator),
- a DWM1001 on a pseudo-terminal (world_sim.devices.dwm1001_emulator),
- an RN2483 (RN2903 for us915) on a pseudo-terminal, all the team's modems on one simulated
  LoRa channel, as `lorascout modem` serves them (radio_sim.virtual_modem),
- the two ODrive axes of its differential drive on a CAN bus (world_sim.devices.odrive_emulator),
and writes the robot's configuration file pointing at them, so that `lorascout robot --config
FILE` runs unchanged, with the real drivers (hal.rplidar, hal.dwm1001, hal.rn2483,
hal.odrive_can), in a process of its own.

The CAN bus is python-can's `udp_multicast` interface (its `virtual` one reaches only its own
process). Its channel is an IPv6 multicast group of interface-local scope (ff11::/16), so the
frames never leave this host. On Linux every udp_multicast bus bound to the interface's port
hears every group joined on the host (IP_MULTICAST_ALL), so separate groups would not keep the
robots' frames apart: the team shares one bus and each robot's axes have node ids of their own
(robot r: 2r and 2r + 1). For the same reason two worlds on one host would hear each other's
axes: a world listens before it starts and refuses a bus where other axes already talk.

Time: `advance_to(now_us)` takes the drive commands that arrived, steps the world to now in
steps no longer than the lockstep simulator's tick (the same World, so the same physics), turns
the emulated wheels by what the world's wheels did, lets the LiDAR and UWB emulators send what
the world measured and the modem bank resolve the air up to now, and broadcasts the axes'
encoder estimates (every 10 ms) and heartbeats (every 100 ms). `serve` calls it every 10 ms
of the wall clock.

One clock for all: the world takes its epoch (a time.monotonic_ns() reading) once, when it has
opened its devices; its time is the monotonic clock since then, and every robot's
configuration gives that epoch to the robot's clock (`[clock] epoch_ns`), so the robot
processes and the world read the same time, the robots tick on the same 50 ms grid, and their
TDMA slots line up as in the lockstep simulator.
"""
from __future__ import annotations

import ipaddress
import json
import math
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import can
import numpy as np

from hal.lora import RadioProfile
from hal.odrive_can import GET_ENCODER_ESTIMATES, HEARTBEAT, MAX_NODE_ID, DiffDriveGeometry
from host_tools.mission import start_poses
from host_tools.safe_io import write_text
from radio_sim.channel import Channel
from radio_sim.virtual_modem import ModemBank
from world_sim.devices.dwm1001_emulator import Dwm1001Emulator
from world_sim.devices.odrive_emulator import OdriveAxes, WorldDiffDrive
from world_sim.devices.rplidar_emulator import RplidarEmulator
from world_sim.map_spec import resolve_map
from world_sim.ros_map import reachable_from_starts
from world_sim.world import World, WorldParams

CAN_INTERFACE = "udp_multicast"
# Interface-local scope (ff11::/16): a group that never leaves this host.
DEFAULT_CAN_CHANNEL = "ff11::6c6f:7261:7363:6f75:7400"
MAX_STEP_US = 50_000             # the lockstep simulator's tick: the world is never stepped further at once
SERVE_PERIOD_US = 10_000         # the world's loop on the wall clock
ENCODER_PERIOD_US = 10_000       # Get_Encoder_Estimates, as an ODrive set to send them every 10 ms
HEARTBEAT_PERIOD_US = 100_000    # ODrive's default heartbeat rate
LATE_US = 50_000                 # a world loop this much behind its slot counts as late
BUS_LISTEN_S = 0.3               # how long a world listens for another world's axes before it starts
# The emulated base: the body of the simulated robot on wheels a real base could have.
WHEEL_RADIUS_M = 0.08
TRACK_WIDTH_M = 0.40
ROBOTS_MAX = (MAX_NODE_ID + 1) // 2


class HilError(RuntimeError):
    """The world cannot be served (the bus is in use, a device cannot be opened)."""


def check_can_channel(text: str) -> str:
    """A udp_multicast channel: an IPv4 or IPv6 multicast group address."""
    try:
        address = ipaddress.ip_address(text)
    except ValueError:
        raise ValueError(f"{text!r} is no IP address; the udp_multicast bus's channel is a multicast group "
                         f"(default {DEFAULT_CAN_CHANNEL}, interface-local: it never leaves this host)") from None
    if not address.is_multicast:
        raise ValueError(f"{text!r} is no multicast address (IPv6 ff00::/8 or IPv4 224.0.0.0/4)")
    return text


def wheel_nodes(robot_index: int) -> tuple[int, int]:
    """The CANSimple node ids of robot `robot_index`'s left and right wheel axes."""
    return 2 * robot_index, 2 * robot_index + 1


def geometry_of(robot_index: int) -> DiffDriveGeometry:
    left, right = wheel_nodes(robot_index)
    return DiffDriveGeometry(left_node=left, right_node=right, wheel_radius_m=WHEEL_RADIUS_M,
                             track_width_m=TRACK_WIDTH_M, left_direction=1, right_direction=-1)


@dataclass(frozen=True)
class HilSettings:
    map_spec: str
    robots: int
    seed: int
    profile: RadioProfile
    scheme: str
    world_params: WorldParams = WorldParams()
    starts: tuple = ()
    can_channel: str = DEFAULT_CAN_CHANNEL


@dataclass
class LoopStats:
    """How the world kept up with the wall clock."""
    loops: int = 0
    late_loops: int = 0          # loops that began LATE_US or more after their slot
    max_lag_ms: float = 0.0
    steps: int = 0

    def to_json(self) -> dict:
        return {"loops": self.loops, "late_loops": self.late_loops, "max_lag_ms": round(self.max_lag_ms, 1),
                "steps": self.steps}


class HilWorld:
    """The world of `settings.robots` robots and every robot's emulated devices, opened at
    once; close() closes them all. HilError if the CAN bus is in use by other axes."""

    def __init__(self, settings: HilSettings) -> None:
        if not 1 <= settings.robots <= ROBOTS_MAX:
            raise ValueError(f"robots must be 1..{ROBOTS_MAX} (two CANSimple node ids each), got {settings.robots}")
        self.settings = settings
        occ, map_start, self.map_label = resolve_map(settings.map_spec)
        self.start_poses = start_poses(occ, map_start, settings.starts, settings.robots)
        params = settings.world_params
        self.world = World(occ, self.start_poses, settings.seed, params)
        self.reachable = reachable_from_starts(occ, self.start_poses, params.robot_radius_m)
        self.channel = Channel(settings.profile, settings.seed, occupancy=occ)
        for i in range(settings.robots):
            # The modem bank's service thread may ask for a position while this thread steps
            # the world: the pose it reads is at most one step (10 ms) old, which the path
            # loss does not notice.
            self.channel.attach(i, lambda i=i: self.world.true_pose(i)[:2])
        self.stats = LoopStats()
        self._closers: list[Callable[[], None]] = []
        try:
            self._open_devices()
        except BaseException:
            self.close()
            raise
        self.epoch_ns = time.monotonic_ns()       # the world's (and every robot's) time zero
        self._next_estimates_us = 0
        self._next_heartbeats_us = 0

    def _open_devices(self) -> None:
        s = self.settings
        try:
            self.bus = can.Bus(channel=s.can_channel, interface=CAN_INTERFACE)
        except (can.CanError, OSError) as exc:
            raise HilError(f"cannot open the CAN bus ({CAN_INTERFACE} on {s.can_channel}): {exc}; without IPv6, "
                           "give an IPv4 group (--can-channel 239.74.163.2; with a TTL of 1 its frames reach the "
                           "local network)") from exc
        self._closers.append(self.bus.shutdown)
        nodes = [n for i in range(s.robots) for n in wheel_nodes(i)]
        _refuse_a_busy_bus(self.bus, nodes, s.can_channel)
        self.axes = OdriveAxes(self.bus, nodes)
        self.drives = [WorldDiffDrive(self.world, i, self.axes, geometry_of(i)) for i in range(s.robots)]
        self.bank = ModemBank(self.channel, s.profile, list(range(s.robots)), start_us=0)
        self._closers.append(self.bank.close)
        self.lidars, self.uwbs = [], []
        for i in range(s.robots):
            self.lidars.append(RplidarEmulator(self.world, i))
            self._closers.append(self.lidars[-1].close)
            self.uwbs.append(Dwm1001Emulator(self.world, i))
            self._closers.append(self.uwbs[-1].close)

    def close(self) -> None:
        for close in reversed(self._closers):
            try:
                close()
            except Exception:          # noqa: BLE001 - close the rest whatever one of them does
                pass
        self._closers.clear()

    def __enter__(self) -> HilWorld:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- time ----------------------------------------------------------------------------
    def advance_to(self, now_us: int) -> None:
        self.axes.take_commands()
        for drive in self.drives:
            drive.apply_commands()
        world = self.world
        while world.now_us < now_us:
            dt_us = min(MAX_STEP_US, now_us - world.now_us)
            world.step(dt_us)
            self.stats.steps += 1
            for drive in self.drives:
                drive.after_step(dt_us)
        for emulator in (*self.lidars, *self.uwbs):
            emulator.advance_to(world.now_us)
        self.bank.advance_to(world.now_us)
        if world.now_us >= self._next_estimates_us:
            self.axes.broadcast_estimates()
            self._next_estimates_us = _next_slot(self._next_estimates_us, world.now_us, ENCODER_PERIOD_US)
        if world.now_us >= self._next_heartbeats_us:
            self.axes.broadcast_heartbeats()
            self._next_heartbeats_us = _next_slot(self._next_heartbeats_us, world.now_us, HEARTBEAT_PERIOD_US)

    def now_us(self) -> int:
        """The shared clock: microseconds since the world's epoch."""
        return (time.monotonic_ns() - self.epoch_ns) // 1000

    def serve(self, should_stop: Callable[[int], bool]) -> float:
        """Follow the wall clock (now_us) from now until should_stop(now_us) is true (asked
        every loop); returns the time it stopped at, in seconds since the world's epoch."""
        slot_us = self.now_us()
        while True:
            now_us = self.now_us()
            lag_us = now_us - slot_us
            self.stats.loops += 1
            self.stats.late_loops += lag_us >= LATE_US
            self.stats.max_lag_ms = max(self.stats.max_lag_ms, lag_us / 1e3)
            self.advance_to(now_us)
            if should_stop(now_us):
                return now_us / 1e6
            slot_us = _next_slot(slot_us, self.now_us(), SERVE_PERIOD_US)
            remaining_us = slot_us - self.now_us()
            if remaining_us > 0:
                time.sleep(remaining_us / 1e6)

    # -- the robots' side ----------------------------------------------------------------
    def robot_config(self, robot_index: int) -> str:
        """Robot `robot_index`'s configuration file (TOML) for `lorascout robot`: its
        devices are this world's emulators."""
        s, p = self.settings, self.settings.world_params
        x, y, yaw = self.start_poses[robot_index]
        g = geometry_of(robot_index)
        can_table = {"backend": "odrive-can", "interface": CAN_INTERFACE, "channel": s.can_channel,
                     "left_node": g.left_node, "right_node": g.right_node, "wheel_radius_m": g.wheel_radius_m,
                     "track_width_m": g.track_width_m, "left_direction": g.left_direction,
                     "right_direction": g.right_direction}
        tables = {
            "robot": {"id": robot_index, "team_size": s.robots, "scheme": s.scheme, "radio_profile": s.profile.name},
            "clock": {"backend": "monotonic", "epoch_ns": self.epoch_ns},
            "lidar": {"backend": "rplidar", "port": self.lidars[robot_index].path, "beams": p.lidar_beams,
                      "range_max_m": p.lidar_range_m},
            "odometry": {**can_table, "start_x_m": x, "start_y_m": y, "start_yaw_deg": math.degrees(yaw)},
            "drive": {**can_table, "max_v_mps": p.max_v_mps, "max_omega_radps": p.max_omega_radps,
                      "robot_radius_m": p.robot_radius_m},
            "radio": {"backend": "rn2483", "port": self.bank.paths[robot_index]},
            "uwb": {"backend": "dwm1001", "port": self.uwbs[robot_index].path},
        }
        head = (f"# Robot {robot_index} of {s.robots} in the hardware-in-the-loop world `lorascout hil` serves on "
                f"{self.map_label} (seed {s.seed}):\n# every device is an emulator of that world process, valid while "
                "it runs. Run it with `lorascout robot --config THIS_FILE`.\n")
        return head + "".join(f"\n[{name}]\n" + "".join(f"{k} = {_toml_value(v)}\n" for k, v in table.items())
                              for name, table in tables.items())

    def write_configs(self, out_dir: Path) -> list[Path]:
        paths = []
        for i in range(self.settings.robots):
            path = out_dir / f"robot{i}.toml"
            write_text(path, self.robot_config(i))
            paths.append(path)
        return paths

    def report(self) -> dict:
        """Ground truth: the team's coverage of the free area the bodies can reach from their
        starts (the lockstep simulator's definition), each robot's, and what became of each
        reception on the air (radio_sim.channel.Channel.counters)."""
        reachable = self.reachable
        total = int(reachable.sum())

        def share(observed: np.ndarray) -> float:
            return round(float((observed & reachable).sum()) / total, 6)

        w = self.world
        area_m2 = total * w.occ.resolution_m ** 2
        return {"map": self.map_label, "sim_s": round(w.now_us / 1e6, 3), "reachable_area_m2": round(area_m2, 2),
                "coverage": share(w.observed_union()),
                "robots": [{"coverage": share(w.observed(i)), "path_length_m": round(w.path_length_m(i), 3),
                            "longest_push_s": round(w.longest_push_s(i), 3),
                            "drive_command": dict(zip(("v_mps", "omega_radps"), w.command(i)))}
                           for i in range(w.n_robots)],
                "air": self.channel.counters(), "loop": self.stats.to_json()}



def _refuse_a_busy_bus(bus: can.BusABC, nodes: Sequence[int], channel: str) -> None:
    """HilError if axes on `nodes` already broadcast on the bus (another world on this host)."""
    ours = set(nodes)
    deadline = time.monotonic() + BUS_LISTEN_S
    while (left := deadline - time.monotonic()) > 0:
        msg = bus.recv(timeout=left)
        if msg is None:
            break
        node, command = msg.arbitration_id >> 5, msg.arbitration_id & 0x1F
        if node in ours and command in (GET_ENCODER_ESTIMATES, HEARTBEAT):
            raise HilError(f"CAN bus {CAN_INTERFACE} {channel}: ODrive node {node} is already broadcasting on it "
                           "(another `lorascout hil` on this host? every udp_multicast bus on one port hears every "
                           "group): stop it first")


def _next_slot(due_us: int, now_us: int, period_us: int) -> int:
    """The first slot of the `period_us` grid through `due_us` that lies after `now_us`."""
    return due_us + ((now_us - due_us) // period_us + 1) * period_us


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    return json.dumps(str(v))          # a TOML basic string for paths and names


# ---- the robot processes --------------------------------------------------------------------

@dataclass
class RobotRun:
    """One `lorascout robot` process: its configuration, log and summary files."""
    index: int
    config: Path
    log: Path
    summary: Path
    proc: subprocess.Popen | None = None
    report: dict | None = None
    exit_status: int | None = None
    exited_s: float | None = None      # when the process was seen to have ended, on the world's clock

    def poll_at(self, now_us: int) -> bool:
        """poll(), noting `now_us` (the world's time) as the end when it is first seen."""
        ended = self.poll()
        if ended and self.exited_s is None:
            self.exited_s = round(now_us / 1e6, 3)
        return ended

    def start(self) -> None:
        # A session of its own: a Ctrl-C on the terminal reaches the world, which stops the
        # robots with one SIGTERM each (a second signal would stop a robot at once).
        with open(self.log, "wb") as log, open(self.summary, "wb") as out:
            self.proc = subprocess.Popen(
                [sys.executable, "-m", "host_tools.cli", "robot", "--config", str(self.config), "--json"], stdout=out, stderr=log, stdin=subprocess.DEVNULL, start_new_session=True,
                cwd=Path(__file__).resolve().parents[1])

    def poll(self) -> bool:
        """True once the process has ended (its summary read)."""
        if self.proc is None:
            return True
        if self.exit_status is None and self.proc.poll() is not None:
            self.exit_status = self.proc.returncode
            try:
                self.report = json.loads(self.summary.read_text() or "null")
            except (OSError, json.JSONDecodeError):
                self.report = None
        return self.exit_status is not None

    def terminate(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)

    def kill(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()

    def to_json(self) -> dict:
        r = self.report or {}
        ticks = r.get("ticks") or 0
        tasks = r.get("tasks", {})
        task_overruns = {name: t["overruns"] for name, t in tasks.items()}
        tick_overruns = r.get("tick", {}).get("overruns", 0)
        worst = max([tick_overruns, *task_overruns.values()], default=0)
        return {"robot_id": self.index, "exit_status": self.exit_status, "termination": r.get("termination"),
                "status": r.get("status"), "wall_s": r.get("wall_s"),
                # The robot's tick loop, and the process's end as the world saw it, on the shared clock.
                "started_s": r.get("started_s"), "ended_s": r.get("ended_s"), "exited_s": self.exited_s,
                "sign_off": r.get("sign_off"), "sign_off_s": r.get("sign_off_s"), "ticks": ticks,
                "ticks_skipped": r.get("ticks_skipped"), "tick_overruns": tick_overruns,
                "task_overruns": task_overruns,
                "task_max_ms": {name: t["max_ms"] for name, t in tasks.items()},
                # The acceptance's figure: the most overruns of any one task (or of whole ticks) per tick.
                "worst_overrun_share": round(worst / ticks, 5) if ticks else None,
                "all_overruns_share": round((tick_overruns + sum(task_overruns.values())) / ticks, 5) if ticks
                else None,
                "error": r.get("error"), "config": str(self.config), "log": str(self.log)}


def run_hil(hil: HilWorld, runs: list[RobotRun], max_s: float | None, interrupted: Callable[[], bool],
            stop_grace_s: float = 20.0) -> str:
    """Start every robot, serve the world until they all ended (or max_s, or interrupted());
    robots still running then get SIGTERM, and `stop_grace_s` later SIGKILL. Returns why the
    world stopped: "robots_ended", "time_limit" or "interrupted"."""
    for run in runs:
        run.start()
    state = {"why": None, "stop_sent_us": None}

    def should_stop(now_us: int) -> bool:
        if all([run.poll_at(now_us) for run in runs]):
            state["why"] = state["why"] or "robots_ended"
            return True
        if state["stop_sent_us"] is None:
            why = "interrupted" if interrupted() else "time_limit" if max_s is not None and now_us >= max_s * 1e6 \
                else None
            if why is not None:
                state["why"], state["stop_sent_us"] = why, now_us
                for run in runs:
                    run.terminate()
        elif now_us - state["stop_sent_us"] > stop_grace_s * 1e6:
            for run in runs:
                run.kill()
        return False

    try:
        hil.serve(should_stop)
    finally:
        for run in runs:
            run.kill()
            run.poll()
    return state["why"]

