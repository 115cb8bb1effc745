/* AUTO's cost and error models (docs/methods/auto.md): what describes a
   reflector (its features), the per (method, class) formulas, their text
   format, and the fit built into the library. m_auto.c makes the choice. */
#include "internal.h"

#include <stdlib.h> /* strtod */

static const char *const refl__auto_class_names[REFL_AUTO_CLASS_COUNT] = {"planar", "convex", "concave", "glass",
                                                                          "partial"};

REFL_API const char *refl_auto_class_name(int c) {
    return c >= 0 && c < REFL_AUTO_CLASS_COUNT ? refl__auto_class_names[c] : "unknown";
}

/* ---- features ---------------------------------------------------------------- */

/* World bounds of object i. */
static void refl__auto_object_box(const refl_scene *s, int i, refl_vec3 *lo, refl_vec3 *hi) {
    const refl_mesh *m = s->meshes[s->objects[i].mesh];
    int v;
    *lo = refl_v3(INFINITY, INFINITY, INFINITY);
    *hi = refl_v3(-INFINITY, -INFINITY, -INFINITY);
    for (v = 0; v < m->vertex_count; ++v) {
        refl_vec3 p = refl_mat4_point(s->objects[i].transform,
                                      refl_v3(m->positions[3 * v], m->positions[3 * v + 1], m->positions[3 * v + 2]));
        *lo = refl__v3_min(*lo, p);
        *hi = refl__v3_max(*hi, p);
    }
}

/* Convex or concave: whether the area-weighted faces look away from the
   surface's area centroid (a sphere, a teapot) or towards it (a bowl
   seen from inside), by their winding's normals. */
static int refl__auto_curvature_class(const refl_scene *s, int i) {
    const refl_mesh *m = s->meshes[s->objects[i].mesh];
    const refl_mat4 *t = &s->objects[i].transform;
    refl_vec3 c = refl_v3(0, 0, 0);
    double area = 0.0, away = 0.0;
    int pass, k, j;
    for (pass = 0; pass < 2; ++pass) {
        if (pass == 1 && area > 0.0) c = refl_v3_scale(c, (float)(1.0 / area));
        for (k = 0; k < m->triangle_count; ++k) {
            refl_vec3 v[3], n, mid;
            float a;
            for (j = 0; j < 3; ++j) {
                const float *q = m->positions + 3 * m->indices[3 * k + j];
                v[j] = refl_mat4_point(*t, refl_v3(q[0], q[1], q[2]));
            }
            n = refl_v3_cross(refl_v3_sub(v[1], v[0]), refl_v3_sub(v[2], v[0]));
            a = refl_v3_length(n);
            if (!(a > 0.0f)) continue;
            mid = refl_v3_scale(refl_v3_add(v[0], refl_v3_add(v[1], v[2])), 1.0f / 3.0f);
            if (pass == 0) {
                c = refl_v3_add(c, refl_v3_scale(mid, a));
                area += a;
            } else {
                away += refl_v3_dot(refl_v3_sub(mid, c), n) >= 0.0f ? a : -a;
            }
        }
    }
    return away >= 0.0 ? REFL_AUTO_CONVEX : REFL_AUTO_CONCAVE;
}

/* The first positive distance along dir from o to the box (o inside: where
   the ray leaves it); INFINITY when it misses. */
static float refl__auto_box_distance(refl_vec3 o, refl_vec3 dir, refl_vec3 lo, refl_vec3 hi) {
    float t0 = -INFINITY, t1 = INFINITY;
    const float oo[3] = {o.x, o.y, o.z}, dd[3] = {dir.x, dir.y, dir.z}, l[3] = {lo.x, lo.y, lo.z},
                h[3] = {hi.x, hi.y, hi.z};
    int a;
    for (a = 0; a < 3; ++a) {
        if (dd[a] == 0.0f) {
            if (oo[a] < l[a] || oo[a] > h[a]) return INFINITY;
            continue;
        }
        {
            float ta = (l[a] - oo[a]) / dd[a], tb = (h[a] - oo[a]) / dd[a];
            t0 = REFL__MAX(t0, REFL__MIN(ta, tb));
            t1 = REFL__MIN(t1, REFL__MAX(ta, tb));
        }
    }
    if (t1 < t0 || t1 <= 0.0f) return INFINITY;
    return t0 > 0.0f ? t0 : t1;
}

