"""Test doubles shared by the test files: a clock the test steps, the Channel handle a
virtual modem talks to, a scripted RN2483 on a real pseudo-terminal, and `lorascout modem`
run as a subprocess."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
import tty
from pathlib import Path

from hal import rn2483_protocol as P

REPO = Path(__file__).resolve().parents[1]


class StepClock:
    """hal.interfaces.Clock whose time the test sets."""

    def __init__(self) -> None:
        self.t_us = 0

    def now_us(self) -> int:
        return self.t_us


class FakePort:
    """Records what a virtual modem asks of the Channel (radio_sim.rn2483.AirPort); answers
    transmit as the Channel does, with the profile's airtime at the profile's operating point
    and the modem's own airtime elsewhere."""

    def __init__(self, profile):
        self.profile = profile
        self.calls: list[tuple] = []             # ("tx", payload, now_us) / ("listen", on, now_us)
        self.tx_air: list[tuple] = []            # (AirInterface, tx_power_dbm) per transmit
        self.listen_air: list = []               # AirInterface per set_listening
        self.refuse = False

    def transmit(self, payload, now_us, air, tx_power_dbm):
        self.calls.append(("tx", bytes(payload), now_us))
        self.tx_air.append((air, tx_power_dbm))
        if self.refuse:
            return None
        if air == self.profile.air_interface():
            return now_us + self.profile.airtime_us(len(payload))
        return now_us + air.airtime_us(len(payload))

    def set_listening(self, listening, now_us, air):
        self.calls.append(("listen", listening, now_us))
        self.listen_air.append(air)


class ScriptedModem(threading.Thread):
    """An RN2483 on a real pty that answers from a script: each `radio rx 0` delivers the
    next scripted line (a frame, `radio_err`, or nothing: the modem then stays silent, as
    with no traffic); commands in `refuse` answer invalid_param, others `ok` or the value a
    module gives. `reply_delay_s` holds every answer back that long, as a module behind a
    slow UART would (a 255-byte `radio tx` alone is about 90 ms at 57600 baud)."""

    def __init__(self, rx_lines, reply_delay_s: float = 0.0):
        super().__init__(daemon=True)
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self.path = os.ttyname(self.slave)
        self.rx_lines = list(rx_lines)
        self.commands: list[str] = []
        self.refuse: set[str] = set()
        self.stop = threading.Event()
        self.reply_delay_s = reply_delay_s

    def send(self, line):
        os.write(self.master, (line + "\r\n").encode())

    def run(self):
        try:
            self._serve()
        except OSError:         # the test closed the pty: the modem is unplugged
            return

    def _serve(self):
        answers = {P.SYS_GET_VER: P.RN2483.version_line, P.SYS_RESET: P.RN2483.version_line,
                   P.MAC_PAUSE: str(P.MAC_PAUSE_MS), P.RADIO_GET_RSSI: "-97", P.RADIO_GET_SNR: "-5"}
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
                if self.reply_delay_s:
                    time.sleep(self.reply_delay_s)
                if cmd in self.refuse:
                    self.send(P.INVALID_PARAM)
                elif cmd == P.RADIO_RX_CONTINUOUS:
                    self.send(P.OK)
                    if self.rx_lines:
                        self.send(self.rx_lines.pop(0))
                else:
                    self.send(answers.get(cmd, P.OK))

    def close(self):
        self.stop.set()
        os.close(self.slave)      # with no slave fd left, the master read fails and run() returns
        self.join(timeout=2)
        os.close(self.master)


class ModemServer:
    """`lorascout modem` as a user runs it: a subprocess serving virtual modems on ptys in
    wall-clock time; `paths` are the devices it printed."""

    def __init__(self, count: int, *extra: str):
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "host_tools.cli", "modem", "--count", str(count), *extra],
            cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        )
        self.paths = [self.proc.stdout.readline().strip() for _ in range(count)]
        if not all(p.startswith("/dev/") for p in self.paths):
            self.proc.kill()
            raise AssertionError(f"lorascout modem printed {self.paths!r}; stderr: {self.proc.stderr.read()}")

    def stop(self, sig=signal.SIGINT) -> int:
        self.proc.send_signal(sig)
        try:
            return self.proc.wait(timeout=10)
        finally:
            if self.proc.poll() is None:
                self.proc.kill()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()
