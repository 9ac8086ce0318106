"""What the simulated UWB ranger and WiFi angle-of-arrival sensor measure: two named
profiles, `paper` and `realistic` (../shared/schemes/wiserx.md section 5.4), one source of
truth for every number the world's UWB and AoA models use.

`paper` is the WiSER-X paper's simulation (true geometry plus zero-mean Gaussian noise,
sigma_r 10 cm, sigma_phi 5 degrees, one range and one bearing per peer every 5 s).
`realistic` adds what walls do: a late first path behind walls (NLOS bias and extra spread
per metre of wall), late-path outliers, wall-dependent dropouts, millimetre output; AoA
bearings every 5 s (one WSR sweep) with multipath outliers, worse behind walls. The NLOS
bias per metre of wall is the world's earlier model (excess delay of a dielectric with
relative permittivity ~5: sqrt(5) - 1 = 1.24); the outlier and dropout rates and the NLOS
AoA figures are engineering estimates, to be replaced by logged hardware statistics.

A path is NLOS when the straight line between the two robots crosses any wall; `wall_m` is
the length of wall it crosses (world_sim.raycast.pair_wall_lengths_m).

Randomness: every (robot, peer, firing) takes the same draws whatever the profile, the
geometry or the outcome (UWB_DRAWS uniforms and one normal; AOA_DRAWS uniforms and one
normal), so changing an outlier or dropout rate changes that sample only, never a later
number. The functions here are vectorised over peers and take the draws as arguments: the
world draws them from the robot's own stream, the tests from theirs.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

import numpy as np

# Uniform draws per sample (the one normal draw comes besides): detection, outlier, outlier size.
UWB_DRAWS = 3
# Detection, outlier, outlier kind, outlier value, sign of a spurious peak.
AOA_DRAWS = 5

SENSING_PROFILE_HELP = ("what the simulated UWB and WiFi AoA measure: 'paper' (the WiSER-X paper's Gaussian "
                        "noise, 10 cm and 5 degrees, every 5 s) or 'realistic' (NLOS bias, spread, outliers and "
                        "dropouts behind walls, mm output; ranges at 2 Hz, bearings every 5 s)")


def _check_fields(obj, limits: dict[str, tuple[float, float]]) -> None:
    """Every field a finite number within its inclusive (lo, hi); ValueError naming it."""
    cls = type(obj).__name__
    for f in fields(obj):
        if f.name == "name":
            continue
        value = getattr(obj, f.name)
        if not isinstance(value, (int, float)) or isinstance(value, bool) or not math.isfinite(value):
            raise ValueError(f"{cls}.{f.name} must be a finite number, got {value!r}")
        lo, hi = limits[f.name]
        if not lo <= value <= hi:
            raise ValueError(f"{cls}.{f.name} must be in [{lo:g}, {hi:g}], got {value!r}")


@dataclass(frozen=True)
class UwbModel:
    """Two-way ranging between two robots' UWB modules.

    range = true distance + noise, and behind walls (wall_m > 0) also
      + nlos_bias_m + nlos_bias_per_wall_m * wall_m, and the noise's variance is
      los_noise_std_m^2 + (nlos_extra_std_m + nlos_extra_std_per_wall_m * wall_m)^2;
    with probability outlier_prob_los / outlier_prob_nlos a late first path adds U(outlier_min_m,
    outlier_max_m); clipped at 0 and rounded to resolution_m (0: not rounded). A range is
    measured with probability exp(-detection_decay_per_wall_m * wall_m), and never beyond
    range_max_m."""

    los_noise_std_m: float
    nlos_bias_m: float
    nlos_bias_per_wall_m: float           # m of delay per m of wall
    nlos_extra_std_m: float
    nlos_extra_std_per_wall_m: float      # m of spread per m of wall
    outlier_prob_los: float
    outlier_prob_nlos: float
    outlier_min_m: float
    outlier_max_m: float
    detection_decay_per_wall_m: float     # 1/m: 1.0 = p_det exp(-w / 1 m); 0 = no dropouts
    range_max_m: float
    resolution_m: float                   # 0: continuous
    rate_hz: float                        # rangings per second per ordered pair

    LIMITS = {
        "los_noise_std_m": (0.0, 10.0), "nlos_bias_m": (0.0, 100.0), "nlos_bias_per_wall_m": (0.0, 100.0),
        "nlos_extra_std_m": (0.0, 10.0), "nlos_extra_std_per_wall_m": (0.0, 10.0),
        "outlier_prob_los": (0.0, 1.0), "outlier_prob_nlos": (0.0, 1.0),
        "outlier_min_m": (0.0, 100.0), "outlier_max_m": (0.0, 100.0),
        "detection_decay_per_wall_m": (0.0, 1000.0), "range_max_m": (0.0, 10_000.0),
        "resolution_m": (0.0, 1.0), "rate_hz": (1e-3, 1000.0),
    }

    def __post_init__(self) -> None:
        _check_fields(self, self.LIMITS)
        if self.outlier_min_m > self.outlier_max_m:
            raise ValueError(f"UwbModel.outlier_min_m ({self.outlier_min_m!r}) must not exceed outlier_max_m "
                             f"({self.outlier_max_m!r})")

    def measure(self, distance_m: np.ndarray, wall_m: np.ndarray, u: np.ndarray,
                z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(ranges_m, measured) for true distances and wall lengths (shape (k,)), given the
        draws u (shape (k, UWB_DRAWS), uniform in [0, 1)) and z (shape (k,), standard normal).
        `measured` is False where the sample is lost (out of range or a dropout)."""
        d = np.asarray(distance_m, dtype=np.float64)
        w = np.asarray(wall_m, dtype=np.float64)
        nlos = w > 0.0
        extra = np.where(nlos, self.nlos_extra_std_m + self.nlos_extra_std_per_wall_m * w, 0.0)
        std = np.sqrt(self.los_noise_std_m ** 2 + extra ** 2)
        bias = np.where(nlos, self.nlos_bias_m + self.nlos_bias_per_wall_m * w, 0.0)
        p_out = np.where(nlos, self.outlier_prob_nlos, self.outlier_prob_los)
        late = np.where(u[:, 1] < p_out, self.outlier_min_m + (self.outlier_max_m - self.outlier_min_m) * u[:, 2], 0.0)
        r = np.maximum(d + bias + std * z + late, 0.0)
        if self.resolution_m > 0.0:
            r = np.round(r / self.resolution_m) * self.resolution_m
        measured = (d <= self.range_max_m) & (u[:, 0] < np.exp(-self.detection_decay_per_wall_m * w))
        return r, measured


