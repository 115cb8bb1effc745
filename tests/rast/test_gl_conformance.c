/* Conformance against a real GL: Mesa's llvmpipe, headless through EGL
   (tests/gl_peer.h). The same primitives go through rast.h and through
   llvmpipe; results are compared pixel for pixel.

   WHAT MUST BE BIT-IDENTICAL, AND WHY
     Both sides snap window coordinates to 1/256 pixel with round-to-nearest
     and decide coverage with exact integer edge functions at pixel centres
     (llvmpipe: lp_setup_tri.c, subpixel_snap(v - pixel_offset) with
     half_pixel_center = 1 from st_atom_rasterizer.c). So coverage is
     identical whenever both see the same snapped vertices. The generators
     below make sure of that: window coordinates lie on a 1/4096 grid that
     avoids the exact half-way points of the 1/256 grid (no rounding ties),
     NDC = window / (size / 2) - 1 with size a power of two (exact in float),
     and clip w is a power of two (x / w == x * (1 / w) exactly). Coverage is
     counted with stencil INCR_WRAP, so every primitive's footprint is
     compared, not only the top one.
       - coverage, stencil values and stencil-op outcomes: exact;
       - depth: the plane-equation arithmetic differs (llvmpipe evaluates
         a0 + dzdx*x + dzdy*y in its own order), so depth values are compared
         within a small tolerance, and depth-test OUTCOMES are compared
         exactly only where they are decidable: triangles of constant depth
         on a k/1024 grid (z_w = z_ndc*0.5+0.5 is exact, a constant plane
         has dzdx = dzdy = 0 on both sides). For sloped depth, a pixel may
         resolve differently only where the competing depths are within the
         tolerance (test depth_sloped_near_ties);
       - colours: within 1/255 per channel (float->unorm8 rounding and
         perspective interpolation order differ).

   WHERE GL ALLOWS DIFFERENCES (each has its own bounded test)
     - Fill-rule orientation. GL only requires that a centre on an edge
       shared by two polygons is drawn by exactly one of them (GL 4.6 core,
       14.6.1); it does not say which. llvmpipe includes the edge at the
       LOWER GL window y ("GL (normally) ends up needing a bottom-left fill
       convention", lp_setup_point.c try_setup_point; for FBOs
       st_atom_rasterizer.c leaves bottom_edge_rule = 0 in Gallium's y-down
       surface frame, whose row 0 is GL's bottom row). Read back and flipped
       so row 0 is the top, that is a BOTTOM-left rule in image
       coordinates, not the top-left rule rast.h's api.h promises. The two
       can only differ for centres lying exactly on a horizontal edge. The
       tests fill_rule_* check api.h's rule analytically, check it exactly
       against llvmpipe drawing the scene mirrored in y (so llvmpipe's own
       arithmetic applies a top-left rule in image coordinates), and bound
       the flipped-readback difference to exactly those horizontal-edge
       centres.
     - Clipping. With a depth/stencil buffer bound llvmpipe has no x/y guard
       band (lp_state_derived.c check_linear_rasterizer: guard_band_xy only
       when there is no zsbuf), so the draw module clips every triangle with
       a vertex outside the clip volume and snaps the new vertices again.
       rast.h clips only at near/far and beyond its +-8192 pixel guard band.
       Clip-generated vertices are computed differently on the two sides, so
       centres very close to an edge of a clipped triangle may go either
       way: tests clip_* allow a coverage difference only where a pixel
       centre is within CLIP_EPS pixels of the exact (double precision)
       boundary of a triangle that needed clipping, and bound the count.
     - Point ties. GL 3.3 core rasterises points as squares and leaves the
       treatment of centres exactly on the square's border to the
       implementation (llvmpipe: its fill rule; the legacy GL 2.1 rule:
       floor-based). The main point test keeps centres off those borders;
       points_on_pixel_boundaries allows a one-pixel shift per axis.
     - Rounding ties of the 1/256 snap (round-half-even vs half-up) are
       avoided by the generators and not tested: GL does not specify them.

   If GL cannot be initialised (no EGL, no llvmpipe) the tests are skipped
   with the reason on stderr; set GL_PEER_REQUIRED=1 to make that a failure.
*/
#define _POSIX_C_SOURCE 200809L
#include <criterion/criterion.h>

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gl_peer.h"
#include "../../rast.h"

#define W 256
#define H 256
#define CLIP_EPS (1.0 / 32.0) /* pixels */

/* ---- random numbers -------------------------------------------------- */

typedef struct rng { uint64_t s; } rng;

