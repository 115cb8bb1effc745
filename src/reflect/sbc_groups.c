/* sbc_groups: SBC's reflection groups (paper 003 IV, and VII-C's pieces
   "whose rays do not intersect"; docs/methods/sbc.md, "2. Reflection
   groups"). Per side seen, the ray map is cut into pieces: neighbouring
   samples stay together when no gap lies between them (one surface
   passing in front of another: the handle before the body), their normals
   turn by less than 45 degrees (no crease: the knob on the lid), and
   either both or neither of their rays cross a neighbour's before its head
   (a concave groove focuses them). A planar piece is one group (the
   paper's one camera per planar mirror); any other is cut into tiles of
   REFL__SB_TILE samples, each tile's group holding its piece's rays
   REFL__SB_GUARD samples past the tile (neighbouring tiles' frustums
   overlap: sbc_project.c splits a reflected triangle across the border to
   the pixel, and the parts on the border pixels all project). Around its
   rays a group has one ring of rays extrapolated, diagonals included (past
   the ray map's edge too), so its frustums reach past the piece's edge: the
   paper's "extended reflectors". Each group is a BSP tree of pinhole
   cameras (cam_sbc.c) built to the requested error in desired-view pixels;
   pieces whose rays do not cross end mostly in pinhole leaves, focusing
   ones in ray lists. A pixel belongs to the group of the nearest sample on
   its own smooth surface. Past the first order a side's pieces lie within
   its parent's and its ring continues the rays linearly; groups come in
   layers (order k; the refractions last) and a pixel belongs, in each layer
   its own history reaches, to the group of the nearest sample on its
   surface with that history.

   Reflection morphing (section VI): a reflector the caller hands a
   prebuilt grid for (desc.sbc.morphs, cam_sbc_morph.c) has no ray map or
   groups of its front side; a group per piece of the grid stands in, its
   pixels those of the piece their view ray meets, reflecting once (the
   first order only). Its sheets are the most its nodes' cameras have. */
#include "sbc_internal.h"

#define REFL__SB_TILE 16            /* a group's tile side in ray map samples (at least) */
#define REFL__SB_TILE_MAX 64        /* ... and at most: larger groups fit their rays worse */
#define REFL__SB_PLANAR_COS 0.9999f /* a piece whose normals all lie this near its first's: planar, untiled */

/* Whether neighbouring samples m1 and m2 lie on one smooth piece of
   surface (refl__sbc_smooth). */
static int refl__sb_smooth(const refl__sb_side *sd, size_t m1, size_t m2) {
    return refl__sbc_smooth(sd->rays[m1].tail, sd->normals[m1], sd->rays[m2].tail, sd->normals[m2]);
}

/* Whether the rays of neighbouring samples m1 and m2 cross before their
   heads (in the plane of the chord between their tails): where a concave
   reflector focuses them. */
static int refl__sb_cross(const refl__sb_side *sd, size_t m1, size_t m2) {
    const refl_sbc_ray *r1 = &sd->rays[m1], *r2 = &sd->rays[m2];
    refl_vec3 e = refl_v3_sub(r2->tail, r1->tail);
    refl_vec3 d1 = refl_v3_sub(r1->head, r1->tail), d2 = refl_v3_sub(r2->head, r2->tail);
    float l1 = refl_v3_length(d1), l2 = refl_v3_length(d2), closing;
    if (!(l1 > 0.0f) || !(l2 > 0.0f)) return 0;
    closing = -refl_v3_dot(e, refl_v3_sub(refl_v3_scale(d2, 1.0f / l2), refl_v3_scale(d1, 1.0f / l1)));
    /* the gap e closes at rate `closing` per unit of length: gone after |e|^2 / closing */
    return closing > 0.0f && refl_v3_dot(e, e) < closing * REFL__MIN(l1, l2);
}

/* Side sd's pieces: comp[m] the smallest sample index of m's piece
   (samples linked through smooth neighbours whose rays cross their
   neighbours' alike: a focusing region and the rest are pieces apart),
   -1 without a ray. */
