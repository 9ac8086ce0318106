"""The inspector's statistics agree with the link layers' own counters on a small network,
and `lorascout inspect` prints, exports and scripts what the capture holds."""
import json

import pytest

from firmware.comms.frame import decode_frame, encode_frame
from firmware.comms.link import LinkLayer
from firmware.schemes import all_dialects
from firmware.schemes.bayer_faigl.records import DIALECT as BF
from hal.lora import profile
from hal.samples import RadioRxFrame
from host_tools import cli
from host_tools.capture import CaptureWriter, read_capture
from host_tools.cmd_inspect import _max_window_use, sender_stats, seq_gaps
from host_tools.pcap import parse_loratap_header, read_pcap
from radio_sim.air_log import HALF_DUPLEX, INJECTED_LOSS, RECEIVED, AirFrame, Reception


class Radio:
    def __init__(self, prof):
        self.prof, self.now_us, self.busy_until_us, self.inbox, self.out = prof, 0, 0, [], []

    def transmit(self, payload):
        if self.busy():
            return False
        self.out.append(bytes(payload))
        self.busy_until_us = self.now_us + self.prof.airtime_us(len(payload))
        return True

    def busy(self):
        return self.now_us < self.busy_until_us

    def poll(self):
        ev = tuple(e for e in self.inbox if e.stamp_us <= self.now_us)
        self.inbox = [e for e in self.inbox if e.stamp_us > self.now_us]
        return ev


def simulate(prof, n_nodes=3, seconds=120, lose_every=5):
    """Every node sends a pose each second and a vertex every 3 s; receiver 2 loses every
    `lose_every`-th frame it would have heard (injected), receivers that transmit miss frames."""
    links = [LinkLayer(i, prof, dialect=BF) for i in range(n_nodes)]
    radios = [Radio(prof) for _ in range(n_nodes)]
    air, heard_by_2 = [], 0
    truth_lost = {}          # (origin, receiver) -> seqs lost
    for t_ms in range(0, seconds * 1000, 50):
        now = t_ms * 1000
        for i, (link, radio) in enumerate(zip(links, radios)):
            if t_ms % 1000 == 150 * i:
                link.enqueue("pose", dict(sender_id=i, x_cm=t_ms // 10, y_cm=i, yaw_cdeg=0, speed_cmps=10,
                                          exploring=1, done=0, returning=0, vertex_count=i), key="pose")
            if t_ms % 3000 == 50 * i:
                link.enqueue("topo", dict(sender_id=i, x_cm=t_ms, y_cm=0, z_cm=0, presence=1, e_inf_code=3, info_version=0))
            radio.now_us = now
            k = len(radio.out)
            link.service(now, radio)
            if len(radio.out) > k:
                payload = radio.out[-1]
                end = radio.busy_until_us
                rx = []
                for j, other in enumerate(radios):
                    if j == i:
                        continue
                    fate = RECEIVED
                    if other.busy_until_us > now:
                        fate = HALF_DUPLEX
                    elif j == 2:
                        heard_by_2 += 1
                        if heard_by_2 % lose_every == 0:
                            fate = INJECTED_LOSS
                    if fate == RECEIVED:
                        other.inbox.append(RadioRxFrame(end, payload, -90.0 - j, 5.0))
                    else:
                        truth_lost.setdefault((i, j), []).append(decode_frame(payload).frame.seq)
                    rx.append(Reception(j, -90.0 - j, 5.0, fate))
                air.append(AirFrame(now, end, i, prof.freq_hz, prof.modulation.sf, prof.modulation.bw_hz,
                                    payload, tuple(rx)))
    return links, air, truth_lost


@pytest.fixture(scope="module")
def network():
    prof = profile("eu868-g3")
    return prof, *simulate(prof)


