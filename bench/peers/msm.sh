#!/usr/bin/env bash
# The mass-spring step side by side in one run: vsurg's implicit Euler (vsurg-bench msm-step:
# conjugate gradient to 1e-3) and PositionBasedDynamics' XPBD (bench/peers/pbd: 10 iterations of
# its distance constraint over every spring, compliance 1/k), on the same scenes written out by
# `vsurg-bench msm-step --export` (the 1026-particle sphere pressed 5 mm, the 6182-particle arm
# twisted 60°, dt 0.2 ms), alternately, REPS rounds. Prints one table: the median time per step
# over the rounds and PBD's time over ours per round (median).
#
# usage: bench/peers/msm.sh BIN_DIR PBD_CHECKOUT
#   PBD_CHECKOUT: a checkout of https://github.com/InteractiveComputerGraphics/PositionBasedDynamics
#   outside this repository (only PositionBasedDynamics/ and Common/ are read; the harness is
#   built beside it in CHECKOUT-harness). Environment: REPS (default 5), STEPS (default 2000),
#   ITERATIONS (PBD's, default 10), OUT (raw JSON lines).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
peers_setup msm.sh "${1:?BIN_DIR}" "${2:?PBD_CHECKOUT}"
reps="${REPS:-5}"
steps="${STEPS:-2000}"
iterations="${ITERATIONS:-10}"

if [ ! -x "$peer-harness/pbd_step" ]; then
  echo "msm.sh: building the harness with PBD's sources in $peer-harness" >&2
  cmake -S "$here/pbd" -B "$peer-harness" -G Ninja -DCMAKE_BUILD_TYPE=Release "-DPBD_DIR=$peer" >/dev/null
  cmake --build "$peer-harness" -j2 >/dev/null
fi

"$bin/vsurg-bench" msm-step --steps 10 --export "$out/scenes" > /dev/null
lines="$out/msm.jsonl"
: > "$lines"
for rep in $(seq "$reps"); do
  "$bin/vsurg-bench" msm-step --steps "$steps" --json | sed "s/^/{\"rep\": $rep, \"result\": /; s/\$/}/" >> "$lines"
  for scene in sphere1026 arm6182; do
    j="$("$peer-harness/pbd_step" "$out/scenes/$scene.msm" "$steps" "$iterations")"
    echo "{\"rep\": $rep, \"result\": $j}" >> "$lines"
  done
  echo "msm.sh: round $rep of $reps done" >&2
done

python3 - "$lines" <<'PY'
import json, statistics, sys
rows = [json.loads(l) for l in open(sys.argv[1])]
print("| scene | particles | springs | who | method | µs per step (median over rounds) | PBD / this (per round, median) |")
print("| --- | --- | --- | --- | --- | --- | --- |")
for scene in ("sphere1026", "arm6182"):
    of = lambda who: [x for x in rows if x["result"]["scene"] == scene and x["result"]["who"] == who]
    pbd = {x["rep"]: x["result"]["step_us_median"] for x in of("pbd")}
    for who in ("vsurg", "pbd"):
        xs = of(who)
        us = statistics.median(x["result"]["step_us_median"] for x in xs)
        ratio = statistics.median(pbd[x["rep"]] / x["result"]["step_us_median"] for x in xs)
        r = xs[0]["result"]
        print(f"| {scene} | {r['particles']} | {r['springs']} | {who} | {r['method']} | {us:.1f} | {ratio:.2f} |")
PY
echo "raw: $lines" >&2
