"""`python -m host_tools.team_failures`: issue 24's bounds on failed and slow robots, seed by
seed, from sweeps' trials."""
from __future__ import annotations

import json

import pytest

from host_tools.team_failures import main


def _failure_trial(seed: int, survivors: float, recovered: float | None, robot: int = 1, stopped: bool = True) -> dict:
    return {"map": "intel", "strategy": "wiserx", "seed": seed, "coverage_survivors": survivors,
            "termination": "complete" if stopped else "time_limit",
            "failures": [{"robot": robot, "at_coverage": 0.6, "failed_at_s": 100.0, "recovered": recovered}]}


def _write(path, trials) -> None:
    path.mkdir()
    (path / "trials.jsonl").write_text("".join(json.dumps(t) + "\n" for t in trials))


def test_recovery_pairs_the_seeds_and_holds_only_when_every_bound_does(tmp_path, capsys):
    _write(tmp_path / "with", [_failure_trial(s, 0.95 + 0.01 * s, 0.8) for s in range(5)])
    _write(tmp_path / "without", [_failure_trial(s, 0.85 + 0.01 * s, 0.5) for s in range(5)])
    assert main(["recovery", str(tmp_path / "with"), str(tmp_path / "without")]) == 0
    row = capsys.readouterr().out.splitlines()[2]
    assert row == "| intel | wiserx | 0-4 | 5 of 5 | 0.9700, 0.8700 | +0.1000, 5 of 5 | 0.80 | 5 of 5 | yes |"


@pytest.mark.parametrize("change, why", [
    (dict(survivors=0.86), "gained 0.01"),
    (dict(survivors=0.95, recovered=0.6), "saw too little of what only the failed robot had seen"),
    (dict(survivors=0.95, stopped=False), "a survivor did not stop by itself"),
])
def test_recovery_fails_a_bound(tmp_path, capsys, change, why):
    _write(tmp_path / "with", [_failure_trial(s, **{"survivors": 0.95, "recovered": 0.8, **change}) for s in range(5)])
    _write(tmp_path / "without", [_failure_trial(s, 0.85, 0.5) for s in range(5)])
    assert main(["recovery", str(tmp_path / "with"), str(tmp_path / "without")]) == 1, why
    assert capsys.readouterr().out.rstrip().endswith("| NO |")


def test_recovery_refuses_sweeps_that_failed_other_robots(tmp_path, capsys):
    _write(tmp_path / "with", [_failure_trial(0, 0.95, 0.8, robot=1)])
    _write(tmp_path / "without", [_failure_trial(0, 0.85, 0.5, robot=2)])
    assert main(["recovery", str(tmp_path / "with"), str(tmp_path / "without")]) == 2
    assert "the two sweeps failed different robots" in capsys.readouterr().err


def _slow_trial(strategy: str, seed: int, t_total_s: float, shares: list[float], coverage: float = 0.99) -> dict:
    return {"map": "intel", "strategy": strategy, "seed": seed, "t_total_s": t_total_s, "coverage": coverage,
            "termination": "complete", "speed_factors": {"1": 0.5}, "observed_share": shares}


def test_slow_compares_termination_coverage_and_the_slow_robots_share(tmp_path, capsys):
    trials = [_slow_trial("wiserx", s, 600.0 + s, [0.5, 0.2, 0.5]) for s in range(5)]
    trials += [_slow_trial("divide", s, 1000.0 + s, [0.4, 0.3, 0.4]) for s in range(5)]
    _write(tmp_path / "slow", trials)
    assert main(["slow", str(tmp_path / "slow")]) == 0
    row = capsys.readouterr().out.splitlines()[2]
    assert row.startswith("| intel | 0-4 | wiserx / divide: 0.60, ") and "| 0.40 | 5 and 5 of 5 | yes |" in row
    trials[0:5] = [_slow_trial("wiserx", s, 900.0, [0.5, 0.45, 0.5]) for s in range(5)]
    _write(tmp_path / "slower", trials)
    assert main(["slow", str(tmp_path / "slower")]) == 1


def test_a_folder_without_trials_is_an_error_naming_it(tmp_path, capsys):
    assert main(["slow", str(tmp_path)]) == 2
    assert f"{tmp_path}/trials.jsonl: no such file" in capsys.readouterr().err
