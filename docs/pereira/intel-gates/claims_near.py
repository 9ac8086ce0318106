"""Who claimed the regions near a point, when, from where, and which waypoints the claimant
held then: runs one five-robot Pereira mission over eu868-g3 and prints every claim (explored)
of a region with a place within R metres of (X, Y), with the claimant's waypoints after its
planning stage (x, y, e_bit, region index in its graph).

    PYTHONPATH=. NUMBA_NUM_THREADS=1 .venv/bin/python docs/pereira/intel-gates/claims_near.py \\
        ../shared/maps/intel.yaml 0 9 20 4
"""
import sys

import numpy as np

from firmware.schemes.pereira import scheme as pereira_scheme
from host_tools.mission import MissionConfig, run_mission

X, Y, R = (float(v) for v in sys.argv[3:6])
Pereira = pereira_scheme.Pereira
judge_regions, after_plan = Pereira._judge_regions, Pereira.after_plan
now_s = {}


def logged_judge(self):
    graph = self.store.graph()
    before = dict(self._claimed)
    held = list(self.s.waypoints.items)
    judge_regions(self)
    for rid, said in self._claimed.items():
        k = graph.region_index(rid)
        if before.get(rid) == said or not said[3] or k is None:
            continue
        xy = graph.places[list(graph.regions[k].places), :2] / 10.0
        if np.hypot(xy[:, 0] - X, xy[:, 1] - Y).min() > R:
            continue
        labels = self._labels(graph, [(w.x_m, w.y_m) for w in held]) if held else []
        print(f"{now_s[self.s.robot_id]:.0f} s robot {self.s.robot_id} at ({self._xy[0]:.1f}, {self._xy[1]:.1f}) "
              f"claims region {k} (anchor {said[:2]} dm, {len(xy)} places, x {xy[:, 0].min():.1f}-{xy[:, 0].max():.1f}, "
              f"y {xy[:, 1].min():.1f}-{xy[:, 1].max():.1f}); its waypoints:",
              [(round(w.x_m, 1), round(w.y_m, 1), round(w.e_bit), label) for w, label in zip(held, labels)])


def timed_after_plan(self, pose, now_us):
    now_s[self.s.robot_id] = now_us / 1e6
    after_plan(self, pose, now_us)


Pereira._judge_regions, Pereira.after_plan = logged_judge, timed_after_plan
result = run_mission(MissionConfig(map_spec=sys.argv[1], robots=5, seed=int(sys.argv[2]), strategy="pereira",
                                   max_sim_s=4000, radio="eu868-g3"))
print("coverage", result.coverage)
