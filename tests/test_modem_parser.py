"""The RN2483 command state machine (radio_sim.rn2483), without any I/O."""
from __future__ import annotations

import pytest
from hypothesis import given, settings, strategies as st

from hal import rn2483_protocol as P
from hal.lora import PROFILES, LoraModulation, RadioProfile, time_on_air_us
from hal.samples import RadioRxFrame, RadioTxDone
from radio_sim.rn2483 import (
    MAC_PAUSE_MS, VERSION_LINE, RadioSettings, Rn2483, hweui_for, on_air_settings,
)
from tests.doubles import FakePort

PROFILE = PROFILES["eu868-g3"]


def configured(port=None, node_id=3) -> tuple[Rn2483, FakePort]:
    """A modem set to the channel's operating point, as hal.rn2483 sets it up."""
    port = port or FakePort(PROFILE)
    m = Rn2483(node_id, port, on_air_settings(PROFILE))
    for cmd in ["mac pause"] + P.network_config_commands(PROFILE, P.RN2483):
        assert m.command(cmd, 0) in (["ok"], [str(MAC_PAUSE_MS)]), cmd
    assert m.on_air
    return m, port


def test_sys_and_mac_answers_are_the_real_modules():
    m = Rn2483(7)
    assert m.command("sys get ver", 0) == ["RN2483 1.0.5 Oct 31 2018 15:06:52"]
    assert m.command("sys reset", 0) == [VERSION_LINE]
    eui = m.command("sys get hweui", 0)[0]
    assert len(eui) == 16 and int(eui, 16) >= 0 and eui == eui.upper()
    assert eui != Rn2483(8).command("sys get hweui", 0)[0] and eui == hweui_for(7)
    assert m.command("mac pause", 0) == ["4294967245"]
    assert m.command("mac resume", 0) == ["ok"]
    assert m.command("mac get rxdelay1", 0) == ["1000"]
    assert m.command("mac get rxdelay2", 0) == ["2000"]


def test_power_on_defaults_match_the_module():
    m = Rn2483(0)
    got = {k: m.command(f"radio get {k}", 0)[0] for k in
           ("mod", "freq", "pwr", "sf", "bw", "cr", "crc", "iqi", "sync", "prlen", "wdt", "bitrate",
            "fdev", "afcbw", "rxbw", "bt", "snr", "rssi")}
    assert got == {"mod": "lora", "freq": "868100000", "pwr": "1", "sf": "sf12", "bw": "125",
                   "cr": "4/5", "crc": "on", "iqi": "off", "sync": "34", "prlen": "8", "wdt": "15000",
                   "bitrate": "50000", "fdev": "25000", "afcbw": "41.7", "rxbw": "25", "bt": "0.5",
                   "snr": "-128", "rssi": "-128"}
    rn2903 = Rn2483(0, model=P.RN2903)
    assert rn2903.command("sys get ver", 0) == ["RN2903 1.0.5 Nov 06 2018 10:45:27"]
    assert rn2903.command("radio get freq", 0) == ["923300000"]
    assert rn2903.command("radio get pwr", 0) == ["2"]


