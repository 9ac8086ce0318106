"""The relative-position EKF's constants (../shared/schemes/wiserx.md sections 1.3, 2 and 4,
A1-A5), with units in the names. Each field's metadata holds its unit, valid range
(inclusive) and meaning, as firmware.params declares the explorer's; EkfParams checks
itself when built.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, fields


def _p(default, unit: str, lo, hi, doc: str):
    return field(default=default, metadata={"unit": unit, "lo": lo, "hi": hi, "doc": doc})


# Chi-square quantiles at 99 % (the spec's gate, section 2): 1 degree of freedom (a range or
# a bearing alone) and 2 (a range and a bearing of one stamp).
CHI2_99_1DOF = 6.634896601021214
CHI2_99_2DOF = 9.210340371976184          # -2 ln(0.01)


@dataclass(frozen=True)
class EkfParams:
    # Motion: constant velocity driven by white-noise acceleration of this power spectral
    # density, Q(dt) = q [[dt^3/3 I, dt^2/2 I], [dt^2/2 I, dt I]] (A1; q tuned by the NEES test
    # of section 6.2).
    accel_psd_m2ps3: float = _p(0.1, 'm^2/s^3', 0.0, 100.0, "q: white-noise acceleration of a teammate's motion")
    # R = diag(range_std^2, bearing_std^2): the sensor model's line-of-sight noise (section 2).
    range_std_m: float = _p(0.10, 'm', 1e-4, 100.0, 'UWB range noise (standard deviation)')
    bearing_std_rad: float = _p(math.radians(5.0), 'rad', 1e-4, math.pi, 'AoA bearing noise (standard deviation)')
    # P0: the first range and bearing turned into a position covariance; no velocity known.
    init_speed_std_mps: float = _p(0.5, 'm/s', 0.0, 100.0, "a new track's velocity uncertainty (per axis)")
    # Gate: normalised innovation squared above this rejects the sample (99 %).
    gate_1dof: float = _p(CHI2_99_1DOF, '', 0.0, 1e6, 'gate on a range or a bearing alone (chi-square, 1 dof)')
    gate_2dof: float = _p(CHI2_99_2DOF, '', 0.0, 1e6, 'gate on a range and bearing together (chi-square, 2 dof)')
    reinit_after_rejections: int = _p(3, 'samples', 1, 1000, 'after this many rejections in a row a track starts again')
    # A range and a bearing this close in time start a track together (their stamps rarely
    # coincide on real sensors).
    pair_max_gap_s: float = _p(0.5, 's', 0.0, 60.0, 'a range and a bearing this close in time start a track')
    # The Gaussian second-order filter's terms in the update (ekf.update): without them the
    # filter is overconfident wherever the range circle's sagitta across the position's
    # lateral spread exceeds the range noise (beyond ~13 m at 10 cm and 5 degrees; NEES test
    # A2 on ten seeds: time-averaged NEES 2.3 to 19.7, median 4.1, without; 1.8 to 1.9 with).
    second_order: bool = _p(True, 'bool', None, None, "the update's second-order terms of the range and bearing")
    # Closer than this the bearing's linearisation means nothing (two bodies cannot be closer).
    min_range_m: float = _p(0.1, 'm', 0.0, 10.0, 'no update while the predicted range is below this')
    # Window mode (A3-A5): all samples of window_s reduced to one range (mean of every second
    # sample) and one bearing (the largest cluster within window_cluster_rad, if it holds at
    # least window_min_share of the samples), with the pose at the window's middle.
    window_s: float = _p(5.0, 's', 0.1, 600.0, 'window mode: samples of this long make one update')
    window_cluster_rad: float = _p(math.radians(10.0), 'rad', 0.0, math.pi,
                                   "window mode: bearings this close to a sample are in its cluster")
    window_min_share: float = _p(0.5, '', 0.0, 1.0, "window mode: the cluster's least share of the window's bearings")

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(f.default, bool):
                if not isinstance(value, bool):
                    raise ValueError(f"EkfParams.{f.name} must be a bool, got {value!r}")
                continue
            lo, hi = f.metadata["lo"], f.metadata["hi"]
            ok_type = isinstance(value, int) if isinstance(f.default, int) else isinstance(value, (int, float))
            if isinstance(value, bool) or not ok_type or not math.isfinite(value) or not lo <= value <= hi:
                kind = "an integer" if isinstance(f.default, int) else "a number"
                raise ValueError(f"EkfParams.{f.name} must be {kind} in [{lo:g}, {hi:g}] {f.metadata['unit']}".rstrip()
                                 + f", got {value!r}")
