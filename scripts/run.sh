#!/usr/bin/env bash
# The main job: installs dependencies, builds, and prints the SH tables summary.
# (Later issues make this the comparison of every technique on the default scene.)
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
softgi_install_deps
softgi_build build Release -DSOFTGI_BUILD_TESTS=OFF -DSOFTGI_BUILD_BENCH=OFF
"$SOFTGI_ROOT/build/app/softgi" tables --order "${SOFTGI_ORDER:-4}"
