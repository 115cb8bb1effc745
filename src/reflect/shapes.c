/* Built-in shapes: Newell's teapot, sphere, torus, box and plane. */
#include "internal.h"

/* ---- shapes ------------------------------------------------------------------

   Every shape builds its arrays here and hands them, with explicit normals,
   to refl_mesh_create, which copies them; the temporaries are freed with
   the same allocator. All triangles wind counter-clockwise seen from the
   side the normals point to (outside). Sizes must be finite and positive
   (REFL_ERROR_INVALID_SIZE), segment counts at least their minimum
   (REFL_ERROR_INVALID_ARGUMENT), and no shape may exceed 2^24 vertices
   (REFL_ERROR_INVALID_SIZE). On failure *out is NULL and nothing is held.

   TEAPOT
       Martin Newell's 1975 data as circulated in the teaset (306 control
       points, 32 bicubic Bezier patches, 1-based indices as published: rim,
       body, handle, spout, lid, and the bottom Frank Crow added). The data
       is z-up; (x, y, z) -> (x, z, -y) makes it y-up with the base on y = 0,
       original proportions (no 1.3 vertical stretch). Bounds: x -3 ..
       3.4340751 (the spout lip's cubic peaks between grid lines, so a
       tessellation reaches up to 1.8 / (8 tess^2) less), y 0 .. 3.15,
       z -2 .. 2.

       Each patch is sampled on a (tess + 1)^2 grid in double. A patch is
       P(u, v) = sum B_r(v) B_c(u) point[row r][column c]. The cubic de
       Casteljau evaluation returns control points exactly at the ends and
       keeps equal points equal, and evaluates a curve from whichever end
       is nearer, so a boundary two patches share (in either direction, as
       the body and bottom do) and the collapsed pole rows give
       bit-identical positions on both sides.

       Normals are Pu x Pv. At the poles (the lid knob's top, the bottom's
       centre) a whole row collapses to a point and Pu = 0; there the normal
       is the limit Puv x Pv, which for this data is exactly the axis.

       Copies of the data do not all orient every patch alike (this one
       does: no patch needs a flip), so each patch is oriented on its own,
       without trusting the table: its normal at the centre (u = v = 1/2)
       must point along a direction that is outward for its part (up on the
       rim's curl, the lid and the spout's lip; away from the axis on the
       body and the knob; away from the tube's middle plane on the handle
       and the spout; down on the bottom). The centre is far from any
       degenerate point, so the test is never close (cosines 0.70 and up).

       Vertices are welded where the positions are identical and the
       normals agree to within REFL__TEAPOT_WELD_COS (the patches are
       tangent-continuous where they meet, so their normals differ by
       rounding only); the welded normal is the normalised sum. Triangles
       with two coincident corners (one per grid cell at a pole) are
       dropped: 32 tess^2 2 - 8 tess triangles remain. The teapot is not
       closed: the pot's rim, the lid's edge, the spout's lip and the
       handle's ends are open boundaries, and the handle and spout pass
       through the body.
*/

enum { REFL__SHAPE_MAX_VERTICES = 1 << 24 };

/* Hands the arrays to refl_mesh_create. */
static refl_result refl__shape_finish(const float *positions, const float *normals, const float *texcoords,
                                      long long vertex_count, const uint32_t *indices, long long index_count,
                                      const refl_allocator *a, refl_mesh **out) {
    refl_mesh_desc d;
    memset(&d, 0, sizeof d);
    d.positions = positions;
    d.normals = normals;
    d.texcoords = texcoords;
    d.indices = indices;
    d.vertex_count = (int)vertex_count;
    d.index_count = (int)index_count;
    d.allocator = refl__allocator(a);
    return refl_mesh_create(&d, out);
}

/* One block for a shape's vertices (position, normal, texcoord) and
   indices: a single allocation, so there is one failure to handle. */
typedef struct refl__shape_arrays {
    float *pos, *nrm, *uv;
    uint32_t *idx;
} refl__shape_arrays;

static int refl__shape_alloc(const refl_allocator *a, long long nv, long long ni, refl__shape_arrays *s) {
    float *block = (float *)refl__calloc(a, (size_t)(8 * nv + ni), sizeof(float));
    if (!block) return 0;
    s->pos = block;
    s->nrm = block + 3 * nv;
    s->uv = block + 6 * nv;
    s->idx = (uint32_t *)(void *)(block + 8 * nv); /* uint32_t and float: same size and alignment */
    return 1;
}

static int refl__shape_size_ok(float v) { return refl__isfinite(v) && v > 0.0f; }

static void refl__shape_quad(uint32_t *idx, uint32_t a, uint32_t b, uint32_t c, uint32_t d) {
    /* a b c d counter-clockwise: two triangles sharing the diagonal a-c */
    idx[0] = a; idx[1] = b; idx[2] = c;
    idx[3] = a; idx[4] = c; idx[5] = d;
}

/* ---- teapot ---------------------------------------------------------------- */

