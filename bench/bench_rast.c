/* bench_rast - rast.h against Mesa llvmpipe (headless EGL) at 1920x1080.

   Usage: bench_rast [--csv FILE] [--runs N]
          bench_rast --child rast|gl THREADS RUNS   (one side's timings; with
                     BENCH_RAST_ROW=NAME only that row: for perf record)

   Rows (each frame = clear colour/depth/stencil + the draws + finish):
     points_1M_size1    1M points of size 1, depth test LESS
     points_1M_size2    1M points of size 2, depth test LESS
     mesh_100k          100k-triangle displaced grid in perspective, depth
                        test LESS, smooth colour (indexed)
     mesh_1M            the same with 1M triangles
     stencil_8_passes   8 full-screen stencil INCR passes, colour masked
                        (rast: rast_draw_fullscreen; GL: a full-screen quad)
     blend_4_quads      4 full-screen quads blended SRC_ALPHA /
                        ONE_MINUS_SRC_ALPHA, no depth test
   for 1 and 2 threads. rast.h gets rast_context_desc.num_threads = T;
   llvmpipe gets LP_NUM_THREADS = T (note that llvmpipe's vertex processing
   and triangle setup run on the calling thread besides its T rasteriser
   threads). Every (renderer, thread count) runs in a fresh child process
   (this program re-executed with --child), because llvmpipe reads
   LP_NUM_THREADS once, when its screen is created. GL geometry is uploaded
   into VBOs before timing; frames end with glFinish plus a 1-pixel
   glReadPixels. Reported: the median over N timed frames (default 7) after
   one warm-up frame.

   Memory: one more child per row draws that row through rast.h alone (2
   threads) into RGBA8 colour, float depth, 8-bit stencil and RGBA32F accum
   targets at 1920x1080 and reports its peak RSS (getrusage ru_maxrss),
   against the budget 64 MB + 64 bytes per submitted vertex (vertex_count of
   the draws of one frame). Judged: the peak less the caller's own vertex
   and index arrays (the input, which an application holds anyway; for the
   1M mesh alone they are 109 bytes per vertex). Also shown: the peak with
   them, and the budget if every index counted as a submitted vertex.
*/
#define _POSIX_C_SOURCE 200809L
/* The implementation comes from tests/rast_impl.c (linked in by the Makefile). */
#include "../rast.h"
#include "../tests/rast/gl_peer.h"

#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#define BW 1920
#define BH 1080
#define VF GL_PEER_FLOATS_PER_VERTEX

enum { ROW_POINTS1, ROW_POINTS2, ROW_MESH100K, ROW_MESH1M, ROW_STENCIL, ROW_BLEND, NROWS };
static const char *row_names[NROWS] = {
    "points_1M_size1", "points_1M_size2", "mesh_100k", "mesh_1M", "stencil_8_passes", "blend_4_quads"
};

/* ---- geometry ------------------------------------------------------------ */

typedef struct geometry {
    float *v;
    int nv;
    uint32_t *idx;
    int ni;
} geometry;

