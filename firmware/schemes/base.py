"""The interface every coordination scheme implements, and what the firmware hands it.

A scheme declares its name, its variants, the record types it owns (its dialect, a
firmware.comms.schema.Dialect defined in its package's records.py) and what it needs from
the HAL. The agent gives it the shared services (`Services`) once, then tells
it what happens: records received from its dialect, travel, the end of a target, the end of
a planning cycle. It may add periodic tasks of its own. In each planning cycle it owns one
stage, in two steps, run by the shared planner (firmware.services.planner):

    filter_waypoints(view)   which of this robot's waypoints it still wants (before this
                             cycle's target outcome is decided)
    rank(view, own)          own candidates in, the ranked candidates it wants out: filter,
                             add team targets, cost beyond the local window, rank (where a
                             grid path in the local map reaches a candidate, the planner
                             costs it by that path instead)

Choosing among the ranked candidates, routing and strike keeping stay in the shared
services. A scheme never touches another scheme's state, and host tools ask it for its
statistics (`stats`) and drawable geometry (`drawables`) instead of reaching in.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Hashable, Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, Protocol

import numpy as np

from firmware.comms.schema import Dialect
from firmware.params import ExplorationParams, TaskRates
from firmware.scheduler import Task
from firmware.services.local_map import BinnedScan, LocalMap
from firmware.services.deployment import Deployment
from firmware.services.pose import TravelMilestones
from firmware.services.roster import Roster
from firmware.services.targets import Candidate, Target
from firmware.services.topo_map import TopoMap
from firmware.services.waypoints import WaypointSet
from hal.interfaces import MeshLink, UwbRanger, WifiAoa
from hal.samples import LidarScan, OdometrySample

# What a scheme may need from the robot (Scheme.needs):
NEEDS = {
    "radio": "the LoRa modem and a radio profile (the link layer)",
    "relay": "the link layer's managed flooding (multi-hop)",
    "uwb": "a UWB ranger",
    "aoa": "a WiFi angle-of-arrival sensor",
    "mesh": "a high-bandwidth mesh link (dense-map baselines)",
    "shared_frame": "odometry in one frame shared by the whole team",
    "region_map": "the building's doorways, loaded into the scheme before it starts (the scheme checks)",
    "floor_plan": "the deployment's boundary and coarse floor plan (where there is navigable area), given before "
                  "the start",
}

# Link-layer priorities for the records schemes send: higher goes first.
PRIORITY_INFO = 1
PRIORITY_MOTION = 2
PRIORITY_STATUS = 3


class Send(Protocol):
    def __call__(self, rtype: str, values: Mapping[str, int], priority: int, key: Hashable | None = None) -> bool:
        """Queue a record for the air: higher priority first; a queued record with the same
        key is replaced. False if the link dropped it."""


@dataclass(frozen=True)
class Services:
    """The shared services a scheme works with; the agent owns them."""

    robot_id: int
    params: ExplorationParams
    rates: TaskRates
    local_map: LocalMap
    waypoints: WaypointSet
    topo: TopoMap                   # the places visited; routes beyond the local window
    roster: Roster
    send: Send | None               # (record type, values, priority) onto the air; None without a link
    mesh: MeshLink | None
    last_scan_binned: Callable[[], BinnedScan]   # the newest scan in world-frame bins
    has_planned: Callable[[], bool]              # a planning cycle has run (waypoints exist)
    queued: Callable[[str], int] = lambda rtype: 0          # records of a type waiting on the link
    withdraw: Callable[[Hashable], bool] = lambda key: False   # take a queued record back by its key
    on_air_until_us: Callable[[], int] = lambda: 0           # when this robot's last frame ends on the air
    radio_Bps: float | None = None       # bytes a second the link can send for ever (LinkLayer.sustained_Bps)
    bytes_sent: Callable[[], int] = lambda: 0               # bytes this robot has put on the air so far
    missed_from: Callable[[int], list[int]] = lambda sender: []    # a teammate's frames lost lately (seqs)
    keys_sent_in: Callable[[int], tuple] = lambda seq: ()         # keys of the records in an own recent frame
    current_target: Callable[[], Target | None] = lambda: None   # where the robot is heading
    # This robot's pose (x_m, y_m, yaw_rad) at a time, for samples taken then (services.pose).
    pose_at: Callable[[int], tuple[float, float, float] | None] = lambda stamp_us: None
    uwb: UwbRanger | None = None                 # with "uwb" in the scheme's needs
    aoa: WifiAoa | None = None                   # with "aoa" in the scheme's needs
    deployment: Deployment | None = None         # what the team knew before it started, if anything
    # The newest scan as taken, with the pose at its time stamp (x_m, y_m, yaw_rad, scan), in
    # the robot's odometry frame; None before the first.
    last_scan: Callable[[], tuple[float, float, float, LidarScan] | None] = lambda: None


@dataclass
class PlanningView:
    """One planning cycle as the scheme's stage sees it."""

    x_m: float
    y_m: float
    now_us: int
    sight: np.ndarray                       # the local map's sight layer (firmware.kernels states)
    target: Target | None                   # the robot's current target, if any
    blocked_edges: frozenset                # topological edges this robot found crossing walls
    graph_costs: Callable[[list[Candidate]], np.ndarray]   # metres along the topological graph
    # The robot has nothing left of its own and takes a last look (WaypointSet.look_again):
    # a scheme may leave that place to a teammate only if the teammate reported having seen
    # it, not because it passed nearby.
    closing: bool = False
    # The local map's cells a grid path reaches from the robot this cycle (None: not given).
    reachable: np.ndarray | None = None