def test_stats_agree_with_link_counters(network, tmp_path):
    prof, links, air, truth_lost = network
    path = tmp_path / "net.jsonl"
    with CaptureWriter(path, prof.name) as w:
        for a in air:
            w.write(a)
    header, it = read_capture(path)
    stats = sender_stats(list(it), profile(header.profile))
    for link in links:
        c, st = link.counters, stats[link.node_id]
        assert st.frames == c["sent.frames"] > 0
        assert st.bytes == c["sent.bytes"]
        assert st.airtime_us_by_sub_band == {"g3": c["airtime_us.g3"]}
        assert st.reasons == {"ok": c["sent.frames"]}
        assert st.seq_lost_on_air == 0
        assert 0 < st.duty_cycle_max_by_sub_band["g3"] <= 0.10
        # what each receiver accepted, summed over originators, is its received.ok
        got = sum(stats[o].rx_by_receiver.get(link.node_id, {}).get("received", 0) for o in stats)
        assert got == c["received.ok"]
    for (origin, receiver), lost in truth_lost.items():
        heard = [s for s in range(stats[origin].frames) if s not in lost]
        # gaps show only between the first and the last frame a receiver heard
        assert stats[origin].rx_by_receiver[receiver] == {
            "received": len(heard), "lost": sum(1 for s in lost if heard[0] < s < heard[-1])}
    assert any(r == 2 for (_, r) in truth_lost)       # the injected loss happened


def test_rate_and_window_figures():
    prof = profile("eu868-g1")
    a = [AirFrame(t * 1_000_000, t * 1_000_000 + 100_000, 1, prof.freq_hz, 7, 125_000,
                  encode_frame(1, t if t < 5 else t + 2, [("topo", dict(sender_id=1, x_cm=0, y_cm=0, z_cm=0,
                                                                        presence=0, e_inf_code=0, info_version=0))]), ())
         for t in range(10)]
    st = sender_stats(a, prof)[1]
    assert st.frames == 10 and st.bytes == 220 and st.airtime_us == 1_000_000     # 22-byte frames
    assert st.duration_s == pytest.approx(9.1) and st.bytes_per_s == pytest.approx(220 / 9.1)
    assert st.peak_bytes_per_s_10s == pytest.approx(22.0)
    assert st.duty_cycle_max_by_sub_band == {"g1": pytest.approx(1_000_000 / 3_600_000_000)}
    assert st.duty_cycle_limit_by_sub_band == {"g1": 0.01}
    assert st.seq_lost_on_air == 2
    assert sender_stats(a[:1], None)[1].airtime_us_by_sub_band == {"g1": 100_000}   # EU table fallback


def test_max_window_matches_brute_force():
    iv = [(0, 5), (7, 9), (20, 30), (31, 32), (50, 51)]
    for w in (1, 3, 10, 15, 25, 60):
        brute = max(sum(max(0, min(e, end) - max(s, end - w)) for s, e in iv) for end in range(0, 80))
        assert _max_window_use(iv, w) == brute


def test_seq_gaps_rfc1982():
    assert seq_gaps([65534, 65535, 1, 2]) == 1
    assert seq_gaps([5, 5, 4, 6, 9]) == 2
    assert seq_gaps([]) == 0


def _capture(tmp_path, network):
    prof, _, air, _ = network
    path = tmp_path / "c.jsonl"
    bad = bytearray(air[3].payload)
    bad[8] ^= 0x04
    with CaptureWriter(path, prof.name) as w:
        for k, a in enumerate(air[:12]):
            w.write(a if k != 3 else AirFrame(a.start_us, a.end_us, a.sender_id, a.freq_hz, a.sf, a.bw_hz,
                                              bytes(bad), a.receptions))
    return path


def test_cli_text_marks_rejections_and_names_fields(tmp_path, network, capsys):
    path = _capture(tmp_path, network)
    assert cli.main(["inspect", str(path)]) == 0
    out = capsys.readouterr().out
    assert "profile eu868-g3, 12 frames" in out
    assert "REJECTED BAD_CRC" in out and "decode: ok=11, bad_crc=1" in out
    assert "core.pose          sender_id=0 x_cm=0 y_cm=0 yaw_cdeg=0 speed_cmps=10 exploring=1 (bool)" in out
    assert "dialect 1 bayer_faigl" in out and "bayer_faigl.topo" in out
    assert "per-sender statistics" in out and "g3:" in out and "/ 10 %" in out
    assert cli.main(["inspect", str(path), "--summary"]) == 0
    assert "REJECTED" not in capsys.readouterr().out


