#!/usr/bin/env bash
# The `reflect` command end to end: every built-in scene renders to a real
# image, info lists a real glTF asset, --help works for each command, and
# bad input (missing or truncated files, unknown names and options, bad
# sizes) exits non-zero with a message naming the problem, never a crash.
# Prints the plain "N passed, N failed" line; exits 1 on any failure.
set -u
bin=${1:-build/reflect}
assets=${ASSETS:-../shared/assets}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
pass=0 fail=0

ok() { # ok NAME CMD...: the command succeeds
    local name=$1; shift
    if "$@" >"$tmp/out" 2>"$tmp/err"; then pass=$((pass + 1))
    else fail=$((fail + 1)); echo "FAIL $name: exit $?"; cat "$tmp/err"; fi
}
refuses() { # refuses NAME PATTERN CMD...: non-zero exit (not a crash), stderr matches PATTERN
    local name=$1 pattern=$2; shift 2
    "$@" >"$tmp/out" 2>"$tmp/err"
    local code=$?
    if [ $code -ne 0 ] && [ $code -lt 128 ] && grep -qE "$pattern" "$tmp/err"; then pass=$((pass + 1))
    else fail=$((fail + 1)); echo "FAIL $name: exit $code, stderr:"; cat "$tmp/err"; fi
}

for s in default mirror-room concave glass; do
    ok "render $s" "$bin" render --builtin "$s" --size 96x64 --threads 2 --out "$tmp/$s.png"
    ok "$s.png is a 96x64 image" bash -c "oiiotool --info '$tmp/$s.png' | grep -q '96 x  *64'"
done
ok "render --stats prints timings" bash -c "'$bin' render --builtin default --size 64x48 --out '$tmp/s.png' --stats | grep -q 'total ms'"
ok "render to EXR" "$bin" render --builtin glass --size 32x24 --out "$tmp/g.exr"
ok "help" "$bin" --help
ok "render --help" "$bin" render --help
ok "info --help" "$bin" info --help
ok "info builtin" bash -c "'$bin' info --builtin default | grep -q teapot"
if [ -d "$assets" ]; then
    ok "info Duck.glb" bash -c "'$bin' info '$assets/Duck.glb' | grep -q 'triangles    4212'"
    ok "render Box.glb" "$bin" render "$assets/Box.glb" --size 48x48 --out "$tmp/box.png"
    ok "render with an HDR environment" "$bin" render --builtin default --size 48x36 \
        --env "$assets/env/studio_small_03_1k.hdr" --out "$tmp/env.png"
    head -c 3000 "$assets/Duck.glb" >"$tmp/truncated.glb"
    refuses "truncated glb" "truncated.glb" "$bin" render "$tmp/truncated.glb" --out "$tmp/x.png"
else
    echo "note: $assets not found; the asset cases are skipped"
fi
refuses "missing file" "nope.glb" "$bin" info "$tmp/nope.glb"
refuses "unknown builtin" "no built-in scene" "$bin" render --builtin nowhere
refuses "unknown method" "unknown method" "$bin" render --builtin default --method magic
refuses "bad size" "expected WxH" "$bin" render --builtin default --size 0x10
refuses "unknown option" "unknown option" "$bin" render --builtin default --frobnicate 1
refuses "no scene" "give one scene" "$bin" render
refuses "unknown command" "unknown command" "$bin" paint
refuses "missing environment" "nothing.hdr" "$bin" render --builtin default --env "$tmp/nothing.hdr" --out "$tmp/y.png"
refuses "method not built yet" "not available" "$bin" render --builtin default --method sbc --out "$tmp/z.png"

echo "cli: $pass passed, $fail failed"
[ $fail -eq 0 ]
