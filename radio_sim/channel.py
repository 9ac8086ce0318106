"""The shared LoRa channel every simulated or emulated modem transmits into.

Model (LoRaSim, Bor et al. 2016, `full_collision` mode; ns-3 lorawan):
- A frame occupies the air for `RadioProfile.airtime_us(len(payload))`, from the call to
  `transmit` on, when it is sent at the profile's operating point (the default, and what the
  in-process modems do). A transmitter may name another `AirInterface` (frequency, SF, BW,
  CR, preamble, CRC, sync word, IQ polarity, or FSK) and its own power, as the virtual
  RN2483 modems do after `radio set`: the frame then takes that interface's time on air,
  only receivers armed with an equal reception key can decode it, and only frames with an
  equal interference key (same frequency, SF and BW) can collide with it. Sensitivity,
  noise floor and preamble grace are those of the frame's own modulation.
- At each receiver, two overlapping frames E (earlier start) and L collide in time unless the
  overlap ends before the last 5 of L's preamble symbols, i.e. E.end_us <= L.start_us +
  (preamble_symbols - 5) * T_sym (L may lose its first 3 of 8 preamble symbols). As in
  LoRaSim, a pair that does not collide in time harms neither frame. A pair that collides in
  time is judged by power at that receiver: under 6 dB apart both are lost, otherwise the
  weaker is lost (capture). An interferer below the receiver's sensitivity is ignored.
- Fates at a receiver, first match wins: half_duplex (the receiver transmitted during any
  part of the frame), out_of_range (RSSI below sensitivity), not_listening (not armed, or
  armed for another frequency/SF/BW/sync word/IQ polarity, when the frame started),
  collided, not_listening (armed at the start but disarmed before the end: another frame
  was delivered first, or the receiver was stopped), then injected
  faults (injected_loss, corrupted), else received.
- Reception is one-shot like the RN2483's `radio rx 0`: a delivered frame (received or
  corrupted) disarms the receiver until `set_listening(node, True)`. Transmitting disarms it
  too (the RN2483 leaves receive mode to send); arming while transmitting takes effect when
  the frame ends. Nodes are armed when attached.
- SNR is reported as an SX127x reports it: its packet SNR register holds quarter dB in a
  signed byte, so the figure stays within -32..+31.75 dB however strong the signal.
- The `ideal` profile (Bayer & Faigl): every other attached node receives every frame,
  regardless of range, walls, collisions, half duplex, arming or air settings; injected faults, if any
  were asked for, still apply. The armed state is tracked the same way so modem emulators
  behave identically on top of it.
- An optional hard range (`max_range_m`, an experiment's disc model, as Pereira et al.'s
  simulator cut links at 5 m): a receiver farther than that from the sender when the frame
  starts does not get it (fate out_of_range), on any profile, the ideal one included. On a
  LoRa profile it comes on top of the path loss: a frame needs both, and a frame from beyond
  the range does not collide with another at that receiver either.

Time is whatever `now_us` the caller passes, non-decreasing across all calls. Every call that
takes a time first resolves the frames that ended at or before it, so the receiver state a
call changes is always the state at that time.

Random streams: injected faults draw from `stream(seed, "radio.channel")`, three uniforms
per (frame, receiver) in resolution order (end time, sender id) then receiver id, plus the
bit positions of each corruption; shadowing draws from `stream(seed, "radio.shadowing")`,
so turning shadowing on does not move the faults.
"""
from __future__ import annotations

import heapq
import math
import operator
from collections import deque
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Callable

from hal.lora import AirInterface, RadioProfile
from hal.samples import RadioEvent, RadioRxFrame, RadioTxDone
from radio_sim.air_log import (
    COLLIDED, CORRUPTED, FATES, HALF_DUPLEX, INJECTED_LOSS, NOT_LISTENING, OUT_OF_RANGE, RECEIVED,
    AirFrame, Reception,
)
from radio_sim.faults import NO_FAULT, FaultParams, draw_faults, flip_bits
from radio_sim.propagation import FSK_SENSITIVITY_DBM, PropagationParams, WallCounter, sensitivity_dbm
from world_sim.occupancy_map import OccupancyMap
from world_sim.seeding import stream

