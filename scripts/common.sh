# Shared by scripts/run.sh and scripts/test.sh: dependency installation and the CMake builds.
set -euo pipefail
SOFTGI_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
JOBS="${SOFTGI_JOBS:-$(nproc 2>/dev/null || echo 2)}"
# Vulkan's loader wants a private runtime dir; headless machines often lack one.
if [ -z "${XDG_RUNTIME_DIR:-}" ] || [ ! -d "${XDG_RUNTIME_DIR:-}" ]; then
  export XDG_RUNTIME_DIR="/tmp/softgi-runtime-$(id -u)"
  mkdir -p "$XDG_RUNTIME_DIR" && chmod 0700 "$XDG_RUNTIME_DIR"
fi

softgi_install_deps() {
  bash "$SOFTGI_ROOT/scripts/install-deps.sh"
}

# softgi_build DIR BUILD_TYPE [extra cmake args...]
softgi_build() {
  local dir="$1" type="$2"
  shift 2
  echo "== configure $dir ($type) =="
  cmake -S "$SOFTGI_ROOT" -B "$SOFTGI_ROOT/$dir" -G Ninja -DCMAKE_BUILD_TYPE="$type" "$@"
  echo "== build $dir =="
  cmake --build "$SOFTGI_ROOT/$dir" -j "$JOBS"
}