/* r / D (see refl_auto_features.nearness), box[] the objects' world bounds
   (lo, hi per object). */
static float refl__auto_nearness(const refl_scene *s, int object, const refl_vec3 *box) {
    refl_vec3 c = refl_v3_scale(refl_v3_add(box[2 * object], box[2 * object + 1]), 0.5f);
    float r = 0.5f * refl_v3_length(refl_v3_sub(box[2 * object + 1], box[2 * object])), sum = 0.0f;
    int x, y, z, o;
    for (x = -1; x <= 1; ++x)
        for (y = -1; y <= 1; ++y)
            for (z = -1; z <= 1; ++z) {
                refl_vec3 d = refl_v3_normalize(refl_v3((float)x, (float)y, (float)z));
                float best = INFINITY;
                if (!x && !y && !z) continue;
                for (o = 0; o < s->object_count; ++o)
                    if (o != object) best = REFL__MIN(best, refl__auto_box_distance(c, d, box[2 * o], box[2 * o + 1]));
                sum += best > r ? r / best : 1.0f; /* a miss: 0 */
            }
    return sum / 26.0f;
}

/* The scene point a pixel's depth puts on its view ray (the eye-space
   distance along forward undone from the window depth of a perspective
   projection with the rays' near and far planes). */
static refl_vec3 refl__auto_pixel_point(const refl__view_rays *r, const refl_frame *f, int x, int y) {
    float nx = 2.0f * ((float)x + 0.5f) / (float)r->width - 1.0f, ny = 1.0f - 2.0f * ((float)y + 0.5f) / (float)r->height;
    float zn = 2.0f * f->depth[(size_t)y * (size_t)f->width + (size_t)x] - 1.0f, n = r->znear, fa = r->zfar;
    float z = 2.0f * n * fa / ((fa + n) - zn * (fa - n));
    refl_vec3 d = refl_v3_add(r->forward, refl_v3_add(refl_v3_scale(r->right, nx), refl_v3_scale(r->up, ny)));
    return refl_v3_add(r->eye, refl_v3_scale(d, z));
}

static int refl__auto_inside(refl_vec3 p, refl_vec3 lo, refl_vec3 hi) {
    return p.x >= lo.x && p.y >= lo.y && p.z >= lo.z && p.x <= hi.x && p.y <= hi.y && p.z <= hi.z;
}

/* Whether the ray o + t d, tmin < t < tmax, meets a triangle of object i
   (the ray taken into the object's own space, where t means the same). */
static int refl__auto_ray_meets_object(const refl_scene *s, int i, refl_vec3 o, refl_vec3 d, float tmin, float tmax) {
    const refl_mesh *m = s->meshes[s->objects[i].mesh];
    refl_mat4 inv;
    int k;
    if (!refl_mat4_invert(s->objects[i].transform, &inv)) return 0;
    o = refl_mat4_point(inv, o);
    d = refl_mat4_dir(inv, d);
    for (k = 0; k < m->triangle_count; ++k) {
        const float *a = m->positions + 3 * m->indices[3 * k], *b = m->positions + 3 * m->indices[3 * k + 1],
                    *c = m->positions + 3 * m->indices[3 * k + 2];
        refl_vec3 e1 = refl_v3(b[0] - a[0], b[1] - a[1], b[2] - a[2]), e2 = refl_v3(c[0] - a[0], c[1] - a[1], c[2] - a[2]);
        refl_vec3 q = refl_v3_cross(d, e2), sv, r;
        float det = refl_v3_dot(e1, q), u, v, t;
        if (det == 0.0f) continue;
        sv = refl_v3(o.x - a[0], o.y - a[1], o.z - a[2]);
        u = refl_v3_dot(sv, q) / det;
        if (u < 0.0f || u > 1.0f) continue;
        r = refl_v3_cross(sv, e1);
        v = refl_v3_dot(d, r) / det;
        if (v < 0.0f || u + v > 1.0f) continue;
        t = refl_v3_dot(e2, r) / det;
        if (t > tmin && t < tmax) return 1;
    }
    return 0;
}

/* Whether the mirror ray from p (on object i) along d meets a reflector's
   triangles before a diffuse object's box (a diffuse box around p, such as
   the wall a mirror hangs on, hides nothing): another reflector, or with
   `self` (a concave one) object i again past `gap`. Reflectors are tested
   only where the ray meets their box. */
