/* GRAPHCAM: reflections of a graph-camera impostor (paper 004, sections 3
   and 5; docs/graphcam.md). Each frame the scene's diffuse objects are
   drawn through the graph camera (cam_graph.c) into colour, depth and
   frustum-id images: every triangle is clipped in world space to each
   frustum's region it reaches and rasterised with that frustum's matrix
   (triangles wholly inside go through the base pass's programs
   unchanged). Each mirror pixel's reflected ray is then intersected with
   the impostor by one of the paper's two algorithms, and composited as
   ENVMAP composites (gbuffer.c). What lies outside every frustum is not
   in the impostor: there the flat diffuse objects (the floor reaching out
   of the maze) are billboards, intersected exactly (impostor.c). A ray
   the impostor cannot answer (it meets neither and yet meets the scene,
   or meets a mirror or glass first, which the impostor leaves out) goes
   to RAYTRACE's tracer; only a ray that escapes the scene shows the
   environment. One bounce (stats.depth 1).

   The impostor's construction and its ray march are the graph camera's
   own here; the generic impostor of the SPOC method could share the
   march's crossing test (refl__gci_crossing) and the clipped-triangle
   drawing. */
#include "internal.h"

/* ---- construction --------------------------------------------------------------- */

enum { REFL__GCI_FLOATS = 8 };    /* a clipped vertex: world position, world normal, uv */
enum { REFL__GCI_MAX_POLY = 3 + REFL_GRAPHCAM_MAX_PLANES };

/* One object in one frustum: the base pass's context with the frustum's
   matrix, its whole triangles and its clipped pieces. */
typedef struct refl__gci_draw {
    refl__draw_ctx dc;
    refl_mat4 m;                  /* the frustum's draw matrix (world to clip) */
    uint32_t *inside;
    int inside_count, inside_cap;
    float *pieces;                /* REFL__GCI_FLOATS per vertex, 3 vertices a triangle */
    int piece_count, piece_cap;   /* vertices */
} refl__gci_draw;

static int refl__gci_piece_vertex(void *user, const float *vertex, int index, rast_vertex_out *out, int max_out) {
    const refl__gci_draw *d = (const refl__gci_draw *)user;
    const float *mm = d->m.m;
    int k;
    (void)index;
    (void)max_out;
    for (k = 0; k < 4; ++k)
        out->position[k] = mm[k] * vertex[0] + mm[4 + k] * vertex[1] + mm[8 + k] * vertex[2] + mm[12 + k];
    for (k = 0; k < REFL__GCI_FLOATS; ++k) out->varyings[k] = vertex[k];
    return 1;
}

/* Sutherland-Hodgman in double: poly (n vertices of REFL__GCI_FLOATS) kept
   where plane >= 0; the new count. */
static int refl__gci_clip(double (*poly)[REFL__GCI_FLOATS], int n, const double pl[4],
                          double (*tmp)[REFL__GCI_FLOATS]) {
    int i, k, m = 0;
    for (i = 0; i < n; ++i) {
        const double *a = poly[i], *b = poly[(i + 1) % n];
        double ea = pl[0] * a[0] + pl[1] * a[1] + pl[2] * a[2] + pl[3];
        double eb = pl[0] * b[0] + pl[1] * b[1] + pl[2] * b[2] + pl[3];
        if (ea >= 0.0) memcpy(tmp[m++], a, sizeof tmp[0]);
        if ((ea >= 0.0) != (eb >= 0.0)) {
            double t = ea / (ea - eb);
            for (k = 0; k < REFL__GCI_FLOATS; ++k) tmp[m][k] = a[k] + t * (b[k] - a[k]);
            ++m;
        }
    }
    memcpy(poly, tmp, (size_t)m * sizeof tmp[0]);
    return m;
}

static int refl__gci_grow(const refl_allocator *al, void **arr, int *cap, int need, size_t size) {
    void *n;
    int c = *cap ? *cap : 64;
    if (need <= *cap) return 1;
    while (c < need) c *= 2;
    n = refl__alloc(al, (size_t)c * size);
    if (!n) return 0;
    if (*arr) memcpy(n, *arr, (size_t)*cap * size);
    refl__free(al, *arr);
    *arr = n;
    *cap = c;
    return 1;
}

/* Sorts object `object`'s triangles for frustum f: wholly inside (the
   planes the rasteriser does not clip), clipped into pieces, or out. */
