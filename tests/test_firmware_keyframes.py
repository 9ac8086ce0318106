"""Keyframes: what a robot keeps of a place (and what the dense baselines send) must restore
that place as the scan taken there showed it."""
import math

import numpy as np
from hypothesis import given, settings, strategies as st

from firmware.local_map import BinnedScan, KeyframeStore, LocalMap, bin_scan, decode_keyframe, encode_keyframe, keyframe_bytes
from firmware.params import ExplorationParams

P = ExplorationParams()
BEAMS = 360
INCREMENT_RAD = 2.0 * math.pi / BEAMS


def _room_scan(rng: np.random.Generator) -> np.ndarray:
    """Ranges in whole centimetres (what a keyframe stores), some beams at range_max."""
    ranges = rng.integers(30, 900, BEAMS) / 100.0
    ranges[rng.random(BEAMS) < 0.1] = 10.0
    return ranges


@settings(max_examples=100, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), yaw_rad=st.floats(-math.pi, math.pi), x_m=st.floats(-3.0, 3.0),
       y_m=st.floats(-3.0, 3.0))
def test_a_restored_keyframe_is_the_scan_taken_there(seed, yaw_rad, x_m, y_m):
    ranges = _room_scan(np.random.default_rng(seed))
    live = LocalMap(P, 0.0, 0.0, KeyframeStore(BEAMS))
    live.integrate_scan(x_m, y_m, yaw_rad, -math.pi, INCREMENT_RAD, ranges, 10.0)
    store = KeyframeStore(BEAMS)
    store.add(bin_scan(x_m, y_m, yaw_rad, -math.pi, INCREMENT_RAD, ranges, 10.0, BEAMS))
    restored = LocalMap(P, 0.0, 0.0, store)
    restored.integrate_keyframe(store.get(0))
    assert np.array_equal(live.logodds, restored.logodds)


def test_keyframes_on_fixed_world_bearings_would_not_restore_the_scan():
    """The check above can fail: bins on fixed world bearings (what keyframes were before)
    move a grazing wall's beams and so clear or miss many cells."""
    ranges = _room_scan(np.random.default_rng(7))
    live = LocalMap(P, 0.0, 0.0, KeyframeStore(BEAMS))
    live.integrate_scan(0.0, 0.0, 0.4, -math.pi, INCREMENT_RAD, ranges, 10.0)
    moved = bin_scan(0.0, 0.0, 0.4, -math.pi, INCREMENT_RAD, ranges, 10.0, BEAMS)
    fixed = moved._replace(bearing0_rad=round(moved.bearing0_rad / INCREMENT_RAD) * INCREMENT_RAD)
    restored = LocalMap(P, 0.0, 0.0, KeyframeStore(BEAMS))
    restored.integrate_keyframe(fixed)
    assert np.count_nonzero(live.logodds != restored.logodds) > 100


@settings(max_examples=200, deadline=None)
@given(sender=st.integers(0, 255), x_m=st.floats(-20000.0, 20000.0), y_m=st.floats(-20000.0, 20000.0),
       bearing0_rad=st.floats(-10.0, 10.0), bins=st.integers(1, 720), seed=st.integers(0, 2**32 - 1))
def test_keyframe_wire_round_trip(sender, x_m, y_m, bearing0_rad, bins, seed):
    ranges = np.random.default_rng(seed).integers(0, 65535, bins) / 100.0
    scan = BinnedScan(x_m, y_m, bearing0_rad, ranges, 12.0)
    data = encode_keyframe(sender, scan)
    assert len(data) == keyframe_bytes(bins)
    got_sender, got = decode_keyframe(data)
    assert got_sender == sender
    assert abs(got.x_m - x_m) <= 0.005 and abs(got.y_m - y_m) <= 0.005 and got.range_max_m == 12.0
    turn = 2 * math.pi
    wrapped = abs((got.bearing0_rad - bearing0_rad + math.pi) % turn - math.pi)
    assert wrapped <= turn / 65536
    assert np.array_equal(got.ranges_m, ranges)


def test_a_keyframe_at_360_bins_is_735_bytes():
    assert keyframe_bytes(P.keyframe_bins) == 735


@settings(max_examples=2000, deadline=None)
@given(data=st.binary(max_size=800))
def test_random_bytes_into_decode_keyframe_never_raise(data):
    out = decode_keyframe(data)
    if out is not None:
        assert len(data) == keyframe_bytes(len(out[1].ranges_m))
