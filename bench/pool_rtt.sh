#!/bin/bash
# The deformation pool against a thread per session and the UDP floor, side by side (BENCHMARKS.md,
# "A deformation pool instead of a thread per session"). Run from the repository root after a build.
cd "$(dirname "$0")/../build"
for n in 64 128; do for r in 1 2 3; do
for cfg in "floor x" "own -1" "pool 0" "pool 1"; do set -- $cfg
  if [ $1 = floor ]; then bin/vsurg-bench udp-floor --stations $n --seconds 5 --json; else bin/vsurg-bench haptic-rtt --stations $n --seconds 5 --json --pool-workers $2; fi | python3 -c "import json,sys; j=json.load(sys.stdin); print('$n r$r $1 $2', {k:round(v,1) for k,v in j.items() if k in ['rtt_p50_us','rtt_p99_us','rtt_p999_us']}, 'loss %.5f' % j['loss'], 'cpu/station %.4f' % j.get('server_cpu_per_station',0))"
done; done; done
