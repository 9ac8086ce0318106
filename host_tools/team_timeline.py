"""One team mission as a timeline: every few simulated seconds the team's coverage, which
robots had stopped, and chosen counters of each robot's (the `explorer_stats` of `--json`),
so an end game shows where the time goes:

    python -m host_tools.team_timeline --map ../shared/maps/maze_a.yaml --robots 5 \\
        --scheme pereira --radio eu868-g3 --seed 0 --every-s 40 --stat waypoints_taken_back

prints a Markdown table (time, coverage, the stopped robots' ids, each counter per robot) and
the mission's end. Exit status 0, or 2 on unusable input (named before the mission runs, or,
for a counter the scheme does not keep, at its first sample).
"""
from __future__ import annotations

import argparse
import sys

from host_tools.mission import MissionConfig, resolve_map, run_mission


class TimelineError(ValueError):
    """What is wrong with the input, named."""


def timeline(cfg: MissionConfig, every_s: float, stats: list[str]) -> tuple[list[tuple], object]:
    """(rows, result): a row (time s, coverage, stopped ids, {stat: per-robot values}) every
    every_s of simulated time from the start, and the mission's result."""
    coverage = {"now": 0.0}
    rows: list[tuple] = []
    step_us = int(round(every_s * 1e6))

    def progress(_t_s: float, c: float) -> None:
        coverage["now"] = c

    def observe(now_us: int, agents) -> None:
        if now_us % step_us:
            return
        per_robot = [a.stats() for a in agents]
        missing = [s for s in stats if s not in per_robot[0]]
        if missing:
            raise TimelineError(f"--stat {missing[0]}: not a counter of scheme {cfg.strategy!r} "
                                f"(it keeps: {', '.join(sorted(per_robot[0]))})")
        rows.append((now_us / 1e6, coverage["now"], [i for i, a in enumerate(agents) if a.done],
                     {s: [st[s] for st in per_robot] for s in stats}))

    result = run_mission(cfg, progress=progress, observer=observe)
    return rows, result


def markdown(rows: list[tuple], stats: list[str]) -> str:
    head = "| t (s) | coverage | stopped | " + " | ".join(stats) + " |" if stats else "| t (s) | coverage | stopped |"
    lines = [head, "|" + "---|" * (3 + len(stats))]
    for t, c, stopped, values in rows:
        cells = [f"{t:.0f}", f"{c:.4f}", " ".join(map(str, stopped)) or "-"]
        cells += [" ".join(str(v) for v in values[s]) for s in stats]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m host_tools.team_timeline",
                                 description="a team mission's coverage, stopped robots and counters over time")
    ap.add_argument("--map", required=True, help="map spec (PATH.yaml, cave:SEED[:WxH], ...)")
    ap.add_argument("--robots", type=int, default=5)
    ap.add_argument("--scheme", default="minpos")
    ap.add_argument("--radio", default="ideal-100Bps")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--max-sim-s", type=float, default=14400.0)
    ap.add_argument("--every-s", type=float, default=40.0, help="simulated seconds between rows (a whole number)")
    ap.add_argument("--stat", action="append", default=[], help="a per-robot counter to show (repeat for more)")
    args = ap.parse_args(argv)
    try:
        if not 1 <= args.robots <= 64:
            raise TimelineError(f"--robots {args.robots}: must be 1 to 64")
        if args.every_s < 1 or args.every_s != int(args.every_s):
            raise TimelineError(f"--every-s {args.every_s:g}: must be a whole number of seconds, at least 1")
        if args.max_sim_s <= 0:
            raise TimelineError(f"--max-sim-s {args.max_sim_s:g}: must be positive")
        try:
            resolve_map(args.map)
        except (OSError, ValueError) as e:
            raise TimelineError(f"--map {args.map}: {e}") from None
        cfg = MissionConfig(map_spec=args.map, robots=args.robots, seed=args.seed, strategy=args.scheme,
                            radio=args.radio, max_sim_s=args.max_sim_s)
        rows, result = timeline(cfg, args.every_s, args.stat)
    except (TimelineError, ValueError, KeyError) as e:
        # A KeyError's str() is its argument's repr: print the message itself.
        print(f"team_timeline: {e.args[0] if isinstance(e, KeyError) and e.args else e}", file=sys.stderr)
        return 2
    print(markdown(rows, args.stat))
    print(f"\n{result.termination}: coverage {result.coverage:.4f}, T_total {result.t_total_s:.1f} s, "
          f"paths " + ", ".join(f"{p:.0f}" for p in result.path_length_m) + " m")
    return 0


if __name__ == "__main__":
    sys.exit(main())