static void refl__sb_pieces(const refl__sb *sb, refl__sb_side *sd) {
    uint8_t *crossing = sd->crossing;
    int u, v, mw = sb->map_w, mh = sb->map_h, m, k, pass;
    memset(crossing, 0, (size_t)mw * (size_t)mh);
    for (m = 0; m < mw * mh; ++m) sd->comp[m] = sd->valid[m] ? m : -1;
    /* first which rays cross a neighbour's, then the links */
    for (pass = 0; pass < 2; ++pass)
        for (v = 0; v < mh; ++v)
            for (u = 0; u < mw; ++u) {
                int a = v * mw + u;
                if (!sd->valid[a]) continue;
                for (k = 0; k < 2; ++k) {
                    int b = k ? a + mw : a + 1, ra, rb;
                    if ((k ? v + 1 >= mh : u + 1 >= mw) || !sd->valid[b]) continue;
                    if (!pass) {
                        if (refl__sb_cross(sd, (size_t)a, (size_t)b)) crossing[a] = crossing[b] = 1;
                        continue;
                    }
                    if (crossing[a] != crossing[b] || !refl__sb_smooth(sd, (size_t)a, (size_t)b)) continue;
                    /* a history's pieces lie within its parent's: the rays of one
                       smooth piece of the mirror before */
                    if (sd->parent >= 0 && sb->sides[sd->parent].comp[a] != sb->sides[sd->parent].comp[b]) continue;
                    ra = refl__sbc_root(sd->comp, a);
                    rb = refl__sbc_root(sd->comp, b);
                    if (ra < rb) sd->comp[rb] = ra;
                    else sd->comp[ra] = rb;
                }
            }
    for (m = 0; m < mw * mh; ++m)
        if (sd->comp[m] >= 0) sd->comp[m] = refl__sbc_root(sd->comp, m);
}

/* A higher layer's ring ray m (window mw x mh): continued linearly from
   member m1 beside it and the member (u2, v2) beyond that (tail, head and
   first reflector point alike); 0 when (u2, v2) is none. Those rays are no
   reflections of a surface the view sees, so the first order's
   tangent-plane rule has nothing to extend. */
static int refl__sb_ring_linear(int mw, int mh, refl_sbc_ray *rays, refl__sbc_hit *hits, const uint8_t *valid,
                                size_t m, size_t m1, int u2, int v2) {
    const refl_sbc_ray *a = &rays[m1], *b;
    if (u2 < 0 || v2 < 0 || u2 >= mw || v2 >= mh || valid[(size_t)v2 * (size_t)mw + (size_t)u2] != 1) return 0;
    b = &rays[(size_t)v2 * (size_t)mw + (size_t)u2];
    rays[m].tail = refl_v3_sub(refl_v3_scale(a->tail, 2.0f), b->tail);
    rays[m].head = refl_v3_sub(refl_v3_scale(a->head, 2.0f), b->head);
    rays[m].first = refl_v3_sub(refl_v3_scale(a->first, 2.0f), b->first);
    hits[m].object = -1;
    return 1;
}

/* One ring of rays extrapolated around the members (valid 1) of a window
   [u0, u0 + mw) x [v0, v0 + mh) of side sd's map, piece `comp`, diagonal
   neighbours included (else the unit frustums at a convex corner of the
   piece lack a corner ray): the sample's view ray meets the tangent plane
   of its member neighbour, the normal continues linearly from the member
   beyond that one (past grazing the ray goes straight on). So the
   frustums reach past the piece's edge (the paper's "extended
   reflectors"), wherever the piece ends: at a silhouette, a crease, or a
   surface passing in front. Past the first order: refl__sb_ring_linear. */
