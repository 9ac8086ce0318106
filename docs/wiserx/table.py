"""The README's WiSER-X table from docs/wiserx/runs/*.json (one line per trial, then medians).

    python docs/wiserx/table.py docs/wiserx/runs
"""
import json
import statistics
import sys
from pathlib import Path

ORDER = ("wiserx", "wiserx-blind", "independent")


def fmt(v, nd=3):
    return "-" if v is None else (f"{v:.{nd}f}" if isinstance(v, float) else str(v))


def main(folder):
    runs = [json.loads(p.read_text()) for p in sorted(Path(folder).glob("intel_*_s*.json"))]
    print("| scheme | seed | coverage at last self-stop | last self-stop (s) | robots' stops (s) | t_90 / t_95 (s) "
          "| overlap at t_90 | overlap at end | LoRa bytes |")
    print("|---|---|---|---|---|---|---|---|---|")
    for scheme in ORDER:
        mine = sorted((r for r in runs if r["scheme"] == scheme), key=lambda r: r["seed"])
        for r in mine:
            stops = ", ".join("last" if s is None else f"{s:.0f}" for s in r["stops_s"])
            print(f"| `{scheme}` | {r['seed']} | {r['coverage']:.3f} | {r['t_total_s']:.0f} | {stops} | "
                  f"{fmt(r['t_90_s'], 0)} / {fmt(r['t_95_s'], 0)} | {fmt(r['overlap_at_t90'], 2)} | "
                  f"{r['overlap']:.2f} | {r['lora_bytes']} |")
    print()
    med = {}
    for scheme in ORDER:
        mine = [r for r in runs if r["scheme"] == scheme]
        if not mine:
            continue
        med[scheme] = {k: statistics.median(r[k] for r in mine if r[k] is not None)
                       for k in ("coverage", "t_total_s", "t_95_s", "overlap_at_t90", "overlap")}
        m = med[scheme]
        print(f"- `{scheme}` ({len(mine)} seeds), medians: coverage {m['coverage']:.3f}, last self-stop "
              f"{m['t_total_s']:.0f} s, t_95 {m['t_95_s']:.0f} s, overlap at t_90 {m['overlap_at_t90']:.2f}, "
              f"at the end {m['overlap']:.2f}")
    if "wiserx" in med and "independent" in med:
        w, i = med["wiserx"], med["independent"]
        print(f"- ratios of medians, wiserx / independent: last self-stop {w['t_total_s'] / i['t_total_s']:.2f}, "
              f"last self-stop / independent's t_95 {w['t_total_s'] / i['t_95_s']:.2f}, overlap at t_90 "
              f"{w['overlap_at_t90'] / i['overlap_at_t90']:.2f}")
    if "wiserx" in med and "wiserx-blind" in med:
        w, b = med["wiserx"], med["wiserx-blind"]
        print(f"- wiserx / wiserx-blind: last self-stop {w['t_total_s'] / b['t_total_s']:.2f}, overlap at t_90 "
              f"{w['overlap_at_t90'] / b['overlap_at_t90']:.2f}")


if __name__ == "__main__":
    main(sys.argv[1])
