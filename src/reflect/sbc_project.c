/* sbc_project: SBC's projection and triangle emission (paper 003 V-A and
   V-B; docs/methods/sbc.md, "3. Projection" and "4. Rasterisation"), a
   batch of groups at a time (the stencil's values: sbc_draw.c draws them).

   Every vertex of every object inside a group's box (its rays' tails and
   heads, grown by a quarter) is projected into the group
   (refl_sbc_project_sheets), moving it to its first reflector point, which
   must lie in the group's box too (a leaf's map far outside its rays sends
   points anywhere); the window depth is the paper's visibility offset
   (k - 1 + z/D) g for order k, in a depth buffer of the reflections' own, z
   measured as the distance from the vertex to its first reflector point
   (consistent across leaves, where each leaf's image-plane height is not),
   past the first order to the last reflector point (the tail of the
   history's sample it lands on). g = 1 / k_max of the window range, k_max
   the longest history sampled: the paper's g = D / (k_max + 1) with yon at
   2D spends it alike, and k_max = 1 keeps z/D. A group whose rays fold
   (cam_sbc_raylist.c's sheets, at most three) projects every vertex into
   each sheet at once and emits each sheet's triangles apart: a point seen
   twice in a focusing mirror shows twice. A vertex with no image in a sheet
   takes its image one fold away (the sheets meet at the fold), and a
   triangle with such vertices is split as a mixed one and drawn only when
   no wider than REFL__SB_FOLD_SAMPLES samples: wider, it spans the caustic,
   where the two sheets' images part.

   A reflected triangle is drawn when all three vertices project; one
   outside the group's box is dropped whole. Triangles are subdivided in
   four, at most REFL__SB_LEVELS times: always while an edge is longer than
   1/32 of the scene's diagonal (the paper's pre-subdivision, per frame),
   while mixed (one or two vertices project; the paper's fix for jagged
   edges; at most desc.sbc.mixed_levels times, unless the part holds a
   point where one of the group's rays meets the triangle; by default
   REFL__SB_MIXED_LEVELS times, and where the group's rays end, along a
   tile's border, down to the pixel: refl__sb_mixed_split), while no vertex
   projects but such a point lies inside (a group narrower than the
   triangle), and while an edge's projected midpoint lies more than
   REFL__SB_EDGE_PX from the midpoint of its projected ends (the
   straight-edge error the paper bounds by pre-subdividing). In a group
   whose rays fold, a triangle whose edges still bend more than
   REFL__SB_FOLD_BEND_PX at the last level is not drawn (SBC-traced, the
   frame's own groups): it lies across a fold, where the map is no longer
   near linear, and its inside would show points that project elsewhere,
   in front of the true ones; its pixels are holes, which the tracer
   renders (sbc_resolve.c). A refraction group leaves out the back faces
   none of its rays meets (refl__sb_refraction_back_face). The
   reflector's own triangles project too (the knob seen in the lid), except
   the surface the rays leave (refl__sb_own_surface). A morphing grid's
   group projects through the eye's tetrahedron of nodes, blended, with no
   ray map of this frame to check against. */
#include "sbc_internal.h"

#define REFL__SB_EDGE_PX 0.5f       /* straight-edge error that splits a reflected triangle */
#define REFL__SB_LEVELS 6           /* subdivisions of a scene triangle at most */
#define REFL__SB_CHUNK 256          /* scene triangles per emission job */
#define REFL__SB_OWN_NEAR 0.25f     /* a reflector's triangle this near (in edges) to its reflection: its surface */
#define REFL__SB_FOLD_SAMPLES 4.0f  /* a triangle straddling a fold wider than this (in samples): not drawn */
#define REFL__SB_FOLD_BEND_PX 1.0f /* a folding group's triangle bent this much at the last level: not drawn */
#define REFL__SB_ELSEWHERE_LEVELS 3 /* subdivisions, at most, of a triangle with its images in other sheets */
#define REFL__SB_MIXED_PX 1.0f      /* a mixed part is split while it may reach this many pixels ... */
#define REFL__SB_MIXED_MAX 16       /* ... down to this level at most (a 64k-fold magnification) */

/* Subdivision midpoints a job has projected: an edge shared by two
   triangles (the split's inner edges, neighbours in the mesh) is split
   by both, and its midpoint projects alike (the same world position,
   group and sheet). Direct-mapped by the edge's ends, compared exactly, so
   a hit is what projecting again would give, bit for bit. */
#define REFL__SB_MEMO 512
typedef struct refl__sb_memo {
    uint8_t used[REFL__SB_MEMO];
    struct {
        refl_vec3 ends[2];        /* the edge's ends, the lesser bytes first */
        refl__sb_pv mid;
    } entry[REFL__SB_MEMO];
} refl__sb_memo;

/* Whether g projects: a tree of this frame or a morph's piece. */
static int refl__sb_live(const refl__sb_group *g) { return g->sbc != NULL || g->morph != NULL; }