static void refl__sb_ring(const refl__sb *sb, const refl__sb_side *sd, int comp, int u0, int v0, int mw, int mh,
                          refl_sbc_ray *rays, refl__sbc_hit *hits, uint8_t *valid) {
    static const int du[8] = {-1, 1, 0, 0, -1, 1, -1, 1}, dv[8] = {0, 0, -1, 1, -1, -1, 1, 1};
    const refl__pass *p = sb->p;
    int u, v, k;
    for (v = 0; v < mh; ++v)
        for (u = 0; u < mw; ++u) {
            size_t m = (size_t)v * (size_t)mw + (size_t)u;
            if (valid[m]) continue;
            for (k = 0; k < 8; ++k) {
                int u1 = u + du[k], v1 = v + dv[k], u2 = u0 + u + 2 * du[k], v2 = v0 + v + 2 * dv[k], x, y;
                size_t m1, g1;
                refl_vec3 o, d, q1, n1, n;
                float tmax, den, t;
                if (u1 < 0 || v1 < 0 || u1 >= mw || v1 >= mh) continue;
                m1 = (size_t)v1 * (size_t)mw + (size_t)u1;
                if (valid[m1] != 1) continue;
                if (sd->layer) { /* past the first order: linearly */
                    if (!refl__sb_ring_linear(mw, mh, rays, hits, valid, m, m1, u2 - u0, v2 - v0)) continue;
                    valid[m] = 2;
                    break;
                }
                g1 = (size_t)(v0 + v1) * (size_t)sb->map_w + (size_t)(u0 + u1);
                q1 = rays[m1].tail;
                n1 = sd->normals[g1];
                n = n1;
                if (u2 >= 0 && v2 >= 0 && u2 < sb->map_w && v2 < sb->map_h) {
                    size_t g2 = (size_t)v2 * (size_t)sb->map_w + (size_t)u2;
                    if (sd->comp[g2] == comp) n = refl_v3_sub(refl_v3_scale(n1, 2.0f), sd->normals[g2]);
                }
                x = (u0 + u) * sb->factor + sb->factor / 2; /* past the frame's edge too */
                y = (v0 + v) * sb->factor + sb->factor / 2;
                refl__view_rays_get(&p->rays, (float)x + 0.5f, (float)y + 0.5f, &o, &d, &tmax);
                den = refl_v3_dot(d, n1);
                if (fabsf(den) < 1e-6f) continue;
                t = refl_v3_dot(refl_v3_sub(q1, o), n1) / den;
                if (!(t > 0.0f) || !refl__isfinite(t)) continue;
                if (refl__sb_ray(sb, refl_v3_add(o, refl_v3_scale(d, t)), n, d, &rays[m], &hits[m])) {
                    valid[m] = 2;
                    break;
                }
            }
        }
    for (k = 0; k < mw * mh; ++k) valid[k] = valid[k] != 0;
}

static void refl__sb_box_add(refl_vec3 *lo, refl_vec3 *hi, refl_vec3 p) {
    lo->x = REFL__MIN(lo->x, p.x); lo->y = REFL__MIN(lo->y, p.y); lo->z = REFL__MIN(lo->z, p.z);
    hi->x = REFL__MAX(hi->x, p.x); hi->y = REFL__MAX(hi->y, p.y); hi->z = REFL__MAX(hi->z, p.z);
}

static int refl__sb_hit_before(const refl__sbc_hit *a, const refl__sbc_hit *b) {
    return a->object < b->object || (a->object == b->object && a->triangle < b->triangle);
}

/* Sorts n hits from a into out by object and triangle, stably (a
   bottom-up merge sort; a is scratch). */
static void refl__sb_sort_hits(refl__sbc_hit *a, refl__sbc_hit *out, int n) {
    int width, i;
    refl__sbc_hit *src = a, *dst = out, *t;
    for (width = 1; width < n; width *= 2) {
        for (i = 0; i < n; i += 2 * width) {
            int l = i, m = REFL__MIN(i + width, n), r = m, e = REFL__MIN(i + 2 * width, n), o = i;
            while (l < m || r < e)
                dst[o++] = r >= e || (l < m && !refl__sb_hit_before(&src[r], &src[l])) ? src[l++] : src[r++];
        }
        t = src; src = dst; dst = t;
    }
    if (src != out) memcpy(out, src, (size_t)n * sizeof(refl__sbc_hit));
}

/* Builds group g's tree from its piece's rays in its tile grown by
   REFL__SB_GUARD samples, and a ring around them (a job). */
