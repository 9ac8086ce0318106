"""Meier et al.'s split-rate sweep (issue 22; the paper's Fig. 6 and Tables 1 and 2): what a
split rate costs in bytes and what it buys, from finished sweeps of `meier` that differ only
in `meier_split_rate_hz`:

    for sr in 0.04 0.2 1 4; do
        lorascout sweep --maps ../shared/maps/maze_a.yaml --schemes meier --radio eu868-g3 \\
            --robots 5 --seeds 10 --set meier_split_rate_hz=$sr --set meier_radio_share=1 \\
            --out out/split_rate/sr-$sr
    done
    python -m host_tools.split_rate out/split_rate/sr-* --out out/split_rate

(`meier_radio_share=1` lets the split rate, not the robot's byte budget, set the pace, up to
what the link sustains.) Each folder's trials.jsonl is read (the split rate of a trial is
its `--set meier_split_rate_hz`, the parameter's default if not set); per map, radio and
split rate: the bytes a second per robot, p_max and T_total against them (split_rate.png),
the share of each kind of record (Table 1) and the approximation error (Table 2). Written to
--out as tables.md, tables.json and split_rate.png; the Markdown is printed too.
"""
from __future__ import annotations

import argparse
import json
import statistics
import sys
from pathlib import Path

from firmware.params import ExplorationParams
from host_tools.compare_grids import GridError, load_records

# Records a robot sends, by kind: explorer_stats keys, in the order of the table.
RECORD_KINDS = (("emerged", "poly_emerged_records"), ("vanished", "poly_vanished_records"),
                ("broken", "poly_broken_records"), ("edge split", "poly_edge_split_records"),
                ("refresh", "poly_refresh_records"), ("alive blocks", "poly_alive_records_sent"),
                ("target", "target_records_sent"), ("lost-frame request", "nack_records_sent"))
DEFAULTS = ExplorationParams()


def _fields(t: dict) -> dict:
    if t["strategy"] != "meier" or "polygon_maps" not in t:
        raise ValueError(f"a trial of {t['strategy']!r}, not of meier's polygons")
    stats, maps = t["explorer_stats"], t["polygon_maps"]
    return {
        "map": str(t["map"]), "radio": str(t["radio"]), "seed": int(t["seed"]),
        "split_rate_hz": float(t.get("params_overrides", {}).get("meier_split_rate_hz", DEFAULTS.meier_split_rate_hz)),
        "radio_share": float(t.get("params_overrides", {}).get("meier_radio_share", DEFAULTS.meier_radio_share)),
        "bytes_per_s": statistics.fmean(float(b) for b in t["radio_stats"]["bytes_per_s_mean"]),
        "p_max_m": max(float(x) for x in t["path_length_m"]), "t_total_s": float(t["t_total_s"]),
        "splits_per_s": statistics.fmean(float(x) for x in maps["split_rate_hz"]),
        "error": statistics.fmean(float(x) for x in maps["approximation_error_mean"]),
        "records": {kind: sum(int(n) for n in stats.get(key, [0])) for kind, key in RECORD_KINDS},
    }


def rows(trials: list[dict]) -> list[dict]:
    """One row per map, radio, radio share and split rate (in that order), from the trials."""
    groups: dict[tuple[str, str, float, float], list[dict]] = {}
    for t in trials:
        groups.setdefault((t["map"], t["radio"], t["radio_share"], t["split_rate_hz"]), []).append(t)
    out = []
    for (map_label, radio, share, rate), ts in sorted(groups.items()):
        total = sum(sum(t["records"].values()) for t in ts)
        out.append({
            "map": map_label, "radio": radio, "radio_share": share, "split_rate_hz": rate, "trials": len(ts),
            "seeds": sorted(t["seed"] for t in ts),
            "bytes_per_s": statistics.fmean(t["bytes_per_s"] for t in ts),
            "p_max_m": statistics.median(t["p_max_m"] for t in ts),
            "t_total_s": statistics.median(t["t_total_s"] for t in ts),
            "splits_per_s": statistics.fmean(t["splits_per_s"] for t in ts),
            "error": statistics.fmean(t["error"] for t in ts),
            "record_share": {kind: (sum(t["records"][kind] for t in ts) / total if total else 0.0)
                             for kind, _ in RECORD_KINDS},
        })
    return out


