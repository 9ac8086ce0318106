"""Issue 24's bounds on failed and slow robots, from sweeps (../shared/schemes/wiserx.md 6.5
and 6.6), seed by seed:

    python -m host_tools.team_failures recovery WITH_OUT WITHOUT_OUT
    python -m host_tools.team_failures slow OUT [--scheme wiserx] [--against divide]

`recovery` pairs a sweep with a failing robot (`--fail random` or `--fail R@P%`) with the same
sweep under `--set wiserx.tau_enabled=false` (eq. 6: a failed teammate's trail still counts)
and asks, per map and scheme: the survivors' final coverage with the recovery rule minus
without it (median >= 0.05, above 0 on >= 80 % of seeds); the share of the area only the
failed robot had seen that the survivors saw by the end (median >= 0.70); the survivors'
coverage (median >= 0.90); every survivor stopped by itself.

`slow` reads one sweep with a slow robot (`--slow R=F`) that ran both schemes and asks, per
map: the scheme's termination time over the other's (ratio of medians <= 0.80, with its 90 %
bootstrap interval), coverage within 0.03 of the other's (medians), and the slow robot's
share of the observed area at most 0.8 times the fast robots' mean share (median over seeds).

Each prints a Markdown table; exit status 0 when every row meets its bounds, 1 when one does
not, 2 on unusable input.
"""
from __future__ import annotations

import argparse
import statistics
import sys
from pathlib import Path

from host_tools.compare_grids import GridError, load_records, seed_range
from host_tools.sweep import ratio_interval

RECOVERED_MIN = 0.05          # survivors' coverage with the recovery rule minus without (median)
RECOVERED_POSITIVE_SHARE = 0.8
LOST_SEEN_MIN = 0.70          # of what only the failed robot had seen, the share survivors saw (median)
SURVIVORS_COVERAGE_MIN = 0.90
SLOW_RATIO_MAX = 0.80         # T_term(scheme) / T_term(against)
COVERAGE_TOLERANCE = 0.03
SLOW_SHARE_MAX = 0.8          # the slow robot's observed share / the fast robots' mean


def _failure_fields(t: dict) -> dict:
    (f,) = t["failures"]          # one failing robot a trial
    return {"map": str(t["map"]), "strategy": str(t["strategy"]), "seed": int(t["seed"]),
            "failure": (int(f["robot"]), f.get("at_s"), f.get("at_coverage")),
            "failed": f.get("failed_at_s") is not None, "recovered": f.get("recovered"),
            "coverage_survivors": float(t["coverage_survivors"]),
            "stopped": str(t["termination"]).startswith("complete")}


def _slow_fields(t: dict) -> dict:
    return {"map": str(t["map"]), "strategy": str(t["strategy"]), "seed": int(t["seed"]),
            "t_total_s": float(t["t_total_s"]), "coverage": float(t["coverage"]),
            "stopped": str(t["termination"]).startswith("complete"),
            "slow": {int(r): float(f) for r, f in t["speed_factors"].items()},
            "observed_share": [float(x) for x in t["observed_share"]]}


def recovery(with_rule: list[dict], without: list[dict]) -> list[dict]:
    """One row per (map, scheme) over the seeds both sweeps ran, with the same failure."""
    other = {(t["map"], t["strategy"], t["seed"]): t for t in without}
    groups: dict[tuple[str, str], list[tuple[dict, dict]]] = {}
    for t in with_rule:
        o = other.get((t["map"], t["strategy"], t["seed"]))
        if o is None:
            continue
        if o["failure"] != t["failure"]:
            raise GridError(f"{t['map']} {t['strategy']} seed {t['seed']}: the two sweeps failed different robots "
                            f"or at different moments ({t['failure']} against {o['failure']})")
        groups.setdefault((t["map"], t["strategy"]), []).append((t, o))
    rows = []
    for key in sorted(groups):
        pairs = sorted(groups[key], key=lambda p: p[0]["seed"])
        gained = [t["coverage_survivors"] - o["coverage_survivors"] for t, o in pairs]
        seen = [t["recovered"] for t, _ in pairs if t["recovered"] is not None]
        rows.append({"map": key[0], "scheme": key[1], "seeds": [t["seed"] for t, _ in pairs],
                     "failed": sum(t["failed"] for t, _ in pairs), "gained": gained,
                     "lost_seen": seen, "survivors": [t["coverage_survivors"] for t, _ in pairs],
                     "survivors_without": [o["coverage_survivors"] for _, o in pairs],
                     "stopped": sum(t["stopped"] for t, _ in pairs)})
    return rows


def recovery_meets(r: dict) -> bool:
    n = len(r["seeds"])
    return (statistics.median(r["gained"]) >= RECOVERED_MIN
            and sum(g > 0 for g in r["gained"]) >= RECOVERED_POSITIVE_SHARE * n
            and bool(r["lost_seen"]) and statistics.median(r["lost_seen"]) >= LOST_SEEN_MIN
            and statistics.median(r["survivors"]) >= SURVIVORS_COVERAGE_MIN and r["stopped"] == n)


