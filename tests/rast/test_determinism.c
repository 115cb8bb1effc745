/* Determinism: the same scene gives byte-identical colour, depth, stencil
   and accumulation buffers for every thread count (1, 2, 3, 8), tile size
   (16, 32, 64), a tiny batch size (forcing flushes in the middle of
   draws) and a caller-supplied parallel_for that runs jobs in reverse or
   interleaved order on the calling thread.

   The scenes are built so that order matters everywhere: blending (not
   commutative), depth LEQUAL/GREATER with ties, stencil INCR_WRAP/INVERT,
   clears and accumulation between draws, overlapping points and lines,
   vertex callbacks emitting 2 outputs, fragment callbacks that discard.
   A rasteriser that lets two threads touch one pixel, reorders primitives
   inside a tile, or computes interpolants relative to tile origins will
   produce different bytes for some configuration. */
#include "../test_util.h"

enum { DW = 100, DH = 76 }; /* not multiples of any tile size */

typedef struct scene_data {
    float *tris;  /* NT triangles: 3 vertices of 4 + 4 floats */
    int nt;
    float *pts;   /* NP points: 4 + 4 floats */
    int np;
    float *lines; /* NL lines: 2 vertices of 4 + 4 */
    int nl;
    float *cbv;   /* callback input vertices: x, y, z, r (window) */
    int ncb;
    uint32_t *idx;
    int nidx;
} scene_data;

static scene_data g_scene;

static void make_scene(void) {
    tu_rng rng = tu_rng_make(123456);
    int i, k;
    scene_data *s = &g_scene;
    if (s->tris) return;
    s->nt = 3000;
    s->np = 100000;
    s->nl = 1500;
    s->ncb = 600;
    s->nidx = 3 * 400;
    s->tris = malloc(sizeof(float) * 8 * 3 * (size_t)s->nt);
    s->pts = malloc(sizeof(float) * 8 * (size_t)s->np);
    s->lines = malloc(sizeof(float) * 8 * 2 * (size_t)s->nl);
    s->cbv = malloc(sizeof(float) * 4 * (size_t)s->ncb);
    s->idx = malloc(sizeof(uint32_t) * (size_t)s->nidx);
    cr_assert(s->tris && s->pts && s->lines && s->cbv && s->idx);
    for (i = 0; i < s->nt; i++) {
        /* mostly small and medium triangles, some huge (clipped), some
           crossing the near plane, shared z values to create depth ties */
        int kind = tu_rng_int(&rng, 0, 9);
        double cx = tu_rng_range(&rng, -10, DW + 10), cy = tu_rng_range(&rng, -10, DH + 10);
        double size = kind < 7 ? tu_rng_range(&rng, 1, 8) : kind < 9 ? 25 : 20000;
        if (kind == 9 && tu_rng_int(&rng, 0, 4)) size = 5; /* few huge ones */
        double z = (tu_rng_int(&rng, 0, 7) - 3.5) / 4.0;
        for (k = 0; k < 3; k++) {
            float *o = s->tris + 8 * (3 * i + k);
            double w = kind == 7 ? tu_rng_range(&rng, 0.2, 3.0) : 1.0;
            tu_clip_from_window(o, cx + tu_rng_range(&rng, -size, size),
                                cy + tu_rng_range(&rng, -size, size), z, w, DW, DH);
            if (kind == 8 && k == 0) o[2] = -1.5f * o[3]; /* crosses the near plane */
            o[4] = tu_rng_float(&rng);
            o[5] = tu_rng_float(&rng);
            o[6] = tu_rng_float(&rng);
            o[7] = (float)tu_rng_range(&rng, 0.2, 0.9);
        }
    }
    for (i = 0; i < s->np; i++) {
        float *o = s->pts + 8 * i;
        tu_clip_from_window(o, tu_rng_range(&rng, -2, DW + 2), tu_rng_range(&rng, -2, DH + 2),
                            (tu_rng_int(&rng, 0, 4) - 2) / 3.0, tu_rng_range(&rng, 0.5, 2), DW, DH);
        for (k = 4; k < 8; k++) o[k] = tu_rng_float(&rng);
    }
    for (i = 0; i < 2 * s->nl; i++) {
        float *o = s->lines + 8 * i;
        tu_clip_from_window(o, tu_rng_range(&rng, -20, DW + 20), tu_rng_range(&rng, -20, DH + 20),
                            tu_rng_range(&rng, -0.9, 0.9), tu_rng_range(&rng, 0.5, 2), DW, DH);
        for (k = 4; k < 8; k++) o[k] = tu_rng_float(&rng);
    }
    /* callback vertices in clusters of 3 (small triangles); each indexed
       triangle uses the vertices of one cluster in a random order, so
       vertices are shared between triangles */
    for (i = 0; i < s->ncb; i++) {
        float *o = s->cbv + 4 * i;
        if (i % 3 == 0) {
            o[0] = (float)tu_rng_range(&rng, -5, DW + 5);
            o[1] = (float)tu_rng_range(&rng, -5, DH + 5);
        } else {
            o[0] = o[-4 * (i % 3)] + (float)tu_rng_range(&rng, -9, 9);
            o[1] = o[-4 * (i % 3) + 1] + (float)tu_rng_range(&rng, -9, 9);
        }
        o[2] = (float)tu_rng_range(&rng, -0.8, 0.8);
        o[3] = tu_rng_float(&rng);
    }
    for (i = 0; i < s->nidx; i += 3) {
        int c = 3 * tu_rng_int(&rng, 0, s->ncb / 3 - 1), r = tu_rng_int(&rng, 0, 2);
        s->idx[i] = (uint32_t)(c + r);
        s->idx[i + 1] = (uint32_t)(c + (r + 1 + (i & 1)) % 3);
        s->idx[i + 2] = (uint32_t)(c + (r + 2 - (i & 1)) % 3);
    }
}

