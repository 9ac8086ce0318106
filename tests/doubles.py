"""Shared test doubles: a clock the test steps, a fake radio, a scripted HAL, a planner rig
that runs the shared planner and a scheme on a hand-built local map, the Channel handle a
virtual modem talks to, a scripted RN2483 on a real pseudo-terminal, `lorascout modem` run
as a subprocess, a pair of ODrive axes on a python-can bus, a wall clock that moves only
when told and a task whose runs take scripted times on it, and `lorascout robot` run as a
subprocess. Tests import them from here."""
from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import threading
import time
import tty
from pathlib import Path

import can
import numpy as np

from firmware.agent import ExplorerAgent
from firmware.params import ExplorationParams, TaskRates
from firmware.schemes import build
from firmware.schemes.base import Services
from firmware.services.local_map import LocalMap
from firmware.services.planner import Plan, Planner
from firmware.services.roster import Roster
from firmware.services.targets import TargetKeeper
from firmware.services.topo_map import TopoMap
from firmware.services.waypoints import WaypointSet
from hal import rn2483_protocol as P
from hal.bundle import Hal
from hal.odrive_can import DiffDriveGeometry
from hal.lora import RadioProfile
from hal.samples import DriveLimits, LidarScan, OdometrySample, RadioRxFrame, RadioTxDone
from world_sim.devices.odrive_emulator import OdriveAxes
from world_sim.occupancy_map import OccupancyMap

REPO = Path(__file__).resolve().parents[1]


class StepClock:
    """A clock the test moves by hand (t_us)."""

    def __init__(self) -> None:
        self.t_us = 0

    def now_us(self) -> int:
        return self.t_us


class FakeRadio:
    """Half-duplex modem stand-in: busy for the profile's airtime after transmit()."""

    def __init__(self, prof: RadioProfile, refuse: bool = False):
        self.prof, self.refuse = prof, refuse
        self.now_us = 0
        self.busy_until_us = 0
        self.sent: list[tuple[int, bytes]] = []
        self.inbox: list = []

    def transmit(self, payload: bytes) -> bool:
        if self.refuse or self.busy() or len(payload) > self.prof.max_payload_bytes:
            return False
        self.sent.append((self.now_us, payload))
        self.busy_until_us = self.now_us + self.prof.airtime_us(len(payload))
        self.inbox.append(RadioTxDone(self.busy_until_us, True))
        return True

    def busy(self) -> bool:
        return self.now_us < self.busy_until_us

    def poll(self):
        out = tuple(e for e in self.inbox if e.stamp_us <= self.now_us)
        self.inbox = [e for e in self.inbox if e.stamp_us > self.now_us]
        return out

    def deliver(self, payload: bytes) -> None:
        self.inbox.append(RadioRxFrame(self.now_us, bytes(payload), -80.0, 7.5))


class ScriptedHal:
    """A robot standing still at the origin with a LiDAR that sees `ranges_m` every 100 ms;
    its radio sends nothing and hears nothing."""

    def __init__(self, ranges_m: np.ndarray):
        self.t_us = 0
        self.ranges_m = ranges_m.astype(np.float32)
        self.commands = []
        self._last_scan_us = -1

    def now_us(self):
        return self.t_us

    def latest_scan(self):
        if self.t_us - self._last_scan_us < 100_000:
            return None
        self._last_scan_us = self.t_us
        n = len(self.ranges_m)
        return LidarScan(self.t_us, -math.pi, 2 * math.pi / n, 10.0, self.ranges_m)

    def read(self):
        return OdometrySample(self.t_us, 0.0, 0.0, 0.0, 0.0, 0.0)   # the wheels never turn

    def limits(self):
        return DriveLimits(0.8, 1.5, 0.25)

    def command(self, v_mps, omega_radps):
        self.commands.append((v_mps, omega_radps))

    def ranges(self):
        return ()

    def bearings(self):
        return ()

    def transmit(self, payload):
        return False

    def busy(self):
        return False

    def poll(self):
        return ()

    def hal(self) -> Hal:
        return Hal(robot_id=0, clock=self, lidar=self, odometry=self, drive=self, radio=self, uwb=self, aoa=self)

    def run(self, agent: ExplorerAgent, seconds: float) -> ExplorerAgent:
        """Tick the agent every 50 ms until it is done or `seconds` have passed."""
        while self.t_us < seconds * 1e6 and not agent.done:
            agent.tick()
            self.t_us += 50_000
        return agent


