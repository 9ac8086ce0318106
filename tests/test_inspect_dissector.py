"""Wireshark Lua dissector: shipped file is the generated one; its CRC loop matches crcmod;
tshark shows every record field by name, unit and value (skipped only without tshark)."""
import shutil
import subprocess

import pytest
from hypothesis import given, settings, strategies as st

from firmware.comms.frame import encode_frame, frame_crc, seal
from firmware.comms.schema import RECORD_TYPES, SCHEMA_FINGERPRINT
from host_tools.dissector.generate import SHIPPED, _crc_table, generate_lua, lua_algorithm_crc
from host_tools.pcap import PcapWriter, loratap_header


def test_shipped_lua_is_the_generated_one():
    assert SHIPPED.read_text(encoding="utf-8") == generate_lua(), (
        "run: python -m host_tools.dissector.generate")


def test_every_field_is_declared_in_the_lua():
    lua = generate_lua()
    for rt in RECORD_TYPES:
        for f in rt.fields:
            assert f'"lorascout.{rt.name}.{f.name}"' in lua
    assert 'DissectorTable.get("loratap.syncword"):add(SYNC_WORD, p)' in lua and "SYNC_WORD = 0x12" in lua
    assert f"FINGERPRINT = 0x{SCHEMA_FINGERPRINT:04X}" in lua


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=260))
def test_lua_crc_algorithm_matches_crcmod(data):
    table, init, xorout = _crc_table()
    assert lua_algorithm_crc(data, table, init, xorout, SCHEMA_FINGERPRINT) == frame_crc(data)


def _extreme(rt, pick):
    return {f.name: (f.min_value if pick == "min" else f.max_value) for f in rt.fields}


@pytest.mark.skipif(shutil.which("tshark") is None, reason="tshark not installed")
def test_tshark_decodes_every_field(tmp_path):
    pcap = tmp_path / "t.pcap"
    topo = dict(sender_id=3, x_cm=-12345, y_cm=800000, z_cm=-7, presence=1, e_inf_code=200, info_version=0)
    good = encode_frame(3, 4242, [("topo", topo)] * 2 + [("pose", _extreme(RECORD_TYPES[1], "min"))]
                        + [(rt.name, _extreme(rt, "max")) for rt in RECORD_TYPES], hops_left=2)
    bad = bytearray(good)
    bad[12] ^= 0x01
    # CRC-valid frame whose pose yaw is out of range (32767 cdeg)
    pose_bytes = bytearray(12)
    pose_bytes[7] = 0x7F
    pose_bytes[8] = 0xFF
    oor = seal(bytes([0x11, 13, 9, 0, 1, 0, 0x20]) + bytes(pose_bytes))
    with PcapWriter(pcap) as w:
        for i, frame in enumerate((good, bytes(bad), oor)):
            w.write(1_000_000 * (i + 1), loratap_header(869_525_000, 125_000, 7, -87.0, 6.5) + frame)
    lua = tmp_path / "lorascout.lua"
    lua.write_text(generate_lua())
    out = subprocess.run(["tshark", "-X", f"lua_script:{lua}", "-r", str(pcap), "-V"],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    text = out.stdout
    assert "Lua: Error" not in text and "Lua Error" not in text, text
    assert text.count("lorascout frame") == 3
    for needle in ("Sender id: 3", "Sequence number: 4242", "Hops left: 2", "CRC status: good",
                   "x_cm (cm): -12345", "y_cm (cm): 800000", "z_cm (cm): -7", "presence (bool): 1",
                   "e_inf_code (16*log2(1+bit), saturating): 200", "yaw_cdeg (0.01 deg): -18000",
                   "yaw_cdeg (0.01 deg): 18000", "vertex_count (vertices): 4095", "path_cost_dm (dm): 65535",
                   "x_cm (cm): -8388608", "x_cm (cm): 8388607", "Bad frame CRC", "yaw_cdeg (0.01 deg): 32767",
                   "value 32767 outside [-18000, 18000]", "Expert Info (Warning/Malformed)"):
        assert needle in text, needle
    for rt in RECORD_TYPES:
        for f in rt.fields:
            assert f"{f.name} ({f.unit})" in text
