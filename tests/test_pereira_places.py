"""Pereira's places on the air (Pereira.on_travel): one every d_build_m of travel, none where
the region graph holds a place within pereira_place_skip_m already, and, on leaving such
ground, the last place passed over first so the new places join the old ones.

The map: a corridor y in [19, 21] m from x = 5 to 35 m, walls along both sides. Teammate 1
drove its west part (places at x = 6 .. 12 m); this robot (0) drives the whole corridor."""
import dataclasses

from firmware.params import ExplorationParams
from firmware.schemes.pereira.records import Place, values_of
from firmware.services.local_map import LocalMap
from hal.samples import OdometrySample
from tests.doubles import PlannerRig
from tests.doubles import paint_box as paint

P = ExplorationParams()
ME, OTHER = 0, 1
TEAMMATE_X_M = [6.0, 7.0, 8.0, 9.0, 10.0, 11.0, 12.0]


def _drive(params: ExplorationParams) -> tuple[PlannerRig, list[Place]]:
    """Robot 0 drives the corridor's axis from x = 5 to 25 m in 5 cm steps; its own places."""
    local_map = LocalMap(params, 20.0, 20.0)
    local_map.logodds[:] = 0.0
    paint(local_map, 5.0, 35.0, 19.0, 21.0, params.logodds_min)
    paint(local_map, 5.0, 35.0, 18.8, 18.9, params.logodds_max)
    paint(local_map, 5.0, 35.0, 21.1, 21.2, params.logodds_max)
    rig = PlannerRig(local_map, "pereira", ME, params)
    for k, x in enumerate(TEAMMATE_X_M):
        rig.scheme.on_record("place", values_of(Place(OTHER, k + 1, round(x * 10), 200, 8, 1 if k else 0)), 0)
    for step in range(401):
        x_m = 5.0 + 0.05 * step
        rig.scheme.on_travel(OdometrySample(step * 100_000, x_m, 20.0, 0.0, 0.5, 0.0), step * 100_000)
    graph = rig.scheme.store.graph()
    mine = [Place(sender, oseq, x, y, clear, link_back)
            for x, y, sender, oseq, clear, link_back in graph.places.tolist() if sender == ME]
    return rig, sorted(mine, key=lambda p: p.oseq)


def test_a_place_every_d_build_m_by_default():
    rig, mine = _drive(P)
    assert [p.x_dm for p in mine] == [round((5.0 + k * P.d_build_m) * 10) for k in range(21)]
    assert rig.stat("places_skipped") == 0


def test_no_place_where_the_graph_holds_one_and_the_last_passed_over_first_on_leaving():
    params = dataclasses.replace(P, pereira_place_skip_m=0.5)
    rig, mine = _drive(params)
    xs = [p.x_dm / 10 for p in mine]
    # 5 m (no place near), 6 m (the first on the teammate's ground), 7 .. 12 m passed over,
    # 12 m sent on leaving, then 13 .. 25 m.
    assert xs == [5.0, 6.0, 12.0] + [float(x) for x in range(13, 26)]
    assert rig.stat("places_skipped") == 6
    by_oseq = {p.oseq: p for p in mine}
    entry, rejoin, first_new = mine[1], mine[2], mine[3]
    assert by_oseq[entry.oseq - entry.link_back] is mine[0]
    assert rejoin.link_back == 0                         # no trajectory edge across the ground passed over
    assert by_oseq[first_new.oseq - first_new.link_back] is rejoin
    graph = rig.scheme.store.graph()
    assert len({int(r) for r in graph.region_of_place}) == 1    # the new places join the teammate's
