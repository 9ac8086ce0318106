"""python -m host_tools.team_gain: a team's p_max against one robot's path, seed by seed."""
from host_tools.team_gain import main
from tests.doubles import write_grid


def _trial(seed, paths, coverage=1.0, strategy="minpos", map_name="intel.yaml"):
    return {"map": map_name, "strategy": strategy, "radio": "ideal-100Bps", "seed": seed,
            "path_length_m": paths, "coverage": coverage}


def _cells(out: str, prefix: str) -> list[list[str]]:
    return [[c.strip() for c in line.split("|")] for line in out.splitlines() if line.startswith(prefix)]


def test_each_seed_is_paired_with_the_one_robot_run_of_the_same_seed(tmp_path, capsys):
    team = write_grid(tmp_path, "team", [_trial(0, [100.0, 250.0, 90.0]), _trial(1, [300.0, 280.0]),
                                         _trial(7, [10.0, 10.0])])   # seed 7 has no one-robot run
    one = write_grid(tmp_path, "one", [_trial(0, [500.0], strategy="independent"),
                                       _trial(1, [1000.0], strategy="independent")])
    assert main([str(team), str(one)]) == 0
    (row,) = _cells(capsys.readouterr().out, "| intel")
    assert row[3] == "3" and row[4] == "0-1"
    assert row[5] == "0.40, 0.50"           # 300 / 1000 and 250 / 500
    assert row[6] == "2 of 2" and row[8] == "2 of 2"


def test_a_seed_over_the_bound_or_below_the_coverage_target_fails(tmp_path, capsys):
    one = write_grid(tmp_path, "one", [_trial(s, [100.0], strategy="independent") for s in range(2)])
    over = write_grid(tmp_path, "over", [_trial(0, [50.0, 61.0]), _trial(1, [45.0, 30.0])])
    assert main([str(over), str(one)]) == 1
    (row,) = _cells(capsys.readouterr().out, "| intel")
    assert row[5] == "0.53, 0.61" and row[6] == "1 of 2"
    short = write_grid(tmp_path, "short", [_trial(0, [50.0, 50.0], coverage=0.98996), _trial(1, [40.0, 30.0])])
    assert main([str(short), str(one), "--bound", "0.6"]) == 1
    (row,) = _cells(capsys.readouterr().out, "| intel")
    assert row[7] == "0.9899" and row[8] == "1 of 2"


def test_grids_with_nothing_to_pair_or_a_bad_bound_are_errors(tmp_path, capsys):
    team = write_grid(tmp_path, "team", [_trial(0, [50.0, 50.0])])
    other = write_grid(tmp_path, "other", [_trial(0, [100.0], map_name="willow.yaml")])
    assert main([str(team), str(other)]) == 2
    assert "holds no team run" in capsys.readouterr().err
    assert main([str(team), str(tmp_path / "nowhere")]) == 2
    assert "no such file" in capsys.readouterr().err
    assert main([str(team), str(other), "--bound", "0"]) == 2
    assert "--bound 0.0: must be above 0" in capsys.readouterr().err


def test_t_total_is_compared_seed_by_seed_and_as_a_ratio_of_medians(tmp_path, capsys):
    def timed(seed, robots, t_total_s):
        return {**_trial(seed, [10.0] * robots, strategy="pereira"), "t_total_s": t_total_s}

    team = write_grid(tmp_path, "team", [timed(0, 2, 70.0), timed(1, 2, 90.0), timed(2, 2, 40.0)])
    one = write_grid(tmp_path, "one", [timed(0, 1, 100.0), timed(1, 1, 100.0), timed(2, 1, 80.0)])
    assert main([str(team), str(one), "--measure", "t_total", "--bound", "0.8"]) == 1
    out = capsys.readouterr().out
    assert "T_total / one robot's T_total: median, worst" in out
    (row,) = _cells(out, "| intel")
    assert row[5] == "0.70, 0.90" and row[6] == "2 of 3"       # 0.7, 0.9, 0.5
    assert row[9].startswith("0.70 (")                          # median 70 over median 100
    no_times = write_grid(tmp_path, "no_times", [_trial(0, [100.0], strategy="independent")])
    assert main([str(team), str(no_times), "--measure", "t_total"]) == 2
    assert "t_total_s" in capsys.readouterr().err