/* Whether box [a, b] (any two corners' extremes) meets box [lo, hi]. */
static int refl__sb_in_box(refl_vec3 lo, refl_vec3 hi, refl_vec3 a, refl_vec3 b) {
    return REFL__MAX(a.x, b.x) >= lo.x && REFL__MIN(a.x, b.x) <= hi.x && REFL__MAX(a.y, b.y) >= lo.y &&
           REFL__MIN(a.y, b.y) <= hi.y && REFL__MAX(a.z, b.z) >= lo.z && REFL__MIN(a.z, b.z) <= hi.z;
}

/* Point p's first reflector points in g's sheets (refl_sbc_project_sheets),
   each within g's box (a leaf's map far outside the rays it was fitted to
   can send a point anywhere): the mask of those it has. */
static int refl__sb_images(const refl__sb_side *sd, const refl__sb_group *g, refl_vec3 p, refl_vec3 *f, float *z) {
    refl_vec3 lo = sd->layer ? g->first_lo : g->lo, hi = sd->layer ? g->first_hi : g->hi;
    int mask = refl_sbc_project_sheets(g->sbc, p, REFL__MAX(g->sheets, 1), f, z), k;
    for (k = 0; k < REFL__SB_SHEETS; ++k)
        if ((mask >> k & 1) && !refl__sb_in_box(lo, hi, f[k], f[k])) mask &= ~(1 << k);
    return mask;
}

static void refl__sb_place(const refl__sb *sb, const refl__sb_group *g, refl__sb_pv *v, refl_vec3 f, float z);

/* Projects v into group g's sheet v->sheet: its first reflector point,
   seen by the view, at window depth dist / D. */
static void refl__sb_project(const refl__sb *sb, const refl__sb_group *g, refl__sb_pv *v) {
    refl_vec3 f[REFL__SB_SHEETS];
    float z[REFL__SB_SHEETS];
    int k;
    v->ok = 0;
    v->ambiguous = 0;
    v->across = 0;
    if (!refl__sb_in_box(g->lo, g->hi, v->world, v->world)) return;
    if (g->morph) { /* the eye's nodes, located once per frame, blended in v's sheet */
        float slot[4 * 4 * REFL__SB_SHEETS];
        int masks[4];
        refl__sbm_project4_sheets(g->morph, g->morph_nodes, g->morph_w, g->piece, v->world, REFL__MAX(g->sheets, 1),
                                  slot, masks);
        if (refl__sbm_blend_sheet(slot, masks, g->morph_w, v->sheet, &f[0], &z[0], &v->across, &v->ambiguous))
            refl__sb_place(sb, g, v, f[0], z[0]);
        return;
    }
    k = refl__sbc_sheet_image(refl__sb_images(&sb->sides[g->side], g, v->world, f, z), v->sheet, &v->across);
    if (k >= 0) refl__sb_place(sb, g, v, f[k], z[k]);
}

/* Projects v[0] (world, normal, uv set; in g's box) into each of g's
   sheets, v[k] for sheet k: one search of the leaf for all. */
static void refl__sb_project_sheets(const refl__sb *sb, const refl__sb_group *g, refl__sb_pv *v) {
    refl_vec3 f[REFL__SB_SHEETS];
    float z[REFL__SB_SHEETS], slot[4 * 4 * REFL__SB_SHEETS];
    int k, mask = 0, masks[4], sheets = REFL__MAX(g->sheets, 1);
    if (sheets == 1) {
        v[0].sheet = 0;
        refl__sb_project(sb, g, &v[0]);
        return;
    }
    if (g->morph)
        refl__sbm_project4_sheets(g->morph, g->morph_nodes, g->morph_w, g->piece, v[0].world, sheets, slot, masks);
    else
        mask = refl__sb_images(&sb->sides[g->side], g, v[0].world, f, z);
    for (k = 0; k < sheets; ++k) {
        int image;
        v[k] = v[0];
        v[k].sheet = k;
        v[k].ok = v[k].ambiguous = 0;
        if (g->morph) {
            if (refl__sbm_blend_sheet(slot, masks, g->morph_w, k, &f[0], &z[0], &v[k].across, &v[k].ambiguous))
                refl__sb_place(sb, g, &v[k], f[0], z[0]);
            continue;
        }
        image = refl__sbc_sheet_image(mask, k, &v[k].across);
        if (image >= 0) refl__sb_place(sb, g, &v[k], f[image], z[image]);
    }
}

/* Places v at its first reflector point f in group g (z: the leaf's
   depth there): window position, and the visibility offset as depth. */