/* Pure vertex program with 2 outputs: the vertex itself and a copy moved by
   (7, -5) pixels at another w; vertex 5 of every 97 emits nothing (drops
   its primitives), 1 of every 13 emits only one. */
static int det_vertex(void *user, const float *vertex, int index, rast_vertex_out *out,
                      int max_out) {
    int n = index % 97 == 5 ? 0 : index % 13 == 0 ? 1 : 2, k;
    (void)user;
    if (n > max_out) n = max_out;
    for (k = 0; k < n; k++) {
        tu_clip_from_window(out[k].position, vertex[0] + 7 * k, vertex[1] - 5 * k, vertex[2],
                            1.0 + 0.75 * k, DW, DH);
        out[k].varyings[0] = vertex[3];
        out[k].varyings[1] = (float)k;
        out[k].varyings[2] = 1.0f - vertex[3];
        out[k].varyings[3] = 0.6f;
        out[k].varyings[4] = vertex[3] * 10.0f; /* fog coordinate */
    }
    return n;
}

/* Pure fragment program: colour from varyings and position, discards on a
   pattern. */
static int det_fragment(void *user, const rast_fragment_in *in, float rgba[4]) {
    (void)user;
    if ((in->x * 7 + in->y * 13) % 11 == 0) return 0;
    rgba[0] = in->varyings[0] * 0.5f + (float)(in->x & 7) / 16.0f;
    rgba[1] = in->varyings[1] * in->z;
    rgba[2] = in->front_facing ? 0.25f : 0.75f;
    rgba[3] = 0.5f + 0.001f * in->w;
    return 1;
}

typedef struct frame {
    uint8_t *c8;
    float *c32, *depth, *accum;
    uint8_t *sten;
} frame;

