/* render_fuzz.c - libFuzzer target for the scene and render API: the bytes
   pick a built-in scene, overwrite numbers of its materials, lights,
   environment and ambient term as the caller may write them directly
   (NaN, infinities, huge and negative values included), and choose the
   view and every field of the render desc, then render. A render must
   return REFL_OK with every pixel finite and opaque, or an error with a
   message where the API promises one; no crash, sanitizer report, leak or
   hang. `make fuzz` runs it after the loader's target.

   The frame's size is bounded here (at most 24 x 24), and valid but costly
   counts (samples, cube size, point density) are cut to small ones: the
   fuzzer looks for wrong answers and crashes, and needs many runs a second;
   the work bounds have their own tests. Every other value, refused ones
   included, reaches the API as the bytes give it. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../reflect.h"

typedef struct bytes {
    const uint8_t *p;
    size_t n;
} bytes;

static uint8_t take_u8(bytes *b) {
    uint8_t v = 0;
    if (b->n) {
        v = *b->p++;
        b->n--;
    }
    return v;
}

/* Little-endian, the bytes taken one statement at a time: the operands of
   one expression are evaluated in an order each compiler picks, and an
   input must decode the same in every build. */
static int take_i16(bytes *b) {
    int lo = take_u8(b), hi = take_u8(b);
    return (int16_t)(lo | hi << 8);
}

/* A count the API accepts up to `valid` and that costs in proportion to
   it: valid but large values are cut to `cheap`, so that a run stays
   short; negative and too-large (refused) values pass as they are. */
static int take_count(bytes *b, int cheap, int valid) {
    int v = take_i16(b);
    return v > cheap && v <= valid ? cheap : v;
}

/* A float: mostly a small one near `usual`, sometimes any bit pattern. */
static float take_float(bytes *b, float usual) {
    uint8_t how = take_u8(b);
    if (how < 160) return usual;
    if (how < 224) return usual + ((float)take_i16(b) / 4096.0f);
    {
        uint32_t u = 0;
        float f;
        int k;
        for (k = 0; k < 4; ++k) u |= (uint32_t)take_u8(b) << (8 * k);
        memcpy(&f, &u, sizeof f);
        return f;
    }
}

static void take_vec3(bytes *b, refl_vec3 *v) {
    v->x = take_float(b, v->x);
    v->y = take_float(b, v->y);
    v->z = take_float(b, v->z);
}

/* The scene's numbers, written as a caller may write them directly. */
static void edit_scene(bytes *b, refl_scene *s) {
    int k, c, edits = take_u8(b) % 8;
    for (k = 0; k < edits && s->material_count; ++k) {
        refl_material *m = &s->materials[take_u8(b) % s->material_count];
        switch (take_u8(b) % 8) {
        case 0: m->type = (refl_material_type)(take_u8(b) % 6); break;
        case 1: for (c = 0; c < 4; ++c) m->color[c] = take_float(b, m->color[c]); break;
        case 2: m->reflectance = take_float(b, m->reflectance); m->fresnel = take_u8(b) & 1; break;
        case 3: m->ior = take_float(b, m->ior); m->attenuation = take_float(b, m->attenuation); break;
        case 4: m->mirror_weight = take_float(b, m->mirror_weight); break;
        case 5: m->fresnel_min = take_float(b, 0); m->fresnel_max = take_float(b, 0); break;
        case 6: m->fade_distance = take_float(b, 0); m->fade_min = take_float(b, 0); m->fade_max = take_float(b, 1); break;
        default: for (c = 0; c < 3; ++c) m->emissive[c] = take_float(b, 0); break;
        }
    }
    for (k = 0; k < s->light_count && (take_u8(b) & 1); ++k) {
        take_vec3(b, &s->lights[k].position);
        take_vec3(b, &s->lights[k].direction);
        s->lights[k].radius = take_float(b, s->lights[k].radius);
        for (c = 0; c < 3; ++c) s->lights[k].color[c] = take_float(b, s->lights[k].color[c]);
    }
    if (take_u8(b) & 1)
        for (c = 0; c < 3; ++c) s->ambient[c] = take_float(b, s->ambient[c]);
    if (take_u8(b) & 1) {
        s->environment.intensity = take_float(b, s->environment.intensity);
        for (c = 0; c < 3; ++c) s->environment.color[c] = take_float(b, s->environment.color[c]);
    }
}

