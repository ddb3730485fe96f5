#!/usr/bin/env bash
# The main job: installs dependencies, builds, and compares every registered technique with the
# ray-traced ground truth on the default built-in scene (SOFTGI_SCENE overrides it): images, error
# maps, out/compare/compare.json and out/compare/summary.md, which is printed at the end.
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
softgi_install_deps
bash "$SOFTGI_ROOT/scripts/fetch-assets.sh"  # CC0 asset set: SOFTGI_SCENE=bunny needs it
softgi_build build Release -DSOFTGI_BUILD_TESTS=OFF -DSOFTGI_BUILD_BENCH=OFF
"$SOFTGI_ROOT/build/app/softgi" compare --scene "${SOFTGI_SCENE:-spheres}" --out "$SOFTGI_ROOT/out/compare"
cat "$SOFTGI_ROOT/out/compare/summary.md"
