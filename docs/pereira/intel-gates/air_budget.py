"""Where a Pereira mission's bytes went, from a capture (`lorascout run ... --capture FILE`):
bytes by record kind (the record's size; the rest of each frame is header, group tags and
CRC), and of the place, gate and claim records sent, how many were copies of one already on
the air (pushes), how soon after the previous copy, and how many sends reached no robot
that had not heard that record before.

    PYTHONPATH=. .venv/bin/python docs/pereira/intel-gates/air_budget.py CAPTURE
"""
import bisect
import collections
import json
import subprocess
import sys

from firmware.schemes import all_dialects

DIALECTS = all_dialects()
SHARED = ("place", "gate", "claim")

out = subprocess.run([sys.executable, "-m", "host_tools.cli", "inspect", "--json", sys.argv[1]],
                     capture_output=True, text=True, check=True).stdout
frames = json.loads(out)["frames"]
total = sum(f["size_bytes"] for f in frames)
kinds = collections.Counter(f"{r['dialect']}.{r['type']}" for f in frames for r in f["records"])
print(f"{len(frames)} frames, {total} bytes")
in_records = 0
for kind, n in kinds.most_common():
    b = n * DIALECTS.record(kind.split(".")[1]).size_bytes
    in_records += b
    print(f"  {kind:18s} {n:6d} records {b:7d} B {100 * b / total:5.1f} %")
print(f"  frame headers, group tags, CRC       {total - in_records:7d} B {100 * (total - in_records) / total:5.1f} %")

last_sent, holders = {}, collections.defaultdict(set)
gaps, copies, reached_none = [], 0, 0
for f in frames:
    heard = {rc["receiver_id"] for rc in f["receptions"] if rc["fate"] == "received"}
    for r in f["records"]:
        if r["type"] not in SHARED:
            continue
        v = r["values"]
        key = (r["type"], v["sender_id"], v["oseq"])
        if key in last_sent:
            copies += 1
            gaps.append((f["start_us"] - last_sent[key]) / 1e6)
        last_sent[key] = f["start_us"]
        h = holders[key]
        h.update({v["sender_id"], f["sender_id"]})
        reached_none += not (heard - h)
        h |= heard
gaps.sort()
sent = sum(kinds[f"pereira.{k}"] for k in SHARED)
print(f"places, gates, claims: {sent} sent, {copies} copies of a record already on the air, "
      f"{reached_none} sends that reached no robot new")
for s in (2.25, 10.0, 20.0):
    print(f"  copies within {s} s of the previous copy: {bisect.bisect(gaps, s)}")
