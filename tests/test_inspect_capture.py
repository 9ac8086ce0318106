"""Capture files: round trip, determinism, and errors that name file, line and field."""
import json

import pytest

from host_tools.capture import LEGACY_FINGERPRINT_NAME, CaptureError, CaptureWriter, read_capture
from firmware.comms.frame import encode_frame
from firmware.comms.schema import CORE
from firmware.schemes import all_dialects
from firmware.schemes.bayer_faigl.records import DIALECT as BF
from radio_sim.air_log import COLLIDED, RECEIVED, AirFrame, Reception

TOPO = dict(sender_id=3, x_cm=10, y_cm=-20, z_cm=0, presence=1, e_inf_code=77, info_version=0)


def frames():
    p = encode_frame(3, 1, [("topo", TOPO)])
    return [
        AirFrame(1_000, 42_216, 3, 869_525_000, 7, 125_000, p,
                 (Reception(1, -87.254, 6.5, RECEIVED), Reception(2, -120.0, -3.25, COLLIDED))),
        AirFrame(2_000_000, 2_041_216, 1, 869_525_000, 7, 125_000, b"\x00\x01", ()),
    ]


def test_round_trip_and_header(tmp_path):
    path = tmp_path / "a.jsonl"
    with CaptureWriter(path, "eu868-g3", {"seed": 7}) as w:
        for a in frames():
            w.write(a)
    assert w.frames_written == 2
    header, it = read_capture(path)
    assert header.profile == "eu868-g3"
    assert header.fingerprints == all_dialects().fingerprints()
    assert header.fingerprints["core"] == CORE.fingerprint and header.fingerprints["bayer_faigl"] == BF.fingerprint
    assert json.loads(path.read_text().splitlines()[0])["fingerprints"]["core"] == f"0x{CORE.fingerprint:04X}"
    assert header.meta == {"seed": 7} and header.crc == "modbus"
    got = list(it)
    want = frames()
    assert got[1] == want[1]
    assert got[0].payload == want[0].payload and got[0].receptions[0].rssi_dbm == -87.25   # 0.01 dB
    assert got[0].receptions[1] == want[0].receptions[1]


def test_identical_input_gives_identical_bytes(tmp_path):
    for name in ("a", "b"):
        with CaptureWriter(tmp_path / name, "eu868-g1") as w:
            for a in frames():
                w.write(a)
    assert (tmp_path / "a").read_bytes() == (tmp_path / "b").read_bytes()


def test_lines_are_greppable_json(tmp_path):
    path = tmp_path / "a.jsonl"
    with CaptureWriter(path, "eu868-g3") as w:
        w.write(frames()[0])
    lines = path.read_text().splitlines()
    assert json.loads(lines[0])["format"] == "lorascout-capture"
    assert '"sender_id": 3,' in lines[1] and "collided" in lines[1]


def _write(tmp_path, lines):
    path = tmp_path / "bad.jsonl"
    path.write_text("\n".join(lines) + "\n")
    return path


HEADER = json.dumps({"format": "lorascout-capture", "version": 1, "profile": "eu868-g3"})
GOOD = {"start_us": 0, "end_us": 10, "sender_id": 1, "freq_hz": 869525000, "sf": 7, "bw_hz": 125000,
        "payload": "0011", "rx": [[2, -80.0, 5.0, "received"]]}


@pytest.mark.parametrize("change, where", [
    ({"payload": "0g"}, "line 3: field 'payload'"),
    ({"start_us": "late"}, "line 3: field 'start_us': expected an integer"),
    ({"end_us": -1}, "line 3: field 'end_us': -1 outside"),
    ({"sender_id": 300}, "line 3: field 'sender_id'"),
    ({"rx": [[2, -80.0, 5.0, "lost"]]}, "line 3: field 'rx[0].fate'"),
    ({"rx": [[2, "loud", 5.0, "received"]]}, "line 3: field 'rx[0].rssi_dbm'"),
    ({"rx": [[2, -80.0]]}, "line 3: field 'rx[0]'"),
    ({"payload": "00" * 256}, "line 3: field 'payload': 256 bytes"),
])
def test_bad_frame_lines_name_line_and_field(tmp_path, change, where):
    path = _write(tmp_path, [HEADER, json.dumps(GOOD), json.dumps({**GOOD, **change})])
    header, it = read_capture(path)
    assert next(it).payload == b"\x00\x11"
    with pytest.raises(CaptureError) as e:
        next(it)
    assert f"{path}:3" in str(e.value) and where.split(": ", 1)[1] in str(e.value)


def test_missing_field_and_broken_json(tmp_path):
    row = dict(GOOD)
    del row["sf"]
    with pytest.raises(CaptureError, match=r":2: field 'sf': missing"):
        list(read_capture(_write(tmp_path, [HEADER, json.dumps(row)]))[1])
    with pytest.raises(CaptureError, match=r":2: not JSON"):
        list(read_capture(_write(tmp_path, [HEADER, "{nope"]))[1])


@pytest.mark.parametrize("first, msg", [
    ("", "empty file"),
    ("{]", "header is not JSON"),
    (json.dumps({"format": "pcap"}), "field 'format'"),
    (json.dumps({"format": "lorascout-capture", "version": 9, "profile": "x"}), "field 'version'"),
    (json.dumps({"format": "lorascout-capture", "version": 1}), "field 'profile'"),
    (json.dumps({"format": "lorascout-capture", "version": 1, "profile": "x", "fingerprints": ["0x1"]}),
     "field 'fingerprints': expected an object"),
    (json.dumps({"format": "lorascout-capture", "version": 1, "profile": "x", "fingerprints": {"core": "zz"}}),
     "field 'fingerprints.core': expected hex"),
    (json.dumps({"format": "lorascout-capture", "version": 1, "profile": "x", "schema_fingerprint": "0x10000"}),
     "field 'schema_fingerprint': '0x10000' is not a 16-bit value"),
])
def test_bad_headers(tmp_path, first, msg):
    path = tmp_path / "h.jsonl"
    path.write_text(first + "\n" if first else "")
    with pytest.raises(CaptureError, match=msg) as e:
        read_capture(path)
    assert f"{path}:1" in str(e.value)


def test_binary_and_missing_files(tmp_path):
    path = tmp_path / "bin"
    path.write_bytes(b"\xff\xfe\x00garbage")
    with pytest.raises(CaptureError, match=":1: not UTF-8"):
        read_capture(path)
    with pytest.raises(CaptureError, match="cannot open"):
        read_capture(tmp_path / "nope.jsonl")


def test_header_fingerprints_absent_or_from_before_dialects(tmp_path):
    path = tmp_path / "h.jsonl"
    path.write_text(HEADER + "\n")
    assert read_capture(path)[0].fingerprints is None
    path.write_text(json.dumps({"format": "lorascout-capture", "version": 1, "profile": "x",
                                "schema_fingerprint": "0x762D"}) + "\n")
    assert read_capture(path)[0].fingerprints == {LEGACY_FINGERPRINT_NAME: 0x762D}