static uint64_t rng_state = 0x243F6A8885A308D3ull;
static double urand(void) {
    uint64_t z = (rng_state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    return (double)(z >> 11) * (1.0 / 9007199254740992.0);
}

static void *xmalloc(size_t n) {
    void *p = malloc(n);
    if (!p) {
        fprintf(stderr, "bench_rast: out of memory (%zu bytes)\n", n);
        exit(2);
    }
    return p;
}

static void make_points(geometry *g, int n) {
    int i;
    g->nv = n;
    g->v = xmalloc((size_t)n * VF * sizeof(float));
    g->idx = NULL;
    g->ni = 0;
    for (i = 0; i < n; i++) {
        float *q = g->v + (size_t)i * VF;
        q[0] = (float)(urand() * 2 - 1);
        q[1] = (float)(urand() * 2 - 1);
        q[2] = (float)(urand() * 1.8 - 0.9);
        q[3] = 1.0f;
        q[4] = (float)urand();
        q[5] = (float)urand();
        q[6] = (float)urand();
        q[7] = 1.0f;
    }
}

/* A displaced, tilted grid seen in perspective (60 degree vertical field of
   view, 16:9), covering most of the screen; smooth per-vertex colours. */
static void make_mesh(geometry *g, int nx, int ny) {
    const double f = 1.0 / tan(30.0 * 3.14159265358979 / 180.0), aspect = (double)BW / BH;
    const double zn = 0.5, zf = 50.0;
    int i, j, k = 0;
    g->nv = (nx + 1) * (ny + 1);
    g->ni = nx * ny * 6;
    g->v = xmalloc((size_t)g->nv * VF * sizeof(float));
    g->idx = xmalloc((size_t)g->ni * sizeof(uint32_t));
    for (j = 0; j <= ny; j++)
        for (i = 0; i <= nx; i++) {
            double u = (double)i / nx, w = (double)j / ny;
            double X = -4.6 + 9.2 * u;
            double Y = -2.7 + 5.4 * w + 0.25 * sin(9.0 * u + 2.0) * cos(7.0 * w);
            double Z = -4.2 - 2.5 * w + 0.35 * sin(13.0 * u) * sin(11.0 * w + 1.0);
            float *q = g->v + (size_t)(j * (nx + 1) + i) * VF;
            q[0] = (float)(X * f / aspect);
            q[1] = (float)(Y * f);
            q[2] = (float)(((zf + zn) / (zn - zf)) * Z + 2.0 * zf * zn / (zn - zf));
            q[3] = (float)(-Z);
            q[4] = (float)(0.5 + 0.5 * sin(20.0 * u));
            q[5] = (float)(0.5 + 0.5 * cos(17.0 * w));
            q[6] = (float)(0.5 + 0.5 * sin(5.0 * (u + w)));
            q[7] = 1.0f;
        }
    for (j = 0; j < ny; j++)
        for (i = 0; i < nx; i++) {
            uint32_t a = (uint32_t)(j * (nx + 1) + i), b = a + 1, c = a + (uint32_t)(nx + 1), d = c + 1;
            g->idx[k++] = a; g->idx[k++] = b; g->idx[k++] = d;
            g->idx[k++] = a; g->idx[k++] = d; g->idx[k++] = c;
        }
}

/* n full-screen quads (two triangles each) with colour rgb_k, alpha 0.5. */
static void make_quads(geometry *g, int n) {
    static const float corners[6][2] = { { -1, -1 }, { 1, -1 }, { 1, 1 }, { -1, -1 }, { 1, 1 }, { -1, 1 } };
    int q, k;
    g->nv = 6 * n;
    g->v = xmalloc((size_t)g->nv * VF * sizeof(float));
    g->idx = NULL;
    g->ni = 0;
    for (q = 0; q < n; q++)
        for (k = 0; k < 6; k++) {
            float *p = g->v + (size_t)(q * 6 + k) * VF;
            p[0] = corners[k][0];
            p[1] = corners[k][1];
            p[2] = 0.0f;
            p[3] = 1.0f;
            p[4] = (float)((q + 1) & 1);
            p[5] = (float)(((q + 1) >> 1) & 1);
            p[6] = (float)(((q + 1) >> 2) & 1);
            p[7] = 0.5f;
        }
}

static void make_row_geometry(int row, geometry *g) {
    memset(g, 0, sizeof *g);
    switch (row) {
    case ROW_POINTS1:
    case ROW_POINTS2: make_points(g, 1000000); break;
    case ROW_MESH100K: make_mesh(g, 250, 200); break;   /* 100,000 triangles */
    case ROW_MESH1M: make_mesh(g, 1000, 500); break;    /* 1,000,000 triangles */
    case ROW_STENCIL: make_quads(g, 1); break;          /* GL only */
    default: make_quads(g, 4); break;
    }
}

static void free_geometry(geometry *g) {
    free(g->v);
    free(g->idx);
    memset(g, 0, sizeof *g);
}

static double now_ms(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1e3 + ts.tv_nsec / 1e6;
}

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static double median(double *t, int n) {
    qsort(t, (size_t)n, sizeof *t, cmp_double);
    return n % 2 ? t[n / 2] : 0.5 * (t[n / 2 - 1] + t[n / 2]);
}

/* ---- rast.h side --------------------------------------------------------- */

typedef struct rast_side {
    rast_context *ctx;
    uint8_t *color;
    float *depth;
    uint8_t *stencil;
    float *accum;
} rast_side;

static int rast_side_init(rast_side *r, int threads) {
    rast_context_desc cd;
    rast_targets t;
    rast_result res;
    memset(r, 0, sizeof *r);
    memset(&cd, 0, sizeof cd);
    cd.num_threads = threads;
    res = rast_context_create(&cd, &r->ctx);
    if (res != RAST_OK) {
        fprintf(stderr, "rast_context_create: %s\n", rast_result_string(res));
        return -1;
    }
    r->color = xmalloc((size_t)BW * BH * 4);
    r->depth = xmalloc((size_t)BW * BH * sizeof(float));
    r->stencil = xmalloc((size_t)BW * BH);
    r->accum = xmalloc((size_t)BW * BH * 4 * sizeof(float));
    /* touch every target so the peak RSS counts them, as an application's would */
    memset(r->color, 0, (size_t)BW * BH * 4);
    memset(r->depth, 0, (size_t)BW * BH * sizeof(float));
    memset(r->stencil, 0, (size_t)BW * BH);
    memset(r->accum, 0, (size_t)BW * BH * 4 * sizeof(float));
    memset(&t, 0, sizeof t);
    t.color.ptr = r->color; t.color.width = BW; t.color.height = BH; t.color.stride = BW * 4;
    t.depth.ptr = r->depth; t.depth.width = BW; t.depth.height = BH; t.depth.stride = BW * 4;
    t.stencil.ptr = r->stencil; t.stencil.width = BW; t.stencil.height = BH; t.stencil.stride = BW;
    t.accum.ptr = r->accum; t.accum.width = BW; t.accum.height = BH; t.accum.stride = BW * 16;
    res = rast_set_targets(r->ctx, &t);
    if (res != RAST_OK) {
        fprintf(stderr, "rast_set_targets: %s\n", rast_result_string(res));
        return -1;
    }
    return 0;
}

static void rast_side_fini(rast_side *r) {
    rast_context_destroy(r->ctx);
    free(r->color);
    free(r->depth);
    free(r->stencil);
    free(r->accum);
}

static int rast_frame(rast_side *r, int row, const geometry *g) {
    rast_state s;
    rast_clear_desc c;
    rast_draw_desc d;
    int ok = 1, i;
    memset(&s, 0, sizeof s);
    rast_set_state(r->ctx, &s);
    memset(&c, 0, sizeof c);
    c.flags = RAST_CLEAR_COLOR | RAST_CLEAR_DEPTH | RAST_CLEAR_STENCIL;
    c.color[3] = 1.0f;
    c.depth = 1.0f;
    ok &= rast_clear(r->ctx, &c) == RAST_OK;

    memset(&d, 0, sizeof d);
    d.vertices = g->v;
    d.vertex_count = g->nv;
    d.stride = VF;
    d.num_varyings = 4;
    d.indices = g->idx;
    d.index_count = g->ni;
    switch (row) {
    case ROW_POINTS1:
    case ROW_POINTS2:
        s.depth_test = 1;
        s.point_size = row == ROW_POINTS1 ? 1.0f : 2.0f;
        d.primitive = RAST_POINTS;
        ok &= rast_set_state(r->ctx, &s) == RAST_OK;
        ok &= rast_draw(r->ctx, &d) == RAST_OK;
        break;
    case ROW_MESH100K:
    case ROW_MESH1M:
        s.depth_test = 1;
        d.primitive = RAST_TRIANGLES;
        ok &= rast_set_state(r->ctx, &s) == RAST_OK;
        ok &= rast_draw(r->ctx, &d) == RAST_OK;
        break;
    case ROW_STENCIL: {
        static const float rgba[4] = { 1, 1, 1, 1 };
        s.stencil_test = 1;
        s.stencil_front.func = RAST_ALWAYS;
        s.stencil_front.pass = RAST_INCR;
        s.stencil_back = s.stencil_front;
        s.color_write = RAST_MASK(0);
        ok &= rast_set_state(r->ctx, &s) == RAST_OK;
        for (i = 0; i < 8; i++) ok &= rast_draw_fullscreen(r->ctx, 0.5f, rgba) == RAST_OK;
        break;
    }
    default:
        s.blend = 1;
        s.blend_src_rgb = s.blend_src_alpha = RAST_SRC_ALPHA;
        s.blend_dst_rgb = s.blend_dst_alpha = RAST_ONE_MINUS_SRC_ALPHA;
        d.primitive = RAST_TRIANGLES;
        ok &= rast_set_state(r->ctx, &s) == RAST_OK;
        ok &= rast_draw(r->ctx, &d) == RAST_OK;
        break;
    }
    ok &= rast_finish(r->ctx) == RAST_OK;
    return ok ? 0 : -1;
}

/* Submitted vertices per frame of a row, for the memory budget. */
static long row_vertices(int row, const geometry *g) {
    if (row == ROW_STENCIL) return 8L * 4; /* 8 rectangles */
    return g->nv;
}

/* ---- GL side --------------------------------------------------------------- */

static void gl_frame(gl_peer *p, int row, const geometry *g) {
    uint8_t px[4];
    int i;
    glDisable(GL_SCISSOR_TEST);
    glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    glDepthMask(GL_TRUE);
    glStencilMask(0xFF);
    glClearColor(0, 0, 0, 1);
    glClearDepth(1.0);
    glClearStencil(0);
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT | GL_STENCIL_BUFFER_BIT);
    switch (row) {
    case ROW_POINTS1:
    case ROW_POINTS2:
    case ROW_MESH100K:
    case ROW_MESH1M:
        glEnable(GL_DEPTH_TEST);
        glDepthFunc(GL_LESS);
        glDisable(GL_STENCIL_TEST);
        glDisable(GL_BLEND);
        if (row == ROW_MESH100K || row == ROW_MESH1M) gl_peer_draw(p, GL_TRIANGLES, 0, g->ni);
        else gl_peer_draw(p, GL_POINTS, 0, g->nv);
        break;
    case ROW_STENCIL:
        glDisable(GL_DEPTH_TEST);
        glDisable(GL_BLEND);
        glEnable(GL_STENCIL_TEST);
        glStencilFunc(GL_ALWAYS, 0, 0xFF);
        glStencilOp(GL_KEEP, GL_KEEP, GL_INCR);
        glColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
        for (i = 0; i < 8; i++) gl_peer_draw(p, GL_TRIANGLES, 0, 6);
        break;
    default:
        glDisable(GL_DEPTH_TEST);
        glDisable(GL_STENCIL_TEST);
        glEnable(GL_BLEND);
        glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
        gl_peer_draw(p, GL_TRIANGLES, 0, g->nv);
        break;
    }
    glFinish();
    glReadPixels(0, 0, 1, 1, GL_RGBA, GL_UNSIGNED_BYTE, px);
}

