#!/usr/bin/env bash
# A change to the haptic path measured side by side: the bare-UDP floor, vsurg-bench haptic-rtt
# built before the change (A) and after it (B), alternating, REPS rounds of SECONDS_EACH s per
# station count. Build A from a worktree of the old commit (or copy its binary before rebuilding).
#   usage: REPS=3 SECONDS_EACH=10 [RT=20] [STROKE_MM=3] bench/ab_rtt.sh A_BENCH B_BENCH STATIONS...
#   e.g.   bench/ab_rtt.sh /tmp/old/vsurg-bench build/bin/vsurg-bench 1 8 64
# RT: every run's --realtime-priority (the endpoint's and the stations' threads SCHED_FIFO at RT
# where permitted, as vsurg-server and vsurg-station run by default; the floor's echo likewise).
# Default 0: normal policy, as OpenIGTLink's comparison runs. STROKE_MM: haptic-rtt's --stroke-mm
# (each stylus circles at this radius once a second; default 0, it rests). TWIST_DEG: haptic-rtt's
# --twist-deg (each station grasps the arm and turns it; default 0, no grasp).
set -euo pipefail
[ $# -ge 3 ] || { sed -n 2,9p "$0"; exit 2; }
A=$1; B=$2; shift 2
REPS=${REPS:-3}; SECONDS_EACH=${SECONDS_EACH:-10}; RT=${RT:-0}; STROKE_MM=${STROKE_MM:-0}
TWIST_DEG=${TWIST_DEG:-0}
for n in "$@"; do for r in $(seq "$REPS"); do
  for who in floor A B; do
    case $who in
      floor) out=$("$B" udp-floor --stations "$n" --seconds "$SECONDS_EACH" --realtime-priority "$RT" --json) ;;
      A) out=$("$A" haptic-rtt --stations "$n" --seconds "$SECONDS_EACH" --realtime-priority "$RT" --stroke-mm "$STROKE_MM" --twist-deg "$TWIST_DEG" --json) ;;
      B) out=$("$B" haptic-rtt --stations "$n" --seconds "$SECONDS_EACH" --realtime-priority "$RT" --stroke-mm "$STROKE_MM" --twist-deg "$TWIST_DEG" --json) ;;
    esac
    echo "$out" | python3 -c "import json,sys; j=json.load(sys.stdin); print('n=$n rep=$r who=$who rt=%d p50=%.1f p99=%.1f p999=%.1f loss=%.4f cpu_per_station=%.4f process_cpu_per_station=%s driver=%s' % (j['realtime_priority'], j['rtt_p50_us'], j['rtt_p99_us'], j['rtt_p999_us'], j['loss'], j['server_cpu_per_station'], '%.4f' % j['server_process_cpu_per_station'] if 'server_process_cpu_per_station' in j else '-', '%.2f cores, %.1f%% slots late, latest %.1f ms' % (j['driver_busy_cores'], 100 * j['driver_late_slots'], j['driver_max_late_us'] / 1e3) if 'driver_busy_cores' in j else '-'))"
  done
done; done
