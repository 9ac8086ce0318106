"""Where a Pereira team left reachable ground unseen, and what its robots last decided about
the waypoints there. Runs one five-robot mission over eu868-g3, groups the reachable cells no
robot observed into 8-connected pockets, and prints for the largest pockets the last three
decisions each robot took on waypoints within 1.5 m of one: time (s), waypoint x, y (m),
e_bit, C if a teammate's claim covered its region, K if kept after the planning stage (x:
dropped), L if kept but ranked last.

    PYTHONPATH=. NUMBA_NUM_THREADS=1 .venv/bin/python docs/pereira/intel-gates/unseen_pockets.py \\
        ../shared/maps/intel.yaml 0 [NAME=VALUE ...]

(map, seed, then --set style overrides).
"""
import collections
import sys

import numpy as np
import scipy.ndimage as ndimage
from scipy.spatial import cKDTree

from firmware.schemes.pereira import scheme as pereira_scheme
from host_tools.mission import MissionConfig, run_mission
from host_tools.overrides import params_with, scheme_settings

NEAR_M = 1.5
decisions = []   # (t_s, robot, x, y, e_bit, claimed, kept, last)
filter_waypoints = pereira_scheme.Pereira.filter_waypoints


def logged_filter(self, view):
    held = list(self.s.waypoints.items)
    filter_waypoints(self, view)
    kept = {(w.x_m, w.y_m) for w in self.s.waypoints.items}
    others = self._explored_by_others()
    if held:
        graph = self.store.graph()
        labels = self._labels(graph, [(w.x_m, w.y_m) for w in held]) if others else [None] * len(held)
        for w, label in zip(held, labels):
            decisions.append((view.now_us / 1e6, self.s.robot_id, w.x_m, w.y_m, w.e_bit,
                              label is not None and label in others, (w.x_m, w.y_m) in kept,
                              (w.x_m, w.y_m) in self._last_resort))


pereira_scheme.Pereira.filter_waypoints = logged_filter
overrides = tuple((kv.split("=")[0], float(kv.split("=")[1])) for kv in sys.argv[3:])
config = MissionConfig(map_spec=sys.argv[1], robots=5, seed=int(sys.argv[2]), strategy="pereira",
                       max_sim_s=4000, radio="eu868-g3")
result = run_mission(config, params=params_with(overrides), scheme_settings=scheme_settings(overrides))
print("coverage", result.coverage, "robots", result.robot_status, "T_total", result.t_total_s)
occ = result.world.occ
unseen = result.reachable & ~result.world.observed_union()
pockets, n = ndimage.label(unseen, structure=np.ones((3, 3)))
cells = ndimage.sum(unseen, pockets, range(1, n + 1))
print(f"{unseen.sum() * occ.resolution_m ** 2:.1f} m2 unseen in {n} pockets")
for k in np.argsort(-cells)[:8]:
    rows, cols = np.nonzero(pockets == k + 1)
    xs = occ.origin_x_m + (cols + 0.5) * occ.resolution_m
    ys = occ.origin_y_m + (rows + 0.5) * occ.resolution_m
    print(f"pocket of {cells[k] * occ.resolution_m ** 2:.2f} m2: x {xs.min():.1f}-{xs.max():.1f}, "
          f"y {ys.min():.1f}-{ys.max():.1f}")
    tree = cKDTree(np.stack([xs, ys], axis=1))
    by_robot = collections.defaultdict(list)
    for d in decisions:
        if tree.query((d[2], d[3]))[0] < NEAR_M:
            by_robot[d[1]].append(d)
    for robot, ds in sorted(by_robot.items()):
        print(f"   robot {robot}: {len(ds)} decisions from {ds[0][0]:.0f} s, the last:",
              [(round(d[0]), round(d[2], 1), round(d[3], 1), round(d[4]), "C" if d[5] else "-",
                "K" if d[6] else "x", "L" if d[7] else "") for d in ds[-3:]])
