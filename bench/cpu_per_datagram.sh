#!/usr/bin/env bash
# What a node pays per answered stylus datagram, against what an echo pays, side by side: the
# plain echo (one recvfrom and one sendto a datagram), the batched echo (one recvmmsg and one
# sendmmsg for what is queued, as the server's I/O thread reads and answers) and vsurg-bench
# haptic-rtt (the server's endpoint, sessions and physics; pressing stations, or twisting ones
# with TWIST_DEG), alternating in each round at each station count. Each figure is CPU time read
# from the thread or process itself (CLOCK_THREAD_CPUTIME_ID, getrusage), divided by the
# datagrams answered; the ratios are each round's own. Beside them, each datagram's residence
# (kernel arrival stamp to its answer's send): the batched echo's p99, exact, and the node's
# (the endpoint's histogram: the p99's bucket bound, "le").
#   usage: [ROUNDS=3] [SECONDS_EACH=5] [TWIST_DEG=0] bench/cpu_per_datagram.sh [BIN_DIR] N...
#   e.g.   bench/cpu_per_datagram.sh build/bin 64 128
set -euo pipefail
BIN=${1:-build/bin}; shift || true
[ $# -ge 1 ] || set -- 64 128
ROUNDS=${ROUNDS:-3}; SECONDS_EACH=${SECONDS_EACH:-5}; TWIST_DEG=${TWIST_DEG:-0}
for n in "$@"; do for r in $(seq "$ROUNDS"); do
  plain=$("$BIN/vsurg-bench" udp-floor --stations "$n" --seconds "$SECONDS_EACH" --json)
  batched=$("$BIN/vsurg-bench" udp-floor --stations "$n" --seconds "$SECONDS_EACH" --batch 64 \
              --json)
  node=$("$BIN/vsurg-bench" haptic-rtt --stations "$n" --seconds "$SECONDS_EACH" \
           --twist-deg "$TWIST_DEG" --json)
  python3 - "$n" "$r" "$plain" "$batched" "$node" <<'PY'
import json, sys
n, r = sys.argv[1], sys.argv[2]
plain, batched, node = (json.loads(a) for a in sys.argv[3:6])
p, b = plain['server_cpu_per_datagram_us'], batched['server_cpu_per_datagram_us']
io, proc = node['server_io_cpu_per_datagram_us'], node['server_process_cpu_per_datagram_us']
floor = min(p, b)
print(f'n={n} round={r} plain={p:.2f}us batched={b:.2f}us ({batched["datagrams_per_receive"]:.2f}/call) '
      f'node_io={io:.2f}us node_process={proc:.2f}us ratio_io={io / floor:.2f} '
      f'ratio_process={proc / floor:.2f} loss plain/batched/node='
      f'{plain["loss"]:.4f}/{batched["loss"]:.4f}/{node["loss"]:.4f} '
      f'residence_p99 echo={batched.get("echo_residence_p99_us", 0):.0f}us '
      f'(le {batched.get("echo_residence_p99_le_us", 0):.0f}) node_le={node["server_residence_p99_le_us"]:.0f}us')
PY
done; done
