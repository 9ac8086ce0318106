"""Link layer against a fake RadioModem: aggregation, priorities, duty cycle, rate cap,
duplicates, relay, drops, determinism."""
import dataclasses

import pytest
from hypothesis import given, settings, strategies as st

from firmware.comms.frame import decode_frame, encode_frame, with_hops
from firmware.comms.link import RATE_WINDOW_US, TDMA_GUARD_US, LinkLayer, TdmaSchedule, counter_names
from firmware.comms.schema import SENDER, Dialect, DialectSet, Field, RecordType
from firmware.schemes import all_dialects
from firmware.schemes.bayer_faigl.records import DIALECT as BF
from hal.interfaces import RadioModem
from hal.lora import profile
from tests.doubles import FakeRadio


def Link(*args, **kwargs):
    """A link of a robot running Bayer & Faigl (it sends topo records beside the core's)."""
    return LinkLayer(*args, dialect=BF, **kwargs)


def topo(i, sender=1):
    return dict(sender_id=sender, x_cm=i, y_cm=-i, z_cm=0, presence=1, e_inf_code=i % 256, info_version=0)


def pose(sender=1, x=0):
    return dict(sender_id=sender, x_cm=x, y_cm=0, yaw_cdeg=0, speed_cmps=0, exploring=1, done=0,
                returning=0, vertex_count=0)


def step(link, radio, now_us):
    radio.now_us = now_us
    link.service(now_us, radio)


def test_fake_radio_satisfies_the_hal_protocol():
    assert isinstance(FakeRadio(profile("eu868-g3")), RadioModem)


def test_counters_all_present_from_start():
    link = Link(1, profile("eu868-g3"))
    assert set(link.counters) == set(counter_names("g3"))
    assert all(v == 0 for v in link.counters.values())
    assert {"received.ok", "received.bad_crc", "received.out_of_range", "deferred.duty_cycle",
            "airtime_us.g3", "dropped.too_large"} <= set(link.counters)


def test_aggregates_up_to_max_payload_then_sends_the_rest():
    prof = profile("eu868-g3")
    link, radio = Link(1, prof), FakeRadio(prof)
    for i in range(25):
        assert link.enqueue("topo", topo(i))
    step(link, radio, 0)
    assert len(radio.sent) == 1 and len(radio.sent[0][1]) == 252      # 20 vertices, 12 B each, 3 tags
    f = decode_frame(radio.sent[0][1]).frame
    assert [v["x_cm"] for _, v in f.records] == list(range(20)) and f.seq == 0
    step(link, radio, 1000)                       # still on the air
    assert len(radio.sent) == 1 and link.counters["deferred.radio_busy"] == 1
    step(link, radio, radio.busy_until_us)
    f2 = decode_frame(radio.sent[1][1]).frame
    assert [v["x_cm"] for _, v in f2.records] == list(range(20, 25)) and f2.seq == 1
    c = link.counters
    assert (c["sent.frames"], c["sent.records"], c["sent.bytes"]) == (2, 25, 252 + 9 + 1 + 60)
    assert link.bytes_sent() == 252 + 9 + 1 + 60
    assert c["airtime_us.g3"] == prof.airtime_us(252) + prof.airtime_us(70)
    assert c["tx_done.ok"] == 1 and link.queue_len == 0


def test_priority_first_and_mixed_types_grouped():
    prof = dataclasses.replace(profile("eu868-g3"), max_payload_bytes=9 + 1 + 12 + 1 + 12)
    link, radio = Link(1, prof), FakeRadio(prof)
    link.enqueue("topo", topo(1), priority=0)
    link.enqueue("topo", topo(2), priority=0)
    link.enqueue("pose", pose(x=5), priority=5)
    step(link, radio, 0)
    f = decode_frame(radio.sent[0][1]).frame
    assert [(n, v["x_cm"]) for n, v in f.records] == [("pose", 5), ("topo", 1)]   # core first, then own
    assert f.dialect_id == BF.id


