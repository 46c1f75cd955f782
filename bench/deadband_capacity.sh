#!/bin/bash
# How many stations a node holds when each sends through the perceptual deadband (PERIOD_MS, 13 by
# default: the wan grid's 72-86 datagrams/s in contact since the 15-ms contact heartbeat; it was
# 20, 47-55/s, before it) against the UDP floor at the same rate, side by side within each round,
# and 64 full-rate stations as the reference
# (BENCHMARKS.md, "Stations per node behind the deadband"). Normal priority, vsurg-server's
# defaults (one I/O thread, a deformation thread per session, visual frames at 60 Hz).
# Run from the repository root after a build. ROUNDS (3), SECONDS_EACH (5),
# COUNTS ("128 256 512 1024"), PERIOD_MS (13).
cd "$(dirname "$0")/../build" || exit 1
show() {
  python3 -c "
import json, sys
j = json.load(sys.stdin)
print('$1', {k: round(v, 1) for k, v in j.items() if k in ['rtt_p50_us', 'rtt_p99_us', 'rtt_p999_us']},
      'loss %.5f' % j['loss'], 'cpu/station %.5f' % j.get('server_cpu_per_station', 0))"
}
s=${SECONDS_EACH:-5}
p=${PERIOD_MS:-13}
for r in $(seq "${ROUNDS:-3}"); do
  bin/vsurg-bench udp-floor --stations 64 --seconds "$s" --json | show "r$r 64 full-rate floor"
  bin/vsurg-bench haptic-rtt --stations 64 --seconds "$s" --json | show "r$r 64 full-rate vsurg"
  for n in ${COUNTS:-128 256 512 1024}; do
    bin/vsurg-bench udp-floor --stations "$n" --seconds "$s" --period-ms "$p" --json |
      show "r$r $n deadband floor"
    bin/vsurg-bench haptic-rtt --stations "$n" --seconds "$s" --period-ms "$p" --json |
      show "r$r $n deadband vsurg"
  done
done
