"""MR-TopoMap's parameters (mrtopomap.md section 2, 4 and 5), units in the names.

Each declared field (firmware.declared) has its unit, valid range and meaning, and is changed
for a run or a sweep with `--set mrtopomap.NAME=VALUE`. The descriptor's code scale and the
virtual scan's rays are plain fields: they are the meaning of the records on the air (every
robot must quantise and compare descriptors alike), not one robot's tuning.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from firmware.declared import check_declared, number


@dataclass(frozen=True)
class MrTopoParams:
    # ---- place descriptor (5.2): the records' meaning, not settable ----
    r_min_m: float = 0.2              # ranges clipped to [r_min_m, the scan's range_max] before the log
    log_r_lo_m: float = 0.2           # desc_mean's code scale: ln(0.2 m) .. ln(10 m) in 31 steps
    log_r_hi_m: float = 10.0
    std_hi: float = 1.4               # desc_std's code scale: 0 .. 1.4 (ln units) in 7 steps
    grid_rays: int = 96               # rays per virtual scan (3 per descriptor bin)
    # ---- Algorithm 1: vertex building (1.2, A4, A5, A18) ----
    th_build: float = number(0.97, '', 0.5, 1.0, "re-entry: a known vertex scoring this much (the code's build "
                             "threshold)")
    d_vertex_m: float = number(2.5, 'm', 0.5, 50.0, 'a new vertex only farther than this from every vertex held')
    r_reentry_m: float = number(4.0, 'm', 0.0, 100.0, 're-entry vertices are looked for this close')
    eval_every_m: float = number(0.25, 'm', 0.01, 100.0, 'Algorithm 1 runs at most every this much travel ...')
    eval_every_us: int = number(1_000_000, 'us', 1_000, 3_600_000_000, '... or this much time (scan stamps), '
                                'whichever comes first')
    # ---- unexplored directions (A10, A12, 5.5) ----
    ud_crop_m: float = number(12.0, 'm', 1.0, 100.0, 'side of the square around a vertex searched for frontiers')
    ud_min_cells: int = number(10, 'cells', 1, 100_000, 'an 8-connected frontier cluster needs this many cells')
    ud_class_edges_m: tuple[float, float] = (3.0, 6.0)    # distance classes 1: <= 3 m, 2: 3-6 m, 3: > 6 m
    ud_class_mid_m: tuple[float, float, float] = (1.5, 4.5, 7.5)   # f_i = vertex + this along the sector
    explored_radius_m: float = number(1.5, 'm', 0.0, 100.0, "a direction is explored when the robot comes this close "
                                      "to its f_i, or no reachable frontier cell is left this close to its cluster")
    # ---- Algorithm 2 made frame-free: merging (5.3, A1-A3) ----
    th_merge: float = number(0.95, '', 0.5, 1.0, 'a vertex pair scoring this much is a hypothesis (calibrated, 5.2)')
    th_grid_offset: float = number(0.04, '', 0.0, 0.5, 'a profile-grid cell needs th_merge - this ...')
    grid_top: int = number(16, 'places', 1, 1000, '... and is the best cell of one of this many distinct places for '
                           'the received vertex (the spec: 3; see merge.py)')
    grid_spacing_m: float = number(0.5, 'm', 0.1, 10.0, "the profile grid's lattice over the own map")
    grid_clearance_m: float = number(0.25, 'm', 0.0, 5.0, 'a grid cell lies at least this far from the nearest '
                                     'non-free cell')
    inlier_m: float = number(1.5, 'm', 0.01, 100.0, 'two hypotheses agree: the pair maps within this ...')
    inlier_deg: float = number(6.0, 'deg', 0.1, 180.0, '... and their yaws differ by at most this')
    cluster_sep_m: float = number(3.0, 'm', 0.0, 100.0, 'a hypothesis this close (and cluster_sep_deg) to a kept '
                                  'cluster is the same')
    cluster_sep_deg: float = number(10.0, 'deg', 0.0, 180.0, '... in yaw')
    k_min: int = number(4, 'hypotheses', 1, 1000, "merge on a consensus of at least this many (the paper's three or "
                        "more; three let look-alike triples through every check, see merge.py)")
    ratio: float = number(2.0, '', 1.0, 1000.0, "... at least this many times the best other cluster's support")
    nfa_max: float = number(0.01, 'clusters', 0.0, 1e6, '... and only if chance would give fewer than this many '
                            'clusters as strong (the a-contrario test in merge.py)')
    occ_radius_m: float = number(15.0, 'm', 0.0, 1000.0, "occupancy check: the teammate's vertices this close to an "
                                 "inlier")
    occ_depth_m: float = number(0.3, 'm', 0.0, 10.0, 'bad: deeper than this inside the own walls')
    occ_share: float = number(0.02, '', 0.0, 1.0, 'refuse when more than max(occ_tolerated, this share of those '
                              'tested) are bad')
    occ_tolerated: int = number(1, 'vertices', 0, 100_000, '... (the least number tolerated)')
    view_known: float = number(0.8, '', 0.0, 1.0, "view check: a mapped vertex whose virtual view the own map knows "
                               "this well ...")
    view_score: float = number(0.4, '', 0.0, 1.0, '... contradicts the cluster when its descriptor scores below this '
                               'there')
    view_share: float = number(0.12, '', 0.0, 1.0, 'refuse when more than max(view_tolerated, this share of such '
                               'vertices) contradict')
    view_tolerated: int = number(1, 'vertices', 0, 100_000, '... (the least number tolerated)')
    view_good: float = number(0.8, '', 0.0, 1.0, '... and confirms it when it scores this much or more there;')
    view_confirm: float = number(0.65, '', 0.0, 1.0, 'refuse when fewer than this share of such vertices confirm it,')
    view_min_seen: int = number(10, 'vertices', 0, 100_000, 'or fewer than this many could be tested (wait for more '
                                'records)')
    sigma_psi_deg: float = number(3.0, 'deg', 0.01, 180.0, "one descriptor yaw's error (5.2: medians 1-2 deg; 4-5 "
                                  "deg at 0.3 m in clutter) ...")
    sigma_pos_m: float = number(0.4, 'm', 0.001, 100.0, "... and one pair's position error: they weigh the "
                                "descriptor yaw against the Procrustes yaw in the fit")
    # ---- the scheme's schedule and planning (1.3, eq. 1) ----
    merge_period_s: float = number(5.0, 's', 0.5, 3600.0, "teammates' frames are estimated again this often (if "
                                   "their records or the own map changed)")
    grid_period_s: float = number(20.0, 's', 1.0, 3600.0, "the own map's profile grid is rendered again this often")
    link_period_s: float = number(60.0, 's', 0.0, 3600.0, "own direct merges go on the air (mrlink) when made, moved "
                                  "or withdrawn, and again this often; teammates' are weighed against them "
                                  "(links.py; 0: none sent or used)")
    w: float = number(0.5, '', 0.0, 1.0, "eq. (1)'s weight of the own vertices' centre against merged teammates'")
    team_near_m: float = number(3.0, 'm', 0.0, 100.0, "an own waypoint this close to a merged teammate's vertex (in "
                                "line of sight, no open direction near) is left to the team (0: never)")

    def __post_init__(self) -> None:
        check_declared(self)

    @property
    def inlier_rad(self) -> float:
        return math.radians(self.inlier_deg)

    @property
    def cluster_sep_rad(self) -> float:
        return math.radians(self.cluster_sep_deg)

    @property
    def th_grid(self) -> float:
        return self.th_merge - self.th_grid_offset


DEFAULT = MrTopoParams()
