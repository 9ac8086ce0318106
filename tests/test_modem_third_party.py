"""Third-party RN2483 drivers from PyPI, used unchanged, against `lorascout modem` (virtual
modems on real pseudo-terminals, wall clock): loranode 0.0.4 (a Python RN2483 library) and
loramdm 0.0.3 (a command-line tool that sends `;`-separated command lines to a serial LoRa
modem and prints what comes back). They configure every documented `radio set` parameter,
and transmit and receive through the virtual modems."""
from __future__ import annotations

import signal
import subprocess
import sys
import time

import pytest

from hal import rn2483_protocol as P
from hal.lora import PROFILES
from hal.rn2483 import Rn2483Modem
from hal.samples import RadioRxFrame
from tests.doubles import ModemServer, deliverable_sigint, in_thread, send_to_a_listening_library

PROFILE = PROFILES["eu868-g3"]

# Every documented `radio set` parameter with a value other than its power-on default, and
# what `radio get` prints for it.
EVERY_RADIO_SET = [
    ("mod", "fsk", "fsk"), ("bitrate", "100000", "100000"), ("fdev", "5000", "5000"),
    ("afcbw", "125", "125"), ("rxbw", "62.5", "62.5"), ("bt", "0.3", "0.3"), ("sync", "C194C1", "C194C1"),
    ("mod", "lora", "lora"), ("freq", "869525000", "869525000"), ("pwr", "14", "14"), ("sf", "sf9", "sf9"),
    ("bw", "250", "250"), ("cr", "4/7", "4/7"), ("prlen", "10", "10"), ("crc", "off", "off"),
    ("iqi", "on", "on"), ("sync", "12", "12"), ("wdt", "5000", "5000"),
]
assert {name for name, _, _ in EVERY_RADIO_SET} == {
    "mod", "freq", "pwr", "sf", "afcbw", "rxbw", "bitrate", "fdev", "prlen", "crc", "iqi", "cr", "wdt",
    "sync", "bw", "bt"}


def _configure(lib, settings):
    for name, value, readback in settings:
        assert lib.serial_sr(f"radio set {name}", value) == "ok", (name, value)
        assert lib.serial_sr(f"radio get {name}") == readback, name


def _receive_with(lib, sender, payload_hex: str, timeout_s: float = 20.0) -> str | None:
    """`lib` listens (`radio rx 0`, answered before the sender keys up, so no sleep decides
    the race) while `sender` transmits once with `send_p2p`; the hex `lib` received, or None
    if its reception ended in `radio_err`."""
    assert lib.serial_sr("radio rx", "0") == "ok"
    t, box = in_thread(lib.serial_r)            # the line that ends the reception
    sender.send_p2p(payload_hex)
    t.join(timeout=timeout_s)
    assert not t.is_alive(), "no line ended the reception"
    assert "error" not in box, box.get("error")
    line = box["value"]
    if line == P.RADIO_ERR:
        return None
    assert line.startswith(P.RADIO_RX_PREFIX.rstrip() + " "), line
    return line[len(P.RADIO_RX_PREFIX):]


@pytest.mark.realtime
def test_loranode_sets_every_radio_parameter_and_two_libraries_talk_with_those_settings():
    loranode = pytest.importorskip("loranode")
    with ModemServer(2) as server:
        a = loranode.RN2483Controller(server.paths[0])
        b = loranode.RN2483Controller(server.paths[1])
        try:
            for lib in (a, b):
                _configure(lib, EVERY_RADIO_SET)
            # The library's own setters too.
            a.set_sf(9), a.set_bw(250), a.set_cr("4/7"), a.set_crc("off"), a.set_pwr(14)
            assert (a.get_sf(), a.get_bw(), a.get_cr(), a.get_pwr()) == ("sf9", "250", "4/7", "14")
            # Same frequency, SF, BW, sync word and IQ inversion: they hear each other.
            assert _receive_with(b, a, "4C6962546F4C6962") == "4C6962546F4C6962"       # "LibToLib"
            # The receiver with IQ not inverted hears nothing; its watchdog (5 s) ends the wait.
            assert b.serial_sr("radio set iqi", "off") == "ok"
            t0 = time.monotonic()
            assert _receive_with(b, a, "4E6F7420686561726421") is None
            assert 4.5 < time.monotonic() - t0 < 10
        finally:
            a.device.close()
            b.device.close()
        assert server.stop() == 0


