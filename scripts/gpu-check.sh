#!/usr/bin/env bash
# The GPU check: the Vulkan parity tests and the frame benchmarks of every technique, on a machine
# with a real GPU that has a driver and nothing else (no packages, no network).
#
#   scripts/gpu-check.sh bundle [FILE]   here, on a machine with the project's dependencies: a build
#                                        without OpenImageIO (build-gpucheck/, SOFTGI_WITH_OIIO=OFF),
#                                        its binaries, every shared library they need beyond glibc,
#                                        the Vulkan validation layer and the models, packed into FILE
#                                        (default build-gpucheck/gpu-check.tar.xz)
#   scripts/gpu-check.sh run FILE OUT    there: unpacks FILE and writes OUT/gpu-check.json (device,
#                                        parity tests, benchmarks at 512x512 and 1024x1024) beside
#                                        the raw outputs and logs; needs only bash, tar and xz
#
# Environment for run: GPU_CHECK_BACKENDS (default vulkan) the benchmarks' backends; GPU_CHECK_SIZES
# (default "512 1024") their frame sides; GPU_CHECK_TIMEOUT (default 300) seconds per step.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BINARIES=(softgi_tests_vulkan bench_techniques)

usage() {
  sed -n '2,17p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//' >&2
  exit 2
}

# Shared libraries a binary loads, except glibc's own (they must match the target's loader).
libs_of() {
  ldd "$1" | awk '/=> \// {print $3}' | grep -Ev '/(ld-linux[^/]*|libc|libm|libpthread|libdl|librt|libresolv)\.so' || true
}

bundle() {
  local file="${1:-$ROOT/build-gpucheck/gpu-check.tar.xz}"
  local build="$ROOT/build-gpucheck" stage
  echo "gpu-check: configuring $build (no OpenImageIO, no app, no viewer)"
  cmake -S "$ROOT" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DSOFTGI_WITH_OIIO=OFF -DSOFTGI_BUILD_APP=OFF \
    -DSOFTGI_BUILD_VIEWER=OFF -DSOFTGI_BUILD_TESTS=ON -DSOFTGI_BUILD_BENCH=ON >/dev/null
  echo "gpu-check: building ${BINARIES[*]}"
  cmake --build "$build" -j "${SOFTGI_JOBS:-$(nproc)}" --target "${BINARIES[@]}"
  stage="$(mktemp -d)"
  trap 'rm -rf "$stage"' RETURN
  mkdir -p "$stage/gpu-check/bin" "$stage/gpu-check/lib" "$stage/gpu-check/layers" "$stage/gpu-check/assets"
  local b lib
  for b in "${BINARIES[@]}"; do
    local path
    path="$(find "$build" -type f -name "$b" -perm -u+x | head -n 1)"
    [ -n "$path" ] || { echo "gpu-check: $b was not built" >&2; exit 1; }
    cp "$path" "$stage/gpu-check/bin/"
    strip --strip-unneeded "$stage/gpu-check/bin/$b"
    for lib in $(libs_of "$path"); do cp -L -n "$lib" "$stage/gpu-check/lib/"; done
  done
  if ls "$stage/gpu-check/lib" | grep -qi openimageio; then
    echo "gpu-check: the bundle would carry OpenImageIO; the build did not switch it off" >&2
    exit 1
  fi
  # The validation layer, so that the parity tests run with it as they do here; its manifest points
  # next to itself.
  local layer=/usr/lib/x86_64-linux-gnu/libVkLayer_khronos_validation.so
  local manifest=/usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json
  if [ -f "$layer" ] && [ -f "$manifest" ]; then
    cp "$layer" "$stage/gpu-check/layers/"
    sed 's#"library_path": *"[^"]*"#"library_path": "./libVkLayer_khronos_validation.so"#' "$manifest" \
      >"$stage/gpu-check/layers/VkLayer_khronos_validation.json"
    for lib in $(libs_of "$layer"); do cp -L -n "$lib" "$stage/gpu-check/lib/"; done
  else
    echo "gpu-check: no Vulkan validation layer here: the parity tests will run without it" >&2
  fi
  if [ -d "$ROOT/assets/models" ]; then cp -r "$ROOT/assets/models" "$stage/gpu-check/assets/"; fi
  cp "${BASH_SOURCE[0]}" "$stage/gpu-check/gpu-check.sh"
  git -C "$ROOT" rev-parse HEAD >"$stage/gpu-check/commit" 2>/dev/null || echo unknown >"$stage/gpu-check/commit"
  mkdir -p "$(dirname "$file")"
  tar -C "$stage" -cJf "$file.tmp" gpu-check
  mv "$file.tmp" "$file"
  echo "gpu-check: wrote $file ($(du -h "$file" | cut -f1); unpacked $(du -sh "$stage/gpu-check" | cut -f1))"
}

