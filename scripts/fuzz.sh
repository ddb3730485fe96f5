#!/usr/bin/env bash
# Fuzzes softgi's file readers with libFuzzer + ASan + UBSan, one target after the other:
#
#   scene_file  io::parse_scene_json   tests/fuzz/fuzz_scene_file.cpp  corpus tests/fuzz/corpus
#   gltf        io::load_gltf          tests/fuzz/fuzz_gltf.cpp        corpus tests/fuzz/corpus_gltf
#   env_image   io::read_rgb_float     tests/fuzz/fuzz_env_image.cpp   corpus tests/fuzz/corpus_env_image
#
#   bash scripts/fuzz.sh [SECONDS] [TARGET...]   SECONDS per target (default 600), every target by default
#   SOFTGI_FUZZ_MERGE=0 bash scripts/fuzz.sh 60  the same without merging new inputs into the corpora
#
# Builds build-fuzz/fuzz_TARGET with clang++ -fsanitize=fuzzer,address,undefined from the sources
# the readers need (core/src/{sh,scene,proxies,io}, compiled once for all targets), runs each for
# SECONDS on its seed corpus with its dictionary (tests/fuzz/TARGET.dict), then merges the inputs
# that add coverage back into the corpus (-merge=1). Crashes are written to build-fuzz/crashes/TARGET/
# and make the script exit non-zero after every target has run. The tests io_fuzz_corpus.* replay
# every corpus in every test build.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
RUN_SECONDS="${1:-600}"
[[ "$RUN_SECONDS" =~ ^[0-9]+$ ]] || { echo "fuzz.sh: SECONDS must be a whole number, got '$RUN_SECONDS'" >&2; exit 2; }
shift $(( $# > 0 ? 1 : 0 ))
ALL_TARGETS=(scene_file gltf env_image)
TARGETS=("$@")
[ ${#TARGETS[@]} -gt 0 ] || TARGETS=("${ALL_TARGETS[@]}")
for t in "${TARGETS[@]}"; do
  [[ " ${ALL_TARGETS[*]} " == *" $t "* ]] || { echo "fuzz.sh: unknown target '$t' (targets: ${ALL_TARGETS[*]})" >&2; exit 2; }
done
MERGE="${SOFTGI_FUZZ_MERGE:-1}"
BUILD="$ROOT/build-fuzz"
JOBS="${SOFTGI_JOBS:-2}"

# Per target: corpus folder, dictionary, largest input (bytes).
corpus_of() { case "$1" in scene_file) echo "$ROOT/tests/fuzz/corpus" ;; *) echo "$ROOT/tests/fuzz/corpus_$1" ;; esac; }
dict_of() { case "$1" in scene_file) echo "$ROOT/tests/fuzz/scene.dict" ;; *) echo "$ROOT/tests/fuzz/$1.dict" ;; esac; }
max_len_of() { case "$1" in gltf) echo 8192 ;; *) echo 4096 ;; esac; }
# Seconds one input may take. OpenEXR allocates an attribute of the size its header declares (up
# to 2 GiB) before finding the file truncated, which takes seconds on a busy machine: not a hang.
timeout_of() { case "$1" in env_image) echo 60 ;; *) echo 20 ;; esac; }

bash "$ROOT/scripts/install-deps.sh"
command -v clang++ >/dev/null || { echo "fuzz.sh: clang++ not found (Debian package clang)" >&2; exit 1; }

mkdir -p "$BUILD/obj"
# A generated Ninja file gives incremental, header-tracked rebuilds without touching the CMake build.
CXXFLAGS="-std=c++20 -g -O1 -fno-omit-frame-pointer -fsanitize=address,undefined -fno-sanitize-recover=undefined"
DEFS="-DSOFTGI_SOURCE_DIR=\\\"$ROOT\\\" -DSOFTGI_FUZZ_DATA_DIR=\\\"$ROOT/tests/fuzz/data\\\" -DSOFTGI_WITH_OIIO=1"
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
  for src in "$ROOT"/core/src/*.cpp "$ROOT"/core/src/{sh,scene,proxies,io}/*.cpp; do
    [ -f "$src" ] || continue
    rel="${src#"$ROOT"/}"
    obj="obj/${rel//\//_}.o"
    echo "build $obj: cxx $src"
    objs+=("$obj")
  done
  for t in "${ALL_TARGETS[@]}"; do
    echo "build obj/fuzz_$t.o: cxx $ROOT/tests/fuzz/fuzz_$t.cpp"
    echo "build fuzz_$t: link obj/fuzz_$t.o ${objs[*]}"
  done
} > "$BUILD/build.ninja"
echo "== build (clang, fuzzer + ASan + UBSan): ${TARGETS[*]} =="
ninja -C "$BUILD" -j "$JOBS" "${TARGETS[@]/#/fuzz_}"

symbolizer="$(command -v llvm-symbolizer || command -v llvm-symbolizer-14 || true)"
export ASAN_OPTIONS="detect_leaks=1:abort_on_error=0${symbolizer:+:external_symbolizer_path=$symbolizer}"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
# Leaks inside third-party libraries that softgi cannot free, each named with its reason there.
export LSAN_OPTIONS="suppressions=$ROOT/tests/fuzz/lsan.supp:print_suppressions=0"
failed=()
for t in "${TARGETS[@]}"; do
  corpus="$(corpus_of "$t")"
  work="$BUILD/work/$t"
  crashes="$BUILD/crashes/$t"
  mkdir -p "$work" "$crashes"
  echo "== fuzz $t for ${RUN_SECONDS} s (corpus: ${corpus#"$ROOT"/}, $(ls "$corpus" | wc -l) files) =="
  status=0
  # (libpng reports every broken PNG on stderr; those lines are dropped.)
  "$BUILD/fuzz_$t" "$work" "$corpus" -dict="$(dict_of "$t")" -max_total_time="$RUN_SECONDS" \
    -max_len="$(max_len_of "$t")" -timeout="$(timeout_of "$t")" -rss_limit_mb=4096 -print_final_stats=1 \
    -artifact_prefix="$crashes/" 2> >(grep --line-buffered -v '^libpng error: ' >&2) || status=$?
  if [ "$MERGE" != 0 ]; then
    echo "== merge new coverage into ${corpus#"$ROOT"/} =="
    before=$(ls "$corpus" | wc -l)
    "$BUILD/fuzz_$t" -merge=1 -max_len="$(max_len_of "$t")" -timeout="$(timeout_of "$t")" -rss_limit_mb=4096 \
      "$corpus" "$work" 2>&1 | tail -n 3
    echo "fuzz.sh: $t corpus $before -> $(ls "$corpus" | wc -l) files"
  fi
  if [ "$status" -ne 0 ]; then
    echo "fuzz.sh: $t stopped with status $status; reproducers in $crashes/:" >&2
    ls -la "$crashes" >&2
    failed+=("$t")
  fi
done
if [ ${#failed[@]} -gt 0 ]; then
  echo "fuzz.sh: findings in: ${failed[*]}" >&2
  exit 1
fi
echo "fuzz.sh: no crash in ${RUN_SECONDS} s per target (${TARGETS[*]})"