@pytest.mark.parametrize("name,value,readback", [
    ("mod", "fsk", "fsk"), ("mod", "lora", "lora"),
    ("freq", "433050000", "433050000"), ("freq", "434790000", "434790000"),
    ("freq", "863000000", "863000000"), ("freq", "870000000", "870000000"),
    ("sf", "sf7", "sf7"), ("sf", "sf12", "sf12"),
    ("bw", "125", "125"), ("bw", "250", "250"), ("bw", "500", "500"),
    ("cr", "4/5", "4/5"), ("cr", "4/8", "4/8"),
    ("pwr", "-3", "-3"), ("pwr", "15", "15"), ("pwr", "0", "0"),
    ("crc", "off", "off"), ("crc", "on", "on"),
    ("sync", "12", "12"), ("sync", "ab", "AB"), ("sync", "7", "07"),
    ("prlen", "0", "0"), ("prlen", "65535", "65535"),
    ("wdt", "0", "0"), ("wdt", "4294967295", "4294967295"),
    ("iqi", "on", "on"), ("iqi", "off", "off"),
    ("bitrate", "1", "1"), ("bitrate", "300000", "300000"), ("fdev", "0", "0"), ("fdev", "200000", "200000"),
    ("afcbw", "62.5", "62.5"), ("afcbw", "2.6", "2.6"), ("rxbw", "250", "250"), ("rxbw", "166.7", "166.7"),
    ("bt", "none", "none"), ("bt", "1.0", "1.0"), ("bt", "0.3", "0.3"),
])
def test_every_setting_round_trips(name, value, readback):
    m = Rn2483(0)
    assert m.command(f"radio set {name} {value}", 0) == ["ok"]
    assert m.command(f"radio get {name}", 0) == [readback]


@pytest.mark.parametrize("line", [
    "", "sys", "sys get", "sys get version", "SYS GET VER", "mac", "mac pause now", "mac get rxdelay3",
    "mac tx uncnf 1 00", "radio", "radio get", "radio get freq extra", "radio get foo",
    "radio set", "radio set freq", "radio set freq 868100000 1", "radio set mod lorawan",
    "radio set freq 433049999", "radio set freq 434790001", "radio set freq 862999999",
    "radio set freq 870000001", "radio set freq 8681e5", "radio set freq -868100000",
    "radio set freq 99999999999", "radio set sf sf6", "radio set sf sf13", "radio set sf 7",
    "radio set sf SF7", "radio set bw 62", "radio set bw 125.0", "radio set cr 4/4", "radio set cr 4/9",
    "radio set cr 5/4", "radio set pwr -4", "radio set pwr 16", "radio set pwr +5", "radio set pwr 1.5",
    "radio set crc yes", "radio set sync 123", "radio set sync xz", "radio set sync ",
    "radio set prlen 65536", "radio set prlen -1", "radio set wdt 4294967296",
    "radio  get sf", "radio get  sf", "radio tx 0", "radio tx abc", "radio tx 0g", "radio tx 00 11",
    "radio tx " + "00" * 256, "radio rx", "radio rx -1", "radio rx 65536", "radio rx x",
    "radio rxstop now", "radio cw", "radio cw yes", "sys get ver\x00", "sys get vér", "x" * 700,
    "radio set iqi 1", "radio set bitrate 0", "radio set bitrate 300001", "radio set fdev 200001",
    "radio set afcbw 62", "radio set rxbw 300", "radio set bt 0.7", "radio get iqi now",
    "sys sleep 99", "sys sleep 4294967297", "sys sleep", "sys get nvm 2FF", "sys get nvm 400",
    "sys set nvm 300", "sys set nvm 300 100", "sys set nvm 300 zz", "sys set pindig GPIO14 1",
    "sys set pindig GPIO1 2", "sys set pinmode GPIO4 ana", "sys set pinmode GPIO1 out",
    "sys get pinana GPIO4", "sys get pindig", "sys factoryreset", "sys erasefw",
])
def test_malformed_or_unknown_is_invalid_param(line):
    m = Rn2483(0)
    assert m.command(line, 0) == ["invalid_param"]


def test_fsk_sync_takes_up_to_eight_bytes_lora_one():
    m = Rn2483(0)
    assert m.command("radio set sync 1234", 0) == ["invalid_param"]
    assert m.command("radio set mod fsk", 0) == ["ok"]
    assert m.command("radio set sync 0123456789abcdef", 0) == ["ok"]
    assert m.command("radio set sync 0123456789abcdef01", 0) == ["invalid_param"]


def test_sys_reset_restores_defaults():
    m, _ = configured()
    assert m.command("radio get sf", 0) == ["sf7"]
    assert m.command("sys reset", 5) == [VERSION_LINE]
    assert m.command("radio get sf", 5) == ["sf12"] and not m.on_air


