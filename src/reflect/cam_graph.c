/* cam_graph: the graph camera of paper 004, section 5 (after Popescu,
   Rosen and Adamo-Villani's graph camera): a tree of planar pinhole
   frusta grown from a root pinhole by bends; docs/graphcam.md.

   A bend of frustum F at the planar portal quad Q with child eye C maps a
   point P to the point where the line C-P meets Q's plane pi, then images
   that point as F does. In homogeneous coordinates the map to the plane is
       H = C pi^T - (pi . C) I          (H P lies on pi and on line C-P)
   with pi oriented so that pi . C < 0 (the child's region is pi . P > 0;
   the weight pi . P - pi . C of H P is then positive), so the child's
   matrix is M_F H: one 4x4 for the whole path to the root. A mirror bend
   uses the reflection R in pi instead (C = R eye_F, the same image: the
   parent's x, y, w rows vanish at eye_F, so M_F R P and M_F H P differ by
   a positive factor), which makes the child's x, y, w rows bit for bit
   those of PLANAR's mirrored camera (m_planar.c: projection * view * R).

   Depth: a child's z row is c pi - w, so z / w = -1 on the portal and
   rises along each of its rays (pi / w is linear-fractional, 0 on the
   portal, positive beyond); c = 2 / the largest pi / w at the corners of
   the frustum's far face, so z / w <= 1 up to its far plane. The window
   depth gd adds the frustum's level k of L: gd = (k + (z / w + 1) / 2) / L.

   Regions are convex (plane lists), so clipping a segment is one interval
   and point location is a floor map of candidate frusta per cell, then
   plane tests. */
#include "internal.h"

/* ---- small double helpers ------------------------------------------------------- */

static double refl__gc_plane_eval(const double pl[4], refl_vec3 p) {
    return pl[0] * p.x + pl[1] * p.y + pl[2] * p.z + pl[3];
}

/* The plane through a, b, c (normal (b - a) x (c - a), unit); 0 when degenerate. */
static int refl__gc_plane3(refl_vec3 a, refl_vec3 b, refl_vec3 c, double out[4]) {
    double u[3] = {(double)b.x - a.x, (double)b.y - a.y, (double)b.z - a.z};
    double v[3] = {(double)c.x - a.x, (double)c.y - a.y, (double)c.z - a.z};
    double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
    double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (!(len > 0.0) || !(len < HUGE_VAL)) return 0;
    out[0] = n[0] / len; out[1] = n[1] / len; out[2] = n[2] / len;
    out[3] = -(out[0] * a.x + out[1] * a.y + out[2] * a.z);
    return 1;
}

/* Row r of a column-major 4x4 at p (w = 1), in double. */
static double refl__gc_row(const refl_mat4 *m, int r, refl_vec3 p) {
    return (double)m->m[r] * p.x + (double)m->m[4 + r] * p.y + (double)m->m[8 + r] * p.z + (double)m->m[12 + r];
}

/* Inverse of a column-major 4x4 in double (Gauss-Jordan, partial pivoting); 0 when singular. */
static int refl__gc_invert(const refl_mat4 *m, double inv[16]) {
    double a[4][8];
    int i, j, k;
    for (i = 0; i < 4; ++i)
        for (j = 0; j < 4; ++j) {
            a[i][j] = m->m[j * 4 + i];
            a[i][4 + j] = i == j;
        }
    for (k = 0; k < 4; ++k) {
        int piv = k;
        double best = fabs(a[k][k]);
        for (i = k + 1; i < 4; ++i)
            if (fabs(a[i][k]) > best) best = fabs(a[i][k]), piv = i;
        if (!(best > 0.0)) return 0;
        if (piv != k)
            for (j = 0; j < 8; ++j) {
                double t = a[k][j];
                a[k][j] = a[piv][j];
                a[piv][j] = t;
            }
        for (j = 7; j >= k; --j) a[k][j] /= a[k][k];
        for (i = 0; i < 4; ++i)
            if (i != k && a[i][k] != 0.0) {
                double f = a[i][k];
                for (j = k; j < 8; ++j) a[i][j] -= f * a[k][j];
            }
    }
    for (i = 0; i < 4; ++i)
        for (j = 0; j < 4; ++j) inv[j * 4 + i] = a[i][4 + j];
    return 1;
}

/* ---- regions -------------------------------------------------------------------- */

static int refl__gc_inside_first(const refl_graphcam_frustum *f, refl_vec3 p, double tol, int planes) {
    int k;
    for (k = 0; k < planes && k < f->plane_count; ++k)
        if (refl__gc_plane_eval(f->planes[k], p) < -tol) return 0;
    return 1;
}

