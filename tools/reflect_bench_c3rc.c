/* `reflect bench`, C3RC part (paper 000): its Tables 1 and 2 reproduced
   on this machine beside the paper's GPU numbers, and the camera's
   reflection error against the reflector triangles' size in pixels.

   Tables: the default scene (the 4,000-triangle teapot reflecting a floor,
   a torus, a sphere and a box) sampled at the paper's six point counts
   (density = count / the scene's surface area), 640x480, in two
   configurations: the defaults (1000-point leaves, split cameras) and the
   paper's (leaves of 122 points, one camera per reflector triangle):
     Table 1: kd-tree build time (median), average leaf depth, points per leaf;
     Table 2: C3RC reflection time (median frame's cull + project wall time),
              culling and projection thread time, valid-projection ratio
              counted as the paper counts it (valid projections over every
              point of the leaves the box test accepted), and the
              reflection error against one-bounce RAYTRACE.
   The paper ran on a Pentium 4 Xeon with a Quadro FX 3400 (projection on
   the GPU); here two CPU cores do everything. */
#define _POSIX_C_SOURCE 200809L
#include "../reflect.h"
#include "reflect_bench.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* World surface area of every object. */
static double scene_area(const refl_scene *s) {
    double total = 0.0;
    int i, t;
    for (i = 0; i < s->object_count; ++i) {
        const refl_mesh *m = s->meshes[s->objects[i].mesh];
        for (t = 0; t < m->triangle_count; ++t) {
            refl_vec3 v[3];
            int k;
            for (k = 0; k < 3; ++k) {
                const float *q = m->positions + 3 * m->indices[3 * t + k];
                v[k] = refl_mat4_point(s->objects[i].transform, refl_v3(q[0], q[1], q[2]));
            }
            total += 0.5 * refl_v3_length(refl_v3_cross(refl_v3_sub(v[1], v[0]), refl_v3_sub(v[2], v[0])));
        }
    }
    return total;
}

/* All objects' points at a density, in one array (caller frees). */
static float *sample_all(const refl_scene *s, float density, int *count) {
    float *all = NULL;
    int i, n = 0;
    for (i = 0; i < s->object_count; ++i) {
        refl_points *p = NULL;
        float *grown;
        if (refl_mesh_sample_points(s->meshes[s->objects[i].mesh], &s->objects[i].transform, density,
                                    0x9e3779b97f4a7c15ull + (uint64_t)i, NULL, &p) != REFL_OK)
            break;
        grown = (float *)realloc(all, (size_t)(n + p->count) * 3 * sizeof(float) + 1);
        if (!grown) {
            refl_points_destroy(p);
            break;
        }
        all = grown;
        memcpy(all + 3 * (size_t)n, p->positions, (size_t)p->count * 3 * sizeof(float));
        n += p->count;
        refl_points_destroy(p);
    }
    if (i < s->object_count) {
        free(all);
        return NULL;
    }
    *count = n;
    return all;
}

static refl_scene *default_scene(int tess) {
    refl_builtin_desc bd;
    refl_scene *s = NULL;
    memset(&bd, 0, sizeof bd);
    bd.teapot_tess = tess;
    return refl_scene_builtin("default", &bd, &s) == REFL_OK ? s : NULL;
}

static refl_view view_640(const refl_scene *s) {
    refl_view v = s->camera;
    v.width = 640;
    v.height = 480;
    return v;
}

/* The paper's Tables 1 and 2 (its scenes, its hardware), by point count. */
static const struct {
    const char *scene;
    int kpoints;
    double build_ms, depth, per_leaf, total_ms, cull_ms, project_ms, valid;
} paper[] = {{"Dinosaur", 10, 6, 3.4, 123, 48, 25, 23, 19},   {"Bunny1", 37, 25, 4.7, 121, 121, 63, 58, 19},
             {"Dragon1", 100, 95, 5.7, 122, 250, 134, 116, 20}, {"Bunny0", 147, 190, 6.1, 121, 264, 136, 128, 19},
             {"Dragon0", 437, 533, 7.2, 121, 588, 273, 315, 20}, {"Statue0", 543, 577, 7.4, 122, 650, 304, 346, 21}};

/* The configurations the tables run: name, kd-tree leaf size (0: the
   default), camera_split_px (0: the default; -1: one camera per triangle). */