@pytest.mark.parametrize("n_bytes", [0, 1, 12, 255])
def test_tx_on_air_goes_through_the_channel_and_ends_with_the_channels_done(n_bytes):
    m, port = configured()
    line = "radio tx " + "a5" * n_bytes
    assert m.command(line, 1000) == ["ok"]
    assert port.calls[-1] == ("tx", b"\xa5" * n_bytes, 1000)
    assert m.next_deadline_us() is None           # the Channel, not the module, ends it
    assert m.command("radio tx 00", 1001) == ["busy"]
    assert m.command("radio rx 0", 1001) == ["busy"]
    assert m.command("radio set sf sf8", 1001) == ["busy"]
    assert m.command("radio get sf", 1001) == ["sf7"]
    end = 1000 + PROFILE.airtime_us(n_bytes)
    assert m.deliver(RadioTxDone(stamp_us=end, ok=True), end) == ["radio_tx_ok"]
    assert m.command("radio tx 00", end) == ["ok"]
    assert m.deliver(RadioTxDone(stamp_us=end + 5, ok=False), end + 5) == ["radio_err"]


def test_bare_radio_tx_sends_an_empty_frame():
    m, port = configured()
    assert m.command("radio tx", 0) == ["ok"] and port.calls[-1] == ("tx", b"", 0)


def test_tx_of_256_bytes_is_invalid_and_sends_nothing():
    m, port = configured()
    n_calls = len(port.calls)
    assert m.command("radio tx " + "00" * 256, 0) == ["invalid_param"]
    assert len(port.calls) == n_calls and m.state == "idle"


def test_channel_refusal_is_invalid_param():
    m, port = configured()
    port.refuse = True
    assert m.command("radio tx 0102", 0) == ["invalid_param"] and m.state == "idle"


def test_rx_gives_one_frame_with_two_spaces_and_upper_case_hex_then_stops():
    m, port = configured()
    assert m.command("radio rx 0", 10) == ["ok"]
    assert port.calls[-1] == ("listen", True, 10)
    assert m.command("radio tx 00", 11) == ["busy"]
    assert m.command("radio set freq 868100000", 11) == ["busy"]
    frame = RadioRxFrame(stamp_us=500, payload=b"\x01\xab\xff", rssi_dbm=-97.6, snr_db=-7.4)
    assert m.deliver(frame, 500) == ["radio_rx  01ABFF"]
    assert m.deliver(frame, 501) == []               # one-shot: the next frame is not taken
    assert m.command("radio get rssi", 502) == ["-98"]
    assert m.command("radio get snr", 502) == ["-7"]
    assert m.command("radio tx 00", 503) == ["ok"]


def test_snr_is_clamped_to_the_modules_range():
    m, _ = configured()
    m.command("radio rx 0", 0)
    m.deliver(RadioRxFrame(stamp_us=1, payload=b"", rssi_dbm=-20.0, snr_db=300.0), 1)
    assert m.command("radio get snr", 1) == ["127"]
    m.command("radio rx 0", 1)
    m.deliver(RadioRxFrame(stamp_us=2, payload=b"", rssi_dbm=-20.0, snr_db=-300.0), 2)
    assert m.command("radio get snr", 2) == ["-128"]


def test_rxstop_stops_listening_and_answers_ok():
    m, port = configured()
    m.command("radio rx 0", 10)
    assert m.command("radio rxstop", 20) == ["ok"]
    assert port.calls[-1] == ("listen", False, 20)
    assert m.deliver(RadioRxFrame(stamp_us=30, payload=b"x", rssi_dbm=-50, snr_db=5), 30) == []
    assert m.command("radio rxstop", 40) == ["ok"]   # idle: nothing to stop, still ok


def test_watchdog_ends_reception_with_radio_err():
    m, port = configured()
    assert m.command("radio set wdt 15000", 0) == ["ok"]
    assert m.command("radio rx 0", 1_000) == ["ok"]
    assert m.next_deadline_us() == 15_001_000
    assert m.expire(15_000_999) == []
    assert m.expire(15_001_000) == ["radio_err"]
    assert port.calls[-1] == ("listen", False, 15_001_000)
    assert m.state == "idle"