/* ---- children -------------------------------------------------------------- */

static int child_time(const char *who, int threads, int runs) {
    int row, only_row = -1;
    const char *only = getenv("BENCH_RAST_ROW");
    gl_peer *gp = NULL;
    rast_side rs;
    int is_gl = strcmp(who, "gl") == 0;
    for (row = 0; only && row < NROWS; row++)
        if (!strcmp(only, row_names[row])) only_row = row;
    if (is_gl) {
        char buf[16];
        snprintf(buf, sizeof buf, "%d", threads);
        setenv("LP_NUM_THREADS", buf, 1); /* before the screen is created */
        gp = calloc(1, sizeof *gp);
        if (!gp || gl_peer_init(gp, BW, BH) != 0) {
            printf("ERROR %s\n", gp ? gp->err : "out of memory");
            return 1;
        }
        printf("INFO renderer=%s | %s\n", gp->renderer, gp->version);
        gl_peer_point_size(gp, 1.0f);
    } else if (rast_side_init(&rs, threads) != 0) {
        printf("ERROR rast context\n");
        return 1;
    }
    for (row = 0; row < NROWS; row++) {
        geometry g;
        double t[64];
        int i, n = runs;
        if (only_row >= 0 && row != only_row) continue;
        make_row_geometry(row, &g);
        if (is_gl) {
            gl_peer_upload(gp, g.v, g.nv, g.idx, g.ni);
            gl_peer_point_size(gp, row == ROW_POINTS2 ? 2.0f : 1.0f);
        }
        for (i = -1; i < n; i++) {
            double t0 = now_ms(), dt;
            if (is_gl) gl_frame(gp, row, &g);
            else if (rast_frame(&rs, row, &g) != 0) {
                printf("ERROR rast frame failed on row %s\n", row_names[row]);
                return 1;
            }
            dt = now_ms() - t0;
            if (i >= 0) t[i] = dt;
            else if (dt > 3000.0 && n > 3) n = 3; /* keep the whole bench bounded */
        }
        if (is_gl && gl_peer_error() != GL_NO_ERROR) {
            printf("ERROR GL error on row %s\n", row_names[row]);
            return 1;
        }
        printf("RESULT %d %.3f %d\n", row, median(t, n), n);
        fflush(stdout);
        free_geometry(&g);
    }
    if (is_gl) {
        gl_peer_destroy(gp);
        free(gp);
    } else {
        rast_side_fini(&rs);
    }
    return 0;
}