static int refl__auto_meets_reflector(const refl_scene *s, int object, int self, float gap, const refl_vec3 *box,
                                      refl_vec3 p, refl_vec3 d) {
    float diffuse = INFINITY;
    int o;
    for (o = 0; o < s->object_count; ++o)
        if (!refl__is_reflector(&s->materials[s->objects[o].material]) && !refl__auto_inside(p, box[2 * o], box[2 * o + 1]))
            diffuse = REFL__MIN(diffuse, refl__auto_box_distance(p, d, box[2 * o], box[2 * o + 1]));
    for (o = 0; o < s->object_count; ++o) {
        if (!refl__is_reflector(&s->materials[s->objects[o].material]) || (o == object && !self)) continue;
        if (!refl__auto_inside(p, box[2 * o], box[2 * o + 1]) &&
            !(refl__auto_box_distance(p, d, box[2 * o], box[2 * o + 1]) < diffuse))
            continue;
        if (refl__auto_ray_meets_object(s, o, p, d, o == object ? gap : 0.0f, diffuse)) return 1;
    }
    return 0;
}

/* refl_auto_features.beyond: over at most 32 of object i's pixels, evenly
   through the stencil, the share whose mirror ray (from the surface's point
   and normal the depth buffer gives) meets a reflector: another, or a
   concave one itself. */
#define REFL__AUTO_BEYOND_SAMPLES 32
static float refl__auto_beyond(const refl_scene *s, const refl__view_rays *rays, const refl_frame *f, int object,
                               int concave, long long pixels, const refl_vec3 *box) {
    uint8_t id = (uint8_t)(object < 254 ? object + 1 : 255);
    long long step = pixels / REFL__AUTO_BEYOND_SAMPLES + 1, seen = 0;
    float gap = 0.01f * refl_v3_length(refl_v3_sub(box[2 * object + 1], box[2 * object]));
    int x, y, sampled = 0, met = 0;
    for (y = 0; y < f->height; ++y)
        for (x = 0; x < f->width; ++x) {
            size_t i = (size_t)y * (size_t)f->width + (size_t)x;
            int dx = x + 1 < f->width && f->stencil[i + 1] == id ? 1 : x > 0 && f->stencil[i - 1] == id ? -1 : 0;
            int dy = y + 1 < f->height && f->stencil[i + (size_t)f->width] == id       ? 1
                     : y > 0 && f->stencil[i - (size_t)f->width] == id ? -1
                                                                        : 0;
            refl_vec3 p, n, view;
            if (f->stencil[i] != id || seen++ % step) continue;
            if (!dx || !dy || !(f->depth[i] < 1.0f)) continue; /* no surface to take a normal from */
            p = refl__auto_pixel_point(rays, f, x, y);
            n = refl_v3_cross(refl_v3_scale(refl_v3_sub(refl__auto_pixel_point(rays, f, x + dx, y), p), (float)dx),
                              refl_v3_scale(refl_v3_sub(refl__auto_pixel_point(rays, f, x, y + dy), p), (float)dy));
            view = refl_v3_normalize(refl_v3_sub(p, rays->eye));
            n = refl_v3_normalize(n);
            if (!(refl_v3_length(n) > 0.5f)) continue;
            if (refl_v3_dot(n, view) > 0.0f) n = refl_v3_scale(n, -1.0f);
            sampled++;
            met += refl__auto_meets_reflector(s, object, concave, gap, box, p,
                                              refl_v3_sub(view, refl_v3_scale(n, 2.0f * refl_v3_dot(view, n))));
        }
    return sampled ? (float)met / (float)sampled : 0.0f;
}

/* Whether PLANAR would show object i from eye: it has planar faces (PLANAR
   draws it) and the eye is in front of one of its mirror faces or it has
   glass ones (PLANAR shows a mirror seen from behind as nothing). */