static uint64_t rng_next(rng *r) {
    uint64_t z = (r->s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}
static int rng_int(rng *r, int n) { return (int)(rng_next(r) % (uint64_t)n); }
static double rng_unit(rng *r) { return (double)(rng_next(r) >> 11) * (1.0 / 9007199254740992.0); }
static double rng_range(rng *r, double lo, double hi) { return lo + (hi - lo) * rng_unit(r); }

/* A window coordinate in [lo, hi) on the 1/4096 grid, never on an exact
   half of the 1/256 snapping grid (k/4096 with k % 16 == 8). */
static double rng_coord(rng *r, int lo, int hi) {
    int k;
    do k = rng_int(r, 4096); while ((k & 15) == 8);
    return (double)(lo + rng_int(r, hi - lo)) + k / 4096.0;
}

/* A window coordinate exactly on the 1/256 snapping grid: snapping is then
   the identity, so both sides interpolate from the very same positions. */
static double rng_coord256(rng *r, int lo, int hi) {
    return (double)(lo + rng_int(r, hi - lo)) + rng_int(r, 256) / 256.0;
}

/* Moves a coordinate on the 1/4096 grid off an exact 1/256 half-way point. */
static double untie(double x) {
    double k = x * 4096.0;
    if (fmod(fabs(k), 16.0) == 8.0) x += 1.0 / 4096.0;
    return x;
}

/* A point-centre coordinate in [lo, hi): as above, and its snapped value is
   also never a multiple of 1/2, so no pixel centre lies on the border of a
   square of integer size. */
static double rng_point_coord(rng *r, int lo, int hi) {
    int k;
    do k = rng_int(r, 4096);
    while ((k & 15) == 8 || k < 16 || k > 4080 || (k > 2032 && k < 2064));
    return (double)(lo + rng_int(r, hi - lo)) + k / 4096.0;
}

/* ---- vertices ---------------------------------------------------------- */

enum { VF = GL_PEER_FLOATS_PER_VERTEX }; /* x y z w r g b a */

/* Image coordinates (row 0 at the top) and NDC z -> clip position * w. */
static void put_vertex(float *v, double x_img, double y_img, double z_ndc, float w,
                       const float rgba[4]) {
    float xn = (float)(x_img / (W / 2)) - 1.0f;   /* exact: W/2 a power of two */
    float yn = 1.0f - (float)(y_img / (H / 2));
    v[0] = xn * w;
    v[1] = yn * w;
    v[2] = (float)z_ndc * w;
    v[3] = w;
    memcpy(v + 4, rgba, 4 * sizeof(float));
}

static void rand_color(rng *r, float c[4]) {
    int i;
    for (i = 0; i < 4; i++) c[i] = (float)rng_unit(r);
}

static float rand_pow2_w(rng *r) {
    static const float ws[] = { 0.5f, 1.0f, 2.0f, 4.0f, 8.0f };
    return ws[rng_int(r, 5)];
}

/* ---- rast_state -> GL ------------------------------------------------- */

static GLenum gl_compare(rast_compare c, GLenum def) {
    switch (c) {
    case RAST_NEVER: return GL_NEVER;
    case RAST_LESS: return GL_LESS;
    case RAST_EQUAL: return GL_EQUAL;
    case RAST_LEQUAL: return GL_LEQUAL;
    case RAST_GREATER: return GL_GREATER;
    case RAST_NOTEQUAL: return GL_NOTEQUAL;
    case RAST_GEQUAL: return GL_GEQUAL;
    case RAST_ALWAYS: return GL_ALWAYS;
    default: return def;
    }
}

static GLenum gl_stencil_op(rast_stencil_op o) {
    switch (o) {
    case RAST_ZERO: return GL_ZERO;
    case RAST_REPLACE: return GL_REPLACE;
    case RAST_INCR: return GL_INCR;
    case RAST_DECR: return GL_DECR;
    case RAST_INVERT: return GL_INVERT;
    case RAST_INCR_WRAP: return GL_INCR_WRAP;
    case RAST_DECR_WRAP: return GL_DECR_WRAP;
    default: return GL_KEEP;
    }
}

static GLenum gl_blend_factor(rast_blend_factor f, GLenum def) {
    switch (f) {
    case RAST_ZERO_FACTOR: return GL_ZERO;
    case RAST_ONE: return GL_ONE;
    case RAST_SRC_COLOR: return GL_SRC_COLOR;
    case RAST_ONE_MINUS_SRC_COLOR: return GL_ONE_MINUS_SRC_COLOR;
    case RAST_DST_COLOR: return GL_DST_COLOR;
    case RAST_ONE_MINUS_DST_COLOR: return GL_ONE_MINUS_DST_COLOR;
    case RAST_SRC_ALPHA: return GL_SRC_ALPHA;
    case RAST_ONE_MINUS_SRC_ALPHA: return GL_ONE_MINUS_SRC_ALPHA;
    case RAST_DST_ALPHA: return GL_DST_ALPHA;
    case RAST_ONE_MINUS_DST_ALPHA: return GL_ONE_MINUS_DST_ALPHA;
    case RAST_CONSTANT_COLOR: return GL_CONSTANT_COLOR;
    case RAST_ONE_MINUS_CONSTANT_COLOR: return GL_ONE_MINUS_CONSTANT_COLOR;
    case RAST_CONSTANT_ALPHA: return GL_CONSTANT_ALPHA;
    case RAST_ONE_MINUS_CONSTANT_ALPHA: return GL_ONE_MINUS_CONSTANT_ALPHA;
    case RAST_SRC_ALPHA_SATURATE: return GL_SRC_ALPHA_SATURATE;
    default: return def;
    }
}

static GLenum gl_blend_eq(rast_blend_equation e) {
    switch (e) {
    case RAST_FUNC_SUBTRACT: return GL_FUNC_SUBTRACT;
    case RAST_FUNC_REVERSE_SUBTRACT: return GL_FUNC_REVERSE_SUBTRACT;
    case RAST_FUNC_MIN: return GL_MIN;
    case RAST_FUNC_MAX: return GL_MAX;
    default: return GL_FUNC_ADD;
    }
}

static GLuint mask8(unsigned m) { return (m & 0x100u) ? (m & 0xFFu) : 0xFFu; }

static void gl_stencil_face(GLenum face, const rast_stencil_face *f) {
    glStencilFuncSeparate(face, gl_compare(f->func, GL_ALWAYS), f->ref, mask8(f->read_mask));
    glStencilOpSeparate(face, gl_stencil_op(f->fail), gl_stencil_op(f->depth_fail),
                        gl_stencil_op(f->pass));
    glStencilMaskSeparate(face, mask8(f->write_mask));
}

/* The subset of rast_state these tests use. The scissor is in image rows
   (top-left origin); GL counts rows from the bottom unless it draws the
   scene mirrored. */
static void gl_apply_state(gl_peer *g, const rast_state *s, int mirrored) {
    unsigned cw = s->color_write ? (s->color_write & 15u) : 15u;
    float ps = s->point_size <= 0.0f ? 1.0f : floorf(s->point_size + 0.5f);
    if (ps < 1.0f) ps = 1.0f;
    if (ps > 256.0f) ps = 256.0f;

    if (s->cull == RAST_CULL_BACK || s->cull == RAST_CULL_FRONT ||
        s->cull == RAST_CULL_FRONT_AND_BACK) {
        glEnable(GL_CULL_FACE);
        glCullFace(s->cull == RAST_CULL_BACK ? GL_BACK
                   : s->cull == RAST_CULL_FRONT ? GL_FRONT : GL_FRONT_AND_BACK);
    } else {
        glDisable(GL_CULL_FACE);
    }
    glFrontFace(s->front_face == RAST_CW ? GL_CW : GL_CCW);
    gl_peer_shading(g, s->shading == RAST_FLAT);
    gl_peer_point_size(g, ps);

    if (s->stencil_test) glEnable(GL_STENCIL_TEST); else glDisable(GL_STENCIL_TEST);
    gl_stencil_face(GL_FRONT, &s->stencil_front);
    gl_stencil_face(GL_BACK, &s->stencil_back);

    if (s->depth_test) glEnable(GL_DEPTH_TEST); else glDisable(GL_DEPTH_TEST);
    glDepthFunc(gl_compare(s->depth_func, GL_LESS));
    glDepthMask(s->depth_write_disabled ? GL_FALSE : GL_TRUE);

    if (s->blend) glEnable(GL_BLEND); else glDisable(GL_BLEND);
    glBlendFuncSeparate(gl_blend_factor(s->blend_src_rgb, GL_ONE),
                        gl_blend_factor(s->blend_dst_rgb, GL_ZERO),
                        gl_blend_factor(s->blend_src_alpha, GL_ONE),
                        gl_blend_factor(s->blend_dst_alpha, GL_ZERO));
    glBlendEquationSeparate(gl_blend_eq(s->blend_eq_rgb), gl_blend_eq(s->blend_eq_alpha));
    glBlendColor(s->blend_color[0], s->blend_color[1], s->blend_color[2], s->blend_color[3]);
    glColorMask((cw & 1) != 0, (cw & 2) != 0, (cw & 4) != 0, (cw & 8) != 0);
    if (s->scissor_test) {
        glEnable(GL_SCISSOR_TEST);
        glScissor(s->scissor[0], mirrored ? s->scissor[1] : H - s->scissor[1] - s->scissor[3], s->scissor[2],
                  s->scissor[3]);
    } else {
        glDisable(GL_SCISSOR_TEST);
    }
}

/* ---- the pair: one scene, two renderers --------------------------------- */

typedef struct pair {
    gl_peer gl;
    rast_context *rc;
    uint8_t r_rgba[W * H * 4], g_rgba[W * H * 4];
    float r_depth[W * H], g_depth[W * H];
    uint8_t r_st[W * H], g_st[W * H];
    int mirror_gl; /* GL draws the scene mirrored in y and is read back unflipped */
    /* rast.h reads vertex arrays at rast_finish(): each draw gets its own
       copy, kept until pair_read. */
    float *keep[64];
    int nkeep;
} pair;

static pair *pair_create(void) {
    pair *p = calloc(1, sizeof *p);
    rast_context_desc cd;
    rast_targets t;
    rast_result res;
    cr_assert_not_null(p);
    if (gl_peer_init(&p->gl, W, H) != 0) {
        const char *req = getenv("GL_PEER_REQUIRED");
        char why[600];
        snprintf(why, sizeof why, "llvmpipe through EGL unavailable: %s", p->gl.err);
        fprintf(stderr, "test_gl_conformance: %s\n", why);
        free(p);
        if (req && *req && strcmp(req, "0") != 0) cr_assert_fail("%s (GL_PEER_REQUIRED is set)", why);
        cr_skip_test("%s", why);
    }
    memset(&cd, 0, sizeof cd);
    res = rast_context_create(&cd, &p->rc);
    cr_assert_eq(res, RAST_OK, "rast_context_create: %s", rast_result_string(res));
    memset(&t, 0, sizeof t);
    t.color.ptr = p->r_rgba; t.color.width = W; t.color.height = H; t.color.stride = W * 4;
    t.depth.ptr = p->r_depth; t.depth.width = W; t.depth.height = H; t.depth.stride = W * 4;
    t.stencil.ptr = p->r_st; t.stencil.width = W; t.stencil.height = H; t.stencil.stride = W;
    res = rast_set_targets(p->rc, &t);
    cr_assert_eq(res, RAST_OK, "rast_set_targets: %s", rast_result_string(res));
    return p;
}

static void pair_release(pair *p) {
    while (p->nkeep > 0) free(p->keep[--p->nkeep]);
}

static void pair_destroy(pair *p) {
    rast_context_destroy(p->rc);
    pair_release(p);
    gl_peer_destroy(&p->gl);
    free(p);
}

static void pair_clear(pair *p, const float rgba[4], float depth, uint8_t stencil) {
    rast_state s;
    rast_clear_desc c;
    memset(&s, 0, sizeof s);
    rast_set_state(p->rc, &s);
    memset(&c, 0, sizeof c);
    c.flags = RAST_CLEAR_COLOR | RAST_CLEAR_DEPTH | RAST_CLEAR_STENCIL;
    memcpy(c.color, rgba, sizeof c.color);
    c.depth = depth;
    c.stencil = stencil;
    cr_assert_eq(rast_clear(p->rc, &c), RAST_OK);

    glDisable(GL_SCISSOR_TEST);
    glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    glDepthMask(GL_TRUE);
    glStencilMask(0xFF);
    glClearColor(rgba[0], rgba[1], rgba[2], rgba[3]);
    glClearDepth(depth);
    glClearStencil(stencil);
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT | GL_STENCIL_BUFFER_BIT);
}

