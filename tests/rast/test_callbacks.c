/* Vertex and fragment callbacks.

   Vertex callback contract (api.h): reads vertex `index`, writes up to
   max_out outputs and returns how many; 0 drops every primitive using the
   vertex; points: each output is a point; lines and triangles: drawn once
   per layer k < the smallest count of their vertices, from output k.
   Fragment callback: returns 0 to discard; a discarded fragment changes
   nothing (GL: discard happens before the stencil and depth tests, so not
   even the stencil fail op runs). */
#include "../test_util.h"

enum { CW_ = 64, CH_ = 64 };

/* Input vertices for the callback tests are (window x, window y, id): the
   callback does the projection, so a wrong `vertex` pointer or `index`
   shows up as misplaced geometry. */
typedef struct vcb {
    int counts[64];          /* outputs to emit per vertex index (-1: 1) */
    double shift_x;          /* layer k is shifted by k * shift_x pixels */
    int seen_max_out;        /* max_out the callback was given */
    int bad_pointer;         /* vertex pointer / index mismatch seen */
    const float *base;       /* the draw's vertex array */
    int stride;
} vcb;

static int vertex_cb(void *user, const float *vertex, int index, rast_vertex_out *out,
                     int max_out) {
    vcb *u = (vcb *)user;
    int n = u->counts[index], k;
    __atomic_store_n(&u->seen_max_out, max_out, __ATOMIC_RELAXED);
    if (vertex != u->base + (size_t)index * u->stride || vertex[2] != (float)index)
        __atomic_store_n(&u->bad_pointer, 1, __ATOMIC_RELAXED);
    if (n > max_out) n = max_out;
    for (k = 0; k < n; k++) {
        float c[4];
        tu_clip_from_window(c, vertex[0] + k * u->shift_x, vertex[1], 0.0, 1.0 + 0.5 * k, CW_,
                            CH_);
        memcpy(out[k].position, c, sizeof c);
        out[k].varyings[0] = (float)index / 64.0f;
        out[k].varyings[1] = (float)k;
        out[k].varyings[2] = 0.5f;
        out[k].varyings[3] = 1.0f;
    }
    return n;
}

static void draw_cb(rast_context *ctx, rast_primitive prim, const float *v, int nv,
                    const uint32_t *idx, int ni, vcb *u, int max_outputs) {
    rast_state s;
    rast_draw_desc d;
    tu_state_count(&s);
    s.vertex_fn = vertex_cb;
    s.vertex_user = u;
    s.max_vertex_outputs = max_outputs;
    tu_set_state(ctx, &s);
    memset(&d, 0, sizeof d);
    d.primitive = prim;
    d.vertices = v;
    d.vertex_count = nv;
    d.stride = 3;
    d.num_varyings = 4;
    d.indices = idx;
    d.index_count = ni;
    u->base = v;
    u->stride = 3;
    cr_assert_eq(rast_draw(ctx, &d), RAST_OK);
    tu_finish(ctx);
}

/* A 3x3 grid of vertices (ids 0..8) forming 8 triangles, indexed. The
   callback emits 0 outputs for vertex 4 (the centre, used by 6 of the 8
   triangles) and 1 for the rest: exactly the 2 triangles not using vertex
   4 are drawn, compared per pixel with the fill-rule reference. With 1
   output everywhere, all 8 are drawn (sanity). */
