"""The shared LoRa channel: collisions and capture, the preamble rule at its exact boundary,
half duplex, range and walls, one-shot reception, the ideal profile, injected faults,
determinism, event order, the simulated modem, and the wall-crossing kernel."""
from __future__ import annotations

import math
from dataclasses import replace
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hal.interfaces import RadioModem
from hal.lora import AirInterface, LoraModulation, profile
from hal.samples import RadioRxFrame, RadioTxDone
from hal.sim.radio import SimRadioModem, attach_sim_radios
from radio_sim.air_log import (
    COLLIDED, CORRUPTED, FATES, HALF_DUPLEX, INJECTED_LOSS, NOT_LISTENING, OUT_OF_RANGE, RECEIVED,
)
from radio_sim.channel import Channel
from radio_sim.faults import FaultParams
from radio_sim.propagation import (
    SUBCELLS_PER_CELL, PropagationParams, WallCounter, count_wall_crossings_nb,
    count_wall_crossings_ref, sensitivity_dbm, traversed_cells_ref,
)
from world_sim.occupancy_map import OccupancyMap
from world_sim.seeding import stream
from tests.doubles import StepClock

G1 = profile("eu868-g1")                    # SF7 / BW125, 14 dBm
T_SYM_US = 1024                             # 2^7 / 125 kHz
AIRTIME_12B_US = 41_216
GRACE_US = 3 * T_SYM_US                     # the first 3 of 8 preamble symbols may be lost


class World:
    """Nodes at positions that a test may move; a channel over them; every AirFrame kept."""

    def __init__(self, positions: dict[int, tuple[float, float]], prof=G1, seed: int = 7, **kwargs):
        self.positions = dict(positions)
        self.channel = Channel(prof, seed, **kwargs)
        for node_id in sorted(self.positions):
            self.channel.attach(node_id, lambda n=node_id: self.positions[n])
        self.frames = []
        self.channel.add_sink(self.frames.append)

    def fate(self, sender_id: int, receiver_id: int, nth: int = 0) -> str:
        sent = [f for f in self.frames if f.sender_id == sender_id]
        return next(r.fate for r in sent[nth].receptions if r.receiver_id == receiver_id)

    def rssi(self, sender_id: int, receiver_id: int) -> float:
        sent = [f for f in self.frames if f.sender_id == sender_id]
        return next(r.rssi_dbm for r in sent[0].receptions if r.receiver_id == receiver_id)


# ---------------------------------------------------------------------------------------------
# collisions and capture
# ---------------------------------------------------------------------------------------------


def test_same_start_equal_power_both_lost():
    w = World({0: (0.0, 0.0), 1: (10.0, 0.0), 2: (-10.0, 0.0)})
    w.channel.transmit(1, b"A" * 12, 0)
    w.channel.transmit(2, b"B" * 12, 0)
    w.channel.advance_to(AIRTIME_12B_US)
    assert w.fate(1, 0) == COLLIDED and w.fate(2, 0) == COLLIDED
    assert w.fate(1, 2) == HALF_DUPLEX and w.fate(2, 1) == HALF_DUPLEX
    assert [e for e in w.channel.take_events(0)] == []
    assert w.channel.listening(0)  # nothing was delivered, so the receiver is still armed


@pytest.mark.parametrize("near_m, far_m, near_survives", [
    (10.0, 20.0, True),                              # 8.1 dB apart: capture
    (10.0, 10.0 * 10 ** (6.01 / 27), True),          # just over 6 dB
    (10.0, 10.0 * 10 ** (5.99 / 27), False),         # just under 6 dB: both lost
])
def test_same_start_capture_threshold(near_m, far_m, near_survives):
    w = World({0: (0.0, 0.0), 1: (near_m, 0.0), 2: (-far_m, 0.0)})
    w.channel.transmit(1, b"N" * 12, 0)
    w.channel.transmit(2, b"F" * 12, 0)
    w.channel.advance_to(AIRTIME_12B_US)
    assert w.fate(1, 0) == (RECEIVED if near_survives else COLLIDED)
    assert w.fate(2, 0) == COLLIDED
    events = w.channel.take_events(0)
    assert [e.payload for e in events] == ([b"N" * 12] if near_survives else [])


