"""Shared test doubles: clocks, a fake radio, a scripted HAL, and a planner rig that runs the
shared planner and a scheme on a hand-built local map. Tests import them from here."""
from __future__ import annotations

import math

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
from hal.bundle import Hal
from hal.lora import RadioProfile
from hal.samples import DriveLimits, LidarScan, OdometrySample, RadioRxFrame, RadioTxDone


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