/* Resident set now, in kB (/proc/self/statm), or -1. */
static long rss_now_kb(void) {
    FILE *f = fopen("/proc/self/statm", "r");
    long size = 0, resident = -1;
    if (!f) return -1;
    if (fscanf(f, "%ld %ld", &size, &resident) != 2) resident = -1;
    fclose(f);
    return resident < 0 ? -1 : resident * (sysconf(_SC_PAGESIZE) / 1024);
}

static int child_rss(int row, int threads) {
    rast_side rs;
    geometry g;
    struct rusage ru;
    long before;
    int i;
    make_row_geometry(row, &g);
    if (row == ROW_STENCIL) free_geometry(&g); /* rast draws rectangles only */
    if (rast_side_init(&rs, threads) != 0) {
        printf("ERROR rast context\n");
        return 1;
    }
    before = rss_now_kb(); /* process + caller's geometry + targets, before any draw */
    for (i = 0; i < 2; i++)
        if (rast_frame(&rs, row, &g) != 0) {
            printf("ERROR rast frame failed\n");
            return 1;
        }
    getrusage(RUSAGE_SELF, &ru);
    printf("RSS %d %ld %ld %ld %ld %ld\n", row, (long)ru.ru_maxrss, row_vertices(row, &g), (long)g.ni,
           before, (long)(((size_t)g.nv * VF * sizeof(float) + (size_t)g.ni * sizeof(uint32_t)) / 1024));
    rast_side_fini(&rs);
    free_geometry(&g);
    return 0;
}