Test(callbacks, vertex_zero_outputs_drop_primitives) {
    static const uint32_t idx[24] = {0, 1, 4, 0, 4, 3, 1, 2, 5, 1, 5, 4,
                                     3, 4, 7, 3, 7, 6, 4, 5, 8, 4, 8, 7};
    float v[9 * 3];
    vcb u;
    rast_context *ctx = tu_ctx(2, 16);
    tu_fb fb;
    tu_check chk = {0, {0}};
    int i, drop, x, y, t, dropped_tris = 0;
    for (i = 0; i < 9; i++) {
        v[3 * i] = (float)(4.25 + 27.5 * (i % 3));
        v[3 * i + 1] = (float)(3.75 + 27.5 * (i / 3));
        v[3 * i + 2] = (float)i;
    }
    tu_fb_init(&fb, CW_, CH_, TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    for (drop = 0; drop < 2; drop++) {
        memset(&u, 0, sizeof u);
        for (i = 0; i < 9; i++) u.counts[i] = 1;
        if (drop) u.counts[4] = 0;
        memset(fb.stencil, 0, CW_ * CH_);
        draw_cb(ctx, RAST_TRIANGLES, v, 9, idx, 24, &u, 0);
        cr_assert_eq(u.bad_pointer, 0, "callback got a vertex pointer not at base + index*stride");
        cr_assert_eq(u.seen_max_out, 1, "max_vertex_outputs 0 means 1, got %d", u.seen_max_out);
        for (y = 0; y < CH_; y++)
            for (x = 0; x < CW_; x++) {
                int ex = 0;
                for (t = 0; t < 8; t++) {
                    double tri[6];
                    int k, uses4 = 0;
                    for (k = 0; k < 3; k++) {
                        tri[2 * k] = v[3 * idx[3 * t + k]];
                        tri[2 * k + 1] = v[3 * idx[3 * t + k] + 1];
                        uses4 |= idx[3 * t + k] == 4;
                    }
                    if (drop && uses4) continue;
                    ex += tu_ref_covers(tri, x + 0.5, y + 0.5);
                }
                TU_CHECK(&chk, *tu_sten(&fb, x, y) == ex, "drop %d: (%d,%d) = %d expected %d",
                         drop, x, y, *tu_sten(&fb, x, y), ex);
            }
    }
    for (t = 0; t < 8; t++) dropped_tris += idx[3 * t] == 4 || idx[3 * t + 1] == 4 || idx[3 * t + 2] == 4;
    cr_assert(dropped_tris > 0 && dropped_tris < 8);
    TU_CHECK_DONE(&chk);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* Points and lines with 0, 1 or 2 outputs per vertex (max_vertex_outputs 2):
   points: one point per output (layer 1 shifted by 20 px); lines: drawn
   once per layer below the smaller count of their two vertices. */
Test(callbacks, vertex_outputs_points_and_lines) {
    float v[6 * 3];
    vcb u;
    rast_context *ctx = tu_ctx(1, 16);
    tu_fb fb;
    tu_check chk = {0, {0}};
    int i, x, y;
    /* six points in the left column, different counts */
    static const int counts[6] = {0, 1, 2, 2, 1, 0};
    tu_fb_init(&fb, CW_, CH_, TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    for (i = 0; i < 6; i++) {
        v[3 * i] = 5.3f;
        v[3 * i + 1] = (float)(4.3 + 10 * i);
        v[3 * i + 2] = (float)i;
    }
    memset(&u, 0, sizeof u);
    memcpy(u.counts, counts, sizeof counts);
    u.shift_x = 20;
    draw_cb(ctx, RAST_POINTS, v, 6, NULL, 0, &u, 2);
    cr_assert_eq(u.seen_max_out, 2);
    for (y = 0; y < CH_; y++)
        for (x = 0; x < CW_; x++) {
            int ex = 0;
            for (i = 0; i < 6; i++) {
                int k;
                for (k = 0; k < counts[i]; k++)
                    ex += x == 5 + 20 * k && y == 4 + 10 * i; /* size-1 point, no ties */
            }
            TU_CHECK(&chk, *tu_sten(&fb, x, y) == ex, "points: (%d,%d) = %d expected %d", x, y,
                     *tu_sten(&fb, x, y), ex);
        }
    /* lines (0,1) (2,3) (4,5) as horizontal-ish segments: layers min(count) =
       0, 2, 0 -> only the middle line, twice (shifted copy) */
    for (i = 0; i < 6; i++) {
        v[3 * i] = (float)(i % 2 ? 15.5 : 2.5);
        v[3 * i + 1] = (float)(10.5 + 20 * (i / 2));
    }
    memset(fb.stencil, 0, CW_ * CH_);
    draw_cb(ctx, RAST_LINES, v, 6, NULL, 0, &u, 2);
    for (y = 0; y < CH_; y++)
        for (x = 0; x < CW_; x++) {
            int in_line = y == 30 && ((x >= 3 && x <= 14) || (x >= 23 && x <= 34));
            int maybe = y == 30 && (x == 2 || x == 15 || x == 22 || x == 35); /* end pixels */
            int got = *tu_sten(&fb, x, y);
            if (maybe) TU_CHECK(&chk, got <= 1, "lines: (%d,%d) = %d", x, y, got);
            else TU_CHECK(&chk, got == in_line, "lines: (%d,%d) = %d expected %d", x, y, got,
                          in_line);
        }
    TU_CHECK_DONE(&chk);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* Triangles drawn once per layer k < min count: a triangle whose vertices
   emit (2, 2, 2) is drawn twice (layer 1 shifted by 30 px and at w = 1.5,
   same window position), one with (2, 1, 2) once, with (2, 0, 2) never. */
Test(callbacks, vertex_outputs_triangle_layers) {
    float v[9 * 3];
    vcb u;
    rast_context *ctx = tu_ctx(3, 16);
    tu_fb fb;
    tu_check chk = {0, {0}};
    static const int counts[9] = {2, 2, 2, 2, 1, 2, 2, 0, 2};
    static const double tri[3][2] = {{2.25, 2.5}, {20.75, 4.25}, {6.5, 17.75}};
    int i, x, y, l;
    tu_fb_init(&fb, CW_, CH_, TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    for (i = 0; i < 9; i++) {
        v[3 * i] = (float)tri[i % 3][0];
        v[3 * i + 1] = (float)(tri[i % 3][1] + 20 * (i / 3));
        v[3 * i + 2] = (float)i;
    }
    memset(&u, 0, sizeof u);
    memcpy(u.counts, counts, sizeof counts);
    u.shift_x = 30;
    draw_cb(ctx, RAST_TRIANGLES, v, 9, NULL, 0, &u, 4);
    cr_assert_eq(u.seen_max_out, 4);
    cr_assert_eq(u.bad_pointer, 0);
    for (y = 0; y < CH_; y++)
        for (x = 0; x < CW_; x++) {
            int ex = 0;
            for (l = 0; l < 3; l++) {
                int layers = l == 0 ? 2 : l == 1 ? 1 : 0, k, j;
                for (k = 0; k < layers; k++) {
                    double t6[6];
                    for (j = 0; j < 3; j++) {
                        t6[2 * j] = tri[j][0] + 30 * k;
                        t6[2 * j + 1] = tri[j][1] + 20 * l;
                    }
                    ex += tu_ref_covers(t6, x + 0.5, y + 0.5);
                }
            }
            TU_CHECK(&chk, *tu_sten(&fb, x, y) == ex, "(%d,%d) = %d expected %d", x, y,
                     *tu_sten(&fb, x, y), ex);
        }
    TU_CHECK_DONE(&chk);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* The callback's varyings reach the default colour path (num_varyings 4 =
   colour): each pixel of the two layers carries (index/64, layer, .5, 1). */
Test(callbacks, vertex_outputs_carry_varyings) {
    float v[3 * 3];
    vcb u;
    rast_context *ctx = tu_ctx(2, 16);
    tu_fb fb;
    rast_state s;
    rast_draw_desc d;
    tu_check chk = {0, {0}};
    static const double tri[3][2] = {{2.25, 2.5}, {20.75, 4.25}, {6.5, 17.75}};
    int i, x, y;
    long n = 0;
    tu_fb_init(&fb, CW_, CH_, TU_COLOR32F);
    tu_fb_bind(ctx, &fb);
    for (i = 0; i < 3; i++) {
        v[3 * i] = (float)tri[i][0];
        v[3 * i + 1] = (float)tri[i][1];
        v[3 * i + 2] = (float)i;
    }
    memset(&u, 0, sizeof u);
    u.counts[0] = u.counts[1] = u.counts[2] = 2;
    u.shift_x = 30;
    u.base = v;
    u.stride = 3;
    memset(&s, 0, sizeof s);
    s.vertex_fn = vertex_cb;
    s.vertex_user = &u;
    s.max_vertex_outputs = 2;
    s.shading = RAST_FLAT; /* last vertex: index 2 */
    tu_set_state(ctx, &s);
    memset(&d, 0, sizeof d);
    d.vertices = v;
    d.vertex_count = 3;
    d.stride = 3;
    d.num_varyings = 4;
    cr_assert_eq(rast_draw(ctx, &d), RAST_OK);
    tu_finish(ctx);
    for (y = 0; y < CH_; y++)
        for (x = 0; x < CW_; x++) {
            const float *c = tu_pxf(&fb, x, y);
            if (c[3] == 0) continue;
            n++;
            TU_CHECK(&chk, c[0] == 2.0f / 64 && c[1] == (x >= 30 ? 1.0f : 0.0f) && c[2] == 0.5f,
                     "(%d,%d) colour %g %g %g", x, y, c[0], c[1], c[2]);
        }
    TU_CHECK_DONE(&chk);
    cr_assert(n > 200, "drew %ld", n);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

/* ---- fragment callback ------------------------------------------------------ */

/* Writes (x/64, y/64, front, 1) and discards on a checkerboard. */
static int frag_checker(void *user, const rast_fragment_in *in, float rgba[4]) {
    (void)user;
    if (((in->x + in->y) & 1) == 0) return 0;
    rgba[0] = in->x / 64.0f;
    rgba[1] = in->y / 64.0f;
    rgba[2] = in->front_facing ? 1.0f : 0.0f;
    rgba[3] = 1.0f;
    return 1;
}

/* Discarded fragments leave colour, depth and stencil untouched, even with
   stencil ops on every path (fail op with func NEVER, pass op with
   ALWAYS); kept fragments write the callback's colour at their own pixel,
   and front_facing follows the winding (left quad CCW in NDC = front). */
Test(callbacks, fragment_discard_touches_nothing) {
    enum { W = 32, H = 16 };
    rast_context *ctx = tu_ctx(2, 16);
    tu_fb fb;
    tu_check chk = {0, {0}};
    const double quads[24] = {0, 0, 0, 16, 16, 16, 0, 0, 16, 16, 16, 0,
                              16, 0, 32, 0, 32, 16, 16, 0, 32, 16, 16, 16};
    int pass, x, y;
    tu_fb_init(&fb, W, H, TU_COLOR32F | TU_DEPTH | TU_STENCIL);
    tu_fb_bind(ctx, &fb);
    for (pass = 0; pass < 2; pass++) {
        rast_state s;
        memset(&s, 0, sizeof s);
        s.fragment_fn = frag_checker;
        s.stencil_test = 1;
        s.stencil_front.func = pass ? RAST_ALWAYS : RAST_NEVER;
        s.stencil_front.fail = RAST_INVERT;
        s.stencil_front.depth_fail = RAST_INVERT;
        s.stencil_front.pass = RAST_INVERT;
        s.stencil_back = s.stencil_front;
        s.depth_test = 1;
        s.depth_func = RAST_ALWAYS;
        memset(fb.stencil, 0x5A, W * H);
        {
            int i;
            for (i = 0; i < W * H; i++) fb.depth[i] = 0.75f;
            for (i = 0; i < 4 * W * H; i++) fb.rgba32f[i] = -1.0f;
        }
        tu_set_state(ctx, &s);
        tu_draw_tris_px(ctx, W, H, quads, 4, 0.0);
        for (y = 0; y < H; y++)
            for (x = 0; x < W; x++) {
                int kept = (x + y) & 1;
                const float *c = tu_pxf(&fb, x, y);
                uint8_t es = kept ? (uint8_t)~0x5A : 0x5A;
                float ed = kept && pass ? 0.5f : 0.75f;
                TU_CHECK(&chk, *tu_sten(&fb, x, y) == es, "pass %d (%d,%d) stencil 0x%02x, "
                         "expected 0x%02x", pass, x, y, *tu_sten(&fb, x, y), es);
                TU_CHECK(&chk, *tu_depth(&fb, x, y) == ed, "pass %d (%d,%d) depth %g expected %g",
                         pass, x, y, *tu_depth(&fb, x, y), ed);
                if (kept && pass)
                    TU_CHECK(&chk, c[0] == x / 64.0f && c[1] == y / 64.0f &&
                                       c[2] == (x < 16 ? 1.0f : 0.0f) && c[3] == 1.0f,
                             "(%d,%d) colour %g %g %g %g", x, y, c[0], c[1], c[2], c[3]);
                else
                    TU_CHECK(&chk, c[0] == -1.0f && c[3] == -1.0f, "pass %d (%d,%d) colour "
                             "written for a %s fragment", pass, x, y,
                             kept ? "stencil-failed" : "discarded");
            }
    }
    TU_CHECK_DONE(&chk);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}

typedef struct deriv_rec {
    int hits, has;
    float v[3], dx[3], dy[3];
} deriv_rec;

static int frag_deriv(void *user, const rast_fragment_in *in, float rgba[4]) {
    deriv_rec *r = (deriv_rec *)user + in->y * CW_ + in->x;
    int k;
    r->hits++;
    r->has = in->ddx != NULL && in->ddy != NULL;
    for (k = 0; k < 3; k++) {
        r->v[k] = in->varyings[k];
        if (r->has) {
            r->dx[k] = in->ddx[k];
            r->dy[k] = in->ddy[k];
        }
    }
    rgba[0] = rgba[1] = rgba[2] = rgba[3] = 1;
    return 1;
}

/* fragment_derivatives: for varyings that are linear in window position
   (w = 1 everywhere), ddx / ddy equal the analytic slopes per pixel in x
   and in image y (rows growing downwards, like rast_fragment_in.y). Without
   the flag, ddx and ddy are NULL. */
Test(callbacks, fragment_derivatives_of_linear_varyings) {
    static const double slope[3][2] = {{0.25, -0.5}, {-1.75, 0.125}, {0.0, 3.0}};
    static const double tri[3][2] = {{-10, -8}, {90, 5}, {12, 85}};
    rast_context *ctx = tu_ctx(2, 16);
    tu_fb fb;
    tu_check chk = {0, {0}};
    deriv_rec *rec = calloc(CW_ * CH_, sizeof *rec);
    float v[3 * 7];
    int flag, i, k, x, y;
    long n = 0;
    cr_assert_not_null(rec);
    tu_fb_init(&fb, CW_, CH_, TU_COLOR8);
    tu_fb_bind(ctx, &fb);
    for (i = 0; i < 3; i++) {
        tu_clip_from_window(v + 7 * i, tri[i][0], tri[i][1], 0.0, 1.0, CW_, CH_);
        for (k = 0; k < 3; k++)
            v[7 * i + 4 + k] = (float)(slope[k][0] * tri[i][0] + slope[k][1] * tri[i][1] + k);
    }
    for (flag = 0; flag < 2; flag++) {
        rast_state s;
        memset(rec, 0, sizeof *rec * CW_ * CH_);
        memset(&s, 0, sizeof s);
        s.fragment_fn = frag_deriv;
        s.fragment_user = rec;
        s.fragment_derivatives = flag;
        tu_set_state(ctx, &s);
        cr_assert_eq(tu_draw(ctx, RAST_TRIANGLES, v, 3, 3), RAST_OK);
        tu_finish(ctx);
        for (y = 0; y < CH_; y++)
            for (x = 0; x < CW_; x++) {
                const deriv_rec *r = rec + y * CW_ + x;
                if (!r->hits) continue;
                n++;
                TU_CHECK(&chk, r->has == flag, "flag %d: ddx/ddy %s", flag,
                         r->has ? "given" : "NULL");
                for (k = 0; k < 3; k++) {
                    double val = slope[k][0] * (x + 0.5) + slope[k][1] * (y + 0.5) + k;
                    TU_CHECK(&chk, fabs(r->v[k] - val) < 1e-4, "(%d,%d) varying %d = %g, "
                             "expected %g", x, y, k, r->v[k], val);
                    if (flag && r->has)
                        TU_CHECK(&chk, fabs(r->dx[k] - slope[k][0]) < 1e-4 &&
                                           fabs(r->dy[k] - slope[k][1]) < 1e-4,
                                 "(%d,%d) varying %d: ddx %g ddy %g, expected %g %g", x, y, k,
                                 r->dx[k], r->dy[k], slope[k][0], slope[k][1]);
                }
            }
    }
    TU_CHECK_DONE(&chk);
    cr_assert(n > 2000);
    free(rec);
    rast_context_destroy(ctx);
    tu_fb_free(&fb);
}