static void draw_arr(rast_context *ctx, rast_primitive prim, const float *v, int n, int nvar,
                     const uint32_t *idx, int ni) {
    rast_draw_desc d;
    memset(&d, 0, sizeof d);
    d.primitive = prim;
    d.vertices = v;
    d.vertex_count = n;
    d.stride = 4 + nvar;
    d.num_varyings = nvar;
    d.indices = idx;
    d.index_count = ni;
    cr_assert_eq(rast_draw(ctx, &d), RAST_OK);
}

/* The whole scene, on whatever context it is given. float_color selects
   RGBA32F instead of RGBA8. Draw data lives in g_scene (valid until the
   final rast_finish). */
static void render(rast_context *ctx, frame *f, int float_color) {
    const scene_data *sc = &g_scene;
    rast_targets t;
    rast_state s;
    rast_clear_desc cl;
    int i;
    memset(&t, 0, sizeof t);
    if (float_color) {
        t.color = (rast_view){f->c32, DW, DH, DW * 16};
        t.color_format = RAST_COLOR_RGBA32F;
    } else {
        t.color = (rast_view){f->c8, DW, DH, DW * 4};
    }
    t.depth = (rast_view){f->depth, DW, DH, DW * 4};
    t.stencil = (rast_view){f->sten, DW, DH, DW};
    t.accum = (rast_view){f->accum, DW, DH, DW * 16};
    cr_assert_eq(rast_set_targets(ctx, &t), RAST_OK);

    memset(&s, 0, sizeof s);
    tu_set_state(ctx, &s);
    memset(&cl, 0, sizeof cl);
    cl.flags = RAST_CLEAR_COLOR | RAST_CLEAR_DEPTH | RAST_CLEAR_STENCIL | RAST_CLEAR_ACCUM;
    cl.color[2] = 0.2f;
    cl.color[3] = 1.0f;
    cl.depth = 1.0f;
    cl.stencil = 3;
    cl.accum[0] = 0.125f;
    cr_assert_eq(rast_clear(ctx, &cl), RAST_OK);

    /* 1: blended, depth LEQUAL (ties between equal z), stencil INCR_WRAP */
    s.depth_test = 1;
    s.depth_func = RAST_LEQUAL;
    s.blend = 1;
    s.blend_src_rgb = s.blend_src_alpha = RAST_SRC_ALPHA;
    s.blend_dst_rgb = s.blend_dst_alpha = RAST_ONE_MINUS_SRC_ALPHA;
    s.stencil_test = 1;
    s.stencil_front.func = s.stencil_back.func = RAST_ALWAYS;
    s.stencil_front.pass = RAST_INCR_WRAP;
    s.stencil_back.pass = RAST_INVERT;
    s.stencil_front.depth_fail = RAST_DECR;
    s.stencil_back.depth_fail = RAST_INCR;
    tu_set_state(ctx, &s);
    draw_arr(ctx, RAST_TRIANGLES, sc->tris, 3 * 2000, 4, NULL, 0);

    /* 2: culling, stencil-dependent, reverse subtract, partial colour mask,
       smooth vs flat, depth GREATER without writes */
    memset(&s, 0, sizeof s);
    s.cull = RAST_CULL_BACK;
    s.shading = RAST_FLAT;
    s.depth_test = 1;
    s.depth_func = RAST_GREATER;
    s.depth_write_disabled = 1;
    s.stencil_test = 1;
    s.stencil_front.func = RAST_NOTEQUAL;
    s.stencil_front.ref = 4;
    s.stencil_front.read_mask = RAST_MASK(0x07);
    s.stencil_front.pass = RAST_REPLACE;
    s.stencil_front.fail = RAST_DECR_WRAP;
    s.stencil_back = s.stencil_front;
    s.blend = 1;
    s.blend_eq_rgb = RAST_FUNC_REVERSE_SUBTRACT;
    s.blend_src_rgb = RAST_DST_COLOR;
    s.blend_dst_rgb = RAST_ONE;
    s.blend_eq_alpha = RAST_FUNC_MAX;
    s.color_write = RAST_MASK(RAST_WRITE_R | RAST_WRITE_G | RAST_WRITE_A);
    tu_set_state(ctx, &s);
    draw_arr(ctx, RAST_TRIANGLES, sc->tris + 8 * 3 * 2000, 3 * (sc->nt - 2000), 4, NULL, 0);

    /* 3: scissored clear and an accumulation load */
    memset(&s, 0, sizeof s);
    s.scissor_test = 1;
    s.scissor[0] = 13;
    s.scissor[1] = 9;
    s.scissor[2] = 50;
    s.scissor[3] = 40;
    tu_set_state(ctx, &s);
    memset(&cl, 0, sizeof cl);
    cl.flags = RAST_CLEAR_COLOR | RAST_CLEAR_STENCIL;
    cl.color[0] = 0.5f;
    cl.stencil = 9;
    cr_assert_eq(rast_clear(ctx, &cl), RAST_OK);
    cr_assert_eq(rast_accum(ctx, RAST_ACCUM, 0.5f), RAST_OK);

    /* 4: 100k points, sizes 1, 2 and 4 in batches, blend MAX and ADD, fog */
    for (i = 0; i < 5; i++) {
        int n = sc->np / 5;
        memset(&s, 0, sizeof s);
        s.point_size = (float)(i == 4 ? 4 : 1 + (i & 1)); /* 1, 2, 1, 2, 4 */
        s.blend = 1;
        s.blend_eq_rgb = i & 1 ? RAST_FUNC_MAX : RAST_FUNC_ADD;
        s.blend_src_rgb = RAST_ONE;
        s.blend_dst_rgb = RAST_ONE_MINUS_SRC_ALPHA;
        s.depth_test = 1;
        s.depth_func = RAST_LEQUAL;
        s.fog = i % 3 == 0 ? RAST_FOG_EXP : RAST_FOG_NONE;
        s.fog_density = 0.3f;
        s.fog_color[1] = 1.0f;
        s.stencil_test = 1;
        s.stencil_front.func = s.stencil_back.func = RAST_ALWAYS;
        s.stencil_front.pass = s.stencil_back.pass = RAST_INCR;
        tu_set_state(ctx, &s);
        draw_arr(ctx, RAST_POINTS, sc->pts + 8 * (size_t)(i * n), n, 4, NULL, 0);
    }
    cr_assert_eq(rast_accum(ctx, RAST_MULT, 0.75f), RAST_OK);
    cr_assert_eq(rast_accum(ctx, RAST_ACCUM, 0.25f), RAST_OK);

    /* 5: lines with depth and blending */
    memset(&s, 0, sizeof s);
    s.depth_test = 1;
    s.blend = 1;
    s.blend_src_rgb = s.blend_src_alpha = RAST_ONE;
    s.blend_dst_rgb = s.blend_dst_alpha = RAST_ONE;
    s.depth_offset = -0.01f;
    tu_set_state(ctx, &s);
    draw_arr(ctx, RAST_LINES, sc->lines, 2 * sc->nl, 4, NULL, 0);

    /* 6: vertex callback with 2 outputs (indexed triangles and points),
       fog from a varying, fragment callback with discard */
    memset(&s, 0, sizeof s);
    s.vertex_fn = det_vertex;
    s.max_vertex_outputs = 2;
    s.fog = RAST_FOG_LINEAR;
    s.fog_start = 1.0f;
    s.fog_end = 9.0f;
    s.fog_varying = 5;
    s.blend = 1;
    s.blend_src_rgb = RAST_SRC_ALPHA;
    s.blend_dst_rgb = RAST_ONE_MINUS_SRC_ALPHA;
    s.depth_test = 1;
    s.depth_func = RAST_LEQUAL;
    tu_set_state(ctx, &s);
    {
        rast_draw_desc d;
        memset(&d, 0, sizeof d);
        d.vertices = sc->cbv;
        d.vertex_count = sc->ncb;
        d.stride = 4;
        d.num_varyings = 5;
        d.indices = sc->idx;
        d.index_count = sc->nidx;
        cr_assert_eq(rast_draw(ctx, &d), RAST_OK);
        d.primitive = RAST_POINTS;
        d.indices = NULL;
        d.index_count = 0;
        cr_assert_eq(rast_draw(ctx, &d), RAST_OK);
    }
    s.vertex_fn = NULL;
    s.max_vertex_outputs = 0;
    s.fog = RAST_FOG_NONE;
    s.fog_varying = 0;
    s.fragment_fn = det_fragment;
    s.stencil_test = 1;
    s.stencil_front.func = s.stencil_back.func = RAST_GEQUAL;
    s.stencil_front.ref = s.stencil_back.ref = 5;
    s.stencil_front.pass = s.stencil_back.pass = RAST_INVERT;
    s.stencil_front.fail = s.stencil_back.fail = RAST_INCR;
    tu_set_state(ctx, &s);
    draw_arr(ctx, RAST_TRIANGLES, sc->tris, 3 * 500, 4, NULL, 0);

    /* 7: full-screen stencil pass and a return */
    memset(&s, 0, sizeof s);
    s.stencil_test = 1;
    s.stencil_front.func = s.stencil_back.func = RAST_LESS;
    s.stencil_front.ref = s.stencil_back.ref = 7;
    s.stencil_front.pass = s.stencil_back.pass = RAST_ZERO;
    s.blend = 1;
    s.blend_src_rgb = RAST_CONSTANT_ALPHA;
    s.blend_dst_rgb = RAST_ONE_MINUS_CONSTANT_ALPHA;
    s.blend_color[3] = 0.3f;
    tu_set_state(ctx, &s);
    {
        static const float c[4] = {0.9f, 0.1f, 0.4f, 1.0f};
        cr_assert_eq(rast_draw_fullscreen(ctx, 0.3f, c), RAST_OK);
    }
    cr_assert_eq(rast_accum(ctx, RAST_ADD, -0.0625f), RAST_OK);
    cr_assert_eq(rast_accum(ctx, RAST_RETURN, 0.8f), RAST_OK);
    draw_arr(ctx, RAST_TRIANGLES, sc->tris + 8 * 3 * 2500, 3 * 300, 4, NULL, 0);

    /* 8: the fast paths (no stencil, no callbacks): smooth colours, some in
       perspective, with depth LESS (RGBA8 takes four pixels at a time, and
       which pixels share a group depends on the tile), splatted points,
       then constant-colour blended triangles through the blend table */
    memset(&s, 0, sizeof s);
    s.depth_test = 1;
    tu_set_state(ctx, &s);
    draw_arr(ctx, RAST_TRIANGLES, sc->tris + 8 * 3 * 500, 3 * 1500, 4, NULL, 0);
    s.depth_func = RAST_LEQUAL;
    s.point_size = 2;
    tu_set_state(ctx, &s);
    draw_arr(ctx, RAST_POINTS, sc->pts, 20000, 4, NULL, 0);
    s.point_size = 1; /* one-pixel splats have their own records and loops */
    tu_set_state(ctx, &s);
    draw_arr(ctx, RAST_POINTS, sc->pts + 8 * 20000, 30000, 4, NULL, 0);
    s.blend = 1;
    s.blend_src_rgb = s.blend_src_alpha = RAST_SRC_ALPHA;
    s.blend_dst_rgb = s.blend_dst_alpha = RAST_ONE_MINUS_SRC_ALPHA;
    tu_set_state(ctx, &s);
    {
        rast_draw_desc d;
        memset(&d, 0, sizeof d);
        d.vertices = sc->tris + 8 * 3 * 2000;
        d.vertex_count = 3 * 500;
        d.stride = 8; /* positions only: the draw colour */
        d.color[0] = 0.2f; d.color[1] = 0.7f; d.color[2] = 0.4f; d.color[3] = 0.6f;
        cr_assert_eq(rast_draw(ctx, &d), RAST_OK);
        /* without depth: whole spans and rectangles blend four at a time */
        s.depth_test = 0;
        tu_set_state(ctx, &s);
        d.vertices = sc->tris + 8 * 3 * 2300;
        d.vertex_count = 3 * 150;
        cr_assert_eq(rast_draw(ctx, &d), RAST_OK);
        cr_assert_eq(rast_draw_fullscreen(ctx, 0.5f, d.color), RAST_OK);
    }
    tu_finish(ctx);
}