static refl_result refl__auto_planar_seen(const refl_scene *s, int i, refl_vec3 eye, int *out) {
    refl__planar_face *faces = NULL;
    uint8_t *only = (uint8_t *)refl__calloc(&s->allocator, (size_t)s->object_count, 1);
    int count = 0, k;
    refl_result r;
    *out = 0;
    if (!only) return REFL_ERROR_OUT_OF_MEMORY;
    only[i] = 1;
    r = refl__planar_find_faces(s, only, &faces, &count);
    for (k = 0; r == REFL_OK && k < count; ++k)
        *out |= faces[k].glass || faces[k].n[0] * eye.x + faces[k].n[1] * eye.y + faces[k].n[2] * eye.z > faces[k].d;
    if (r == REFL_OK) refl__planar_free_faces(s, faces, count);
    refl__free(&s->allocator, only);
    return r;
}

/* The features of object i with `pixels` pixels on screen in frame f (its
   stencil and depth, the base pass's), seen along rays. */
static refl_result refl__auto_features(const refl_scene *s, int i, const refl__view_rays *rays, const refl_frame *f,
                                       long long pixels, refl_auto_features *out) {
    const refl_material *mat = &s->materials[s->objects[i].material];
    refl_vec3 *box = (refl_vec3 *)refl__calloc(&s->allocator, (size_t)s->object_count, 2 * sizeof(refl_vec3));
    int planar = 0, o;
    refl_result r = REFL_OK;
    memset(out, 0, sizeof *out);
    if (!box) return REFL_ERROR_OUT_OF_MEMORY;
    for (o = 0; o < s->object_count; ++o) refl__auto_object_box(s, o, &box[2 * o], &box[2 * o + 1]);
    out->pixels = pixels;
    out->scene_triangles = (float)refl_scene_triangles(s);
    out->nearness = refl__auto_nearness(s, i, box);
    if (mat->type == REFL_GLASS) {
        out->reflector_class = REFL_AUTO_GLASS; /* the tracer takes no bounce past glass's own (trace.c) */
    } else if ((r = refl__auto_planar_seen(s, i, rays->eye, &planar)) == REFL_OK) {
        out->reflector_class = planar                      ? REFL_AUTO_PLANAR
                               : mat->type == REFL_PARTIAL ? REFL_AUTO_PARTIAL
                                                           : refl__auto_curvature_class(s, i);
        out->beyond = refl__auto_beyond(s, rays, f, i, out->reflector_class == REFL_AUTO_CONCAVE, pixels, box);
    }
    refl__free(&s->allocator, box);
    return r;
}

/* Pixels of object i in a stencil (ids past 254 share 255). */
static long long refl__auto_pixels(const uint8_t *stencil, size_t n, int object) {
    uint8_t id = (uint8_t)(object < 254 ? object + 1 : 255);
    long long count = 0;
    size_t k;
    for (k = 0; k < n; ++k) count += stencil[k] == id;
    return count;
}

REFL_API refl_result refl_auto_reflector_features(const refl_scene *scene, const refl_view *view,
                                                  const refl_frame *frame, int object, refl_auto_features *out) {
    if (!scene || !view || !frame || !out || object < 0 || object >= scene->object_count ||
        view->width != frame->width || view->height != frame->height)
        return REFL_ERROR_INVALID_ARGUMENT;
    refl__view_rays rays;
    refl__view_rays_init(&rays, view, scene);
    return refl__auto_features(scene, object, &rays, frame,
                               refl__auto_pixels(frame->stencil, (size_t)frame->width * (size_t)frame->height, object),
                               out);
}

/* ---- models ------------------------------------------------------------------ */

REFL_API void refl_auto_predict(const refl_auto_model *m, const refl_auto_features *f, float *error_px,
                                float *cost_ms) {
    double px = (double)f->pixels, s = sqrt(px);
    double cost = m->cost[0] + m->cost[1] * px / 1000.0 + m->cost[2] * f->scene_triangles / 1000.0 +
                  m->cost[3] * px * f->beyond / 1000.0;
    double err = m->error[0] + m->error[1] * s + m->error[2] * s * f->nearness;
    if (cost_ms) *cost_ms = (float)REFL__MAX(cost, 0.001);
    if (error_px) *error_px = (float)REFL__MAX(err, 0.0);
}

/* The fit built in: `reflect bench --fit-auto FILE` at the settings in its
   comment, pasted here (docs/methods/auto.md). */
