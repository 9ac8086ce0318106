"""`--set NAME=VALUE`: explorer parameters changed from the command line, typed and checked,
applied to a run or a sweep, and recorded with the results (so a sweep does not mix trials
of different parameters when it resumes)."""
import json

import pytest

from firmware.params import ExplorationParams
from host_tools.cli import main
from host_tools.mission import MissionConfig
from host_tools.overrides import describe, params_with, parse_overrides
from host_tools.sweep import PARTIAL_NAME, trial_key


def test_values_are_typed_by_the_parameter_sorted_and_the_last_one_counts():
    got = parse_overrides(["target_seen_within_m=1.5", "presence_holds_target=true", "info_rays=32",
                           "presence_holds_target = off"])
    assert got == (("info_rays", 32), ("presence_holds_target", False), ("target_seen_within_m", 1.5))
    assert isinstance(got[0][1], int) and isinstance(got[2][1], float)
    p = params_with(got)
    assert (p.info_rays, p.presence_holds_target, p.target_seen_within_m) == (32, False, 1.5)
    assert p.d_cam_m == ExplorationParams().d_cam_m
    assert describe(got) == "info_rays=32, presence_holds_target=false, target_seen_within_m=1.5"
    assert parse_overrides([]) == () and params_with(()) == ExplorationParams()


@pytest.mark.parametrize("item, says", [
    ("target_seen_within_m", "expected NAME=VALUE"),
    ("=1.5", "expected NAME=VALUE"),
    ("no_such_thing=1", "no parameter 'no_such_thing'"),
    ("info_rays=1.5", "info_rays takes a int, not '1.5'"),
    ("presence_holds_target=maybe", "presence_holds_target takes a bool, not 'maybe'"),
    ("d_cam_m=far", "d_cam_m takes a float, not 'far'"),
    ("d_cam_m=nan", "must be a finite number"),
])
def test_bad_settings_say_which_and_why(item, says):
    with pytest.raises(ValueError, match=f"--set '{item}'") as err:
        parse_overrides([item])
    assert says in str(err.value)


def test_run_applies_and_reports_them_and_rejects_bad_ones(capsys):
    argv = ["run", "--map", "cave:4:40x40", "--max-sim-s", "20", "--json", "--quiet"]
    assert main(argv) == 0
    plain = json.loads(capsys.readouterr().out)
    assert main(argv + ["--set", "d_cam_m=3.0"]) == 0
    changed = json.loads(capsys.readouterr().out)
    assert plain["params_overrides"] == {} and changed["params_overrides"] == {"d_cam_m": 3.0}
    assert changed["trajectory_sha256"] != plain["trajectory_sha256"]
    assert main(argv + ["--set", "d_cam_m"]) == 2
    assert "lorascout run: --set 'd_cam_m': expected NAME=VALUE" in capsys.readouterr().err


def test_a_sweep_records_them_and_resumes_only_trials_with_the_same(tmp_path, capsys):
    argv = ["sweep", "--maps", "cave:4:40x40", "--strategies", "minpos", "--robots", "2", "--seeds", "1",
            "--max-sim-s", "20", "--jobs", "1", "--quiet", "--out", str(tmp_path), "--resume"]
    assert main(argv) == 0
    capsys.readouterr()
    variant = argv + ["--set", "target_seen_within_m=1.5", "--set", "presence_holds_target=1"]
    assert main(variant) == 0
    out, err = capsys.readouterr()
    assert "resuming: 0 trials done earlier, 1 to run" in err   # the default trial is not this one
    assert "explorer parameters changed: presence_holds_target=true, target_seen_within_m=1.5" in out
    reports = [json.loads(line) for line in (tmp_path / PARTIAL_NAME).read_text().splitlines()]
    assert [r["params_overrides"] for r in reports] == [
        {}, {"presence_holds_target": True, "target_seen_within_m": 1.5}]
    tables = json.loads((tmp_path / "tables.json").read_text())
    assert tables["spec"]["overrides"] == [["presence_holds_target", True], ["target_seen_within_m", 1.5]]
    assert tables["table3_p_max"][0]["minpos"]["trials"] == 1
    assert main(variant) == 0
    assert "resuming: 1 trials done earlier, 0 to run" in capsys.readouterr().err
    assert main(argv + ["--set", "nope=1"]) == 2
    assert "lorascout sweep: --set 'nope=1': the explorer has no parameter 'nope'" in capsys.readouterr().err


def test_reports_from_before_overrides_existed_count_as_the_defaults():
    cfg = MissionConfig(map_spec="cave:4:40x40", robots=2, seed=0, max_sim_s=20.0, strategy="minpos")
    old = {"map_spec": "cave:4:40x40", "strategy": "minpos", "radio": cfg.radio, "seed": 0, "robots": 2,
           "max_sim_s": 20.0}
    assert trial_key(old) == trial_key(cfg)
    assert trial_key(old) != trial_key(cfg, (("d_cam_m", 3.0),))
