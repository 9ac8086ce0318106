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
    ("info_rays=1.5", "info_rays takes an int, not '1.5'"),
    ("presence_holds_target=maybe", "presence_holds_target takes a bool, not 'maybe'"),
    ("d_cam_m=far", "d_cam_m takes a float, not 'far'"),
    ("d_cam_m=nan", "d_cam_m = nan is outside the valid range 0.5 <= d_cam_m <= 100 m"),
    ("resolution_m=0", "resolution_m = 0.0 is outside the valid range 0.02 <= resolution_m <= 1 m"),
    ("info_rays=0", "info_rays = 0 is outside the valid range 1 <= info_rays <= 4096 rays"),
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
    with pytest.raises(SystemExit) as stop:
        main(argv + ["--set", "d_cam_m"])
    assert stop.value.code == 2
    assert "argument --set: 'd_cam_m': expected NAME=VALUE" in capsys.readouterr().err


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
    with pytest.raises(SystemExit) as stop:
        main(argv + ["--set", "nope=1"])
    assert stop.value.code == 2
    assert "argument --set: 'nope=1': the explorer has no parameter 'nope'" in capsys.readouterr().err


def test_reports_from_before_overrides_existed_count_as_the_defaults():
    cfg = MissionConfig(map_spec="cave:4:40x40", robots=2, seed=0, max_sim_s=20.0, strategy="minpos")
    old = {"map_spec": "cave:4:40x40", "strategy": "minpos", "radio": cfg.radio, "seed": 0, "robots": 2,
           "max_sim_s": 20.0}
    assert trial_key(old) == trial_key(cfg)
    assert trial_key(old) != trial_key(cfg, (("d_cam_m", 3.0),))


@pytest.mark.parametrize("items, says", [
    (["logodds_min=5"], "logodds_min = 5.0 is outside the valid range -1000 <= logodds_min < 0 log-odds"),
    (["logodds_max=0.1"], "logodds_occupied = 0.3 must be below logodds_max = 0.1"),
    (["logodds_min=-1", "logodds_free=-2"], "logodds_min = -1 must be below logodds_free = -2"),
    (["resolution_m=0.02", "d_local_m=100"], "window of 10000 x 10000 cells"),
    (["recenter_distance_m=30"], "recenter_distance_m = 30 must be below d_local_m = 20"),
    (["tight_passage_cost=0.5"], "tight_passage_cost = 0.5 must be 0 (no tight passages in ordinary plans) or at least 1"),
])
def test_parameters_are_checked_together_against_their_relations(items, says):
    with pytest.raises(ValueError, match="--set ") as err:
        parse_overrides(items)
    assert says in str(err.value)


def test_every_default_lies_in_its_declared_range():
    from firmware.params import check_params
    check_params(ExplorationParams())      # raises otherwise


def test_help_and_readme_list_every_parameter_from_the_declaration(cli):
    import dataclasses
    from pathlib import Path

    from host_tools.overrides import README_BLOCK, params_markdown
    from host_tools.readme_sync import markers

    from host_tools.overrides import scheme_fields, schemes_with_params

    names = [f.name for f in dataclasses.fields(ExplorationParams)]
    names += [f"{scheme}.{name}" for scheme in schemes_with_params() for name in scheme_fields(scheme)]
    assert "wiserx.tau_enabled" in names and "mrtopomap.nfa_max" in names
    for command in ("run", "sweep"):
        helped = cli(command, "--help")
        assert helped.code == 0
        for name in names:
            assert f" {name} " in helped.out, (command, name)
    assert "0.02 <= resolution_m <= 1 m, default 0.1: cell size of the local dense map" in helped.out
    readme = (Path(__file__).resolve().parent.parent / "README.md").read_text()
    begin, end = markers(README_BLOCK)
    block = readme[readme.index(begin):readme.index(end)]
    assert params_markdown() in block, "README's parameter table is stale: python -m host_tools.readme_sync"


# ---- a scheme's own parameters: --set SCHEME.NAME=VALUE ----------------------------------------

