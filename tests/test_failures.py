"""Robots that fail and robots that are slower (world_sim World.power_off / set_speed_factor,
MissionConfig.failures / speed_factors, `lorascout run --fail R@S --slow R=F`): issue 24's
failed and slow robots, for any scheme."""
from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from host_tools.mission import DRAWN, Failure, MissionConfig, drawn_failures, run_mission
from world_sim.occupancy_map import OccupancyMap
from world_sim.world import World, WorldParams

TICK_US = 50_000


def _hall(size_m: float = 30.0) -> OccupancyMap:
    cells = int(size_m / 0.1)
    free = np.ones((cells, cells), dtype=bool)
    free[[0, -1], :] = False
    free[:, [0, -1]] = False
    return OccupancyMap(free, 0.1, 0.0, 0.0, "hall")


def _world(n: int = 3) -> World:
    poses = [(5.0 + 4.0 * i, 5.0, 0.0) for i in range(n)]
    return World(_hall(), poses, seed=4, params=WorldParams().with_sensing_profile("paper"))


def _run(world: World, seconds: float, drive=lambda w: None) -> tuple[list, list]:
    ranges, bearings = [[] for _ in range(world.n_robots)], [[] for _ in range(world.n_robots)]
    for _ in range(int(seconds * 1e6 / TICK_US)):
        drive(world)
        world.step(TICK_US)
        for i in range(world.n_robots):
            ranges[i] += world.take_uwb_ranges(i)
            bearings[i] += world.take_aoa_bearings(i)
    return ranges, bearings


def _forward_all(w: World) -> None:
    for i in range(w.n_robots):
        w.set_command(i, 10.0, 0.0)


def test_a_failed_robot_stops_and_is_neither_measured_nor_measures():
    w = _world()
    _run(w, 1.0, _forward_all)
    w.power_off(1)
    stopped_at = w.true_pose(1)
    ranges, bearings = _run(w, 5.0, _forward_all)
    assert w.true_pose(1) == stopped_at and not w.powered(1) and w.powered(0)
    assert w.true_pose(0).x_m > stopped_at.x_m - 4.0 + 1.0           # the others drive on
    assert ranges[1] == [] and bearings[1] == []
    for i in (0, 2):
        assert ranges[i] and bearings[i]
        assert {m.peer_id for m in ranges[i]} | {m.peer_id for m in bearings[i]} == {0, 1, 2} - {i, 1}


def test_a_failure_leaves_the_others_measurements_of_each_other_as_they_were():
    """The sensors draw their noise for every peer whether it answers or not: robots 0 and
    2 measure each other exactly as in a world where robot 1 did not fail."""
    seen = []
    for fail in (False, True):
        w = _world()
        _run(w, 1.0)
        if fail:
            w.power_off(1)
        ranges, bearings = _run(w, 5.0)
        seen.append([(m.stamp_us, m.peer_id, m.range_m) for m in ranges[0] if m.peer_id == 2]
                    + [(m.stamp_us, m.peer_id, m.bearing_rad) for m in bearings[2] if m.peer_id == 0])
    assert seen[0] and seen[0] == seen[1]


def test_a_slow_robot_covers_its_share_of_the_distance():
    w = _world(2)
    w.set_speed_factor(1, 0.5)
    _run(w, 4.0, _forward_all)
    assert w.path_length_m(0) == pytest.approx(4.0 * w.params.max_v_mps, rel=1e-6)
    assert w.path_length_m(1) == pytest.approx(0.5 * w.path_length_m(0), rel=1e-6)


@pytest.mark.parametrize("factor", [0.0, -0.5, 1.5, float("nan")])
def test_a_speed_factor_outside_0_1_is_refused(factor):
    with pytest.raises(ValueError, match="speed factor of robot 1"):
        _world(2).set_speed_factor(1, factor)


