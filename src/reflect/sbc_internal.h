/* Private declarations of the SBC method (paper 003; docs/methods/sbc.md):
   a frame's state and the entry points its stages share.
     m_sbc.c        options, setup, the frame's orchestration, the method
     sbc_raymap.c   1. ray maps; past the first order, the histories
     sbc_groups.c   2. pieces, rings, reflection groups and their trees,
                       each pixel's group; morphing grids' groups
     sbc_project.c  3. projection, 4. triangle emission and subdivision,
                       in batches of groups
     sbc_draw.c     4. the batches drawn into the reflections' targets
     sbc_resolve.c  5. composite, cracks, the ray-traced fallback
     sbc_measure.c  refl_sbc_measure_camera_error
   This header needs internal.h and cam_sbc_internal.h only (the G-buffer
   and the tracer are pointers to m_envmap.c's and m_raytrace.c's types);
   among themselves the SBC modules may come in any order. They use the
   G-buffer and composite of m_envmap.c, the tracer of m_raytrace.c, the
   draw programs of shade.c and metrics.c's summary, so they follow those
   in the Makefile's REFLECT_IMPL. */
#include "cam_sbc_internal.h"

#define REFL__SB_MIXED_LEVELS 4     /* subdivisions while mixed with no scale known yet, at most */
#define REFL__SB_GUARD 2            /* a tile's group also holds its piece's rays this many samples past it */
#define REFL__SB_MEMORY_MB 2048     /* the frame's working memory at most (desc.sbc.memory_mb's default) */
#define REFL__SB_BATCH 254          /* groups projected and drawn at once, at most: the stencil's values but 0 */
#define REFL__SB_FLOATS 12          /* per emitted vertex: clip position, world position, normal, uv */
#define REFL__SB_ORDERS 8           /* reflection orders traced at most (desc.depth beyond: cut here) */
#define REFL__SB_HISTORIES 64       /* histories beyond the first order, at most: the rest end a step early */
#define REFL__SB_SHEETS REFL_SBC_SHEETS /* a group's sheets at most (refl_sbc_project_sheets) */

/* ---- the state of a frame ------------------------------------------------------ */

/* What a side's ray map holds per sample (refl__sb_side: rays, hits, normals,
   comp, group, valid, crossing): the bound desc.sbc.memory_mb counts it. */
#define REFL__SB_SAMPLE_BYTES \
    (sizeof(refl_sbc_ray) + sizeof(refl__sbc_hit) + sizeof(refl_vec3) + 2 * sizeof(int) + 2)

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

/* A reflection group: one piece of a side's ray map, whole when planar,
   else within one tile, its rays (those of the piece in the tile grown by
   REFL__SB_GUARD samples: neighbouring tiles' frustums overlap) and one
   ring of rays extrapolated around them. */
