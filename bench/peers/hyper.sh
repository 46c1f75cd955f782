#!/usr/bin/env bash
# The neo-Hookean FEM's implicit step side by side in one run: vsurg's (vsurg-bench hyper-step:
# backward Euler with lumped masses, Newton to 1e-6 of the largest load, each Newton system by
# diagonally preconditioned CG to a fraction of that) and VegaFEM's (bench/peers/vegafem:
# IsotropicHyperelasticFEM with NeoHookeanIsotropicMaterial, the same energy, in
# ImplicitBackwardEulerSparse with Vega's consistent mass matrix, Newton until the residual is 1e-6
# of the step's first, Jacobi PCG to 1e-6) on the same bar under 20 mN·m, written out by
# vsurg-bench hyper-step --export (mesh, material, fixed base, tip forces, h = 1 ms, no damping),
# run alternately REPS rounds per size. Prints one table: the median over the rounds of each time
# per step, and VegaFEM's time over ours per round (median, lowest-highest).
#
# usage: bench/peers/hyper.sh BIN_DIR VEGAFEM_CHECKOUT [RINGS...]
#   as fem.sh (RINGS default: 4 5, 5 760 and 11 250 tetrahedra). Environment: REPS (default 3),
#   STEPS (timed steps per run, default 20), PIN_CPU (common.sh).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
peers_setup hyper.sh "${1:?BIN_DIR}" "${2:?VEGAFEM_CHECKOUT}"
shift 2
rings=("$@")
[ ${#rings[@]} -gt 0 ] || rings=(4 5)
reps="${REPS:-3}"
steps="${STEPS:-20}"

peers_build_vega hyper.sh "$peer"

lines="$out/hyper.jsonl"
: > "$lines"
for r in "${rings[@]}"; do
  "$bin/vsurg-bench" hyper-step --rings "$r" --export "$out/hyperbar$r"
  for rep in $(seq "$reps"); do
    for who in vsurg vegafem; do
      case $who in
        vsurg) j=$(peers_pinned "$bin/vsurg-bench" hyper-step --rings "$r" --steps "$steps" --json) ;;
        vegafem) j=$(peers_pinned "$peer-harness/vega_hyper_step" "$out/hyperbar$r" "$steps" 1e-6) ;;
      esac
      echo "{\"rings\": $r, \"rep\": $rep, \"run\": \"$who\", \"result\": $j}" >> "$lines"
    done
  done
done

python3 - "$lines" <<'PY'
import json, statistics, sys
rows = [json.loads(l) for l in open(sys.argv[1])]
print("| tets | who | ms per step (median over rounds) | Newton iterations | largest displacement after the run | VegaFEM / this (per round: median, lowest-highest) |")
print("| --- | --- | --- | --- | --- | --- |")
for r in sorted({x["rings"] for x in rows}):
    of = lambda who: [x for x in rows if x["rings"] == r and x["run"] == who]
    vega = {x["rep"]: x["result"]["ms_median"] for x in of("vegafem")}
    for who in ("vsurg", "vegafem"):
        xs = of(who)
        ms = statistics.median(x["result"]["ms_median"] for x in xs)
        it = xs[0]["result"].get("newton_iterations")
        per_round = [vega[x["rep"]] / x["result"]["ms_median"] for x in xs]
        ratio = f"{statistics.median(per_round):.2f} ({min(per_round):.2f}-{max(per_round):.2f})"
        moved = statistics.median(x["result"]["max_displacement_m"] for x in xs)
        print(f"| {xs[0]['result']['tets']} | {who} | {ms:.2f} | {'' if it is None else f'{it:.1f}'} | {moved * 1e3:.3f} mm | {ratio} |")
PY
echo "raw: $lines" >&2