def test_rx_window_closes_after_n_symbols():
    m, _ = configured()
    assert m.command("radio rx 10", 0) == ["ok"]
    assert m.next_deadline_us() == 10 * 1024          # SF7/BW125: 1.024 ms per symbol
    assert m.expire(10 * 1024) == ["radio_err"]


def test_tx_longer_than_the_watchdog_fails_without_reaching_the_air():
    m, port = configured()
    m.command("radio set wdt 10", 0)                  # 10 ms, shorter than any 255-byte frame
    n_calls = len(port.calls)
    assert m.command("radio tx " + "00" * 255, 0) == ["ok"]
    assert len(port.calls) == n_calls
    assert m.expire(10_000) == ["radio_err"]


@pytest.mark.parametrize("setting", ["radio set freq 868100000", "radio set sf sf9", "radio set bw 250",
                                     "radio set cr 4/6", "radio set crc off", "radio set sync 34",
                                     "radio set prlen 12", "radio set iqi on", "radio set mod fsk",
                                     "radio set pwr 3"])
def test_every_air_setting_goes_to_the_channel_with_the_frame(setting):
    m, port = configured()
    assert m.command(setting, 0) == ["ok"]
    assert m.command("radio tx 0102030405060708090a0b0c", 100) == ["ok"]
    air, power_dbm = port.tx_air[-1]
    assert air == m.settings.air_interface()
    assert power_dbm == m.settings.pwr_dbm             # no front-end gain on this board
    changed = (air != PROFILE.air_interface(), power_dbm != 15)
    assert any(changed)
    assert m.next_deadline_us() is None                # the Channel ends the frame
    assert m.command("radio rx 0", 100) == ["busy"]
    assert m.deliver(RadioTxDone(stamp_us=200, ok=True), 200) == ["radio_tx_ok"]
    assert m.command("radio rx 0", 200) == ["ok"] and port.listen_air[-1] == air


def test_air_interface_of_the_settings():
    s = RadioSettings()                                # power-on: 868.1 MHz SF12 sync 34
    air = s.air_interface()
    assert (air.freq_hz, air.modulation.sf, air.sync_word, air.iq_inverted, air.is_lora) == (
        868_100_000, 12, 0x34, False, True)
    fsk = RadioSettings(mod="fsk", sync_hex="C194C1", bitrate_bps=100_000, rxbw_khz="62.5").air_interface()
    assert (fsk.is_lora, fsk.fsk_bitrate_bps, fsk.fsk_sync_bytes, fsk.fsk_rx_bw_hz, fsk.sync_word) == (
        False, 100_000, 3, 62_500, 0xC194C1)
    # FSK: 8 preamble bytes, 3 sync, 1 length, 12 payload, 2 CRC = 26 bytes at 100 kb/s
    assert fsk.airtime_us(12) == 26 * 8 * 10


def test_without_a_channel_the_modem_times_its_own_frames():
    m = Rn2483(0)
    m.command("radio set sf sf7", 0)
    assert m.command("radio tx 0102030405060708090a0b0c", 100) == ["ok"]
    end = 100 + m.settings.airtime_us(12)
    assert m.next_deadline_us() == end
    assert m.expire(end - 1) == [] and m.expire(end) == ["radio_tx_ok"]


def test_radio_cw_keeps_the_radio_busy_until_switched_off():
    m, port = configured()
    n_calls = len(port.calls)
    assert m.command("radio cw on", 0) == ["ok"]
    assert m.command("radio tx 00", 1) == ["busy"] and m.command("radio set sf sf8", 1) == ["busy"]
    assert m.command("radio cw off", 2) == ["ok"] and m.command("radio tx 00", 3) == ["ok"]
    assert m.command("radio cw on", 4) == ["busy"]     # transmitting
    assert port.calls[n_calls:] == [("tx", b"\x00", 3)]


