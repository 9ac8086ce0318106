"""`lorascout inspect --serial` against a scripted RN2483 on a real pseudo-terminal."""
import json
import os
import threading
import time
import tty

import pytest

from firmware.comms.frame import encode_frame
from host_tools import cli

pytest.importorskip("serial")

TOPO = dict(sender_id=5, x_cm=-12345, y_cm=2, z_cm=3, presence=1, e_inf_code=9, info_version=0)


class ScriptedModem(threading.Thread):
    """Answers the RN2483 command subset; each `radio rx 0` delivers the next scripted line
    (a frame, `radio_err`, or nothing: the modem then stays silent, as with no traffic)."""

    def __init__(self, rx_lines):
        super().__init__(daemon=True)
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self.path = os.ttyname(self.slave)
        self.rx_lines = list(rx_lines)
        self.commands: list[str] = []
        self.refuse: set[str] = set()
        self.stop = threading.Event()

    def send(self, line):
        os.write(self.master, (line + "\r\n").encode())

    def run(self):
        try:
            self._serve()
        except OSError:         # the test closed the pty: the modem is unplugged
            return

    def _serve(self):
        buf = b""
        while not self.stop.is_set():
            try:
                chunk = os.read(self.master, 1024)
            except OSError:
                return
            buf += chunk
            while b"\r\n" in buf:
                raw, buf = buf.split(b"\r\n", 1)
                cmd = raw.decode()
                self.commands.append(cmd)
                if cmd == "sys get ver":
                    self.send("RN2483 1.0.5 Oct 31 2018 15:06:52")
                elif cmd == "mac pause":
                    self.send("4294967245")
                elif cmd == "radio get rssi":
                    self.send("-97")
                elif cmd == "radio get snr":
                    self.send("-5")
                elif cmd == "radio rx 0":
                    self.send("ok")
                    if self.rx_lines:
                        self.send(self.rx_lines.pop(0))
                elif cmd in self.refuse:
                    self.send("invalid_param")
                else:
                    self.send("ok")

    def close(self):
        self.stop.set()
        os.close(self.slave)      # with no slave fd left, the master read fails and run() returns
        self.join(timeout=2)
        os.close(self.master)


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
    assert "radio set freq 868100000" in m.commands and "radio set sync 12" in m.commands
    assert m.commands.count("radio rx 0") == 5            # re-armed after every line
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
    assert "modem refused 'radio set sync 12': 'invalid_param'" in capsys.readouterr().err
