#!/usr/bin/env bash
# Soak test (not in CI): STATIONS headless stations for SECONDS against one vsurg-server, with
# instructors' monitors and web dashboards attached and evaluators submitting all along. Records
# every 5 s the server's resident memory, open descriptors and threads, and at the end each
# station's round trip, the monitors' view of it minute by minute, what the dashboards received
# (deploy/soak_dashboard.py: the live page's stream, one session page's stream, page and API
# loads every 5 s), and whether every acknowledged evaluation is in the store. Prints a summary
# and writes OUT_DIR/soak-timeline.csv and OUT_DIR/summary.txt.
#
# usage: [DASHBOARDS=4] deploy/soak.sh BIN_DIR [STATIONS=32] [SECONDS=600] [OUT_DIR=soak-out]
# Pass: memory and descriptors flat (within ±5% of their mean after a 60 s warm-up), no station
# lost its session, every acknowledged evaluation stored, no dashboard stream broke and no page or
# API request failed. Exit 0 on pass, 1 otherwise.
set -euo pipefail
bin="$(cd "${1:?BIN_DIR}" && pwd)"
stations="${2:-32}"
seconds="${3:-600}"
out="${4:-soak-out}"
dashboards="${DASHBOARDS:-4}"
mkdir -p "$out"
out="$(cd "$out" && pwd)"
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
export VSURG_SCENES="$root/scenes"
source "$root/deploy/processes.sh"
vsurg_temp_and_cleanup
station_pids=()
vsurg_start_server "$bin" "$out/server.log" --max-sessions $((stations + 8)) --http 127.0.0.1:0
http_port="$(sed -n 's/.*"http_port":\([0-9]*\).*/\1/p' "$tmp/ready.json")"
adm() { "$bin/vsurg-admin" "$@" --server "$server" --token "$admin_token"; }
token_of() { adm user-add --name "$1" --role "$2" ${3:+--group "$3"} --issue-token | tail -1; }
instructor="$(token_of soak-instructor instructor)"
"$bin/vsurg-sim" trainee --scene arm-torsion --style good --out "$tmp/arm.csv"
"$bin/vsurg-sim" trainee --scene sphere-palpation-256 --style good --out "$tmp/sphere.csv"

