# Shared by deploy/demo_flow.sh, deploy/soak.sh and the site's flows (cluster_flow.sh,
# rolling_restart.sh): a temporary folder and the processes started
# in it, cleaned up on exit, and a vsurg-server on a fresh store. Source it.

# Sets $tmp (a new temporary folder) and $pids (processes to stop); both go on exit.
vsurg_temp_and_cleanup() {
  tmp="$(mktemp -d)"
  pids=()
  trap vsurg_cleanup EXIT
}
vsurg_cleanup() {
  local p
  for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
  for p in "${pids[@]}"; do wait "$p" 2>/dev/null || true; done
  rm -rf "$tmp"
}

# vsurg_start_server BIN LOG [vsurg-server options...]: a store in $tmp with its first
# administrator ($admin_token), a vsurg-server on it on free ports ($server_pid, in $pids), and
# once it serves, $server (127.0.0.1:PORT of its gRPC listener). Exits when it does not start.
vsurg_start_server() {
  local bin="$1" log="$2"
  shift 2
  admin_token="$("$bin/vsurg-server" init --db "$tmp/vsurg.db" 2>/dev/null)"
  "$bin/vsurg-server" --db "$tmp/vsurg.db" --listen 127.0.0.1:0 --udp-port 0 \
    --ready-file "$tmp/ready.json" "$@" 2> "$log" &
  server_pid=$!
  pids+=("$server_pid")
  for _ in $(seq 300); do [ -s "$tmp/ready.json" ] && break; sleep 0.1; done
  local port
  port="$(sed -n 's/.*"grpc_port":\([0-9]*\).*/\1/p' "$tmp/ready.json")"
  [ -n "$port" ] || { echo "vsurg-server did not start; see $log" >&2; exit 1; }
  server="127.0.0.1:$port"
}

# vsurg_site_begin TITLE: what a site's flow starts with (deploy/cluster_flow.sh,
# deploy/rolling_restart.sh; $root set): $tmp and $pids as above, a private PostgreSQL in its own
# folder ($pg_dir: the server runs as another user) started on loopback ($uri, psql_q SQL), both
# cleaned up on exit; and the flows' helpers: step TITLE, now_ms, wait_file FILE, port_of FILE KEY.
vsurg_site_begin() {
  vsurg_temp_and_cleanup
  pg_dir="$(mktemp -d -t vsurg-pg.XXXXXX)"
  trap 'vsurg_cleanup_all' EXIT
  step "$1, in $pg_dir"
  uri="$("$root/deploy/postgres.sh" start "$pg_dir" | tail -1)"
}
vsurg_cleanup_all() {
  vsurg_cleanup
  "$root/deploy/postgres.sh" stop "$pg_dir" >/dev/null 2>&1 || true
}
step() { echo; echo "== $* =="; }
now_ms() { date +%s%3N; }
wait_file() { for _ in $(seq 300); do [ -s "$1" ] && return 0; sleep 0.1; done; echo "no $1" >&2; exit 1; }
port_of() { sed -n "s/.*\"$2\":\([0-9]*\).*/\1/p" "$1"; }
psql_q() { psql -qAt "$uri" -c "$1"; }
