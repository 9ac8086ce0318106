"""`lorascout map`: what a map asks of a team, before any mission: the area the robot body
can reach (what coverage is scored against) and, for a planner that keeps a clearance from
walls, the share of it a LiDAR can see at all from where that planner may drive."""
from __future__ import annotations

import argparse
import sys

from host_tools.map_report import PLANNER_CLEARANCE_M, drivable_centres, observable_share
from host_tools.options import JSON, MAP, QUIET, Opt, add_options
from host_tools.progress import progress_bar
from host_tools.safe_io import atomic_path, strict_dumps
from world_sim.map_spec import resolve_map
from world_sim.world import WorldParams

OPTIONS = (
    MAP,
    Opt("--clearance-m", "float", "the planner's distance from wall cells, one or more (default: the firmware's "
        "robot radius plus safety margin)", unit="m", lo=0.0, lo_open=True, hi=10.0, nargs="+",
        default=[PLANNER_CLEARANCE_M], metavar="M"),
    Opt("--stride-m", "float", "stand the LiDAR on the drivable cells every this many metres", unit="m", lo=0.01,
        hi=100.0, default=0.1, metavar="M"),
    Opt("--png", "out_file", "draw the drivable cells and what no station sees, for the first clearance",
        metavar="FILE"),
    JSON, QUIET,
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_options(p, OPTIONS)


def main(args: argparse.Namespace) -> int:
    world = WorldParams()
    try:
        occ, start, label = resolve_map(args.map)
    except (ValueError, KeyError, OSError) as exc:
        print(f"lorascout map: {exc}", file=sys.stderr)
        return 2
    results = []
    for clearance_m in args.clearance_m:
        bar = progress_bar(None, f"clearance {clearance_m} m", "stations", args.quiet)
        try:
            share, unseen = observable_share(occ, (start[0], start[1]), clearance_m,
                                             body_radius_m=world.robot_radius_m, lidar_beams=world.lidar_beams,
                                             lidar_range_m=world.lidar_range_m, stride_m=args.stride_m,
                                             on_station=bar.update)
        except ValueError as exc:
            bar.close()
            print(f"lorascout map: {exc}", file=sys.stderr)
            return 2
        bar.close()
        if args.png is not None and not results:
            from host_tools.plots import plot_unobservable

            try:
                with atomic_path(args.png) as tmp:
                    plot_unobservable(occ, drivable_centres(occ, (start[0], start[1]), clearance_m), unseen,
                                      f"{label}: clearance {clearance_m} m sees {100 * share.observable_share:.2f} % "
                                      f"of the reachable area; red: {share.unobservable_m2:.2f} m² seen from nowhere",
                                      tmp)
            except OSError as exc:
                print(f"lorascout map: cannot write {args.png}: {exc}", file=sys.stderr)
                return 1
        results.append(share)
    if args.json:
        print(strict_dumps({"map": label, "resolution_m": occ.resolution_m, "body_radius_m": world.robot_radius_m,
                          "lidar_beams": world.lidar_beams, "lidar_range_m": world.lidar_range_m,
                          "clearances": [r.to_json() for r in results]}, sort_keys=True))
        return 0
    print(f"{label}: {occ.resolution_m} m cells; {results[0].reachable_m2:.1f} m² reachable by the robot body "
          f"(radius {world.robot_radius_m} m); LiDAR {world.lidar_beams} beams, {world.lidar_range_m:g} m, "
          f"stood every {results[0].stride_m:.2f} m on the drivable cells")
    print()
    print("| clearance [m] | drivable [m²] | stations | observable share (coverage ceiling) | seen from nowhere [m²] |")
    print("|---:|---:|---:|---:|---:|")
    for r in results:
        print(f"| {r.clearance_m:.2f} | {r.drivable_m2:.1f} | {r.stations} | {r.observable_share:.4f} | "
              f"{r.unobservable_m2:.2f} |")
    if args.png is not None:
        print(f"\nwrote {args.png}")
    return 0
