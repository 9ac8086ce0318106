"""MR-TopoMap's parameters (mrtopomap.md section 2, 4 and 5), units in the names.

Kept in the package until the scheme is wired in; then they belong in firmware/params.py
(a typed MrTopoParams overridable with --set), as the other schemes' packages do.
"""
from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class MrTopoParams:
    # ---- place descriptor (5.2) ----
    r_min_m: float = 0.2              # ranges clipped to [r_min_m, the scan's range_max] before the log
    log_r_lo_m: float = 0.2           # desc_mean's code scale: ln(0.2 m) .. ln(10 m) in 31 steps
    log_r_hi_m: float = 10.0
    std_hi: float = 1.4               # desc_std's code scale: 0 .. 1.4 (ln units) in 7 steps
    # ---- Algorithm 1: vertex building (1.2, A4, A5, A18) ----
    th_build: float = 0.97            # re-entry: a known vertex scoring this much (code's build threshold)
    d_vertex_m: float = 2.5           # a new vertex only farther than this from every vertex held
    r_reentry_m: float = 4.0          # re-entry vertices are looked for this close
    eval_every_m: float = 0.25        # Algorithm 1 runs at most every this much travel ...
    eval_every_us: int = 1_000_000    # ... or this much time (scan stamps), whichever comes first
    # ---- unexplored directions (A10, A12, 5.5) ----
    ud_crop_m: float = 12.0           # side of the square around the vertex searched for frontiers
    ud_min_cells: int = 10            # an 8-connected frontier cluster needs this many cells (1 m at 0.1 m)
    ud_class_edges_m: tuple[float, float] = (3.0, 6.0)    # distance classes 1: <= 3 m, 2: 3-6 m, 3: > 6 m
    ud_class_mid_m: tuple[float, float, float] = (1.5, 4.5, 7.5)   # f_i = vertex + this along the sector
    explored_radius_m: float = 1.5    # a sector is explored when the robot comes this close to f_i,
    #                                   or no reachable frontier cell is left this close to its cluster
    # ---- Algorithm 2 made frame-free: merging (5.3, A1-A3) ----
    th_merge: float = 0.95            # a vertex pair scoring this much is a hypothesis (calibrated, 5.2)
    th_grid_offset: float = 0.04      # a profile-grid cell needs th_merge - this ...
    grid_top: int = 16                # ... and is the best cell of one of this many distinct places (>= cluster_sep
    #                                   apart) for the received vertex (the spec: its 3 best cells; see merge.py)
    grid_spacing_m: float = 0.5       # the profile grid's lattice over the own map
    grid_rays: int = 96               # rays per virtual scan (3 per bin)
    grid_clearance_m: float = 0.25    # a grid cell lies at least this far from the nearest non-free cell
    inlier_m: float = 1.5             # two hypotheses agree: the pair maps within this ...
    inlier_deg: float = 6.0           # ... and their yaws differ by at most this
    cluster_sep_m: float = 3.0        # a hypothesis this close (and cluster_sep_deg) to a kept cluster is the same
    cluster_sep_deg: float = 10.0
    k_min: int = 4                    # merge on a consensus of at least this many (the paper's "three or more";
    #                                   the spec's K = 3 let look-alike triples through every check, see merge.py)
    ratio: float = 2.0                # ... at least this many times the best other cluster's support
    nfa_max: float = 0.01             # ... and only if chance would give fewer than this many clusters as strong
    #                                   (the a-contrario test in merge.py; calibrated on static tests, see there)
    occ_radius_m: float = 15.0        # occupancy check: the teammate's vertices this close to an inlier
    occ_depth_m: float = 0.3          # bad: deeper than this inside the own walls
    occ_share: float = 0.02           # reject when more than max(occ_tolerated, occ_share * tested) are bad
    occ_tolerated: int = 1
    view_known: float = 0.8           # view check: a mapped vertex whose virtual view the own map knows this well ...
    view_score: float = 0.4           # ... contradicts the cluster when its descriptor scores below this there
    view_share: float = 0.12          # refuse when more than max(view_tolerated, view_share * such vertices) contradict
    view_tolerated: int = 1
    view_good: float = 0.8            # ... and confirms it when it scores this much or more there;
    view_confirm: float = 0.65        # refuse when fewer than this share of such vertices confirm it,
    view_min_seen: int = 10           # or fewer than this many could be tested (too little of the own map known
    #                                   where the teammate was to confirm anything: wait for more records)
    sigma_psi_deg: float = 3.0        # one descriptor yaw's error (5.2: medians 1-2 deg; 4-5 deg at 0.3 m in clutter)
    sigma_pos_m: float = 0.4          # ... and one pair's position error: they weigh the descriptor yaw against
    #                                   the Procrustes yaw in the fit (calibrated on static tests)

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
