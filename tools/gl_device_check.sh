#!/usr/bin/env bash
# gl_device_check.sh - the GL path on a GPU machine, in one short run
# (docs/gl.md). Runs binaries built elsewhere and carried along
# (build/bin/reflect_gl: links libEGL.so.1, libm and libc only), so the
# machine needs no build tools: only a GLVND libEGL (libegl1, libglvnd0)
# and the vendor's EGL driver.
#
#   bash tools/gl_device_check.sh            from the repository root
#
# Environment:
#   OUT           where the results go (default out/gl_device); 9 files
#   GL_LIBS_DIR   optional: folders (colon-separated) holding libEGL.so.1 and
#                 libGLdispatch.so.0 unpacked from .deb files; put first on
#                 LD_LIBRARY_PATH
#   GL_CHECK_SIZES, GL_CHECK_SCENE_SIZE, GL_CHECK_POINTS, GL_CHECK_VALIDATE_POINTS
#                 the frames' sizes (default 640x480,1920x1080,3840x2160),
#                 the every-scene size (640x480), the projection bench's points
#                 per camera (4000000) and the validation's (100000): smaller
#                 ones try the script out on llvmpipe, e.g.
#                 GL_CHECK_SIZES=160x120 GL_CHECK_SCENE_SIZE=160x120
#                 GL_CHECK_POINTS=20000 GL_CHECK_VALIDATE_POINTS=20000
#   GL_CHECK_EMBREE=0  skips the Embree step
# When /usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json exists,
# GLVND's EGL is pointed at it (and /usr/local/nvidia/lib64 and lib join
# LD_LIBRARY_PATH), so the NVIDIA driver answers rather than Mesa.
#
# Writes: info.txt (EGL vendor, GL renderer and version, the libraries
# resolved), validate.txt and validate.csv (every camera's GLSL projection
# against its C projection on 10^5 points, the SBC morph grid's per-sheet
# blend among them), bench.txt and bench.csv (the
# projection rate on 4 x 10^6 points per camera, GL beside one CPU thread:
# SBC's rows against the paper's 20 M vertices/s), frames.txt and
# frames.csv (PLANAR on mirror-room and default, C3RC and SBC on default, through GL
# against the CPU path on every core at 640x480, 1920x1080 and 3840x2160:
# C3RC's GL frame against the paper's 48-650 ms, SBC's vertex rate in
# gl_mvertices_per_s), scenes.txt and scenes.csv (PLANAR, C3RC and SBC on
# every built-in scene at 640x480: the GL frame's and the CPU frame's mean
# reflection error against RAYTRACE, which the GL path holds within 1 px
# of the CPU's), and, when build/bin/reflect's libraries resolve
# (Embree, OpenImageIO, tinygltf: install them or carry them in
# GL_LIBS_DIR), embree/ (reflect bench --only sbc: RAYTRACE through our BVH
# and through Embree beside SBC on the CPU, default scene, the same three
# sizes, DIR/sbc_resolution.csv) and summary.txt (the rows to compare, side
# by side). Each step has its own time limit, 12 minutes in all.
set -u
cd "$(dirname "$0")/.." || exit 1
OUT=${OUT:-out/gl_device}
SIZES=${GL_CHECK_SIZES:-640x480,1920x1080,3840x2160}
SCENE_SIZE=${GL_CHECK_SCENE_SIZE:-640x480}
POINTS=${GL_CHECK_POINTS:-4000000}
VALIDATE_POINTS=${GL_CHECK_VALIDATE_POINTS:-100000}
mkdir -p "$OUT"
BIN=build/bin/reflect_gl
VENDOR_JSON=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json

if [ -n "${GL_LIBS_DIR:-}" ]; then
  export LD_LIBRARY_PATH="$GL_LIBS_DIR${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
fi
if [ -f "$VENDOR_JSON" ]; then
  export __EGL_VENDOR_LIBRARY_FILENAMES="$VENDOR_JSON"
  for d in /usr/local/nvidia/lib64 /usr/local/nvidia/lib; do
    [ -d "$d" ] && export LD_LIBRARY_PATH="${LD_LIBRARY_PATH:+$LD_LIBRARY_PATH:}$d"
  done
fi

{
  echo "date: $(date -u)"
  echo "host: $(uname -a)"
  echo "__EGL_VENDOR_LIBRARY_FILENAMES=${__EGL_VENDOR_LIBRARY_FILENAMES:-}"
  echo "LD_LIBRARY_PATH=${LD_LIBRARY_PATH:-}"
  command -v nvidia-smi >/dev/null && nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv
  echo "--- libraries of $BIN"
  if command -v ldd >/dev/null; then ldd "$BIN"; else echo "(no ldd)"; fi
  echo "--- reflect_gl info"
} >"$OUT/info.txt" 2>&1