def room(width_m: float, height_m: float, res: float = 0.1) -> OccupancyMap:
    """Free rectangle with a one-cell wall border."""
    rows, cols = int(round(height_m / res)), int(round(width_m / res))
    free = np.ones((rows, cols), dtype=bool)
    free[0, :] = free[-1, :] = free[:, 0] = free[:, -1] = False
    return OccupancyMap(free=free, resolution_m=res, origin_x_m=0.0, origin_y_m=0.0, name="room")


def paint_box(local_map: LocalMap, x0_m: float, x1_m: float, y0_m: float, y1_m: float, logodds: float) -> None:
    """Set the log-odds of the window cells from (x0, y0) to (x1, y1) m, both corners' cells
    included."""
    i0, j0 = local_map.cell_of(x0_m, y0_m)
    i1, j1 = local_map.cell_of(x1_m, y1_m)
    local_map.logodds[i0:i1 + 1, j0:j1 + 1] = logodds


class PlannerRig:
    """The shared planner and a scheme over a hand-built local map, without a robot: what
    one planning cycle decides. `local_map.logodds` is painted by the test."""

    def __init__(self, local_map: LocalMap, scheme: str = "bayer-faigl:minpos", robot_id: int = 0,
                 params: ExplorationParams = ExplorationParams()) -> None:
        self.local_map = local_map
        self.topo = TopoMap(params.d_build_m, params.d_connect_m)
        self.waypoints = WaypointSet(params)
        self.roster = Roster(robot_id)
        self.targets = TargetKeeper(params, self.waypoints)
        self.scheme = build(scheme)
        self.scheme.attach(Services(robot_id, params, TaskRates(), local_map, self.waypoints, self.topo, self.roster,
                                    send=None, mesh=None, last_scan_binned=None, has_planned=lambda: True))
        self.planner = Planner(params, local_map, self.topo, self.waypoints, self.targets, self.scheme)

    def plan(self, x_m: float, y_m: float, now_us: int = 1_000_000) -> Plan:
        return self.planner.plan(x_m, y_m, now_us)

    def stat(self, name: str) -> int:
        """A counter of the scheme's (Scheme.stats) or of how targets ended (targets_*)."""
        if name.startswith("targets_"):
            return self.targets.counts[name[len("targets_"):]]
        return self.scheme.stats()[name]


