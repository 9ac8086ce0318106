"""The relative-position EKF's constants (../shared/schemes/wiserx.md sections 1.3, 2 and 4,
A1-A5), with units in the names. Each field declares its unit, valid range
(inclusive) and meaning (firmware.declared); both classes check themselves when built, and
`--set wiserx.NAME=VALUE` changes a WiserxParams field for a run or a sweep.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from firmware.declared import check_declared, choice, flag, number

# Chi-square quantiles at 99 % (the spec's gate, section 2): 1 degree of freedom (a range or
# a bearing alone) and 2 (a range and a bearing of one stamp).
CHI2_99_1DOF = 6.634896601021214
CHI2_99_2DOF = 9.210340371976184          # -2 ln(0.01)


@dataclass(frozen=True)
class EkfParams:
    # Motion: constant velocity driven by white-noise acceleration of this power spectral
    # density, Q(dt) = q [[dt^3/3 I, dt^2/2 I], [dt^2/2 I, dt I]] (A1; q tuned by the NEES test
    # of section 6.2).
    accel_psd_m2ps3: float = number(0.1, 'm^2/s^3', 0.0, 100.0, "q: white-noise acceleration of a teammate's motion")
    # R = diag(range_std^2, bearing_std^2): the sensor model's line-of-sight noise (section 2).
    range_std_m: float = number(0.10, 'm', 1e-4, 100.0, 'UWB range noise (standard deviation)')
    bearing_std_rad: float = number(math.radians(5.0), 'rad', 1e-4, math.pi, 'AoA bearing noise (standard deviation)')
    # P0: the first range and bearing turned into a position covariance; no velocity known.
    init_speed_std_mps: float = number(0.5, 'm/s', 0.0, 100.0, "a new track's velocity uncertainty (per axis)")
    # Gate: normalised innovation squared above this rejects the sample (99 %).
    gate_1dof: float = number(CHI2_99_1DOF, '', 0.0, 1e6, 'gate on a range or a bearing alone (chi-square, 1 dof)')
    gate_2dof: float = number(CHI2_99_2DOF, '', 0.0, 1e6, 'gate on a range and bearing together (chi-square, 2 dof)')
    reinit_after_rejections: int = number(3, 'samples', 1, 1000, 'after this many rejections in a row a track starts again')
    # A range and a bearing this close in time start a track together (their stamps rarely
    # coincide on real sensors).
    pair_max_gap_s: float = number(0.5, 's', 0.0, 60.0, 'a range and a bearing this close in time start a track')
    # The Gaussian second-order filter's terms in the update (ekf.update): without them the
    # filter is overconfident wherever the range circle's sagitta across the position's
    # lateral spread exceeds the range noise (beyond ~13 m at 10 cm and 5 degrees; NEES test
    # A2 on ten seeds: time-averaged NEES 2.3 to 19.7, median 4.1, without; 1.8 to 1.9 with).
    second_order: bool = flag(True, "the update's second-order terms of the range and bearing")
    # Closer than this the bearing's linearisation means nothing (two bodies cannot be closer).
    min_range_m: float = number(0.1, 'm', 0.0, 10.0, 'no update while the predicted range is below this')
    # Window mode (A3-A5): all samples of window_s reduced to one range (mean of every second
    # sample) and one bearing (the largest cluster within window_cluster_rad, if it holds at
    # least window_min_share of the samples), with the pose at the window's middle.
    window_s: float = number(5.0, 's', 0.1, 600.0, 'window mode: samples of this long make one update')
    window_cluster_rad: float = number(math.radians(10.0), 'rad', 0.0, math.pi,
                                   "window mode: bearings this close to a sample are in its cluster")
    window_min_share: float = number(0.5, '', 0.0, 1.0, "window mode: the cluster's least share of the window's bearings")
    # Behind walls (A30, where the scheme asks for it): the noise of a range or bearing taken
    # while the own map shows walls between the robot and the track's prediction.
    nlos_range_std_per_wall_m: float = number(0.3, 'm', 0.0, 100.0, 'range noise added per wall in between (A30)')
    nlos_bearing_std_factor: float = number(2.0, '', 1.0, 100.0, 'bearing noise multiplied with walls in between (A30)')

    def __post_init__(self) -> None:
        check_declared(self)

    def noise(self, walls: int = 0) -> tuple[float, float]:
        """(range_std_m, bearing_std_rad) of a sample with `walls` walls in between."""
        if walls <= 0:
            return self.range_std_m, self.bearing_std_rad
        return (self.range_std_m + self.nlos_range_std_per_wall_m * walls,
                self.bearing_std_rad * self.nlos_bearing_std_factor)


FILL_RULES = ("disc", "pts2")


@dataclass(frozen=True)
class WiserxParams:
    """The constants of the track layer (relpos), the coverage record (hgrid) and the utility
    (../shared/schemes/wiserx.md sections 1.4-1.8, 2 and A3-A30); the default is the spec's
    complete mode, `WiserxParams.paper()` its paper mode."""

    # --- relpos: the per-teammate track layer (A3, A4, A18, A19, A26) ---
    # A bearing counts only within bearing_median_tol of the circular median of the last
    # bearing_median_k bearings to that teammate, each taken as its residual against the
    # track's prediction at its time (so a teammate driving past does not look like
    # multipath); with fewer than bearing_median_min of them, only the EKF's gate decides.
    bearing_median_k: int = number(5, 'samples', 1, 100, 'bearings whose circular median a new bearing must be near')
    bearing_median_min: int = number(3, 'samples', 1, 100, 'bearings needed before the median check applies')
    bearing_median_tol_rad: float = number(math.radians(10.0), 'rad', 0.0, math.pi,
                                       "a bearing's largest distance from the recent median")
    # A range jumping from the last accepted one by more than range_jump_m plus
    # range_jump_speed_mps times the time between them is held back, unless range_jump_agree
    # held-back ranges in a row agree with each other within range_jump_m (the code's 3 m rule).
    range_jump_m: float = number(3.0, 'm', 0.0, 1000.0, 'a range jumping this far from the last accepted one is held back')
    range_jump_speed_mps: float = number(2.0, 'm/s', 0.0, 100.0, 'the jump allowed grows at this rate with the gap in time')
    range_jump_agree: int = number(3, 'samples', 1, 100, 'held-back ranges that agree in a row are taken')
    # Neither a range nor a bearing of a teammate for this long: it failed (tau = 0); the
    # next sample revives it (A18).
    silence_fail_s: float = number(30.0, 's', 0.1, 1e6, 'a teammate not heard for this long counts as failed')
    # An estimate counts for beta (eq. 3) while its last accepted update is this recent (A13).
    fresh_s: float = number(30.0, 's', 0.0, 1e6, "an estimate counts for beta this long after its last update")
    # Estimates farther than this outside the boundary are not recorded (A26).
    boundary_margin_m: float = number(2.0, 'm', 0.0, 1000.0, 'estimates this far outside the boundary are not recorded')

    # --- hgrid: the coverage record (1.4, A6-A9, 5.8) ---
    sensor_range_m: float = number(10.0, 'm', 0.1, 1000.0, 'r: the LiDAR range, the hgrid cell side at most')
    insert_period_s: float = number(5.0, 's', 0.1, 1e4, 'own pose and fresh estimates go into the hgrid this often')
    fill_rule: str = choice("disc", FILL_RULES, "disc: >= fill_disc_share of a cell within r of recorded "
                             "positions; pts2: >= 2 recorded positions in the cell (the authors' code)")
    fill_disc_share: float = number(0.5, '', 0.0, 1.0, 'disc rule: the share of a cell within r of positions that fills it')
    fill_lattice_m: float = number(1.0, 'm', 0.05, 100.0, 'disc rule: the spacing of the points a cell is tested at')
    footprint_min_area_m2: float = number(25.0, 'm^2', 0.0, 1e6, 'an hgrid cell with less navigable area is not counted')
    soft_fill: float = number(0.85, '', 0.0, 1.0, 'soft termination: from this fill on, frontiers with too much loss are invalid')
    hard_fill: float = number(0.95, '', 0.0, 1.0, 'hard termination: at this fill the robot stops (if hard_enabled)')
    hard_enabled: bool = flag(False, 'stop at hard_fill')
    tau_enabled: bool = flag(True, "eq. (7): a failed teammate's points stop counting (else eq. 6)")
    # Without deployment knowledge (no boundary given): a square this wide around the start.
    fallback_boundary_m: float = number(100.0, 'm', 1.0, 1e5, 'the boundary assumed when none is given')

    # --- utility: eqs. (2)-(7) (1.5, A10-A16) ---
    # kappa1: the authors' code has r / 2 (paper mode). The complete mode takes 0.8 r (the
    # spec's ablation, A11): its viewpoints are the planner's waypoints, which stand up to
    # d_cam (9.5 m) back from the unknown they look at, not frontier cells, and a teammate's
    # recorded position stands for what its 10 m LiDAR saw around it. Intel lab, 3 robots,
    # realistic sensing, seed 1: last self-stop 1253 s at r / 2, 806 s at 0.8 r; coverage
    # then 0.993 and 0.974.
    kappa1_m: float = number(8.0, 'm', 0.0, 1000.0, "the sigmoid's midpoint (0.8 r; r / 2 in paper mode)")
    kappa2_m: float = number(0.1, 'm', 1e-3, 1000.0, "the sigmoid's steepness")
    info_cell_m: float = number(0.5, 'm', 0.05, 10.0, 'unknown cells are counted in blocks of this side for I and E')
    beta_min_distance_m: float = number(1.12, 'm', 1.0, 1000.0, 'beta = log10(max(d, this)) (>= 0.05 at 1.12 m)')
    invalid_ratio: float = number(0.90, '', 0.0, 1.0, 'after soft: a viewpoint losing more than this share of I_0 is invalid')
    commit_share: float = number(0.5, '', 0.0, 1.0, 'a target is kept until its remaining path is this share of its first')
    relative_sensing: bool = flag(True, 'use UWB and AoA (False: wiserx-blind)')
    # A30: a sample taken while the own map shows walls between this robot and where the
    # track predicts the teammate counts with the noise of EkfParams.noise(walls). Off: on
    # the Intel lab (3 robots, realistic sensing, seeds 1-4, 300 s; docs/wiserx/update_error.py)
    # it took more samples and left the error just after an update no smaller (median 1.12 m
    # in line of sight and 3.59 m behind walls, against 0.88 m and 3.52 m without).
    nlos_from_map: bool = flag(False, "inflate a range's and a bearing's noise by the walls the own map shows in "
                               "between (A30)")

    # --- the LoRa digest (5.6; the `lora` variant) ---
    lora_digest: bool = flag(False, "send the own filled hgrid cells over LoRa, 64 a record (True: wiserx-lora)")
    # The spec's 30 s, less: a digest late in its TDMA slot must not read as 30 s of silence
    # (the heartbeat, every 10 s, keeps a robot alive as well).
    digest_period_s: float = number(20.0, 's', 1.0, 3600.0, 'one digest record (64 cells) this often, round robin')

    def __post_init__(self) -> None:
        check_declared(self)
        if self.soft_fill > self.hard_fill:
            raise ValueError(f"WiserxParams.soft_fill ({self.soft_fill:g}) must not exceed hard_fill ({self.hard_fill:g})")

    @classmethod
    def paper(cls, **changes) -> WiserxParams:
        """The spec's paper mode: the authors' fill rule (>= 2 positions per cell), a 5 m2
        footprint, soft 0.85 and hard 0.95, kappa1 = r / 2."""
        return cls(**{"fill_rule": "pts2", "footprint_min_area_m2": 5.0, "hard_enabled": True, "kappa1_m": 5.0,
                      **changes})
