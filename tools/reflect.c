/* reflect: the command-line face of reflect.h.

     reflect render [SCENE.glb | --builtin NAME] [options]   render one frame
     reflect info   [SCENE.glb | --builtin NAME]             describe a scene
     reflect compare A B [--mask M] [--threshold T] [--diff OUT] [--warn X] [--fail X]
                                                             image error of B against A
     reflect --help | reflect COMMAND --help

   Scenes come from glTF files (tools/gltf_load) or the built-in scenes;
   images go out through OpenImageIO (tools/image_io). The implementations
   come from tests/rast_impl.c and tests/reflect_impl.c (linked in by the
   Makefile). */
#define _POSIX_C_SOURCE 200809L
#include "../reflect.h"
#include "cli_options.h"
#include "gltf_load.h"
#include "image_io.h"
#include "reflect_bench.h"
#include "reflect_gl.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

static const char *const usage_main =
    "usage: reflect COMMAND [options]\n"
    "\n"
    "commands:\n"
    "  render   render one frame of a scene with one method to an image\n"
    "  info     list a scene's objects, materials, triangles and bounds\n"
    "  compare  RMSE, PSNR and pixels over a threshold between two images\n"
    "  bench    every method x scene x setting: times, errors, CSV and charts\n"
    "           (bench --gl: the GL path's projection rates and frames, docs/gl.md)\n"
    "  path     every method along a camera path: error, time and flicker per frame\n"
    "\n"
    "'reflect COMMAND --help' describes each command; 'reflect --version' prints\n"
    "the version.\n";

static const char *const usage_render =
    "usage: reflect render [SCENE.glb | --builtin NAME] [options]\n"
    "\n"
    "  --builtin NAME     a built-in scene: default, mirror-room, concave, glass, maze, teapots,\n"
    "                     hybrid\n"
    "  --method M         direct, raytrace (the reference), envmap, planar, c3rc, sbc, spoc,\n"
    "                     graphcam, layered-em (paper 001, layered shells) or auto (per\n"
    "                     reflector, the cheapest predicted to meet --error-budget)\n"
    "                     (in any case)\n"
    "  --depth N          reflection / refraction bounces (default 6)\n"
    "  --spp N            samples per pixel, a square 1..64 (default 1): each pixel the\n"
    "                     mean of sqrt(N) x sqrt(N) samples\n"
    "  --gl               draw through GL (headless EGL, docs/gl.md): PLANAR, C3RC, SBC,\n"
    "                     SPOC or GRAPHCAM, one bounce; LAYERED_EM at its defaults\n"
    "  --shadows          hard shadows from every light\n"
    "  --soft-shadows N   soft shadows: N samples of every light (with --shadows)\n"
    "  --light-radius R   give every light this radius (directional: radians)\n"
    "  --fresnel MIN,MAX  every mirror's reflection weighted by MAX - (MAX - MIN) cos^2\n"
    "                     of the incidence (paper 003's Fresnel blend; each in 0..1)\n"
    "  --fade D,MIN,MAX   every mirror's reflection faded from MAX to MIN, quadratically\n"
    "                     in its distance up to D (paper 003's attenuation; PLANAR: none)\n"
    "  --envmap-size N    ENVMAP cube face size in pixels, 1..2048 (default 256)\n"
    "  --no-culling       PLANAR: render every mirror at every level (paper 002's count)\n"
    "  --max-renderings N PLANAR: mirror renderings per frame at most (default 256);\n"
    "                     the mirrors past them are ray traced\n"
    "  --light-volumes    PLANAR, RAYTRACE: light reflected by planar mirrors lights the scene\n"
    "  --caustics N       with --light-volumes: N samples of every light with a radius\n"
    "  --translucency K   PLANAR, RAYTRACE: glass fogged by exp(-K distance) behind it\n"
    "  --density D        C3RC: points per unit area (default: one per 2x2 pixels\n"
    "                     at the reflectors' distance)\n"
    "  --leaf-points N    C3RC: kd-tree leaf size (default 1000)\n"
    "  --max-splat N      C3RC: largest splat side in pixels, 1..64 (default 8)\n"
    "  --camera-split PX  C3RC: split a triangle's camera while its estimated error\n"
    "                     exceeds PX pixels (default 0.1; -1: one camera per triangle)\n"
    "  --error-px E       SBC: largest camera error in pixels (default 1)\n"
    "  --ray-factor F     SBC: one reflected ray per F x F pixels, 1..64 (default 2)\n"
    "  --spoc-size N      SPOC: impostor size in texels, 8..4096 (default 512)\n"
    "  --spoc-strength K  SPOC: the push, 0..64 (default 1; 0: a plain depth image)\n"
    "  --spoc-step S      SPOC: marching pieces per texel of a ray's projection,\n"
    "                     1/16..16 (default 1)\n"
    "  --spoc-layers N    SPOC: impostor depth layers, 1..4 (default 3)\n"
    "  --spoc-glass G     SPOC: glass traced (default: RAYTRACE's tracer), estimate\n"
    "                     (the paper's: the exit from the back faces' depth and\n"
    "                     normals) or exact (the exit on the mesh)\n"
    "  --trace-fallback   SBC: ray trace the reflector pixels nothing was drawn on,\n"
    "                     and those whose point the ray map's samples contradict\n"
    "  --greedy           RAYTRACE: paper 001's two greedy ray paths through glass\n"
    "                     instead of the full ray tree\n"
    "  --unpruned         RAYTRACE: every branch of the ray tree to --depth (default:\n"
    "                     a branch under 1/1024 of the pixel's weight stops)\n"
    "  --lem-samples N    LAYERED_EM: viewpoint samples on the circle around each lens,\n"
    "                     1..3600 (default 45)\n"
    "  --lem-layers N     LAYERED_EM: environment layers per lens, 1..4 (default 1)\n"
    "  --lem-shell K      LAYERED_EM: every layer's shell, auto (per layer, from its\n"
    "                     hits), sphere, cylinder, box or quad (inner layers; the\n"
    "                     outermost auto's closed kind) (default auto)\n"
    "  --lem-frame F      LAYERED_EM: box and cylinder shells on the world axes, on\n"
    "                     the frame fitted to the layer's hits, or auto (both,\n"
    "                     chosen per layer): world, fitted or auto (default auto)\n"
    "  --lem-direct 0|1   LAYERED_EM: direct images (--lem-direct-from) against\n"
    "                     disocclusion, off or on (default on)\n"
    "  --lem-direct-from F  LAYERED_EM: direct images from the lens's centre, the\n"
    "                     viewpoint (the sample's views without the lens) or by\n"
    "                     material (the viewpoint for glass, the centre for mirrors):\n"
    "                     centre, viewpoint or material (default centre)\n"
    "  --lem-direct-conf C  LAYERED_EM: a direct image's pixel weighed by how little\n"
    "                     the lens images' rows cover its texels, or by its hit's\n"
    "                     distance from theirs: coverage or distance (default coverage)\n"
    "  --lem-lens-layers 0|1  LAYERED_EM: another lens a lens's path meets, traced\n"
    "                     (0) or a layer of the lens's environment (1) (default 0)\n"
    "  --lem-continue 0|1  LAYERED_EM: a sample's eye ray meeting something before\n"
    "                     the lens continued through it, so hidden parts of the lens\n"
    "                     give records too, off or on (default on)\n"
    "  --lem-share 0|1    LAYERED_EM: the lenses share their outermost layer, one\n"
    "                     map per sample solved from every lens's rows, off or on\n"
    "                     (default off)\n"
    "  --lem-edge PX      LAYERED_EM: the tessellation's t, edges split until they\n"
    "                     project under PX pixels, 0.05..1000 (default 1)\n"
    "  --prebuild         LAYERED_EM: infer every viewpoint sample's map first (with\n"
    "                     progress), then render the frame from them\n"
    "  --frames N         render the frame N times with one renderer, 1..1000, and\n"
    "                     keep (and report) the last: a kept renderer's frame\n"
    "  --sbc-paper        SBC: the paper's method, no search of the scene (heads where\n"
    "                     the rays leave its box); default: SBC-traced, every ray map\n"
    "                     sample traced against the scene's BVH\n"
    "  --graphcam-size N  GRAPHCAM: the impostor's width, 16..8192 (the maze's graph camera:\n"
    "                     default 1920 x 1176; other scenes: one frustum, the view's own\n"
    "                     pinhole, default twice the frame's width)\n"
    "  --graphcam-alg A   GRAPHCAM: segments (the paper's algorithm 2, default) or\n"
    "                     uniform (algorithm 1)\n"
    "  --graphcam-step S  GRAPHCAM: segments: pixels a step (default 1); uniform: world\n"
    "                     units a step (default: the camera's bounds' diagonal / 2048)\n"
    "  --error-budget PX  AUTO: the reflection error in pixels a method may be predicted\n"
    "                     to make (default 1); --stats prints each reflector's choice\n"
    "  --auto-models FILE AUTO: cost and error models (reflect bench --fit-auto writes\n"
    "                     them; default: those built in)\n"
    "  --size WxH         image size (default: the scene camera's, else 640x480)\n"
    "  --eye X,Y,Z        camera position     } default: the scene's camera,\n"
    "  --target X,Y,Z     point looked at     } else one framing the scene\n"
    "  --up X,Y,Z         up direction (default 0,1,0)\n"
    "  --fov DEGREES      vertical field of view (default 45)\n"
    "  --camera N         the glTF file's N-th perspective camera, 0 first (reflect info\n"
    "                     counts them)\n"
    "  --env FILE         environment: an equirectangular image, or a pattern\n"
    "                     with %s for six faces px nx py ny pz nz\n"
    "  --normalize SIZE   scale a glTF scene to this bounding-box diagonal\n"
    "  --tess N           teapot patches N x N for built-in scenes (default 8)\n"
    "  --threads N        worker threads (default: one per CPU)\n"
    "  --time-limit S     stop a render still running after S seconds (checked between\n"
    "                     phases, reflector methods and bands of traced rows); exit 1\n"
    "  --out FILE         output image, format by extension (default out.png): 8-bit\n"
    "                     formats (PNG ...) sRGB-encoded; EXR, HDR and PFM linear, unclamped\n"
    "  --exposure EV      scale the colours by 2^EV before writing, -64..64 (default 0)\n"
    "  --tonemap T        8-bit output: clamp (default), reinhard or aces\n"
    "  --mirror NAME      make the objects named NAME (or of the material NAME) mirrors;\n"
    "                     repeatable\n"
    "  --glass NAME       likewise glass (index 1.5)\n"
    "  --stats            print timings and model sizes\n"
    "\n"
    "Options take their value as the next argument or after '=' (--size=640x480).\n"
    "Exit status: 0 the image was written; 1 the scene could not be loaded, rendered\n"
    "or written; 2 bad usage.\n";

