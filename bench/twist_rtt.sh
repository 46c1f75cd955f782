#!/usr/bin/env bash
# Stations that twist, side by side: the bare-UDP floor, the server updating a quasi-static model
# at every request (--quasi-static-interval-ms 0, as before) and at most once per INTERVAL_MS
# (the default 8), alternating in each round. Each station grasps the arm in the warm-up and
# turns it by up to TWIST_DEG there and back every 2 s (vsurg-bench haptic-rtt --twist-deg).
#   usage: [ROUNDS=3] [SECONDS_EACH=5] [COUNTS="4 8 16"] [TWIST_DEG=20] [INTERVAL_MS=8]
#          bench/twist_rtt.sh [BIN_DIR]
set -euo pipefail
BIN=${1:-build/bin}
ROUNDS=${ROUNDS:-3}; SECONDS_EACH=${SECONDS_EACH:-5}; COUNTS=${COUNTS:-"4 8 16"}
TWIST_DEG=${TWIST_DEG:-20}; INTERVAL_MS=${INTERVAL_MS:-8}
for n in $COUNTS; do for r in $(seq "$ROUNDS"); do
  for who in floor every coalesced; do
    case $who in
      floor) out=$("$BIN/vsurg-bench" udp-floor --stations "$n" --seconds "$SECONDS_EACH" --json) ;;
      every) out=$("$BIN/vsurg-bench" haptic-rtt --stations "$n" --seconds "$SECONDS_EACH" \
                     --twist-deg "$TWIST_DEG" --quasi-static-interval-ms 0 --json) ;;
      coalesced) out=$("$BIN/vsurg-bench" haptic-rtt --stations "$n" --seconds "$SECONDS_EACH" \
                         --twist-deg "$TWIST_DEG" --quasi-static-interval-ms "$INTERVAL_MS" --json) ;;
    esac
    echo "$out" | python3 -c "
import json, sys
j = json.load(sys.stdin)
print('n=$n round=$r who=$who p50=%.1f p99=%.1f loss=%.4f io_cpu_per_station=%.4f server_cpu_per_station=%s deformations_per_station_s=%s' % (
    j['rtt_p50_us'], j['rtt_p99_us'], j['loss'], j['server_cpu_per_station'],
    '%.4f' % j['server_process_cpu_per_station'] if 'server_process_cpu_per_station' in j else '-',
    '%.0f' % j['deformations_per_station_s'] if 'deformations_per_station_s' in j else '-'))"
  done
done; done