def markdown(table: list[dict]) -> str:
    head = ("| map | radio | radio share | split rate [1/s] | trials | B/s per robot | p_max [m], median "
            "| T_total [s], median | splits achieved [1/s] | approximation error |")
    lines = ["Cost and gain of each split rate (the paper's Fig. 6 and Table 2):", "", head,
             "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in table:
        lines.append(f"| {r['map']} | {r['radio']} | {r['radio_share']:g} | {r['split_rate_hz']:g} | {r['trials']} "
                     f"| {r['bytes_per_s']:.1f} "
                     f"| {r['p_max_m']:.1f} | {r['t_total_s']:.0f} | {r['splits_per_s']:.3f} | {r['error']:.4f} |")
    kinds = [kind for kind, _ in RECORD_KINDS]
    lines += ["", "Share of the records sent, by kind (the paper's Table 1):", "",
              "| map | radio | radio share | split rate [1/s] | " + " | ".join(kinds) + " |",
              "|---|---|---:|---:|" + "---:|" * len(kinds)]
    for r in table:
        shares = " | ".join(f"{100 * r['record_share'][k]:.1f} %" for k in kinds)
        lines.append(f"| {r['map']} | {r['radio']} | {r['radio_share']:g} | {r['split_rate_hz']:g} | {shares} |")
    return "\n".join(lines) + "\n"


def plot(trials: list[dict], table: list[dict], path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for ax, key, label in ((axes[0], "p_max_m", "p_max [m]"), (axes[1], "t_total_s", "T_total [s]")):
        for map_label, radio, share in sorted({(r["map"], r["radio"], r["radio_share"]) for r in table}):
            mine = [r for r in table if (r["map"], r["radio"], r["radio_share"]) == (map_label, radio, share)]
            line, = ax.plot([r["bytes_per_s"] for r in mine], [r[key] for r in mine], "o-",
                            label=f"{map_label}, {radio}, radio share {share:g} (medians)")
            for r in mine:
                ax.annotate(f"{r['split_rate_hz']:g}/s", (r["bytes_per_s"], r[key]), textcoords="offset points",
                            xytext=(4, 4), fontsize=8)
            each = [t for t in trials if (t["map"], t["radio"], t["radio_share"]) == (map_label, radio, share)]
            ax.scatter([t["bytes_per_s"] for t in each], [t[key] for t in each], s=10, alpha=0.4,
                       color=line.get_color())
        ax.set_xlabel("LoRa bytes a second per robot (mean)")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle("Meier et al.: what each split rate costs and buys (labels: split rate)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m host_tools.split_rate",
                                 description="tabulate and plot finished meier sweeps that differ in the split rate")
    ap.add_argument("sweeps", nargs="+", type=Path, help="the --out folders of the sweeps")
    ap.add_argument("--out", type=Path, required=True, help="folder for tables.md, tables.json, split_rate.png")
    args = ap.parse_args(argv)
    try:
        trials = [t for out in args.sweeps for t in load_records(out, _fields)]
        if args.out.exists() and not args.out.is_dir():
            raise GridError(f"--out {args.out}: exists and is not a folder")
    except GridError as exc:
        print(f"split_rate: {exc}", file=sys.stderr)
        return 2
    table = rows(trials)
    args.out.mkdir(parents=True, exist_ok=True)
    text = markdown(table)
    (args.out / "tables.md").write_text(text)
    (args.out / "tables.json").write_text(json.dumps(table, indent=1) + "\n")
    plot(trials, table, args.out / "split_rate.png")
    print(text, end="")
    return 0


if __name__ == "__main__":
    sys.exit(main())