static void frame_alloc(frame *f) {
    f->c8 = calloc(DW * DH, 4);
    f->c32 = calloc(DW * DH, 16);
    f->depth = calloc(DW * DH, 4);
    f->accum = calloc(DW * DH, 16);
    f->sten = calloc(DW * DH, 1);
    cr_assert(f->c8 && f->c32 && f->depth && f->accum && f->sten);
}

static void frame_free(frame *f) {
    free(f->c8);
    free(f->c32);
    free(f->depth);
    free(f->accum);
    free(f->sten);
}

static void compare_frames(const frame *ref, const frame *f, int float_color, const char *cfg) {
    long d;
    if (float_color) {
        d = tu_first_diff(ref->c32, f->c32, DW * DH * 16);
        cr_assert(d < 0, "%s: float colour differs first at pixel %ld", cfg, d / 16);
    } else {
        d = tu_first_diff(ref->c8, f->c8, DW * DH * 4);
        cr_assert(d < 0, "%s: colour differs first at pixel (%ld,%ld), %ld bytes differ", cfg,
                  (d / 4) % DW, (d / 4) / DW, tu_count_diff_bytes(ref->c8, f->c8, DW * DH * 4));
    }
    d = tu_first_diff(ref->depth, f->depth, DW * DH * 4);
    cr_assert(d < 0, "%s: depth differs first at pixel (%ld,%ld)", cfg, (d / 4) % DW, (d / 4) / DW);
    d = tu_first_diff(ref->sten, f->sten, DW * DH);
    cr_assert(d < 0, "%s: stencil differs first at pixel (%ld,%ld)", cfg, d % DW, d / DW);
    d = tu_first_diff(ref->accum, f->accum, DW * DH * 16);
    cr_assert(d < 0, "%s: accum differs first at pixel (%ld,%ld)", cfg, (d / 16) % DW,
              (d / 16) / DW);
}