static const struct {
    const char *name;
    int leaf_points;
    float split_px;
} configs[] = {{"defaults", 0, 0.0f}, {"paper", 122, -1.0f}};

static int tables(const char *dir, int threads, int repeats) {
    refl_scene *s = default_scene(8);
    refl_view v;
    refl_frame *f = NULL, *truth = NULL;
    refl_render_desc d;
    char path[1024];
    FILE *csv;
    double area;
    int row, config, ok = 1, rows = (int)(sizeof paper / sizeof paper[0]);
    if (!s) return 0;
    v = view_640(s);
    area = scene_area(s);
    snprintf(path, sizeof path, "%s/c3rc_tables.csv", dir);
    csv = fopen(path, "w");
    if (!csv || refl_frame_create(v.width, v.height, NULL, &f) != REFL_OK ||
        refl_frame_create(v.width, v.height, NULL, &truth) != REFL_OK) {
        if (csv) fclose(csv);
        refl_frame_destroy(f);
        refl_scene_destroy(s);
        return 0;
    }
    memset(&d, 0, sizeof d);
    d.method = REFL_RAYTRACE;
    d.threads = threads;
    d.depth = 1;
    ok = refl_render(s, &v, &d, truth) == REFL_OK;
    fprintf(csv, "config,leaf_points,camera_split_px,paper_scene,paper_kpoints,points,build_ms,paper_build_ms,avg_depth,paper_depth,points_per_leaf,"
                 "paper_per_leaf,reflect_ms,paper_total_ms,cull_thread_ms,paper_cull_ms,project_thread_ms,"
                 "paper_project_ms,valid_pct,paper_valid_pct,projections,cameras,leaves,boxes_culled,"
                 "error_mean_px,error_p95_px,wrong,empty\n");
    for (config = 0; ok && config < (int)(sizeof configs / sizeof configs[0]); ++config) {
        refl_kdtree_desc kd;
        memset(&kd, 0, sizeof kd);
        kd.leaf_points = configs[config].leaf_points;
        fprintf(stderr, "  C3RC tables 1 and 2, %s (leaf %d points, %s; default scene, 4k-triangle teapot, 640x480; "
                        "paper: Quadro FX 3400)\n"
                        "  %8s %9s %7s %6s %7s | %9s %9s %9s %6s | paper: %6s %6s %6s %6s %5s\n",
                configs[config].name, kd.leaf_points ? kd.leaf_points : 1000,
                configs[config].split_px < 0.0f ? "one camera per triangle" : "split cameras", "points", "build ms",
                "depth", "/leaf", "cams", "refl ms", "cull ms*", "proj ms*", "valid", "build", "total", "cull", "proj",
                "valid");
        for (row = 0; ok && row < rows; ++row) {
            float density = (float)(paper[row].kpoints * 1000.0 / area);
            double build[16], refl[16];
            int count = 0, k, n = repeats < 1 ? 1 : repeats > 16 ? 16 : repeats;
            float *pts = sample_all(s, density, &count);
            refl_kdtree *tree = NULL;
            refl_reflection_error err;
            if (!pts) { ok = 0; break; }
            for (k = 0; k < n && ok; ++k) {
                double t0 = refl_bench_now_ms();
                refl_kdtree_destroy(tree);
                tree = NULL;
                ok = refl_kdtree_build(pts, count, &kd, &tree) == REFL_OK;
                build[k] = refl_bench_now_ms() - t0;
            }
            free(pts);
            memset(&d, 0, sizeof d);
            d.method = REFL_C3RC;
            d.threads = threads;
            d.depth = 1;
            d.c3rc.point_density = density;
            d.c3rc.kd_leaf_points = configs[config].leaf_points;
            d.c3rc.camera_split_px = configs[config].split_px;
            for (k = 0; k < n && ok; ++k) {
                ok = refl_render(s, &v, &d, f) == REFL_OK;
                refl[k] = f->stats.ms_reflect;
            }
            if (ok && refl_measure_reflection_error(f, truth, NULL, &err) != REFL_OK) memset(&err, 0, sizeof err);
            if (ok) {
                double b = refl_bench_median(build, n), r = refl_bench_median(refl, n);
                double valid = f->stats.c3rc.projections ? 100.0 * (double)f->stats.c3rc.projected / (double)f->stats.c3rc.projections : 0.0;
                fprintf(csv, "%s,%d,%g,%s,%d,%d,%.2f,%.0f,%.2f,%.1f,%.1f,%.0f,%.2f,%.0f,%.2f,%.0f,%.2f,%.0f,%.1f,%.0f,%lld,%lld,%lld,%lld,"
                             "%.3f,%.3f,%.4f,%.4f\n",
                        configs[config].name, kd.leaf_points ? kd.leaf_points : 1000, (double)configs[config].split_px,
                        paper[row].scene, paper[row].kpoints, tree->point_count, b, paper[row].build_ms,
                        tree->average_leaf_depth, paper[row].depth, tree->average_leaf_points, paper[row].per_leaf, r,
                        paper[row].total_ms, f->stats.c3rc.ms_cull, paper[row].cull_ms, f->stats.c3rc.ms_project,
                        paper[row].project_ms, valid, paper[row].valid, f->stats.c3rc.projections, f->stats.c3rc.cameras,
                        f->stats.c3rc.leaves, f->stats.c3rc.culled, err.mean, err.p95, err.wrong, err.empty);
                fprintf(stderr, "  %8d %9.1f %7.2f %6.0f %7lld | %9.1f %9.1f %9.1f %5.1f%% | paper: %6.0f %6.0f %6.0f %6.0f %4.0f%%"
                                "  (error p95 %.2f px, empty %.3f)\n",
                        tree->point_count, b, tree->average_leaf_depth, tree->average_leaf_points, f->stats.c3rc.cameras, r,
                        f->stats.c3rc.ms_cull, f->stats.c3rc.ms_project, valid, paper[row].build_ms, paper[row].total_ms,
                        paper[row].cull_ms, paper[row].project_ms, paper[row].valid, err.p95, err.empty);
            }
            refl_kdtree_destroy(tree);
        }
    }
    fprintf(stderr, "  (* thread time summed over %s threads)\n", threads ? "the given" : "all");
    fclose(csv);
    refl_frame_destroy(f);
    refl_frame_destroy(truth);
    refl_scene_destroy(s);
    if (ok) fprintf(stderr, "wrote %s\n", path);
    return ok;
}