static void pair_draw(pair *p, const rast_state *s, rast_primitive prim, const float *v, int n) {
    rast_draw_desc d;
    rast_result res;
    float *copy = malloc((size_t)n * VF * sizeof(float));
    cr_assert_not_null(copy);
    cr_assert_lt(p->nkeep, 64, "too many draws before pair_read");
    memcpy(copy, v, (size_t)n * VF * sizeof(float));
    p->keep[p->nkeep++] = copy;
    res = rast_set_state(p->rc, s);
    cr_assert_eq(res, RAST_OK, "rast_set_state: %s", rast_result_string(res));
    memset(&d, 0, sizeof d);
    d.primitive = prim;
    d.vertices = copy;
    d.vertex_count = n;
    d.stride = VF;
    d.num_varyings = 4;
    res = rast_draw(p->rc, &d);
    cr_assert_eq(res, RAST_OK, "rast_draw: %s", rast_result_string(res));

    gl_apply_state(&p->gl, s, p->mirror_gl);
    if (p->mirror_gl) {
        /* y -> -y in clip space: GL window y == image y. Mirroring reverses
           the winding, so the front face flips too. */
        float *m = malloc((size_t)n * VF * sizeof(float));
        int i;
        cr_assert_not_null(m);
        memcpy(m, v, (size_t)n * VF * sizeof(float));
        for (i = 0; i < n; i++) m[i * VF + 1] = -m[i * VF + 1];
        glFrontFace(s->front_face == RAST_CW ? GL_CCW : GL_CW);
        gl_peer_draw_vertices(&p->gl, prim == RAST_POINTS ? GL_POINTS : GL_TRIANGLES, m, n);
        free(m);
    } else {
        gl_peer_draw_vertices(&p->gl, prim == RAST_POINTS ? GL_POINTS : GL_TRIANGLES, v, n);
    }
}

static void pair_read(pair *p) {
    GLenum e;
    cr_assert_eq(rast_finish(p->rc), RAST_OK);
    pair_release(p);
    gl_peer_read_rgba8(&p->gl, p->g_rgba);
    gl_peer_read_depth(&p->gl, p->g_depth);
    gl_peer_read_stencil(&p->gl, p->g_st);
    if (p->mirror_gl) { /* undo the flip: GL's row 0 already is the top */
        gl_peer__flip(p->g_rgba, W * 4, H);
        gl_peer__flip(p->g_depth, W * 4, H);
        gl_peer__flip(p->g_st, W, H);
    }
    e = gl_peer_error();
    cr_assert_eq(e, GL_NO_ERROR, "GL error 0x%x", (unsigned)e);
}

/* ---- comparisons --------------------------------------------------------- */

/* Which pixels may differ (NULL: none). */
typedef int (*allow_fn)(void *user, int x, int y);

static int compare_stencil(const pair *p, const char *what, allow_fn allow, void *user,
                           int *allowed_out) {
    int x, y, bad = 0, allowed = 0, shown = 0;
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            int i = y * W + x;
            if (p->r_st[i] == p->g_st[i]) continue;
            if (allow && allow(user, x, y)) { allowed++; continue; }
            if (shown++ < 12)
                fprintf(stderr, "%s: stencil/coverage differs at (%d,%d): rast %u, llvmpipe %u\n",
                        what, x, y, p->r_st[i], p->g_st[i]);
            bad++;
        }
    if (allowed_out) *allowed_out = allowed;
    return bad;
}

static int compare_color(const pair *p, const char *what, int tol, allow_fn allow, void *user) {
    int x, y, c, bad = 0, shown = 0;
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            const uint8_t *a = p->r_rgba + (y * W + x) * 4, *b = p->g_rgba + (y * W + x) * 4;
            int worst = 0;
            for (c = 0; c < 4; c++) {
                int d = abs((int)a[c] - (int)b[c]);
                if (d > worst) worst = d;
            }
            if (worst <= tol) continue;
            if (allow && allow(user, x, y)) continue;
            if (shown++ < 12)
                fprintf(stderr, "%s: colour differs at (%d,%d): rast %u %u %u %u, llvmpipe %u %u %u %u\n",
                        what, x, y, a[0], a[1], a[2], a[3], b[0], b[1], b[2], b[3]);
            bad++;
        }
    return bad;
}

static int compare_depth(const pair *p, const char *what, float tol, allow_fn allow, void *user) {
    int x, y, bad = 0, shown = 0;
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            int i = y * W + x;
            float d = fabsf(p->r_depth[i] - p->g_depth[i]);
            if (d <= tol) continue;
            if (allow && allow(user, x, y)) continue;
            if (shown++ < 12)
                fprintf(stderr, "%s: depth differs at (%d,%d): rast %.9g, llvmpipe %.9g\n",
                        what, x, y, (double)p->r_depth[i], (double)p->g_depth[i]);
            bad++;
        }
    return bad;
}

static const float black[4] = { 0, 0, 0, 0 };

/* ---- interpolation slack ---------------------------------------------------

   Coverage uses the snapped vertices on both sides, but attribute and depth
   planes need not: llvmpipe builds them from the unsnapped float positions
   (lp_state_setup.c, calc_coef4: dx01/dy01 of the vertex floats, a0 at the
   framebuffer origin), rast.h from the snapped ones (barycentrics from the
   integer edge functions: setup.c rast__emit_tri, raster.c). GL leaves the
   sub-pixel precision of window coordinates to the implementation (GL 4.6
   core 14.6.1 interpolates "with respect to the vertices" it rasterises),
   so both are right. Moving each vertex by at most 1/512 pixel per axis
   changes an attribute inside the triangle by at most
   (|dc/dx| + |dc/dy|) / 512. Where vertices are off the 1/256 grid,
   colours are therefore compared within 1/255 plus twice that bound,
   computed per pixel from the exact gradient of the triangle that covers it
   (found by an ID pass), and depth within 4e-6 plus twice the depth bound.
   Where vertices are on the 1/256 grid no slack is given for colours. */

typedef struct slack_map {
    uint32_t id[W * H];   /* triangle + 1 on top at the pixel (GL's), 0: none */
    uint32_t rid[W * H];  /* the same from rast.h (differs only at depth ties) */
    float color[W * H];   /* extra colour tolerance, unorm8 steps */
    float depth[W * H];   /* depth tolerance */
} slack_map;

/* Image-space position, window z and 1/w of vertex k of triangle t. */
static void tri_window(const float *v, int t, double x[3], double y[3], double z[3], double iw[3]) {
    int k;
    for (k = 0; k < 3; k++) {
        const float *q = v + (t * 3 + k) * VF;
        iw[k] = 1.0 / q[3];
        x[k] = (q[0] * iw[k] + 1.0) * (W / 2);
        y[k] = (1.0 - q[1] * iw[k]) * (H / 2);
        z[k] = q[2] * iw[k] * 0.5 + 0.5;
    }
}

/* Barycentrics of (px, py); returns 0 for a degenerate triangle. */
static int bary(const double x[3], const double y[3], double px, double py, double b[3]) {
    double d = (x[1] - x[0]) * (y[2] - y[0]) - (x[2] - x[0]) * (y[1] - y[0]);
    if (d == 0) return 0;
    b[1] = ((px - x[0]) * (y[2] - y[0]) - (x[2] - x[0]) * (py - y[0])) / d;
    b[2] = ((x[1] - x[0]) * (py - y[0]) - (px - x[0]) * (y[1] - y[0])) / d;
    b[0] = 1.0 - b[1] - b[2];
    return 1;
}

/* Perspective-correct colour channel c of triangle t at (px, py). */
static double tri_color(const float *v, int t, int c, const double x[3], const double y[3],
                        const double iw[3], double px, double py) {
    double b[3], num = 0, den = 0;
    int k;
    if (!bary(x, y, px, py, b)) return 0;
    for (k = 0; k < 3; k++) {
        num += b[k] * iw[k] * v[(t * 3 + k) * VF + 4 + c];
        den += b[k] * iw[k];
    }
    return num / den;
}

/* Slack at pixel (x, y) for triangle t (colour steps, depth). */
static void pixel_slack(const float *v, int t, int x, int y, float *cs, float *ds) {
    {
        {
            double tx[3], ty[3], tz[3], iw[3], b0[3], bx[3], by[3], px = x + 0.5, py = y + 0.5;
            double worst = 0, h = 1.0 / 16;
            int c;
            *cs = 0;
            *ds = 4e-6f;
            if (t < 0) return;
            tri_window(v, t, tx, ty, tz, iw);
            if (!bary(tx, ty, px, py, b0) || !bary(tx, ty, px + 1, py, bx) || !bary(tx, ty, px, py + 1, by))
                return;
            for (c = 0; c < 4; c++) {
                double gx = (tri_color(v, t, c, tx, ty, iw, px + h, py) -
                             tri_color(v, t, c, tx, ty, iw, px - h, py)) / (2 * h);
                double gy = (tri_color(v, t, c, tx, ty, iw, px, py + h) -
                             tri_color(v, t, c, tx, ty, iw, px, py - h)) / (2 * h);
                double g = (fabs(gx) + fabs(gy)) * 255.0;
                if (g > worst) worst = g;
            }
            *cs = (float)(2.0 * worst / 512.0);
            {
                double z0 = b0[0] * tz[0] + b0[1] * tz[1] + b0[2] * tz[2];
                double zx = bx[0] * tz[0] + bx[1] * tz[1] + bx[2] * tz[2];
                double zy = by[0] * tz[0] + by[1] * tz[1] + by[2] * tz[2];
                *ds = (float)(4e-6 + 2.0 * (fabs(zx - z0) + fabs(zy - z0)) / 512.0);
            }
        }
    }
}