static int refl__gc_inside(const refl_graphcam_frustum *f, refl_vec3 p, double tol) {
    int k;
    for (k = 0; k < f->plane_count; ++k)
        if (refl__gc_plane_eval(f->planes[k], p) < -tol) return 0;
    return 1;
}

/* The region's bounding box: its vertices are the points where three of its
   planes meet that every other plane keeps (at most C(16, 3) candidates). */
static void refl__gc_region_box(refl_graphcam_frustum *f) {
    int a, b, c, any = 0;
    double scale = 0.0;
    refl_vec3 lo = refl_v3(0, 0, 0), hi = lo;
    for (a = 0; a < 4; ++a) {
        double s = fabs(f->portal[a].x) + fabs(f->portal[a].y) + fabs(f->portal[a].z);
        if (s > scale) scale = s;
    }
    for (a = 0; a < f->plane_count; ++a)
        for (b = a + 1; b < f->plane_count; ++b)
            for (c = b + 1; c < f->plane_count; ++c) {
                const double *p = f->planes[a], *q = f->planes[b], *r = f->planes[c];
                double n1[3] = {q[1] * r[2] - q[2] * r[1], q[2] * r[0] - q[0] * r[2], q[0] * r[1] - q[1] * r[0]};
                double det = p[0] * n1[0] + p[1] * n1[1] + p[2] * n1[2], x[3];
                double n2[3] = {r[1] * p[2] - r[2] * p[1], r[2] * p[0] - r[0] * p[2], r[0] * p[1] - r[1] * p[0]};
                double n3[3] = {p[1] * q[2] - p[2] * q[1], p[2] * q[0] - p[0] * q[2], p[0] * q[1] - p[1] * q[0]};
                refl_vec3 v;
                int k;
                if (fabs(det) < 1e-9) continue;
                for (k = 0; k < 3; ++k) x[k] = -(p[3] * n1[k] + q[3] * n2[k] + r[3] * n3[k]) / det;
                v = refl_v3((float)x[0], (float)x[1], (float)x[2]);
                if (!refl__v3_finite(v) || !refl__gc_inside(f, v, 1e-5 * (scale + 1.0) + 1e-4 * (fabs(x[0]) + fabs(x[1]) + fabs(x[2]))))
                    continue;
                lo = any ? refl__v3_min(lo, v) : v;
                hi = any ? refl__v3_max(hi, v) : v;
                any = 1;
            }
    f->lo = lo;
    f->hi = hi;
}

/* The floor map: per cell of a grid over the frusta's x, z boxes, the
   frusta whose box reaches it. */
static void refl__gc_build_map(refl_graphcam *cam) {
    refl_vec3 lo, hi;
    int i, x, z, n = 64;
    refl_graphcam_bounds(cam, &lo, &hi);
    cam->map_w = cam->map_h = n;
    cam->map_lo[0] = lo.x;
    cam->map_lo[1] = lo.z;
    cam->map_cell[0] = (hi.x - lo.x) / (float)n;
    cam->map_cell[1] = (hi.z - lo.z) / (float)n;
    if (!(cam->map_cell[0] > 0.0f)) cam->map_cell[0] = 1.0f;
    if (!(cam->map_cell[1] > 0.0f)) cam->map_cell[1] = 1.0f;
    memset(cam->map, 0, sizeof cam->map);
    for (i = 0; i < cam->count; ++i) {
        const refl_graphcam_frustum *f = &cam->frusta[i];
        int x0 = (int)floorf((f->lo.x - lo.x) / cam->map_cell[0]) - 1, x1 = (int)floorf((f->hi.x - lo.x) / cam->map_cell[0]) + 1;
        int z0 = (int)floorf((f->lo.z - lo.z) / cam->map_cell[1]) - 1, z1 = (int)floorf((f->hi.z - lo.z) / cam->map_cell[1]) + 1;
        x0 = REFL__CLAMP(x0, 0, n - 1); x1 = REFL__CLAMP(x1, 0, n - 1);
        z0 = REFL__CLAMP(z0, 0, n - 1); z1 = REFL__CLAMP(z1, 0, n - 1);
        for (z = z0; z <= z1; ++z)
            for (x = x0; x <= x1; ++x) cam->map[z * n + x] |= 1ull << i;
    }
}

/* After a frustum's planes change: its box, its levels, the map. */
static void refl__gc_update(refl_graphcam *cam, int f) {
    refl__gc_region_box(&cam->frusta[f]);
    if (cam->frusta[f].level + 1 > cam->levels) cam->levels = cam->frusta[f].level + 1;
    refl__gc_build_map(cam);
}