def test_key_supersedes_older_record():
    prof = profile("eu868-g3")
    link, radio = Link(1, prof), FakeRadio(prof)
    link.enqueue("pose", pose(x=1), key="pose")
    link.enqueue("pose", pose(x=2), key="pose")
    assert link.queue_len == 1 and link.counters["superseded"] == 1
    step(link, radio, 0)
    assert [v["x_cm"] for _, v in decode_frame(radio.sent[0][1]).frame.records] == [2]


def test_withdraw_takes_a_queued_record_back_by_its_key():
    prof = profile("eu868-g3")
    link, radio = Link(1, prof), FakeRadio(prof)
    link.enqueue("topo", topo(1), key=("push", 1))
    link.enqueue("topo", topo(2), key=("push", 2))
    assert link.withdraw(("push", 1)) and not link.withdraw(("push", 1)) and not link.withdraw("nothing")
    assert link.queue_len == 1
    step(link, radio, 0)
    assert len(radio.sent) == 1 and len(decode_frame(radio.sent[0][1]).frame.records) == 1


def test_queue_full_and_too_large():
    prof = profile("eu868-g3")
    link = Link(1, prof, queue_limit=2)
    assert link.enqueue("topo", topo(1)) and link.enqueue("topo", topo(2))
    assert not link.enqueue("topo", topo(3))                 # no better than what waits
    assert link.enqueue("topo", topo(4), priority=1)          # evicts the oldest least important
    assert link.counters["dropped.queue_full"] == 2 and link.queue_len == 2
    small = dataclasses.replace(prof, max_payload_bytes=21)
    tiny = Link(1, small)
    assert not tiny.enqueue("topo", topo(1)) and tiny.counters["dropped.too_large"] == 1
    assert Link(1, dataclasses.replace(prof, max_payload_bytes=22)).enqueue("topo", topo(1))
    with pytest.raises(ValueError, match="x_cm"):
        link.enqueue("topo", topo(1 << 24))


def _brute_window_max_us(log, window_us):
    """Reference: largest own airtime in any window of length W (the max is reached with a
    window ending at some frame end)."""
    best = 0
    for _, end in log:
        start = end - window_us
        best = max(best, sum(max(0, min(e, end) - max(s, start)) for s, e in log))
    return best


def test_duty_cycle_holds_in_every_one_hour_window():
    prof = profile("eu868-g1")                 # 1 %: 36 s per hour
    link, radio = Link(1, prof), FakeRadio(prof)
    log = []
    for t_s in range(0, 2 * 3600 + 1):        # a record a second for two hours
        link.enqueue("pose", pose(x=t_s), key="pose")
        n = len(radio.sent)
        step(link, radio, t_s * 1_000_000)
        if len(radio.sent) > n:
            log.append((radio.now_us, radio.busy_until_us))
    c = link.counters
    assert c["deferred.duty_cycle"] > 0
    assert _brute_window_max_us(log, prof.duty_cycle_window_us) <= 36_000_000
    first_hour = sum(e - s for s, e in log if e <= 3600_000_000)
    assert first_hour > 0.95 * 36_000_000       # the budget is used, not wasted
    assert c["airtime_us.g1"] == sum(e - s for s, e in log)
    assert link.duty_cycle_headroom_us(2 * 3600 * 1_000_000) >= 0


@settings(max_examples=30, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 40), st.integers(1, 30)), min_size=1, max_size=60))
def test_window_sum_matches_plain_reference(events):
    """The O(1) window sum equals the obvious sum over the log, for arbitrary send times."""
    prof = dataclasses.replace(profile("eu868-g1"), duty_cycle=0.05, duty_cycle_window_us=10_000_000)
    link, radio = Link(1, prof), FakeRadio(prof)
    now, log = 0, []
    for gap_ds, n_records in events:
        now += gap_ds * 100_000
        for i in range(n_records):
            link.enqueue("topo", topo(i))
        k = len(radio.sent)
        step(link, radio, now)
        if len(radio.sent) > k:
            log.append((radio.now_us, radio.busy_until_us))
        for probe in (now, now + 123_456):
            want = sum(max(0, min(e, probe) - max(s, probe - 10_000_000)) for s, e in log)
            assert link._window_use_us(probe) == want
    assert _brute_window_max_us(log, 10_000_000) <= 500_000


