/* reflect_gl - the GL path's checks as a program of its own that links
   libEGL alone (no OpenImageIO, Embree or tinygltf), so it runs on a bare
   machine with a vendor's EGL (tools/gl_device_check.sh):

     reflect_gl info                    EGL vendor, GL renderer and version
     reflect_gl validate [--points N] [--csv FILE]
                                        every camera's GLSL projection against its C
                                        projection (transform feedback); fails when
                                        they disagree beyond the bounds of docs/gl.md
     reflect_gl bench [--points N] [--repeats R] [--csv FILE]
                                        projection rate of every camera, GL beside C

   Exit status 0 on success, 1 on a failed check, 2 on bad usage, 3 when no
   EGL context can be created. */
#define _POSIX_C_SOURCE 200809L
#include "../reflect.h"
#include "reflect_gl.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int main(int argc, char **argv) {
    const char *cmd = argc > 1 ? argv[1] : "", *csv_path = NULL;
    long long points = -1;
    int repeats = 5, i, failed = 0;
    rgl_context *g = NULL;
    char err[1024];
    FILE *csv = NULL;
    if (strcmp(cmd, "info") && strcmp(cmd, "validate") && strcmp(cmd, "bench")) {
        fprintf(stderr, "usage: reflect_gl info | validate [--points N] [--csv FILE] |"
                        " bench [--points N] [--repeats R] [--csv FILE]\n");
        return 2;
    }
    for (i = 2; i < argc; ++i) {
        if (!strcmp(argv[i], "--points") && i + 1 < argc) points = atoll(argv[++i]);
        else if (!strcmp(argv[i], "--repeats") && i + 1 < argc) repeats = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--csv") && i + 1 < argc) csv_path = argv[++i];
        else {
            fprintf(stderr, "reflect_gl: unknown argument %s\n", argv[i]);
            return 2;
        }
    }
    if (points < 0) points = !strcmp(cmd, "bench") ? 1000000 : 100000;
    if (rgl_create(&g, err, sizeof err) != 0) {
        fprintf(stderr, "reflect_gl: no GL context: %s\n", err);
        return 3;
    }
    printf("EGL vendor:  %s\nGL renderer: %s\nGL version:  %s\n", rgl_egl_vendor(g), rgl_renderer(g),
           rgl_version(g));
    if (!strcmp(cmd, "info")) {
        rgl_destroy(g);
        return 0;
    }
    if (csv_path && !(csv = fopen(csv_path, "w"))) {
        fprintf(stderr, "reflect_gl: cannot write %s\n", csv_path);
        rgl_destroy(g);
        return 2;
    }
    if (csv)
        fprintf(csv, "renderer,camera,points,projected,disagree,max_rel,p999_rel,gl_seconds,gl_mpoints_per_s,"
                     "cpu_seconds,cpu_mpoints_per_s,fixture\n");
    for (i = 0; i < RGL_CAMERAS; ++i) {
        rgl_validation v;
        if (rgl_validate(g, i, points, !strcmp(cmd, "bench") ? repeats : 1, &v, err, sizeof err) != 0) {
            fprintf(stderr, "reflect_gl: camera %d: %s\n", i, err);
            failed = 1;
            continue;
        }
        printf("%-12s %9lld points, %9lld projected, %6lld disagree (%.2e), max rel %.2e, p99.9 %.2e, "
               "GL %.2f M/s, C %.2f M/s, leaves %lld/%lld  [%s]\n",
               v.camera, v.points, v.projected, v.disagree, (double)v.disagree / (double)v.points, v.max_rel,
               v.p999_rel, v.points / v.gl_seconds * 1e-6, v.points / v.cpu_seconds * 1e-6, v.pinhole_points, v.raylist_points, v.note);
        if (csv)
            fprintf(csv, "\"%s\",%s,%lld,%lld,%lld,%.3e,%.3e,%.6f,%.3f,%.6f,%.3f,\"%s\"\n", rgl_renderer(g), v.camera,
                    v.points, v.projected, v.disagree, v.max_rel, v.p999_rel, v.gl_seconds,
                    v.points / v.gl_seconds * 1e-6, v.cpu_seconds, v.points / v.cpu_seconds * 1e-6, v.note);
        if (!strcmp(cmd, "validate") && !rgl_validation_ok(&v)) {
            fprintf(stderr, "reflect_gl: %s: GLSL and C disagree beyond the bounds\n", v.camera);
            failed = 1;
        }
    }
    if (csv) fclose(csv);
    rgl_destroy(g);
    return failed;
}
