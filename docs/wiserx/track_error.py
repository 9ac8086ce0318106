"""How far each robot's teammate estimates (WiSER-X's relpos tracks) are from the truth, once
per simulated second after the first 20 s, over every ordered pair of robots: the median and
90th percentile error (m), and the share of pair-seconds with an estimate updated within the
last 30 s. Robots share one frame here (frames shared), so the truth needs no transform;
each robot's own odometry drift counts as error.

    PYTHONPATH=. NUMBA_NUM_THREADS=1 .venv/bin/python docs/wiserx/track_error.py MAP SECONDS PROFILE [SEED]
"""
import json
import math
import sys

import numpy as np

import host_tools.mission as mission
from recorded_world import record_worlds
from world_sim.world import WorldParams


def main(argv):
    map_spec, secs, profile = argv[0], float(argv[1]), argv[2]
    seed = int(argv[3]) if len(argv) > 3 else 1
    worlds, errs, avail = record_worlds(), [], []

    def observe(now_us, agents):
        if now_us < 20_000_000:
            return
        for i, a in enumerate(agents):
            est = {e.peer_id: e for e in a.scheme.relpos.estimates(now_us, 30.0)}
            for j in range(len(agents)):
                if j != i:
                    e = est.get(j)
                    avail.append(e is not None)
                    if e is not None:
                        tx, ty, _ = worlds[-1].true_pose(j)
                        errs.append(math.hypot(e.x_m - tx, e.y_m - ty))

    r = mission.run_mission(mission.MissionConfig(map_spec=map_spec, robots=3, seed=seed, max_sim_s=secs,
                                                  strategy="wiserx"),
                            observer=observe, world_params=WorldParams().with_sensing_profile(profile))
    e = np.array(errs)
    counts = {k[8:]: int(sum(v)) for k, v in r.to_json()["explorer_stats"].items() if k.startswith("uwb_aoa_")}
    print(json.dumps({"map": map_spec, "profile": profile, "seed": seed, "seconds": secs, "pair_seconds": len(avail),
                      "median_m": round(float(np.median(e)), 2), "p90_m": round(float(np.percentile(e, 90)), 2),
                      "available": round(float(np.mean(avail)), 3), "samples": counts}))


if __name__ == "__main__":
    main(sys.argv[1:])