static void refl__sb_build_group(void *arg, int g) {
    refl__sb *sb = (refl__sb *)arg;
    const refl__pass *p = sb->p;
    const refl_allocator *al = &p->scene->allocator;
    refl__sb_group *gr = &sb->groups[g];
    const refl__sb_side *sd = &sb->sides[gr->side];
    /* the ring may lie a sample past the map's edge: the frustums reach the frame's edge pixels */
    int u0 = REFL__MAX(gr->u0 - REFL__SB_GUARD, -1), v0 = REFL__MAX(gr->v0 - REFL__SB_GUARD, -1);
    int u1 = REFL__MIN(gr->u1 + REFL__SB_GUARD, sb->map_w + 1), v1 = REFL__MIN(gr->v1 + REFL__SB_GUARD, sb->map_h + 1);
    int mw = u1 - u0, mh = v1 - v0, u, v, count = 0, met = 0;
    size_t n = (size_t)mw * (size_t)mh, k;
    refl_sbc_ray *rays = (refl_sbc_ray *)refl__calloc(al, n, sizeof(refl_sbc_ray));
    refl__sbc_hit *hits = (refl__sbc_hit *)refl__calloc(al, n, sizeof(refl__sbc_hit));
    uint8_t *valid = (uint8_t *)refl__calloc(al, n, 1);
    refl_sbc_desc d;
    refl_vec3 grow;
    if (!rays || !hits || !valid) {
        gr->result = REFL_ERROR_OUT_OF_MEMORY;
    } else {
        for (v = v0; v < v1; ++v)
            for (u = u0; u < u1; ++u) {
                size_t m;
                if (u < 0 || v < 0 || u >= sb->map_w || v >= sb->map_h) continue;
                m = (size_t)v * (size_t)sb->map_w + (size_t)u;
                k = (size_t)(v - v0) * (size_t)mw + (size_t)(u - u0);
                if (!sd->valid[m] || sd->comp[m] != gr->comp) continue;
                rays[k] = sd->rays[m];
                hits[k] = sd->hits[m];
                valid[k] = 1;
            }
        refl__sb_ring(sb, sd, gr->comp, u0, v0, mw, mh, rays, hits, valid);
        for (k = 0; k < n; ++k) {
            if (!valid[k]) continue;
            if (!count++) {
                gr->lo = gr->hi = rays[k].tail;
                gr->first_lo = gr->first_hi = rays[k].first;
            }
            refl__sb_box_add(&gr->first_lo, &gr->first_hi, rays[k].first);
            refl__sb_box_add(&gr->lo, &gr->hi, rays[k].tail);
            refl__sb_box_add(&gr->lo, &gr->hi, rays[k].head);
            if (hits[k].object >= 0) hits[met++] = hits[k]; /* k >= met: nothing unread is overwritten */
        }
        /* a quarter of its size around: ray lists reach past the heads,
           cameras below the tails (cam_sbc_raylist.c, cam_sbc_fit.c) */
        grow = refl_v3_add(refl_v3_scale(refl_v3_sub(gr->hi, gr->lo), 0.25f),
                           refl_v3(1e-4f * sb->diagonal, 1e-4f * sb->diagonal, 1e-4f * sb->diagonal));
        gr->lo = refl_v3_sub(gr->lo, grow);
        gr->hi = refl_v3_add(gr->hi, grow);
        grow = refl_v3_add(refl_v3_scale(refl_v3_sub(gr->first_hi, gr->first_lo), 0.25f),
                           refl_v3(1e-4f * sb->diagonal, 1e-4f * sb->diagonal, 1e-4f * sb->diagonal));
        gr->first_lo = refl_v3_sub(gr->first_lo, grow);
        gr->first_hi = refl_v3_add(gr->first_hi, grow);
        /* by object and triangle, ties in map order (a stable merge: qsort is not) */
        if (met && (gr->hits = (refl__sbc_hit *)refl__calloc(al, (size_t)met, sizeof(refl__sbc_hit))) != NULL) {
            refl__sb_sort_hits(hits, gr->hits, met);
            gr->hit_count = met;
        } else if (met) {
            gr->result = REFL_ERROR_OUT_OF_MEMORY;
            count = 0;
        }
    }
    if (count) { /* a group without a ray (every normal turned away) reflects nothing */
        memset(&d, 0, sizeof d);
        d.error_px = sb->error_px;
        d.view_proj = p->vp;
        d.width = p->frame->width;
        d.height = p->frame->height;
        d.allocator = *al;
        gr->result = refl_sbc_build(rays, valid, mw, mh, &d, &gr->sbc);
        if (gr->result == REFL_OK) {
            refl_sbc_stats st;
            refl_sbc_get_stats(gr->sbc, &st);
            gr->sheets = REFL__CLAMP(st.sheets, 1, REFL__SB_SHEETS);
        }
    }
    refl__free(al, rays);
    refl__free(al, hits);
    refl__free(al, valid);
}

/* Pixel k's group in side sdk, whose samples are samples of sd, the
   side the pixel shows (sdk == sd in the first layer): that of the nearest
   sample on the pixel's own smooth piece of surface, else of the sample
   nearby whose point lies nearest the pixel's; -1: none. */
