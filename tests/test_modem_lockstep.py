"""hal.rn2483.Rn2483Modem against virtual modems on real ptys, in lockstep with the shared
Channel, and the determinism check: the serial path gives what the in-process
SimRadioModem gives on the same seed and the same scripted traffic."""
from __future__ import annotations

import os
import time

import pytest
import serial

from hal.interfaces import RadioModem
from hal.lora import PROFILES
from hal.rn2483 import Rn2483Error, Rn2483Modem
from hal.samples import RadioRxFrame, RadioTxDone
from hal.sim.radio import SimRadioModem
from radio_sim.channel import Channel
from radio_sim.faults import FaultParams
from radio_sim.virtual_modem import LockstepSerialRadios, ModemBank, open_serial_radios
from world_sim.seeding import stream
from tests.doubles import StepClock

PROFILE = PROFILES["eu868-g3"]


def serial_radios(channel, clock, node_ids, profile):
    return open_serial_radios(channel, profile, clock, node_ids)


def test_backend_configures_the_modem_and_exchanges_frames_in_lockstep():
    clock = StepClock()
    channel = Channel(PROFILE, seed=1)
    for i in range(2):
        channel.attach(i, lambda i=i: (10.0 * i, 0.0))
    bank, (a, b) = serial_radios(channel, clock, [0, 1], PROFILE)
    try:
        assert isinstance(a, RadioModem)
        assert a.version == "RN2483 1.0.5 Oct 31 2018 15:06:52"
        m = bank.bank.modems[0]
        assert (m.settings.freq_hz, m.settings.sf, m.settings.bw_khz, m.settings.sync_word,
                m.settings.wdt_ms, m.settings.pwr_dbm) == (869_525_000, 7, 125, 0x12, 0, 15)
        assert m.on_air and m.mac_paused and m.state == "rx"
        assert channel.listening(0) and channel.listening(1)

        assert a.transmit(b"hello, b") is True
        assert a.busy() and a.transmit(b"again") is False
        assert a.transmit(b"x" * 256) is False
        end_us = PROFILE.airtime_us(8)
        clock.t_us = end_us - 1
        bank.advance_to(clock.t_us)
        assert a.busy() and a.poll() == () and b.poll() == ()
        clock.t_us = end_us
        bank.advance_to(clock.t_us)
        assert not a.busy()
        assert a.poll() == (RadioTxDone(stamp_us=end_us, ok=True),)
        [frame] = b.poll()
        assert isinstance(frame, RadioRxFrame) and frame.payload == b"hello, b"
        assert frame.stamp_us == end_us
        rssi = PROFILE.tx_power_dbm - channel.propagation.path_loss_db(10.0)
        assert frame.rssi_dbm == round(rssi)
        assert not channel.listening(1)                   # the re-arming is queued, not yet served...
        bank.advance_to(clock.t_us)                       # ...until the runner hands time over
        assert channel.listening(1)                       # poll re-armed `radio rx 0`

        # Empty and maximum-size frames, the other way round.
        for payload in (b"", bytes(range(255))):
            assert b.transmit(payload)
            clock.t_us += PROFILE.airtime_us(len(payload))
            bank.advance_to(clock.t_us)
            assert b.poll() == (RadioTxDone(stamp_us=clock.t_us, ok=True),)
            [got] = a.poll()
            assert got.payload == payload
    finally:
        a.close()
        b.close()
        bank.close()


def test_bank_rejects_time_running_backwards():
    channel = Channel(PROFILE, seed=0)
    channel.attach(0, lambda: (0.0, 0.0))
    with ModemBank(channel, PROFILE, [0]) as bank:
        bank.advance_to(10)
        with pytest.raises(ValueError, match="time runs forwards"):
            bank.advance_to(9)


def test_backend_names_the_command_and_the_wrong_answer():
    # loop:// echoes what is written, so the "answer" to `sys reset` is `sys reset`.
    with pytest.raises(Rn2483Error, match=r"loop://: command 'sys reset' answered 'sys reset', expected a version line"):
        Rn2483Modem("loop://", PROFILE, reply_timeout_s=0.2, reset_timeout_s=0.2)


def test_backend_times_out_on_a_silent_device():
    master, slave = os.openpty()
    try:
        with pytest.raises(Rn2483Error, match=r"command 'sys reset': no answer within 0.2 s"):
            Rn2483Modem(os.ttyname(slave), PROFILE, reply_timeout_s=0.2, reset_timeout_s=0.2)
    finally:
        os.close(master)
        os.close(slave)


