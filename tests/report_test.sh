#!/usr/bin/env bash
# `reflect bench --report DIR --quick` opened in headless Chromium: the page
# names no network address, every image on it loads (the page's own script
# writes <body data-check="images=N broken=B errors=E"> after the load
# event, and Chromium's --dump-dom shows it), and no error event fires. A
# copy with one image removed must show it broken, so the check can fail.
# Skips, saying why, when Chromium is missing or cannot start.
# Prints "N passed, N failed"; exits 1 on any failure.
set -u
bin=${1:-build/bin/reflect}
browser=$(command -v chromium || command -v chromium-browser || true)
if [ -z "$browser" ]; then
    echo "report test: skipped: chromium is not installed (tools/deps.sh installs Debian's chromium)"
    exit 0
fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
pass=0 fail=0

# dom PAGE OUT: the page's DOM after load, by headless Chromium with no
# network and a new empty profile
dom() {
    timeout -k 5 60 "$browser" --headless --no-sandbox --disable-gpu --disable-quic --no-first-run \
        --disable-background-networking --disable-component-update --disable-sync \
        --user-data-dir="$tmp/profile-$RANDOM" --virtual-time-budget=10000 --dump-dom "file://$1" \
        >"$2" 2>"$tmp/chromium.err"
}

if ! "$bin" bench --report "$tmp/report" --quick >"$tmp/bench.log" 2>&1; then
    echo "FAIL reflect bench --report --quick:"; tail -20 "$tmp/bench.log"
    echo "0 passed, 1 failed"; exit 1
fi
page=$tmp/report/index.html
images=$(grep -o '<img ' "$page" | wc -l)
if [ "$images" -gt 20 ]; then pass=$((pass + 1)); else fail=$((fail + 1)); echo "FAIL the page has $images images"; fi
if grep -qiE '(src|href)="(https?:)?//' "$page"; then
    fail=$((fail + 1)); echo "FAIL the page refers to the network:"; grep -oiE '(src|href)="(https?:)?//[^"]*"' "$page"
else pass=$((pass + 1)); fi

if ! dom "$page" "$tmp/dom.html" || ! grep -q '<body' "$tmp/dom.html"; then
    echo "report test: skipped: chromium did not start or dump the page:"; tail -5 "$tmp/chromium.err"
    exit 0
fi
check=$(grep -o 'data-check="[^"]*"' "$tmp/dom.html")
if [ "$check" = "data-check=\"images=$images broken=0 errors=0\"" ]; then pass=$((pass + 1))
else fail=$((fail + 1)); echo "FAIL in Chromium: ${check:-no check ran} (want images=$images broken=0 errors=0)"; fi

# the check can fail: one picture gone
cp -r "$tmp/report" "$tmp/broken"
rm "$tmp/broken/img/heat-legend.png"
dom "$tmp/broken/index.html" "$tmp/dom-broken.html"
check=$(grep -o 'data-check="[^"]*"' "$tmp/dom-broken.html")
if [ "$check" = "data-check=\"images=$images broken=1 errors=1\"" ]; then pass=$((pass + 1))
else fail=$((fail + 1)); echo "FAIL a missing image: ${check:-no check ran} (want broken=1 errors=1)"; fi

echo "report test: $pass passed, $fail failed"
[ $fail -eq 0 ]