static refl_result refl__gci_collect(const refl_allocator *al, const refl_graphcam *cam, int f,
                                     refl__gci_draw *d) {
    const refl_graphcam_frustum *fr = &cam->frusta[f];
    const refl_mesh *m = d->dc.mesh;
    int t, k, j;
    for (t = 0; t < m->triangle_count; ++t) {
        const uint32_t *tri = m->indices + 3 * t;
        double poly[REFL__GCI_MAX_POLY][REFL__GCI_FLOATS], tmp[REFL__GCI_MAX_POLY][REFL__GCI_FLOATS];
        int n = 3, all_in = 1, out = 0;
        for (k = 0; k < 3; ++k) {
            uint32_t v = tri[k];
            refl_vec3 p = refl_mat4_point(d->dc.model, refl_v3(m->positions[3 * v], m->positions[3 * v + 1],
                                                                m->positions[3 * v + 2]));
            refl_vec3 nn = refl_mat4_dir(d->dc.normal_m, refl_v3(m->normals[3 * v], m->normals[3 * v + 1],
                                                                 m->normals[3 * v + 2]));
            poly[k][0] = p.x; poly[k][1] = p.y; poly[k][2] = p.z;
            poly[k][3] = nn.x; poly[k][4] = nn.y; poly[k][5] = nn.z;
            poly[k][6] = m->texcoords ? m->texcoords[2 * v] : 0.0f;
            poly[k][7] = m->texcoords ? m->texcoords[2 * v + 1] : 0.0f;
        }
        for (j = 0; j < fr->plane_count && !out; ++j) {
            const double *pl = fr->planes[j];
            int below = 0;
            for (k = 0; k < 3; ++k) below += pl[0] * poly[k][0] + pl[1] * poly[k][1] + pl[2] * poly[k][2] + pl[3] < 0.0;
            if (below == 3) out = 1;
            else if (below && j >= fr->rast_clipped) all_in = 0;
        }
        if (out) continue;
        if (all_in) {
            if (!refl__gci_grow(al, (void **)&d->inside, &d->inside_cap, d->inside_count + 3, sizeof(uint32_t)))
                return REFL_ERROR_OUT_OF_MEMORY;
            for (k = 0; k < 3; ++k) d->inside[d->inside_count++] = tri[k];
            continue;
        }
        for (j = fr->rast_clipped; j < fr->plane_count && n >= 3; ++j) n = refl__gci_clip(poly, n, fr->planes[j], tmp);
        if (n < 3) continue;
        if (!refl__gci_grow(al, (void **)&d->pieces, &d->piece_cap, d->piece_count + 3 * (n - 2),
                            REFL__GCI_FLOATS * sizeof(float)))
            return REFL_ERROR_OUT_OF_MEMORY;
        for (k = 1; k + 1 < n; ++k) { /* a fan */
            const int corner[3] = {0, k, k + 1};
            int c, e;
            for (c = 0; c < 3; ++c) {
                float *o = d->pieces + (size_t)REFL__GCI_FLOATS * (size_t)d->piece_count++;
                for (e = 0; e < REFL__GCI_FLOATS; ++e) o[e] = (float)poly[corner[c]][e];
            }
        }
    }
    return REFL_OK;
}

REFL_API void refl_graphcam_impostor_destroy(refl_graphcam_impostor *imp) {
    refl_allocator al;
    if (!imp) return;
    al = imp->allocator;
    refl__free(&al, imp->rgba);
    refl__free(&al, imp->depth);
    refl__free(&al, imp->frustum);
    refl__free(&al, imp);
}

/* Whether object i's box reaches frustum f's box. */
static int refl__gci_overlaps(const refl_scene *s, int i, const refl_graphcam_frustum *f) {
    refl_vec3 lo, hi, wlo, whi;
    int c;
    refl_mesh_bounds(s->meshes[s->objects[i].mesh], &lo, &hi);
    for (c = 0; c < 8; ++c) {
        refl_vec3 p = refl_mat4_point(s->objects[i].transform,
                                      refl_v3(c & 1 ? hi.x : lo.x, c & 2 ? hi.y : lo.y, c & 4 ? hi.z : lo.z));
        wlo = c ? refl__v3_min(wlo, p) : p;
        whi = c ? refl__v3_max(whi, p) : p;
    }
    return !(whi.x < f->lo.x || wlo.x > f->hi.x || whi.y < f->lo.y || wlo.y > f->hi.y || whi.z < f->lo.z ||
             wlo.z > f->hi.z);
}

