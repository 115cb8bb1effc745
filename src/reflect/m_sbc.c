/* SBC: Popescu, Sacks and Mei's sample-based camera reflections (paper
   003). Per frame:
     1. ray maps (section IV-A): the reflectors' G-buffer (ENVMAP's) gives
        every reflector pixel its surface point and normal; every
        factor x factor pixels one reflected ray is taken, tail on the
        reflector, head twice as far as what it meets (or where it leaves
        the scene's box, grown 1%), first reflector point = tail.
        Past the first order (desc.depth > 1; section III-B's higher-order
        rays, IV's reflection histories): each sample's reflected ray is
        traced on through the mirrors and glass alone (a BVH of those; a
        partial reflector ends a history), up to desc.depth reflections
        (at most REFL__SB_ORDERS). Every history sampled (A, B, AB, BA,
        ABA, ...; at most REFL__SB_HISTORIES past the first order) is a
        side of its own, whose ray at a sample has its tail on the last
        reflector, its head clipped as above and its first reflector point
        the sample's. Glass seen directly also refracts (Fig. 20b): in at
        the sample's point (Snell, the material's ior), totally reflected
        inside while it must, out where it can within the depth: a side
        "refracted through" of its own, tail at the exit.
     2. reflection groups (section IV, and VII-C's pieces "whose rays do
        not intersect"): per reflector object and side seen (the G-buffer's
        id, negative on back faces: the inside of an open mesh), the ray
        map is cut into pieces: neighbouring samples stay together when no
        gap lies between them (one surface passing in front of another:
        the handle before the body), their normals turn by less than 45
        degrees (no crease: the knob on the lid), and either both or
        neither of their rays cross a neighbour's before its head (a
        concave groove focuses them). A group is a piece within a tile of
        REFL__SB_TILE samples, with one ring of rays extrapolated around
        it, diagonals included (the sample's view ray meets the tangent
        plane of its neighbour in the piece, the normal continues linearly;
        past grazing the ray goes straight on), so its frustums reach past
        the piece's edge: the paper's "extended reflectors". Each group is
        a BSP tree of pinhole cameras (cam_sbc.c) built to the requested
        error in desired-view pixels; pieces whose rays do not cross end
        mostly in pinhole leaves, focusing ones in ray lists. A pixel
        belongs to the group of the nearest sample on its own smooth
        surface. Past the first order a side's pieces lie within its
        parent's (the rays of one smooth piece of the mirror before) and
        its ring continues the rays linearly; groups come in layers (order
        k; the refractions last) and a pixel belongs, in each layer its own
        history reaches (traced per pixel as the samples are), to the group
        of the nearest sample on its surface with that history.
     3. projection (section V-A): every vertex of every object inside a
        group's box (its rays' tails and heads, grown by a quarter) is
        projected into the group (refl_sbc_project_sheets), moving it to
        its first reflector point, which must lie in the group's box too
        (a leaf's map far outside its rays sends points anywhere); the
        window depth is the paper's visibility
        offset (k - 1 + z/D) g for order k, in a depth buffer of the
        reflections' own, z measured as the distance from the vertex to its
        first reflector point (consistent across leaves, where each leaf's
        image-plane height is not), past the first order to the last
        reflector point (the tail of the history's sample it lands on).
        g = 1 / k_max of the window range, k_max the longest history
        sampled: the paper's g = D / (k_max + 1) with yon at 2D spends it
        alike, and k_max = 1 keeps z/D: the one-bounce frames' bytes.
        A group whose rays fold (cam_sbc.c's sheets: 1 + the folds of its
        ray lists, at most three) projects every vertex into each sheet at
        once and draws each sheet's triangles into its pixels, the depth
        test keeping the nearest: a point seen twice in a focusing mirror
        shows twice. A vertex with no image in a sheet takes its image one
        fold away (the sheets meet at the fold), and a triangle with such
        vertices is split as a mixed one and drawn only when no wider than
        REFL__SB_FOLD_SAMPLES samples: wider, it spans the caustic, where
        the two sheets' images part (concave bowl 320x240: mean 0.15 px
        with the limit, 0.43 without).
     4. rasterisation (section V-B): a reflected triangle is drawn when all
        three vertices project; one outside the group's box is dropped
        whole. Triangles are subdivided in four, at most REFL__SB_LEVELS
        times: always while an edge is longer than 1/32 of the scene's
        diagonal (the paper's pre-subdivision, per frame), while mixed (one
        or two vertices project; the paper's fix for jagged edges; at most
        desc.sbc.mixed_levels times, REFL__SB_MIXED_LEVELS by default and
        none with the fallback, unless the part holds a point where one
        of the group's rays meets the triangle), while no vertex projects
        but such a point lies inside (a group narrower than the triangle),
        and while an edge's projected midpoint lies more than
        REFL__SB_EDGE_PX from the midpoint of its projected ends (the
        straight-edge error the paper bounds by pre-subdividing). Reflected
        triangles are drawn by rast.h twice (colour as DIRECT shades the
        surface, then its world point; each pass with its depth buffer),
        stencilled to the group's pixels. Groups go through projection and
        drawing in batches of up to 254 (the stencil's values; the
        projected vertices of one batch at a time). The reflector's own
        triangles project too (the knob seen in the lid), except the
        surface the rays leave: a triangle facing away from every vertex's
        first reflector point (unless the group's rays meet it: the body's
        inside seen through the lid's gap faces away), or with a vertex
        nearer it than a quarter of the triangle's longest edge (tested
        before each subdivision too: such a triangle is not split). Layers are drawn in order, into one
        depth buffer; after order k < k_max, where a mirror or glass (drawn
        transparent black) is nearest the pixel is cleared: order k + 1
        shows there, and nowhere an order-k point lies in front (the
        offset): lower orders occlude higher ones. Refractions draw into
        targets of their own (they add to the reflection, never hide it);
        their own glass is not drawn.
     5. composite (section V-D): the reflected colour, or the environment
        along the pixel's reflected ray where nothing was drawn, times the
        material's reflectance (Schlick's Fresnel, or V-D's Fresnel blend
        and distance fade, when the material asks), as ENVMAP composites;
        glass adds the environment refracted once. A pixel of a group
        (of the first layer) that nothing was drawn on, between two drawn
        pixels of its group on opposite sides, is a crack (reflected
        triangles subdivided to different depths meet at a T-junction)
        and takes the nearer one's reflection (default 640x480 factor 2:
        holes 6.7% to 4.9%, mean 0.34 to 0.36 px; 1080p factor 4 holes
        6.5% to 4.8%; past the first order, the order with it: two
        facing mirrors at depth 2 holes 2.1% to 1.2%, colour off 2.6% to
        1.8%). With desc.sbc.trace_fallback (beyond the paper) a pixel still
        without a reflection, or whose first-order point the samples
        around it contradict (refl__sb_fallback), is rendered as RAYTRACE
        renders it (refl__rt_pixel) when its reflected ray meets anything,
        and mixed triangles are not split (step 4), their pixels traced:
        640x480 factor 2 holes 4.9% to 0.01%, mean 0.36 to 0.24 px, p95
        1.41 to 1.00 px, 296 to 175 ms a frame.
        Past the first order (refl__sb_resolve_row_deep): the nearest
        order's colour (its order read off the offset), or the environment
        along the last reflected ray, times the product of the reflectances
        along the pixel's own history (each bounce as RAYTRACE weighs it,
        faded by its reflected ray's length when the material asks);
        glass adds (1 - F) tint times what the refraction layer drew (or
        the environment beyond the glass), times (1 - F) at the exit and
        the absorption inside; reflections inside the glass short of total
        are left out. frame->points: the first point past the first
        reflector, as RAYTRACE's, or with desc.debug.points_last the last.
   Reflection morphing (section VI): a reflector the caller hands a
   prebuilt grid for (refl_render_desc.sbc.morphs, cam_sbc_morph.c) has no
   ray map or groups of its front side here; a group per piece of the grid
   projects instead (the eye's tetrahedron, blended; no check against this
   frame's ray map, which it has none of), its pixels those of the piece
   their view ray meets; morphing draws the first order only. Its sheets
   are the most its nodes' cameras have, and sheet k blends each node's
   image in sheet k (or one fold away), as a runtime group draws them.
   Diffuse shading needs no eye vector (Lambert), so the paper's true eye
   vector for point lights has nothing to change here. Deterministic: work
   is split into jobs whose outputs are drawn in job order. */
#include "internal.h"

#define REFL__SB_FACTOR 2           /* default ray map down-sampling */
#define REFL__SB_TILE 16            /* a group's tile side in ray map samples (at least) */
#define REFL__SB_TILE_MAX 64        /* ... and at most: larger groups fit their rays worse */
#define REFL__SB_EDGE_PX 0.5f       /* straight-edge error that splits a reflected triangle */
#define REFL__SB_LEVELS 6           /* subdivisions of a scene triangle at most */
#define REFL__SB_MIXED_LEVELS 4     /* of those, while mixed (desc.sbc.mixed_levels' default) */
#define REFL__SB_CHUNK 256          /* scene triangles per emission job */
#define REFL__SB_BATCH 254          /* groups projected and drawn at once, at most: the stencil's values but 0 */
#define REFL__SB_FLOATS 12          /* per emitted vertex: clip position, world position, normal, uv */
#define REFL__SB_OWN_NEAR 0.25f     /* a reflector's triangle this near (in edges) to its reflection: its surface */
#define REFL__SB_ORDERS 8           /* reflection orders traced at most (desc.depth beyond: cut here) */
#define REFL__SB_HISTORIES 64       /* histories beyond the first order, at most: the rest end a step early */
#define REFL__SB_SHEETS REFL_SBC_SHEETS /* a group's sheets at most (refl_sbc_project_sheets) */
#define REFL__SB_FOLD_SAMPLES 4.0f  /* a triangle straddling a fold wider than this (in samples): not drawn */
#define REFL__SB_ELSEWHERE_LEVELS 3 /* subdivisions, at most, of a triangle with its images in other sheets */

/* A reflector object's side seen: its ray map over the whole frame. */
typedef struct refl__sb_side {
    int object;                   /* the last reflector of its history */
    float id;                     /* its pixels' G-buffer id: object + 1, negated for the back side */
    int order;                    /* reflections along its history (a refraction's: 1, in a layer of its own) */
    int layer;                    /* order - 1; sb->orders for refractions */
    int parent;                   /* the side one reflection shorter (-1 at order 1) */
    int kind;                     /* 0 reflected; 1 refracted through the glass of `parent`;
                                     2 refracted into it, meeting a surface inside */
    refl_sbc_ray *rays;
    refl__sbc_hit *hits;           /* per sample: what its ray meets */
    uint8_t *valid;               /* 1: the sample shows the side, with a ray */
    refl_vec3 *normals;           /* per sample, towards the viewer */
    int *comp;                    /* per sample: its smooth piece (refl__sb_pieces), -1: none */
    int *group;                   /* per sample with a ray: its group */
    uint8_t *crossing;            /* per sample: its ray crosses a neighbour's (refl__sb_cross) */
} refl__sb_side;

/* A reflection group: one piece of a side's ray map within one tile, its
   rays (those of the piece in the tile grown by a sample: neighbouring
   tiles' frustums overlap) and one ring of rays extrapolated around them. */
typedef struct refl__sb_group {
    int side, object, comp;       /* comp: its piece of the side */
    int u0, v0, u1, v1;           /* its tile: samples [u0, u1) x [v0, v1) */
    refl_sbc *sbc;
    int sheets;                   /* its rays split at their folds: each sheet projects and draws apart */
    refl_vec3 lo, hi;             /* where its points may lie: its rays' box, grown */
    refl_vec3 first_lo, first_hi; /* past the first order: its first reflector points' box, grown alike */
    refl__sbc_hit *hits;           /* what its rays meet, by object and triangle */
    int hit_count;
    refl_result result;
    const refl_sbc_morph *morph;  /* instead of sbc: a morphing grid's piece (refl__sb_morph_groups) */
    int piece;
    int morph_nodes[4];           /* the eye's tetrahedron in the grid and its weights, located once */
    float morph_w[4];
} refl__sb_group;

/* A scene point and what a group makes of it. */
typedef struct refl__sb_pv {
    refl_vec3 world, normal;
    int sheet;                    /* the group's sheet it projects in */
    int across;                   /* it has none there: its image one fold away (refl__sbc_sheet_image) */
    float uv[2];
    float clip[4];                /* the first reflector point's, depth replaced */
    float sx, sy;                 /* its window position */
    refl_vec3 first;              /* its first reflector point */
    refl_vec3 from;               /* where its ray leaves the last reflector (order 1: first) */
    float dist;                   /* to `from` */
    int ok;
    int ambiguous;                /* morph groups: projects at some of the eye's nodes, not all */
} refl__sb_pv;

