#!/usr/bin/env bash
# Installs the project's Debian packages (only the missing ones), builds with -j2 and runs every
# test through ctest. Exits non-zero on any failure. Usage: deploy/test.sh [extra cmake -D options]
set -euo pipefail
source "$(dirname "$0")/lib.sh"
root="$(vsurg_root)"
vsurg_install_packages
vsurg_build "$@"
ctest --test-dir "$root/build" --output-on-failure -j2 --timeout 300