CAPTURE_THRESHOLD_DB = 6.0
# Preamble symbols a receiver needs to lock on; the earlier ones may be lost to an overlap.
PREAMBLE_SYMBOLS_NEEDED = 5
# SX1276 datasheet, RegPktSnrValue: the last packet's SNR in quarter dB, two's complement.
REPORTED_SNR_MIN_DB = -32.0
REPORTED_SNR_MAX_DB = 31.75

_FRAME_END = 0
_DUPLICATE_DUE = 1


@dataclass(eq=False)
class _Frame:
    seq: int
    sender_id: int
    start_us: int
    end_us: int
    payload: bytes
    # receiver id -> (rssi_dbm, snr_db), ascending receiver id; every node attached at the start
    link: dict[int, tuple[float, float]]
    armed_at_start: set[int]
    air: AirInterface
    reception_key: tuple
    interference_key: tuple
    sensitivity_dbm: float
    preamble_grace_us: Fraction
    beyond_range: frozenset[int] = frozenset()   # receivers farther than max_range_m at the start


@dataclass(eq=False)
class _Node:
    node_id: int
    position_fn: Callable[[], tuple[float, float]]
    listen_since_us: int | None      # armed since this time; None = not armed
    listen_key: tuple = ()            # the AirInterface.reception_key it is armed with
    tx_frame: _Frame | None = None
    arm_after_tx: bool = False        # set_listening(True) arrived while transmitting
    events: list[RadioEvent] = field(default_factory=list)
    # duplicates that came due while the node was not armed: (reception_key, payload, rssi_dbm, snr_db)
    waiting_duplicates: deque = field(default_factory=deque)


