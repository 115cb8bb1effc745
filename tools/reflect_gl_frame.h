/* reflect_gl_frame.h - what the GL path's methods share (inside the GL
   host; tools/reflect_gl_frame.c): the scene's triangles in world space
   for GL, the float G-buffer framebuffer, the base pass from the eye (each
   object's stencil mark chosen by the method) read back, the pixels' eye
   rays, and the CPU's shading of what a pixel shows. PLANAR
   (reflect_gl_frame.c), C3RC (reflect_gl_c3rc.c) and SBC (reflect_gl_sbc.c)
   draw their reflections into the same framebuffer after the base pass.
   Include after reflect.h, reflect_gl.h and reflect_gl_funcs.h. */
#ifndef REFLECT_GL_FRAME_H
#define REFLECT_GL_FRAME_H

#include <stdint.h>

enum { RGL_VERTEX_FLOATS = 9 }; /* world position, normal, uv, object id + 1 */
extern const int rgl_vertex_sizes[3]; /* its attributes' floats: 3, 3, 3 */

/* A planar mirror object: its world plane n . x = d, n towards the eye. */
typedef struct rgl_mirror {
    int object;
    double n[3], d;
} rgl_mirror;

/* The scene's triangles in world space (RGL_VERTEX_FLOATS per vertex),
   each object's range, and its planar mirrors seen from the front. */
typedef struct rgl_geometry {
    float *v;
    long long vertex_count;
    long long *first;        /* per object, and one past the last */
    rgl_mirror *mirrors;
    int mirror_count;
} rgl_geometry;

/* A frame in progress: the framebuffer (3 RGBA32F targets: world point and
   object id + 1, normal and the side seen (1: a back face), uv; depth and stencil), the geometry's vertex
   buffer bound at attributes 0-2, and the base pass read back. */
typedef struct rgl_pass {
    const refl_scene *scene;
    const refl_view *view;
    int w, h;
    rgl_geometry geo;
    refl_mat4 view_m, proj_m, vp, vp_inv;
    GLuint fbo, rb[4], vao, vbo, base_prog;
    float *base[3];          /* the base pass: point + id, normal, uv; rows top first */
    uint8_t *marks;          /* the base pass's stencil: each pixel's object's mark */
} rgl_pass;

/* The G-buffer shaders: a vertex shader's inputs and outputs (the caller
   writes gl_Position) and the fragment shader writing the three targets. */
extern const char rgl_frame_vs_head[];
extern const char rgl_frame_fs[];

/* Builds the geometry, the framebuffer and the vertex buffer, draws the
   base pass with object o marking its pixels with mark[o] (0: none) and
   reads it back. On failure: nonzero, the reason in err, p left for
   rgl_pass_end. */
int rgl_pass_begin(rgl_pass *p, const refl_scene *scene, const refl_view *view, const uint8_t *mark, char *err,
                   size_t n);
void rgl_pass_end(rgl_context *g, rgl_pass *p);
/* A method's frame through GL from its base pass to its end: the pass,
   the marks it was drawn with, the method's own GL objects (0: none) and
   its reflections read back, which rgl_method_end releases, so a method's
   error exit frees only what is its own; t0 and t_cpu time the frame. */
typedef struct rgl_method_pass {
    rgl_pass ps;
    uint8_t *mark;           /* per object: the mark its pixels take (0: none) */
    GLuint prog, vao, vbo;   /* the method's program and vertices */
    GLuint tex, tbuf;        /* its data as a buffer texture (rgl_method_data) */
    GLuint ray_tex[2];       /* its pixels' rays (rgl_pass_reflect_begin's) */
    float *drawn[3];         /* colour attachments read back (rgl_method_read) */
    double t0, t_cpu;        /* when the frame began; the CPU's share of it so far */
} rgl_method_pass;
/* The reflector methods' start (C3RC, SBC, SPOC, GRAPHCAM): *st zeroed,
   the clock started, frame checked against the view's size, each mirror
   and partial reflector (objects below 254) marking its pixels with its
   object + 1 in m->mark, the base pass drawn. Nonzero on failure, the
   reason in err, m left for rgl_method_end. */
int rgl_method_begin(rgl_method_pass *m, const refl_scene *scene, const refl_view *view, const refl_frame *frame,
                     rgl_frame_stats *st, char *err, size_t n);
/* The method's data (`floats` floats) as its buffer texture, replacing
   the last, bound on texture unit 0. Nonzero with the reason in err. */
int rgl_method_data(rgl_method_pass *m, const float *data, long long floats, char *err, size_t n);
/* Colour attachments 0 .. count - 1 (at most 3) read into m->drawn
   (allocated on the first read), then GL's errors checked (`what`: the
   draw, for err). Nonzero with the reason in err. */
