#!/usr/bin/env bash
# A private PostgreSQL from Debian's `postgresql` package, for tests, demos and benchmarks: a new
# cluster in a folder of ours, listening on 127.0.0.1 only (and a socket in the same folder), its
# one role `vsurg` trusted, one database `vsurg`. Nothing of the machine's own PostgreSQL is used.
#
#   deploy/postgres.sh start DIR [PORT]   creates DIR, starts the server (PORT 0 or none: a free
#                                         one); prints its URI and writes it to DIR/uri
#   deploy/postgres.sh stop DIR           stops it and removes DIR
#
# VSURG_PG_SETTINGS adds server settings to the start (e.g. "-c fsync=off", for the test that
# the store refuses a server that would lose acknowledged writes).
#
# initdb refuses to run as root: as root, the cluster belongs to the package's `postgres` user
# (runuser); otherwise to the caller.
set -euo pipefail

pg_bin() {
  local d
  d="$(ls -d /usr/lib/postgresql/*/bin 2>/dev/null | sort -V | tail -1)"
  [ -x "$d/initdb" ] || { echo "postgres.sh: no PostgreSQL server; install the postgresql package" >&2; exit 1; }
  echo "$d"
}

as_owner() {
  if [ "$(id -u)" -eq 0 ]; then runuser -u postgres -- "$@"; else "$@"; fi
}

free_port() {
  # An unbound loopback port: bind to port 0 and read what the kernel chose.
  /usr/bin/python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'
}

cmd="${1:-}"
dir="${2:-}"
[ -n "$cmd" ] && [ -n "$dir" ] || { echo "usage: $0 start DIR [PORT] | stop DIR" >&2; exit 2; }

case "$cmd" in
  start)
    bin="$(pg_bin)"
    port="${3:-0}"
    "$0" stop "$dir"  # what an interrupted run left there
    mkdir -p "$dir"
    dir="$(cd "$dir" && pwd)"
    if [ "$(id -u)" -eq 0 ]; then
      chown postgres: "$dir"
      runuser -u postgres -- test -x "$dir" || {
        echo "postgres.sh: the postgres user cannot reach $dir (a parent folder is private); use a folder under /tmp" >&2
        exit 1
      }
    fi
    chmod 700 "$dir"
    as_owner "$bin/initdb" -D "$dir/data" -A trust -U vsurg -E UTF8 --locale=C.UTF-8 >"$dir/initdb.log" 2>&1 \
      || { cat "$dir/initdb.log" >&2; exit 1; }
    for attempt in 1 2 3 4 5; do
      [ "$port" = 0 ] && p="$(free_port)" || p="$port"
      if as_owner "$bin/pg_ctl" -D "$dir/data" -l "$dir/server.log" -w -t 30 \
          -o "-k $dir -p $p -c listen_addresses=127.0.0.1 -c max_connections=200 ${VSURG_PG_SETTINGS:-}" start >/dev/null; then
        port="$p"
        break
      fi
      [ "$attempt" = 5 ] || [ "${3:-0}" != 0 ] && { tail -5 "$dir/server.log" >&2; exit 1; }
    done
    "$bin/createdb" -h 127.0.0.1 -p "$port" -U vsurg vsurg
    uri="postgresql://vsurg@127.0.0.1:$port/vsurg"
    echo "$uri" > "$dir/uri"
    echo "$uri"
    ;;
  stop)
    bin="$(pg_bin)"
    if [ -d "$dir/data" ]; then
      as_owner "$bin/pg_ctl" -D "$dir/data" -m fast -w stop >/dev/null 2>&1 || true
    fi
    rm -rf "$dir"
    ;;
  *)
    echo "usage: $0 start DIR [PORT] | stop DIR" >&2
    exit 2
    ;;
esac