static const char *const usage_info =
    "usage: reflect info [SCENE.glb | --builtin NAME] [--normalize SIZE] [--tess N] [--camera N]\n"
    "\n"
    "Prints the objects (mesh, triangles, material), the materials, the\n"
    "lights, the camera and the scene's bounds.\n";

static const char *const usage_compare =
    "usage: reflect compare A B [--mask M] [--threshold T] [--diff OUT]\n"
    "                           [--warn X [--warn-percent P]] [--fail X [--fail-percent P]]\n"
    "\n"
    "Compares two images of one size by their channels as stored in 8 bits:\n"
    "R, G and B, and alpha too when either image has a pixel that is not\n"
    "opaque (a transparent pixel differs from an opaque one of its colour).\n"
    "Prints the channels and pixels compared, the RMSE and the largest\n"
    "difference (in channel units, 0..1), the PSNR (dB; inf when identical)\n"
    "and the fraction of pixels with a channel differing by more than the\n"
    "threshold; with --warn or --fail, a last line: result PASS, WARN or FAIL.\n"
    "\n"
    "Exit status (as idiff's, where this command's usage errors keep 2):\n"
    "  0  compared, and within --warn and --fail\n"
    "  1  over the --warn limit, within --fail\n"
    "  2  bad usage, or an unreadable or mismatched image\n"
    "  3  over the --fail limit\n"
    "\n"
    "  --mask M           compare only the pixels where M (same size) is not black\n"
    "  --threshold T      per channel, 0..1 or a fraction like 4/255 (default\n"
    "                     2/255); 0 counts any difference\n"
    "  --diff OUT         write a heat map of the difference: per pixel the largest\n"
    "                     channel difference, black (0) through blue, red and\n"
    "                     yellow to white (64/255 or more); outside --mask, black\n"
    "  --warn X           warn when more than --warn-percent of the pixels (default\n"
    "                     0: any) have a channel differing by more than X (0..1 or N/255)\n"
    "  --fail X           fail likewise, beyond --fail-percent (default 0)\n"
    "  --warn-percent P, --fail-percent P   0..100\n";

typedef struct options {
    const char *file, *builtin, *method, *env, *out;
    int width, height, threads, tess, stats, depth, shadows, envmap_size, no_culling, soft_samples;
    int light_volumes, caustic_samples, max_renderings, spp;
    float translucency;
    int leaf_points, max_splat, ray_factor, trace_fallback, sbc_paper, greedy, unpruned, prebuild, lem_samples, lem_layers;
    float lem_edge;
    int lem_shell;                /* --lem-shell */
    int lem_direct;               /* --lem-direct: -1 off, 1 on, 0 unset */
    int lem_lens_layers;          /* --lem-lens-layers: -1 traced, 1 layers, 0 unset */
    int lem_continue;             /* --lem-continue: -1 off, 1 on, 0 unset */
    int lem_share;                /* --lem-share: -1 off, 1 on, 0 unset */
    int lem_direct_from, lem_direct_conf; /* --lem-direct-from, --lem-direct-conf: 0 unset */
    int lem_frame;                /* --lem-frame */
    int frames;                   /* --frames */
    int graphcam_size, graphcam_alg;
    float graphcam_step;
    float density, camera_split, error_px;
    int spoc_size, spoc_layers;   /* --spoc-size, --spoc-layers, --spoc-strength (-1: unset), --spoc-step */
    int spoc_glass;               /* --spoc-glass: refl_spoc_glass */
    float spoc_strength, spoc_step;
    int has_eye, has_target, has_up;
    refl_vec3 eye, target, up;
    float fov, normalize, light_radius;
    refl_display_desc display; /* --exposure, --tonemap */
    const char *mirror[8], *glass[8]; /* --mirror, --glass */
    int mirror_count, glass_count;
    int gl;                       /* --gl: the GL path (tools/reflect_gl_frame.c) */
    int camera;                   /* --camera: which glTF camera */
    float time_limit;             /* --time-limit: seconds; 0 none */
    float error_budget;           /* --error-budget: AUTO's; 0: its default */
    const char *auto_models;      /* --auto-models FILE */
    float fresnel[2];             /* --fresnel: min, max; max 0: off */
    refl_vec3 fade;               /* --fade: distance, min, max; distance 0: off */
} options;

static int fail(const char *fmt, const char *arg) {
    fprintf(stderr, "reflect: ");
    fprintf(stderr, fmt, arg);
    fprintf(stderr, "\n");
    return 2;
}

static int parse_vec3(const char *s, refl_vec3 *v) {
    char extra;
    return sscanf(s, "%f,%f,%f%c", &v->x, &v->y, &v->z, &extra) == 3 && isfinite(v->x) &&
           isfinite(v->y) && isfinite(v->z);
}

static int parse_int(const char *s, int lo, int hi, int *out) {
    char *end;
    long v = strtol(s, &end, 10);
    if (*s == '\0' || *end != '\0' || v < lo || v > hi) return 0;
    *out = (int)v;
    return 1;
}

/* "0" or "1" into an option's -1 (off) or 1 (on); its 0 stays "the default" */
static int parse_on_off(const char *s, int *out) {
    int on;
    if (!parse_int(s, 0, 1, &on)) return 0;
    *out = on ? 1 : -1;
    return 1;
}

static int parse_float(const char *s, float lo, float hi, float *out) {
    char *end;
    float v = (float)strtod(s, &end); /* compared as floats: "0.001" is 1e-3f */
    if (*s == '\0' || *end != '\0' || !(v >= lo && v <= hi)) return 0;
    *out = v;
    return 1;
}

/* The options that take a value, and those that do not. */
static const char *const value_options[] = {
    "--builtin", "--normalize", "--tess", "--method", "--size", "--eye", "--target", "--up", "--fov", "--env",
    "--threads", "--out", "--depth", "--spp", "--soft-shadows", "--caustics", "--translucency", "--light-radius",
    "--fresnel", "--fade", "--max-renderings", "--envmap-size", "--density", "--leaf-points", "--camera-split",
    "--error-px", "--ray-factor", "--max-splat", "--exposure", "--tonemap", "--mirror", "--glass", "--camera", "--time-limit",
    "--graphcam-size", "--graphcam-alg", "--graphcam-step", "--spoc-size", "--spoc-layers", "--spoc-glass", "--spoc-strength", "--spoc-step", "--lem-samples", "--lem-layers", "--lem-edge", "--lem-shell", "--lem-frame", "--lem-direct", "--lem-lens-layers", "--lem-continue", "--lem-share", "--lem-direct-from", "--lem-direct-conf", "--frames",
    "--error-budget", "--auto-models", NULL};
static const char *const flag_options[] = {"--help", "-h", "--stats", "--shadows", "--no-culling",
                                           "--light-volumes", "--trace-fallback", "--gl", "--sbc-paper",
                                           "--greedy", "--unpruned", "--prebuild", NULL};