/* Runs this program with args, collects its stdout. */
static char *run_child(char *const args[]) {
    int fd[2], status;
    pid_t pid;
    size_t cap = 4096, len = 0;
    char *out = xmalloc(cap);
    if (pipe(fd) != 0) {
        perror("pipe");
        exit(2);
    }
    fflush(stdout);
    pid = fork();
    if (pid < 0) {
        perror("fork");
        exit(2);
    }
    if (pid == 0) {
        close(fd[0]);
        dup2(fd[1], 1);
        close(fd[1]);
        execv("/proc/self/exe", args);
        perror("execv /proc/self/exe");
        _exit(127);
    }
    close(fd[1]);
    for (;;) {
        ssize_t k;
        if (len + 1024 > cap) {
            char *o = realloc(out, cap * 2);
            if (!o) exit(2);
            out = o;
            cap *= 2;
        }
        k = read(fd[0], out + len, cap - len - 1);
        if (k < 0 && errno == EINTR) continue;
        if (k <= 0) break;
        len += (size_t)k;
    }
    out[len] = '\0';
    close(fd[0]);
    while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
    }
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0)
        fprintf(stderr, "bench_rast: child %s %s %s exited abnormally (status 0x%x)\n", args[1],
                args[2], args[3], (unsigned)status);
    return out;
}

