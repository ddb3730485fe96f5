#!/usr/bin/env bash
# Loads a report's page (DIR/index.html, softgi report) in headless Chromium and checks what a reader
# would see: the page's script ran to the end (data-ready), no script error (the page's own count and
# Chromium's console log), every chart container holds a drawn SVG, and a screenshot that is not blank.
# Usage: check-report-html.sh DIR. Exit 0: all checks pass; 1: one failed (named); 77: no Chromium here (the test is then skipped).
# Writes DIR/check/dom.html, console.log and screenshot.png.
set -euo pipefail

DIR="${1:?usage: check-report-html.sh REPORT_DIR}"
[ -f "$DIR/index.html" ] || { echo "check-report-html: $DIR/index.html does not exist" >&2; exit 1; }
DIR="$(cd "$DIR" && pwd)"

BROWSER=""
for b in chromium-headless-shell chromium google-chrome; do
  if command -v "$b" >/dev/null; then BROWSER="$(command -v "$b")"; break; fi
done
if [ -z "$BROWSER" ]; then
  echo "check-report-html: SKIP: no headless Chromium (chromium-headless-shell, chromium or google-chrome);" \
       "scripts/install-deps.sh installs chromium-headless-shell" >&2
  exit 77
fi
command -v oiiotool >/dev/null || { echo "check-report-html: SKIP: oiiotool (openimageio-tools) is missing" >&2; exit 77; }

OUT="$DIR/check"
mkdir -p "$OUT"
# The virtual time budget lets the page's scripts and chart rendering finish before the DOM is read.
FLAGS=(--headless --no-sandbox --disable-gpu --allow-file-access-from-files --virtual-time-budget=20000 --hide-scrollbars)
# A profile of its own, so that runs do not share state with each other or with a user's browser.
PROFILE="$(mktemp -d "${TMPDIR:-/tmp}/softgi-chromium.XXXXXX")"
trap 'rm -rf "$PROFILE"' EXIT
URL="file://$DIR/index.html"

fail() { echo "check-report-html: FAIL: $*" >&2; exit 1; }

timeout 120 "$BROWSER" "${FLAGS[@]}" --user-data-dir="$PROFILE/dom" --enable-logging=stderr --v=0 --dump-dom "$URL" \
  >"$OUT/dom.html" 2>"$OUT/console.log" || fail "$BROWSER did not load $URL (see $OUT/console.log)"

attr() { grep -o "<body[^>]*" "$OUT/dom.html" | grep -o "data-$1=\"[^\"]*\"" | head -n 1 | sed 's/.*="\(.*\)"/\1/'; }
ready="$(attr ready)"; errors="$(attr errors)"; charts="$(attr charts)"
echo "check-report-html: $BROWSER loaded $URL: data-ready=$ready data-errors=$errors data-charts=$charts"
[ "$ready" = "1" ] || fail "the page's script did not finish (data-ready=$ready)"
[ "$errors" = "0" ] || fail "the page counted $errors script error(s): $(grep -o '<pre id="page-errors"[^<]*' "$OUT/dom.html")"

# Chromium logs the page's console as INFO:CONSOLE lines; an uncaught exception or console.error from
# the page's own file is a failure (Chromium's own messages, dbus and GPU ones, are not the page's).
page_console="$(grep -E ':CONSOLE[:(]' "$OUT/console.log" | grep -F "source: file://$DIR/" || true)"
if [ -n "$page_console" ]; then
  fail "the page wrote to the console:
$page_console"
fi

containers="$(grep -o 'class="chart vega-embed' "$OUT/dom.html" | wc -l)"
svgs="$(grep -o '<svg[^>]*class="marks"' "$OUT/dom.html" | wc -l)"
echo "check-report-html: $containers chart container(s), $svgs drawn chart(s) (SVG)"
[ "$containers" -ge 1 ] || fail "no chart container in the page"
[ "$charts" -ge "$containers" ] || fail "$charts charts drawn for $containers containers"
[ "$svgs" -ge "$containers" ] || fail "$svgs SVG charts for $containers containers"

timeout 120 "$BROWSER" "${FLAGS[@]}" --user-data-dir="$PROFILE/shot" --window-size=1280,1600 --screenshot="$OUT/screenshot.png" "$URL" \
  >/dev/null 2>&1 || fail "$BROWSER could not take a screenshot of $URL"
[ -s "$OUT/screenshot.png" ] || fail "no screenshot was written"
# A blank (one-colour) page has a standard deviation of 0 in every channel; text and charts on white
# give tens of levels (of 255).
stddev="$(oiiotool --stats "$OUT/screenshot.png" | grep -m1 'Stats StdDev' | awk '{ print $3 }')"
echo "check-report-html: screenshot $OUT/screenshot.png, standard deviation $stddev of 255 (red)"
awk -v s="$stddev" 'BEGIN { exit !(s > 5) }' || fail "the screenshot is blank (standard deviation $stddev of 255)"
echo "check-report-html: PASS"
