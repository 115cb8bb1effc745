/* C3RC: Mei, Popescu and Sacks' hybrid backward-forward reflections
   (paper 000). Per frame:
     1. every surface is sampled with points (refl_mesh_sample_points, world
        space), each shaded once as DIRECT shows it (diffuse model clamped,
        a partial reflector's diffuse share, mirrors and glass black), and
        the points go into a kd-tree (section 4); the default density is
        raised on the objects a folding camera shows magnified
        (refl__c3_object_densities);
     2. each reflector triangle the view sees (front faces, and the back
        faces of an open mesh's inside) becomes a continuous 3-ray camera
        from the reflected rays at its vertices (section 5), split in four
        while the error its rays' interpolation would make is estimated
        above camera_split_px (beyond the paper: its one camera per triangle
        errs by 1.5 px at p95 on the 4,000-triangle teapot);
     3. backward: the kd-tree is walked with the camera's box test
        (section 5.2), after a cheaper one against planes bounding the
        volume's convex hull, to find the leaves it may see;
     4. forward: every point of those leaves is projected with the camera,
        every valid projection (the paper's GPU kept one; here all) lands on
        the reflector point a v1 + b v2 + c v3, seen by the view at a pixel,
        and is splatted there as a square; the point nearest the reflector
        (the paper's push-back) wins each pixel, its depth taken where the
        pixel's own ray meets the point's tangent plane (refl__c3_depth_at).
        A camera does not draw its reflector's own points within one
        triangle edge (refl__c3_near_self). Where a pixel's reflected ray
        turns fast from its neighbours', a point shows on it only if that
        ray meets the point's surfel (refl__c3_ray_meets); a pixel whose
        splats all missed shows its neighbours' nearest point.
   Pixels no point reaches show the environment along their reflected ray
   (the paper's environment-mapped background), unless a nearer surface's
   points surround them: a pixel in such a gap, empty or showing a surface
   behind (where a reflection magnifies, the random points leave gaps their
   splats do not close), goes to RAYTRACE's tracer (refl_c3rc_in_gap,
   stats.c3rc.traced). One bounce, as the paper:
   with desc.depth > 1 a pixel showing a reflector's point goes on through
   RAYTRACE's tracer (refl__trace_beyond).

   Splats: the side grows with the point spacing the camera shows on
   screen, estimated per projection from the sweeping triangle's area at t
   against the reflector piece's area in pixels (the paper's "increase the
   splat size where rays converge"), up to max_splat, or from the
   camera's first fold interval on (section 5.1), up to its own size on
   screen (refl__c3_in_fold). Level of detail: a
   leaf's points are shuffled (refl_kdtree), so where a camera minifies a
   whole leaf, a prefix of it at the needed density is drawn. A diffuse
   surface's points that face away from the ray are not drawn.

   A splat only covers pixels that show the camera's triangle's side (the
   G-buffer's object id, negated on back faces) and lie within two pixels
   of its plane: another part of the same reflector in front hides it.
   Visibility is a per-pixel atomic minimum of (t, point index), so the
   image is the same for any thread count and order.

   Glass is declined (refl__declines_glass) and goes to RAYTRACE's tracer: a
   C3RC interpolates rays that leave the reflector straight, while light
   through a glass object bends again at its back surface, and the exit
   rays of one triangle's three corners can leave through different back
   triangles (they cross inside a thick object), so no three-ray camera
   spans them; the paper has no refraction. */
#include "internal.h"

#define REFL__C3_EMPTY (~(uint64_t)0)
#define REFL__C3_LOD_SPACING 0.5f   /* pixels between drawn points where a leaf is thinned */
#define REFL__C3_SPLAT_SCALE 1.5f   /* splat side per point spacing (random points leave gaps) */
/* At a pixel, a splat's depth grows by this many pixel widths (in the
   sweep plane) per pixel between the pixel and the point's projection:
   the slope of a surface seen at 76 degrees from its normal. Points of
   one surface then compare by how near they project, and a surface
   behind by more than that slope stays hidden. */
#define REFL__C3_SAME_SURFACE_SLOPE 4.0f
/* Where a reflector pixel's reflected ray turns from a neighbour's by more
   than this (radians), a point splatted on it must be a surfel its ray
   meets (refl__c3_ray_meets): the disc about the point in its tangent
   plane, of radius REFL__C3_DISC per point spacing of its object. */
#define REFL__C3_TURN_TEST 0.05f
#define REFL__C3_DISC 1.0f
#define REFL__C3_GRAZE 0.2f         /* |cos| below which a ray grazes a point's tangent plane */
/* A pixel's point is in a gap of another surface's points where those
   around it are nearer than this share of its depth (refl_c3rc_in_gap). */
#define REFL__C3_GAP_NEARER 0.9f

/* A camera to build: a piece of reflector triangle `triangle`, its
   corners as barycentrics of the triangle's vertices (rows: corners). */
typedef struct refl__c3_job {
    int object, triangle;
    float corner[3][3];
} refl__c3_job;

#define REFL__C3_SPLIT_PX 0.1f     /* default estimated camera error that splits a triangle's camera */
#define REFL__C3_SPLIT_DEPTH 4      /* at most 4^4 cameras per reflector triangle */
#define REFL__C3_AUTO_POINTS 2e6    /* the most points the default density samples */
#define REFL__C3_PIXELS_PER_POINT 4.0 /* the default density: a point per 2 x 2 pixels */
#define REFL__C3_MAX_BOOST 64.0f    /* the most a magnified object's density is raised */
#define REFL__C3_MAX_POINTS 33554432.0 /* 2^25 points at most: about 2 GiB with the kd-tree */
#define REFL__C3_POINT_BYTES 64.0   /* per point: position, normal, colour, ids, tree */

typedef struct refl__c3_counts {
    long long tests, culled, leaves, tries, valid, multiple;
    double ms_cull, ms_project;
} refl__c3_counts;

/* The scene's samples in a kd-tree, and per tree point its shade, normal
   and where it was sampled: what refl__c3_points makes, and what a
   renderer keeps across frames (it depends on the scene and the density,
   not on the view). */
typedef struct refl__c3_samples {
    refl_kdtree *tree;
    float *rgb, *normal;
    uint8_t *diffuse;             /* on a diffuse object (culled when facing away) */
    float *object_density;        /* per object: the points per unit area it was sampled at */
    int32_t *object, *triangle;   /* where it was sampled */
    float spacing_scale;          /* >= 1: how much farther apart the points lie than the default
                                     density wanted, where REFL__C3_AUTO_POINTS capped it (the
                                     gaps refl_c3rc_in_gap looks across grow with it) */
} refl__c3_samples;

static void refl__c3_samples_free(const refl_allocator *al, refl__c3_samples *pts) {
    if (!pts) return;
    refl_kdtree_destroy(pts->tree);
    refl__free(al, pts->rgb);
    refl__free(al, pts->normal);
    refl__free(al, pts->diffuse);
    refl__free(al, pts->object_density);
    refl__free(al, pts->object);
    refl__free(al, pts->triangle);
    refl__free(al, pts);
}

typedef struct refl__c3 {
    refl__pass *p;
    refl__em em;                  /* the reflectors' G-buffer (gbuffer.c) */
    uint64_t *key;                /* per pixel: t bits << 32 | tree point, REFL__C3_EMPTY */
    uint8_t *touched;             /* per pixel: a splat reached it whose surfel its ray missed */
    uint8_t *gap;                 /* per pixel: REFL__TRACE_ALL in a gap of the points (refl_c3rc_in_gap) */
    float *ray;                   /* per pixel: reflected ray, its turn to the neighbours' (refl__c3_ray_row) */
    refl__c3_samples *s;          /* the points: this frame's own or the renderer's */
    float density;
    float wanted_density;         /* the default density before REFL__C3_AUTO_POINTS capped it */
    float tmax;                   /* longest possible sweep: the scene's diagonal */
    float pixel_angle;            /* world size of a pixel per unit of distance */
    int max_splat;
    refl__c3_job *jobs;
    refl__c3_counts *counts;      /* one per job, summed in order afterwards */
} refl__c3;

/* The state of one camera while its leaves are drawn. */
typedef struct refl__c3_cam {
    const refl__c3 *c3;
    refl_c3rc cam;
    int object, triangle;
    float screen_area;            /* the triangle's area in pixels */
    float edge;                   /* longest edge (world) */
    float near_self;              /* its reflector's own points nearer (in t) are not drawn */
    float bary[4];                /* barycentric solve of the base: e1.e1, e1.e2, e2.e2, 1 / det */
    refl_vec3 base_normal;        /* unit, the side the rays leave */
    int lod;                      /* thinning allowed: no multiple projections */
    float fold[4][2];             /* section 5.1's sweep intervals where the rays fold */
    int folds;
    float screen_edge;            /* the longest edge in pixels */
    float id;                     /* G-buffer id of its pixels: object + 1, negated for a back face */
    float sweep;                  /* the largest t a scene point can have (INFINITY: unknown) */
    float hull[14][4];            /* planes n . x <= w bounding the volume up to t = sweep */
    int hull_count;
    refl__c3_counts *n;
    double t_cull;
} refl__c3_cam;

/* Atomic minimum: the smaller key wins whatever the order of arrival. */
static void refl__c3_min(uint64_t *slot, uint64_t key) {
#if defined(__GNUC__) || defined(__clang__)
    uint64_t cur = __atomic_load_n(slot, __ATOMIC_RELAXED);
    while (key < cur && !__atomic_compare_exchange_n(slot, &cur, key, 1, __ATOMIC_RELAXED, __ATOMIC_RELAXED)) {
    }
#else
#error "C3RC needs an atomic compare-and-swap (GCC or Clang builtins)"
#endif
}

/* Sets a per-pixel flag that any thread may set (only ever to 1). */
static void refl__c3_mark(uint8_t *slot) {
#if defined(__GNUC__) || defined(__clang__)
    __atomic_store_n(slot, (uint8_t)1, __ATOMIC_RELAXED);
#else
#error "C3RC needs atomic stores (GCC or Clang builtins)"
#endif
}

/* A float's bits: non-negative floats order as their bits do. */
static uint32_t refl__c3_bits(float f) {
    uint32_t u;
    f = f > 0.0f ? f : 0.0f;
    memcpy(&u, &f, sizeof u);
    return u;
}

static double refl__c3_sweep_area(const refl_c3rc *c, float t) {
    refl_vec3 a = refl_v3_add(c->v[0], refl_v3_scale(c->d[0], t));
    refl_vec3 b = refl_v3_add(c->v[1], refl_v3_scale(c->d[1], t));
    refl_vec3 d = refl_v3_add(c->v[2], refl_v3_scale(c->d[2], t));
    return 0.5 * (double)refl_v3_length(refl_v3_cross(refl_v3_sub(b, a), refl_v3_sub(d, a)));
}

/* Window coordinates of a world point; 0 behind the eye. */
static int refl__c3_window(const refl__pass *p, refl_vec3 q, float *x, float *y) {
    const float *m = p->vp.m;
    float cx = m[0] * q.x + m[4] * q.y + m[8] * q.z + m[12];
    float cy = m[1] * q.x + m[5] * q.y + m[9] * q.z + m[13];
    float cw = m[3] * q.x + m[7] * q.y + m[11] * q.z + m[15];
    if (!(cw > 0.0f)) return 0;
    *x = (cx / cw + 1.0f) * 0.5f * (float)p->frame->width;
    *y = (1.0f - cy / cw) * 0.5f * (float)p->frame->height;
    return 1;
}

