#!/usr/bin/env bash
# What sessions nobody drives cost a driven one, side by side in one run: one station's round
# trip at 1 kHz (vsurg-bench haptic-rtt, 10 s) with no other session, with 12 never-started
# mass-spring sessions as the server now keeps them (no deformation thread), and with the same 12
# each running its deformation thread (as every session did before), alternating, 3 runs each.
# usage: bench/idle_sessions.sh [BIN_DIR] [IDLE=12] [SECONDS=10]
set -euo pipefail
B="$(cd "${1:-build/bin}" && pwd)"
idle="${2:-12}"
seconds="${3:-10}"
export VSURG_SCENES="$(cd "$(dirname "$0")/.." && pwd)/scenes"
printf '%-28s %4s %10s %10s %11s %8s\n' setting run p50_us p99_us p99.9_us loss
for rep in 1 2 3; do
  for mode in none idle idle-threads; do
    case "$mode" in
      none) extra=() ;;
      idle) extra=(--idle "$idle") ;;
      idle-threads) extra=(--idle "$idle" --idle-threads) ;;
    esac
    "$B/vsurg-bench" haptic-rtt --stations 1 --seconds "$seconds" --scene arm-torsion \
      ${extra[@]+"${extra[@]}"} --json |
      sed -n 's/.*"loss":\([0-9.e+-]*\).*"rtt_p50_us":\([0-9.e+-]*\).*"rtt_p999_us":\([0-9.e+-]*\).*"rtt_p99_us":\([0-9.e+-]*\).*/\1 \2 \3 \4/p' |
      while read -r loss p50 p999 p99; do
        printf '%-28s %4d %10.0f %10.0f %11.0f %8.4f\n' "$mode ($idle sessions)" "$rep" "$p50" "$p99" "$p999" "$loss"
      done
  done
done