static const char refl__auto_builtin_text[] =
    /* BEGIN reflect-auto-models */
    "# AUTO's models: reflect bench --fit-auto at 160x120, depth 6, 1 thread, the least CPU time of 3 runs;\n"
    "# 376 measurements. Format: docs/methods/auto.md\n"
    "reflect-auto-models 1\n"
    "model raytrace planar samples 16 cost 0 0.280766875 0.234565675 0.820157349 error 0.0256169215 0 0.000114816816\n"
    "model raytrace convex samples 24 cost 0 0.301235169 0.382935077 0.680519164 error 0.0558485948 3.7902857e-05 0\n"
    "model raytrace concave samples 4 cost 2.94272423 0.708163083 0 0 error 0 -0 0\n"
    "model raytrace glass samples 12 cost 0 4.80613613 0 0 error 0.0146860834 4.11042638e-05 0\n"
    "model envmap planar samples 16 cost 0 1.32376838 6.09208441 0 error 61.1364632 0.295978576 0\n"
    "model envmap convex samples 24 cost 4.89492273 0 6.42392349 26.766386 error 10.7442989 0.262971252 0.115641475\n"
    "model envmap concave samples 4 cost 60.2070427 1.48427951 0 0 error 10.9808044 0.681709051 0\n"
    "model envmap glass samples 12 cost 0 1.971259 7.91393661 0 error 4.06330967 0 0.33362934\n"
    "model planar planar samples 16 cost 0.286280692 0.0865384936 0 0.0403313339 error 0.011730846 0 0.000114916584\n"
    "model planar glass samples 4 cost 0.671843886 4.97891474 0 0 error 1.40949059 0.086932607 0\n"
    "model sbc planar samples 16 cost 0 0 11.2081823 18.0261364 error 12.6745625 0 0\n"
    "model sbc convex samples 24 cost 0 48.3443527 9.52583599 0 error 2.84519005 0 0\n"
    "model sbc concave samples 4 cost 1193.5946 21.0324478 0 0 error 0.321325213 0 0\n"
    "model sbc glass samples 12 cost 0 197.787811 0 0 error 0.354570776 0.00665073562 0\n"
    "model c3rc planar samples 16 cost 4.57652044 4.39078617 0.285620421 6.70639181 error 14.4407129 0 0\n"
    "model c3rc convex samples 24 cost 0 24.656353 50.1859283 0 error 2.24362826 0.00938056968 0.0222640969\n"
    "model c3rc concave samples 4 cost 734.590515 53.9262695 0 0 error 0.954164445 0.00149633072 0\n"
    "model spoc planar samples 16 cost 1008.32855 53.122776 0 0 error 0.190361559 0 0\n"
    "model spoc convex samples 24 cost 0 0 188.303207 1636.38171 error 0.515378654 0 0.00456233229\n"
    "model spoc concave samples 4 cost 91.2259369 16.4253235 0 0 error 0.0998715907 0.00130300026 0\n"
    "model graphcam planar samples 16 cost 2.41092968 1.7383554 0 7.78908062 error 0.128060907 0 0.00101106486\n"
    "model graphcam convex samples 24 cost 0 3.62351322 1.65514469 4.31655931 error 0.169825569 0.000422568264 0.00282092649\n"
    "model graphcam concave samples 4 cost 0 7.24963999 0 0 error 0.0997946933 0.000461926946 0\n"
    "model layered-em planar samples 16 cost 56.1801796 70.1999664 0 21.982069 error 30.1073189 0.646942735 0\n"
    "model layered-em convex samples 24 cost 0 78.8940125 4.5122838 20.8688469 error 19.5882607 0.663140535 0\n"
    "model layered-em concave samples 4 cost 0 91.817337 0 0 error 43.4465179 0.451022446 0\n"
    "model layered-em glass samples 12 cost 0 203.930496 0 0 error 9.64736557 0.219346628 0\n"
    /* END reflect-auto-models */
    ;

REFL_API void refl_auto_models_builtin(refl_auto_models *out) {
    refl_result r;
    if (!out) return;
    r = refl_auto_models_parse(refl__auto_builtin_text, sizeof refl__auto_builtin_text - 1, out, NULL, 0);
    REFL_ASSERT(r == REFL_OK);
    (void)r;
}

static void refl__auto_say(char *message, size_t size, const char *fmt, ...) {
    va_list ap;
    if (!message || !size) return;
    va_start(ap, fmt);
    vsnprintf(message, size, fmt, ap);
    va_end(ap);
}