static int refl__sb_pixel_group(const refl__sb *sb, size_t k, const refl__sb_side *sd, const refl__sb_side *sdk) {
    const refl_frame *fr = sb->p->frame;
    int x = (int)(k % (size_t)fr->width), y = (int)(k / (size_t)fr->width), du, dv, best = -1, near = -1, u, v;
    float best_d2 = INFINITY, near_d2 = INFINITY;
    refl_vec3 q = refl_v3(sb->em->surface[3 * k], sb->em->surface[3 * k + 1], sb->em->surface[3 * k + 2]);
    refl_vec3 n = refl_v3_normalize(refl_v3(sb->em->gbuf[4 * k], sb->em->gbuf[4 * k + 1], sb->em->gbuf[4 * k + 2]));
    u = x / sb->factor;
    v = y / sb->factor;
    for (dv = -2; dv <= 2; ++dv)
        for (du = -2; du <= 2; ++du) {
            int us = u + du, vs = v + dv, sx, sy;
            size_t m;
            refl_vec3 e;
            float d2, l, p2;
            if (us < 0 || vs < 0 || us >= sb->map_w || vs >= sb->map_h) continue;
            m = (size_t)vs * (size_t)sb->map_w + (size_t)us;
            if (!sdk->valid[m]) continue;
            e = refl_v3_sub(sd->rays[m].tail, q);
            d2 = refl_v3_dot(e, e);
            l = sqrtf(d2);
            if (d2 < near_d2) {
                near_d2 = d2;
                near = sdk->group[m];
            }
            if (fabsf(refl_v3_dot(sd->normals[m], n)) < REFL__SBC_SMOOTH_COS ||
                fabsf(refl_v3_dot(n, e)) > REFL__SBC_SMOOTH_SIN * l ||
                fabsf(refl_v3_dot(sd->normals[m], e)) > REFL__SBC_SMOOTH_SIN * l)
                continue;
            refl__sb_sample_pixel(sb, us, vs, &sx, &sy);
            p2 = (float)((sx - x) * (sx - x) + (sy - y) * (sy - y));
            if (p2 < best_d2) {
                best_d2 = p2;
                best = sdk->group[m];
            }
        }
    return best >= 0 ? best : near;
}

/* Row y's pixels' groups in the layers past the first: each pixel's own
   history traced (refl__sb_trace_path), each order's side found, and the
   pixel's group there (refl__sb_pixel_group). */
static void refl__sb_assign_row(void *arg, int y) {
    refl__sb *sb = (refl__sb *)arg;
    const refl_frame *fr = sb->p->frame;
    size_t npx = (size_t)fr->width * (size_t)fr->height;
    int x, k, l;
    for (x = 0; x < fr->width; ++x) {
        size_t i = (size_t)y * (size_t)fr->width + (size_t)x;
        int side = sb->group_of[i] ? sb->groups[sb->group_of[i] - 1].side : -1, s;
        refl_vec3 d, q, n;
        refl__sb_path pa;
        refl__sb_refr rp;
        for (l = 1; l < sb->layers; ++l) sb->group_of[(size_t)l * npx + i] = 0;
        if (side < 0) continue;
        refl__sb_pixel_view(sb, i, &d, &q, &n);
        refl__sb_trace_path(sb, q, n, d, sb->em->gbuf[4 * i + 3], &pa);
        for (s = side, k = 1; k < pa.count && s >= 0; ++k)
            if ((s = refl__sb_find_side(sb, s, pa.id[k], 0)) >= 0)
                sb->group_of[(size_t)k * npx + i] = refl__sb_pixel_group(sb, i, &sb->sides[side], &sb->sides[s]) + 1;
        if (sb->layers > sb->orders && (k = refl__sb_refract_path(sb, q, n, d, sb->em->gbuf[4 * i + 3], &rp)) > 0 &&
            (s = refl__sb_find_side(sb, side, 0.0f, k)) >= 0)
            sb->group_of[(size_t)sb->orders * npx + i] =
                refl__sb_pixel_group(sb, i, &sb->sides[side], &sb->sides[s]) + 1;
    }
}

/* Side sd's pieces that need no tiles (planar, their rays crossing no
   neighbour's: a pinhole camera fits them whole, however large), as
   `whole` per piece root, with their samples' box (4 per root: u0, v0,
   u1, v1). */
static void refl__sb_whole_pieces(const refl__sb *sb, const refl__sb_side *sd, uint8_t *whole, int *box) {
    int u, v, mw = sb->map_w;
    for (v = 0; v < sb->map_h; ++v)
        for (u = 0; u < mw; ++u) {
            int m = v * mw + u, r = sd->comp[m];
            if (!sd->valid[m] || r < 0) continue;
            if (r == m) {
                whole[r] = 1;
                box[4 * r] = box[4 * r + 2] = u;
                box[4 * r + 1] = box[4 * r + 3] = v;
            }
            whole[r] = (uint8_t)(whole[r] && !sd->crossing[m] &&
                                 refl_v3_dot(sd->normals[m], sd->normals[r]) >= REFL__SB_PLANAR_COS);
            box[4 * r] = REFL__MIN(box[4 * r], u);
            box[4 * r + 1] = REFL__MIN(box[4 * r + 1], v);
            box[4 * r + 2] = REFL__MAX(box[4 * r + 2], u + 1);
            box[4 * r + 3] = REFL__MAX(box[4 * r + 3], v + 1);
        }
}