static void take_desc(bytes *b, refl_render_desc *d) {
    memset(d, 0, sizeof *d);
    d->method = (refl_method)(take_u8(b) % (REFL_METHOD_COUNT + 1));
    d->threads = take_u8(b) % 5;
    d->depth = (int8_t)take_u8(b) % 12;
    d->spp = take_u8(b) % 12;
    if (take_u8(b) & 1) {
        d->lighting.shadows = take_u8(b) & 1;
        d->lighting.soft_shadow_samples = take_count(b, 16, 1024);
        d->lighting.light_volumes = take_u8(b) & 1;
        d->lighting.caustic_samples = take_count(b, 16, 1024);
        d->lighting.translucency = take_float(b, 0);
    }
    if (take_u8(b) & 1) {
        d->envmap.size = take_count(b, 64, 2048);
        d->planar.no_culling = take_u8(b) & 1;
        d->planar.max_renderings = take_i16(b);
    }
    if (take_u8(b) & 1) {
        d->c3rc.point_density = take_float(b, 0);
        if (d->c3rc.point_density > 1e4f && d->c3rc.point_density < 1e12f) d->c3rc.point_density = 1e4f;
        d->c3rc.kd_leaf_points = take_i16(b);
        d->c3rc.max_splat = (int8_t)take_u8(b);
        d->c3rc.camera_split_px = take_float(b, 0);
    }
    if (take_u8(b) & 1) {
        d->sbc.error_px = take_float(b, 0);
        d->sbc.ray_factor = (int8_t)take_u8(b);
        d->sbc.batch_groups = take_i16(b);
        d->sbc.trace_fallback = take_u8(b) & 1;
        d->sbc.mixed_levels = (int8_t)take_u8(b);
        d->sbc.mode = take_u8(b) % 3;
        d->sbc.memory_mb = take_i16(b);
    }
    /* The groups below come after the ones above, so that the kept inputs
       (fuzz/render_seeds/) still decode to the descs they were found with. */
    if (take_u8(b) & 1) {
        d->raytrace.greedy = take_u8(b) & 1;
        d->raytrace.unpruned = take_u8(b) & 1;
    }
    if (take_u8(b) & 1) {
        refl_layered_em_options *o = &d->layered_em;
        o->samples = take_count(b, 8, 3600);
        o->face_size = take_count(b, 16, 1024);
        o->supersample = take_count(b, 2, 8);
        o->edge_px = take_float(b, 0);
        o->angle_degrees = take_float(b, 0);
        o->theta_c_degrees = take_float(b, 0);
        o->iterations = take_count(b, 20, 100000);
        o->single_view = (int8_t)take_u8(b);
        o->layers = (int8_t)take_u8(b);
        o->keep_stale_maps = (int8_t)take_u8(b);
        o->shell = (int8_t)take_u8(b);
        o->shell_frame = (int8_t)take_u8(b);
        o->direct_images = (int8_t)take_u8(b);
        o->lens_layers = (int8_t)take_u8(b);
        o->direct_from = (int8_t)take_u8(b);
        o->direct_confidence = (int8_t)take_u8(b);
        o->kept_mib = take_i16(b);
        o->continue_incoming = (int8_t)take_u8(b);
        o->share_outer_layer = (int8_t)take_u8(b);
    }
    if (take_u8(b) & 1) {
        d->spoc.size = take_count(b, 32, 4096);
        d->spoc.strength = take_float(b, 0);
        d->spoc.step_scale = take_float(b, 0);
        d->spoc.max_edge_px = take_float(b, 0);
        d->spoc.layers = (int8_t)take_u8(b);
        d->spoc.glass = (int8_t)take_u8(b);
    }
    if (take_u8(b) & 1) {
        d->graphcam.size = take_count(b, 32, 8192);
        d->graphcam.algorithm = (int8_t)take_u8(b);
        d->graphcam.step = take_float(b, 0);
    }
    if (take_u8(b) & 1) d->automatic.error_budget_px = take_float(b, 0);
}

/* Valid but costly frames cut to small ones, as take_count cuts counts:
   LAYERED_EM's first frame (and AUTO's, which may pick it) infers its maps
   from several traced views of each lens at the frame's size and samples,
   and fits its shells to the hits seen from every viewpoint sample (45 by
   default); the unpruned ray tree doubles with each bounce; SPOC's
   impostors are 512 pixels a side by default (take_count cuts only a size
   the bytes give). */
static void cut_costly_frames(refl_view *v, refl_render_desc *d) {
    if (d->spoc.size == 0) d->spoc.size = 32;
    if (d->method == REFL_LAYERED_EM || d->method == REFL_AUTO) {
        if (d->layered_em.samples == 0) d->layered_em.samples = 8;
        if (v->width > 12) v->width = 12;
        if (v->height > 12) v->height = 12;
        if (d->spp > 4) d->spp = 4;
        if (d->depth > 4) d->depth = 4;
    }
    if (d->raytrace.unpruned && d->depth > 6) d->depth = 6;
}

/* What a successful render promises: every pixel finite and opaque. */
static void check_frame(const refl_frame *f) {
    size_t i, n = (size_t)f->width * (size_t)f->height;
    for (i = 0; i < 4 * n; ++i)
        if (!isfinite(f->rgba[i]) || (i % 4 == 3 && f->rgba[i] != 1.0f)) {
            fprintf(stderr, "render_fuzz: pixel %zu channel %zu is %g\n", i / 4, i % 4, (double)f->rgba[i]);
            abort();
        }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    const char *const *names = refl_builtin_names();
    bytes b = {data, size};
    refl_scene *s = NULL;
    refl_frame *f = NULL;
    refl_render_desc d;
    refl_view v;
    refl_builtin_desc bd;
    int count = 0;
    refl_result r;
    while (names[count]) ++count;
    memset(&bd, 0, sizeof bd);
    bd.teapot_tess = 1 + take_u8(&b) % 4; /* small teapots: many runs a second */
    if (refl_scene_builtin(names[take_u8(&b) % count], &bd, &s) != REFL_OK) return 0;
    edit_scene(&b, s);
    v = s->camera;
    v.width = 1 + take_u8(&b) % 24;
    v.height = 1 + take_u8(&b) % 24;
    if (take_u8(&b) & 1) {
        take_vec3(&b, &v.eye);
        take_vec3(&b, &v.target);
        take_vec3(&b, &v.up);
        v.fovy_degrees = take_float(&b, v.fovy_degrees);
        v.znear = take_float(&b, v.znear);
        v.zfar = take_float(&b, v.zfar);
    }
    take_desc(&b, &d);
    cut_costly_frames(&v, &d);
    if (refl_frame_create(v.width, v.height, NULL, &f) == REFL_OK) {
        r = refl_render(s, &v, &d, f);
        if (r == REFL_OK) check_frame(f);
        if (r == REFL_ERROR_INVALID_ARGUMENT && !f->message[0]) {
            fprintf(stderr, "render_fuzz: INVALID_ARGUMENT without a message\n");
            abort();
        }
        refl_frame_destroy(f);
    }
    refl_scene_destroy(s);
    return 0;
}
