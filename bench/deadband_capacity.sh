#!/bin/bash
# How many stations a node holds when each sends through the perceptual deadband (about one
# stylus sample in 20: --period-ms 20, the wan grid's 47-55 datagrams/s) against the UDP floor at
# the same rate, side by side within each round, and 64 full-rate stations as the reference
# (BENCHMARKS.md, "Stations per node behind the deadband"). Normal priority, vsurg-server's
# defaults (one I/O thread, a deformation thread per session, visual frames at 60 Hz).
# Run from the repository root after a build. ROUNDS (3), SECONDS_EACH (5),
# COUNTS ("128 256 512 1024").
cd "$(dirname "$0")/../build" || exit 1
show() {
  python3 -c "
import json, sys
j = json.load(sys.stdin)
print('$1', {k: round(v, 1) for k, v in j.items() if k in ['rtt_p50_us', 'rtt_p99_us', 'rtt_p999_us']},
      'loss %.5f' % j['loss'], 'cpu/station %.5f' % j.get('server_cpu_per_station', 0))"
}
s=${SECONDS_EACH:-5}
for r in $(seq "${ROUNDS:-3}"); do
  bin/vsurg-bench udp-floor --stations 64 --seconds "$s" --json | show "r$r 64 full-rate floor"
  bin/vsurg-bench haptic-rtt --stations 64 --seconds "$s" --json | show "r$r 64 full-rate vsurg"
  for n in ${COUNTS:-128 256 512 1024}; do
    bin/vsurg-bench udp-floor --stations "$n" --seconds "$s" --period-ms 20 --json |
      show "r$r $n deadband floor"
    bin/vsurg-bench haptic-rtt --stations "$n" --seconds "$s" --period-ms 20 --json |
      show "r$r $n deadband vsurg"
  done
done