static int refl__gc_add_plane(refl_graphcam_frustum *f, const double pl[4]) {
    if (f->plane_count >= REFL_GRAPHCAM_MAX_PLANES) return 0;
    memcpy(f->planes[f->plane_count++], pl, 4 * sizeof(double));
    return 1;
}

/* ---- the root ------------------------------------------------------------------- */

/* The root from a view matrix and a projection whose x, y scales are 1 / tx,
   1 / ty (tx, ty: tangents of the half angles). */
static refl_result refl__gc_root(refl_graphcam *cam, refl_mat4 view_m, refl_mat4 proj, refl_vec3 eye, double tx,
                                 double ty, double znear, double zfar, int width, int height) {
    refl_graphcam_frustum *f;
    refl_vec3 s = refl_v3(view_m.m[0], view_m.m[4], view_m.m[8]);
    refl_vec3 u = refl_v3(view_m.m[1], view_m.m[5], view_m.m[9]);
    refl_vec3 fw = refl_v3(-view_m.m[2], -view_m.m[6], -view_m.m[10]);
    refl_vec3 corner[4];
    double pl[4];
    int k;
    if (width <= 0 || height <= 0 || width > 16384 || height > 16384) return REFL_ERROR_INVALID_ARGUMENT;
    memset(cam, 0, sizeof *cam);
    cam->width = width;
    cam->height = height;
    cam->levels = 1;
    cam->count = 1;
    f = &cam->frusta[0];
    f->parent = -1;
    f->eye = eye;
    f->m = refl_mat4_mul(proj, view_m);
    for (k = 0; k < 4; ++k) { /* near corners, counter-clockwise seen from the eye */
        double sx = (k == 1 || k == 2) ? tx : -tx, sy = k >= 2 ? ty : -ty;
        corner[k] = refl_v3((float)(eye.x + znear * (fw.x + sx * s.x + sy * u.x)),
                            (float)(eye.y + znear * (fw.y + sx * s.y + sy * u.y)),
                            (float)(eye.z + znear * (fw.z + sx * s.z + sy * u.z)));
        f->portal[k] = corner[k];
    }
    pl[0] = fw.x; pl[1] = fw.y; pl[2] = fw.z;
    pl[3] = -(fw.x * (double)eye.x + fw.y * (double)eye.y + fw.z * (double)eye.z) - znear;
    refl__gc_add_plane(f, pl);
    for (k = 0; k < 4; ++k) /* sides: through the eye and an edge of the near face, inward */
        if (!refl__gc_plane3(eye, corner[k], corner[(k + 1) & 3], pl)) return REFL_ERROR_INVALID_ARGUMENT;
        else {
            refl_vec3 c = refl_v3_add(eye, fw);
            if (refl__gc_plane_eval(pl, c) < 0.0) {
                int j;
                for (j = 0; j < 4; ++j) pl[j] = -pl[j];
            }
            refl__gc_add_plane(f, pl);
        }
    f->rast_clipped = 5;
    pl[0] = -fw.x; pl[1] = -fw.y; pl[2] = -fw.z;
    pl[3] = fw.x * (double)eye.x + fw.y * (double)eye.y + fw.z * (double)eye.z + zfar;
    refl__gc_add_plane(f, pl);
    refl__gc_update(cam, 0);
    return REFL_OK;
}

REFL_API refl_result refl_graphcam_init(refl_graphcam *cam, const refl_view *view, int width, int height) {
    float fovy, aspect;
    double ty;
    refl_mat4 view_m, proj;
    refl_vec3 fw;
    if (!cam || !view) return REFL_ERROR_INVALID_ARGUMENT;
    fovy = view->fovy_degrees > 0.0f ? view->fovy_degrees : 45.0f;
    fw = refl_v3_sub(view->target, view->eye);
    if (!(fovy < 180.0f) || !(view->znear > 0.0f) || !(view->zfar > view->znear) || !refl__v3_finite(view->eye) ||
        !(refl_v3_length(fw) > 0.0f) || !(refl_v3_length(refl_v3_cross(fw, view->up)) > 0.0f) || width <= 0 ||
        height <= 0)
        return REFL_ERROR_INVALID_ARGUMENT;
    aspect = (float)width / (float)height;
    /* the base pass's matrices (render.c), so a one-frustum camera draws as it does */
    view_m = refl_mat4_look_at(view->eye, view->target, view->up);
    proj = refl_mat4_perspective(fovy * (float)(REFL__PI / 180.0), aspect, view->znear, view->zfar);
    ty = 1.0 / proj.m[5];
    return refl__gc_root(cam, view_m, proj, view->eye, 1.0 / proj.m[0], ty, view->znear, view->zfar, width, height);
}

