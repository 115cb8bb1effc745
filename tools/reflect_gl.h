/* reflect_gl.h - the GL host of reflect.h's GL hooks (tools/reflect_gl.c):
   a headless EGL context (any vendor's EGL through GLVND: Mesa's llvmpipe
   here, a GPU's driver elsewhere) with desktop GL 3.3 core, the GL entry
   points loaded through eglGetProcAddress (so the host links libEGL only),
   and on top of it the cross-validation of every camera's GLSL projection
   against its C projection (transform feedback) and the projection rate.

   Every failure returns nonzero with the reason in err; nothing aborts, so
   callers skip cleanly where there is no EGL device. Include after
   reflect.h. */
#ifndef REFLECT_GL_H
#define REFLECT_GL_H

#include <stddef.h>
#include <stdio.h>

/* The context: opaque, one per process at a time. */
typedef struct rgl_context rgl_context;

/* Creates the context (made current). 0 on success; else nonzero with the
   reason in err. */
int rgl_create(rgl_context **out, char *err, size_t err_size);
void rgl_destroy(rgl_context *g);
const char *rgl_renderer(const rgl_context *g);  /* GL_RENDERER */
const char *rgl_version(const rgl_context *g);   /* GL_VERSION */
const char *rgl_egl_vendor(const rgl_context *g); /* EGL_VENDOR, and the EGL platform used */

/* A camera's GLSL projection against its C projection on `points` random
   points (a fixed seed): how many were compared, how many the two
   disagreed on (one projects and the other not, or a different count of
   C3RC images), and the largest and 99.9th-percentile error of the
   agreeing ones, relative to the fixture's scene size (docs/gl.md). */
typedef struct rgl_validation {
    const char *camera;      /* "mirror", "c3rc", "sbc-convex", "sbc-concave", "graphcam", "sbc-morph", "lem-shell", "spoc",
                                "sbc-morph-sheets" (the morph grid per sheet, as refl_render blends it) */
    long long points, projected, disagree;
    long long pinhole_points, raylist_points; /* SBC: agreeing points per leaf kind */
    double max_rel, p999_rel;
    double gl_seconds;       /* the transform-feedback pass alone (upload excluded), best of `repeats` */
    double cpu_seconds;      /* the C projection of the same points on one thread */
    char note[160];          /* the fixture: cameras, leaves */
} rgl_validation;

enum { RGL_CAMERAS = 9 };
/* Fixture i (0 .. RGL_CAMERAS - 1): builds it, projects `points` points
   both ways (GL `repeats` times, the best time kept). 0 on success. */
int rgl_validate(rgl_context *g, int i, long long points, int repeats, rgl_validation *out, char *err,
                 size_t err_size);

/* A frame of PLANAR through GL (tools/reflect_gl_frame.c): GL draws the
   base pass and each planar mirror through refl_mirror_project, the CPU
   shades with reflect.h's shading and composites as PLANAR does; the
   other mirrors and partial reflectors (curved ones) the CPU fills as
   CPU PLANAR hands them over, traced (docs/gl.md). Fills frame's stencil
   (on the reflectors' pixels: the object + 1; 0 elsewhere) and points
   (what each reflector pixel shows, NaN elsewhere), and rgb (3 linear
   floats per pixel, rows top first); frame is the view's size. One
   bounce. 0 on success. */
