"""How far WiSER-X's teammate estimates are from the truth just after an update (issue 24's
EKF acceptance: median <= 0.35 m in line of sight, <= 0.9 m behind walls): once per
simulated second after the first 20 s, every ordered pair whose track took an update in the
last second, its estimate's distance to the teammate's true position, split by whether a
wall stands between the two robots then; with the median distance between the two. Robots share one frame (frames shared), so each
robot's own odometry drift counts as error.

    PYTHONPATH=. NUMBA_NUM_THREADS=1 .venv/bin/python docs/wiserx/update_error.py MAP SECONDS PROFILE SEED...
        [--set wiserx.NAME=VALUE ...] [--png FILE]

--png draws the errors' cumulative distributions, in line of sight and behind walls, with
issue 24's bounds.
"""
import json
import math
import sys

import numpy as np

import host_tools.mission as mission
from host_tools.overrides import parse_overrides, scheme_settings
from recorded_world import record_worlds
from world_sim.raycast import wall_length_m
from world_sim.world import WorldParams


def one_mission(map_spec: str, secs: float, profile: str, seed: int, settings) -> dict[str, list[float]]:
    worlds = record_worlds()
    errors = {"los": [], "nlos": [], "los_distance": [], "nlos_distance": []}
    seen_update: dict[tuple[int, int], int] = {}

    def observe(now_us, agents):
        if now_us < 20_000_000:
            return
        w = worlds[-1]
        occ = w.occ
        for i, a in enumerate(agents):
            for j, track in a.scheme.relpos.tracks.items():
                if track.updated_us is None or seen_update.get((i, j)) == track.updated_us:
                    continue
                seen_update[(i, j)] = track.updated_us
                e = track.estimate(now_us, 1.0)
                if e is None:
                    continue
                xi, yi, _ = w.true_pose(i)
                xj, yj, _ = w.true_pose(j)
                walls = wall_length_m(w.clearance.wall_u8, occ.origin_x_m, occ.origin_y_m, occ.resolution_m, xi, yi, xj, yj)
                kind = "nlos" if walls > 0 else "los"
                errors[kind].append(math.hypot(e.x_m - xj, e.y_m - yj))
                errors[kind + "_distance"].append(math.hypot(xj - xi, yj - yi))

    mission.run_mission(mission.MissionConfig(map_spec=map_spec, robots=3, seed=seed, max_sim_s=secs,
                                              strategy="wiserx"),
                        observer=observe, scheme_settings=settings,
                        world_params=WorldParams().with_sensing_profile(profile))
    return errors


def plot(errors: dict[str, list[float]], title: str, path: str) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    for kind, bound, colour in (("los", 0.35, "tab:blue"), ("nlos", 0.9, "tab:red")):
        e = np.sort(errors[kind])
        if len(e):
            ax.plot(e, np.arange(1, len(e) + 1) / len(e), color=colour,
                    label=f"{'line of sight' if kind == 'los' else 'behind walls'} ({len(e)} updates)")
        ax.axvline(bound, color=colour, linestyle=":", linewidth=1)
    ax.axhline(0.5, color="grey", linewidth=0.5)
    ax.set_xscale("log")
    ax.set_xlabel("estimate's error just after an update (m); dotted: issue 24's medians")
    ax.set_ylabel("share of updates")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main(argv):
    png = argv[argv.index("--png") + 1] if "--png" in argv else None
    options = ("--set", "--png")
    sets = [argv[k + 1] for k, a in enumerate(argv) if a == "--set"]
    rest = [a for k, a in enumerate(argv) if a not in options and (k == 0 or argv[k - 1] not in options)]
    map_spec, secs, profile, seeds = rest[0], float(rest[1]), rest[2], [int(s) for s in rest[3:]] or [1]
    settings = scheme_settings(parse_overrides(sets))
    errors = {"los": [], "nlos": [], "los_distance": [], "nlos_distance": []}
    for seed in seeds:
        for k, v in one_mission(map_spec, secs, profile, seed, settings).items():
            errors[k] += v
    out = {"map": map_spec, "profile": profile, "seeds": seeds, "seconds": secs, "settings": dict(settings)}
    for k in ("los", "nlos"):
        e, d = np.array(errors[k]), np.array(errors[k + "_distance"])
        out[k] = {"updates": len(e), "median_m": round(float(np.median(e)), 2) if len(e) else None,
                  "p90_m": round(float(np.percentile(e, 90)), 2) if len(e) else None,
                  "median_distance_m": round(float(np.median(d)), 2) if len(d) else None}
    print(json.dumps(out))
    if png is not None:
        plot(errors, f"{map_spec.split('/')[-1]}, {profile} sensing, 3 robots, seeds {' '.join(map(str, seeds))}, "
                     f"{secs:g} s", png)


if __name__ == "__main__":
    main(sys.argv[1:])
