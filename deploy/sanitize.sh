#!/usr/bin/env bash
# The sanitizer builds of the tests, each in its own build folder (deploy/test.sh runs this after
# the main build; it can also run alone):
#
#   build-asan/  AddressSanitizer + UndefinedBehaviorSanitizer (GCC), every unit and integration
#                test (not the speed-vs-error study, a numerical run the physics tests cover, and
#                not the e2e demo flow, which the main build runs);
#   build-tsan/  ThreadSanitizer (GCC) on the threaded suites: the simulation and its deformation
#                thread, the UDP endpoint, the station channel, the store's writer.
#
# Usage: deploy/sanitize.sh [asan|tsan|all]   (default all). Exits non-zero on any report.
set -euo pipefail
source "$(dirname "$0")/lib.sh"
root="$(vsurg_root)"
which="${1:-all}"
case "$which" in asan|tsan|all) ;; *) echo "usage: deploy/sanitize.sh [asan|tsan|all]" >&2; exit 2 ;; esac
vsurg_install_packages
supp="$root/tests/sanitizers"
# -O1: sanitizer builds are about finding faults; they compile faster and still run briskly.
common=(-G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g"
        -DVSURG_BENCH=OFF)

if [ "$which" = asan ] || [ "$which" = all ]; then
  cmake -S "$root" -B "$root/build-asan" "${common[@]}" -DVSURG_SANITIZE=ON >/dev/null
  cmake --build "$root/build-asan" -j2
  ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:strict_string_checks=1:detect_stack_use_after_return=1" \
  LSAN_OPTIONS="suppressions=$supp/lsan.supp:print_suppressions=0" \
  UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1" \
    ctest --test-dir "$root/build-asan" --output-on-failure -j2 --timeout 600 -L 'unit|integration'
fi

if [ "$which" = tsan ] || [ "$which" = all ]; then
  suites=(simulation_test server_net_test station_channel_test db_test)
  cmake -S "$root" -B "$root/build-tsan" "${common[@]}" -DVSURG_TSAN=ON >/dev/null
  cmake --build "$root/build-tsan" -j2 --target "${suites[@]}"
  # Only those suites were built: run them directly (gtest), not through ctest's whole list.
  for s in "${suites[@]}"; do
    echo "tsan: $s"
    TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1:suppressions=$supp/tsan.supp" \
      "$root/build-tsan/bin/$s" --gtest_brief=1
  done
fi
