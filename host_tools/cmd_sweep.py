"""`lorascout sweep`: the grid of maps x strategies x seeds, in parallel, reduced to tables
(CSV, JSON, Markdown) and path figures (PNG)."""
from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

from hal.lora import PROFILES
from host_tools.overrides import parse_overrides
from host_tools.progress import progress_bar
from host_tools.scheme_option import add_schemes_option
from host_tools.sweep import (PARTIAL_NAME, WRITTEN, SweepSpec, code_fingerprint, load_partial, markdown, run_local,
                               run_ray, save, trial_key)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--maps", nargs="+", required=True, help="map specs (PATH.yaml, cave:SEED, tunnel:SEED)")
    add_schemes_option(p)
    p.add_argument("--robots", type=int, default=5)
    p.add_argument("--seeds", type=int, default=10, help="trials per map and strategy (seeds 0..N-1)")
    p.add_argument("--first-seed", type=int, default=0)
    p.add_argument("--radio", default="ideal-100Bps", choices=sorted(PROFILES))
    p.add_argument("--also-radio", nargs="+", default=[], choices=sorted(PROFILES), metavar="PROFILE",
                   help="repeat the trials of the strategies that use the LoRa link (greedy, minpos) on "
                        "these profiles and tabulate what they cost against --radio")
    p.add_argument("--max-sim-s", type=float, default=14400.0)
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE", dest="overrides",
                   help="change an explorer parameter (firmware/params.py) for every trial; repeatable. "
                        "Recorded with each trial and in the tables")
    p.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="local worker processes (default: cores)")
    p.add_argument("--ray", default=None, metavar="ADDRESS",
                   help="run on a Ray cluster instead ('local' starts one here)")
    p.add_argument("--out", type=Path, default=Path("out/sweep"), help="where tables and figures go")
    p.add_argument("--resume", action="store_true",
                   help=f"keep the trials an interrupted run of the same sweep finished (OUT/{PARTIAL_NAME}) "
                        "with the same code (firmware, HAL, world, radio, mission) and run only the rest")
    p.add_argument("--tables-of-code", default=None, metavar="FINGERPRINT",
                   help=f"run nothing: tabulate the grid's trials in OUT/{PARTIAL_NAME} that ran the code "
                        "whose fingerprint (code_sha256) starts with this, e.g. an older grid after a change "
                        "to the tables; every trial of the grid must be there")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def main(args: argparse.Namespace) -> int:
    if args.robots < 1 or args.seeds < 1:
        print("lorascout sweep: --robots and --seeds must be at least 1", file=sys.stderr)
        return 2
    try:
        overrides = parse_overrides(args.overrides)
    except ValueError as exc:
        print(f"lorascout sweep: {exc}", file=sys.stderr)
        return 2
    spec = SweepSpec(tuple(args.maps), tuple(args.strategies), args.robots, args.seeds, args.radio,
                     args.max_sim_s, args.first_seed, tuple(r for r in args.also_radio if r != args.radio),
                     overrides)
    trials = spec.trials()
    wanted = {trial_key(c, overrides) for c in trials}
    if args.tables_of_code is not None:
        return _tabulate_earlier(args.out, spec, wanted, args.tables_of_code)
    try:
        kept = load_partial(args.out) if args.resume else []
        code = code_fingerprint()
        earlier = [r for r in kept if trial_key(r) in wanted and r.get("code_sha256") == code]
    except (ValueError, OSError) as exc:
        print(f"lorascout sweep: {exc}", file=sys.stderr)
        return 2
    done_keys = {trial_key(r) for r in earlier}
    todo = [c for c in trials if trial_key(c, overrides) not in done_keys]
    other_code = sum(1 for r in kept if trial_key(r) in wanted and r.get("code_sha256") != code)
    if args.resume:
        # Trials of other code stay in the file (nothing is thrown away) but count for nothing.
        print(f"resuming: {len(earlier)} trials done earlier, {len(todo)} to run"
              + (f" ({other_code} earlier trials ran other code and are run again)" if other_code else ""),
              file=sys.stderr)
    args.out.mkdir(parents=True, exist_ok=True)
    bar = progress_bar(len(todo), "sweep", "trial", args.quiet)
    counted = {"n": 0}
    # Each finished trial goes to disk at once: an interrupted sweep loses only what ran.
    with open(args.out / PARTIAL_NAME, "w") as partial:
        for report in kept:            # rewritten whole: a line cut short is gone, not appended to
            partial.write(json.dumps(report, sort_keys=True) + "\n")
        def finished(report: dict) -> None:
            # Stamped with the code read once at the start: the workers run that code, whatever
            # the files say by the time a trial ends.
            report["code_sha256"] = code
            partial.write(json.dumps(report, sort_keys=True) + "\n")
            partial.flush()
            bar.update(1)
            if bar.disable and not args.quiet:
                # No terminal (a grid left running for hours with its output in a log): a line
                # per trial instead of the bar.
                counted["n"] += 1
                print(f"trial {counted['n']}/{len(todo)}: {report['strategy']} on {report['map']} seed "
                      f"{report['seed']} ({report['radio']}): p_max {max(report['path_length_m']):.0f} m, "
                      f"coverage {report['coverage']:.4f}, {report['termination']}, {report['wall_s']:.0f} s",
                      file=sys.stderr, flush=True)

        try:
            if args.ray is not None:
                results = run_ray(todo, None if args.ray == "local" else args.ray, finished, overrides)
            else:
                results = run_local(todo, args.jobs, finished, overrides)
        except (ValueError, KeyError, OSError, RuntimeError) as exc:
            bar.close()
            print(f"lorascout sweep: {exc}", file=sys.stderr)
            return 2
    bar.close()
    t = save(args.out, spec, earlier + results)
    print(markdown(t))
    print(f"wrote {args.out}/{WRITTEN}")
    return 0


def _tabulate_earlier(out: Path, spec: SweepSpec, wanted: set[tuple], fingerprint: str) -> int:
    """The tables of a grid whose trials all ran earlier, on the code `fingerprint` names."""
    if len(fingerprint) < 8:
        print("lorascout sweep: --tables-of-code needs at least 8 hex digits of a fingerprint", file=sys.stderr)
        return 2
    try:
        kept = load_partial(out)
    except (ValueError, OSError) as exc:
        print(f"lorascout sweep: {exc}", file=sys.stderr)
        return 2
    found = {}
    for r in kept:
        key = trial_key(r)
        if str(r.get("code_sha256", "")).startswith(fingerprint) and key in wanted:
            found.setdefault(key, r)
    if len(found) < len(wanted):
        print(f"lorascout sweep: {out / PARTIAL_NAME} holds {len(found)} of the grid's {len(wanted)} trials "
              f"of code {fingerprint}; tables need them all", file=sys.stderr)
        return 2
    t = save(out, spec, list(found.values()))
    print(markdown(t))
    print(f"wrote {out}/{WRITTEN} from {len(found)} trials of code {fingerprint}")
    return 0
