"""Link layer: record queue -> aggregated frames -> radio, with the law's airtime budget.

Pure and deterministic: time enters only as `now_us` arguments, the radio only as the HAL
RadioModem passed to `service`. One instance per robot.

Dialects: a link sends core records and the records of its own dialect (the scheme's, or
none), and decodes frames of every dialect in its DialectSet, delivering each record as
(sender, record name, values) whatever dialect it came in.

Per `service(now_us, radio)` call:
1. drain radio events: decode each received frame, count its reason, drop duplicates by
   (sender, seq) with a 64-frame RFC 1982 window per sender (256 senders at most, so memory
   is bounded), optionally queue it for relay (managed flood: hop limit in the header,
   duplicates never relayed), and hand its records to `received()`.
2. if the radio is idle, something waits and (with a TDMA schedule) the robot's slot is open
   long enough: build one frame (relays first, else the
   highest-priority records that fit `max_frame_bytes`: the profile's payload limit,
   or less under a byte-rate cap whose window holds less; grouped by type, core records
   first; a frame of this link's dialect, or of dialect 0 if it holds core records only), and send
   it only if (a) the sub-band airtime budget holds in the duty-cycle window ending when this
   frame would end (the worst window, see `_duty_cycle_ok`) and (b) with a byte-rate cap,
   the bytes sent in the last RATE_WINDOW_US plus this frame stay within cap x window.
   Otherwise it waits, and the reason is counted.

Counters (`counters`, all present from the start; see counter_names):
    sent.frames / sent.bytes / sent.records   everything this radio put on the air (relays too;
                                              records: own records only)
    relayed                                   frames re-sent for another originator
    airtime_us.<sub-band>                     own transmit time, per sub-band
    deferred.duty_cycle / .rate_cap / .radio_busy / .slot   service calls that had something
                                              to send but waited, by reason
    dropped.queue_full / .too_large / .relay_queue_full   records or relays thrown away
    superseded                                queued records replaced by a newer one (same key)
    received.<reason>                         frames by decode reason (ok = new, accepted;
                                              unknown_dialect = a dialect id not in our set)
    received.duplicate / .own / .records      repeats, own frames heard back, records delivered
    tx_done.ok / tx_done.failed               the modem's transmit-finished events
"""
from __future__ import annotations

from collections import deque
from collections.abc import Hashable, Mapping
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

from firmware.comms.codec import REASONS, Reason, encode
from firmware.comms.frame import (MAX_FRAME_BYTES, MAX_HOPS, MAX_RECORDS_PER_GROUP, SEQ_MODULUS,
                                  decode_frame, encode_frame_records, frame_size_bytes, seq_newer,
                                  with_hops)
from firmware.comms.schema import CORE_DIALECT_ID, Dialect, DialectSet, default_dialects
from hal.interfaces import RadioModem
from hal.lora import RadioProfile
from hal.samples import RadioRxFrame, RadioTxDone

DEDUP_WINDOW = 64
RATE_WINDOW_US = 10_000_000   # a byte-rate cap holds over every window this long (DESIGN.md's peak window)
TDMA_GUARD_US = 20_000   # idle time at the end of each slot: clock offset and modem turnaround