@pytest.mark.parametrize("cap_Bps", [20.0, 100.0])
def test_byte_rate_cap_holds_over_every_10_s_window(cap_Bps):
    """Not just on average: a token bucket let a frame of burst through on top of the cap
    (105 B/s over 10 s at 100 B/s). Every window the inspector measures peaks over stays
    within cap x window, and a saturated link still uses most of it."""
    prof = profile("eu868-g3")
    link, radio = Link(1, prof, byte_rate_cap_Bps=cap_Bps), FakeRadio(prof)
    for t_ms in range(0, 120_000, 10):
        while link.queue_len < 40:
            link.enqueue("topo", topo(t_ms % 1000))
        step(link, radio, t_ms * 1000)
    assert link.counters["deferred.rate_cap"] > 0
    times = [t for t, _ in radio.sent]
    sizes = [len(f) for _, f in radio.sent]
    assert max(sizes) <= cap_Bps * RATE_WINDOW_US / 1e6
    worst = max(sum(n for t, n in zip(times, sizes) if t0 <= t < t0 + RATE_WINDOW_US) for t0 in times)
    assert worst <= cap_Bps * RATE_WINDOW_US / 1e6
    assert sum(sizes) >= 0.9 * cap_Bps * 120


def test_ideal_profile_takes_its_cap_and_inf_disables_it():
    ideal = profile("ideal-100Bps")
    assert Link(1, ideal)._rate_Bps == 100
    assert Link(1, ideal).max_frame_bytes == 250            # four to a 10 s window of 1000 bytes
    assert Link(1, ideal, byte_rate_cap_Bps=20.0).max_frame_bytes == 200
    assert Link(1, ideal, byte_rate_cap_Bps=float("inf")).max_frame_bytes == 255
    assert Link(1, ideal, byte_rate_cap_Bps=float("inf"))._rate_Bps is None
    assert Link(1, profile("eu868-g3"))._rate_Bps is None


def test_radio_refusal_keeps_the_records():
    prof = profile("eu868-g3")
    link, radio = Link(1, prof), FakeRadio(prof, refuse=True)
    link.enqueue("topo", topo(1))
    step(link, radio, 0)
    assert link.queue_len == 1 and link.counters["deferred.radio_busy"] == 1 and link.next_seq == 0


def test_duplicates_suppressed_with_rfc1982_wrap():
    prof = profile("eu868-g3")
    link, radio = Link(2, prof), FakeRadio(prof)
    seqs = [65534, 65535, 0, 1, 65535, 1, 0, 3, 2, 2]
    for s in seqs:
        radio.deliver(encode_frame(7, s, [("topo", topo(s % 100, sender=7))]))
    step(link, radio, 0)
    got = link.received()
    assert [v["x_cm"] for _, _, v in got] == [s % 100 for s in (65534, 65535, 0, 1, 3, 2)]
    assert all(sender == 7 and name == "topo" for sender, name, _ in got)
    c = link.counters
    assert (c["received.ok"], c["received.duplicate"], c["received.records"]) == (6, 4, 6)
    assert link.received() == []
    # A restart (seq far behind the window) is accepted and restarts the window.
    radio.deliver(encode_frame(7, 1000, [("topo", topo(1, sender=7))]))
    radio.deliver(encode_frame(7, 1000, [("topo", topo(1, sender=7))]))
    step(link, radio, 1)
    assert len(link.received()) == 1 and link.counters["received.duplicate"] == 5