/* ---- bends ---------------------------------------------------------------------- */

static refl_result refl__gc_bend(refl_graphcam *cam, int parent, const refl_vec3 portal[4], refl_vec3 eye,
                                 int mirror, float far, int *out) {
    const refl_graphcam_frustum *pf;
    refl_graphcam_frustum *f;
    double pi[4], size = 0.0, tol, pc, wmax = 0.0;
    refl_mat4 h;
    int k, j, child;
    if (out) *out = -1;
    if (!cam || !portal || parent < 0 || parent >= cam->count || cam->count >= REFL_GRAPHCAM_MAX_FRUSTA ||
        !(far > 0.0f) || !refl__isfinite(far))
        return REFL_ERROR_INVALID_ARGUMENT;
    pf = &cam->frusta[parent];
    for (k = 0; k < 4; ++k) {
        if (!refl__v3_finite(portal[k])) return REFL_ERROR_INVALID_ARGUMENT;
        size = REFL__MAX(size, (double)refl_v3_length(refl_v3_sub(portal[k], portal[(k + 1) & 3])));
    }
    if (!refl__gc_plane3(portal[0], portal[1], portal[2], pi)) return REFL_ERROR_INVALID_ARGUMENT;
    tol = 1e-3 * size;
    for (k = 0; k < 4; ++k) /* planar, and inside the parent's own frustum (entry, sides, far) */
        if (fabs(refl__gc_plane_eval(pi, portal[k])) > tol || !refl__gc_inside_first(pf, portal[k], tol, 6))
            return REFL_ERROR_INVALID_ARGUMENT;
    /* the parent's eye must see the portal from one side */
    if (fabs(refl__gc_plane_eval(pi, pf->eye)) <= tol) return REFL_ERROR_INVALID_ARGUMENT;
    if (mirror) {
        double e = refl__gc_plane_eval(pi, pf->eye);
        eye = refl_v3((float)(pf->eye.x - 2.0 * e * pi[0]), (float)(pf->eye.y - 2.0 * e * pi[1]),
                      (float)(pf->eye.z - 2.0 * e * pi[2]));
    }
    if (!refl__v3_finite(eye)) return REFL_ERROR_INVALID_ARGUMENT;
    pc = refl__gc_plane_eval(pi, eye);
    if (fabs(pc) <= tol) return REFL_ERROR_INVALID_ARGUMENT;
    if (pc > 0.0) {
        for (k = 0; k < 4; ++k) pi[k] = -pi[k];
        pc = -pc;
    }
    child = cam->count;
    f = &cam->frusta[child];
    memset(f, 0, sizeof *f);
    f->parent = parent;
    f->level = pf->level + 1;
    f->mirror = mirror;
    f->eye = eye;
    memcpy(f->portal, portal, 4 * sizeof(refl_vec3));
    if (mirror) {
        double n[3] = {pi[0], pi[1], pi[2]};
        h = refl__planar_reflection(n, -pi[3]);
    } else { /* H = C pi^T - (pi . C) I */
        const float c[4] = {eye.x, eye.y, eye.z, 1.0f};
        for (j = 0; j < 4; ++j)
            for (k = 0; k < 4; ++k) h.m[j * 4 + k] = (float)((double)c[k] * pi[j] - (j == k ? pc : 0.0));
    }
    f->m = refl_mat4_mul(pf->m, h);
    /* planes: entry, sides (through the eye and the portal's edges), far */
    refl__gc_add_plane(f, pi);
    for (k = 0; k < 4; ++k) {
        double pl[4];
        refl_vec3 mid = refl_v3_scale(refl_v3_add(refl_v3_add(portal[0], portal[1]), refl_v3_add(portal[2], portal[3])), 0.25f);
        if (!refl__gc_plane3(eye, portal[k], portal[(k + 1) & 3], pl)) return REFL_ERROR_INVALID_ARGUMENT;
        if (refl__gc_plane_eval(pl, mid) < 0.0)
            for (j = 0; j < 4; ++j) pl[j] = -pl[j];
        refl__gc_add_plane(f, pl);
    }
    {
        double pl[4] = {-pi[0], -pi[1], -pi[2], -pi[3] + far};
        refl__gc_add_plane(f, pl);
    }
    /* the depth row: c pi - w, c from the far face's corners */
    for (k = 0; k < 4; ++k) {
        double s = (far - pc) / (refl__gc_plane_eval(pi, portal[k]) - pc);
        refl_vec3 q = refl_v3((float)(eye.x + s * ((double)portal[k].x - eye.x)), (float)(eye.y + s * ((double)portal[k].y - eye.y)),
                              (float)(eye.z + s * ((double)portal[k].z - eye.z)));
        double w = refl__gc_row(&f->m, 3, q);
        if (!(w > 0.0)) return REFL_ERROR_INVALID_ARGUMENT; /* the portal is not in front of the parent's eye */
        wmax = REFL__MAX(wmax, far / w);
    }
    {
        double c = 2.0 / wmax;
        for (k = 0; k < 4; ++k) f->m.m[k * 4 + 2] = (float)(c * pi[k] - (double)f->m.m[k * 4 + 3]);
    }
    cam->count++;
    refl__gc_update(cam, child);
    if (out) *out = child;
    return REFL_OK;
}

