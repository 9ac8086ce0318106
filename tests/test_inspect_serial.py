"""`lorascout inspect --serial` against a scripted RN2483 on a real pseudo-terminal."""
import json
import time

import pytest

from firmware.comms.frame import encode_frame
from hal import rn2483_protocol as P
from hal.lora import PROFILES
from host_tools import cli
from tests.doubles import ScriptedModem

pytest.importorskip("serial")

TOPO = dict(sender_id=5, x_cm=-12345, y_cm=2, z_cm=3, presence=1, e_inf_code=9, info_version=0)


@pytest.fixture
def modem_factory():
    made = []

    def make(lines):
        m = ScriptedModem(lines)
        m.start()
        made.append(m)
        return m
    yield make
    for m in made:
        m.close()


def test_serial_receive_decodes_and_rearms(modem_factory, tmp_path, capsys):
    good = encode_frame(5, 300, [("topo", TOPO)])
    bad = bytearray(encode_frame(5, 302, [("topo", TOPO)]))
    bad[7] ^= 0x40
    m = modem_factory([f"radio_rx  {good.hex()}", "radio_err", f"radio_rx  {bytes(bad).hex()}",
                       "radio_rx  zz", f"radio_rx  {encode_frame(6, 1, [('topo', TOPO)]).hex()}"])
    cap = tmp_path / "live.jsonl"
    pcap = tmp_path / "live.pcap"
    rc = cli.main(["inspect", "--serial", m.path, "--profile", "eu868-g1", "--count", "3", "--timeout", "20",
                   "--json", "--write-capture", str(cap), "--pcap", str(pcap)])
    assert rc == 0
    doc = json.loads(capsys.readouterr().out)
    assert [f["reason"] for f in doc["frames"]] == ["ok", "bad_crc", "ok"]
    f0 = doc["frames"][0]
    assert f0["seq"] == 300 and f0["records"][0]["values"]["x_cm"] == -12345
    assert f0["receptions"] == [{"receiver_id": 0, "rssi_dbm": -97.0, "snr_db": -5.0, "fate": "received"}]
    assert f0["freq_hz"] == 868_100_000
    assert doc["senders"]["5"]["frames"] == 1 and doc["senders"]["255"]["reasons"] == {"bad_crc": 1}
    # The driver configured the profile...
    assert m.commands[:3] == ["sys reset", "sys get ver", "mac pause"]
    assert m.commands[3:3 + 11] == P.network_config_commands(PROFILES["eu868-g1"], P.RN2483)
    # ...re-armed after every line, the last frame's too (what the sixth arming catches is
    # not reported: three frames were asked for), asked each frame's rssi and snr...
    assert m.commands.count("radio rx 0") == 6 and m.commands.count("radio get rssi") >= 3
    # ...and left the module idle.
    assert m.commands[-1] == "radio rxstop"
    assert cap.read_text().count("\n") == 4               # header + 3 frames
    assert pcap.stat().st_size > 24


def test_serial_timeout_when_the_air_is_quiet(modem_factory, capsys):
    m = modem_factory([])
    rc = cli.main(["inspect", "--serial", m.path, "--timeout", "0.6", "--no-configure", "--summary"])
    assert rc == 0
    deadline = time.monotonic() + 5          # the modem thread reads the last command a moment later
    while m.commands[-1] != "radio rxstop" and time.monotonic() < deadline:
        time.sleep(0.01)
    assert "radio set mod lora" not in m.commands and m.commands[-1] == "radio rxstop"
    assert "decode:" in capsys.readouterr().out


def test_serial_reports_a_refused_setting(modem_factory, capsys):
    m = modem_factory([])
    m.refuse.add("radio set sync 12")
    rc = cli.main(["inspect", "--serial", m.path, "--timeout", "5"])
    assert rc == 1
    assert "command 'radio set sync 12' answered 'invalid_param', expected 'ok'" in capsys.readouterr().err