if [ ! -x "$BIN" ]; then
  echo "missing $BIN: build it with 'make build/bin/reflect_gl' and carry build/bin" | tee -a "$OUT/info.txt"
  exit 1
fi
timeout -k 5 30 "$BIN" info >>"$OUT/info.txt" 2>&1
rc=$?
cat "$OUT/info.txt"
if [ $rc -ne 0 ]; then
  echo "gl_device_check: no GL context (exit $rc); see $OUT/info.txt" >&2
  exit 1
fi

status=0
echo "=== validate ($VALIDATE_POINTS points per camera)"
timeout -k 5 60 "$BIN" validate --points "$VALIDATE_POINTS" --csv "$OUT/validate.csv" >"$OUT/validate.txt" 2>&1 || status=1
cat "$OUT/validate.txt"

echo "=== bench: projection rate ($POINTS points per camera, GL best of 5)"
timeout -k 5 90 "$BIN" bench --points "$POINTS" --repeats 5 --csv "$OUT/bench.csv" >"$OUT/bench.txt" 2>&1 || status=1
cat "$OUT/bench.txt"

echo "=== frames: PLANAR, C3RC and SBC through GL against the CPU path (RAYTRACE as truth up to 640x480)"
timeout -k 5 240 "$BIN" frames --sizes "$SIZES" --methods planar,c3rc,sbc \
  --truth-max-pixels 307200 --csv "$OUT/frames.csv" >"$OUT/frames.txt" 2>&1 || status=1
cat "$OUT/frames.txt"

echo "=== scenes: PLANAR, C3RC, SBC, SPOC and GRAPHCAM on every built-in scene at $SCENE_SIZE, GL and CPU against RAYTRACE"
timeout -k 5 180 "$BIN" frames --sizes "$SCENE_SIZE" --methods planar,c3rc,sbc,spoc,graphcam --scenes all \
  --csv "$OUT/scenes.csv" >"$OUT/scenes.txt" 2>&1 || status=1
cat "$OUT/scenes.txt"

echo "=== Embree: RAYTRACE (our BVH, Embree) and SBC on the CPU at the same sizes (reflect bench --only sbc)"
REFLECT=build/bin/reflect
missing=""
if [ -x "$REFLECT" ] && command -v ldd >/dev/null; then
  missing=$(ldd "$REFLECT" 2>&1 | grep "not found" | awk '{print $1}' | tr '\n' ' ')
elif [ ! -x "$REFLECT" ]; then
  missing="$REFLECT itself"
fi
if [ "${GL_CHECK_EMBREE:-1}" = 0 ]; then
  echo "skipped: GL_CHECK_EMBREE=0" | tee "$OUT/embree.txt"
elif [ -z "$missing" ]; then
  timeout -k 5 240 "$REFLECT" bench --only sbc --out "$OUT/embree" >"$OUT/embree.txt" 2>&1 || status=1
  grep -i "resolution\|embree\|raytrace\|crossover" "$OUT/embree.txt" | head -40
else
  echo "skipped: missing $missing(carry them in GL_LIBS_DIR)" | tee "$OUT/embree.txt"
fi

{
  echo "--- SBC projection rate (GL, M vertices/s) against the paper's 20 M/s"
  grep "^sbc" "$OUT/bench.txt"
  echo "--- frames: GL frame against the CPU path (C3RC against the paper's 48-650 ms)"
  grep -E "^(planar|c3rc|sbc) " "$OUT/frames.txt"
  echo "--- every built-in scene at $SCENE_SIZE: mean reflection error against RAYTRACE, GL and CPU"
  grep -E "^(planar|c3rc|sbc|spoc|graphcam) " "$OUT/scenes.txt" | sed -E 's/ cameras:.*vs RAYTRACE:/:/'
  echo "--- Embree and our BVH at the same sizes (default scene; embree/sbc_resolution.csv)"
  if [ -f "$OUT/embree/sbc_resolution.csv" ]; then cat "$OUT/embree/sbc_resolution.csv"; else cat "$OUT/embree.txt"; fi
} >"$OUT/summary.txt" 2>&1
cat "$OUT/summary.txt"
echo "gl_device_check: results in $OUT (exit $status)"
exit $status