REFL_API refl_result refl_graphcam_bend(refl_graphcam *cam, int parent, const refl_vec3 portal[4], refl_vec3 eye,
                                        float far, int *out) {
    return refl__gc_bend(cam, parent, portal, eye, 0, far, out);
}

REFL_API refl_result refl_graphcam_bend_mirror(refl_graphcam *cam, int parent, const refl_vec3 portal[4], float far,
                                               int *out) {
    return refl__gc_bend(cam, parent, portal, refl_v3(0, 0, 0), 1, far, out);
}

REFL_API refl_result refl_graphcam_split(refl_graphcam *cam, int parent, const refl_vec3 (*portals)[4],
                                         const refl_vec3 *eyes, int count, float far, int *first) {
    int i, idx;
    refl_result r;
    if (first) *first = -1;
    if (!cam || !portals || !eyes || count <= 0) return REFL_ERROR_INVALID_ARGUMENT;
    for (i = 0; i < count; ++i) {
        if ((r = refl__gc_bend(cam, parent, portals[i], eyes[i], 0, far, &idx)) != REFL_OK) return r;
        if (i == 0 && first) *first = idx;
    }
    return REFL_OK;
}

/* A merge: a bend of a at portal_a and a bend of b at portal_b with one
   eye, the two portals sharing an edge and lying on either side of the
   plane through the eye and that edge, so the two halves are adjacent and
   disjoint. Both halves take the level after the deeper parent's, and each
   parent ends at its half's portal plane. */
REFL_API refl_result refl_graphcam_merge(refl_graphcam *cam, int a, int b, const refl_vec3 portal_a[4],
                                         const refl_vec3 portal_b[4], refl_vec3 eye, float far, int *first) {
    const refl_vec3 *portal[2];
    refl_vec3 edge[2], mid[2];
    double size = 0.0, split[4];
    int parent[2], half[2], j, k, shared = 0, count, levels, level;
    refl_result r = REFL_OK;
    if (first) *first = -1;
    if (!cam || !portal_a || !portal_b || a < 0 || b < 0 || a >= cam->count || b >= cam->count || a == b ||
        cam->count + 2 > REFL_GRAPHCAM_MAX_FRUSTA || cam->frusta[a].plane_count >= REFL_GRAPHCAM_MAX_PLANES ||
        cam->frusta[b].plane_count >= REFL_GRAPHCAM_MAX_PLANES || !refl__v3_finite(eye))
        return REFL_ERROR_INVALID_ARGUMENT;
    portal[0] = portal_a;
    portal[1] = portal_b;
    parent[0] = a;
    parent[1] = b;
    for (j = 0; j < 2; ++j) {
        mid[j] = refl_v3(0, 0, 0);
        for (k = 0; k < 4; ++k) {
            if (!refl__v3_finite(portal[j][k])) return REFL_ERROR_INVALID_ARGUMENT;
            size = REFL__MAX(size, (double)refl_v3_length(refl_v3_sub(portal[j][k], portal[j][(k + 1) & 3])));
            mid[j] = refl_v3_add(mid[j], refl_v3_scale(portal[j][k], 0.25f));
        }
    }
    for (j = 0; j < 4; ++j) /* the shared edge: two corners of portal_a that are corners of portal_b */
        for (k = 0; k < 4; ++k)
            if (shared < 2 && refl_v3_length(refl_v3_sub(portal_a[j], portal_b[k])) <= 1e-4 * size)
                edge[shared++] = portal_a[j];
    if (shared < 2 || !refl__gc_plane3(eye, edge[0], edge[1], split) ||
        !(refl__gc_plane_eval(split, mid[0]) * refl__gc_plane_eval(split, mid[1]) < 0.0))
        return REFL_ERROR_INVALID_ARGUMENT;
    count = cam->count;
    levels = cam->levels;
    for (j = 0; j < 2 && r == REFL_OK; ++j) r = refl__gc_bend(cam, parent[j], portal[j], eye, 0, far, &half[j]);
    if (r != REFL_OK) { /* as it was */
        cam->count = count;
        cam->levels = levels;
        refl__gc_build_map(cam);
        return r;
    }
    level = REFL__MAX(cam->frusta[a].level, cam->frusta[b].level) + 1;
    for (j = 0; j < 2; ++j) {
        refl_graphcam_frustum *h = &cam->frusta[half[j]];
        double end[4];
        for (k = 0; k < 4; ++k) end[k] = -h->planes[0][k];
        h->level = level;
        h->merged_with = half[1 - j] + 1;
        refl__gc_add_plane(&cam->frusta[parent[j]], end);
    }
    for (j = 0; j < 2; ++j) {
        refl__gc_update(cam, parent[j]);
        refl__gc_update(cam, half[j]);
    }
    if (first) *first = half[0];
    return REFL_OK;
}

