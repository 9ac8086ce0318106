"""What a team gains over one robot: per map and team scheme, each seed's p_max (the longest
path of the team's robots) over the path of one robot alone on the same map and seed, with
the coverage of the team's runs, and the ratio of the two medians with its 90 % bootstrap
interval. Issue 20's acceptance asks for p_max <= 0.6 x the one robot's path on every seed,
with coverage >= 0.99 in every team run. `--measure t_total` compares the missions' T_total
instead (Pereira et al.'s scaling experiment: T_total with 2 robots <= 0.8 x one robot's).

    python -m host_tools.team_gain TEAM_OUT ONE_OUT [--bound 0.6] [--measure p_max|t_total]

reads TEAM_OUT/trials.jsonl (a sweep with --robots N > 1) and ONE_OUT/trials.jsonl (a sweep
with --robots 1) and prints a Markdown table; exit status 0 when every row meets the bound
and the coverage target, 1 when one does not, 2 on unusable input."""
from __future__ import annotations

import argparse
import statistics
import sys
from pathlib import Path

from host_tools.compare_grids import GridError, load_records, seed_range
from host_tools.sweep import COVERAGE_TARGET, coverage_floor, ratio_interval

MEASURES = {"p_max": "p_max / one robot's path", "t_total": "T_total / one robot's T_total"}


def _fields(measure: str):
    def fields(t: dict) -> dict:
        value = max(float(x) for x in t["path_length_m"]) if measure == "p_max" else float(t["t_total_s"])
        return {"map": str(t["map"]), "strategy": str(t["strategy"]), "radio": str(t["radio"]),
                "seed": int(t["seed"]), "robots": len(t["path_length_m"]), "value": value,
                "coverage": float(t["coverage"])}
    return fields


def gains(team: list[dict], one: list[dict]) -> list[dict]:
    """One row per (map, team scheme, radio) over the seeds a one-robot run has on that map."""
    alone = {(t["map"], t["seed"]): t for t in one if t["robots"] == 1}
    groups: dict[tuple[str, str, str], list[dict]] = {}
    for t in team:
        if t["robots"] > 1 and (t["map"], t["seed"]) in alone:
            groups.setdefault((t["map"], t["strategy"], t["radio"]), []).append(t)
    rows = []
    for key in sorted(groups):
        runs = sorted(groups[key], key=lambda t: t["seed"])
        mates = [alone[(t["map"], t["seed"])]["value"] for t in runs]
        ratios = [t["value"] / m for t, m in zip(runs, mates)]
        rows.append({"map": key[0], "scheme": key[1], "radio": key[2], "robots": runs[0]["robots"],
                     "seeds": [t["seed"] for t in runs], "ratios": ratios,
                     "of_medians": statistics.median(t["value"] for t in runs) / statistics.median(mates),
                     "interval": ratio_interval([t["value"] for t in runs], mates),
                     "coverage_min": min(t["coverage"] for t in runs),
                     "reached": sum(coverage_floor(t["coverage"]) >= COVERAGE_TARGET for t in runs)})
    return rows


def meets(row: dict, bound: float) -> bool:
    return max(row["ratios"]) <= bound and row["reached"] == len(row["seeds"])


def markdown(rows: list[dict], bound: float, measure: str = "p_max") -> str:
    lines = [f"| map | scheme | robots | seeds | {MEASURES[measure]}: median, worst | seeds within {bound:g} "
             "| lowest coverage | runs >= 0.99 | ratio of the medians (90 % interval) |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        within = sum(x <= bound for x in r["ratios"])
        lines.append(f"| {r['map']} | {r['scheme']} ({r['radio']}) | {r['robots']} | {seed_range(r['seeds'])} "
                     f"| {statistics.median(r['ratios']):.2f}, {max(r['ratios']):.2f} "
                     f"| {within} of {len(r['ratios'])} | {coverage_floor(r['coverage_min']):.4f} "
                     f"| {r['reached']} of {len(r['seeds'])} "
                     f"| {r['of_medians']:.2f} ({r['interval'][0]:.2f} to {r['interval'][1]:.2f}) |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m host_tools.team_gain",
                                 description="a team's p_max against one robot's path, seed by seed")
    ap.add_argument("team", type=Path, help="the --out of a sweep with a team")
    ap.add_argument("one", type=Path, help="the --out of a sweep with --robots 1 on the same maps and seeds")
    ap.add_argument("--bound", type=float, default=0.6,
                    help="the largest ratio that passes (default 0.6)")
    ap.add_argument("--measure", choices=sorted(MEASURES), default="p_max",
                    help="p_max: the longest path (default); t_total: the mission's T_total")
    args = ap.parse_args(argv)
    if not 0.0 < args.bound:
        print(f"error: --bound {args.bound}: must be above 0", file=sys.stderr)
        return 2
    try:
        rows = gains(load_records(args.team, _fields(args.measure)), load_records(args.one, _fields(args.measure)))
    except GridError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    if not rows:
        print(f"error: {args.team} holds no team run on a map and seed that {args.one} ran with one robot",
              file=sys.stderr)
        return 2
    sys.stdout.write(markdown(rows, args.bound, args.measure))
    return 0 if all(meets(r, args.bound) for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