/* FNV-1a over n bytes, continuing from h. */
static uint64_t fnv1a(uint64_t h, const void *p, size_t n) {
    const uint8_t *b = (const uint8_t *)p;
    size_t i;
    for (i = 0; i < n; i++) h = (h ^ b[i]) * 0x100000001B3ull;
    return h;
}

/* With RAST_TEST_DIGEST_DIR set, writes a hash of the reference frame
   there: `make test` compares the SSE2 build's with the plain C one's. */
static void write_digest(const frame *ref, int float_color) {
    const char *dir = getenv("RAST_TEST_DIGEST_DIR");
    char path[512];
    uint64_t h = 0xCBF29CE484222325ull;
    FILE *out;
    if (!dir) return;
    h = float_color ? fnv1a(h, ref->c32, DW * DH * 16) : fnv1a(h, ref->c8, DW * DH * 4);
    h = fnv1a(h, ref->depth, DW * DH * 4);
    h = fnv1a(h, ref->sten, DW * DH);
    h = fnv1a(h, ref->accum, DW * DH * 16);
    snprintf(path, sizeof path, "%s/determinism_%s.txt", dir, float_color ? "rgba32f" : "rgba8");
    out = fopen(path, "w");
    cr_assert_not_null(out, "cannot write %s", path);
    fprintf(out, "%016llx\n", (unsigned long long)h);
    fclose(out);
}