/* Per pixel: the larger slack of GL's and rast's top triangles. */
static void compute_slack(const float *v, slack_map *sm) {
    int x, y;
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            int i = y * W + x;
            float c1, d1, c2, d2;
            pixel_slack(v, (int)sm->id[i] - 1, x, y, &c1, &d1);
            pixel_slack(v, (int)sm->rid[i] - 1, x, y, &c2, &d2);
            sm->color[i] = c1 > c2 ? c1 : c2;
            sm->depth[i] = d1 > d2 ? d1 : d2;
        }
}

/* Renders the triangles once more with flat colours that encode their
   index (same cull and depth state, no stencil, no blending), and fills
   sm->id from llvmpipe's picture. With check_ids, rast.h's IDs must be the
   same everywhere (exact coverage and flat shading from the last vertex). */
static void id_pass(pair *p, const rast_state *s0, const float *v, int ntri, float clear_depth,
                    int check_ids, slack_map *sm) {
    float *iv = malloc((size_t)ntri * 3 * VF * sizeof(float));
    rast_state s = *s0;
    int t, k, i, bad = 0;
    cr_assert_not_null(iv);
    memcpy(iv, v, (size_t)ntri * 3 * VF * sizeof(float));
    for (t = 0; t < ntri; t++)
        for (k = 0; k < 3; k++) {
            float *q = iv + (t * 3 + k) * VF;
            unsigned id = (unsigned)t + 1;
            q[4] = (float)(id & 255) / 255.0f;
            q[5] = (float)((id >> 8) & 255) / 255.0f;
            q[6] = 0.0f;
            q[7] = k == 2 ? 1.0f : 0.0f; /* flat: only the last vertex counts */
        }
    s.shading = RAST_FLAT;
    s.stencil_test = 0;
    s.blend = 0;
    s.color_write = 0;
    s.depth_write_disabled = 0;
    pair_clear(p, black, clear_depth, 0);
    pair_draw(p, &s, RAST_TRIANGLES, iv, ntri * 3);
    pair_read(p);
    for (i = 0; i < W * H; i++) {
        const uint8_t *g = p->g_rgba + i * 4, *r = p->r_rgba + i * 4;
        sm->id[i] = g[3] ? (uint32_t)g[0] | (uint32_t)g[1] << 8 : 0u;
        sm->rid[i] = r[3] ? (uint32_t)r[0] | (uint32_t)r[1] << 8 : 0u;
        if (check_ids && memcmp(g, r, 4) != 0 && bad++ < 8)
            fprintf(stderr, "ID pass: pixel (%d,%d): rast %u %u %u %u, llvmpipe %u %u %u %u\n",
                    i % W, i / W, r[0], r[1], r[2], r[3], g[0], g[1], g[2], g[3]);
    }
    free(iv);
    if (check_ids)
        cr_expect_eq(bad, 0, "ID pass (flat shading, last vertex): %d pixels differ", bad);
    compute_slack(v, sm);
}

static int compare_color_slack(const pair *p, const char *what, const slack_map *sm,
                               allow_fn allow, void *user, int *slack_used) {
    int i, c, bad = 0, shown = 0, used = 0;
    for (i = 0; i < W * H; i++) {
        const uint8_t *a = p->r_rgba + i * 4, *b = p->g_rgba + i * 4;
        int worst = 0;
        for (c = 0; c < 4; c++) {
            int d = abs((int)a[c] - (int)b[c]);
            if (d > worst) worst = d;
        }
        if (worst <= 1) continue;
        if (worst <= 1.0f + sm->color[i]) { used++; continue; }
        if (allow && allow(user, i % W, i / W)) continue;
        if (shown++ < 12)
            fprintf(stderr, "%s: colour differs at (%d,%d) beyond 1 + %.2f: rast %u %u %u %u, "
                    "llvmpipe %u %u %u %u\n", what, i % W, i / W, (double)sm->color[i],
                    a[0], a[1], a[2], a[3], b[0], b[1], b[2], b[3]);
        bad++;
    }
    if (slack_used) *slack_used += used;
    return bad;
}

static int compare_depth_slack(const pair *p, const char *what, const slack_map *sm, double *worst_ratio) {
    int i, bad = 0, shown = 0;
    for (i = 0; i < W * H; i++) {
        float d = fabsf(p->r_depth[i] - p->g_depth[i]);
        if (worst_ratio && d / sm->depth[i] > *worst_ratio) *worst_ratio = d / sm->depth[i];
        if (d <= sm->depth[i]) continue;
        if (shown++ < 12)
            fprintf(stderr, "%s: depth differs at (%d,%d) beyond %.3g: rast %.9g, llvmpipe %.9g\n",
                    what, i % W, i / W, (double)sm->depth[i], (double)p->r_depth[i],
                    (double)p->g_depth[i]);
        bad++;
    }
    return bad;
}

static rast_state counting_state(void) {
    rast_state s;
    memset(&s, 0, sizeof s);
    s.stencil_test = 1;
    s.stencil_front.func = RAST_ALWAYS;
    s.stencil_front.pass = RAST_INCR_WRAP;
    s.stencil_back = s.stencil_front;
    return s;
}

/* ---- triangle soups inside the viewport: everything exact ---------------- */

/* grid256: vertices on the 1/256 grid (else the 1/4096 grid, off ties). */
static int make_soup(rng *r, float *v, int ntri, int constant_depth, int grid256) {
    int t, k;
    for (t = 0; t < ntri; t++) {
        float c[4];
        double cx = rng_coord(r, 0, W), cy = rng_coord(r, 0, H);
        double span = rng_int(r, 4) == 0 ? 200.0 : (rng_int(r, 2) ? 40.0 : 8.0);
        double zc = (rng_int(r, 2048) - 1024) / 1024.0;
        for (k = 0; k < 3; k++) {
            double x, y, z;
            int lo_x = (int)fmax(0.0, cx - span), hi_x = (int)fmin((double)W, cx + span);
            int lo_y = (int)fmax(0.0, cy - span), hi_y = (int)fmin((double)H, cy + span);
            if (hi_x <= lo_x) hi_x = lo_x + 1;
            if (hi_y <= lo_y) hi_y = lo_y + 1;
            x = grid256 ? rng_coord256(r, lo_x, hi_x) : rng_coord(r, lo_x, hi_x);
            y = grid256 ? rng_coord256(r, lo_y, hi_y) : rng_coord(r, lo_y, hi_y);
            if (x >= W) x = W - 0.25; /* stays strictly inside: no clipping */
            if (y >= H) y = H - 0.25;
            z = constant_depth ? zc : rng_range(r, -0.95, 0.95);
            rand_color(r, c);
            put_vertex(v + (t * 3 + k) * VF, x, y, z, rand_pow2_w(r), c);
        }
    }
    return ntri * 3;
}

Test(gl_conformance, triangle_coverage_exact, .timeout = 120) {
    pair *p = pair_create();
    static float v[400 * 3 * VF];
    static slack_map sm;
    rng r = { 0x5EED0001u };
    int pass, slack_used = 0;
    for (pass = 0; pass < 16; pass++) {
        rast_state s = counting_state();
        int n = make_soup(&r, v, 100 + rng_int(&r, 150), 0, 0), bad, badc;
        char what[96];
        static const rast_cull culls[] = { RAST_CULL_NONE, RAST_CULL_BACK, RAST_CULL_FRONT,
                                           RAST_CULL_FRONT_AND_BACK };
        s.cull = culls[pass & 3];
        s.front_face = (pass & 4) ? RAST_CW : RAST_CCW;
        s.shading = (pass & 8) ? RAST_FLAT : RAST_SMOOTH;
        snprintf(what, sizeof what, "soup pass %d (cull %d, front %s, %s)", pass, (int)s.cull,
                 s.front_face == RAST_CW ? "CW" : "CCW", s.shading == RAST_FLAT ? "flat" : "smooth");
        id_pass(p, &s, v, n / 3, 1.0f, 1, &sm);
        pair_clear(p, black, 1.0f, 0);
        pair_draw(p, &s, RAST_TRIANGLES, v, n);
        pair_read(p);
        bad = compare_stencil(p, what, NULL, NULL, NULL);
        badc = compare_color_slack(p, what, &sm, NULL, NULL, &slack_used);
        cr_expect_eq(bad, 0, "%s: %d pixels with a different coverage count", what, bad);
        cr_expect_eq(badc, 0, "%s: %d pixels with colour off by more than 1/255 + slack", what, badc);
    }
    fprintf(stderr, "triangle_coverage_exact: %d pixels needed the interpolation slack "
            "(colour off by more than 1/255 but within it)\n", slack_used);
    pair_destroy(p);
}