@dataclass(frozen=True)
class TdmaSchedule:
    """Time-division access for a team on one shared channel: time is cut into frames of
    `slots` slots of `slot_us`; robot k may start a transmission only inside slot k mod slots,
    and only if it ends `TDMA_GUARD_US` before the slot does. Robots that start together and
    tick in lockstep would otherwise key up together and collide (pure ALOHA), and a robot
    transmitting cannot hear (half duplex). Needs clocks that agree to within the guard."""

    slot_us: int
    slots: int
    own_slot: int

    def __post_init__(self) -> None:
        if self.slot_us <= TDMA_GUARD_US or self.slots < 1 or not 0 <= self.own_slot < self.slots:
            raise ValueError(f"bad TDMA schedule: slot {self.slot_us} us (guard {TDMA_GUARD_US} us), "
                             f"{self.slots} slots, own slot {self.own_slot}")

    @classmethod
    def for_team(cls, profile: RadioProfile, team_size: int, node_id: int,
                 tick_us: int) -> TdmaSchedule | None:
        """One slot per robot, each long enough for the longest frame plus the guard, rounded
        up to whole ticks of the radio task (transmissions start on ticks). None where slots
        buy nothing: a team of one, or a channel model without collisions (ideal profiles)."""
        if team_size <= 1 or profile.ideal:
            return None
        need_us = profile.airtime_us(min(profile.max_payload_bytes, MAX_FRAME_BYTES)) + TDMA_GUARD_US
        slot_us = -(-need_us // tick_us) * tick_us
        return cls(slot_us, team_size, node_id % team_size)

    def may_start(self, now_us: int, airtime_us: int) -> bool:
        in_frame_us = now_us % (self.slot_us * self.slots)
        start_us = self.own_slot * self.slot_us
        return start_us <= in_frame_us and in_frame_us + airtime_us <= start_us + self.slot_us - TDMA_GUARD_US


def counter_names(sub_band: str) -> tuple[str, ...]:
    """Every counter a LinkLayer keeps, all present from the start (zero)."""
    return (
        "sent.frames", "sent.bytes", "sent.records", "relayed", f"airtime_us.{sub_band}",
        "deferred.duty_cycle", "deferred.rate_cap", "deferred.radio_busy", "deferred.slot",
        "dropped.queue_full", "dropped.too_large", "dropped.relay_queue_full", "superseded",
        *(f"received.{r.value}" for r in REASONS),
        "received.duplicate", "received.own", "received.records",
        "tx_done.ok", "tx_done.failed",
    )


class LinkLayer:
    def __init__(self, node_id: int, profile: RadioProfile, relay_hop_limit: int = 0,
                 byte_rate_cap_Bps: float | None = None, queue_limit: int = 64,
                 relay_queue_limit: int = 8, first_seq: int = 0,
                 tdma: TdmaSchedule | None = None, dialect: Dialect | None = None,
                 dialects: DialectSet | None = None) -> None:
        """relay_hop_limit: hops left written into our frames, and whether we relay others'
        (0 = off). byte_rate_cap_Bps: None takes profile.byte_rate_cap_Bps; float('inf')
        disables a profile's cap. tdma: transmit only in this robot's slot (None: whenever
        the radio is idle). dialect: the records this robot sends besides the core's (its
        scheme's dialect; None: core records only). dialects: what it decodes (default:
        every dialect this firmware knows); it must hold `dialect`."""
        if not 0 <= node_id <= 255:
            raise ValueError(f"node_id {node_id} outside [0, 255]")
        if not 0 <= relay_hop_limit <= MAX_HOPS:
            raise ValueError(f"relay_hop_limit {relay_hop_limit} outside [0, {MAX_HOPS}]")
        if queue_limit < 1 or relay_queue_limit < 1:
            raise ValueError("queue limits must be >= 1")
        self.dialects = dialects if dialects is not None else default_dialects()
        if dialect is not None and dialect not in self.dialects:
            raise ValueError(f"dialect {dialect.name!r} (id {dialect.id}) is not in the link's dialect set")
        self.dialect = dialect
        # Record name -> its sort key in a frame: core records first, then own, by code.
        self._sendable: dict[str, tuple[int, int]] = {
            r.name: (d.id != CORE_DIALECT_ID, r.code)
            for d in (self.dialects.core, dialect) if d is not None for r in d.records}
        self.node_id = node_id
        self.profile = profile
        self.relay_hop_limit = relay_hop_limit
        self.queue_limit = queue_limit
        self.relay_queue_limit = relay_queue_limit
        self.tdma = tdma
        cap = profile.byte_rate_cap_Bps if byte_rate_cap_Bps is None else byte_rate_cap_Bps
        self._rate_Bps: Fraction | None = (
            None if cap is None or cap == float("inf") else Fraction(cap))
        if self._rate_Bps is not None and self._rate_Bps <= 0:
            raise ValueError(f"byte_rate_cap_Bps must be > 0, got {cap}")
        # The cap holds over every window of RATE_WINDOW_US, not just on average: a token
        # bucket lets a frame of burst through on top (105 B/s over 10 s at a 100 B/s cap).
        self._rate_window_bytes = (None if self._rate_Bps is None
                                   else int(self._rate_Bps * RATE_WINDOW_US / 1_000_000))
        self._sent_log: deque[tuple[int, int]] = deque()   # own (start_us, bytes) in the window
        self._sent_log_bytes = 0
        # A frame larger than the cap's window could never go, and under a cap frames are
        # sized to split the window evenly, so a saturated link uses all of it: a 1000-byte
        # window holds four 250-byte frames but only three of 252 bytes (76 %).
        self.max_frame_bytes = min(profile.max_payload_bytes, MAX_FRAME_BYTES)
        if self._rate_window_bytes is not None:
            frames_per_window = -(-self._rate_window_bytes // self.max_frame_bytes)
            self.max_frame_bytes = min(self.max_frame_bytes, self._rate_window_bytes // frames_per_window)
        self._budget_us = (None if profile.duty_cycle is None
                           else round(profile.duty_cycle * profile.duty_cycle_window_us))
        self._tx_log: deque[tuple[int, int]] = deque()   # own (start_us, end_us), this sub-band
        self._log_total_us = 0
        self._seq = first_seq % SEQ_MODULUS
        self._order = 0
        # queue entries: [priority, order, type name, record bytes, key]
        self._queue: list[list[Any]] = []
        self._relay: deque[bytes] = deque()
        # sender -> [highest seq, window mask, frames heard in the window since the first]
        self._seen: dict[int, list[int]] = {}
        # Own frames lately sent: (seq, the keys of the records they carried), for a teammate
        # that says it lost one.
        self._frames_sent: deque[tuple[int, tuple[Hashable, ...]]] = deque(maxlen=DEDUP_WINDOW)
        self._rx: list[tuple[int, str, dict[str, int]]] = []
        self._airtime_key = f"airtime_us.{profile.sub_band}"
        self._counters = dict.fromkeys(counter_names(profile.sub_band), 0)

    # ---- firmware-facing ---------------------------------------------------------------

    def enqueue(self, rtype: str, values: Mapping[str, Any] | Any, priority: int = 0,
                key: Hashable | None = None) -> bool:
        """Queue one record. Higher priority goes first; equal priority first come first.
        With `key`, a queued record with the same key is replaced (a newer heartbeat makes
        the old one worthless). False if dropped: too large for a frame, or the queue is full
        of records at least as important. ValueError for values out of range, or a record
        of neither the core nor this link's dialect."""
        rt = self.dialects.record(rtype)
        if rt.name not in self._sendable:
            raise ValueError(f"record {rt.name!r} is of dialect {self.dialects.dialect_of(rt).name!r}; this link "
                             f"sends core records and "
                             + (f"{self.dialect.name!r} records" if self.dialect else "no others"))
        data = encode(rt, values)
        if frame_size_bytes({rt.name: 1}, self.dialects) > self.max_frame_bytes:
            self._counters["dropped.too_large"] += 1
            return False
        if key is not None:
            for i, e in enumerate(self._queue):
                if e[4] == key:
                    del self._queue[i]
                    self._counters["superseded"] += 1
                    break
        if len(self._queue) >= self.queue_limit:
            # Evict the least important, oldest record, unless the newcomer is no better.
            victim = min(range(len(self._queue)), key=lambda i: (self._queue[i][0], self._queue[i][1]))
            self._counters["dropped.queue_full"] += 1
            if self._queue[victim][0] >= priority:
                return False
            del self._queue[victim]
        self._queue.append([priority, self._order, rt.name, data, key])
        self._order += 1
        return True

    def withdraw(self, key: Hashable) -> bool:
        """Take back the queued record with this key before it goes on the air (a repair
        another robot has just sent); True if one was waiting."""
        for i, e in enumerate(self._queue):
            if e[4] == key:
                del self._queue[i]
                return True
        return False

    def received(self) -> list[tuple[int, str, dict[str, int]]]:
        """Records received since the last call: (frame sender id, record type, values)."""
        out, self._rx = self._rx, []
        return out

    @property
    def counters(self) -> dict[str, int]:
        return dict(self._counters)

    def bytes_sent(self) -> int:
        """Bytes of the frames this node has put on the air (its own and relayed)."""
        return self._counters["sent.bytes"]

    @property
    def queue_len(self) -> int:
        return len(self._queue)

    def queued(self, rtype: str) -> int:
        """Records of this type waiting to be sent."""
        return sum(1 for e in self._queue if e[2] == rtype)

    def on_air_until_us(self) -> int:
        """When this node's last frame ends on the air (0 before its first)."""
        return self._tx_log[-1][1] if self._tx_log else 0

    @property
    def next_seq(self) -> int:
        return self._seq

    def sustained_Bps(self) -> float | None:
        """The bytes a second this node can send for ever, in full frames, within the duty
        cycle and the byte-rate cap (None: neither limits it)."""
        limits = []
        if self._budget_us is not None:
            frame = self.max_frame_bytes
            limits.append(frame * self._budget_us / self.profile.duty_cycle_window_us
                          / (self.profile.airtime_us(frame) / 1e6))
        if self._rate_Bps is not None:
            limits.append(float(self._rate_Bps))
        return min(limits) if limits else None

    def duty_cycle_headroom_us(self, now_us: int) -> int | None:
        """Airtime still allowed in the window ending now (None: no duty-cycle limit)."""
        if self._budget_us is None:
            return None
        return self._budget_us - self._window_use_us(now_us)

    def service(self, now_us: int, radio: RadioModem) -> None:
        for event in radio.poll():
            if isinstance(event, RadioRxFrame):
                self._on_frame(event.payload)
            elif isinstance(event, RadioTxDone):
                self._counters["tx_done.ok" if event.ok else "tx_done.failed"] += 1
        if not self._queue and not self._relay:
            return
        if radio.busy():
            self._counters["deferred.radio_busy"] += 1
            return
        if self.tdma is not None and not self.tdma.may_start(now_us, 0):
            self._counters["deferred.slot"] += 1   # not our slot: do not even build a frame
            return
        relay = bool(self._relay)
        if relay:
            frame, taken = self._relay[0], []
        else:
            frame, taken = self._build_frame()
        airtime_us = self.profile.airtime_us(len(frame))
        if self.tdma is not None and not self.tdma.may_start(now_us, airtime_us):
            self._counters["deferred.slot"] += 1
            return
        if not self._duty_cycle_ok(now_us, airtime_us):
            self._counters["deferred.duty_cycle"] += 1
            return
        if not self._rate_ok(now_us, len(frame)):
            self._counters["deferred.rate_cap"] += 1
            return
        if not radio.transmit(frame):
            self._counters["deferred.radio_busy"] += 1
            return
        if relay:
            self._relay.popleft()
            self._counters["relayed"] += 1
        else:
            taken_ids = {id(e) for e in taken}
            self._queue = [e for e in self._queue if id(e) not in taken_ids]
            self._frames_sent.append((self._seq, tuple(e[4] for e in taken if e[4] is not None)))
            self._seq = (self._seq + 1) % SEQ_MODULUS
            self._counters["sent.records"] += len(taken)
        if self._rate_window_bytes is not None:
            self._sent_log.append((now_us, len(frame)))
            self._sent_log_bytes += len(frame)
        self._tx_log.append((now_us, now_us + airtime_us))
        self._log_total_us += airtime_us
        self._counters["sent.frames"] += 1
        self._counters["sent.bytes"] += len(frame)
        self._counters[self._airtime_key] += airtime_us

    # ---- internals ---------------------------------------------------------------------

    def _build_frame(self) -> tuple[bytes, list[list[Any]]]:
        counts: dict[str, int] = {}
        size = frame_size_bytes({}, self.dialects)
        taken: list[list[Any]] = []
        for e in sorted(self._queue, key=lambda e: (-e[0], e[1])):
            n = counts.get(e[2], 0)
            grow = len(e[3]) + (1 if n % MAX_RECORDS_PER_GROUP == 0 else 0)
            if size + grow <= self.max_frame_bytes:
                size += grow
                counts[e[2]] = n + 1
                taken.append(e)
        # Group by type (fewest tags); keep priority order inside a type.
        ordered = sorted(taken, key=lambda e: self._sendable[e[2]])
        frame = encode_frame_records(self.node_id, self._seq, [(e[2], e[3]) for e in ordered],
                                     dialect=self.dialect, dialects=self.dialects,
                                     hops_left=self.relay_hop_limit)
        return frame, taken

    def _window_use_us(self, window_end_us: int) -> int:
        """Own airtime inside [end - W, end]. The log is in time order and pruned to the last
        W, so only its first entries can straddle the window start and only its last entry
        can run past the end: O(1) per call instead of O(frames per hour)."""
        start = window_end_us - self.profile.duty_cycle_window_us
        use = self._log_total_us
        for s, e in self._tx_log:
            if s >= start:
                break
            use -= min(e, start) - s
        for s, e in reversed(self._tx_log):
            if e <= window_end_us:
                break
            use -= e - max(s, window_end_us)
        return use

    def _duty_cycle_ok(self, now_us: int, airtime_us: int) -> bool:
        """ETSI: own transmit time in ANY window of length W must stay <= duty_cycle * W.
        Windows ending before now already held. For a window ending at t in [now, now+a],
        the new frame adds t - now while past frames leave at most as fast, so the sum grows;
        for t beyond now+a the new frame adds a constant and past frames only leave. So the
        window ending at now + airtime is the worst one: checking it is exact."""
        if self._budget_us is None:
            return True
        horizon = now_us - self.profile.duty_cycle_window_us
        while self._tx_log and self._tx_log[0][1] <= horizon:
            s, e = self._tx_log.popleft()
            self._log_total_us -= e - s
        return self._window_use_us(now_us + airtime_us) + airtime_us <= self._budget_us

    def _rate_ok(self, now_us: int, frame_bytes: int) -> bool:
        """Would a frame starting now keep the bytes started in (now - window, now] within
        the cap? That window is the worst one containing this frame (later windows hold
        fewer of the earlier frames), so checking it is exact."""
        if self._rate_window_bytes is None:
            return True
        horizon = now_us - RATE_WINDOW_US
        while self._sent_log and self._sent_log[0][0] <= horizon:
            self._sent_log_bytes -= self._sent_log.popleft()[1]
        return self._sent_log_bytes + frame_bytes <= self._rate_window_bytes

    def _is_duplicate(self, sender: int, seq: int) -> bool:
        """Check and mark (sender, seq). A sequence number far behind the window means the
        sender restarted: accept it and restart the window."""
        st = self._seen.get(sender)
        if st is None:
            self._seen[sender] = [seq, 1, 1]
            return False
        hi, mask, span = st
        if seq_newer(seq, hi):
            shift = (seq - hi) % SEQ_MODULUS
            st[0] = seq
            st[1] = ((mask << shift) | 1) & ((1 << DEDUP_WINDOW) - 1) if shift < DEDUP_WINDOW else 1
            st[2] = min(DEDUP_WINDOW, span + shift) if shift < DEDUP_WINDOW else 1
            return False
        back = (hi - seq) % SEQ_MODULUS
        if back >= DEDUP_WINDOW:
            self._seen[sender] = [seq, 1, 1]
            return False
        if mask >> back & 1:
            return True
        st[1] = mask | (1 << back)
        st[2] = max(span, back + 1)
        return False

    def missed_from(self, sender: int) -> list[int]:
        """Sequence numbers of the sender's frames this node has not received, among the
        last DEDUP_WINDOW up to the newest it has (from the first it heard), oldest first."""
        st = self._seen.get(sender)
        if st is None:
            return []
        hi, mask, span = st
        return [(hi - back) % SEQ_MODULUS for back in range(span - 1, 0, -1) if not mask >> back & 1]

    def keys_sent_in(self, seq: int) -> tuple[Hashable, ...]:
        """The keys of the keyed records this node's frame `seq` carried (none if it is not
        among the last DEDUP_WINDOW frames it sent)."""
        for sent_seq, keys in self._frames_sent:
            if sent_seq == seq:
                return keys
        return ()

    def _on_frame(self, payload: bytes) -> None:
        res = decode_frame(payload, self.dialects)
        if res.frame is None:
            self._counters[f"received.{res.reason.value}"] += 1
            return
        f = res.frame
        if f.sender_id == self.node_id:
            self._counters["received.own"] += 1
            return
        if self._is_duplicate(f.sender_id, f.seq):
            self._counters["received.duplicate"] += 1
            return
        self._counters[f"received.{Reason.OK.value}"] += 1
        self._counters["received.records"] += len(f.records)
        for name, values in f.records:
            self._rx.append((f.sender_id, name, values))
        if self.relay_hop_limit > 0 and f.hops_left > 0:
            if len(payload) > self.max_frame_bytes:
                self._counters["dropped.too_large"] += 1     # more than our rate cap ever lets out
            elif len(self._relay) >= self.relay_queue_limit:
                self._counters["dropped.relay_queue_full"] += 1
            else:
                self._relay.append(with_hops(bytes(payload), f.hops_left - 1, min(MAX_HOPS, f.hops_taken + 1),
                                             self.dialects))