/* Mean screen area, in pixels, of the teapot's triangles that face the
   view and lie in front of it. */
static double mean_triangle_pixels(const refl_scene *s, const refl_view *v, int object) {
    const refl_object *o = &s->objects[object];
    const refl_mesh *m = s->meshes[o->mesh];
    refl_mat4 view_m, proj_m, vp;
    double sum = 0.0;
    long n = 0;
    int t, k;
    refl_view_matrices(v, s, &view_m, &proj_m);
    vp = refl_mat4_mul(proj_m, view_m);
    for (t = 0; t < m->triangle_count; ++t) {
        double x[3], y[3], area;
        int front = 1;
        for (k = 0; k < 3; ++k) {
            const float *q = m->positions + 3 * m->indices[3 * t + k];
            refl_vec3 w = refl_mat4_point(o->transform, refl_v3(q[0], q[1], q[2]));
            const float *a = vp.m;
            double cx = a[0] * w.x + a[4] * w.y + a[8] * w.z + a[12], cy = a[1] * w.x + a[5] * w.y + a[9] * w.z + a[13];
            double cw = a[3] * w.x + a[7] * w.y + a[11] * w.z + a[15];
            if (!(cw > 0.0)) front = 0;
            x[k] = (cx / cw + 1.0) * 0.5 * v->width;
            y[k] = (1.0 - cy / cw) * 0.5 * v->height;
        }
        area = 0.5 * ((x[1] - x[0]) * (y[2] - y[0]) - (x[2] - x[0]) * (y[1] - y[0]));
        if (!front || area >= 0.0) continue; /* y down: front faces wind negative */
        sum -= area;
        ++n;
    }
    return n ? sum / (double)n : 0.0;
}

/* The cameras' error against the reflector triangles' size on screen (the
   teapot at 2x2 .. 32x32 per patch, 640x480, against one-bounce RAYTRACE):
   the paper's cameras (one per triangle), ours (split where a camera's
   estimated error exceeds 0.1 px), and the rendered image's error at the
   default density. */
