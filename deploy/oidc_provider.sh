#!/usr/bin/env bash
# A private OpenID Connect identity provider for tests and demos: Glewlwyd from Debian's
# `glewlwyd` package, in a folder of ours, on 127.0.0.1 only, with its own SQLite database, its
# own RSA signing key and its own copy of the login pages. Nothing of the machine's own Glewlwyd
# is used. It knows one client, `vsurg-dashboard` (public, authorization code with PKCE S256 only,
# the given redirect URI), whose ID tokens carry `preferred_username` and `vsurg_role`, and these
# users (password: NAME-pass-1):
#
#   dr-lee   vsurg_role instructor
#   tia      vsurg_role trainee
#   ada      vsurg_role admin
#   mo       vsurg_role visitor      (no vsurg role)
#   dr-gone  vsurg_role instructor, disabled at the provider
#
#   deploy/oidc_provider.sh start DIR REDIRECT_URI   starts it on a free port; prints its issuer
#                                                    and writes it to DIR/issuer
#   deploy/oidc_provider.sh stop DIR                 stops it and removes DIR
set -euo pipefail

cmd="${1:-}"
dir="${2:-}"
[ -n "$cmd" ] && [ -n "$dir" ] || { echo "usage: $0 start DIR REDIRECT_URI | stop DIR" >&2; exit 2; }

free_port() {
  /usr/bin/python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'
}

schema=/usr/share/dbconfig-common/data/glewlwyd/install/sqlite3
template=/usr/share/glewlwyd/templates/glewlwyd-debian.conf.properties

# The database: Debian's schema, and the user module told to keep the `vsurg_role` property.
make_database() {
  sqlite3 "$dir/glewlwyd.db" < "$schema"
  /usr/bin/python3 - "$dir/glewlwyd.db" <<'EOF'
import json, sqlite3, sys
c = sqlite3.connect(sys.argv[1])
p = json.loads(c.execute("SELECT gumi_parameters FROM g_user_module_instance WHERE gumi_name='database'").fetchone()[0])
p["data-format"]["vsurg_role"] = {"multiple": False, "read": True, "write": True, "profile-read": True, "profile-write": False}
c.execute("UPDATE g_user_module_instance SET gumi_parameters=? WHERE gumi_name='database'", (json.dumps(p),))
c.commit()
EOF
}

# Debian's configuration with our port, database, log and login pages (a copy: Glewlwyd serves
# no symbolic link, and Debian's config.json is one).
make_config() {
  local port="$1"
  cp -rL /usr/share/glewlwyd/webapp "$dir/webapp" 2>/dev/null || true
  rm -rf "$dir/webapp/config.json"
  cp /etc/glewlwyd/config-2.7.json/config.json "$dir/webapp/config.json"
  sed -e "s|^port=.*|port=$port|" \
      -e "s|_G_EXTRNAL_URL_|http://127.0.0.1:$port|" \
      -e 's|^#bind_address=.*|bind_address="127.0.0.1"|' \
      -e 's|^log_mode=.*|log_mode="console"|' \
      -e "s|^# static_files_path=.*|static_files_path=\"$dir/webapp/\"|" \
      -e "s|^@include.*|database = { type = \"sqlite3\" path = \"$dir/glewlwyd.db\" };|" \
      "$template" > "$dir/glewlwyd.conf"
}

