#!/usr/bin/env bash
# The haptic round trip side by side in one run: vsurg's (vsurg-bench haptic-rtt: authenticated
# stylus datagram -> the server's physics -> force datagram), the bare-UDP floor under it
# (vsurg-bench udp-floor: the same stations and pacing against a plain echo) and OpenIGTLink's
# (bench/peers/openigtlink: TRANSFORM over TCP, answered by a TRANSFORM), run alternately,
# REPS rounds per station count, so a slow minute of the machine falls on all three alike.
# Prints one table: the median over the rounds of each p50/p99/p99.9 and loss, and each p99 as
# a ratio to the floor's p99 of the same round (then the median of those ratios).
#
# usage: bench/peers/rtt.sh BIN_DIR OPENIGTLINK_CHECKOUT [STATIONS...]
#   BIN_DIR: vsurg's build/bin; OPENIGTLINK_CHECKOUT: a checkout of
#   https://github.com/openigtlink/OpenIGTLink outside this repository (built here, beside it,
#   in CHECKOUT-build, with our harness in CHECKOUT-harness). STATIONS default: 1 8 64.
#   Environment: REPS (default 5), SECONDS_EACH (default 10), PRIORITY (SCHED_FIFO priority for
#   ours, default 0: none, as OpenIGTLink has none), OUT (a folder for the raw JSON lines).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
peers_setup rtt.sh "${1:?BIN_DIR}" "${2:?OPENIGTLINK_CHECKOUT}"
shift 2
stations=("$@")
[ ${#stations[@]} -gt 0 ] || stations=(1 8 64)
reps="${REPS:-5}"
seconds="${SECONDS_EACH:-10}"
priority="${PRIORITY:-0}"

if [ ! -x "$peer-harness/igtl_rtt" ]; then
  echo "rtt.sh: building OpenIGTLink in $peer-build and the harness in $peer-harness" >&2
  cmake -S "$peer" -B "$peer-build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DBUILD_TESTING=OFF \
    -DBUILD_EXAMPLES=OFF >/dev/null
  cmake --build "$peer-build" -j2 >/dev/null
  cmake -S "$here/openigtlink" -B "$peer-harness" -G Ninja -DCMAKE_BUILD_TYPE=Release \
    "-DOpenIGTLink_DIR=$peer-build" >/dev/null
  cmake --build "$peer-harness" -j2 >/dev/null
fi

raw="$out/rtt.jsonl"
: > "$raw"
for n in "${stations[@]}"; do
  for r in $(seq 1 "$reps"); do
    for who in floor vsurg openigtlink; do
      case "$who" in
        floor) line="$("$bin/vsurg-bench" udp-floor --stations "$n" --seconds "$seconds" \
                  --realtime-priority "$priority" --json)" ;;
        vsurg) line="$("$bin/vsurg-bench" haptic-rtt --stations "$n" --seconds "$seconds" \
                  --realtime-priority "$priority" --json)" ;;
        openigtlink) line="$("$peer-harness/igtl_rtt" --stations "$n" --seconds "$seconds")" ;;
      esac
      printf '{"who":"%s","round":%d,"result":%s}\n' "$who" "$r" "$line" >> "$raw"
    done
    echo "rtt.sh: $n stations, round $r of $reps done" >&2
  done
done

python3 - "$raw" "$seconds" <<'EOF'
import json, statistics, sys
rows = [json.loads(l) for l in open(sys.argv[1])]
by = {}
for r in rows:
    by.setdefault((r["result"]["stations"], r["who"]), []).append(r)
print(f"{sys.argv[2]} s per run, median over the rounds; ratio = p99 / the floor's p99 "
      "of the same round")
print("| stations | who | p50 µs | p99 µs | p99.9 µs | loss | p99 / floor |")
print("| --- | --- | --- | --- | --- | --- | --- |")
for n in sorted({k[0] for k in by}):
    floors = {r["round"]: r["result"]["rtt_p99_us"] for r in by.get((n, "floor"), [])}
    for who in ("floor", "vsurg", "openigtlink"):
        rs = by.get((n, who), [])
        if not rs:
            continue
        med = lambda key: statistics.median(r["result"][key] for r in rs)
        ratios = [r["result"]["rtt_p99_us"] / floors[r["round"]] for r in rs
                  if floors.get(r["round"])]
        ratio = f"{statistics.median(ratios):.2f}" if ratios else "-"
        print(f"| {n} | {who} | {med('rtt_p50_us'):.0f} | {med('rtt_p99_us'):.0f} | "
              f"{med('rtt_p999_us'):.0f} | {max(r['result']['loss'] for r in rs):.4f} | {ratio} |")
EOF
echo "raw results: $raw" >&2