static int listed(const char *const *names, const char *a) {
    for (; *names; ++names)
        if (!strcmp(*names, a)) return 1;
    return 0;
}

/* the value options seen fit cli_given_twice's mask */
typedef char value_options_fit_a_mask[sizeof value_options / sizeof *value_options <= 65 ? 1 : -1];

/* The options whose value is one of a few names (parse_choice). */
static const cli_choice tonemaps[] = {
    {"clamp", REFL_TONEMAP_CLAMP}, {"reinhard", REFL_TONEMAP_REINHARD}, {"aces", REFL_TONEMAP_ACES}, {NULL, 0}};
static const cli_choice lem_direct_froms[] = {{"centre", REFL_LEM_DIRECT_FROM_CENTRE},
                                              {"viewpoint", REFL_LEM_DIRECT_FROM_VIEWPOINT},
                                              {"material", REFL_LEM_DIRECT_FROM_MATERIAL},
                                              {NULL, 0}};
static const cli_choice lem_direct_confs[] = {
    {"coverage", REFL_LEM_DIRECT_COVERAGE}, {"distance", REFL_LEM_DIRECT_DISTANCE}, {NULL, 0}};
static const cli_choice lem_frames[] = {
    {"auto", REFL_LEM_FRAME_AUTO}, {"world", REFL_LEM_FRAME_WORLD}, {"fitted", REFL_LEM_FRAME_FITTED}, {NULL, 0}};
static const cli_choice lem_shells[] = {{"auto", REFL_LEM_SHELL_AUTO},
                                        {"sphere", REFL_LEM_SHELL_SPHERE},
                                        {"cylinder", REFL_LEM_SHELL_CYLINDER},
                                        {"box", REFL_LEM_SHELL_BOX},
                                        {"quad", REFL_LEM_SHELL_QUAD},
                                        {NULL, 0}};
static const cli_choice spoc_glasses[] = {{"traced", REFL_SPOC_GLASS_TRACED},
                                          {"estimate", REFL_SPOC_GLASS_ESTIMATE},
                                          {"exact", REFL_SPOC_GLASS_EXACT_EXIT},
                                          {NULL, 0}};
static const cli_choice graphcam_algs[] = {
    {"segments", REFL_GRAPHCAM_SEGMENTS}, {"uniform", REFL_GRAPHCAM_UNIFORM}, {NULL, 0}};