static const double refl__teapot_points[306][3] = {
    /* rim */
    {1.4, 0.0, 2.4}, {1.4, -0.784, 2.4}, {0.784, -1.4, 2.4}, {0.0, -1.4, 2.4},
    {1.3375, 0.0, 2.53125}, {1.3375, -0.749, 2.53125}, {0.749, -1.3375, 2.53125}, {0.0, -1.3375, 2.53125},
    {1.4375, 0.0, 2.53125}, {1.4375, -0.805, 2.53125}, {0.805, -1.4375, 2.53125}, {0.0, -1.4375, 2.53125},
    {1.5, 0.0, 2.4}, {1.5, -0.84, 2.4}, {0.84, -1.5, 2.4}, {0.0, -1.5, 2.4},
    {-0.784, -1.4, 2.4}, {-1.4, -0.784, 2.4}, {-1.4, 0.0, 2.4}, {-0.749, -1.3375, 2.53125},
    {-1.3375, -0.749, 2.53125}, {-1.3375, 0.0, 2.53125}, {-0.805, -1.4375, 2.53125}, {-1.4375, -0.805, 2.53125},
    {-1.4375, 0.0, 2.53125}, {-0.84, -1.5, 2.4}, {-1.5, -0.84, 2.4}, {-1.5, 0.0, 2.4},
    {-1.4, 0.784, 2.4}, {-0.784, 1.4, 2.4}, {0.0, 1.4, 2.4}, {-1.3375, 0.749, 2.53125},
    {-0.749, 1.3375, 2.53125}, {0.0, 1.3375, 2.53125}, {-1.4375, 0.805, 2.53125}, {-0.805, 1.4375, 2.53125},
    {0.0, 1.4375, 2.53125}, {-1.5, 0.84, 2.4}, {-0.84, 1.5, 2.4}, {0.0, 1.5, 2.4},
    {0.784, 1.4, 2.4}, {1.4, 0.784, 2.4}, {0.749, 1.3375, 2.53125}, {1.3375, 0.749, 2.53125},
    {0.805, 1.4375, 2.53125}, {1.4375, 0.805, 2.53125}, {0.84, 1.5, 2.4}, {1.5, 0.84, 2.4},
    /* body (49) */
    {1.75, 0.0, 1.875}, {1.75, -0.98, 1.875}, {0.98, -1.75, 1.875}, {0.0, -1.75, 1.875},
    {2.0, 0.0, 1.35}, {2.0, -1.12, 1.35}, {1.12, -2.0, 1.35}, {0.0, -2.0, 1.35},
    {2.0, 0.0, 0.9}, {2.0, -1.12, 0.9}, {1.12, -2.0, 0.9}, {0.0, -2.0, 0.9},
    {-0.98, -1.75, 1.875}, {-1.75, -0.98, 1.875}, {-1.75, 0.0, 1.875}, {-1.12, -2.0, 1.35},
    {-2.0, -1.12, 1.35}, {-2.0, 0.0, 1.35}, {-1.12, -2.0, 0.9}, {-2.0, -1.12, 0.9},
    {-2.0, 0.0, 0.9}, {-1.75, 0.98, 1.875}, {-0.98, 1.75, 1.875}, {0.0, 1.75, 1.875},
    {-2.0, 1.12, 1.35}, {-1.12, 2.0, 1.35}, {0.0, 2.0, 1.35}, {-2.0, 1.12, 0.9},
    {-1.12, 2.0, 0.9}, {0.0, 2.0, 0.9}, {0.98, 1.75, 1.875}, {1.75, 0.98, 1.875},
    {1.12, 2.0, 1.35}, {2.0, 1.12, 1.35}, {1.12, 2.0, 0.9}, {2.0, 1.12, 0.9},
    {2.0, 0.0, 0.45}, {2.0, -1.12, 0.45}, {1.12, -2.0, 0.45}, {0.0, -2.0, 0.45},
    {1.5, 0.0, 0.225}, {1.5, -0.84, 0.225}, {0.84, -1.5, 0.225}, {0.0, -1.5, 0.225},
    {1.5, 0.0, 0.15}, {1.5, -0.84, 0.15}, {0.84, -1.5, 0.15}, {0.0, -1.5, 0.15},
    {-1.12, -2.0, 0.45}, {-2.0, -1.12, 0.45}, {-2.0, 0.0, 0.45}, {-0.84, -1.5, 0.225},
    {-1.5, -0.84, 0.225}, {-1.5, 0.0, 0.225}, {-0.84, -1.5, 0.15}, {-1.5, -0.84, 0.15},
    {-1.5, 0.0, 0.15}, {-2.0, 1.12, 0.45}, {-1.12, 2.0, 0.45}, {0.0, 2.0, 0.45},
    {-1.5, 0.84, 0.225}, {-0.84, 1.5, 0.225}, {0.0, 1.5, 0.225}, {-1.5, 0.84, 0.15},
    {-0.84, 1.5, 0.15}, {0.0, 1.5, 0.15}, {1.12, 2.0, 0.45}, {2.0, 1.12, 0.45},
    {0.84, 1.5, 0.225}, {1.5, 0.84, 0.225}, {0.84, 1.5, 0.15}, {1.5, 0.84, 0.15},
    /* handle (121) */
    {-1.6, 0.0, 2.025}, {-1.6, -0.3, 2.025}, {-1.5, -0.3, 2.25}, {-1.5, 0.0, 2.25},
    {-2.3, 0.0, 2.025}, {-2.3, -0.3, 2.025}, {-2.5, -0.3, 2.25}, {-2.5, 0.0, 2.25},
    {-2.7, 0.0, 2.025}, {-2.7, -0.3, 2.025}, {-3.0, -0.3, 2.25}, {-3.0, 0.0, 2.25},
    {-2.7, 0.0, 1.8}, {-2.7, -0.3, 1.8}, {-3.0, -0.3, 1.8}, {-3.0, 0.0, 1.8},
    {-1.5, 0.3, 2.25}, {-1.6, 0.3, 2.025}, {-2.5, 0.3, 2.25}, {-2.3, 0.3, 2.025},
    {-3.0, 0.3, 2.25}, {-2.7, 0.3, 2.025}, {-3.0, 0.3, 1.8}, {-2.7, 0.3, 1.8},
    {-2.7, 0.0, 1.575}, {-2.7, -0.3, 1.575}, {-3.0, -0.3, 1.35}, {-3.0, 0.0, 1.35},
    {-2.5, 0.0, 1.125}, {-2.5, -0.3, 1.125}, {-2.65, -0.3, 0.9375}, {-2.65, 0.0, 0.9375},
    {-2.0, -0.3, 0.9}, {-1.9, -0.3, 0.6}, {-1.9, 0.0, 0.6}, {-3.0, 0.3, 1.35},
    {-2.7, 0.3, 1.575}, {-2.65, 0.3, 0.9375}, {-2.5, 0.3, 1.125}, {-1.9, 0.3, 0.6},
    {-2.0, 0.3, 0.9},
    /* spout (162) */
    {1.7, 0.0, 1.425}, {1.7, -0.66, 1.425}, {1.7, -0.66, 0.6}, {1.7, 0.0, 0.6},
    {2.6, 0.0, 1.425}, {2.6, -0.66, 1.425}, {3.1, -0.66, 0.825}, {3.1, 0.0, 0.825},
    {2.3, 0.0, 2.1}, {2.3, -0.25, 2.1}, {2.4, -0.25, 2.025}, {2.4, 0.0, 2.025},
    {2.7, 0.0, 2.4}, {2.7, -0.25, 2.4}, {3.3, -0.25, 2.4}, {3.3, 0.0, 2.4},
    {1.7, 0.66, 0.6}, {1.7, 0.66, 1.425}, {3.1, 0.66, 0.825}, {2.6, 0.66, 1.425},
    {2.4, 0.25, 2.025}, {2.3, 0.25, 2.1}, {3.3, 0.25, 2.4}, {2.7, 0.25, 2.4},
    {2.8, 0.0, 2.475}, {2.8, -0.25, 2.475}, {3.525, -0.25, 2.49375}, {3.525, 0.0, 2.49375},
    {2.9, 0.0, 2.475}, {2.9, -0.15, 2.475}, {3.45, -0.15, 2.5125}, {3.45, 0.0, 2.5125},
    {2.8, 0.0, 2.4}, {2.8, -0.15, 2.4}, {3.2, -0.15, 2.4}, {3.2, 0.0, 2.4},
    {3.525, 0.25, 2.49375}, {2.8, 0.25, 2.475}, {3.45, 0.15, 2.5125}, {2.9, 0.15, 2.475},
    {3.2, 0.15, 2.4}, {2.8, 0.15, 2.4},
    /* lid (204; 205, 206, 216 and 223 are unused in this version of the data) */
    {0.0, 0.0, 3.15}, {0.0, -0.002, 3.15}, {0.002, 0.0, 3.15}, {0.8, 0.0, 3.15},
    {0.8, -0.45, 3.15}, {0.45, -0.8, 3.15}, {0.0, -0.8, 3.15}, {0.0, 0.0, 2.85},
    {0.2, 0.0, 2.7}, {0.2, -0.112, 2.7}, {0.112, -0.2, 2.7}, {0.0, -0.2, 2.7},
    {-0.002, 0.0, 3.15}, {-0.45, -0.8, 3.15}, {-0.8, -0.45, 3.15}, {-0.8, 0.0, 3.15},
    {-0.112, -0.2, 2.7}, {-0.2, -0.112, 2.7}, {-0.2, 0.0, 2.7}, {0.0, 0.002, 3.15},
    {-0.8, 0.45, 3.15}, {-0.45, 0.8, 3.15}, {0.0, 0.8, 3.15}, {-0.2, 0.112, 2.7},
    {-0.112, 0.2, 2.7}, {0.0, 0.2, 2.7}, {0.45, 0.8, 3.15}, {0.8, 0.45, 3.15},
    {0.112, 0.2, 2.7}, {0.2, 0.112, 2.7}, {0.4, 0.0, 2.55}, {0.4, -0.224, 2.55},
    {0.224, -0.4, 2.55}, {0.0, -0.4, 2.55}, {1.3, 0.0, 2.55}, {1.3, -0.728, 2.55},
    {0.728, -1.3, 2.55}, {0.0, -1.3, 2.55}, {1.3, 0.0, 2.4}, {1.3, -0.728, 2.4},
    {0.728, -1.3, 2.4}, {0.0, -1.3, 2.4}, {-0.224, -0.4, 2.55}, {-0.4, -0.224, 2.55},
    {-0.4, 0.0, 2.55}, {-0.728, -1.3, 2.55}, {-1.3, -0.728, 2.55}, {-1.3, 0.0, 2.55},
    {-0.728, -1.3, 2.4}, {-1.3, -0.728, 2.4}, {-1.3, 0.0, 2.4}, {-0.4, 0.224, 2.55},
    {-0.224, 0.4, 2.55}, {0.0, 0.4, 2.55}, {-1.3, 0.728, 2.55}, {-0.728, 1.3, 2.55},
    {0.0, 1.3, 2.55}, {-1.3, 0.728, 2.4}, {-0.728, 1.3, 2.4}, {0.0, 1.3, 2.4},
    {0.224, 0.4, 2.55}, {0.4, 0.224, 2.55}, {0.728, 1.3, 2.55}, {1.3, 0.728, 2.55},
    {0.728, 1.3, 2.4}, {1.3, 0.728, 2.4},
    /* bottom (270) */
    {0.0, 0.0, 0.0}, {1.5, 0.0, 0.15}, {1.5, 0.84, 0.15}, {0.84, 1.5, 0.15},
    {0.0, 1.5, 0.15}, {1.5, 0.0, 0.075}, {1.5, 0.84, 0.075}, {0.84, 1.5, 0.075},
    {0.0, 1.5, 0.075}, {1.425, 0.0, 0.0}, {1.425, 0.798, 0.0}, {0.798, 1.425, 0.0},
    {0.0, 1.425, 0.0}, {-0.84, 1.5, 0.15}, {-1.5, 0.84, 0.15}, {-1.5, 0.0, 0.15},
    {-0.84, 1.5, 0.075}, {-1.5, 0.84, 0.075}, {-1.5, 0.0, 0.075}, {-0.798, 1.425, 0.0},
    {-1.425, 0.798, 0.0}, {-1.425, 0.0, 0.0}, {-1.5, -0.84, 0.15}, {-0.84, -1.5, 0.15},
    {0.0, -1.5, 0.15}, {-1.5, -0.84, 0.075}, {-0.84, -1.5, 0.075}, {0.0, -1.5, 0.075},
    {-1.425, -0.798, 0.0}, {-0.798, -1.425, 0.0}, {0.0, -1.425, 0.0}, {0.84, -1.5, 0.15},
    {1.5, -0.84, 0.15}, {0.84, -1.5, 0.075}, {1.5, -0.84, 0.075}, {0.798, -1.425, 0.0},
    {1.425, -0.798, 0.0}
};

