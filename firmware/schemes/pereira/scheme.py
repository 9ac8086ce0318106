"""Pereira, Moreira & Veloso (CONTROLO 2014) as a scheme: regions and their exploration
statuses shared over LoRa, frontier categories and a conflict rule (pereira.md).

Each robot publishes evidence as records of its own counter (oseq): a `place` every
d_build_m of travel with the disc its map certifies free, and a `gate` (a doorway, a
corridor mouth) once its map has shown it on three looks in a row (gates.py). Every robot
folds the places and gates it holds into the same region graph (regions.py, store.py).
After each planning cycle it judges which regions it has explored (A2: every place of the
region known in its window, none of its waypoints there, two cycles in a row) and says so,
or takes it back, in a `claim`; the claims it hears give each region's e^o (status.py: eq.
1 and 2, the same-robot override, the loop rule, no clock).

The oracle variant (`pereira:oracle`) holds the doorways of a region map the host loads
as gate records of origin 254 from the start and finds no gates of its own.

Its planning stage places waypoints in regions by its label grid (labels.py), then:
waypoints in regions a teammate's claim calls explored are left to the
team (A5, A6; a robot with nothing else left heads for a region a teammate explores
along their places, or, with none, or no teammate exploring, takes back those still worth
it); the others are
ranked by category (f^fu, f^c, f^fs, f^o) and by Algorithm 1's conflict rule with eq. (3)
against the `intent`s teammates broadcast (choice.py); the shared choice takes the
cheapest of the best rank. Records reach robots out of range through others: a `summary`
every pereira_summary_period_s, answered with what the summariser lacks (gossip.py).
Beyond the local window it routes along a graph of its own places.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import cKDTree

from firmware import kernels
from firmware.scheduler import Task
from firmware.schemes.base import (PRIORITY_INFO, PRIORITY_MOTION, PRIORITY_STATUS, Candidate, OwnPlaces, PlanningView,
                                   Scheme, Services, cost_along_graph)
from firmware.schemes.pereira.choice import CONFLICT_RANK, OTHER, Whereabouts, categorise, conflicts
from firmware.schemes.pereira.gates import GateTracker, detect_gates, place_clear_dm
from firmware.schemes.pereira.gossip import Holdings
from firmware.schemes.pereira.labels import NONE as NO_LABEL
from firmware.schemes.pereira.labels import gate_cells, label_grid
from firmware.schemes.pereira.params import with_tuning
from firmware.schemes.pereira.records import (DIALECT, EMPTY_ORIGIN, GOAL_DIST_MAX_DM, ORACLE_ORIGIN, OSEQ_BITS,
                                              SUMMARY_SLOTS, Claim, Gate, Intent, Place, Summary, dm, encode,
                                              serial_newer, typed, values_of)
from firmware.schemes.pereira.regions import RegionGraph
from firmware.schemes.pereira.store import Store
from firmware.services.local_map import grid_cells_of
from firmware.services.pose import TravelMilestones
from firmware.services.team_view import unseen_after_team_view_bit
from hal.samples import OdometrySample

IDLE, EXPLORING, DONE = 0, 1, 2            # records.INTENT_STATES
LINK_BACK_MAX = 15                         # the place record's 4-bit link_back
PUSH_BACKLOG = 4                           # pushed records waiting on the link at most
NEWS_READ_S = 0.2                          # a frame that left the air is read within this long
# A finished robot keeps the mission going while a teammate's summary, heard less than this
# many summary periods ago, shows it lacking some of the robot's own records: summaries get
# them pushed. A teammate not heard that long is out of range; gossip reaches it later or never.
SETTLE_SUMMARY_PERIODS = 3
WINDOW_MARGIN_CELLS = 2                    # a region judged explored lies this far inside the window
_OWN_TYPES = ("place", "gate", "claim")


class Pereira(Scheme):
    name = "pereira"
    doc = "Pereira et al.'s region statuses merged without clocks, frontier categories and eq. (3), over LoRa"
    variants = {"": "regions from gates and places, statuses as claims, categories and eq. (3), gossip for multi-hop",
                "oracle": "the same, with regions cut at the doorways of a region map the host loads (the ground "
                          "truth's: the paper's oracle condition) instead of gates the robots find",
                "nogossip": "the same without summaries and pushes: a robot holds only the records it heard from "
                            "their origins (the multi-hop ablation)"}
    dialect = DIALECT
    needs = frozenset({"radio", "shared_frame"})

    def __init__(self, variant: str = "") -> None:
        super().__init__(variant)
        self._doorways: tuple[Gate, ...] | None = None

    def needs_of(self) -> frozenset[str]:
        return self.needs | {"region_map"} if self.variant == "oracle" else self.needs

    def load_region_map(self, doorways: Sequence[tuple[int, int, int, int]]) -> None:
        """The team's region map (the oracle variant): doorways in the shared frame as a gate
        record carries them, (x_dm, y_dm, dir_code, half_2cm), e.g. host_tools.region_oracle's
        doorways of the ground truth. They become gate records of origin ORACLE_ORIGIN, held
        by every robot from the start and never sent; the robot then finds no gates of its
        own. Given before the agent starts; ValueError for a value a gate record cannot carry."""
        if self.variant != "oracle":
            raise ValueError(f"scheme {self.spec} finds its own gates; only {self.name}:oracle loads a region map")
        gates = []
        for k, d in enumerate(doorways):
            g = Gate(ORACLE_ORIGIN, k + 1, *(int(v) for v in d))
            try:
                encode(g)
            except ValueError as exc:
                raise ValueError(f"region map: doorway {k + 1} {tuple(d)}: {exc}") from None
            gates.append(g)
        if len(gates) >= 1 << OSEQ_BITS:
            raise ValueError(f"region map: {len(gates)} doorways, at most {(1 << OSEQ_BITS) - 1}")
        self._doorways = tuple(gates)

    def attach(self, services: Services) -> None:
        super().attach(services)
        p = services.params
        if self.variant == "oracle" and self._doorways is None:
            raise ValueError(f"scheme {self.spec} needs the team's region map: give it with load_region_map "
                             "before the robot starts")
        self.pp = with_tuning(p.pereira_widening_kappa)
        self._push_max = 0 if self.variant == "nogossip" else p.pereira_push_max   # 0: no gossip at all
        self.store = Store(self._doorways or (), params=self.pp)
        self.holdings = Holdings()
        self.tracker = GateTracker(self.pp)
        self.where = Whereabouts(p.pereira_margin_m)
        self._own_places = OwnPlaces(services)
        self._milestones = TravelMilestones(p.d_build_m)
        self._oseq = 0
        self._last_place_oseq: int | None = None
        self._passed_over: tuple[float, float, int] | None = None   # the last place skipped: x, y (m), clear (dm)
        self._on_covered_ground = False                      # the last milestone had a place of the graph near
        self._last_resort: set[tuple[float, float]] = set()   # claimed waypoints no teammate came near: ranked last
        self._intents: dict[int, tuple[Intent, int]] = {}     # teammate -> (last intent, when heard)
        self._iseq = 0
        self._said_intent: tuple[int, int, int, int] | None = None   # state, category, goal x dm, goal y dm
        self._said_intent_us = 0
        self._claimed: dict[tuple[int, ...], tuple[int, int, int, int]] = {}   # region id -> anchor x, y, sig, explored
        self._clean: dict[tuple[int, ...], int] = {}         # region id -> cycles in a row it looked explored
        self._category: dict[tuple[float, float], int] = {}  # this cycle's candidates' categories
        self._sight: np.ndarray | None = None
        self._grid: tuple | None = None                      # graph, cycle time, row0, col0, label grid
        self._theirs: tuple | None = None                    # graph, teammates' places (m), their k-d tree
        self._xy = (0.0, 0.0)                                # the robot's position at the last plan
        self._view_key: tuple | None = None
        self._explored_others: set[int] = set()
        self._outbox: dict[tuple[int, int], tuple[str, Place | Gate | Claim]] = {}
        self._summary_turn = 0
        self._held_at_heard: dict[int, dict[int, int]] = {}  # teammate -> what was held when its last summary came
        # teammate -> (upto of this robot's records its last summary gave, when heard)
        self._mine_held_by: dict[int, tuple[int, int]] = {}
        # Regions of waypoints this cycle dropped on teammates' word (a claim) or on a model of
        # what their places saw: not this robot's own judgement, so not a claim of its own.
        self._left_labels: set[int | None] = set()
        self._outbox_us = self._news_until_us = 0
        self._finished = False
        self._retracted = False                              # a teammate took a claim back since wake_up looked
        self._woken_us = 0
        self.counts = dict.fromkeys((
            "places_sent", "gates_sent", "claims_sent", "claims_retracted", "intents_sent", "summaries_sent",
            "records_pushed", "pushes_withdrawn", "records_heard_new", "waypoints_left_to_team", "waypoints_taken_back",
            "choices_yielded", "records_dropped_by_link", "claims_on_stopping", "transit_choices",
            "waypoints_seen_by_team", "claimed_waypoints_kept", "places_skipped"), 0)

    def tasks(self) -> list[Task]:
        p = self.s.params
        return [Task("pereira_gates", 1.0 / p.pereira_gate_period_s, self._task_gates),
                Task("pereira_summary", 1.0 / p.pereira_summary_period_s, self._task_summary),
                Task("pereira_outbox", self.s.rates.radio_hz, self._task_outbox)]

    # --- own evidence -----------------------------------------------------------------
    def _next_oseq(self) -> int:
        self._oseq = self._oseq % ((1 << OSEQ_BITS) - 1) + 1
        return self._oseq

    def _publish(self, name: str, record: Place | Gate | Claim, priority: int) -> None:
        """Own records go into the own set at once and onto the air."""
        self.store.add(record)
        self.holdings.add(name, record)
        self.counts[f"{name}s_sent"] += 1
        if self.s.send is not None and not self.s.send(name, values_of(record), priority):
            self.counts["records_dropped_by_link"] += 1

    def on_travel(self, pose: OdometrySample, now_us: int) -> None:
        """A place every d_build_m of travel, with the disc the robot's map shows free; none
        where the region graph holds a place within pereira_place_skip_m already (a robot
        driving ground the team has driven tells no one anything, and every place it adds
        changes the region's signature, which undoes the claims on it). The first place on
        such ground is sent (its trajectory edge joins the robot's last place to the old
        ones); leaving it, the robot sends the last place it passed over first, so its new
        places join the graph where the old ones lie and no trajectory edge spans the gap."""
        self._own_places.on_travel(pose)
        x_m, y_m = pose.x_m, pose.y_m
        if not self._milestones.due(x_m, y_m) or not self.s.has_planned():
            return
        lm, res = self.s.local_map, self.s.params.resolution_m
        i, j = lm.cell_of(x_m, y_m)
        r = int(math.ceil(self.pp.clear_cap_m / res)) + 3
        i0, i1, j0, j1 = max(0, i - r), min(lm.n, i + r + 1), max(0, j - r), min(lm.n, j + r + 1)
        if i0 >= i1 or j0 >= j1:
            return
        clear = place_clear_dm(lm.state_of(i0, i1, j0, j1), lm.row0 + i0, lm.col0 + j0, res, x_m, y_m, self.pp)
        self._milestones.mark(x_m, y_m)
        skip_dm = self.s.params.pereira_place_skip_m * 10
        covered = skip_dm > 0 and len(self.store.graph().places_within(x_m * 10, y_m * 10, skip_dm)) > 0
        was_covered, self._on_covered_ground = self._on_covered_ground, covered
        if covered and was_covered:
            self._passed_over = (x_m, y_m, clear)
            self._last_place_oseq = None
            self.counts["places_skipped"] += 1
            return
        if self._passed_over is not None:
            self._send_place(*self._passed_over)
            self._passed_over = None
        self._send_place(x_m, y_m, clear)

    def _send_place(self, x_m: float, y_m: float, clear_dm: int) -> None:
        oseq = self._next_oseq()
        gap = (oseq - self._last_place_oseq) % (1 << OSEQ_BITS) if self._last_place_oseq is not None else 0
        link_back = gap if 0 < gap <= LINK_BACK_MAX else 0
        self._publish("place", Place(self.s.robot_id, oseq, dm(x_m), dm(y_m), clear_dm, link_back), PRIORITY_MOTION)
        self._last_place_oseq = oseq

    def _task_gates(self, now_us: int) -> None:
        """Gates in the robot's own window; one record for each newly confirmed gate the
        region graph does not hold yet."""
        if self._finished or not self.s.has_planned() or self._doorways is not None:
            return      # (the oracle variant's regions are the region map's)
        lm, p = self.s.local_map, self.s.params
        # Only around the robot, where its map changes (the sensor's reach, d_cam_m, and a
        # gate's widening radius beyond): gates farther off were looked at when the robot
        # was there, and the whole window costs three times as much. The crop is bordered
        # by unknown cells, so no gate is found against its edge (detect_gates wants the
        # surroundings of a gate observed).
        i, j = lm.cell_of(*self._xy)
        r = int(math.ceil((p.d_cam_m + self.pp.widening_radius_m) / p.resolution_m))
        i0, i1, j0, j1 = max(0, i - r), min(lm.n, i + r + 1), max(0, j - r), min(lm.n, j + r + 1)
        if i0 >= i1 or j0 >= j1:
            return
        state = np.full((i1 - i0 + 2, j1 - j0 + 2), kernels.UNKNOWN, np.uint8)
        state[1:-1, 1:-1] = lm.state_of(i0, i1, j0, j1)
        seen = detect_gates(state, lm.row0 + i0 - 1, lm.col0 + j0 - 1, p.resolution_m, self.pp)
        graph = self.store.graph()
        folded = [graph.gate_key(g) for g in range(len(graph.gates))]
        for g in self.tracker.update(seen, folded):
            x, y, d, half = g.wire()
            self._publish("gate", Gate(self.s.robot_id, self._next_oseq(), x, y, d, half), PRIORITY_STATUS)

    # --- what the robot hears ---------------------------------------------------------
    def on_record(self, rtype: str, values: Mapping[str, int], now_us: int) -> None:
        me = self.s.robot_id
        if rtype in _OWN_TYPES:
            self._cancel_push(values["sender_id"], values["oseq"])
        if values["sender_id"] == me:
            return      # own records relayed back: this robot's view of them is its own (loop rule)
        if values["sender_id"] in (EMPTY_ORIGIN, ORACLE_ORIGIN):
            return      # no robot: an empty summary slot's id, or the region map's (loaded, never heard)
        if rtype == "intent":
            it = typed(rtype, values)
            held = self._intents.get(it.sender_id)
            if held is None or serial_newer(it.iseq, held[0].iseq, 8) or \
                    now_us - held[1] > self.s.params.pereira_intent_expiry_s * 1e6:
                self._intents[it.sender_id] = (it, now_us)
            self.s.roster.heard_at(it.sender_id, it.x_dm / 10.0, it.y_dm / 10.0, now_us)
            return
        if rtype == "summary":
            s = typed(rtype, values)
            said = dict(s.entries)
            if me in said or len(s.entries) < SUMMARY_SLOTS:    # a full summary may leave this robot out
                self._mine_held_by[s.sender_id] = (said.get(me, 0), now_us)
            # Only records held when this teammate's previous summary came are pushed: a
            # summary waits for its sender's slot and is seconds old when heard, so records
            # the whole team heard from their origin since would look lacking. A summary
            # period later they no longer do unless the teammate really lost them.
            held_then = self._held_at_heard.get(s.sender_id, {})
            self._held_at_heard[s.sender_id] = self.holdings.snapshot()
            for name, record in self.holdings.to_push(s.sender_id, s.entries, self._push_max, held_then):
                self._outbox.setdefault((record.sender_id, record.oseq), (name, record))
            return
        record = typed(rtype, values)
        self.holdings.add(rtype, record)
        if self.store.add(record):
            self.counts["records_heard_new"] += 1
            if rtype == "claim" and not record.explored:
                self._retracted = True

    # --- gossip -----------------------------------------------------------------------
    def _task_summary(self, now_us: int) -> None:
        if self.s.send is None or self._push_max == 0:
            return
        entries = self.holdings.summary_entries(self._summary_turn)
        self._summary_turn += 1
        self.s.send("summary", values_of(Summary(self.s.robot_id, entries)), PRIORITY_INFO, key="summary")
        self.counts["summaries_sent"] += 1

    def _task_outbox(self, now_us: int) -> None:
        """Pushes onto the link a few at a time, so one another robot sends first can still
        be cancelled (on_record)."""
        s = self.s
        waiting = sum(s.queued(t) for t in _OWN_TYPES)
        self._outbox_us = now_us
        if waiting or self._outbox:
            self._news_until_us = now_us + int(NEWS_READ_S * 1e6)
        self._news_until_us = max(self._news_until_us, s.on_air_until_us() + int(NEWS_READ_S * 1e6))
        room = PUSH_BACKLOG - waiting
        while room > 0 and self._outbox and s.send is not None:
            key = next(iter(self._outbox))
            name, record = self._outbox.pop(key)
            self.counts["records_pushed"] += 1
            if not s.send(name, values_of(record), 0, key=("push", *key)):
                self.counts["records_dropped_by_link"] += 1
            room -= 1

    def _cancel_push(self, origin: int, oseq: int) -> None:
        """Someone else sent this record: a push of it still waiting here, in the outbox or
        on the link until this robot's slot comes, would repeat what the teammate that
        asked for it has just been sent. If that copy missed it, its next summary asks again."""
        self._outbox.pop((origin, oseq), None)
        if self.s.withdraw(("push", origin, oseq)):
            self.counts["pushes_withdrawn"] += 1

    def has_news(self) -> bool:
        """Own or pushed records waiting, on the air until less than NEWS_READ_S ago, or
        lacking in the summary of a teammate still in range (SETTLE_SUMMARY_PERIODS): a
        frame was lost, and the records go again, pushed, as its summaries show them lacking."""
        if self._outbox_us < self._news_until_us or self._outbox:
            return True
        own = self.holdings.upto(self.s.robot_id)
        in_range_us = SETTLE_SUMMARY_PERIODS * self.s.params.pereira_summary_period_s * 1e6
        return any(upto < own and self._outbox_us - heard_us < in_range_us
                   for upto, heard_us in self._mine_held_by.values())

    def wake_up(self, now_us: int) -> bool:
        """A teammate took back a claim: frontiers this robot left to it may be its again."""
        if not self._retracted or now_us - self._woken_us < self.s.params.known_map_refresh_s * 1e6:
            return False
        self._retracted, self._woken_us, self._finished = False, now_us, False
        return True

    def on_finished(self, frontiers_left_xy: np.ndarray) -> None:
        self._finished = True
        self._claim_all_it_mapped(frontiers_left_xy)
        # The roster learns it from the heartbeat too; the intent stops teammates yielding to it now.
        self._send_intent(DONE, OTHER, *self._position(), 0.0, force=True, now_us=self._said_intent_us)

    # --- the region view --------------------------------------------------------------
    def _explored_by_others(self) -> set[int]:
        """Regions (indices of graph()) some teammate's effective claim calls explored."""
        graph = self.store.graph()
        key = (id(graph), len(self.store))
        if key != self._view_key:
            view = self.store.view(self.s.robot_id)
            self._explored_others = {k for k, r in enumerate(view.regions) if r.explored_by_others}
            self._view_key = key
        return self._explored_others

    def _label_grid(self, graph: RegionGraph, sight: np.ndarray, now_us: int) -> None:
        """This cycle's label grid (labels.py), built once per planning cycle and graph."""
        g = self._grid
        if g is not None and g[0] is graph and g[1] == now_us:
            return
        lm = self.s.local_map
        self._grid = (graph, now_us, lm.row0, lm.col0,
                      label_grid(sight, lm.row0, lm.col0, self.s.params.resolution_m, graph))

    def _labels(self, graph: RegionGraph, xy: list[tuple[float, float]]) -> list[int | None]:
        """Each point's region: the label grid's where it has one for this graph, else the
        nearest place with no gate between (RegionGraph.label)."""
        reach = int(round(self.s.params.pereira_label_reach_m * 10))
        out: list[int | None] = [NO_LABEL] * len(xy)
        g = self._grid
        if g is not None and g[0] is graph:
            _graph, _t, row0, col0, grid = g
            res = self.s.params.resolution_m
            for q, (x, y) in enumerate(xy):
                i, j = int(math.floor(y / res)) - row0, int(math.floor(x / res)) - col0
                if 0 <= i < grid.shape[0] and 0 <= j < grid.shape[1]:
                    out[q] = int(grid[i, j])
        rest = [q for q, k in enumerate(out) if k == NO_LABEL]
        if rest:
            far = graph.labels(np.array([(dm(xy[q][0]), dm(xy[q][1])) for q in rest], np.int64), reach)
            for q, k in zip(rest, far):
                out[q] = k
        return out

    def _position(self) -> tuple[float, float]:
        return self._xy

    # --- the planning stage -----------------------------------------------------------
    def filter_waypoints(self, view: PlanningView) -> None:
        """Waypoints in regions a teammate's claim calls explored are left to the team (A5,
        A6) if a teammate's place lies within d_cam_m of them (pereira_claims_near_only,
        _out_of_teammates_reach; the rest are kept and ranked last); the others are dropped
        where the teammates' places saw what they promise (_seen_by_team; their view stops at
        gates), and their regions are then not claimed by this robot. A robot with
        nothing else worth heading for, while teammates explore, keeps the one on its way to
        a region a teammate is heading for (_transit);
        with none and pereira_take_back, or with no teammate exploring any more and
        pereira_take_back_alone, it takes back those worth it (_worth_taking_back; the spec's
        end-game safety net: a claim made for the region as its claimant knew it must not
        leave a hole)."""
        items = self.s.waypoints.items
        self._last_resort = set()
        if not items:
            return
        others = self._explored_by_others()
        if not others and not self.s.params.pereira_team_view:
            return
        graph = self.store.graph()
        if others:
            self._label_grid(graph, view.sight, view.now_us)
            labels = self._labels(graph, [(w.x_m, w.y_m) for w in items])
        else:
            labels = [None] * len(items)
        claimed = [r is not None and r in others for r in labels]
        if self.s.params.pereira_claims_near_only and any(claimed):
            for k in self._out_of_teammates_reach(graph, items, claimed):
                claimed[k] = False
                self.counts["claimed_waypoints_kept"] += 1
                if self.s.params.pereira_unseen_claimed_last:
                    self._last_resort.add((items[k].x_m, items[k].y_m))
        left = [w for w, c in zip(items, claimed) if c]
        alone = not self.s.roster.any_active(view.now_us)
        seen = self._seen_by_team(graph, view.sight, items, claimed)
        if any(seen) and not others:
            self._label_grid(graph, view.sight, view.now_us)
            labels = self._labels(graph, [(w.x_m, w.y_m) for w in items])
        own = [w for w, c, sn in zip(items, claimed, seen) if not c and not sn]
        transit = None
        if left and not alone and self.s.params.pereira_transit and \
                not self.s.waypoints.worth_heading_for(view.x_m, view.y_m, among=own):
            transit = self._transit(graph, left, view.x_m, view.y_m, view.now_us)
        p = self.s.params
        end_game = alone and p.pereira_take_back_alone
        take_back = left and transit is None and (end_game or (p.pereira_take_back and (alone or all(claimed))))
        back = iter(self._worth_taking_back(graph, view.sight, left, alone) if take_back else [False] * len(left))
        kept = []
        for w, r, c, sn in zip(items, labels, claimed, seen):
            if sn:
                self.counts["waypoints_seen_by_team"] += 1
                self._left_labels.add(r)
            elif not c:
                kept.append(w)
            elif next(back) or w is transit:
                kept.append(w)
                self.counts["transit_choices" if w is transit else "waypoints_taken_back"] += 1
            else:
                self.counts["waypoints_left_to_team"] += 1
                self._left_labels.add(r)
        items[:] = kept

    def _out_of_teammates_reach(self, graph: RegionGraph, items: list, claimed: list[bool]) -> list[int]:
        """Which claimed waypoints (indices) no teammate's place lies within d_cam_m of: no
        teammate could have seen what they promise, whatever the claim says. The label grid
        walks this robot's free cells from a region's places as far as they reach: through a
        doorway no gate marks it carries a claimed region's label into rooms the claimant
        never saw (maze_b seed 5: a wing, a fifth of the maze)."""
        reach_m = self.s.params.d_cam_m
        return [k for k, c in enumerate(claimed) if c and not self._teammate_stood_near(graph, items[k], reach_m)]

    def _seen_by_team(self, graph: RegionGraph, sight: np.ndarray, items: list, claimed: list[bool]) -> list[bool]:
        """Which waypoints in regions no teammate claimed its teammates have seen: in the
        window, a teammate's place within d_cam_m, and less than pereira_revive_left_bit
        left once what LiDARs at the teammates' places would have seen counts as seen (the
        test a take-back passes, services.team_view). Claims come late (A2 wants a whole
        region in one robot's window; a region several robots explored in parts may never
        be claimed), and without this a team that had seen all of maze_a drove on for
        minutes through regions no one had claimed. The robot's current target stays."""
        p = self.s.params
        out = [False] * len(items)
        if not p.pereira_team_view:
            return out
        theirs, tree = self._teammates_places(graph)
        if not len(theirs):
            return out
        t = self.s.current_target()
        held = None if t is None else (t.x_m, t.y_m)
        xy = np.array([(w.x_m, w.y_m) for w in items], np.float64).reshape(-1, 2)
        _ij, inside = self.s.local_map.cells_of(xy)
        near = tree.query(xy, distance_upper_bound=p.d_cam_m)[0] < math.inf
        ask = np.flatnonzero(inside & near & ~np.array(claimed, bool))
        ask = np.array([k for k in ask.tolist() if (items[k].x_m, items[k].y_m) != held], np.int64)
        if len(ask):
            lm = self.s.local_map
            left_bit = unseen_after_team_view_bit(sight, lm.row0, lm.col0, xy[ask], theirs, p,
                                                  self._view_walls(graph, sight))
            for k, bits in zip(ask.tolist(), left_bit.tolist()):
                out[k] = bits < p.pereira_revive_left_bit
        return out

    def _view_walls(self, graph: RegionGraph, sight: np.ndarray) -> np.ndarray | None:
        """What stops the teammates' places' view besides the walls this robot mapped: the
        gates (pereira_gates_block_view), or nothing."""
        if not self.s.params.pereira_gates_block_view:
            return None
        lm = self.s.local_map
        return gate_cells(sight.shape, lm.row0, lm.col0, self.s.params.resolution_m, graph)

    def _teammates_places(self, graph: RegionGraph) -> tuple[np.ndarray, cKDTree | None]:
        """The teammates' places in this graph (rows of x, y in metres) and their k-d tree
        (None if there are none), kept while the graph is the same: the planning stage asks
        every cycle, and the graph changes only when records arrive."""
        held = self._theirs
        if held is None or held[0] is not graph:
            theirs = graph.places[graph.places[:, 2] != self.s.robot_id, :2] / 10.0
            held = self._theirs = (graph, theirs, cKDTree(theirs) if len(theirs) else None)
        return held[1], held[2]

    def _transit(self, graph: RegionGraph, items: list, x_m: float, y_m: float, now_us: int):
        """Of these waypoints (all in regions teammates claimed), the one worth heading for on
        the shortest way to a region teammates are heading for: the distance to the
        waypoint, then from it to a place near it and along the places' edges (teammates
        drove them, or their maps certified them free) to a teammate's place in such a
        region that this robot has not been near. None if no such place is left or none is
        joined to these waypoints. The robot then maps its way through claimed regions,
        whose waypoints it leaves to the team once there are others, instead of stopping
        while its teammates work on."""
        to_work_dm = self._distance_to_work_dm(graph, now_us)
        if to_work_dm is None:
            return None
        reach_dm = self.s.params.pereira_label_reach_m * 10
        pl = graph.places
        best, best_m = None, math.inf
        for w in self.s.waypoints.worth_heading_for(x_m, y_m, among=items):
            near = graph.places_within(w.x_m * 10, w.y_m * 10, reach_dm)
            if not len(near):
                continue
            via_dm = np.hypot(pl[near, 0] - w.x_m * 10, pl[near, 1] - w.y_m * 10) + to_work_dm[near]
            total_m = math.hypot(w.x_m - x_m, w.y_m - y_m) + float(via_dm.min()) / 10
            if total_m < best_m:
                best, best_m = w, total_m
        return best

    def _distance_to_work_dm(self, graph: RegionGraph, now_us: int) -> np.ndarray | None:
        """Each place's distance (dm) along the place graph to the nearest teammate's place
        in a region a teammate is heading for (its intent), that no claim calls explored,
        that this robot has not judged explored itself, and that is pereira_transit_new_m
        from every place of this robot's own; None if there is none. Regions no one claims
        but no one heads for are left alone: claims come late (A2 wants all of a region in
        the claimant's window), and a team that has seen everything still holds many."""
        p = self.s.params
        pl = graph.places
        mine = pl[:, 2] == self.s.robot_id
        done_by_others = self._explored_by_others()
        open_regions = [k for k in self._headings(graph, now_us)
                        if not graph.regions[k].virtual and k not in done_by_others
                        and self._clean.get(graph.regions[k].id, 0) < p.pereira_explored_cycles
                        and not self._claimed.get(graph.regions[k].id, (0, 0, 0, 0))[3]]
        source = np.isin(graph.region_of_place, open_regions) & ~mine
        if mine.any() and source.any():
            gap_dm = cKDTree(pl[mine, :2].astype(np.float64)).query(pl[source, :2].astype(np.float64))[0]
            source[np.flatnonzero(source)[gap_dm < p.pereira_transit_new_m * 10]] = False
        if not source.any():
            return None
        e = graph.edges
        n = len(pl)
        # csgraph reads an explicit zero as no edge: places of two robots may coincide.
        length_dm = np.maximum(np.hypot(pl[e[:, 0], 0] - pl[e[:, 1], 0], pl[e[:, 0], 1] - pl[e[:, 1], 1]), 1e-3)
        edges = coo_matrix((length_dm, (e[:, 0], e[:, 1])), shape=(n, n)).tocsr()
        return dijkstra(edges, directed=False, indices=np.flatnonzero(source), min_only=True)

    def _worth_taking_back(self, graph: RegionGraph, sight: np.ndarray, items: list, alone: bool) -> list[bool]:
        """Which of these waypoints (in regions teammates claimed) to take back: those
        promising pereira_revive_min_bit that no teammate left a place within revive_clear_m
        of, and, in the window, that still promise pereira_revive_left_bit once what LiDARs
        at the teammates' places would have seen counts as seen (services.team_view). The
        robots share no maps, so this robot's map shows everything teammates explored as
        unknown: taking back every rich waypoint, the last robot on maze_a drove its
        teammates' regions again (1144 m against their 100-490 m); with the place test alone
        (commit c368dee, seed 0 over eu868-g3) the team had seen all of maze_a at 840 s and
        the last robot drove on, taking waypoints back, until 1548 s. Beyond the window
        there is nothing to cast against: only a robot with no teammate exploring takes a
        waypoint back there, and only one no teammate's place lies within half the sensor's
        reach (d_cam_m) of, whose LiDAR would have seen most of what it promises (with
        revive_clear_m there, the last robot on maze_a seed 3 drove 915 m, its teammates
        224 to 328 m, retracing their corridors)."""
        p = self.s.params
        lm = self.s.local_map
        rich = [w.e_bit >= p.pereira_revive_min_bit and not self._teammate_stood_near(graph, w, p.revive_clear_m)
                for w in items]
        xy = np.array([(w.x_m, w.y_m) for w in items], np.float64).reshape(-1, 2)
        _ij, inside = lm.cells_of(xy)
        out = [r and alone and not i and not self._teammate_stood_near(graph, w, p.d_cam_m / 2)
               for w, r, i in zip(items, rich, inside.tolist())]
        ask = np.nonzero(np.array(rich) & inside)[0]
        if len(ask):
            theirs, _tree = self._teammates_places(graph)
            left_bit = unseen_after_team_view_bit(sight, lm.row0, lm.col0, xy[ask], theirs, p,
                                                  self._view_walls(graph, sight))
            for k, bits in zip(ask.tolist(), left_bit.tolist()):
                out[k] = bits >= p.pereira_revive_left_bit
        return out

    def _teammate_stood_near(self, graph: RegionGraph, w, radius_m: float) -> bool:
        """Did a teammate leave a place within radius_m of the waypoint?"""
        near = graph.places_within(w.x_m * 10, w.y_m * 10, radius_m * 10)
        return bool((graph.places[near, 2] != self.s.robot_id).any())

    def rank(self, view: PlanningView, own: list[Candidate]) -> list[Candidate]:
        p, me = self.s.params, self.s.robot_id
        self._xy = (view.x_m, view.y_m)
        self._sight = view.sight
        graph = self.store.graph()
        self._label_grid(graph, view.sight, view.now_us)
        (here,) = self._labels(graph, [(view.x_m, view.y_m)])
        self.where.update(graph, here, view.x_m, view.y_m)
        current, previous = self.where.indices(graph)
        labels = self._labels(graph, [(c.x_m, c.y_m) for c in own])
        explored = self._explored_by_others() | {k for k, r in enumerate(graph.regions)
                                                 if self._clean.get(r.id, 0) >= p.pereira_explored_cycles}
        cats = categorise(graph, labels, [(c.x_m, c.y_m) for c in own], current, previous, explored,
                          p.pereira_margin_m)
        heading = self._headings(graph, view.now_us)
        self._category = {}
        for c, r, cat in zip(own, labels, cats):
            clash = r is not None and r in heading and \
                conflicts(math.hypot(c.x_m - view.x_m, c.y_m - view.y_m), me, heading[r])
            c.rank = cat + (CONFLICT_RANK if clash else 0)
            if (c.x_m, c.y_m) in self._last_resort:
                c.rank += 2 * CONFLICT_RANK
            if not p.pereira_by_cost:
                c.gain, c.gain_cost_offset_m = c.e_bit, p.pereira_cost_offset_m
            self.counts["choices_yielded"] += int(clash)
            self._category[(c.x_m, c.y_m)] = cat
        cost_along_graph(view, own)
        return own

    def _headings(self, graph: RegionGraph, now_us: int) -> dict[int, list[tuple[float, int]]]:
        """Region -> (distance to goal in m, id) of each teammate headed there (h_B resolved in
        this robot's graph, A12); stale intents and finished robots left out (A10)."""
        p = self.s.params
        done = {rid for rid, m in self.s.roster.members().items() if m.done}
        out: dict[int, list[tuple[float, int]]] = {}
        for rid, (it, heard_us) in sorted(self._intents.items()):
            if it.state != EXPLORING or rid in done or now_us - heard_us > p.pereira_intent_expiry_s * 1e6:
                continue
            (h,) = self._labels(graph, [(it.goal_x_dm / 10.0, it.goal_y_dm / 10.0)])
            if h is not None:
                out.setdefault(h, []).append((it.goal_dist_dm / 10.0, rid))
        return out

    # --- after each plan: statuses and intent ------------------------------------------
    def after_plan(self, pose: OdometrySample, now_us: int) -> None:
        self._xy = (pose.x_m, pose.y_m)
        if self._sight is not None:
            self._judge_regions()
        t = self.s.current_target()
        if t is None:
            self._send_intent(IDLE, OTHER, pose.x_m, pose.y_m, 0.0, force=False, now_us=now_us)
        else:
            self._send_intent(EXPLORING, self._category.get((t.x_m, t.y_m), OTHER), t.x_m, t.y_m,
                              math.hypot(t.x_m - pose.x_m, t.y_m - pose.y_m), force=False, now_us=now_us)

    def _judge_regions(self) -> None:
        """A2: a region is explored for this robot when all its places lie known in the
        window and none of its waypoints is in it, on pereira_explored_cycles cycles in a
        row; a claim says so, and a retraction follows when one of its waypoints appears
        there again. A claim is re-issued when the region's anchor or signature changes;
        none is sent while a teammate's claim on the same region is effective (it names the
        same places and gates: a second one would tell no one anything)."""
        p = self.s.params
        graph = self.store.graph()
        lm, sight = self.s.local_map, self._sight
        items = self.s.waypoints.items
        # Waypoints left to the team count: a region is not explored for this robot because
        # a teammate says so (else one claim would make every robot claim it too), nor
        # because a model says the teammates' places saw what its waypoints promise (their
        # rays pass through what this robot's map shows unknown: walls it never saw
        # included). A claim is a report others trust. (Where that view is mostly right, as
        # in a cave, teammates then explore such regions again: docs/pereira/intel-gates/.)
        with_waypoints = set(self._labels(graph, [(w.x_m, w.y_m) for w in items])) | self._left_labels
        self._left_labels = set()
        clean: dict[tuple[int, ...], int] = {}
        explored_now: list[int] = []
        for k, reg in enumerate(graph.regions):
            if reg.virtual or k in with_waypoints:
                continue
            ij, inside = lm.cells_of(graph.places[list(reg.places), :2] / 10.0)
            m = WINDOW_MARGIN_CELLS
            if not (inside.all() and (ij >= m).all() and (ij < lm.n - m).all()):
                continue
            if (sight[ij[:, 0], ij[:, 1]] == kernels.UNKNOWN).any():
                continue
            clean[reg.id] = self._clean.get(reg.id, 0) + 1
            if clean[reg.id] >= p.pereira_explored_cycles:
                explored_now.append(k)
        self._clean = clean
        others = self._explored_by_others()
        for k in explored_now:
            if k in others:
                continue      # a teammate's claim says it already, for the same places and gates
            reg = graph.regions[k]
            said = (reg.anchor_x_dm, reg.anchor_y_dm, reg.signature, 1)
            if self._claimed.get(reg.id) != said:
                self._claim(*said)
                self._claimed[reg.id] = said
        for rid, (ax, ay, sig, explored) in list(self._claimed.items()):
            k = graph.region_index(rid)
            if k is None:
                del self._claimed[rid]        # merged away: its claims name a signature no region has
            elif explored and k in with_waypoints and graph.regions[k].signature == sig:
                self._claim(ax, ay, sig, 0)
                self._claimed[rid] = (ax, ay, sig, 0)
                self.counts["claims_retracted"] += 1

    def _claim_all_it_mapped(self, frontiers_left_xy: np.ndarray) -> None:
        """A robot that stops has no frontier left in all it has mapped but those it names:
        every region whose places all lie in what it mapped, with none of those frontiers
        and no teammate's claim on it, is explored for it, wherever its window is now. A2's
        test while exploring looks only at the window and at the waypoints the robot holds;
        a region it explored and left before the test passed would otherwise stay open to
        teammates, who share no map with it and would explore it again."""
        graph = self.store.graph()
        state, row0, col0 = self.s.local_map.whole_state()
        res = self.s.params.resolution_m
        left = set(self._labels(graph, [(float(x), float(y)) for x, y in frontiers_left_xy]))
        others = self._explored_by_others()
        for k, reg in enumerate(graph.regions):
            if reg.virtual or k in left or k in others:
                continue
            ij, on_grid = grid_cells_of(graph.places[list(reg.places), :2] / 10.0, row0, col0, state.shape, res)
            if not on_grid.all() or (state[ij[:, 0], ij[:, 1]] == kernels.UNKNOWN).any():
                continue
            said = (reg.anchor_x_dm, reg.anchor_y_dm, reg.signature, 1)
            if self._claimed.get(reg.id) != said:
                self._claim(*said)
                self._claimed[reg.id] = said
                self.counts["claims_on_stopping"] += 1

    def _claim(self, ax: int, ay: int, sig: int, explored: int) -> None:
        self._publish("claim", Claim(self.s.robot_id, self._next_oseq(), ax, ay, sig, explored, 0), PRIORITY_STATUS)

    def _send_intent(self, state: int, category: int, gx: float, gy: float, dist_m: float, force: bool,
                     now_us: int) -> None:
        """The intent (h, p^r, p^g of the paper's message) when the goal moved, its category
        or the state changed, or every pereira_intent_period_s."""
        p = self.s.params
        if self.s.send is None:
            return
        x, y = self._position()
        said = self._said_intent
        moved = said is None or math.hypot(gx - said[2] / 10.0, gy - said[3] / 10.0) >= p.pereira_intent_move_m
        due = said is None or now_us - self._said_intent_us >= p.pereira_intent_period_s * 1e6
        if not (force or due or moved or (state, category) != said[:2]):
            return
        self._iseq = (self._iseq + 1) % 256
        it = Intent(self.s.robot_id, dm(x), dm(y), dm(gx), dm(gy), min(GOAL_DIST_MAX_DM, int(round(dist_m * 10))),
                    state, category, self._iseq)
        self.s.send("intent", values_of(it), PRIORITY_MOTION, key="intent")
        self._said_intent = (state, category, dm(gx), dm(gy))
        self._said_intent_us = now_us
        self.counts["intents_sent"] += 1

    # --- for the host -----------------------------------------------------------------
    def stats(self) -> dict[str, int]:
        graph = self.store.graph()
        return {**self.counts, "records_held": len(self.store), "map_doorways": len(self._doorways or ()),
                "regions": sum(not r.virtual for r in graph.regions),
                "virtual_regions": sum(r.virtual for r in graph.regions), "gates_held": len(graph.gates),
                "regions_explored_by_others": len(self._explored_by_others())}

    def digests(self) -> dict[str, str]:
        """The record set held and the region graph folded from it (pereira.md 6.3, bar 8)."""
        return {"records": self.store.digest()[:16], "region_graph": self.store.graph().digest()[:16]}

    def drawables(self) -> dict:
        graph = self.store.graph()
        xy = graph.places[:, :2] / 10.0 if len(graph.places) else np.zeros((0, 2))
        segs = graph.segments_cm.reshape(-1, 2, 2) / 100.0 if len(graph.segments_cm) else np.zeros((0, 2, 2))
        return {"title": "Pereira: the region graph robot 0 derived (places coloured by region, gates black)",
                "points": xy, "segments": segs, "regions": graph.region_of_place, "what": "places"}
