"""Meier's split-rate tables (host_tools/split_rate.py): trials grouped by map, radio, radio
share and split rate, records by kind as shares, and bad folders refused by name."""
import json

import pytest

from firmware.params import ExplorationParams
from host_tools.split_rate import main


def _trial(seed, split_rate, bytes_per_s, p_max, splits=10, strategy="meier"):
    return {
        "strategy": strategy, "map": "maze_a.yaml", "radio": "eu868-g3", "seed": seed, "t_total_s": 500.0 + seed,
        "params_overrides": {"meier_split_rate_hz": split_rate, "meier_radio_share": 1.0},
        "radio_stats": {"bytes_per_s_mean": [bytes_per_s, bytes_per_s + 2.0]},
        "path_length_m": [p_max, p_max / 2],
        "explorer_stats": {"poly_emerged_records": [30, 10], "poly_vanished_records": [20, 20],
                           "poly_edge_split_records": [splits, splits], "target_records_sent": [5, 5]},
        "polygon_maps": {"split_rate_hz": [0.1, 0.3], "approximation_error_mean": [0.05, 0.07]},
    }


def _sweep(tmp_path, name, trials):
    out = tmp_path / name
    out.mkdir()
    (out / "trials.jsonl").write_text("".join(json.dumps(t) + "\n" for t in trials))
    return out


def test_each_split_rate_is_a_row_with_its_medians_means_and_shares_of_records(tmp_path, capsys):
    slow = _sweep(tmp_path, "sr-0.1", [_trial(0, 0.1, 10.0, 400.0, splits=0), _trial(1, 0.1, 12.0, 500.0, splits=0)])
    fast = _sweep(tmp_path, "sr-2", [_trial(0, 2.0, 30.0, 300.0, splits=50)])
    assert main([str(fast), str(slow), "--out", str(tmp_path / "tables")]) == 0
    table = json.loads((tmp_path / "tables" / "tables.json").read_text())
    assert [r["split_rate_hz"] for r in table] == [0.1, 2.0]
    assert table[0]["trials"] == 2 and table[0]["bytes_per_s"] == pytest.approx(12.0)   # means of 11 and 13
    assert table[0]["p_max_m"] == pytest.approx(450.0) and table[0]["error"] == pytest.approx(0.06)
    assert table[0]["record_share"]["edge split"] == 0.0
    assert table[1]["record_share"]["edge split"] == pytest.approx(100 / 190)
    assert sum(table[1]["record_share"].values()) == pytest.approx(1.0)
    assert (tmp_path / "tables" / "split_rate.png").stat().st_size > 0
    assert "| maze_a.yaml | eu868-g3 | 1 | 2 | 1 |" in capsys.readouterr().out


def test_a_folder_without_meier_trials_or_with_a_broken_line_is_refused_by_name(tmp_path, capsys):
    other = _sweep(tmp_path, "minpos", [_trial(0, 1.0, 10.0, 400.0, strategy="minpos")])
    assert main([str(other), "--out", str(tmp_path / "t")]) == 2
    assert "minpos/trials.jsonl, line 1" in capsys.readouterr().err
    broken = _sweep(tmp_path, "broken", [_trial(0, 1.0, 10.0, 400.0)])
    with open(broken / "trials.jsonl", "a") as f:
        f.write("{not json\n")
    assert main([str(broken), "--out", str(tmp_path / "t")]) == 2
    assert "broken/trials.jsonl, line 2" in capsys.readouterr().err
    assert main([str(tmp_path / "nowhere"), "--out", str(tmp_path / "t")]) == 2
    assert not (tmp_path / "t").exists()                          # nothing written


def test_a_trial_without_the_parameters_set_counts_at_their_defaults(tmp_path):
    plain = _trial(0, 1.0, 10.0, 400.0)
    del plain["params_overrides"]
    assert main([str(_sweep(tmp_path, "plain", [plain])), "--out", str(tmp_path / "t")]) == 0
    (row,) = json.loads((tmp_path / "t" / "tables.json").read_text())
    defaults = ExplorationParams()
    assert (row["split_rate_hz"], row["radio_share"]) == (defaults.meier_split_rate_hz, defaults.meier_radio_share)
