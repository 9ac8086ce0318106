"""The eight-region test map of Pereira et al.'s scaling experiment (pereira.md 6.3, bar 9):
the files in the repository are what tests/data/draw_pereira8.py draws, the start is in room
1, and the project's own doorway finder cuts it into the paper's eight regions."""
import math
from pathlib import Path

from firmware.params import ExplorationParams
from host_tools import region_oracle
from tests.data import draw_pereira8
from world_sim.map_spec import resolve_map

DATA = Path(__file__).parent / "data"


def test_the_committed_files_are_what_the_script_draws(tmp_path):
    draw_pereira8.write(tmp_path)
    for name in ("pereira8.pgm", "pereira8.yaml"):
        assert (tmp_path / name).read_bytes() == (DATA / name).read_bytes(), name


def test_the_start_is_in_room_1_and_every_room_is_reachable():
    occ, start, _ = resolve_map(str(DATA / "pereira8.yaml"))
    x0, x1, y0, y1 = draw_pereira8.ROOMS["room 1"]
    assert x0 < start[0] < x1 and y0 < start[1] < y1
    for name, (x0, x1, y0, y1) in draw_pereira8.ROOMS.items():
        assert occ.is_free_point((x0 + x1) / 2, (y0 + y1) / 2), name


def test_the_doorway_finder_cuts_it_at_three_doors_and_four_corridor_mouths():
    occ, _, _ = resolve_map(str(DATA / "pereira8.yaml"))
    found = [(x / 10.0, y / 10.0) for x, y, _d, _h in region_oracle.doorways(occ, ExplorationParams())]
    doors = [((x0 + x1) / 2, (y0 + y1) / 2) for x0, x1, y0, y1 in draw_pereira8.DOORS.values()]
    mouths = [(x, (y0 + y1) / 2) for name in ("corridor 2", "corridor 6")
              for x0, x1, y0, y1 in [draw_pereira8.ROOMS[name]] for x in (x0, x1)]
    assert len(found) == len(doors) + len(mouths) == 7
    for x, y in doors + mouths:
        assert min(math.hypot(x - fx, y - fy) for fx, fy in found) < 0.6, (x, y)
