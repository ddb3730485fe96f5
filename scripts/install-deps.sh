#!/usr/bin/env bash
# Installs the Debian 12 packages softgi builds against. Idempotent: does nothing when all are present.
set -euo pipefail

PACKAGES=(
  build-essential cmake ninja-build pkg-config git ca-certificates
  mesa-vulkan-drivers libvulkan-dev vulkan-tools vulkan-validationlayers
  glslang-tools glslang-dev spirv-tools
  libglfw3-dev libglm-dev libeigen3-dev libtinygltf-dev libdraco-dev libstb-dev
  nlohmann-json3-dev libcli11-dev
  libopenimageio-dev openimageio-tools
  libgtest-dev libgmock-dev libbenchmark-dev
  libembree-dev libtbb-dev
  # scripts/fuzz.sh: clang 14 does not pull in libFuzzer and the sanitizer runtimes
  # (libclang_rt.fuzzer-x86_64.a, ...: libclang-rt-14-dev), nor llvm-symbolizer (llvm-14), which
  # turns sanitizer reports into file:line stacks.
  clang libclang-rt-14-dev llvm-14
  # The report page's test loads DIR/index.html in a headless browser (console errors, charts drawn).
  chromium-headless-shell
  # softgi-viewer: Dear ImGui (its library holds the GLFW and Vulkan backends); its tests open the
  # window on a virtual X server.
  libimgui-dev xvfb xauth
)

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PACKAGES[@]} packages present"
  exit 0
fi

echo "install-deps: installing ${#missing[@]} missing packages: ${missing[*]}"
SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null || { echo "install-deps: not root and no sudo; install: ${missing[*]}" >&2; exit 1; }
  SUDO="sudo"
fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get -o DPkg::Lock::Timeout=600 update -q
$SUDO env DEBIAN_FRONTEND=noninteractive apt-get -o DPkg::Lock::Timeout=600 install -y -q --no-install-recommends "${missing[@]}"
echo "install-deps: done"
