"""How a finished sweep's robots navigated, per map and scheme: coverage, how the missions
ended, the tail (T_total / T_90), path, recoveries and ticks inside walls.

    python -m host_tools.nav_table OUT [OUT ...]

reads each OUT/trials.jsonl (as `lorascout sweep --out` writes it) and prints one Markdown
table over all of them."""
from __future__ import annotations

import argparse
import statistics
import sys
from collections import Counter
from pathlib import Path

from host_tools.compare_grids import GridError, load_records, runs_on_target, seed_range
from host_tools.sweep import coverage_floor

HEADER = ("| map | scheme | seeds | body-reachable area | coverage min / median | runs >= 0.99 | terminations "
          "| T_90 median | T_total median | T_total / T_90 median | path median | recoveries median "
          "| robot-ticks in walls |")


def _nav_fields(t: dict) -> dict:
    return {"map": str(t["map"]), "scheme": str(t["strategy"]), "seed": int(t["seed"]),
            "area_m2": float(t["reachable_area_m2"]), "coverage": float(t["coverage"]),
            "termination": str(t["termination"]), "t_total_s": float(t["t_total_s"]),
            "t_90_s": None if t["t_90_s"] is None else float(t["t_90_s"]),
            "path_m": max(float(x) for x in t["path_length_m"]),
            "recoveries": sum(int(x) for x in t["explorer_stats"]["recoveries"]),
            "in_wall": int(t["robots_in_wall"])}


def load(out: Path) -> list[dict]:
    """The trials of one sweep, checked for the fields the table reads."""
    return load_records(out, _nav_fields)


def row(trials: list[dict]) -> str:
    """One table row for the trials of one map and scheme."""
    t0 = trials[0]
    cov = [t["coverage"] for t in trials]
    ends = Counter(t["termination"] for t in trials)
    reached_90 = [t for t in trials if t["t_90_s"] is not None]
    t90 = f"{statistics.median(t['t_90_s'] for t in reached_90):.0f} s ({len(reached_90)} of {len(trials)} reach 0.9)" \
        if reached_90 else "- (none reach 0.9)"
    tail = f"{statistics.median(t['t_total_s'] / t['t_90_s'] for t in reached_90):.1f}" if reached_90 else "-"
    return (f"| {t0['map']} | {t0['scheme']} | {seed_range(sorted(t['seed'] for t in trials))} | {t0['area_m2']:.0f} m² "
            f"| {coverage_floor(min(cov)):.4f} / {coverage_floor(statistics.median(cov)):.4f} "
            f"| {runs_on_target(trials)} of {len(trials)} "
            f"| {', '.join(f'{k} {n}' for k, n in sorted(ends.items()))} | {t90} "
            f"| {statistics.median(t['t_total_s'] for t in trials):.0f} s | {tail} "
            f"| {statistics.median(t['path_m'] for t in trials):.0f} m "
            f"| {statistics.median(t['recoveries'] for t in trials):g} | {sum(t['in_wall'] for t in trials)} |")


def markdown(trials: list[dict]) -> str:
    groups: dict[tuple[str, str], list[dict]] = {}
    for t in trials:
        groups.setdefault((t["map"], t["scheme"]), []).append(t)
    lines = [HEADER, "|" + "---|" * (HEADER.count("|") - 1)]
    lines += [row(groups[key]) for key in sorted(groups)]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m host_tools.nav_table",
                                 description="how a finished sweep's robots navigated, per map and scheme")
    ap.add_argument("outs", type=Path, nargs="+", metavar="OUT", help="the --out of a finished sweep")
    args = ap.parse_args(argv)
    try:
        trials = [t for out in args.outs for t in load(out)]
        seen = Counter((t["map"], t["scheme"], t["seed"]) for t in trials)
        twice = sorted(k for k, n in seen.items() if n > 1)
        if twice:
            raise GridError(f"{len(twice)} trials given twice, e.g. map {twice[0][0]}, scheme {twice[0][1]}, "
                            f"seed {twice[0][2]}: give each trial once (one sweep per map and seed)")
    except GridError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    sys.stdout.write(markdown(trials))
    return 0


if __name__ == "__main__":
    sys.exit(main())
