#!/usr/bin/env bash
# Fuzzes one target (or all, two at a time) with libFuzzer for SECONDS each, from the kept corpus.
#
#   deploy/fuzz.sh TARGET|all SECONDS [--merge] [-- extra libFuzzer flags]
#
# Targets (tests/fuzz/): datagram messages scene_json obj ratings_csv trajectory_csv http_api
# http_framing cluster_messages handoff.
# Builds the targets in build-asan/ (clang: libFuzzer, AddressSanitizer + UndefinedBehaviorSanitizer;
# the same build deploy/sanitize.sh tests); reads the kept corpus tests/fuzz/corpus/TARGET and
# writes what it finds new to build-asan/corpus/TARGET (never into the repository unless --merge,
# which minimises the new inputs into the kept corpus for a commit). A crash, a leak, a property
# failure or an input slower than 10 s stops the run with exit 1 and leaves the input in
# build-asan/crashes/. Prints each target's executions.
set -euo pipefail
source "$(dirname "$0")/lib.sh"
root="$(vsurg_root)"
targets_all=(datagram messages scene_json obj ratings_csv trajectory_csv http_api http_framing
  cluster_messages handoff id_token)
if [ $# -lt 2 ]; then
  echo "usage: deploy/fuzz.sh TARGET|all SECONDS [--merge] [-- libFuzzer flags]" >&2
  echo "targets: ${targets_all[*]}" >&2
  exit 2
fi
target="$1" seconds="$2"
shift 2
merge=0
extra=()
while [ $# -gt 0 ]; do
  case "$1" in
    --merge) merge=1 ;;
    --) shift; extra=("$@"); break ;;
    *) echo "deploy/fuzz.sh: unknown option $1" >&2; exit 2 ;;
  esac
  shift
done
if ! [[ "$seconds" =~ ^[0-9]+$ ]] || [ "$seconds" -lt 1 ]; then
  echo "deploy/fuzz.sh: SECONDS must be a positive whole number" >&2
  exit 2
fi
if [ "$target" = all ]; then
  targets=("${targets_all[@]}")
elif [[ " ${targets_all[*]} " == *" $target "* ]]; then
  targets=("$target")
else
  echo "deploy/fuzz.sh: unknown target '$target' (${targets_all[*]} or all)" >&2
  exit 2
fi

vsurg_install_packages
vsurg_install_packages_of VSURG_FUZZ_PACKAGES
out="$root/build-asan"  # shared with deploy/sanitize.sh: one clang build for both
vsurg_configure_asan
cmake --build "$out" -j2 --target $(printf 'fuzz_%s ' "${targets[@]}")
mkdir -p "$out/crashes"
export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:symbolize=1"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
# One target's run: its log in build-asan/fuzz-TARGET.log, its exit code in the return.
fuzz_one() {
  local t="$1"
  mkdir -p "$out/corpus/$t"
  "$out/bin/fuzz_$t" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -max_len=8192 \
    -print_final_stats=1 -artifact_prefix="$out/crashes/$t-" ${extra[@]+"${extra[@]}"} \
    "$out/corpus/$t" "$root/tests/fuzz/corpus/$t" >"$out/fuzz-$t.log" 2>&1
}
# Two targets at a time: each libFuzzer process runs one thread, and the machine has two cores
# (ten targets at 5 s each: half a minute of CI instead of one). Each pair is reported in order
# once both ended; the first failure stops the run.
for ((i = 0; i < ${#targets[@]}; i += 2)); do
  pair=("${targets[@]:i:2}")
  pids=()
  for t in "${pair[@]}"; do
    echo "fuzz: $t for ${seconds}s"
    fuzz_one "$t" & pids+=($!)
  done
  for k in "${!pair[@]}"; do
    t="${pair[$k]}"
    log="$out/fuzz-$t.log"
    rc=0
    wait "${pids[$k]}" || rc=$?
    runs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' || true)
    echo "fuzz: $t executions=${runs:-?} exit=$rc"
    if [ $rc -ne 0 ]; then
      tail -40 "$log" >&2
      echo "fuzz: $t FAILED; the input is in $out/crashes/" >&2
      wait || true
      exit 1
    fi
  done
  if [ $merge -eq 1 ]; then
    for t in "${pair[@]}"; do
      "$out/bin/fuzz_$t" -merge=1 -max_len=8192 "$root/tests/fuzz/corpus/$t" "$out/corpus/$t" \
        >>"$out/fuzz-$t.log" 2>&1
      echo "fuzz: $t corpus merged into tests/fuzz/corpus/$t ($(ls "$root/tests/fuzz/corpus/$t" | wc -l) files)"
    done
  fi
done
