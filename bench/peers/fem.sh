#!/usr/bin/env bash
# The corotational FEM step side by side in one run: vsurg's (vsurg-bench fem-step: one implicit
# Euler step, one Newton step, CG warm-started and preconditioned by symmetric block Gauss-Seidel,
# at our tolerance 1e-4 and at VegaFEM's 1e-6; and at 1e-6 with block Jacobi, the preconditioner
# it had before) and VegaFEM's (bench/peers/vegafem: ImplicitBackwardEulerSparse, one Newton
# iteration, Jacobi PCG to 1e-6 as Vega's source fixes it) on the same bar, written out by
# vsurg-bench fem-step --export (mesh, material, fixed base, tip torque, h = 1 ms, Rayleigh
# damping), run alternately REPS rounds per size. Prints one table: the median over the rounds of
# each time per step, and VegaFEM's time over ours per round (then the median).
#
# usage: bench/peers/fem.sh BIN_DIR VEGAFEM_CHECKOUT [RINGS...]
#   BIN_DIR: vsurg's build/bin; VEGAFEM_CHECKOUT: a checkout of
#   https://github.com/dyollb/VegaFEM outside this repository (our harness compiles the Vega
#   sources the step needs, without TBB: one thread, as ours, into CHECKOUT-harness). RINGS
#   default: 4 5 (5 760 and 11 250 tetrahedra).
#   Environment: REPS (default 5), STEPS (timed steps per run, default 50), OUT (raw JSON lines),
#   PIN_CPU (the core every run is pinned to, default 0; empty: unpinned; common.sh).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
peers_setup fem.sh "${1:?BIN_DIR}" "${2:?VEGAFEM_CHECKOUT}"
shift 2
rings=("$@")
[ ${#rings[@]} -gt 0 ] || rings=(4 5)
reps="${REPS:-5}"
steps="${STEPS:-50}"

peers_build_vega fem.sh "$peer"

lines="$out/fem.jsonl"
: > "$lines"
for r in "${rings[@]}"; do
  "$bin/vsurg-bench" fem-step --rings "$r" --export "$out/bar$r"
  for rep in $(seq "$reps"); do
    for who in vsurg vsurg-1e-6 vsurg-1e-6-jacobi vegafem; do
      case $who in
        vsurg) j=$(peers_pinned "$bin/vsurg-bench" fem-step --rings "$r" --steps "$steps" --json) ;;
        vsurg-1e-6) j=$(peers_pinned "$bin/vsurg-bench" fem-step --rings "$r" --steps "$steps" --tolerance 1e-6 --json) ;;
        vsurg-1e-6-jacobi) j=$(peers_pinned "$bin/vsurg-bench" fem-step --rings "$r" --steps "$steps" --tolerance 1e-6 --preconditioner jacobi --json) ;;
        vegafem) j=$(peers_pinned "$peer-harness/vega_fem_step" "$out/bar$r" "$steps") ;;
      esac
      echo "{\"rings\": $r, \"rep\": $rep, \"run\": \"$who\", \"result\": $j}" >> "$lines"
    done
  done
done

python3 - "$lines" <<'PY'
import json, statistics, sys
rows = [json.loads(l) for l in open(sys.argv[1])]
print("| tets | who | ms per step (median over rounds) | CG iterations | largest displacement after the run | VegaFEM / this (per round: median, lowest-highest) |")
print("| --- | --- | --- | --- | --- | --- |")
for r in sorted({x["rings"] for x in rows}):
    of = lambda who: [x for x in rows if x["rings"] == r and x["run"] == who]
    vega = {x["rep"]: x["result"]["ms_median"] for x in of("vegafem")}
    for who in ("vsurg", "vsurg-1e-6", "vsurg-1e-6-jacobi", "vegafem"):
        xs = of(who)
        ms = statistics.median(x["result"]["ms_median"] for x in xs)
        it = xs[0]["result"].get("cg_iterations")
        per_round = [vega[x["rep"]] / x["result"]["ms_median"] for x in xs]
        ratio = f"{statistics.median(per_round):.2f} ({min(per_round):.2f}-{max(per_round):.2f})"
        moved = statistics.median(x["result"]["max_displacement_m"] for x in xs)
        print(f"| {xs[0]['result']['tets']} | {who} | {ms:.2f} | {'' if it is None else f'{it:.1f}'} | {moved * 1e3:.3f} mm | {ratio} |")
PY
echo "raw: $lines" >&2
