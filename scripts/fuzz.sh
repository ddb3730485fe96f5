#!/usr/bin/env bash
# Fuzzes the JSON scene-file parser (io::parse_scene_json) with libFuzzer + ASan + UBSan.
#
#   bash scripts/fuzz.sh [SECONDS]      default 600
#
# Builds build-fuzz/fuzz_scene_file with clang++ -fsanitize=fuzzer,address,undefined from the
# sources the parser needs (core/src/{sh,scene,proxies,io}), runs it for SECONDS on the seed corpus
# tests/fuzz/corpus (relative paths in inputs resolve against tests/fuzz/data), then merges the
# inputs that add coverage back into tests/fuzz/corpus (-merge=1). Crashes are written to
# build-fuzz/crashes/ and make the script exit non-zero. The regression test
# io_fuzz_corpus.EveryCorpusFileParsesOrThrows replays the corpus in every test build.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
RUN_SECONDS="${1:-600}"
[[ "$RUN_SECONDS" =~ ^[0-9]+$ ]] || { echo "fuzz.sh: SECONDS must be a whole number, got '$RUN_SECONDS'" >&2; exit 2; }
BUILD="$ROOT/build-fuzz"
JOBS="${SOFTGI_JOBS:-2}"

bash "$ROOT/scripts/install-deps.sh"
command -v clang++ >/dev/null || { echo "fuzz.sh: clang++ not found (Debian package clang)" >&2; exit 1; }

mkdir -p "$BUILD/obj" "$BUILD/work" "$BUILD/crashes"
# A generated Ninja file gives incremental, header-tracked rebuilds without touching the CMake build.
CXXFLAGS="-std=c++20 -g -O1 -fno-omit-frame-pointer -fsanitize=address,undefined -fno-sanitize-recover=undefined"
DEFS="-DSOFTGI_SOURCE_DIR=\\\"$ROOT\\\" -DSOFTGI_FUZZ_DATA_DIR=\\\"$ROOT/tests/fuzz/data\\\""
INCS="-I$ROOT/core/include -isystem /usr/include/eigen3 -isystem /usr/include/Imath"
LIBS="-lOpenImageIO -lOpenImageIO_Util -ltinygltf -ldraco -ltbb -lpthread"
{
  echo "rule cxx"
  echo "  command = clang++ $CXXFLAGS -fsanitize=fuzzer-no-link $DEFS $INCS -MMD -MF \$out.d -c \$in -o \$out"
  echo "  depfile = \$out.d"
  echo "  deps = gcc"
  echo "  description = CXX \$in"
  echo "rule link"
  echo "  command = clang++ $CXXFLAGS -fsanitize=fuzzer \$in -o \$out $LIBS"
  echo "  description = LINK \$out"
  objs=()
  for src in "$ROOT"/core/src/{sh,scene,proxies,io}/*.cpp "$ROOT/tests/fuzz/fuzz_scene_file.cpp"; do
    [ -f "$src" ] || continue
    rel="${src#"$ROOT"/}"
    obj="obj/${rel//\//_}.o"
    echo "build $obj: cxx $src"
    objs+=("$obj")
  done
  echo "build fuzz_scene_file: link ${objs[*]}"
} > "$BUILD/build.ninja"
echo "== build (clang, fuzzer + ASan + UBSan) =="
ninja -C "$BUILD" -j "$JOBS" fuzz_scene_file

echo "== fuzz for ${RUN_SECONDS} s (corpus: tests/fuzz/corpus, $(ls "$ROOT/tests/fuzz/corpus" | wc -l) files) =="
status=0
ASAN_OPTIONS="detect_leaks=1:abort_on_error=0" UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1" \
  "$BUILD/fuzz_scene_file" "$BUILD/work" "$ROOT/tests/fuzz/corpus" \
  -dict="$ROOT/tests/fuzz/scene.dict" -max_total_time="$RUN_SECONDS" -max_len=4096 -timeout=20 \
  -rss_limit_mb=4096 -print_final_stats=1 -artifact_prefix="$BUILD/crashes/" || status=$?

echo "== merge new coverage into tests/fuzz/corpus =="
before=$(ls "$ROOT/tests/fuzz/corpus" | wc -l)
"$BUILD/fuzz_scene_file" -merge=1 -max_len=4096 -timeout=20 "$ROOT/tests/fuzz/corpus" "$BUILD/work" 2>&1 | tail -n 3
after=$(ls "$ROOT/tests/fuzz/corpus" | wc -l)
echo "fuzz.sh: corpus $before -> $after files"
if [ "$status" -ne 0 ]; then
  echo "fuzz.sh: the fuzzer stopped with status $status; reproducers in $BUILD/crashes/:" >&2
  ls -la "$BUILD/crashes" >&2
  exit "$status"
fi
echo "fuzz.sh: no crash in ${RUN_SECONDS} s"
