"""Compare two finished sweeps of the same maps, schemes and seeds that differ in something
else (a parameter set with --set, or the code): per map and scheme, the median p_max of each,
their ratio with the sweep's 90 % bootstrap interval, the lowest and the median coverage, the
runs that reached 0.99 and T_total / T_90.

    python -m host_tools.compare_grids NEW_OUT OLD_OUT [--schemes A:B]

reads NEW_OUT/trials.jsonl and OLD_OUT/trials.jsonl (as `lorascout sweep --out` writes them)
and prints a Markdown table; the ratio is NEW / OLD. With --schemes A:B, scheme A's trials
in NEW against scheme B's in OLD (e.g. a scheme on new code against a baseline whose code
did not change since the older grid ran)."""
from __future__ import annotations

import argparse
import json
import statistics
import sys
from collections.abc import Callable
from pathlib import Path

from host_tools.sweep import COVERAGE_TARGET, coverage_floor, ratio_interval


class GridError(ValueError):
    """A trials file that cannot be compared, with what is wrong and where."""


def load_records(out: Path, fields: Callable[[dict], dict]) -> list[dict]:
    """fields(trial) of every trial in OUT/trials.jsonl; a missing file, a trial lacking a
    field or a malformed line is a GridError naming the file (and the line)."""
    path = out / "trials.jsonl"
    if not path.is_file():
        raise GridError(f"{path}: no such file (is {out} the --out of a finished lorascout sweep?)")
    trials = []
    for line_no, line in enumerate(path.read_text().splitlines(), 1):
        if not line.strip():
            continue
        try:
            trials.append(fields(json.loads(line)))
        except (ValueError, KeyError, TypeError) as e:
            raise GridError(f"{path}, line {line_no}: not a sweep trial ({type(e).__name__}: {e})") from None
    if not trials:
        raise GridError(f"{path}: no trials")
    return trials


def _ratio_fields(t: dict) -> dict:
    return {"map": str(t["map"]), "strategy": str(t["strategy"]), "radio": str(t["radio"]),
            "seed": int(t["seed"]), "p_max_m": max(float(x) for x in t["path_length_m"]),
            "coverage": float(t["coverage"]), "t_total_s": float(t["t_total_s"]),
            "t_90_s": None if t["t_90_s"] is None else float(t["t_90_s"])}


def load_trials(out: Path) -> list[dict]:
    return load_records(out, _ratio_fields)


def _groups(trials: list[dict]) -> dict[tuple[str, str, str], dict[int, dict]]:
    out: dict[tuple[str, str, str], dict[int, dict]] = {}
    for t in trials:
        out.setdefault((t["map"], t["strategy"], t["radio"]), {})[t["seed"]] = t
    return out


def compare(new: list[dict], old: list[dict], schemes: tuple[str, str] | None = None) -> list[dict]:
    """One row per (map, scheme, radio) in both grids, over the seeds both ran; with
    schemes (A, B), one per (map, radio): A in new against B in old."""
    if schemes is not None:
        new = [t for t in new if t["strategy"] == schemes[0]]
        old = [{**t, "strategy": schemes[0]} for t in old if t["strategy"] == schemes[1]]
    a, b = _groups(new), _groups(old)
    rows = []
    for key in sorted(a.keys() & b.keys()):
        seeds = sorted(a[key].keys() & b[key].keys())
        if not seeds:
            continue
        x = [a[key][s] for s in seeds]
        y = [b[key][s] for s in seeds]
        med = lambda ts: statistics.median(t["p_max_m"] for t in ts)  # noqa: E731
        tail = lambda ts: _median_or_none([t["t_total_s"] / t["t_90_s"] for t in ts if t["t_90_s"]])  # noqa: E731
        lo, hi = ratio_interval([t["p_max_m"] for t in x], [t["p_max_m"] for t in y])
        scheme = key[1] if schemes is None else f"{schemes[0]} / {schemes[1]}"
        rows.append({"map": key[0], "scheme": scheme, "radio": key[2], "seeds": seeds,
                     "p_max_new_m": med(x), "p_max_old_m": med(y), "ratio": med(x) / med(y),
                     "interval": (lo, hi),
                     "coverage_min_new": min(t["coverage"] for t in x),
                     "coverage_min_old": min(t["coverage"] for t in y),
                     "coverage_median_new": statistics.median(t["coverage"] for t in x),
                     "coverage_median_old": statistics.median(t["coverage"] for t in y),
                     "reached_new": runs_on_target(x), "reached_old": runs_on_target(y),
                     "tail_new": tail(x), "tail_old": tail(y)})
    return rows


def runs_on_target(trials: list[dict]) -> int:
    """How many trials covered COVERAGE_TARGET (their coverage rounded down, as tabulated)."""
    return sum(coverage_floor(t["coverage"]) >= COVERAGE_TARGET for t in trials)


def seed_range(seeds: list[int]) -> str:
    """Sorted seeds as "0-9" when consecutive, else listed."""
    return f"{seeds[0]}-{seeds[-1]}" if seeds == list(range(seeds[0], seeds[-1] + 1)) else ",".join(map(str, seeds))


def _median_or_none(values: list[float]) -> float | None:
    return statistics.median(values) if values else None


def _tail(value: float | None) -> str:
    """T_total / T_90, or "-" where no run reached 0.9."""
    return "-" if value is None else f"{value:.1f}"


def markdown(rows: list[dict]) -> str:
    lines = ["| map | scheme | seeds | p_max new / old [m] | ratio (90 % interval) | lowest coverage new / old "
             "| median coverage new / old | runs >= 0.99 new / old | T_total / T_90 median new / old |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        seeds = seed_range(r["seeds"])
        lines.append(f"| {r['map']} | {r['scheme']} ({r['radio']}) | {seeds} | {r['p_max_new_m']:.1f} / "
                     f"{r['p_max_old_m']:.1f} | {r['ratio']:.2f} ({r['interval'][0]:.2f} to {r['interval'][1]:.2f}) | "
                     f"{coverage_floor(r['coverage_min_new']):.4f} / {coverage_floor(r['coverage_min_old']):.4f} | "
                     f"{coverage_floor(r['coverage_median_new']):.4f} / "
                     f"{coverage_floor(r['coverage_median_old']):.4f} | "
                     f"{r['reached_new']} / {r['reached_old']} | "
                     f"{_tail(r['tail_new'])} / {_tail(r['tail_old'])} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m host_tools.compare_grids",
                                 description="compare two finished sweeps (ratio NEW / OLD per map and scheme)")
    ap.add_argument("new", type=Path, help="the --out of one sweep")
    ap.add_argument("old", type=Path, help="the --out of the sweep to compare it with")
    ap.add_argument("--schemes", metavar="A:B",
                    help="compare scheme A in NEW with scheme B in OLD (default: each scheme with itself)")
    args = ap.parse_args(argv)
    schemes = None
    if args.schemes is not None:
        schemes = tuple(args.schemes.split(":"))
        if len(schemes) != 2 or not all(schemes):
            ap.error(f"--schemes {args.schemes!r}: expected two scheme names as A:B, e.g. pereira:minpos")
    try:
        rows = compare(load_trials(args.new), load_trials(args.old), schemes)
    except GridError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    if not rows:
        print(f"error: {args.new} and {args.old} share no map, scheme, radio and seed", file=sys.stderr)
        return 2
    sys.stdout.write(markdown(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