def deliverable_sigint() -> None:
    """Popen's preexec_fn for a child a test will interrupt: SIGINT at its default, as under
    a terminal. A test run started in the background (`make test &`, some CI runners)
    inherits SIGINT ignored, and a Python child would then never see its Ctrl-C."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def in_thread(fn):
    """Run fn() on a daemon thread: (the thread, a box that gets "value" or "error")."""
    box: dict = {}

    def run():
        try:
            box["value"] = fn()
        except BaseException as e:  # handed to the test thread
            box["error"] = e

    t = threading.Thread(target=run, daemon=True)
    t.start()
    return t, box


def send_to_a_listening_library(ours, receive, payload: bytes, timeout_s: float = 8.0):
    """Start `receive()` (a third-party library's blocking receive) on a thread and let our
    modem backend `ours` transmit `payload` until it returns: the thread's box."""
    t, box = in_thread(receive)
    deadline = time.monotonic() + timeout_s
    while t.is_alive() and time.monotonic() < deadline:
        if not ours.busy():
            ours.transmit(payload)
        ours.poll()
        time.sleep(0.05)
    t.join(timeout=1)
    return box


class FakePort:
    """Records what a virtual modem asks of the Channel (radio_sim.rn2483.AirPort); answers
    transmit as the Channel does, with the profile's airtime at the profile's operating point
    and the modem's own airtime elsewhere."""

    def __init__(self, profile):
        self.profile = profile
        self.calls: list[tuple] = []             # ("tx", payload, now_us) / ("listen", on, now_us)
        self.tx_air: list[tuple] = []            # (AirInterface, tx_power_dbm) per transmit
        self.listen_air: list = []               # AirInterface per set_listening
        self.refuse = False

    def transmit(self, payload, now_us, air, tx_power_dbm):
        self.calls.append(("tx", bytes(payload), now_us))
        self.tx_air.append((air, tx_power_dbm))
        if self.refuse:
            return None
        if air == self.profile.air_interface():
            return now_us + self.profile.airtime_us(len(payload))
        return now_us + air.airtime_us(len(payload))

    def set_listening(self, listening, now_us, air):
        self.calls.append(("listen", listening, now_us))
        self.listen_air.append(air)


class ScriptedModem(threading.Thread):
    """An RN2483 on a real pty that answers from a script: each `radio rx 0` delivers the
    next scripted line (a frame, `radio_err`, or nothing: the modem then stays silent, as
    with no traffic); commands in `refuse` answer invalid_param, others `ok` or the value a
    module gives. `reply_delay_s` holds every answer back that long, as a module behind a
    slow UART would (a 255-byte `radio tx` alone is about 90 ms at 57600 baud)."""

    def __init__(self, rx_lines, reply_delay_s: float = 0.0):
        super().__init__(daemon=True)
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self.path = os.ttyname(self.slave)
        self.rx_lines = list(rx_lines)
        self.commands: list[str] = []
        self.refuse: set[str] = set()
        self.stop = threading.Event()
        self.reply_delay_s = reply_delay_s

    def send(self, line):
        os.write(self.master, (line + "\r\n").encode())

    def run(self):
        try:
            self._serve()
        except OSError:         # the test closed the pty: the modem is unplugged
            return

    def _serve(self):
        answers = {P.SYS_GET_VER: P.RN2483.version_line, P.SYS_RESET: P.RN2483.version_line,
                   P.MAC_PAUSE: str(P.MAC_PAUSE_MS), P.RADIO_GET_RSSI: "-97", P.RADIO_GET_SNR: "-5"}
        buf = b""
        while not self.stop.is_set():
            try:
                chunk = os.read(self.master, 1024)
            except OSError:
                return
            buf += chunk
            while b"\r\n" in buf:
                raw, buf = buf.split(b"\r\n", 1)
                cmd = raw.decode()
                self.commands.append(cmd)
                if self.reply_delay_s:
                    time.sleep(self.reply_delay_s)
                if cmd in self.refuse:
                    self.send(P.INVALID_PARAM)
                elif cmd == P.RADIO_RX_CONTINUOUS:
                    self.send(P.OK)
                    if self.rx_lines:
                        self.send(self.rx_lines.pop(0))
                else:
                    self.send(answers.get(cmd, P.OK))

    def close(self):
        self.stop.set()
        os.close(self.slave)      # with no slave fd left, the master read fails and run() returns
        self.join(timeout=2)
        os.close(self.master)


class ModemServer:
    """`lorascout modem` as a user runs it: a subprocess serving virtual modems on ptys in
    wall-clock time; `paths` are the devices it printed."""

    def __init__(self, count: int, *extra: str):
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "host_tools.cli", "modem", "--count", str(count), *extra],
            cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=deliverable_sigint,
        )
        self.paths = [self.proc.stdout.readline().strip() for _ in range(count)]
        if not all(p.startswith("/dev/") for p in self.paths):
            self.proc.kill()
            raise AssertionError(f"lorascout modem printed {self.paths!r}; stderr: {self.proc.stderr.read()}")

    def stop(self, sig=signal.SIGINT) -> int:
        self.proc.send_signal(sig)
        try:
            return self.proc.wait(timeout=10)
        finally:
            if self.proc.poll() is None:
                self.proc.kill()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()