/* Parses argv[2..]; returns 0, 1 after --help, or 2 after an error. */
static int parse(int argc, char **argv, int is_render, options *o) {
    int i;
    unsigned long long given = 0; /* the value options seen (cli_given_twice) */
    int choice;
    memset(o, 0, sizeof(*o));
    o->out = "out.png";
    o->spoc_strength = -1.0f;
    for (i = 2; i < argc; ++i) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL, *eq = strchr(a, '=');
        char name[32];
        int inline_value = a[0] == '-' && a[1] == '-' && eq && eq - a < (long)sizeof name;
        if (inline_value) { /* --name=value */
            memcpy(name, a, (size_t)(eq - a));
            name[eq - a] = '\0';
            a = name;
            v = eq + 1;
        }
        if (a[0] == '-' && a[1]) {
            if (listed(flag_options, a)) {
                if (inline_value) return fail("%s takes no value", a);
            } else if (!listed(value_options, a)) {
                return fail(is_render ? "render: unknown option %s (see reflect render --help)"
                                      : "info: unknown option %s (see reflect info --help)", a);
            } else if (!v) {
                return fail("%s needs a value", a);
            } else if (strcmp(a, "--mirror") && strcmp(a, "--glass") &&
                       cli_given_twice("reflect", value_options, a, &given)) {
                return 2;
            }
        }
        if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
            fputs(is_render ? usage_render : usage_info, stdout);
            return 1;
        } else if (!strcmp(a, "--builtin")) {
            o->builtin = v;
        } else if (!strcmp(a, "--normalize")) {
            if (!parse_float(v, 1e-6f, 1e9f, &o->normalize)) return fail("--normalize: not a positive size: %s", v);
        } else if (!strcmp(a, "--tess")) {
            if (!parse_int(v, 1, 64, &o->tess)) return fail("--tess: expected 1..64, got %s", v);
        } else if (!strcmp(a, "--camera")) {
            if (!parse_int(v, 0, 1 << 20, &o->camera)) return fail("--camera: expected a camera number 0.., got %s", v);
        } else if (!is_render) {
            if (a[0] == '-') return fail("info: unknown option %s (see reflect info --help)", a);
            if (o->file) return fail("info: more than one scene given (%s)", a);
            o->file = a;
            continue;
        } else if (!strcmp(a, "--method")) {
            refl_method m = refl_method_from_name(v);
            if (!m || !refl_method_is_built(m)) {
                fprintf(stderr, "reflect: --method: %s '%s'; the methods are:", m ? "not built yet:" : "no method", v);
                for (m = (refl_method)1; m < REFL_METHOD_COUNT; m = (refl_method)(m + 1))
                    if (refl_method_is_built(m)) fprintf(stderr, " %s", refl_method_name(m));
                fprintf(stderr, "\n");
                return 2;
            }
            o->method = v;
        } else if (!strcmp(a, "--time-limit")) {
            if (!parse_float(v, 1e-3f, 1e6f, &o->time_limit)) return fail("--time-limit: expected seconds 0.001..1e6, got %s", v);
        } else if (!strcmp(a, "--mirror") || !strcmp(a, "--glass")) {
            int glass = !strcmp(a, "--glass"), *count = glass ? &o->glass_count : &o->mirror_count;
            if (*count == 8) return fail("%s: at most 8 times", a);
            (glass ? o->glass : o->mirror)[(*count)++] = v;
        } else if (!strcmp(a, "--size")) {
            char *x = strchr(v, 'x'), w[16];
            if (!x || x - v >= (long)sizeof w) return fail("--size: expected WxH, each 1..16384, got %s", v);
            memcpy(w, v, (size_t)(x - v));
            w[x - v] = '\0';
            if (!parse_int(w, 1, RAST_MAX_TARGET_SIZE, &o->width) || !parse_int(x + 1, 1, RAST_MAX_TARGET_SIZE, &o->height))
                return fail("--size: expected WxH, each 1..16384, got %s", v);
        } else if (!strcmp(a, "--eye")) {
            if (!(o->has_eye = parse_vec3(v, &o->eye))) return fail("--eye: expected X,Y,Z, got %s", v);
        } else if (!strcmp(a, "--target")) {
            if (!(o->has_target = parse_vec3(v, &o->target))) return fail("--target: expected X,Y,Z, got %s", v);
        } else if (!strcmp(a, "--up")) {
            if (!(o->has_up = parse_vec3(v, &o->up))) return fail("--up: expected X,Y,Z, got %s", v);
        } else if (!strcmp(a, "--fov")) {
            if (!parse_float(v, 1.0f, 179.0f, &o->fov)) return fail("--fov: expected 1..179 degrees, got %s", v);
        } else if (!strcmp(a, "--env")) {
            o->env = v;
        } else if (!strcmp(a, "--threads")) {
            if (!parse_int(v, 1, RAST_MAX_THREADS, &o->threads)) return fail("--threads: expected 1..64, got %s", v);
        } else if (!strcmp(a, "--exposure")) {
            if (!parse_float(v, -64.0f, 64.0f, &o->display.exposure)) return fail("--exposure: expected -64..64 stops, got %s", v);
        } else if (!strcmp(a, "--tonemap")) {
            if (!parse_choice("reflect", a, v, tonemaps, &choice)) return 2;
            o->display.tonemap = (refl_tonemap)choice;
        } else if (!strcmp(a, "--out")) {
            if (!*v) return fail("%s", "--out: expected a file name, got an empty one");
            o->out = v;
        } else if (!strcmp(a, "--depth")) {
            if (!parse_int(v, 1, 64, &o->depth)) return fail("--depth: expected 1..64, got %s", v);
        } else if (!strcmp(a, "--soft-shadows")) {
            if (!parse_int(v, 1, 1024, &o->soft_samples)) return fail("--soft-shadows: expected 1..1024, got %s", v);
        } else if (!strcmp(a, "--lem-samples")) {
            if (!parse_int(v, 1, 3600, &o->lem_samples)) return fail("--lem-samples: expected 1..3600, got %s", v);
        } else if (!strcmp(a, "--lem-layers")) {
            if (!parse_int(v, 1, 4, &o->lem_layers)) return fail("--lem-layers: expected 1..4, got %s", v);
        } else if (!strcmp(a, "--lem-direct")) {
            if (!parse_on_off(v, &o->lem_direct)) return fail("--lem-direct: expected 0 or 1, got %s", v);
        } else if (!strcmp(a, "--lem-direct-from")) {
            if (!parse_choice("reflect", a, v, lem_direct_froms, &o->lem_direct_from)) return 2;
        } else if (!strcmp(a, "--lem-direct-conf")) {
            if (!parse_choice("reflect", a, v, lem_direct_confs, &o->lem_direct_conf)) return 2;
        } else if (!strcmp(a, "--lem-lens-layers")) {
            if (!parse_on_off(v, &o->lem_lens_layers)) return fail("--lem-lens-layers: expected 0 or 1, got %s", v);
        } else if (!strcmp(a, "--lem-continue")) {
            if (!parse_on_off(v, &o->lem_continue)) return fail("--lem-continue: expected 0 or 1, got %s", v);
        } else if (!strcmp(a, "--lem-share")) {
            if (!parse_on_off(v, &o->lem_share)) return fail("--lem-share: expected 0 or 1, got %s", v);
        } else if (!strcmp(a, "--lem-frame")) {
            if (!parse_choice("reflect", a, v, lem_frames, &o->lem_frame)) return 2;
        } else if (!strcmp(a, "--lem-shell")) {
            if (!parse_choice("reflect", a, v, lem_shells, &o->lem_shell)) return 2;
        } else if (!strcmp(a, "--frames")) {
            if (!parse_int(v, 1, 1000, &o->frames)) return fail("--frames: expected 1..1000, got %s", v);
        } else if (!strcmp(a, "--lem-edge")) {
            if (!parse_float(v, 0.05f, 1000.0f, &o->lem_edge)) return fail("--lem-edge: expected 0.05..1000 pixels, got %s", v);
        } else if (!strcmp(a, "--caustics")) {
            if (!parse_int(v, 1, 1024, &o->caustic_samples)) return fail("--caustics: expected 1..1024, got %s", v);
        } else if (!strcmp(a, "--translucency")) {
            if (!parse_float(v, 0.0f, 1e6f, &o->translucency)) return fail("--translucency: not a density: %s", v);
        } else if (!strcmp(a, "--light-radius")) {
            if (!parse_float(v, 0.0f, 1e6f, &o->light_radius)) return fail("--light-radius: not a size: %s", v);
        } else if (!strcmp(a, "--fresnel")) {
            char extra;
            if (sscanf(v, "%f,%f%c", &o->fresnel[0], &o->fresnel[1], &extra) != 2 ||
                !(o->fresnel[0] >= 0.0f && o->fresnel[0] <= 1.0f && o->fresnel[1] > 0.0f && o->fresnel[1] <= 1.0f))
                return fail("--fresnel: expected MIN,MAX in 0..1 (MAX above 0), got %s", v);
        } else if (!strcmp(a, "--fade")) {
            if (!parse_vec3(v, &o->fade) || !(o->fade.x > 0.0f) || !(o->fade.y >= 0.0f && o->fade.y <= 1.0f) ||
                !(o->fade.z >= 0.0f && o->fade.z <= 1.0f))
                return fail("--fade: expected D,MIN,MAX (D above 0, MIN and MAX in 0..1), got %s", v);
        } else if (!strcmp(a, "--spp")) {
            if (!parse_int(v, 1, 64, &o->spp) || (int)sqrt((double)o->spp) * (int)sqrt((double)o->spp) != o->spp)
                return fail("--spp: expected a square 1..64 (1, 4, 9 ... 64), got %s", v);
        } else if (!strcmp(a, "--max-renderings")) {
            if (!parse_int(v, 1, 1 << 30, &o->max_renderings)) return fail("--max-renderings: expected 1..2^30, got %s", v);
        } else if (!strcmp(a, "--spoc-size")) {
            if (!parse_int(v, 8, 4096, &o->spoc_size)) return fail("--spoc-size: expected 8..4096, got %s", v);
        } else if (!strcmp(a, "--spoc-glass")) {
            if (!parse_choice("reflect", a, v, spoc_glasses, &o->spoc_glass)) return 2;
        } else if (!strcmp(a, "--spoc-layers")) {
            if (!parse_int(v, 1, 4, &o->spoc_layers)) return fail("--spoc-layers: expected 1..4, got %s", v);
        } else if (!strcmp(a, "--error-budget")) {
            if (!parse_float(v, 1e-6f, 1e6f, &o->error_budget)) return fail("--error-budget: expected pixels above 0, got %s", v);
        } else if (!strcmp(a, "--auto-models")) {
            o->auto_models = v;
        } else if (!strcmp(a, "--spoc-strength")) {
            if (!parse_float(v, 0.0f, 64.0f, &o->spoc_strength)) return fail("--spoc-strength: expected 0..64, got %s", v);
        } else if (!strcmp(a, "--spoc-step")) {
            if (!parse_float(v, 0.0625f, 16.0f, &o->spoc_step)) return fail("--spoc-step: expected 0.0625..16, got %s", v);
        } else if (!strcmp(a, "--envmap-size")) {
            if (!parse_int(v, 1, 2048, &o->envmap_size)) return fail("--envmap-size: expected 1..2048, got %s", v);
        } else if (!strcmp(a, "--density")) {
            if (!parse_float(v, 1e-9f, 1e9f, &o->density)) return fail("--density: not a positive density: %s", v);
        } else if (!strcmp(a, "--leaf-points")) {
            if (!parse_int(v, 1, 1 << 24, &o->leaf_points)) return fail("--leaf-points: expected 1..16777216, got %s", v);
        } else if (!strcmp(a, "--graphcam-size")) {
            if (!parse_int(v, 16, 8192, &o->graphcam_size)) return fail("--graphcam-size: expected 16..8192, got %s", v);
        } else if (!strcmp(a, "--graphcam-alg")) {
            if (!parse_choice("reflect", a, v, graphcam_algs, &o->graphcam_alg)) return 2;
        } else if (!strcmp(a, "--graphcam-step")) {
            if (!parse_float(v, 0.0f, 1e6f, &o->graphcam_step)) return fail("--graphcam-step: expected 0..1e6, got %s", v);
        } else if (!strcmp(a, "--camera-split")) {
            if (!parse_float(v, -1.0f, 1e6f, &o->camera_split)) return fail("--camera-split: expected -1..1e6, got %s", v);
        } else if (!strcmp(a, "--error-px")) {
            if (!parse_float(v, 1e-3f, 1e6f, &o->error_px)) return fail("--error-px: expected 0.001..1e6, got %s", v);
        } else if (!strcmp(a, "--ray-factor")) {
            if (!parse_int(v, 1, 64, &o->ray_factor)) return fail("--ray-factor: expected 1..64, got %s", v);
        } else if (!strcmp(a, "--max-splat")) {
            if (!parse_int(v, 1, 64, &o->max_splat)) return fail("--max-splat: expected 1..64, got %s", v);
        } else if (!strcmp(a, "--stats")) {
            o->stats = 1;
            continue;
        } else if (!strcmp(a, "--shadows")) {
            o->shadows = 1;
            continue;
        } else if (!strcmp(a, "--no-culling")) {
            o->no_culling = 1;
            continue;
        } else if (!strcmp(a, "--light-volumes")) {
            o->light_volumes = 1;
            continue;
        } else if (!strcmp(a, "--trace-fallback")) {
            o->trace_fallback = 1;
            continue;
        } else if (!strcmp(a, "--gl")) {
            o->gl = 1;
            continue;
        } else if (!strcmp(a, "--sbc-paper")) {
            o->sbc_paper = 1;
            continue;
        } else if (!strcmp(a, "--greedy")) {
            o->greedy = 1;
            continue;
        } else if (!strcmp(a, "--unpruned")) {
            o->unpruned = 1;
            continue;
        } else if (!strcmp(a, "--prebuild")) {
            o->prebuild = 1;
            continue;
        } else {
            if (o->file) return fail("render: more than one scene given (%s)", a);
            o->file = a;
            continue;
        }
        if (!inline_value) ++i; /* the option's value */
    }
    if (!o->file == !o->builtin) return fail("%s", "give one scene: a glTF file or --builtin NAME");
    return 0;
}