typedef struct rgl_frame_stats {
    int mirrors;             /* planar mirrors drawn through */
    long long vertices;      /* vertices GL transformed, every pass */
    double gl_seconds;       /* upload, both passes and the read-backs */
    double shade_seconds;    /* the CPU's shading and compositing (PLANAR: its hand-over's frame too) */
    int handed;              /* reflectors left to the CPU: PLANAR's that are not planar mirrors (to the CPU's
                                PLANAR); C3RC's, SBC's, SPOC's and GRAPHCAM's glass (to RAYTRACE's tracer) */
    int handed_over;         /* of those, the ones the CPU's frame handed to the tracer (PLANAR: curved) */
    long long handed_pixels; /* pixels of the glass the CPU traced (C3RC, SBC, SPOC, GRAPHCAM) */
    long long traced;        /* PLANAR: pixels the CPU filled; C3RC: the gaps' pixels traced on the CPU */
    long long points;        /* C3RC: the scene's points */
    long long projections;   /* C3RC: points of the leaves the cameras' box tests kept, after level of detail */
} rgl_frame_stats;
int rgl_render_planar(rgl_context *g, const refl_scene *scene, const refl_view *view, refl_frame *frame, float *rgb,
                      rgl_frame_stats *st, char *err, size_t err_size);

/* C3RC and SBC through GL (tools/reflect_gl_c3rc.c, reflect_gl_sbc.c;
   docs/gl.md): the base pass as above, then each reflector's projection
   in the vertex shader (the C3RC and SBC hooks) and GL's rasteriser, the
   CPU compositing as the CPU path does. The same outputs as
   rgl_render_planar: stencil on every mirror and partial reflector (object
   + 1), points where a reflector shows a surface. st->mirrors counts the
   cameras (C3RC) or the reflectors' SBCs. rgl_render dispatches on the
   method (PLANAR, C3RC, SBC, SPOC, GRAPHCAM, LAYERED_EM; else nonzero). */
int rgl_render_c3rc(rgl_context *g, const refl_scene *scene, const refl_view *view, refl_frame *frame, float *rgb,
                    rgl_frame_stats *st, char *err, size_t err_size);
int rgl_render_sbc(rgl_context *g, const refl_scene *scene, const refl_view *view, refl_frame *frame, float *rgb,
                   rgl_frame_stats *st, char *err, size_t err_size);
/* SPOC through GL (tools/reflect_gl_impostor.c; docs/gl.md): the base
   pass, then per reflector its SPOC impostors (built on the CPU as the CPU
   method builds them) marched in a fragment shader
   (refl_spoc_impostor_intersect) along each pixel's reflected ray, the
   exact part of the scene and the rays the impostors missed on the CPU.
   st->mirrors counts the impostors, st->traced the pixels traced,
   st->projections the march's steps. */
int rgl_render_spoc(rgl_context *g, const refl_scene *scene, const refl_view *view, refl_frame *frame, float *rgb,
                    rgl_frame_stats *st, char *err, size_t err_size);
/* GRAPHCAM through GL (tools/reflect_gl_impostor.c; docs/gl.md): the base
   pass, the graph camera's impostor (built on the CPU as the CPU method
   builds it; camera NULL: the view's pinhole at twice the frame's width,
   the CPU method's default) marched in a fragment shader along each
   reflector pixel's reflected ray (refl_graphcam_impostor_intersect,
   algorithm 2, 1 px a step), the billboards and the rays the impostor
   cannot answer on the CPU. st->mirrors counts the frusta, st->traced
   the pixels traced, st->projections the march's steps. rgl_render draws
   GRAPHCAM with camera NULL. */
int rgl_render_graphcam(rgl_context *g, const refl_scene *scene, const refl_view *view, const refl_graphcam *camera,
                        refl_frame *frame, float *rgb, rgl_frame_stats *st, char *err, size_t err_size);
/* The SPOC impostor hook's march (refl_spoc_impostor_intersect, one
   fragment per ray) against refl_impostor_intersect on `rays` random rays
   (a fixed seed) from the teapots' mirror teapot, 80% towards the diffuse
   teapot's impostor: `disagree` rays hit on one side only, max_rel and
   p999_rel the hit distance's error over the impostor's diameter. */
int rgl_validate_spoc_impostor(rgl_context *g, long long rays, rgl_validation *out, char *err, size_t err_size);
/* The graph camera impostor hook's march (refl_graphcam_impostor_intersect)
   against refl_graphcam_intersect (segments, 1 px a step) on `rays`
   random rays (a fixed seed) from around the maze's mirror sphere, the
   maze's camera at 960 x 588: max_rel and p999_rel the hit distance's
   error over the camera's bounds' diagonal. */
