#!/usr/bin/env bash
# The strict property sweep of tests/properties.rs in chunks, on every core,
# at the lowest priority: `tests/sweep/strict.sh OUT_DIR FIRST_SEED CHUNKS [CASES] [JOBS]`.
#
# Each chunk is one run of `random_specs_obey_realizability_and_energy_laws`
# with `PROPTEST_SEED = FIRST_SEED + k` and `PROPTEST_CASES = CASES` (default
# 200), one thread each, JOBS chunks at a time (default: the number of cores).
# Its output goes to OUT_DIR/seed-S.log; `tests/sweep/summary.py OUT_DIR`
# adds the chunks up (cases, refusals, failures, worst value of each law).
# The test binary is copied first, so rebuilding the tree does not touch a
# running sweep.
set -euo pipefail
out=${1:?out dir}; first=${2:?first seed}; chunks=${3:?chunks}
cases=${4:-200}; jobs=${5:-$(nproc)}
cd "$(dirname "$0")/../.."
mkdir -p "$out"
bin=$(cargo test --release --test properties --no-run --message-format=json 2>/dev/null |
  python3 -c 'import json,sys
for l in sys.stdin:
    m = json.loads(l)
    if m.get("reason") == "compiler-artifact" and m.get("executable") and m["target"]["name"] == "properties":
        print(m["executable"])')
cp "$bin" "$out/properties"
seq "$first" $((first + chunks - 1)) | xargs -P "$jobs" -I{} sh -c \
  "PROPTEST_SEED={} PROPTEST_CASES=$cases RAYON_NUM_THREADS=1 nice -n 19 \
   '$out/properties' --exact random_specs_obey_realizability_and_energy_laws --nocapture \
   > '$out/seed-{}.log' 2>&1 || true"