@pytest.mark.parametrize("first, second", [(1, 2), (2, 1)])
@pytest.mark.parametrize("first_bytes, second_bytes", [(12, 12), (12, 40), (40, 12)])
@pytest.mark.parametrize("early_by_us, collide", [(0, False), (1, True)])
def test_preamble_rule_exact_boundary(first, second, first_bytes, second_bytes, early_by_us, collide):
    """Equal power at both receivers. The second frame starts so that the overlap ends exactly
    3 symbols into its preamble (no collision: neither frame is harmed), or starts 1 us
    earlier so the overlap reaches into the 4th symbol (collision: both lost). Receiver 0 is armed throughout; receiver 3 arms only when the
    second frame starts, so it sees the second frame's fate on its own."""
    w = World({0: (0.0, 0.0), 3: (0.0, 5.0), 1: (10.0, 0.0), 2: (-10.0, 0.0)})
    assert abs(w.channel.preamble_grace_us - GRACE_US) == 0
    w.channel.set_listening(3, False, 0)
    first_end = w.channel.transmit(first, bytes(first_bytes), 0)
    second_start = first_end - GRACE_US - early_by_us
    w.channel.set_listening(3, True, second_start)
    w.channel.transmit(second, bytes(second_bytes), second_start)
    w.channel.advance_to(10_000_000)
    assert w.fate(first, 3) == NOT_LISTENING
    if collide:
        assert (w.fate(first, 0), w.fate(second, 0), w.fate(second, 3)) == (COLLIDED, COLLIDED, COLLIDED)
    else:
        # receiver 0 took the first frame and was disarmed by it (one-shot)
        assert (w.fate(first, 0), w.fate(second, 0), w.fate(second, 3)) == (RECEIVED, NOT_LISTENING, RECEIVED)


@pytest.mark.parametrize("later_is_stronger", [True, False])
def test_capture_inside_the_collision_window(later_is_stronger):
    near, far = (10.0, 0.0), (-30.0, 0.0)   # 12.9 dB apart
    w = World({0: (0.0, 0.0), 3: (0.0, 0.1), 1: near if not later_is_stronger else far,
               2: far if not later_is_stronger else near})
    w.channel.set_listening(3, False, 0)
    w.channel.transmit(1, bytes(12), 0)
    w.channel.set_listening(3, True, 20_000)
    w.channel.transmit(2, bytes(12), 20_000)    # 21 ms of overlap: well inside the payload
    w.channel.advance_to(1_000_000)
    if later_is_stronger:
        assert w.fate(1, 0) == COLLIDED and w.fate(2, 0) == RECEIVED and w.fate(2, 3) == RECEIVED
    else:
        assert w.fate(1, 0) == RECEIVED and w.fate(2, 3) == COLLIDED


def test_interferer_below_sensitivity_is_ignored():
    w = World({0: (0.0, 0.0), 1: (10.0, 0.0), 2: (-50_000.0, 0.0)})
    w.channel.transmit(1, bytes(12), 0)
    w.channel.transmit(2, bytes(12), 0)
    w.channel.advance_to(AIRTIME_12B_US)
    assert w.fate(2, 0) == OUT_OF_RANGE
    assert w.fate(1, 0) == RECEIVED


# ---------------------------------------------------------------------------------------------
# half duplex, arming, one-shot reception
# ---------------------------------------------------------------------------------------------


def test_half_duplex_partial_overlap_both_ways():
    w = World({0: (0.0, 0.0), 1: (10.0, 0.0)})
    w.channel.transmit(1, bytes(12), 0)
    w.channel.transmit(0, bytes(12), 20_000)     # 0 starts sending in the middle of 1's frame
    w.channel.advance_to(1_000_000)
    assert w.fate(1, 0) == HALF_DUPLEX and w.fate(0, 1) == HALF_DUPLEX


def test_transmit_disarms_and_back_to_back_frames_need_rearming():
    w = World({0: (0.0, 0.0), 1: (10.0, 0.0)})
    end = w.channel.transmit(0, bytes(12), 0)
    w.channel.transmit(1, bytes(12), end)          # starts as 0's frame ends: no overlap
    w.channel.advance_to(10 * end)
    assert w.fate(1, 0) == NOT_LISTENING           # 0 left receive mode to transmit

    w = World({0: (0.0, 0.0), 1: (10.0, 0.0)})
    end = w.channel.transmit(0, bytes(12), 0)
    w.channel.set_listening(0, True, end)
    w.channel.transmit(1, bytes(12), end)
    w.channel.advance_to(10 * end)
    assert w.fate(1, 0) == RECEIVED


def test_arming_while_transmitting_takes_effect_at_the_end():
    w = World({0: (0.0, 0.0), 1: (10.0, 0.0)})
    end = w.channel.transmit(0, bytes(12), 0)
    w.channel.set_listening(0, True, 1_000)
    assert not w.channel.listening(0)
    w.channel.advance_to(end)
    assert w.channel.listening(0)
    w.channel.transmit(1, bytes(12), end)
    w.channel.advance_to(10 * end)
    assert w.fate(1, 0) == RECEIVED


