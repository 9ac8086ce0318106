"""Issue 27, one test per defect: output paths are checked before the work, results are
written atomically, JSON is strict, inspector input is bounded, and Ctrl-C ends a run or a
sweep with a partial report and exit status 130."""
import json
import math
import os
import signal
import socket
import subprocess
import sys
import threading
import time

import pytest

from firmware.comms.frame import encode_frame
from host_tools.capture import CaptureError, CaptureWriter, read_capture
from host_tools.safe_io import strict_dumps, strict_loads
from radio_sim.air_log import RECEIVED, AirFrame, Reception
from tests.conftest import REPO, tree_state
from tests.doubles import deliverable_sigint

TOPO = dict(sender_id=3, x_cm=10, y_cm=-20, z_cm=0, presence=1, e_inf_code=77, info_version=0)
LORASCOUT = [sys.executable, "-c", "import sys; from host_tools.cli import main; sys.exit(main())"]


def _capture(path, rows=2, rssi=-87.25, bw_hz=125_000):
    with CaptureWriter(path, "eu868-g3") as w:
        for k in range(rows):
            w.write(AirFrame(1_000 + k * 100_000, 42_216 + k * 100_000, 3, 869_525_000, 7, bw_hz,
                             encode_frame(3, k, [("topo", TOPO)]), (Reception(1, rssi, 6.5, RECEIVED),)))
    return path


def _strict(text: str):
    return json.loads(text, parse_constant=lambda c: pytest.fail(f"non-strict JSON constant {c}"))


# ---- output paths are checked before the work ----------------------------------------------

def test_run_refuses_an_output_it_could_not_write_before_the_mission(tmp_path, cli):
    (tmp_path / "out" / "mission.json").mkdir(parents=True)       # a folder where the report goes
    t0 = time.monotonic()
    r = cli("run", "--map", "cave:4:40x40", "--max-sim-s", "3600", "--json", "--quiet", "--out", tmp_path / "out")
    assert r.code == 2 and "mission.json: is a folder, not a file" in r.err and r.out == ""
    assert time.monotonic() - t0 < 5, "refused before the mission, not after"
    (tmp_path / "plain").write_text("x")
    r = cli("run", "--out", tmp_path / "plain" / "sub")
    assert r.code == 2 and "plain is not a folder" in r.err