/* Group `index` of side i, piece `comp`, over samples [u0, u1) x [v0, v1). */
static void refl__sb_group_set(refl__sb *sb, int index, int i, int comp, int u0, int v0, int u1, int v1) {
    refl__sb_group *g = &sb->groups[index];
    g->side = i;
    g->object = sb->sides[i].object;
    g->comp = comp;
    g->u0 = u0;
    g->v0 = v0;
    g->u1 = u1;
    g->v1 = v1;
}

/* The groups: each side's planar pieces whole (the paper's one camera
   per planar mirror), the others (curved: a tree's leaves fit a tile's
   rays better than a whole piece's; focusing: ray lists) cut by tiles of sb->tile samples (the tile side
   doubles, up to REFL__SB_TILE_MAX, while there are more than a batch:
   REFL__SB_BATCH; focusing rays end in ray lists, which a tile keeps
   small), and each pixel's group. */
static refl_result refl__sb_groups(refl__sb *sb) {
    const refl_allocator *al = &sb->p->scene->allocator;
    const refl_frame *fr = sb->p->frame;
    size_t npx = (size_t)fr->width * (size_t)fr->height, k, nmap = (size_t)sb->map_w * (size_t)sb->map_h;
    int *seen, *box, *piece_group, i, pass, u, v, tu, tv;
    uint8_t *whole;
    /* count the groups (whole pieces, a tile's pieces), doubling the tile
       until they fit a batch (fewer groups, fewer projections) or the
       tile reaches REFL__SB_TILE_MAX (more batches then); then list them,
       each sample noting its group. */
    seen = (int *)refl__calloc(al, nmap, sizeof(int));
    box = (int *)refl__calloc(al, nmap, 4 * sizeof(int));
    piece_group = (int *)refl__calloc(al, nmap, sizeof(int));
    whole = (uint8_t *)refl__calloc(al, nmap, 1);
    if (!seen || !box || !piece_group || !whole) {
        refl__free(al, seen);
        refl__free(al, box);
        refl__free(al, piece_group);
        refl__free(al, whole);
        return REFL_ERROR_OUT_OF_MEMORY;
    }
    for (sb->tile = REFL__SB_TILE;; sb->tile *= 2) {
        int tw = (sb->map_w + sb->tile - 1) / sb->tile, th = (sb->map_h + sb->tile - 1) / sb->tile;
        int largest = sb->tile >= REFL__SB_TILE_MAX;
        for (pass = 0; pass < 2; ++pass) {
            sb->group_count = 0;
            for (i = 0; i < sb->side_count; ++i) {
                refl__sb_side *sd = &sb->sides[i];
                refl__sb_whole_pieces(sb, sd, whole, box);
                for (k = 0; k < nmap; ++k) {
                    int r = sd->comp[k];
                    if (!sd->valid[k] || r < 0 || !whole[r]) continue;
                    if ((size_t)r == k) {
                        piece_group[r] = sb->group_count++;
                        if (pass) {
                            refl__sb_group_set(sb, piece_group[r], i, r, box[4 * r], box[4 * r + 1],
                                               box[4 * r + 2], box[4 * r + 3]);
                            sb->groups[piece_group[r]].whole = 1;
                        }
                    }
                    sd->group[k] = piece_group[r];
                }
                for (tv = 0; tv < th; ++tv)
                    for (tu = 0; tu < tw; ++tu) {
                        int first = sb->group_count, nseen = 0, uu0 = tu * sb->tile, vv0 = tv * sb->tile;
                        int uu1 = REFL__MIN(uu0 + sb->tile, sb->map_w), vv1 = REFL__MIN(vv0 + sb->tile, sb->map_h);
                        for (v = vv0; v < vv1; ++v)
                            for (u = uu0; u < uu1; ++u) {
                                size_t m = (size_t)v * (size_t)sb->map_w + (size_t)u;
                                int gi = 0;
                                if (!sd->valid[m] || sd->comp[m] < 0 || whole[sd->comp[m]]) continue;
                                while (gi < nseen && seen[gi] != sd->comp[m]) ++gi;
                                sd->group[m] = first + gi;
                                if (gi < nseen) continue;
                                seen[nseen++] = sd->comp[m];
                                if (pass) refl__sb_group_set(sb, sb->group_count, i, sd->comp[m], uu0, vv0, uu1, vv1);
                                sb->group_count++;
                            }
                    }
            }
            if (sb->group_count > REFL__SB_BATCH && !largest) break;
            if (!pass) {
                sb->groups = (refl__sb_group *)refl__calloc(al, (size_t)REFL__MAX(sb->group_count, 1),
                                                            sizeof(refl__sb_group));
                if (!sb->groups) {
                    refl__free(al, seen);
                    refl__free(al, box);
                    refl__free(al, piece_group);
                    refl__free(al, whole);
                    return REFL_ERROR_OUT_OF_MEMORY;
                }
            }
        }
        if (pass == 2) break;
    }
    refl__free(al, box);
    refl__free(al, piece_group);
    refl__free(al, whole);
    refl__free(al, seen);
    sb->group_of = (int *)refl__calloc(al, npx, (size_t)sb->layers * sizeof(int));
    if (!sb->group_of) return REFL_ERROR_OUT_OF_MEMORY;
    /* each pixel's group in the first layer; the others' by rows */
    for (k = 0; k < npx; ++k) {
        float id = sb->em->gbuf[4 * k + 3];
        const refl__sb_side *sd = NULL;
        sb->group_of[k] = 0;
        for (i = 0; id != 0.0f && i < sb->side_count && sb->sides[i].order == 1 && !sb->sides[i].kind; ++i)
            if (sb->sides[i].id == id) sd = &sb->sides[i];
        if (sd) sb->group_of[k] = refl__sb_pixel_group(sb, k, sd, sd) + 1;
    }
    if (sb->layers > 1) rast_run_jobs(sb->p->rc, fr->height, refl__sb_assign_row, sb);
    return REFL_OK;
}