static int triangle_size(const char *dir, int threads, int full) {
    static const int tess[] = {2, 4, 8, 16, 32};
    char path[1024];
    FILE *dat;
    int i, ok = 1;
    snprintf(path, sizeof path, "%s/c3rc_triangle_size.dat", dir);
    if (!(dat = fopen(path, "w"))) return 0;
    fprintf(dat, "# tess teapot_triangles mean_triangle_pixels paper_mean paper_p95 paper_none split_mean split_p95 "
                 "split_none image_mean image_p95 cameras\n");
    for (i = 0; ok && i < (full ? 5 : 4); ++i) {
        refl_scene *s = default_scene(tess[i]);
        refl_frame *f = NULL, *truth = NULL;
        refl_render_desc d;
        refl_reflection_error paper, split, img;
        refl_view v;
        double px = 0.0;
        int k, teapot = -1;
        if (!s) { ok = 0; break; }
        v = view_640(s);
        for (k = 0; k < s->object_count; ++k)
            if (!strcmp(s->objects[k].name, "teapot")) teapot = k;
        ok = teapot >= 0 && refl_frame_create(v.width, v.height, NULL, &f) == REFL_OK &&
             refl_frame_create(v.width, v.height, NULL, &truth) == REFL_OK;
        memset(&d, 0, sizeof d);
        d.threads = threads;
        d.depth = 1;
        d.method = REFL_RAYTRACE;
        if (ok) ok = refl_render(s, &v, &d, truth) == REFL_OK;
        d.method = REFL_C3RC;
        if (ok) ok = refl_render(s, &v, &d, f) == REFL_OK;
        if (ok) ok = refl_measure_reflection_error(f, truth, NULL, &img) == REFL_OK &&
                     refl_c3rc_measure_camera_error(s, &v, truth, -1.0f, &paper) == REFL_OK &&
                     refl_c3rc_measure_camera_error(s, &v, truth, 0.0f, &split) == REFL_OK;
        if (ok) {
            px = mean_triangle_pixels(s, &v, teapot);
            fprintf(dat, "%d %d %.2f %.4f %.4f %.5f %.4f %.4f %.5f %.4f %.4f %lld\n", tess[i],
                    s->meshes[s->objects[teapot].mesh]->triangle_count, px, paper.mean, paper.p95, paper.wrong,
                    split.mean, split.p95, split.wrong, img.mean, img.p95, f->stats.c3rc.cameras);
            fprintf(stderr, "  C3RC teapot %2dx%-2d (%5d triangles, %7.1f px each): cameras per triangle: mean %.3f "
                            "p95 %.3f px (none %.4f); split (%lld cameras): mean %.3f p95 %.3f px; image: mean %.3f "
                            "p95 %.3f px\n",
                    tess[i], tess[i], s->meshes[s->objects[teapot].mesh]->triangle_count, px, paper.mean, paper.p95,
                    paper.wrong, f->stats.c3rc.cameras, split.mean, split.p95, img.mean, img.p95);
        }
        refl_frame_destroy(f);
        refl_frame_destroy(truth);
        refl_scene_destroy(s);
    }
    fclose(dat);
    if (ok) {
        char script[8192], gp[1100];
        snprintf(script, sizeof script,
                 "set terminal pngcairo size 900,600 noenhanced\nset output '%s/c3rc_triangle_size.png'\n"
                 "set title 'C3RC against one-bounce RAYTRACE, default scene 640x480'\n"
                 "set xlabel 'mean teapot triangle size on screen (pixels)'\n"
                 "set ylabel 'reflection error (pixels)'\nset logscale xy\nset grid\nset key top left\n"
                 "plot '%s' using 3:5 with linespoints title 'a camera per triangle (paper), p95', "
                 "'%s' using 3:4 with linespoints title 'a camera per triangle (paper), mean', "
                 "'%s' using 3:8 with linespoints title 'split cameras (0.1 px), p95', "
                 "'%s' using 3:11 with linespoints title 'rendered image (points), p95'\n",
                 dir, path, path, path, path);
        snprintf(gp, sizeof gp, "%s/c3rc_triangle_size.gp", dir);
        ok = refl_bench_gnuplot(gp, script);
    }
    return ok;
}

int refl_bench_c3rc(const char *dir, int threads, int repeats, int full) {
    return tables(dir, threads, repeats) && triangle_size(dir, threads, full);
}