def test_bad_frames_counted_by_reason_and_own_frames_ignored():
    prof = profile("eu868-g3")
    link, radio = Link(2, prof), FakeRadio(prof)
    good = encode_frame(7, 1, [("topo", topo(1, sender=7))])
    radio.deliver(good[:-1] + bytes([good[-1] ^ 0xFF]))
    radio.deliver(good[:4])
    radio.deliver(b"\x00" * 30)
    radio.deliver(good + b"x")
    radio.deliver(encode_frame(2, 9, [("topo", topo(1, sender=2))]))
    step(link, radio, 0)
    c = link.counters
    assert (c["received.bad_crc"], c["received.truncated"], c["received.unknown_version"],
            c["received.bad_length"], c["received.own"], c["received.ok"]) == (1, 1, 1, 1, 1, 0)
    assert link.received() == []


def test_relay_off_by_default_and_managed_flood_when_on():
    prof = profile("eu868-g3")
    plain, plain_radio = Link(2, prof), FakeRadio(prof)
    plain_radio.deliver(encode_frame(7, 1, [("topo", topo(1, sender=7))], hops_left=3))
    step(plain, plain_radio, 0)
    assert plain_radio.sent == [] and plain.counters["relayed"] == 0

    origin = Link(7, prof, relay_hop_limit=2)
    o_radio = FakeRadio(prof)
    origin.enqueue("topo", topo(1, sender=7))
    step(origin, o_radio, 0)
    original = o_radio.sent[0][1]
    assert decode_frame(original).frame.hops_left == 2

    relay, r_radio = Link(3, prof, relay_hop_limit=2), FakeRadio(prof)
    r_radio.deliver(original)
    r_radio.deliver(original)                         # heard twice: relayed once
    step(relay, r_radio, 0)
    assert len(r_radio.sent) == 1 and relay.counters["relayed"] == 1
    f = decode_frame(r_radio.sent[0][1]).frame
    assert (f.sender_id, f.seq, f.hops_left, f.hops_taken) == (7, 0, 1, 1)
    assert r_radio.sent[0][1] == with_hops(original, 1, 1)
    assert relay.next_seq == 0                        # relays do not use our sequence numbers

    far, f_radio = Link(4, prof, relay_hop_limit=2), FakeRadio(prof)
    f_radio.deliver(r_radio.sent[0][1])
    f_radio.deliver(original)
    step(far, f_radio, 0)
    assert far.counters["received.ok"] == 1 and far.counters["received.duplicate"] == 1
    assert len(far.received()) == 1
    last = decode_frame(f_radio.sent[0][1]).frame
    assert (last.hops_left, last.hops_taken) == (0, 2)       # and nobody relays it again


def test_deterministic_bytes():
    def run():
        prof = profile("eu868-g1")
        link, radio = Link(5, prof, byte_rate_cap_Bps=30.0), FakeRadio(prof)
        for t in range(0, 600):
            link.enqueue("topo", topo(t), priority=t % 3)
            if t % 7 == 0:
                link.enqueue("pose", pose(5, t), key="pose", priority=9)
            step(link, radio, t * 250_000)
        return radio.sent, link.counters
    assert run() == run()


@settings(max_examples=100, deadline=None)
@given(st.integers(0, 65535), st.lists(st.integers(0, 63), min_size=1, max_size=120))
def test_duplicate_iff_seen_before_within_the_window(base, offsets):
    """Within a 64-wide span (wrapping anywhere in the 16-bit space) a frame is a duplicate
    exactly when the same sequence number was accepted before, whatever the arrival order."""
    prof = profile("eu868-g3")
    link, radio = Link(2, prof), FakeRadio(prof)
    seen = set()
    for off in offsets:
        seq = (base + off) % 65536
        radio.deliver(encode_frame(9, seq, [("topo", topo(off, sender=9))]))
        before = link.counters["received.duplicate"]
        step(link, radio, 0)
        assert (link.counters["received.duplicate"] > before) == (seq in seen)
        seen.add(seq)