# JSON string of a file's text (or of a message when it is missing), for the results file.
json_string() {
  local s
  s="$(cat "$1" 2>/dev/null || echo "(missing: $1)")"
  s="${s//\\/\\\\}"
  s="${s//\"/\\\"}"
  s="${s//$'\t'/\\t}"
  s="${s//$'\r'/}"
  s="${s//$'\n'/\\n}"
  printf '"%s"' "$s"
}

# The file's JSON object if it holds a whole one (a benchmark or gtest report), else null: a step
# killed by its timeout leaves a report cut short (both reports end with their top-level array, "]}"),
# which would make the results file unreadable.
json_or_null() {
  if [ -s "$1" ] && head -c 1 "$1" | grep -q '{' && tr -d ' \t\r\n' <"$1" | tail -c 2 | grep -q '\]}'; then
    cat "$1"
  else
    printf 'null'
  fi
}

run() {
  local file="$1" out="$2"
  [ -f "$file" ] || { echo "gpu-check: no bundle at $file" >&2; exit 2; }
  mkdir -p "$out"
  out="$(cd "$out" && pwd)"
  local work
  work="$(mktemp -d)"
  tar -C "$work" -xJf "$file"
  local g="$work/gpu-check" t="${GPU_CHECK_TIMEOUT:-300}"
  export LD_LIBRARY_PATH="$g/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
  export VK_LAYER_PATH="$g/layers"
  export SOFTGI_ASSETS="$g/assets"
  export SOFTGI_CACHE_DIR=off
  if [ -z "${XDG_RUNTIME_DIR:-}" ] || [ ! -d "${XDG_RUNTIME_DIR:-}" ]; then
    export XDG_RUNTIME_DIR="$work/runtime"
    mkdir -p "$XDG_RUNTIME_DIR" && chmod 0700 "$XDG_RUNTIME_DIR"
  fi
  local start
  start="$(date -u +%Y-%m-%dT%H:%M:%SZ)"
  { uname -a; nproc; (nvidia-smi -L 2>&1 || true); } >"$out/machine.txt" 2>&1
  echo "gpu-check: [1/3] Vulkan parity tests (validation on), log in $out/parity.log"
  local parity_rc=0
  SOFTGI_VULKAN_VALIDATION=1 timeout "$t" "$g/bin/softgi_tests_vulkan" --gtest_output="json:$out/parity.json" \
    >"$out/parity.log" 2>&1 || parity_rc=$?
  tail -n 3 "$out/parity.log"
  local sizes=(${GPU_CHECK_SIZES:-512 1024}) backends="${GPU_CHECK_BACKENDS:-vulkan}" bench_entries="" i=2 s
  for s in "${sizes[@]}"; do
    echo "gpu-check: [$i/3] frame benchmarks, every technique and scene, ${s}x${s}, backends $backends"
    local rc=0
    # image_splat's device binning and rasterised splats beside the defaults: the forms a GPU's
    # compute units, rasteriser and blenders run, which lavapipe cannot show.
    timeout "$t" "$g/bin/bench_techniques" --backend="$backends" --size="$s" \
      --variants=image_splat:binning=device,image_splat:splatting=raster \
      --benchmark_out="$out/bench_$s.json" --benchmark_out_format=json >"$out/bench_$s.log" 2>&1 || rc=$?
    grep -E '^\| |device' "$out/bench_$s.log" | head -n 60 || true
    bench_entries+="$(printf ', "bench_%s": {"exit": %d, "results": %s, "log": %s}' "$s" "$rc" \
      "$(json_or_null "$out/bench_$s.json")" "$(json_string "$out/bench_$s.log")")"
    i=3
  done
  {
    printf '{"kind": "softgi gpu-check", "commit": %s, "started": "%s", "finished": "%s", "machine": %s,\n' \
      "$(json_string "$g/commit")" "$start" "$(date -u +%Y-%m-%dT%H:%M:%SZ)" "$(json_string "$out/machine.txt")"
    printf ' "papers": {"004 Figure 9": "82.6 Hz", "000": "84 fps bilateral from 256x256 receivers", "001 (shadows and indirect, per-sphere blocking, pixel shader)": "8-30 fps (Squirrel 26, Robot 12, Packages 30, Assembly 8)", "002": "1.3-2.3 fps"},\n'
    printf ' "parity": {"exit": %d, "results": %s, "log_tail": %s}' "$parity_rc" "$(json_or_null "$out/parity.json")" \
      "$(tail -n 40 "$out/parity.log" >"$out/parity.tail" && json_string "$out/parity.tail")"
    printf '%s}\n' "$bench_entries"
  } >"$out/gpu-check.json.tmp"
  mv "$out/gpu-check.json.tmp" "$out/gpu-check.json"
  rm -rf "$work"
  echo "gpu-check: wrote $out/gpu-check.json (parity exit $parity_rc)"
  [ "$parity_rc" -eq 0 ]
}

case "${1:-}" in
  bundle) shift; bundle "$@" ;;
  run) [ $# -eq 3 ] || usage; run "$2" "$3" ;;
  *) usage ;;
esac