static void parse_results(const char *out, double ms[NROWS], char *info, size_t info_len) {
    const char *line = out;
    int i;
    for (i = 0; i < NROWS; i++) ms[i] = NAN;
    while (line && *line) {
        int row, n;
        double v;
        if (sscanf(line, "RESULT %d %lf %d", &row, &v, &n) == 3 && row >= 0 && row < NROWS) ms[row] = v;
        else if (!strncmp(line, "INFO ", 5) && info) {
            const char *e = strchr(line, '\n');
            size_t l = e ? (size_t)(e - line - 5) : strlen(line + 5);
            if (l >= info_len) l = info_len - 1;
            memcpy(info, line + 5, l);
            info[l] = '\0';
        } else if (!strncmp(line, "ERROR", 5)) {
            const char *e = strchr(line, '\n');
            fprintf(stderr, "bench_rast: child: %.*s\n", (int)(e ? e - line : (long)strlen(line)), line);
        }
        line = strchr(line, '\n');
        if (line) line++;
    }
}

static void cpu_model(char *buf, size_t n) {
    FILE *f = fopen("/proc/cpuinfo", "r");
    char line[512];
    snprintf(buf, n, "unknown");
    if (!f) return;
    while (fgets(line, sizeof line, f)) {
        if (!strncmp(line, "model name", 10)) {
            char *c = strchr(line, ':'), *e;
            if (c) {
                c++;
                while (*c == ' ' || *c == '\t') c++;
                e = c + strlen(c);
                while (e > c && (e[-1] == '\n' || e[-1] == ' ')) *--e = '\0';
                snprintf(buf, n, "%s", c);
            }
            break;
        }
    }
    fclose(f);
}