def test_tdma_sends_only_in_own_slot_and_fits_the_longest_frame():
    prof = profile("eu868-g3")
    tick_us = 50_000
    sched = TdmaSchedule.for_team(prof, 5, 7, tick_us)
    assert sched.own_slot == 2 and sched.slots == 5 and sched.slot_us % tick_us == 0
    assert sched.slot_us >= prof.airtime_us(255) + TDMA_GUARD_US
    assert TdmaSchedule.for_team(prof, 1, 0, tick_us) is None                    # alone on the air
    assert TdmaSchedule.for_team(profile("ideal-100Bps"), 5, 0, tick_us) is None  # no collisions to avoid
    link, radio = Link(7, prof, tdma=sched), FakeRadio(prof)
    for i in range(60):
        link.enqueue("topo", topo(i))
    period = sched.slot_us * sched.slots
    for now in range(0, 3 * period, tick_us):
        step(link, radio, now)
    assert link.queue_len == 0 and len(radio.sent) == 3
    for start, frame in radio.sent:
        offset = start % period
        assert sched.slot_us * 2 <= offset
        assert offset + prof.airtime_us(len(frame)) <= sched.slot_us * 3 - TDMA_GUARD_US
    assert link.counters["deferred.slot"] > 0


def test_tdma_slots_of_a_team_never_overlap():
    prof = profile("eu868-g1")
    scheds = [TdmaSchedule.for_team(prof, 4, k, 50_000) for k in range(4)]
    period = scheds[0].slot_us * 4
    air = prof.airtime_us(255)
    for now in range(0, period, 10_000):
        assert sum(s.may_start(now, 0) for s in scheds) <= 1
        open_ = [s for s in scheds if s.may_start(now, air)]
        assert len(open_) <= 1
    with pytest.raises(ValueError):
        TdmaSchedule(10_000, 4, 0)
    with pytest.raises(ValueError):
        TdmaSchedule(100_000, 4, 4)


def test_a_relay_larger_than_the_rate_cap_lets_out_is_dropped_and_counted():
    """At 20 B/s a 10 s window holds 200 bytes: a bigger frame to relay could never go, and
    left at the head of the relay queue it would block everything behind it."""
    prof = profile("eu868-g3")
    link, radio = Link(3, prof, relay_hop_limit=2, byte_rate_cap_Bps=20.0), FakeRadio(prof)
    big = encode_frame(7, 0, [("topo", topo(i, sender=7)) for i in range(20)], hops_left=2)
    small = encode_frame(7, 1, [("topo", topo(1, sender=7))], hops_left=2)
    assert len(big) > 200 >= len(small)
    radio.deliver(big)
    radio.deliver(small)
    step(link, radio, 0)
    assert link.counters["dropped.too_large"] == 1
    assert [decode_frame(f).frame.seq for _, f in radio.sent] == [1]


BLIP = RecordType(1, "blip", 2, (SENDER, Field("level_id", 8)))
OTHER = Dialect(200, "other", (BLIP,))     # an id no scheme uses


def test_a_link_sends_core_and_own_records_only_and_frames_of_core_records_go_as_dialect_0():
    prof = profile("eu868-g3")
    link, radio = Link(1, prof), FakeRadio(prof)
    with pytest.raises(ValueError, match="unknown record type 'blip'"):
        link.enqueue("blip", dict(sender_id=1, level_id=0))          # in no dialect it knows
    knows_more = Link(1, prof, dialects=DialectSet([*all_dialects(), OTHER]))
    with pytest.raises(ValueError, match="'blip' is of dialect 'other'; this link sends core records and 'bayer_faigl'"):
        knows_more.enqueue("blip", dict(sender_id=1, level_id=0))    # another scheme's record
    quiet = LinkLayer(1, prof)                                        # a scheme without records
    with pytest.raises(ValueError, match="'topo' is of dialect 'bayer_faigl'; this link sends core records and no others"):
        quiet.enqueue("topo", topo(1))
    link.enqueue("pose", pose())
    step(link, radio, 0)
    assert radio.sent[-1][1][1] == 0 and decode_frame(radio.sent[-1][1]).frame.dialect_id == 0
    with pytest.raises(ValueError, match="not in the link's dialect set"):
        LinkLayer(1, prof, dialect=OTHER)