int rgl_method_read(rgl_method_pass *m, int count, const char *what, char *err, size_t n);
/* The reflector methods' last step: the glass handed over
   (rgl_hand_over_glass), st->shade_seconds the CPU's time since t1 plus
   m->t_cpu. Nonzero with the reason in err. */
int rgl_method_finish(const rgl_method_pass *m, refl_frame *frame, float *rgb, rgl_frame_stats *st, double t1,
                      char *err, size_t n);
/* Releases all m holds (the pass, its GL objects, the marks and
   read-backs); returns rc, for a method's error exit. */
int rgl_method_end(rgl_context *g, rgl_method_pass *m, int rc);
/* A method's vertices: `count` of `stride` floats uploaded to a new buffer
   (*vbo) in a new vertex array (*vao), left bound; attribute i (0 ..
   attribs - 1) takes sizes[i] floats after attribute i - 1's. */
void rgl_pass_vertices(const float *v, long long count, int stride, const int *sizes, int attribs, GLuint *vao,
                       GLuint *vbo);
/* The reflections' draw starts (after the base pass): colour and depth
   cleared, the stencil (the marks) kept, prog in use with u_data on
   texture unit 0, u_vp the view's, and the pixels' rays
   (rgl_pass_ray_textures) as u_surf and u_ray. Nonzero when out of
   memory. */
int rgl_pass_reflect_begin(const rgl_pass *p, GLuint prog, GLuint ray_tex[2]);
/* A pixel's size per unit of distance from the eye. */
float rgl_pass_pixel_angle(const rgl_pass *p);
/* Deletes a method's own GL objects (0: none): its program, vertex array
   and buffer, camera data texture and buffer, ray textures. */
void rgl_pass_delete(GLuint prog, GLuint vao, GLuint vbo, GLuint tex, GLuint tbuf, const GLuint ray_tex[2]);
/* Reads colour attachment a (4 floats per pixel), rows top first. */
void rgl_pass_read(const rgl_pass *p, int a, float *out);
/* The eye ray through pixel i's centre (unit direction). */
refl_vec3 rgl_pass_ray(const rgl_pass *p, int i);
/* Per reflector pixel of the base pass, as 2-D RGBA32F textures (rows
   bottom first, as GL's): tex[0] its reflector point and how far its
   reflected ray turns to its 4-neighbours' on the same object (the
   largest distance between the unit rays), tex[1] its reflected ray and
   the side of its surface seen (1 front, -1 back: an open mesh's inside); bound
   to texture units 1 and 2. Nonzero when out of memory. */
int rgl_pass_ray_textures(const rgl_pass *p, GLuint tex[2]);
/* Nonzero with the reason in err when GL reported an error. */
int rgl_pass_check(const char *what, char *err, size_t n);

/* The CPU side: shade pixel data (point + id, normal, uv) into rgb as
   DIRECT shows it (a reflector's diffuse share only), or the environment
   along dir where it shows nothing; clamped below at 0. */
void rgl_shade(const refl_scene *s, const float *pt, const float *nrm, const float *uv, refl_vec3 dir, float rgb[3]);
/* The reflector methods' composite of pixel i (C3RC, SBC): the base pass
   shaded, and on a reflector pixel (its mark: object + 1) its reflectance
   times `shown` (the colour of what it shows, at world point `at`), or
   times the environment along its reflected ray where shown is NULL;
   frame's stencil and points, and rgb. */
void rgl_composite(const rgl_pass *p, int i, const float *shown, const float *at, refl_frame *frame, float *rgb);
/* The reflected eye ray at a reflector pixel: d reflected in the normal
   turned towards the eye. */
refl_vec3 rgl_reflect(refl_vec3 d, refl_vec3 normal);
/* The CPU's tracer for the reflector pixels GL's draw leaves to it (SBC's
   holes, C3RC's gaps): the ray from q along dir traced (bvh of the scene)
   into pt, nrm, uv as the G-buffer holds them; pt's id 0 where it leaves. */
void rgl_trace(const rgl_pass *p, const refl_bvh *bvh, refl_vec3 q, refl_vec3 dir, float pt[4], float nrm[4],
               float uv[4]);
/* The glass in view, which C3RC, SBC, SPOC and GRAPHCAM through GL do not
   draw, from the CPU as the CPU methods hand it over: a one-bounce frame
   with the glass through RAYTRACE's tracer, its pixels replacing GL's
   (st->handed, handed_over, handed_pixels). Nonzero with the reason in
   err on failure. */
int rgl_hand_over_glass(const rgl_pass *ps, refl_frame *frame, float *rgb, rgl_frame_stats *st, char *err, size_t n);

#endif