@dataclass(frozen=True)
class AoaModel:
    """Angle of arrival of a peer's WiFi packets (one bearing per sweep).

    In line of sight: the true bearing + N(0, los_noise_std_rad); with probability
    los_outlier_prob a bearing uniform on the circle instead. Behind walls: N(0,
    nlos_noise_std_rad), and with probability nlos_outlier_prob a multipath bearing: a
    spurious peak at +-U(spurious_min_rad, spurious_max_rad) from the direct path (share
    nlos_spurious_share of them; reflection-like) or uniform on the circle (the rest).
    Measured with probability exp(-detection_decay_per_wall_m * wall_m), never beyond
    range_max_m."""

    los_noise_std_rad: float
    los_outlier_prob: float
    nlos_noise_std_rad: float
    nlos_outlier_prob: float
    nlos_spurious_share: float
    spurious_min_rad: float
    spurious_max_rad: float
    detection_decay_per_wall_m: float     # 1/m: 0.5 = p_det exp(-w / 2 m); 0 = no dropouts
    range_max_m: float
    rate_hz: float                        # bearings per second per peer

    LIMITS = {
        "los_noise_std_rad": (0.0, math.pi), "los_outlier_prob": (0.0, 1.0),
        "nlos_noise_std_rad": (0.0, math.pi), "nlos_outlier_prob": (0.0, 1.0), "nlos_spurious_share": (0.0, 1.0),
        "spurious_min_rad": (0.0, math.pi), "spurious_max_rad": (0.0, math.pi),
        "detection_decay_per_wall_m": (0.0, 1000.0), "range_max_m": (0.0, 10_000.0), "rate_hz": (1e-3, 1000.0),
    }

    def __post_init__(self) -> None:
        _check_fields(self, self.LIMITS)
        if self.spurious_min_rad > self.spurious_max_rad:
            raise ValueError(f"AoaModel.spurious_min_rad ({self.spurious_min_rad!r}) must not exceed "
                             f"spurious_max_rad ({self.spurious_max_rad!r})")

    def measure(self, true_bearing_rad: np.ndarray, distance_m: np.ndarray, wall_m: np.ndarray, u: np.ndarray,
                z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(bearings_rad in [-pi, pi), measured) for the true bearings in the sensor's frame,
        distances and wall lengths (shape (k,)), given u (shape (k, AOA_DRAWS), uniform in
        [0, 1)) and z (shape (k,), standard normal)."""
        truth = np.asarray(true_bearing_rad, dtype=np.float64)
        d = np.asarray(distance_m, dtype=np.float64)
        w = np.asarray(wall_m, dtype=np.float64)
        nlos = w > 0.0
        std = np.where(nlos, self.nlos_noise_std_rad, self.los_noise_std_rad)
        p_out = np.where(nlos, self.nlos_outlier_prob, self.los_outlier_prob)
        outlier = u[:, 1] < p_out
        spurious = outlier & nlos & (u[:, 2] < self.nlos_spurious_share)
        offset = self.spurious_min_rad + (self.spurious_max_rad - self.spurious_min_rad) * u[:, 3]
        sign = np.where(u[:, 4] < 0.5, -1.0, 1.0)
        b = np.where(outlier, -math.pi + 2.0 * math.pi * u[:, 3], truth + std * z)
        b = np.where(spurious, truth + sign * offset, b)
        b = np.mod(b + math.pi, 2.0 * math.pi) - math.pi
        b = np.where(b >= math.pi, -math.pi, b)          # the mod's rounding can give pi itself
        measured = (d <= self.range_max_m) & (u[:, 0] < np.exp(-self.detection_decay_per_wall_m * w))
        return b, measured


@dataclass(frozen=True)
class SensingProfile:
    name: str
    uwb: UwbModel
    aoa: AoaModel

    def __post_init__(self) -> None:
        if not isinstance(self.uwb, UwbModel) or not isinstance(self.aoa, AoaModel):
            raise ValueError(f"SensingProfile {self.name!r}: uwb must be a UwbModel and aoa an AoaModel")


PAPER = SensingProfile(
    name="paper",
    uwb=UwbModel(los_noise_std_m=0.10, nlos_bias_m=0.0, nlos_bias_per_wall_m=0.0, nlos_extra_std_m=0.0,
                 nlos_extra_std_per_wall_m=0.0, outlier_prob_los=0.0, outlier_prob_nlos=0.0, outlier_min_m=0.5,
                 outlier_max_m=3.0, detection_decay_per_wall_m=0.0, range_max_m=50.0, resolution_m=0.0,
                 rate_hz=0.2),
    aoa=AoaModel(los_noise_std_rad=math.radians(5.0), los_outlier_prob=0.0, nlos_noise_std_rad=math.radians(5.0),
                 nlos_outlier_prob=0.0, nlos_spurious_share=0.5, spurious_min_rad=math.radians(20.0),
                 spurious_max_rad=math.radians(90.0), detection_decay_per_wall_m=0.0, range_max_m=50.0,
                 rate_hz=0.2),
)

REALISTIC = SensingProfile(
    name="realistic",
    uwb=UwbModel(los_noise_std_m=0.05, nlos_bias_m=0.3, nlos_bias_per_wall_m=1.2, nlos_extra_std_m=0.15,
                 nlos_extra_std_per_wall_m=0.3, outlier_prob_los=0.02, outlier_prob_nlos=0.10, outlier_min_m=0.5,
                 outlier_max_m=3.0, detection_decay_per_wall_m=1.0, range_max_m=50.0, resolution_m=0.001,
                 rate_hz=2.0),
    aoa=AoaModel(los_noise_std_rad=math.radians(5.0), los_outlier_prob=0.05, nlos_noise_std_rad=math.radians(10.0),
                 nlos_outlier_prob=0.25, nlos_spurious_share=0.5, spurious_min_rad=math.radians(20.0),
                 spurious_max_rad=math.radians(90.0), detection_decay_per_wall_m=0.5, range_max_m=50.0,
                 rate_hz=0.2),
)

SENSING_PROFILES: dict[str, SensingProfile] = {p.name: p for p in (PAPER, REALISTIC)}

# The paper's noise sweep (its Fig. 7): (AoA sigma in degrees, range sigma in metres).
PAPER_NOISE_LEVELS = ((2.0, 0.01), (5.0, 0.10), (10.0, 0.20), (30.0, 1.0))


def sensing_profile(name: str) -> SensingProfile:
    try:
        return SENSING_PROFILES[name]
    except KeyError:
        raise ValueError(f"unknown sensing profile {name!r}; known: {', '.join(SENSING_PROFILES)}") from None


def paper_noise(aoa_std_deg: float, range_std_m: float) -> SensingProfile:
    """The paper profile at another of its noise levels (PAPER_NOISE_LEVELS)."""
    rad = math.radians(aoa_std_deg)
    return SensingProfile(name=f"paper:{aoa_std_deg:g}deg:{range_std_m:g}m",
                          uwb=replace(PAPER.uwb, los_noise_std_m=range_std_m),
                          aoa=replace(PAPER.aoa, los_noise_std_rad=rad, nlos_noise_std_rad=rad))