static void refl__sb_place(const refl__sb *sb, const refl__sb_group *g, refl__sb_pv *v, refl_vec3 f, float z) {
    const refl__pass *p = sb->p;
    const refl__sb_side *sd = g->morph ? NULL : &sb->sides[g->side];
    const float *m = p->vp.m;
    float wd;
    int k, u, w, landed;
    size_t at;
    for (k = 0; k < 4; ++k) v->clip[k] = m[k] * f.x + m[4 + k] * f.y + m[8 + k] * f.z + m[12 + k];
    if (!(v->clip[3] > 0.0f)) return;
    v->first = v->from = f;
    v->dist = g->morph ? z : refl_v3_length(refl_v3_sub(v->world, f)); /* a morph blends its nodes' */
    v->sx = (0.5f + 0.5f * v->clip[0] / v->clip[3]) * (float)p->frame->width;
    v->sy = (0.5f - 0.5f * v->clip[1] / v->clip[3]) * (float)p->frame->height;
    if (!refl__isfinite(v->sx) || !refl__isfinite(v->sy)) return;
    if (!sd) { /* a morph group: the first order, and no ray map of this frame to check against */
        wd = REFL__CLAMP(v->dist / sb->diagonal, 0.0f, 0.999999f);
        if (sb->orders > 1) wd /= (float)sb->orders;
        v->clip[2] = (2.0f * wd - 1.0f) * v->clip[3];
        v->ok = 1;
        return;
    }
    u = (int)REFL__CLAMP(v->sx / (float)sb->factor, 0.0f, (float)(sb->map_w - 1));
    w = (int)REFL__CLAMP(v->sy / (float)sb->factor, 0.0f, (float)(sb->map_h - 1));
    at = (size_t)w * (size_t)sb->map_w + (size_t)u;
    landed = sd->valid[at] && sd->group[at] == (int)(g - sb->groups);
    if (sd->layer) {
        /* beyond the first order the ray leaves the last reflector, not the
           first: z from there (the sample of the history it lands on; one
           measure for all, or surfaces close behind each other fight),
           else the leaf's */
        if (sd->valid[at]) v->from = sd->rays[at].tail;
        v->dist = sd->valid[at] ? refl_v3_length(refl_v3_sub(v->world, v->from)) : z;
    }
    /* the visibility offset (k - 1 + z / D) g, g = D / k_max (window depth
       over [0, D): lower orders in front; k_max = 1: z / D) */
    wd = REFL__CLAMP(v->dist / sb->diagonal, 0.0f, 0.999999f);
    if (sb->orders > 1) wd = ((float)(sd->order - 1) + wd) / (float)sb->orders;
    v->clip[2] = (2.0f * wd - 1.0f) * v->clip[3];
    /* ahead along the reflected ray of the sample it lands on: a leaf's
       frustum starts at an image plane fitted to the tails, so it can reach
       just behind a curved mirror, where nothing is reflected */
    if (landed &&
        !(refl_v3_dot(refl_v3_sub(v->world, v->from), refl_v3_sub(sd->rays[at].head, sd->rays[at].tail)) > 0.0f))
        return;
    v->ok = 1;
}

/* Object o's vertices in the world, projecting nowhere (what a group
   whose box a vertex lies outside makes of it). */
static void refl__sb_base_object(void *arg, int o) {
    refl__sb *sb = (refl__sb *)arg;
    const refl_object *obj = &sb->p->scene->objects[o];
    const refl_mesh *m = sb->p->scene->meshes[obj->mesh];
    refl__sb_pv *out = sb->batch.base[o];
    refl_mat4 normal_m = refl__normal_matrix(obj->transform);
    int i;
    for (i = 0; i < m->vertex_count; ++i) {
        const float *q = m->positions + 3 * (size_t)i, *n = m->normals + 3 * (size_t)i;
        out[i].world = refl_mat4_point(obj->transform, refl_v3(q[0], q[1], q[2]));
        out[i].normal = refl_mat4_dir(normal_m, refl_v3(n[0], n[1], n[2]));
        out[i].uv[0] = m->texcoords ? m->texcoords[2 * i] : 0.0f;
        out[i].uv[1] = m->texcoords ? m->texcoords[2 * i + 1] : 0.0f;
    }
}

/* Projects the vertices of object o in group g's box into g (a job per
   pair): each into every sheet at once. */
static void refl__sb_project_object(void *arg, int index) {
    refl__sb *sb = (refl__sb *)arg;
    const refl_allocator *al = &sb->p->scene->allocator;
    int g = sb->batch.first + index / sb->p->scene->object_count, o = index % sb->p->scene->object_count, i, k;
    int vc = sb->p->scene->meshes[sb->p->scene->objects[o].mesh]->vertex_count, sheets;
    const refl__sb_group *gr = &sb->groups[g];
    const refl__sb_pv *base = sb->batch.base[o];
    refl__sb_slot *slot = &sb->batch.slots[index];
    refl__sb_pv v[REFL__SB_SHEETS];
    if (!refl__sb_live(gr)) return;
    sheets = REFL__MAX(gr->sheets, 1);
    slot->index = (int *)refl__alloc(al, (size_t)REFL__MAX(vc, 1) * sizeof(int));
    if (!slot->index) {
        slot->failed = 1;
        return;
    }
    for (i = 0; i < vc; ++i)
        slot->index[i] = refl__sb_in_box(gr->lo, gr->hi, base[i].world, base[i].world) ? slot->count++ : -1;
    for (k = 0; k < sheets; ++k) {
        slot->pv[k] = (refl__sb_pv *)refl__alloc(al, (size_t)REFL__MAX(slot->count, 1) * sizeof(refl__sb_pv));
        if (!slot->pv[k]) {
            slot->failed = 1;
            return;
        }
    }
    for (i = 0; i < vc; ++i) {
        if (slot->index[i] < 0) continue;
        v[0] = base[i];
        refl__sb_project_sheets(sb, gr, v);
        for (k = 0; k < sheets; ++k) slot->pv[k][slot->index[i]] = v[k];
    }
}