/* The methods a model may name: those that draw reflectors themselves. */
static int refl__auto_modelled(refl_method m) { return m != REFL_METHOD_DEFAULT && m != REFL_DIRECT && m != REFL_AUTO; }

/* One token of at most 31 characters from *s (spaces and tabs between). */
static int refl__auto_token(const char **s, const char *end, char out[32]) {
    int n = 0;
    while (*s < end && (**s == ' ' || **s == '\t' || **s == '\r')) ++*s;
    while (*s < end && **s != ' ' && **s != '\t' && **s != '\r' && **s != '\n') {
        if (n < 31) out[n] = **s;
        ++n;
        ++*s;
    }
    out[n < 31 ? n : 31] = 0;
    return n;
}

static int refl__auto_number(const char *tok, float *out) {
    char *end;
    double v = strtod(tok, &end);
    if (!*tok || *end || !(v - v == 0.0) || fabs(v) > FLT_MAX) return 0;
    *out = (float)v;
    return 1;
}

/* count numbers from *s into v; 0, with the token that is none in bad, if one is not. */
static int refl__auto_numbers(const char **s, const char *end, float *v, int count, char *bad) {
    char tok[32];
    int i;
    for (i = 0; i < count; ++i)
        if (!refl__auto_token(s, end, tok) || !refl__auto_number(tok, &v[i])) {
            memcpy(bad, tok, 32);
            return 0;
        }
    return 1;
}

/* One model line's tokens after "model" into out; the rule it broke, or NULL. */
static const char *refl__auto_model_line(const char *s, const char *end, refl_auto_models *out, char *bad) {
    char tok[32];
    refl_method m;
    refl_auto_model model;
    int c, j;
    float v[8] = {0};
    memset(&model, 0, sizeof model);
    if (!refl__auto_token(&s, end, tok)) return "a method name after 'model'";
    m = refl_method_from_name(tok);
    memcpy(bad, tok, 32);
    if (m == REFL_METHOD_DEFAULT) return "not a method";
    if (!refl__auto_modelled(m)) return "a method that does not draw reflectors itself";
    if (!refl__auto_token(&s, end, tok)) return "a reflector class after the method";
    memcpy(bad, tok, 32);
    for (c = 0; c < REFL_AUTO_CLASS_COUNT && strcmp(tok, refl__auto_class_names[c]); ++c) {}
    if (c == REFL_AUTO_CLASS_COUNT) return "not a class (planar, convex, concave, glass, partial)";
    if (out->model[m][c].fitted) return "a second model for this method and class";
    /* v: samples, cost[0..3] (the fourth optional: files without it read as 0), error[0..2] */
    if (!refl__auto_token(&s, end, tok) || strcmp(tok, "samples")) {
        memcpy(bad, tok, 32);
        return "'samples' after the class";
    }
    if (!refl__auto_numbers(&s, end, v, 1, bad)) return "a finite number";
    if (!refl__auto_token(&s, end, tok) || strcmp(tok, "cost")) {
        memcpy(bad, tok, 32);
        return "'cost' after the samples";
    }
    if (!refl__auto_numbers(&s, end, v + 1, 3, bad)) return "a finite number";
    if (refl__auto_token(&s, end, tok) && refl__auto_number(tok, &v[4])) refl__auto_token(&s, end, tok);
    if (strcmp(tok, "error")) {
        memcpy(bad, tok, 32);
        return "'error' after the costs";
    }
    if (!refl__auto_numbers(&s, end, v + 5, 3, bad)) return "a finite number";
    if (refl__auto_token(&s, end, tok)) {
        memcpy(bad, tok, 32);
        return "the end of the line after the three error terms";
    }
    if (!(v[0] >= 0.0f) || v[0] != floorf(v[0]) || v[0] > 1e9f) {
        snprintf(bad, 32, "%g", v[0]);
        return "a whole count of samples, 0 or more";
    }
    model.fitted = 1;
    model.samples = (int)v[0];
    for (j = 0; j < 4; ++j) model.cost[j] = v[1 + j];
    for (j = 0; j < 3; ++j) model.error[j] = v[5 + j];
    out->model[m][c] = model;
    return NULL;
}

