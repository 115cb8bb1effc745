/* reflect_bench.h - the `reflect bench` subcommand (tools/reflect_bench.c),
   linked into the reflect command with the Embree peer. */
#ifndef REFL_CLI_BENCH_H
#define REFL_CLI_BENCH_H

#include "../reflect.h"

/* argv[1] is "bench"; returns the process exit status. */
int refl_cli_bench(int argc, char **argv);

/* argv[1] is "path" (tools/reflect_path.c): every method along a camera
   path against RAYTRACE; returns the process exit status. */
int refl_cli_path(int argc, char **argv);

/* Writes script to script_path and runs gnuplot on it; 0 on failure. */
int refl_bench_gnuplot(const char *script_path, const char *script);

/* Paper 000's Tables 1 and 2 and C3RC's error against reflector triangle
   size (tools/reflect_bench_c3rc.c), into dir; 0 on failure. */
int refl_bench_c3rc(const char *dir, int threads, int repeats, int full);

/* Paper 003's Fig. 19 (SBC construction at quarter and half resolution
   ray maps) and its projection rate per leaf kind
   (tools/reflect_bench_sbc.c): a table on stdout and dir/sbc_fig19.csv;
   0 on failure. */
int refl_bench_sbc(const char *dir, int threads, int repeats, int full);

/* SBC against RAYTRACE (our BVH and Embree) across resolutions
   (tools/reflect_bench_sbc_sweep.c): time, where SBC's goes, reflection
   error and the crossover; a table on stdout and dir/sbc_resolution.csv;
   0 on failure. */
int refl_bench_sbc_sweep(const char *dir, int threads, int repeats, int full);

/* A camera path of 30 frames on the default scene, each method rendered
   by refl_render per frame and by one renderer kept along the path
   (tools/reflect_bench_path.c): a table on stdout and dir/path.csv; 0 on
   failure, or when the two give other bytes. */
int refl_bench_path(const char *dir, int threads);

/* Paper 004's maze through its graph camera (tools/reflect_bench_graphcam.c):
   construction and frame time of both intersection algorithms, ENVMAP and
   RAYTRACE (ours, Embree) with their error against RAYTRACE, along a short
   path; a table on stdout and dir/graphcam_maze.csv; 0 on failure. */
int refl_bench_graphcam(const char *dir, int threads);

/* reflect bench --report DIR (tools/reflect_report.c): measures every
   method on the built-in scenes, along camera paths and across sizes, and
   writes the static page DIR/index.html with its charts and pictures.
   quick: two scenes at 64x48, few settings, one run each (for tests).
   0 on failure. */
int refl_bench_report(const char *dir, int threads, int repeats, int quick);

/* Per pixel of two RGBA8 images, the largest difference over their first
   `channels` channels, coloured black (0) through blue, red and yellow to
   white (full_scale levels or more), into rgb (3 bytes a pixel). The
   report's heat maps and reflect compare --diff. */
void refl_heat_map(const uint8_t *a, const uint8_t *b, long long count, int channels, int full_scale, uint8_t *rgb);

/* Built-in scene NAME with its teapots tessellated tess (0: the default);
   NULL on failure. */
refl_scene *refl_bench_builtin(const char *name, int tess);

/* `reflect bench --fit-auto FILE` and `--auto-table` (tools/reflect_bench_auto.c):
   AUTO's models fitted, and AUTO against every method; argv[1] is "bench";
   returns the process exit status. */
int refl_bench_auto(int argc, char **argv);
/* Paper 004's Tables 1 and 2 on the two-teapot scene (tools/reflect_bench_spoc.c):
   SPOC's construction and frame time (average, min, max) along a 60-frame
   path at four output and four impostor sizes, the longest ray march,
   RAYTRACE (ours, Embree) on the same frames, and the error against
   RAYTRACE; a table on stdout and dir/spoc_teapots.csv; 0 on failure. */
int refl_bench_spoc(const char *dir, int threads);

/* SPOC (and GRAPHCAM where its camera applies) where paper 004 says
   impostors fail (tools/reflect_bench_spoc.c): the teapots at 160x120
   with the camera orbiting them, the diffuse teapot moved until it
   touches the mirror, the impostor's size and a thin glass refractor,
   against RAYTRACE; a table on stdout and dir/spoc_sweeps.csv; 0 on
   failure or a non-finite pixel. */
int refl_bench_spoc_sweeps(const char *dir, int threads);

/* Paper 001's section 6 table on the hybrid scene (tools/reflect_bench_lem.c):
   LAYERED_EM's phases, rays and triangle tests with its maps kept, at
   640x480 3x3 subsampled (quick: 160x120) for t = 3 and 5 and each layer
   count, against greedy RAYTRACE and the full ray tree; a table on stdout,
   dir/lem_table.csv and dir/lem_table.md; 0 on failure or a non-finite
   pixel. */
int refl_bench_lem(const char *dir, int threads, int quick);

/* The same table's rays and triangle tests (default layers, t = 3 and 5)
   with a uniform grid as the ray caster (bench/grid_peer.h) beside
   refl_bvh: greedy RAYTRACE through a grid of the scene, LAYERED_EM's
   vertices through a grid of the lens objects alone, per grid resolution
   (tools/reflect_bench_lem.c): PBRT's resolution, with sweep a sweep around
   it, and the resolution fitted so that greedy RAYTRACE tests the paper's
   triangles a ray, with the full ray tree's extra cost;
   dir/lem_grid.{csv,md} (sweep; else dir/lem_grid_calib.{csv,md}) and
   dir/lem_grid_calibrated.{csv,md}; 0 on failure, where a grid's hits are
   not refl_bvh's, or where the fit does not converge. */
int refl_bench_lem_grid(const char *dir, int threads, int quick, int sweep);

/* LAYERED_EM where paper 001 says it fails (tools/reflect_bench_lem.c):
   off-sample eyes, sample spacing, layers, a column moved up to the lens,
   the tessellation's thresholds, a column moved after the maps were built;
   error against greedy RAYTRACE over the lens pixels at 160x120;
   dir/lem_sweeps.{csv,md,png}; 0 on failure or a non-finite pixel. */
int refl_bench_lem_sweeps(const char *dir, int threads);

/* LAYERED_EM's options beyond the defaults measured (tools/reflect_bench_lem.c):
   the other lens as a layer (lens_layers) and the direct images' origin and
   confidence, on `hybrid` and `glass` at 160x120 and 320x240 (quick: 160x120),
   against greedy RAYTRACE over the lens pixels and over those the defaults
   trace; dir/lem_options.md; 0 on failure or a non-finite pixel. */
int refl_bench_lem_options(const char *dir, int threads, int quick);

/* LAYERED_EM's shared outer layer (share_outer_layer) against each lens's
   own, on `hybrid` and `glass` at 160x120 over layer counts and shells:
   the frame's map bytes and the error against greedy RAYTRACE over the
   lens pixels, all and per lens; dir/lem_share.md; 0 on failure or a
   non-finite pixel. */
int refl_bench_lem_share(const char *dir, int threads);

/* A monotonic clock in ms, and the median of v[0..n) (sorts v). */
double refl_bench_now_ms(void);
double refl_bench_median(double *v, int n);

/* Renders `repeats` times (at most 32), keeps the last frame, the median
   and the fastest of the frames' stats.ms_total. */
refl_result refl_bench_timed_render(const refl_scene *s, const refl_view *v, const refl_render_desc *d, int repeats,
                                    refl_frame *f, double *median, double *fastest);

#endif
