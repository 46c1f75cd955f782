#!/usr/bin/env bash
# The bench's own driver, side by side: the bare-UDP floor and the server (pressing stations that
# circle STROKE_MM), each with the driver's stations on a socket each (separate machines' worth
# of system calls) and sharing sockets PER_SOCKET to a batch (vsurg-bench --stations-per-socket),
# alternating in each round. Prints each run's round trip, the node's share of it (residence,
# haptic-rtt only) and how many of the two cores the whole process kept busy (user + system CPU
# over wall time, set-up included).
#   usage: [ROUNDS=3] [SECONDS_EACH=5] [COUNTS="64 128"] [STROKE_MM=3] [PER_SOCKET=8]
#          bench/driver_rtt.sh [BIN_DIR]
set -euo pipefail
BIN=${1:-build/bin}
ROUNDS=${ROUNDS:-3}; SECONDS_EACH=${SECONDS_EACH:-5}; COUNTS=${COUNTS:-"64 128"}
STROKE_MM=${STROKE_MM:-3}; PER_SOCKET=${PER_SOCKET:-8}
times=$(mktemp); trap 'rm -f "$times"' EXIT
for n in $COUNTS; do for r in $(seq "$ROUNDS"); do
  for per in 1 "$PER_SOCKET"; do for who in floor server; do
    case $who in
      floor) out=$(/usr/bin/time -f "%U %S %e" -o "$times" "$BIN/vsurg-bench" udp-floor \
                     --stations "$n" --seconds "$SECONDS_EACH" --stations-per-socket "$per" --json) ;;
      server) out=$(/usr/bin/time -f "%U %S %e" -o "$times" "$BIN/vsurg-bench" haptic-rtt \
                      --stations "$n" --seconds "$SECONDS_EACH" --stroke-mm "$STROKE_MM" \
                      --stations-per-socket "$per" --json) ;;
    esac
    echo "$out" | python3 -c "
import json, sys
j = json.load(sys.stdin)
u, s, e = map(float, open('$times').read().split()[-3:])
res = ' residence mean=%.0f p50<=%.0f p99<=%.0f' % (j['server_residence_mean_us'],
      j['server_residence_p50_le_us'], j['server_residence_p99_le_us']) if 'server_residence_mean_us' in j else ''
print('n=$n round=$r per_socket=$per who=$who p50=%.1f p99=%.1f p999=%.1f loss=%.4f busy_cores=%.2f%s' % (
    j['rtt_p50_us'], j['rtt_p99_us'], j['rtt_p999_us'], j['loss'], (u + s) / e, res))"
  done; done
done; done