# Through the administration API as Debian's first administrator: the OpenID Connect plugin, the
# client and the users.
configure() {
  local base="$1" redirect="$2" jar="$dir/admin.cookies"
  api() { curl -sf -b "$jar" -X "$1" -H 'Content-Type: application/json' -d "$3" "$base/api/$2" >/dev/null; }
  curl -sf -c "$jar" -X POST -H 'Content-Type: application/json' \
    -d '{"username":"admin","password":"password"}' "$base/api/auth/" >/dev/null
  /usr/bin/python3 - "$dir" "$base" > "$dir/plugin.json" <<'EOF'
import json, sys
d, base = sys.argv[1], sys.argv[2]
print(json.dumps({"module": "oidc", "name": "oidc", "display_name": "OpenID Connect", "enabled": True,
  "parameters": {"iss": base + "/api/oidc", "jwt-type": "rsa", "jwt-key-size": "256",
    "key": open(d + "/key.pem").read(), "cert": open(d + "/pub.pem").read(),
    "code-duration": 600, "refresh-token-duration": 3600, "access-token-duration": 3600,
    "auth-type-code-enabled": True, "auth-type-token-enabled": False,
    "auth-type-id-token-enabled": False, "auth-type-none-enabled": False,
    "auth-type-password-enabled": False, "auth-type-client-enabled": False,
    "auth-type-refresh-enabled": False, "allowed-scope": ["openid"],
    "pkce-allowed": True, "pkce-method-plain-allowed": False, "jwks-show": True,
    "claims": [
      {"name": "preferred_username", "user-property": "username", "type": "string", "mandatory": True, "on-demand": False, "scope": []},
      {"name": "vsurg_role", "user-property": "vsurg_role", "type": "string", "mandatory": True, "on-demand": False, "scope": []}]}}))
EOF
  api POST mod/plugin/ "@$dir/plugin.json"
  api POST client/ "{\"client_id\":\"vsurg-dashboard\",\"name\":\"vsurg dashboard\",\"enabled\":true,\"confidential\":false,\"redirect_uri\":[\"$redirect\"],\"authorization_type\":[\"code\"],\"scope\":[\"openid\"]}"
  local user role enabled
  while read -r user role enabled; do
    api POST user/ "{\"username\":\"$user\",\"name\":\"$user\",\"enabled\":$enabled,\"password\":\"$user-pass-1\",\"scope\":[\"openid\"],\"vsurg_role\":\"$role\"}"
  done <<'EOF'
dr-lee instructor true
tia trainee true
ada admin true
mo visitor true
dr-gone instructor false
EOF
}

case "$cmd" in
  start)
    redirect="${3:?REDIRECT_URI}"
    command -v glewlwyd >/dev/null || { echo "oidc_provider.sh: install Debian's glewlwyd package" >&2; exit 1; }
    "$0" stop "$dir"
    mkdir -p "$dir"
    dir="$(cd "$dir" && pwd)"
    openssl genpkey -algorithm RSA -pkeyopt rsa_keygen_bits:2048 -out "$dir/key.pem" 2>/dev/null
    openssl pkey -in "$dir/key.pem" -pubout -out "$dir/pub.pem"
    make_database
    for attempt in 1 2 3 4 5; do
      port="$(free_port)"
      make_config "$port"
      glewlwyd -c "$dir/glewlwyd.conf" > "$dir/glewlwyd.log" 2>&1 &
      echo $! > "$dir/pid"
      for _ in $(seq 1 100); do
        curl -sf -o /dev/null "http://127.0.0.1:$port/config.json" && break
        kill -0 "$(cat "$dir/pid")" 2>/dev/null || break
        sleep 0.1
      done
      curl -sf -o /dev/null "http://127.0.0.1:$port/config.json" && break
      [ "$attempt" = 5 ] && { tail -5 "$dir/glewlwyd.log" >&2; exit 1; }
    done
    configure "http://127.0.0.1:$port" "$redirect"
    issuer="http://127.0.0.1:$port/api/oidc"
    echo "$issuer" > "$dir/issuer"
    echo "$issuer"
    ;;
  stop)
    if [ -f "$dir/pid" ]; then
      kill "$(cat "$dir/pid")" 2>/dev/null || true
      for _ in $(seq 1 50); do kill -0 "$(cat "$dir/pid")" 2>/dev/null || break; sleep 0.1; done
    fi
    rm -rf "$dir"
    ;;
  *)
    echo "usage: $0 start DIR REDIRECT_URI | stop DIR" >&2
    exit 2
    ;;
esac
