#!/bin/bash
# Busy polling against sleeping, side by side, alternating within each round (BENCHMARKS.md,
# "Busy polling while the datagrams come fast"): the floor (a plain blocking echo), the floor
# polling by the endpoint's rule, the endpoint never polling (--busy-poll-us 0) and polling
# (POLL_US, 100 µs; vsurg-server's default is 0, never). One I/O thread, normal priority, a deformation thread
# per session (vsurg-server's defaults). Run from the repository root after a build.
# ROUNDS (3), SECONDS_EACH (5), COUNTS ("64 128"), STROKE_MM (3: each stylus circles at that
# radius once a second), POLL_US (100).
cd "$(dirname "$0")/../build" || exit 1
poll=${POLL_US:-100}
for n in ${COUNTS:-64 128}; do for r in $(seq "${ROUNDS:-3}"); do
  for cfg in floor floor-poll sleep poll; do
    case $cfg in
      floor) bin/vsurg-bench udp-floor --stations "$n" --seconds "${SECONDS_EACH:-5}" --json ;;
      floor-poll) bin/vsurg-bench udp-floor --stations "$n" --seconds "${SECONDS_EACH:-5}" --json \
                    --busy-poll-us "$poll" ;;
      sleep|poll) bin/vsurg-bench haptic-rtt --stations "$n" --seconds "${SECONDS_EACH:-5}" --json \
                    --stroke-mm "${STROKE_MM:-3}" --busy-poll-us "$([ $cfg = poll ] && echo "$poll" || echo 0)" ;;
    esac | python3 -c "
import json, sys
j = json.load(sys.stdin)
print('$n r$r $cfg', {k: round(v, 1) for k, v in j.items() if k in ['rtt_p50_us', 'rtt_p99_us', 'rtt_p999_us']},
      'loss %.5f' % j['loss'], 'cpu/station %.4f' % j.get('server_cpu_per_station', 0),
      'polled %d' % j.get('busy_polled_receives', 0))"
  done
done; done