class Scheme(ABC):
    name: ClassVar[str]
    doc: ClassVar[str]
    variants: ClassVar[Mapping[str, str]] = {"": ""}   # variant -> what it does
    default_variant: ClassVar[str] = ""
    dialect: ClassVar[Dialect | None] = None           # its records on the air (None: sends none of its own)
    needs: ClassVar[frozenset[str]] = frozenset()
    relay_hops: ClassVar[int] = 3      # with "relay" in needs: how many hops its frames may travel
    # Its own parameters (a frozen dataclass declared with firmware.declared), changed with
    # `--set NAME.FIELD=VALUE` where NAME is the scheme's; a scheme with a params_type takes
    # `params=` in its constructor. None: it has none beyond firmware.params.
    params_type: ClassVar[type | None] = None

    def __init__(self, variant: str = "") -> None:
        self.variant = self.checked_variant(variant)
        self.s: Services | None = None

    @classmethod
    def checked_variant(cls, variant: str) -> str:
        """The variant asked for ("" for the default); ValueError naming the known ones."""
        variant = variant or cls.default_variant
        if variant not in cls.variants:
            raise ValueError(f"scheme {cls.name!r} has no variant {variant!r}; "
                             f"known: {', '.join(v for v in cls.variants if v) or 'none'}")
        return variant

    @classmethod
    def default_params(cls, variant: str) -> Any:
        """The parameters a variant runs with unless `--set` changes them."""
        return cls.params_type()

    @property
    def records(self) -> tuple[str, ...]:
        """The names of its dialect's record types."""
        return tuple(r.name for r in self.dialect.records) if self.dialect is not None else ()

    @property
    def spec(self) -> str:
        return f"{self.name}:{self.variant}" if self.variant else self.name

    def needs_of(self) -> frozenset[str]:
        """What this instance needs (a scheme composing another adds its needs)."""
        return self.needs

    def attach(self, services: Services) -> None:
        """Called once at setup, before any other call."""
        self.s = services

    def tasks(self) -> list[Task]:
        """Periodic tasks of the scheme's own, run after the core radio task."""
        return []

    def on_record(self, rtype: str, values: Mapping[str, int], now_us: int) -> None:
        """A record of this scheme's dialect, received from a teammate."""

    def on_travel(self, pose: OdometrySample, now_us: int) -> None:
        """Every control tick while the robot explores, with its current pose."""

    def on_target_outcome(self, target: Target, outcome: str) -> None:
        """A target ended (firmware.services.targets: reached, seen_on_way, unreachable,
        stalled)."""

    def filter_waypoints(self, view: PlanningView) -> None:
        """Drop from Services.waypoints what this scheme no longer wants this robot to
        explore (e.g. what teammates have covered)."""

    @abstractmethod
    def rank(self, view: PlanningView, own: list[Candidate]) -> list[Candidate]:
        """The candidates the robot should choose among, each with graph_cost_m (its cost
        beyond the local window) and rank set."""

    def wake_up(self, now_us: int) -> bool:
        """A robot that finished asks this every planning cycle: True if what teammates
        told it since may show it more to explore (a teammate's map can lag behind, or be
        wrong, where this robot stopped), so it plans again and goes on if there is."""
        return False

    def on_finished(self, frontiers_left_xy: np.ndarray) -> None:
        """The robot found nothing more to explore and stopped (wake_up may start it again).
        frontiers_left_xy: the middles (n, 2, metres) of the frontiers it leaves in all it
        has mapped (given up, or behind gaps narrower than its body); none elsewhere."""

    def has_news(self) -> bool:
        """Something this robot still has to tell its team (records of its own waiting to
        go): a mission in which every robot finished ends once no robot has any."""
        return False

    def after_plan(self, pose: OdometrySample, now_us: int) -> None:
        """After each planning cycle (before a finished robot reports done)."""

    def stats(self) -> dict[str, int]:
        """Counters for the mission report (stable keys)."""
        return {}

    def digests(self) -> dict[str, str]:
        """The team's shared state as this robot holds it, as digests that are equal on two
        robots exactly when they hold the same (for the mission report); {} for a scheme
        that keeps none."""
        return {}

    def drawables(self) -> dict[str, Any]:
        """Geometry for plots: any of
        "points" (N x 2 m), "segments" (M x 2 x 2 m), "highlight" (bool per point),
        "title" (what they are), "what" (what one point is, for the legend), "regions" (an
        int per point: a partition the team shares, drawn by colour, the first robot's alone)."""
        return {}


def cost_along_graph(view: PlanningView, candidates: list[Candidate]) -> None:
    """Each candidate's cost beyond the local window: along the topological graph."""
    for c, cost in zip(candidates, view.graph_costs(candidates)):
        c.graph_cost_m = float(cost)


class OwnPlaces:
    """This robot's own places, a topological vertex every d_build of travel, kept to route
    beyond the local window and never sent: for schemes that share no topological map."""

    def __init__(self, services: Services) -> None:
        self.s = services
        self._milestones = TravelMilestones(services.params.d_build_m)

    def on_travel(self, pose: OdometrySample) -> None:
        if not self._milestones.due(pose.x_m, pose.y_m) or not self.s.has_planned():
            return
        # A place of its own (presence, no information): only its position is ever read.
        self.s.topo.add((self.s.robot_id, round(pose.x_m * 100), round(pose.y_m * 100), 0, 1, 0, 0))
        self._milestones.mark(pose.x_m, pose.y_m)