int rgl_validate_graphcam_impostor(rgl_context *g, long long rays, rgl_validation *out, char *err, size_t err_size);
/* LAYERED_EM through GL (tools/reflect_gl_lem.c; docs/gl.md): the CPU's
   plan of each lens (refl_renderer_lem_lenses, a renderer of
   rgl_lem_desc's desc: its maps inferred each call), GL's draws of its
   tessellation through the layers' lookups (the LAYERED_EM shell hook),
   composited on the CPU as the CPU path does; the pixels it traces taken
   from RAYTRACE of the same desc. Stencil on every lens (object + 1);
   st->mirrors counts the lenses, st->traced the pixels traced. */
int rgl_render_layered_em(rgl_context *g, const refl_scene *scene, const refl_view *view, refl_frame *frame,
                          float *rgb, rgl_frame_stats *st, char *err, size_t err_size);
/* The same with a LAYERED_EM desc (NULL: rgl_lem_desc's). */
int rgl_render_layered_em_desc(rgl_context *g, const refl_scene *scene, const refl_view *view,
                               const refl_render_desc *desc, refl_frame *frame, float *rgb, rgl_frame_stats *st,
                               char *err, size_t err_size);
/* The desc of the GL path's LAYERED_EM frame (its defaults: depth 6): the
   CPU frame it compares with. */
void rgl_lem_desc(refl_render_desc *d);
int rgl_render(rgl_context *g, refl_method method, const refl_scene *scene, const refl_view *view, refl_frame *frame,
               float *rgb, rgl_frame_stats *st, char *err, size_t err_size);

/* PSNR (dB) of a GL frame's colours (rgb, from rgl_render_planar) against
   the CPU frame's over the planar mirrors' pixels (gl's stencil), both
   encoded to sRGB8; NaN without mirror pixels. */
double rgl_mirror_psnr(const refl_frame *cpu, const refl_frame *gl, const float *gl_rgb);

/* The GL path's numbers (tools/reflect_gl_bench.c), a line each on stdout
   and, when csv is not NULL, a CSV header and rows. rgl_bench_projection:
   every camera's validation on `points` points, GL timed best of
   `repeats` (check: nonzero when one fails rgl_validation_ok).
   rgl_bench_frames: frames through GL against the CPU path (PLANAR on
   mirror-room and default, C3RC and SBC on default, SPOC on teapots, GRAPHCAM on
   maze (its graph camera, 1920 x 1176) and default (the view's pinhole),
   LAYERED_EM on hybrid against its own CPU frame, PSNR only; `methods`
   "planar,c3rc,sbc,spoc,graphcam,layered-em" or a part of it, NULL all but
   layered-em; `scenes` a comma-separated list of built-in
   scenes each method runs on instead, "all" every one, NULL or "" each
   method's own) at each size of "WxH,WxH,...", RAYTRACE as the
   truth up to truth_max pixels. Return 0 on success. */
int rgl_bench_projection(rgl_context *g, long long points, int repeats, int check, FILE *csv);
int rgl_bench_frames(rgl_context *g, const char *sizes, const char *methods, const char *scenes, long long truth_max,
                     FILE *csv);

/* `reflect bench --gl [--out DIR] [--sizes ...] [--points N] [--repeats R]`:
   both of the above into DIR/gl_projection.csv and DIR/gl_frames.csv. */
int rgl_cli_bench(int argc, char **argv);

/* The agreement a validation must show (docs/gl.md): at most this share
   of points projecting on one side only, and the errors of the others. */
#define RGL_MAX_DISAGREE 1e-3
#define RGL_MAX_P999 1e-4
#define RGL_MAX_REL 1e-2
int rgl_validation_ok(const rgl_validation *v);

#endif