/* The impostor drawn with rc (its targets rebound to the impostor's). */
static refl_result refl__gci_build(const refl_scene *scene, const refl_graphcam *cam, const uint8_t *skip,
                                   rast_context *rc, refl_graphcam_impostor **out) {
    const refl_allocator *al;
    refl_graphcam_impostor *imp;
    refl__gci_draw *draws = NULL;
    rast_targets t;
    size_t npx;
    int f, i, nd = 0;
    refl_result r = REFL_OK;
    rast_result rr = RAST_OK;
    if (!out) return REFL_ERROR_INVALID_ARGUMENT;
    *out = NULL;
    al = &scene->allocator;
    npx = (size_t)cam->width * (size_t)cam->height;
    imp = (refl_graphcam_impostor *)refl__calloc(al, 1, sizeof *imp);
    if (!imp) return REFL_ERROR_OUT_OF_MEMORY;
    imp->allocator = refl__allocator(al);
    imp->width = cam->width;
    imp->height = cam->height;
    imp->rgba = (float *)refl__calloc(al, npx, 4 * sizeof(float));
    imp->depth = (float *)refl__calloc(al, npx, sizeof(float));
    imp->frustum = (uint8_t *)refl__calloc(al, npx, 1);
    draws = (refl__gci_draw *)refl__calloc(al, (size_t)cam->count * (size_t)REFL__MAX(scene->object_count, 1),
                                           sizeof *draws);
    if (!imp->rgba || !imp->depth || !imp->frustum || !draws) r = REFL_ERROR_OUT_OF_MEMORY;
    if (r == REFL_OK) {
        /* colour, depth, and the frustum ids as the stencil */
        t = refl__float_targets(imp->rgba, imp->depth, imp->frustum, cam->width, cam->height);
        rr = rast_set_targets(rc, &t);
        if (rr == RAST_OK) rr = refl__em_clear(rc, RAST_CLEAR_COLOR | RAST_CLEAR_DEPTH | RAST_CLEAR_STENCIL);
    }
    for (f = 0; r == REFL_OK && rr == RAST_OK && f < cam->count; ++f)
        for (i = 0; r == REFL_OK && rr == RAST_OK && i < scene->object_count; ++i) {
            refl__gci_draw *d = &draws[nd];
            rast_state s;
            const refl_material *mat = &scene->materials[scene->objects[i].material];
            if ((skip && skip[i]) || refl__is_reflector(mat)) continue;
            if (!refl__gci_overlaps(scene, i, &cam->frusta[f])) continue;
            ++nd;
            d->m = refl__gc_draw_matrix(cam, f);
            refl__draw_ctx_init(&d->dc, scene, i, d->m);
            if ((r = refl__gci_collect(al, cam, f, d)) != REFL_OK) break;
            memset(&s, 0, sizeof s);
            s.depth_test = 1;
            s.stencil_test = 1;
            s.stencil_front.func = RAST_ALWAYS;
            s.stencil_front.pass = RAST_REPLACE;
            s.stencil_front.ref = (uint8_t)(f + 1);
            s.stencil_back = s.stencil_front;
            s.fragment_fn = refl__base_fragment;
            s.fragment_user = &d->dc;
            if (d->inside_count) {
                s.vertex_fn = refl__base_vertex;
                s.vertex_user = &d->dc;
                rr = rast_set_state(rc, &s);
                if (rr == RAST_OK) rr = refl__draw_mesh(rc, d->dc.mesh, d->inside, d->inside_count, REFL__BASE_VARYINGS);
            }
            if (rr == RAST_OK && d->piece_count) {
                rast_draw_desc dd;
                s.vertex_fn = refl__gci_piece_vertex;
                s.vertex_user = d;
                rr = rast_set_state(rc, &s);
                memset(&dd, 0, sizeof dd);
                dd.primitive = RAST_TRIANGLES;
                dd.vertices = d->pieces;
                dd.vertex_count = d->piece_count;
                dd.stride = REFL__GCI_FLOATS;
                dd.position_size = 3;
                dd.num_varyings = REFL__BASE_VARYINGS;
                if (rr == RAST_OK) rr = rast_draw(rc, &dd);
            }
            imp->triangles += d->inside_count / 3 + d->piece_count / 3;
        }
    /* always finished before the draws' memory goes, also after a failure:
       queued work points into it */
    {
        rast_result fin = rast_finish(rc);
        if (rr == RAST_OK) rr = fin;
    }
    if (r == REFL_OK && rr != RAST_OK) r = refl__result_from_rast(rr);
    for (i = 0; draws && i < nd; ++i) {
        refl__free(al, draws[i].inside);
        refl__free(al, draws[i].pieces);
    }
    refl__free(al, draws);
    if (r != REFL_OK) {
        refl_graphcam_impostor_destroy(imp);
        return r;
    }
    *out = imp;
    return REFL_OK;
}

REFL_API refl_result refl_graphcam_impostor_build(const refl_scene *scene, const refl_graphcam *cam,
                                                  const uint8_t *skip, int threads, refl_graphcam_impostor **out) {
    rast_context *rc = NULL;
    refl_result r;
    if (!out) return REFL_ERROR_INVALID_ARGUMENT;
    *out = NULL;
    if (!scene || !cam || cam->count <= 0 || cam->count > REFL_GRAPHCAM_MAX_FRUSTA || cam->width <= 0 ||
        cam->height <= 0 || threads < 0 || threads > RAST_MAX_THREADS)
        return REFL_ERROR_INVALID_ARGUMENT;
    if ((r = refl__context_create(scene, threads, &rc)) != REFL_OK) return r;
    r = refl__gci_build(scene, cam, skip, rc, out);
    rast_context_destroy(rc);
    return r;
}

/* ---- intersection --------------------------------------------------------------- */

/* What a march keeps between two samples. */
typedef struct refl__gci_sample {
    int valid;                    /* the pixel shows this sample's frustum */
    int frustum;
    double t;                     /* along the ray */
    double gd, GD;                /* the ray's depth, the impostor's */
    int px, py;
} refl__gci_sample;

typedef struct refl__gci_march {
    const refl_graphcam *cam;
    const refl_graphcam_impostor *imp;
    refl_vec3 o, d;
    double behind;                /* the smallest t where the ray passed behind a surface (refl__gci_behind) */
} refl__gci_march;

/* The impostor's depth slope at pixel (x, y) of frustum f: per axis the
   smaller of the two one-sided differences (so a silhouette's jump on one
   side does not count), the larger over the axes. */
