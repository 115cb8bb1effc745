/* rast_demo: what rast.h draws, in one picture.

   - three coloured triangles that cut through each other above a floor,
     seen through a perspective camera, sorted out by the depth test;
   - a row of points of sizes 1 to 8 pixels;
   - a disc written into the stencil buffer only, then a blended full-screen
     pass that tints the pixels inside the disc and nothing else.

   Writes a binary PPM (default rast_demo.ppm):

       cc -std=c99 -O2 rast_demo.c -o rast_demo -lm -pthread
       ./rast_demo out.ppm
*/
#define RAST_IMPLEMENTATION
#include "../rast.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { W = 640, H = 480, DISC_SEGMENTS = 48 };

#define CHECK(call)                                                           \
    do {                                                                      \
        rast_result r_ = (call);                                              \
        if (r_ != RAST_OK) {                                                  \
            fprintf(stderr, "rast_demo: %s failed: %s\n", #call,              \
                    rast_result_string(r_));                                  \
            exit(1);                                                          \
        }                                                                     \
    } while (0)

/* ---- a tiny 4x4 matrix kit; column-major like GL: m[column * 4 + row] ---- */

static void mat_mul(float out[16], const float a[16], const float b[16]) {
    float r[16];
    int c, i, k;
    for (c = 0; c < 4; c++)
        for (i = 0; i < 4; i++) {
            float s = 0.0f;
            for (k = 0; k < 4; k++) s += a[k * 4 + i] * b[c * 4 + k];
            r[c * 4 + i] = s;
        }
    memcpy(out, r, sizeof r);
}

/* gluPerspective */
static void perspective(float m[16], float fovy_degrees, float aspect, float znear, float zfar) {
    float f = 1.0f / tanf(fovy_degrees * 3.14159265f / 360.0f);
    memset(m, 0, 16 * sizeof *m);
    m[0] = f / aspect;
    m[5] = f;
    m[10] = (zfar + znear) / (znear - zfar);
    m[11] = -1.0f;
    m[14] = 2.0f * zfar * znear / (znear - zfar);
}

