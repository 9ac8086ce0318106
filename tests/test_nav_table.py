"""python -m host_tools.nav_table: a finished sweep's navigation, per map and scheme."""
import json

from host_tools.nav_table import main
from tests.doubles import write_grid


def _trial(seed, coverage, termination="complete", t_90_s=300.0, recoveries=2, in_wall=0):
    return {"map": "intel.yaml", "strategy": "independent", "seed": seed, "reachable_area_m2": 396.3,
            "coverage": coverage, "termination": termination, "t_total_s": 900.0, "t_90_s": t_90_s,
            "path_length_m": [500.0 + seed], "explorer_stats": {"recoveries": [recoveries]}, "robots_in_wall": in_wall}


def test_one_row_per_map_and_scheme_over_every_sweep_given(tmp_path, capsys):
    a = write_grid(tmp_path, "a", [_trial(0, 0.9985), _trial(1, 0.98996, "complete_with_unreachable_frontiers", recoveries=4)])
    b = write_grid(tmp_path, "b", [_trial(2, 0.85, "time_limit", t_90_s=None, in_wall=3)])
    assert main([str(a), str(b)]) == 0
    rows = [line for line in capsys.readouterr().out.splitlines() if line.startswith("| intel")]
    assert len(rows) == 1
    cells = [c.strip() for c in rows[0].split("|")][1:-1]
    assert cells[:4] == ["intel.yaml", "independent", "0-2", "396 m²"]
    assert cells[4] == "0.8500 / 0.9899"            # rounded down: 0.98996 has not reached 0.99
    assert cells[5] == "1 of 3"
    assert cells[6] == "complete 1, complete_with_unreachable_frontiers 1, time_limit 1"
    assert cells[7] == "300 s (2 of 3 reach 0.9)" and cells[8] == "900 s" and cells[9] == "3.0"
    assert cells[10] == "501 m" and cells[11] == "2" and cells[12] == "3"


def test_a_broken_or_missing_trials_file_is_named(tmp_path, capsys):
    assert main([str(tmp_path / "nowhere")]) == 2
    assert "no such file" in capsys.readouterr().err
    bad = write_grid(tmp_path, "bad", [_trial(0, 1.0)])
    (bad / "trials.jsonl").write_text(json.dumps(_trial(0, 1.0)) + '\n{"map": "x"}\n')
    assert main([str(bad)]) == 2
    assert "trials.jsonl, line 2" in capsys.readouterr().err


def test_the_same_trial_in_two_sweeps_is_refused(tmp_path, capsys):
    a = write_grid(tmp_path, "a", [_trial(0, 1.0)])
    b = write_grid(tmp_path, "b", [_trial(0, 0.9)])
    assert main([str(a), str(b)]) == 2
    assert "seed 0" in capsys.readouterr().err
