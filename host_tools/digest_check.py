"""Prove a refactor pure: run trials of a recorded grid again and compare trajectory digests.

    python -m host_tools.digest_check docs/sweep/trials.jsonl --per-cell 1 --jobs 2

picks, for every (strategy, map, radio) cell of the recorded grid, the `--per-cell` trials
that took the least wall time, runs each again on the current code, and prints one line per
trial: same or DIFFERENT trajectory SHA-256 (and air-log SHA-256). Exit status 1 if any
differs. A trial recorded with parameter overrides runs with the same ones.
"""
from __future__ import annotations

import argparse
import json
import multiprocessing
import sys
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

from host_tools.mission import MissionConfig
from host_tools.sweep import run_trial


def pick_trials(rows: list[dict], per_cell: int) -> list[dict]:
    """The per_cell fastest recorded trials of every (strategy, map, radio) cell, the
    fastest first (so an interrupted check has compared as many cells as it could)."""
    cells: dict[tuple, list[dict]] = {}
    for r in rows:
        cells.setdefault((r["strategy"], r["map"], r["radio"]), []).append(r)
    picked = []
    for key in sorted(cells):
        picked.extend(sorted(cells[key], key=lambda r: (r["wall_s"], r["seed"]))[:per_cell])
    return sorted(picked, key=lambda r: r["wall_s"])


def _rerun(row: dict) -> dict:
    cfg = MissionConfig(map_spec=row["map_spec"], robots=row["robots"], seed=row["seed"],
                        max_sim_s=row["max_sim_s"], radio=row["radio"], strategy=row["strategy"])
    return run_trial(cfg, tuple(sorted(row.get("params_overrides", {}).items())))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m host_tools.digest_check", description=__doc__.split("\n\n")[0])
    ap.add_argument("trials", type=Path, help="a sweep's trials.jsonl (e.g. docs/sweep/trials.jsonl)")
    ap.add_argument("--per-cell", type=int, default=1, help="trials rerun per (strategy, map, radio) cell")
    ap.add_argument("--jobs", type=int, default=2, help="trials run at once (one numba thread each)")
    args = ap.parse_args(argv)
    if args.per_cell < 1 or args.jobs < 1:
        ap.error("--per-cell and --jobs must be at least 1")
    rows = [json.loads(line) for line in args.trials.read_text().splitlines() if line.strip()]
    picked = pick_trials(rows, args.per_cell)
    print(f"{len(picked)} trials of {len(rows)} from {args.trials}", flush=True)
    ctx = multiprocessing.get_context("spawn")
    differ = 0
    with ProcessPoolExecutor(max_workers=args.jobs, mp_context=ctx,
                             initializer=_one_thread) as pool:
        futures = {pool.submit(_rerun, row): row for row in picked}
        for fut in as_completed(futures):
            row, new = futures[fut], fut.result()
            same = (new["trajectory_sha256"] == row["trajectory_sha256"]
                    and new["air_log_sha256"] == row["air_log_sha256"])
            differ += not same
            print(f"{'same     ' if same else 'DIFFERENT'} {row['strategy']:<12} {row['map']:<14} "
                  f"{row['radio']:<13} seed {row['seed']}  trajectory {new['trajectory_sha256'][:16]}  "
                  f"air {new['air_log_sha256'][:16]}", flush=True)
    print(f"{len(picked) - differ} of {len(picked)} identical", flush=True)
    return 1 if differ else 0


def _one_thread() -> None:
    import numba
    numba.set_num_threads(1)


if __name__ == "__main__":
    sys.exit(main())