def test_one_shot_reception():
    w = World({0: (0.0, 0.0), 1: (10.0, 0.0), 2: (-10.0, 0.0)})
    w.channel.transmit(1, b"first", 0)
    w.channel.transmit(2, b"second", 100_000)
    w.channel.advance_to(1_000_000)
    assert (w.fate(1, 0), w.fate(2, 0)) == (RECEIVED, NOT_LISTENING)
    assert [e.payload for e in w.channel.take_events(0)] == [b"first"]

    w = World({0: (0.0, 0.0), 1: (10.0, 0.0), 2: (-10.0, 0.0)})
    w.channel.transmit(1, b"first", 0)
    w.channel.set_listening(0, True, 50_000)      # the driver's 'radio rx 0' after the first
    w.channel.transmit(2, b"second", 100_000)
    w.channel.advance_to(1_000_000)
    assert (w.fate(1, 0), w.fate(2, 0)) == (RECEIVED, RECEIVED)
    assert [e.payload for e in w.channel.take_events(0)] == [b"first", b"second"]


@pytest.mark.parametrize("arm_at_us, arm_after_the_transmit_call, expected", [
    (-1, False, RECEIVED), (0, False, RECEIVED), (0, True, RECEIVED), (1, True, NOT_LISTENING),
])
def test_must_be_armed_at_the_frame_start(arm_at_us, arm_after_the_transmit_call, expected):
    w = World({0: (0.0, 0.0), 1: (10.0, 0.0)})
    w.channel.set_listening(0, False, 0)
    frame_start_us = 1_000
    if not arm_after_the_transmit_call:
        w.channel.set_listening(0, True, frame_start_us + arm_at_us)
    w.channel.transmit(1, bytes(12), frame_start_us)
    if arm_after_the_transmit_call:
        w.channel.set_listening(0, True, frame_start_us + arm_at_us)
    w.channel.advance_to(1_000_000)
    assert w.fate(1, 0) == expected


def test_rxstop_and_rearm_during_a_frame_loses_it():
    w = World({0: (0.0, 0.0), 1: (10.0, 0.0)})
    w.channel.transmit(1, bytes(12), 0)
    w.channel.set_listening(0, False, 10_000)
    w.channel.set_listening(0, True, 20_000)
    w.channel.advance_to(1_000_000)
    assert w.fate(1, 0) == NOT_LISTENING


def test_refusals_and_time_errors():
    w = World({0: (0.0, 0.0), 1: (10.0, 0.0)})
    assert w.channel.transmit(0, bytes(256), 0) is None          # over max_payload_bytes
    assert w.channel.transmit(0, bytes(255), 0) is not None
    assert w.channel.transmit(0, bytes(1), 5) is None            # still transmitting
    with pytest.raises(ValueError, match="backwards"):
        w.channel.advance_to(4)
    with pytest.raises(KeyError, match="node 9 is not attached"):
        w.channel.transmit(9, b"x", 10)
    with pytest.raises(ValueError, match="already attached"):
        w.channel.attach(1, lambda: (0.0, 0.0))
    with pytest.raises(TypeError):
        w.channel.transmit(1, b"x", 10.5)
    with pytest.raises(TypeError):
        w.channel.advance_to(11.0)
    w.channel.advance_to(np.int64(12))
    assert w.channel.airtime_us_by_node() == {0: G1.airtime_us(255), 1: 0}


# ---------------------------------------------------------------------------------------------
# range and walls
# ---------------------------------------------------------------------------------------------


def _corridor_map(length_m: int, wall_cols: tuple[int, ...], thickness_cells: int = 1) -> OccupancyMap:
    free = np.ones((4, length_m), dtype=bool)
    for c in wall_cols:
        free[:, c:c + thickness_cells] = False
    return OccupancyMap(free, resolution_m=1.0, origin_x_m=0.0, origin_y_m=0.0, name="corridor")


def test_sensitivity_boundary_line_of_sight():
    params = PropagationParams()
    range_m = params.max_range_m(G1.tx_power_dbm, G1.modulation)
    w = World({0: (0.0, 0.0), 1: (0.999 * range_m, 0.0), 2: (-1.001 * range_m, 0.0)})
    w.channel.transmit(0, bytes(12), 0)
    w.channel.advance_to(AIRTIME_12B_US)
    assert w.fate(0, 1) == RECEIVED and w.fate(0, 2) == OUT_OF_RANGE
    assert w.rssi(0, 1) == pytest.approx(sensitivity_dbm(G1.modulation), abs=0.05)