/* Thin slivers, tiny triangles and long edges: the cases where rounding of
   the edge functions matters most. */
Test(gl_conformance, triangle_slivers_exact, .timeout = 120) {
    pair *p = pair_create();
    static float v[600 * 3 * VF];
    rng r = { 0x5EED0002u };
    int pass;
    for (pass = 0; pass < 6; pass++) {
        rast_state s = counting_state();
        int t, n = 0, bad;
        char what[64];
        for (t = 0; t < 600; t++) {
            float c[4];
            double x0 = rng_coord(&r, 0, W), y0 = rng_coord(&r, 0, H);
            double x1 = rng_coord(&r, 0, W), y1 = rng_coord(&r, 0, H);
            double f = rng_unit(&r), x2, y2;
            /* third vertex close to the line through the first two */
            x2 = x0 + (x1 - x0) * f + (rng_int(&r, 64) - 32) / 4096.0;
            y2 = y0 + (y1 - y0) * f + (rng_int(&r, 64) - 32) / 4096.0;
            x2 = untie(floor(x2 * 4096.0) / 4096.0);
            y2 = untie(floor(y2 * 4096.0) / 4096.0);
            if (x2 < 0 || x2 >= W || y2 < 0 || y2 >= H) { t--; continue; }
            if (pass >= 3) { /* tiny triangles around pixel centres */
                x1 = untie(x0 + (rng_int(&r, 15) - 7) / 256.0 * 3 + 1.0 / 4096);
                y1 = untie(y0 + (rng_int(&r, 15) - 7) / 256.0 * 3 + 1.0 / 4096);
                x2 = untie(x0 + (rng_int(&r, 15) - 7) / 256.0 * 3 + 1.0 / 4096);
                y2 = untie(y0 + (rng_int(&r, 15) - 7) / 256.0 * 3 + 1.0 / 4096);
                if (x1 < 0 || x1 >= W || y1 < 0 || y1 >= H || x2 < 0 || x2 >= W || y2 < 0 ||
                    y2 >= H) { t--; continue; }
            }
            rand_color(&r, c);
            put_vertex(v + (n + 0) * VF, x0, y0, 0.0, 1.0f, c);
            put_vertex(v + (n + 1) * VF, x1, y1, 0.0, 1.0f, c);
            put_vertex(v + (n + 2) * VF, x2, y2, 0.0, 1.0f, c);
            n += 3;
        }
        snprintf(what, sizeof what, "slivers pass %d", pass);
        pair_clear(p, black, 1.0f, 0);
        pair_draw(p, &s, RAST_TRIANGLES, v, n);
        pair_read(p);
        bad = compare_stencil(p, what, NULL, NULL, NULL);
        cr_expect_eq(bad, 0, "%s: %d pixels with a different coverage count", what, bad);
        bad = compare_color(p, what, 1, NULL, NULL);
        cr_expect_eq(bad, 0, "%s: %d pixels with colour off by more than 1/255", what, bad);
    }
    pair_destroy(p);
}

/* ---- the fill rule on edges through pixel centres ------------------------ */

/* A jittered mesh whose vertices all lie on pixel centres: every edge (most
   of them sloped, many horizontal and vertical) passes through centres. */
static int make_centre_mesh(rng *r, float *v, int x0, int y0, int nx, int ny, int cell) {
    static double px[33][33], py[33][33];
    int i, j, n = 0, jit = cell >= 6; /* jitter < cell/4: no fold-overs */
    for (j = 0; j <= ny; j++)
        for (i = 0; i <= nx; i++) {
            /* boundary vertices move only along the boundary */
            int jx = (jit && i > 0 && i < nx) ? rng_int(r, 3) - 1 : 0;
            int jy = (jit && j > 0 && j < ny) ? rng_int(r, 3) - 1 : 0;
            px[j][i] = x0 + i * cell + jx + 0.5;
            py[j][i] = y0 + j * cell + jy + 0.5;
        }
    for (j = 0; j < ny; j++)
        for (i = 0; i < nx; i++) {
            float c[4];
            int flip = rng_int(r, 2);
            rand_color(r, c);
            if (!flip) {
                put_vertex(v + n++ * VF, px[j][i], py[j][i], 0, 1, c);
                put_vertex(v + n++ * VF, px[j + 1][i], py[j + 1][i], 0, 1, c);
                put_vertex(v + n++ * VF, px[j + 1][i + 1], py[j + 1][i + 1], 0, 1, c);
                put_vertex(v + n++ * VF, px[j][i], py[j][i], 0, 1, c);
                put_vertex(v + n++ * VF, px[j + 1][i + 1], py[j + 1][i + 1], 0, 1, c);
                put_vertex(v + n++ * VF, px[j][i + 1], py[j][i + 1], 0, 1, c);
            } else {
                put_vertex(v + n++ * VF, px[j][i], py[j][i], 0, 1, c);
                put_vertex(v + n++ * VF, px[j + 1][i], py[j + 1][i], 0, 1, c);
                put_vertex(v + n++ * VF, px[j][i + 1], py[j][i + 1], 0, 1, c);
                put_vertex(v + n++ * VF, px[j][i + 1], py[j][i + 1], 0, 1, c);
                put_vertex(v + n++ * VF, px[j + 1][i], py[j + 1][i], 0, 1, c);
                put_vertex(v + n++ * VF, px[j + 1][i + 1], py[j + 1][i + 1], 0, 1, c);
            }
        }
    return n;
}

/* Several meshes and free triangles with vertices on pixel centres. Also
   returns the mesh rectangles for the analytic check. */
typedef struct centre_scene {
    float v[6 * 32 * 32 * 4 * VF];
    int n;
    int mesh[4][4]; /* x0, y0, x1, y1 of the outer centres, image coords */
    int nmesh;
} centre_scene;

static void make_centre_scene(rng *r, centre_scene *cs) {
    int m;
    cs->n = 0;
    cs->nmesh = 4;
    for (m = 0; m < 4; m++) {
        int x0 = 8 + (m & 1) * 128, y0 = 8 + (m >> 1) * 128, cell = 4 + m * 2, nx = 104 / cell;
        cs->n += make_centre_mesh(r, cs->v + cs->n * VF, x0, y0, nx, nx, cell);
        cs->mesh[m][0] = x0; cs->mesh[m][1] = y0;
        cs->mesh[m][2] = x0 + nx * cell; cs->mesh[m][3] = y0 + nx * cell;
    }
}

typedef struct hedges { const float *v; int n; } hedges;

/* Is the centre of (x, y) exactly on a horizontal edge of some triangle? */
static int on_horizontal_edge(void *user, int x, int y) {
    const hedges *he = (const hedges *)user;
    int t, k;
    double cx = x + 0.5, cy = y + 0.5;
    for (t = 0; t + 2 < he->n; t += 3)
        for (k = 0; k < 3; k++) {
            const float *a = he->v + (t + k) * VF, *b = he->v + (t + (k + 1) % 3) * VF;
            double ay = (1.0 - a[1] / a[3]) * (H / 2), by = (1.0 - b[1] / b[3]) * (H / 2);
            double ax = (a[0] / a[3] + 1.0) * (W / 2), bx = (b[0] / b[3] + 1.0) * (W / 2);
            if (ay == cy && by == cy && cx >= fmin(ax, bx) && cx <= fmax(ax, bx)) return 1;
        }
    return 0;
}

/* api.h: "the fill rule is top-left in image coordinates". Checked without
   any GL: each jittered mesh tiles the rectangle between its outer centres,
   so exactly the centres with x in [x0, x1) and y in [y0, y1) (image
   coordinates, y down) are covered, each exactly once. */
