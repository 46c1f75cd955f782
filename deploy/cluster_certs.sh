#!/usr/bin/env bash
# Certificates for the internal API's mutual TLS (docs/SCALING.md, "Mutual TLS"): a site CA and
# one certificate per process name, each naming that name (common name and DNS subject
# alternative name) and good for both ends of a connection. A node's certificate must name its
# --node-name; the control replicas share one naming --cluster-control-name (vsurg-control).
#
#   deploy/cluster_certs.sh DIR NAME...    e.g. deploy/cluster_certs.sh /etc/vsurg/pki vsurg-control sim-0 sim-1
#
# Writes DIR/ca.pem and DIR/ca.key (once: an existing CA is reused, so certificates can be added
# or renewed later) and DIR/NAME.pem, DIR/NAME.key for each NAME (replaced through a rename, so a
# running process that re-reads them never sees half a file). DAYS (default 365) sets the
# validity. ECDSA P-256 throughout. A site with its own PKI (cert-manager, Vault) issues the same
# shape of certificate instead; deploy/k8s/cluster-tls.yaml does it with cert-manager.
set -euo pipefail
if [ $# -lt 2 ]; then
  echo "usage: $0 DIR NAME..." >&2
  exit 2
fi
dir="$1"
shift
days="${DAYS:-365}"
mkdir -p "$dir"
umask 077
if [ ! -s "$dir/ca.pem" ] || [ ! -s "$dir/ca.key" ]; then
  openssl req -x509 -new -nodes -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 \
    -keyout "$dir/ca.key" -out "$dir/ca.pem" -days "$days" -subj "/CN=vsurg site CA" \
    -addext "basicConstraints=critical,CA:TRUE" -addext "keyUsage=critical,keyCertSign,cRLSign" \
    2>/dev/null
fi
for name in "$@"; do
  case "$name" in
    *[!A-Za-z0-9._-]* | "") echo "$0: '$name': a name of letters, digits, '.', '_' and '-'" >&2; exit 2 ;;
  esac
  work="$(mktemp -d "$dir/.new.XXXXXX")"
  openssl req -new -nodes -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 \
    -keyout "$work/key.pem" -out "$work/req.csr" -subj "/CN=$name" 2>/dev/null
  printf '%s\n' "subjectAltName=DNS:$name" "basicConstraints=critical,CA:FALSE" \
    "keyUsage=critical,digitalSignature" "extendedKeyUsage=serverAuth,clientAuth" > "$work/ext"
  openssl x509 -req -in "$work/req.csr" -CA "$dir/ca.pem" -CAkey "$dir/ca.key" \
    -set_serial "0x$(openssl rand -hex 16)" -days "$days" -extfile "$work/ext" \
    -out "$work/cert.pem" 2>/dev/null
  mv -f "$work/key.pem" "$dir/$name.key"
  mv -f "$work/cert.pem" "$dir/$name.pem"
  rm -rf "$work"
done