def test_three_walls_put_a_line_of_sight_link_out_of_range():
    params = PropagationParams()
    los_range_m = params.max_range_m(G1.tx_power_dbm, G1.modulation)
    walled_range_m = params.max_range_m(G1.tx_power_dbm, G1.modulation, walls=3)
    distance_m = 2_900.0
    assert walled_range_m < distance_m < los_range_m
    a, b = (0.5, 2.0), (0.5 + distance_m, 2.0)
    open_w = World({0: a, 1: b}, occupancy=_corridor_map(3_000, ()))
    walled = World({0: a, 1: b}, occupancy=_corridor_map(3_000, (1_000, 1_500, 2_000)))
    for w in (open_w, walled):
        w.channel.transmit(0, bytes(12), 0)
        w.channel.advance_to(AIRTIME_12B_US)
    assert open_w.fate(0, 1) == RECEIVED
    assert walled.fate(0, 1) == OUT_OF_RANGE
    assert open_w.rssi(0, 1) - walled.rssi(0, 1) == pytest.approx(3 * params.wall_loss_db)
    # nearer than the walled range, the same three walls still let it through
    near = World({0: a, 1: (0.5 + 2_300.0, 2.0)}, occupancy=_corridor_map(3_000, (1_000, 1_500, 2_000)))
    near.channel.transmit(0, bytes(12), 0)
    near.channel.advance_to(AIRTIME_12B_US)
    assert near.fate(0, 1) == RECEIVED


def test_wall_counter_counts_runs_not_cells():
    thick = WallCounter(_corridor_map(100, (10, 50), thickness_cells=5))
    assert thick.walls_between((0.5, 2.0), (99.5, 2.0)) == 2
    assert thick.walls_between((99.5, 2.0), (0.5, 2.0)) == 2
    assert thick.walls_between((0.5, 2.0), (30.5, 2.0)) == 1
    assert thick.walls_between((12.5, 2.0), (30.5, 2.0)) == 0     # starting inside a wall
    assert thick.walls_between((-50.0, 2.0), (200.0, 2.0)) == 2   # outside the map counts as free


def test_propagation_numbers():
    p = PropagationParams()
    assert p.path_loss_db(1.0) == pytest.approx(31.2)
    assert p.path_loss_db(0.2) == pytest.approx(31.2)
    assert p.path_loss_db(10.0, walls=2) == pytest.approx(31.2 + 27.0 + 12.0)
    assert p.noise_floor_dbm(125_000) == pytest.approx(-174 + 10 * math.log10(125_000) + 6)
    assert sensitivity_dbm(LoraModulation(7, 250_000)) == -124.25
    assert sensitivity_dbm(LoraModulation(12, 125_000)) == -133.25
    with pytest.raises(ValueError, match="SF6"):
        sensitivity_dbm(LoraModulation(6, 125_000))
    with pytest.raises(ValueError, match="wall_loss_db"):
        PropagationParams(wall_loss_db=-1.0)


# ---------------------------------------------------------------------------------------------
# ideal profile, faults, determinism, ordering
# ---------------------------------------------------------------------------------------------


def test_ideal_profile_delivers_everything():
    ideal = profile("ideal-100Bps")
    far = {i: (i * 40_000.0, 0.0) for i in range(5)}
    w = World(far, prof=ideal, occupancy=_corridor_map(50, (5, 10, 20, 30)))
    w.channel.set_listening(3, False, 0)          # arming does not matter on the ideal link
    ends = [w.channel.transmit(i, bytes([i]) * 20, 0) for i in range(5)]
    assert ends == [200_000] * 5
    w.channel.advance_to(200_000)
    assert len(w.frames) == 5
    assert all(r.fate == RECEIVED for f in w.frames for r in f.receptions)
    assert all(len(f.receptions) == 4 for f in w.frames)
    for i in range(5):
        events = w.channel.take_events(i)
        # all five end together: resolved by sender id, so node i's TX done is i-th
        assert [type(e) for e in events] == [RadioRxFrame] * i + [RadioTxDone] + [RadioRxFrame] * (4 - i)
        assert [e.payload[0] for e in events if isinstance(e, RadioRxFrame)] == [j for j in range(5) if j != i]


def test_a_hard_range_cuts_the_ideal_link_at_that_distance():
    """Pereira's disc model: nodes at 0, 8 and 16 m with a 10 m range; neighbours hear each
    other, the ends do not, whatever the ideal link otherwise promises."""
    ideal = profile("ideal-100Bps")
    w = World({0: (0.0, 0.0), 1: (8.0, 0.0), 2: (16.0, 0.0)}, prof=ideal, max_range_m=10.0)
    for i in range(3):
        w.channel.transmit(i, bytes([i]) * 10, 0)
    w.channel.advance_to(1_000_000)
    assert (w.fate(0, 1), w.fate(1, 0), w.fate(1, 2), w.fate(2, 1)) == (RECEIVED,) * 4
    assert w.fate(0, 2) == w.fate(2, 0) == OUT_OF_RANGE
    assert [e.payload[0] for e in w.channel.take_events(0) if isinstance(e, RadioRxFrame)] == [1]
    assert [e.payload[0] for e in w.channel.take_events(1) if isinstance(e, RadioRxFrame)] == [0, 2]
    # Where the sender is when the frame starts counts: node 2 moves within range of node 0.
    w.positions[2] = (9.5, 0.0)
    w.channel.transmit(2, b"\x02", 1_000_000)
    w.channel.advance_to(2_000_000)
    assert w.fate(2, 0, nth=1) == RECEIVED
    # Exactly at the range still hears (farther than, not as far as).
    w2 = World({0: (0.0, 0.0), 1: (10.0, 0.0)}, prof=ideal, max_range_m=10.0)
    w2.channel.transmit(0, b"x", 0)
    w2.channel.advance_to(1_000_000)
    assert w2.fate(0, 1) == RECEIVED