/* Loads the scene the options name; prints why not and returns NULL. */
static refl_scene *load_scene(const options *o, int *camera_count) {
    refl_scene *s = NULL;
    refl_result r;
    char err[1024] = "";
    const char *line;
    if (o->builtin) {
        refl_builtin_desc bd;
        memset(&bd, 0, sizeof bd);
        bd.teapot_tess = o->tess;
        r = refl_scene_builtin(o->builtin, &bd, &s);
        if (r == REFL_ERROR_UNKNOWN_NAME) {
            const char *const *n = refl_builtin_names();
            fprintf(stderr, "reflect: no built-in scene '%s'; there are:", o->builtin);
            for (; *n; ++n) fprintf(stderr, " %s", *n);
            fprintf(stderr, "\n");
            return NULL;
        }
        if (r != REFL_OK) {
            fprintf(stderr, "reflect: built-in scene '%s': %s\n", o->builtin, refl_result_string(r));
            return NULL;
        }
        if (o->normalize > 0.0f) refl_scene_normalize(s, o->normalize);
        if (o->camera > 0) {
            fprintf(stderr, "reflect: --camera %d: a built-in scene has one camera (0)\n", o->camera);
            refl_scene_destroy(s);
            return NULL;
        }
        if (camera_count) *camera_count = 1;
        return s;
    } else {
        refl_gltf_options go;
        memset(&go, 0, sizeof go);
        go.normalize_size = o->normalize;
        go.camera = o->camera;
        go.camera_count = camera_count;
        r = refl_gltf_load(o->file, &go, &s, err, sizeof err);
        if (r != REFL_OK) {
            fprintf(stderr, "reflect: %s\n", err[0] ? err : refl_result_string(r));
            return NULL;
        }
        for (line = err; *line;) { /* one warning per line */
            size_t n = strcspn(line, "\n");
            fprintf(stderr, "reflect: warning: %.*s\n", (int)n, line);
            line += n + (line[n] == '\n');
        }
    }
    return s;
}

/* The render's progress callback: a bar on a terminal, and the stop at
   --time-limit. */
typedef struct progress_state {
    int bar;
    double start_ms, limit_ms; /* limit 0: none */
    int stopped;
} progress_state;

static int progress(void *user, float done) {
    progress_state *ps = (progress_state *)user;
    if (ps->bar) {
        int i, n = (int)(done * 30.0f + 0.5f);
        fprintf(stderr, "\r[");
        for (i = 0; i < 30; ++i) fputc(i < n ? '#' : ' ', stderr);
        fprintf(stderr, "] %3d%%%s", (int)(done * 100.0f + 0.5f), done >= 1.0f ? "\n" : "");
        fflush(stderr);
    }
    if (ps->limit_ms > 0.0 && refl_bench_now_ms() - ps->start_ms > ps->limit_ms) {
        if (ps->bar) fputc('\n', stderr);
        ps->stopped = 1;
    }
    return ps->stopped;
}

/* --prebuild and --frames: one renderer, its maps built ahead (LAYERED_EM;
   the prebuild's time and maps printed with --stats), then the frame
   rendered `frames` times, the last one kept. */
static refl_result render_kept(const refl_scene *s, const refl_view *v, const refl_render_desc *d, refl_frame *f,
                               int prebuild, int frames, int stats) {
    refl_renderer *rr = NULL;
    refl_result r = refl_renderer_create(s, d, &rr);
    int k;
    if (r != REFL_OK) return r;
    if (prebuild) r = refl_renderer_prebuild(rr, v, f);
    if (r == REFL_OK && prebuild && stats)
        printf("prebuild ms  %.2f (%d maps inferred)\n", f->stats.ms_total, f->stats.layered_em.maps_inferred);
    for (k = 0; k < frames && r == REFL_OK; ++k) r = refl_renderer_render(rr, v, f);
    refl_renderer_destroy(rr);
    return r;
}

/* --mirror and --glass: the objects named `name`, or whose material is,
   get a mirror (glass) material. Returns 0 when nothing has that name. */
static int override_material(refl_scene *s, const char *name, int glass) {
    refl_material m = glass ? refl_material_glass(1.5f) : refl_material_mirror(1.0f);
    int i, id = -1, found = 0;
    for (i = 0; i < s->object_count; ++i) {
        refl_object *o = &s->objects[i];
        if (strcmp(o->name, name) && strcmp(s->materials[o->material].name, name)) continue;
        if (id < 0) {
            snprintf(m.name, sizeof m.name, "%s", glass ? "--glass" : "--mirror");
            if ((id = refl_scene_add_material(s, &m)) < 0) return 0;
        }
        o->material = id;
        found = 1;
    }
    if (found) refl_scene_touch(s);
    return found;
}

/* Whether a file name asks for a float format (linear, unclamped). */
static int is_float_format(const char *path) {
    static const char *const exts[] = {".exr", ".hdr", ".pfm"};
    size_t n = strlen(path), k;
    for (k = 0; k < 3; ++k)
        if (n >= 4 && !strcasecmp(path + n - 4, exts[k])) return 1;
    return 0;
}

/* The frame written in the format the extension names: float formats get
   the linear colours times 2^exposure, 8-bit ones the display colours
   (refl_frame_to_srgb8: exposure, tone map, sRGB). */
static refl_result write_frame(const char *path, const refl_frame *f, const refl_display_desc *d, char *err,
                               size_t err_size) {
    size_t i, n = (size_t)f->width * (size_t)f->height * 4;
    refl_result r;
    err[0] = '\0';
    if (is_float_format(path)) {
        float *rgbaf = (float *)malloc(n * sizeof(float)), scale = exp2f(d->exposure);
        if (!rgbaf) return REFL_ERROR_OUT_OF_MEMORY;
        for (i = 0; i < n; ++i) rgbaf[i] = i % 4 == 3 ? f->rgba[i] : f->rgba[i] * scale;
        r = refl_image_write(path, f->width, f->height, 4, NULL, rgbaf, err, err_size);
        free(rgbaf);
    } else { /* RGB: the frame is opaque, and PPM or JPEG hold no alpha */
        uint8_t *rgba8 = (uint8_t *)malloc(n);
        if (!rgba8) return REFL_ERROR_OUT_OF_MEMORY;
        refl_frame_to_srgb8(f, d, rgba8);
        for (i = 0; i < n / 4; ++i) memmove(rgba8 + 3 * i, rgba8 + 4 * i, 3);
        r = refl_image_write(path, f->width, f->height, 3, rgba8, NULL, err, err_size);
        free(rgba8);
    }
    return r;
}

/* --gl: PLANAR, C3RC, SBC, SPOC or GRAPHCAM (through gc, NULL: the view's
   pinhole) through the GL host (one bounce), or LAYERED_EM (its
   defaults), written as any frame is. */
static int render_gl(const options *o, const refl_scene *s, const refl_view *v, refl_method m,
                     const refl_graphcam *gc) {
    rgl_context *g = NULL;
    refl_frame *f = NULL;
    rgl_frame_stats st;
    size_t i, n = (size_t)v->width * (size_t)v->height;
    float *rgb = NULL;
    char err[1024];
    int code = 1;
    if (m != REFL_PLANAR && m != REFL_C3RC && m != REFL_SBC && m != REFL_SPOC && m != REFL_GRAPHCAM &&
        m != REFL_LAYERED_EM) {
        fprintf(stderr, "reflect: --gl draws PLANAR, C3RC, SBC, SPOC, GRAPHCAM and LAYERED_EM only"
                        " (--method planar, c3rc, sbc, spoc, graphcam or layered-em)\n");
        return 2;
    }
    if (rgl_create(&g, err, sizeof err) != 0) {
        fprintf(stderr, "reflect: --gl: no GL context: %s\n", err);
        return 1;
    }
    rgb = (float *)malloc(n * 3 * sizeof(float));
    if (!rgb || refl_frame_create(v->width, v->height, NULL, &f) != REFL_OK) {
        fprintf(stderr, "reflect: out of memory\n");
        goto out;
    }
    if ((m == REFL_GRAPHCAM ? rgl_render_graphcam(g, s, v, gc, f, rgb, &st, err, sizeof err)
                            : rgl_render(g, m, s, v, f, rgb, &st, err, sizeof err)) != 0) {
        fprintf(stderr, "reflect: --gl: %s\n", err);
        goto out;
    }
    for (i = 0; i < n; ++i) {
        memcpy(f->rgba + 4 * i, rgb + 3 * i, 3 * sizeof(float));
        f->rgba[4 * i + 3] = 1.0f;
    }
    if (write_frame(o->out, f, &o->display, err, sizeof err) != REFL_OK) {
        fprintf(stderr, "reflect: %s\n", err);
        goto out;
    }
    if (o->stats)
        printf("method       %s (GL path, %s)\nrenderer     %s\nsize         %dx%d\n%s %d\n"
               "GL vertices  %lld\nGL ms        %.2f\nCPU ms       %.2f\n",
               refl_method_name(m), m == REFL_LAYERED_EM ? "its defaults" : "one bounce", rgl_renderer(g), v->width,
               v->height,
               m == REFL_PLANAR ? "mirrors     " : m == REFL_C3RC ? "cameras     " : m == REFL_SPOC ? "impostors   " : m == REFL_GRAPHCAM ? "frusta      " : m == REFL_LAYERED_EM ? "lenses      " : "reflectors  ", st.mirrors,
               st.vertices, 1e3 * st.gl_seconds, 1e3 * st.shade_seconds);
    if (o->stats && (m == REFL_SPOC || m == REFL_GRAPHCAM))
        printf("steps        %lld\nray traced   %lld pixel(s) the impostor could not answer\n", st.projections, st.traced);
    code = 0;
out:
    free(rgb);
    refl_frame_destroy(f);
    rgl_destroy(g);
    return code;
}