/* 1-based, as published; row r of a patch is entries 4r .. 4r + 3. */
static const unsigned short refl__teapot_patches[32][16] = {
    /* rim */
    {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16},
    {4, 17, 18, 19, 8, 20, 21, 22, 12, 23, 24, 25, 16, 26, 27, 28},
    {19, 29, 30, 31, 22, 32, 33, 34, 25, 35, 36, 37, 28, 38, 39, 40},
    {31, 41, 42, 1, 34, 43, 44, 5, 37, 45, 46, 9, 40, 47, 48, 13},
    /* body */
    {13, 14, 15, 16, 49, 50, 51, 52, 53, 54, 55, 56, 57, 58, 59, 60},
    {16, 26, 27, 28, 52, 61, 62, 63, 56, 64, 65, 66, 60, 67, 68, 69},
    {28, 38, 39, 40, 63, 70, 71, 72, 66, 73, 74, 75, 69, 76, 77, 78},
    {40, 47, 48, 13, 72, 79, 80, 49, 75, 81, 82, 53, 78, 83, 84, 57},
    {57, 58, 59, 60, 85, 86, 87, 88, 89, 90, 91, 92, 93, 94, 95, 96},
    {60, 67, 68, 69, 88, 97, 98, 99, 92, 100, 101, 102, 96, 103, 104, 105},
    {69, 76, 77, 78, 99, 106, 107, 108, 102, 109, 110, 111, 105, 112, 113, 114},
    {78, 83, 84, 57, 108, 115, 116, 85, 111, 117, 118, 89, 114, 119, 120, 93},
    /* handle */
    {121, 122, 123, 124, 125, 126, 127, 128, 129, 130, 131, 132, 133, 134, 135, 136},
    {124, 137, 138, 121, 128, 139, 140, 125, 132, 141, 142, 129, 136, 143, 144, 133},
    {133, 134, 135, 136, 145, 146, 147, 148, 149, 150, 151, 152, 69, 153, 154, 155},
    {136, 143, 144, 133, 148, 156, 157, 145, 152, 158, 159, 149, 155, 160, 161, 69},
    /* spout */
    {162, 163, 164, 165, 166, 167, 168, 169, 170, 171, 172, 173, 174, 175, 176, 177},
    {165, 178, 179, 162, 169, 180, 181, 166, 173, 182, 183, 170, 177, 184, 185, 174},
    {174, 175, 176, 177, 186, 187, 188, 189, 190, 191, 192, 193, 194, 195, 196, 197},
    {177, 184, 185, 174, 189, 198, 199, 186, 193, 200, 201, 190, 197, 202, 203, 194},
    /* lid: knob, then the lid proper */
    {204, 204, 204, 204, 207, 208, 209, 210, 211, 211, 211, 211, 212, 213, 214, 215},
    {204, 204, 204, 204, 210, 217, 218, 219, 211, 211, 211, 211, 215, 220, 221, 222},
    {204, 204, 204, 204, 219, 224, 225, 226, 211, 211, 211, 211, 222, 227, 228, 229},
    {204, 204, 204, 204, 226, 230, 231, 207, 211, 211, 211, 211, 229, 232, 233, 212},
    {212, 213, 214, 215, 234, 235, 236, 237, 238, 239, 240, 241, 242, 243, 244, 245},
    {215, 220, 221, 222, 237, 246, 247, 248, 241, 249, 250, 251, 245, 252, 253, 254},
    {222, 227, 228, 229, 248, 255, 256, 257, 251, 258, 259, 260, 254, 261, 262, 263},
    {229, 232, 233, 212, 257, 264, 265, 234, 260, 266, 267, 238, 263, 268, 269, 242},
    /* bottom */
    {270, 270, 270, 270, 279, 280, 281, 282, 275, 276, 277, 278, 271, 272, 273, 274},
    {270, 270, 270, 270, 282, 289, 290, 291, 278, 286, 287, 288, 274, 283, 284, 285},
    {270, 270, 270, 270, 291, 298, 299, 300, 288, 295, 296, 297, 285, 292, 293, 294},
    {270, 270, 270, 270, 300, 305, 306, 279, 297, 303, 304, 275, 294, 301, 302, 271}
};