/* A group's vertices of one object: those in the group's box, projected
   (into each sheet), the others as they are (refl__sb's base). */
typedef struct refl__sb_slot {
    int *index;                   /* per mesh vertex: its place in pv, -1: outside the box (base) */
    refl__sb_pv *pv[REFL__SB_SHEETS]; /* per sheet of the group */
    int count;                    /* vertices in the box */
    int failed;
} refl__sb_slot;

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

/* One emission job: triangles [first, first + count) of `object` into `group`'s `sheet`. */
typedef struct refl__sb_job {
    int group, object, sheet, first, count;
    float *out;                   /* REFL__SB_FLOATS per vertex, three per triangle */
    size_t out_count, out_cap;    /* vertices */
    long long projections, projected;
    refl__sb_memo *memo;          /* while it runs, from its first midpoint on (NULL: none to spare) */
    int failed;
} refl__sb_job;

typedef struct refl__sb {
    refl__pass *p;
    refl__em em;                  /* the reflectors' G-buffer and surface points */
    refl__sb_side *sides;
    int side_count, sides1;       /* sides, and those of the first order (they come first) */
    refl__sb_group *groups;
    int group_count;
    int map_w, map_h, tile;       /* the ray map's size; a group's tile side in samples */
    int factor;
    int mixed_levels;             /* desc.sbc.mixed_levels resolved */
    float error_px;
    float diagonal;               /* the scene's, grown 1%: D */
    refl_vec3 box_lo, box_hi;     /* the scene's box, grown 1% */
    refl_bvh *bvh;                /* the scene's, for the rays' first hits (the renderer's) */
    refl_bvh *own_bvh;            /* bvh when no renderer keeps it */
    /* higher orders (desc.depth > 1): the paper's reflection histories */
    int budget;                   /* bounces a path may take: desc.depth, at most REFL__SB_ORDERS */
    int orders;                   /* reflection orders drawn (k_max): the longest history sampled */
    int layers;                   /* orders, plus one for refractions when any was sampled */
    refl_bvh *mirrors;            /* the mirrors and glass alone (the paper traces the reflectors alone) */
    int *mirror_object;           /* its objects' scene indices */
    refl_mat4 *normal_m;          /* per object: the normals' matrix */
    float *sample_id;             /* budget x map: per order, the side id each sample's path meets, 0: none */
    uint8_t *sample_refr;         /* per sample: the kind of its refraction path (1, 2), 0: none */
    int *sample_side;             /* (budget + 1) x map: per layer, each sample's side, -1: none */
    int *group_of;                /* layers x pixels: per layer and pixel, group index + 1, 0: none */
    int *morph_base;              /* per object: its morph groups' first index, -1: none */
    int batch, batch0, batch1;    /* groups per batch; those projected and drawn now: [batch0, batch1) */
    int layer;                    /* the batch's layer (one per batch) */
    int map_first;                /* the first side refl__sb_map_side's jobs map */
    uint8_t *stencil;             /* per pixel: its group's place in the batch + 1, 0: none */
    refl__sb_pv **base;           /* per object: every mesh vertex in the world, projecting nowhere */
    refl__sb_slot *slots;         /* per group of the batch x object: its vertices */
    refl__sb_job *jobs;
    int job_count;
    uint8_t *color;               /* scratch targets of the reflections: the colour pass's */
    float *depth, *points;        /* (colour, depth), the points pass's (points, depth) */
    float *points_depth;
    uint8_t *refr_color;          /* the same for the refraction layer, drawn apart: */
    float *refr_depth, *refr_points, *refr_points_depth; /* it adds to the reflections, never hides them */
    refl__rt *tracer;             /* desc.sbc.trace_fallback: how RAYTRACE renders a pixel; else NULL */
    long long *traced_rays;       /* ... and per row, the rays the fallback cast */
} refl__sb;

/* Whether g projects: a tree of this frame or a morph's piece. */
static int refl__sb_live(const refl__sb_group *g) { return g->sbc != NULL || g->morph != NULL; }

/* The layer g draws in: its side's; a morph's piece reflects once. */
static int refl__sb_group_layer(const refl__sb *sb, const refl__sb_group *g) {
    return g->morph ? 0 : sb->sides[g->side].layer;
}

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

/* The ray map sample (u, v)'s pixel. */
static void refl__sb_sample_pixel(const refl__sb *sb, int u, int v, int *x, int *y) {
    const refl_frame *fr = sb->p->frame;
    *x = REFL__MIN(u * sb->factor + sb->factor / 2, fr->width - 1);
    *y = REFL__MIN(v * sb->factor + sb->factor / 2, fr->height - 1);
}

/* The ray from q along r (tail = first = q), its head clipped as the
   module comment says (refl__sbc_scene_ray), and what it meets first in
   *met; 0 for a ray of zero length. */
static int refl__sb_ray_dir(const refl__sb *sb, refl_vec3 q, refl_vec3 r, refl_sbc_ray *ray, refl__sbc_hit *met) {
    return refl__sbc_scene_ray(sb->bvh, sb->box_lo, sb->box_hi, sb->diagonal, q, r, ray, met);
}

/* The reflected ray of surface point q with normal n (towards the
   viewer) seen along view direction d (refl__sb_ray_dir). */
static int refl__sb_ray(const refl__sb *sb, refl_vec3 q, refl_vec3 n, refl_vec3 d, refl_sbc_ray *ray,
                        refl__sbc_hit *met) {
    n = refl_v3_normalize(n);
    /* a normal turned past grazing (extrapolated beyond a silhouette)
       reflects as the limit does: straight on, not back */
    return refl__sb_ray_dir(sb, q, refl_v3_dot(d, n) < -1e-4f ? refl_v3_reflect(d, n) : d, ray, met);
}

/* ---- higher orders: paths through the mirrors and glass alone ---- */

/* Reflectors a history goes on through: mirrors and glass. A partial
   reflector ends it (its diffuse share is drawn where it is met). */
static int refl__sb_goes_on(const refl_material *m) { return m->type == REFL_MIRROR || m->type == REFL_GLASS; }

/* What a path from o along unit d meets first among the mirrors and glass
   (h->object: the scene's index), within the scene's box. */
static int refl__sb_mirror_hit(const refl__sb *sb, refl_vec3 o, refl_vec3 d, refl_hit *h) {
    float reach = refl__sbc_box_exit(sb->box_lo, sb->box_hi, o, d);
    if (!sb->mirrors || !refl_bvh_intersect(sb->mirrors, o, d, 1e-4f * sb->diagonal, reach, h)) return 0;
    h->object = sb->mirror_object[h->object];
    return 1;
}

/* A hit's point (barycentric, as RAYTRACE reads it), geometric and
   shading normals (unit, as the mesh winds and interpolates them); the
   triangle's longest edge. */
static float refl__sb_surface(const refl__sb *sb, const refl_hit *h, refl_vec3 *p, refl_vec3 *ng, refl_vec3 *ns) {
    const refl_object *o = &sb->p->scene->objects[h->object];
    refl__hit_geom g;
    refl__hit_surface(sb->p->scene->meshes[o->mesh], &o->transform, &sb->normal_m[h->object], h, &g);
    *p = g.p;
    *ng = g.ng;
    *ns = g.ns;
    return REFL__MAX(refl_v3_length(refl_v3_sub(g.v[1], g.v[0])),
                     REFL__MAX(refl_v3_length(refl_v3_sub(g.v[2], g.v[1])), refl_v3_length(refl_v3_sub(g.v[0], g.v[2]))));
}

/* The material of G-buffer side id `id` (object + 1, negated on the back). */
static const refl_material *refl__sb_material(const refl__sb *sb, float id) {
    const refl_scene *scene = sb->p->scene;
    return &scene->materials[scene->objects[(int)fabsf(id) - 1].material];
}

/* A pixel's reflection history: per order k (index k - 1) the side it
   reflects at (G-buffer id: object + 1, negated on the back), the point,
   its unit normal facing the incoming ray, the incoming unit direction, and
   the product of the reflectances through order k (each as RAYTRACE
   weighs its bounce, the fades of the bounces before k included: order
   k's own fades by what it shows); `out` the last order's reflected
   direction. */
typedef struct refl__sb_path {
    int count;
    float id[REFL__SB_ORDERS], weight[REFL__SB_ORDERS];
    refl_vec3 q[REFL__SB_ORDERS], n[REFL__SB_ORDERS], d[REFL__SB_ORDERS];
    refl_vec3 out;
} refl__sb_path;

/* The history of reflector point q (side id, unit normal n towards the
   viewer) seen along d, through sb->orders reflections at most: the first
   reflects as refl__sb_ray does, later ones as RAYTRACE reflects. */
static void refl__sb_trace_path(const refl__sb *sb, refl_vec3 q, refl_vec3 n, refl_vec3 d, float id,
                                refl__sb_path *pa) {
    const refl_scene *scene = sb->p->scene;
    int object = (int)fabsf(id) - 1, k;
    refl_vec3 r;
    n = refl_v3_normalize(n);
    r = refl_v3_dot(d, n) < -1e-4f ? refl_v3_reflect(d, n) : d;
    pa->count = 1;
    pa->id[0] = id;
    pa->q[0] = q;
    pa->n[0] = n;
    pa->d[0] = d;
    pa->weight[0] = refl_material_reflectance(&scene->materials[scene->objects[object].material],
                                              REFL__CLAMP(-refl_v3_dot(d, n), 0.0f, 1.0f));
    for (k = 1; k < sb->orders; ++k) {
        refl_hit h;
        refl_vec3 p, ng, ns, rd;
        float edge;
        int front;
        if (!refl__sb_mirror_hit(sb, pa->q[k - 1], r, &h)) break;
        edge = refl__sb_surface(sb, &h, &p, &ng, &ns);
        front = refl_v3_dot(r, ng) < 0.0f;
        if (!front) {
            ng = refl_v3_scale(ng, -1.0f);
            ns = refl_v3_scale(ns, -1.0f);
        }
        if (refl_v3_dot(r, ns) > 0.0f) ns = ng;
        /* into its own reflector's other side, or its own facets within an
           edge: a shading normal sent it (nearly) along the surface or below
           its facet (RAYTRACE then reflects about the facet, which the
           G-buffer does not hold), not a reflection seen */
        if (h.object + 1 == (int)fabsf(pa->id[k - 1]) && (front != (pa->id[k - 1] > 0.0f) || h.t < edge)) break;
        pa->id[k] = front ? (float)(h.object + 1) : -(float)(h.object + 1);
        pa->q[k] = p;
        pa->n[k] = ns;
        pa->d[k] = r;
        /* RAYTRACE fades a bounce by its reflected ray's length (paper 003 V-D) */
        pa->weight[k] = pa->weight[k - 1] * refl_material_fade(refl__sb_material(sb, pa->id[k - 1]), h.t) *
                        refl_material_reflectance(&scene->materials[scene->objects[h.object].material],
                                                  REFL__CLAMP(-refl_v3_dot(r, ns), 0.0f, 1.0f));
        pa->count = k + 1;
        rd = refl_v3_reflect(r, ns);
        if (refl_v3_dot(rd, ng) <= 0.0f) rd = refl_v3_reflect(r, ng);
        r = rd;
    }
    pa->out = r;
}

/* The path refracted through glass (paper 003's Fig. 20b): in at q (unit
   normal n towards the viewer, seen along d), reflected totally inside
   while it must, out where it refracts, within sb->budget interfaces and
   meeting only its own glass. tail: the exit point; out: the direction
   beyond; normal: the exit's, facing out; weight: what RAYTRACE's
   refracted branch keeps past the entry's (1 - F) and tint: (1 - F) at
   the exit times the absorption inside. Its partial reflections inside
   are left out. 1: such a path; 2: it meets another object inside (the
   floor under a glass sunk into it; the whole scene's BVH tells): tail
   where the last segment starts, out along it, weight the absorption up
   to the object; 0: still inside when the budget runs out (RAYTRACE's
   black); -1: it leaves without meeting its glass again (a silhouette
   pixel whose point lies just off the glass). */
typedef struct refl__sb_refr {
    refl_vec3 tail, out, normal;
    float weight;
} refl__sb_refr;