/* AUTO's choices, one line a reflector: the features, the method and its
   predictions, and the cheaper methods it passed over and why. */
static void print_auto_choices(const refl_scene *s, const refl_auto_frame_stats *a) {
    int i, m;
    if (a->count) printf("auto         budget %g px; per reflector: class, pixels, nearness, beyond -> choice\n", (double)a->budget_px);
    for (i = 0; i < a->count && i < REFL_AUTO_MAX_CHOICES; ++i) {
        const refl_auto_choice *c = &a->choices[i];
        int first = 1;
        printf("  %-10.32s %s, %lld px, near %.2f, beyond %.2f -> %s (%.2f px, %.1f ms%s)", s->objects[c->object].name,
               refl_auto_class_name(c->features.reflector_class), c->features.pixels, (double)c->features.nearness,
               (double)c->features.beyond,
               refl_method_name(c->method), (double)c->error_px[c->method], (double)c->cost_ms[c->method],
               c->over_budget ? ", over budget: the least error" : "");
        for (m = 0; m < REFL_METHOD_COUNT; ++m) {
            if (m == (int)c->method || !c->candidate[m] ||
                (c->candidate[m] > 0 && c->cost_ms[m] >= c->cost_ms[c->method]))
                continue;
            printf("%s%s ", first ? "; cheaper: " : ", ", refl_method_name((refl_method)m));
            if (c->candidate[m] < 0) printf("cannot draw it");
            else printf("%.2f px over budget (%.1f ms)", (double)c->error_px[m], (double)c->cost_ms[m]);
            first = 0;
        }
        printf("\n");
    }
    if (a->count > REFL_AUTO_MAX_CHOICES) printf("  (%d more)\n", a->count - REFL_AUTO_MAX_CHOICES);
}

static int cmd_render(const options *o) {
    static refl_auto_models auto_models; /* --auto-models */
    refl_scene *s = load_scene(o, NULL);
    refl_graphcam *maze_cam = NULL; /* the maze's graph camera, for GRAPHCAM on --builtin maze */
    refl_frame *f = NULL;
    refl_view v;
    refl_render_desc d;
    refl_result r;
    char err[1024] = "";
    int code = 1, i;
    progress_state ps;
    memset(&ps, 0, sizeof ps);
    if (!s) return 1;
    for (i = 0; i < o->mirror_count + o->glass_count; ++i) {
        int glass = i >= o->mirror_count;
        const char *name = glass ? o->glass[i - o->mirror_count] : o->mirror[i];
        if (!override_material(s, name, glass)) {
            fprintf(stderr, "reflect: %s %s: no object or material of that name (reflect info lists them)\n",
                    glass ? "--glass" : "--mirror", name);
            refl_scene_destroy(s);
            return 2;
        }
    }
    refl_scene_complete(s); /* a file may have no camera, light or sky */
    if (o->env) {
        refl_environment env;
        if ((r = refl_env_load(o->env, &env, NULL, err, sizeof err)) != REFL_OK) {
            fprintf(stderr, "reflect: %s\n", err[0] ? err : refl_result_string(r));
            goto done;
        }
        r = refl_scene_set_environment(s, &env);
        refl_env_free(&env, NULL);
        if (r != REFL_OK) {
            fprintf(stderr, "reflect: %s: %s\n", o->env, refl_result_string(r));
            goto done;
        }
    }
    v = s->camera;
    if (o->has_eye) v.eye = o->eye;
    if (o->has_target) v.target = o->target;
    if (o->has_up) v.up = o->up;
    if (o->fov > 0.0f) v.fovy_degrees = o->fov;
    v.width = o->width ? o->width : (v.width > 0 ? v.width : 640);
    v.height = o->height ? o->height : (v.height > 0 ? v.height : 480);
    memset(&d, 0, sizeof d);
    d.threads = o->threads;
    d.depth = o->depth;
    d.spp = o->spp;
    d.lighting.shadows = o->shadows;
    d.envmap.size = o->envmap_size;
    d.spoc.size = o->spoc_size;
    d.spoc.layers = o->spoc_layers;
    d.spoc.glass = o->spoc_glass;
    /* the desc's 0 is the default strength and a negative one the plain depth image */
    d.spoc.strength = o->spoc_strength < 0.0f ? 0.0f : o->spoc_strength == 0.0f ? -1.0f : o->spoc_strength;
    d.spoc.step_scale = o->spoc_step;
    d.planar.no_culling = o->no_culling;
    d.planar.max_renderings = o->max_renderings;
    d.lighting.light_volumes = o->light_volumes;
    d.lighting.caustic_samples = o->caustic_samples;
    d.lighting.translucency = o->translucency;
    d.lighting.soft_shadow_samples = o->soft_samples;
    d.c3rc.point_density = o->density;
    d.c3rc.kd_leaf_points = o->leaf_points;
    d.c3rc.max_splat = o->max_splat;
    d.c3rc.camera_split_px = o->camera_split;
    d.sbc.error_px = o->error_px;
    d.sbc.ray_factor = o->ray_factor;
    d.sbc.trace_fallback = o->trace_fallback;
    d.sbc.mode = o->sbc_paper ? REFL_SBC_PAPER : REFL_SBC_TRACED;
    d.graphcam.size = o->graphcam_size;
    d.graphcam.algorithm = o->graphcam_alg;
    d.graphcam.step = o->graphcam_step;
    if (o->builtin && !strcmp(o->builtin, "maze")) {
        int w = o->graphcam_size ? o->graphcam_size : 1920;
        maze_cam = (refl_graphcam *)malloc(sizeof *maze_cam);
        if (!maze_cam || refl_graphcam_maze(maze_cam, w, (int)((long)w * 1176 / 1920)) != REFL_OK) {
            fprintf(stderr, "reflect: the maze's graph camera could not be built\n");
            goto done;
        }
        d.graphcam.camera = maze_cam;
    }
    d.raytrace.greedy = o->greedy;
    d.raytrace.unpruned = o->unpruned;
    d.layered_em.samples = o->lem_samples;
    d.layered_em.layers = o->lem_layers;
    d.layered_em.edge_px = o->lem_edge;
    d.layered_em.shell = o->lem_shell;
    d.layered_em.direct_images = o->lem_direct;
    d.layered_em.lens_layers = o->lem_lens_layers;
    d.layered_em.continue_incoming = o->lem_continue;
    d.layered_em.share_outer_layer = o->lem_share;
    d.layered_em.direct_from = o->lem_direct_from;
    d.layered_em.direct_confidence = o->lem_direct_conf;
    d.layered_em.shell_frame = o->lem_frame;
    if (o->light_radius > 0.0f) {
        int i;
        for (i = 0; i < s->light_count; ++i) s->lights[i].radius = o->light_radius;
    }
    if (o->fresnel[1] > 0.0f || o->fade.x > 0.0f) {
        int i;
        for (i = 0; i < s->material_count; ++i) {
            refl_material *m = &s->materials[i];
            if (o->fresnel[1] > 0.0f) {
                m->fresnel_min = o->fresnel[0];
                m->fresnel_max = o->fresnel[1];
            }
            if (o->fade.x > 0.0f) {
                m->fade_distance = o->fade.x;
                m->fade_min = o->fade.y;
                m->fade_max = o->fade.z;
            }
        }
    }
    if (o->method) d.method = refl_method_from_name(o->method); /* checked by parse */
    d.automatic.error_budget_px = o->error_budget;
    if (o->auto_models) {
        char msg[200];
        struct stat st;
        /* the library's loader opens what it is given: a FIFO would block it */
        if (stat(o->auto_models, &st) == 0 && !S_ISREG(st.st_mode)) {
            fprintf(stderr, "reflect: --auto-models: %s: not a regular file\n", o->auto_models);
            goto done;
        }
        if (refl_auto_models_load(o->auto_models, &auto_models, msg, sizeof msg) != REFL_OK) {
            fprintf(stderr, "reflect: --auto-models: %s\n", msg);
            goto done;
        }
        d.automatic.models = &auto_models;
    }
    if (o->gl) {
        code = render_gl(o, s, &v, d.method, d.graphcam.camera);
        goto done;
    }
    ps.bar = isatty(2);
    ps.limit_ms = o->time_limit * 1000.0;
    ps.start_ms = refl_bench_now_ms();
    if (ps.bar || ps.limit_ms > 0.0) {
        d.progress = progress;
        d.progress_user = &ps;
    }
    if ((r = refl_frame_create(v.width, v.height, NULL, &f)) != REFL_OK) {
        fprintf(stderr, "reflect: frame %dx%d: %s\n", v.width, v.height, refl_result_string(r));
        goto done;
    }
    r = o->prebuild || o->frames > 1 ? render_kept(s, &v, &d, f, o->prebuild, o->frames > 1 ? o->frames : 1, o->stats)
                                     : refl_render(s, &v, &d, f);
    if (r == REFL_ERROR_CANCELLED && ps.stopped) {
        fprintf(stderr, "reflect: render with %s stopped at the time limit (--time-limit %g); nothing written\n",
                refl_method_name(d.method), (double)o->time_limit);
        goto done;
    }
    if (r != REFL_OK) {
        fprintf(stderr, "reflect: render with %s: %s%s%s\n", refl_method_name(d.method), refl_result_string(r),
                f->message[0] ? ": " : "", f->message);
        goto done;
    }
    if (f->stats.traced_beyond)
        fprintf(stderr, "reflect: %lld reflector pixels whose path goes past the bounces %s models ray traced\n",
                f->stats.traced_beyond, refl_method_name(d.method));
    if (f->stats.handed_over)
        fprintf(stderr, "reflect: %d reflector%s %s cannot draw ray traced instead\n", f->stats.handed_over,
                f->stats.handed_over > 1 ? "s" : "", refl_method_name(d.method));
    if ((r = write_frame(o->out, f, &o->display, err, sizeof err)) != REFL_OK) {
        fprintf(stderr, "reflect: %s\n", err[0] ? err : refl_result_string(r));
        goto done;
    }
    if (o->stats) {
        const refl_stats *st = &f->stats;
        printf("method       %s\n", refl_method_name(d.method));
        printf("size         %dx%d\n", f->width, f->height);
        printf("total ms     %.2f\n", st->ms_total);
        printf("  build ms   %.2f\n  base ms    %.2f\n  reflect ms %.2f\n  compose ms %.2f\n", st->ms_build,
               st->ms_base, st->ms_reflect, st->ms_composite);
        printf("depth        %d bounce%s\n", st->depth, st->depth == 1 ? "" : "s");
        printf("triangles    %lld\nrays         %lld\ntri tests    %lld\n", st->triangles, st->rays, st->triangle_tests);
        if (st->handed_over) printf("ray traced   %d reflector(s) the method cannot draw\n", st->handed_over);
        if (st->traced_beyond) printf("ray traced   %lld pixel(s) past the method's bounces\n", st->traced_beyond);
        if (st->envmap.cube_faces) printf("cube faces   %lld\n", st->envmap.cube_faces);
        if (st->spoc.impostors)
            printf("impostors    %lld\nsteps        %lld (at most %lld per ray and impostor)\n", st->spoc.impostors,
                   st->spoc.steps, st->spoc.max_steps);
        if (st->spoc.traced) printf("ray traced   %lld pixel(s) whose march missed its object\n", st->spoc.traced);
        if (st->planar.renderings || st->planar.culled)
            printf("renderings   %lld (deepest level %lld, culled %lld)\n", st->planar.renderings,
                   st->planar.deepest, st->planar.culled);
        if (st->planar.traced) printf("ray traced   %lld pixels past the rendering budget\n", st->planar.traced);
        if (st->c3rc.cameras) {
            const refl_c3rc_frame_stats *c = &st->c3rc;
            printf("points       %lld\ncameras      %lld\nleaves       %lld\n", c->points, c->cameras, c->leaves);
            printf("projections  %lld (valid %lld, %.1f%%)\nbox tests    %lld (rejected %.1f%%)\n"
                   "  cull ms    %.2f (thread time)\n  project ms %.2f (thread time)\n",
                   c->projections, c->projected,
                   c->projections ? 100.0 * (double)c->projected / (double)c->projections : 0.0, c->box_tests,
                   c->box_tests ? 100.0 * (double)c->culled / (double)c->box_tests : 0.0, c->ms_cull, c->ms_project);
            if (c->traced) printf("ray traced   %lld pixels in gaps of the points\n", c->traced);
        }
        if (st->sbc.histories) {
            const refl_sbc_frame_stats *b = &st->sbc;
            printf("histories    %d\ngroups       %d\nleaves       %lld pinhole, %lld ray-list\n", b->histories,
                   b->groups, b->pinhole_leaves, b->ray_leaves);
            printf("projections  %lld (valid %lld, %.1f%%)\n", b->projections, b->projected,
                   b->projections ? 100.0 * (double)b->projected / (double)b->projections : 0.0);
            if (b->traced) printf("ray traced   %lld pixels\n", b->traced);
        }
        if (st->graphcam.frusta) {
            const refl_graphcam_frame_stats *g = &st->graphcam;
            printf("frusta       %d\nimpostor     %lld triangles\nrays         %lld (hit %lld, %lld ray traced)\n"
                   "steps        %lld (at most %lld a ray)\n", g->frusta, g->triangles, g->rays, g->hits, g->traced, g->steps,
                   g->max_steps);
        }
        if (st->layered_em.maps_held) {
            const refl_layered_em_frame_stats *l = &st->layered_em;
            printf("maps         %d inferred, %d kept, %d held\n", l->maps_inferred, l->maps_kept, l->maps_held);
            printf("  trace ms   %.2f (%lld vertices, %lld triangle tests)\n  tess ms    %.2f\n  draw ms    %.2f\n"
                   "traced px   %lld (no triangle covered them, or their paths left through another lens)\n",
                   l->ms_trace, l->vertices, l->vertex_tests, l->ms_tessellate, l->ms_draw, l->traced_pixels);
            if (l->direct_rows) printf("direct rows  %lld (direct images' rows in the maps inferred)\n", l->direct_rows);
            if (l->continued_pixels)
                printf("continued    %lld (sample pixels whose eye ray reached the lens through what hid it)\n",
                       l->continued_pixels);
            if (l->quad_misses) printf("quad misses  %lld (vertex terms past a quad layer)\n", l->quad_misses);
            if (l->solves)
                printf("solves       %d (at most %d iterations; %d stopped at the cap short of the tolerance)\n",
                       l->solves, l->solve_iterations, l->solves_capped);
        }
        printf("model bytes  %lld\nreflectors   %d\n", st->model_bytes, st->reflectors);
        print_auto_choices(s, &st->automatic);
    }
    code = 0;
done:
    free(maze_cam);
    refl_frame_destroy(f);
    refl_scene_destroy(s);
    return code;
}