int main(int argc, char **argv) {
    const char *csv = NULL;
    int runs = 7, i, ti;
    static const int thread_counts[2] = { 1, 2 };
    double rast_ms[2][NROWS], gl_ms[2][NROWS];
    char gl_info[256] = "unavailable", cpu[256], runs_s[16];
    FILE *f;
    double t_start = now_ms();

    if (argc >= 4 && !strcmp(argv[1], "--child")) {
        int threads = atoi(argv[3]);
        if (!strcmp(argv[2], "rss")) return child_rss(argc >= 5 ? atoi(argv[4]) : 0, threads);
        return child_time(argv[2], threads, argc >= 5 ? atoi(argv[4]) : 7);
    }
    for (i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--csv") && i + 1 < argc) csv = argv[++i];
        else if (!strcmp(argv[i], "--runs") && i + 1 < argc) runs = atoi(argv[++i]);
        else {
            fprintf(stderr, "usage: %s [--csv FILE] [--runs N]\n", argv[0]);
            return 2;
        }
    }
    if (runs < 1) runs = 1;
    if (runs > 64) runs = 64;
    snprintf(runs_s, sizeof runs_s, "%d", runs);

    cpu_model(cpu, sizeof cpu);
    printf("bench_rast: %dx%d, median of %d frames after 1 warm-up; frame = clear + draw + finish\n",
           BW, BH, runs);
    printf("machine: nproc %ld, cpu %s\n", sysconf(_SC_NPROCESSORS_ONLN), cpu);
    fflush(stdout);

    for (ti = 0; ti < 2; ti++) {
        char tstr[16];
        char *args[6], *out;
        snprintf(tstr, sizeof tstr, "%d", thread_counts[ti]);
        args[0] = argv[0]; args[1] = (char *)"--child"; args[3] = tstr; args[4] = runs_s; args[5] = NULL;
        args[2] = (char *)"rast";
        out = run_child(args);
        parse_results(out, rast_ms[ti], NULL, 0);
        free(out);
        args[2] = (char *)"gl";
        out = run_child(args);
        parse_results(out, gl_ms[ti], gl_info, sizeof gl_info);
        free(out);
    }
    printf("llvmpipe: %s\n\n", gl_info);
    printf("%-18s %7s %10s %12s %8s\n", "row", "threads", "rast_ms", "llvmpipe_ms", "ratio");
    for (i = 0; i < NROWS; i++)
        for (ti = 0; ti < 2; ti++) {
            double r = rast_ms[ti][i], g = gl_ms[ti][i];
            printf("%-18s %7d %10.2f %12.2f %8.2f\n", row_names[i], thread_counts[ti], r, g, r / g);
        }
    if (csv) {
        char dir[1024];
        char *slash;
        snprintf(dir, sizeof dir, "%s", csv);
        slash = strrchr(dir, '/');
        if (slash && slash != dir) {
            *slash = '\0';
            mkdir(dir, 0777); /* one level, as in out/bench_rast.csv */
        }
        f = fopen(csv, "w");
        if (!f) {
            fprintf(stderr, "bench_rast: cannot write %s: %s\n", csv, strerror(errno));
            return 1;
        }
        fprintf(f, "row,threads,rast_ms,llvmpipe_ms,ratio\n");
        for (i = 0; i < NROWS; i++)
            for (ti = 0; ti < 2; ti++) {
                double r = rast_ms[ti][i], g = gl_ms[ti][i];
                fprintf(f, "%s,%d,%.3f,%.3f,%.3f\n", row_names[i], thread_counts[ti], r, g, r / g);
            }
        fclose(f);
    }

    printf("\npeak RSS of a rast-only child per row (2 threads; RGBA8 + depth + stencil + accum "
           "targets at %dx%d = %.1f MB)\n", BW, BH, BW * BH * (4.0 + 4 + 1 + 16) / 1048576.0);
    printf("  vertices: vertex_count submitted per frame; budget_MB = 64 MB + 64 B x vertices;\n"
           "  before_MB: resident before the first draw (process, caller's arrays, touched targets);\n"
           "  caller_MB: the caller's vertex and index arrays; ok: rss_MB - caller_MB <= budget_MB;\n"
           "  idx_budget_MB: the budget if every index counted as a submitted vertex\n");
    printf("%-18s %9s %9s %8s %10s %10s %10s %5s %14s\n", "row", "vertices", "indices", "rss_MB",
           "before_MB", "caller_MB", "budget_MB", "ok", "idx_budget_MB");
    for (i = 0; i < NROWS; i++) {
        char rowstr[8], *args[6], *out, *l;
        long rss_kb = -1, nvert = 0, nidx = 0, before_kb = 0, caller_kb = 0;
        int row;
        snprintf(rowstr, sizeof rowstr, "%d", i);
        args[0] = argv[0]; args[1] = (char *)"--child"; args[2] = (char *)"rss"; args[3] = (char *)"2";
        args[4] = rowstr; args[5] = NULL;
        out = run_child(args);
        l = strstr(out, "RSS ");
        if (!l || sscanf(l, "RSS %d %ld %ld %ld %ld %ld", &row, &rss_kb, &nvert, &nidx, &before_kb, &caller_kb) != 6) {
            printf("%-18s (failed)\n", row_names[i]);
        } else {
            double mb = rss_kb / 1024.0, caller = caller_kb / 1024.0, budget = 64.0 + 64.0 * nvert / 1048576.0;
            double ibudget = 64.0 + 64.0 * (nidx > nvert ? nidx : nvert) / 1048576.0;
            printf("%-18s %9ld %9ld %8.1f %10.1f %10.1f %10.1f %5s %14.1f\n", row_names[i], nvert, nidx, mb,
                   before_kb / 1024.0, caller, budget, mb - caller <= budget ? "yes" : "OVER", ibudget);
        }
        free(out);
    }
    printf("\ntotal %.1f s\n", (now_ms() - t_start) / 1000.0);
    return 0;
}
