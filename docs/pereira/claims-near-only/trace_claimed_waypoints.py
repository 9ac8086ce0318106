"""Trace the waypoints inside a box: at every planning cycle from a time on where a robot holds
one, print the robot, where it is, whether no teammate explores (alone), and per waypoint: x, y,
e_bit, C if a teammate's claim covers its region, whether it lies in the window, the distance
to the nearest teammate's place (m), the bits left unseen once the teammates' places' view
counts as seen (in the window only), and K if the robot kept it after the planning stage.

    PYTHONPATH=. NUMBA_NUM_THREADS=1 .venv/bin/python docs/pereira/claims-near-only/trace_claimed_waypoints.py \\
        5 ../shared/maps/maze_b.yaml 60,15,95,50 0 pereira_claims_near_only=0

(the arguments: seed, map, the box x0,y0,x1,y1 in m, the first time in s, then --set style
overrides). On f72f457's code (no such test) this printed, at 36 s, robot 2 at the wing's door
dropping waypoints 14 to 16 m from every teammate's place, with all of their 50 kbit unseen by
the team, because a teammate's claim covered their region.
"""
import sys, math
import numpy as np
from firmware.schemes.pereira import scheme as S
from firmware.services.team_view import unseen_after_team_view_bit
from host_tools.mission import MissionConfig, run_mission
from host_tools.sweep import params_with, scheme_settings
cls = S.Pereira
x0, y0, x1, y1 = (float(v) for v in sys.argv[3].split(","))
t_from = float(sys.argv[4])
overrides = tuple((kv.split("=")[0], float(kv.split("=")[1])) for kv in sys.argv[5:])
orig_f = cls.filter_waypoints
def filt(self, view):
    items = list(self.s.waypoints.items)
    box = [w for w in items if x0 <= w.x_m <= x1 and y0 <= w.y_m <= y1]
    info = None
    if box and view.now_us >= t_from * 1e6:
        others = self._explored_by_others()
        graph = self.store.graph()
        self._label_grid(graph, view.sight, view.now_us)
        labels = self._labels(graph, [(w.x_m, w.y_m) for w in box])
        lm = self.s.local_map
        xy = np.array([(w.x_m, w.y_m) for w in box], float)
        inside = lm.cells_of(xy)[1]
        theirs, tree = self._teammates_places(graph)
        dnear = tree.query(xy)[0] if tree is not None else [math.inf] * len(box)
        lb = [None] * len(box)
        ask = np.flatnonzero(inside)
        if len(ask) and len(theirs):
            bits = unseen_after_team_view_bit(view.sight, lm.row0, lm.col0, xy[ask], theirs, self.s.params)
            for k, b in zip(ask.tolist(), bits.tolist()):
                lb[k] = round(b)
        info = [(round(w.x_m,1), round(w.y_m,1), round(w.e_bit), "C" if (l is not None and l in others) else "-", int(i), round(float(d),1), b)
                for w, l, i, d, b in zip(box, labels, inside.tolist(), dnear, lb)]
    orig_f(self, view)
    if info is not None:
        kept = {(round(w.x_m,1), round(w.y_m,1)) for w in self.s.waypoints.items}
        print(view.now_us // 1000000, "r", self.s.robot_id, "at", (round(view.x_m, 1), round(view.y_m, 1)),
              "alone", not self.s.roster.any_active(view.now_us),
              [(t + ("K" if t[:2] in kept else "x",)) for t in info], flush=True)
cls.filter_waypoints = filt
cfg = MissionConfig(map_spec=sys.argv[2], robots=5, seed=int(sys.argv[1]), strategy="pereira", max_sim_s=4000, radio="eu868-g3")
r = run_mission(cfg, params=params_with(overrides), scheme_settings=scheme_settings(overrides))
print("coverage", r.coverage)
