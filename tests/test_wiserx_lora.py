"""`wiserx:lora` (../shared/schemes/wiserx.md 5.6): an 11-byte digest of the hgrid cells a
robot filled by its own positions, over LoRa; robots out of UWB and WiFi reach stay alive
to each other and count each other's fill."""
from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from firmware.comms import codec
from firmware.schemes.wiserx.hgrid import HGrid
from firmware.schemes.wiserx.params import WiserxParams
from firmware.schemes.wiserx.records import CELLS_PER_CHUNK, HGRID, cells_of_chunk, chunk_fields
from host_tools.mission import MissionConfig, run_mission


@settings(max_examples=60, deadline=None)
@given(st.lists(st.booleans(), min_size=1, max_size=300))
def test_a_grid_sent_chunk_by_chunk_reads_back_cell_for_cell(filled):
    heard = set()
    for chunk in range(-(-len(filled) // CELLS_PER_CHUNK)):
        values = {"sender_id": 3, "chunk": chunk, "chunks_m1": 0, "done": 0, "fill_pct": 50,
                  **chunk_fields(filled, chunk)}
        got = codec.decode(HGRID, codec.encode(HGRID, values)).values
        heard |= set(cells_of_chunk(got["chunk"], got["bitmap_hi"], got["bitmap_lo"], len(filled)))
    assert heard == {k for k, on in enumerate(filled) if on}


def test_cells_a_teammate_said_it_filled_count_while_it_is_alive():
    g = HGrid(0, (0.0, 0.0, 40.0, 20.0), params=WiserxParams(sensor_range_m=10.0))     # 2 rows x 4 columns
    g.hear(2, [1, 6])
    assert g.filled().tolist() == [[False, True, False, False], [False, False, True, False]]
    assert g.fill() == 0.25 and not g.own_filled().any()
    g.set_alive(2, False)
    assert g.fill() == 0.0                                # eq. (7): a failed robot's word stops counting
    g.set_alive(2, True)
    assert g.fill() == 0.25


def test_own_filled_is_what_the_own_positions_fill():
    g = HGrid(0, (0.0, 0.0, 40.0, 20.0), params=WiserxParams(sensor_range_m=10.0, fill_rule="pts2"))
    for x in (1.0, 2.0, 31.0):
        g.insert(0, x, 1.0, 1.0, 0)
    g.insert(1, 31.0, 2.0, 1.0, 0)                        # a teammate's estimate is not the robot's own
    assert g.own_filled().tolist() == [[True, False, False, False], [False] * 4]
    assert g.filled()[0, 3]


def test_out_of_uwb_reach_is_not_taken_for_failed_when_lora_says_alive():
    runs = {s: run_mission(MissionConfig(map_spec="cave:4:40x40", robots=3, seed=1, max_sim_s=3000, strategy=s,
                                         radio="eu868-g3")) for s in ("wiserx", "wiserx:lora")}
    alone, lora = (runs[s].explorer_stats() for s in ("wiserx", "wiserx:lora"))
    assert sum(alone["uwb_aoa_failures"]) > 0            # the cave's walls cut UWB and WiFi
    assert sum(lora["uwb_aoa_failures"]) == 0
    assert all(n > 0 for n in lora["digests_sent"]) and all(n > 0 for n in lora["digests_heard"])
    assert runs["wiserx"].radio["bytes_sent"] == [0, 0, 0]
    assert all(r.termination.startswith("complete") and r.coverage >= 0.99 for r in runs.values())