def test_a_mission_goes_on_without_a_failed_robot_and_says_so():
    cfg = MissionConfig(map_spec="cave:3:30x30", robots=3, seed=0, max_sim_s=900.0, strategy="minpos",
                        failures=(Failure(1, at_s=30.0),), speed_factors=((2, 0.5),))
    r = run_mission(cfg)
    stop = int(30.0 * 1e6 / TICK_US)
    track = r.trajectories[1]
    assert np.array_equal(track[stop:], np.repeat(track[stop:stop + 1], len(track) - stop, axis=0))
    assert not np.array_equal(track[stop - 100], track[stop])          # it was driving before
    assert r.robot_status[1] == "failed" and r.termination in ("complete", "complete_with_unreachable_frontiers")
    assert r.t_total_s < cfg.max_sim_s
    last_sent_by_1 = max(f.start_us for f in r.air_frames if f.sender_id == 1)
    assert last_sent_by_1 < 30_000_000
    doc = json.loads(json.dumps(r.to_json()))
    assert doc["failures"] == [{"robot": 1, "at_s": 30.0, "failed_at_s": 30.0, "lost_at_failure": pytest.approx(
        r.lost_at_failure[1], abs=1e-6), "recovered": pytest.approx(r.recovered[1], abs=1e-6)}]
    assert doc["speed_factors"] == {"2": 0.5}
    assert len(doc["observed_share"]) == 3 and sum(r.observed_share) - r.coverage == pytest.approx(r.overlap)
    # What only robot 1 had seen when it failed, from the world as it was then (the same
    # mission cut at that moment), and how much of it the survivors saw by the end.
    then = run_mission(dataclasses.replace(cfg, max_sim_s=30.0)).world
    reachable = r.reachable
    only_1 = then.observed(1) & reachable & ~then.observed(0) & ~then.observed(2)
    survivors = (r.world.observed(0) | r.world.observed(2)) & reachable
    assert only_1.sum() > 0
    assert r.lost_at_failure[1] == only_1.sum() / reachable.sum()
    assert r.recovered[1] == (only_1 & survivors).sum() / only_1.sum()
    assert r.coverage_survivors == survivors.sum() / reachable.sum() <= r.coverage


def test_a_robot_fails_once_the_team_has_seen_the_share_given():
    cfg = MissionConfig(map_spec="cave:3:30x30", robots=2, seed=0, max_sim_s=600.0, failures=(Failure(0, at_coverage=0.5),))
    samples = []
    r = run_mission(cfg, progress=lambda sim_s, coverage: samples.append((sim_s, coverage)))
    at = r.failed_at_s[0]
    assert at == next(t for t, c in samples if c >= 0.5) and samples[0][1] < 0.5
    assert r.robot_status[0] == "failed" and at < r.t_total_s
    assert [{k: f[k] for k in ("robot", "at_coverage", "failed_at_s")} for f in r.to_json()["failures"]] == [
        {"robot": 0, "at_coverage": 0.5, "failed_at_s": at}]


def test_a_drawn_failure_is_the_seeds_and_the_same_for_every_scheme(cli):
    drawn = {seed: drawn_failures((DRAWN,), seed, 3) for seed in range(40)}
    assert drawn[7] == drawn_failures((DRAWN,), 7, 3)
    for (failure,) in drawn.values():
        assert 0 <= failure.robot < 3 and failure.at_s is None and 0.5 <= failure.at_coverage <= 0.7
    assert {f.robot for (f,) in drawn.values()} == {0, 1, 2} and len({f.at_coverage for (f,) in drawn.values()}) > 30
    runs = [json.loads(cli("run", "--map", "cave:3:30x30", "--robots", "3", "--seed", "7", "--scheme", scheme,
                           "--fail", "random", "--max-sim-s", "120", "--json", "--quiet").out) for scheme in
            ("minpos", "independent")]
    (f,) = drawn[7]
    for doc in runs:
        assert (doc["failures"][0]["robot"], doc["failures"][0]["at_coverage"]) == (f.robot, f.at_coverage)


def test_a_team_that_all_failed_ends_there():
    r = run_mission(MissionConfig(map_spec="cave:3:30x30", robots=2, seed=0, max_sim_s=600.0,
                                  failures=(Failure(0, at_s=10.0), Failure(1, at_s=12.5))))
    assert r.termination == "all_failed" and r.robot_status == ["failed", "failed"]
    assert r.t_total_s == pytest.approx(12.5)


@pytest.mark.parametrize("argv, says", [
    (["--robots", "3", "--fail", "3@10"], "robot 3 is not in the team of 3 (--robots"),
    (["--robots", "3", "--slow", "5=0.5"], "robot 5 is not in the team of 3 (--robots"),
    (["--robots", "3", "--fail", "1@10", "--fail", "1@20"], "robot 1 given twice"),
    (["--robots", "2", "--max-sim-s", "60", "--fail", "0@61"], "after the mission's end (--max-sim-s 60)"),
    (["--robots", "2", "--fail", "0@120%"], "P must be in (0, 100]"),
    (["--robots", "3", "--fail", "random", "--fail", "1@20"], "random draws the failing robot; give it alone"),
])
def test_failures_and_slow_robots_outside_the_team_or_the_mission_are_refused_before_it_runs(cli, argv, says):
    res = cli("run", "--map", "cave:3:30x30", *argv)
    assert res.code == 2 and says in res.err and ("--fail" in res.err or "--slow" in res.err)
