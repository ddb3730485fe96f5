#!/usr/bin/env bash
# Fetches the real asset set into assets/ (git-ignored; $SOFTGI_ASSETS overrides the location, as in
# softgi::scene::assets_dir()): four lat-long HDR environment maps and two glTF models from the CC0
# npm package @pmndrs/assets (HDRIs from Poly Haven, 512x256 EXR; bunny and Suzanne as Draco GLB).
#
# The package ships each file as a JS module `export default 'data:<mime>;base64,<payload>'`; the
# payload is decoded to assets/hdri/<name>.exr and assets/models/<name>.glb and checked against
# scripts/assets.sha256. `npm pack` downloads only the tarball (no node_modules, no install scripts).
# Idempotent: does nothing when every file is present with the right checksum.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
ASSETS="${SOFTGI_ASSETS:-$ROOT/assets}"
SUMS="$ROOT/scripts/assets.sha256"
PACKAGE="@pmndrs/assets"
VERSION="1.7.0"  # pinned: the checksums below belong to this version's payloads
FILES=(hdri/sky.exr hdri/sunset.exr hdri/apartment.exr hdri/studio.exr models/bunny.glb models/suzi.glb)

die() { echo "fetch-assets: error: $*" >&2; exit 1; }

[ -f "$SUMS" ] || die "checksum list $SUMS is missing"
for tool in tar base64 sha256sum sed mktemp; do
  command -v "$tool" >/dev/null || die "'$tool' not found (Debian package coreutils/tar/sed)"
done

expected_sum() {  # the checksum listed for one relative path
  local sum
  sum="$(awk -v f="$1" '$2 == f { print $1 }' "$SUMS")"
  [ -n "$sum" ] || die "no checksum for $1 in $SUMS"
  echo "$sum"
}

file_ok() {  # present and matching its checksum
  [ -f "$ASSETS/$1" ] && [ "$(sha256sum "$ASSETS/$1" | awk '{ print $1 }')" = "$(expected_sum "$1")" ]
}

missing=()
for f in "${FILES[@]}"; do
  file_ok "$f" || missing+=("$f")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "fetch-assets: all ${#FILES[@]} files present in $ASSETS, checksums match"
else
echo "fetch-assets: ${#missing[@]} of ${#FILES[@]} files missing or changed in $ASSETS: ${missing[*]}"

# npm: present on most developer machines; on a bare Debian 12 install it the way install-deps.sh does.
if ! command -v npm >/dev/null; then
  echo "fetch-assets: npm not found; installing Debian packages nodejs npm"
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then
    command -v sudo >/dev/null || die "npm is missing and this is not root and has no sudo; install: nodejs npm"
    SUDO="sudo"
  fi
  $SUDO apt-get -o DPkg::Lock::Timeout=600 update -q
  $SUDO env DEBIAN_FRONTEND=noninteractive apt-get -o DPkg::Lock::Timeout=600 install -y -q --no-install-recommends nodejs npm
  command -v npm >/dev/null || die "npm still not found after installing nodejs npm"
fi

TMP="$(mktemp -d "${TMPDIR:-/tmp}/softgi-assets.XXXXXX")"
trap 'rm -rf "$TMP"' EXIT

echo "fetch-assets: downloading $PACKAGE@$VERSION (about 14 MB) with npm pack"
if ! (cd "$TMP" && npm pack --silent "$PACKAGE@$VERSION" >"$TMP/pack.log" 2>&1); then
  cat "$TMP/pack.log" >&2
  die "npm pack $PACKAGE@$VERSION failed (no network or no access to the npm registry? see the npm output above)"
fi
TARBALL="$(find "$TMP" -maxdepth 1 -name "*.tgz" | head -n 1)"
[ -n "$TARBALL" ] || die "npm pack $PACKAGE@$VERSION produced no tarball in $TMP"

members=()
for f in "${missing[@]}"; do members+=("package/$f.js"); done
tar -xzf "$TARBALL" -C "$TMP" "${members[@]}" || die "tarball $TARBALL lacks one of: ${members[*]}"