Test(gl_conformance, fill_rule_top_left_analytic, .timeout = 60) {
    static centre_scene cs;
    static uint8_t st[W * H];
    rng r = { 0x5EED0003u };
    rast_context *ctx;
    rast_context_desc cd;
    rast_targets t;
    rast_state s = counting_state();
    rast_draw_desc d;
    rast_clear_desc c;
    int x, y, m, bad = 0, shown = 0;
    make_centre_scene(&r, &cs);
    memset(&cd, 0, sizeof cd);
    cr_assert_eq(rast_context_create(&cd, &ctx), RAST_OK);
    memset(&t, 0, sizeof t);
    t.stencil.ptr = st; t.stencil.width = W; t.stencil.height = H; t.stencil.stride = W;
    cr_assert_eq(rast_set_targets(ctx, &t), RAST_OK);
    memset(&c, 0, sizeof c);
    c.flags = RAST_CLEAR_STENCIL;
    rast_clear(ctx, &c);
    rast_set_state(ctx, &s);
    memset(&d, 0, sizeof d);
    d.primitive = RAST_TRIANGLES; d.vertices = cs.v; d.vertex_count = cs.n;
    d.stride = VF; d.num_varyings = 4;
    cr_assert_eq(rast_draw(ctx, &d), RAST_OK);
    cr_assert_eq(rast_finish(ctx), RAST_OK);
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            int want = 0;
            for (m = 0; m < cs.nmesh; m++)
                if (x >= cs.mesh[m][0] && x < cs.mesh[m][2] && y >= cs.mesh[m][1] && y < cs.mesh[m][3])
                    want = 1;
            if (st[y * W + x] != want) {
                if (shown++ < 12)
                    fprintf(stderr, "fill rule (api.h top-left): pixel (%d,%d) covered %u times, want %d\n",
                            x, y, st[y * W + x], want);
                bad++;
            }
        }
    rast_context_destroy(ctx);
    cr_expect_eq(bad, 0, "%d pixels violate api.h's top-left rule on meshes with vertices on "
                 "pixel centres (see stderr)", bad);
}

/* The same scene through llvmpipe drawn mirrored in y (GL window y = image
   y, read back unflipped): llvmpipe's rule then is top-left in image
   coordinates, with its own exact integer arithmetic. Must match exactly. */
Test(gl_conformance, fill_rule_vs_llvmpipe_mirrored, .timeout = 60) {
    pair *p = pair_create();
    static centre_scene cs;
    rng r = { 0x5EED0003u };
    rast_state s = counting_state();
    int bad, c;
    make_centre_scene(&r, &cs);
    p->mirror_gl = 1;
    pair_clear(p, black, 1.0f, 0);
    pair_draw(p, &s, RAST_TRIANGLES, cs.v, cs.n);
    pair_read(p);
    bad = compare_stencil(p, "fill rule (llvmpipe mirrored)", NULL, NULL, NULL);
    c = compare_color(p, "fill rule (llvmpipe mirrored)", 1, NULL, NULL);
    cr_expect_eq(bad, 0, "%d pixels differ from llvmpipe's top-left rule (mirrored scene)", bad);
    cr_expect_eq(c, 0, "%d pixels with colour off by more than 1/255", c);
    pair_destroy(p);
}

/* The plain comparison (GL read back and flipped): llvmpipe's rule is then
   bottom-left in image coordinates (see the top of the file). GL allows
   either, so differences are allowed exactly at centres lying on
   horizontal edges, and nowhere else; sloped and vertical edges through
   centres must agree. Prints how many such centres differ. */
Test(gl_conformance, fill_rule_vs_llvmpipe_flipped, .timeout = 60) {
    pair *p = pair_create();
    static centre_scene cs;
    rng r = { 0x5EED0003u };
    rast_state s = counting_state();
    hedges he;
    int bad, allowed = 0;
    make_centre_scene(&r, &cs);
    he.v = cs.v;
    he.n = cs.n;
    pair_clear(p, black, 1.0f, 0);
    pair_draw(p, &s, RAST_TRIANGLES, cs.v, cs.n);
    pair_read(p);
    bad = compare_stencil(p, "fill rule (llvmpipe flipped)", on_horizontal_edge, &he, &allowed);
    fprintf(stderr, "fill_rule_vs_llvmpipe_flipped: %d pixel centres on horizontal edges resolve "
            "differently (GL-allowed: llvmpipe is bottom-left in image coordinates)\n", allowed);
    cr_expect_eq(bad, 0, "%d pixels differ away from horizontal edges through centres", bad);
    pair_destroy(p);
}

/* ---- depth and stencil sequences ---------------------------------------- */

static rast_compare rand_compare(rng *r) { return (rast_compare)(1 + rng_int(r, 8)); }
static rast_stencil_op rand_op(rng *r) { return (rast_stencil_op)(1 + rng_int(r, 8)); }

static rast_stencil_face rand_face(rng *r) {
    rast_stencil_face f;
    memset(&f, 0, sizeof f);
    f.func = rand_compare(r);
    f.ref = (uint8_t)rng_int(r, 256);
    f.read_mask = rng_int(r, 3) == 0 ? 0u : RAST_MASK(rng_int(r, 256));
    f.write_mask = rng_int(r, 3) == 0 ? 0u : RAST_MASK(rng_int(r, 256));
    f.fail = rand_op(r);
    f.depth_fail = rand_op(r);
    f.pass = rand_op(r);
    return f;
}

/* Constant-depth triangles (z on a k/1024 grid): depth values and every
   depth-test outcome are exact on both sides, so stencil, depth and
   coverage must be identical; colours within 1/255. */
Test(gl_conformance, stencil_depth_sequences_exact, .timeout = 120) {
    pair *p = pair_create();
    static float v[120 * 3 * VF];
    rng r = { 0x5EED0004u };
    int seq;
    for (seq = 0; seq < 10; seq++) {
        int draw;
        char what[96];
        float clear_rgba[4];
        float clear_depth = (float)(rng_int(&r, 1025) / 1024.0);
        uint8_t clear_st = (uint8_t)rng_int(&r, 256);
        rand_color(&r, clear_rgba);
        pair_clear(p, clear_rgba, clear_depth, clear_st);
        for (draw = 0; draw < 8; draw++) {
            rast_state s;
            int n = make_soup(&r, v, 20 + rng_int(&r, 100), 1, 1);
            memset(&s, 0, sizeof s);
            s.stencil_test = rng_int(&r, 5) != 0;
            s.stencil_front = rand_face(&r);
            s.stencil_back = rng_int(&r, 2) ? rand_face(&r) : s.stencil_front;
            s.depth_test = rng_int(&r, 5) != 0;
            s.depth_func = rand_compare(&r);
            s.depth_write_disabled = rng_int(&r, 4) == 0;
            s.cull = (rast_cull)rng_int(&r, 4);
            s.front_face = rng_int(&r, 2) ? RAST_CW : RAST_CCW;
            s.color_write = rng_int(&r, 4) == 0 ? (unsigned)(1 + rng_int(&r, 15)) : 0u;
            pair_draw(p, &s, RAST_TRIANGLES, v, n);
        }
        pair_read(p);
        snprintf(what, sizeof what, "stencil/depth sequence %d", seq);
        {
            int bs = compare_stencil(p, what, NULL, NULL, NULL);
            int bd = compare_depth(p, what, 0.0f, NULL, NULL);
            int bc = compare_color(p, what, 1, NULL, NULL);
            cr_expect_eq(bs, 0, "%s: %d stencil values differ", what, bs);
            cr_expect_eq(bd, 0, "%s: %d depth values differ (constant depths must be exact)", what, bd);
            cr_expect_eq(bc, 0, "%s: %d colours off by more than 1/255", what, bc);
        }
    }
    pair_destroy(p);
}

/* Sloped depth planes, some with vertices on the 1/256 grid and some off
   it. Depth values may differ in the last bits (llvmpipe: float plane
   equation at the framebuffer origin; rast.h: double plane from the snapped
   first vertex) and by the snapping bound (see "interpolation slack"): depth
   must agree within the per-pixel tolerance everywhere it was written. A
   pixel may then resolve to a different surface only at a near tie: where
   GL's and rast's final depths agree within that tolerance. */
typedef struct depth_ctx { const pair *p; const slack_map *sm; } depth_ctx;
static int near_depth_tie(void *user, int x, int y) {
    const depth_ctx *dc = (const depth_ctx *)user;
    int i = y * W + x;
    return fabsf(dc->p->r_depth[i] - dc->p->g_depth[i]) <= dc->sm->depth[i];
}