static const char *material_type_name(refl_material_type t) {
    switch (t) {
    case REFL_MIRROR: return "mirror";
    case REFL_GLASS: return "glass";
    case REFL_PARTIAL: return "partial";
    default: return "diffuse";
    }
}

/* A threshold as a number in [0, 1] or a fraction such as 4/255. */
static int parse_threshold(const char *s, double *out) {
    double num, den = 1.0;
    char extra;
    if (sscanf(s, "%lf/%lf%c", &num, &den, &extra) != 2 && sscanf(s, "%lf%c", &num, &extra) != 1) return 0;
    if (!(den > 0.0) || !(num / den >= 0.0 && num / den <= 1.0)) return 0;
    *out = num / den;
    return 1;
}

static uint8_t *read_rgba8(const char *path, int *width, int *height) {
    uint8_t *px = NULL;
    char err[1024] = "";
    refl_result r = refl_image_read_rgba8(path, width, height, &px, NULL, err, sizeof err);
    if (r != REFL_OK) {
        fprintf(stderr, "reflect: %s\n", err[0] ? err : refl_result_string(r));
        return NULL;
    }
    return px;
}

/* Two RGBA8 images compared over their first `channels` channels: the
   numbers refl_image_compare gives for RGB, and per pixel the largest
   difference in levels (worst[i]). */
static void compare_pixels(const uint8_t *a, const uint8_t *b, int count, int channels, double threshold,
                           refl_image_diff *d, uint8_t *worst) {
    double sum = 0.0;
    int i, c, max_diff = 0;
    memset(d, 0, sizeof *d);
    for (i = 0; i < count; ++i) {
        int w = 0;
        for (c = 0; c < channels; ++c) {
            int x = abs((int)a[4 * i + c] - (int)b[4 * i + c]);
            sum += (double)x * x;
            if (x > w) w = x;
        }
        worst[i] = (uint8_t)w;
        if (w > max_diff) max_diff = w;
        if (w / 255.0 > threshold) d->pixels_over++;
    }
    d->rmse = sqrt(sum / ((double)channels * count)) / 255.0;
    d->psnr = d->rmse > 0.0 ? 20.0 * log10(1.0 / d->rmse) : INFINITY;
    d->max_error = max_diff / 255.0;
    d->fraction_over = (double)d->pixels_over / count;
}

/* Pixels whose largest channel difference exceeds limit, as a fraction. */
static double fraction_over(const uint8_t *worst, int count, double limit) {
    long long n = 0;
    int i;
    for (i = 0; i < count; ++i) n += worst[i] / 255.0 > limit + 1e-6 / 255.0;
    return (double)n / count;
}

