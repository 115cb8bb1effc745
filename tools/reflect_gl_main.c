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
     reflect_gl frames [--sizes WxH,...] [--methods planar,c3rc,sbc,spoc,graphcam] [--scenes NAME,...|all]
                       [--truth-max-pixels N] [--csv FILE]
                                        PLANAR (mirror-room, default), C3RC and SBC (default),
                                        SPOC (teapots), GRAPHCAM (maze: its graph
                                        camera; default: the view's pinhole),
                                        or each on the built-in scenes listed, through GL
                                        against the CPU path (reflection error, PSNR
                                        over reflector pixels, frame times); RAYTRACE
                                        as the truth up to N pixels (default 640x480)

   Exit status 0 on success, 1 on a failed check, 2 on bad usage, 3 when no
   EGL context can be created. */
#define _POSIX_C_SOURCE 200809L
#include "../reflect.h"
#include "reflect_gl.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int main(int argc, char **argv) {
    const char *cmd = argc > 1 ? argv[1] : "", *csv_path = NULL, *sizes = "640x480", *methods = NULL, *scenes = NULL;
    long long points = -1, truth_max = 640 * 480;
    int repeats = 5, i, failed = 0;
    rgl_context *g = NULL;
    char err[1024];
    FILE *csv = NULL;
    if (strcmp(cmd, "info") && strcmp(cmd, "validate") && strcmp(cmd, "bench") && strcmp(cmd, "frames")) {
        fprintf(stderr, "usage: reflect_gl info | validate [--points N] [--csv FILE] |"
                        " bench [--points N] [--repeats R] [--csv FILE] |"
                        " frames [--sizes WxH,...] [--methods planar,c3rc,sbc,spoc,graphcam,layered-em] [--scenes NAME,...|all]"
                        " [--truth-max-pixels N] [--csv FILE]\n");
        return 2;
    }
    for (i = 2; i < argc; ++i) {
        if (!strcmp(argv[i], "--points") && i + 1 < argc) points = atoll(argv[++i]);
        else if (!strcmp(argv[i], "--repeats") && i + 1 < argc) repeats = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--csv") && i + 1 < argc) csv_path = argv[++i];
        else if (!strcmp(argv[i], "--sizes") && i + 1 < argc) sizes = argv[++i];
        else if (!strcmp(argv[i], "--methods") && i + 1 < argc) methods = argv[++i];
        else if (!strcmp(argv[i], "--scenes") && i + 1 < argc) scenes = argv[++i];
        else if (!strcmp(argv[i], "--truth-max-pixels") && i + 1 < argc) truth_max = atoll(argv[++i]);
        else if (!strcmp(argv[i], "--help")) {
            printf("see the top of tools/reflect_gl_main.c\n");
            return 0;
        } else {
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
    failed = !strcmp(cmd, "frames") ? rgl_bench_frames(g, sizes, methods, scenes, truth_max, csv)
                                    : rgl_bench_projection(g, points, !strcmp(cmd, "bench") ? repeats : 1,
                                                           !strcmp(cmd, "validate"), csv);
    if (csv) fclose(csv);
    rgl_destroy(g);
    return failed;
}