static refl__sb_pv refl__sb_mid(const refl__sb *sb, const refl__sb_group *g, const refl__sb_pv *a, const refl__sb_pv *b,
                                refl__sb_job *j) {
    refl__sb_pv m;
    refl_vec3 ends[2];
    uint32_t h = 2166136261u, w;
    int k, slot, ordered = memcmp(&a->world, &b->world, sizeof(refl_vec3)) <= 0;
    ends[0] = ordered ? a->world : b->world;
    ends[1] = ordered ? b->world : a->world;
    for (k = 0; k < 6; ++k) { /* FNV-1a over the ends' words */
        memcpy(&w, (const float *)ends + k, sizeof w);
        h = (h ^ w) * 16777619u;
    }
    slot = (int)(h % REFL__SB_MEMO);
    if (!j->memo && (j->memo = (refl__sb_memo *)refl__alloc(&sb->p->scene->allocator, sizeof(refl__sb_memo))))
        memset(j->memo->used, 0, sizeof j->memo->used);
    if (j->memo && j->memo->used[slot] && !memcmp(j->memo->entry[slot].ends, ends, sizeof ends)) {
        m = j->memo->entry[slot].mid;
    } else {
        m.world = refl_v3_scale(refl_v3_add(a->world, b->world), 0.5f);
        m.sheet = j->sheet;
        refl__sb_project(sb, g, &m);
        j->projections++;
        j->projected += m.ok;
        if (j->memo) {
            j->memo->used[slot] = 1;
            memcpy(j->memo->entry[slot].ends, ends, sizeof ends);
            j->memo->entry[slot].mid = m;
        }
    }
    /* the ends' own attributes: a crease's two sides share positions, not normals */
    m.normal = refl_v3_scale(refl_v3_add(a->normal, b->normal), 0.5f);
    m.uv[0] = 0.5f * (a->uv[0] + b->uv[0]);
    m.uv[1] = 0.5f * (a->uv[1] + b->uv[1]);
    return m;
}

static void refl__sb_put(refl__sb_job *j, const refl__sb_pv *v) {
    float *o = j->out + REFL__SB_FLOATS * j->out_count++;
    memcpy(o, v->clip, 4 * sizeof(float));
    o[4] = v->world.x; o[5] = v->world.y; o[6] = v->world.z;
    o[7] = v->normal.x; o[8] = v->normal.y; o[9] = v->normal.z;
    o[10] = v->uv[0]; o[11] = v->uv[1];
}

/* Whether triangle (a, b, c), outwards as its vertex normals point, faces
   away from the point every vertex's ray leaves (`from`): each ray meets
   its back. */
static int refl__sb_faces_away(const refl__sb_pv *a, const refl__sb_pv *b, const refl__sb_pv *c) {
    const refl__sb_pv *v[3];
    refl_vec3 n = refl_v3_cross(refl_v3_sub(b->world, a->world), refl_v3_sub(c->world, a->world));
    int k;
    v[0] = a; v[1] = b; v[2] = c;
    if (refl_v3_dot(n, refl_v3_add(a->normal, refl_v3_add(b->normal, c->normal))) < 0.0f) n = refl_v3_scale(n, -1.0f);
    for (k = 0; k < 3; ++k)
        if (refl_v3_dot(refl_v3_sub(v[k]->from, v[k]->world), n) > 0.0f) return 0;
    return 1;
}

/* Whether a reflector's triangle, projected into a group of its own, is
   the surface the group's rays leave rather than a part of the reflector
   they meet (the knob seen in the lid): it faces away from the point
   every vertex's ray leaves, or lies nearer one than a fraction of its
   edge. */
static int refl__sb_own_surface(const refl__sb_pv *a, const refl__sb_pv *b, const refl__sb_pv *c, float edge, int met) {
    if (REFL__MIN(a->dist, REFL__MIN(b->dist, c->dist)) < REFL__SB_OWN_NEAR * edge) return 1;
    return !met && refl__sb_faces_away(a, b, c);
}

/* A scene triangle being emitted into a group: whether it belongs to the
   group's reflector, its longest edge, and the points where the group's
   rays meet it. */
typedef struct refl__sb_tri {
    int self;
    float edge;
    const refl__sbc_hit *hits;
    int hit_count;
} refl__sb_tri;

/* Whether a refraction group (SBC-traced) leaves out triangle (a, b, c)
   as a back face: it faces away from its vertices' rays and none of the
   group's rays meets it, so a surface in front hides it (the underside of
   a floor tile seen through the glass, behind the tile's top). Where the
   refracted rays fold, that surface's triangles across the fold are not
   drawn, and the depth test showed the back face instead, dark lines
   across the glass; left out, the pixel is a refraction hole, traced
   (sbc_resolve.c), unless another surface was drawn there. A back face
   the rays do meet (an open mesh's inside) is drawn; SBC-paper's rays
   meet nothing, so it cannot tell and draws them all. */
static int refl__sb_refraction_back_face(const refl__sb *sb, const refl__sb_group *g, const refl__sb_pv *a,
                                         const refl__sb_pv *b, const refl__sb_pv *c, const refl__sb_tri *t) {
    return !g->morph && sb->sides[g->side].kind && sb->bvh && !t->hit_count && refl__sb_faces_away(a, b, c);
}