def test_map_png_is_checked_before_the_analysis(tmp_path, cli):
    (tmp_path / "old.png").write_bytes(b"old picture")
    r = cli("map", "--map", "cave:4:40x40", "--png", tmp_path, "--quiet")
    assert r.code == 2 and "argument --png" in r.err and "is a folder" in r.err
    r = cli("map", "--map", "cave:4:40x40", "--png", tmp_path / "old.png", "--stride-m", "2", "--json", "--quiet")
    assert r.code == 0
    assert (tmp_path / "old.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"   # replaced whole, by a PNG
    assert [p.name for p in tmp_path.iterdir()] == ["old.png"], "no temporary file left behind"


def test_a_run_writes_its_report_atomically_and_prints_it_first(tmp_path, cli):
    r = cli("run", "--map", "cave:4:40x40", "--max-sim-s", "5", "--json", "--quiet", "--out", tmp_path)
    assert r.code == 0
    printed = _strict(r.out)
    written = _strict((tmp_path / "mission.json").read_text())
    assert printed["trajectory_sha256"] == written["trajectory_sha256"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mission.json", "mission.png"]


# ---- inspect: pcap, strict JSON, bounded input, exact lines ----------------------------------

def test_inspect_pcap_leaves_an_existing_pcap_when_a_row_cannot_be_written(tmp_path, cli):
    good = _capture(tmp_path / "good.jsonl")
    assert cli("inspect", good, "--pcap", tmp_path / "out.pcap", "--summary").code == 0
    before = (tmp_path / "out.pcap").read_bytes()
    assert len(before) > 24
    bad = tmp_path / "bad.jsonl"
    lines = good.read_text().splitlines()
    row = json.loads(lines[2])
    row["bw_hz"] = 100_000
    bad.write_text("\n".join(lines[:2] + [json.dumps(row)]) + "\n")
    r = cli("inspect", bad, "--pcap", tmp_path / "out.pcap", "--summary")
    assert r.code == 1 and "Traceback" not in r.err
    assert f"{bad}:3: field 'bw_hz': bandwidth 100000 Hz is not a multiple of 125 kHz" in r.err
    assert (tmp_path / "out.pcap").read_bytes() == before


def test_inspect_json_is_strict(tmp_path, cli):
    path = _capture(tmp_path / "nan.jsonl", rssi=math.nan)      # a modem's garbled RSSI: written as null
    assert '"rx": [[1, null, 6.5, "received"]]' in path.read_text()
    header, frames = read_capture(path)
    assert math.isnan(next(frames).receptions[0].rssi_dbm)
    r = cli("inspect", path, "--json")
    assert r.code == 0
    doc = _strict(r.out)
    assert doc["frames"][0]["receptions"][0]["rssi_dbm"] is None
    assert doc["null_reasons"]["frames[0].receptions[0].rssi_dbm"] == "nan is not a number JSON can hold"
    # NaN and Infinity in a capture are refused on input, naming line and field.
    text = path.read_text().replace("null", "NaN", 1)
    path.write_text(text)
    r = cli("inspect", path, "--json")
    assert r.code == 1 and f"{path}:2: not strict JSON (NaN is not a number JSON can hold)" in r.err
    with pytest.raises(ValueError):
        strict_loads('{"a": Infinity}')
    assert strict_dumps({"a": math.inf}) == '{"a": null, "null_reasons": {"a": "inf is not a number JSON can hold"}}'


def test_inspect_dev_zero_ends_with_an_error():
    done = subprocess.run(LORASCOUT + ["inspect", "/dev/zero"], capture_output=True, text=True, timeout=10,
                          cwd=REPO)
    assert done.returncode == 1
    assert "/dev/zero:1: line longer than 1048576 bytes" in done.stderr and "Traceback" not in done.stderr


def test_deep_nesting_and_bad_bytes_give_errors_with_exact_lines(tmp_path):
    good = _capture(tmp_path / "g.jsonl", rows=5).read_text().splitlines()
    deep = tmp_path / "deep.jsonl"
    deep.write_text("\n".join(good[:3]) + "\n" + "[" * 200_000 + "\n")
    with pytest.raises(CaptureError, match=r"deep.jsonl:4: nested too deeply"):
        list(read_capture(deep)[1])
    raw = tmp_path / "raw.jsonl"
    raw.write_bytes(("\n".join(good[:5]) + "\n").encode() + b'{"start_us": 1, \xff}\n' + good[5].encode() + b"\n")
    with pytest.raises(CaptureError, match=r"raw.jsonl:6: not UTF-8 text"):
        list(read_capture(raw)[1])
    header_only = tmp_path / "h.jsonl"
    header_only.write_text("[" * 100_000)
    with pytest.raises(CaptureError, match=r"h.jsonl:1: header is nested too deeply"):
        read_capture(header_only)


def test_a_failed_mission_leaves_an_earlier_capture_alone(tmp_path, cli):
    cap = tmp_path / "air.jsonl"
    cap.write_text("earlier capture\n")
    r = cli("run", "--map", "cave:4:40x40", "--start", "0.1,0.1", "--capture", cap, "--quiet")
    assert r.code == 2 and "not on a free cell" in r.err
    assert cap.read_text() == "earlier capture\n"
    assert [p.name for p in tmp_path.iterdir()] == ["air.jsonl"]


# ---- Ctrl-C ----------------------------------------------------------------------------------

def test_ctrl_c_ends_a_run_with_a_partial_report_and_status_130(tmp_path, cli, monkeypatch, sigint_as_in_a_terminal):
    import host_tools.cmd_run as cmd_run
    from host_tools.progress import progress_bar

    def bar_that_presses_ctrl_c(total, desc, unit, quiet):
        bar = progress_bar(total, desc, unit, True)
        sim_s = [0.0]

        def update_then_interrupt(n):
            sim_s[0] += n
            if sim_s[0] >= 10:
                signal.raise_signal(signal.SIGINT)     # what the terminal sends
        bar.update = update_then_interrupt
        return bar

    monkeypatch.setattr(cmd_run, "progress_bar", bar_that_presses_ctrl_c)
    r = cli("run", "--map", "cave:4:40x40", "--max-sim-s", "3600", "--json", "--out", tmp_path)
    assert r.code == 130, r
    report = _strict(r.out)
    assert report["termination"] == "interrupted" and 10 <= report["t_total_s"] < 12
    assert _strict((tmp_path / "mission.json").read_text())["termination"] == "interrupted"
    assert "interrupted after" in r.err and "Traceback" not in r.err
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_ctrl_c_stops_a_sweep_and_keeps_every_finished_trial(tmp_path):
    out = tmp_path / "grid"
    argv = ["sweep", "--maps", "cave:4:40x40", "--strategies", "minpos", "--robots", "2", "--seeds", "6",
            "--max-sim-s", "20", "--jobs", "2", "--out", str(out)]
    proc = subprocess.Popen(LORASCOUT + argv, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=deliverable_sigint,
                            env={**os.environ, "NUMBA_NUM_THREADS": "1"})
    err_lines = []
    for line in proc.stderr:                        # one line per finished trial (no terminal)
        err_lines.append(line)
        if line.startswith("trial 1/6"):
            break
    proc.send_signal(signal.SIGINT)
    out_text, rest = proc.communicate(timeout=60)
    err = "".join(err_lines) + rest
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "INTERRUPTED:" in err and "--resume" in err
    kept = [json.loads(line) for line in (out / "trials.partial.jsonl").read_text().splitlines()]
    finished = int(err.split("INTERRUPTED: ")[1].split(" of")[0])
    assert 1 <= len(kept) == finished < 6
    tables = json.loads((out / "tables.json").read_text())
    assert tables["interrupted"].startswith("INTERRUPTED") and "INTERRUPTED" in out_text
    assert tables["table3_p_max"][0]["minpos"]["trials"] == len(kept)
    # Resuming runs only the rest.
    done = subprocess.run(LORASCOUT + argv + ["--resume", "--quiet"], cwd=REPO, capture_output=True, text=True,
                          timeout=600, env={**os.environ, "NUMBA_NUM_THREADS": "1"})
    assert done.returncode == 0, done.stderr
    assert f"resuming: {len(kept)} trials done earlier, {6 - len(kept)} to run" in done.stderr


# ---- sweep: --overwrite, --ray ---------------------------------------------------------------

def test_overwrite_starts_again_and_keeps_the_earlier_trials_file(tmp_path, cli):
    argv = ["sweep", "--maps", "cave:4:40x40", "--strategies", "minpos", "--robots", "2", "--seeds", "1",
            "--max-sim-s", "20", "--jobs", "1", "--quiet", "--out", tmp_path]
    assert cli(*argv).code == 0
    first = (tmp_path / "trials.partial.jsonl").read_text()
    before = tree_state(tmp_path)
    r = cli(*argv)
    assert r.code == 2 and "already holds a grid (1 trials in" in r.err and tree_state(tmp_path) == before
    assert cli(*argv, "--overwrite").code == 0
    assert (tmp_path / "trials.partial.jsonl.old").read_text() == first
    assert len((tmp_path / "trials.partial.jsonl").read_text().splitlines()) == 1
    assert not [p.name for p in tmp_path.iterdir() if p.name.startswith(".")], "no temporary files left"


def test_sweep_ray_to_an_address_that_never_answers_fails_in_bounded_time(tmp_path, cli):
    pytest.importorskip("ray")
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(8)
    accepted = []
    stop = threading.Event()

    def accept_and_say_nothing():
        server.settimeout(0.2)
        while not stop.is_set():
            try:
                accepted.append(server.accept()[0])
            except OSError:
                pass
    t = threading.Thread(target=accept_and_say_nothing, daemon=True)
    t.start()
    try:
        t0 = time.monotonic()
        r = cli("sweep", "--maps", "cave:4:40x40", "--ray", f"127.0.0.1:{server.getsockname()[1]}", "--out",
                tmp_path / "out")
        took = time.monotonic() - t0
    finally:
        stop.set()
        t.join()
        for c in accepted:
            c.close()
        server.close()
    assert r.code == 2 and ("no Ray cluster answered within 6 s" in r.err or "cannot join the Ray cluster" in r.err), r
    assert took < 10
    assert not (tmp_path / "out").exists(), "nothing was created"


# ---- bench from any folder -------------------------------------------------------------------

def test_bench_finds_the_shared_maps_from_any_folder(tmp_path, cli, monkeypatch, shared_maps):
    monkeypatch.chdir(tmp_path)
    r = cli("bench", "--scenario", "intel-1robot", "--sim-s", "1", "--warmup-sim-s", "0", "--json", "--quiet")
    assert r.code == 0, r
    assert _strict(r.out)["map"] == "intel.yaml"