echo "soak: $stations stations for ${seconds}s against $server (pid $server_pid)"
for i in $(seq -w 1 "$stations"); do
  token="$(token_of "soak-t$i" trainee group-a)"
  if [ $((10#$i % 2)) -eq 0 ]; then scene=arm-torsion traj=arm.csv; else scene=sphere-palpation-256 traj=sphere.csv; fi
  "$bin/vsurg-station" --server "$server" --token "$token" --scene "$scene" --device replay \
    --trajectory "$tmp/$traj" --headless --width 160 --height 100 --fps 2 --duration "$((seconds + 20))" \
    --realtime-priority 0 --json > "$out/station-$i.json" 2> "$out/station-$i.log" &
  pids+=($!)
  station_pids+=($!)
done
sleep 5
# Instructors follow four sessions live.
for s in $(adm sessions 2>/dev/null | awk -F'\t' '$4=="running"{print $1}' | head -4); do
  "$bin/vsurg-monitor" follow --server "$server" --token "$instructor" --session "$s" --text \
    --print-hz 2 > "$out/monitor-$s.log" 2>&1 &
  pids+=($!)
done
# Instructors' dashboards in browsers' stead, each its own user; like the stations, they outlive
# the sampling window, so their ending is never in the figures.
dashboard_pids=()
for d in $(seq 1 "$dashboards"); do
  python3 "$root/deploy/soak_dashboard.py" "$http_port" "$(token_of "soak-web$d" instructor)" \
    "$((seconds + 10))" "$out/dashboard-$d.json" 2> "$out/dashboard-$d.log" &
  pids+=($!)
  dashboard_pids+=($!)
done

# Evaluators all along; the server's resources every 5 s, for SECONDS (the stations run 20 s
# longer, so their ending is never in the figures).
echo "t_s,rss_kb,fds,threads" > "$out/soak-timeline.csv"
acked=0 failed=0
start=$(date +%s)
batch=0
while :; do
  now=$(( $(date +%s) - start ))
  [ "$now" -ge "$seconds" ] && break
  rss=$(awk '/VmRSS/{print $2}' "/proc/$server_pid/status")
  fds=$(ls "/proc/$server_pid/fd" | wc -l)
  threads=$(ls "/proc/$server_pid/task" | wc -l)
  echo "$now,$rss,$fds,$threads" >> "$out/soak-timeline.csv"
  batch=$((batch + 1))
  printf 'evaluator_id,group,i1,i2,i3,i4,i5,i6,i7,i8,i9,subject\nev-a,intern,7,7,8,8,9,9,7,6,6,soak-%d\nev-b,chief,8,8,8,8,8,8,8,8,8,soak-%d\n' \
    "$batch" "$batch" > "$tmp/ratings.csv"
  if adm import --input "$tmp/ratings.csv" --subject-kind model > "$tmp/import.log" 2>&1 &&
     grep -q "imported 2 evaluations" "$tmp/import.log"; then
    acked=$((acked + 2))
  else
    failed=$((failed + 1))
  fi
  sleep 5
done
for p in "${station_pids[@]}" "${dashboard_pids[@]}"; do wait "$p" || true; done
stored=$(adm export --format csv --out "$tmp/export.csv" >/dev/null 2>&1 && tail -n +2 "$tmp/export.csv" | wc -l)
stored_submissions=$((stored / 9))
# Out here, not in the summary's { … } | tee: that block runs in a subshell, so a variable set
# there is gone when the verdict below reads it (set -u ended the script there before).
lost=$(grep -L '"session"' "$out"/station-*.json | wc -l)

{
  echo "soak: $stations stations, ${seconds}s, server pid $server_pid"
  awk -F, -v warm=60 'NR>1 && $1>=warm { n++; r[n]=$2; f[n]=$3; t[n]=$4; sr+=$2; sf+=$3 }
    END { if (n==0) { print "no samples after warm-up"; exit }
      mr=sr/n; mf=sf/n; minr=r[1]; maxr=r[1]; minf=f[1]; maxf=f[1]
      for (i=1;i<=n;i++) { if(r[i]<minr)minr=r[i]; if(r[i]>maxr)maxr=r[i]; if(f[i]<minf)minf=f[i]; if(f[i]>maxf)maxf=f[i] }
      printf "%d samples after a %d s warm-up\n", n, warm
      printf "server RSS after warm-up: mean %.1f MB, min %.1f, max %.1f (%+.1f%% / %+.1f%%), first %.1f, last %.1f\n", mr/1024, minr/1024, maxr/1024, 100*(minr-mr)/mr, 100*(maxr-mr)/mr, r[1]/1024, r[n]/1024
      printf "server open descriptors: mean %.1f, min %d, max %d (%+.1f%% / %+.1f%%); threads %d..%d\n", mf, minf, maxf, 100*(minf-mf)/mf, 100*(maxf-mf)/mf, t[1], t[n]
      ok = (maxr-mr)/mr <= 0.05 && (mr-minr)/mr <= 0.05 && (maxf-mf)/mf <= 0.05 && (mf-minf)/mf <= 0.05
      print (ok ? "flat: yes" : "flat: NO") }' "$out/soak-timeline.csv"
  echo "station RTT (each station's whole run, µs):"
  key() { sed -n "s/.*\"$1\":\([0-9.e+-]*\).*/\1/p" "$2"; }
  for f in "$out"/station-*.json; do
    [ -s "$f" ] && echo "$(key rtt_p50_us "$f") $(key rtt_p99_us "$f") $(key loss "$f")"
  done | sort -n -k2 | awk '{ n++; p50[n]=$1; p99[n]=$2; loss+=$3 }
    END { if (n==0) { print "  no station summaries"; exit }
      printf "  %d stations: p99 median %.0f, worst %.0f; p50 median %.0f; mean loss %.4f%%\n", n, p99[int((n+1)/2)], p99[n], p50[int((n+1)/2)], 100*loss/n }'
  echo "monitored RTT per minute (instructors' telemetry, p99 of 2 Hz samples, µs):"
  cat "$out"/monitor-*.log 2>/dev/null | sed -n 's/^watch_s=\([0-9.]*\) .* rtt_us=\([0-9]*\).*/\1 \2/p' |
    awk '{ m=int($1/60); v[m]=v[m] " " $2 } END { for (m in v) print m, v[m] }' | sort -n |
    while read -r minute values; do
      printf '  minute %d: p99 %s\n' "$minute" "$(echo $values | tr ' ' '\n' | sort -n | awk '{a[NR]=$1} END{i=int(NR*0.99); if (i<1) i=1; print a[i]}')"
    done
  echo "dashboards (live page + one session page each; frames and KiB per minute, all dashboards):"
  python3 - "$out" "$dashboards" <<'PY'
import json, sys, glob
runs = [json.load(open(f)) for f in sorted(glob.glob(sys.argv[1] + "/dashboard-*.json"))]
if len(runs) != int(sys.argv[2]):
    print(f"  {len(runs)} of {sys.argv[2]} dashboards wrote a summary")
frames = [sum(r["frames_per_minute"][m] for r in runs) for m in range(len(runs[0]["frames_per_minute"]))] if runs else []
kib = [sum(r["kbytes_per_minute"][m] for r in runs) for m in range(len(runs[0]["kbytes_per_minute"]))] if runs else []
print("  frames per minute:", " ".join(map(str, frames)))
print("  KiB per minute:", " ".join(map(str, kib)))
if runs:
    p50 = max(r["request_ms_p50"] or 0 for r in runs)
    p99 = max(r["request_ms_p99"] or 0 for r in runs)
    print(f"  streams: {sum(r['streams'] for r in runs)}, requests: {sum(r['requests'] for r in runs)}, "
          f"latency p50 {p50:.1f} ms, p99 {p99:.1f} ms (the worst dashboard's)")
breaks = [b for r in runs for b in r["stream_breaks"]]
errors = [e for r in runs for e in r["request_errors"]]
print(f"dashboard stream breaks: {len(breaks)}", "; ".join(breaks[:5]))
print(f"dashboard request errors: {len(errors)}", "; ".join(errors[:5]))
print("dashboards complete:", "yes" if len(runs) == int(sys.argv[2]) else "NO")
PY
  echo "evaluations: $acked acknowledged, $failed import rounds failed, $stored_submissions stored"
  echo "stations without a session summary: $lost"
} | tee "$out/summary.txt"
grep -q "flat: yes" "$out/summary.txt" && [ "$acked" -eq "$stored_submissions" ] && [ "$lost" -eq 0 ] &&
  grep -q "^dashboard stream breaks: 0" "$out/summary.txt" &&
  grep -q "^dashboard request errors: 0" "$out/summary.txt" &&
  grep -q "^dashboards complete: yes" "$out/summary.txt"