/* Whether triangle (a, b, c) holds point p of its plane (its edges
   included, with a little room). */
static int refl__sb_holds(const refl__sb_pv *a, const refl__sb_pv *b, const refl__sb_pv *c, refl_vec3 p) {
    const refl__sb_pv *v[3];
    refl_vec3 n = refl_v3_cross(refl_v3_sub(b->world, a->world), refl_v3_sub(c->world, a->world));
    float room = -1e-3f * refl_v3_dot(n, n);
    int k;
    v[0] = a; v[1] = b; v[2] = c;
    for (k = 0; k < 3; ++k) {
        refl_vec3 e = refl_v3_sub(v[(k + 1) % 3]->world, v[k]->world);
        if (refl_v3_dot(refl_v3_cross(e, refl_v3_sub(p, v[k]->world)), n) < room) return 0;
    }
    return 1;
}

/* A projected triangle's width plus height in pixels. */
static float refl__sb_extent(const refl__sb_pv *a, const refl__sb_pv *b, const refl__sb_pv *c) {
    return REFL__MAX(REFL__MAX(a->sx, b->sx), c->sx) - REFL__MIN(REFL__MIN(a->sx, b->sx), c->sx) +
           REFL__MAX(REFL__MAX(a->sy, b->sy), c->sy) - REFL__MIN(REFL__MIN(a->sy, b->sy), c->sy);
}

/* The pixels per unit of length of the largest image of an edge between
   two of (a, b, c) that both project; `known` (an ancestor's) when fewer
   than two project. */
static float refl__sb_scale(const refl__sb_pv *a, const refl__sb_pv *b, const refl__sb_pv *c, float known) {
    const refl__sb_pv *v[3];
    float best = -1.0f;
    int k;
    v[0] = a; v[1] = b; v[2] = c;
    for (k = 0; k < 3; ++k) {
        const refl__sb_pv *p = v[k], *q = v[(k + 1) % 3];
        float dx = p->sx - q->sx, dy = p->sy - q->sy, l = refl_v3_length(refl_v3_sub(p->world, q->world));
        if (p->ok && q->ok && l > 0.0f) best = REFL__MAX(best, sqrtf(dx * dx + dy * dy) / l);
    }
    return best >= 0.0f ? best : known;
}

/* Whether a mixed part (a, b, c) may reach the pixels of group g where its
   rays end (within `reach` pixels of a vertex that projects): for a whole
   piece any pixel of its box; for a tile those along its border (two
   samples either side), where the next tile's rays begin. Inside a tile a
   vertex fails for other reasons (a silhouette, a fold, a ray list's
   gap), as costly to chase to the pixel as rare to matter. */
static int refl__sb_mixed_near(const refl__sb *sb, const refl__sb_group *g, const refl__sb_pv *a,
                               const refl__sb_pv *b, const refl__sb_pv *c, float reach) {
    const refl__sb_pv *v[3];
    float x0 = (float)(g->u0 * sb->factor), y0 = (float)(g->v0 * sb->factor);
    float x1 = (float)(g->u1 * sb->factor), y1 = (float)(g->v1 * sb->factor), band = 2.0f * (float)sb->factor;
    float lx = INFINITY, ly = INFINITY, hx = -INFINITY, hy = -INFINITY;
    int k;
    if (g->morph) return 0;
    v[0] = a; v[1] = b; v[2] = c;
    for (k = 0; k < 3; ++k)
        if (v[k]->ok) {
            lx = REFL__MIN(lx, v[k]->sx - reach); hx = REFL__MAX(hx, v[k]->sx + reach);
            ly = REFL__MIN(ly, v[k]->sy - reach); hy = REFL__MAX(hy, v[k]->sy + reach);
        }
    if (hx < x0 - band || lx > x1 + band || hy < y0 - band || ly > y1 + band) return 0; /* off the group */
    return g->whole || lx < x0 + band || hx > x1 - band || ly < y0 + band || hy > y1 - band;
}

/* Whether mixed part (a, b, c) at subdivision level `level` is split
   further (desc.sbc.mixed_levels 0): REFL__SB_MIXED_LEVELS times, and where
   the group's rays end (refl__sb_mixed_near) to the pixel, while it may
   reach REFL__SB_MIXED_PX or more, judged by `scale` (refl__sb_scale). The
   parts on a tile's border pixels then all project: the group's rays reach
   REFL__SB_GUARD samples past them. */
static int refl__sb_mixed_split(const refl__sb *sb, const refl__sb_group *g, const refl__sb_pv *a, const refl__sb_pv *b,
                                const refl__sb_pv *c, int level, float scale) {
    float la = refl_v3_length(refl_v3_sub(a->world, b->world));
    float lb = refl_v3_length(refl_v3_sub(b->world, c->world));
    float lc = refl_v3_length(refl_v3_sub(c->world, a->world));
    float reach = scale * REFL__MAX(la, REFL__MAX(lb, lc));
    if (level < REFL__SB_MIXED_LEVELS) return 1;
    return scale > 0.0f && reach > REFL__SB_MIXED_PX && refl__sb_mixed_near(sb, g, a, b, c, reach);
}