class Channel:
    def __init__(
        self,
        profile: RadioProfile,
        seed: int,
        occupancy: OccupancyMap | None = None,
        propagation: PropagationParams = PropagationParams(),
        faults: FaultParams = FaultParams(),
        loss_rule: Callable[[int, int, bytes], bool] | None = None,
        max_range_m: float | None = None,
    ) -> None:
        """loss_rule(sender id, receiver id, payload): True loses that reception as an
        injected loss (an experiment's or a test's targeted fault; drawn faults come on top).
        max_range_m: the hard range (None: none)."""
        if max_range_m is not None and not (math.isfinite(max_range_m) and max_range_m > 0):
            raise ValueError(f"max_range_m must be a positive number of metres or None, got {max_range_m!r}")
        self.profile = profile
        self.loss_rule = loss_rule
        self.max_range_m = None if max_range_m is None else float(max_range_m)
        self.seed = int(seed)
        self.occupancy = occupancy
        self.propagation = propagation
        self.faults = faults
        self.sensitivity_dbm = sensitivity_dbm(profile.modulation)
        self.noise_floor_dbm = propagation.noise_floor_dbm(profile.modulation.bw_hz)
        self.symbol_time_us: Fraction = profile.modulation.symbol_time_us
        self.preamble_grace_us: Fraction = (
            max(profile.modulation.preamble_symbols - PREAMBLE_SYMBOLS_NEEDED, 0) * self.symbol_time_us
        )
        # The network's operating point: what transmit/set_listening use when not told otherwise.
        self.air: AirInterface = profile.air_interface()
        self._air_facts: dict[AirInterface, tuple[tuple, tuple, float, float, Fraction]] = {}
        self._walls = WallCounter(occupancy) if occupancy is not None else None
        self._fault_rng = stream(self.seed, "radio.channel")
        self._shadow_rng = stream(self.seed, "radio.shadowing")
        self._nodes: dict[int, _Node] = {}
        self._heap: list[tuple[int, int, int, int, object]] = []
        self._window: list[_Frame] = []   # frames that may still overlap an unresolved one
        self._unresolved: dict[int, _Frame] = {}
        self._seq = 0
        self._now_us = 0
        self._sinks: list[Callable[[AirFrame], None]] = []
        self._counts: dict[str, int] = {f: 0 for f in FATES}
        self._counts.update(frames=0, duplicates_delivered=0)
        self._airtime_us: dict[int, int] = {}

    # -- set-up ------------------------------------------------------------------------------

    def attach(self, node_id: int, position_fn: Callable[[], tuple[float, float]]) -> None:
        if node_id in self._nodes:
            raise ValueError(f"node {node_id} is already attached to the channel")
        # Armed from "now": a frame already on the air has no reception record for it.
        self._nodes[node_id] = _Node(int(node_id), position_fn, listen_since_us=self._now_us,
                                     listen_key=self.air.reception_key())
        self._airtime_us[node_id] = 0

    def add_sink(self, fn: Callable[[AirFrame], None]) -> None:
        self._sinks.append(fn)

    # -- the contract ------------------------------------------------------------------------

    def transmit(self, node_id: int, payload: bytes, now_us: int, *, air: AirInterface | None = None,
                 tx_power_dbm: float | None = None) -> int | None:
        """Start a frame now; its end time in us, or None (nothing sent) if the node is
        already transmitting or the payload exceeds the profile's max_payload_bytes.
        `air` and `tx_power_dbm` default to the profile's operating point and power."""
        now_us = operator.index(now_us)
        self.advance_to(now_us)
        node = self._node(node_id)
        payload = bytes(payload)
        air = self.air if air is None else air
        if node.tx_frame is not None or len(payload) > self.profile.max_payload_bytes:
            return None
        rx_key, if_key, sens_dbm, noise_dbm, grace_us = self._facts(air)
        # The profile's own timing (the ideal link's byte rate included) at its operating point.
        airtime_us = self.profile.airtime_us(len(payload)) if air == self.air else air.airtime_us(len(payload))
        end_us = now_us + airtime_us
        armed = {n.node_id for n in self._nodes.values()
                 if n.listen_since_us is not None and n is not node and n.listen_key == rx_key}
        power_dbm = self.profile.tx_power_dbm if tx_power_dbm is None else float(tx_power_dbm)
        frame = _Frame(self._seq, node.node_id, now_us, end_us, payload,
                       self._links_from(node, power_dbm, noise_dbm), armed,
                       air, rx_key, if_key, sens_dbm, grace_us, self._beyond_range(node))
        self._seq += 1
        self._airtime_us[node.node_id] += end_us - now_us
        node.tx_frame = frame
        node.listen_since_us = None
        node.arm_after_tx = False
        self._window.append(frame)
        self._unresolved[frame.seq] = frame
        heapq.heappush(self._heap, (end_us, _FRAME_END, node.node_id, frame.seq, frame))
        return end_us

    def set_listening(self, node_id: int, listening: bool, now_us: int, *, air: AirInterface | None = None) -> None:
        """Arm (one-shot) or disarm the node's receiver; it listens for frames sent with `air`
        (default: the profile's operating point)."""
        now_us = operator.index(now_us)
        self.advance_to(now_us)
        node = self._node(node_id)
        if not listening:
            node.listen_since_us = None
            node.arm_after_tx = False
            return
        key = self._facts(self.air if air is None else air)[0]
        if node.listen_since_us is not None and node.listen_key != key:
            node.listen_since_us = None          # retuned: an arming for other settings ends
        node.listen_key = key
        if node.tx_frame is not None:
            # The transmitter and receiver share one front end: the arming takes effect when
            # the frame is out (a virtual modem reset mid-frame can ask for this).
            node.arm_after_tx = True
            return
        self._arm(node, now_us)

    def advance_to(self, now_us: int) -> None:
        """Resolve every frame (and injected duplicate) due at or before now_us, in order of
        time, then sender id. O(1) when nothing is due."""
        if now_us < self._now_us:
            raise ValueError(f"channel time went backwards: {now_us} us after {self._now_us} us")
        if now_us.__class__ is not int:
            now_us = operator.index(now_us)   # integer microseconds only (numpy ints accepted)
        self._now_us = now_us
        heap = self._heap
        while heap and heap[0][0] <= now_us:
            _, kind, _, _, item = heapq.heappop(heap)
            if kind == _FRAME_END:
                self._resolve(item)  # type: ignore[arg-type]
            else:
                self._duplicate_due(*item)  # type: ignore[misc]

    def take_events(self, node_id: int) -> list[RadioEvent]:
        node = self._node(node_id)
        events, node.events = node.events, []
        return events

    def next_event_us(self) -> int | None:
        return self._heap[0][0] if self._heap else None

    # -- queries -----------------------------------------------------------------------------

    @property
    def now_us(self) -> int:
        """The latest time the channel was advanced to."""
        return self._now_us

    @property
    def node_ids(self) -> tuple[int, ...]:
        return tuple(self._nodes)

    def transmitting(self, node_id: int) -> bool:
        """Whether the node's frame is still on the air at the channel's current time
        (call advance_to first to ask about a later time)."""
        return self._node(node_id).tx_frame is not None

    def tx_end_us(self, node_id: int) -> int | None:
        frame = self._node(node_id).tx_frame
        return None if frame is None else frame.end_us

    def listening(self, node_id: int) -> bool:
        return self._node(node_id).listen_since_us is not None

    def counters(self) -> dict[str, int]:
        """Receptions per fate over all finished frames, plus `frames` (finished frames) and
        `duplicates_delivered` (injected duplicate copies handed to a receiver)."""
        return dict(self._counts)

    def airtime_us_by_node(self) -> dict[int, int]:
        """Total time on air each node has started so far (frames still on the air count in
        full)."""
        return dict(self._airtime_us)

    # -- internals ---------------------------------------------------------------------------

    def _node(self, node_id: int) -> _Node:
        try:
            return self._nodes[node_id]
        except KeyError:
            raise KeyError(f"node {node_id} is not attached to the channel (attached: {sorted(self._nodes)})") from None

    def _facts(self, air: AirInterface) -> tuple[tuple, tuple, float, float, Fraction]:
        """(reception key, interference key, sensitivity dBm, noise floor dBm, preamble grace us)
        of an air interface; a handful of interfaces occur per run, so they are cached."""
        facts = self._air_facts.get(air)
        if facts is None:
            sens_dbm = sensitivity_dbm(air.modulation) if air.is_lora else FSK_SENSITIVITY_DBM
            facts = (air.reception_key(), air.interference_key(), sens_dbm,
                     self.propagation.noise_floor_dbm(air.noise_bw_hz),
                     air.preamble_grace_us(PREAMBLE_SYMBOLS_NEEDED))
            self._air_facts[air] = facts
        return facts

    def _links_from(self, sender: _Node, tx_power_dbm: float, noise_floor_dbm: float) -> dict[int, tuple[float, float]]:
        """RSSI and SNR at every other attached node, fixed at the frame's start (robots move
        centimetres during a frame)."""
        sx, sy = sender.position_fn()
        params = self.propagation
        links: dict[int, tuple[float, float]] = {}
        for rid in sorted(self._nodes):
            if rid == sender.node_id:
                continue
            rx, ry = self._nodes[rid].position_fn()
            walls = self._walls.walls_between((sx, sy), (rx, ry)) if self._walls is not None else 0
            rssi_dbm = tx_power_dbm - params.path_loss_db(math.hypot(rx - sx, ry - sy), walls)
            if params.shadowing_std_db > 0:
                rssi_dbm -= float(self._shadow_rng.normal(0.0, params.shadowing_std_db))
            snr_db = min(max(rssi_dbm - noise_floor_dbm, REPORTED_SNR_MIN_DB), REPORTED_SNR_MAX_DB)
            links[rid] = (rssi_dbm, snr_db)
        return links

    def _beyond_range(self, sender: _Node) -> frozenset[int]:
        """The nodes farther than max_range_m from the sender now (positions at the frame's
        start, as for the path loss)."""
        if self.max_range_m is None:
            return frozenset()
        sx, sy = sender.position_fn()
        out = set()
        for rid, node in self._nodes.items():
            if rid != sender.node_id:
                rx, ry = node.position_fn()
                if math.hypot(rx - sx, ry - sy) > self.max_range_m:
                    out.add(rid)
        return frozenset(out)

    def _physical_fate(self, frame: _Frame, rid: int, rssi_dbm: float) -> str:
        if self.profile.ideal:
            return OUT_OF_RANGE if rid in frame.beyond_range else RECEIVED
        for other in self._window:
            if other.sender_id == rid and other.start_us < frame.end_us and frame.start_us < other.end_us:
                return HALF_DUPLEX
        if rssi_dbm < frame.sensitivity_dbm or rid in frame.beyond_range:
            return OUT_OF_RANGE
        if rid not in frame.armed_at_start:
            return NOT_LISTENING
        for other in self._window:
            if other is frame or other.sender_id == frame.sender_id:
                continue
            if other.interference_key != frame.interference_key:
                continue  # another frequency or spreading factor
            if not (other.start_us < frame.end_us and frame.start_us < other.end_us):
                continue
            other_link = other.link.get(rid)
            if other_link is None or other_link[0] < frame.sensitivity_dbm or rid in other.beyond_range:
                continue    # too weak, or beyond the hard range, to harm this frame here
            early, late = (frame, other) if frame.start_us <= other.start_us else (other, frame)
            if early.end_us - late.start_us <= late.preamble_grace_us:
                continue  # the overlap only ate the late frame's first preamble symbols
            margin_db = rssi_dbm - other_link[0]
            if margin_db < CAPTURE_THRESHOLD_DB:  # under 6 dB apart, or the weaker one
                return COLLIDED
        # Armed at the start, but the one-shot receiver was taken by another frame (or
        # stopped) before this one ended.
        node = self._nodes[rid]
        if node.listen_since_us is None or node.listen_since_us > frame.start_us:
            return NOT_LISTENING
        return RECEIVED

    def _resolve(self, frame: _Frame) -> None:
        sender = self._nodes[frame.sender_id]
        sender.tx_frame = None
        sender.events.append(RadioTxDone(frame.end_us, True))
        if sender.arm_after_tx:
            sender.arm_after_tx = False
            self._arm(sender, frame.end_us)
        receptions: list[Reception] = []
        for rid, (rssi_dbm, snr_db) in frame.link.items():
            fate = self._physical_fate(frame, rid, rssi_dbm)
            draw = draw_faults(self.faults, self._fault_rng) if self.faults.any else NO_FAULT
            payload = frame.payload
            if fate == RECEIVED:
                if draw.lost or (self.loss_rule is not None and self.loss_rule(frame.sender_id, rid, payload)):
                    fate = INJECTED_LOSS
                elif draw.corrupted and payload:
                    fate = CORRUPTED
                    payload = flip_bits(payload, self._fault_rng)
            if fate in (RECEIVED, CORRUPTED):
                self._deliver(self._nodes[rid], RadioRxFrame(frame.end_us, payload, rssi_dbm, snr_db))
                if fate == RECEIVED and draw.duplicated:
                    due_us = frame.end_us + self.faults.duplicate_delay_us
                    heapq.heappush(
                        self._heap,
                        (due_us, _DUPLICATE_DUE, rid, self._seq,
                         (rid, due_us, frame.reception_key, payload, rssi_dbm, snr_db)),
                    )
                    self._seq += 1
            self._counts[fate] += 1
            receptions.append(Reception(rid, rssi_dbm, snr_db, fate))
        self._counts["frames"] += 1
        del self._unresolved[frame.seq]
        if self._unresolved:
            oldest_start_us = min(f.start_us for f in self._unresolved.values())
            self._window = [f for f in self._window if f.end_us > oldest_start_us]
        else:
            self._window = []
        fa = frame.air
        # FSK frames have no spreading factor; LoRaTap and the inspector then show SF 0.
        air = AirFrame(
            frame.start_us, frame.end_us, frame.sender_id, fa.freq_hz,
            fa.modulation.sf if fa.is_lora else 0, fa.noise_bw_hz,
            frame.payload, tuple(receptions),
        )
        for sink in self._sinks:
            sink(air)

    def _arm(self, node: _Node, now_us: int) -> None:
        if node.listen_since_us is not None:
            return  # already armed: keep the original arming time
        for frame in self._unresolved.values():
            if (frame.start_us == now_us and frame.sender_id != node.node_id
                    and frame.reception_key == node.listen_key):
                frame.armed_at_start.add(node.node_id)  # armed in the same microsecond
        if node.waiting_duplicates and node.waiting_duplicates[0][0] == node.listen_key:
            _, payload, rssi_dbm, snr_db = node.waiting_duplicates.popleft()
            self._deliver(node, RadioRxFrame(now_us, payload, rssi_dbm, snr_db))
            self._counts["duplicates_delivered"] += 1
            return
        node.listen_since_us = now_us

    def _deliver(self, node: _Node, event: RadioRxFrame) -> None:
        node.events.append(event)
        node.listen_since_us = None

    def _duplicate_due(self, rid: int, due_us: int, key: tuple, payload: bytes, rssi_dbm: float,
                       snr_db: float) -> None:
        node = self._nodes[rid]
        if (node.listen_since_us is not None and node.listen_key == key) or self.profile.ideal:
            self._deliver(node, RadioRxFrame(due_us, payload, rssi_dbm, snr_db))
            self._counts["duplicates_delivered"] += 1
        else:
            node.waiting_duplicates.append((key, payload, rssi_dbm, snr_db))
