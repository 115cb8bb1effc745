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
exits2() { # exits2 NAME PATTERN CMD...: exit status 2 and stderr matches PATTERN
    local name=$1 pattern=$2; shift 2
    "$@" >"$tmp/out" 2>"$tmp/err"
    local code=$?
    if [ $code -eq 2 ] && grep -qE "$pattern" "$tmp/err"; then pass=$((pass + 1))
    else fail=$((fail + 1)); echo "FAIL $name: exit $code (want 2), stderr:"; cat "$tmp/err"; fi
}
one_line() { # one_line NAME PATTERN CMD...: exit status 2, and stderr is one line matching PATTERN
    local name=$1 pattern=$2; shift 2
    "$@" >"$tmp/out" 2>"$tmp/err"
    local code=$?
    if [ $code -eq 2 ] && [ "$(wc -l <"$tmp/err")" -eq 1 ] && grep -qE "$pattern" "$tmp/err"; then pass=$((pass + 1))
    else fail=$((fail + 1)); echo "FAIL $name: exit $code (want 2 and one line), stderr:"; cat "$tmp/err"; fi
}

# colour: a PNG is sRGB-encoded, so a constant grey sky (sRGB 128, decoded
# to linear on load) comes out as 128 again; an EXR keeps linear values
oiiotool --pattern constant:color=0.50196,0.50196,0.50196 8x4 3 -d uint8 -o "$tmp/grey.png"
ok "render with a grey sky" "$bin" render --builtin default --env "$tmp/grey.png" --size 32x24 --out "$tmp/grey-out.png"
ok "the grey sky is 128 in the PNG" bash -c \
    "oiiotool '$tmp/grey-out.png' --cut 32x4+0+0 --printstats | grep -qE 'Stats (Min|Max): 0\.(498|50[0-3])[0-9]* 0\.(498|50[0-3])[0-9]* 0\.(498|50[0-3])'"
ok "render to EXR" "$bin" render --builtin default --env "$tmp/grey.png" --size 32x24 --out "$tmp/grey-out.exr"
ok "the grey sky is linear 0.216 in the EXR" bash -c \
    "oiiotool '$tmp/grey-out.exr' --cut 32x4+0+0 --printstats | grep -qE 'Stats Min: 0\.21[4-8]'"
# HDR: a sky of linear 4 stays 4 in the EXR, in the sky and in the mirror
# that reflects it (RAYTRACE), and clips to 255 in the PNG unless exposed
# down (-2 stops: linear 1, 255 still) or tone mapped (Reinhard: 4/5 ->
# sRGB 231)
oiiotool --pattern constant:color=4,4,4 8x4 3 -d float -o "$tmp/bright.exr"
ok "render with an HDR sky" "$bin" render --builtin default --method raytrace --env "$tmp/bright.exr" --size 32x24 \
    --out "$tmp/bright-out.exr"
ok "the HDR sky is linear 4 in the EXR" bash -c \
    "oiiotool '$tmp/bright-out.exr' --cut 32x4+0+0 --printstats | grep -qE 'Stats Min: (3\.99|4\.00)[0-9]* (3\.99|4\.00)'"
ok "the mirror reflects the HDR sky above 1" bash -c \
    "oiiotool '$tmp/bright-out.exr' --printstats | grep -qE 'Stats Max: ([2-9]|[1-9][0-9])\.'"
ok "--exposure -3 halves the sky to linear 0.5 in the EXR" bash -c \
    "'$bin' render --builtin default --env '$tmp/bright.exr' --size 32x24 --exposure -3 --out '$tmp/b3.exr' &&
     oiiotool '$tmp/b3.exr' --cut 32x4+0+0 --printstats | grep -qE 'Stats Min: 0\.(49|50)[0-9]* 0\.(49|50)'"
ok "--tonemap reinhard maps the sky of 4 to sRGB 231" bash -c \
    "'$bin' render --builtin default --env '$tmp/bright.exr' --size 32x24 --tonemap reinhard --out '$tmp/b-r.png' &&
     oiiotool '$tmp/b-r.png' --cut 32x4+0+0 --printstats | grep -qE 'Stats Min: 0\.90[0-9]* 0\.90'"