/* How far the projected midpoints of triangle (a, b, c)'s edges (into
   ab, bc, ca) lie from the midpoints of their projected ends at most, in
   pixels squared: the straight-edge error; infinite when a midpoint does
   not project. */
static float refl__sb_bend(const refl__sb *sb, const refl__sb_group *g, refl__sb_job *j, const refl__sb_pv *a,
                           const refl__sb_pv *b, const refl__sb_pv *c, refl__sb_pv *ab, refl__sb_pv *bc,
                           refl__sb_pv *ca) {
    const refl__sb_pv *e[3][2] = {{a, b}, {b, c}, {c, a}};
    refl__sb_pv *mid[3];
    float most = 0.0f;
    int k;
    mid[0] = ab; mid[1] = bc; mid[2] = ca;
    for (k = 0; k < 3; ++k) {
        float dx, dy;
        *mid[k] = refl__sb_mid(sb, g, e[k][0], e[k][1], j);
        dx = mid[k]->sx - 0.5f * (e[k][0]->sx + e[k][1]->sx);
        dy = mid[k]->sy - 0.5f * (e[k][0]->sy + e[k][1]->sy);
        most = mid[k]->ok ? REFL__MAX(most, dx * dx + dy * dy) : INFINITY;
    }
    return most;
}

/* Emits triangle (a, b, c) at subdivision level `level`, split as the
   module comment says; scale: the pixels per unit of length an ancestor's
   projected edge had (0: none projected two vertices yet). */
static void refl__sb_emit(const refl__sb *sb, const refl__sb_group *g, refl__sb_job *j, const refl__sb_pv *a,
                          const refl__sb_pv *b, const refl__sb_pv *c, int level, float scale, const refl__sb_tri *t) {
    const float max_edge = sb->diagonal / 32.0f;
    int ok = a->ok + b->ok + c->ok, split = 0;
    int across = (a->ok && a->across) + (b->ok && b->across) + (c->ok && c->across);
    int elsewhere = across && across == ok; /* every image from other sheets: drawn in those */
    refl__sb_pv ab, bc, ca;
    int have_mid = 0;
    refl_vec3 lo = refl__v3_min(a->world, refl__v3_min(b->world, c->world));
    refl_vec3 hi = refl__v3_max(a->world, refl__v3_max(b->world, c->world));
    if (!refl__sb_in_box(g->lo, g->hi, lo, hi)) return; /* nothing of it can reflect in the group */
    if (elsewhere) ok = 0;
    /* the surface the rays leave, whole: its parts would be dropped one by one */
    if (t->self && ok == 3 && refl__sb_own_surface(a, b, c, t->edge, t->hit_count > 0)) return;
    scale = refl__sb_scale(a, b, c, scale);
    if (level >= REFL__SB_LEVELS && ok > 0 && ok < 3 && sb->mixed_levels < 0 && level < REFL__SB_MIXED_MAX) {
        split = refl__sb_mixed_split(sb, g, a, b, c, level, scale);
    } else if (level < REFL__SB_LEVELS) {
        float la = refl_v3_length(refl_v3_sub(a->world, b->world));
        float lb = refl_v3_length(refl_v3_sub(b->world, c->world));
        float lc = refl_v3_length(refl_v3_sub(c->world, a->world));
        float ext = ok == 3 ? refl__sb_extent(a, b, c) : 0.0f;
        if (REFL__MAX(la, REFL__MAX(lb, lc)) > max_edge) {
            split = 1;
        } else if (ok == 3 && across) { /* straddles a fold: finer where the sheets meet */
            split = level < REFL__SB_MIXED_LEVELS;
        } else if (ok == 3 && ext > 2.0f * REFL__SB_EDGE_PX) { /* smaller: no edge can bend further */
            split = refl__sb_bend(sb, g, j, a, b, c, &ab, &bc, &ca) > REFL__SB_EDGE_PX * REFL__SB_EDGE_PX;
            have_mid = 1;
        } else if (ok < 3) {
            int k;
            if (ok > 0 && sb->mixed_levels < 0)
                split = refl__sb_mixed_split(sb, g, a, b, c, level, scale);
            else
                split = ok > 0 && level < sb->mixed_levels;
            for (k = 0; k < t->hit_count && !split && (!elsewhere || level < REFL__SB_ELSEWHERE_LEVELS); ++k)
                split = refl__sb_holds(a, b, c, t->hits[k].point);
        }
    }
    if (!split) {
        if (ok < 3) return;
        /* straddling a fold, drawn only where the sheets' images meet */
        if (across && refl__sb_extent(a, b, c) > REFL__SB_FOLD_SAMPLES * (float)sb->factor) return;
        if (refl__sb_refraction_back_face(sb, g, a, b, c, t)) return;
        /* the reflector's own surface around the rays' tails */
        if (t->self && refl__sb_own_surface(a, b, c, t->edge, t->hit_count > 0)) return;
        /* where the rays fold, a triangle still bent at the last level lies
           across a fold: its inside is no image of the scene (SBC-traced
           traces its pixels; a morph group has no ray map to check) */
        if (level >= REFL__SB_LEVELS && g->sheets > 1 && sb->bvh && !g->morph && refl__sb_extent(a, b, c) > 2.0f * REFL__SB_FOLD_BEND_PX &&
            refl__sb_bend(sb, g, j, a, b, c, &ab, &bc, &ca) > REFL__SB_FOLD_BEND_PX * REFL__SB_FOLD_BEND_PX)
            return;
        if (j->out_count + 3 > j->out_cap) {
            size_t cap = j->out_cap ? 2 * j->out_cap : 3 * 256;
            float *o = (float *)refl__alloc(&sb->p->scene->allocator, cap * REFL__SB_FLOATS * sizeof(float));
            if (!o) {
                j->failed = 1;
                return;
            }
            if (j->out_count) memcpy(o, j->out, j->out_count * REFL__SB_FLOATS * sizeof(float));
            refl__free(&sb->p->scene->allocator, j->out);
            j->out = o;
            j->out_cap = cap;
        }
        refl__sb_put(j, a);
        refl__sb_put(j, b);
        refl__sb_put(j, c);
        return;
    }
    if (!have_mid) {
        ab = refl__sb_mid(sb, g, a, b, j);
        bc = refl__sb_mid(sb, g, b, c, j);
        ca = refl__sb_mid(sb, g, c, a, j);
    }
    refl__sb_emit(sb, g, j, a, &ab, &ca, level + 1, scale, t);
    refl__sb_emit(sb, g, j, &ab, b, &bc, level + 1, scale, t);
    refl__sb_emit(sb, g, j, &ca, &bc, c, level + 1, scale, t);
    refl__sb_emit(sb, g, j, &ab, &bc, &ca, level + 1, scale, t);
}

