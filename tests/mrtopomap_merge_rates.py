"""How often MR-TopoMap's merge is right, wrong or absent on random static draws of the test
world (tests/test_mrtopomap_world.py), the calibration behind merge.py's thresholds:

    python -m tests.mrtopomap_merge_rates --draws 600 [--seed 77] [--set occ_radius_m=10] [--json OUT]

Draw k takes map k mod 3 (cave:1:60x60, intel, depot) and, in turns of three, half-overlapping
areas (A the left 60 %, B the right 60 %) or disjoint ones (left and right 40 %), random
frames for both robots, the profile grid and A's own map. A merge is right within 1.2 m RMS
and 5 degrees of the truth (issue 25's bound for every merged pair), wrong otherwise.
"""
from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from firmware.schemes.mr_topomap import merge as M
from firmware.schemes import params_of
from firmware.schemes.mr_topomap.params import MrTopoParams
from host_tools.overrides import parse_overrides
from tests import test_mrtopomap_world as W

MAPS = ("cave:1:60x60", "intel.yaml", "depot.yaml")
MODES = ("half", "disjoint")
RIGHT_M, RIGHT_DEG = 1.2, 5.0


def draw(k: int, rng: np.random.Generator, params: MrTopoParams) -> dict:
    spec, mode = MAPS[k % len(MAPS)], MODES[(k // len(MAPS)) % len(MODES)]
    seed = int(rng.integers(0, 10**6))
    fa, fb = W.random_frame(rng), W.random_frame(rng)
    A, B, _, bxy, own = W.pair_records(spec, seed, fa, fb, mode)
    grid = M.ProfileGrid.of_map(own.state, own.row0, own.col0, own.res_m, W.RANGE_MAX, params)
    r = M.estimate(M.VertexSet(A), M.VertexSet(B), grid, own, params)
    out = {"map": spec, "mode": mode, "seed": seed, "merged": r.merged, "reason": r.reason, "support": r.support}
    if r.merged:
        rms_m, yaw_deg = W.merge_error(r.T, fa, fb, bxy)
        out.update(rms_m=rms_m, yaw_deg=yaw_deg, right=rms_m <= RIGHT_M and yaw_deg <= RIGHT_DEG)
    return out


def table(rows: list[dict]) -> str:
    lines = ["| map | areas | draws | merged right | merged wrong | not merged |", "|---|---|---|---|---|---|"]
    for spec in MAPS:
        for mode in MODES:
            sel = [r for r in rows if r["map"] == spec and r["mode"] == mode]
            right = sum(1 for r in sel if r["merged"] and r["right"])
            wrong = sum(1 for r in sel if r["merged"] and not r["right"])
            lines.append(f"| {spec} | {mode} | {len(sel)} | {right} | {wrong} | {len(sel) - right - wrong} |")
    return "\n".join(lines)


def _params(settings: list[str]) -> MrTopoParams:
    """NAME=VALUE items as `--set mrtopomap.NAME=VALUE` takes them (typed and checked)."""
    try:
        return params_of("mrtopomap", parse_overrides([f"mrtopomap.{item}" for item in settings]))
    except ValueError as exc:
        raise SystemExit(str(exc)) from None


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tests.mrtopomap_merge_rates", description=__doc__.split("\n\n")[0])
    ap.add_argument("--draws", type=int, default=60, help="random draws (default 60)")
    ap.add_argument("--seed", type=int, default=77, help="the draws' random seed (default 77)")
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE", help="a MrTopoParams field")
    ap.add_argument("--json", metavar="OUT", help="write every draw as JSON lines here")
    a = ap.parse_args(argv)
    if a.draws < 1:
        ap.error(f"--draws {a.draws}: must be at least 1")
    params = _params(a.set)
    rng = np.random.default_rng(a.seed)
    rows = []
    for k in range(a.draws):
        rows.append(draw(k, rng, params))
        print(f"\r{k + 1}/{a.draws} draws", end="", file=sys.stderr, flush=True)
    print(file=sys.stderr)
    if a.json:
        with open(a.json, "w") as f:
            f.writelines(json.dumps(r) + "\n" for r in rows)
    print(table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