static double refl__gci_slope(const refl_graphcam_impostor *imp, int f, int x, int y) {
    double best = 0.0, g = imp->depth[(size_t)y * (size_t)imp->width + (size_t)x];
    int axis;
    for (axis = 0; axis < 2; ++axis) {
        double side = HUGE_VAL;
        int k;
        for (k = -1; k <= 1; k += 2) {
            int nx = x + (axis ? 0 : k), ny = y + (axis ? k : 0);
            size_t i;
            if (nx < 0 || ny < 0 || nx >= imp->width || ny >= imp->height) continue;
            i = (size_t)ny * (size_t)imp->width + (size_t)nx;
            if (imp->frustum[i] != f + 1) continue;
            side = REFL__MIN(side, fabs(imp->depth[i] - g));
        }
        if (side < HUGE_VAL) best = REFL__MAX(best, side);
    }
    return best;
}

/* Whether the ray crosses the impostor's depth between samples a and b
   (both valid, one frustum): the ray in front at a, behind at b, and the
   stored depth continuous between their pixels: a jump larger than three
   times the ray's own depth change plus twice the surface's slope over
   the pixels between is the "skin" between two depth layers at a
   silhouette, not a surface. The slope is the smaller of the two
   samples' pixels': a feature a pixel thin (a far teapot's knob, seen
   against the floor) has a steep "slope" on both sides, which let the
   rays through the view ray behind it cross there, a dotted line of
   points in mid-air. *s: the crossing's fraction from a to b. */
static int refl__gci_crossing(refl__gci_march *mc, const refl__gci_sample *a, const refl__gci_sample *b, double *s) {
    double da = a->gd - a->GD, db = b->gd - b->GD, px, slope;
    if (!a->valid || !b->valid || a->frustum != b->frustum || !(da < 0.0) || !(db >= 0.0)) return 0;
    slope = REFL__MIN(refl__gci_slope(mc->imp, a->frustum, a->px, a->py), refl__gci_slope(mc->imp, b->frustum, b->px, b->py));
    px = REFL__MAX(b->px > a->px ? b->px - a->px : a->px - b->px, b->py > a->py ? b->py - a->py : a->py - b->py);
    if (fabs(b->GD - a->GD) > 3.0 * fabs(b->gd - a->gd) + 2.0 * REFL__MAX(px, 1.0) * slope) return 0;
    *s = da / (da - db);
    return 1;
}

/* Whether sample b lies behind the impostor's surface by more than the
   surface's thickness estimate: twice its depth spread over the pixel
   (refl__gci_slope) plus the ray's own depth change since sample a (so a
   ray grazing a surface, or just past a crossing, does not count). The
   depth image holds no surface the view cannot see: such a ray has
   entered the unseen space behind a surface (past a silhouette, which the
   crossing test refuses as a skin) and may have gone through its back,
   the ball's far side that the concave bowl reflects. */
static int refl__gci_behind(const refl__gci_march *mc, const refl__gci_sample *a, const refl__gci_sample *b) {
    double thickness;
    if (!b->valid || !(b->gd > b->GD)) return 0;
    thickness = 2.0 * refl__gci_slope(mc->imp, b->frustum, b->px, b->py);
    if (a->valid && a->frustum == b->frustum) thickness += fabs(b->gd - a->gd);
    return b->gd - b->GD > thickness;
}

/* The ray's point at t. */
static refl_vec3 refl__gci_ray_at(const refl__gci_march *mc, double t) {
    return refl_v3((float)(mc->o.x + t * mc->d.x), (float)(mc->o.y + t * mc->d.y), (float)(mc->o.z + t * mc->d.z));
}

/* Fills sample x for the ray at t, seen through frustum f (-1: none). */
static void refl__gci_sample_at(refl__gci_march *mc, int f, double t, refl__gci_sample *x) {
    refl_vec3 p = refl__gci_ray_at(mc, t);
    double c[4];
    x->valid = 0;
    x->frustum = f;
    x->t = t;
    if (f < 0) return;
    refl__gc_clip(mc->cam, f, p, c);
    if (!(c[3] > 0.0)) return;
    {
        double u = (c[0] / c[3] + 1.0) * 0.5 * mc->cam->width, v = (1.0 - c[1] / c[3]) * 0.5 * mc->cam->height;
        size_t i;
        if (!(u >= 0.0 && v >= 0.0 && u < mc->cam->width && v < mc->cam->height)) return;
        x->px = (int)u;
        x->py = (int)v;
        i = (size_t)x->py * (size_t)mc->imp->width + (size_t)x->px;
        if (mc->imp->frustum[i] != f + 1) return;
        x->gd = (c[2] / c[3] + 1.0) * 0.5;
        x->GD = mc->imp->depth[i];
        x->valid = 1;
    }
}

static void refl__gci_fill_hit(refl__gci_march *mc, const refl__gci_sample *a, const refl__gci_sample *b, double s,
                               refl_graphcam_hit *hit) {
    const float *px = mc->imp->rgba + 4 * ((size_t)b->py * (size_t)mc->imp->width + (size_t)b->px);
    double t = a->t + s * (b->t - a->t);
    hit->t = (float)t;
    hit->point = refl__gci_ray_at(mc, t);
    hit->rgb[0] = px[0];
    hit->rgb[1] = px[1];
    hit->rgb[2] = px[2];
    hit->frustum = b->frustum;
}

