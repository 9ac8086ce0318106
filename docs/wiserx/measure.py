"""One mission, the figures the WiSER-X section of the README reports, as one JSON line:
coverage when the last robot stopped by itself, that time, overlap then and at 90 % union
coverage, the times of 90 % and 95 % union coverage, each robot's stop time, LoRa bytes.

    PYTHONPATH=. NUMBA_NUM_THREADS=1 .venv/bin/python docs/wiserx/measure.py MAP SCHEME SEED [ROBOTS] [PROFILE] [FRAMES]
"""
import json
import sys

import numpy as np

import host_tools.mission as mission
from recorded_world import record_worlds
from world_sim.world import WorldParams


def main(argv):
    map_spec, scheme, seed = argv[0], argv[1], int(argv[2])
    robots = int(argv[3]) if len(argv) > 3 else 3
    profile = argv[4] if len(argv) > 4 else "realistic"
    frames = argv[5] if len(argv) > 5 else "own"
    worlds = record_worlds()
    marks = {"t_90_s": None, "t_95_s": None, "overlap_at_t90": None, "overlap_at_t95": None}
    stops = {}
    reach = {}

    def observe(now_us, agents):
        w = worlds[-1]
        if "mask" not in reach:
            from world_sim.ros_map import reachable_from_starts
            reach["mask"] = reachable_from_starts(w.occ, [w.true_pose(i) for i in range(len(agents))],
                                                  robot_radius_m=WorldParams().robot_radius_m)
            reach["n"] = int(reach["mask"].sum())
        m, n = reach["mask"], reach["n"]
        union = float((w.observed_union() & m).sum()) / n
        for level, key, okey in ((0.9, "t_90_s", "overlap_at_t90"), (0.95, "t_95_s", "overlap_at_t95")):
            if marks[key] is None and union >= level:
                own = sum(float((w.observed(i) & m).sum()) / n for i in range(len(agents)))
                marks[key], marks[okey] = now_us / 1e6, round(own - union, 4)
        for i, a in enumerate(agents):
            if a.done and i not in stops:
                stops[i] = now_us / 1e6

    cfg = mission.MissionConfig(map_spec=map_spec, robots=robots, seed=seed, max_sim_s=3600, radio="eu868-g3",
                                strategy=scheme, frames=frames)
    r = mission.run_mission(cfg, observer=observe, world_params=WorldParams().with_sensing_profile(profile))
    js = r.to_json()
    es = js["explorer_stats"]
    out = {"map": js["map"], "scheme": scheme, "seed": seed, "robots": robots, "profile": profile, "frames": frames,
           "coverage": js["coverage"], "t_total_s": js["t_total_s"], "termination": js["termination"],
           "overlap": js["overlap"], **marks, "stops_s": [stops.get(i) for i in range(robots)],
           "lora_bytes": int(sum(js["radio_stats"]["bytes_sent"])), "path_length_m": js["path_length_m"],
           "wall_s": js["wall_s"]}
    for key in ("soft_at_s", "hgrid_fill_permille", "waypoints_invalid", "uwb_aoa_failures", "uwb_aoa_revivals",
                "hgrid_points_teammates", "hgrid_cells_footprint"):
        if key in es:
            out[key] = es[key]
    print(json.dumps(out))


if __name__ == "__main__":
    main(sys.argv[1:])
