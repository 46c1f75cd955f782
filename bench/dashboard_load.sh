#!/usr/bin/env bash
# What the web dashboard costs the haptic path, side by side in one run: 8 stations' round trip
# at 1 kHz through the server's own stack (store, session manager, dashboard listening) with no
# dashboard client and with 20 clients each following the live page (every session, 4 Hz) and
# one session's page (10 Hz, with the deformed surface), alternating, 3 runs each (REPS=N for more)
# (vsurg-bench haptic-rtt --dashboard-clients). Then the live page's first paint and first data
# in headless Chromium on loopback (bench/dashboard_paint.py), 5 loads.
# usage: bench/dashboard_load.sh [BIN_DIR] [STATIONS=8] [CLIENTS=20] [SECONDS=10]
set -euo pipefail
B="$(cd "${1:-build/bin}" && pwd)"
stations="${2:-8}"
clients="${3:-20}"
seconds="${4:-10}"
root="$(cd "$(dirname "$0")/.." && pwd)"
export VSURG_SCENES="$root/scenes"
printf '%-22s %4s %10s %10s %11s %8s %12s\n' setting run p50_us p99_us p99.9_us loss events_MB
for rep in $(seq "${REPS:-3}"); do
  for c in 0 "$clients"; do
    "$B/vsurg-bench" haptic-rtt --stations "$stations" --seconds "$seconds" --scene arm-torsion \
      --realtime-priority "${PRIORITY:-20}" \
      --dashboard-clients "$c" --json |
      /usr/bin/python3 -c "
import json, sys
j = json.load(sys.stdin)
print('%-22s %4d %10.0f %10.0f %11.0f %8.4f %12.1f' % ('%d dashboard clients' % j['dashboard_clients'],
      $rep, j['rtt_p50_us'], j['rtt_p99_us'], j['rtt_p999_us'], j['loss'], j['dashboard_bytes'] / 1e6))"
  done
done
echo
/usr/bin/python3 "$root/bench/dashboard_paint.py" "$B" "$root/scenes" 5