/* Samples a march takes over a length at `step` a sample (at least 1, at most 10^6). */
static long long refl__gci_samples(double length, double step) {
    double n = ceil(length / step);
    return n < 1.0 ? 1 : n > 1e6 ? 1000000 : (long long)n;
}

/* One march step: sample b after a (k: b's index); 1 when the ray crosses
   the impostor between them (the hit filled in), else b becomes a. */
static int refl__gci_step(refl__gci_march *mc, refl__gci_sample *a, const refl__gci_sample *b, long long k,
                          refl_graphcam_hit *hit) {
    double s;
    hit->steps++;
    if (k > 0 && refl__gci_crossing(mc, a, b, &s)) {
        refl__gci_fill_hit(mc, a, b, s, hit);
        return 1;
    }
    if (b->t < mc->behind && refl__gci_behind(mc, a, b)) mc->behind = b->t;
    *a = *b;
    return 0;
}

/* Algorithm 1: uniform steps of `step` world units over the part of the
   ray inside the camera's bounds. */
static int refl__gci_uniform(refl__gci_march *mc, double t0, double t1, double step, refl_graphcam_hit *hit) {
    refl__gci_sample a, b;
    long long n, k;
    if (!(t1 > t0)) return 0;
    n = refl__gci_samples(t1 - t0, step);
    memset(&a, 0, sizeof a);
    for (k = 0; k <= n; ++k) {
        double t = t0 + (t1 - t0) * (double)k / (double)n;
        refl__gci_sample_at(mc, refl_graphcam_locate(mc->cam, refl__gci_ray_at(mc, t)), t, &b);
        if (refl__gci_step(mc, &a, &b, k, hit)) return 1;
    }
    return 0;
}

/* Algorithm 2 in one frustum: the ray's piece [t0, t1] in it projects to a
   straight image segment, walked `step` pixels at a time (the point of
   each step found by perspective-correct interpolation). */
static int refl__gci_segment(refl__gci_march *mc, int f, double t0, double t1, double step, refl_graphcam_hit *hit) {
    refl__gci_sample a, b;
    double ca[4], cb[4], du, dv;
    long long n, k;
    refl__gc_clip(mc->cam, f, refl__gci_ray_at(mc, t0), ca);
    refl__gc_clip(mc->cam, f, refl__gci_ray_at(mc, t1), cb);
    if (!(ca[3] > 0.0) || !(cb[3] > 0.0)) return 0;
    du = (cb[0] / cb[3] - ca[0] / ca[3]) * 0.5 * mc->cam->width;
    dv = (cb[1] / cb[3] - ca[1] / ca[3]) * 0.5 * mc->cam->height;
    n = refl__gci_samples(sqrt(du * du + dv * dv), step);
    memset(&a, 0, sizeof a);
    for (k = 0; k <= n; ++k) {
        /* image fraction sf -> ray fraction: homogeneous interpolation */
        double sf = (double)k / (double)n, den = (1.0 - sf) * cb[3] + sf * ca[3];
        double tf = den > 0.0 ? sf * ca[3] / den : sf;
        refl__gci_sample_at(mc, f, t0 + (t1 - t0) * tf, &b);
        if (refl__gci_step(mc, &a, &b, k, hit)) return 1;
    }
    return 0;
}

/* refl_graphcam_intersect, and *behind: the smallest t before the hit
   (any, without one) where the ray passed behind a surface by more than
   its thickness estimate (refl__gci_behind); HUGE_VAL where it did not. */
