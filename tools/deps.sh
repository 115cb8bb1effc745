#!/usr/bin/env bash
# Installs the Debian packages this project needs (DESIGN.md section 7) when
# any of them is missing. Idempotent: quiet and quick when all are installed.
# Used by `make deps`, and so by `make test`, `make bench` and `make demo`.
set -euo pipefail

packages=(
    build-essential pkg-config
    libcriterion-dev                                      # tests
    libegl-dev libgles-dev libgl-dev libegl-mesa0 libgl1-mesa-dri  # headless GL (llvmpipe)
    gnuplot-nox                                           # bench charts
    libopenimageio-dev openimageio-tools                  # images, image compare
    libtinygltf-dev                                       # glTF scenes
    libembree-dev                                         # ray-tracing peer
    valgrind
)
# Wanted by one test only (tests/report_test.sh opens the report page in
# headless Chromium, and skips without it): a failed install warns.
optional=(chromium)

if ! command -v dpkg-query >/dev/null 2>&1; then
    echo "deps: dpkg-query not found, so this is not Debian; install the equivalents of:" >&2
    echo "  ${packages[*]}" >&2
    exit 0
fi

installed() { grep -qx installed <<<"$(dpkg-query -W -f='${db:Status-Status}\n' "$1" 2>/dev/null || true)"; }
missing=() missing_optional=()
for p in "${packages[@]}"; do installed "$p" || missing+=("$p"); done
for p in "${optional[@]}"; do installed "$p" || missing_optional+=("$p"); done
if [ ${#missing[@]} -eq 0 ] && [ ${#missing_optional[@]} -eq 0 ]; then
    exit 0
fi

# Runs a command as root: directly when root, else through sudo (which may
# ask for a password on a terminal; without one it must not need to).
as_root() {
    if [ "$(id -u)" -eq 0 ]; then
        "$@"
    elif command -v sudo >/dev/null 2>&1; then
        if [ -t 0 ]; then sudo "$@"; else sudo -n "$@"; fi
    else
        echo "deps: not root and sudo is not installed; as root, run:" >&2
        echo "  apt-get install --no-install-recommends ${missing[*]}" >&2
        exit 1
    fi
}

if [ ${#missing[@]} -gt 0 ]; then
    echo "deps: installing missing Debian packages: ${missing[*]}"
    as_root env DEBIAN_FRONTEND=noninteractive apt-get update
    as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends "${missing[@]}"
fi
if [ ${#missing_optional[@]} -gt 0 ]; then
    # in a subshell, so that as_root's exit (no root, no sudo) only warns
    echo "deps: installing optional Debian packages: ${missing_optional[*]}"
    ( [ ${#missing[@]} -gt 0 ] || as_root env DEBIAN_FRONTEND=noninteractive apt-get update
      as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends "${missing_optional[@]}" ) ||
        echo "deps: could not install ${missing_optional[*]}; the tests that need them will skip" >&2
fi
