"""LoRaTap pcap: exact header bytes, code saturation, both packet modes."""
import struct

import pytest

from host_tools.pcap import (LINKTYPE_LORATAP, loratap_header, parse_loratap_header, read_pcap,
                             write_pcap)
from radio_sim.air_log import COLLIDED, RECEIVED, AirFrame, Reception


def test_loratap_v0_header_bytes():
    h = loratap_header(869_525_000, 250_000, 9, -87.0, -6.25)
    assert len(h) == 15
    assert h == bytes([0, 0, 0, 15]) + (869_525_000).to_bytes(4, "big") + bytes(
        [2, 9, 52, 52, 52, (-25) & 0xFF, 0x12])
    d = parse_loratap_header(h)
    assert d == {"freq_hz": 869_525_000, "bw_hz": 250_000, "sf": 9, "rssi_dbm": -87, "max_rssi_dbm": -87,
                 "current_rssi_dbm": -87, "snr_db": -6.25, "sync_word": 0x12}


def test_codes_saturate():
    assert parse_loratap_header(loratap_header(868_100_000, 125_000, 7, -200.0, 99.0))["rssi_dbm"] == -139
    assert parse_loratap_header(loratap_header(868_100_000, 125_000, 7, 200.0, -99.0))["snr_db"] == -32.0
    assert parse_loratap_header(loratap_header(868_100_000, 125_000, 7, 200.0, 99.0))["snr_db"] == 31.75
    with pytest.raises(ValueError, match="125 kHz"):
        loratap_header(868_100_000, 100_000, 7, 0, 0)


def _frames():
    return [
        AirFrame(1_500_000, 1_541_216, 3, 869_525_000, 7, 125_000, b"\x11abc",
                 (Reception(2, -100.0, 1.0, RECEIVED), Reception(1, -90.0, 2.0, COLLIDED),
                  Reception(4, -95.0, 3.0, RECEIVED))),
        AirFrame(3_000_000, 3_041_216, 1, 869_525_000, 7, 125_000, b"\x11xyz", ()),
    ]


def test_per_frame_mode_uses_best_rssi(tmp_path):
    path = tmp_path / "a.pcap"
    assert write_pcap(path, _frames()) == 2
    raw = path.read_bytes()
    assert struct.unpack_from("<IHHiIII", raw)[6] == LINKTYPE_LORATAP == 270
    linktype, pkts = read_pcap(path)
    assert linktype == 270 and [t for t, _ in pkts] == [1_500_000, 3_000_000]
    assert parse_loratap_header(pkts[0][1])["rssi_dbm"] == -90      # best, whatever its fate
    assert pkts[0][1][15:] == b"\x11abc"
    assert parse_loratap_header(pkts[1][1])["rssi_dbm"] == -139     # nobody heard it


def test_per_receiver_mode(tmp_path):
    path = tmp_path / "b.pcap"
    assert write_pcap(path, _frames(), mode="per-receiver") == 2
    _, pkts = read_pcap(path)
    assert [parse_loratap_header(p)["rssi_dbm"] for _, p in pkts] == [-100, -95]
    with pytest.raises(ValueError, match="pcap mode"):
        write_pcap(tmp_path / "c.pcap", _frames(), mode="both")
    assert not (tmp_path / "c.pcap").exists()


def test_read_pcap_rejects_bad_files(tmp_path):
    (tmp_path / "x").write_bytes(b"\x00" * 10)
    with pytest.raises(ValueError, match="too short"):
        read_pcap(tmp_path / "x")
    write_pcap(tmp_path / "y", _frames())
    data = (tmp_path / "y").read_bytes()
    (tmp_path / "y").write_bytes(data[:-2])
    with pytest.raises(ValueError, match="truncated packet"):
        read_pcap(tmp_path / "y")
