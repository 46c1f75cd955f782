#!/bin/bash
# The endpoint with one I/O thread against two (SO_REUSEPORT, sessions steered by id) and the UDP
# floor, side by side, alternating within each round (BENCHMARKS.md, "Two I/O threads on one
# port"). Normal scheduling priority, a deformation thread per session (vsurg-server's defaults).
# Run from the repository root after a build. ROUNDS (3), SECONDS_EACH (5), COUNTS ("64 128"),
# STROKE_MM (0: the stylus rests; else it circles at that radius once a second).
cd "$(dirname "$0")/../build" || exit 1
for n in ${COUNTS:-64 128}; do for r in $(seq "${ROUNDS:-3}"); do
  for cfg in floor 1 2; do
    if [ "$cfg" = floor ]; then
      bin/vsurg-bench udp-floor --stations "$n" --seconds "${SECONDS_EACH:-5}" --json
    else
      bin/vsurg-bench haptic-rtt --stations "$n" --seconds "${SECONDS_EACH:-5}" --json --io-threads "$cfg" \
        --stroke-mm "${STROKE_MM:-0}"
    fi | python3 -c "
import json, sys
j = json.load(sys.stdin)
print('$n r$r io=$cfg', {k: round(v, 1) for k, v in j.items() if k in ['rtt_p50_us', 'rtt_p99_us', 'rtt_p999_us']},
      'loss %.5f' % j['loss'], 'cpu/station %.4f' % j.get('server_cpu_per_station', 0))"
  done
done; done