Test(gl_conformance, depth_sloped_near_ties, .timeout = 120) {
    pair *p = pair_create();
    static float v[300 * 3 * VF];
    static slack_map sm;
    rng r = { 0x5EED0005u };
    int pass, total_ties = 0, slack_used = 0;
    double worst_ratio = 0;
    for (pass = 0; pass < 8; pass++) {
        rast_state s;
        depth_ctx dc;
        int n = make_soup(&r, v, 300, 0, pass & 1), bd, bc, ties, all;
        char what[80];
        static const rast_compare funcs[] = { RAST_LESS, RAST_LESS, RAST_LEQUAL, RAST_GREATER,
                                              RAST_GEQUAL, RAST_NOTEQUAL, RAST_LESS, RAST_GREATER };
        float clear_depth;
        memset(&s, 0, sizeof s);
        s.depth_test = 1;
        s.depth_func = funcs[pass];
        clear_depth = (s.depth_func == RAST_GREATER || s.depth_func == RAST_GEQUAL) ? 0.0f : 1.0f;
        snprintf(what, sizeof what, "sloped depth pass %d (func %d, %s grid)", pass,
                 (int)s.depth_func, (pass & 1) ? "1/256" : "1/4096");
        id_pass(p, &s, v, n / 3, clear_depth, 0, &sm);
        pair_clear(p, black, clear_depth, 0);
        pair_draw(p, &s, RAST_TRIANGLES, v, n);
        pair_read(p);
        dc.p = p;
        dc.sm = &sm;
        bd = compare_depth_slack(p, what, &sm, &worst_ratio);
        all = compare_color_slack(p, "(informational)", &sm, NULL, NULL, NULL);
        bc = compare_color_slack(p, what, &sm, near_depth_tie, &dc, &slack_used);
        ties = all - bc;
        total_ties += ties;
        cr_expect_eq(bd, 0, "%s: %d depth values differ by more than the tolerance", what, bd);
        cr_expect_eq(bc, 0, "%s: %d pixels resolved differently although depths differ", what, bc);
        cr_expect_leq(ties, W * H / 1000, "%s: %d near-tie pixels resolved differently: too many",
                      what, ties);
    }
    fprintf(stderr, "depth_sloped_near_ties: %d pixels resolved differently at depth near-ties; "
            "worst depth difference %.2f of its tolerance\n", total_ties, worst_ratio);
    pair_destroy(p);
}

/* ---- points -------------------------------------------------------------- */

/* n points with random colours, depths and w; every edge_every-th centre
   lies within `size` pixels of a target edge (inside), so that squares
   reach past it. */
static void random_points(rng *r, float *v, int n, int size, int edge_every) {
    int i;
    for (i = 0; i < n; i++) {
        float c[4];
        double x = rng_point_coord(r, 0, W), y = rng_point_coord(r, 0, H);
        if (i % edge_every == 0) {
            if (rng_int(r, 2)) x = rng_int(r, 2) ? rng_point_coord(r, 0, size) : rng_point_coord(r, W - size, W);
            else y = rng_int(r, 2) ? rng_point_coord(r, 0, size) : rng_point_coord(r, H - size, H);
        }
        rand_color(r, c);
        put_vertex(v + i * VF, x, y, (rng_int(r, 2047) - 1023) / 1024.0, rand_pow2_w(r), c);
    }
}

Test(gl_conformance, points_exact, .timeout = 120) {
    pair *p = pair_create();
    static float v[1500 * VF];
    rng r = { 0x5EED0006u };
    int size;
    pair_clear(p, black, 1.0f, 0);
    for (size = 1; size <= 8; size++) {
        rast_state s;
        int n = 1500 / size;
        random_points(&r, v, n, size, 7);
        memset(&s, 0, sizeof s);
        s.point_size = (float)size;
        s.depth_test = 1;
        s.depth_func = RAST_LESS;
        s.stencil_test = 1;
        s.stencil_front.func = RAST_ALWAYS;
        s.stencil_front.depth_fail = RAST_INCR_WRAP; /* count both outcomes */
        s.stencil_front.pass = RAST_INCR_WRAP;
        s.stencil_back = s.stencil_front;
        pair_draw(p, &s, RAST_POINTS, v, n);
    }
    pair_read(p);
    {
        int bs = compare_stencil(p, "points", NULL, NULL, NULL);
        int bd = compare_depth(p, "points", 0.0f, NULL, NULL);
        int bc = compare_color(p, "points", 1, NULL, NULL);
        cr_expect_eq(bs, 0, "points: %d pixels with a different coverage count", bs);
        cr_expect_eq(bd, 0, "points: %d depth values differ (constant depths must be exact)", bd);
        cr_expect_eq(bc, 0, "points: %d colours off by more than 1/255", bc);
    }
    pair_destroy(p);
}

/* Points through rast.h's splat path (RGBA8, depth test, no stencil,
   blending or callbacks: records of position, depth and colour only),
   sizes 1 to 8 near the target's edges and across a scissor rectangle
   whose edges cut squares and tiles: colour and depth equal llvmpipe's. */
Test(gl_conformance, splatted_points_exact, .timeout = 120) {
    pair *p = pair_create();
    static float v[1500 * VF];
    rng r = { 0x5EED0016u };
    int size, scissored;
    pair_clear(p, black, 1.0f, 0);
    for (scissored = 0; scissored < 2; scissored++)
        for (size = 1; size <= 8; size++) {
            rast_state s;
            int n = 1500 / size;
            random_points(&r, v, n, size, 5);
            memset(&s, 0, sizeof s);
            s.point_size = (float)size;
            s.depth_test = 1;
            s.depth_func = size & 1 ? RAST_LESS : RAST_LEQUAL;
            s.scissor_test = scissored;
            s.scissor[0] = 61; s.scissor[1] = 37; s.scissor[2] = W / 2; s.scissor[3] = H / 2;
            pair_draw(p, &s, RAST_POINTS, v, n);
        }
    pair_read(p);
    {
        int bd = compare_depth(p, "splatted points", 0.0f, NULL, NULL);
        int bc = compare_color(p, "splatted points", 1, NULL, NULL);
        cr_expect_eq(bd, 0, "splatted points: %d depth values differ (constant depths must be exact)", bd);
        cr_expect_eq(bc, 0, "splatted points: %d colours off by more than 1/255", bc);
    }
    pair_destroy(p);
}

/* GL: a point whose centre is outside the clip volume is discarded, even
   when its square would reach into the viewport (GL 4.6 core 13.7: "If the
   primitive under consideration is a point, then clipping passes it
   unchanged if it lies within the clip volume; otherwise, it is
   discarded"). */
Test(gl_conformance, points_centre_outside_discarded, .timeout = 60) {
    pair *p = pair_create();
    float v[64 * VF];
    rng r = { 0x5EED0007u };
    rast_state s = counting_state();
    int i, bad, drawn = 0;
    for (i = 0; i < 64; i++) {
        float c[4] = { 1, 1, 1, 1 };
        double x = rng_point_coord(&r, 16, W - 16), y = rng_point_coord(&r, 16, H - 16);
        switch (i & 3) {
        case 0: x = -(rng_int(&r, 3) + 0.25 + rng_int(&r, 60) / 256.0); break;
        case 1: x = W + rng_int(&r, 3) + 0.25 + rng_int(&r, 60) / 256.0; break;
        case 2: y = -(rng_int(&r, 3) + 0.25 + rng_int(&r, 60) / 256.0); break;
        default: y = H + rng_int(&r, 3) + 0.25 + rng_int(&r, 60) / 256.0; break;
        }
        put_vertex(v + i * VF, x, y, 0.0, 1.0f, c);
    }
    s.point_size = 8.0f;
    pair_clear(p, black, 1.0f, 0);
    pair_draw(p, &s, RAST_POINTS, v, 64);
    pair_read(p);
    for (i = 0; i < W * H; i++) drawn += p->g_st[i] != 0;
    fprintf(stderr, "points_centre_outside_discarded: llvmpipe drew %d pixels\n", drawn);
    bad = compare_stencil(p, "points outside", NULL, NULL, NULL);
    cr_expect_eq(bad, 0, "%d pixels differ for points with centres outside the viewport", bad);
    pair_destroy(p);
}

/* Points whose squares have pixel centres exactly on their border. GL
   leaves the tie to the implementation; each point must still cover exactly
   size x size pixels on both sides, shifted by at most one pixel per axis. */
