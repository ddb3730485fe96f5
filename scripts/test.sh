#!/usr/bin/env bash
# Builds and runs every test: the Release build through ctest, then the same suite built with
# AddressSanitizer and UndefinedBehaviorSanitizer (Debug).
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
softgi_install_deps
softgi_build build Release -DSOFTGI_WERROR=ON
echo "== ctest (Release) =="
ctest --test-dir "$SOFTGI_ROOT/build" --output-on-failure -j "$JOBS"
softgi_build build-asan Debug -DSOFTGI_SANITIZE=ON -DSOFTGI_BUILD_BENCH=OFF -DSOFTGI_WERROR=ON
echo "== ctest (Debug, ASan + UBSan) =="
ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
  ctest --test-dir "$SOFTGI_ROOT/build-asan" --output-on-failure -j "$JOBS"