static int refl__sb_refract_path(const refl__sb *sb, refl_vec3 q, refl_vec3 n, refl_vec3 d, float id,
                                 refl__sb_refr *rp) {
    const refl_scene *scene = sb->p->scene;
    int object = (int)fabsf(id) - 1, b;
    const refl_material *m;
    float ior, len = 0.0f, f;
    refl_vec3 t, pos = q;
    if (object < 0 || object >= scene->object_count || sb->budget < 2 || !sb->mirrors) return 0;
    m = &scene->materials[scene->objects[object].material];
    if (m->type != REFL_GLASS) return 0;
    ior = m->ior > 0.0f ? m->ior : 1.5f;
    f = refl_fresnel_dielectric(REFL__CLAMP(-refl_v3_dot(d, n), 0.0f, 1.0f), 1.0f, ior);
    if (!(f < 1.0f) || !refl_v3_refract(d, n, 1.0f / ior, &t)) return 0;
    for (b = 1; b < sb->budget; ++b) {
        refl_hit h, in;
        refl_vec3 p, ng, ns, t2, rd;
        int entering;
        if (!refl__sb_mirror_hit(sb, pos, t, &h) || h.object != object) return -1;
        if (refl_bvh_intersect(sb->bvh, pos, t, 1e-4f * sb->diagonal, h.t, &in) && in.object != object) {
            rp->tail = pos;
            rp->out = t;
            rp->normal = b > 1 ? rp->normal : refl_v3_scale(n, -1.0f);
            rp->weight = expf(-REFL__MAX(m->attenuation, 0.0f) * (len + in.t));
            return 2;
        }
        refl__sb_surface(sb, &h, &p, &ng, &ns);
        /* as RAYTRACE: a face turned towards the ray is entered (an inner
           wall of a glass whose parts overlap), else left; the normals
           turned against the ray */
        entering = refl_v3_dot(t, ng) < 0.0f;
        if (!entering) {
            ng = refl_v3_scale(ng, -1.0f);
            ns = refl_v3_scale(ns, -1.0f);
        }
        if (refl_v3_dot(t, ns) > 0.0f) ns = ng;
        len += h.t;
        pos = p;
        f = refl_fresnel_dielectric(REFL__CLAMP(-refl_v3_dot(t, ns), 0.0f, 1.0f), entering ? 1.0f : ior,
                                    entering ? ior : 1.0f);
        if (f < 1.0f && refl_v3_refract(t, ns, entering ? 1.0f / ior : ior, &t2)) {
            rp->tail = p;
            rp->out = t2;
            rp->normal = refl_v3_scale(ns, -1.0f);
            rp->weight = (1.0f - f) * expf(-REFL__MAX(m->attenuation, 0.0f) * len);
            return 1;
        }
        /* totally reflected inside: a reflection on the way */
        rp->normal = ns;
        rd = refl_v3_reflect(t, ns);
        if (refl_v3_dot(rd, ng) <= 0.0f) rd = refl_v3_reflect(t, ng);
        t = rd;
    }
    return 0;
}

/* Pixel i's view direction, surface point and unit normal towards the
   viewer (as the ray map and the composite take them). */
static void refl__sb_pixel_view(const refl__sb *sb, size_t i, refl_vec3 *d, refl_vec3 *q, refl_vec3 *n) {
    const refl__pass *p = sb->p;
    int x = (int)(i % (size_t)p->frame->width), y = (int)(i / (size_t)p->frame->width);
    refl_vec3 o;
    float tmax;
    const float *gb = sb->em.gbuf + 4 * i;
    refl__view_rays_get(&p->rays, (float)x + 0.5f, (float)y + 0.5f, &o, d, &tmax);
    *n = refl_v3_normalize(refl_v3(gb[0], gb[1], gb[2]));
    if (refl_v3_dot(*n, *n) == 0.0f) *n = refl_v3_scale(*d, -1.0f); /* degenerate: face the eye */
    if (refl_v3_dot(*n, *d) > 0.0f) *n = refl_v3_scale(*n, -1.0f);
    *q = refl_v3(sb->em.surface[3 * i], sb->em.surface[3 * i + 1], sb->em.surface[3 * i + 2]);
}

/* Side sd's ray map: a ray per sample showing the side (valid 1), with
   the sample's unit normal turned towards the viewer. */
static void refl__sb_ray_map(const refl__sb *sb, refl__sb_side *sd) {
    const refl__pass *p = sb->p;
    int u, v, W = p->frame->width, mw = sb->map_w;
    for (v = 0; v < sb->map_h; ++v)
        for (u = 0; u < mw; ++u) {
            size_t m = (size_t)v * (size_t)mw + (size_t)u, i;
            int x, y;
            refl_vec3 o, d, n;
            float tmax;
            const float *gb;
            refl__sb_sample_pixel(sb, u, v, &x, &y);
            i = (size_t)y * (size_t)W + (size_t)x;
            gb = sb->em.gbuf + 4 * i;
            sd->valid[m] = 0;
            if (gb[3] != sd->id) continue;
            refl__view_rays_get(&p->rays, (float)x + 0.5f, (float)y + 0.5f, &o, &d, &tmax);
            n = refl_v3_normalize(refl_v3(gb[0], gb[1], gb[2]));
            sd->normals[m] = refl_v3_dot(n, d) > 0.0f ? refl_v3_scale(n, -1.0f) : n;
            sd->valid[m] = (uint8_t)refl__sb_ray(sb, refl_v3(sb->em.surface[3 * i], sb->em.surface[3 * i + 1],
                                                             sb->em.surface[3 * i + 2]),
                                                 sd->normals[m], d, &sd->rays[m], &sd->hits[m]);
        }
}

/* A side of a higher layer: the rays of the samples whose history it is
   (sb->sample_side), at its order's reflector (or out of its glass),
   first reflector point on the pixel's own reflector. */
static void refl__sb_ray_map_higher(const refl__sb *sb, refl__sb_side *sd, int self) {
    size_t count = (size_t)sb->map_w * (size_t)sb->map_h, m;
    const int *own = sb->sample_side + (size_t)sd->layer * count;
    for (m = 0; m < count; ++m) {
        int x, y, ok = 0;
        size_t i;
        refl_vec3 d, q, n;
        sd->valid[m] = 0;
        if (own[m] != self) continue;
        refl__sb_sample_pixel(sb, (int)(m % (size_t)sb->map_w), (int)(m / (size_t)sb->map_w), &x, &y);
        i = (size_t)y * (size_t)sb->p->frame->width + (size_t)x;
        refl__sb_pixel_view(sb, i, &d, &q, &n);
        if (sd->kind) {
            refl__sb_refr rp;
            if (refl__sb_refract_path(sb, q, n, d, sb->sides[sd->parent].id, &rp) == sd->kind) {
                ok = refl__sb_ray_dir(sb, rp.tail, rp.out, &sd->rays[m], &sd->hits[m]);
                sd->normals[m] = rp.normal;
            }
        } else {
            refl__sb_path pa;
            int k = sd->order - 1;
            refl__sb_trace_path(sb, q, n, d, sb->em.gbuf[4 * i + 3], &pa);
            if (pa.count > k) {
                ok = refl__sb_ray_dir(sb, pa.q[k], k + 1 < pa.count ? pa.d[k + 1] : pa.out, &sd->rays[m],
                                      &sd->hits[m]);
                sd->normals[m] = pa.n[k];
            }
        }
        sd->rays[m].first = q;
        sd->valid[m] = (uint8_t)ok;
    }
}

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

/* Side i's ray map and pieces (a job: sides map in parallel). */
static void refl__sb_map_side(void *arg, int job) {
    refl__sb *sb = (refl__sb *)arg;
    const refl_allocator *al = &sb->p->scene->allocator;
    int i = sb->map_first + job;
    refl__sb_side *sd = &sb->sides[i];
    size_t n = (size_t)sb->map_w * (size_t)sb->map_h;
    sd->normals = (refl_vec3 *)refl__calloc(al, n, sizeof(refl_vec3));
    sd->rays = (refl_sbc_ray *)refl__calloc(al, n, sizeof(refl_sbc_ray));
    sd->hits = (refl__sbc_hit *)refl__calloc(al, n, sizeof(refl__sbc_hit));
    sd->valid = (uint8_t *)refl__calloc(al, n, 1);
    sd->comp = (int *)refl__calloc(al, n, sizeof(int));
    sd->group = (int *)refl__calloc(al, n, sizeof(int));
    sd->crossing = (uint8_t *)refl__calloc(al, n, 1);
    if (sd->normals && sd->rays && sd->hits && sd->valid && sd->comp && sd->group && sd->crossing) {
        if (sd->layer) refl__sb_ray_map_higher(sb, sd, i);
        else refl__sb_ray_map(sb, sd);
        refl__sb_pieces(sb, sd);
    }
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
                refl__sb_sample_pixel(sb, u0 + u, v0 + v, &x, &y);
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

static int refl__sbc_hit_before(const refl__sbc_hit *a, const refl__sbc_hit *b) {
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
                dst[o++] = r >= e || (l < m && !refl__sbc_hit_before(&src[r], &src[l])) ? src[l++] : src[r++];
        }
        t = src; src = dst; dst = t;
    }
    if (src != out) memcpy(out, src, (size_t)n * sizeof(refl__sbc_hit));
}

/* Builds group g's tree from its piece's rays in its tile grown by one
   sample, and a ring around them (a job). */