def recovery_markdown(rows: list[dict]) -> str:
    lines = ["| map | scheme | seeds | robot failed | survivors' coverage with rule, without (medians) "
             f"| gained: median (>= {RECOVERED_MIN:g}), seeds above 0 | of what only it had seen, survivors saw "
             f"(median, >= {LOST_SEEN_MIN:g}) | stopped by themselves | holds |",
             "|---|---|---|---|---|---|---|---|:---:|"]
    for r in rows:
        n = len(r["seeds"])
        seen = f"{statistics.median(r['lost_seen']):.2f}" if r["lost_seen"] else "-"
        lines.append(f"| {r['map']} | {r['scheme']} | {seed_range(r['seeds'])} | {r['failed']} of {n} "
                     f"| {statistics.median(r['survivors']):.4f}, {statistics.median(r['survivors_without']):.4f} "
                     f"| {statistics.median(r['gained']):+.4f}, {sum(g > 0 for g in r['gained'])} of {n} "
                     f"| {seen} | {r['stopped']} of {n} | {'yes' if recovery_meets(r) else 'NO'} |")
    return "\n".join(lines) + "\n"


def slow(trials: list[dict], scheme: str, against: str) -> list[dict]:
    """One row per map over the seeds both schemes ran."""
    by = {(t["map"], t["strategy"], t["seed"]): t for t in trials}
    rows = []
    for m in sorted({t["map"] for t in trials}):
        seeds = sorted(s for (mm, st, s) in by if mm == m and st == scheme and (m, against, s) in by)
        if not seeds:
            continue
        mine = [by[(m, scheme, s)] for s in seeds]
        theirs = [by[(m, against, s)] for s in seeds]
        shares = []
        for t in mine:
            (robot, _), = t["slow"].items()
            fast = [x for k, x in enumerate(t["observed_share"]) if k != robot]
            shares.append(t["observed_share"][robot] / (sum(fast) / len(fast)) if sum(fast) > 0 else float("inf"))
        t_mine, t_theirs = [t["t_total_s"] for t in mine], [t["t_total_s"] for t in theirs]
        rows.append({"map": m, "scheme": scheme, "against": against, "seeds": seeds,
                     "ratio": statistics.median(t_mine) / statistics.median(t_theirs),
                     "interval": ratio_interval(t_mine, t_theirs),
                     "coverage": statistics.median(t["coverage"] for t in mine),
                     "coverage_against": statistics.median(t["coverage"] for t in theirs),
                     "slow_share": statistics.median(shares),
                     "stopped": sum(t["stopped"] for t in mine), "stopped_against": sum(t["stopped"] for t in theirs)})
    return rows


def slow_meets(r: dict) -> bool:
    return (r["ratio"] <= SLOW_RATIO_MAX and abs(r["coverage"] - r["coverage_against"]) <= COVERAGE_TOLERANCE
            and r["slow_share"] <= SLOW_SHARE_MAX and r["stopped"] == len(r["seeds"]))


def slow_markdown(rows: list[dict]) -> str:
    lines = [f"| map | seeds | T_term: scheme / against (medians, <= {SLOW_RATIO_MAX:g}), 90 % interval "
             f"| coverage (medians, within {COVERAGE_TOLERANCE:g}) | slow robot's share / fast robots' mean "
             f"(median, <= {SLOW_SHARE_MAX:g}) | stopped by themselves | holds |",
             "|---|---|---|---|---|---|:---:|"]
    for r in rows:
        n = len(r["seeds"])
        lo, hi = r["interval"]
        lines.append(f"| {r['map']} | {seed_range(r['seeds'])} | {r['scheme']} / {r['against']}: {r['ratio']:.2f}, "
                     f"{lo:.2f} to {hi:.2f} | {r['coverage']:.4f} against {r['coverage_against']:.4f} "
                     f"| {r['slow_share']:.2f} | {r['stopped']} and {r['stopped_against']} of {n} "
                     f"| {'yes' if slow_meets(r) else 'NO'} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m host_tools.team_failures",
                                 description="issue 24's bounds on failed and slow robots, seed by seed")
    sub = ap.add_subparsers(dest="what", required=True)
    rec = sub.add_parser("recovery", help="a failing robot: with the recovery rule against without it")
    rec.add_argument("with_rule", type=Path, help="the --out of a sweep with --fail")
    rec.add_argument("without", type=Path, help="the same sweep with --set wiserx.tau_enabled=false")
    sl = sub.add_parser("slow", help="a slow robot: one scheme's termination against another's")
    sl.add_argument("out", type=Path, help="the --out of a sweep with --slow that ran both schemes")
    sl.add_argument("--scheme", default="wiserx")
    sl.add_argument("--against", default="divide")
    args = ap.parse_args(argv)
    try:
        if args.what == "recovery":
            rows = recovery(load_records(args.with_rule, _failure_fields), load_records(args.without, _failure_fields))
            text, ok = recovery_markdown(rows), all(recovery_meets(r) for r in rows)
        else:
            rows = slow(load_records(args.out, _slow_fields), args.scheme, args.against)
            text, ok = slow_markdown(rows), all(slow_meets(r) for r in rows)
    except GridError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    if not rows:
        print("error: no map and seed that both sweeps (or both schemes) ran", file=sys.stderr)
        return 2
    sys.stdout.write(text)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