def test_a_hard_range_on_a_lora_profile_also_silences_interference_from_beyond_it():
    """On eu868-g1, node 1 at 4.9 m and node 2 at 5.1 m on the other side reach node 0 within
    6 dB of each other, so their frames collide there; with a 5 m range node 2 is out of range
    and its frame no longer harms node 1's."""
    for rng, fate_far, fate_near in ((None, COLLIDED, COLLIDED), (5.0, OUT_OF_RANGE, RECEIVED)):
        w = World({0: (0.0, 0.0), 1: (4.9, 0.0), 2: (-5.1, 0.0)}, prof=G1, max_range_m=rng)
        w.channel.transmit(1, bytes(12), 0)
        w.channel.transmit(2, bytes(12), 0)
        w.channel.advance_to(AIRTIME_12B_US + 1)
        assert (w.fate(1, 0), w.fate(2, 0)) == (fate_near, fate_far)


@pytest.mark.parametrize("bad", [0.0, -1.0, math.inf, math.nan])
def test_a_hard_range_must_be_a_positive_distance(bad):
    with pytest.raises(ValueError, match="max_range_m"):
        Channel(profile("ideal-100Bps"), 0, max_range_m=bad)


def _fault_run(seed: int, n_frames: int, faults: FaultParams):
    w = World({0: (0.0, 0.0), 1: (10.0, 0.0)}, seed=seed, faults=faults)
    delivered = []
    t_us = 0
    for k in range(n_frames):
        w.channel.transmit(1, k.to_bytes(4, "little") + bytes(8), t_us)
        t_us += 100_000
        w.channel.advance_to(t_us)
        delivered += [e for e in w.channel.take_events(0) if isinstance(e, RadioRxFrame)]
        w.channel.set_listening(0, True, t_us)
        waiting = w.channel.take_events(0)        # a duplicate handed over at the re-arm
        if waiting:
            delivered += waiting                  # it used up the one-shot: arm again
            w.channel.set_listening(0, True, t_us)
    return w, delivered


def test_injected_faults_at_their_rates():
    n = 3000
    faults = FaultParams(loss_probability=0.2, corruption_probability=0.1, duplication_probability=0.1)
    w, delivered = _fault_run(seed=11, n_frames=n, faults=faults)
    counts = w.channel.counters()
    expected = {INJECTED_LOSS: 0.2, CORRUPTED: 0.8 * 0.1, "duplicates_delivered": 0.8 * 0.9 * 0.1}
    for key, p in expected.items():
        sigma = math.sqrt(n * p * (1 - p))
        assert abs(counts[key] - n * p) < 4.5 * sigma, (key, counts[key], n * p)
    assert counts[RECEIVED] + counts[CORRUPTED] + counts[INJECTED_LOSS] == n
    assert counts["frames"] == n
    # each corrupted payload differs from what was sent in 1..3 bits; duplicates are exact
    flips = []
    duplicates = 0
    for e in delivered:
        if e.stamp_us % 100_000 == 0:       # a duplicate, handed over at the re-arm after frame k
            k = e.stamp_us // 100_000 - 1
            duplicates += 1
            assert e.payload == k.to_bytes(4, "little") + bytes(8)
        else:
            k = (e.stamp_us - AIRTIME_12B_US) // 100_000
            sent = k.to_bytes(4, "little") + bytes(8)
            flips.append(sum(bin(x ^ y).count("1") for x, y in zip(e.payload, sent)))
    assert duplicates == counts["duplicates_delivered"]
    assert sum(1 for f in flips if f) == counts[CORRUPTED]
    assert all(0 <= f <= 3 for f in flips) and {1, 2, 3} <= set(flips)
    assert len(delivered) == counts[RECEIVED] + counts[CORRUPTED] + counts["duplicates_delivered"]


def test_faults_off_means_no_faults():
    w, delivered = _fault_run(seed=11, n_frames=200, faults=FaultParams())
    assert w.channel.counters()[RECEIVED] == 200 and len(delivered) == 200