/* ---- reflection morphing (paper 003 VI): groups backed by prebuilt grids ---- */

/* The caller's grid for object o whose tetrahedra hold the eye, or NULL. */
static const refl_sbc_morph *refl__sb_morph_for(const refl__pass *p, int o) {
    int k, nodes[4];
    float w[4];
    for (k = 0; k < p->desc.sbc.morph_count; ++k) {
        const refl_sbc_morph *m = p->desc.sbc.morphs[k];
        if (m && refl_sbc_morph_object(m) == o)
            return refl_sbc_morph_locate(m, p->view->eye, nodes, w) >= 0 ? m : NULL;
    }
    return NULL;
}

/* Row y's front pixels of objects drawn from grids: the group of the
   piece their view ray meets (a job per row). */
static void refl__sb_morph_row(void *arg, int y) {
    refl__sb *sb = (refl__sb *)arg;
    const refl__pass *p = sb->p;
    int x, W = p->frame->width;
    for (x = 0; x < W; ++x) {
        size_t i = (size_t)y * (size_t)W + (size_t)x;
        float id = sb->em->gbuf[4 * i + 3], tmax;
        int o = (int)id - 1, piece;
        refl_vec3 org, d;
        if (!(id >= 1.0f) || o >= p->scene->object_count || sb->morph_base[o] < 0) continue;
        refl__view_rays_get(&p->rays, (float)x + 0.5f, (float)y + 0.5f, &org, &d, &tmax);
        piece = refl_sbc_morph_piece_at(sb->groups[sb->morph_base[o]].morph, org, d);
        sb->group_of[i] = piece >= 0 ? sb->morph_base[o] + piece + 1 : 0;
    }
}

/* Adds a group per piece of every grid in use whose object shows its
   front (after the frame's own groups are built) after the first layer's
   groups (batches go layer by layer), and gives them their pixels. */