/* Whether sweep t lies in or past the camera's first fold interval
   (section 5.1): where its rays converge, then diverge again, a point
   covers as many pixels as the magnification asks (the paper's "increase
   the splat size" in the quasi-convergence region), up to the camera's own
   size on screen. Past the fold the rays spread and the splats shrink by
   themselves. */
static int refl__c3_in_fold(const refl__c3_cam *k, float t) { return k->folds > 0 && t >= k->fold[0][0]; }

/* The push-back depth of a splat at a pixel: where the camera's ray
   through the pixel's reflector point r (its barycentrics in the base, the
   rays interpolated there) meets the plane of the point pt with normal
   np, so that the points of one surface compare as the surface at the
   pixel's centre and not as their own (the nearest one at the edge of a
   pixel's footprint would win every pixel it covers). Within `reach` of
   the point's own t; t itself where the ray grazes the plane. */
static float refl__c3_depth_at(const refl__c3_cam *k, refl_vec3 r, refl_vec3 pt, refl_vec3 np, float t, float reach) {
    const refl_c3rc *c = &k->cam;
    refl_vec3 w = refl_v3_sub(r, c->v[0]), d;
    float w1 = refl_v3_dot(w, refl_v3_sub(c->v[1], c->v[0])), w2 = refl_v3_dot(w, refl_v3_sub(c->v[2], c->v[0]));
    float b = (k->bary[2] * w1 - k->bary[1] * w2) * k->bary[3], cc = (k->bary[0] * w2 - k->bary[1] * w1) * k->bary[3];
    float dn, s;
    d = refl_v3_add(refl_v3_add(refl_v3_scale(c->d[0], 1.0f - b - cc), refl_v3_scale(c->d[1], b)), refl_v3_scale(c->d[2], cc));
    dn = refl_v3_dot(d, np);
    if (!(fabsf(dn) > 0.2f * refl_v3_length(d))) return t;
    s = refl_v3_dot(refl_v3_sub(pt, r), np) / dn;
    return REFL__CLAMP(s, t - reach, t + reach);
}

/* The reflected ray of reflector pixel (x, y), as the composite
   reflects it (its G-buffer normal turned to the viewer); 0 where it has
   no normal. */
static int refl__c3_pixel_ray(const refl__c3 *c3, int x, int y, refl_vec3 *u) {
    const float *g = c3->em.gbuf + 4 * ((size_t)y * (size_t)c3->p->frame->width + (size_t)x);
    refl_vec3 o, d, n;
    float tmax;
    refl__view_rays_get(&c3->p->rays, (float)x + 0.5f, (float)y + 0.5f, &o, &d, &tmax);
    n = refl_v3_normalize(refl_v3(g[0], g[1], g[2]));
    if (refl_v3_dot(n, n) == 0.0f) return 0;
    if (refl_v3_dot(d, n) > 0.0f) n = refl_v3_scale(n, -1.0f);
    *u = refl_v3_normalize(refl_v3_reflect(d, n));
    return 1;
}

/* A row job: per reflector pixel, its reflected ray and how far (radians)
   it turns to its 4-neighbours' on the same side of the same reflector
   (the most of them; -1: no ray). */
static void refl__c3_ray_row(void *arg, int y) {
    refl__c3 *c3 = (refl__c3 *)arg;
    int w = c3->p->frame->width, h = c3->p->frame->height, x, k;
    for (x = 0; x < w; ++x) {
        size_t i = (size_t)y * (size_t)w + (size_t)x;
        float *out = c3->ray + 4 * i, turn = 0.0f;
        refl_vec3 u, v;
        out[3] = -1.0f;
        if (fabsf(c3->em.gbuf[4 * i + 3]) < 1.0f || !refl__c3_pixel_ray(c3, x, y, &u)) continue;
        for (k = 0; k < 4; ++k) {
            int xs = x + (k == 0) - (k == 1), ys = y + (k == 2) - (k == 3);
            if (xs < 0 || ys < 0 || xs >= w || ys >= h ||
                c3->em.gbuf[4 * ((size_t)ys * (size_t)w + (size_t)xs) + 3] != c3->em.gbuf[4 * i + 3] ||
                !refl__c3_pixel_ray(c3, xs, ys, &v))
                continue;
            turn = REFL__MAX(turn, refl_v3_length(refl_v3_sub(u, v)));
        }
        out[0] = u.x;
        out[1] = u.y;
        out[2] = u.z;
        out[3] = turn;
    }
}

/* Whether reflector pixel j's reflected ray (refl__c3_ray_row) meets the
   disc of radius `radius` about point pt in its tangent plane (normal np),
   where the ray turns fast (REFL__C3_TURN_TEST). There a pixel's footprint
   spans far apart parts of the scene, its neighbours' rays skip past
   whole objects, and a camera's interpolated rays stray most from the
   true ones, so a splat reaches pixels whose own ray sees something else
   (an object squeezed to a sliver beside the sky, the far edge of the
   floor): a point is then a surfel, shown only where the pixel's ray
   meets it. Where the ray grazes the plane, its distance from pt counts. */
static int refl__c3_ray_meets(const refl__c3 *c3, size_t j, refl_vec3 pt, refl_vec3 np, float radius) {
    const float *ray = c3->ray + 4 * j, *r = c3->em.surface + 3 * j;
    refl_vec3 u = refl_v3(ray[0], ray[1], ray[2]), w = refl_v3_sub(pt, refl_v3(r[0], r[1], r[2]));
    float un = refl_v3_dot(u, np), s;
    if (!(ray[3] >= REFL__C3_TURN_TEST)) return 1; /* a slowly turning ray, or none */
    s = fabsf(un) > REFL__C3_GRAZE ? refl_v3_dot(w, np) / un : refl_v3_dot(w, u);
    if (!(s > 0.0f)) return 0;
    w = refl_v3_sub(w, refl_v3_scale(u, s));
    return refl_v3_dot(w, w) <= radius * radius;
}

/* Splats point i, projected at pr, into the pixels of the camera's
   reflector around its reflector point. */
static void refl__c3_splat(const refl__c3_cam *k, int i, const refl_c3rc_projection *pr, float density) {
    const refl__c3 *c3 = k->c3;
    const refl__pass *p = c3->p;
    const refl_c3rc *c = &k->cam;
    int w = p->frame->width, h = p->frame->height, side, x0, y0, x, y;
    refl_vec3 q = refl_v3_add(refl_v3_add(refl_v3_scale(c->v[0], pr->a), refl_v3_scale(c->v[1], pr->b)),
                              refl_v3_scale(c->v[2], pr->c));
    const float *tq = c3->s->tree->positions + 3 * (size_t)i;
    refl_vec3 pt = refl_v3(tq[0], tq[1], tq[2]), np = refl_v3(0.0f, 0.0f, 0.0f);
    float px, py, tol, plane_tol, pix, spacing = 0.0f, pix_sweep = 0.0f, facing = 0.0f, reach, disc;
    if (!refl__c3_window(p, q, &px, &py)) return;
    {   /* the point spacing on screen: a point's share of surface, turned
           into the sweep plane along the ray, then into pixels */
        refl_vec3 dir = refl_v3_add(refl_v3_add(refl_v3_scale(c->d[0], pr->a), refl_v3_scale(c->d[1], pr->b)),
                                    refl_v3_scale(c->d[2], pr->c));
        refl_vec3 e1 = refl_v3_sub(refl_v3_add(c->v[1], refl_v3_scale(c->d[1], pr->t)),
                                   refl_v3_add(c->v[0], refl_v3_scale(c->d[0], pr->t)));
        refl_vec3 e2 = refl_v3_sub(refl_v3_add(c->v[2], refl_v3_scale(c->d[2], pr->t)),
                                   refl_v3_add(c->v[0], refl_v3_scale(c->d[0], pr->t)));
        refl_vec3 ns = refl_v3_cross(e1, e2);
        float sweep = 0.5f * refl_v3_length(ns), cs, cp;
        const float *nn = c3->s->normal + 3 * (size_t)i;
        np = refl_v3(nn[0], nn[1], nn[2]);
        dir = refl_v3_normalize(dir);
        cs = fabsf(refl_v3_dot(refl_v3_normalize(ns), dir));
        cp = refl_v3_dot(np, dir);
        /* a diffuse surface's back, seen through gaps in its front: not drawn */
        if (cp > 0.0f && c3->s->diffuse[i]) return;
        cp = fabsf(cp);
        facing = cp;
        if (sweep > 0.0f && density > 0.0f)
            spacing = sqrtf(cp / REFL__MAX(cs, 0.05f) * k->screen_area / (sweep * density));
        if (k->screen_area > 0.0f) pix_sweep = sqrtf(sweep / k->screen_area);
    }
    side = (int)ceilf(REFL__C3_SPLAT_SCALE * REFL__MIN(spacing, 1e4f));
    side = REFL__CLAMP(side, 1, refl__c3_in_fold(k, pr->t) ? REFL__MAX(c3->max_splat, (int)ceilf(2.0f * k->screen_edge))
                                                          : c3->max_splat);
    x0 = (int)floorf(px - 0.5f * (float)side + 0.5f);
    y0 = (int)floorf(py - 0.5f * (float)side + 0.5f);
    /* the surface seen there must be this triangle's: within two pixels
       of its plane (a neighbour across an edge is; another part of the
       reflector hiding it is not) and of its size from the point */
    pix = c3->pixel_angle * refl_v3_length(refl_v3_sub(q, p->view->eye));
    plane_tol = 2.0f * pix;
    tol = k->edge + (float)side * pix;
    reach = (float)side * pix_sweep / REFL__MAX(facing, 0.2f);
    disc = density > 0.0f ? REFL__C3_DISC / sqrtf(density) : INFINITY;
    for (y = REFL__MAX(y0, 0); y < REFL__MIN(y0 + side, h); ++y)
        for (x = REFL__MAX(x0, 0); x < REFL__MIN(x0 + side, w); ++x) {
            size_t j = (size_t)y * (size_t)w + (size_t)x;
            const float *r = c3->em.surface + 3 * j;
            refl_vec3 dq;
            float depth;
            if (c3->em.gbuf[4 * j + 3] != k->id) continue; /* its object, the side it faces */
            dq = refl_v3_sub(q, refl_v3(r[0], r[1], r[2]));
            if (refl_v3_dot(dq, dq) > tol * tol || fabsf(refl_v3_dot(dq, k->base_normal)) > plane_tol) continue;
            /* (the reflector's own points are spared: its neighbourhood
               is not drawn, refl__c3_near_self, so what the ray meets
               there may have no point at all) */
            if (c3->s->object[i] != k->object && !refl__c3_ray_meets(c3, j, pt, np, disc)) {
                refl__c3_mark(&c3->touched[j]);
                continue;
            }
            depth = refl__c3_depth_at(k, refl_v3(r[0], r[1], r[2]), pt, np, pr->t, reach) +
                    REFL__C3_SAME_SURFACE_SLOPE * pix_sweep * hypotf((float)x + 0.5f - px, (float)y + 0.5f - py);
            refl__c3_min(&((refl__c3 *)c3)->key[j], ((uint64_t)refl__c3_bits(depth) << 32) | (uint64_t)(uint32_t)i);
        }
}