/* Outward reference per patch (data frame, z up), tested against the
   normal at the patch centre p: */
enum {
    REFL__TP_UP,     /* +z: rim curl, lid, spout lip */
    REFL__TP_DOWN,   /* -z: bottom */
    REFL__TP_RADIAL, /* (p.x, p.y, 0): body, knob */
    REFL__TP_SIDE    /* (0, p.y, 0): handle, spout tube (symmetric about y = 0) */
};
static const unsigned char refl__teapot_outward[32] = {
    REFL__TP_UP, REFL__TP_UP, REFL__TP_UP, REFL__TP_UP,
    REFL__TP_RADIAL, REFL__TP_RADIAL, REFL__TP_RADIAL, REFL__TP_RADIAL,
    REFL__TP_RADIAL, REFL__TP_RADIAL, REFL__TP_RADIAL, REFL__TP_RADIAL,
    REFL__TP_SIDE, REFL__TP_SIDE, REFL__TP_SIDE, REFL__TP_SIDE,
    REFL__TP_SIDE, REFL__TP_SIDE, REFL__TP_UP, REFL__TP_UP,
    REFL__TP_RADIAL, REFL__TP_RADIAL, REFL__TP_RADIAL, REFL__TP_RADIAL,
    REFL__TP_UP, REFL__TP_UP, REFL__TP_UP, REFL__TP_UP,
    REFL__TP_DOWN, REFL__TP_DOWN, REFL__TP_DOWN, REFL__TP_DOWN
};