/* A caller-driven job runner: runs every job on the calling thread, in
   reverse order (mode 0) or odd indices first then even descending (1). */
typedef struct runner {
    int mode;
    long calls, jobs;
} runner;

static void run_jobs(void *user, int count, rast_job_fn job, void *job_arg) {
    runner *r = (runner *)user;
    int i;
    r->calls++;
    r->jobs += count;
    if (r->mode == 0) {
        for (i = count - 1; i >= 0; i--) job(job_arg, i);
    } else {
        for (i = 1; i < count; i += 2) job(job_arg, i);
        for (i = (count - 1) & ~1; i >= 0; i -= 2) job(job_arg, i);
    }
}

/* full: every thread count x tile size; otherwise a diagonal subset */
static void check_determinism(int float_color, int full) {
    static const int threads[] = {1, 2, 3, 8};
    static const int tiles[] = {16, 32, 64};
    frame ref, f;
    rast_context_desc cd;
    rast_context *ctx;
    size_t a, b;
    int m, nonzero = 0, i;
    char cfg[96];
    make_scene();
    frame_alloc(&ref);
    frame_alloc(&f);
    ctx = tu_ctx(1, 64);
    cr_assert_eq(rast_context_threads(ctx), 1);
    render(ctx, &ref, float_color);
    rast_context_destroy(ctx);
    /* sanity: the scene is not trivially empty */
    for (i = 0; i < DW * DH; i++) nonzero += ref.sten[i] != 3 && ref.sten[i] != 9;
    cr_assert(nonzero > DW * DH / 4, "scene too empty for a meaningful comparison");
    write_digest(&ref, float_color);
    for (a = 0; a < 4; a++)
        for (b = 0; b < 3; b++) {
            if (threads[a] == 1 && tiles[b] == 64) continue;
            if (!full && (a + b) % 3 != 0) continue;
            ctx = tu_ctx(threads[a], tiles[b]);
            /* the workers really run (unless the implementation has none:
               the Makefile's RAST_NO_THREADS build says so) */
            cr_assert_eq(rast_context_threads(ctx), getenv("RAST_TEST_NO_THREADS") ? 1 : threads[a]);
            render(ctx, &f, float_color);
            rast_context_destroy(ctx);
            snprintf(cfg, sizeof cfg, "threads %d tile %d", threads[a], tiles[b]);
            compare_frames(&ref, &f, float_color, cfg);
        }
    /* a tiny batch: flushes in the middle of draws */
    memset(&cd, 0, sizeof cd);
    cd.num_threads = 3;
    cd.tile_size = 16;
    cd.batch_bytes = 4096;
    cr_assert_eq(rast_context_create(&cd, &ctx), RAST_OK);
    render(ctx, &f, float_color);
    rast_context_destroy(ctx);
    compare_frames(&ref, &f, float_color, "batch_bytes 4096");
    /* caller-driven jobs in unusual orders */
    for (m = 0; m < (full ? 2 : 1); m++) {
        runner r = {m, 0, 0};
        memset(&cd, 0, sizeof cd);
        cd.num_threads = 4;
        cd.tile_size = 32;
        cd.parallel_for = run_jobs;
        cd.parallel_for_user = &r;
        cr_assert_eq(rast_context_create(&cd, &ctx), RAST_OK);
        render(ctx, &f, float_color);
        rast_context_destroy(ctx);
        snprintf(cfg, sizeof cfg, "parallel_for mode %d", m);
        compare_frames(&ref, &f, float_color, cfg);
        cr_assert(r.calls > 0 && r.jobs > 1, "parallel_for was never used (%ld calls)", r.calls);
    }
    frame_free(&ref);
    frame_free(&f);
    free(g_scene.tris);
    free(g_scene.pts);
    free(g_scene.lines);
    free(g_scene.cbv);
    free(g_scene.idx);
    memset(&g_scene, 0, sizeof g_scene);
}

Test(determinism, identical_bytes_rgba8, .timeout = 120) { check_determinism(0, 1); }
Test(determinism, identical_bytes_rgba32f, .timeout = 120) { check_determinism(1, 0); }