for f in "${missing[@]}"; do
  js="$TMP/package/$f.js"
  # Exactly one data URI: export default 'data:<mime>;base64,<payload>'
  head -c 64 "$js" | grep -q "^export default 'data:[^;']*;base64," \
    || die "$PACKAGE@$VERSION package/$f.js is not of the form export default 'data:...;base64,...'"
  mkdir -p "$(dirname "$ASSETS/$f")"
  sed -e "s/^export default 'data:[^;']*;base64,//" -e "s/'[[:space:];]*\$//" "$js" | tr -d '\n' \
    | base64 -d >"$ASSETS/$f.tmp" || die "could not decode the base64 payload of package/$f.js"
  got="$(sha256sum "$ASSETS/$f.tmp" | awk '{ print $1 }')"
  want="$(expected_sum "$f")"
  if [ "$got" != "$want" ]; then
    rm -f "$ASSETS/$f.tmp"
    die "$f: checksum $got does not match $want listed in $SUMS"
  fi
  mv "$ASSETS/$f.tmp" "$ASSETS/$f"
  echo "fetch-assets: $ASSETS/$f ($(wc -c <"$ASSETS/$f") bytes, sha256 ok)"
done
(cd "$ASSETS" && sha256sum --quiet -c "$SUMS") || die "checksum verification of $ASSETS failed"
echo "fetch-assets: done; ${#FILES[@]} files in $ASSETS (CC0 1.0, $PACKAGE@$VERSION)"
fi

# The charting library `softgi report` copies into every report so that its page works offline:
# Vega, Vega-Lite and vega-embed (BSD-3-Clause), their minified browser builds and licences, into
# assets/web/. Pinned versions; checked against scripts/web.sha256.
WEB_SUMS="$ROOT/scripts/web.sha256"
WEB_PACKAGES=("vega@5.33.0:build/vega.min.js" "vega-lite@5.23.0:build/vega-lite.min.js" "vega-embed@6.29.0:build/vega-embed.min.js")
[ -f "$WEB_SUMS" ] || die "checksum list $WEB_SUMS is missing"
if (cd "$ASSETS" 2>/dev/null && sha256sum --quiet -c "$WEB_SUMS" >/dev/null 2>&1); then
  echo "fetch-assets: charting library present in $ASSETS/web, checksums match"
  exit 0
fi
command -v npm >/dev/null || die "npm not found (Debian packages nodejs npm), needed for the charting library"
WEB_TMP="$(mktemp -d "${TMPDIR:-/tmp}/softgi-web.XXXXXX")"
trap 'rm -rf "${TMP:-}" "$WEB_TMP"' EXIT
mkdir -p "$ASSETS/web"
for entry in "${WEB_PACKAGES[@]}"; do
  spec="${entry%%:*}"
  file="${entry#*:}"
  name="${spec%@*}"
  echo "fetch-assets: downloading $spec with npm pack"
  mkdir -p "$WEB_TMP/$name"
  if ! (cd "$WEB_TMP/$name" && npm pack --silent "$spec" >"$WEB_TMP/$name/pack.log" 2>&1); then
    cat "$WEB_TMP/$name/pack.log" >&2
    die "npm pack $spec failed (no network or no access to the npm registry?)"
  fi
  tarball="$(find "$WEB_TMP/$name" -maxdepth 1 -name "*.tgz" | head -n 1)"
  [ -n "$tarball" ] || die "npm pack $spec produced no tarball"
  tar -xzf "$tarball" -C "$WEB_TMP/$name" "package/$file" package/LICENSE || die "$spec lacks package/$file or package/LICENSE"
  cp "$WEB_TMP/$name/package/$file" "$ASSETS/web/$(basename "$file").tmp"
  cp "$WEB_TMP/$name/package/LICENSE" "$ASSETS/web/$name.LICENSE.tmp"
  mv "$ASSETS/web/$(basename "$file").tmp" "$ASSETS/web/$(basename "$file")"
  mv "$ASSETS/web/$name.LICENSE.tmp" "$ASSETS/web/$name.LICENSE"
done
(cd "$ASSETS" && sha256sum --quiet -c "$WEB_SUMS") || die "checksum verification of $ASSETS/web failed"
echo "fetch-assets: charting library in $ASSETS/web (BSD-3-Clause: ${WEB_PACKAGES[*]%%:*})"
