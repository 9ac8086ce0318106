"""host_tools.team_timeline: a team mission's coverage, stopped robots and counters over time."""
from host_tools.team_timeline import main


def test_rows_every_few_seconds_with_the_counters_asked_for(capsys):
    assert main(["--map", "cave:5:20x20", "--robots", "2", "--scheme", "minpos", "--max-sim-s", "60",
                 "--every-s", "10", "--stat", "targets_reached"]) == 0
    out = capsys.readouterr().out
    rows = [line for line in out.splitlines() if line.startswith("| ") and not line.startswith("| t (s)")]
    assert [r.split(" | ")[0] for r in rows] == ["| 0", "| 10", "| 20", "| 30"]      # it ends at 38 s
    coverage = [float(r.split(" | ")[1]) for r in rows]
    assert coverage == sorted(coverage) and coverage[-1] > coverage[0]
    assert all(r.strip("| ").split(" | ")[3].split() == ["0", "0"] for r in rows[:2])   # per robot
    assert out.splitlines()[-1].startswith("complete: coverage 1.0000")


def test_a_counter_the_scheme_does_not_keep_is_named(capsys):
    assert main(["--map", "cave:5:20x20", "--robots", "2", "--scheme", "minpos", "--max-sim-s", "10",
                 "--stat", "no_such_counter"]) == 2
    assert "--stat no_such_counter" in capsys.readouterr().err


def test_bad_input_is_named_before_the_mission(capsys):
    assert main(["--map", "no/such/map.yaml", "--max-sim-s", "10"]) == 2
    assert "--map no/such/map.yaml" in capsys.readouterr().err
    assert main(["--map", "cave:5:20x20", "--every-s", "2.5"]) == 2
    assert "--every-s 2.5" in capsys.readouterr().err
    assert main(["--map", "cave:5:20x20", "--radio", "nosuch", "--max-sim-s", "5"]) == 2
    assert "unknown radio profile 'nosuch'" in capsys.readouterr().err