refuses "--tonemap of an unknown name" "expected clamp, reinhard or aces" "$bin" render --builtin default --tonemap x
refuses "--exposure out of range" "expected -64..64" "$bin" render --builtin default --exposure 100

for s in default mirror-room concave glass maze; do
    ok "render $s" "$bin" render --builtin "$s" --size 96x64 --threads 2 --out "$tmp/$s.png"
    ok "$s.png is a 96x64 image" bash -c "oiiotool --info '$tmp/$s.png' | grep -q '96 x  *64'"
done
ok "a one-bounce method says how many pixels past its bounce were traced" bash -c \
    "'$bin' render --builtin mirror-room --method envmap --size 32x24 --out '$tmp/e.png' 2>&1 | grep -q 'reflector pixels whose path goes past the bounces envmap models ray traced'"
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
    # every method on every asset and built-in scene: every pixel opaque,
    # no NaN (alpha's minimum 1 and no NaN count in the linear EXR)
    for scene in "$assets"/*.glb --builtin=default --builtin=mirror-room --builtin=concave --builtin=glass; do
        case $scene in --builtin=*) src=(--builtin "${scene#--builtin=}") ;; *) src=("$scene") ;; esac
        for m in direct raytrace envmap planar c3rc sbc graphcam; do
            ok "$(basename -- "$scene") with $m: every pixel opaque, no NaN" bash -c \
                "'$bin' render $(printf "'%s' " "${src[@]}") --method $m --size 32x24 --depth 2 --envmap-size 16 --out '$tmp/alpha.exr' 2>/dev/null &&
                 oiiotool '$tmp/alpha.exr' --printstats >'$tmp/alpha.txt' &&
                 grep -qE 'Stats Min: [^ ]+ [^ ]+ [^ ]+ 1\.000000' '$tmp/alpha.txt' && grep -qE 'NanCount: 0 0 0 0' '$tmp/alpha.txt'"
        done
    done
    ok "--camera picks ToyCar's eighth camera" bash -c "'$bin' info '$assets/ToyCar.glb' --camera 7 2>/dev/null | grep -q 'camera       7 of 8'"
    refuses "--camera past the last" "camera 8 does not exist: the scene has 8" "$bin" render "$assets/ToyCar.glb" --camera 8 --out "$tmp/x.png"
    ok "ignored glTF features are named" bash -c \
        "'$bin' info '$assets/ToyCar.glb' 2>&1 >/dev/null | grep -q 'warning: .*ToyCar.glb: not drawn: normalTexture (2 uses)'"
    head -c 3000 "$assets/Duck.glb" >"$tmp/truncated.glb"
    refuses "truncated glb" "truncated.glb" "$bin" render "$tmp/truncated.glb" --out "$tmp/x.png"
else
    echo "note: $assets not found; the asset cases are skipped"
fi
for m in raytrace envmap planar c3rc; do
    ok "render --method $m" "$bin" render --builtin mirror-room --method $m --size 48x36 --depth 2 --out "$tmp/m-$m.png"
done
ok "render the maze through its graph camera, both algorithms" bash -c \
    "'$bin' render --builtin maze --method graphcam --graphcam-size 480 --size 48x36 --depth 1 --out '$tmp/gc.png' --stats | grep -q 'frusta       15' &&
     '$bin' render --builtin maze --method graphcam --graphcam-size 480 --graphcam-alg uniform --size 48x36 --depth 1 --out '$tmp/gc1.png'"
refuses "--graphcam-alg of an unknown name" "segments or uniform" "$bin" render --builtin maze --method graphcam --graphcam-alg x
ok "render glass through SPOC's refraction, two layers" bash -c \
    "'$bin' render --builtin glass --method spoc --spoc-glass estimate --spoc-layers 2 --spoc-size 64 --size 48x36 --depth 2 --stats --out '$tmp/sg.png' 2>&1 | grep -q 'impostors    64'"
refuses "--spoc-glass of an unknown name" "traced, estimate or exact" "$bin" render --builtin glass --method spoc --spoc-glass x
ok "render planar with soft shadows" "$bin" render --builtin mirror-room --method planar --shadows --soft-shadows 4 \
    --light-radius 0.3 --size 48x36 --out "$tmp/soft.png"
ok "render planar --no-culling counts renderings" bash -c \
    "'$bin' render --builtin mirror-room --method planar --no-culling --depth 2 --size 32x24 --out '$tmp/n.png' --stats | grep -q 'deepest level 12'"
ok "render c3rc --stats counts projections" bash -c \
    "'$bin' render --builtin default --method c3rc --density 40 --max-splat 3 --leaf-points 200 --size 64x48 --out '$tmp/c.png' --stats | grep -q '^projections  [1-9]'"
refuses "bad --density" "density: not a positive" "$bin" render --builtin default --method c3rc --density -1
refuses "bad --max-splat" "max-splat: expected" "$bin" render --builtin default --method c3rc --max-splat 0
ok "render sbc --stats counts projections" bash -c \
    "'$bin' render --builtin default --method sbc --error-px 2 --ray-factor 4 --size 64x48 --out '$tmp/s.png' --stats | grep -q '^projections  [1-9]'"
ok "render sbc --trace-fallback" "$bin" render --builtin default --method sbc --trace-fallback --ray-factor 4 \
    --size 64x48 --out "$tmp/th.png"
ok "render sbc with the Fresnel blend and the fade" "$bin" render --builtin default --method sbc --fresnel 0.2,0.9 \
    --fade 4,0.1,1 --size 48x36 --out "$tmp/vd.png"
refuses "bad --fresnel" "fresnel: expected" "$bin" render --builtin default --fresnel 0.5
refuses "bad --fade" "fade: expected" "$bin" render --builtin default --fade 0,0.1,1
refuses "bad --ray-factor" "ray-factor: expected" "$bin" render --builtin default --method sbc --ray-factor 0
refuses "bad --soft-shadows" "soft-shadows: expected" "$bin" render --builtin default --soft-shadows 0
ok "render planar with light volumes, caustics and translucency" "$bin" render --builtin mirror-room --method planar \
    --shadows --light-volumes --caustics 4 --light-radius 0.3 --translucency 0.5 --size 48x36 --out "$tmp/lv.png"
refuses "bad --caustics" "caustics: expected" "$bin" render --builtin default --light-volumes --caustics 0
refuses "missing file" "nope.glb" "$bin" info "$tmp/nope.glb"
refuses "unknown builtin" "no built-in scene" "$bin" render --builtin nowhere
exits2 "unknown method" "no method .magic." "$bin" render --builtin default --method magic
refuses "bad size" "expected WxH" "$bin" render --builtin default --size 0x10
exits2 "unknown option" "unknown option" "$bin" render --builtin default --frobnicate 1
exits2 "no scene" "give one scene" "$bin" render
refuses "unknown command" "unknown command" "$bin" paint
refuses "missing environment" "nothing.hdr" "$bin" render --builtin default --env "$tmp/nothing.hdr" --out "$tmp/y.png"
refuses "--time-limit stops a long render and writes nothing" "stopped at the time limit.*nothing written" \
    "$bin" render --builtin glass --method raytrace --depth 8 --size 1024x768 --time-limit 0.05 --out "$tmp/limited.png"
ok "nothing written after the time limit" test ! -e "$tmp/limited.png"
ok "path: every frame of each method against the truth" bash -c "'$bin' path --builtin default --frames 3 --size 32x24 \
    --methods envmap,PLANAR --out '$tmp/path' --images >/dev/null && [ \$(wc -l <'$tmp/path/orbit.csv') = 7 ] && \
    grep -q '^orbit,planar,2,.*,0.0000,0.0000,0.00000,0.00000,999.000,0.0000,0.0,0$' '$tmp/path/orbit.csv' && \
    [ -s '$tmp/path/envmap-0002.png' ] && [ -s '$tmp/path/raytrace-0000.png' ]"
exits2 "path: an unknown path" "orbit, dolly, pan, focus or rim" "$bin" path --path spiral
ok "path: the rim path moves the view" bash -c "'$bin' path --builtin concave --path rim --frames 2 --size 16x12 \
    --methods planar --out '$tmp/rim' --images >/dev/null && ! cmp -s '$tmp/rim/raytrace-0000.png' '$tmp/rim/raytrace-0001.png'"
# pops (reflect path's rule, tools/reflect_path.c): the CSV's last column,
# a count per method in the summary; an exact method has none
ok "path: the pop column" bash -c "'$bin' path --builtin concave --path focus --frames 4 --size 24x18 \
    --methods planar --out '$tmp/pop' >'$tmp/pop.txt' && head -1 '$tmp/pop/focus.csv' | grep -q ',pop$' && \
    grep -qE '^planar .* 0$' '$tmp/pop.txt'"
refuses "a device is not a scene file" "/dev/zero: not a regular file" "$bin" info /dev/zero
ok "render auto --stats: each reflector's choice and why" bash -c \
    "'$bin' render --builtin mirror-room --method auto --error-budget 2 --size 64x48 --out '$tmp/au.png' --stats |
     grep -qE '^  wall mirror planar, [1-9][0-9]* px, near [0-9.]+, beyond [0-9.]+ -> planar \\('"
refuses "auto models that do not parse" "reflect: .-auto-models: auto models, line 2: 'round': expected not a class" bash -c \
    "printf 'reflect-auto-models 1\\nmodel envmap round samples 1 cost 1 0 0 error 0 0 0\\n' >'$tmp/bad.txt' &&
     '$bin' render --builtin default --method auto --auto-models '$tmp/bad.txt' --size 16x12 --out '$tmp/z.png'"
exits2 "an error budget of none" "error-budget: expected pixels above 0" "$bin" render --builtin default --method auto --error-budget 0

# the command line's manners: --version, --name=value, method names in any
# case, an unknown option named as such wherever it stands, exit status 2
# for every usage error, RGB for formats without alpha, material overrides
ok "--version" bash -c "'$bin' --version | grep -qE '^reflect [0-9]+\.[0-9]+\.[0-9]+$'"
ok "--name=value and a method in capitals" "$bin" render --builtin default --method=RAYTRACE --size=32x24 --out="$tmp/eq.png"
ok "PPM output (no alpha)" bash -c "'$bin' render --builtin default --size 32x24 --out '$tmp/rgb.ppm' &&
    oiiotool --info '$tmp/rgb.ppm' | grep -q '3 channel'"
exits2 "an unknown option last" "unknown option --frobnicate" "$bin" render --builtin default --frobnicate
exits2 "a flag given a value" "takes no value" "$bin" render --builtin default --stats=1
exits2 "a value missing" "needs a value" "$bin" render --builtin default --size
ok "--mirror and --glass make diffuse objects reflective" bash -c \
    "'$bin' render --builtin default --method raytrace --mirror sphere --glass red --size 32x24 --out '$tmp/ov.png' --stats |
     grep -q 'total ms'"
ok "--error-px at the bound the help gives" "$bin" render --builtin default --method sbc --error-px 0.001 --size 16x12 --out "$tmp/ep.png"
exits2 "--size past int" "expected WxH" "$bin" render --builtin default --size 4294967297x2
ok "--sbc-paper renders" "$bin" render --builtin default --method sbc --sbc-paper --size 32x24 --out "$tmp/sp.png"
ok "--greedy renders" "$bin" render --builtin glass --method raytrace --greedy --size 32x24 --out "$tmp/gr.png"
ok "--unpruned renders" "$bin" render --builtin glass --method raytrace --unpruned --depth 8 --size 32x24 --out "$tmp/un.png"
ok "layered-em renders" "$bin" render --builtin glass --method layered-em --size 32x24 --out "$tmp/le.png"
ok "layered-em --prebuild renders from every sample's map" bash -c \
    "'$bin' render --builtin glass --method layered-em --lem-samples 4 --prebuild --stats --size 32x24 --out '$tmp/lp.png' | grep -q 'maps         0 inferred, 4 kept, 8 held'"
ok "--frames 2: the second frame takes the first's maps" bash -c \
    "'$bin' render --builtin glass --method layered-em --lem-samples 4 --frames 2 --stats --size 32x24 --out '$tmp/lf.png' | grep -q 'maps         0 inferred, 4 kept, 4 held'"
refuses "--lem-samples out of range" "lem-samples" "$bin" render --builtin glass --lem-samples 0 --out "$tmp/x.png"
ok "--lem-shell box --lem-direct 0 renders" "$bin" render --builtin glass --method layered-em --lem-shell box --lem-direct 0 --size 32x24 --out "$tmp/lb.png"
refuses "--lem-shell of no kind" "lem-shell" "$bin" render --builtin glass --lem-shell cone --out "$tmp/x.png"
refuses "--lem-direct out of range" "lem-direct" "$bin" render --builtin glass --lem-direct 2 --out "$tmp/x.png"
ok "--lem-direct-from viewpoint --lem-direct-conf distance renders" "$bin" render --builtin glass --method layered-em --lem-direct-from viewpoint --lem-direct-conf distance --size 32x24 --out "$tmp/ld.png"
refuses "--lem-direct-from of no place" "lem-direct-from" "$bin" render --builtin glass --lem-direct-from above --out "$tmp/x.png"
refuses "--lem-direct-conf of no kind" "lem-direct-conf" "$bin" render --builtin glass --lem-direct-conf guess --out "$tmp/x.png"
ok "--lem-lens-layers 0 renders" "$bin" render --builtin hybrid --method layered-em --lem-lens-layers 0 --size 32x24 --out "$tmp/ll.png"
refuses "--lem-lens-layers out of range" "lem-lens-layers" "$bin" render --builtin glass --lem-lens-layers 2 --out "$tmp/x.png"
ok "--lem-continue 0 renders" "$bin" render --builtin hybrid --method layered-em --lem-continue 0 --size 32x24 --out "$tmp/lc.png"
refuses "--lem-continue out of range" "lem-continue" "$bin" render --builtin glass --lem-continue 2 --out "$tmp/x.png"
ok "--lem-share 1 renders" "$bin" render --builtin hybrid --method layered-em --lem-share 1 --size 32x24 --out "$tmp/lsh.png"
refuses "--lem-share out of range" "lem-share" "$bin" render --builtin glass --lem-share 2 --out "$tmp/x.png"
refuses "--lem-share with --lem-lens-layers 1" "share_outer_layer" "$bin" render --builtin hybrid --method layered-em --lem-share 1 --lem-lens-layers 1 --out "$tmp/x.png"
ok "--lem-frame fitted renders" "$bin" render --builtin glass --method layered-em --lem-shell cylinder --lem-frame fitted --size 32x24 --out "$tmp/lf.png"
refuses "--lem-frame of no frame" "lem-frame" "$bin" render --builtin glass --lem-frame tilted --out "$tmp/x.png"
exits2 "--mirror of no object" "no object or material" "$bin" render --builtin default --mirror nothing
# hostile input: a value option given twice (the second would silently
# win), an empty output name, and files that are not regular files (a
# FIFO blocks its open, a directory reads as huge) as the scene, a glTF's
# buffer or the environment: each refused at once
exits2 "a value option given twice" "size: given twice" "$bin" render --builtin default --size 8x8 --size=16x12
exits2 "two built-in scenes" "builtin: given twice" "$bin" render --builtin default --builtin glass
# (each under a timeout: a run the parser let through would render for long)
one_line "path: a value option given twice" "^reflect path: --size: given twice$" \
    timeout 20 "$bin" path --builtin default --frames 2 --size 8x8 --size 16x12 --out "$tmp/p1"
one_line "path: two built-in scenes" "^reflect path: --builtin: given twice$" \
    timeout 20 "$bin" path --builtin default --builtin glass --frames 2 --size 8x8 --out "$tmp/p2"
one_line "bench: a value option given twice" "^reflect bench: --out: given twice$" \
    timeout 20 "$bin" bench --only c3rc --out "$tmp/b1" --out "$tmp/b2"
one_line "bench --fit-auto: a value option given twice" "^reflect bench: --size: given twice$" \
    timeout 20 "$bin" bench --fit-auto "$tmp/m.txt" --size 32x32 --size 64x64 --out "$tmp/b4"
one_line "bench --gl: a value option given twice" "^reflect bench: --repeats: given twice$" \
    timeout 20 "$bin" bench --gl --repeats 1 --repeats 2 --out "$tmp/b5"
ok "a refused path or bench writes nothing" bash -c "[ -z \"\$(ls -d '$tmp'/p[12] '$tmp'/b[1245] '$tmp/m.txt' 2>/dev/null)\" ]"
# an option whose value is one of a few names: refused in one line that
# lists them all, inline value or not
for opt in tonemap lem-direct-from lem-direct-conf lem-frame lem-shell spoc-glass graphcam-alg; do
    one_line "--$opt of an unknown name lists the names" "^reflect: --$opt: expected [a-z]+(, [a-z]+)* or [a-z]+, got bogus$" \
        "$bin" render --builtin glass --$opt bogus --out "$tmp/x.png"
done
one_line "--lem-shell= of an unknown name" "^reflect: --lem-shell: expected auto, sphere, cylinder, box or quad, got cone$" \
    "$bin" render --builtin glass --lem-shell=cone --out "$tmp/x.png"
one_line "path: an unknown path lists the paths" "^reflect path: --path: expected orbit, dolly, pan, focus or rim, got spiral$" \
    timeout 20 "$bin" path --path spiral --frames 2 --size 8x8 --out "$tmp/p3"
one_line "bench: --only of no table" \
    "^reflect bench: --only: expected c3rc, sbc, path, graphcam, spoc, spoc-sweeps, lem, lem-sweeps, lem-options, lem-share, lem-grid or lem-grid-calib, got nope$" \
    timeout 20 "$bin" bench --only nope --out "$tmp/b3"
exits2 "an empty --out" "out: expected a file name" "$bin" render --builtin default --out=
mkdir "$tmp/hostile" && mkfifo "$tmp/hostile/fifo" && mkdir "$tmp/hostile/dir" &&
for uri in fifo dir; do
    sed "s#\"uri\": \"data:application/octet-stream;base64,[^\"]*\"#\"uri\": \"$uri\"#" \
        "$(dirname "$0")/../fuzz/seeds/triangle.gltf" >"$tmp/hostile/$uri.gltf"
    refuses "a glTF buffer naming a $uri" "hostile/$uri: not a regular file" \
        timeout 20 "$bin" render "$tmp/hostile/$uri.gltf" --size 8x8 --out "$tmp/x.png"
done
refuses "a FIFO as the scene" "fifo: not a regular file" timeout 20 "$bin" info "$tmp/hostile/fifo"
refuses "a FIFO as the environment" "fifo: cannot open: not a regular file" \
    timeout 20 "$bin" render --builtin default --env "$tmp/hostile/fifo" --size 8x8 --out "$tmp/x.png"
refuses "a FIFO as the auto models" "fifo: not a regular file" \
    timeout 20 "$bin" render --builtin default --method auto --auto-models "$tmp/hostile/fifo" --size 8x8 --out "$tmp/x.png"

# compare: PPMs written here, so every number is known. a is black; b has
# two pixels 255 off in red and one 10 off in green: RMSE
# sqrt((2*255^2 + 10^2) / (3*8)) / 255, 3 of 8 pixels over 2/255, 2 over 10/255.
printf 'P3\n4 2\n255\n0 0 0  0 0 0  0 0 0  0 0 0\n0 0 0  0 0 0  0 0 0  0 0 0\n' >"$tmp/a.ppm"
printf 'P3\n4 2\n255\n255 0 0  0 10 0  0 0 0  0 0 0\n0 0 0  0 0 0  0 0 0  255 0 0\n' >"$tmp/b.ppm"
printf 'P3\n4 2\n255\n255 255 255  9 9 9  0 0 0  0 0 0\n0 0 0  0 0 0  0 0 0  0 0 0\n' >"$tmp/mask.ppm"
printf 'P3\n1 1\n255\n0 0 0\n' >"$tmp/one.ppm"
prints() { # prints NAME PATTERN... -- CMD...: exit 0 and every pattern on stdout
    local name=$1; shift
    local patterns=()
    while [ "$1" != "--" ]; do patterns+=("$1"); shift; done
    shift
    "$@" >"$tmp/out" 2>"$tmp/err"
    local code=$? p missing=
    for p in "${patterns[@]}"; do grep -qE "$p" "$tmp/out" || missing="$missing [$p]"; done
    if [ $code -eq 0 ] && [ -z "$missing" ]; then pass=$((pass + 1))
    else fail=$((fail + 1)); echo "FAIL $name: exit $code, missing$missing; stdout:"; cat "$tmp/out" "$tmp/err"; fi
}
ok "compare --help" "$bin" compare --help
status() { # status NAME CODE PATTERN CMD...: exit status CODE, stdout matches PATTERN
    local name=$1 want=$2 pattern=$3; shift 3
    "$@" >"$tmp/out" 2>"$tmp/err"
    local code=$?
    if [ $code -eq "$want" ] && grep -qE "$pattern" "$tmp/out"; then pass=$((pass + 1))
    else fail=$((fail + 1)); echo "FAIL $name: exit $code (want $want), stdout:"; cat "$tmp/out" "$tmp/err"; fi
}
# thresholds: 3 pixels of b differ from a by more than 9/255, 2 by more than 10/255
status "compare --warn: within" 0 '^result +PASS$' "$bin" compare "$tmp/a.ppm" "$tmp/b.ppm" --warn 1
status "compare --warn: over" 1 '^result +WARN$' "$bin" compare "$tmp/a.ppm" "$tmp/b.ppm" --warn 9/255
status "compare --fail: over" 3 '^result +FAIL$' "$bin" compare "$tmp/a.ppm" "$tmp/b.ppm" --warn 9/255 --fail 9/255
status "compare --fail-percent: 2 of 8 within 30%" 0 '^result +PASS$' \
    "$bin" compare "$tmp/a.ppm" "$tmp/b.ppm" --fail 10/255 --fail-percent 30
status "compare --fail-percent: 3 of 8 over 30%" 3 '^result +FAIL$' \
    "$bin" compare "$tmp/a.ppm" "$tmp/b.ppm" --fail 9/255 --fail-percent 30
status "compare --warn-percent" 0 '^result +PASS$' "$bin" compare "$tmp/a.ppm" "$tmp/b.ppm" --warn 0 --warn-percent 37.5
status "compare without limits prints no result" 0 '^over threshold' "$bin" compare "$tmp/a.ppm" "$tmp/b.ppm"
exits2 "compare bad --fail" "fail: expected" "$bin" compare "$tmp/a.ppm" "$tmp/b.ppm" --fail 2
exits2 "compare bad --warn-percent" "percent: 0..100" "$bin" compare "$tmp/a.ppm" "$tmp/b.ppm" --warn 0 --warn-percent 101
# --diff: 255 off is white, 10 off a dark blue (10/64 of the way to blue), equal is black
ok "compare --diff" bash -c "'$bin' compare '$tmp/a.ppm' '$tmp/b.ppm' --diff '$tmp/d.ppm' >/dev/null && \
    [ \"\$(tail -c 24 '$tmp/d.ppm' | od -An -tu1 | tr -s ' \n' ' ')\" = \
      ' 255 255 255 16 16 143 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 255 255 255 ' ]"
ok "compare --diff with a mask: black outside it" bash -c "'$bin' compare '$tmp/a.ppm' '$tmp/b.ppm' \
    --mask '$tmp/mask.ppm' --diff '$tmp/dm.ppm' >/dev/null && \
    [ \"\$(tail -c 24 '$tmp/dm.ppm' | od -An -tu1 | tr -s ' \n' ' ')\" = \
      ' 255 255 255 16 16 143 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 ' ]"
# alpha: a transparent black pixel differs from an opaque black one
oiiotool --pattern constant:color=0,0,0,1 4x2 4 -d uint8 -o "$tmp/opaque.png"
oiiotool --pattern constant:color=0,0,0,0 4x2 4 -d uint8 -o "$tmp/clear.png"
prints "compare alpha" '^channels +RGBA$' '^max diff +1\.000000' '^over threshold +1\.000000' -- \
    "$bin" compare "$tmp/opaque.png" "$tmp/clear.png"
prints "compare opaque images by RGB" '^channels +RGB$' '^psnr +inf' -- "$bin" compare "$tmp/opaque.png" "$tmp/a.ppm"
status "compare alpha --fail" 3 '^result +FAIL$' "$bin" compare "$tmp/opaque.png" "$tmp/clear.png" --fail 0
prints "compare identical" '^pixels +8$' '^rmse +0\.000000$' '^psnr +inf' '^max diff +0\.000000' \
    '^over threshold +0\.000000 \(0 pixels' -- "$bin" compare "$tmp/a.ppm" "$tmp/a.ppm"
prints "compare a render with itself (96x64)" '^psnr +inf' '^over threshold +0\.000000' '^pixels +6144$' -- \
    "$bin" compare "$tmp/default.png" "$tmp/default.png"
prints "compare different" '^pixels +8$' '^rmse +0\.288786$' '^psnr +10\.79 dB$' '^max diff +1\.000000 \(255/255\)$' \
    '^over threshold +0\.375000 \(3 pixels' -- "$bin" compare "$tmp/a.ppm" "$tmp/b.ppm"
prints "compare --threshold" '^over threshold +0\.250000 \(2 pixels' -- \
    "$bin" compare "$tmp/a.ppm" "$tmp/b.ppm" --threshold 10/255
prints "compare --threshold 0.05" '^over threshold +0\.250000' -- \
    "$bin" compare "$tmp/b.ppm" "$tmp/a.ppm" --threshold 0.05
prints "compare --mask" '^pixels +2$' '^rmse +0\.408562$' '^over threshold +1\.000000' -- \
    "$bin" compare --mask "$tmp/mask.ppm" "$tmp/a.ppm" "$tmp/b.ppm"
exits2 "compare missing file" "nope\.png" "$bin" compare "$tmp/a.ppm" "$tmp/nope.png"
exits2 "compare missing mask" "nomask\.png" "$bin" compare "$tmp/a.ppm" "$tmp/b.ppm" --mask "$tmp/nomask.png"
exits2 "compare sizes differ" "one\.ppm: 1x1, but .*a\.ppm is 4x2" "$bin" compare "$tmp/a.ppm" "$tmp/one.ppm"
exits2 "compare one image" "give two images" "$bin" compare "$tmp/a.ppm"
exits2 "compare three images" "more than two" "$bin" compare "$tmp/a.ppm" "$tmp/a.ppm" "$tmp/a.ppm"
exits2 "compare bad threshold" "threshold: expected" "$bin" compare "$tmp/a.ppm" "$tmp/b.ppm" --threshold 1.5
exits2 "compare empty mask" "selects no pixels" "$bin" compare "$tmp/a.ppm" "$tmp/b.ppm" --mask "$tmp/a.ppm"
exits2 "compare unknown option" "unknown option" "$bin" compare "$tmp/a.ppm" "$tmp/b.ppm" --frobnicate

echo "cli: $pass passed, $fail failed"
[ $fail -eq 0 ]
