#!/usr/bin/env bash
# Stations that twist, side by side: the bare-UDP floor, the server sending the twisted limb's
# frames as moved vertices (--vertex-frames: stations that hold no coil limb) and as the twist's
# numbers (stations that hold the scene's limb, as vsurg-station does), alternating in each
# round. Each station grasps the arm in the warm-up and turns it by up to TWIST_DEG there and
# back every 2 s (vsurg-bench haptic-rtt --twist-deg); the model updates at most once per
# INTERVAL_MS while grasped (the default 8). BASE_BIN=DIR adds the vsurg-bench of DIR (a build of
# an earlier commit) as a fourth, "before".
#   usage: [ROUNDS=3] [SECONDS_EACH=5] [COUNTS="4 8 16"] [TWIST_DEG=20] [INTERVAL_MS=8]
#          [BASE_BIN=DIR] bench/twist_rtt.sh [BIN_DIR]
set -euo pipefail
BIN=${1:-build/bin}
ROUNDS=${ROUNDS:-3}; SECONDS_EACH=${SECONDS_EACH:-5}; COUNTS=${COUNTS:-"4 8 16"}
TWIST_DEG=${TWIST_DEG:-20}; INTERVAL_MS=${INTERVAL_MS:-8}
for n in $COUNTS; do for r in $(seq "$ROUNDS"); do
  for who in floor ${BASE_BIN:+before} vertices twist; do
    twist=(--stations "$n" --seconds "$SECONDS_EACH" --twist-deg "$TWIST_DEG"
           --quasi-static-interval-ms "$INTERVAL_MS" --json)
    case $who in
      floor) out=$("$BIN/vsurg-bench" udp-floor --stations "$n" --seconds "$SECONDS_EACH" --json) ;;
      before) out=$("$BASE_BIN/vsurg-bench" haptic-rtt "${twist[@]}") ;;
      vertices) out=$("$BIN/vsurg-bench" haptic-rtt "${twist[@]}" --vertex-frames) ;;
      twist) out=$("$BIN/vsurg-bench" haptic-rtt "${twist[@]}") ;;
    esac
    echo "$out" | python3 -c "
import json, sys
j = json.load(sys.stdin)
opt = lambda k, f: f % j[k] if k in j else '-'
print('n=$n round=$r who=$who p50=%.1f p99=%.1f loss=%.4f io_cpu_per_station=%.4f server_cpu_per_station=%s deformations_per_station_s=%s frame_kB_per_station_s=%s' % (
    j['rtt_p50_us'], j['rtt_p99_us'], j['loss'], j['server_cpu_per_station'],
    opt('server_process_cpu_per_station', '%.4f'), opt('deformations_per_station_s', '%.0f'),
    '%.1f' % (j['frame_bytes_per_station_s'] / 1e3) if 'frame_bytes_per_station_s' in j else '-'))"
  done
done; done