def test_cli_json_and_pcap(tmp_path, network, capsys):
    path = _capture(tmp_path, network)
    pcap = tmp_path / "c.pcap"
    assert cli.main(["inspect", str(path), "--json", "--pcap", str(pcap), "--pcap-mode", "per-receiver"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["reasons"]["bad_crc"] == 1 and len(doc["frames"]) == 12
    f0 = doc["frames"][0]
    assert f0["reason"] == "ok" and f0["records"][0]["type"] in ("pose", "topo")
    assert {(r["dialect"], r["type"]) for fr in doc["frames"] if fr["reason"] == "ok" for r in fr["records"]} == {
        ("core", "pose"), ("bayer_faigl", "topo")}
    assert doc["header"]["fingerprints"] == {n: f"0x{fp:04X}" for n, fp in all_dialects().fingerprints().items()}
    assert set(doc["senders"]) <= {"0", "1", "2"}
    n_rx = sum(1 for fr in doc["frames"] for r in fr["receptions"] if r["fate"] == "received")
    linktype, pkts = read_pcap(pcap)
    assert linktype == 270 and len(pkts) == n_rx
    assert parse_loratap_header(pkts[0][1])["sync_word"] == 0x12


def test_cli_errors_and_helpers(tmp_path, capsys):
    bad = tmp_path / "bad.jsonl"
    bad.write_text('{"format": "lorascout-capture", "version": 1, "profile": "eu868-g3"}\n{"start_us": 1}\n')
    assert cli.main(["inspect", str(bad)]) == 1
    err = capsys.readouterr().err
    assert f"{bad}:2: field 'end_us': missing" in err
    assert cli.main(["inspect"]) == 1 and "nothing to do" in capsys.readouterr().err
    lua = tmp_path / "x.lua"
    assert cli.main(["inspect", "--write-dissector", str(lua), "--schema"]) == 0
    out = capsys.readouterr().out
    assert "loratap.syncword" in lua.read_text() and "### `topo` (dialect 1, code 1" in out
    for d in all_dialects():
        assert f"## Dialect {d.id} `{d.name}` (fingerprint 0x{d.fingerprint:04X})" in out


def test_cli_warns_for_each_capture_dialect_it_will_fail_to_check(tmp_path, network, capsys):
    import dataclasses

    from firmware.comms.schema import CORE, SENDER, Dialect, DialectSet, RecordType
    prof, _, air, _ = network
    topo = BF.by_name["topo"]
    changed = Dialect(BF.id, BF.name, (dataclasses.replace(topo, doc="", fields=tuple(
        dataclasses.replace(f, hi=100) if f.name == "z_cm" else f for f in topo.fields)),))
    other = Dialect(9, "other", (RecordType(1, "blip", 1, (SENDER,)),))
    same, theirs = tmp_path / "same.jsonl", tmp_path / "theirs.jsonl"
    for path, dialects in ((same, None), (theirs, DialectSet([CORE, changed, other]))):
        with CaptureWriter(path, prof.name, dialects=dialects) as w:
            w.write(air[0])
    assert cli.main(["inspect", str(same), "--summary"]) == 0
    assert "warning" not in capsys.readouterr().err
    assert cli.main(["inspect", str(theirs), "--summary"]) == 0
    err = capsys.readouterr().err
    assert f"capture dialect 'bayer_faigl' fingerprint 0x{changed.fingerprint:04X} differs from ours " \
           f"0x{BF.fingerprint:04X}; its frames will fail the CRC" in err
    assert f"capture dialect 'other' (fingerprint 0x{other.fingerprint:04X}) is not one of ours" in err
    assert "'core'" not in err