/* Normals closer than about 0.8 degrees weld; the tangent-continuous joins
   of the data differ by rounding (about 1e-7), creases by far more. */
#define REFL__TEAPOT_WELD_COS 0.9999

static double refl__tp_lerp(double a, double b, double t) {
    /* exact at t = 0 and t = 1, and for equal ends */
    return a == b ? a : (1.0 - t) * a + t * b;
}

/* Cubic through p[0], p[stride], p[2 stride], p[3 stride] (3 doubles each)
   at t = i / n: value and derivative. Evaluated from the end nearer to t,
   with the parameter measured from that end, so the same curve given in
   reverse order gives bit-identical results at the mirrored parameter (at
   t = 1/2 the two orders agree because addition is commutative). */
static void refl__tp_curve(const double *p, int stride, int i, int n, double value[3], double deriv[3]) {
    double q[4][3], t;
    int k, c, reverse = 2 * i > n;
    t = reverse ? (double)(n - i) / (double)n : (double)i / (double)n;
    for (k = 0; k < 4; ++k)
        for (c = 0; c < 3; ++c) q[k][c] = p[(reverse ? 3 - k : k) * stride + c];
    for (c = 0; c < 3; ++c) {
        double a = refl__tp_lerp(q[0][c], q[1][c], t), b = refl__tp_lerp(q[1][c], q[2][c], t);
        double d = refl__tp_lerp(q[2][c], q[3][c], t);
        double e = refl__tp_lerp(a, b, t), f = refl__tp_lerp(b, d, t);
        value[c] = refl__tp_lerp(e, f, t);
        deriv[c] = reverse ? 3.0 * (e - f) : 3.0 * (f - e);
    }
}

static void refl__tp_cross(const double a[3], const double b[3], double r[3]) {
    r[0] = a[1] * b[2] - a[2] * b[1];
    r[1] = a[2] * b[0] - a[0] * b[2];
    r[2] = a[0] * b[1] - a[1] * b[0];
}