REFL_API refl_result refl_auto_models_parse(const char *text, size_t length, refl_auto_models *out, char *message,
                                            size_t message_size) {
    const char *s = text, *end = text + length;
    int line = 0, header = 0;
    refl__auto_say(message, message_size, "%s", "");
    if (!out || (!text && length)) return REFL_ERROR_INVALID_ARGUMENT;
    memset(out, 0, sizeof *out);
    while (s < end) {
        const char *eol = (const char *)memchr(s, '\n', (size_t)(end - s)), *q = s;
        char tok[32], bad[32] = "";
        const char *why = NULL;
        if (!eol) eol = end;
        ++line;
        if (memchr(s, 0, (size_t)(eol - s))) why = "text without NUL bytes";
        else if (!refl__auto_token(&q, eol, tok) || tok[0] == '#') {
            /* blank or comment */
        } else if (!header) {
            if (strcmp(tok, "reflect-auto-models") || !refl__auto_token(&q, eol, tok) || strcmp(tok, "1") ||
                refl__auto_token(&q, eol, tok))
                why = "the header 'reflect-auto-models 1' first";
            header = 1;
        } else if (strcmp(tok, "model")) {
            memcpy(bad, tok, 32);
            why = "'model' (or a '#' comment)";
        } else {
            why = refl__auto_model_line(q, eol, out, bad);
        }
        if (why) {
            if (bad[0]) refl__auto_say(message, message_size, "auto models, line %d: '%s': expected %s", line, bad, why);
            else refl__auto_say(message, message_size, "auto models, line %d: expected %s", line, why);
            memset(out, 0, sizeof *out);
            return REFL_ERROR_INVALID_ARGUMENT;
        }
        s = eol + 1;
    }
    if (!header) {
        refl__auto_say(message, message_size, "%s", "auto models: empty (no 'reflect-auto-models 1' header)");
        return REFL_ERROR_INVALID_ARGUMENT;
    }
    return REFL_OK;
}

REFL_API refl_result refl_auto_models_load(const char *path, refl_auto_models *out, char *message,
                                           size_t message_size) {
    FILE *f;
    char *text;
    long size;
    size_t got;
    refl_result r;
    refl__auto_say(message, message_size, "%s", "");
    if (!path || !out) return REFL_ERROR_INVALID_ARGUMENT;
    f = fopen(path, "rb");
    if (!f || fseek(f, 0, SEEK_END) != 0 || (size = ftell(f)) < 0 || size > (1L << 20) || fseek(f, 0, SEEK_SET) != 0) {
        refl__auto_say(message, message_size, "auto models: %s: %s", path,
                       !f ? "cannot be opened" : "not a readable file of at most 1 MiB");
        if (f) fclose(f);
        return REFL_ERROR_INVALID_ARGUMENT;
    }
    text = (char *)refl__alloc(NULL, (size_t)size + 1);
    if (!text) {
        fclose(f);
        return REFL_ERROR_OUT_OF_MEMORY;
    }
    got = fread(text, 1, (size_t)size, f);
    fclose(f);
    r = refl_auto_models_parse(text, got, out, message, message_size);
    refl__free(NULL, text);
    return r;
}

REFL_API size_t refl_auto_models_format(const refl_auto_models *models, char *out, size_t cap) {
    size_t n = 0;
    int m, c;
    char line[320];
    const char *head = "reflect-auto-models 1\n";
    if (!models) return 0;
    for (m = -1; m < REFL_METHOD_COUNT; ++m)
        for (c = 0; c < (m < 0 ? 1 : REFL_AUTO_CLASS_COUNT); ++c) {
            const refl_auto_model *a = m < 0 ? NULL : &models->model[m][c];
            int len;
            if (a && !a->fitted) continue;
            len = a ? snprintf(line, sizeof line,
                               "model %s %s samples %d cost %.9g %.9g %.9g %.9g error %.9g %.9g %.9g\n",
                               refl_method_name((refl_method)m), refl__auto_class_names[c], a->samples,
                               (double)a->cost[0], (double)a->cost[1], (double)a->cost[2], (double)a->cost[3],
                               (double)a->error[0],
                               (double)a->error[1], (double)a->error[2])
                    : snprintf(line, sizeof line, "%s", head);
            if (out && n + (size_t)len < cap) memcpy(out + n, line, (size_t)len + 1);
            n += (size_t)len;
        }
    return n;
}
