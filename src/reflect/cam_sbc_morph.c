/* cam_sbc_morph: paper 003's reflection morphing mode (section VI): a
   grid of panoramic sample-based cameras around one reflector, blended
   for the eye.
     Grid: nodes[0] x nodes[1] x nodes[2] nodes spanning the reflector's
     world box grown by margin times its diagonal (or a given region). A
     cell is cut into 6 tetrahedra along its main diagonal (Kuhn's
     triangulation): for local coordinates f sorted as f_a >= f_b >= f_c
     the tetrahedron runs from the cell's low corner through + e_a and
     + e_a + e_b to the high corner, with barycentric weights 1 - f_a,
     f_a - f_b, f_b - f_c, f_c. Neighbouring cells share faces, so the
     weights are continuous across the grid. Cells overlapping the
     reflector's box hold no eye (their nodes would look at the reflector
     from opposite sides); nodes no such cell uses are not built.
     Pieces: the reflector's triangles joined through shared vertices (the
     mesh splits vertices at creases: the teapot's lid, knob, body, spout
     and handle come apart). The desired view's pixel shows one piece, and
     a point reflects at most about once in a smooth piece, so blending
     first points per piece is meaningful where blending across pieces
     (the spout's reflection at one node, the body's at another) is not.
     Node cameras: per face of a cube around the node (90 degrees, one
     extra sample all round so neighbouring faces' rays overlap) the ray
     of each sample meets each piece at its first hit of that piece (the
     other pieces are passed through: none hides another); a front-facing
     hit is a ray with tail = first = the hit, reflected about the
     interpolated normal, its head clipped as runtime mode clips it (twice
     as far as what it meets plus 1% of the scene diagonal, or a tenth of
     the diagonal when it meets nothing, inside the scene box grown 1%).
     Remedy (a): extend_rings rings of samples past the reflector's
     silhouette (samples whose ray meets no piece) get extrapolated rays
     (the sample's ray meets the tangent plane of a member neighbour; the
     normal continues linearly; past grazing the ray goes straight on), as
     runtime mode's single ring does. Not past a piece's other edges: there
     the extension lies beside the neighbouring piece's real surface, and
     points reflected in it were drawn over the piece's own pixels; more
     than one ring does worse still (docs/methods/sbc.md). Each (piece, face) with
     rays is one SBC built to error_px face pixels with the face's own
     view-projection, widened by remedy (b) (pinhole leaves only: most of
     a curved reflector's leaves are ray lists, so it helps little).
     Projection at a node: a point outside the piece's box there (its rays'
     tails and heads, grown by a quarter as runtime mode grows a group's)
     does not project; else the piece's face SBCs in face order, keeping
     only a first point the point lies ahead of along the unextended ray
     of the sample it lands on (runtime mode's check: a leaf reaches a
     little behind the reflector); a first point in the face's own
     90-degree cone takes that face's answer, else the first face that
     projects it (the overlap). Rendering projects into each sheet of the
     face SBCs (refl_sbc_project_sheets) so: seen from a node, a point near
     the teapot's knob or in a concave bowl lies in the frustums of rays
     before and past their fold, and one image per piece (the public
     projections here, the paper's) drew it in one place only; sheet k
     of the four nodes is blended with sheet k (refl__sbm_blend_sheet).
     No unit frustum spans
     neighbours off one smooth piece of surface (refl__sbm_links).
     check_ambiguous counts the paper's construction criterion: the heads
     of every node's unextended rays, and points a tenth of the way along
     from their tails (the tails themselves lie on every frustum's floor),
     projected at the other nodes of the tetrahedra holding both.
   Deterministic: each node is built by one job from its own inputs; sums
   run in a fixed order. */
#include "cam_sbc_internal.h"

#define REFL__SBM_HITS 64        /* hits walked along one node ray at most */
#define REFL__SBM_PIECES 1024    /* smooth pieces of a reflector at most */

/* A node: per piece, where its rays meet the scene (refl__sbc_hit, as
   runtime mode's groups keep them: it subdivides a scene triangle towards
   such points), its ray ends, its SBCs per face. */
typedef struct refl__sbm_node {
    refl_vec3 pos;
    int built;
    refl_sbc **sbc;              /* [piece * 6 + face]; NULL where the piece shows nothing */
    signed char **dirs;          /* [piece * 6 + face]: per face sample, its unextended ray's unit
                                    direction times 127 (zero: no such ray), or NULL */
    int face;                    /* face samples per side (the maps have face + 2) */
    float *box;                  /* per piece: its rays' tails' and heads' box (lows, highs), grown */
    refl__sbc_hit **hits;        /* per piece: what its rays meet, in face and map order */
    int *hit_count;
    refl_vec3 **ends;            /* with check_ambiguous, during the build: per piece, its
                                    unextended rays' heads and points a tenth along from the tails */
    int *end_count;
    refl_result result;
} refl__sbm_node;

struct refl_sbc_morph {
    refl_allocator allocator;
    int object;
    int n[3];
    refl_vec3 lo, step;          /* node (i, j, k) = lo + (i, j, k) * step */
    refl_vec3 box_lo, box_hi;    /* the reflector's world box */
    int piece_count;
    int *piece;                  /* per reflector triangle */
    float *pos, *nrm;            /* world positions and normals of the reflector's vertices */
    const uint32_t *indices;     /* a copy, 3 per triangle */
    uint32_t *index_copy;
    int triangle_count;
    refl_bvh *bvh;               /* the reflector alone: hit.triangle */
    refl__sbm_node *nodes;
    uint8_t *cell_ok;            /* per cell: clear of the reflector's box */
    refl_sbc_morph_stats stats;
};

struct refl_sbc_morph_cache {
    refl_allocator allocator;
    int tet, piece, count;
    const float *points;
    float *slot;                 /* per point and tetrahedron node: first (3), dist */
    uint8_t *ok;                 /* per point: bit i, projects at node i */
    int cap;
};

static int refl__sbm_node_project(const refl__sbm_node *nd, int piece, refl_vec3 p, refl_vec3 *first);

/* What a build job reads. */
typedef struct refl__sbm_build {
    refl_sbc_morph *m;
    const refl_scene *scene;
    refl_bvh *scene_bvh;
    refl_vec3 scene_lo, scene_hi;
    float diagonal;
    int face, rings;
    float error_px, widen;
    const int *list;             /* the nodes to build: job i builds nodes[list[i]] */
    int check;                   /* desc.check_ambiguous */
} refl__sbm_build;

