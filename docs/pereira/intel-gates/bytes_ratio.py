"""Mean LoRa bytes per second per robot (over every robot of every trial) of one scheme in one
sweep against another's, per map and radio: the figure issue 23 bounds at 0.8.

    python docs/pereira/intel-gates/bytes_ratio.py NEW/trials.jsonl SCHEME OLD/trials.jsonl SCHEME
"""
import collections
import json
import sys


def mean_bps(path: str, scheme: str) -> dict[tuple[str, str], float]:
    per = collections.defaultdict(list)
    for line in open(path):
        t = json.loads(line)
        if t["strategy"] == scheme:
            per[(t["map"], t["radio"])].extend(t["radio_stats"]["bytes_per_s_mean"])
    return {k: sum(v) / len(v) for k, v in per.items()}


new_path, new_scheme, old_path, old_scheme = sys.argv[1:5]
new, old = mean_bps(new_path, new_scheme), mean_bps(old_path, old_scheme)
print(f"| map | radio | {new_scheme} B/s | {old_scheme} B/s | ratio |")
print("|---|---|---|---|---|")
for key in sorted(new.keys() & old.keys()):
    print(f"| {key[0]} | {key[1]} | {new[key]:.1f} | {old[key]:.1f} | {new[key] / old[key]:.2f} |")