static int refl__gci_intersect(const refl_graphcam *cam, const refl_graphcam_impostor *imp, refl_vec3 o,
                               refl_vec3 dir, float tmin, float tmax, refl_graphcam_algorithm algorithm, float step,
                               refl_graphcam_hit *hit, double *behind) {
    refl__gci_march mc;
    refl_graphcam_hit h;
    refl_vec3 lo, hi;
    double t0 = tmin, t1 = tmax;
    int k, found = 0;
    memset(&h, 0, sizeof h);
    h.frustum = -1;
    *behind = HUGE_VAL;
    if (hit) *hit = h;
    if (!cam || !imp || !hit || imp->width != cam->width || imp->height != cam->height || !refl__v3_finite(o) ||
        !refl__v3_finite(dir) || !(refl_v3_dot(dir, dir) > 0.0f) || !(tmax > tmin) || !(step >= 0.0f))
        return 0;
    mc.cam = cam;
    mc.imp = imp;
    mc.o = o;
    mc.d = dir;
    mc.behind = HUGE_VAL;
    refl_graphcam_bounds(cam, &lo, &hi);
    /* the ray inside the camera's bounds (slabs) */
    for (k = 0; k < 3; ++k) {
        double oc = k == 0 ? o.x : k == 1 ? o.y : o.z, dc = k == 0 ? dir.x : k == 1 ? dir.y : dir.z;
        double l = k == 0 ? lo.x : k == 1 ? lo.y : lo.z, u = k == 0 ? hi.x : k == 1 ? hi.y : hi.z;
        if (dc == 0.0) {
            if (oc < l || oc > u) return 0;
        } else {
            double a = (l - oc) / dc, b = (u - oc) / dc;
            if (a > b) { double tt = a; a = b; b = tt; }
            t0 = REFL__MAX(t0, a);
            t1 = REFL__MIN(t1, b);
        }
    }
    if (!(t1 > t0)) return 0;
    if (algorithm == REFL_GRAPHCAM_UNIFORM) {
        double st = step > 0.0f ? step : refl_v3_length(refl_v3_sub(hi, lo)) / 2048.0;
        found = refl__gci_uniform(&mc, t0, t1, st / refl_v3_length(dir), &h);
    } else {
        /* the pieces of the ray in each frustum, nearest first; a piece
           starting past the best hit so far cannot improve it (regions
           may overlap, so every earlier piece is searched) */
        double best = HUGE_VAL, ta[REFL_GRAPHCAM_MAX_FRUSTA], tb[REFL_GRAPHCAM_MAX_FRUSTA];
        int order[REFL_GRAPHCAM_MAX_FRUSTA], pieces = 0, j;
        refl_vec3 a = refl__gci_ray_at(&mc, t0), b = refl__gci_ray_at(&mc, t1);
        for (k = 0; k < cam->count; ++k) {
            float s0, s1;
            if (!refl_graphcam_clip_segment(cam, k, a, b, &s0, &s1)) continue;
            ta[k] = t0 + (t1 - t0) * s0;
            tb[k] = t0 + (t1 - t0) * s1;
            for (j = pieces++; j > 0 && ta[order[j - 1]] > ta[k]; --j) order[j] = order[j - 1]; /* stable */
            order[j] = k;
        }
        for (j = 0; j < pieces; ++j) {
            refl_graphcam_hit hk;
            k = order[j];
            if (ta[k] >= best) break;
            memset(&hk, 0, sizeof hk);
            if (refl__gci_segment(&mc, k, ta[k], tb[k], step > 0.0f ? step : 1.0, &hk) && hk.t < best) {
                long long steps = h.steps + hk.steps;
                best = hk.t;
                h = hk;
                h.steps = steps;
                found = 1;
            } else {
                h.steps += hk.steps;
            }
        }
    }
    *hit = h;
    if (!found) hit->frustum = -1;
    if (!found || mc.behind < h.t) *behind = mc.behind;
    return found;
}

REFL_API int refl_graphcam_intersect(const refl_graphcam *cam, const refl_graphcam_impostor *imp, refl_vec3 o,
                                     refl_vec3 dir, float tmin, float tmax, refl_graphcam_algorithm algorithm,
                                     float step, refl_graphcam_hit *hit) {
    double behind;
    return refl__gci_intersect(cam, imp, o, dir, tmin, tmax, algorithm, step, hit, &behind);
}

/* ---- the method ----------------------------------------------------------------- */

typedef struct refl__gcm {
    refl__pass *p;
    refl__em em;
    const refl_graphcam *cam;
    const refl_graphcam_impostor *imp;
    refl_bvh *flat;               /* the flat diffuse objects (NULL: none) */
    int *flat_object;             /* its object index -> scene object */
    refl_bvh *unheld;             /* the mirrors and glass, which the impostor leaves out (NULL: none) */
    int *unheld_object;
    const refl_bvh *scene_bvh;    /* the whole scene: does a ray the impostor misses escape? */
    refl_bvh *scene_owned;
    uint8_t *handed;              /* per pixel: REFL__TRACE_ALL where RAYTRACE's tracer draws it */
    refl__rt_object *objects;     /* per scene object: transforms for hit surfaces */
    long long *steps, *max_steps, *rays, *hits, *traced; /* per row */
} refl__gcm;

/* The BVH of the scene objects `keep` accepts, and its object index ->
   scene object (*out NULL: none). */
static refl_result refl__gcm_sub_bvh(refl__gcm *g, int (*keep)(const refl_scene *, int), refl_bvh **out, int **map) {
    const refl_scene *scene = g->p->scene;
    const refl_allocator *al = &scene->allocator;
    size_t objects = (size_t)REFL__MAX(scene->object_count, 1);
    refl_object *objs = (refl_object *)refl__calloc(al, objects, sizeof(refl_object));
    refl_scene sub;
    refl_result r = REFL_OK;
    int i, n = 0;
    *map = (int *)refl__calloc(al, objects, sizeof(int));
    if (!objs || !*map) r = REFL_ERROR_OUT_OF_MEMORY;
    for (i = 0; r == REFL_OK && i < scene->object_count; ++i)
        if (keep(scene, i)) {
            (*map)[n] = i;
            objs[n++] = scene->objects[i];
        }
    if (r == REFL_OK && n) {
        sub = *scene;
        sub.objects = objs;
        sub.object_count = n;
        r = refl_bvh_build(&sub, al, out);
    }
    refl__free(al, objs);
    return r;
}

static int refl__gcm_is_billboard(const refl_scene *scene, int i) {
    return !refl__is_reflector(&scene->materials[scene->objects[i].material]) && refl_object_is_flat(scene, i);
}

static int refl__gcm_is_unheld(const refl_scene *scene, int i) {
    return refl__is_reflector(&scene->materials[scene->objects[i].material]);
}

