"""Limited range and multi-hop (issue 23 items 4 and 5; pereira.md 6.2): with a hard radio
range on the ideal link, robots farther apart than the range hear nothing from each other,
and a robot learns the records of one it never hears through a robot between them, by the
scheme's summaries and pushes (application gossip), and not without them."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from host_tools.mission import MissionConfig, run_mission
from host_tools.overrides import params_with
from radio_sim.air_log import OUT_OF_RANGE, RECEIVED

RES_M = 0.1
CORRIDOR_X_M = (2.0, 9.0, 16.0, 23.0)   # parallel corridors 7 m apart, centre to centre
HALF_WIDTH_M = 1.25
Y_M = (1.0, 37.0)
RANGE_M = 11.0                       # the outer corridors are 11.5 m apart at their nearest walls


def parallel_corridors(folder: Path, n: int) -> Path:
    """A ROS map of n parallel closed corridors, 2.5 m x 36 m (beyond the LiDAR's 10 m, so the
    robots drive them), no way between them."""
    w, h = int((CORRIDOR_X_M[n - 1] + 3) / RES_M), int((Y_M[1] + 1) / RES_M)
    img = np.zeros((h, w), np.uint8)                      # walls (black)
    for cx in CORRIDOR_X_M[:n]:
        c0, c1 = int(round((cx - HALF_WIDTH_M) / RES_M)), int(round((cx + HALF_WIDTH_M) / RES_M))
        r0, r1 = h - int(round(Y_M[1] / RES_M)), h - int(round(Y_M[0] / RES_M))   # rows top-down
        img[r0:r1, c0:c1] = 254
    Image.fromarray(img).save(folder / f"corridors{n}.png")
    (folder / f"corridors{n}.yaml").write_text(f"image: corridors{n}.png\nresolution: 0.1\norigin: [0.0, 0.0, 0.0]\n"
                                               "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n")
    return folder / f"corridors{n}.yaml"


def chain_mission(map_path: Path, scheme: str = "pereira", push_max: int = 6, robots: int = 3, flush_s: float = 0.0):
    cfg = MissionConfig(map_spec=str(map_path), robots=robots, seed=0, strategy=scheme, radio="ideal-100Bps",
                        max_sim_s=400, range_m=RANGE_M, flush_s=flush_s,
                        starts=tuple((x, 2.0, math.pi / 2) for x in CORRIDOR_X_M[:robots]))
    return run_mission(cfg, params=params_with((("pereira_push_max", push_max),)))


def held_from(agent, origin: int) -> int:
    """How many of origin's records the robot holds."""
    return sum(1 for r in agent.scheme.store.records() if r.sender_id == origin)


@pytest.fixture(scope="module")
def corridors(tmp_path_factory):
    return parallel_corridors(tmp_path_factory.mktemp("corridors"), 3)


def test_the_ends_of_a_chain_hear_nothing_of_each_other_and_learn_through_the_middle(corridors):
    r = chain_mission(corridors)
    assert r.termination == "complete" and r.coverage >= 0.99 and r.to_json()["range_m"] == RANGE_M
    fates: dict[tuple[int, int], set[str]] = {}
    for f in r.air_frames:
        for rec in f.receptions:
            fates.setdefault((f.sender_id, rec.receiver_id), set()).add(rec.fate)
    # Farther apart than the range: nothing at all; closer (the middle and either end): heard.
    assert fates[(0, 2)] == fates[(2, 0)] == {OUT_OF_RANGE}
    for pair in ((0, 1), (1, 0), (1, 2), (2, 1)):
        assert RECEIVED in fates[pair]
    a, b, c = r.agents
    # The ends hold each other's records: they came through robot 1's pushes only.
    assert held_from(a, 2) > 0 and held_from(c, 0) > 0
    assert sum(r.to_json()["explorer_stats"]["records_pushed"]) > 0
    assert held_from(b, 0) > 0 and held_from(b, 2) > 0


@pytest.mark.parametrize("scheme, push_max", [("pereira", 0), ("pereira-nogossip", 6)])
def test_without_gossip_the_ends_of_the_chain_never_learn_each_others_records(corridors, scheme, push_max):
    r = chain_mission(corridors, scheme, push_max)
    assert r.termination == "complete"
    a, b, c = r.agents
    assert held_from(a, 2) == 0 and held_from(c, 0) == 0
    assert held_from(b, 0) > 0 and held_from(b, 2) > 0
    assert sum(r.to_json()["explorer_stats"]["records_pushed"]) == 0
    assert sum(r.to_json()["explorer_stats"]["summaries_sent"]) == 0


@pytest.mark.parametrize("push_max", [6, 0])
def test_a_four_robot_chain_converges_through_the_middle_and_not_without_relaying(tmp_path, push_max):
    """Four corridors, the range reaching only the next one: the ends are two hops apart.
    With gossip every robot ends holding the same records (after a flush phase for the
    last ones on their way); with none the ends never learn of each other."""
    r = chain_mission(parallel_corridors(tmp_path, 4), push_max=push_max, robots=4, flush_s=120.0)
    assert r.termination == "complete" and r.coverage >= 0.99
    heard = {(f.sender_id, rec.receiver_id) for f in r.air_frames for rec in f.receptions if rec.fate == RECEIVED}
    assert not heard & {(0, 2), (0, 3), (1, 3), (2, 0), (3, 0), (3, 1)}
    ends = r.agents[0], r.agents[3]
    if push_max:
        assert held_from(ends[0], 3) > 0 and held_from(ends[1], 0) > 0
        assert r.to_json()["scheme_digests"]["agree"]
    else:
        assert held_from(ends[0], 3) == held_from(ends[1], 0) == 0
        assert not r.to_json()["scheme_digests"]["agree"]


def test_run_and_sweep_take_a_range_record_it_and_refuse_a_bad_one(tmp_path, capsys):
    from host_tools.cli import main
    from host_tools.sweep import PARTIAL_NAME

    assert main(["run", "--map", "cave:4:20x20", "--robots", "2", "--max-sim-s", "5", "--range-m", "7.5",
                 "--json", "--quiet"]) == 0
    assert json.loads(capsys.readouterr().out)["range_m"] == 7.5
    argv = ["sweep", "--maps", "cave:4:20x20", "--strategies", "independent", "--robots", "1", "--seeds", "1",
            "--max-sim-s", "5", "--jobs", "1", "--quiet", "--out", str(tmp_path)]
    assert main(argv + ["--range-m", "5"]) == 0
    (trial,) = [json.loads(line) for line in (tmp_path / PARTIAL_NAME).read_text().splitlines()]
    assert trial["range_m"] == 5.0
    assert "radio ideal-100Bps within 5 m" in capsys.readouterr().out
    # Another range is another grid: its trial is run again, not taken from the first.
    assert main(argv + ["--resume"]) == 0
    assert "resuming: 0 trials done earlier, 1 to run" in capsys.readouterr().err
    assert main(argv + ["--resume", "--range-m", "5"]) == 0
    assert "resuming: 1 trials done earlier, 0 to run" in capsys.readouterr().err
    for bad in ("0", "-3", "nan"):
        with pytest.raises(SystemExit):
            main(["run", "--range-m", bad])
        assert "--range-m" in capsys.readouterr().err