def test_shadowing_spread_and_independent_of_fault_draws():
    def run(shadowing_std_db):
        faults = FaultParams(loss_probability=0.3)
        w = World({0: (0.0, 0.0), 1: (10.0, 0.0)}, seed=4, faults=faults,
                  propagation=PropagationParams(shadowing_std_db=shadowing_std_db))
        for k in range(400):
            w.channel.set_listening(0, True, k * 100_000)
            w.channel.transmit(1, bytes(12), k * 100_000)
        w.channel.advance_to(10 ** 9)
        return [f.receptions[0] for f in w.frames]

    plain, shadowed = run(0.0), run(4.0)
    assert [r.fate for r in plain] == [r.fate for r in shadowed]   # same losses, same frames
    deviation_db = np.array([s.rssi_dbm - p.rssi_dbm for p, s in zip(plain, shadowed)])
    assert len({r.rssi_dbm for r in plain}) == 1
    assert abs(deviation_db.mean()) < 0.6 and 3.5 < deviation_db.std() < 4.5


def test_duplicate_waits_for_the_receiver_to_rearm():
    w = World({0: (0.0, 0.0), 1: (10.0, 0.0)}, faults=FaultParams(duplication_probability=1.0,
                                                                duplicate_delay_us=1_000))
    end = w.channel.transmit(1, b"dup", 0)
    w.channel.advance_to(end + 50_000)
    assert [e.stamp_us for e in w.channel.take_events(0)] == [end]
    w.channel.set_listening(0, True, end + 60_000)
    events = w.channel.take_events(0)
    assert [(e.stamp_us, e.payload) for e in events] == [(end + 60_000, b"dup")]
    assert not w.channel.listening(0)             # the copy used up the one-shot like a frame
    # armed at the due time: handed over right then
    w.channel.set_listening(0, True, end + 70_000)
    end2 = w.channel.transmit(1, b"two", end + 70_000)
    w.channel.set_listening(0, True, end2 + 1)
    w.channel.advance_to(end2 + 5_000)
    assert [(e.stamp_us, e.payload) for e in w.channel.take_events(0)] == [(end2, b"two"), (end2 + 1_000, b"two")]


def _scenario(seed: int):
    """Five moving nodes in a walled map, random traffic, shadowing and faults on."""
    t = {"us": 0}

    def mover(i):
        return lambda: (3.0 + 40.0 * i + 1e-6 * t["us"], 2.0 + 0.5 * math.sin(i + 1e-6 * t["us"]))

    occ = _corridor_map(220, (30, 31, 90, 150))
    channel = Channel(G1, seed, occupancy=occ, propagation=PropagationParams(shadowing_std_db=4.0),
                      faults=FaultParams(0.05, 0.05, 0.05))
    for i in range(5):
        channel.attach(i, mover(i))
    frames = []
    channel.add_sink(frames.append)
    traffic = stream(1234, "test.traffic")
    events = []
    for step in range(400):
        t["us"] = step * 20_000
        for i in range(5):
            if traffic.random() < 0.15:
                channel.transmit(i, traffic.bytes(int(traffic.integers(1, 40))), t["us"])
        channel.advance_to(t["us"])
        for i in range(5):
            events += [(i, e) for e in channel.take_events(i)]
            if not channel.transmitting(i):
                channel.set_listening(i, True, t["us"])
    return frames, events, channel.counters()


def test_determinism_same_seed_same_air():
    first = _scenario(seed=5)
    second = _scenario(seed=5)
    assert first == second
    frames, events, counts = first
    assert len(frames) > 100
    fates = {r.fate for f in frames for r in f.receptions}
    assert {RECEIVED, COLLIDED, HALF_DUPLEX, NOT_LISTENING} <= fates
    assert sum(counts[f] for f in FATES) == sum(len(f.receptions) for f in frames)
    assert _scenario(seed=6)[0] != frames


def test_event_and_sink_order():
    w = World({0: (0.0, 0.0), 1: (10.0, 0.0), 2: (-10.0, 0.0)})
    w.channel.transmit(2, bytes(12), 0)
    w.channel.transmit(1, bytes(12), 0)           # same end time: resolved by sender id
    w.channel.transmit(0, bytes(20), 0)           # ends later
    assert w.channel.next_event_us() == AIRTIME_12B_US
    w.channel.advance_to(10_000_000)
    assert [f.sender_id for f in w.frames] == [1, 2, 0]
    assert w.channel.next_event_us() is None
    # per-node events come oldest first: node 1's own TX done, then a frame from node 0
    w.channel.take_events(1)
    w.channel.set_listening(1, True, 10_000_000)
    w.channel.transmit(1, b"mine", 10_000_001)
    w.channel.transmit(0, b"late", 10_100_000)
    w.channel.advance_to(20_000_000)
    events = w.channel.take_events(1)
    assert [type(e) for e in events] == [RadioTxDone]   # 1 was not armed after its own frame
    assert w.fate(0, 1, nth=1) == NOT_LISTENING


