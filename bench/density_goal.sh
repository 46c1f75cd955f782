#!/usr/bin/env bash
# The node-density goal, side by side: per round the bare-UDP floor (udp-floor) and the server
# (haptic-rtt, pressing stations that circle STROKE_MM), alternating, at each station count; prints
# each run's round trip, read (as the driver reads and decodes each answer) and at arrival (the
# answer's kernel stamp at the station's socket: without the driver's own queueing), the round's
# p99 ratios, and the bench's own driver: the cores its one
# thread kept busy and the share of its pacer's slots sent more than a slot (125 µs) late. A round
# whose driver ran late on more than 1% of its slots is marked DRIVER-BOUND: its stations went out
# in catch-up bursts and its answers waited in the driver's sockets, so its round trips measure
# the driver as much as the node (docs/BENCHMARKS.md, "The bench's own driver at its limit").
#   usage: [ROUNDS=3] [SECONDS_EACH=5] [COUNTS="32 48 64 96 128"] [STROKE_MM=3]
#          bench/density_goal.sh [BIN_DIR]
set -euo pipefail
BIN=${1:-build/bin}
ROUNDS=${ROUNDS:-3}; SECONDS_EACH=${SECONDS_EACH:-5}; COUNTS=${COUNTS:-"32 48 64 96 128"}
STROKE_MM=${STROKE_MM:-3}
for n in $COUNTS; do for r in $(seq "$ROUNDS"); do
  floor=$("$BIN/vsurg-bench" udp-floor --stations "$n" --seconds "$SECONDS_EACH" --json)
  server=$("$BIN/vsurg-bench" haptic-rtt --stations "$n" --seconds "$SECONDS_EACH" \
             --stroke-mm "$STROKE_MM" --json)
  python3 - "$n" "$r" "$floor" "$server" <<'PY'
import json, sys
n, r = sys.argv[1], sys.argv[2]
runs = {'floor': json.loads(sys.argv[3]), 'server': json.loads(sys.argv[4])}
for who, j in runs.items():
    bound = ' DRIVER-BOUND' if j['driver_late_slots'] > 0.01 else ''
    print('n=%s round=%s %-6s p50=%.1f p99=%.1f p999=%.1f arrival p50=%.1f p99=%.1f p999=%.1f loss=%.4f driver=%.2f cores, %.1f%% slots late, latest %.1f ms%s' % (
        n, r, who, j['rtt_p50_us'], j['rtt_p99_us'], j['rtt_p999_us'], j['arrival_rtt_p50_us'],
        j['arrival_rtt_p99_us'], j['arrival_rtt_p999_us'], j['loss'], j['driver_busy_cores'],
        100 * j['driver_late_slots'], j['driver_max_late_us'] / 1e3, bound))
f, s = runs['floor'], runs['server']
print('n=%s round=%s p99 ratio %.2f, at arrival %.2f' % (
    n, r, s['rtt_p99_us'] / f['rtt_p99_us'], s['arrival_rtt_p99_us'] / f['arrival_rtt_p99_us']))
PY
done; done