def test_two_modules_at_power_on_defaults_talk_to_each_other():
    """SF12 at 868.1 MHz, sync 34: not the network's operating point, but a real pair hears
    itself there, and so does a virtual one."""
    loranode = pytest.importorskip("loranode")
    with ModemServer(2) as server:
        a = loranode.RN2483Controller(server.paths[0])      # `sys reset`: power-on settings
        b = loranode.RN2483Controller(server.paths[1])
        try:
            assert (a.get_sf(), a.get_freq()) == ("sf12", "868100000")
            assert _receive_with(b, a, "44656661756C7473") == "44656661756C7473"        # "Defaults"
        finally:
            a.device.close()
            b.device.close()
        assert server.stop() == 0


def test_loranode_and_our_backend_on_the_network_operating_point():
    loranode = pytest.importorskip("loranode")
    with ModemServer(2) as server:
        lib = loranode.RN2483Controller(server.paths[0])     # sys reset, hweui, rxdelay1/2
        assert len(lib.hweui) == 16 and lib.rxdelay1 == "1000" and lib.rxdelay2 == "2000"
        for line in P.network_config_commands(PROFILE, P.RN2483):
            name, value = line.removeprefix("radio set ").split(" ")
            assert lib.serial_sr(f"radio set {name}", value) == "ok", line
        ours = Rn2483Modem(server.paths[1], PROFILE)
        try:
            lib.send_p2p("4C6962546F4F757273")                  # "LibToOurs"
            deadline = time.monotonic() + 5
            frames = []
            while time.monotonic() < deadline and not frames:
                ours.wait(0.05)
                frames = [e for e in ours.poll() if isinstance(e, RadioRxFrame)]
            assert [f.payload for f in frames] == [b"LibToOurs"]
            assert -32 <= frames[0].snr_db <= 32 and frames[0].rssi_dbm < 0

            box = send_to_a_listening_library(ours, lib.recv_p2p, b"OursToLib")
            assert "error" not in box, box.get("error")
            assert box.get("value") == b"OursToLib".hex().upper()
            assert ours.command_errors == []
        finally:
            ours.close()
            lib.device.close()
        assert server.stop() == 0


def _loramdm(path: str, commands: list[str], *extra: str) -> subprocess.Popen:
    pytest.importorskip("loramdm")
    # -s: pause after each command line; -t: read timeout (it reads until the line is quiet).
    return subprocess.Popen([sys.executable, "-m", "loramdm", f"-d{path}", f"-b{P.BAUDRATE}", "-s0.02", "-t0.1",
                             ";".join(commands), *extra],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=deliverable_sigint)


def test_loramdm_cli_configures_every_parameter_and_its_frames_cross_the_air():
    settings = [f"radio set {name} {value}" for name, value, _ in EVERY_RADIO_SET]
    lora_part = EVERY_RADIO_SET[7:]
    gets = [f"radio get {name}" for name, _, _ in lora_part]
    version = P.RN2483.version_line
    with ModemServer(2) as server:
        # Receiver: loramdm listening (-l) after `radio rx 0`, on the same settings, watchdog off.
        rx = _loramdm(server.paths[1], ["sys reset"] + settings + ["radio set wdt 0", "radio rx 0"], "-l")
        seen: list[str] = []
        try:
            while seen.count("ok") < len(settings) + 2:          # every setting, wdt, and rx armed
                line = rx.stdout.readline()
                assert line, f"loramdm stopped: {rx.stderr.read()}"
                seen.append(line.rstrip("\n"))
            tx = _loramdm(server.paths[0], ["sys reset"] + settings + gets +
                          ["radio set wdt 0", "radio tx 4C6F72616D646D", "sys get ver", "sys get ver"])
            out, err = tx.communicate(timeout=60)
            assert tx.returncode == 0, err
            lines = out.splitlines()
            assert lines[:1 + len(settings)] == [version] + ["ok"] * len(settings)
            assert lines[1 + len(settings):][:len(gets)] == [readback for _, _, readback in lora_part]
            assert lines.count("ok") == len(settings) + 2 and "radio_tx_ok" in lines
            time.sleep(0.5)
        finally:
            rx.send_signal(signal.SIGINT)
            rx_out, _ = rx.communicate(timeout=10)
        assert "radio_rx  4C6F72616D646D" in seen + rx_out.splitlines()          # "Loramdm"
        assert server.stop() == 0