Test(gl_conformance, points_on_pixel_boundaries, .timeout = 60) {
    pair *p = pair_create();
    float v[64 * VF];
    int i, n = 0, size, bad = 0, shifted = 0;
    for (size = 1; size <= 8; size++)
        for (i = 0; i < 4; i++) {
            /* odd sizes tie on integer coordinates, even on half-integers */
            double base_x = 16 + (size - 1) * 30, base_y = 20 + i * 60;
            double off = (size & 1) ? 0.0 : 0.5;
            float c[4] = { 1, 1, 1, 1 };
            /* case 0: tie in x and y; 1: in y only; 2: in x only; 3: none */
            double x = base_x + off + ((i & 1) ? 0.25 : 0.0);
            double y = base_y + off + ((i & 2) ? 0.25 : 0.0);
            put_vertex(v + n * VF, x, y, 0.0, 1.0f, c);
            n++;
        }
    pair_clear(p, black, 1.0f, 0);
    for (size = 1; size <= 8; size++) {
        rast_state s = counting_state();
        s.point_size = (float)size;
        pair_draw(p, &s, RAST_POINTS, v + (size - 1) * 4 * VF, 4);
    }
    pair_read(p);
    for (size = 1; size <= 8; size++)
        for (i = 0; i < 4; i++) {
            int bx = 16 + (size - 1) * 30, by = 20 + i * 60, x, y;
            int rc = 0, gc = 0, rminx = 1000, rminy = 1000, gminx = 1000, gminy = 1000;
            for (y = by - 12; y < by + 12; y++)
                for (x = bx - 12; x < bx + 12; x++) {
                    if (p->r_st[y * W + x]) { rc++; if (x < rminx) rminx = x; if (y < rminy) rminy = y; }
                    if (p->g_st[y * W + x]) { gc++; if (x < gminx) gminx = x; if (y < gminy) gminy = y; }
                }
            if (rc != size * size || gc != size * size || abs(rminx - gminx) > 1 ||
                abs(rminy - gminy) > 1 || (i == 3 && (rminx != gminx || rminy != gminy))) {
                fprintf(stderr, "point size %d case %d: rast %d px at (%d,%d), llvmpipe %d px at (%d,%d)\n",
                        size, i, rc, rminx, rminy, gc, gminx, gminy);
                bad++;
            } else if (rminx != gminx || rminy != gminy) {
                fprintf(stderr, "point size %d case %d: tie broken differently: rast square at "
                        "(%d,%d), llvmpipe at (%d,%d) (GL-allowed)\n",
                        size, i, rminx, rminy, gminx, gminy);
                shifted++;
            }
        }
    fprintf(stderr, "points_on_pixel_boundaries: %d of 32 tie cases broken differently\n", shifted);
    cr_expect_eq(bad, 0, "%d tie points are not size x size or moved by more than a pixel", bad);
    pair_destroy(p);
}

/* ---- clipping: near plane, w = 0 and the guard band ---------------------- */

typedef struct clip_poly { int n; double x[16], y[16]; } clip_poly;

/* The exact visible polygon of a clip-space triangle in image coordinates:
   clipped (double precision) at near z >= -w and far z <= w (together they
   imply w >= 0); x/y clipping does not move any edge a centre could lie on. */
static void exact_clip(const float *v, clip_poly *out) {
    double in[16][4], tmp[16][4];
    int n = 3, plane, i, k;
    for (i = 0; i < 3; i++)
        for (k = 0; k < 4; k++) in[i][k] = v[i * VF + k];
    for (plane = 0; plane < 2; plane++) {
        int m = 0;
        for (i = 0; i < n; i++) {
            const double *a = in[i], *b = in[(i + 1) % n];
            double da = plane == 0 ? a[2] + a[3] : a[3] - a[2];
            double db = plane == 0 ? b[2] + b[3] : b[3] - b[2];
            if (da >= 0) { memcpy(tmp[m++], a, sizeof tmp[0]); }
            if ((da >= 0) != (db >= 0)) {
                double t = da / (da - db);
                for (k = 0; k < 4; k++) tmp[m][k] = a[k] + (b[k] - a[k]) * t;
                m++;
            }
        }
        n = m;
        memcpy(in, tmp, sizeof tmp);
    }
    out->n = 0;
    for (i = 0; i < n; i++) {
        if (in[i][3] <= 1e-30) continue;
        out->x[out->n] = (in[i][0] / in[i][3] + 1.0) * (W / 2);
        out->y[out->n] = (1.0 - in[i][1] / in[i][3]) * (H / 2);
        out->n++;
    }
}

static double seg_dist(double px, double py, double ax, double ay, double bx, double by) {
    double dx = bx - ax, dy = by - ay, l2 = dx * dx + dy * dy, t;
    if (l2 <= 0) return hypot(px - ax, py - ay);
    t = ((px - ax) * dx + (py - ay) * dy) / l2;
    if (t < 0) t = 0;
    if (t > 1) t = 1;
    return hypot(px - (ax + t * dx), py - (ay + t * dy));
}

static int needs_clip(const float *v) {
    int i;
    for (i = 0; i < 3; i++) {
        const float *q = v + i * VF;
        if (!(q[3] > 0) || fabsf(q[0]) > q[3] || fabsf(q[1]) > q[3] || fabsf(q[2]) > q[3]) return 1;
    }
    return 0;
}

typedef struct clip_set { clip_poly poly[400]; int n; } clip_set;

static int near_clipped_edge(void *user, int x, int y) {
    const clip_set *cs = (const clip_set *)user;
    double cx = x + 0.5, cy = y + 0.5;
    int t, k;
    for (t = 0; t < cs->n; t++) {
        const clip_poly *q = &cs->poly[t];
        for (k = 0; k < q->n; k++) {
            int k1 = (k + 1) % q->n;
            if (seg_dist(cx, cy, q->x[k], q->y[k], q->x[k1], q->y[k1]) < CLIP_EPS) return 1;
        }
    }
    return 0;
}

static void run_clip_case(pair *p, const char *what, const float *v, int ntri, int max_allowed) {
    static clip_set cs;
    rast_state s = counting_state();
    int t, bad, allowed = 0, bc, clipped = 0;
    cs.n = 0;
    for (t = 0; t < ntri && cs.n < 400; t++)
        if (needs_clip(v + t * 3 * VF)) {
            exact_clip(v + t * 3 * VF, &cs.poly[cs.n++]);
            clipped++;
        }
    pair_clear(p, black, 1.0f, 0);
    pair_draw(p, &s, RAST_TRIANGLES, v, ntri * 3);
    pair_read(p);
    bad = compare_stencil(p, what, near_clipped_edge, &cs, &allowed);
    bc = compare_color(p, what, 1, near_clipped_edge, &cs);
    fprintf(stderr, "%s: %d of %d triangles need clipping; %d coverage differences within %g px "
            "of a clipped edge (allowed)\n", what, clipped, ntri, allowed, CLIP_EPS);
    cr_expect_eq(bad, 0, "%s: %d coverage differences away from clipped edges", what, bad);
    cr_expect_leq(allowed, max_allowed, "%s: %d coverage differences along clipped edges "
                  "(more than %d)", what, allowed, max_allowed);
    cr_expect_eq(bc, 0, "%s: %d colours off by more than 1/255 away from clipped edges", what, bc);
}

/* Perspective scenes with geometry behind the eye: triangles crossing the
   near plane and w = 0 (glFrustum-like projection, near 1, far 100). */
Test(gl_conformance, clip_near_and_w0, .timeout = 120) {
    pair *p = pair_create();
    static float v[200 * 3 * VF];
    rng r = { 0x5EED0008u };
    int pass;
    for (pass = 0; pass < 4; pass++) {
        int t, k;
        char what[64];
        for (t = 0; t < 200; t++) {
            double ex = rng_range(&r, -8, 8), ey = rng_range(&r, -8, 8), ez = rng_range(&r, -30, 3);
            for (k = 0; k < 3; k++) {
                float c[4], *q = v + (t * 3 + k) * VF;
                double x = ex + rng_range(&r, -6, 6), y = ey + rng_range(&r, -6, 6);
                double z = ez + rng_range(&r, -6, 6);
                const double n_ = 1.0, f_ = 100.0;
                rand_color(&r, c);
                q[0] = (float)x;
                q[1] = (float)y;
                q[2] = (float)(((f_ + n_) / (n_ - f_)) * z + 2.0 * f_ * n_ / (n_ - f_));
                q[3] = (float)(-z);
                memcpy(q + 4, c, sizeof c);
            }
        }
        snprintf(what, sizeof what, "near/w=0 clipping pass %d", pass);
        run_clip_case(p, what, v, 200, 200);
    }
    pair_destroy(p);
}

/* Huge triangles: vertices up to 8000 pixels outside the viewport (inside
   rast.h's guard band, so rast does not clip; llvmpipe with a depth/stencil
   buffer clips to the viewport) and some far beyond (both clip). */
Test(gl_conformance, clip_guard_band, .timeout = 120) {
    pair *p = pair_create();
    static float v[120 * 3 * VF];
    rng r = { 0x5EED0009u };
    int pass;
    for (pass = 0; pass < 4; pass++) {
        int t, k;
        char what[64];
        int reach = pass < 2 ? 8000 : 200000;
        for (t = 0; t < 120; t++) {
            float c[4];
            rand_color(&r, c);
            for (k = 0; k < 3; k++) {
                double x = rng_coord(&r, -reach, W + reach), y = rng_coord(&r, -reach, H + reach);
                if (k == 0 && t % 2 == 0) { x = rng_coord(&r, 0, W); y = rng_coord(&r, 0, H); }
                put_vertex(v + (t * 3 + k) * VF, x, y, rng_range(&r, -0.9, 0.9), rand_pow2_w(&r), c);
            }
        }
        snprintf(what, sizeof what, "guard band pass %d (reach %d px)", pass, reach);
        run_clip_case(p, what, v, 120, 1200);
    }
    pair_destroy(p);
}
