"""LoRa time on air: the DESIGN.md golden values, monotonicity, and that the channel uses
exactly the profile's airtime for every frame."""
from __future__ import annotations

import dataclasses

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hal.lora import LoraModulation, RadioProfile, profile, time_on_air_us
from radio_sim.channel import Channel

GOLDEN_US = [
    # (payload bytes, sf, bw_hz, time on air in us): 8-symbol preamble, CR 4/5, explicit header, CRC on
    (12, 7, 125_000, 41_216),
    (12, 8, 125_000, 82_432),
    (12, 9, 125_000, 144_384),
    (12, 10, 125_000, 288_768),
    (12, 11, 125_000, 577_536),
    (12, 12, 125_000, 1_155_072),
    (32, 7, 125_000, 71_936),
    (32, 9, 125_000, 246_784),
    (32, 12, 125_000, 1_810_432),
    (12, 7, 250_000, 20_608),
    (12, 7, 500_000, 10_304),
]


@pytest.mark.parametrize("payload_bytes, sf, bw_hz, expected_us", GOLDEN_US)
def test_golden_time_on_air(payload_bytes, sf, bw_hz, expected_us):
    assert time_on_air_us(payload_bytes, LoraModulation(sf, bw_hz)) == expected_us


@pytest.mark.parametrize("payload_bytes, sf, bw_hz, expected_us", GOLDEN_US)
def test_channel_frame_lasts_the_golden_airtime(payload_bytes, sf, bw_hz, expected_us):
    base = profile("eu868-g1")
    prof = dataclasses.replace(base, modulation=LoraModulation(sf, bw_hz))
    channel = Channel(prof, seed=1)
    channel.attach(0, lambda: (0.0, 0.0))
    channel.attach(1, lambda: (5.0, 0.0))
    frames = []
    channel.add_sink(frames.append)
    start_us = 1_000
    end_us = channel.transmit(0, bytes(payload_bytes), start_us)
    assert end_us == start_us + expected_us
    assert channel.next_event_us() == end_us
    channel.advance_to(end_us - 1)
    assert channel.transmitting(0) and frames == []
    channel.advance_to(end_us)
    assert not channel.transmitting(0)
    assert [(f.start_us, f.end_us) for f in frames] == [(start_us, end_us)]


def test_ideal_profile_airtime_is_bytes_over_100_Bps():
    ideal = profile("ideal-100Bps")
    assert ideal.airtime_us(12) == 120_000
    assert ideal.airtime_us(255) == 2_550_000
    channel = Channel(ideal, seed=0)
    channel.attach(0, lambda: (0.0, 0.0))
    assert channel.transmit(0, bytes(50), 7) == 7 + 500_000


@settings(max_examples=200, deadline=None)
@given(
    payload_bytes=st.integers(0, 254),
    sf=st.integers(7, 12),
    bw_hz=st.sampled_from([125_000, 250_000, 500_000]),
    cr=st.integers(1, 4),
)
def test_airtime_non_decreasing_in_payload_and_sf(payload_bytes, sf, bw_hz, cr):
    mod = LoraModulation(sf, bw_hz, cr)
    here = time_on_air_us(payload_bytes, mod)
    assert time_on_air_us(payload_bytes + 1, mod) >= here
    if sf < 12:
        assert time_on_air_us(payload_bytes, LoraModulation(sf + 1, bw_hz, cr)) >= here


@settings(max_examples=100, deadline=None)
@given(payload_bytes=st.integers(0, 255), name=st.sampled_from(["eu868-g1", "eu868-g3", "eu868-g3-bw250", "us915"]))
def test_channel_refuses_only_oversized_frames(payload_bytes, name):
    prof: RadioProfile = profile(name)
    channel = Channel(prof, seed=0)
    channel.attach(0, lambda: (0.0, 0.0))
    end_us = channel.transmit(0, bytes(payload_bytes), 0)
    if payload_bytes > prof.max_payload_bytes:
        assert end_us is None and not channel.transmitting(0)
    else:
        assert end_us == prof.airtime_us(payload_bytes)
