"""The geometry of Pereira's gate detector and region fold (pereira.md section 2 and 5.2),
units in the names.

The scheme's behaviour (margin, periods, expiry, gossip, revival) is declared in
firmware/params.py as pereira_* parameters, overridable with --set and listed in the
README. These stay here: every robot must fold the same records into the same regions, so
the fold's thresholds belong to the dialect's meaning rather than to one robot's tuning.
Only widening_kappa, the tuning knob the spec names (section 7), is taken from
ExplorationParams.pereira_widening_kappa by the scheme.
"""
from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class PereiraParams:
    # ---- gate detection on the robot's own map (5.2 a) ----
    r_min_m: float = 0.32             # narrowest passable clearance (robot radius + safety margin)
    gvd_angle_deg: float = 120.0      # nearest walls of a GVD pair at least this far apart, seen from the cell
    ridge_angle_deg: float = 60.0     # the same for the ridge, where widenings are looked for
    local_min_radius_m: float = 1.0   # candidate: no GVD cell within max(this, c) narrower by c_tie
    w_max_m: float = 5.1              # candidate: 2c at most this
    widening_kappa: float = 0.5       # candidate: some ridge cell with clearance >= (1 + kappa) c ...
    widening_radius_m: float = 3.0    # ... within max(this, widening_radius_c * c)
    widening_radius_c: float = 3.0
    widening_off_axis_deg: float = 45.0   # ... at least this far off the jamb axis (beyond the gate line)
    observed_margin_m: float = 0.5    # candidate: nearest frontier unknown cell >= c + this
    nms_radius_m: float = 1.5         # non-maximum suppression: max(this, nms_radius_c * c)
    nms_radius_c: float = 2.0
    c_tie_m: float = 0.25             # clearances this close count as tied (0.1 m bumps, on both walls)
    side_depth_m: float = 0.5         # across its axis, free space reaches c + this on both sides
    jamb_search_m: float = 0.3        # second jamb: nearest wall within c + this, >= gvd_angle_deg from the first
    # ---- confirmation (5.2 a.6) ----
    k_confirm: int = 3                # cycles in a row a gate must be seen
    confirm_dist_m: float = 0.3       # "the same gate" between cycles
    confirm_angle_deg: float = 15.0
    # ---- places (5.2 b) ----
    clear_cap_m: float = 2.6          # certified radius computed up to this (edges never need more than d_connect)
    # ---- the fold (5.2 c) ----
    d_connect_m: float = 2.5          # certified edges at most this long
    r_match_m: float = 0.75           # gate records within this and r_match_deg fold into one gate
    r_match_deg: float = 30.0
    gate_extension_m: float = 0.15    # gate segment pushed this far into each jamb
    side_radius_m: float = 2.5        # a gate side is real if a place on it lies this close to the gate
    # ---- claim resolution (5.3) ----
    resolve_radius_m: float = 2.5     # nearest place to a claim's anchor, no gate between
    virtual_resolve_m: float = 1.0    # or a virtual region whose gate lies this close

    # integer thresholds the fold uses (wire units: dm, pi/256 dir codes, cm)
    @property
    def d_connect_dm(self) -> int:
        return int(round(self.d_connect_m * 10))

    @property
    def r_match_dm(self) -> int:
        return int(round(self.r_match_m * 10))

    @property
    def r_match_codes(self) -> int:
        """Largest dir_code difference (modulo 256) within r_match_deg."""
        return int(math.floor(self.r_match_deg / 180.0 * 256 + 1e-9))

    @property
    def gate_extension_cm(self) -> int:
        return int(round(self.gate_extension_m * 100))

    @property
    def side_radius_cm(self) -> int:
        return int(round(self.side_radius_m * 100))

    @property
    def resolve_radius_dm(self) -> int:
        return int(round(self.resolve_radius_m * 10))

    @property
    def virtual_resolve_cm(self) -> int:
        return int(round(self.virtual_resolve_m * 100))


PARAMS = PereiraParams()


def with_tuning(widening_kappa: float) -> PereiraParams:
    """PARAMS with the one knob a robot's parameters set (ExplorationParams.pereira_widening_kappa):
    the scheme and a host finding a map's doorways with the same detector use this."""
    return PARAMS if widening_kappa == PARAMS.widening_kappa else \
        PereiraParams(**{**PARAMS.__dict__, "widening_kappa": widening_kappa})