def test_backend_reports_an_unopenable_port():
    with pytest.raises(Rn2483Error, match="/dev/does-not-exist: cannot open"):
        Rn2483Modem("/dev/does-not-exist", PROFILE)


# -- determinism: in-process vs serial ---------------------------------------------------

POSITIONS = [(0.0, 0.0), (25.0, 0.0), (0.0, 60.0), (400.0, 300.0), (60_000.0, 0.0)]  # the last is out of range
TICK_US = 10_000


def _normalise(tick, node, event):
    # The module reports integer dBm and dB; the firmware sees the same through either path.
    if isinstance(event, RadioTxDone):
        return ("done", tick, node, event.ok)
    return ("rx", tick, node, event.payload, round(event.rssi_dbm), max(-128, min(127, round(event.snr_db))))


def run_script(kind: str, seed: int, ticks: int, profile=PROFILE, min_size: int = 0):
    clock = StepClock()
    channel = Channel(profile, seed, faults=FaultParams(0.1, 0.1, 0.2, duplicate_delay_us=15_000))
    air: list = []
    channel.add_sink(air.append)
    ids = list(range(len(POSITIONS)))
    for i, p in zip(ids, POSITIONS):
        channel.attach(i, lambda p=p: p)
    bank = None
    if kind == "sim":
        radios = [SimRadioModem(channel, i, clock) for i in ids]
    else:
        bank, radios = serial_radios(channel, clock, ids, profile)
    script = stream(seed, "test.modem_script", 0)
    trace = []
    try:
        for tick in range(ticks):
            clock.t_us = tick * TICK_US
            if bank is not None:
                bank.advance_to(clock.t_us)
            for i, radio in enumerate(radios):
                if script.random() < 0.04:
                    size = int(script.integers(min_size, 64)) if script.random() < 0.9 else 255
                    payload = bytes(script.integers(0, 256, size, dtype="uint8"))
                    trace.append(("tx", tick, i, radio.transmit(payload)))
                if script.random() < 0.5:
                    trace.append(("busy", tick, i, radio.busy()))
                trace.extend(_normalise(tick, i, e) for e in radio.poll())
    finally:
        if bank is not None:
            for r in radios:
                r.close()
            bank.close()
    return trace, air, channel.counters()


@pytest.mark.parametrize("seed", [7, 11, 12345])
def test_serial_path_matches_in_process_modem_on_the_same_seed(seed):
    ticks = 600
    sim_trace, sim_air, sim_counts = run_script("sim", seed, ticks)
    ser_trace, ser_air, ser_counts = run_script("serial", seed, ticks)
    # The script must really exercise the channel: refusals, collisions, faults, deliveries.
    kinds = {t[0] for t in sim_trace}
    assert {"tx", "busy", "done", "rx"} <= kinds
    assert any(t[0] == "tx" and t[3] is False for t in sim_trace)
    assert sim_counts["collided"] > 0 and sim_counts["received"] > 20 and sim_counts["out_of_range"] > 0
    assert sim_counts["half_duplex"] > 0
    assert sim_counts["injected_loss"] > 0 and sim_counts["corrupted"] > 0
    assert sim_counts["duplicates_delivered"] > 0
    assert ser_air == sim_air                 # every frame and every fate, identical
    assert ser_trace == sim_trace             # what each firmware saw, tick by tick
    assert ser_counts == sim_counts


@pytest.mark.parametrize("profile_name", ["ideal-100Bps", "eu868-g3-bw250", "eu868-g1"])
def test_serial_path_matches_in_process_modem_on_other_profiles(profile_name):
    # On the ideal link an empty frame ends the microsecond it starts: the in-process modem
    # shows it done (and received) to the robots that poll later in the same tick, the
    # serial path, which learns it from the modems' lines, at the next tick. Real links
    # have no frame shorter than a tick, so the script sends no empty frame here.
    sim = run_script("sim", 5, 300, PROFILES[profile_name], min_size=1)
    ser = run_script("serial", 5, 300, PROFILES[profile_name], min_size=1)
    assert sim[2]["frames"] > 10
    if PROFILES[profile_name].ideal:
        # The ideal link can hand a node several frames between two polls; the module keeps
        # one last RSSI/SNR, so those are compared only on real links.
        sim = ([e[:4] for e in sim[0]],) + sim[1:]
        ser = ([e[:4] for e in ser[0]],) + ser[1:]
    assert ser == sim


def test_serial_runs_repeat_exactly():
    a = run_script("serial", 3, 150)
    b = run_script("serial", 3, 150)
    assert a == b and len(a[0]) > 20