static const float refl__sbm_forward[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
static const float refl__sbm_up[6][3] = {{0, 1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}, {0, 1, 0}, {0, 1, 0}};

/* The cube face whose cone holds direction v (the largest component;
   ties to the earlier axis). */
static int refl__sbm_face_of(refl_vec3 v) {
    float ax = fabsf(v.x), ay = fabsf(v.y), az = fabsf(v.z);
    if (ax >= ay && ax >= az) return v.x >= 0.0f ? 0 : 1;
    if (ay >= az) return v.y >= 0.0f ? 2 : 3;
    return v.z >= 0.0f ? 4 : 5;
}

/* Face f's basis: forward, right, up (gluLookAt's). */
static void refl__sbm_basis(int f, refl_vec3 *fw, refl_vec3 *rt, refl_vec3 *up) {
    refl_vec3 u = refl_v3(refl__sbm_up[f][0], refl__sbm_up[f][1], refl__sbm_up[f][2]);
    *fw = refl_v3(refl__sbm_forward[f][0], refl__sbm_forward[f][1], refl__sbm_forward[f][2]);
    *rt = refl_v3_normalize(refl_v3_cross(*fw, u));
    *up = refl_v3_cross(*rt, *fw);
}

/* The unit direction of face sample (i, j): sample 1 + x's centre is
   pixel x of the face's image, so samples 0 and face + 1 lie just beyond it. */
static refl_vec3 refl__sbm_dir(const refl__sbm_build *b, refl_vec3 fw, refl_vec3 rt, refl_vec3 up, int i, int j) {
    float x = 2.0f * ((float)i - 0.5f) / (float)b->face - 1.0f, y = 1.0f - 2.0f * ((float)j - 0.5f) / (float)b->face;
    return refl_v3_normalize(refl_v3_add(fw, refl_v3_add(refl_v3_scale(rt, x), refl_v3_scale(up, y))));
}

/* The reflected ray at q (unit normal n towards the node, view direction d):
   runtime mode's head rule (refl__sbc_scene_ray). 0 for a ray of no length. */
static int refl__sbm_ray(const refl__sbm_build *b, refl_vec3 q, refl_vec3 n, refl_vec3 d, refl_sbc_ray *ray,
                         refl__sbc_hit *met) {
    refl_vec3 r = refl_v3_dot(d, n) < -1e-4f ? refl_v3_reflect(d, n) : d; /* past grazing: straight on */
    return refl__sbc_scene_ray(b->scene_bvh, b->scene_lo, b->scene_hi, b->diagonal, q, r, ray, met);
}

/* Vertex a of triangle t, world. */
static refl_vec3 refl__sbm_vertex(const refl_sbc_morph *m, const float *arr, int t, int a) {
    const float *v = arr + 3 * (size_t)m->indices[3 * (size_t)t + (size_t)a];
    return refl_v3(v[0], v[1], v[2]);
}

/* The unit normal of a hit: interpolated (shading), and whether the hit
   is on the triangle's front (geometric normal against d). */
static refl_vec3 refl__sbc_hit_normal(const refl_sbc_morph *m, const refl_hit *h, refl_vec3 d, int *front) {
    refl_vec3 a = refl__sbm_vertex(m, m->pos, h->triangle, 0), b = refl__sbm_vertex(m, m->pos, h->triangle, 1);
    refl_vec3 c = refl__sbm_vertex(m, m->pos, h->triangle, 2);
    refl_vec3 g = refl_v3_cross(refl_v3_sub(b, a), refl_v3_sub(c, a));
    refl_vec3 n = refl_v3_add(refl_v3_scale(refl__sbm_vertex(m, m->nrm, h->triangle, 0), 1.0f - h->u - h->v),
                              refl_v3_add(refl_v3_scale(refl__sbm_vertex(m, m->nrm, h->triangle, 1), h->u),
                                          refl_v3_scale(refl__sbm_vertex(m, m->nrm, h->triangle, 2), h->v)));
    *front = refl_v3_dot(g, d) < 0.0f;
    return refl_v3_normalize(n);
}

/* One face of one node: every piece's rays (valid: 1 on the piece, k + 1
   on ring k) in rays/valid/normals, P maps of S samples each. */
static void refl__sbm_face_maps(const refl__sbm_build *b, refl_vec3 o, int f, refl_sbc_ray *rays, uint8_t *valid,
                                refl_vec3 *normals, refl__sbc_hit *met, uint8_t *miss) {
    static const int du[8] = {-1, 1, 0, 0, -1, 1, -1, 1}, dv[8] = {0, 0, -1, 1, -1, -1, 1, 1};
    const refl_sbc_morph *m = b->m;
    int W = b->face + 2, P = m->piece_count, i, j, k, ring, e;
    size_t S = (size_t)W * (size_t)W;
    refl_vec3 fw, rt, up;
    refl__sbm_basis(f, &fw, &rt, &up);
    memset(valid, 0, S * (size_t)P);
    for (j = 0; j < W; ++j)
        for (i = 0; i < W; ++i) {
            refl_vec3 d = refl__sbm_dir(b, fw, rt, up, i, j);
            float tmin = 0.0f;
            refl_hit h;
            size_t s = (size_t)j * (size_t)W + (size_t)i;
            miss[s] = 1;
            /* every piece's first hit along the ray */
            for (k = 0; k < REFL__SBM_HITS && refl_bvh_intersect(m->bvh, o, d, tmin, INFINITY, &h); ++k) {
                miss[s] = 0;
                int pc = m->piece[h.triangle], front;
                size_t at = (size_t)pc * S + s;
                refl_vec3 n;
                tmin = h.t;
                if (valid[at]) continue;
                n = refl__sbc_hit_normal(m, &h, d, &front);
                valid[at] = 255; /* seen: later hits of the piece are hidden by this one */
                if (!front) continue;
                normals[at] = refl_v3_dot(n, d) > 0.0f ? refl_v3_scale(n, -1.0f) : n;
                if (refl__sbm_ray(b, refl_v3_add(o, refl_v3_scale(d, h.t)), normals[at], d, &rays[at], &met[at]))
                    valid[at] = 1;
            }
        }
    for (k = 0; k < (int)(S * (size_t)P); ++k)
        if (valid[k] == 255) valid[k] = 0;
    /* remedy (a): ring r from members and earlier rings only */
    for (ring = 1; ring <= b->rings; ++ring)
        for (k = 0; k < P; ++k) {
            uint8_t *vk = valid + (size_t)k * S;
            refl_sbc_ray *rk = rays + (size_t)k * S;
            refl_vec3 *nk = normals + (size_t)k * S;
            refl__sbc_hit *mk = met + (size_t)k * S;
            for (j = 0; j < W; ++j)
                for (i = 0; i < W; ++i) {
                    size_t s = (size_t)j * (size_t)W + (size_t)i;
                    /* past the silhouette only: where another piece lies, extending
                       this one would put a fictional surface beside a real one */
                    if (vk[s] || !miss[s]) continue;
                    for (e = 0; e < 8; ++e) {
                        int i1 = i + du[e], j1 = j + dv[e], i2 = i + 2 * du[e], j2 = j + 2 * dv[e];
                        float den, t;
                        refl_vec3 d, n1, n;
                        size_t s1;
                        if (i1 < 0 || j1 < 0 || i1 >= W || j1 >= W) continue;
                        s1 = (size_t)j1 * (size_t)W + (size_t)i1;
                        if (!vk[s1] || vk[s1] > ring) continue;
                        n1 = nk[s1];
                        n = n1;
                        if (i2 >= 0 && j2 >= 0 && i2 < W && j2 < W && vk[(size_t)j2 * W + (size_t)i2] &&
                            vk[(size_t)j2 * W + (size_t)i2] <= ring)
                            n = refl_v3_normalize(refl_v3_sub(refl_v3_scale(n1, 2.0f), nk[(size_t)j2 * W + (size_t)i2]));
                        d = refl__sbm_dir(b, fw, rt, up, i, j);
                        den = refl_v3_dot(d, n1);
                        if (fabsf(den) < 1e-6f) continue;
                        t = refl_v3_dot(refl_v3_sub(rk[s1].tail, o), n1) / den;
                        if (!(t > 0.0f) || !refl__isfinite(t)) continue;
                        if (refl_v3_length(n) > 0.0f &&
                            refl__sbm_ray(b, refl_v3_add(o, refl_v3_scale(d, t)), n, d, &rk[s], &mk[s])) {
                            nk[s] = n;
                            vk[s] = (uint8_t)(ring + 1);
                            break;
                        }
                    }
                }
        }
}

/* A piece's face map's links (refl_sbc_desc.links): neighbours on one
   smooth piece of surface. A mesh piece is joined through shared vertices
   only, so the knob seen in front of the lid is the lid's piece, and a
   unit frustum between a ray off the knob's silhouette and one off the lid
   behind it holds points of the body's rim that neither reflects (at
   512-sample faces most of the teapot's error); runtime mode cuts its
   groups at the same links. */
static void refl__sbm_links(const refl_sbc_ray *rays, const uint8_t *valid, const refl_vec3 *normals, int W,
                            uint8_t *links) {
    int u, v;
    for (v = 0; v < W; ++v)
        for (u = 0; u < W; ++u) {
            size_t a = (size_t)v * (size_t)W + (size_t)u, r = a + 1, d = a + (size_t)W;
            links[a] = 0;
            if (!valid[a]) continue;
            if (u + 1 < W && valid[r] && refl__sbc_smooth(rays[a].tail, normals[a], rays[r].tail, normals[r]))
                links[a] |= 1;
            if (v + 1 < W && valid[d] && refl__sbc_smooth(rays[a].tail, normals[a], rays[d].tail, normals[d]))
                links[a] |= 2;
        }
}

/* Builds node `index` (a job): per face, every piece's map and SBC. */
static void refl__sbm_build_node(void *arg, int index) {
    const refl__sbm_build *b = (const refl__sbm_build *)arg;
    refl_sbc_morph *m = b->m;
    refl__sbm_node *nd = &m->nodes[b->list[index]];
    const refl_allocator *al = &m->allocator;
    int W = b->face + 2, P = m->piece_count, f, k;
    size_t S = (size_t)W * (size_t)W, i;
    refl_sbc_ray *rays = (refl_sbc_ray *)refl__calloc(al, S * (size_t)P, sizeof(refl_sbc_ray));
    uint8_t *valid = (uint8_t *)refl__calloc(al, S * (size_t)P, 1);
    refl_vec3 *normals = (refl_vec3 *)refl__calloc(al, S * (size_t)P, sizeof(refl_vec3));
    refl__sbc_hit *met = (refl__sbc_hit *)refl__calloc(al, S * (size_t)P, sizeof(refl__sbc_hit));
    uint8_t *miss = (uint8_t *)refl__calloc(al, S, 1); /* per sample: the ray meets no piece */
    uint8_t *links = (uint8_t *)refl__calloc(al, S, 1);
    nd->hits = (refl__sbc_hit **)refl__calloc(al, (size_t)P, sizeof(refl__sbc_hit *));
    nd->hit_count = (int *)refl__calloc(al, (size_t)P, sizeof(int));
    nd->ends = (refl_vec3 **)refl__calloc(al, (size_t)P, sizeof(refl_vec3 *));
    nd->end_count = (int *)refl__calloc(al, (size_t)P, sizeof(int));
    nd->sbc = (refl_sbc **)refl__calloc(al, (size_t)P * 6, sizeof(refl_sbc *));
    nd->dirs = (signed char **)refl__calloc(al, (size_t)P * 6, sizeof(signed char *));
    nd->face = b->face;
    nd->box = (float *)refl__calloc(al, (size_t)P * 6, sizeof(float));
    if (!rays || !valid || !normals || !met || !miss || !links || !nd->hits || !nd->hit_count || !nd->ends || !nd->end_count ||
        !nd->sbc || !nd->dirs || !nd->box) {
        nd->result = REFL_ERROR_OUT_OF_MEMORY;
    } else {
        for (f = 0; f < 6 && nd->result == REFL_OK; ++f) {
            refl_vec3 fw, rt, up;
            refl_sbc_desc d;
            refl__sbm_face_maps(b, nd->pos, f, rays, valid, normals, met, miss);
            refl__sbm_basis(f, &fw, &rt, &up);
            memset(&d, 0, sizeof d);
            d.error_px = b->error_px;
            d.widen = b->widen;
            d.width = d.height = b->face;
            /* W samples span (face + 2) / face of the 90-degree image: pixels beyond
               [0, face) are the overlap */
            d.view_proj = refl_mat4_mul(refl_mat4_perspective((float)(REFL__PI / 2.0), 1.0f, 1e-3f * b->diagonal,
                                                              4.0f * b->diagonal),
                                        refl_mat4_look_at(nd->pos, refl_v3_add(nd->pos, fw), up));
            d.allocator = *al;
            for (k = 0; k < P && nd->result == REFL_OK; ++k) {
                float *bx = nd->box + 6 * (size_t)k;
                int count = 0, e, c;
                if (f == 0)
                    for (c = 0; c < 3; ++c) {
                        bx[c] = INFINITY;
                        bx[3 + c] = -INFINITY;
                    }
                for (i = 0; i < S; ++i) {
                    const refl_sbc_ray *ry = &rays[(size_t)k * S + i];
                    const refl__sbc_hit *h = &met[(size_t)k * S + i];
                    /* the tail itself lies on every node's frustums' floor, the
                       reflector: a tenth of the way along stands for it */
                    refl_vec3 near = refl_v3_add(ry->tail, refl_v3_scale(refl_v3_sub(ry->head, ry->tail), 0.1f));
                    int *ends = &nd->end_count[k];
                    if (!valid[(size_t)k * S + i]) continue;
                    ++count;
                    if ((h->object >= 0 && refl__push(al, (void **)&nd->hits[k], &nd->hit_count[k], sizeof *h, h) < 0) ||
                        (b->check && valid[(size_t)k * S + i] == 1 &&
                         (refl__push(al, (void **)&nd->ends[k], ends, sizeof(refl_vec3), &near) < 0 ||
                          refl__push(al, (void **)&nd->ends[k], ends, sizeof(refl_vec3), &ry->head) < 0))) {
                        nd->result = REFL_ERROR_OUT_OF_MEMORY;
                        break;
                    }
                    for (e = 0; e < 2; ++e) {
                        const float *q = e ? &ry->head.x : &ry->tail.x;
                        for (c = 0; c < 3; ++c) {
                            bx[c] = REFL__MIN(bx[c], q[c]);
                            bx[3 + c] = REFL__MAX(bx[3 + c], q[c]);
                        }
                    }
                }
                if (count < 4) continue; /* no unit frustum: nothing to project with */
                {
                    signed char *dm = (signed char *)refl__calloc(al, S, 3);
                    nd->dirs[(size_t)k * 6 + (size_t)f] = dm;
                    if (!dm) {
                        nd->result = REFL_ERROR_OUT_OF_MEMORY;
                        break;
                    }
                    for (i = 0; i < S; ++i) {
                        const refl_sbc_ray *ry = &rays[(size_t)k * S + i];
                        refl_vec3 r = refl_v3_normalize(refl_v3_sub(ry->head, ry->tail));
                        if (valid[(size_t)k * S + i] != 1) continue;
                        dm[3 * i] = (signed char)lrintf(127.0f * r.x);
                        dm[3 * i + 1] = (signed char)lrintf(127.0f * r.y);
                        dm[3 * i + 2] = (signed char)lrintf(127.0f * r.z);
                    }
                }
                refl__sbm_links(rays + (size_t)k * S, valid + (size_t)k * S, normals + (size_t)k * S, W, links);
                d.links = links;
                nd->result = refl_sbc_build(rays + (size_t)k * S, valid + (size_t)k * S, W, W, &d,
                                            &nd->sbc[(size_t)k * 6 + (size_t)f]);
            }
        }
        /* grown by a quarter of its size, as runtime mode grows a group's box
           (cameras reach below the tails, ray lists past the heads): nothing
           outside projects */
        for (i = 0; i < 3 * (size_t)P; ++i) {
            float *bx = nd->box + 6 * (i / 3), g;
            size_t c = i % 3;
            if (!(bx[c] <= bx[3 + c])) continue;
            g = 0.25f * (bx[3 + c] - bx[c]) + 1e-4f * b->diagonal;
            bx[c] -= g;
            bx[3 + c] += g;
        }
    }
    refl__free(al, rays);
    refl__free(al, valid);
    refl__free(al, normals);
    refl__free(al, met);
    refl__free(al, miss);
    refl__free(al, links);
}

REFL_API void refl_sbc_morph_destroy(refl_sbc_morph *morph) {
    refl_allocator a;
    int i, k, n;
    if (!morph) return;
    a = morph->allocator;
    n = morph->n[0] * morph->n[1] * morph->n[2];
    for (i = 0; morph->nodes && i < n; ++i) {
        for (k = 0; morph->nodes[i].sbc && k < 6 * morph->piece_count; ++k) refl_sbc_destroy(morph->nodes[i].sbc[k]);
        refl__free(&a, morph->nodes[i].sbc);
        for (k = 0; morph->nodes[i].dirs && k < 6 * morph->piece_count; ++k) refl__free(&a, morph->nodes[i].dirs[k]);
        refl__free(&a, morph->nodes[i].dirs);
        refl__free(&a, morph->nodes[i].box);
        for (k = 0; morph->nodes[i].hits && k < morph->piece_count; ++k) refl__free(&a, morph->nodes[i].hits[k]);
        refl__free(&a, morph->nodes[i].hits);
        refl__free(&a, morph->nodes[i].hit_count);
        for (k = 0; morph->nodes[i].ends && k < morph->piece_count; ++k) refl__free(&a, morph->nodes[i].ends[k]);
        refl__free(&a, morph->nodes[i].ends);
        refl__free(&a, morph->nodes[i].end_count);
    }
    refl__free(&a, morph->nodes);
    refl__free(&a, morph->cell_ok);
    refl__free(&a, morph->piece);
    refl__free(&a, morph->pos);
    refl__free(&a, morph->nrm);
    refl__free(&a, morph->index_copy);
    refl_bvh_destroy(morph->bvh);
    refl__free(&a, morph);
}

/* The reflector in world space, its pieces, and its BVH. */
static refl_result refl__sbm_reflector(refl_sbc_morph *m, const refl_scene *scene, int object) {
    const refl_object *obj = &scene->objects[object];
    const refl_mesh *mesh = scene->meshes[obj->mesh];
    const refl_allocator *al = &m->allocator;
    refl_mat4 nm = refl__normal_matrix(obj->transform);
    int V = mesh->vertex_count, T = mesh->triangle_count, i, *parent, *label;
    refl_scene one;
    refl_result r;
    m->pos = (float *)refl__calloc(al, (size_t)V, 3 * sizeof(float));
    m->nrm = (float *)refl__calloc(al, (size_t)V, 3 * sizeof(float));
    m->piece = (int *)refl__calloc(al, (size_t)T, sizeof(int));
    m->index_copy = (uint32_t *)refl__calloc(al, (size_t)T, 3 * sizeof(uint32_t));
    parent = (int *)refl__calloc(al, (size_t)V, sizeof(int));
    label = (int *)refl__calloc(al, (size_t)V, sizeof(int));
    if (!m->pos || !m->nrm || !m->piece || !m->index_copy || !parent || !label) {
        refl__free(al, parent);
        refl__free(al, label);
        return REFL_ERROR_OUT_OF_MEMORY;
    }
    memcpy(m->index_copy, mesh->indices, (size_t)T * 3 * sizeof(uint32_t));
    m->indices = m->index_copy;
    m->triangle_count = T;
    m->box_lo = refl_v3(INFINITY, INFINITY, INFINITY);
    m->box_hi = refl_v3(-INFINITY, -INFINITY, -INFINITY);
    for (i = 0; i < V; ++i) {
        const float *p = mesh->positions + 3 * (size_t)i, *n = mesh->normals + 3 * (size_t)i;
        refl_vec3 w = refl_mat4_point(obj->transform, refl_v3(p[0], p[1], p[2]));
        refl_vec3 wn = refl_v3_normalize(refl_mat4_dir(nm, refl_v3(n[0], n[1], n[2])));
        m->pos[3 * (size_t)i] = w.x;
        m->pos[3 * (size_t)i + 1] = w.y;
        m->pos[3 * (size_t)i + 2] = w.z;
        m->nrm[3 * (size_t)i] = wn.x;
        m->nrm[3 * (size_t)i + 1] = wn.y;
        m->nrm[3 * (size_t)i + 2] = wn.z;
        m->box_lo = refl__v3_min(m->box_lo, w);
        m->box_hi = refl__v3_max(m->box_hi, w);
        parent[i] = i;
        label[i] = -1;
    }
    /* pieces: triangles joined through shared vertices, numbered by first triangle */
    for (i = 0; i < T; ++i) {
        int a = refl__sbc_root(parent, (int)m->indices[3 * i]), k;
        for (k = 1; k < 3; ++k) {
            int c = refl__sbc_root(parent, (int)m->indices[3 * i + k]);
            if (c < a) { parent[a] = c; a = c; } else parent[c] = a;
        }
    }
    for (i = 0; i < T; ++i) {
        int root = refl__sbc_root(parent, (int)m->indices[3 * i]);
        if (label[root] < 0) label[root] = m->piece_count++;
        m->piece[i] = label[root];
    }
    refl__free(al, parent);
    refl__free(al, label);
    /* the BVH of a scene holding the reflector alone (it copies the triangles) */
    one = *scene;
    one.objects = (refl_object *)obj;
    one.object_count = 1;
    r = refl_bvh_build(&one, al, &m->bvh);
    return r;
}

/* The paper's construction check: a tail or head of a node's unextended
   ray (of one piece) is ambiguous for a cell when another node of one of
   the cell's tetrahedra holding both does not project it into the piece
   (two corners share a tetrahedron when one lies at or above the other
   along every axis). Counted over every cell clear of the reflector and
   every such ordered pair of its corners; the ends are freed after. */
static void refl__sbm_check(refl_sbc_morph *m) {
    int i, j, k, a, c, piece, e;
    const refl_allocator *al = &m->allocator;
    for (k = 0; k + 1 < m->n[2]; ++k)
        for (j = 0; j + 1 < m->n[1]; ++j)
            for (i = 0; i + 1 < m->n[0]; ++i) {
                if (!m->cell_ok[(k * (m->n[1] - 1) + j) * (m->n[0] - 1) + i]) continue;
                for (a = 0; a < 8; ++a)
                    for (c = 0; c < 8; ++c) {
                        const refl__sbm_node *na = &m->nodes[((k + (a >> 2)) * m->n[1] + j + (a >> 1 & 1)) * m->n[0] + i + (a & 1)];
                        const refl__sbm_node *nc = &m->nodes[((k + (c >> 2)) * m->n[1] + j + (c >> 1 & 1)) * m->n[0] + i + (c & 1)];
                        if (a == c || ((a & c) != a && (a & c) != c)) continue; /* not comparable: no shared tetrahedron */
                        for (piece = 0; piece < m->piece_count; ++piece)
                            for (e = 0; e < na->end_count[piece]; ++e) {
                                refl_vec3 q;
                                m->stats.ends_checked++;
                                if (!refl__sbm_node_project(nc, piece, na->ends[piece][e], &q)) m->stats.ambiguous_ends++;
                            }
                    }
            }
    for (i = 0; i < m->n[0] * m->n[1] * m->n[2]; ++i)
        for (piece = 0; m->nodes[i].ends && piece < m->piece_count; ++piece) {
            refl__free(al, m->nodes[i].ends[piece]);
            m->nodes[i].ends[piece] = NULL;
            m->nodes[i].end_count[piece] = 0;
        }
}

REFL_API refl_result refl_sbc_morph_build(const refl_scene *scene, int object, const refl_sbc_morph_desc *desc,
                                          refl_sbc_morph **out_morph) {
    refl_sbc_morph_desc d;
    refl_sbc_morph *m;
    refl__sbm_build b;
    refl_vec3 lo, hi, ext;
    rast_context *rc = NULL;
    rast_context_desc cd;
    refl_result r;
    double t0 = refl__now_ms();
    int i, j, k, count, cells;
    if (out_morph) *out_morph = NULL;
    if (!scene || !out_morph || object < 0 || object >= scene->object_count || !scene->objects)
        return REFL_ERROR_INVALID_ARGUMENT;
    {
        int mi = scene->objects[object].mesh;
        const refl_mesh *mesh;
        if (mi < 0 || mi >= scene->mesh_count || !scene->meshes || !scene->meshes[mi]) return REFL_ERROR_INVALID_ARGUMENT;
        mesh = scene->meshes[mi];
        if (mesh->triangle_count < 1 || mesh->vertex_count < 3 || !mesh->positions || !mesh->normals || !mesh->indices)
            return REFL_ERROR_INVALID_ARGUMENT;
    }
    if (desc) d = *desc;
    else memset(&d, 0, sizeof d);
    for (k = 0; k < 3; ++k) {
        if (!d.nodes[k]) d.nodes[k] = 4;
        if (d.nodes[k] < 2 || d.nodes[k] > 64) return REFL_ERROR_INVALID_ARGUMENT;
    }
    if (!d.face_size) d.face_size = 128;
    if (d.face_size < 4 || d.face_size > 1024) return REFL_ERROR_INVALID_ARGUMENT;
    if (!(d.margin >= 0.0f && d.margin <= 1e6f) || !(d.error_px >= 0.0f && d.error_px <= 1e6f) ||
        !(d.widen <= 1e6f) || d.widen != d.widen)
        return REFL_ERROR_INVALID_ARGUMENT;
    if (d.margin == 0.0f) d.margin = 0.5f;
    if (d.error_px == 0.0f) d.error_px = 1.0f;
    if (d.widen == 0.0f) d.widen = 0.1f;
    if (d.widen < 0.0f) d.widen = 0.0f;
    if (!d.extend_rings) d.extend_rings = 1;
    if (d.extend_rings < 0) d.extend_rings = 0;
    if (d.extend_rings > 64) return REFL_ERROR_INVALID_ARGUMENT;
    {
        const float *a = &d.region_lo.x, *c = &d.region_hi.x;
        int zero = 1;
        for (k = 0; k < 3; ++k) {
            if (!refl__isfinite(a[k]) || !refl__isfinite(c[k])) return REFL_ERROR_INVALID_ARGUMENT;
            zero &= a[k] == 0.0f && c[k] == 0.0f;
        }
        for (k = 0; !zero && k < 3; ++k)
            if (!(a[k] < c[k])) return REFL_ERROR_INVALID_ARGUMENT;
        if (zero) d.region_lo = d.region_hi = refl_v3(NAN, NAN, NAN);
    }
    m = (refl_sbc_morph *)refl__calloc(&d.allocator, 1, sizeof *m);
    if (!m) return REFL_ERROR_OUT_OF_MEMORY;
    m->allocator = d.allocator;
    m->object = object;
    for (k = 0; k < 3; ++k) m->n[k] = d.nodes[k];
    memset(&b, 0, sizeof b);
    r = refl__sbm_reflector(m, scene, object);
    /* a map per piece and face at every node: a triangle soup would need one per triangle */
    if (r == REFL_OK && m->piece_count > REFL__SBM_PIECES) r = REFL_ERROR_UNSUPPORTED;
    if (r == REFL_OK) r = refl_bvh_build(scene, &m->allocator, &b.scene_bvh);
    if (r != REFL_OK) goto fail;
    /* the grid */
    if (d.region_lo.x == d.region_lo.x) {
        lo = d.region_lo;
        hi = d.region_hi;
    } else {
        float g = d.margin * refl_v3_length(refl_v3_sub(m->box_hi, m->box_lo));
        lo = refl_v3_sub(m->box_lo, refl_v3(g, g, g));
        hi = refl_v3_add(m->box_hi, refl_v3(g, g, g));
    }
    ext = refl_v3_sub(hi, lo);
    m->lo = lo;
    m->step = refl_v3(ext.x / (float)(m->n[0] - 1), ext.y / (float)(m->n[1] - 1), ext.z / (float)(m->n[2] - 1));
    if (!(m->step.x > 0.0f && m->step.y > 0.0f && m->step.z > 0.0f)) {
        r = REFL_ERROR_INVALID_ARGUMENT; /* a degenerate reflector box with no margin */
        goto fail;
    }
    count = m->n[0] * m->n[1] * m->n[2];
    cells = (m->n[0] - 1) * (m->n[1] - 1) * (m->n[2] - 1);
    m->nodes = (refl__sbm_node *)refl__calloc(&m->allocator, (size_t)count, sizeof(refl__sbm_node));
    m->cell_ok = (uint8_t *)refl__calloc(&m->allocator, (size_t)cells, 1);
    if (!m->nodes || !m->cell_ok) {
        r = REFL_ERROR_OUT_OF_MEMORY;
        goto fail;
    }
    for (k = 0; k < m->n[2]; ++k)
        for (j = 0; j < m->n[1]; ++j)
            for (i = 0; i < m->n[0]; ++i)
                refl_sbc_morph_node(m, i, j, k, &m->nodes[(k * m->n[1] + j) * m->n[0] + i].pos);
    for (k = 0; k + 1 < m->n[2]; ++k)
        for (j = 0; j + 1 < m->n[1]; ++j)
            for (i = 0; i + 1 < m->n[0]; ++i) {
                refl_vec3 a = m->nodes[(k * m->n[1] + j) * m->n[0] + i].pos;
                refl_vec3 c = m->nodes[((k + 1) * m->n[1] + j + 1) * m->n[0] + i + 1].pos;
                int overlap = a.x < m->box_hi.x && c.x > m->box_lo.x && a.y < m->box_hi.y && c.y > m->box_lo.y &&
                              a.z < m->box_hi.z && c.z > m->box_lo.z;
                int di, dj, dk, cell = (k * (m->n[1] - 1) + j) * (m->n[0] - 1) + i;
                if (overlap) continue;
                m->cell_ok[cell] = 1;
                m->stats.tetrahedra += 6;
                for (dk = 0; dk < 2; ++dk)
                    for (dj = 0; dj < 2; ++dj)
                        for (di = 0; di < 2; ++di) m->nodes[((k + dk) * m->n[1] + j + dj) * m->n[0] + i + di].built = 1;
            }
    /* the scene box and diagonal as runtime mode grows them */
    refl_scene_bounds(scene, &lo, &hi);
    ext = refl_v3_add(refl_v3_scale(refl_v3_sub(hi, lo), 0.01f), refl_v3(1e-4f, 1e-4f, 1e-4f));
    b.scene_lo = refl_v3_sub(lo, ext);
    b.scene_hi = refl_v3_add(hi, ext);
    b.diagonal = refl_v3_length(refl_v3_sub(b.scene_hi, b.scene_lo));
    b.m = m;
    b.scene = scene;
    b.face = d.face_size;
    b.rings = d.extend_rings;
    b.error_px = d.error_px;
    b.widen = d.widen;
    b.check = d.check_ambiguous;
    memset(&cd, 0, sizeof cd);
    cd.num_threads = d.threads;
    cd.allocator.alloc = m->allocator.alloc;
    cd.allocator.free = m->allocator.free;
    cd.allocator.user = m->allocator.user;
    r = refl__result_from_rast(rast_context_create(&cd, &rc));
    if (r != REFL_OK) goto fail;
    {
        /* the built nodes' indices, as jobs */
        int *list = (int *)refl__calloc(&m->allocator, (size_t)count, sizeof(int)), nb = 0;
        if (!list) {
            r = REFL_ERROR_OUT_OF_MEMORY;
            goto fail;
        }
        for (i = 0; i < count; ++i)
            if (m->nodes[i].built) list[nb++] = i;
        b.list = list;
        rast_run_jobs(rc, nb, refl__sbm_build_node, &b);
        refl__free(&m->allocator, list);
    }
    for (i = 0; i < count && r == REFL_OK; ++i) {
        if (!m->nodes[i].built) continue;
        m->stats.nodes_built++;
        if (m->nodes[i].result != REFL_OK) r = m->nodes[i].result;
        for (k = 0; m->nodes[i].sbc && k < 6 * m->piece_count; ++k) {
            refl_sbc_stats st;
            if (!m->nodes[i].sbc[k]) continue;
            refl_sbc_get_stats(m->nodes[i].sbc[k], &st);
            m->stats.sbcs++;
            m->stats.bytes += 3 * (long long)(d.face_size + 2) * (long long)(d.face_size + 2); /* its dirs */
            m->stats.rays += st.rays;
            m->stats.pinhole_leaves += st.pinhole_leaves;
            m->stats.ray_leaves += st.ray_leaves;
            m->stats.bytes += st.bytes;
        }
        m->stats.bytes += (long long)(12 * m->piece_count) * (long long)sizeof(float *);
        for (k = 0; m->nodes[i].hit_count && k < m->piece_count; ++k)
            m->stats.bytes += (long long)m->nodes[i].hit_count[k] * (long long)sizeof(refl__sbc_hit);
    }
    if (r != REFL_OK) goto fail;
    if (d.check_ambiguous) refl__sbm_check(m);
    rast_context_destroy(rc);
    refl_bvh_destroy(b.scene_bvh);
    {
        long long tn = 0, tt = 0;
        refl_bvh_stats(m->bvh, &tn, &tt);
        m->stats.bytes += (long long)sizeof *m + (long long)count * (long long)sizeof(refl__sbm_node) + cells +
                          (long long)m->triangle_count * (long long)(sizeof(int) + 3 * sizeof(uint32_t)) +
                          (long long)scene->meshes[scene->objects[object].mesh]->vertex_count * 6 *
                              (long long)sizeof(float) +
                          tt * 44 + tn * 32; /* the BVH: about its triangles' and nodes' sizes */
    }
    m->stats.nodes = count;
    m->stats.pieces = m->piece_count;
    m->stats.ms_build = refl__now_ms() - t0;
    *out_morph = m;
    return REFL_OK;
fail:
    if (rc) rast_context_destroy(rc);
    refl_bvh_destroy(b.scene_bvh);
    refl_sbc_morph_destroy(m);
    return r;
}

REFL_API void refl_sbc_morph_get_stats(const refl_sbc_morph *morph, refl_sbc_morph_stats *out) {
    if (!out) return;
    if (!morph) memset(out, 0, sizeof *out);
    else *out = morph->stats;
}

/* Where points projecting into piece `piece` for the eye may lie: the
   tetrahedron's nodes' boxes; empty (lo above hi) when none of them saw
   the piece. */
static void refl__sbm_piece_box(const refl_sbc_morph *m, refl_vec3 eye, int piece, refl_vec3 *lo, refl_vec3 *hi) {
    float bx[6] = {INFINITY, INFINITY, INFINITY, -INFINITY, -INFINITY, -INFINITY}, w[4];
    int nodes[4], k, c;
    if (refl_sbc_morph_locate(m, eye, nodes, w) >= 0)
        for (k = 0; k < 4; ++k) {
            const float *nb = m->nodes[nodes[k]].box;
            if (!(w[k] > 0.0f) || !nb) continue;
            for (c = 0; c < 3; ++c) {
                bx[c] = REFL__MIN(bx[c], nb[6 * piece + c]);
                bx[3 + c] = REFL__MAX(bx[3 + c], nb[6 * piece + 3 + c]);
            }
        }
    *lo = refl_v3(bx[0], bx[1], bx[2]);
    *hi = refl_v3(bx[3], bx[4], bx[5]);
}

/* The hits of piece `piece` at the eye's tetrahedron's nodes (of positive
   weight), appended to out (room for refl__sbc_hit_total's count); how many. */
static int refl__sbm_tet_hits(const refl_sbc_morph *m, refl_vec3 eye, int piece, refl__sbc_hit *out) {
    int nodes[4], k, n = 0;
    float w[4];
    if (refl_sbc_morph_locate(m, eye, nodes, w) < 0) return 0;
    for (k = 0; k < 4; ++k) {
        const refl__sbm_node *nd = &m->nodes[nodes[k]];
        if (!(w[k] > 0.0f) || !nd->hit_count || !nd->hit_count[piece]) continue;
        if (out) memcpy(out + n, nd->hits[piece], (size_t)nd->hit_count[piece] * sizeof *out);
        n += nd->hit_count[piece];
    }
    return n;
}

REFL_API int refl_sbc_morph_object(const refl_sbc_morph *morph) { return morph ? morph->object : -1; }

REFL_API int refl_sbc_morph_node(const refl_sbc_morph *morph, int i, int j, int k, refl_vec3 *position) {
    if (!morph || i < 0 || j < 0 || k < 0 || i >= morph->n[0] || j >= morph->n[1] || k >= morph->n[2]) return 0;
    if (position)
        *position = refl_v3(morph->lo.x + (float)i * morph->step.x, morph->lo.y + (float)j * morph->step.y,
                            morph->lo.z + (float)k * morph->step.z);
    return 1;
}

REFL_API int refl_sbc_morph_locate(const refl_sbc_morph *morph, refl_vec3 eye, int nodes[4], float weights[4]) {
    const float *e = &eye.x, *lo, *st;
    double f[3];
    int c[3], ord[3] = {0, 1, 2}, k, t, node, perm;
    if (!morph || !nodes || !weights) return -1;
    lo = &morph->lo.x;
    st = &morph->step.x;
    for (k = 0; k < 3; ++k) {
        double g = ((double)e[k] - (double)lo[k]) / (double)st[k], r = floor(g + 0.5);
        if (!(g >= -1e-5 && g <= (double)(morph->n[k] - 1) + 1e-5)) return -1; /* outside, or NaN */
        if (fabs(g - r) < 1e-5) g = r;                                         /* on a node's plane */
        c[k] = (int)REFL__MIN(floor(g), (double)(morph->n[k] - 2));
        c[k] = REFL__MAX(c[k], 0);
        f[k] = g - (double)c[k];
    }
    if (!morph->cell_ok[(c[2] * (morph->n[1] - 1) + c[1]) * (morph->n[0] - 1) + c[0]]) return -1;
    /* axes by falling local coordinate (ties keep x, y, z order) */
    for (k = 0; k < 2; ++k)
        for (t = 0; t < 2 - k; ++t)
            if (f[ord[t + 1]] > f[ord[t]]) {
                int s = ord[t];
                ord[t] = ord[t + 1];
                ord[t + 1] = s;
            }
    node = (c[2] * morph->n[1] + c[1]) * morph->n[0] + c[0];
    nodes[0] = node;
    for (k = 0; k < 3; ++k) {
        static const int unit[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
        const int *u = unit[ord[k]];
        node += (u[2] * morph->n[1] + u[1]) * morph->n[0] + u[0];
        nodes[k + 1] = node;
    }
    weights[0] = (float)(1.0 - f[ord[0]]);
    weights[1] = (float)(f[ord[0]] - f[ord[1]]);
    weights[2] = (float)(f[ord[1]] - f[ord[2]]);
    weights[3] = (float)f[ord[2]];
    perm = ord[0] * 2 + (ord[1] > ord[2]); /* which of the six orders */
    return ((c[2] * (morph->n[1] - 1) + c[1]) * (morph->n[0] - 1) + c[0]) * 6 + perm;
}

REFL_API int refl_sbc_morph_piece_at(const refl_sbc_morph *morph, refl_vec3 origin, refl_vec3 dir) {
    refl_hit h;
    int front;
    if (!morph) return -1;
    if (!refl_bvh_intersect(morph->bvh, origin, dir, 0.0f, INFINITY, &h)) return -1;
    refl__sbc_hit_normal(morph, &h, dir, &front);
    return front ? morph->piece[h.triangle] : -1;
}

/* p at one node: the piece's face SBCs, the face owning the answer first. */
/* Whether p lies ahead of first point q along the unextended ray of the
   node's sample that q lands on (when it has one): runtime mode's check
   (sbc_project.c, refl__sb_place), since a leaf's frustum reaches a little
   behind the reflector and an extrapolated ring's, at a silhouette, folds
   back over it. */
static int refl__sbm_ahead(const refl__sbm_node *nd, int piece, refl_vec3 p, refl_vec3 q) {
    refl_vec3 v = refl_v3_sub(q, nd->pos), fw, rt, up;
    int f = refl__sbm_face_of(v), W = nd->face + 2, i, j;
    const signed char *dm = nd->dirs[(size_t)piece * 6 + (size_t)f], *dr;
    float w, x, y;
    if (!dm) return 1;
    refl__sbm_basis(f, &fw, &rt, &up);
    w = refl_v3_dot(v, fw);
    if (!(w > 0.0f)) return 1;
    x = refl_v3_dot(v, rt) / w;
    y = refl_v3_dot(v, up) / w;
    i = (int)REFL__CLAMP(floorf((x + 1.0f) * 0.5f * (float)nd->face) + 1.0f, 0.0f, (float)(W - 1));
    j = (int)REFL__CLAMP(floorf((1.0f - y) * 0.5f * (float)nd->face) + 1.0f, 0.0f, (float)(W - 1));
    dr = dm + 3 * ((size_t)j * (size_t)W + (size_t)i);
    if (!dr[0] && !dr[1] && !dr[2]) return 1;
    return refl_v3_dot(refl_v3_sub(p, q), refl_v3((float)dr[0], (float)dr[1], (float)dr[2])) > 0.0f;
}

/* Whether the node has the piece's cameras and p lies in their box. */
static int refl__sbm_node_holds(const refl__sbm_node *nd, int piece, refl_vec3 p) {
    const float *bx;
    if (!nd->built || !nd->sbc) return 0;
    bx = nd->box + 6 * (size_t)piece;
    return p.x >= bx[0] && p.x <= bx[3] && p.y >= bx[1] && p.y <= bx[4] && p.z >= bx[2] && p.z <= bx[5];
}

static int refl__sbm_node_project(const refl__sbm_node *nd, int piece, refl_vec3 p,
                                  refl_vec3 *first) {
    refl_vec3 q, keep = {0.0f, 0.0f, 0.0f};
    float z;
    int f, got = 0;
    if (!refl__sbm_node_holds(nd, piece, p)) return 0;
    for (f = 0; f < 6; ++f) {
        const refl_sbc *s = nd->sbc[(size_t)piece * 6 + (size_t)f];
        if (!s || !refl_sbc_project(s, p, &q, &z) || !refl__sbm_ahead(nd, piece, p, q)) continue;
        if (refl__sbm_face_of(refl_v3_sub(q, nd->pos)) == f) {
            *first = q;
            return 1;
        }
        if (!got) keep = q;
        got = 1;
    }
    *first = keep;
    return got;
}

/* p at one node in each of `sheets` sheets of the piece's face SBCs
   (refl_sbc_project_sheets), a sheet choosing among the faces as
   refl__sbm_node_project does: the mask of the sheets with an image. */
static int refl__sbm_node_sheets(const refl__sbm_node *nd, int piece, refl_vec3 p, int sheets, refl_vec3 *first) {
    int f, k, mask = 0, own = 0;
    if (!refl__sbm_node_holds(nd, piece, p)) return 0;
    for (f = 0; f < 6; ++f) {
        const refl_sbc *s = nd->sbc[(size_t)piece * 6 + (size_t)f];
        refl_vec3 q[REFL_SBC_SHEETS];
        float z[REFL_SBC_SHEETS];
        int got = s ? refl_sbc_project_sheets(s, p, sheets, q, z) : 0;
        for (k = 0; k < sheets; ++k) {
            if (!(got >> k & 1) || (own >> k & 1) || !refl__sbm_ahead(nd, piece, p, q[k])) continue;
            if (refl__sbm_face_of(refl_v3_sub(q[k], nd->pos)) == f) {
                own |= 1 << k;
                first[k] = q[k];
            } else if (!(mask >> k & 1)) {
                first[k] = q[k];
            }
            mask |= 1 << k;
        }
    }
    return mask;
}

/* The most sheets the piece's face SBCs at the nodes of positive weight have. */
static int refl__sbm_piece_sheets(const refl_sbc_morph *m, const int nodes[4], const float w[4], int piece) {
    int k, f, sheets = 1;
    for (k = 0; k < 4; ++k) {
        const refl__sbm_node *nd = &m->nodes[nodes[k]];
        if (!(w[k] > 0.0f) || !nd->built || !nd->sbc) continue;
        for (f = 0; f < 6; ++f) {
            refl_sbc_stats st;
            if (!nd->sbc[(size_t)piece * 6 + (size_t)f]) continue;
            refl_sbc_get_stats(nd->sbc[(size_t)piece * 6 + (size_t)f], &st);
            sheets = REFL__MAX(sheets, REFL__MIN(st.sheets, REFL_SBC_SHEETS));
        }
    }
    return sheets;
}

/* Blends slots (first, dist) of the nodes in mask with weights w: 1, or 0
   when a node of positive weight is missing (ambiguous when any is there). */
static int refl__sbm_blend(const float *slot, int mask, const float w[4], refl_vec3 *first, float *dist,
                           int *ambiguous) {
    double f[3] = {0.0, 0.0, 0.0}, dd = 0.0;
    int k, need = 0;
    for (k = 0; k < 4; ++k)
        if (w[k] > 0.0f) need |= 1 << k;
    if (ambiguous) *ambiguous = (need & mask) != 0 && (need & mask) != need;
    if ((need & mask) != need || !need) return 0;
    for (k = 0; k < 4; ++k) {
        if (!(need >> k & 1)) continue;
        f[0] += (double)w[k] * slot[4 * k];
        f[1] += (double)w[k] * slot[4 * k + 1];
        f[2] += (double)w[k] * slot[4 * k + 2];
        dd += (double)w[k] * slot[4 * k + 3];
    }
    *first = refl_v3((float)f[0], (float)f[1], (float)f[2]);
    *dist = (float)dd;
    return 1;
}

/* p at the four nodes into slot (4 floats each); the mask of those projecting. */
static int refl__sbm_project4(const refl_sbc_morph *m, const int nodes[4], const float w[4], int piece, refl_vec3 p,
                              float *slot) {
    int k, mask = 0;
    for (k = 0; k < 4; ++k) {
        refl_vec3 q;
        if (!(w[k] > 0.0f) || !refl__sbm_node_project(&m->nodes[nodes[k]], piece, p, &q)) continue;
        slot[4 * k] = q.x;
        slot[4 * k + 1] = q.y;
        slot[4 * k + 2] = q.z;
        slot[4 * k + 3] = refl_v3_length(refl_v3_sub(p, q));
        mask |= 1 << k;
    }
    return mask;
}

/* p at the four nodes in each of `sheets` sheets: node k's sheet j in
   slot[4 * (k * REFL_SBC_SHEETS + j)] (first, dist), masks[k] its sheets
   with an image. */
static void refl__sbm_project4_sheets(const refl_sbc_morph *m, const int nodes[4], const float w[4], int piece,
                                      refl_vec3 p, int sheets, float *slot, int masks[4]) {
    int k, j;
    for (k = 0; k < 4; ++k) {
        refl_vec3 q[REFL_SBC_SHEETS];
        masks[k] = w[k] > 0.0f ? refl__sbm_node_sheets(&m->nodes[nodes[k]], piece, p, sheets, q) : 0;
        for (j = 0; j < sheets; ++j) {
            float *sl = slot + 4 * ((size_t)k * REFL_SBC_SHEETS + (size_t)j);
            if (!(masks[k] >> j & 1)) continue;
            sl[0] = q[j].x;
            sl[1] = q[j].y;
            sl[2] = q[j].z;
            sl[3] = refl_v3_length(refl_v3_sub(p, q[j]));
        }
    }
}

/* Sheet `sheet` of those, blended as refl__sbm_blend does: each node's
   image in it, else one a fold away (refl__sbc_sheet_image; *across then:
   the sheets meet at the fold). */
static int refl__sbm_blend_sheet(const float *slot, const int masks[4], const float w[4], int sheet, refl_vec3 *first,
                                 float *dist, int *across, int *ambiguous) {
    float pick[16];
    int k, mask = 0;
    *across = 0;
    for (k = 0; k < 4; ++k) {
        int a, image = refl__sbc_sheet_image(masks[k], sheet, &a);
        if (image < 0) continue;
        memcpy(pick + 4 * k, slot + 4 * ((size_t)k * REFL_SBC_SHEETS + (size_t)image), 4 * sizeof(float));
        mask |= 1 << k;
        if (w[k] > 0.0f) *across |= a;
    }
    return refl__sbm_blend(pick, mask, w, first, dist, ambiguous);
}

REFL_API int refl_sbc_morph_project_node(const refl_sbc_morph *morph, int i, int j, int k, int piece, refl_vec3 p,
                                         refl_vec3 *first, float *dist) {
    const refl__sbm_node *nd;
    refl_vec3 q;
    if (!morph || piece < 0 || piece >= morph->piece_count || !refl_sbc_morph_node(morph, i, j, k, NULL)) return 0;
    nd = &morph->nodes[(k * morph->n[1] + j) * morph->n[0] + i];
    if (!refl__sbm_node_project(nd, piece, p, &q)) return 0;
    if (first) *first = q;
    if (dist) *dist = refl_v3_length(refl_v3_sub(p, q));
    return 1;
}

REFL_API int refl_sbc_morph_project(const refl_sbc_morph *morph, refl_vec3 eye, int piece, refl_vec3 p,
                                    refl_vec3 *first, float *dist, int *ambiguous) {
    int nodes[4], mask;
    float w[4], slot[16], dd;
    refl_vec3 f;
    if (ambiguous) *ambiguous = 0;
    if (!morph || piece < 0 || piece >= morph->piece_count || refl_sbc_morph_locate(morph, eye, nodes, w) < 0)
        return 0;
    mask = refl__sbm_project4(morph, nodes, w, piece, p, slot);
    if (!refl__sbm_blend(slot, mask, w, &f, &dd, ambiguous)) return 0;
    if (first) *first = f;
    if (dist) *dist = dd;
    return 1;
}

REFL_API int refl_sbc_morph_sheets(const refl_sbc_morph *morph, refl_vec3 eye, int piece) {
    int nodes[4];
    float w[4];
    if (!morph || piece < 0 || piece >= morph->piece_count || refl_sbc_morph_locate(morph, eye, nodes, w) < 0) return 0;
    return refl__sbm_piece_sheets(morph, nodes, w, piece);
}

REFL_API int refl_sbc_morph_project_sheet(const refl_sbc_morph *morph, refl_vec3 eye, int piece, int sheet, refl_vec3 p,
                                          refl_vec3 *first, float *dist, int *across) {
    int nodes[4], masks[4], sheets, a;
    float w[4], slot[4 * 4 * REFL_SBC_SHEETS], dd;
    refl_vec3 f;
    if (across) *across = 0;
    if (!morph || piece < 0 || piece >= morph->piece_count || refl_sbc_morph_locate(morph, eye, nodes, w) < 0)
        return 0;
    sheets = refl__sbm_piece_sheets(morph, nodes, w, piece);
    if (sheet < 0 || sheet >= sheets) return 0;
    refl__sbm_project4_sheets(morph, nodes, w, piece, p, sheets, slot, masks);
    if (!refl__sbm_blend_sheet(slot, masks, w, sheet, &f, &dd, &a, NULL)) return 0;
    if (first) *first = f;
    if (dist) *dist = dd;
    if (across) *across = a;
    return 1;
}

REFL_API refl_result refl_sbc_morph_cache_create(const refl_allocator *a, refl_sbc_morph_cache **out_cache) {
    refl_sbc_morph_cache *c;
    refl_allocator al = refl__allocator(a);
    if (!out_cache) return REFL_ERROR_INVALID_ARGUMENT;
    *out_cache = c = (refl_sbc_morph_cache *)refl__calloc(&al, 1, sizeof *c);
    if (!c) return REFL_ERROR_OUT_OF_MEMORY;
    c->allocator = al;
    c->tet = -1;
    return REFL_OK;
}

REFL_API void refl_sbc_morph_cache_destroy(refl_sbc_morph_cache *cache) {
    refl_allocator a;
    if (!cache) return;
    a = cache->allocator;
    refl__free(&a, cache->slot);
    refl__free(&a, cache->ok);
    refl__free(&a, cache);
}

REFL_API refl_result refl_sbc_morph_project_points(const refl_sbc_morph *morph, refl_vec3 eye, int piece,
                                                   const float *points, int count, refl_sbc_morph_cache *cache,
                                                   refl_vec3 *first, float *dist, uint8_t *status,
                                                   long long *ambiguous) {
    int nodes[4], tet, i, fresh;
    float w[4], local[16];
    long long amb = 0;
    if (ambiguous) *ambiguous = 0;
    if (!morph || count < 0 || (count > 0 && (!points || !first || !dist || !status)) || piece < 0 ||
        piece >= morph->piece_count)
        return REFL_ERROR_INVALID_ARGUMENT;
    tet = refl_sbc_morph_locate(morph, eye, nodes, w);
    if (tet < 0) return REFL_ERROR_INVALID_ARGUMENT;
    fresh = !cache || cache->tet != tet || cache->piece != piece || cache->count != count || cache->points != points;
    if (cache && fresh) {
        if (count > cache->cap) {
            refl__free(&cache->allocator, cache->slot);
            refl__free(&cache->allocator, cache->ok);
            cache->cap = 0;
            cache->slot = (float *)refl__calloc(&cache->allocator, (size_t)count, 16 * sizeof(float));
            cache->ok = (uint8_t *)refl__calloc(&cache->allocator, (size_t)count, 1);
            if (!cache->slot || !cache->ok) {
                cache->tet = -1;
                return REFL_ERROR_OUT_OF_MEMORY;
            }
            cache->cap = count;
        }
        cache->tet = -1; /* valid again only once filled */
    }
    for (i = 0; i < count; ++i) {
        float *slot = cache ? cache->slot + 16 * (size_t)i : local;
        int mask, a = 0;
        if (fresh) {
            /* every node of the tetrahedron, weighed or not: the cache serves the whole tetrahedron */
            static const float all[4] = {1.0f, 1.0f, 1.0f, 1.0f};
            const float *pp = points + 3 * (size_t)i;
            mask = refl__sbm_project4(morph, nodes, cache ? all : w, piece, refl_v3(pp[0], pp[1], pp[2]), slot);
            if (cache) cache->ok[i] = (uint8_t)mask;
        } else {
            mask = cache->ok[i];
        }
        status[i] = (uint8_t)refl__sbm_blend(slot, mask, w, &first[i], &dist[i], &a);
        if (a) status[i] = 2;
        amb += a;
    }
    if (cache && fresh) {
        cache->tet = tet;
        cache->piece = piece;
        cache->count = count;
        cache->points = points;
    }
    if (ambiguous) *ambiguous = amb;
    return REFL_OK;
}

/* ---- GL hook (gl_hooks.c; docs/gl.md, "SBC morph grid") ---------------------------
   The eye's tetrahedron for one piece: its four weights, and per node of
   positive weight its position, the piece's box there, its face SBCs (each
   a whole SBC block, refl_gl_pack_sbc) and the face maps of its unextended
   rays' directions (refl__sbm_ahead's check). A node of no weight, not
   built or without the piece's cameras has offset -1 (it projects
   nothing, as refl__sbm_node_project). */
/* The texel offsets (from the block's header) of a node's parts, laid out
   in order: node header (7 texels), the faces' SBC blocks, the faces'
   direction maps (W x W texels each, W = face + 2). */
static long long refl__sbm_gl_node(refl__gl_out *o, const refl__sbm_node *nd, int piece) {
    long long at = o->n / 4, sbc_at[6], dir_at[6], next, need;
    int f, W = nd->face + 2, i;
    const float *bx = nd->box + 6 * (size_t)piece;
    next = at + 7;
    for (f = 0; f < 6; ++f) {
        const refl_sbc *s = nd->sbc[(size_t)piece * 6 + (size_t)f];
        sbc_at[f] = -1;
        if (!s) continue;
        if ((need = refl_gl_pack_sbc(s, NULL, 0)) < 0) return need;
        sbc_at[f] = next;
        next += need / 4;
    }
    for (f = 0; f < 6; ++f) {
        dir_at[f] = nd->dirs && nd->dirs[(size_t)piece * 6 + (size_t)f] ? next : -1;
        if (dir_at[f] >= 0) next += (long long)W * W;
    }
    refl__gl_put4(o, nd->pos.x, nd->pos.y, nd->pos.z, nd->face);
    refl__gl_put4(o, bx[0], bx[1], bx[2], 0);
    refl__gl_put4(o, bx[3], bx[4], bx[5], 0);
    refl__gl_put4(o, sbc_at[0], sbc_at[1], sbc_at[2], sbc_at[3]);
    refl__gl_put4(o, sbc_at[4], sbc_at[5], -1, -1);
    refl__gl_put4(o, dir_at[0], dir_at[1], dir_at[2], dir_at[3]);
    refl__gl_put4(o, dir_at[4], dir_at[5], -1, -1);
    for (f = 0; f < 6; ++f) {
        const refl_sbc *s = nd->sbc[(size_t)piece * 6 + (size_t)f];
        long long n;
        if (!s) continue;
        n = refl_gl_pack_sbc(s, o->out ? o->out + o->n : NULL, o->out ? o->cap - o->n : 0);
        o->n += n;
    }
    for (f = 0; f < 6; ++f) {
        const signed char *dm = dir_at[f] >= 0 ? nd->dirs[(size_t)piece * 6 + (size_t)f] : NULL;
        for (i = 0; dm && i < W * W; ++i) refl__gl_put4(o, dm[3 * i], dm[3 * i + 1], dm[3 * i + 2], 0);
    }
    return next;
}

static long long refl__sbm_gl_pack(refl__gl_out *o, const refl_sbc_morph *m, refl_vec3 eye, int piece) {
    int nodes[4], k;
    float w[4];
    long long at[4], next = 6;
    if (!m || piece < 0 || piece >= m->piece_count || refl_sbc_morph_locate(m, eye, nodes, w) < 0)
        return REFL_ERROR_INVALID_ARGUMENT;
    for (k = 0; k < 4; ++k) {
        const refl__sbm_node *nd = &m->nodes[nodes[k]];
        at[k] = -1;
        if (!(w[k] > 0.0f) || !nd->built || !nd->sbc) continue;
        at[k] = next; /* sized below, with a counting pass of its own */
        {
            refl__gl_out count = {NULL, 0, next * 4};
            long long r = refl__sbm_gl_node(&count, nd, piece);
            if (r < 0) return r;
            next = count.n / 4;
        }
    }
    if (next >= 16777216) return REFL_ERROR_INVALID_ARGUMENT; /* offsets stored as floats */
    refl__gl_put4(o, REFL_GL_SBC_MORPH, REFL_GL_LAYOUT_VERSION, piece, next);
    refl__gl_put4(o, w[0] > 0.0f ? w[0] : 0.0f, w[1] > 0.0f ? w[1] : 0.0f, w[2] > 0.0f ? w[2] : 0.0f,
                      w[3] > 0.0f ? w[3] : 0.0f);
    /* the node offsets; node 0's texel also holds the piece's sheets */
    for (k = 0; k < 4; ++k) refl__gl_put4(o, at[k], k == 0 ? refl__sbm_piece_sheets(m, nodes, w, piece) : 0, 0, 0);
    for (k = 0; k < 4; ++k)
        if (at[k] >= 0 && refl__sbm_gl_node(o, &m->nodes[nodes[k]], piece) < 0) return REFL_ERROR_INVALID_ARGUMENT;
    return o->n;
}

REFL_API long long refl_gl_pack_sbc_morph(const refl_sbc_morph *morph, refl_vec3 eye, int piece, float *out,
                                          long long cap) {
    refl__gl_out o = {NULL, 0, 0};
    long long need = refl__sbm_gl_pack(&o, morph, eye, piece);
    return refl__gl_fill(&o, need, out, cap) ? refl__sbm_gl_pack(&o, morph, eye, piece) : need;
}