/* What the reflected rays meet besides the impostor: the flat diffuse
   objects as billboards (for their parts outside the graph camera), the
   mirrors and glass, and the whole scene. */
static refl_result refl__gcm_exact(refl__gcm *g) {
    refl_bvh *bvh = NULL;
    refl_result r;
    g->objects = refl__rt_objects_new(g->p->scene);
    if (!g->objects) return REFL_ERROR_OUT_OF_MEMORY;
    r = refl__gcm_sub_bvh(g, refl__gcm_is_billboard, &g->flat, &g->flat_object);
    if (r == REFL_OK) r = refl__gcm_sub_bvh(g, refl__gcm_is_unheld, &g->unheld, &g->unheld_object);
    if (r == REFL_OK) r = refl__models_bvh(g->p, &bvh, &g->scene_owned);
    g->scene_bvh = bvh;
    return r;
}

/* One frame row: each reflector pixel's reflected ray against the impostor. */
static void refl__gcm_row(void *arg, int y) {
    refl__gcm *g = (refl__gcm *)arg;
    const refl__pass *p = g->p;
    refl_frame *fr = p->frame;
    refl_vec3 lo, hi;
    float eps;
    int x;
    refl_graphcam_bounds(g->cam, &lo, &hi);
    eps = 1e-4f * (refl_v3_length(refl_v3_sub(hi, lo)) + 1.0f);
    for (x = 0; x < fr->width; ++x) {
        size_t i = (size_t)y * (size_t)fr->width + (size_t)x;
        const float *gb = g->em.gbuf + 4 * i;
        const float *q = g->em.surface + 3 * i;
        refl_vec3 o, d, n, s, off;
        refl_graphcam_hit hit;
        refl_hit h;
        float tmax;
        double behind;
        int found, hand;
        if (fabsf(gb[3]) < 1.0f) continue;
        refl__view_rays_get(&p->rays, (float)x + 0.5f, (float)y + 0.5f, &o, &d, &tmax);
        n = refl_v3_normalize(refl_v3(gb[0], gb[1], gb[2]));
        if (refl_v3_dot(n, n) == 0.0f) n = refl_v3_scale(d, -1.0f);
        if (refl_v3_dot(d, n) > 0.0f) n = refl_v3_scale(n, -1.0f);
        s = refl_v3(q[0], q[1], q[2]);
        g->rays[y]++;
        d = refl_v3_reflect(d, n);
        found = refl__gci_intersect(g->cam, g->imp, s, d, eps, 1e30f, (refl_graphcam_algorithm)p->desc.graphcam.algorithm,
                                    p->desc.graphcam.step, &hit, &behind);
        /* the first flat surface the ray meets, where no frustum holds it */
        if (g->flat && refl_bvh_intersect(g->flat, s, d, eps, found ? hit.t : 1e30f, &h)) {
            refl_vec3 at;
            float rgb[3];
            refl__exact_hit_shade(p->scene, &g->objects[g->flat_object[h.object]], &h, rgb, &at, NULL);
            if (refl_graphcam_locate(g->cam, at) < 0) {
                memcpy(hit.rgb, rgb, sizeof rgb);
                hit.point = at;
                hit.t = h.t;
                found = 1;
            }
        }
        g->steps[y] += hit.steps;
        if (hit.steps > g->max_steps[y]) g->max_steps[y] = hit.steps;
        /* What the impostor cannot answer goes to RAYTRACE's tracer: a ray
           it does not stop that still meets the scene (it left every
           frustum, or passed behind what the impostor shows), one that
           passed behind a surface before what it meets (refl__gci_behind:
           it may have gone through the surface's unseen back), and a
           mirror or glass met first (the impostor holds neither; past one
           bounce that path is refl__trace_beyond's). Only a ray that
           escapes the scene shows the environment. The exact rays start
           off the surface on the mirror's side: the G-buffer's point may
           lie a hair behind it, where a ray into a corner slips out of the
           scene. */
        hand = 0;
        off = refl_v3_add(s, refl_v3_scale(n, eps));
        if ((!found || behind < hit.t) && refl_bvh_intersect(g->scene_bvh, off, d, 0.0f, 1e30f, &h))
            hand = refl__is_reflector(g->objects[h.object].material) ? 2 : 1;
        if (!hand && found && g->unheld && refl_bvh_occluded(g->unheld, off, d, 0.0f, hit.t)) hand = 2;
        if (hand) {
            (hand == 2 && p->trace ? p->trace : g->handed)[i] = REFL__TRACE_ALL;
            g->traced[y]++;
            continue;
        }
        if (found) {
            g->hits[y]++;
            refl__em_composite(p, gb, x, y, hit.rgb, hit.point);
        } else {
            refl__em_composite(p, gb, x, y, NULL, refl_v3(NAN, NAN, NAN));
        }
    }
}