static int write_diff(const char *path, const uint8_t *a, const uint8_t *b, const uint8_t *mask, int w, int h,
                      int channels) {
    uint8_t *rgb = (uint8_t *)malloc((size_t)w * (size_t)h * 3);
    char err[512] = "";
    refl_result r;
    int i;
    if (!rgb) return 0;
    refl_heat_map(a, b, (long long)w * h, channels, 64, rgb);
    for (i = 0; mask && i < w * h; ++i)
        if (!(mask[4 * i] | mask[4 * i + 1] | mask[4 * i + 2])) memset(rgb + 3 * i, 0, 3);
    r = refl_image_write(path, w, h, 3, rgb, NULL, err, sizeof err);
    free(rgb);
    if (r != REFL_OK) fprintf(stderr, "reflect: %s\n", err[0] ? err : refl_result_string(r));
    return r == REFL_OK;
}

static int cmd_compare(int argc, char **argv) {
    const char *path[3] = {NULL, NULL, NULL}, *diff = NULL; /* A, B, mask */
    uint8_t *px[3] = {NULL, NULL, NULL}, *worst = NULL;
    int w[3] = {0, 0, 0}, h[3] = {0, 0, 0}, images = 0, count, channels = 3, i, k, code = 2;
    double threshold = 2.0 / 255.0, warn = -1.0, failx = -1.0, warn_pct = 0.0, fail_pct = 0.0;
    refl_image_diff d;
    for (i = 2; i < argc; ++i) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        float pct;
        if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
            fputs(usage_compare, stdout);
            return 0;
        } else if (!strcmp(a, "--mask") || !strcmp(a, "--threshold") || !strcmp(a, "--diff") || !strcmp(a, "--warn") ||
                   !strcmp(a, "--fail") || !strcmp(a, "--warn-percent") || !strcmp(a, "--fail-percent")) {
            if (!v) return fail("%s needs a value", a);
            if (!strcmp(a, "--mask")) path[2] = v;
            else if (!strcmp(a, "--diff")) diff = v;
            else if (!strcmp(a, "--threshold") && !parse_threshold(v, &threshold))
                return fail("--threshold: expected 0..1 or N/255, got %s", v);
            else if (!strcmp(a, "--warn") && !parse_threshold(v, &warn))
                return fail("--warn: expected 0..1 or N/255, got %s", v);
            else if (!strcmp(a, "--fail") && !parse_threshold(v, &failx))
                return fail("--fail: expected 0..1 or N/255, got %s", v);
            else if (strstr(a, "-percent")) {
                if (!parse_float(v, 0.0f, 100.0f, &pct)) return fail("--warn-percent, --fail-percent: 0..100, not %s", v);
                if (a[2] == 'w') warn_pct = pct;
                else fail_pct = pct;
            }
            ++i;
        } else if (a[0] == '-' && a[1] != '\0') {
            return fail("compare: unknown option %s (see reflect compare --help)", a);
        } else {
            if (images == 2) return fail("compare: more than two images given (%s)", a);
            path[images++] = a;
        }
    }
    if (images < 2) return fail("%s", "compare: give two images (see reflect compare --help)");
    for (k = 0; k < 3; ++k) {
        if (!path[k]) continue;
        if (!(px[k] = read_rgba8(path[k], &w[k], &h[k]))) goto done;
        if (k && (w[k] != w[0] || h[k] != h[0])) {
            fprintf(stderr, "reflect: %s: %dx%d, but %s is %dx%d\n", path[k], w[k], h[k], path[0], w[0], h[0]);
            goto done;
        }
    }
    count = w[0] * h[0];
    for (i = 0; i < count; ++i) /* alpha counts where either image has any */
        if (px[0][4 * i + 3] != 255 || px[1][4 * i + 3] != 255) channels = 4;
    if (diff && !write_diff(diff, px[0], px[1], px[2], w[0], h[0], channels)) goto done;
    if (px[2]) { /* keep the masked pixels of both, packed in place */
        int n = 0;
        for (i = 0; i < count; ++i)
            if (px[2][4 * i] | px[2][4 * i + 1] | px[2][4 * i + 2]) {
                memmove(px[0] + 4 * n, px[0] + 4 * i, 4);
                memmove(px[1] + 4 * n, px[1] + 4 * i, 4);
                ++n;
            }
        if (!n) {
            fprintf(stderr, "reflect: %s: the mask selects no pixels (all black)\n", path[2]);
            goto done;
        }
        count = n;
    }
    if (!(worst = (uint8_t *)malloc((size_t)count))) goto done;
    /* as reflect.h's refl_measure_image_error: a difference of exactly the
       threshold is not over it, whatever the rounding of T */
    compare_pixels(px[0], px[1], count, channels, threshold + 1e-6 / 255.0, &d, worst);
    printf("channels        %s\n", channels == 4 ? "RGBA" : "RGB");
    printf("pixels          %d\n", count);
    printf("rmse            %.6f\n", d.rmse);
    printf("psnr            %.2f dB\n", d.psnr);
    printf("max diff        %.6f (%d/255)\n", d.max_error, (int)(d.max_error * 255.0 + 0.5));
    printf("over threshold  %.6f (%lld pixels over %.6f)\n", d.fraction_over, d.pixels_over, threshold);
    code = 0;
    if (failx >= 0.0 && 100.0 * fraction_over(worst, count, failx) > fail_pct) code = 3;
    else if (warn >= 0.0 && 100.0 * fraction_over(worst, count, warn) > warn_pct) code = 1;
    if (failx >= 0.0 || warn >= 0.0) printf("result          %s\n", code == 3 ? "FAIL" : code == 1 ? "WARN" : "PASS");
done:
    for (k = 0; k < 3; ++k) free(px[k]);
    free(worst);
    return code;
}

static int cmd_info(const options *o) {
    int cameras = 0;
    refl_scene *s = load_scene(o, &cameras);
    refl_vec3 lo, hi;
    int i;
    if (!s) return 1;
    refl_scene_bounds(s, &lo, &hi);
    printf("scene        %s\n", o->file ? o->file : o->builtin);
    printf("objects      %d\nmeshes       %d\nmaterials    %d\nlights       %d\ntextures     %d\n", s->object_count,
           s->mesh_count, s->material_count, s->light_count, s->texture_count);
    printf("triangles    %lld\n", refl_scene_triangles(s));
    printf("bounds       (%g, %g, %g) .. (%g, %g, %g)\n", lo.x, lo.y, lo.z, hi.x, hi.y, hi.z);
    if (s->has_camera)
        printf("camera       %d of %d: eye (%g, %g, %g) target (%g, %g, %g) fovy %g\n", o->camera, cameras,
               s->camera.eye.x, s->camera.eye.y, s->camera.eye.z, s->camera.target.x, s->camera.target.y,
               s->camera.target.z, s->camera.fovy_degrees);
    printf("\n%-4s %-24s %10s  %-8s %s\n", "#", "object", "triangles", "type", "material");
    for (i = 0; i < s->object_count; ++i) {
        const refl_object *ob = &s->objects[i];
        const refl_material *m = &s->materials[ob->material];
        printf("%-4d %-24.24s %10d  %-8s %s\n", i, ob->name[0] ? ob->name : "-", s->meshes[ob->mesh]->triangle_count,
               material_type_name(m->type), m->name[0] ? m->name : "-");
    }
    refl_scene_destroy(s);
    return 0;
}

int main(int argc, char **argv) {
    options o;
    int r;
    if (argc >= 2 && !strcmp(argv[1], "--version")) {
        printf("reflect %d.%d.%d\n", REFL_VERSION_MAJOR, REFL_VERSION_MINOR, REFL_VERSION_PATCH);
        return 0;
    }
    if (argc < 2 || !strcmp(argv[1], "--help") || !strcmp(argv[1], "-h")) {
        fputs(usage_main, argc < 2 ? stderr : stdout);
        return argc < 2 ? 2 : 0;
    }
    if (!strcmp(argv[1], "render") || !strcmp(argv[1], "info")) {
        int is_render = !strcmp(argv[1], "render");
        r = parse(argc, argv, is_render, &o);
        if (r) return r == 1 ? 0 : 2;
        return is_render ? cmd_render(&o) : cmd_info(&o);
    }
    if (!strcmp(argv[1], "compare")) return cmd_compare(argc, argv);
    if (!strcmp(argv[1], "path")) return refl_cli_path(argc, argv);
    if (!strcmp(argv[1], "bench")) {
        int i;
        for (i = 2; i < argc; ++i)
            if (!strcmp(argv[i], "--gl")) return rgl_cli_bench(argc, argv);
            else if (!strcmp(argv[i], "--fit-auto") || !strcmp(argv[i], "--auto-table")) return refl_bench_auto(argc, argv);
        return refl_cli_bench(argc, argv);
    }
    fprintf(stderr, "reflect: unknown command '%s'\n\n%s", argv[1], usage_main);
    return 2;
}
