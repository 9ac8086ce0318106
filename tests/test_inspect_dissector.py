"""Wireshark Lua dissector: shipped file is the generated one; its CRC loop matches crcmod
for every dialect; tshark shows every dialect's record fields by name, unit and value
(skipped only without tshark)."""
import shutil
import subprocess

import pytest
from hypothesis import given, settings, strategies as st

from firmware.comms.frame import encode_frame, frame_crc, seal
from firmware.comms.schema import CORE, SENDER, Dialect, DialectSet, Field, RecordType
from firmware.schemes import all_dialects
from host_tools.dissector.generate import SHIPPED, _crc_table, generate_lua, lua_algorithm_crc
from host_tools.pcap import PcapWriter, loratap_header

DIALECTS = all_dialects()


def test_shipped_lua_is_the_generated_one():
    assert SHIPPED.read_text(encoding="utf-8") == generate_lua(), (
        "run: python -m host_tools.dissector.generate")


def test_every_dialect_and_field_is_declared_in_the_lua():
    lua = generate_lua()
    for d in DIALECTS:
        assert f'[{d.id}] = {{ name = "{d.name}", fingerprint = 0x{d.fingerprint:04X}' in lua
        for rt in d.records:
            assert f'[{rt.code}] = {{ name = "{rt.name}", size = {rt.size_bytes}' in lua
            for f in rt.fields:
                assert f'"lorascout.{rt.name}.{f.name}"' in lua
    assert 'DissectorTable.get("loratap.syncword"):add(SYNC_WORD, p)' in lua and "SYNC_WORD = 0x12" in lua
    assert f"CORE_FINGERPRINT = 0x{CORE.fingerprint:04X}" in lua


@settings(max_examples=200, deadline=None)
@given(st.sampled_from(sorted(DIALECTS.by_id)), st.binary(min_size=1, max_size=260))
def test_lua_crc_algorithm_matches_crcmod(dialect_id, data):
    table, init, xorout = _crc_table()
    body = data[:1] + bytes([dialect_id]) + data[1:]
    dialect_fp = 0 if dialect_id == 0 else DIALECTS.get(dialect_id).fingerprint
    assert lua_algorithm_crc(body, table, init, xorout, (CORE.fingerprint, dialect_fp)) == frame_crc(body)


def _extreme(rt, pick):
    return {f.name: (f.min_value if pick == "min" else f.max_value) for f in rt.fields}


def _tshark(tmp_path, frames, dialects=None):
    pcap = tmp_path / "t.pcap"
    with PcapWriter(pcap) as w:
        for i, frame in enumerate(frames):
            w.write(1_000_000 * (i + 1), loratap_header(869_525_000, 125_000, 7, -87.0, 6.5) + frame)
    lua = tmp_path / "lorascout.lua"
    lua.write_text(generate_lua(dialects))
    out = subprocess.run(["tshark", "-X", f"lua_script:{lua}", "-r", str(pcap), "-V"],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert "Lua: Error" not in out.stdout and "Lua Error" not in out.stdout, out.stdout
    return out.stdout


@pytest.mark.skipif(shutil.which("tshark") is None, reason="tshark not installed")
def test_tshark_decodes_every_field(tmp_path):
    topo = dict(sender_id=3, x_cm=-12345, y_cm=800000, z_cm=-7, presence=1, e_inf_code=200, info_version=0)
    pose = DIALECTS.record("pose")
    topo_dialect = DIALECTS.dialect_of("topo")
    good = encode_frame(3, 4242, [("topo", topo)] * 2 + [("pose", _extreme(pose, "min"))]
                        + [(rt.name, _extreme(rt, "max")) for d in (CORE, topo_dialect) for rt in d.records],
                        hops_left=2)
    # One frame carries one scheme's dialect: the others' records come in frames of their own.
    others = [encode_frame(3, 4243 + k, [(rt.name, _extreme(rt, "max")) for rt in d.records])
              for k, d in enumerate(d for d in DIALECTS if d not in (CORE, topo_dialect))]
    bad = bytearray(good)
    bad[12] ^= 0x01
    # CRC-valid core-only frame whose pose yaw is out of range (32767 cdeg)
    pose_bytes = bytearray(12)
    pose_bytes[7] = 0x7F
    pose_bytes[8] = 0xFF
    oor = seal(bytes([0x21, 0, 13, 9, 0, 1, 0, 0x08]) + bytes(pose_bytes))
    text = _tshark(tmp_path, (good, bytes(bad), oor, *others))
    assert text.count("lorascout frame") == 3 + len(others)
    for needle in ("Sender id: 3", "Sequence number: 4242", "Hops left: 2", "CRC status: good",
                   "Dialect: bayer_faigl (1)", "Dialect: core (0)", "lorascout frame, dialect 1 bayer_faigl",
                   "2 x bayer_faigl.topo", "bayer_faigl.topo record 0", "core.pose record 2",
                   "Record dialect: frame's dialect (1)", "Record dialect: core (0)",
                   "x_cm (cm): -12345", "y_cm (cm): 800000", "z_cm (cm): -7", "presence (bool): 1",
                   "e_inf_code (16*log2(1+bit), saturating): 200", "yaw_cdeg (0.01 deg): -18000",
                   "yaw_cdeg (0.01 deg): 18000", "vertex_count (vertices): 4095", "info_version (revisions): 127",
                   "x_cm (cm): -8388608", "x_cm (cm): 8388607", "Bad frame CRC", "yaw_cdeg (0.01 deg): 32767",
                   "value 32767 outside [-18000, 18000]", "Expert Info (Warning/Malformed)"):
        assert needle in text, needle
    for d in DIALECTS:
        for rt in d.records:
            for f in rt.fields:
                assert f"{f.name} ({f.unit})" in text


@pytest.mark.skipif(shutil.which("tshark") is None, reason="tshark not installed")
def test_tshark_decodes_a_new_dialect_and_flags_unknown_ones(tmp_path):
    """A dialect added to the set is decoded as soon as the dissector is regenerated; a
    dissector without it flags its frames as of an unknown dialect."""
    other = Dialect(7, "other", (RecordType(3, "blip", 2, (SENDER, Field("level_id", 8, unit="levels"))),))
    more = DialectSet([*DIALECTS, other])
    frame = encode_frame(5, 9, [("pose", _extreme(CORE.records[0], "max")), ("blip", dict(sender_id=5, level_id=77))],
                         dialects=more)
    text = _tshark(tmp_path, (frame,), more)
    for needle in ("Dialect: other (7)", "CRC status: good", "1 x other.blip", "level_id (levels): 77",
                   "core.pose record 0"):
        assert needle in text, needle
    text = _tshark(tmp_path, (frame,))
    assert "Dialect: Unknown (7)" in text and "[Expert Info (Error/Malformed): dialect id 7]" in text
    assert "blip" not in text and "CRC status" not in text