static refl_result refl__sb_morph_groups(refl__sb *sb) {
    const refl__pass *p = sb->p;
    const refl_scene *scene = p->scene;
    const refl_allocator *al = &scene->allocator;
    size_t npx = (size_t)p->frame->width * (size_t)p->frame->height, k;
    int o, add = 0, piece, ins = 0, i;
    refl__sb_group *groups;
    refl__sbc_hit *scratch;
    sb->morph_base = (int *)refl__calloc(al, (size_t)scene->object_count, sizeof(int));
    if (!sb->morph_base) return REFL_ERROR_OUT_OF_MEMORY;
    for (o = 0; o < scene->object_count; ++o) sb->morph_base[o] = -2; /* -2: not shown */
    for (k = 0; k < npx; ++k) {
        float id = sb->em->gbuf[4 * k + 3];
        if (id >= 1.0f && (int)id - 1 < scene->object_count) sb->morph_base[(int)id - 1] = -1;
    }
    for (o = 0; o < scene->object_count; ++o) {
        const refl_sbc_morph *m = sb->morph_base[o] == -1 ? refl__sb_morph_for(p, o) : NULL;
        refl_sbc_morph_stats st;
        sb->morph_base[o] = -1;
        if (!m) continue;
        refl_sbc_morph_get_stats(m, &st);
        sb->morph_base[o] = add; /* from the insertion point, set below */
        add += st.pieces;
        p->frame->stats.model_bytes += st.bytes;
    }
    if (!add) return REFL_OK;
    while (ins < sb->group_count && !sb->sides[sb->groups[ins].side].layer) ++ins;
    for (o = 0; o < scene->object_count; ++o)
        if (sb->morph_base[o] >= 0) sb->morph_base[o] += ins;
    groups = (refl__sb_group *)refl__calloc(al, (size_t)(sb->group_count + add), sizeof(refl__sb_group));
    if (!groups) return REFL_ERROR_OUT_OF_MEMORY;
    if (ins) memcpy(groups, sb->groups, (size_t)ins * sizeof(refl__sb_group));
    if (sb->group_count > ins)
        memcpy(groups + ins + add, sb->groups + ins, (size_t)(sb->group_count - ins) * sizeof(refl__sb_group));
    refl__free(al, sb->groups);
    sb->groups = groups;
    /* the later layers' groups moved on by `add`: their samples' and pixels' indices too */
    for (i = 0; i < sb->side_count; ++i) {
        refl__sb_side *sd = &sb->sides[i];
        size_t n = (size_t)sb->map_w * (size_t)sb->map_h;
        if (!sd->layer) continue;
        for (k = 0; k < n; ++k)
            if (sd->group[k] >= ins) sd->group[k] += add;
    }
    for (k = npx; k < (size_t)sb->layers * npx; ++k)
        if (sb->group_of[k] > ins) sb->group_of[k] += add;
    for (o = 0; o < scene->object_count; ++o) {
        const refl_sbc_morph *m = sb->morph_base[o] < 0 ? NULL : refl__sb_morph_for(p, o);
        refl_sbc_morph_stats st;
        refl_sbc_morph_get_stats(m, &st);
        for (piece = 0; piece < st.pieces; ++piece) {
            refl__sb_group *g = &groups[sb->morph_base[o] + piece];
            g->side = -1;
            g->object = o;
            g->morph = m;
            g->piece = piece;
            refl_sbc_morph_locate(m, p->view->eye, g->morph_nodes, g->morph_w); /* refl__sb_morph_for found it */
            g->sheets = refl__sbm_piece_sheets(m, g->morph_nodes, g->morph_w, piece);
            refl__sbm_piece_box(m, p->view->eye, piece, &g->lo, &g->hi);
            /* where the tetrahedron's nodes' rays meet the scene, by object and triangle */
            g->hit_count = refl__sbm_tet_hits(m, p->view->eye, piece, NULL);
            if (!g->hit_count) continue;
            g->hits = (refl__sbc_hit *)refl__calloc(al, (size_t)g->hit_count, sizeof(refl__sbc_hit));
            scratch = (refl__sbc_hit *)refl__calloc(al, (size_t)g->hit_count, sizeof(refl__sbc_hit));
            if (g->hits && scratch) {
                refl__sbm_tet_hits(m, p->view->eye, piece, scratch);
                refl__sb_sort_hits(scratch, g->hits, g->hit_count);
            }
            refl__free(al, scratch);
            if (!g->hits) {
                sb->group_count += add; /* freed with the others */
                return REFL_ERROR_OUT_OF_MEMORY;
            }
        }
    }
    sb->group_count += add;
    rast_run_jobs(p->rc, p->frame->height, refl__sb_morph_row, sb);
    return REFL_OK;
}

static void refl__sb_groups_free(refl__sb *sb) {
    const refl_allocator *al = &sb->p->scene->allocator;
    int i;
    for (i = 0; sb->groups && i < sb->group_count; ++i) {
        refl_sbc_destroy(sb->groups[i].sbc);
        refl__free(al, sb->groups[i].hits);
    }
    refl__free(al, sb->groups);
    refl__free(al, sb->group_of);
    refl__free(al, sb->morph_base);
}