static const char *refl__options_graphcam(refl_render_desc *d) {
    const refl_graphcam_options *o = &d->graphcam;
    if (o->size < 0 || o->size > 8192) return "graphcam.size: 0 (twice the frame's width) to 8192";
    if (o->algorithm < 0 || o->algorithm > 1) return "graphcam.algorithm: 0 (SEGMENTS) or 1 (UNIFORM)";
    if (!(o->step >= 0.0f) || !refl__isfinite(o->step)) return "graphcam.step: finite, 0 or more";
    if (o->camera && (o->camera->count <= 0 || o->camera->count > REFL_GRAPHCAM_MAX_FRUSTA ||
                      o->camera->width <= 0 || o->camera->height <= 0 || o->camera->width > 16384 ||
                      o->camera->height > 16384))
        return "graphcam.camera: a camera made by refl_graphcam_init";
    return NULL;
}

static refl_result refl__method_graphcam(refl__pass *p) {
    const refl_scene *scene = p->scene;
    const refl_allocator *al = &scene->allocator;
    refl_frame *fr = p->frame;
    refl__gcm g;
    refl_graphcam *own = NULL;
    refl_graphcam_impostor *imp = NULL;
    unsigned char *seen = NULL;
    double t0 = refl__now_ms(), t1;
    refl_result r = REFL_OK;
    int any = 0, y;
    long long handed = 0;
    size_t npx = (size_t)fr->width * (size_t)fr->height;
    memset(&g, 0, sizeof g);
    g.p = p;
    g.em.p = p;
    r = refl__em_gbuffer_new(&g.em, &seen, &any);
    if (r == REFL_OK && any) {
        g.cam = p->desc.graphcam.camera;
        if (!g.cam) { /* the view's pinhole */
            refl_view v = *p->view;
            int w = p->desc.graphcam.size > 0 ? p->desc.graphcam.size : 2 * fr->width;
            int h = (int)((long long)w * fr->height / fr->width);
            own = (refl_graphcam *)refl__alloc(al, sizeof *own);
            if (!own) r = REFL_ERROR_OUT_OF_MEMORY;
            v.znear = p->rays.znear;
            v.zfar = p->rays.zfar;
            if (r == REFL_OK) r = refl_graphcam_init(own, &v, w, REFL__MAX(h, 1));
            g.cam = own;
        }
        g.em.surface = (float *)refl__calloc(al, npx, 3 * sizeof(float));
        g.steps = (long long *)refl__calloc(al, (size_t)fr->height, 5 * sizeof(long long));
        g.handed = (uint8_t *)refl__calloc(al, npx, 1);
        if (r == REFL_OK && (!g.em.surface || !g.steps || !g.handed)) r = REFL_ERROR_OUT_OF_MEMORY;
        if (r == REFL_OK) {
            g.max_steps = g.steps + fr->height;
            g.rays = g.max_steps + fr->height;
            g.hits = g.rays + fr->height;
            g.traced = g.hits + fr->height;
            /* the impostor replaces the diffuse scene; reflectors stay out */
            t1 = refl__now_ms();
            fr->stats.ms_reflect += t1 - t0;
            r = refl__gci_build(scene, g.cam, NULL, p->rc, &imp);
            if (r == REFL_OK) r = refl__gcm_exact(&g);
            t0 = refl__now_ms();
            fr->stats.ms_build += t0 - t1;
        }
        if (r == REFL_OK) {
            g.imp = imp;
            if (g.flat) fr->stats.model_bytes += refl__bvh_bytes(g.flat);
            if (g.unheld) fr->stats.model_bytes += refl__bvh_bytes(g.unheld);
            fr->stats.graphcam.frusta = g.cam->count;
            fr->stats.graphcam.triangles = imp->triangles;
            fr->stats.model_bytes += (long long)((size_t)imp->width * (size_t)imp->height * (4 * sizeof(float) + sizeof(float) + 1));
            rast_run_jobs(p->rc, fr->height, refl__em_surface_row, &g.em);
            rast_run_jobs(p->rc, fr->height, refl__gcm_row, &g);
            for (y = 0; y < fr->height; ++y) {
                fr->stats.graphcam.steps += g.steps[y];
                fr->stats.graphcam.rays += g.rays[y];
                fr->stats.graphcam.hits += g.hits[y];
                fr->stats.graphcam.traced += g.traced[y];
                handed += g.traced[y];
                if (g.max_steps[y] > fr->stats.graphcam.max_steps) fr->stats.graphcam.max_steps = g.max_steps[y];
            }
        }
    }
    if (r == REFL_OK) {
        rast_targets t = refl__frame_targets(fr);
        r = refl__result_from_rast(rast_set_targets(p->rc, &t));
    }
    if (r == REFL_OK && handed) r = refl__trace_marked(p, g.handed);
    t1 = refl__now_ms();
    fr->stats.ms_reflect += t1 - t0;
    refl_graphcam_impostor_destroy(imp);
    refl_bvh_destroy(g.flat);
    refl__free(al, g.flat_object);
    refl_bvh_destroy(g.unheld);
    refl__free(al, g.unheld_object);
    refl_bvh_destroy(g.scene_owned);
    refl__free(al, g.handed);
    refl__free(al, g.objects);
    refl__free(al, own);
    refl__free(al, g.steps);
    refl__free(al, g.em.surface);
    refl__free(al, g.em.gbuf);
    refl__free(al, g.em.draws);
    refl__free(al, seen);
    return r;
}
