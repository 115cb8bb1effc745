#!/usr/bin/env bash
# fuzz/run.sh BIN SECONDS: runs a libFuzzer target for SECONDS (seed 1, so
# a run is repeatable on one machine). build/fuzz/gltf_fuzz, the glTF
# loader's: the seed corpus is fuzz/seeds/ plus the assets of
# ../shared/assets up to 300 KB (larger ones make each run slow), copied
# into build/fuzz/seeds/ at run time. build/fuzz/render_fuzz, the render
# API's: it starts from fuzz/render_seeds/ (inputs that once failed). What a target finds new goes
# to build/fuzz/corpus/ (render_corpus/) and is kept for the next run; a
# crashing or hanging input goes to build/fuzz/crashes/ and fails the run.
#
# fuzz/run.sh --available: exit 0 when clang can build a libFuzzer target.
set -euo pipefail
cd "$(dirname "$0")/.."
cxx=${FUZZ_CXX:-clang++}

if [ "${1:-}" = --available ]; then
    command -v "$cxx" >/dev/null 2>&1 || exit 1
    tmp=$(mktemp -d)
    trap 'rm -rf "$tmp"' EXIT
    printf '#include <cstdint>\n#include <cstddef>\nextern "C" int LLVMFuzzerTestOneInput(const uint8_t *, size_t) { return 0; }\n' \
        >"$tmp/t.cpp"
    "$cxx" -fsanitize=fuzzer,address,undefined "$tmp/t.cpp" -o "$tmp/t" >/dev/null 2>&1
    exit $?
fi

bin=$1
seconds=$2
if [ "$(basename "$bin")" = render_fuzz ]; then
    mkdir -p build/fuzz/render_corpus build/fuzz/crashes
    exec "$bin" -seed=1 -max_total_time="$seconds" -timeout=20 -rss_limit_mb=2560 -max_len=256 -len_control=0 \
        -artifact_prefix=build/fuzz/crashes/render- -print_final_stats=1 build/fuzz/render_corpus fuzz/render_seeds
fi
assets=${ASSETS:-../shared/assets}
work=build/fuzz
rm -rf "$work/seeds"
mkdir -p "$work/seeds" "$work/corpus" "$work/crashes"
cp fuzz/seeds/* "$work/seeds/"
if [ -d "$assets" ]; then
    for f in "$assets"/*.glb; do
        [ "$(stat -c %s "$f")" -le 300000 ] && cp "$f" "$work/seeds/"
    done
else
    echo "fuzz: $assets not found; seeds from fuzz/seeds/ only"
fi
"$bin" -seed=1 -max_total_time="$seconds" -timeout=20 -rss_limit_mb=2560 -dict=fuzz/gltf.dict \
    -artifact_prefix="$work/crashes/" -print_final_stats=1 "$work/corpus" "$work/seeds"
