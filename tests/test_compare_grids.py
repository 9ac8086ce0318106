"""python -m host_tools.compare_grids: two sweeps' trials, compared per map and scheme."""
import json

from host_tools.compare_grids import main
from tests.doubles import write_grid


def _trial(seed, p_max, coverage=1.0, strategy="minpos", map_name="maze_a.yaml"):
    return {"map": map_name, "strategy": strategy, "radio": "ideal-100Bps", "seed": seed,
            "path_length_m": [p_max / 2, p_max], "coverage": coverage, "t_total_s": 600.0, "t_90_s": 300.0}


def test_the_ratio_is_of_the_medians_over_the_seeds_both_ran(tmp_path, capsys):
    new = write_grid(tmp_path, "new", [_trial(0, 200.0), _trial(1, 300.0, 0.98996), _trial(2, 400.0), _trial(9, 10.0)])
    old = write_grid(tmp_path, "old", [_trial(0, 400.0), _trial(1, 600.0), _trial(2, 800.0),
                                  _trial(0, 100.0, strategy="greedy")])
    assert main([str(new), str(old)]) == 0
    rows = [line for line in capsys.readouterr().out.splitlines() if line.startswith("| maze_a")]
    assert len(rows) == 1          # greedy is in one grid only; seed 9 in one only
    cells = [c.strip() for c in rows[0].split("|")]
    assert cells[3] == "0-2" and cells[4] == "300.0 / 600.0" and cells[5].startswith("0.50 (")
    assert cells[6] == "0.9899 / 1.0000" and cells[7] == "1.0000 / 1.0000"     # rounded down
    assert cells[8] == "2 / 3"                      # 0.98996 has not reached 0.99
    assert cells[9] == "2.0 / 2.0"


def test_one_scheme_in_new_against_another_in_old(tmp_path, capsys):
    new = write_grid(tmp_path, "new", [_trial(0, 300.0, strategy="pereira"), _trial(1, 500.0, strategy="pereira"),
                                       _trial(0, 1.0)])
    old = write_grid(tmp_path, "old", [_trial(0, 100.0), _trial(1, 200.0), _trial(0, 5.0, strategy="pereira")])
    assert main([str(new), str(old), "--schemes", "pereira:minpos"]) == 0
    rows = [line for line in capsys.readouterr().out.splitlines() if line.startswith("| maze_a")]
    assert len(rows) == 1
    cells = [c.strip() for c in rows[0].split("|")]
    assert cells[2].startswith("pereira / minpos") and cells[4] == "400.0 / 150.0"
    assert cells[5].startswith("2.67 (")


def test_schemes_must_be_two_names(tmp_path, capsys):
    grid = write_grid(tmp_path, "g", [_trial(0, 1.0)])
    for bad in ("pereira", "pereira:", ":minpos", "a:b:c"):
        try:
            main([str(grid), str(grid), "--schemes", bad])
        except SystemExit as e:
            assert e.code == 2
        else:
            raise AssertionError(f"--schemes {bad} accepted")
        assert "--schemes" in capsys.readouterr().err


def test_a_scheme_with_no_run_reaching_0_9_has_no_tail(tmp_path, capsys):
    slow = {**_trial(0, 100.0, 0.85), "t_90_s": None}
    new = write_grid(tmp_path, "new", [_trial(0, 100.0)])
    old = write_grid(tmp_path, "old", [slow])
    assert main([str(new), str(old)]) == 0
    row = next(line for line in capsys.readouterr().out.splitlines() if line.startswith("| maze_a"))
    assert [c.strip() for c in row.split("|")][9] == "2.0 / -"


def test_a_broken_trials_file_is_named_with_its_line(tmp_path, capsys):
    new = write_grid(tmp_path, "new", [_trial(0, 200.0)])
    old = tmp_path / "old"
    old.mkdir()
    (old / "trials.jsonl").write_text(json.dumps(_trial(0, 1.0)) + "\n{\"map\": \"x\"}\n")
    assert main([str(new), str(old)]) == 2
    err = capsys.readouterr().err
    assert "trials.jsonl, line 2" in err and "KeyError" in err


def test_a_missing_grid_or_nothing_in_common_is_an_error(tmp_path, capsys):
    new = write_grid(tmp_path, "new", [_trial(0, 200.0)])
    assert main([str(new), str(tmp_path / "nowhere")]) == 2
    assert "no such file" in capsys.readouterr().err
    other = write_grid(tmp_path, "other", [_trial(0, 200.0, map_name="intel.yaml")])
    assert main([str(new), str(other)]) == 2
    assert "share no map" in capsys.readouterr().err