def test_sys_sleep_answers_when_it_wakes_and_hears_nothing_meanwhile():
    m, _ = configured()
    assert m.command("sys sleep 100", 1_000) == []
    assert m.next_deadline_us() == 101_000
    assert m.command("sys get ver", 50_000) == []      # the UART is not listened to
    assert m.expire(100_999) == [] and m.expire(101_000) == ["ok"]
    assert m.command("radio get sf", 101_000) == ["sf7"]


def test_nvm_pins_and_factory_reset():
    m, _ = configured()
    assert m.command("sys get nvm 300", 0) == ["FF"]
    assert m.command("sys set nvm 3ff a5", 0) == ["ok"] and m.command("sys get nvm 3FF", 0) == ["A5"]
    assert m.command("sys set pinmode GPIO5 digout", 0) == ["ok"]
    assert m.command("sys set pindig GPIO5 1", 0) == ["ok"] and m.command("sys get pindig GPIO5", 0) == ["1"]
    assert m.command("sys set pinmode GPIO0 ana", 0) == ["ok"] and m.command("sys get pinana GPIO0", 0) == ["0"]
    assert m.command("sys get vdd", 0) == ["3300"]
    assert m.command("sys reset", 0) == [VERSION_LINE]
    assert m.command("sys get nvm 3FF", 0) == ["A5"]     # EEPROM survives a reset...
    assert m.command("radio get sf", 0) == ["sf12"]
    assert m.command("sys factoryRESET", 0) == [VERSION_LINE]
    assert m.command("sys get nvm 3FF", 0) == ["FF"]     # ...not a factory reset
    assert m.command("sys get pindig GPIO5", 0) == ["0"]


def test_erase_fw_leaves_the_command_set():
    m, _ = configured()
    assert m.command("sys eraseFW", 0) == []
    assert m.command("sys reset", 1) == [] and m.command("sys get ver", 2) == []


def test_rn2903_tunes_the_us_band_and_its_power_steps():
    m = Rn2483(0, model=P.RN2903)
    assert m.command("radio set freq 902000000", 0) == ["ok"]
    assert m.command("radio set freq 928000000", 0) == ["ok"]
    assert m.command("radio set freq 868100000", 0) == ["invalid_param"]
    assert m.command("radio set freq 928000001", 0) == ["invalid_param"]
    assert m.command("radio set pwr 20", 0) == ["ok"] and m.command("radio get pwr", 0) == ["20"]
    for bad in ("1", "13", "18", "19", "21"):
        assert m.command(f"radio set pwr {bad}", 0) == ["invalid_param"], bad
    assert Rn2483(0).command("radio set freq 915000000", 0) == ["invalid_param"]


def test_airtime_follows_the_modems_settings():
    s = RadioSettings(sf=9, bw_khz=125, cr=1, preamble_symbols=8, crc_on=True)
    assert s.airtime_us(12) == 144_384                # DESIGN.md golden value
    s = RadioSettings(sf=7, bw_khz=500)
    assert s.airtime_us(12) == 10_304
    s = RadioSettings(sf=12, cr=4, preamble_symbols=12, crc_on=False)
    assert s.airtime_us(40) == time_on_air_us(40, LoraModulation(12, 125_000, 4, 12, False))


def test_sys_reset_during_reception_stops_listening():
    m, port = configured()
    m.command("radio rx 0", 5)
    m.command("sys reset", 6)
    assert port.calls[-1] == ("listen", False, 6) and m.state == "idle"


def test_sys_reset_during_transmission_drops_the_late_done():
    m, port = configured()
    m.command("radio tx 00", 0)
    m.command("sys reset", 1)
    assert m.deliver(RadioTxDone(stamp_us=50_000, ok=True), 50_000) == []