static void normalize(float v[3]) {
    float len = sqrtf(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    v[0] /= len; v[1] /= len; v[2] /= len;
}

static void cross(float out[3], const float a[3], const float b[3]) {
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

/* gluLookAt */
static void look_at(float m[16], const float eye[3], const float at[3], const float up[3]) {
    float f[3], s[3], u[3];
    int i;
    for (i = 0; i < 3; i++) f[i] = at[i] - eye[i];
    normalize(f);
    cross(s, f, up);
    normalize(s);
    cross(u, s, f);
    memset(m, 0, 16 * sizeof *m);
    for (i = 0; i < 3; i++) {
        m[i * 4 + 0] = s[i];
        m[i * 4 + 1] = u[i];
        m[i * 4 + 2] = -f[i];
    }
    m[12] = -(s[0] * eye[0] + s[1] * eye[1] + s[2] * eye[2]);
    m[13] = -(u[0] * eye[0] + u[1] * eye[1] + u[2] * eye[2]);
    m[14] = f[0] * eye[0] + f[1] * eye[1] + f[2] * eye[2];
    m[15] = 1.0f;
}

static int write_ppm(const char *path, const uint8_t *rgba) {
    FILE *f = fopen(path, "wb");
    int i, ok;
    if (!f) return 0;
    fprintf(f, "P6\n%d %d\n255\n", W, H);
    for (i = 0; i < W * H; i++) fwrite(rgba + 4 * i, 1, 3, f);
    ok = !ferror(f);
    return fclose(f) == 0 && ok;
}

int main(int argc, char **argv) {
    const char *path = argc > 1 ? argv[1] : "rast_demo.ppm";
    uint8_t *rgba = (uint8_t *)malloc((size_t)W * H * 4);
    float *depth = (float *)malloc((size_t)W * H * sizeof(float));
    uint8_t *stencil = (uint8_t *)malloc((size_t)W * H);

    /* World-space triangles and a floor, each vertex x, y, z, r, g, b, a.
       Every triangle stands on the floor and leans through the other two. */
    static const float scene[] = {
        /* floor: two triangles */
        -3.0f, -1.0f, -3.0f,  0.25f, 0.25f, 0.30f, 1.0f,
        -3.0f, -1.0f,  3.0f,  0.45f, 0.45f, 0.50f, 1.0f,
         3.0f, -1.0f,  3.0f,  0.25f, 0.25f, 0.30f, 1.0f,
        -3.0f, -1.0f, -3.0f,  0.25f, 0.25f, 0.30f, 1.0f,
         3.0f, -1.0f,  3.0f,  0.25f, 0.25f, 0.30f, 1.0f,
         3.0f, -1.0f, -3.0f,  0.10f, 0.10f, 0.15f, 1.0f,
        /* red */
        -1.6f, -0.9f,  0.6f,  1.0f, 0.2f, 0.1f, 1.0f,
         1.4f, -0.9f, -0.9f,  0.6f, 0.0f, 0.0f, 1.0f,
         0.5f,  1.4f,  0.9f,  1.0f, 0.7f, 0.5f, 1.0f,
        /* green */
         1.6f, -0.9f,  0.6f,  0.1f, 0.9f, 0.2f, 1.0f,
        -1.2f, -0.9f, -1.0f,  0.0f, 0.5f, 0.1f, 1.0f,
        -0.6f,  1.3f,  0.8f,  0.6f, 1.0f, 0.6f, 1.0f,
        /* blue */
         0.0f, -0.9f,  1.6f,  0.1f, 0.3f, 1.0f, 1.0f,
        -0.3f, -0.9f, -1.6f,  0.0f, 0.1f, 0.6f, 1.0f,
         0.1f,  1.5f, -0.2f,  0.6f, 0.8f, 1.0f, 1.0f,
    };
    float points[8 * 7];
    float disc[(DISC_SEGMENTS + 1) * 3];
    uint32_t disc_indices[DISC_SEGMENTS * 3];
    float proj[16], view[16], view_proj[16];
    const float eye[3] = { 3.2f, 2.0f, 4.5f }, at[3] = { 0.0f, 0.1f, 0.0f }, up[3] = { 0.0f, 1.0f, 0.0f };
    const float tint[4] = { 1.0f, 0.85f, 0.2f, 0.45f };
    rast_context *ctx;
    rast_context_desc cd = {0};
    rast_targets t = {0};
    rast_clear_desc c = {0};
    rast_state s;
    rast_draw_desc d;
    int i;

    if (!rgba || !depth || !stencil) {
        fprintf(stderr, "rast_demo: out of memory\n");
        return 1;
    }

    CHECK(rast_context_create(&cd, &ctx));
    t.color = (rast_view){ rgba, W, H, W * 4 };
    t.depth = (rast_view){ depth, W, H, W * (int)sizeof(float) };
    t.stencil = (rast_view){ stencil, W, H, W };
    CHECK(rast_set_targets(ctx, &t));

    c.flags = RAST_CLEAR_COLOR | RAST_CLEAR_DEPTH | RAST_CLEAR_STENCIL;
    c.color[0] = 0.08f; c.color[1] = 0.09f; c.color[2] = 0.12f; c.color[3] = 1.0f;
    c.depth = 1.0f;
    c.stencil = 0;
    CHECK(rast_clear(ctx, &c));

    /* 1. The scene, depth-tested, through a perspective camera. */
    perspective(proj, 45.0f, (float)W / (float)H, 0.1f, 50.0f);
    look_at(view, eye, at, up);
    mat_mul(view_proj, proj, view);

    memset(&s, 0, sizeof s);
    s.depth_test = 1;
    CHECK(rast_set_state(ctx, &s));
    memset(&d, 0, sizeof d);
    d.primitive = RAST_TRIANGLES;
    d.vertices = scene;
    d.vertex_count = (int)(sizeof scene / sizeof scene[0] / 7);
    d.position_size = 3;
    d.num_varyings = 4;
    d.matrix = view_proj;
    CHECK(rast_draw(ctx, &d));

    /* 2. Points of sizes 1..8 along the bottom, straight in NDC. */
    memset(&s, 0, sizeof s);
    for (i = 0; i < 8; i++) {
        float *p = points + 7 * i;
        p[0] = -0.8f + 1.6f * (float)i / 7.0f; p[1] = -0.85f; p[2] = 0.0f;
        p[3] = 1.0f; p[4] = 0.5f + 0.5f * (float)i / 7.0f; p[5] = 1.0f - (float)i / 7.0f; p[6] = 1.0f;
    }
    for (i = 0; i < 8; i++) {
        s.point_size = (float)(i + 1);
        CHECK(rast_set_state(ctx, &s));
        memset(&d, 0, sizeof d);
        d.primitive = RAST_POINTS;
        d.vertices = points + 7 * i;
        d.vertex_count = 1;
        d.position_size = 3;
        d.num_varyings = 4;
        CHECK(rast_draw(ctx, &d));
    }

    /* 3. A disc into the stencil only (stencil := 1, no colour writes) ... */
    disc[0] = 0.15f; disc[1] = 0.45f; disc[2] = 0.0f;
    for (i = 0; i < DISC_SEGMENTS; i++) {
        float a = 2.0f * 3.14159265f * (float)i / (float)DISC_SEGMENTS;
        disc[3 * (i + 1) + 0] = 0.15f + 0.32f * cosf(a) * (float)H / (float)W;
        disc[3 * (i + 1) + 1] = 0.45f + 0.32f * sinf(a);
        disc[3 * (i + 1) + 2] = 0.0f;
        disc_indices[3 * i + 0] = 0;
        disc_indices[3 * i + 1] = (uint32_t)(i + 1);
        disc_indices[3 * i + 2] = (uint32_t)((i + 1) % DISC_SEGMENTS + 1);
    }
    memset(&s, 0, sizeof s);
    s.stencil_test = 1;
    s.stencil_front.func = RAST_ALWAYS;
    s.stencil_front.ref = 1;
    s.stencil_front.pass = RAST_REPLACE;
    s.stencil_back = s.stencil_front;
    s.color_write = RAST_MASK(0);
    CHECK(rast_set_state(ctx, &s));
    memset(&d, 0, sizeof d);
    d.primitive = RAST_TRIANGLES;
    d.vertices = disc;
    d.vertex_count = DISC_SEGMENTS + 1;
    d.position_size = 3;
    d.indices = disc_indices;
    d.index_count = DISC_SEGMENTS * 3;
    CHECK(rast_draw(ctx, &d));

    /* ... then a blended full-screen pass where stencil == 1. */
    memset(&s, 0, sizeof s);
    s.stencil_test = 1;
    s.stencil_front.func = RAST_EQUAL;
    s.stencil_front.ref = 1;
    s.stencil_back = s.stencil_front;
    s.blend = 1;
    s.blend_src_rgb = s.blend_src_alpha = RAST_SRC_ALPHA;
    s.blend_dst_rgb = s.blend_dst_alpha = RAST_ONE_MINUS_SRC_ALPHA;
    CHECK(rast_set_state(ctx, &s));
    CHECK(rast_draw_fullscreen(ctx, 0.0f, tint));

    CHECK(rast_finish(ctx));
    printf("rast_demo: %dx%d with %d threads\n", W, H, rast_context_threads(ctx));
    rast_context_destroy(ctx);

    if (!write_ppm(path, rgba)) {
        fprintf(stderr, "rast_demo: cannot write %s\n", path);
        return 1;
    }
    printf("rast_demo: wrote %s\n", path);
    free(rgba);
    free(depth);
    free(stencil);
    return 0;
}