static void refl__sb_emit_job(void *arg, int index) {
    refl__sb *sb = (refl__sb *)arg;
    refl__sb_job *j = &sb->batch.jobs[index];
    const refl_scene *scene = sb->p->scene;
    const refl_mesh *m = scene->meshes[scene->objects[j->object].mesh];
    const refl__sb_slot *slot = &sb->batch.slots[(j->group - sb->batch.first) * scene->object_count + j->object];
    const refl__sb_pv *base = sb->batch.base[j->object], *pv = slot->pv[j->sheet], *v[3];
    const refl__sb_group *g = &sb->groups[j->group];
    int lo = 0, hi = g->hit_count, tr;
    refl__sb_tri t;
    t.self = g->object == j->object;
    /* a refraction's own glass: the rays have left it (a lens cannot see
       itself; a concave glass seeing itself beyond its exit is left out) */
    if (t.self && !g->morph && sb->sides[g->side].kind) return;
    /* the group's hits on this job's triangles start at the first not before (object, first) */
    while (lo < hi) {
        int mid = (lo + hi) / 2;
        const refl__sbc_hit *h = &g->hits[mid];
        if (h->object < j->object || (h->object == j->object && h->triangle < j->first)) lo = mid + 1;
        else hi = mid;
    }
    for (tr = j->first; tr < j->first + j->count && !j->failed; ++tr) {
        const uint32_t *tri = m->indices + 3 * (size_t)tr;
        const refl__sb_pv *a, *b, *c;
        int k;
        for (k = 0; k < 3; ++k) v[k] = slot->index[tri[k]] < 0 ? &base[tri[k]] : &pv[slot->index[tri[k]]];
        a = v[0];
        b = v[1];
        c = v[2];
        t.edge = t.self ? REFL__MAX(refl_v3_length(refl_v3_sub(a->world, b->world)),
                                    REFL__MAX(refl_v3_length(refl_v3_sub(b->world, c->world)),
                                              refl_v3_length(refl_v3_sub(c->world, a->world))))
                        : 0.0f;
        t.hits = g->hits ? g->hits + lo : NULL; /* none in SBC-paper mode */
        t.hit_count = 0;
        while (lo < g->hit_count && g->hits[lo].object == j->object && g->hits[lo].triangle == tr) {
            ++lo;
            ++t.hit_count;
        }
        refl__sb_emit(sb, g, j, a, b, c, 0, 0.0f, &t);
    }
    refl__free(&scene->allocator, j->memo);
    j->memo = NULL;
}

