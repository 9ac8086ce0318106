"""`lorascout modem` as a user runs it: a subprocess serving real pseudo-terminals in wall
clock time, driven by plain pyserial, by our backend, and by a third-party RN2483 library
(loranode 0.0.4 from PyPI, unchanged)."""
from __future__ import annotations

import signal
import time

import pytest
import serial

from hal.lora import PROFILES
from hal.rn2483 import Rn2483Modem
from hal.samples import RadioRxFrame, RadioTxDone
from tests.doubles import ModemServer, send_to_a_listening_library

PROFILE = PROFILES["eu868-g3"]
SETUP = ("mac pause", "radio set mod lora", "radio set freq 869525000", "radio set sf sf7",
         "radio set bw 125", "radio set cr 4/5", "radio set pwr 14", "radio set crc on",
         "radio set sync 12", "radio set prlen 8", "radio set wdt 0")


def cmd(port: serial.Serial, line: str) -> str:
    port.write(line.encode() + b"\r\n")
    reply = port.readline()
    assert reply.endswith(b"\r\n"), (line, reply)
    return reply[:-2].decode()


@pytest.mark.realtime
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_plain_pyserial_talks_to_the_printed_devices(sig):
    with ModemServer(2) as server:
        a = serial.Serial(server.paths[0], 57600, timeout=5)
        b = serial.Serial(server.paths[1], 57600, timeout=5)
        try:
            assert cmd(a, "sys get ver") == "RN2483 1.0.5 Oct 31 2018 15:06:52"
            assert cmd(a, "sys get hweui") != cmd(b, "sys get hweui")
            for port in (a, b):
                for line in SETUP:
                    assert cmd(port, line) in ("ok", "4294967245"), line
            assert cmd(b, "radio rx 0") == "ok"
            t0 = time.monotonic()
            assert cmd(a, "radio tx 48656c6c6f") == "ok"
            assert a.readline() == b"radio_tx_ok\r\n"
            took_s = time.monotonic() - t0
            # The modem waits the frame's time on air (wall clock) before radio_tx_ok.
            assert PROFILE.airtime_us(5) / 1e6 <= took_s < PROFILE.airtime_us(5) / 1e6 + 0.5
            assert b.readline() == b"radio_rx  48656C6C6F\r\n"
            assert int(cmd(b, "radio get rssi")) < 0
            assert -128 <= int(cmd(b, "radio get snr")) <= 127
            assert cmd(a, "radio tx 123") == "invalid_param"
            assert cmd(a, "bogus") == "invalid_param"
        finally:
            a.close()
            b.close()
        assert server.stop(sig) == 0


def test_our_backend_over_the_wall_clock_server():
    with ModemServer(2) as server:
        a = Rn2483Modem(server.paths[0], PROFILE)
        b = Rn2483Modem(server.paths[1], PROFILE)
        try:
            assert a.transmit(b"\x00\x01ping")
            deadline = time.monotonic() + 5
            got_a, got_b = [], []
            while time.monotonic() < deadline and not (got_a and got_b):
                got_a += a.poll()
                got_b += b.poll()
                time.sleep(0.002)
            assert [type(e) for e in got_a] == [RadioTxDone] and got_a[0].ok
            assert [e.payload for e in got_b] == [b"\x00\x01ping"]
        finally:
            a.close()
            b.close()
        assert server.stop() == 0


def test_third_party_loranode_library_transmits_and_receives():
    loranode = pytest.importorskip("loranode")  # test extra: loranode==0.0.4
    with ModemServer(2) as server:
        lib = loranode.RN2483Controller(server.paths[0])       # sys reset, hweui, rxdelay1/2
        assert len(lib.hweui) == 16 and lib.rxdelay1 == "1000" and lib.rxdelay2 == "2000"
        # The library sets SF/BW/CR/CRC/power itself; frequency and sync word it leaves to
        # its raw command method, which is part of its public interface.
        lib.set_sf(7)
        lib.set_bw(125)
        lib.set_cr("4/5")
        lib.set_crc("on")
        lib.set_pwr(14)
        assert lib.serial_sr("radio set freq", "869525000") == "ok"
        assert lib.serial_sr("radio set sync", "12") == "ok"
        assert (lib.get_sf(), lib.get_bw(), lib.get_cr(), lib.get_freq()) == ("sf7", "125", "4/5", "869525000")

        ours = Rn2483Modem(server.paths[1], PROFILE)
        try:
            # library -> our backend
            ours.poll()
            lib.send_p2p("4c6962546f4f757273")                  # "LibToOurs"
            deadline = time.monotonic() + 5
            frames = []
            while time.monotonic() < deadline and not frames:
                frames = [e for e in ours.poll() if isinstance(e, RadioRxFrame)]
                time.sleep(0.002)
            assert [f.payload for f in frames] == [b"LibToOurs"]

            # our backend -> library (recv_p2p blocks in `radio rx 0` until a frame comes)
            box = send_to_a_listening_library(ours, lib.recv_p2p, b"OursToLib")
            assert "error" not in box, box.get("error")
            assert box.get("value") == b"OursToLib".hex().upper()
        finally:
            ours.close()
            lib.device.close()
        assert server.stop() == 0


def test_round_trip_time_of_the_wall_clock_server():
    with ModemServer(1) as server:
        port = serial.Serial(server.paths[0], 57600, timeout=5)
        try:
            n = 200
            t0 = time.perf_counter()
            for _ in range(n):
                assert cmd(port, "radio get snr") == "-128"
            rtt_us = (time.perf_counter() - t0) / n * 1e6
        finally:
            port.close()
        assert server.stop() == 0
    print(f"wall-clock server round trip: {rtt_us:.0f} us")
    assert rtt_us < 20_000


def test_us915_is_served_by_rn2903_modems_that_our_backend_drives():
    us915 = PROFILES["us915"]
    with ModemServer(2, "--radio", "us915") as server:
        port = serial.Serial(server.paths[0], 57600, timeout=5)
        try:
            assert cmd(port, "sys get ver") == "RN2903 1.0.5 Nov 06 2018 10:45:27"
            assert cmd(port, "radio set freq 868100000") == "invalid_param"
        finally:
            port.close()
        a = Rn2483Modem(server.paths[0], us915)
        b = Rn2483Modem(server.paths[1], us915)
        try:
            assert a.model.name == "RN2903" and a.version.startswith("RN2903")
            assert a.transmit(b"over the US band")
            deadline = time.monotonic() + 5
            got = []
            while time.monotonic() < deadline and not got:
                got = [e for e in b.poll() if isinstance(e, RadioRxFrame)]
                a.poll()
                time.sleep(0.002)
            assert [e.payload for e in got] == [b"over the US band"]
            assert a.command_errors == [] and b.command_errors == []
        finally:
            a.close()
            b.close()
        assert server.stop() == 0