/* The truncated volume (t <= k->sweep) is the convex hull of the tails
   and vi + sweep di (every point of it a convex combination of them):
   planes through three of those six points with all six on one side bound
   it, and a box or point beyond one of them cannot project. */
static void refl__c3_hull(refl__c3_cam *k) {
    static const int tri[14][3] = {{0, 1, 2}, {3, 4, 5}, {0, 1, 3}, {0, 1, 4}, {0, 3, 4}, {1, 3, 4},
                                   {1, 2, 4}, {1, 2, 5}, {1, 4, 5}, {2, 4, 5}, {2, 0, 5}, {2, 0, 3},
                                   {2, 5, 3}, {0, 5, 3}};
    refl_vec3 q[6];
    float scale = 0.0f;
    int i, j;
    k->hull_count = 0;
    if (!(k->sweep < FLT_MAX)) return;
    for (i = 0; i < 3; ++i) {
        q[i] = k->cam.v[i];
        q[i + 3] = refl_v3_add(k->cam.v[i], refl_v3_scale(k->cam.d[i], k->sweep));
    }
    for (i = 0; i < 6; ++i) scale = REFL__MAX(scale, refl_v3_length(refl_v3_sub(q[i], q[0])));
    for (i = 0; i < 14; ++i) {
        refl_vec3 n = refl_v3_normalize(refl_v3_cross(refl_v3_sub(q[tri[i][1]], q[tri[i][0]]),
                                                      refl_v3_sub(q[tri[i][2]], q[tri[i][0]])));
        float w = refl_v3_dot(n, q[tri[i][0]]), eps = 1e-4f * scale + 1e-6f * fabsf(w), lo = 0.0f, hi = 0.0f;
        if (refl_v3_dot(n, n) == 0.0f) continue;
        for (j = 0; j < 6; ++j) {
            float e = refl_v3_dot(n, q[j]) - w;
            lo = REFL__MIN(lo, e);
            hi = REFL__MAX(hi, e);
        }
        if (hi <= eps) { /* all on the negative side */
            k->hull[k->hull_count][0] = n.x; k->hull[k->hull_count][1] = n.y; k->hull[k->hull_count][2] = n.z;
            k->hull[k->hull_count++][3] = w + eps;
        } else if (lo >= -eps) {
            k->hull[k->hull_count][0] = -n.x; k->hull[k->hull_count][1] = -n.y; k->hull[k->hull_count][2] = -n.z;
            k->hull[k->hull_count++][3] = -w + eps;
        }
    }
}

static int refl__c3_box(void *user, const float lo[3], const float hi[3]) {
    refl__c3_cam *k = (refl__c3_cam *)user;
    double t0 = refl__now_ms();
    int i, seen = 1;
    for (i = 0; i < k->hull_count && seen; ++i) { /* the box's corner least along the plane's normal */
        const float *h = k->hull[i];
        float m = h[0] * (h[0] > 0.0f ? lo[0] : hi[0]) + h[1] * (h[1] > 0.0f ? lo[1] : hi[1]) +
                  h[2] * (h[2] > 0.0f ? lo[2] : hi[2]);
        seen = m <= h[3];
    }
    if (seen)
        seen = refl_c3rc_box_visible(&k->cam, refl_v3(lo[0], lo[1], lo[2]), refl_v3(hi[0], hi[1], hi[2]), k->sweep);
    k->t_cull += refl__now_ms() - t0;
    k->n->tests++;
    k->n->culled += !seen;
    return seen;
}

/* How many of a leaf's `count` (shuffled) points camera c draws, its
   piece's screen area and base normal given, at frame density `density`:
   all, or where the camera minifies the whole box lo-hi, enough for
   REFL__C3_LOD_SPACING pixels between points. The sweep t of any point in
   the box lies between its distances from the base plane over the largest
   and smallest di . n. */
static int refl__c3_lod_keep(const refl_c3rc *c, refl_vec3 base_normal, float screen_area, float density,
                             const float lo[3], const float hi[3], int count) {
    float dmin = FLT_MAX, dmax = -FLT_MAX, dn_min = FLT_MAX, dn_max = -FLT_MAX, t_lo, t_hi, area, spacing, keep;
    double a0, a1, a2;
    int corner, i;
    for (i = 0; i < 3; ++i) {
        float dn = refl_v3_dot(c->d[i], base_normal);
        dn_min = REFL__MIN(dn_min, dn);
        dn_max = REFL__MAX(dn_max, dn);
    }
    if (count < 16 || !(dn_min > 0.05f) || !(screen_area > 0.0f)) return count;
    for (corner = 0; corner < 8; ++corner) {
        refl_vec3 q = refl_v3(corner & 1 ? hi[0] : lo[0], corner & 2 ? hi[1] : lo[1], corner & 4 ? hi[2] : lo[2]);
        float d = refl_v3_dot(refl_v3_sub(q, c->v[0]), base_normal);
        dmin = REFL__MIN(dmin, d);
        dmax = REFL__MAX(dmax, d);
    }
    if (!(dmax > 0.0f)) return count;
    t_lo = REFL__MAX(dmin, 0.0f) / dn_max;
    t_hi = dmax / dn_min;
    a0 = refl__c3_sweep_area(c, t_lo);
    a1 = refl__c3_sweep_area(c, 0.5f * (t_lo + t_hi));
    a2 = refl__c3_sweep_area(c, t_hi);
    area = (float)REFL__MIN(a0, REFL__MIN(a1, a2));
    if (!(area > 0.0f)) return count;
    /* the densest the box's points can appear: every surface facing the ray */
    spacing = sqrtf(screen_area / (area * density));
    if (spacing >= REFL__C3_LOD_SPACING) return count;
    keep = (spacing / REFL__C3_LOD_SPACING) * (spacing / REFL__C3_LOD_SPACING);
    return REFL__MAX(1, (int)ceilf(keep * (float)count));
}

/* How many of a leaf's (shuffled) points camera k draws: thinned only
   where its rays do not fold. */
static int refl__c3_lod_count(const refl__c3_cam *k, const refl_kdtree_node *leaf) {
    if (!k->lod) return leaf->count;
    return refl__c3_lod_keep(&k->cam, k->base_normal, k->screen_area, k->c3->density, leaf->lo, leaf->hi, leaf->count);
}

/* Whether tree point i, seen by camera k at sweep t, is its reflector's
   own surface within one triangle edge of the camera: there the sampled
   (flat) neighbours of a curved reflector cross the smoothly interpolated
   rays at grazing angles, and would win the push-back over what the ray
   truly sees. The paper samples no reflector; farther self-reflections
   (a spout in the body) are kept, black as one-bounce RAYTRACE shows
   them. */
static int refl__c3_near_self(const refl__c3_cam *k, int i, float t) {
    return k->c3->s->object[i] == k->object && t < k->near_self;
}

static void refl__c3_leaf(void *user, const refl_kdtree *tree, const refl_kdtree_node *leaf) {
    refl__c3_cam *k = (refl__c3_cam *)user;
    const refl__c3 *c3 = k->c3;
    double t0 = refl__now_ms();
    int count = refl__c3_lod_count(k, leaf), i, j, n;
    float thinned = (float)count / (float)REFL__MAX(leaf->count, 1);
    refl_c3rc_projection pr[3];
    k->n->leaves++;
    k->n->tries += count; /* the paper's count: every point of a leaf the box test accepts */
    for (i = leaf->first; i < leaf->first + count; ++i) {
        const float *q = tree->positions + 3 * (size_t)i;
        /* a reflector's own triangle would see all of itself at t = 0 */
        if (c3->s->triangle[i] == k->triangle && c3->s->object[i] == k->object) continue;
        for (j = 0; j < k->hull_count; ++j) {
            const float *h = k->hull[j];
            if (h[0] * q[0] + h[1] * q[1] + h[2] * q[2] > h[3]) break;
        }
        if (j < k->hull_count) continue; /* outside the volume's hull */
        n = refl_c3rc_project(&k->cam, refl_v3(q[0], q[1], q[2]), pr);
        k->n->valid += n;
        if (n > 1) k->n->multiple += n - 1;
        for (j = 0; j < n; ++j)
            if (pr[j].t > 0.0f && !refl__c3_near_self(k, i, pr[j].t))
                refl__c3_splat(k, i, &pr[j], c3->s->object_density[c3->s->object[i]] * thinned);
    }
    k->n->ms_project += refl__now_ms() - t0;
}

/* A reflector triangle in the world: vertices, unit smooth normals, the
   unit geometric normal towards the viewer, and whether that turned it
   (a back face seen: an open mesh's inside reflects on its back side, as
   the rasteriser and RAYTRACE turn its normals). */
typedef struct refl__c3_tri {
    refl_vec3 v[3], n[3], ng;
    int back;
} refl__c3_tri;

static void refl__c3_triangle(const refl__pass *p, int object, int triangle, refl__c3_tri *t) {
    const refl_object *o = &p->scene->objects[object];
    const refl_mesh *m = p->scene->meshes[o->mesh];
    const uint32_t *tri = m->indices + 3 * (size_t)triangle;
    refl_mat4 normal_m = refl__normal_matrix(o->transform);
    int i;
    for (i = 0; i < 3; ++i) {
        const float *q = m->positions + 3 * (size_t)tri[i], *n = m->normals + 3 * (size_t)tri[i];
        t->v[i] = refl_mat4_point(o->transform, refl_v3(q[0], q[1], q[2]));
        t->n[i] = refl_v3_normalize(refl_mat4_dir(normal_m, refl_v3(n[0], n[1], n[2])));
    }
    t->ng = refl_v3_cross(refl_v3_sub(t->v[1], t->v[0]), refl_v3_sub(t->v[2], t->v[0]));
    t->back = !(refl_v3_dot(t->ng, refl_v3_sub(p->view->eye, t->v[0])) > 0.0f);
    t->ng = refl_v3_normalize(t->back ? refl_v3_scale(t->ng, -1.0f) : t->ng);
}

/* The point at barycentrics b of the triangle, and its normal interpolated
   and normalised (as RAYTRACE's). */
static void refl__c3_at(const refl__c3_tri *t, const float b[3], refl_vec3 *q, refl_vec3 *n) {
    *q = refl_v3_add(refl_v3_add(refl_v3_scale(t->v[0], b[0]), refl_v3_scale(t->v[1], b[1])),
                     refl_v3_scale(t->v[2], b[2]));
    *n = refl_v3_normalize(refl_v3_add(refl_v3_add(refl_v3_scale(t->n[0], b[0]), refl_v3_scale(t->n[1], b[1])),
                                       refl_v3_scale(t->n[2], b[2])));
}

/* The reflected ray at reflector point q with smooth normal n, of a
   triangle with unit normal ng facing the viewer (turned when `back`):
   the smooth normal turned to the side seen, or the geometric one where
   the smooth one still faces away, as RAYTRACE chooses. */