def test_scheme_settings_are_typed_by_the_declaration_and_reach_the_scheme():
    from firmware.schemes import build, params_of

    got = parse_overrides(["wiserx.tau_enabled=off", "wiserx.bearing_median_k=7", "wiserx.fill_rule=pts2",
                           "mrtopomap.nfa_max=0.001", "d_cam_m=3"])
    assert got == (("d_cam_m", 3.0), ("mrtopomap.nfa_max", 0.001), ("wiserx.bearing_median_k", 7),
                   ("wiserx.fill_rule", "pts2"), ("wiserx.tau_enabled", False))
    assert params_with(got) == params_with((("d_cam_m", 3.0),))      # the explorer's own take only theirs
    wiserx = params_of("wiserx:paper", got)
    assert (wiserx.tau_enabled, wiserx.bearing_median_k, wiserx.fill_rule) == (False, 7, "pts2")
    assert wiserx.hard_enabled and wiserx.kappa1_m == 5.0            # the variant's own defaults stay
    assert params_of("mrtopomap", got).nfa_max == 0.001
    assert params_of("bayer-faigl:minpos", got) is None              # no parameters, none named
    assert build("wiserx", got).params == wiserx.__class__(tau_enabled=False, bearing_median_k=7, fill_rule="pts2")
    assert build("wiserx").params.tau_enabled is True


@pytest.mark.parametrize("item, says", [
    ("wiserx.kappa1_m=-1", "wiserx.kappa1_m = -1.0 is outside the valid range 0 <= kappa1_m <= 1000 m"),
    ("wiserx.kappa1_m=nan", "wiserx.kappa1_m = nan is outside the valid range"),
    ("wiserx.bearing_median_k=2.5", "wiserx.bearing_median_k takes an int, not '2.5'"),
    ("wiserx.tau_enabled=maybe", "wiserx.tau_enabled takes a bool, not 'maybe'"),
    ("wiserx.fill_rule=square", "wiserx.fill_rule = 'square': fill_rule is disc or pts2"),
    ("wiserx.kappa=5", "scheme 'wiserx' has no parameter 'kappa' (it has: bearing_median_k,"),
    ("mrtopomap.grid_rays=48", "scheme 'mrtopomap' has no parameter 'grid_rays'"),   # the records' meaning
    ("minpos.x=1", "no scheme 'minpos' (the schemes with parameters of their own: "),
    ("meier.x=1", "scheme 'meier' has no parameters of its own"),
])
def test_bad_scheme_settings_say_which_and_why(item, says):
    with pytest.raises(ValueError, match=f"--set '{item}'") as err:
        parse_overrides([item])
    assert says in str(err.value)


def test_scheme_settings_are_checked_together_in_every_variant():
    with pytest.raises(ValueError) as err:
        parse_overrides(["wiserx.soft_fill=0.97"])
    assert "soft_fill (0.97) must not exceed hard_fill (0.95) (in wiserx:complete)" in str(err.value)


def test_every_schemes_defaults_lie_in_their_declaration():
    from firmware.declared import check_declared
    from firmware.schemes import SCHEMES, scheme_class

    for name in SCHEMES:
        cls = scheme_class(name)
        for variant in cls.variants if cls.params_type is not None else ():
            check_declared(cls.default_params(variant))          # raises otherwise


def test_a_run_with_a_scheme_setting_runs_it_and_records_it(cli):
    argv = ["run", "--map", "cave:4:40x40", "--robots", "2", "--max-sim-s", "30", "--json", "--quiet"]
    blind = json.loads(cli(*argv, "--scheme", "wiserx:blind").out)
    set_blind = json.loads(cli(*argv, "--scheme", "wiserx", "--set", "wiserx.relative_sensing=false").out)
    seeing = json.loads(cli(*argv, "--scheme", "wiserx").out)
    assert set_blind["params_overrides"] == {"wiserx.relative_sensing": False}
    assert set_blind["trajectory_sha256"] == blind["trajectory_sha256"] != seeing["trajectory_sha256"]


def test_a_scheme_setting_for_a_scheme_not_run_is_refused(cli):
    r = cli("run", "--map", "cave:4:40x40", "--scheme", "minpos", "--set", "wiserx.tau_enabled=false")
    assert r.code == 2
    assert "--set wiserx.tau_enabled=false: no scheme of this run is 'wiserx' (--scheme minpos)" in r.err
    r = cli("sweep", "--maps", "cave:4:40x40", "--schemes", "minpos", "greedy", "--set", "mrtopomap.k_min=5")
    assert r.code == 2 and "no scheme of this run is 'mrtopomap' (--schemes minpos greedy)" in r.err
