#!/usr/bin/env bash
# The mass-spring step side by side in one run: vsurg's implicit Euler (vsurg-bench msm-step:
# conjugate gradient to 1e-3, and to VegaFEM's 1e-6 with no energy floor), PositionBasedDynamics' XPBD
# (bench/peers/pbd: 10 iterations of its distance constraint over every spring, compliance 1/k)
# and, given its checkout, VegaFEM's implicit mass-spring step (bench/peers/vegafem: backward
# Euler, one Newton iteration, Jacobi PCG to 1e-6), on the same scenes written out by
# `vsurg-bench msm-step --export` (the 1026-particle sphere pressed 5 mm, the 6182-particle arm
# twisted 60°, dt 0.2 ms), alternately, REPS rounds. Prints one table: the median time per step
# over the rounds and each peer's time over this row's per round (median).
#
# usage: bench/peers/msm.sh BIN_DIR PBD_CHECKOUT [VEGAFEM_CHECKOUT]
#   PBD_CHECKOUT: a checkout of https://github.com/InteractiveComputerGraphics/PositionBasedDynamics
#   outside this repository (only PositionBasedDynamics/ and Common/ are read; the harness is
#   built beside it in CHECKOUT-harness). VEGAFEM_CHECKOUT: https://github.com/dyollb/VegaFEM, the
#   harness built in CHECKOUT-harness as fem.sh builds it. Environment: REPS (default 5), STEPS
#   (default 2000), ITERATIONS (PBD's, default 10), OUT (raw JSON lines), PIN_CPU (the core every
#   run is pinned to, default 0; empty: unpinned; common.sh).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
peers_setup msm.sh "${1:?BIN_DIR}" "${2:?PBD_CHECKOUT}"
vega="${3:-}"
if [ -n "$vega" ]; then
  [ -d "$vega/libraries" ] || { echo "msm.sh: $vega is not a VegaFEM checkout" >&2; exit 2; }
  vega="$(cd "$vega" && pwd)"
  peers_outside msm.sh "$vega"
  peers_build_vega msm.sh "$vega"
fi
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
  for tolerance in 1e-3 1e-6; do
    # At VegaFEM's 1e-6 ours iterates to it too (no energy floor): like for like.
    floor=1e-13; [ "$tolerance" = 1e-6 ] && floor=0
    peers_pinned "$bin/vsurg-bench" msm-step --steps "$steps" --tolerance "$tolerance" \
      --energy-floor "$floor" --json |
      sed "s/^/{\"rep\": $rep, \"who\": \"vsurg $tolerance\", \"result\": /; s/\$/}/" >> "$lines"
  done
  for scene in sphere1026 arm6182; do
    j="$(peers_pinned "$peer-harness/pbd_step" "$out/scenes/$scene.msm" "$steps" "$iterations")"
    echo "{\"rep\": $rep, \"who\": \"pbd\", \"result\": $j}" >> "$lines"
    if [ -n "$vega" ]; then
      j="$(peers_pinned "$vega-harness/vega_msm_step" "$out/scenes/$scene.msm" "$((steps / 10))")"
      echo "{\"rep\": $rep, \"who\": \"vegafem\", \"result\": $j}" >> "$lines"
    fi
  done
  echo "msm.sh: round $rep of $reps done" >&2
done

python3 - "$lines" <<'PY'
import json, statistics, sys
rows = [json.loads(l) for l in open(sys.argv[1])]
print("| scene | particles | springs | who | method | µs per step (median over rounds) | PBD / this | VegaFEM / this |")
print("| --- | --- | --- | --- | --- | --- | --- | --- |")
for scene in ("sphere1026", "arm6182"):
    of = lambda who: [x for x in rows if x["result"]["scene"] == scene and x["who"] == who]
    peers = {p: {x["rep"]: x["result"]["step_us_median"] for x in of(p)} for p in ("pbd", "vegafem")}
    for who in ("vsurg 1e-3", "vsurg 1e-6", "pbd", "vegafem"):
        xs = of(who)
        if not xs:
            continue
        us = statistics.median(x["result"]["step_us_median"] for x in xs)
        ratio = lambda p: (f"{statistics.median(peers[p][x['rep']] / x['result']['step_us_median'] for x in xs):.2f}"
                           if peers[p] and who not in ("pbd", "vegafem") else "")
        r = xs[0]["result"]
        print(f"| {scene} | {r['particles']} | {r['springs']} | {who.split()[0]} | {r['method']} | {us:.1f} | {ratio('pbd')} | {ratio('vegafem')} |")
PY
echo "raw: $lines" >&2