def test_a_link_delivers_records_of_every_dialect_it_knows_and_counts_the_rest():
    prof = profile("eu868-g3")
    known = DialectSet([*all_dialects(), OTHER])
    link, radio = LinkLayer(2, prof, dialect=BF, dialects=known), FakeRadio(prof)
    radio.deliver(encode_frame(7, 1, [("pose", pose(7)), ("topo", topo(1, sender=7))]))
    radio.deliver(encode_frame(8, 1, [("pose", pose(8)), ("blip", dict(sender_id=8, level_id=3))], dialects=known))
    step(link, radio, 0)
    assert [(s, n) for s, n, _ in link.received()] == [(7, "pose"), (7, "topo"), (8, "pose"), (8, "blip")]
    # A peer that knows only our dialects counts the other scheme's frames and reads the rest.
    plain, plain_radio = Link(3, prof), FakeRadio(prof)
    plain_radio.deliver(encode_frame(8, 1, [("blip", dict(sender_id=8, level_id=3))], dialects=known))
    plain_radio.deliver(encode_frame(8, 2, [("pose", pose(8))], dialect=OTHER, dialects=known))
    step(plain, plain_radio, 0)
    assert plain.counters["received.unknown_dialect"] == 1 and plain.counters["received.ok"] == 1
    assert [(s, n) for s, n, _ in plain.received()] == [(8, "pose")]


def test_the_sustained_byte_rate_is_full_frames_within_the_duty_cycle_or_the_cap():
    g3 = LinkLayer(0, profile("eu868-g3"))
    full = g3.max_frame_bytes
    frames_an_hour = 0.1 * 3600e6 / profile("eu868-g3").airtime_us(full)       # 10 % of the hour
    assert g3.sustained_Bps() == pytest.approx(frames_an_hour * full / 3600)
    assert LinkLayer(0, profile("eu868-g1")).sustained_Bps() == pytest.approx(g3.sustained_Bps() / 10)
    assert LinkLayer(0, profile("ideal-100Bps")).sustained_Bps() == 100.0
    assert LinkLayer(0, profile("us915")).sustained_Bps() is None                # neither limit


def test_a_receiver_knows_which_frames_it_missed_and_the_sender_what_keyed_records_they_carried():
    prof = profile("ideal-100Bps")
    tx, tx_radio = Link(1, prof), FakeRadio(prof)
    rx, rx_radio = Link(2, prof), FakeRadio(prof)
    now = 0
    for i in range(8):                                  # frames 0..7, one keyed record each
        tx.enqueue("topo", topo(i), key=("topo", i))
        now = tx_radio.busy_until_us
        step(tx, tx_radio, now)
    assert [tx.keys_sent_in(i) for i in (0, 5, 7)] == [(("topo", 0),), (("topo", 5),), (("topo", 7),)]
    assert tx.keys_sent_in(8) == ()                     # not sent (yet)
    for seq in (0, 1, 4):
        rx_radio.deliver(tx_radio.sent[seq][1])
    step(rx, rx_radio, now)
    assert rx.missed_from(1) == [2, 3]                  # up to the newest heard
    rx_radio.deliver(tx_radio.sent[7][1])
    rx_radio.deliver(tx_radio.sent[3][1])               # a late one fills its gap
    step(rx, rx_radio, now)
    assert rx.missed_from(1) == [2, 5, 6]
    assert rx.missed_from(9) == []                      # never heard
    late, late_radio = Link(3, prof), FakeRadio(prof)   # came into range at frame 5
    for seq in (5, 7):
        late_radio.deliver(tx_radio.sent[seq][1])
    step(late, late_radio, now)
    assert late.missed_from(1) == [6]