class FakeAxes:
    """Two emulated ODrive axes on the bus (world_sim.devices.odrive_emulator, the HIL world's
    axes): they take the drive's commands and, on `run`, turn at the commanded speed and
    broadcast their encoder estimates every `period_s`."""

    def __init__(self, channel: str, geometry: DiffDriveGeometry) -> None:
        self.bus = can.Bus(channel, interface="virtual")
        self.nodes = (geometry.left_node, geometry.right_node)
        self.emulated = OdriveAxes(self.bus, self.nodes)

    @property
    def turns(self) -> dict[int, float]:
        return {n: self.emulated[n].turns for n in self.nodes}

    @property
    def velocity(self) -> dict[int, float]:
        """The last velocity each axis was sent."""
        return {n: self.emulated[n].input_vel for n in self.nodes}

    @property
    def state(self) -> dict[int, int]:
        return {n: self.emulated[n].state for n in self.nodes}

    @property
    def control_mode(self) -> dict[int, int | None]:
        return {n: self.emulated[n].control_mode for n in self.nodes}

    def take_commands(self) -> None:
        self.emulated.take_commands()

    def run(self, seconds: float, period_s: float = 0.01) -> None:
        self.take_commands()
        for _ in range(round(seconds / period_s)):
            for n in self.nodes:
                axis = self.emulated[n]
                axis.turn(axis.commanded_turns_per_s() * period_s, period_s)
            self.emulated.broadcast_estimates()


class ManualWallClock(StepClock):
    """A wall clock for host_tools.robot_loop that moves only when told: sleeping jumps to
    the deadline, and work (a scripted slow task) moves it by `spend_us`."""

    def sleep_until_us(self, t_us: int) -> None:
        self.t_us = max(self.t_us, t_us)

    def spend_us(self, took_us: int) -> None:
        self.t_us += took_us


class ScriptedSlowTask:
    """A firmware task (firmware.scheduler.Task's `run`) whose runs take the scripted times
    on a ManualWallClock, in turn."""

    def __init__(self, clock: ManualWallClock, took_us: list[int]) -> None:
        self.clock = clock
        self.took_us = took_us
        self.runs = 0

    def __call__(self, now_us: int) -> None:
        self.clock.spend_us(self.took_us[self.runs % len(self.took_us)])
        self.runs += 1


class RobotProcess:
    """`lorascout robot` as a user runs it: a subprocess whose stderr (the log) is read on a
    thread, so a test can wait for a line and then signal it."""

    def __init__(self, *argv: str):
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "host_tools.cli", "robot", *argv], cwd=REPO, stdout=subprocess.PIPE,
            stderr=subprocess.PIPE, text=True, preexec_fn=deliverable_sigint)
        self.log_lines: list[str] = []
        self._reader = threading.Thread(target=self._read_log, daemon=True)
        self._reader.start()

    def _read_log(self) -> None:
        for line in self.proc.stderr:
            self.log_lines.append(line)

    def wait_for_log(self, text: str, timeout_s: float) -> str:
        """The first log line holding `text`; AssertionError if none came within timeout_s."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            found = [line for line in self.log_lines if text in line]
            if found:
                return found[0]
            if self.proc.poll() is not None and not self._reader.is_alive():
                break
            time.sleep(0.05)
        raise AssertionError(f"no log line with {text!r} within {timeout_s} s; log: {''.join(self.log_lines)[-2000:]}")

    def stop(self, sig: int, timeout_s: float = 10.0) -> tuple[int, str]:
        """Send `sig`; (exit status, stdout) once the process ended."""
        self.proc.send_signal(sig)
        try:
            self.proc.wait(timeout=timeout_s)      # the summary is small: it fits the pipe's buffer
        finally:
            if self.proc.poll() is None:
                self.proc.kill()
        self._reader.join(timeout=2)
        return self.proc.returncode, self.proc.stdout.read()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()


def write_grid(folder, name: str, trials: list[dict]):
    """A sweep's --out holding these trials as its trials.jsonl."""
    import json
    out = folder / name
    out.mkdir()
    (out / "trials.jsonl").write_text("".join(json.dumps(t) + "\n" for t in trials))
    return out
