#!/usr/bin/env bash
# Builds and runs every test: the Release build through ctest (and its Vulkan suite once more with
# the device's buffers unmapped, as a discrete GPU's are), then the same suite built with
# AddressSanitizer and UndefinedBehaviorSanitizer (Debug), then each fuzz target (scripts/fuzz.sh)
# for a short time. Fetches the CC0 asset set first so the tests that need it (bunny, HDR maps) run.
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
softgi_install_deps
bash "$SOFTGI_ROOT/scripts/fetch-assets.sh"
softgi_build build Release -DSOFTGI_WERROR=ON
# Fitted proxy sets (the bunny's 32 spheres take ~12 s of CPU, far more under the sanitizers) are
# cached by a hash of the mesh, the fit's parameters and the fitting code's version: one cache for
# both builds, so the sanitizer run reads what the Release run fitted.
export SOFTGI_CACHE_DIR="${SOFTGI_CACHE_DIR:-$SOFTGI_ROOT/build/cache}"
mkdir -p "$SOFTGI_CACHE_DIR"
echo "== ctest (Release) =="
ctest --test-dir "$SOFTGI_ROOT/build" --output-on-failure -j "$JOBS"
# The Vulkan suite again with the device's buffers left unmapped, as a discrete GPU's are: uploads
# and downloads through staging buffers and readbacks through host copies, the paths a CPU device
# (lavapipe) never takes otherwise.
if [ -x "$SOFTGI_ROOT/build/tests/softgi_tests_vulkan" ]; then
  echo "== Vulkan tests, device memory unmapped (Release) =="
  SOFTGI_VULKAN_VALIDATION=1 SOFTGI_VULKAN_UNMAPPED_DEVICE_MEMORY=1 "$SOFTGI_ROOT/build/tests/softgi_tests_vulkan" --gtest_brief=1
fi
softgi_build build-asan Debug -DSOFTGI_SANITIZE=ON -DSOFTGI_BUILD_BENCH=OFF -DSOFTGI_WERROR=ON
echo "== ctest (Debug, ASan + UBSan) =="
ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
  ctest --test-dir "$SOFTGI_ROOT/build-asan" --output-on-failure -j "$JOBS"
# Every fuzz target (scene files, glTF/GLB, environment images) for SOFTGI_FUZZ_SECONDS each
# (default 60) after a clang build of the readers; the corpora in the checkout are left as they are.
echo "== fuzz (${SOFTGI_FUZZ_SECONDS:-60} s per target) =="
SOFTGI_FUZZ_MERGE=0 bash "$SOFTGI_ROOT/scripts/fuzz.sh" "${SOFTGI_FUZZ_SECONDS:-60}"
