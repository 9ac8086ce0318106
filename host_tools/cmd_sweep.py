"""`lorascout sweep`: the grid of maps x strategies x seeds, in parallel, reduced to tables
(CSV, JSON, Markdown) and path figures (PNG)."""
from __future__ import annotations

import argparse
import contextlib
import os
import re
import signal
import sys
import threading
from pathlib import Path

from host_tools.options import (FAIL, FLUSH_S, FRAMES, LIDAR_PHASE, MAX_SIM_S, QUIET, RADIO, RANGE_M, ROBOTS, SCHEMES, SEED_MAX,
                                SET, SLOW, SPREAD, SPREAD_MAX, WHEEL_SLIP, Opt, add_options, check_spread,
                                with_default)
from host_tools.overrides import check_schemes_used, combine_overrides, params_help
from host_tools.progress import progress_bar
from host_tools.safe_io import strict_dumps, write_text
from host_tools.sweep import (PARTIAL_NAME, WRITTEN, SweepSpec, code_fingerprint, load_partial, markdown, probe_ray,
                               run_local, run_ray, save, trial_key)

EXIT_INTERRUPTED = 130
OLD_PARTIAL_NAME = PARTIAL_NAME + ".old"     # where --overwrite moves an earlier grid's trials

OPTIONS = (
    Opt("--maps", "map", "map specs (PATH.yaml, cave:SEED[:WxH], tunnel:SEED[:WxH], office:SEED[:WxH])", nargs="+", required=True,
        metavar="MAP"),
    SCHEMES,
    with_default(ROBOTS, 5),
    Opt("--seeds", "int", "trials per map and strategy (seeds FIRST..FIRST+N-1)", lo=1, hi=100_000, default=10),
    Opt("--first-seed", "int", "the first trial's seed", lo=0, hi=SEED_MAX, default=0, metavar="FIRST"),
    RADIO,
    Opt("--also-radio", "choice", "repeat the trials of the strategies that use the LoRa link (greedy, minpos) on "
        "these profiles and tabulate what they cost against --radio", nargs="+", choices=RADIO.choices, default=[],
        metavar="PROFILE"),
    RANGE_M, FRAMES, SPREAD, SPREAD_MAX, MAX_SIM_S, FLUSH_S, WHEEL_SLIP, LIDAR_PHASE, FAIL, SLOW, SET,
    Opt("--jobs", "int", "local worker processes", lo=1, hi=256, default=os.cpu_count() or 1),
    Opt("--ray", "address", "run on a Ray cluster instead: 'local' starts one here, 'auto' finds one, or "
        "HOST:PORT (refused at once if nothing answers there)", metavar="ADDRESS"),
    Opt("--out", "out_dir", "where tables and figures go", default="out/sweep", metavar="DIR"),
    Opt("--resume", "flag", f"keep the trials an interrupted run of the same sweep finished (OUT/{PARTIAL_NAME}) "
        "with the same code (firmware, HAL, world, radio, mission) and run only the rest"),
    Opt("--overwrite", "flag", f"start the grid again in an OUT that holds one: its trials file is moved to "
        f"OUT/{OLD_PARTIAL_NAME} (replacing an older one there), its tables are replaced when the new ones are "
        "written"),
    Opt("--tables-of-code", "text", f"run nothing: tabulate the grid's trials in OUT/{PARTIAL_NAME} that ran the "
        "code whose fingerprint (code_sha256) starts with this, e.g. an older grid after a change to the tables; "
        "every trial of the grid must be there", metavar="FINGERPRINT"),
    QUIET,
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_options(p, OPTIONS)
    p.formatter_class = argparse.RawDescriptionHelpFormatter
    p.epilog = params_help()


@contextlib.contextmanager
def _ctrl_c_deferred():
    """SIGINT held back (delivered when the block ends), in the main thread. The handler is
    swapped rather than the signal masked: a SIGINT that reached the process just before the
    block still runs its Python handler at the next bytecode, inside the block, and the
    KeyboardInterrupt would split a trial's write from its count."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: held.append((signum, frame)))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        if held and callable(previous):
            previous(*held[0])


def _existing_grid(out: Path) -> str | None:
    """What in OUT belongs to an earlier grid, or None."""
    partial = out / PARTIAL_NAME
    if partial.is_file() and partial.stat().st_size > 0:
        with open(partial, "rb") as f:
            lines = sum(chunk.count(b"\n") for chunk in iter(lambda: f.read(1 << 20), b""))
        return f"{lines} trials in {partial}"
    if (out / "tables.json").exists():
        return f"the tables in {out / 'tables.json'}"
    return None


def main(args: argparse.Namespace) -> int:
    # Everything that can be refused is refused before any file is touched or trial run.
    try:
        overrides = combine_overrides(args.overrides)
        check_schemes_used(overrides, args.strategies, "--schemes")
        last_seed = args.first_seed + args.seeds - 1
        if last_seed > SEED_MAX:
            raise ValueError(f"--first-seed {args.first_seed} with --seeds {args.seeds} reaches seed {last_seed}; "
                             f"seeds go up to {SEED_MAX}")
        check_spread(args.spread, args.spread_max)
        if args.resume and args.overwrite:
            raise ValueError("--resume keeps the earlier trials and --overwrite starts again: give one of them")
        if args.tables_of_code is not None and not re.fullmatch(r"[0-9a-fA-F]{8,64}", args.tables_of_code):
            raise ValueError(f"--tables-of-code {args.tables_of_code!r}: needs at least 8 hex digits of a "
                             "fingerprint (code_sha256)")
        spec = SweepSpec(tuple(args.maps), tuple(args.strategies), args.robots, args.seeds, args.radio,
                         args.max_sim_s, args.first_seed, tuple(r for r in args.also_radio if r != args.radio),
                         overrides, args.wheel_slip, args.lidar_phase_ms, args.range_m, args.frames, args.spread,
                         args.spread_max, tuple(args.failures), tuple(args.speed_factors), args.flush_s)
        trials = spec.trials()
    except ValueError as exc:
        print(f"lorascout sweep: {exc}", file=sys.stderr)
        return 2
    wanted = {trial_key(c, overrides) for c in trials}
    if args.tables_of_code is not None:
        return _tabulate_earlier(args.out, spec, wanted, args.tables_of_code)
    if args.ray not in (None, "local"):
        try:
            probe_ray(args.ray)
        except RuntimeError as exc:
            print(f"lorascout sweep: {exc}; nothing was run or changed", file=sys.stderr)
            return 2
    earlier_grid = _existing_grid(args.out)
    if earlier_grid is not None and not (args.resume or args.overwrite):
        print(f"lorascout sweep: {args.out} already holds a grid ({earlier_grid}); nothing was changed. Give "
              f"--resume to keep its trials and run only the rest, or --overwrite to start again (its trials "
              f"file is kept as {OLD_PARTIAL_NAME})", file=sys.stderr)
        return 2
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
    partial_path = args.out / PARTIAL_NAME
    try:
        args.out.mkdir(parents=True, exist_ok=True)
        if args.resume:
            # Rewritten whole, atomically: a line cut short is gone, not appended to.
            write_text(partial_path, "".join(strict_dumps(r, sort_keys=True) + "\n" for r in kept))
        elif args.overwrite and partial_path.exists():
            os.replace(partial_path, args.out / OLD_PARTIAL_NAME)
        partial = open(partial_path, "a", encoding="utf-8")
    except OSError as exc:
        print(f"lorascout sweep: {exc}", file=sys.stderr)
        return 2
    bar = progress_bar(len(todo), "sweep", "trial", args.quiet)
    finished_now: list[dict] = []
    # Each finished trial goes to disk at once: an interrupted sweep loses only what was running.
    with partial:
        def finished(report: dict) -> None:
            # Stamped with the code read once at the start: the workers run that code, whatever
            # the files say by the time a trial ends.
            report["code_sha256"] = code
            with _ctrl_c_deferred():      # a trial on disk is a trial counted, and the other way round
                partial.write(strict_dumps(report, sort_keys=True) + "\n")
                partial.flush()
                os.fsync(partial.fileno())
                finished_now.append(report)
            bar.update(1)
            if bar.disable and not args.quiet:
                # No terminal (a grid left running for hours with its output in a log): a line
                # per trial instead of the bar.
                print(f"trial {len(finished_now)}/{len(todo)}: {report['strategy']} on {report['map']} seed "
                      f"{report['seed']} ({report['radio']}): p_max {max(report['path_length_m']):.0f} m, "
                      f"coverage {report['coverage']:.4f}, {report['termination']}, {report['wall_s']:.0f} s",
                      file=sys.stderr, flush=True)

        try:
            if args.ray is not None:
                results = run_ray(todo, None if args.ray == "local" else args.ray, finished, overrides)
            else:
                results = run_local(todo, args.jobs, finished, overrides)
        except KeyboardInterrupt:
            bar.close()
            return _interrupted(args.out, spec, earlier + finished_now, len(finished_now), len(todo))
        except (ValueError, KeyError, OSError, RuntimeError) as exc:
            bar.close()
            print(f"lorascout sweep: {exc} ({len(finished_now)} trials finished and kept in {partial_path})",
                  file=sys.stderr)
            return 2
    bar.close()
    t = save(args.out, spec, earlier + results)
    print(markdown(t))
    print(f"wrote {args.out}/{WRITTEN}")
    return 0


def _interrupted(out: Path, spec: SweepSpec, results: list[dict], finished: int, todo: int) -> int:
    """Ctrl-C: the finished trials are in the trials file already; the tables of what is there
    are printed and written, marked as interrupted (no figures: they need every trial)."""
    note = (f"INTERRUPTED: {finished} of the {todo} trials to run finished (kept in {out / PARTIAL_NAME}); "
            "run the same command with --resume to run the rest")
    print(f"lorascout sweep: {note}", file=sys.stderr)
    if results:
        try:
            t = save(out, spec, results, interrupted=note)
        except (OSError, ValueError) as exc:
            print(f"lorascout sweep: could not write the partial tables: {exc}", file=sys.stderr)
        else:
            print(markdown(t))
    return EXIT_INTERRUPTED


def _tabulate_earlier(out: Path, spec: SweepSpec, wanted: set[tuple], fingerprint: str) -> int:
    """The tables of a grid whose trials all ran earlier, on the code `fingerprint` names."""
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