static double refl__tp_dot(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/* Position and (unnormalised, possibly zero) normal of patch cp (16 points,
   row-major) at u = i / n, v = j / n. */
static void refl__tp_eval(const double cp[16][3], int i, int j, int n, double pos[3], double nrm[3]) {
    double c[4][3], cu[4][3], pu[3], pv[3], puv[3], dummy[3];
    double lu, lv;
    int r;
    for (r = 0; r < 4; ++r) refl__tp_curve(cp[4 * r], 3, i, n, c[r], cu[r]);
    refl__tp_curve(c[0], 3, j, n, pos, pv);
    refl__tp_curve(cu[0], 3, j, n, pu, puv);
    refl__tp_cross(pu, pv, nrm);
    if (refl__tp_dot(nrm, nrm) > 0.0) return;
    /* A collapsed row (v = 0 or 1) has Pu = 0 along it; near it
       Pu ~ (v - v0) Puv, so the normal tends to +-(Puv x Pv). Likewise
       for a collapsed column. */
    lu = refl__tp_dot(pu, pu);
    lv = refl__tp_dot(pv, pv);
    if (lu <= lv) {
        refl__tp_cross(puv, pv, nrm);
        if (2 * j > n) { nrm[0] = -nrm[0]; nrm[1] = -nrm[1]; nrm[2] = -nrm[2]; }
    } else {
        /* Pv ~ (u - u0) Puv; the mixed derivative along u at this v */
        double cv[4][3];
        for (r = 0; r < 4; ++r) refl__tp_curve(cp[r], 12, j, n, dummy, cv[r]);
        refl__tp_curve(cv[0], 3, i, n, dummy, puv);
        refl__tp_cross(pu, puv, nrm);
        if (2 * i > n) { nrm[0] = -nrm[0]; nrm[1] = -nrm[1]; nrm[2] = -nrm[2]; }
    }
}

static uint32_t refl__tp_hash(const float p[3]) {
    uint32_t h = 2166136261u, w;
    int k;
    for (k = 0; k < 3; ++k) {
        memcpy(&w, &p[k], sizeof w);
        h = (h ^ w) * 16777619u;
        h ^= h >> 15;
    }
    return h;
}

REFL_API refl_result refl_mesh_teapot(int tess, const refl_allocator *a, refl_mesh **out) {
    int n, side, patch, i, j, k, r;
    long long grid, raw_count, welded = 0, index_count = 0;
    size_t table_size = 1, bytes;
    double cp[16][3];
    unsigned char *block;
    double *sum;               /* welded: normal sums */
    float *raw_pos, *raw_nrm;  /* every patch's grid */
    float *pos, *first;        /* welded: position, first normal */
    int *map, *head, *next;
    uint32_t *idx;
    refl_result res;

    if (!out) return REFL_ERROR_INVALID_ARGUMENT;
    *out = NULL;
    if (tess == 0) tess = 8;
    if (tess < 1 || tess > 64) return REFL_ERROR_INVALID_ARGUMENT;
    n = tess;
    side = n + 1;
    grid = (long long)side * side;
    raw_count = 32 * grid;
    while (table_size < 2 * (size_t)raw_count) table_size *= 2;

    /* one block: doubles first, then 4-byte arrays */
    bytes = (size_t)raw_count * (3 * sizeof(double) + 12 * sizeof(float) + 2 * sizeof(int)) +
            table_size * sizeof(int) + (size_t)(32 * n * n * 6) * sizeof(uint32_t);
    block = (unsigned char *)refl__alloc(a, bytes);
    if (!block) return REFL_ERROR_OUT_OF_MEMORY;
    sum = (double *)(void *)block;
    raw_pos = (float *)(void *)(sum + 3 * raw_count);
    raw_nrm = raw_pos + 3 * raw_count;
    pos = raw_nrm + 3 * raw_count;
    first = pos + 3 * raw_count;
    map = (int *)(void *)(first + 3 * raw_count);
    next = map + raw_count;
    head = next + raw_count;
    idx = (uint32_t *)(void *)(head + table_size);

    /* evaluate, orient (data frame), rotate to y-up */
    for (patch = 0; patch < 32; ++patch) {
        double p[3], nr[3], ref[3] = {0.0, 0.0, 0.0};
        double flip;
        for (k = 0; k < 16; ++k)
            for (r = 0; r < 3; ++r) cp[k][r] = refl__teapot_points[refl__teapot_patches[patch][k] - 1][r];
        refl__tp_eval((const double(*)[3])cp, 1, 1, 2, p, nr);
        switch (refl__teapot_outward[patch]) {
        case REFL__TP_UP: ref[2] = 1.0; break;
        case REFL__TP_DOWN: ref[2] = -1.0; break;
        case REFL__TP_RADIAL: ref[0] = p[0]; ref[1] = p[1]; break;
        default: ref[1] = p[1]; break;
        }
        flip = refl__tp_dot(nr, ref) < 0.0 ? -1.0 : 1.0;
        for (j = 0; j < side; ++j)
            for (i = 0; i < side; ++i) {
                long long v = patch * grid + (long long)j * side + i;
                double len;
                refl__tp_eval((const double(*)[3])cp, i, j, n, p, nr);
                len = sqrt(refl__tp_dot(nr, nr));
                if (!(len > 0.0)) { /* not in this data; the axis keeps it finite */
                    nr[0] = 0.0; nr[1] = 0.0; nr[2] = 1.0; len = 1.0;
                }
                len = flip / len;
                /* (x, y, z) -> (x, z, -y); + 0.0f makes -0 into +0 for the hash */
                raw_pos[3 * v + 0] = (float)p[0] + 0.0f;
                raw_pos[3 * v + 1] = (float)p[2] + 0.0f;
                raw_pos[3 * v + 2] = (float)-p[1] + 0.0f;
                raw_nrm[3 * v + 0] = (float)(nr[0] * len);
                raw_nrm[3 * v + 1] = (float)(nr[2] * len);
                raw_nrm[3 * v + 2] = (float)(-nr[1] * len);
            }
        /* winding follows the normal: cells (i, j) (i+1, j) (i+1, j+1)
           (i, j+1) run counter-clockwise around Pu x Pv */
        for (j = 0; j < n; ++j)
            for (i = 0; i < n; ++i) {
                long long v00 = patch * grid + (long long)j * side + i;
                long long c[4];
                int t;
                c[0] = v00; c[1] = v00 + 1; c[2] = v00 + side + 1; c[3] = v00 + side;
                if (flip < 0.0) { long long s = c[1]; c[1] = c[3]; c[3] = s; }
                for (t = 0; t < 2; ++t) {
                    long long tri[3];
                    tri[0] = c[0]; tri[1] = c[1 + t]; tri[2] = c[2 + t];
                    /* a pole cell has one triangle with two corners on the pole */
                    if (!memcmp(raw_pos + 3 * tri[0], raw_pos + 3 * tri[1], 3 * sizeof(float)) ||
                        !memcmp(raw_pos + 3 * tri[1], raw_pos + 3 * tri[2], 3 * sizeof(float)) ||
                        !memcmp(raw_pos + 3 * tri[2], raw_pos + 3 * tri[0], 3 * sizeof(float)))
                        continue;
                    for (k = 0; k < 3; ++k) idx[index_count++] = (uint32_t)tri[k];
                }
            }
    }

    /* weld: same position bits, normals within REFL__TEAPOT_WELD_COS */
    for (k = 0; k < (int)table_size; ++k) head[k] = -1;
    for (k = 0; k < (int)raw_count; ++k) {
        const float *p = raw_pos + 3 * k, *nr = raw_nrm + 3 * k;
        uint32_t h = refl__tp_hash(p) & (uint32_t)(table_size - 1);
        int w;
        for (w = head[h]; w >= 0; w = next[w]) {
            const float *f = first + 3 * w;
            if (!memcmp(pos + 3 * w, p, 3 * sizeof(float)) &&
                (double)f[0] * nr[0] + (double)f[1] * nr[1] + (double)f[2] * nr[2] > REFL__TEAPOT_WELD_COS)
                break;
        }
        if (w < 0) {
            w = (int)welded++;
            memcpy(pos + 3 * w, p, 3 * sizeof(float));
            memcpy(first + 3 * w, nr, 3 * sizeof(float));
            sum[3 * w] = sum[3 * w + 1] = sum[3 * w + 2] = 0.0;
            next[w] = head[h];
            head[h] = w;
        }
        for (r = 0; r < 3; ++r) sum[3 * w + r] += nr[r];
        map[k] = w;
    }
    for (k = 0; k < (int)welded; ++k) {
        double len = sqrt(sum[3 * k] * sum[3 * k] + sum[3 * k + 1] * sum[3 * k + 1] + sum[3 * k + 2] * sum[3 * k + 2]);
        /* the summed normals are within 0.8 degrees of each other */
        for (r = 0; r < 3; ++r) first[3 * k + r] = (float)(sum[3 * k + r] / len);
    }
    for (k = 0; k < (int)index_count; ++k) idx[k] = (uint32_t)map[idx[k]];

    res = refl__shape_finish(pos, first, NULL, welded, idx, index_count, a, out);
    refl__free(a, block);
    return res;
}

/* ---- sphere ------------------------------------------------------------------ */

REFL_API refl_result refl_mesh_sphere(float radius, int slices, int stacks, const refl_allocator *a,
                                      refl_mesh **out) {
    refl__shape_arrays s;
    long long nv, ni, v = 0;
    uint32_t *ix;
    int i, j, ring0;
    refl_result res;

    if (!out) return REFL_ERROR_INVALID_ARGUMENT;
    *out = NULL;
    if (slices < 3 || stacks < 2) return REFL_ERROR_INVALID_ARGUMENT;
    if (!refl__shape_size_ok(radius)) return REFL_ERROR_INVALID_SIZE;
    /* a pole vertex per slice at each end (its own texcoord, so no
       triangle is degenerate), and rings with a seam column */
    nv = 2LL * slices + ((long long)stacks - 1) * ((long long)slices + 1);
    if (nv > REFL__SHAPE_MAX_VERTICES) return REFL_ERROR_INVALID_SIZE;
    ni = 6LL * slices * ((long long)stacks - 1);
    if (!refl__shape_alloc(a, nv, ni, &s)) return REFL_ERROR_OUT_OF_MEMORY;

    for (j = 0; j < slices; ++j, ++v) { /* top pole */
        s.pos[3 * v + 1] = radius;
        s.nrm[3 * v + 1] = 1.0f;
        s.uv[2 * v] = (float)((j + 0.5) / slices);
    }
    ring0 = (int)v;
    for (i = 1; i < stacks; ++i) {
        double theta = REFL__PI * i / stacks, y = cos(theta), rr = sin(theta);
        for (j = 0; j <= slices; ++j, ++v) {
            /* the seam column repeats column 0's angle: identical positions */
            double phi = 2.0 * REFL__PI * (j % slices) / slices;
            double d[3];
            int c;
            d[0] = rr * cos(phi); d[1] = y; d[2] = -rr * sin(phi);
            for (c = 0; c < 3; ++c) {
                s.nrm[3 * v + c] = (float)d[c];
                s.pos[3 * v + c] = (float)(radius * d[c]);
            }
            s.uv[2 * v] = (float)j / (float)slices;
            s.uv[2 * v + 1] = (float)i / (float)stacks;
        }
    }
    for (j = 0; j < slices; ++j, ++v) { /* bottom pole */
        s.pos[3 * v + 1] = -radius;
        s.nrm[3 * v + 1] = -1.0f;
        s.uv[2 * v] = (float)((j + 0.5) / slices);
        s.uv[2 * v + 1] = 1.0f;
    }

    /* phi grows from +x towards -z and theta downwards; (down, along)
       is counter-clockwise seen from outside */
    ix = s.idx;
    for (j = 0; j < slices; ++j, ix += 3) {
        ix[0] = (uint32_t)j;
        ix[1] = (uint32_t)(ring0 + j);
        ix[2] = (uint32_t)(ring0 + j + 1);
    }
    for (i = 0; i + 1 < stacks - 1; ++i)
        for (j = 0; j < slices; ++j, ix += 6) {
            uint32_t a0 = (uint32_t)(ring0 + i * (slices + 1) + j), b0 = a0 + (uint32_t)(slices + 1);
            refl__shape_quad(ix, a0, b0, b0 + 1, a0 + 1);
        }
    for (j = 0; j < slices; ++j, ix += 3) {
        uint32_t last = (uint32_t)(ring0 + (stacks - 2) * (slices + 1) + j);
        ix[0] = last;
        ix[1] = (uint32_t)(nv - slices + j);
        ix[2] = last + 1;
    }
    res = refl__shape_finish(s.pos, s.nrm, s.uv, nv, s.idx, ni, a, out);
    refl__free(a, s.pos);
    return res;
}

/* ---- torus ------------------------------------------------------------------- */

REFL_API refl_result refl_mesh_torus(float major_radius, float minor_radius, int slices, int sides,
                                     const refl_allocator *a, refl_mesh **out) {
    refl__shape_arrays s;
    long long nv, ni, v = 0;
    int i, j;
    refl_result res;

    if (!out) return REFL_ERROR_INVALID_ARGUMENT;
    *out = NULL;
    if (slices < 3 || sides < 3) return REFL_ERROR_INVALID_ARGUMENT;
    /* a ring torus: the tube may not reach the axis */
    if (!refl__shape_size_ok(major_radius) || !refl__shape_size_ok(minor_radius) ||
        !(minor_radius < major_radius))
        return REFL_ERROR_INVALID_SIZE;
    nv = ((long long)slices + 1) * ((long long)sides + 1);
    if (nv > REFL__SHAPE_MAX_VERTICES) return REFL_ERROR_INVALID_SIZE;
    ni = 6LL * slices * sides;
    if (!refl__shape_alloc(a, nv, ni, &s)) return REFL_ERROR_OUT_OF_MEMORY;

    for (i = 0; i <= slices; ++i) {
        double phi = 2.0 * REFL__PI * (i % slices) / slices, cp = cos(phi), sp = sin(phi);
        for (j = 0; j <= sides; ++j, ++v) {
            double th = 2.0 * REFL__PI * (j % sides) / sides, ct = cos(th), st = sin(th);
            double d[3], ring = major_radius + minor_radius * ct;
            d[0] = ct * cp; d[1] = st; d[2] = -ct * sp;
            s.nrm[3 * v + 0] = (float)d[0];
            s.nrm[3 * v + 1] = (float)d[1];
            s.nrm[3 * v + 2] = (float)d[2];
            s.pos[3 * v + 0] = (float)(ring * cp);
            s.pos[3 * v + 1] = (float)(minor_radius * st);
            s.pos[3 * v + 2] = (float)(-ring * sp);
            s.uv[2 * v] = (float)i / (float)slices;
            s.uv[2 * v + 1] = (float)j / (float)sides;
        }
    }
    /* phi (around y, from +x towards -z) then theta (around the tube,
       outside first, then up): counter-clockwise seen from outside */
    for (i = 0; i < slices; ++i)
        for (j = 0; j < sides; ++j) {
            uint32_t a0 = (uint32_t)(i * (sides + 1) + j), b0 = a0 + (uint32_t)(sides + 1);
            refl__shape_quad(s.idx + 6 * ((long long)i * sides + j), a0, b0, b0 + 1, a0 + 1);
        }
    res = refl__shape_finish(s.pos, s.nrm, s.uv, nv, s.idx, ni, a, out);
    refl__free(a, s.pos);
    return res;
}

/* ---- box ----------------------------------------------------------------------- */

REFL_API refl_result refl_mesh_box(refl_vec3 size, const refl_allocator *a, refl_mesh **out) {
    /* faces +x -x +y -y +z -z: normal and the face's "up" (texcoord v = 0
       edge); its right is up x normal */
    static const float face[6][2][3] = {
        {{1, 0, 0}, {0, 1, 0}},  {{-1, 0, 0}, {0, 1, 0}}, {{0, 1, 0}, {0, 0, -1}},
        {{0, -1, 0}, {0, 0, 1}}, {{0, 0, 1}, {0, 1, 0}},  {{0, 0, -1}, {0, 1, 0}}};
    static const float corner[4][2] = {{0, 0}, {0, 1}, {1, 1}, {1, 0}}; /* (u, v), CCW */
    float pos[24 * 3], nrm[24 * 3], uv[24 * 2], h[3];
    uint32_t idx[36];
    int f, k, c;

    if (!out) return REFL_ERROR_INVALID_ARGUMENT;
    *out = NULL;
    if (!refl__shape_size_ok(size.x) || !refl__shape_size_ok(size.y) || !refl__shape_size_ok(size.z))
        return REFL_ERROR_INVALID_SIZE;
    h[0] = 0.5f * size.x; h[1] = 0.5f * size.y; h[2] = 0.5f * size.z;
    for (f = 0; f < 6; ++f) {
        const float *nn = face[f][0], *up = face[f][1];
        float right[3];
        right[0] = up[1] * nn[2] - up[2] * nn[1];
        right[1] = up[2] * nn[0] - up[0] * nn[2];
        right[2] = up[0] * nn[1] - up[1] * nn[0];
        for (k = 0; k < 4; ++k) {
            int v = 4 * f + k;
            float su = 2.0f * corner[k][0] - 1.0f, sv = 1.0f - 2.0f * corner[k][1];
            for (c = 0; c < 3; ++c) {
                pos[3 * v + c] = h[c] * (nn[c] + su * right[c] + sv * up[c]);
                nrm[3 * v + c] = nn[c];
            }
            uv[2 * v] = corner[k][0];
            uv[2 * v + 1] = corner[k][1];
        }
        /* top-left, bottom-left, bottom-right: (-up) x right = normal */
        refl__shape_quad(idx + 6 * f, (uint32_t)(4 * f), (uint32_t)(4 * f + 1), (uint32_t)(4 * f + 2),
                         (uint32_t)(4 * f + 3));
    }
    return refl__shape_finish(pos, nrm, uv, 24, idx, 36, a, out);
}

/* ---- plane ----------------------------------------------------------------------- */

REFL_API refl_result refl_mesh_plane(float size, int divisions, const refl_allocator *a, refl_mesh **out) {
    refl__shape_arrays s;
    long long nv, ni, v = 0;
    int i, j, d = divisions;
    refl_result res;

    if (!out) return REFL_ERROR_INVALID_ARGUMENT;
    *out = NULL;
    if (divisions < 1) return REFL_ERROR_INVALID_ARGUMENT;
    if (!refl__shape_size_ok(size)) return REFL_ERROR_INVALID_SIZE;
    nv = ((long long)d + 1) * ((long long)d + 1);
    if (nv > REFL__SHAPE_MAX_VERTICES) return REFL_ERROR_INVALID_SIZE;
    ni = 6LL * d * d;
    if (!refl__shape_alloc(a, nv, ni, &s)) return REFL_ERROR_OUT_OF_MEMORY;

    /* vertex (i, j): x from column i, z from row j; texcoords (i, j) / d,
       so seen from above with -z up the image's top row is at -z */
    for (j = 0; j <= d; ++j)
        for (i = 0; i <= d; ++i, ++v) {
            /* (2i - d) / 2d: symmetric about the centre, exactly 0 there */
            s.pos[3 * v + 0] = (float)((double)(2 * i - d) / (2.0 * d) * size);
            s.pos[3 * v + 2] = (float)((double)(2 * j - d) / (2.0 * d) * size);
            s.nrm[3 * v + 1] = 1.0f;
            s.uv[2 * v] = (float)i / (float)d;
            s.uv[2 * v + 1] = (float)j / (float)d;
        }
    /* (i, j) (i, j+1) (i+1, j+1): +z then +x, counter-clockwise from +y */
    for (j = 0; j < d; ++j)
        for (i = 0; i < d; ++i) {
            uint32_t a0 = (uint32_t)(j * (d + 1) + i), b0 = a0 + (uint32_t)(d + 1);
            refl__shape_quad(s.idx + 6 * ((long long)j * d + i), a0, b0, b0 + 1, a0 + 1);
        }
    res = refl__shape_finish(s.pos, s.nrm, s.uv, nv, s.idx, ni, a, out);
    refl__free(a, s.pos);
    return res;
}
