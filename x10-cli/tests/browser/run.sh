#!/usr/bin/env bash
# The run's timeline pages in a real headless browser: `x10 sim --html` writes the pages of
# four example robots (Figure 4.4, the bumper, the doorbell, and the explorer with its arena),
# then check-page.mjs opens each in Chromium and uses it as a reader would (zoom, wheel, drag,
# a view from the address, the arena's slider), failing on any script error. ./test-all runs
# it. `x10 monitor --html` writes its page with the same code (x10_sim::timeline).
#
# Needs node (as the emulated RP2040s do) and Chromium (installed with apt-get when missing and
# root or sudo is at hand; otherwise one line says how).
set -Eeuo pipefail
trap 'echo "FAILED: $BASH_COMMAND" >&2' ERR
cd "$(dirname "${BASH_SOURCE[0]}")/../../.."

browser=""
for b in "${CHROMIUM:-}" chromium chromium-browser google-chrome; do
    if [ -n "$b" ] && command -v "$b" >/dev/null 2>&1; then browser=$b; break; fi
done
if [ -z "$browser" ]; then
    if command -v apt-get >/dev/null 2>&1 && { [ "$(id -u)" = 0 ] || command -v sudo >/dev/null 2>&1; }; then
        s=(); [ "$(id -u)" = 0 ] || s=(sudo)
        echo "installing chromium with apt-get (the timeline pages are tested in it)"
        "${s[@]}" apt-get update -qq && "${s[@]}" apt-get install -y -qq chromium >/dev/null ||
            { echo "test-all: installing chromium failed (above): run   sudo apt-get install chromium   then ./test-all again" >&2; exit 1; }
        browser=chromium
    else
        echo "test-all: no Chromium to test the timeline pages in: install it (Debian/Ubuntu: sudo apt-get install chromium) or set CHROMIUM, then ./test-all again" >&2
        exit 1
    fi
fi
command -v node >/dev/null || { echo "test-all: node is missing (apt-get install nodejs)" >&2; exit 1; }
# Node 20 has WebSocket behind a flag; later versions have it by default.
flag=()
[ "$(node -e 'process.stdout.write(typeof WebSocket)')" = function ] || flag=(--experimental-websocket)

pages=$(mktemp -d)
trap 'rm -rf "$pages"' EXIT
cargo build -q -p x10-cli --bin x10
x10=${CARGO_TARGET_DIR:-target}/debug/x10
"$x10" sim fig4_4 --html "$pages/fig4_4.html" >/dev/null
"$x10" sim bumper --html "$pages/bumper.html" >/dev/null
"$x10" sim doorbell --html "$pages/doorbell.html" >/dev/null
"$x10" sim explorer --duration-ms 20000 --html "$pages/explorer.html" >/dev/null
CHROMIUM=$browser node "${flag[@]}" --no-warnings x10-cli/tests/browser/check-page.mjs "$pages"/*.html