def test_open_serial_radios_and_garbage_on_the_line():
    from hypothesis import given, settings, strategies as st

    clock = StepClock()
    channel = Channel(PROFILE, seed=2)
    for i in range(2):
        channel.attach(i, lambda i=i: (5.0 * i, 0.0))
    # The drivers read their ptys all the time, so the garbage goes to a third modem.
    channel.attach(2, lambda: (10.0, 0.0))
    bank = ModemBank(channel, PROFILE, [0, 1, 2])
    radios = [Rn2483Modem(path, PROFILE, clock, lockstep=True) for path in bank.paths[:2]]
    link = LockstepSerialRadios(bank, radios)
    raw = serial.Serial(bank.paths[2], 57600, timeout=2)
    try:
        @settings(max_examples=40, deadline=None)
        @given(st.binary(max_size=300))
        def garbage_then_a_query(junk):
            raw.reset_input_buffer()
            raw.write(junk.replace(b"\n", b"") + b"\r\n")
            answer = raw.readline()
            assert answer.endswith(b"\r\n") and len(answer) < 100
            raw.write(b"sys get ver\r\n")
            assert raw.readline() == b"RN2483 1.0.5 Oct 31 2018 15:06:52\r\n"

        garbage_then_a_query()
        raw.write(b"x" * 5000)          # an endless line overflows the module's buffer
        assert raw.readline() == b"invalid_param\r\n"
        raw.write(b"\r\n")
        assert raw.readline() == b"invalid_param\r\n"
        link.advance_to(1)              # the service thread survived all of it
        assert radios[0].transmit(b"still fine")
        link.advance_to(2)
        assert bank.modems[0].state == "tx"
    finally:
        raw.close()
        link.close()


@pytest.mark.realtime
def test_no_call_waits_for_a_slow_module():
    """Every answer of this module takes 100 ms: transmit, busy and poll still return at once
    (the writer thread waits for the answers), and the frame's fate arrives later."""
    from tests.doubles import ScriptedModem

    modem = ScriptedModem([], reply_delay_s=0.1)
    modem.start()
    radio = Rn2483Modem(modem.path, PROFILE, reply_timeout_s=2.0)     # start-up waits, as it may
    try:
        worst_s = 0.0
        for call in (lambda: radio.transmit(bytes(255)), radio.busy, radio.poll, radio.poll):
            t0 = time.perf_counter()
            call()
            worst_s = max(worst_s, time.perf_counter() - t0)
        assert worst_s < 0.02, f"a call took {worst_s * 1e3:.1f} ms"
        assert radio.busy()                        # still sending, as far as the driver knows
        deadline = time.monotonic() + 5
        while time.monotonic() < deadline and "radio tx " + "00" * 255 not in modem.commands:
            time.sleep(0.01)
        assert "radio tx " + "00" * 255 in modem.commands      # the writer got it out meanwhile
        modem.send("radio_tx_ok")                  # the frame's end, as the module reports it
        deadline = time.monotonic() + 5
        events = ()
        while time.monotonic() < deadline and not events:
            radio.wait(0.05)
            events = radio.poll()
        assert events == (RadioTxDone(stamp_us=events[0].stamp_us, ok=True),) and not radio.busy()
    finally:
        radio.close()
        modem.close()


def test_driver_survives_garbage_from_the_module():
    from tests.doubles import ScriptedModem

    # Each `radio rx 0` of the scripted module ends with one of these reception lines.
    rng = stream(4, "test.modem_garbage", 0)
    junk = ["zz", "ABC", "0", "\u00e9\u00ff junk"]    # ("radio_rx  " alone is an empty frame)
    junk += ["".join(chr(int(c)) for c in rng.integers(32, 0x250, int(rng.integers(1, 40)))) for _ in range(20)]
    good = "radio_rx  " + b"still here".hex().upper()
    modem = ScriptedModem(["radio_rx  " + j for j in junk] + [good])
    modem.start()
    radio = Rn2483Modem(modem.path, PROFILE)
    try:
        frames = []
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline and not frames:
            radio.wait(0.05)
            frames = [e for e in radio.poll() if isinstance(e, RadioRxFrame)]
        assert [f.payload for f in frames] == [b"still here"]
        assert radio.lines_ignored == len(junk)
        # Noise on the line while no command waits for an answer is counted and dropped.
        modem.send("\u00e9 noise \x01")
        deadline = time.monotonic() + 5
        while time.monotonic() < deadline and radio.lines_ignored == len(junk):
            time.sleep(0.01)
        assert radio.lines_ignored == len(junk) + 1 and radio.poll() == ()
    finally:
        radio.close()
        modem.close()