@settings(max_examples=300, deadline=None)
@given(st.text(max_size=80))
def test_any_text_gets_exactly_one_answer_and_never_raises(line):
    m = Rn2483(1, FakePort(PROFILE), on_air_settings(PROFILE))
    out = m.command(line, 0)
    if line.startswith(("sys sleep ", "sys eraseFW")) and out == []:
        return                                          # the two commands answered later or never
    assert len(out) == 1 and all("\n" not in x and "\r" not in x for x in out)


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=255))
def test_any_payload_round_trips_through_radio_rx(payload):
    m, port = configured()
    assert m.command("radio tx " + payload.hex(), 0) == ["ok"]
    assert port.calls[-1][1] == payload
    rx, _ = configured(node_id=4)
    rx.command("radio rx 0", 0)
    [line] = rx.deliver(RadioRxFrame(stamp_us=1, payload=payload, rssi_dbm=-80, snr_db=3), 1)
    assert line.startswith("radio_rx  ") and bytes.fromhex(line[10:]) == payload


def test_ideal_link_prints_frames_whatever_the_modem_is_doing():
    ideal = PROFILES["ideal-100Bps"]
    port = FakePort(ideal)
    m = Rn2483(0, port, on_air_settings(ideal), ideal_link=True)
    for cmd in P.network_config_commands(ideal, P.RN2483):
        m.command(cmd, 0)
    assert m.on_air
    frame = RadioRxFrame(stamp_us=5, payload=b"\x01", rssi_dbm=-40.0, snr_db=20.0)
    assert m.deliver(frame, 5) == ["radio_rx  01"] and m.state == "idle"
    m.command("radio tx 00", 6)
    assert m.deliver(frame, 7) == ["radio_rx  01"] and m.state == "tx"
    # A real link keeps the module's rule: outside `radio rx` nothing is printed.
    real, _ = configured()
    assert real.deliver(frame, 5) == []


def test_profiles_outside_the_modules_bands_are_refused():
    vhf = RadioProfile("vhf", 169_400_000, "x", None, LoraModulation(7, 125_000), 255, 10.0)
    with pytest.raises(ValueError, match="vhf.*169400000 Hz is outside the bands of the RN2483"):
        on_air_settings(vhf)
    with pytest.raises(ValueError, match="us915.*outside the RN2483's bands"):
        P.network_config_commands(PROFILES["us915"], P.RN2483)
    for name in ("eu868-g1", "eu868-g3", "eu868-g3-bw250", "ideal-100Bps", "us915"):
        assert on_air_settings(PROFILES[name]).freq_hz == PROFILES[name].freq_hz
    assert on_air_settings(PROFILES["us915"]).pwr_dbm == 20           # the RN2903's top step
    assert on_air_settings(PROFILES["eu868-g3"]).pwr_dbm == 15        # the RN2483's top step


@settings(max_examples=300, deadline=None)
@given(st.text(max_size=80), st.binary(max_size=255))
def test_the_drivers_line_parser_never_raises_and_reads_what_the_module_prints(text, payload):
    assert P.parse_rx_line(text) is None or text.startswith("radio_rx ")
    P.is_async_line(text)
    rx, _ = configured(node_id=4)
    rx.command("radio rx 0", 0)
    [line] = rx.deliver(RadioRxFrame(stamp_us=1, payload=payload, rssi_dbm=-80, snr_db=3), 1)
    assert P.is_async_line(line) and P.parse_rx_line(line) == payload


def test_network_config_uses_each_modules_power_steps():
    assert "radio set pwr 15" in P.network_config_commands(PROFILES["eu868-g3"], P.RN2483)   # 27 dBm asked
    assert "radio set pwr 14" in P.network_config_commands(PROFILES["eu868-g1"], P.RN2483)
    assert "radio set pwr 20" in P.network_config_commands(PROFILES["us915"], P.RN2903)
    assert P.model_of_version("RN2903 1.0.5 Nov 06 2018 10:45:27") is P.RN2903
    assert P.model_of_version("RN2483X") is None and P.model_for_freq(433_050_000) is P.RN2483