static refl_vec3 refl__c3_ray(refl_vec3 eye, refl_vec3 q, refl_vec3 n, refl_vec3 ng, int back) {
    refl_vec3 u = refl_v3_normalize(refl_v3_sub(q, eye));
    if (back) n = refl_v3_scale(n, -1.0f);
    if (!(refl_v3_dot(u, n) < 0.0f)) n = ng;
    return refl_v3_reflect(u, n);
}

/* The camera of a job's piece of reflector triangle, seen from the view:
   the reflected rays at its corners (refl__c3_ray), its size on screen and
   the side it faces. 0 when the rays make no camera. */
static int refl__c3_setup(const refl__pass *p, const refl__c3_job *job, refl__c3_cam *k) {
    refl__c3_tri t;
    refl_vec3 v[3], d[3];
    float sx[3], sy[3];
    int i, on_screen = 1;
    refl__c3_triangle(p, job->object, job->triangle, &t);
    k->object = job->object;
    k->triangle = job->triangle;
    k->id = t.back ? -(float)(job->object + 1) : (float)(job->object + 1);
    for (i = 0; i < 3; ++i) {
        refl_vec3 n;
        refl__c3_at(&t, job->corner[i], &v[i], &n);
        d[i] = refl__c3_ray(p->view->eye, v[i], n, t.ng, t.back);
        on_screen &= refl__c3_window(p, v[i], &sx[i], &sy[i]);
    }
    if (refl_c3rc_init(&k->cam, v, d) != REFL_OK) return 0;
    k->edge = REFL__MAX(refl_v3_length(refl_v3_sub(v[1], v[0])),
                        REFL__MAX(refl_v3_length(refl_v3_sub(v[2], v[1])), refl_v3_length(refl_v3_sub(v[0], v[2]))));
    k->near_self = REFL__MAX(refl_v3_length(refl_v3_sub(t.v[1], t.v[0])),
                             REFL__MAX(refl_v3_length(refl_v3_sub(t.v[2], t.v[1])), refl_v3_length(refl_v3_sub(t.v[0], t.v[2]))));
    {
        refl_vec3 e1 = refl_v3_sub(v[1], v[0]), e2 = refl_v3_sub(v[2], v[0]);
        float a = refl_v3_dot(e1, e1), b = refl_v3_dot(e1, e2), c = refl_v3_dot(e2, e2), det = a * c - b * b;
        k->bary[0] = a; k->bary[1] = b; k->bary[2] = c;
        k->bary[3] = det != 0.0f ? 1.0f / det : 0.0f;
    }
    k->screen_edge = 0.0f;
    for (i = 0; on_screen && i < 3; ++i)
        k->screen_edge = REFL__MAX(k->screen_edge, hypotf(sx[(i + 1) % 3] - sx[i], sy[(i + 1) % 3] - sy[i]));
    k->screen_area = on_screen ? 0.5f * fabsf((sx[1] - sx[0]) * (sy[2] - sy[0]) - (sx[2] - sx[0]) * (sy[1] - sy[0]))
                               : 0.0f;
    k->base_normal = t.ng;
    return 1;
}

/* A growing list of jobs. */
typedef struct refl__c3_list {
    refl__c3_job *v;
    int count, cap;
    const refl_allocator *al;
} refl__c3_list;

static refl_result refl__c3_push(refl__c3_list *l, const refl__c3_job *job) {
    if (l->count == l->cap) {
        int cap = l->cap ? 2 * l->cap : 1024;
        refl__c3_job *v = (refl__c3_job *)refl__alloc(l->al, (size_t)cap * sizeof(refl__c3_job));
        if (!v || cap < l->cap) {
            refl__free(l->al, v);
            return REFL_ERROR_OUT_OF_MEMORY;
        }
        if (l->count) memcpy(v, l->v, (size_t)l->count * sizeof(refl__c3_job));
        refl__free(l->al, l->v);
        l->v = v;
        l->cap = cap;
    }
    l->v[l->count++] = *job;
    return REFL_OK;
}

/* How far, in pixels, the job's camera may put a point from where the
   smooth reflector shows it: at the edge midpoints and the centre, the
   angle between the camera's interpolated ray and the true reflected ray,
   times the distance over which a ray offset becomes a pixel offset (up
   to tmax, less where the rays spread: an offset dt along the reflector
   moves the ray at distance t by dt (1 + t k), k the rays' turn per unit
   length), times pixels per unit on the reflector. */
static float refl__c3_error_px(const refl__pass *p, const refl__c3_tri *t, const refl__c3_job *job, float tmax) {
    static const float mid[4][3] = {{0.5f, 0.5f, 0.0f}, {0.0f, 0.5f, 0.5f}, {0.5f, 0.0f, 0.5f},
                                    {1.0f / 3.0f, 1.0f / 3.0f, 1.0f / 3.0f}};
    refl_vec3 v[3], d[3];
    float sx[3], sy[3], turn = 0.0f, delta = 0.0f, area, screen;
    int i, j;
    for (i = 0; i < 3; ++i) {
        refl_vec3 n;
        refl__c3_at(t, job->corner[i], &v[i], &n);
        d[i] = refl__c3_ray(p->view->eye, v[i], n, t->ng, t->back);
        if (!refl__c3_window(p, v[i], &sx[i], &sy[i])) return 0.0f; /* crosses the eye plane: no scale */
    }
    for (i = 0; i < 3; ++i) {
        float len = refl_v3_length(refl_v3_sub(v[(i + 1) % 3], v[i]));
        if (len > 0.0f) turn = REFL__MAX(turn, refl_v3_length(refl_v3_sub(d[(i + 1) % 3], d[i])) / len);
    }
    for (j = 0; j < 4; ++j) {
        float b[3];
        refl_vec3 q, n, camera = refl_v3(0, 0, 0);
        for (i = 0; i < 3; ++i) {
            b[i] = mid[j][0] * job->corner[0][i] + mid[j][1] * job->corner[1][i] + mid[j][2] * job->corner[2][i];
            camera = refl_v3_add(camera, refl_v3_scale(d[i], mid[j][i]));
        }
        refl__c3_at(t, b, &q, &n);
        delta = REFL__MAX(delta, refl_v3_length(refl_v3_sub(refl_v3_normalize(camera),
                                                            refl__c3_ray(p->view->eye, q, n, t->ng, t->back))));
    }
    area = 0.5f * refl_v3_length(refl_v3_cross(refl_v3_sub(v[1], v[0]), refl_v3_sub(v[2], v[0])));
    screen = 0.5f * fabsf((sx[1] - sx[0]) * (sy[2] - sy[0]) - (sx[2] - sx[0]) * (sy[1] - sy[0]));
    if (!(area > 0.0f)) return 0.0f;
    return delta * tmax / (1.0f + tmax * turn) * sqrtf(screen / area);
}

/* Appends the cameras of one reflector triangle: its own, split in four at
   the edge midpoints while refl__c3_error_px exceeds split_px (< 0: never)
   (down to REFL__C3_SPLIT_DEPTH levels): no more cameras than the
   triangle's curvature and size on screen need. */
static refl_result refl__c3_split(const refl__pass *p, const refl__c3_tri *t, const refl__c3_job *job, float tmax,
                                  float split_px, int depth, refl__c3_list *out) {
    refl__c3_job sub;
    float m[3][3];
    int i, k;
    if (split_px < 0.0f || depth >= REFL__C3_SPLIT_DEPTH || refl__c3_error_px(p, t, job, tmax) <= split_px)
        return refl__c3_push(out, job);
    for (i = 0; i < 3; ++i) /* midpoint of edge i, i + 1 */
        for (k = 0; k < 3; ++k) m[i][k] = 0.5f * (job->corner[i][k] + job->corner[(i + 1) % 3][k]);
    sub.object = job->object;
    sub.triangle = job->triangle;
    for (i = 0; i < 4; ++i) {
        refl_result r;
        for (k = 0; k < 3; ++k) {
            if (i == 3) { /* the middle piece */
                sub.corner[0][k] = m[0][k]; sub.corner[1][k] = m[1][k]; sub.corner[2][k] = m[2][k];
            } else { /* the piece at corner i */
                sub.corner[0][k] = job->corner[i][k];
                sub.corner[1][k] = m[i][k];
                sub.corner[2][k] = m[(i + 2) % 3][k];
            }
        }
        if ((r = refl__c3_split(p, t, &sub, tmax, split_px, depth + 1, out)) != REFL_OK) return r;
    }
    return REFL_OK;
}

/* Appends triangle `triangle` of `object`'s cameras. */
static refl_result refl__c3_add_triangle(const refl__pass *p, int object, int triangle, float tmax, float split_px,
                                         refl__c3_list *out) {
    refl__c3_tri t;
    refl__c3_job job;
    memset(&job, 0, sizeof job);
    job.object = object;
    job.triangle = triangle;
    job.corner[0][0] = job.corner[1][1] = job.corner[2][2] = 1.0f;
    refl__c3_triangle(p, object, triangle, &t);
    return refl__c3_split(p, &t, &job, tmax, split_px == 0.0f ? REFL__C3_SPLIT_PX : split_px, 0, out);
}

/* The largest sweep t a point within tmax of the camera's base can have
   (INFINITY: unbounded): t = distance / |a d1 + b d2 + c d3| >= distance
   / sqrt(min di . dj); converging rays sweep past tmax. */
static float refl__c3_sweep_bound(const refl_c3rc *c, float tmax) {
    float dmin = REFL__MIN(refl_v3_dot(c->d[0], c->d[1]),
                           REFL__MIN(refl_v3_dot(c->d[1], c->d[2]), refl_v3_dot(c->d[2], c->d[0])));
    return dmin > 0.25f ? tmax / sqrtf(dmin) : INFINITY;
}

/* Section 5.1's sweep intervals where camera c's rays fold (out: fold),
   over its sweep bound and at most four scene diagonals (tmax); how many.
   Level of detail thins only a camera with none. */
static int refl__c3_folds(const refl_c3rc *c, float sweep, float tmax, float fold[4][2]) {
    return refl_c3rc_multiple_intervals(c, REFL__MIN(sweep, 4.0f * tmax), fold);
}

/* One camera: reflector triangle jobs[index], built and drawn. */
static void refl__c3_camera(void *arg, int index) {
    const refl__c3 *c3 = (const refl__c3 *)arg;
    refl__c3_cam k;
    memset(&k, 0, sizeof k);
    k.c3 = c3;
    k.n = &((refl__c3 *)c3)->counts[index];
    if (!refl__c3_setup(c3->p, &c3->jobs[index], &k)) return;
    k.sweep = refl__c3_sweep_bound(&k.cam, c3->tmax);
    refl__c3_hull(&k);
    k.folds = refl__c3_folds(&k.cam, k.sweep, c3->tmax, k.fold);
    k.lod = k.folds == 0;
    refl_kdtree_query(c3->s->tree, refl__c3_box, refl__c3_leaf, &k);
    k.n->ms_cull += k.t_cull;
}

/* A point's texture coordinates: the barycentrics of p in its (world)
   triangle applied to the mesh's uvs. */