REFL_API refl_result refl_graphcam_bound(refl_graphcam *cam, int frustum, refl_vec3 n, float d) {
    double pl[4], len;
    if (!cam || frustum < 0 || frustum >= cam->count || !refl__v3_finite(n) || !refl__isfinite(d))
        return REFL_ERROR_INVALID_ARGUMENT;
    len = sqrt((double)n.x * n.x + (double)n.y * n.y + (double)n.z * n.z);
    if (!(len > 0.0)) return REFL_ERROR_INVALID_ARGUMENT;
    pl[0] = n.x / len; pl[1] = n.y / len; pl[2] = n.z / len; pl[3] = d / len;
    if (!refl__gc_add_plane(&cam->frusta[frustum], pl)) return REFL_ERROR_INVALID_ARGUMENT;
    refl__gc_update(cam, frustum);
    return REFL_OK;
}

/* ---- queries -------------------------------------------------------------------- */

REFL_API int refl_graphcam_contains(const refl_graphcam *cam, int f, refl_vec3 p) {
    if (!cam || f < 0 || f >= cam->count) return 0;
    return refl__gc_inside(&cam->frusta[f], p, 0.0);
}

REFL_API int refl_graphcam_locate(const refl_graphcam *cam, refl_vec3 p) {
    unsigned long long cand = ~0ull;
    int i;
    if (!cam || !refl__v3_finite(p)) return -1;
    if (cam->map_w > 0) {
        int x = (int)floorf((p.x - cam->map_lo[0]) / cam->map_cell[0]);
        int z = (int)floorf((p.z - cam->map_lo[1]) / cam->map_cell[1]);
        if (x < 0 || z < 0 || x >= cam->map_w || z >= cam->map_h) return -1;
        cand = cam->map[z * cam->map_w + x];
    }
    for (i = 0; i < cam->count; ++i)
        if ((cand >> i & 1ull) && refl__gc_inside(&cam->frusta[i], p, 0.0)) return i;
    return -1;
}

/* Clip coordinates of p in frustum f, z with f's level. */
static void refl__gc_clip(const refl_graphcam *cam, int f, refl_vec3 p, double c[4]) {
    const refl_graphcam_frustum *fr = &cam->frusta[f];
    double L = (double)cam->levels, k;
    int r;
    for (r = 0; r < 4; ++r) c[r] = refl__gc_row(&fr->m, r, p);
    k = (double)fr->level;
    c[2] = c[2] / L + (2.0 * k + 1.0 - L) / L * c[3];
}

/* Frustum f's matrix with its level in z: what the rasteriser draws with. */
static refl_mat4 refl__gc_draw_matrix(const refl_graphcam *cam, int f) {
    const refl_graphcam_frustum *fr = &cam->frusta[f];
    refl_mat4 m = fr->m;
    double L = (double)cam->levels, k = (double)fr->level;
    int c;
    if (cam->levels == 1) return m;
    for (c = 0; c < 4; ++c)
        m.m[c * 4 + 2] = (float)((double)fr->m.m[c * 4 + 2] / L + (2.0 * k + 1.0 - L) / L * fr->m.m[c * 4 + 3]);
    return m;
}