/* Projection and emission jobs of the batch's groups, run. */
static refl_result refl__sb_project_all(refl__sb *sb) {
    const refl_scene *scene = sb->p->scene;
    const refl_allocator *al = &scene->allocator;
    int pairs = (sb->batch.end - sb->batch.first) * scene->object_count, i, g, o, t, k, n = 0;
    size_t slot_bytes = 0;
    if (!sb->batch.base) { /* the first batch: every object's vertices in the world, once */
        sb->batch.base =
            (refl__sb_pv **)refl__calloc(al, (size_t)REFL__MAX(scene->object_count, 1), sizeof(refl__sb_pv *));
        if (!sb->batch.base) return REFL_ERROR_OUT_OF_MEMORY;
        for (o = 0; o < scene->object_count; ++o) {
            int vc = scene->meshes[scene->objects[o].mesh]->vertex_count;
            sb->batch.base[o] = (refl__sb_pv *)refl__calloc(al, (size_t)REFL__MAX(vc, 1), sizeof(refl__sb_pv));
            if (!sb->batch.base[o]) return REFL_ERROR_OUT_OF_MEMORY;
        }
        rast_run_jobs(sb->p->rc, scene->object_count, refl__sb_base_object, sb);
    }
    sb->batch.slots = (refl__sb_slot *)refl__calloc(al, (size_t)REFL__MAX(pairs, 1), sizeof(refl__sb_slot));
    if (!sb->batch.slots) return REFL_ERROR_OUT_OF_MEMORY;
    rast_run_jobs(sb->p->rc, pairs, refl__sb_project_object, sb);
    for (i = 0; i < pairs; ++i) {
        const refl__sb_slot *slot = &sb->batch.slots[i];
        int v;
        if (slot->failed) return REFL_ERROR_OUT_OF_MEMORY;
        if (!slot->index) continue; /* no tree */
        sb->p->frame->stats.sbc.projections += scene->meshes[scene->objects[i % scene->object_count].mesh]->vertex_count;
        for (v = 0; v < slot->count; ++v) { /* a vertex projects into every sheet at once */
            int ok = 0;
            for (k = 0; k < REFL__SB_SHEETS && slot->pv[k]; ++k) ok |= slot->pv[k][v].ok;
            sb->p->frame->stats.sbc.projected += ok;
            sb->p->frame->stats.sbc.ambiguous += slot->pv[0][v].ambiguous;
        }
    }
    for (g = sb->batch.first; g < sb->batch.end; ++g)
        for (o = 0; o < scene->object_count; ++o)
            n += REFL__MAX(sb->groups[g].sheets, 1) *
                 ((scene->meshes[scene->objects[o].mesh]->triangle_count + REFL__SB_CHUNK - 1) / REFL__SB_CHUNK);
    /* the batch's projected vertices within the memory bound */
    for (i = 0; i < pairs; ++i) {
        const refl__sb_slot *slot = &sb->batch.slots[i];
        if (!slot->index) continue;
        slot_bytes += (size_t)scene->meshes[scene->objects[i % scene->object_count].mesh]->vertex_count * sizeof(int) +
                      (size_t)slot->count * (size_t)REFL__MAX(sb->groups[sb->batch.first + i / scene->object_count].sheets, 1) *
                          sizeof(refl__sb_pv);
    }
    if (sb->memory_fixed + slot_bytes >= sb->memory_limit) {
        sb->p->frame->message = "sbc.memory_mb: a batch's projected vertices exceed it";
        return REFL_ERROR_OUT_OF_MEMORY;
    }
    sb->batch.jobs = (refl__sb_job *)refl__calloc(al, (size_t)REFL__MAX(n, 1), sizeof(refl__sb_job));
    if (!sb->batch.jobs) return REFL_ERROR_OUT_OF_MEMORY;
    for (g = sb->batch.first; g < sb->batch.end; ++g) {
        if (!refl__sb_live(&sb->groups[g])) continue;
        for (o = 0; o < scene->object_count; ++o) {
            int tc = scene->meshes[scene->objects[o].mesh]->triangle_count;
            for (k = 0; k < REFL__MAX(sb->groups[g].sheets, 1); ++k)
                for (t = 0; t < tc; t += REFL__SB_CHUNK) {
                    refl__sb_job *j = &sb->batch.jobs[sb->batch.job_count++];
                    j->group = g;
                    j->object = o;
                    j->sheet = k;
                    j->first = t;
                    j->count = REFL__MIN(REFL__SB_CHUNK, tc - t);
                }
        }
    }
    rast_run_jobs(sb->p->rc, sb->batch.job_count, refl__sb_emit_job, sb);
    for (i = 0; i < sb->batch.job_count; ++i)
        if (sb->batch.jobs[i].failed) return REFL_ERROR_OUT_OF_MEMORY;
    return REFL_OK;
}

/* Frees the batch's projected vertices and emitted triangles. */
static void refl__sb_batch_clear(refl__sb *sb) {
    const refl_allocator *al = &sb->p->scene->allocator;
    int pairs = (sb->batch.end - sb->batch.first) * sb->p->scene->object_count, i, k;
    for (i = 0; sb->batch.slots && i < pairs; ++i) {
        refl__free(al, sb->batch.slots[i].index);
        for (k = 0; k < REFL__SB_SHEETS; ++k) refl__free(al, sb->batch.slots[i].pv[k]);
    }
    for (i = 0; sb->batch.jobs && i < sb->batch.job_count; ++i) refl__free(al, sb->batch.jobs[i].out);
    refl__free(al, sb->batch.slots);
    refl__free(al, sb->batch.jobs);
    sb->batch.slots = NULL;
    sb->batch.jobs = NULL;
    sb->batch.job_count = 0;
}

static void refl__sb_batch_free(refl__sb *sb) {
    const refl_allocator *al = &sb->p->scene->allocator;
    int i;
    refl__sb_batch_clear(sb);
    for (i = 0; sb->batch.base && i < sb->p->scene->object_count; ++i) refl__free(al, sb->batch.base[i]);
    refl__free(al, sb->batch.base);
    sb->batch.base = NULL;
}