static int refl__c3_uv(const refl_mesh *m, refl_mat4 transform, int triangle, refl_vec3 p, float uv[2]) {
    const uint32_t *tri = m->indices + 3 * (size_t)triangle;
    refl_vec3 v[3], e1, e2, w, n;
    float nn, b, c;
    int i;
    if (!m->texcoords) return 0;
    for (i = 0; i < 3; ++i) {
        const float *q = m->positions + 3 * (size_t)tri[i];
        v[i] = refl_mat4_point(transform, refl_v3(q[0], q[1], q[2]));
    }
    e1 = refl_v3_sub(v[1], v[0]);
    e2 = refl_v3_sub(v[2], v[0]);
    w = refl_v3_sub(p, v[0]);
    n = refl_v3_cross(e1, e2);
    nn = refl_v3_dot(n, n);
    if (!(nn > 0.0f)) return 0;
    b = refl_v3_dot(refl_v3_cross(w, e2), n) / nn;
    c = refl_v3_dot(refl_v3_cross(e1, w), n) / nn;
    for (i = 0; i < 2; ++i)
        uv[i] = (1.0f - b - c) * m->texcoords[2 * tri[0] + (uint32_t)i] + b * m->texcoords[2 * tri[1] + (uint32_t)i] +
                c * m->texcoords[2 * tri[2] + (uint32_t)i];
    return 1;
}

typedef struct refl__c3_shade_arg {
    refl__c3 *c3;
    int chunk;
} refl__c3_shade_arg;

/* Shades tree points [index * chunk, ...) as DIRECT shows their surface. */
static void refl__c3_shade(void *arg, int index) {
    const refl__c3_shade_arg *a = (const refl__c3_shade_arg *)arg;
    refl__c3 *c3 = a->c3;
    const refl_scene *scene = c3->p->scene;
    int i, end = REFL__MIN(c3->s->tree->point_count, (index + 1) * a->chunk);
    for (i = index * a->chunk; i < end; ++i) {
        const refl_object *o = &scene->objects[c3->s->object[i]];
        const refl_material *m = &scene->materials[o->material];
        const float *q = c3->s->tree->positions + 3 * (size_t)i, *n = c3->s->normal + 3 * (size_t)i;
        refl_vec3 pt = refl_v3(q[0], q[1], q[2]);
        float rgb[3] = {0.0f, 0.0f, 0.0f}, rgba[4], uv[2];
        if (m->type == REFL_DIFFUSE || m->type == REFL_PARTIAL) {
            int has_uv = refl__c3_uv(scene->meshes[o->mesh], o->transform, c3->s->triangle[i], pt, uv);
            refl_shade_diffuse(scene, m, pt, refl_v3(n[0], n[1], n[2]), has_uv ? uv : NULL, rgb);
            refl__surface_rgba(m, rgb, rgba);
            memcpy(rgb, rgba, sizeof rgb);
        }
        memcpy(c3->s->rgb + 3 * (size_t)i, rgb, sizeof rgb);
    }
}

/* Samples every object at the density, builds the kd-tree over the
   points and shades them (tree order). */
static double refl__c3_object_area(const refl_scene *scene, int i);

static refl_result refl__c3_points(refl__c3 *c3) {
    const refl__pass *p = c3->p;
    const refl_scene *scene = p->scene;
    const refl_allocator *al = &scene->allocator;
    refl_points **pts;
    float *all = NULL, *nrm = NULL;
    int32_t *obj = NULL, *tri = NULL;
    long long total = 0;
    refl_kdtree_desc kd;
    refl__c3_shade_arg sa;
    refl_result r = REFL_OK;
    int i, k;
    double expect = 0.0;
    /* refused before a point is allocated, with what they would take */
    for (i = 0; i < scene->object_count; ++i)
        expect += refl__c3_object_area(scene, i) * (double)c3->s->object_density[i];
    if (!(expect <= REFL__C3_MAX_POINTS)) {
        refl__frame_say(p->frame, "c3rc.point_density: about %.3g points (%.0f MiB), more than C3RC's %.0f", expect,
                        expect * REFL__C3_POINT_BYTES / 1048576.0, REFL__C3_MAX_POINTS);
        return REFL_ERROR_INVALID_SIZE;
    }
    pts = (refl_points **)refl__calloc(al, (size_t)REFL__MAX(scene->object_count, 1), sizeof(refl_points *));
    if (!pts) return REFL_ERROR_OUT_OF_MEMORY;
    for (i = 0; i < scene->object_count && r == REFL_OK; ++i) {
        const refl_object *o = &scene->objects[i];
        r = refl_mesh_sample_points(scene->meshes[o->mesh], &o->transform, c3->s->object_density[i],
                                    0x9e3779b97f4a7c15ull + (uint64_t)i, al, &pts[i]);
        if (r == REFL_OK) total += pts[i]->count;
    }
    if (r == REFL_OK && total > INT32_MAX / 4) r = REFL_ERROR_INVALID_SIZE;
    if (r == REFL_OK) {
        all = (float *)refl__calloc(al, (size_t)total, 3 * sizeof(float));
        nrm = (float *)refl__calloc(al, (size_t)total, 3 * sizeof(float));
        obj = (int32_t *)refl__calloc(al, (size_t)total, sizeof(int32_t));
        tri = (int32_t *)refl__calloc(al, (size_t)total, sizeof(int32_t));
        if (!all || !nrm || !obj || !tri) r = REFL_ERROR_OUT_OF_MEMORY;
    }
    if (r == REFL_OK) {
        size_t at = 0;
        for (i = 0; i < scene->object_count; ++i) {
            memcpy(all + 3 * at, pts[i]->positions, (size_t)pts[i]->count * 3 * sizeof(float));
            memcpy(nrm + 3 * at, pts[i]->normals, (size_t)pts[i]->count * 3 * sizeof(float));
            for (k = 0; k < pts[i]->count; ++k) {
                obj[at + (size_t)k] = i;
                tri[at + (size_t)k] = (int32_t)pts[i]->triangles[k];
            }
            at += (size_t)pts[i]->count;
        }
        memset(&kd, 0, sizeof kd);
        kd.leaf_points = p->desc.c3rc.kd_leaf_points;
        kd.allocator = *al;
        r = refl_kdtree_build(all, (int)total, &kd, &c3->s->tree);
    }
    if (r == REFL_OK) { /* per-point data in tree order */
        int n = c3->s->tree->point_count;
        c3->s->rgb = (float *)refl__calloc(al, (size_t)REFL__MAX(n, 1), 3 * sizeof(float));
        c3->s->normal = (float *)refl__calloc(al, (size_t)REFL__MAX(n, 1), 3 * sizeof(float));
        c3->s->object = (int32_t *)refl__calloc(al, (size_t)REFL__MAX(n, 1), sizeof(int32_t));
        c3->s->triangle = (int32_t *)refl__calloc(al, (size_t)REFL__MAX(n, 1), sizeof(int32_t));
        c3->s->diffuse = (uint8_t *)refl__calloc(al, (size_t)REFL__MAX(n, 1), 1);
        if (!c3->s->rgb || !c3->s->normal || !c3->s->object || !c3->s->triangle || !c3->s->diffuse) r = REFL_ERROR_OUT_OF_MEMORY;
        for (i = 0; r == REFL_OK && i < n; ++i) {
            uint32_t src = c3->s->tree->order[i];
            memcpy(c3->s->normal + 3 * (size_t)i, nrm + 3 * (size_t)src, 3 * sizeof(float));
            c3->s->object[i] = obj[src];
            c3->s->triangle[i] = tri[src];
            c3->s->diffuse[i] = !refl__is_reflector(&scene->materials[scene->objects[obj[src]].material]);
        }
        if (r == REFL_OK && n > 0) {
            sa.c3 = c3;
            sa.chunk = 4096;
            rast_run_jobs(p->rc, (n + sa.chunk - 1) / sa.chunk, refl__c3_shade, &sa);
        }
    }
    for (i = 0; i < scene->object_count; ++i) refl_points_destroy(pts[i]);
    refl__free(al, pts);
    refl__free(al, all);
    refl__free(al, nrm);
    refl__free(al, obj);
    refl__free(al, tri);
    return r;
}