REFL_API int refl_graphcam_project_in(const refl_graphcam *cam, int f, refl_vec3 p, float out[3]) {
    double c[4];
    if (!cam || f < 0 || f >= cam->count || !out) return 0;
    refl__gc_clip(cam, f, p, c);
    if (!(c[3] > 0.0)) return 0;
    out[0] = (float)((c[0] / c[3] + 1.0) * 0.5 * cam->width);
    out[1] = (float)((1.0 - c[1] / c[3]) * 0.5 * cam->height);
    out[2] = (float)((c[2] / c[3] + 1.0) * 0.5);
    return 1;
}

REFL_API int refl_graphcam_project(const refl_graphcam *cam, refl_vec3 p, float out[3], int *frustum) {
    int f = refl_graphcam_locate(cam, p);
    if (frustum) *frustum = f;
    return f >= 0 && refl_graphcam_project_in(cam, f, p, out);
}

REFL_API int refl_graphcam_unproject(const refl_graphcam *cam, int f, float u, float v, float gd, refl_vec3 *p) {
    double inv[16], c[4], w[4];
    refl_mat4 m;
    int r;
    if (!cam || f < 0 || f >= cam->count || !p) return 0;
    m = refl__gc_draw_matrix(cam, f);
    if (!refl__gc_invert(&m, inv)) return 0;
    c[0] = 2.0 * u / cam->width - 1.0;
    c[1] = 1.0 - 2.0 * v / cam->height;
    c[2] = 2.0 * gd - 1.0;
    c[3] = 1.0;
    for (r = 0; r < 4; ++r) w[r] = inv[r] * c[0] + inv[4 + r] * c[1] + inv[8 + r] * c[2] + inv[12 + r] * c[3];
    if (!(fabs(w[3]) > 0.0)) return 0;
    *p = refl_v3((float)(w[0] / w[3]), (float)(w[1] / w[3]), (float)(w[2] / w[3]));
    return refl__v3_finite(*p);
}

REFL_API int refl_graphcam_clip_segment(const refl_graphcam *cam, int f, refl_vec3 a, refl_vec3 b, float *t0,
                                        float *t1) {
    const refl_graphcam_frustum *fr;
    double lo = 0.0, hi = 1.0;
    int k;
    if (!cam || f < 0 || f >= cam->count) return 0;
    fr = &cam->frusta[f];
    for (k = 0; k < fr->plane_count; ++k) {
        double ea = refl__gc_plane_eval(fr->planes[k], a), eb = refl__gc_plane_eval(fr->planes[k], b);
        if (ea < 0.0 && eb < 0.0) return 0;
        if (ea < 0.0) lo = REFL__MAX(lo, ea / (ea - eb));
        else if (eb < 0.0) hi = REFL__MIN(hi, ea / (ea - eb));
        if (lo > hi) return 0;
    }
    if (t0) *t0 = (float)lo;
    if (t1) *t1 = (float)hi;
    return 1;
}

REFL_API void refl_graphcam_bounds(const refl_graphcam *cam, refl_vec3 *lo, refl_vec3 *hi) {
    refl_vec3 l = refl_v3(0, 0, 0), h = l;
    int i;
    for (i = 0; cam && i < cam->count; ++i) {
        l = i ? refl__v3_min(l, cam->frusta[i].lo) : cam->frusta[i].lo;
        h = i ? refl__v3_max(h, cam->frusta[i].hi) : cam->frusta[i].hi;
    }
    if (lo) *lo = l;
    if (hi) *hi = h;
}

/* ---- the maze (scene.c builds its geometry from the same layout) ----------------- */

/* The maze's corridors, breadth first: corridor 0 the entrance (from z = 0
   northwards, -z), each of the first 7 ending in a T whose two branches
   are corridors 2i + 1 and 2i + 2 (an H-tree: branches turn 90 degrees,
   three levels). A corridor is 2 wide (walls on its centre line +-1);
   one ending in a T has a 2 x 2 junction square at its end. */
static void refl__maze_layout(refl__maze_corridor out[REFL__MAZE_CORRIDORS]) {
    static const float len[4] = {10.0f, 8.0f, 6.0f, 3.0f};
    int i;
    out[0].s[0] = 0.0f;
    out[0].s[1] = 0.0f;
    out[0].d[0] = 0.0f;
    out[0].d[1] = -1.0f;
    out[0].length = len[0];
    out[0].level = 0;
    out[0].parent = -1;
    for (i = 0; i < 7; ++i) {
        const refl__maze_corridor *c = &out[i];
        float ax = c->s[0] + c->d[0] * (c->length - 2.0f), az = c->s[1] + c->d[1] * (c->length - 2.0f);
        float lx = -c->d[1], lz = c->d[0]; /* lateral */
        int b;
        for (b = 0; b < 2; ++b) {
            refl__maze_corridor *k = &out[2 * i + 1 + b];
            float sgn = b ? -1.0f : 1.0f;
            k->parent = i;
            k->level = c->level + 1;
            k->s[0] = ax + c->d[0] + sgn * lx;
            k->s[1] = az + c->d[1] + sgn * lz;
            k->d[0] = sgn * lx;
            k->d[1] = sgn * lz;
            k->length = len[k->level];
        }
    }
}