static void refl__sb_build_group(void *arg, int g) {
    refl__sb *sb = (refl__sb *)arg;
    const refl__pass *p = sb->p;
    const refl_allocator *al = &p->scene->allocator;
    refl__sb_group *gr = &sb->groups[g];
    const refl__sb_side *sd = &sb->sides[gr->side];
    int u0 = REFL__MAX(gr->u0 - 1, 0), v0 = REFL__MAX(gr->v0 - 1, 0);
    int u1 = REFL__MIN(gr->u1 + 1, sb->map_w), v1 = REFL__MIN(gr->v1 + 1, sb->map_h);
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
                size_t m = (size_t)v * (size_t)sb->map_w + (size_t)u;
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
           cameras below the tails (see cam_sbc.c) */
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
    refl__sb_pv *out = sb->base[o];
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
    int g = sb->batch0 + index / sb->p->scene->object_count, o = index % sb->p->scene->object_count, i, k;
    int vc = sb->p->scene->meshes[sb->p->scene->objects[o].mesh]->vertex_count, sheets;
    const refl__sb_group *gr = &sb->groups[g];
    const refl__sb_pv *base = sb->base[o];
    refl__sb_slot *slot = &sb->slots[index];
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

/* Whether a reflector's triangle, projected into a group of its own, is
   the surface the group's rays leave rather than a part of the reflector
   they meet (the knob seen in the lid): it faces away from the point
   every vertex's ray leaves (`from`), or lies nearer one than a fraction
   of its edge. */
static int refl__sb_own_surface(const refl__sb_pv *a, const refl__sb_pv *b, const refl__sb_pv *c, float edge, int met) {
    const refl__sb_pv *v[3];
    refl_vec3 n = refl_v3_cross(refl_v3_sub(b->world, a->world), refl_v3_sub(c->world, a->world));
    int k;
    v[0] = a; v[1] = b; v[2] = c;
    /* outwards, as the vertex normals point */
    if (refl_v3_dot(n, refl_v3_add(a->normal, refl_v3_add(b->normal, c->normal))) < 0.0f) n = refl_v3_scale(n, -1.0f);
    if (REFL__MIN(a->dist, REFL__MIN(b->dist, c->dist)) < REFL__SB_OWN_NEAR * edge) return 1;
    if (met) return 0;
    for (k = 0; k < 3; ++k)
        if (refl_v3_dot(refl_v3_sub(v[k]->from, v[k]->world), n) > 0.0f) return 0;
    return 1;
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

/* Emits triangle (a, b, c) at subdivision level `level`, split as the
   module comment says. */
static void refl__sb_emit(const refl__sb *sb, const refl__sb_group *g, refl__sb_job *j, const refl__sb_pv *a,
                          const refl__sb_pv *b, const refl__sb_pv *c, int level, const refl__sb_tri *t) {
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
    if (level < REFL__SB_LEVELS) {
        float la = refl_v3_length(refl_v3_sub(a->world, b->world));
        float lb = refl_v3_length(refl_v3_sub(b->world, c->world));
        float lc = refl_v3_length(refl_v3_sub(c->world, a->world));
        float ext = ok == 3 ? refl__sb_extent(a, b, c) : 0.0f;
        if (REFL__MAX(la, REFL__MAX(lb, lc)) > max_edge) {
            split = 1;
        } else if (ok == 3 && across) { /* straddles a fold: finer where the sheets meet */
            split = level < REFL__SB_MIXED_LEVELS;
        } else if (ok == 3 && ext > 2.0f * REFL__SB_EDGE_PX) { /* smaller: no edge can bend further */
            const refl__sb_pv *e[3][2] = {{a, b}, {b, c}, {c, a}};
            refl__sb_pv *mid[3];
            int k;
            mid[0] = &ab; mid[1] = &bc; mid[2] = &ca;
            for (k = 0; k < 3; ++k) {
                float dx, dy;
                *mid[k] = refl__sb_mid(sb, g, e[k][0], e[k][1], j);
                dx = mid[k]->sx - 0.5f * (e[k][0]->sx + e[k][1]->sx);
                dy = mid[k]->sy - 0.5f * (e[k][0]->sy + e[k][1]->sy);
                if (!mid[k]->ok || dx * dx + dy * dy > REFL__SB_EDGE_PX * REFL__SB_EDGE_PX) split = 1;
            }
            have_mid = 1;
        } else if (ok < 3) {
            int k;
            split = ok > 0 && level < sb->mixed_levels;
            for (k = 0; k < t->hit_count && !split && (!elsewhere || level < REFL__SB_ELSEWHERE_LEVELS); ++k)
                split = refl__sb_holds(a, b, c, t->hits[k].point);
        }
    }
    if (!split) {
        if (ok < 3) return;
        /* straddling a fold, drawn only where the sheets' images meet */
        if (across && refl__sb_extent(a, b, c) > REFL__SB_FOLD_SAMPLES * (float)sb->factor) return;
        /* the reflector's own surface around the rays' tails */
        if (t->self && refl__sb_own_surface(a, b, c, t->edge, t->hit_count > 0)) return;
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
    refl__sb_emit(sb, g, j, a, &ab, &ca, level + 1, t);
    refl__sb_emit(sb, g, j, &ab, b, &bc, level + 1, t);
    refl__sb_emit(sb, g, j, &ca, &bc, c, level + 1, t);
    refl__sb_emit(sb, g, j, &ab, &bc, &ca, level + 1, t);
}

static void refl__sb_emit_job(void *arg, int index) {
    refl__sb *sb = (refl__sb *)arg;
    refl__sb_job *j = &sb->jobs[index];
    const refl_scene *scene = sb->p->scene;
    const refl_mesh *m = scene->meshes[scene->objects[j->object].mesh];
    const refl__sb_slot *slot = &sb->slots[(j->group - sb->batch0) * scene->object_count + j->object];
    const refl__sb_pv *base = sb->base[j->object], *pv = slot->pv[j->sheet], *v[3];
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
        t.hits = g->hits + lo;
        t.hit_count = 0;
        while (lo < g->hit_count && g->hits[lo].object == j->object && g->hits[lo].triangle == tr) {
            ++lo;
            ++t.hit_count;
        }
        refl__sb_emit(sb, g, j, a, b, c, 0, &t);
    }
    refl__free(&scene->allocator, j->memo);
    j->memo = NULL;
}

/* The targets of draw pass `pass`: 0 the reflections' colour, 1 their
   points, each with its own depth buffer (the batch draws both passes). */
static rast_targets refl__sb_targets(const refl__sb *sb, int pass) {
    const refl_frame *fr = sb->p->frame;
    int refr = sb->layer >= sb->orders; /* the refraction layer draws apart */
    rast_targets t;
    memset(&t, 0, sizeof t);
    t.color.width = t.depth.width = t.stencil.width = fr->width;
    t.color.height = t.depth.height = t.stencil.height = fr->height;
    t.depth.ptr = refr ? (pass ? sb->refr_points_depth : sb->refr_depth) : pass ? sb->points_depth : sb->depth;
    t.depth.stride = (int)sizeof(float) * fr->width;
    t.stencil.ptr = sb->stencil;
    t.stencil.stride = fr->width;
    t.color.ptr = refr ? (pass ? (void *)sb->refr_points : (void *)sb->refr_color)
                       : pass ? (void *)sb->points : (void *)sb->color;
    t.color.stride = pass ? 4 * (int)sizeof(float) * fr->width : 4 * fr->width;
    t.color_format = pass ? RAST_COLOR_RGBA32F : RAST_COLOR_RGBA8;
    return t;
}

/* Clears both passes' colour and depth, once before the batches (the
   refraction layer's too, when there is one). */
static refl_result refl__sb_clear(refl__sb *sb) {
    rast_result rr = RAST_OK;
    int pass;
    for (pass = 0; pass < (sb->layers > sb->orders ? 4 : 2) && rr == RAST_OK; ++pass) {
        rast_targets t;
        sb->layer = pass < 2 ? 0 : sb->orders;
        t = refl__sb_targets(sb, pass & 1);
        if ((rr = rast_set_targets(sb->p->rc, &t)) == RAST_OK)
            rr = refl__em_clear(sb->p->rc, RAST_CLEAR_COLOR | RAST_CLEAR_DEPTH);
    }
    if (rr == RAST_OK) rr = rast_finish(sb->p->rc);
    return refl__result_from_rast(rr);
}

/* After the groups of order k < k_max: where a mirror or glass (drawn
   transparent black, alpha 0) is nearest, the reflection goes on there, so
   the order k + 1 draws may (they lie behind every order-k point, by the
   visibility offset); the mirror hid the order-k points behind it. */
static void refl__sb_pass_through(refl__sb *sb) {
    size_t k, npx = (size_t)sb->p->frame->width * (size_t)sb->p->frame->height;
    for (k = 0; k < npx; ++k)
        if (sb->depth[k] < 1.0f && sb->color[4 * k + 3] == 0) sb->depth[k] = sb->points_depth[k] = 1.0f;
}

/* The points pass's fragments: the world position and the object drawn
   (user: the object's index + 1, as a float), which the fallback checks
   against what the ray map's samples meet. */
static int refl__sb_point_fragment(void *user, const rast_fragment_in *in, float rgba[4]) {
    rgba[0] = in->varyings[0];
    rgba[1] = in->varyings[1];
    rgba[2] = in->varyings[2];
    rgba[3] = *(const float *)user;
    return 1;
}

/* Draws the batch's jobs into the scratch targets: colour, then the points
   with the same depth test, each job stencilled to its group's pixels. */
static refl_result refl__sb_draw(refl__sb *sb) {
    refl__pass *p = sb->p;
    const refl_scene *scene = p->scene;
    refl_frame *fr = p->frame;
    refl__draw_ctx *dc = (refl__draw_ctx *)refl__calloc(&scene->allocator, (size_t)scene->object_count,
                                                        sizeof(refl__draw_ctx));
    float *ids = (float *)refl__calloc(&scene->allocator, (size_t)scene->object_count, sizeof(float));
    rast_result rr = RAST_OK;
    int pass, i;
    size_t k, npx = (size_t)fr->width * (size_t)fr->height;
    if (!dc || !ids) {
        refl__free(&scene->allocator, dc);
        refl__free(&scene->allocator, ids);
        return REFL_ERROR_OUT_OF_MEMORY;
    }
    for (i = 0; i < scene->object_count; ++i) {
        refl__draw_ctx_init(&dc[i], scene, i, p->vp);
        ids[i] = (float)(i + 1);
    }
    for (k = 0; k < npx; ++k) {
        int g = sb->group_of[(size_t)sb->layer * npx + k] - 1;
        sb->stencil[k] = (uint8_t)(g >= sb->batch0 && g < sb->batch1 ? g - sb->batch0 + 1 : 0);
    }
    for (pass = 0; pass < 2 && rr == RAST_OK; ++pass) {
        rast_targets t = refl__sb_targets(sb, pass);
        if ((rr = rast_set_targets(p->rc, &t)) != RAST_OK) break;
        for (i = 0; i < sb->job_count && rr == RAST_OK; ++i) {
            const refl__sb_job *j = &sb->jobs[i];
            const refl__draw_ctx *d = &dc[j->object];
            rast_state s;
            rast_draw_desc dd;
            if (!j->out_count) continue;
            memset(&s, 0, sizeof s);
            s.depth_test = 1;
            s.stencil_test = 1;
            s.stencil_front.func = RAST_EQUAL;
            s.stencil_front.ref = (uint8_t)(j->group - sb->batch0 + 1);
            s.stencil_back = s.stencil_front;
            if (pass == 1) {
                s.fragment_fn = refl__sb_point_fragment;
                s.fragment_user = &ids[j->object];
            } else {
                s.fragment_fn = d->material->type == REFL_DIFFUSE || d->material->type == REFL_PARTIAL
                                    ? refl__base_fragment
                                    : refl__clear_fragment;
                s.fragment_user = (void *)d;
            }
            memset(&dd, 0, sizeof dd);
            dd.primitive = RAST_TRIANGLES;
            dd.vertices = j->out;
            dd.vertex_count = (int)j->out_count;
            dd.stride = REFL__SB_FLOATS;
            dd.position_size = 4;
            dd.num_varyings = REFL__SB_FLOATS - 4;
            if ((rr = rast_set_state(p->rc, &s)) == RAST_OK) rr = rast_draw(p->rc, &dd);
            if (pass == 0) fr->stats.triangles += (long long)(j->out_count / 3);
        }
        if (rr == RAST_OK) rr = rast_finish(p->rc);
    }
    refl__free(&scene->allocator, dc);
    refl__free(&scene->allocator, ids);
    return refl__result_from_rast(rr);
}

/* Frees the batch's projected vertices and emitted triangles. */
static void refl__sb_free_batch(refl__sb *sb) {
    const refl_allocator *al = &sb->p->scene->allocator;
    int pairs = (sb->batch1 - sb->batch0) * sb->p->scene->object_count, i, k;
    for (i = 0; sb->slots && i < pairs; ++i) {
        refl__free(al, sb->slots[i].index);
        for (k = 0; k < REFL__SB_SHEETS; ++k) refl__free(al, sb->slots[i].pv[k]);
    }
    for (i = 0; sb->jobs && i < sb->job_count; ++i) refl__free(al, sb->jobs[i].out);
    refl__free(al, sb->slots);
    refl__free(al, sb->jobs);
    sb->slots = NULL;
    sb->jobs = NULL;
    sb->job_count = 0;
}

/* Where pixel (x, y) of a group, with nothing drawn on it, takes its
   reflection from (past the first order, its order too): the nearer of two drawn pixels of its
   group on opposite sides of it (left and right, above and below, or
   diagonally). Reflected triangles subdivided to different depths meet
   at edges bent differently (a T-junction), and the crack between them
   is a pixel wide; a hole wider than that stays one. Itself when none. */
static size_t refl__sb_crack_source(const refl__sb *sb, int x, int y) {
    static const int dir[4][2] = {{1, 0}, {0, 1}, {1, 1}, {1, -1}};
    const refl_frame *fr = sb->p->frame;
    size_t i = (size_t)y * (size_t)fr->width + (size_t)x, best = i;
    int k, e;
    for (k = 0; k < 4; ++k) {
        size_t side[2];
        int ok = 1;
        for (e = 0; e < 2 && ok; ++e) {
            int sx = x + (e ? -dir[k][0] : dir[k][0]), sy = y + (e ? -dir[k][1] : dir[k][1]);
            if (sx < 0 || sy < 0 || sx >= fr->width || sy >= fr->height) ok = 0;
            else side[e] = (size_t)sy * (size_t)fr->width + (size_t)sx;
            ok = ok && sb->group_of[side[e]] == sb->group_of[i] && sb->depth[side[e]] < 1.0f;
        }
        for (e = 0; e < 2 && ok; ++e)
            if (best == i || sb->depth[side[e]] < sb->depth[best]) best = side[e];
    }
    return best;
}

static void refl__sb_pixel_view(const refl__sb *sb, size_t i, refl_vec3 *d, refl_vec3 *q, refl_vec3 *n);

/* Pixel (x, y) under desc.sbc.trace_fallback (refl__sb_fallback): where
   its reflected ray (taken as the ray map's samples take it) meets
   anything, the pixel is rendered as RAYTRACE renders it, colour and
   point, and 1 is returned; else 0, and it keeps what SBC made of it (a
   hole: the environment, as without the option; most holes are the sky
   seen in the mirror, one ray each). */
static int refl__sb_trace_pixel(const refl__sb *sb, int x, int y) {
    refl_frame *fr = sb->p->frame;
    size_t i = (size_t)y * (size_t)fr->width + (size_t)x;
    refl_vec3 d, q, n, shown;
    refl_sbc_ray ray;
    refl__sbc_hit met;
    float rgb[3], depth;
    uint8_t stencil;
    int c;
    refl__sb_pixel_view(sb, i, &d, &q, &n);
    sb->traced_rays[y]++;
    if (!refl__sb_ray(sb, q, n, d, &ray, &met) || met.object < 0) return 0;
    refl__rt_pixel(sb->tracer, x, y, &sb->traced_rays[y], rgb, &shown, &depth, &stencil);
    for (c = 0; c < 3; ++c) fr->color[4 * i + (size_t)c] = refl__rt_unorm8(rgb[c]);
    fr->color[4 * i + 3] = 255;
    fr->points[3 * i] = shown.x;
    fr->points[3 * i + 1] = shown.y;
    fr->points[3 * i + 2] = shown.z;
    return 1;
}

/* Whether pixel i, of a group or not, shows nothing drawn (src: where
   its reflection comes from, itself or a crack's neighbour). */
static int refl__sb_hole(const refl__sb *sb, size_t i, size_t src) {
    return !(sb->group_of[i] && sb->depth[src] < 1.0f);
}

/* Whether desc.sbc.trace_fallback traces pixel i (src as above; first:
   what it shows is a first-order reflection): a hole, or a first-order
   point the ray map's samples around the pixel contradict: on an object
   none of their four rays meets, or nearer than the nearest of what they
   meet or farther than the farthest. Where the reflection is continuous
   between the samples, the distance to what it shows is too, and lies
   between theirs; a point outside is a surface the samples do not see:
   the floor drawn below the lid's rim where the truth sees the teapot's
   own surface (default 1920x1080 factor 4, mixed triangles split: mean
   1.01 -> 0.69 px with the distances, 0.67 px and max 549 -> 441 px with
   the objects too, 3% more rays). A thin object between the samples is
   traced too: exact, at a ray's cost. */
static int refl__sb_fallback(const refl__sb *sb, size_t i, size_t src, int first) {
    const refl_frame *fr = sb->p->frame;
    const refl__sb_side *sd;
    const float *shown = sb->points + 4 * src;
    int x = (int)(i % (size_t)fr->width), y = (int)(i / (size_t)fr->width), f = sb->factor, k;
    int u0 = (x - f / 2 + f) / f - 1, v0 = (y - f / 2 + f) / f - 1; /* the samples around it: u0, u0 + 1 */
    float lo = INFINITY, hi = 0.0f, d;
    int met_shown = 0, object = (int)shown[3] - 1;
    refl_vec3 q = refl_v3(sb->em.surface[3 * i], sb->em.surface[3 * i + 1], sb->em.surface[3 * i + 2]);
    if (refl__sb_hole(sb, i, src)) return 1;
    if (!first || sb->groups[sb->group_of[i] - 1].morph) return 0; /* a morph group has no samples here */
    sd = &sb->sides[sb->groups[sb->group_of[i] - 1].side];
    for (k = 0; k < 4; ++k) {
        int u = u0 + (k & 1), v = v0 + (k >> 1);
        size_t at = (size_t)v * (size_t)sb->map_w + (size_t)u;
        if (u < 0 || v < 0 || u >= sb->map_w || v >= sb->map_h || sd->valid[at] != 1) return 0;
        d = sd->hits[at].object < 0 ? INFINITY : refl_v3_length(refl_v3_sub(sd->hits[at].point, sd->rays[at].tail));
        lo = REFL__MIN(lo, d);
        hi = REFL__MAX(hi, d);
        met_shown |= sd->hits[at].object == object;
    }
    d = refl_v3_length(refl_v3_sub(refl_v3(shown[0], shown[1], shown[2]), q));
    return !met_shown || d < lo || d > hi;
}

static void refl__sb_resolve_row(void *arg, int y) {
    const refl__sb *sb = (const refl__sb *)arg;
    const refl_frame *fr = sb->p->frame;
    int x, c;
    for (x = 0; x < fr->width; ++x) {
        size_t i = (size_t)y * (size_t)fr->width + (size_t)x, src = i;
        float sub[3];
        if (sb->em.gbuf[4 * i + 3] == 0.0f) continue;
        if (sb->group_of[i] && !(sb->depth[i] < 1.0f)) src = refl__sb_crack_source(sb, x, y);
        if (sb->tracer && refl__sb_fallback(sb, i, src, 1) && refl__sb_trace_pixel(sb, x, y)) continue;
        /* a pixel of no group (its tile's samples lie on other surfaces)
           shows the environment, as one nothing reflects in */
        if (!refl__sb_hole(sb, i, src)) {
            const float *q = sb->points + 4 * src;
            for (c = 0; c < 3; ++c) sub[c] = (float)sb->color[4 * src + (size_t)c] * (1.0f / 255.0f);
            refl__em_composite(sb->p, sb->em.gbuf + 4 * i, x, y, sub, refl_v3(q[0], q[1], q[2]));
        } else {
            refl__em_composite(sb->p, sb->em.gbuf + 4 * i, x, y, NULL, refl_v3(NAN, NAN, NAN));
        }
    }
}

/* Pixel k's group in side sdk, whose samples are samples of sd, the
   side the pixel shows (sdk == sd in the first layer): that of the nearest
   sample on the pixel's own smooth piece of surface, else of the sample
   nearby whose point lies nearest the pixel's; -1: none. */
static int refl__sb_pixel_group(const refl__sb *sb, size_t k, const refl__sb_side *sd, const refl__sb_side *sdk) {
    const refl_frame *fr = sb->p->frame;
    int x = (int)(k % (size_t)fr->width), y = (int)(k / (size_t)fr->width), du, dv, best = -1, near = -1, u, v;
    float best_d2 = INFINITY, near_d2 = INFINITY;
    refl_vec3 q = refl_v3(sb->em.surface[3 * k], sb->em.surface[3 * k + 1], sb->em.surface[3 * k + 2]);
    refl_vec3 n = refl_v3_normalize(refl_v3(sb->em.gbuf[4 * k], sb->em.gbuf[4 * k + 1], sb->em.gbuf[4 * k + 2]));
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

/* The side of history `parent` followed by side id `id` (kind 0) or
   refracted through parent's glass (kind 1); -1: none sampled. */
static int refl__sb_find_side(const refl__sb *sb, int parent, float id, int kind) {
    int i;
    /* a child comes after its parent and the first order's sides */
    for (i = REFL__MAX(parent + 1, sb->sides1); i < sb->side_count; ++i)
        if (sb->sides[i].parent == parent && sb->sides[i].kind == kind && (kind || sb->sides[i].id == id)) return i;
    return -1;
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
        refl__sb_trace_path(sb, q, n, d, sb->em.gbuf[4 * i + 3], &pa);
        for (s = side, k = 1; k < pa.count && s >= 0; ++k)
            if ((s = refl__sb_find_side(sb, s, pa.id[k], 0)) >= 0)
                sb->group_of[(size_t)k * npx + i] = refl__sb_pixel_group(sb, i, &sb->sides[side], &sb->sides[s]) + 1;
        if (sb->layers > sb->orders && (k = refl__sb_refract_path(sb, q, n, d, sb->em.gbuf[4 * i + 3], &rp)) > 0 &&
            (s = refl__sb_find_side(sb, side, 0.0f, k)) >= 0)
            sb->group_of[(size_t)sb->orders * npx + i] =
                refl__sb_pixel_group(sb, i, &sb->sides[side], &sb->sides[s]) + 1;
    }
}

/* Sample rows [v, v + 1)'s histories: the side ids of their paths into
   sb->sample_id, and whether their glass refracts them out. */
static void refl__sb_sample_row(void *arg, int v) {
    refl__sb *sb = (refl__sb *)arg;
    size_t count = (size_t)sb->map_w * (size_t)sb->map_h;
    int u, k;
    for (u = 0; u < sb->map_w; ++u) {
        size_t m = (size_t)v * (size_t)sb->map_w + (size_t)u, i;
        int x, y;
        refl_vec3 d, q, n;
        refl__sb_path pa;
        refl__sb_refr rp;
        for (k = 0; k < sb->budget; ++k) sb->sample_id[(size_t)k * count + m] = 0.0f;
        sb->sample_refr[m] = 0;
        if (sb->sample_side[m] < 0) continue;
        refl__sb_sample_pixel(sb, u, v, &x, &y);
        i = (size_t)y * (size_t)sb->p->frame->width + (size_t)x;
        refl__sb_pixel_view(sb, i, &d, &q, &n);
        refl__sb_trace_path(sb, q, n, d, sb->em.gbuf[4 * i + 3], &pa);
        for (k = 0; k < pa.count; ++k) sb->sample_id[(size_t)k * count + m] = pa.id[k];
        k = refl__sb_refract_path(sb, q, n, d, pa.id[0], &rp);
        sb->sample_refr[m] = (uint8_t)(k > 0 ? k : 0);
    }
}

/* The higher layers' sides (the paper's reflection groups AB, ABA, ...
   and refractions through glass): every sample's history traced through
   the mirrors and glass alone, one side per history sampled (at most
   REFL__SB_HISTORIES; in sample order, so the same for any thread
   count), then their ray maps and pieces, a layer at a time (a piece lies
   within its parent's). */
static refl_result refl__sb_histories(refl__sb *sb) {
    const refl_scene *scene = sb->p->scene;
    const refl_allocator *al = &scene->allocator;
    size_t count = (size_t)sb->map_w * (size_t)sb->map_h, m;
    refl_scene sub;
    refl_object *objs = (refl_object *)refl__calloc(al, (size_t)REFL__MAX(scene->object_count, 1), sizeof(refl_object));
    refl_result r = REFL_OK;
    int i, n = 0, k, first, longest = 1, refr = 0, cap = sb->side_count + REFL__SB_HISTORIES;
    sb->mirror_object = (int *)refl__calloc(al, (size_t)REFL__MAX(scene->object_count, 1), sizeof(int));
    sb->normal_m = (refl_mat4 *)refl__calloc(al, (size_t)REFL__MAX(scene->object_count, 1), sizeof(refl_mat4));
    sb->sample_id = (float *)refl__calloc(al, (size_t)sb->budget * count, sizeof(float));
    sb->sample_refr = (uint8_t *)refl__calloc(al, count, 1);
    sb->sample_side = (int *)refl__calloc(al, (size_t)(sb->budget + 1) * count, sizeof(int));
    if (!objs || !sb->mirror_object || !sb->normal_m || !sb->sample_id || !sb->sample_refr || !sb->sample_side) {
        refl__free(al, objs);
        return REFL_ERROR_OUT_OF_MEMORY;
    }
    for (i = 0; i < scene->object_count; ++i) {
        refl_mat4 xf = scene->objects[i].transform;
        sb->normal_m[i] = refl__normal_matrix(xf);
        if (!refl__sb_goes_on(&scene->materials[scene->objects[i].material])) continue;
        sb->mirror_object[n] = i;
        objs[n++] = scene->objects[i];
    }
    sub = *scene;
    sub.objects = objs;
    sub.object_count = n;
    if (n) r = refl_bvh_build(&sub, al, &sb->mirrors);
    refl__free(al, objs);
    if (r != REFL_OK || !n) return r;
    /* every sample's first side, then its history */
    for (m = 0; m < (size_t)(sb->budget + 1) * count; ++m) sb->sample_side[m] = -1;
    for (i = 0; i < sb->side_count; ++i)
        for (m = 0; m < count; ++m)
            if (sb->sides[i].valid[m]) sb->sample_side[m] = i;
    sb->orders = sb->budget;
    rast_run_jobs(sb->p->rc, sb->map_h, refl__sb_sample_row, sb);
    for (k = 1; k < sb->budget; ++k)
        for (m = 0; m < count; ++m) {
            int parent = sb->sample_side[(size_t)(k - 1) * count + m], s;
            float id = sb->sample_id[(size_t)k * count + m];
            if (parent < 0 || id == 0.0f) continue;
            if ((s = refl__sb_find_side(sb, parent, id, 0)) < 0 && sb->side_count < cap) {
                refl__sb_side *sd = &sb->sides[s = sb->side_count++];
                sd->object = (int)fabsf(id) - 1;
                sd->id = id;
                sd->order = k + 1;
                sd->layer = k;
                sd->parent = parent;
            }
            sb->sample_side[(size_t)k * count + m] = s;
            if (s >= 0) longest = k + 1;
        }
    /* the refractions' layer follows the longest history's */
    sb->orders = longest;
    for (m = 0; m < count; ++m) {
        int parent = sb->sample_side[m], s;
        if (!sb->sample_refr[m] || parent < 0) continue;
        if ((s = refl__sb_find_side(sb, parent, 0.0f, sb->sample_refr[m])) < 0 && sb->side_count < cap) {
            refl__sb_side *sd = &sb->sides[s = sb->side_count++];
            sd->object = sb->sides[parent].object;
            sd->id = sb->sides[parent].id;
            sd->order = 1;
            sd->layer = longest;
            sd->parent = parent;
            sd->kind = sb->sample_refr[m];
        }
        sb->sample_side[(size_t)longest * count + m] = s;
        refr |= s >= 0;
    }
    sb->layers = longest + refr;
    for (k = 1; k < sb->layers; ++k) {
        for (first = 0; first < sb->side_count && sb->sides[first].layer != k; ++first) {}
        for (n = first; n < sb->side_count && sb->sides[n].layer == k; ++n) {}
        sb->map_first = first;
        rast_run_jobs(sb->p->rc, n - first, refl__sb_map_side, sb);
        for (i = first; i < n; ++i)
            if (!sb->sides[i].rays || !sb->sides[i].hits || !sb->sides[i].valid || !sb->sides[i].normals ||
                !sb->sides[i].comp || !sb->sides[i].group || !sb->sides[i].crossing)
                return REFL_ERROR_OUT_OF_MEMORY;
    }
    return REFL_OK;
}

/* refl__sb_resolve_row past the first order: a pixel's reflected colour
   is the nearest order's drawn colour (its order read off the visibility
   offset) times the reflectances along the pixel's own history to that
   order, or the environment along its last reflected ray times them all;
   glass adds what its refraction layer drew (else the environment beyond
   the glass) times (1 - F) tint at the entry and the refraction path's
   weight. The point shown: the first past the first reflector, as RAYTRACE
   records it (the second reflector's surface on an order-2 path), or with
   desc.debug.points_last the last one drawn (NaN where none). */
static void refl__sb_resolve_row_deep(void *arg, int y) {
    const refl__sb *sb = (const refl__sb *)arg;
    const refl__pass *p = sb->p;
    const refl_scene *scene = p->scene;
    refl_frame *fr = p->frame;
    size_t npx = (size_t)fr->width * (size_t)fr->height;
    int x, c, last = p->desc.debug.points_last;
    for (x = 0; x < fr->width; ++x) {
        size_t i = (size_t)y * (size_t)fr->width + (size_t)x, src = i;
        const float *g = sb->em.gbuf + 4 * i;
        int object = (int)fabsf(g[3]) - 1, k;
        const refl_material *m;
        float rgb[3], sub[3], w;
        refl_vec3 d, q, n, shown = refl_v3(NAN, NAN, NAN), t;
        refl__sb_path pa;
        if (g[3] == 0.0f || object < 0 || object >= scene->object_count) continue;
        if (sb->group_of[i] && !(sb->depth[i] < 1.0f)) src = refl__sb_crack_source(sb, x, y);
        if (sb->tracer && refl__sb_fallback(sb, i, src, (int)(sb->depth[src] * (float)sb->orders) == 0) &&
            refl__sb_trace_pixel(sb, x, y))
            continue;
        m = &scene->materials[scene->objects[object].material];
        refl__sb_pixel_view(sb, i, &d, &q, &n);
        refl__sb_trace_path(sb, q, n, d, g[3], &pa);
        if (!refl__sb_hole(sb, i, src)) {
            const float *pt = sb->points + 4 * src;
            k = REFL__CLAMP((int)(sb->depth[src] * (float)sb->orders), 0, pa.count - 1);
            for (c = 0; c < 3; ++c) sub[c] = (float)sb->color[4 * src + (size_t)c] * (1.0f / 255.0f);
            shown = refl_v3(pt[0], pt[1], pt[2]);
        } else {
            k = pa.count - 1;
            refl_environment_lookup(&scene->environment, pa.out, sub);
            for (c = 0; c < 3; ++c) sub[c] = REFL__CLAMP(sub[c], 0.0f, 1.0f);
        }
        /* order k's bounce fades by the distance to what it shows (none: wholly) */
        w = pa.weight[k] * refl_material_fade(refl__sb_material(sb, pa.id[k]),
                                              shown.x == shown.x ? refl_v3_length(refl_v3_sub(shown, pa.q[k])) : INFINITY);
        if (!last && pa.count > 1 && (k > 0 || !(shown.x == shown.x))) shown = pa.q[1];
        for (c = 0; c < 3; ++c) rgb[c] = w * sub[c];
        if (m->type == REFL_GLASS) {
            float ior = m->ior > 0.0f ? m->ior : 1.5f, tsub[3], f = pa.weight[0], tw = 1.0f;
            int tinted = m->tint[0] + m->tint[1] + m->tint[2] > 0.0f;
            refl_vec3 tshown = refl_v3(NAN, NAN, NAN);
            if (refl_v3_refract(d, n, 1.0f / ior, &t)) {
                refl__sb_refr rp;
                int through = sb->layers > sb->orders ? refl__sb_refract_path(sb, q, n, d, g[3], &rp) : -1;
                if (through < 0) { /* no refraction sampled, or off the glass: refracted once, as ENVMAP */
                    refl_environment_lookup(&scene->environment, t, tsub);
                } else if (!through) {
                    tsub[0] = tsub[1] = tsub[2] = 0.0f; /* still inside when the bounces run out */
                } else if (sb->group_of[(size_t)sb->orders * npx + i] && sb->refr_depth[i] < 1.0f) {
                    const float *pt = sb->refr_points + 4 * i;
                    for (c = 0; c < 3; ++c) tsub[c] = (float)sb->refr_color[4 * i + (size_t)c] * (1.0f / 255.0f);
                    if (through == 1) tshown = refl_v3(pt[0], pt[1], pt[2]); /* inside glass: none, as RAYTRACE */
                    tw = rp.weight;
                } else {
                    refl_environment_lookup(&scene->environment, rp.out, tsub);
                    tw = rp.weight;
                }
                for (c = 0; c < 3; ++c)
                    rgb[c] += (1.0f - f) * (tinted ? m->tint[c] : 1.0f) * tw * REFL__CLAMP(tsub[c], 0.0f, 1.0f);
                if (f < 0.5f) shown = tshown;
            } else {
                for (c = 0; c < 3; ++c) rgb[c] = sub[c]; /* total internal reflection */
            }
        }
        refl__em_put(fr, i, rgb, shown);
    }
}

/* ---- reflection morphing (paper 003 VI): groups backed by prebuilt grids ---- */

/* Row y's front pixels of objects drawn from grids: the group of the
   piece their view ray meets (a job per row). */
static void refl__sb_morph_row(void *arg, int y) {
    refl__sb *sb = (refl__sb *)arg;
    const refl__pass *p = sb->p;
    int x, W = p->frame->width;
    for (x = 0; x < W; ++x) {
        size_t i = (size_t)y * (size_t)W + (size_t)x;
        float id = sb->em.gbuf[4 * i + 3], tmax;
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
        float id = sb->em.gbuf[4 * k + 3];
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

/* The sides seen (reflector objects and sides with a pixel), their ray
   maps and pieces, and the groups: each side's pieces cut by tiles of
   sb->tile samples (the tile side doubles, up to REFL__SB_TILE_MAX, while
   there are more than a batch: REFL__SB_BATCH), and each pixel's group. */
static refl_result refl__sb_groups(refl__sb *sb) {
    const refl_scene *scene = sb->p->scene;
    const refl_allocator *al = &scene->allocator;
    const refl_frame *fr = sb->p->frame;
    size_t npx = (size_t)fr->width * (size_t)fr->height, k;
    uint8_t *sides = (uint8_t *)refl__calloc(al, (size_t)scene->object_count, 1);
    int *seen, i, side, pass, u, v, tu, tv;
    if (!sides) return REFL_ERROR_OUT_OF_MEMORY;
    for (k = 0; k < npx; ++k) {
        float id = sb->em.gbuf[4 * k + 3];
        int o = (int)fabsf(id) - 1;
        if (o >= 0 && o < scene->object_count) sides[o] |= (uint8_t)(id > 0.0f ? 1 : 2);
    }
    sb->sides = (refl__sb_side *)refl__calloc(al, 2 * (size_t)scene->object_count + REFL__SB_HISTORIES,
                                              sizeof(refl__sb_side));
    if (!sb->sides) {
        refl__free(al, sides);
        return REFL_ERROR_OUT_OF_MEMORY;
    }
    for (i = 0; i < scene->object_count; ++i)
        for (side = 0; side < 2; ++side)
            if ((sides[i] & (1 << side)) && !(side == 0 && refl__sb_morph_for(sb->p, i))) {
                refl__sb_side *sd = &sb->sides[sb->side_count++];
                sd->object = i;
                sd->id = side ? -(float)(i + 1) : (float)(i + 1);
                sd->order = 1;
                sd->parent = -1;
            }
    refl__free(al, sides);
    sb->map_first = 0;
    sb->sides1 = sb->side_count;
    rast_run_jobs(sb->p->rc, sb->side_count, refl__sb_map_side, sb);
    for (i = 0; i < sb->side_count; ++i)
        if (!sb->sides[i].rays || !sb->sides[i].hits || !sb->sides[i].valid || !sb->sides[i].normals ||
            !sb->sides[i].comp || !sb->sides[i].group || !sb->sides[i].crossing)
            return REFL_ERROR_OUT_OF_MEMORY;
    if (sb->budget > 1) {
        refl_result r = refl__sb_histories(sb);
        if (r != REFL_OK) return r;
    }
    /* count the groups (a tile's pieces), doubling the tile until they
       fit a batch (fewer groups, fewer projections) or the tile reaches
       REFL__SB_TILE_MAX (more batches then); then list them, each sample
       noting its group. */
    seen = (int *)refl__calloc(al, (size_t)sb->map_w * (size_t)sb->map_h, sizeof(int));
    if (!seen) return REFL_ERROR_OUT_OF_MEMORY;
    for (sb->tile = REFL__SB_TILE;; sb->tile *= 2) {
        int tw = (sb->map_w + sb->tile - 1) / sb->tile, th = (sb->map_h + sb->tile - 1) / sb->tile;
        int largest = sb->tile >= REFL__SB_TILE_MAX;
        for (pass = 0; pass < 2; ++pass) {
            sb->group_count = 0;
            for (i = 0; i < sb->side_count; ++i)
                for (tv = 0; tv < th; ++tv)
                    for (tu = 0; tu < tw; ++tu) {
                        refl__sb_side *sd = &sb->sides[i];
                        int first = sb->group_count, nseen = 0, uu0 = tu * sb->tile, vv0 = tv * sb->tile;
                        int uu1 = REFL__MIN(uu0 + sb->tile, sb->map_w), vv1 = REFL__MIN(vv0 + sb->tile, sb->map_h);
                        for (v = vv0; v < vv1; ++v)
                            for (u = uu0; u < uu1; ++u) {
                                size_t m = (size_t)v * (size_t)sb->map_w + (size_t)u;
                                int gi = 0;
                                if (!sd->valid[m]) continue;
                                while (gi < nseen && seen[gi] != sd->comp[m]) ++gi;
                                sd->group[m] = first + gi;
                                if (gi < nseen) continue;
                                seen[nseen++] = sd->comp[m];
                                if (pass) {
                                    refl__sb_group *g = &sb->groups[sb->group_count];
                                    g->side = i;
                                    g->object = sd->object;
                                    g->comp = sd->comp[m];
                                    g->u0 = uu0;
                                    g->v0 = vv0;
                                    g->u1 = uu1;
                                    g->v1 = vv1;
                                }
                                sb->group_count++;
                            }
                    }
            if (sb->group_count > REFL__SB_BATCH && !largest) break;
            if (!pass) {
                sb->groups = (refl__sb_group *)refl__calloc(al, (size_t)REFL__MAX(sb->group_count, 1),
                                                            sizeof(refl__sb_group));
                if (!sb->groups) {
                    refl__free(al, seen);
                    return REFL_ERROR_OUT_OF_MEMORY;
                }
            }
        }
        if (pass == 2) break;
    }
    refl__free(al, seen);
    sb->group_of = (int *)refl__calloc(al, npx, (size_t)sb->layers * sizeof(int));
    if (!sb->group_of) return REFL_ERROR_OUT_OF_MEMORY;
    /* each pixel's group in the first layer; the others' by rows */
    for (k = 0; k < npx; ++k) {
        float id = sb->em.gbuf[4 * k + 3];
        const refl__sb_side *sd = NULL;
        sb->group_of[k] = 0;
        for (i = 0; id != 0.0f && i < sb->side_count && sb->sides[i].order == 1 && !sb->sides[i].kind; ++i)
            if (sb->sides[i].id == id) sd = &sb->sides[i];
        if (sd) sb->group_of[k] = refl__sb_pixel_group(sb, k, sd, sd) + 1;
    }
    if (sb->layers > 1) rast_run_jobs(sb->p->rc, fr->height, refl__sb_assign_row, sb);
    return REFL_OK;
}

/* Projection and emission jobs of the batch's groups, run. */
static refl_result refl__sb_project_all(refl__sb *sb) {
    const refl_scene *scene = sb->p->scene;
    const refl_allocator *al = &scene->allocator;
    int pairs = (sb->batch1 - sb->batch0) * scene->object_count, i, g, o, t, k, n = 0;
    if (!sb->base) { /* the first batch: every object's vertices in the world, once */
        sb->base = (refl__sb_pv **)refl__calloc(al, (size_t)REFL__MAX(scene->object_count, 1), sizeof(refl__sb_pv *));
        if (!sb->base) return REFL_ERROR_OUT_OF_MEMORY;
        for (o = 0; o < scene->object_count; ++o) {
            int vc = scene->meshes[scene->objects[o].mesh]->vertex_count;
            sb->base[o] = (refl__sb_pv *)refl__calloc(al, (size_t)REFL__MAX(vc, 1), sizeof(refl__sb_pv));
            if (!sb->base[o]) return REFL_ERROR_OUT_OF_MEMORY;
        }
        rast_run_jobs(sb->p->rc, scene->object_count, refl__sb_base_object, sb);
    }
    sb->slots = (refl__sb_slot *)refl__calloc(al, (size_t)REFL__MAX(pairs, 1), sizeof(refl__sb_slot));
    if (!sb->slots) return REFL_ERROR_OUT_OF_MEMORY;
    rast_run_jobs(sb->p->rc, pairs, refl__sb_project_object, sb);
    for (i = 0; i < pairs; ++i) {
        const refl__sb_slot *slot = &sb->slots[i];
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
    for (g = sb->batch0; g < sb->batch1; ++g)
        for (o = 0; o < scene->object_count; ++o)
            n += REFL__MAX(sb->groups[g].sheets, 1) *
                 ((scene->meshes[scene->objects[o].mesh]->triangle_count + REFL__SB_CHUNK - 1) / REFL__SB_CHUNK);
    sb->jobs = (refl__sb_job *)refl__calloc(al, (size_t)REFL__MAX(n, 1), sizeof(refl__sb_job));
    if (!sb->jobs) return REFL_ERROR_OUT_OF_MEMORY;
    for (g = sb->batch0; g < sb->batch1; ++g) {
        if (!refl__sb_live(&sb->groups[g])) continue;
        for (o = 0; o < scene->object_count; ++o) {
            int tc = scene->meshes[scene->objects[o].mesh]->triangle_count;
            for (k = 0; k < REFL__MAX(sb->groups[g].sheets, 1); ++k)
                for (t = 0; t < tc; t += REFL__SB_CHUNK) {
                    refl__sb_job *j = &sb->jobs[sb->job_count++];
                    j->group = g;
                    j->object = o;
                    j->sheet = k;
                    j->first = t;
                    j->count = REFL__MIN(REFL__SB_CHUNK, tc - t);
                }
        }
    }
    rast_run_jobs(sb->p->rc, sb->job_count, refl__sb_emit_job, sb);
    for (i = 0; i < sb->job_count; ++i)
        if (sb->jobs[i].failed) return REFL_ERROR_OUT_OF_MEMORY;
    return REFL_OK;
}

static void refl__sb_free(refl__sb *sb) {
    const refl_allocator *al = &sb->p->scene->allocator;
    int i;
    for (i = 0; sb->groups && i < sb->group_count; ++i) {
        refl_sbc_destroy(sb->groups[i].sbc);
        refl__free(al, sb->groups[i].hits);
    }
    for (i = 0; sb->sides && i < sb->side_count; ++i) {
        refl__free(al, sb->sides[i].rays);
        refl__free(al, sb->sides[i].valid);
        refl__free(al, sb->sides[i].hits);
        refl__free(al, sb->sides[i].normals);
        refl__free(al, sb->sides[i].comp);
        refl__free(al, sb->sides[i].group);
        refl__free(al, sb->sides[i].crossing);
    }
    refl__free(al, sb->sides);
    refl__sb_free_batch(sb);
    for (i = 0; sb->base && i < sb->p->scene->object_count; ++i) refl__free(al, sb->base[i]);
    refl__free(al, sb->base);
    refl_bvh_destroy(sb->own_bvh);
    refl_bvh_destroy(sb->mirrors);
    refl__free(al, sb->mirror_object);
    refl__free(al, sb->normal_m);
    refl__free(al, sb->sample_id);
    refl__free(al, sb->sample_refr);
    refl__free(al, sb->sample_side);
    refl__free(al, sb->refr_color);
    refl__free(al, sb->refr_depth);
    refl__free(al, sb->refr_points);
    refl__free(al, sb->refr_points_depth);
    refl__free(al, sb->groups);
    refl__free(al, sb->em.gbuf);
    refl__free(al, sb->em.draws);
    refl__free(al, sb->em.surface);
    refl__free(al, sb->group_of);
    refl__free(al, sb->morph_base);
    refl__free(al, sb->stencil);
    refl__free(al, sb->color);
    refl__free(al, sb->depth);
    refl__free(al, sb->points);
    refl__free(al, sb->points_depth);
    if (sb->tracer) refl__rt_end(sb->tracer);
    refl__free(al, sb->tracer);
    refl__free(al, sb->traced_rays);
}

/* Everything up to the groups' trees (shared with refl_sbc_measure_camera_error). */
static refl_result refl__sb_setup(refl__sb *sb, refl__pass *p) {
    const refl_allocator *al = &p->scene->allocator;
    size_t npx = (size_t)p->frame->width * (size_t)p->frame->height;
    unsigned char *seen = NULL;
    refl_vec3 lo, hi, grow;
    refl_result r;
    int any = 0, g;
    memset(sb, 0, sizeof *sb);
    sb->p = p;
    sb->em.p = p;
    sb->factor = p->desc.sbc.ray_factor > 0 ? p->desc.sbc.ray_factor : REFL__SB_FACTOR;
    sb->map_w = (p->frame->width + sb->factor - 1) / sb->factor;
    sb->map_h = (p->frame->height + sb->factor - 1) / sb->factor;
    sb->error_px = p->desc.sbc.error_px > 0.0f ? p->desc.sbc.error_px : 1.0f;
    /* with the fallback, the pixels a group's edge leaves uncovered are
       traced: splitting mixed triangles costs more than it buys (default
       640x480 factor 2 with the fallback: 305 -> 178 ms a frame, mean
       0.29 -> 0.24 px) */
    sb->mixed_levels = p->desc.sbc.mixed_levels > 0   ? p->desc.sbc.mixed_levels
                       : p->desc.sbc.mixed_levels < 0 ? 0
                       : p->desc.sbc.trace_fallback   ? 0
                                                      : REFL__SB_MIXED_LEVELS;
    sb->batch = p->desc.sbc.batch_groups > 0 ? p->desc.sbc.batch_groups : REFL__SB_BATCH;
    sb->budget = REFL__CLAMP(p->desc.depth, 1, REFL__SB_ORDERS);
    sb->orders = sb->layers = 1;
    refl_scene_bounds(p->scene, &lo, &hi);
    grow = refl_v3_scale(refl_v3_sub(hi, lo), 0.01f);
    grow = refl_v3_add(grow, refl_v3(1e-4f, 1e-4f, 1e-4f));
    sb->box_lo = refl_v3_sub(lo, grow);
    sb->box_hi = refl_v3_add(hi, grow);
    sb->diagonal = refl_v3_length(refl_v3_sub(sb->box_hi, sb->box_lo));
    r = refl__em_gbuffer_new(&sb->em, &seen, &any);
    refl__free(al, seen);
    if (r != REFL_OK || !any) return r;
    if ((r = refl__models_bvh(p, &sb->bvh, &sb->own_bvh)) != REFL_OK) return r;
    sb->em.surface = (float *)refl__calloc(al, npx, 3 * sizeof(float));
    if (!sb->em.surface) return REFL_ERROR_OUT_OF_MEMORY;
    rast_run_jobs(p->rc, p->frame->height, refl__em_surface_row, &sb->em);
    if ((r = refl__sb_groups(sb)) != REFL_OK) return r;
    p->frame->stats.sbc.histories += sb->side_count;
    p->frame->stats.sbc.groups += sb->group_count;
    for (g = 0; p->desc.debug.sbc_ray_map && g < sb->side_count && !sb->sides[g].layer; ++g)
        p->desc.debug.sbc_ray_map(p->desc.debug.sbc_ray_map_user, sb->sides[g].object, sb->sides[g].rays, sb->sides[g].valid,
                            sb->map_w, sb->map_h);
    rast_run_jobs(p->rc, sb->group_count, refl__sb_build_group, sb);
    if ((r = refl__sb_morph_groups(sb)) != REFL_OK) return r;
    for (g = 0; g < sb->group_count; ++g) {
        refl_sbc_stats st;
        if (sb->groups[g].result != REFL_OK) return sb->groups[g].result;
        refl_sbc_get_stats(sb->groups[g].sbc, &st);
        p->frame->stats.sbc.pinhole_leaves += st.pinhole_leaves;
        p->frame->stats.sbc.ray_leaves += st.ray_leaves;
        p->frame->stats.rays += st.rays;
        p->frame->stats.model_bytes += st.bytes;
    }
    return REFL_OK;
}

/* refl_sbc_measure_camera_error's state: per truth pixel, the distance to
   the nearest image of its point and the kind of leaf that made it. */
typedef struct refl__sb_measure {
    const refl_frame *truth;
    const refl__sb *sb;
    double *error;                /* INFINITY: no image within REFL__SB_MEASURE_REACH */
    uint8_t *kind;                /* refl_sbc_leaf_kind */
    double *own_error;            /* at sample pixels: through the pixel's own group, INFINITY: none */
    uint8_t *own_kind;            /* ... and its leaf there; NONE off the samples */
    int cells_x, cells_y;         /* REFL__SB_MEASURE_CELL pixel cells, each listing the groups */
    int *cell_start, *cell_list;  /* whose images can land within reach of its pixels */
    refl_sbc_camera_error *out;
} refl__sb_measure;

#define REFL__SB_MEASURE_REACH 8.0 /* pixels: an image further off shows another point */
#define REFL__SB_MEASURE_CELL 32   /* pixels per side of the measure's cells */

/* Group g's pixels that an image of it can reach: an image lands on the
   group's first reflector points (its tile and ring), and one further off
   than the reach does not count. */
static void refl__sb_measure_rect(const refl__sb *sb, const refl__sb_group *g, int r[4]) {
    const int reach = (int)REFL__SB_MEASURE_REACH + 1;
    r[0] = (g->u0 - 1) * sb->factor - reach;
    r[1] = (g->v0 - 1) * sb->factor - reach;
    r[2] = (g->u1 + 1) * sb->factor + reach;
    r[3] = (g->v1 + 1) * sb->factor + reach;
}

/* The cells' group lists (counted, then filled), groups in index order. */
static refl_result refl__sb_measure_cells(refl__sb_measure *ms) {
    const refl__sb *sb = ms->sb;
    const refl_allocator *al = &sb->p->scene->allocator;
    const int cell = REFL__SB_MEASURE_CELL;
    int pass, g, cx, cy, cells;
    ms->cells_x = (ms->truth->width + cell - 1) / cell;
    ms->cells_y = (ms->truth->height + cell - 1) / cell;
    cells = ms->cells_x * ms->cells_y;
    ms->cell_start = (int *)refl__calloc(al, (size_t)cells + 1, sizeof(int));
    if (!ms->cell_start) return REFL_ERROR_OUT_OF_MEMORY;
    for (pass = 0; pass < 2; ++pass) {
        for (g = 0; g < sb->group_count; ++g) {
            int r[4];
            if (!sb->groups[g].sbc) continue;
            refl__sb_measure_rect(sb, &sb->groups[g], r);
            for (cy = REFL__MAX(r[1], 0) / cell; cy <= REFL__MIN(r[3] / cell, ms->cells_y - 1); ++cy)
                for (cx = REFL__MAX(r[0], 0) / cell; cx <= REFL__MIN(r[2] / cell, ms->cells_x - 1); ++cx) {
                    if (!pass) ms->cell_start[cy * ms->cells_x + cx + 1]++;
                    else ms->cell_list[ms->cell_start[cy * ms->cells_x + cx]++] = g;
                }
        }
        if (!pass) {
            for (cx = 0; cx < cells; ++cx) ms->cell_start[cx + 1] += ms->cell_start[cx];
            ms->cell_list = (int *)refl__calloc(al, (size_t)REFL__MAX(ms->cell_start[cells], 1), sizeof(int));
            if (!ms->cell_list) return REFL_ERROR_OUT_OF_MEMORY;
        } else { /* the fill moved every start to the next cell's */
            for (cx = cells; cx > 0; --cx) ms->cell_start[cx] = ms->cell_start[cx - 1];
            ms->cell_start[0] = 0;
        }
    }
    return REFL_OK;
}

/* Row y of the truth: each point projected into every group of its
   reflector, as the method projects a vertex. */
static void refl__sb_measure_row(void *arg, int y) {
    refl__sb_measure *ms = (refl__sb_measure *)arg;
    const refl__sb *sb = ms->sb;
    const refl_frame *t = ms->truth;
    int x, c;
    for (x = 0; x < t->width; ++x) {
        size_t i = (size_t)y * (size_t)t->width + (size_t)x;
        const float *q = t->points + 3 * i;
        int object = t->stencil[i] - 1, own = sb->group_of[i] - 1;
        int cell = (y / REFL__SB_MEASURE_CELL) * ms->cells_x + x / REFL__SB_MEASURE_CELL;
        double best = INFINITY;
        refl_sbc_leaf_kind kind = REFL_SBC_LEAF_NONE;
        refl__sb_pv v;
        int sx, sy;
        ms->error[i] = ms->own_error[i] = INFINITY;
        ms->kind[i] = ms->own_kind[i] = REFL_SBC_LEAF_NONE;
        if (object < 0 || !refl__isfinite(q[0]) || !refl__isfinite(q[1]) || !refl__isfinite(q[2])) continue;
        memset(&v, 0, sizeof v);
        v.world = refl_v3(q[0], q[1], q[2]);
        refl__sb_sample_pixel(sb, x / sb->factor, y / sb->factor, &sx, &sy);
        if (sx == x && sy == y) { /* a sample: its own group's camera, where the build checked the fit */
            refl_sbc_leaf_kind k = own >= 0 && sb->groups[own].sbc ? refl_sbc_leaf_at(sb->groups[own].sbc, v.world)
                                                                   : REFL_SBC_LEAF_NONE;
            ms->own_kind[i] = (uint8_t)(k == REFL_SBC_LEAF_RAY_LIST ? REFL_SBC_LEAF_RAY_LIST : REFL_SBC_LEAF_PINHOLE);
            for (v.sheet = 0; k != REFL_SBC_LEAF_NONE && v.sheet < sb->groups[own].sheets; ++v.sheet) {
                refl__sb_project(sb, &sb->groups[own], &v);
                if (v.ok)
                    ms->own_error[i] = REFL__MIN(ms->own_error[i], hypot((double)v.sx - ((double)x + 0.5),
                                                                          (double)v.sy - ((double)y + 0.5)));
            }
        }
        for (c = ms->cell_start[cell]; c < ms->cell_start[cell + 1]; ++c) {
            const refl__sb_group *gr = &sb->groups[ms->cell_list[c]];
            double dx, dy, e;
            int rect[4];
            if (gr->object != object && !(object == 254 && gr->object >= 254)) continue;
            refl__sb_measure_rect(sb, gr, rect);
            if (x < rect[0] || x > rect[2] || y < rect[1] || y > rect[3]) continue;
            for (v.sheet = 0; v.sheet < gr->sheets; ++v.sheet) {
                refl__sb_project(sb, gr, &v);
                if (!v.ok) continue;
                dx = (double)v.sx - ((double)x + 0.5);
                dy = (double)v.sy - ((double)y + 0.5);
                e = sqrt(dx * dx + dy * dy);
                if (e < best) {
                    best = e;
                    kind = refl_sbc_leaf_at(gr->sbc, v.world);
                }
            }
        }
        if (best <= REFL__SB_MEASURE_REACH) {
            ms->error[i] = best;
        } else if (own >= 0 && sb->groups[own].sbc) { /* no image: charged to the leaf its own group holds it in */
            kind = refl_sbc_leaf_at(sb->groups[own].sbc, v.world);
        }
        ms->kind[i] = (uint8_t)(kind == REFL_SBC_LEAF_RAY_LIST ? REFL_SBC_LEAF_RAY_LIST : REFL_SBC_LEAF_PINHOLE);
    }
}

/* The summaries of the pixels the measure left, by leaf kind: over every
   pixel the nearest image, over the ray map's sample pixels the image
   through the pixel's own group. */
static refl_result refl__sb_measure_summary(const refl__sb_measure *ms) {
    const refl__sb *sb = ms->sb;
    const refl_allocator *al = &sb->p->scene->allocator;
    int w = ms->truth->width, h = ms->truth->height, k, x, y;
    double *errors = (double *)refl__calloc(al, (size_t)w * (size_t)h, sizeof(double));
    refl_reflection_error *out[4];
    if (!errors) return REFL_ERROR_OUT_OF_MEMORY;
    out[0] = &ms->out->pinhole;
    out[1] = &ms->out->ray_list;
    out[2] = &ms->out->pinhole_samples;
    out[3] = &ms->out->ray_list_samples;
    for (k = 0; k < 4; ++k) {
        uint8_t want = (uint8_t)(k & 1 ? REFL_SBC_LEAF_RAY_LIST : REFL_SBC_LEAF_PINHOLE);
        const uint8_t *kind = k < 2 ? ms->kind : ms->own_kind;
        const double *error = k < 2 ? ms->error : ms->own_error;
        long long counted = 0, matched = 0;
        double sum = 0.0;
        for (y = 0; y < h; ++y)
            for (x = 0; x < w; ++x) {
                size_t i = (size_t)y * (size_t)w + (size_t)x;
                if (kind[i] != want) continue;
                ++counted;
                if (error[i] == INFINITY) continue;
                errors[matched++] = error[i];
                sum += error[i];
            }
        refl__metric_summary(errors, matched, sum, counted, counted - matched, 0, out[k]);
    }
    refl__free(al, errors);
    return REFL_OK;
}

static const char *refl__options_sbc(refl_render_desc *d) {
    const refl_sbc_options *o = &d->sbc;
    if (!(o->error_px >= 0.0f) || !refl__isfinite(o->error_px)) return "sbc.error_px: finite, 0 (1) or more";
    if (o->ray_factor < 0 || o->ray_factor > 64) return "sbc.ray_factor: 0 (2) to 64";
    if (o->batch_groups < 0 || o->batch_groups > 254) return "sbc.batch_groups: 0 (254) to 254";
    if (o->trace_fallback < 0 || o->trace_fallback > 1) return "sbc.trace_fallback: 0 or 1";
    if (o->mixed_levels > 6) return "sbc.mixed_levels: negative (never), 0 (the default) or 1 to 6";
    if (o->morph_count < 0 || (o->morph_count > 0 && !o->morphs))
        return "sbc.morphs: morph_count 0, or the array of that many grids";
    return NULL;
}

/* An SBC frame, or (ms) SBC's cameras measured in place of its reflections. */
static refl_result refl__sb_run(refl__pass *p, refl__sb_measure *ms) {
    const refl_allocator *al = &p->scene->allocator;
    refl_frame *fr = p->frame;
    size_t npx = (size_t)fr->width * (size_t)fr->height;
    double t0 = refl__now_ms(), t1;
    refl__sb sb;
    refl_result r = refl__sb_setup(&sb, p);
    int i;
    t1 = refl__now_ms();
    fr->stats.ms_build += t1 - t0;
    if (ms) {
        size_t n = (size_t)fr->width * (size_t)fr->height;
        ms->sb = &sb;
        ms->error = (double *)refl__calloc(al, n, sizeof(double));
        ms->kind = (uint8_t *)refl__calloc(al, n, 1);
        ms->own_error = (double *)refl__calloc(al, n, sizeof(double));
        ms->own_kind = (uint8_t *)refl__calloc(al, n, 1);
        if (r == REFL_OK && (!ms->error || !ms->kind || !ms->own_error || !ms->own_kind))
            r = REFL_ERROR_OUT_OF_MEMORY;
        /* no reflector in view: nothing to measure (the truth shows none either) */
        if (r == REFL_OK && sb.group_of && (r = refl__sb_measure_cells(ms)) == REFL_OK) {
            rast_run_jobs(p->rc, fr->height, refl__sb_measure_row, ms);
            r = refl__sb_measure_summary(ms);
        }
        refl__free(al, ms->error);
        refl__free(al, ms->kind);
        refl__free(al, ms->own_error);
        refl__free(al, ms->own_kind);
        refl__free(al, ms->cell_start);
        refl__free(al, ms->cell_list);
        refl__sb_free(&sb);
        return r;
    }
    if (r == REFL_OK && sb.group_count) {
        sb.color = (uint8_t *)refl__calloc(al, npx, 4);
        sb.depth = (float *)refl__calloc(al, npx, sizeof(float));
        sb.points = (float *)refl__calloc(al, npx, 4 * sizeof(float));
        sb.points_depth = (float *)refl__calloc(al, npx, sizeof(float));
        sb.stencil = (uint8_t *)refl__calloc(al, npx, 1);
        if (!sb.color || !sb.depth || !sb.points || !sb.points_depth || !sb.stencil) r = REFL_ERROR_OUT_OF_MEMORY;
        if (r == REFL_OK && sb.layers > sb.orders) {
            sb.refr_color = (uint8_t *)refl__calloc(al, npx, 4);
            sb.refr_depth = (float *)refl__calloc(al, npx, sizeof(float));
            sb.refr_points = (float *)refl__calloc(al, npx, 4 * sizeof(float));
            sb.refr_points_depth = (float *)refl__calloc(al, npx, sizeof(float));
            if (!sb.refr_color || !sb.refr_depth || !sb.refr_points || !sb.refr_points_depth)
                r = REFL_ERROR_OUT_OF_MEMORY;
        }
        if (r == REFL_OK) r = refl__sb_clear(&sb);
        /* groups in batches of the stencil's values, each within one layer
           (the sides, so the groups, come layer by layer); a group's pixels
           are its own in its layer, so a layer's batches' depth tests never
           meet, and the orders meet by the visibility offset */
        for (sb.batch0 = 0; r == REFL_OK && sb.batch0 < sb.group_count; sb.batch0 = sb.batch1) {
            int end = REFL__MIN(sb.batch0 + sb.batch, sb.group_count);
            sb.layer = refl__sb_group_layer(&sb, &sb.groups[sb.batch0]);
            sb.batch1 = sb.batch0 + 1;
            while (sb.batch1 < end && refl__sb_group_layer(&sb, &sb.groups[sb.batch1]) == sb.layer) ++sb.batch1;
            r = refl__sb_project_all(&sb);
            for (i = 0; i < sb.job_count; ++i) {
                fr->stats.sbc.projections += sb.jobs[i].projections;
                fr->stats.sbc.projected += sb.jobs[i].projected;
            }
            if (r == REFL_OK) r = refl__sb_draw(&sb);
            refl__sb_free_batch(&sb);
            if (r == REFL_OK && sb.layer + 1 < sb.orders &&
                (sb.batch1 == sb.group_count || refl__sb_group_layer(&sb, &sb.groups[sb.batch1]) != sb.layer))
                refl__sb_pass_through(&sb);
        }
        t0 = refl__now_ms();
        fr->stats.ms_reflect += t0 - t1;
        if (r == REFL_OK && p->desc.sbc.trace_fallback) {
            sb.tracer = (refl__rt *)refl__calloc(al, 1, sizeof(refl__rt));
            sb.traced_rays = (long long *)refl__calloc(al, (size_t)fr->height, sizeof(long long));
            if (!sb.tracer || !sb.traced_rays) r = REFL_ERROR_OUT_OF_MEMORY;
            if (r == REFL_OK) r = refl__rt_begin(sb.tracer, p, sb.bvh);
        }
        if (r == REFL_OK)
            rast_run_jobs(p->rc, fr->height, sb.layers > 1 ? refl__sb_resolve_row_deep : refl__sb_resolve_row, &sb);
        for (i = 0; sb.traced_rays && i < fr->height; ++i) fr->stats.rays += sb.traced_rays[i];
        fr->stats.ms_composite += refl__now_ms() - t0;
    }
    if (r == REFL_OK) {
        rast_targets t = refl__frame_targets(fr);
        r = refl__result_from_rast(rast_set_targets(p->rc, &t));
    }
    refl__sb_free(&sb);
    return r;
}

static refl_result refl__method_sbc(refl__pass *p) { return refl__sb_run(p, NULL); }

REFL_API refl_result refl_sbc_measure_camera_error(const refl_scene *scene, const refl_view *view,
                                                  const refl_render_desc *desc, const refl_frame *truth,
                                                  refl_sbc_camera_error *out) {
    refl__sb_measure ms;
    refl_render_desc given, d;
    refl_frame *frame = NULL;
    rast_context *rc = NULL;
    refl__pass p;
    const char *why;
    refl_result r;
    if (!out) return REFL_ERROR_INVALID_ARGUMENT;
    memset(out, 0, sizeof *out);
    if (!scene || !view || !truth || !truth->points || !truth->stencil) return REFL_ERROR_INVALID_ARGUMENT;
    if (view->width != truth->width || view->height != truth->height) return REFL_ERROR_INVALID_SIZE;
    memset(&given, 0, sizeof given);
    if (desc) given = *desc;
    given.method = REFL_SBC;
    given.depth = 1; /* the first order's cameras, as the truth's points are first bounces */
    given.object_methods = NULL;
    given.object_method_count = 0;
    if ((r = refl__resolve_desc(&given, &d, &why)) != REFL_OK) return r;
    memset(&ms, 0, sizeof ms);
    ms.truth = truth;
    ms.out = out;
    r = refl_frame_create(truth->width, truth->height, &scene->allocator, &frame);
    if (r == REFL_OK && refl__frame_rule(scene, view, frame)) r = REFL_ERROR_INVALID_ARGUMENT;
    if (r == REFL_OK) r = refl__context_create(scene, d.threads, &rc);
    if (r == REFL_OK) r = refl__base_pass(&p, scene, view, &d, frame, rc, NULL);
    if (r == REFL_OK) r = refl__sb_run(&p, &ms);
    rast_context_destroy(rc);
    refl_frame_destroy(frame);
    return r;
}