@pytest.mark.realtime
def test_idle_advance_is_cheap():
    import time as _time
    w = World({i: (float(i), 0.0) for i in range(5)})
    w.channel.transmit(0, bytes(12), 0)
    w.channel.advance_to(AIRTIME_12B_US)
    start = _time.perf_counter()
    for t_us in range(AIRTIME_12B_US, AIRTIME_12B_US + 100_000):
        w.channel.advance_to(t_us)
    per_call_us = (_time.perf_counter() - start) * 1e6 / 100_000
    assert per_call_us < 20.0


# ---------------------------------------------------------------------------------------------
# the simulated modem
# ---------------------------------------------------------------------------------------------


def test_sim_radio_modem_transmit_busy_poll_and_rearm():
    clock = StepClock()
    channel = Channel(G1, seed=3)
    pos = [(0.0, 0.0), (10.0, 0.0), (-10.0, 0.0)]
    modems = attach_sim_radios(channel, clock, [lambda p=p: p for p in pos])
    a, b, c = modems
    assert isinstance(a, RadioModem)
    assert a.transmit(b"hello")
    assert a.busy() and not a.transmit(b"again")
    clock.t_us = G1.airtime_us(5) - 1
    assert a.busy()
    clock.t_us = G1.airtime_us(5)
    assert not a.busy()
    assert a.poll() == (RadioTxDone(G1.airtime_us(5), True),)
    got = b.poll()
    assert [(type(e), e.payload) for e in got] == [(RadioRxFrame, b"hello")]
    # b was re-armed by poll(); c was not polled: c misses the next frame (one-shot)
    clock.t_us = 200_000
    assert a.transmit(b"again")
    clock.t_us = 400_000
    assert [e.payload for e in b.poll() if isinstance(e, RadioRxFrame)] == [b"again"]
    assert [e.payload for e in c.poll() if isinstance(e, RadioRxFrame)] == [b"hello"]


def test_sim_radio_modem_is_a_registered_backend():
    from hal.registry import backend_class

    assert backend_class("radio", "sim") is SimRadioModem


# ---------------------------------------------------------------------------------------------
# the wall-crossing kernel against its reference
# ---------------------------------------------------------------------------------------------

_Q_CHOICES = [1, 2, 4, SUBCELLS_PER_CELL]


@st.composite
def _segments(draw):
    q = draw(st.sampled_from(_Q_CHOICES))
    rows, cols = draw(st.integers(1, 12)), draw(st.integers(1, 12))
    bits = draw(st.lists(st.booleans(), min_size=rows * cols, max_size=rows * cols))
    wall = np.array(bits, dtype=np.uint8).reshape(rows, cols)
    # points on grid lines and corners are the hard cases: draw them often
    coord = st.one_of(
        st.integers(-2 * q, 14 * q),
        st.integers(-2, 14).map(lambda k: k * q),
    )
    x0, y0, x1, y1 = (draw(coord) for _ in range(4))
    return wall, q, x0, y0, x1, y1


@settings(max_examples=400, deadline=None)
@given(_segments())
def test_wall_crossings_numba_matches_reference(case):
    wall, q, x0, y0, x1, y1 = case
    assert count_wall_crossings_nb(wall, x0, y0, x1, y1, q) == count_wall_crossings_ref(wall, x0, y0, x1, y1, q)


