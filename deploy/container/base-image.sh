#!/usr/bin/env bash
# A Debian 12 base image from Debian's own archive, for a machine where no image registry answers
# (ours: only Debian's archive and npm are reachable). debootstrap a minimal system into a folder,
# import it into podman as localhost/debian:12, then build the image on it:
#
#   deploy/container/base-image.sh            (needs root, debootstrap and podman)
#   podman build --build-arg BASE=localhost/debian:12 -f deploy/container/Dockerfile \
#     -t localhost/vsurg-server .
set -euo pipefail
mirror="${VSURG_DEBIAN_MIRROR:-http://deb.debian.org/debian}"
root="$(mktemp -d)"
trap 'rm -rf "$root"' EXIT
debootstrap --variant=minbase bookworm "$root" "$mirror"
# apt inside the image speaks to the same mirror; no docs, no caches.
echo "deb $mirror bookworm main" > "$root/etc/apt/sources.list"
rm -rf "$root/var/cache/apt/archives/"*.deb "$root/var/lib/apt/lists/"*
tar -C "$root" -c . | podman import --change 'CMD ["/bin/bash"]' - localhost/debian:12
podman images localhost/debian