typedef struct refl__sb_group {
    int side, object, comp;       /* comp: its piece of the side */
    int u0, v0, u1, v1;           /* its tile: samples [u0, u1) x [v0, v1) */
    int whole;                    /* the whole piece (a planar one), not a tile of it */
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
   (into each sheet), the others as they are (the batch's base). */
typedef struct refl__sb_slot {
    int *index;                   /* per mesh vertex: its place in pv, -1: outside the box (base) */
    refl__sb_pv *pv[REFL__SB_SHEETS]; /* per sheet of the group */
    int count;                    /* vertices in the box */
    int failed;
} refl__sb_slot;

/* One emission job: triangles [first, first + count) of `object` into `group`'s `sheet`. */
typedef struct refl__sb_job {
    int group, object, sheet, first, count;
    float *out;                   /* REFL__SB_FLOATS per vertex, three per triangle */
    size_t out_count, out_cap;    /* vertices */
    long long projections, projected;
    struct refl__sb_memo *memo;   /* while it runs, from its first midpoint on (NULL: none to spare; sbc_project.c) */
    int failed;
} refl__sb_job;

/* The mirrors and glass alone, which histories past the first order are
   traced through (the paper traces the reflectors alone; sbc_raymap.c). */
typedef struct refl__sb_mirrors {
    refl_bvh *bvh;                /* NULL: the scene has none */
    int *object;                  /* its objects' scene indices */
    refl_mat4 *normal_m;          /* per scene object: the normals' matrix */
} refl__sb_mirrors;

/* While the histories are sampled (sbc_raymap.c): per ray map sample. */
typedef struct refl__sb_samples {
    float *id;                    /* budget x map: per order, the side id each sample's path meets, 0: none */
    uint8_t *refr;                /* per sample: the kind of its refraction path (1, 2), 0: none */
    int *side;                    /* (budget + 1) x map: per layer, each sample's side, -1: none */
} refl__sb_samples;

/* The groups projected and drawn at once (sbc_project.c). */
typedef struct refl__sb_batch {
    int size;                     /* groups per batch at most (desc.sbc.batch_groups resolved) */
    int first, end;               /* the groups projected and drawn now: [first, end) */
    int layer;                    /* their layer (one per batch) */
    refl__sb_pv **base;           /* per object: every mesh vertex in the world, projecting nowhere (kept) */
    refl__sb_slot *slots;         /* per group of the batch x object: its vertices */
    refl__sb_job *jobs;
    int job_count;
} refl__sb_batch;

/* Scratch targets the groups draw into (sbc_draw.c): the colour pass's
   (colour, depth) and the points pass's (world point and object + 1, depth). */
typedef struct refl__sb_canvas {
    float *color;                 /* linear RGBA, as the frame's */
    float *depth;
    float *points, *points_depth;
} refl__sb_canvas;

/* The fallback's tracer (sbc_resolve.c), while the composite runs: for
   every pixel with desc.sbc.trace_fallback, else (SBC-traced) for the
   pixels of groups whose rays fold (refl__sb_checked). */
typedef struct refl__sb_tracer {
    struct refl__rt *rt;          /* how RAYTRACE renders a pixel; NULL: no fallback */
    long long *rays;              /* per row, the rays the fallback cast */
    long long *pixels;            /* per row, the pixels it rendered */
    int folds_only;               /* only the pixels of folding groups */
} refl__sb_tracer;

typedef struct refl__sb {
    refl__pass *p;
    struct refl__em *em;          /* the reflectors' G-buffer and surface points (m_envmap.c's) */
    /* options, resolved */
    int factor;                   /* a ray map sample every factor x factor pixels */
    int mixed_levels;             /* desc.sbc.mixed_levels resolved: -1 to the pixel, 0 never, else levels */
    float error_px;
    size_t memory_limit;          /* desc.sbc.memory_mb, in bytes */
    size_t memory_fixed;          /* what the ray maps and the groups' trees hold */
    long long vertices;           /* the scene's, all objects': a group's slot indexes them all */
    /* the scene */
    float diagonal;               /* the scene's, grown 1%: D */
    refl_vec3 box_lo, box_hi;     /* the scene's box, grown 1% */
    refl_bvh *bvh;                /* the scene's, for the rays' first hits (the renderer's) */
    refl_bvh *own_bvh;            /* bvh when no renderer keeps it */
    /* 1. ray maps (sbc_raymap.c) */
    int map_w, map_h;             /* the ray map's size */
    refl__sb_side *sides;
    int side_count, sides1;       /* sides, and those of the first order (they come first) */
    int map_first;                /* the first side refl__sb_map_side's jobs map */
    /* higher orders (desc.depth > 1): the paper's reflection histories */
    int budget;                   /* bounces a path may take: desc.depth, at most REFL__SB_ORDERS */
    int orders;                   /* reflection orders drawn (k_max): the longest history sampled */
    int layers;                   /* orders, plus one for refractions when any was sampled */
    refl__sb_mirrors mirrors;
    refl__sb_samples samples;
    /* 2. groups (sbc_groups.c) */
    refl__sb_group *groups;
    int group_count;
    int tile;                     /* a group's tile side in samples */
    int *group_of;                /* layers x pixels: per layer and pixel, group index + 1, 0: none */
    int *morph_base;              /* per object: its morph groups' first index, -1: none */
    /* 3., 4. projected and drawn in batches (sbc_project.c, sbc_draw.c) */
    refl__sb_batch batch;
    uint8_t *stencil;             /* per pixel: its group's place in the batch + 1, 0: none */
    refl__sb_canvas drawn;        /* the reflections */
    refl__sb_canvas refr;         /* the refraction layer's, drawn apart: it adds to them, never hides them */
    /* 5. composite (sbc_resolve.c) */
    refl__sb_tracer tracer;
} refl__sb;

/* ---- cam_sbc_morph.c: a morphing grid's pieces, as groups of a frame ---------------- */

/* For the eye in grid m: where points projecting into piece `piece` may
   lie; its nodes' hits (appended to out when not NULL; how many); at the
   eye's tetrahedron (nodes, weights w), the piece's sheets, a point's
   images at the four nodes per sheet (into slot, masks), and sheet
   `sheet` of those blended (1, or 0 when a node of positive weight has no
   image). */
static void refl__sbm_piece_box(const refl_sbc_morph *m, refl_vec3 eye, int piece, refl_vec3 *lo, refl_vec3 *hi);
static int refl__sbm_tet_hits(const refl_sbc_morph *m, refl_vec3 eye, int piece, refl__sbc_hit *out);
static int refl__sbm_piece_sheets(const refl_sbc_morph *m, const int nodes[4], const float w[4], int piece);
static void refl__sbm_project4_sheets(const refl_sbc_morph *m, const int nodes[4], const float w[4], int piece,
                                      refl_vec3 p, int sheets, float *slot, int masks[4]);
static int refl__sbm_blend_sheet(const float *slot, const int masks[4], const float w[4], int sheet, refl_vec3 *first,
                                 float *dist, int *across, int *ambiguous);

/* ---- m_sbc.c ------------------------------------------------------------------- */

/* Everything up to the groups' trees (a frame's, or the camera measure's);
   refl__sb_free frees it, also after a failure. */
static refl_result refl__sb_setup(refl__sb *sb, refl__pass *p);
static void refl__sb_free(refl__sb *sb);

/* ---- sbc_raymap.c: 1. ray maps, histories -------------------------------------- */

/* The sides seen, their ray maps and pieces; past the first order the
   histories' sides too. refl__sb_ray_maps_free frees them. */
static refl_result refl__sb_ray_maps(refl__sb *sb);
static void refl__sb_ray_maps_free(refl__sb *sb);
/* The ray map sample (u, v)'s pixel. */
static void refl__sb_sample_pixel(const refl__sb *sb, int u, int v, int *x, int *y);
/* The reflected ray of surface point q with normal n (towards the viewer)
   seen along view direction d, and what it meets first; 0 for a ray of
   zero length. */
static int refl__sb_ray(const refl__sb *sb, refl_vec3 q, refl_vec3 n, refl_vec3 d, refl_sbc_ray *ray,
                        refl__sbc_hit *met);
/* Pixel i's view direction, surface point and unit normal towards the viewer. */
static void refl__sb_pixel_view(const refl__sb *sb, size_t i, refl_vec3 *d, refl_vec3 *q, refl_vec3 *n);
/* The material of G-buffer side id `id` (object + 1, negated on the back). */
static const refl_material *refl__sb_material(const refl__sb *sb, float id);

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
static void refl__sb_trace_path(const refl__sb *sb, refl_vec3 q, refl_vec3 n, refl_vec3 d, float id,
                                refl__sb_path *pa);
/* What a path from o along unit d meets first among the mirrors and glass. */
static int refl__sb_mirror_hit(const refl__sb *sb, refl_vec3 o, refl_vec3 near, refl_vec3 d, int self, refl_hit *h);
/* Where a path leaves the depth buffer's point q of object `object`, seen along d. */
static refl_vec3 refl__sb_path_start(const refl__sb *sb, refl_vec3 q, refl_vec3 d, int object);
/* A path refracted through glass (refl__sb_refract_path). */
typedef struct refl__sb_refr {
    refl_vec3 tail, out, normal;
    float weight;
} refl__sb_refr;
static int refl__sb_refract_path(const refl__sb *sb, refl_vec3 q, refl_vec3 n, refl_vec3 d, float id,
                                 refl__sb_refr *rp);
/* The side of history `parent` followed by side id `id` (kind 0) or
   refracted through parent's glass (kind 1); -1: none sampled. */
static int refl__sb_find_side(const refl__sb *sb, int parent, float id, int kind);

/* ---- sbc_groups.c: 2. pieces and groups ------------------------------------------ */

/* Side sd's pieces (sd->comp), from its ray map. */
static void refl__sb_pieces(const refl__sb *sb, refl__sb_side *sd);
/* The groups of the sides' pieces and each pixel's group per layer; then
   (a job per group) each group's tree; then the morphing grids' groups.
   refl__sb_groups_free frees them. */
static refl_result refl__sb_groups(refl__sb *sb);
static void refl__sb_build_group(void *arg, int g);
static refl_result refl__sb_morph_groups(refl__sb *sb);
static void refl__sb_groups_free(refl__sb *sb);
/* The caller's grid for object o whose tetrahedra hold the eye, or NULL. */
static const refl_sbc_morph *refl__sb_morph_for(const refl__pass *p, int o);

/* ---- sbc_project.c: 3. projection, 4. emission ----------------------------------- */

/* Projects v (world set) into group g's sheet v->sheet. */
static void refl__sb_project(const refl__sb *sb, const refl__sb_group *g, refl__sb_pv *v);
/* The batch's projection and emission jobs, run; refl__sb_batch_clear
   frees what they made, refl__sb_batch_free that and the base too. */
static refl_result refl__sb_project_all(refl__sb *sb);
static void refl__sb_batch_clear(refl__sb *sb);
static void refl__sb_batch_free(refl__sb *sb);

/* ---- sbc_draw.c: 4. drawing ------------------------------------------------------- */

/* The reflections' targets, made and cleared; refl__sb_draw_end frees them. */
static refl_result refl__sb_draw_begin(refl__sb *sb);
static void refl__sb_draw_end(refl__sb *sb);
/* Draws the batch's jobs into them. */
static refl_result refl__sb_draw(refl__sb *sb);
/* After the last batch of an order below k_max: the next order shows
   where a mirror or glass was drawn nearest. */
static void refl__sb_pass_through(refl__sb *sb);

/* ---- sbc_resolve.c: 5. composite ---------------------------------------------------- */

/* Every reflector pixel of the frame from what was drawn (with
   desc.sbc.trace_fallback, traced where that fails). */
static refl_result refl__sb_resolve(refl__sb *sb);