REFL_API refl_result refl_graphcam_maze(refl_graphcam *cam, int width, int height) {
    refl__maze_corridor c[REFL__MAZE_CORRIDORS];
    int idx[REFL__MAZE_CORRIDORS];
    const float eye_h = 1.25f, back = 6.0f;
    refl_mat4 view_m, proj;
    refl_vec3 eye = refl_v3(0.0f, eye_h, 4.0f);
    double tx = 1.05 / 4.0, ty = 1.4 / 4.0, zn = 0.5, zf = 30.0;
    refl_result r;
    int i;
    if (!cam) return REFL_ERROR_INVALID_ARGUMENT;
    if (width == 0 && height == 0) width = 1920, height = 1176;
    refl__maze_layout(c);
    view_m = refl_mat4_look_at(eye, refl_v3(0.0f, eye_h, 0.0f), refl_v3(0, 1, 0));
    memset(&proj, 0, sizeof proj);
    proj.m[0] = (float)(1.0 / tx);
    proj.m[5] = (float)(1.0 / ty);
    proj.m[10] = (float)((zf + zn) / (zn - zf));
    proj.m[11] = -1.0f;
    proj.m[14] = (float)(2.0 * zf * zn / (zn - zf));
    if ((r = refl__gc_root(cam, view_m, proj, eye, tx, ty, zn, zf, width, height)) != REFL_OK) return r;
    idx[0] = 0;
    for (i = 1; i < REFL__MAZE_CORRIDORS; ++i) {
        const refl__maze_corridor *p = &c[c[i].parent], *k = &c[i];
        /* the portal: a vertical quad from the junction's apex (the middle
           of its near edge) to its far corner on the branch's side */
        float ax = p->s[0] + p->d[0] * (p->length - 2.0f), az = p->s[1] + p->d[1] * (p->length - 2.0f);
        float fx = ax + 2.0f * p->d[0] + k->d[0], fz = az + 2.0f * p->d[1] + k->d[1];
        refl_vec3 portal[4];
        portal[0] = refl_v3(ax, 0.0f, az);
        portal[1] = refl_v3(fx, 0.0f, fz);
        portal[2] = refl_v3(fx, REFL__MAZE_WALL_H, fz);
        portal[3] = refl_v3(ax, REFL__MAZE_WALL_H, az);
        /* the eye on the branch's axis, `back` behind its entry */
        r = refl_graphcam_bend(cam, idx[k->parent], portal,
                               refl_v3(k->s[0] - back * k->d[0], eye_h, k->s[1] - back * k->d[1]), 2.0f * k->length + 4.0f,
                               &idx[i]);
        if (r != REFL_OK) return r;
    }
    for (i = 0; i < REFL__MAZE_CORRIDORS; ++i) { /* each frustum inside its corridor */
        const refl__maze_corridor *k = &c[i];
        refl_vec3 d = refl_v3(k->d[0], 0.0f, k->d[1]), l = refl_v3(-k->d[1], 0.0f, k->d[0]);
        float sd = k->s[0] * k->d[0] + k->s[1] * k->d[1], sl = -k->s[0] * k->d[1] + k->s[1] * k->d[0];
        /* a T's junction square: its half on a branch's side is the branch's
           (the part of it beyond the portal, where the branch's rays pass);
           the corridor ending there stops at the square */
        float end = i < 7 ? k->length - 2.0f : k->length;
        if (i > 0 && (r = refl_graphcam_bound(cam, idx[i], d, -(sd - 1.0f))) != REFL_OK) return r;
        if ((r = refl_graphcam_bound(cam, idx[i], refl_v3_scale(d, -1.0f), sd + end)) != REFL_OK ||
            (r = refl_graphcam_bound(cam, idx[i], l, -(sl - 1.0f))) != REFL_OK ||
            (r = refl_graphcam_bound(cam, idx[i], refl_v3_scale(l, -1.0f), sl + 1.0f)) != REFL_OK)
            return r;
    }
    return REFL_OK;
}
