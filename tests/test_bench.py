"""`lorascout bench` reports how the cost scales: robot-seconds per wall second, each task's
time per robot-second, both by quarter of the run (the figures, not their values, are
tested here: timings belong to benchmarks, not to tests)."""
import json

from host_tools.cmd_bench import QUARTERS, SCENARIOS


def test_the_scaling_scenarios_cover_team_and_map_size():
    teams = {c.robots for name, c in SCENARIOS.items() if name.startswith("cave100-")}
    sizes = {c.map_spec for name, c in SCENARIOS.items() if name.endswith("-5robots") and name.startswith("cave")}
    assert teams == {1, 5, 20} and SCENARIOS["cave200-50robots"].robots == 50
    assert sizes == {"cave:1:60x60", "cave:1:100x100", "cave:1:200x200"}


def test_bench_reports_cost_per_robot_second_by_quarter(cli):
    r = cli("bench", "--scenario", "cave60-5robots", "--sim-s", "8", "--warmup-sim-s", "0", "--json", "--quiet")
    assert r.code == 0, r
    report = json.loads(r.out)
    assert report["robots"] == 5 and report["robot_s_per_wall_s"] > 0
    assert len(report["robot_s_per_wall_s_by_quarter"]) == QUARTERS
    assert all(q is not None and q > 0 for q in report["robot_s_per_wall_s_by_quarter"])
    per_task = report["task_ms_per_robot_s_by_quarter"]
    assert {"radio", "lidar", "control", "planning", "heartbeat"} <= set(per_task)
    assert all(len(q) == QUARTERS for q in per_task.values())
    assert set(report["last_over_first_quarter"]) == set(per_task)
    # Budgets come from the task table (its periods), the heartbeat's too.
    assert report["tasks"]["radio"]["budget_ms"] == 50.0 and report["tasks"]["heartbeat"]["budget_ms"] == 10000.0
