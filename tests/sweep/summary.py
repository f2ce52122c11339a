#!/usr/bin/env python3
"""Adds up the chunks of tests/sweep/strict.sh: `summary.py OUT_DIR`.

Prints the seeds run, the cases solved and refused (typed `Unresolved`),
the chunks that failed (with the failing case's message), and the worst
value of every law over all chunks with the case it was seen at.
"""
import pathlib
import re
import sys

out = pathlib.Path(sys.argv[1])
solved = refused = 0
seeds = []
failed = []
unfinished = []
worst = {}
for log in sorted(out.glob("seed-*.log")):
    text = log.read_text(errors="replace")
    seed = log.stem.split("-", 1)[1]
    m = re.search(r"\[properties\] seed \S+, (\d+) cases requested, (\d+) solved \(shrinking included\), (\d+) refused", text)
    if not m:
        unfinished.append(seed)
        continue
    seeds.append(seed)
    solved += int(m.group(2))
    refused += int(m.group(3))
    if "test result: ok" not in text:
        msg = re.search(r"property failed: (.*)", text)
        failed.append((seed, msg.group(1)[:400] if msg else "?"))
    for name, value, at in re.findall(r"\[properties\] worst (.+?): (\S+) at (.*)", text):
        v = float(value)
        if name not in worst or v > worst[name][0]:
            worst[name] = (v, f"seed {seed}: {at[:300]}")
print(f"chunks finished: {len(seeds)}; running or cut: {len(unfinished)}")
print(f"cases solved: {solved} (shrinking included); refused as unresolved: {refused}")
print(f"chunks failed: {len(failed)}")
for seed, msg in failed:
    print(f"  seed {seed}: {msg}")
for name, (v, at) in worst.items():
    print(f"worst {name}: {v:.3e}  ({at})")