@settings(max_examples=300, deadline=None)
@given(_segments())
def test_reference_traversal_is_exact(case):
    _, q, x0, y0, x1, y1 = case
    cells = traversed_cells_ref(x0, y0, x1, y1, q)
    assert cells[0] == (y0 // q, x0 // q) and cells[-1] == (y1 // q, x1 // q)
    assert len(set(cells)) == len(cells)
    for (r0, c0), (r1, c1) in zip(cells, cells[1:]):
        assert max(abs(r1 - r0), abs(c1 - c0)) == 1
    # every point of the segment lies in a visited cell, met in order
    index = {cell: i for i, cell in enumerate(cells)}
    last = 0
    for k in range(65):
        t = Fraction(k, 64)
        x, y = x0 + t * (x1 - x0), y0 + t * (y1 - y0)
        cell = (math.floor(y / q), math.floor(x / q))
        assert cell in index
        assert index[cell] >= last
        last = index[cell]


def test_reference_traversal_diagonal_steps_only_through_corners():
    # exactly through the corner at (1, 1): straight from cell (0, 0) to cell (1, 1)
    assert traversed_cells_ref(0, 0, 7, 7, 4) == [(0, 0), (1, 1)]
    # the same direction reversed: leaving a cell happens just after the grid line
    assert traversed_cells_ref(7, 7, 0, 0, 4) == [(1, 1), (0, 0)]
    # an end point on a grid line belongs to the cell above / right of it
    assert traversed_cells_ref(0, 0, 8, 8, 4) == [(0, 0), (1, 1), (2, 2)]
    assert traversed_cells_ref(8, 8, 0, 0, 4) == [(2, 2), (1, 1), (0, 0)]
    # just off the corner: one side cell is visited
    assert traversed_cells_ref(0, 1, 7, 7, 4) == [(0, 0), (1, 0), (1, 1)]
    # along a grid line: the cells above it
    assert traversed_cells_ref(0, 4, 11, 4, 4) == [(1, 0), (1, 1), (1, 2)]
    wall = np.zeros((2, 2), dtype=np.uint8)
    wall[0, 1] = wall[1, 0] = 1
    # a diagonal through the shared corner of two wall cells slips through
    assert count_wall_crossings_ref(wall, 0, 0, 7, 7, 4) == 0
    assert count_wall_crossings_nb(wall, 0, 0, 7, 7, 4) == 0
    assert count_wall_crossings_nb(wall, 0, 1, 7, 7, 4) == 1


# ---------------------------------------------------------------------------------------------
# air interfaces other than the profile's: who hears whom, who collides with whom
# ---------------------------------------------------------------------------------------------

NET = G1.air_interface()                                       # 868.1 MHz SF7 BW125, sync 12


@pytest.mark.parametrize("change, heard", [
    ({}, True),
    ({"freq_hz": 868_300_000}, False),
    ({"modulation": LoraModulation(8, 125_000)}, False),
    ({"modulation": LoraModulation(7, 250_000)}, False),
    ({"sync_word": 0x34}, False),
    ({"iq_inverted": True}, False),
    # Coding rate, preamble and CRC travel in the explicit header: the receiver follows them.
    ({"modulation": LoraModulation(7, 125_000, cr=4, preamble_symbols=12, crc_on=False)}, True),
])
def test_a_receiver_hears_only_frames_sent_with_its_settings(change, heard):
    w = World({0: (0.0, 0.0), 1: (10.0, 0.0)})
    tx_air = replace(NET, **change)
    w.channel.set_listening(0, True, 0)                        # armed for the network's settings
    end_us = w.channel.transmit(1, bytes(12), 0, air=tx_air)
    assert end_us == tx_air.airtime_us(12)                     # the frame's own time on air
    w.channel.advance_to(end_us)
    assert w.fate(1, 0) == (RECEIVED if heard else NOT_LISTENING)
    assert w.frames[0].freq_hz == tx_air.freq_hz and w.frames[0].sf == tx_air.modulation.sf
    # Retuned to the sender's settings, the receiver hears the next frame.
    w.channel.set_listening(0, True, end_us, air=tx_air)
    w.channel.transmit(1, bytes(12), end_us, air=tx_air)
    w.channel.advance_to(end_us + tx_air.airtime_us(12))
    assert w.fate(1, 0, nth=1) == RECEIVED


def test_power_on_defaults_hear_each_other_off_the_networks_point():
    defaults = AirInterface(868_100_000, LoraModulation(12, 125_000), sync_word=0x34)
    w = World({0: (0.0, 0.0), 1: (10.0, 0.0)})
    w.channel.set_listening(0, True, 0, air=defaults)
    end_us = w.channel.transmit(1, b"hi", 0, air=defaults, tx_power_dbm=1.0)
    w.channel.advance_to(end_us)
    [frame] = w.channel.take_events(0)
    assert frame.payload == b"hi" and frame.rssi_dbm == pytest.approx(1.0 - w.channel.propagation.path_loss_db(10.0))


def test_other_spreading_factors_do_not_collide_other_sync_words_do():
    w = World({0: (0.0, 0.0), 1: (10.0, 0.0), 2: (-10.0, 0.0), 3: (0.0, 10.0)})
    sf8 = replace(NET, modulation=LoraModulation(8, 125_000))
    w.channel.transmit(1, b"A" * 12, 0)
    w.channel.transmit(2, b"B" * 12, 0, air=sf8)               # same time, other SF
    w.channel.advance_to(sf8.airtime_us(12))
    assert w.fate(1, 0) == RECEIVED
    w.channel.set_listening(0, True, w.channel.now_us)
    t = w.channel.now_us
    w.channel.transmit(1, b"A" * 12, t)
    w.channel.transmit(3, b"C" * 12, t, air=replace(NET, sync_word=0x34))   # same chirps, other sync
    w.channel.advance_to(t + AIRTIME_12B_US)
    assert w.fate(1, 0, nth=1) == COLLIDED


def test_reported_snr_stays_in_the_radios_register_range():
    w = World({0: (0.0, 0.0), 1: (1.0, 0.0), 2: (3000.0, 0.0)})
    w.channel.transmit(1, bytes(4), 0)
    w.channel.advance_to(G1.airtime_us(4))
    [near] = w.channel.take_events(0)
    assert near.snr_db == 31.75                                # 14 dBm at 1 m: far above the ceiling
    assert near.rssi_dbm - w.channel.noise_floor_dbm > 90