/* The depth a key holds (refl__c3_splat). */
static float refl__c3_key_depth(uint64_t key) {
    uint32_t u = (uint32_t)(key >> 32);
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

/* Whether reflector pixel (x, y), showing `shown` (REFL__C3_EMPTY: no
   point), lies in a gap of a nearer surface's points: along a row, a
   column or a diagonal through it, both ways within f->reach pixels of the
   same reflector side, the first pixel showing another object's point
   (any point, for an empty pixel) shows it nearer (REFL__C3_GAP_NEARER).
   Where a reflection magnifies, the random points leave gaps their
   splats do not close, and a gap shows the environment or the surface
   behind the one the ray meets (the floor behind a concave bowl, the
   bowl behind the ball at its focus): no point tells C3RC what the ray
   meets there, so the pixel goes to the tracer. A pixel that nearer
   points do not surround keeps what it shows: an object's silhouette
   over what lies behind it, the environment where the rays leave the
   scene. The GL path (tools/reflect_gl_c3rc.c) asks it too. */
REFL_API int refl_c3rc_in_gap(const refl_c3rc_splats *f, int x, int y, uint64_t shown) {
    static const int dir[4][2] = {{1, 0}, {0, 1}, {1, 1}, {1, -1}};
    int w = f->width, h = f->height, a, side, s;
    float id = f->side[(size_t)f->side_stride * ((size_t)y * (size_t)w + (size_t)x)];
    float depth = shown == REFL__C3_EMPTY ? INFINITY : refl__c3_key_depth(shown);
    int32_t object = shown == REFL__C3_EMPTY ? -1 : f->point_object[shown & 0xffffffffu];
    for (a = 0; a < 4; ++a) {
        int nearer = 0;
        for (side = -1; side <= 1; side += 2)
            for (s = 1; s <= f->reach; ++s) {
                int xs = x + side * s * dir[a][0], ys = y + side * s * dir[a][1];
                size_t j = (size_t)ys * (size_t)w + (size_t)xs;
                uint64_t kj;
                if (xs < 0 || ys < 0 || xs >= w || ys >= h || f->side[(size_t)f->side_stride * j] != id) break;
                kj = f->key[j];
                if (kj == REFL__C3_EMPTY || f->point_object[kj & 0xffffffffu] == object) continue;
                nearer += refl__c3_key_depth(kj) < REFL__C3_GAP_NEARER * depth;
                break;
            }
        if (nearer == 2) return 1;
    }
    return 0;
}

REFL_API int refl_c3rc_gap_reach(int max_splat, float spacing_scale) {
    /* the splats close gaps up to max_splat across; points spaced wider
       than the density wanted leave wider ones */
    return (int)REFL__MIN(ceilf(2.0f * (float)max_splat * REFL__MAX(spacing_scale, 1.0f)), 256.0f);
}

/* Composites one row: the winning point's colour (or the environment
   along the reflected ray) times the reflectance, as ENVMAP composites;
   a pixel in a gap of the points (refl_c3rc_in_gap) is marked for the
   tracer instead. */
static void refl__c3_resolve_row(void *arg, int y) {
    const refl__c3 *c3 = (const refl__c3 *)arg;
    const refl_frame *fr = c3->p->frame;
    refl_c3rc_splats splats;
    int x;
    splats.width = fr->width;
    splats.height = fr->height;
    splats.side = c3->em.gbuf + 3;
    splats.side_stride = 4;
    splats.key = c3->key;
    splats.point_object = c3->s->object;
    splats.reach = refl_c3rc_gap_reach(c3->max_splat, c3->s->spacing_scale);
    for (x = 0; x < fr->width; ++x) {
        size_t i = (size_t)y * (size_t)fr->width + (size_t)x;
        uint64_t key = c3->key[i];
        if (key == REFL__C3_EMPTY && c3->touched[i]) {
            /* splats reached it but its ray met none: it shows what its
               4-neighbours on the reflector show nearest, not a hole */
            int n;
            uint64_t best = REFL__C3_EMPTY;
            for (n = 0; n < 4; ++n) {
                int xs = x + (n == 0) - (n == 1), ys = y + (n == 2) - (n == 3);
                size_t j = (size_t)ys * (size_t)fr->width + (size_t)xs;
                if (xs < 0 || ys < 0 || xs >= fr->width || ys >= fr->height ||
                    c3->em.gbuf[4 * j + 3] != c3->em.gbuf[4 * i + 3])
                    continue;
                best = REFL__MIN(best, c3->key[j]);
            }
            key = best;
        }
        if (refl_c3rc_in_gap(&splats, x, y, key)) {
            /* RAYTRACE's colour and point: here, or with the bounces past
               C3RC's when the frame traces them (refl__trace_beyond) */
            (c3->p->trace ? c3->p->trace : c3->gap)[i] = REFL__TRACE_ALL;
        } else if (key != REFL__C3_EMPTY) {
            size_t k = (size_t)(key & 0xffffffffu);
            const float *q = c3->s->tree->positions + 3 * k;
            refl__em_composite(c3->p, c3->em.gbuf + 4 * i, x, y, c3->s->rgb + 3 * k, refl_v3(q[0], q[1], q[2]));
            /* a reflector's point: the path goes on past C3RC's one bounce */
            if (c3->p->trace && !c3->s->diffuse[k]) c3->p->trace[i] = REFL__TRACE_COLOUR;
        } else {
            refl__em_composite(c3->p, c3->em.gbuf + 4 * i, x, y, NULL, refl_v3(NAN, NAN, NAN));
        }
    }
}

/* Whether triangle t of object i can be seen: front-facing, or a back
   face (the inside of an open mesh) with a pixel of its object's back
   side in its screen box (x0, y0)-(x1, y1) whose surface lies in its
   plane, within two pixels. Boxes over 4096 pixels are not scanned. */
static int refl__c3_back_seen(const refl__c3 *c3, const refl_object *o, const refl_mesh *m, int t, int i, int x0,
                              int y0, int x1, int y1) {
    const refl__pass *p = c3->p;
    const uint32_t *tri = m->indices + 3 * (size_t)t;
    refl_vec3 v[3], ng;
    int k, x, y, w = p->frame->width;
    for (k = 0; k < 3; ++k) {
        const float *q = m->positions + 3 * (size_t)tri[k];
        v[k] = refl_mat4_point(o->transform, refl_v3(q[0], q[1], q[2]));
    }
    ng = refl_v3_cross(refl_v3_sub(v[1], v[0]), refl_v3_sub(v[2], v[0]));
    if (refl_v3_dot(ng, refl_v3_sub(p->view->eye, v[0])) > 0.0f) return 1;
    if ((long long)(x1 - x0) * (y1 - y0) > 4096) return 1;
    ng = refl_v3_normalize(ng);
    for (y = y0; y < y1; ++y)
        for (x = x0; x < x1; ++x) {
            size_t j = (size_t)y * (size_t)w + (size_t)x;
            const float *r = c3->em.surface + 3 * j;
            refl_vec3 d;
            if (c3->em.gbuf[4 * j + 3] != -(float)(i + 1)) continue;
            d = refl_v3_sub(refl_v3(r[0], r[1], r[2]), v[0]);
            if (fabsf(refl_v3_dot(d, ng)) <= 2.0f * c3->pixel_angle * refl_v3_length(refl_v3_sub(refl_v3(r[0], r[1], r[2]), p->view->eye)))
                return 1;
        }
    return 0;
}

/* The cameras worth building: those of the reflector triangles that can
   be seen (front faces whose screen box holds a pixel of their object, a
   summed-area table per object answering that in constant time, and back
   faces seen, refl__c3_back_seen), split where one camera would be too
   coarse (refl__c3_split). */
static refl_result refl__c3_jobs(refl__c3 *c3, const unsigned char *seen, int *count) {
    const refl__pass *p = c3->p;
    const refl_scene *scene = p->scene;
    const refl_allocator *al = &scene->allocator;
    int w = p->frame->width, h = p->frame->height, i, t, x, y;
    refl__c3_list list;
    refl_result r = REFL_OK;
    uint32_t *sat = (uint32_t *)refl__calloc(al, (size_t)(w + 1) * (size_t)(h + 1), sizeof(uint32_t));
    if (!sat) return REFL_ERROR_OUT_OF_MEMORY;
    memset(&list, 0, sizeof list);
    list.al = al;
    for (i = 0; i < scene->object_count && r == REFL_OK; ++i) {
        const refl_object *o = &scene->objects[i];
        const refl_mesh *m = scene->meshes[o->mesh];
        if (!seen[i]) continue;
        for (y = 0; y < h; ++y)
            for (x = 0; x < w; ++x) {
                size_t a = (size_t)(y + 1) * (size_t)(w + 1) + (size_t)(x + 1);
                uint32_t here = fabsf(c3->em.gbuf[4 * ((size_t)y * (size_t)w + (size_t)x) + 3]) == (float)(i + 1);
                sat[a] = here + sat[a - 1] + sat[a - (size_t)(w + 1)] - sat[a - (size_t)(w + 1) - 1];
            }
        for (t = 0; t < m->triangle_count && r == REFL_OK; ++t) {
            float sx, sy, lx = FLT_MAX, ly = FLT_MAX, hx = -FLT_MAX, hy = -FLT_MAX;
            int k, x0, y0, x1, y1, front = 1;
            for (k = 0; k < 3; ++k) {
                const float *q = m->positions + 3 * (size_t)m->indices[3 * (size_t)t + (size_t)k];
                if (!refl__c3_window(p, refl_mat4_point(o->transform, refl_v3(q[0], q[1], q[2])), &sx, &sy)) {
                    front = 0; /* crosses the eye plane: keep it, box unknown */
                    break;
                }
                lx = REFL__MIN(lx, sx); hx = REFL__MAX(hx, sx);
                ly = REFL__MIN(ly, sy); hy = REFL__MAX(hy, sy);
            }
            if (front) {
                x0 = REFL__CLAMP((int)floorf(lx), 0, w);
                y0 = REFL__CLAMP((int)floorf(ly), 0, h);
                x1 = REFL__CLAMP((int)floorf(hx) + 1, 0, w);
                y1 = REFL__CLAMP((int)floorf(hy) + 1, 0, h);
                if (x1 <= x0 || y1 <= y0) continue;
                if (sat[(size_t)y1 * (size_t)(w + 1) + (size_t)x1] - sat[(size_t)y0 * (size_t)(w + 1) + (size_t)x1] -
                        sat[(size_t)y1 * (size_t)(w + 1) + (size_t)x0] + sat[(size_t)y0 * (size_t)(w + 1) + (size_t)x0] ==
                    0)
                    continue;
                if (!refl__c3_back_seen(c3, o, m, t, i, x0, y0, x1, y1)) continue;
            }
            r = refl__c3_add_triangle(p, i, t, c3->tmax, p->desc.c3rc.camera_split_px, &list);
        }
    }
    refl__free(al, sat);
    c3->jobs = list.v;
    *count = list.count;
    return r;
}

/* Object i's surface area in the world. */
static double refl__c3_object_area(const refl_scene *scene, int i) {
    const refl_object *o = &scene->objects[i];
    const refl_mesh *m = scene->meshes[o->mesh];
    double area = 0.0;
    int t, k;
    for (t = 0; t < m->triangle_count; ++t) {
        refl_vec3 v[3];
        for (k = 0; k < 3; ++k) {
            const float *q = m->positions + 3 * (size_t)m->indices[3 * (size_t)t + (size_t)k];
            v[k] = refl_mat4_point(o->transform, refl_v3(q[0], q[1], q[2]));
        }
        area += 0.5 * (double)refl_v3_length(refl_v3_cross(refl_v3_sub(v[1], v[0]), refl_v3_sub(v[2], v[0])));
    }
    return area;
}

/* The default density: one point per 2 x 2 pixels where the reflectors
   are (the footprint at the distance of their nearest bounds), at most
   REFL__C3_AUTO_POINTS in all; splats grow where that is too few.
   *wanted: the density before that cap. */
static float refl__c3_auto_density(const refl__c3 *c3, const unsigned char *seen, float *wanted) {
    const refl__pass *p = c3->p;
    const refl_scene *scene = p->scene;
    float nearest = FLT_MAX, size;
    double area = 0.0;
    int i, corner;
    for (i = 0; i < scene->object_count; ++i) {
        const refl_object *o = &scene->objects[i];
        refl_vec3 lo, hi, c;
        if (!seen[i]) continue;
        refl_mesh_bounds(scene->meshes[o->mesh], &lo, &hi);
        for (corner = 0; corner < 9; ++corner) {
            refl_vec3 q = corner == 8 ? refl_v3_scale(refl_v3_add(lo, hi), 0.5f)
                                      : refl_v3(corner & 1 ? hi.x : lo.x, corner & 2 ? hi.y : lo.y, corner & 4 ? hi.z : lo.z);
            c = refl_mat4_point(o->transform, q);
            nearest = REFL__MIN(nearest, refl_v3_length(refl_v3_sub(c, p->view->eye)));
        }
    }
    size = 2.0f * REFL__MAX(nearest, p->rays.znear) * c3->pixel_angle;
    /* at most REFL__C3_AUTO_POINTS over the whole scene (a viewer close to
       a mirror would ask for tens of millions) */
    for (i = 0; i < scene->object_count; ++i) area += refl__c3_object_area(scene, i);
    *wanted = 0.0f;
    if (!(size > 0.0f)) return 0.0f;
    *wanted = (float)(1.0 / ((double)size * size));
    return (float)REFL__MIN(1.0 / ((double)size * size), area > 0.0 ? REFL__C3_AUTO_POINTS / area : 0.0);
}


/* Raises dens (per object, points per unit area) where camera cam, of
   screen_area pixels, folds (section 5.1: its rays converge, the paper's
   quasi-convergence region) and shows an object magnified, to one point
   per REFL__C3_PIXELS_PER_POINT pixels there: the magnification at the
   object's centre and box corners is the camera's screen area over its
   sweeping triangle's area at their t. Diffuse objects only (a
   reflector's own points show black); at most REFL__C3_MAX_BOOST times
   the frame's density. */
static void refl__c3_raise_densities(const refl_scene *scene, const refl_c3rc *cam, float screen_area, float density,
                                     float tmax, float *dens) {
    float folds[4][2];
    int i, corner;
    if (!(screen_area > 0.0f) || refl_c3rc_multiple_intervals(cam, 4.0f * tmax, folds) == 0) return;
    for (i = 0; i < scene->object_count; ++i) {
        const refl_object *o = &scene->objects[i];
        refl_vec3 lo, hi;
        if (refl__is_reflector(&scene->materials[o->material])) continue;
        refl_mesh_bounds(scene->meshes[o->mesh], &lo, &hi);
        for (corner = 0; corner < 9; ++corner) {
            refl_c3rc_projection pr[3];
            refl_vec3 q = corner == 8 ? refl_v3_scale(refl_v3_add(lo, hi), 0.5f)
                                      : refl_v3(corner & 1 ? hi.x : lo.x, corner & 2 ? hi.y : lo.y, corner & 4 ? hi.z : lo.z);
            int m = refl_c3rc_project(cam, refl_mat4_point(o->transform, q), pr), r;
            for (r = 0; r < m; ++r) {
                double sweep = refl__c3_sweep_area(cam, pr[r].t);
                float want = sweep > 0.0 ? (float)((double)screen_area / (sweep * REFL__C3_PIXELS_PER_POINT)) : FLT_MAX;
                dens[i] = REFL__MAX(dens[i], REFL__MIN(want, REFL__C3_MAX_BOOST * density));
            }
        }
    }
}

/* The budget: all objects together at most REFL__C3_AUTO_POINTS points,
   the raises above the frame's density scaled down together. Returns the
   largest factor an object's density was scaled down by (1: none). */
static float refl__c3_density_budget(const refl_scene *scene, float density, float *dens) {
    double total = 0.0, area_all = 0.0;
    float most = 1.0f;
    int i;
    for (i = 0; i < scene->object_count; ++i) {
        double area = refl__c3_object_area(scene, i);
        total += area * (double)dens[i];
        area_all += area * (double)density;
    }
    if (total > REFL__C3_AUTO_POINTS && total > area_all) {
        double keep = REFL__MAX(0.0, (REFL__C3_AUTO_POINTS - area_all) / (total - area_all));
        for (i = 0; i < scene->object_count; ++i) {
            float kept = density + (float)(keep * (double)(dens[i] - density));
            if (kept > 0.0f) most = REFL__MAX(most, dens[i] / kept);
            dens[i] = kept;
        }
    }
    return most;
}

/* Each object's sampling density (c3->s->object_density): the frame's,
   raised (when `magnify`) where a folding camera shows the object
   magnified (refl__c3_raise_densities), within the budget. */
static refl_result refl__c3_object_densities(refl__c3 *c3, int jobs, int magnify) {
    const refl__pass *p = c3->p;
    const refl_scene *scene = p->scene;
    float *dens = (float *)refl__calloc(&scene->allocator, (size_t)REFL__MAX(scene->object_count, 1), sizeof(float));
    int i, j;
    if (!dens) return REFL_ERROR_OUT_OF_MEMORY;
    c3->s->object_density = dens;
    for (i = 0; i < scene->object_count; ++i) dens[i] = c3->density;
    c3->s->spacing_scale = c3->density > 0.0f && c3->wanted_density > c3->density
                               ? sqrtf(c3->wanted_density / c3->density) : 1.0f;
    if (!magnify) return REFL_OK;
    for (j = 0; j < jobs; ++j) {
        refl__c3_cam k;
        memset(&k, 0, sizeof k);
        if (refl__c3_setup(p, &c3->jobs[j], &k)) refl__c3_raise_densities(scene, &k.cam, k.screen_area, c3->density, c3->tmax, dens);
    }
    c3->s->spacing_scale *= sqrtf(refl__c3_density_budget(scene, c3->density, dens));
    return REFL_OK;
}

static const char *refl__options_c3rc(refl_render_desc *d) {
    const refl_c3rc_options *o = &d->c3rc;
    if (!(o->point_density >= 0.0f) || !refl__isfinite(o->point_density))
        return "c3rc.point_density: finite, 0 (from the view) or more";
    if (o->kd_leaf_points < 0) return "c3rc.kd_leaf_points: 0 (1000) or more";
    if (o->max_splat < 0 || o->max_splat > 64) return "c3rc.max_splat: 0 (8) to 64";
    if (!refl__isfinite(o->camera_split_px)) return "c3rc.camera_split_px: finite";
    return NULL;
}

static refl_result refl__method_c3rc(refl__pass *p) {
    const refl_scene *scene = p->scene;
    const refl_allocator *al = &scene->allocator;
    refl_frame *fr = p->frame;
    refl__c3 c3;
    unsigned char *seen = NULL;
    size_t npx = (size_t)fr->width * (size_t)fr->height, k;
    double t0 = refl__now_ms(), t1, t_jobs = 0.0;
    refl_result r = REFL_OK;
    refl_vec3 lo, hi;
    int i, any = 0, jobs = 0;
    memset(&c3, 0, sizeof c3);
    c3.p = p;
    c3.em.p = p;
    c3.pixel_angle = 2.0f * refl_v3_length(p->rays.up) / (float)fr->height;
    c3.max_splat = p->desc.c3rc.max_splat > 0 ? p->desc.c3rc.max_splat : 8;
    refl_scene_bounds(scene, &lo, &hi);
    c3.tmax = 1.01f * refl_v3_length(refl_v3_sub(hi, lo));
    r = refl__em_gbuffer_new(&c3.em, &seen, &any);
    if (r == REFL_OK && any) {
        c3.em.surface = (float *)refl__calloc(al, npx, 3 * sizeof(float));
        c3.key = (uint64_t *)refl__alloc(al, npx * sizeof(uint64_t));
        c3.ray = (float *)refl__alloc(al, npx * 4 * sizeof(float));
        c3.touched = (uint8_t *)refl__calloc(al, npx, 1);
        c3.gap = (uint8_t *)refl__calloc(al, npx, 1);
        if (!c3.em.surface || !c3.key || !c3.ray || !c3.touched || !c3.gap) r = REFL_ERROR_OUT_OF_MEMORY;
    }
    if (r == REFL_OK && any) {
        refl__models *models = p->models;
        c3.density = p->desc.c3rc.point_density > 0.0f ? p->desc.c3rc.point_density
                     : models && models->c3             ? models->c3_density
                                                        : refl__c3_auto_density(&c3, seen, &c3.wanted_density);
        for (k = 0; k < npx; ++k) c3.key[k] = REFL__C3_EMPTY;
        rast_run_jobs(p->rc, fr->height, refl__em_surface_row, &c3.em);
        rast_run_jobs(p->rc, fr->height, refl__c3_ray_row, &c3);
        t1 = refl__now_ms();
        r = refl__c3_jobs(&c3, seen, &jobs); /* the cameras, before the points: they size the densities */
        t_jobs = refl__now_ms() - t1;
        if (r == REFL_OK && models && models->c3) {
            c3.s = models->c3; /* a renderer's density never changes */
        } else if (r == REFL_OK) {
            c3.s = (refl__c3_samples *)refl__calloc(al, 1, sizeof *c3.s);
            r = c3.s ? refl__c3_object_densities(&c3, jobs, !(p->desc.c3rc.point_density > 0.0f))
                     : REFL_ERROR_OUT_OF_MEMORY;
            if (r == REFL_OK) r = refl__c3_points(&c3);
            fr->stats.scene_models_built++;
            if (r == REFL_OK && models) {
                models->c3 = c3.s;
                models->c3_density = c3.density;
            }
        }
        t1 = refl__now_ms();
        fr->stats.ms_build += t1 - t0 - t_jobs;
        t0 = t1 - t_jobs; /* the cameras count as reflection time */
        if (r == REFL_OK) {
            c3.counts = (refl__c3_counts *)refl__calloc(al, (size_t)REFL__MAX(jobs, 1), sizeof(refl__c3_counts));
            if (!c3.counts) r = REFL_ERROR_OUT_OF_MEMORY;
        }
        if (r == REFL_OK) {
            rast_run_jobs(p->rc, jobs, refl__c3_camera, &c3);
            for (i = 0; i < jobs; ++i) {
                const refl__c3_counts *n = &c3.counts[i];
                fr->stats.c3rc.leaves += n->leaves;
                fr->stats.c3rc.culled += n->culled;
                fr->stats.c3rc.box_tests += n->tests;
                fr->stats.c3rc.projections += n->tries;
                fr->stats.c3rc.projected += n->valid;
                fr->stats.c3rc.multiple += n->multiple;
                fr->stats.c3rc.ms_cull += n->ms_cull;
                fr->stats.c3rc.ms_project += n->ms_project;
            }
            fr->stats.c3rc.cameras += jobs;
            fr->stats.c3rc.points += c3.s->tree->point_count;
            fr->stats.model_bytes += (long long)c3.s->tree->point_count * (long long)(3 * sizeof(float)) +
                                     (long long)c3.s->tree->node_count * (long long)sizeof(refl_kdtree_node) +
                                     (long long)jobs * (long long)sizeof(refl_c3rc);
            t1 = refl__now_ms();
            fr->stats.ms_reflect += t1 - t0;
            t0 = t1;
            rast_run_jobs(p->rc, fr->height, refl__c3_resolve_row, &c3);
            fr->stats.ms_composite += refl__now_ms() - t0;
            for (k = 0; k < npx; ++k)
                fr->stats.c3rc.traced += (p->trace ? p->trace[k] : c3.gap[k]) == REFL__TRACE_ALL;
            if (fr->stats.c3rc.traced && !p->trace) r = refl__trace_marked(p, c3.gap);
        }
    }
    if (r == REFL_OK) {
        rast_targets t = refl__frame_targets(fr);
        r = refl__result_from_rast(rast_set_targets(p->rc, &t));
    }
    if (!p->models || p->models->c3 != c3.s) refl__c3_samples_free(al, c3.s); /* this frame's own */
    refl__free(al, c3.em.gbuf);
    refl__free(al, c3.em.draws);
    refl__free(al, seen);
    refl__free(al, c3.em.surface);
    refl__free(al, c3.key);
    refl__free(al, c3.ray);
    refl__free(al, c3.touched);
    refl__free(al, c3.gap);
    refl__free(al, c3.jobs);
    refl__free(al, c3.counts);
    return r;
}

/* ---- the cameras' own error ----------------------------------------------------- */

/* Every piece of every reflector triangle C3RC builds a camera for, seen
   from the view (the pass p set up on a frame `shape` of the view's size,
   which it only reads the size of): what refl_c3rc_measure_camera_error
   and refl_c3rc_view_cameras share. */
static refl_result refl__c3_view_jobs(const refl_scene *scene, const refl_view *view, float split_px, refl__pass *p,
                                      refl_frame *shape, refl__c3_list *list) {
    refl_vec3 lo, hi;
    float tmax;
    int i, t;
    refl_result r = REFL_OK;
    memset(p, 0, sizeof *p);
    memset(shape, 0, sizeof *shape);
    memset(list, 0, sizeof *list);
    list->al = &scene->allocator;
    if (!refl__isfinite(split_px)) return REFL_ERROR_INVALID_ARGUMENT;
    for (i = 0; i < scene->object_count; ++i)
        if (scene->objects[i].mesh < 0 || scene->objects[i].mesh >= scene->mesh_count ||
            scene->objects[i].material < 0 || scene->objects[i].material >= scene->material_count)
            return REFL_ERROR_INVALID_ARGUMENT;
    shape->width = view->width;
    shape->height = view->height;
    p->scene = scene;
    p->view = view;
    p->frame = shape;
    refl_view_matrices(view, scene, &p->view_m, &p->proj_m);
    p->vp = refl_mat4_mul(p->proj_m, p->view_m);
    refl__view_rays_init(&p->rays, view, scene);
    refl_scene_bounds(scene, &lo, &hi);
    tmax = 1.01f * refl_v3_length(refl_v3_sub(hi, lo));
    for (i = 0; i < scene->object_count && r == REFL_OK; ++i)
        if (refl__is_reflector(&scene->materials[scene->objects[i].material]))
            for (t = 0; t < scene->meshes[scene->objects[i].mesh]->triangle_count && r == REFL_OK; ++t)
                r = refl__c3_add_triangle(p, i, t, tmax, split_px, list);
    return r;
}

enum { REFL__C3_CELL = 8, REFL__C3_REACH = 8 };

REFL_API refl_result refl_c3rc_measure_camera_error(const refl_scene *scene, const refl_view *view,
                                                    const refl_frame *truth, float split_px,
                                                    refl_reflection_error *out) {
    const refl_allocator *al;
    refl__pass p;
    refl_frame shape;
    refl__c3_list list;
    refl__c3_cam *cams = NULL;
    int *cell_start = NULL, *cell_list = NULL;
    double *errors = NULL, sum = 0.0;
    long long counted = 0, matched = 0;
    int w, h, cw, ch, cells, i, c, x, y, n;
    refl_result r;
    if (!out) return REFL_ERROR_INVALID_ARGUMENT;
    memset(out, 0, sizeof *out);
    if (!scene || !view || !truth || !truth->points || !truth->stencil) return REFL_ERROR_INVALID_ARGUMENT;
    if (view->width != truth->width || view->height != truth->height) return REFL_ERROR_INVALID_SIZE;
    al = &scene->allocator;
    w = truth->width;
    h = truth->height;
    /* every reflector triangle's cameras, as C3RC builds them */
    r = refl__c3_view_jobs(scene, view, split_px, &p, &shape, &list);
    /* binned by their screen boxes grown by REFL__C3_REACH, in cells of
       REFL__C3_CELL pixels */
    cw = (w + REFL__C3_CELL - 1) / REFL__C3_CELL;
    ch = (h + REFL__C3_CELL - 1) / REFL__C3_CELL;
    cells = cw * ch;
    if (r == REFL_OK) {
        cams = (refl__c3_cam *)refl__calloc(al, (size_t)REFL__MAX(list.count, 1), sizeof(refl__c3_cam));
        cell_start = (int *)refl__calloc(al, (size_t)cells + 1, sizeof(int));
        errors = (double *)refl__calloc(al, (size_t)w * (size_t)h, sizeof(double));
        if (!cams || !cell_start || !errors) r = REFL_ERROR_OUT_OF_MEMORY;
    }
    for (c = 0; c < 2 && r == REFL_OK; ++c) { /* count, then fill */
        for (i = 0; i < list.count; ++i) {
            refl__c3_cam *k = &cams[i];
            float lx = FLT_MAX, ly = FLT_MAX, hx = -FLT_MAX, hy = -FLT_MAX, sx, sy;
            int v, x0, y0, x1, y1, front = 1;
            if (c == 0 && !refl__c3_setup(&p, &list.v[i], k)) k->object = -1;
            if (k->object < 0) continue;
            for (v = 0; v < 3; ++v) {
                front &= refl__c3_window(&p, k->cam.v[v], &sx, &sy);
                lx = REFL__MIN(lx, sx); hx = REFL__MAX(hx, sx);
                ly = REFL__MIN(ly, sy); hy = REFL__MAX(hy, sy);
            }
            if (!front || hx < -REFL__C3_REACH || hy < -REFL__C3_REACH || lx > (float)(w + REFL__C3_REACH) ||
                ly > (float)(h + REFL__C3_REACH))
                continue;
            x0 = REFL__CLAMP((int)floorf(lx) - REFL__C3_REACH, 0, w - 1) / REFL__C3_CELL;
            y0 = REFL__CLAMP((int)floorf(ly) - REFL__C3_REACH, 0, h - 1) / REFL__C3_CELL;
            x1 = REFL__CLAMP((int)floorf(hx) + REFL__C3_REACH, 0, w - 1) / REFL__C3_CELL;
            y1 = REFL__CLAMP((int)floorf(hy) + REFL__C3_REACH, 0, h - 1) / REFL__C3_CELL;
            for (y = y0; y <= y1; ++y)
                for (x = x0; x <= x1; ++x) {
                    if (c == 0) cell_start[y * cw + x + 1]++;
                    else cell_list[cell_start[y * cw + x]++] = i;
                }
        }
        if (c == 0) {
            for (x = 0; x < cells; ++x) cell_start[x + 1] += cell_start[x];
            cell_list = (int *)refl__calloc(al, (size_t)REFL__MAX(cell_start[cells], 1), sizeof(int));
            if (!cell_list) r = REFL_ERROR_OUT_OF_MEMORY;
        } else { /* the fill advanced every start to the next cell's */
            for (x = cells; x > 0; --x) cell_start[x] = cell_start[x - 1];
            cell_start[0] = 0;
        }
    }
    /* each truth point, projected by the cameras near its pixel: the
       nearest image within reach */
    for (y = 0; y < h && r == REFL_OK; ++y)
        for (x = 0; x < w; ++x) {
            size_t j = (size_t)y * (size_t)w + (size_t)x;
            const float *q = truth->points + 3 * j;
            int cell = (y / REFL__C3_CELL) * cw + x / REFL__C3_CELL, object = truth->stencil[j] - 1;
            double best = INFINITY;
            refl_c3rc_projection pr[3];
            if (object < 0 || !refl__isfinite(q[0]) || !refl__isfinite(q[1]) || !refl__isfinite(q[2])) continue;
            ++counted;
            for (c = cell_start[cell]; c < cell_start[cell + 1]; ++c) {
                const refl__c3_cam *k = &cams[cell_list[c]];
                if (k->object != object && !(object == 254 && k->object >= 254)) continue;
                n = refl_c3rc_project(&k->cam, refl_v3(q[0], q[1], q[2]), pr);
                for (i = 0; i < n; ++i) {
                    const refl_c3rc *cm = &k->cam;
                    refl_vec3 s = refl_v3_add(refl_v3_add(refl_v3_scale(cm->v[0], pr[i].a),
                                                          refl_v3_scale(cm->v[1], pr[i].b)),
                                              refl_v3_scale(cm->v[2], pr[i].c));
                    float sx, sy;
                    double dx, dy;
                    if (!refl__c3_window(&p, s, &sx, &sy)) continue;
                    dx = (double)sx - ((double)x + 0.5);
                    dy = (double)sy - ((double)y + 0.5);
                    best = REFL__MIN(best, sqrt(dx * dx + dy * dy));
                }
            }
            if (best <= (double)REFL__C3_REACH) {
                errors[matched++] = best;
                sum += best;
            }
        }
    if (r == REFL_OK) refl__metric_summary(errors, matched, sum, counted, counted - matched, 0, out);
    refl__free(al, list.v);
    refl__free(al, cams);
    refl__free(al, cell_start);
    refl__free(al, cell_list);
    refl__free(al, errors);
    return r;
}

/* ---- the view's cameras, for a host that draws them (the GL path) --------------- */

REFL_API refl_result refl_c3rc_view_cameras(const refl_scene *scene, const refl_view *view, float split_px,
                                            refl_c3rc_view_camera **out, int *count) {
    refl__pass p;
    refl_frame shape;
    refl__c3_list list;
    refl_c3rc_view_camera *cams = NULL;
    refl_vec3 lo, hi;
    float tmax, fold[4][2];
    int i, n = 0;
    refl_result r;
    if (!out || !count) return REFL_ERROR_INVALID_ARGUMENT;
    *out = NULL;
    *count = 0;
    if (!scene || !view || view->width < 1 || view->height < 1) return REFL_ERROR_INVALID_ARGUMENT;
    r = refl__c3_view_jobs(scene, view, split_px, &p, &shape, &list);
    refl_scene_bounds(scene, &lo, &hi);
    tmax = 1.01f * refl_v3_length(refl_v3_sub(hi, lo)); /* as refl__method_c3rc's c3.tmax */
    if (r == REFL_OK && !(cams = (refl_c3rc_view_camera *)refl__calloc(&scene->allocator,
                                                                       (size_t)(list.count ? list.count : 1), sizeof *cams)))
        r = REFL_ERROR_OUT_OF_MEMORY;
    for (i = 0; r == REFL_OK && i < list.count; ++i) {
        refl__c3_cam k;
        memset(&k, 0, sizeof k);
        if (!refl__c3_setup(&p, &list.v[i], &k)) continue;
        cams[n].cam = k.cam;
        cams[n].object = k.object;
        cams[n].triangle = k.triangle;
        cams[n].back = k.id < 0.0f;
        cams[n].screen_area = k.screen_area;
        cams[n].screen_edge = k.screen_edge;
        cams[n].near_self = k.near_self;
        cams[n].sweep = refl__c3_sweep_bound(&k.cam, tmax);
        cams[n].base_normal = k.base_normal;
        cams[n].lod = refl__c3_folds(&k.cam, cams[n].sweep, tmax, fold) == 0;
        ++n;
    }
    refl__free(&scene->allocator, list.v);
    if (r != REFL_OK) {
        refl__free(&scene->allocator, cams);
        return r;
    }
    *out = cams;
    *count = n;
    return REFL_OK;
}

REFL_API refl_result refl_c3rc_object_densities(const refl_scene *scene, const refl_c3rc_view_camera *cams, int count,
                                                float density, float *out, float *scaled_down) {
    refl_vec3 lo, hi;
    float tmax, most;
    int i;
    if (!scene || !out || count < 0 || (count > 0 && !cams) || !(density >= 0.0f) || !refl__isfinite(density))
        return REFL_ERROR_INVALID_ARGUMENT;
    refl_scene_bounds(scene, &lo, &hi);
    tmax = 1.01f * refl_v3_length(refl_v3_sub(hi, lo));
    for (i = 0; i < scene->object_count; ++i) out[i] = density;
    for (i = 0; i < count; ++i) refl__c3_raise_densities(scene, &cams[i].cam, cams[i].screen_area, density, tmax, out);
    most = refl__c3_density_budget(scene, density, out);
    if (scaled_down) *scaled_down = most;
    return REFL_OK;
}

REFL_API void refl_c3rc_view_cameras_free(const refl_scene *scene, refl_c3rc_view_camera *cams) {
    if (scene && cams) refl__free(&scene->allocator, cams);
}

REFL_API int refl_c3rc_view_camera_lod(const refl_c3rc_view_camera *vc, const float lo[3], const float hi[3], int count,
                                       float density) {
    if (!vc || !lo || !hi || !vc->lod) return count;
    return refl__c3_lod_keep(&vc->cam, vc->base_normal, vc->screen_area, density, lo, hi, count);
}
