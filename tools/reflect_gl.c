/* reflect_gl.c - the GL host of reflect.h's GL hooks (see reflect_gl.h):
   the EGL context, the GL entry points, and the cross-validation of every
   camera's GLSL projection against its C projection by transform
   feedback, on fixtures built here (a sphere and a concave bowl seen from
   one eye; docs/gl.md). */
#define _POSIX_C_SOURCE 200809L
#include "../reflect.h"
#include "reflect_gl.h"

#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <GL/gl.h>

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "name_in_list.h"
#include "reflect_gl_funcs.h"

#ifndef EGL_PLATFORM_SURFACELESS_MESA
#define EGL_PLATFORM_SURFACELESS_MESA 0x31DD
#endif
#ifndef EGL_PLATFORM_DEVICE_EXT
#define EGL_PLATFORM_DEVICE_EXT 0x313F
#endif

rgl_funcs rgl;

struct rgl_context {
    EGLDisplay dpy;
    EGLContext ctx;
    GLuint fbo, rb;
    char renderer[160], version[160], vendor[200];
};

static int rgl__fail(char *err, size_t n, const char *what) {
    if (err && n) snprintf(err, n, "%s", what);
    return -1;
}

/* A GL 3.3 core context on dpy, made current without a surface; 0 on success. */
static int rgl__context_on(rgl_context *g, EGLDisplay dpy, char *err, size_t n) {
    static const EGLint conf_pbuf[] = {EGL_SURFACE_TYPE, EGL_PBUFFER_BIT, EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT,
                                       EGL_NONE};
    static const EGLint conf_any[] = {EGL_SURFACE_TYPE, 0, EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
    static const EGLint ctx_attrs[] = {EGL_CONTEXT_MAJOR_VERSION, 3, EGL_CONTEXT_MINOR_VERSION, 3,
                                       EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                                       EGL_NONE};
    EGLint major = 0, minor = 0, nconf = 0;
    EGLConfig conf = NULL;
    if (!eglInitialize(dpy, &major, &minor)) {
        snprintf(err, n, "eglInitialize failed (0x%x)", (unsigned)eglGetError());
        return -1;
    }
    if (!eglBindAPI(EGL_OPENGL_API)) {
        eglTerminate(dpy);
        return rgl__fail(err, n, "eglBindAPI(EGL_OPENGL_API) failed: no desktop GL through EGL");
    }
    if ((!eglChooseConfig(dpy, conf_pbuf, &conf, 1, &nconf) || nconf < 1) &&
        (!eglChooseConfig(dpy, conf_any, &conf, 1, &nconf) || nconf < 1)) {
        eglTerminate(dpy);
        return rgl__fail(err, n, "eglChooseConfig found no desktop-GL config");
    }
    g->ctx = eglCreateContext(dpy, conf, EGL_NO_CONTEXT, ctx_attrs);
    if (g->ctx == EGL_NO_CONTEXT) {
        snprintf(err, n, "eglCreateContext(GL 3.3 core) failed (0x%x)", (unsigned)eglGetError());
        eglTerminate(dpy);
        return -1;
    }
    if (!eglMakeCurrent(dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, g->ctx)) {
        snprintf(err, n, "eglMakeCurrent without a surface failed (0x%x)", (unsigned)eglGetError());
        eglDestroyContext(dpy, g->ctx);
        g->ctx = EGL_NO_CONTEXT;
        eglTerminate(dpy);
        return -1;
    }
    g->dpy = dpy;
    return 0;
}

int rgl_create(rgl_context **out, char *err, size_t n) {
    const char *cext = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS), *s, *platform = "default";
    PFNEGLGETPLATFORMDISPLAYEXTPROC get_display =
        (PFNEGLGETPLATFORMDISPLAYEXTPROC)eglGetProcAddress("eglGetPlatformDisplayEXT");
    rgl_context *g;
    int ok = 0;
    *out = NULL;
    g = (rgl_context *)calloc(1, sizeof *g);
    if (!g) return rgl__fail(err, n, "out of memory");
    g->dpy = EGL_NO_DISPLAY;
    g->ctx = EGL_NO_CONTEXT;
    snprintf(err, n, "no EGL display (client extensions: %s)", cext ? cext : "(none)");
    /* a device first (a GPU's driver lists its GPUs), then Mesa's
       surfaceless platform, then the default display */
    if (get_display && name_in_list(cext, "EGL_EXT_platform_device", ' ')) {
        PFNEGLQUERYDEVICESEXTPROC query_devices = (PFNEGLQUERYDEVICESEXTPROC)eglGetProcAddress("eglQueryDevicesEXT");
        EGLDeviceEXT devs[16];
        EGLint nd = 0, i;
        if (query_devices && query_devices(16, devs, &nd)) {
            for (i = 0; i < nd && !ok; i++) {
                EGLDisplay d = get_display(EGL_PLATFORM_DEVICE_EXT, devs[i], NULL);
                if (d != EGL_NO_DISPLAY && rgl__context_on(g, d, err, n) == 0) {
                    ok = 1;
                    platform = "device";
                }
            }
        }
    }
    if (!ok && get_display && name_in_list(cext, "EGL_MESA_platform_surfaceless", ' ')) {
        EGLDisplay d = get_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, NULL);
        if (d != EGL_NO_DISPLAY && rgl__context_on(g, d, err, n) == 0) {
            ok = 1;
            platform = "surfaceless";
        }
    }
    if (!ok) {
        EGLDisplay d = eglGetDisplay(EGL_DEFAULT_DISPLAY);
        if (d != EGL_NO_DISPLAY && rgl__context_on(g, d, err, n) == 0) ok = 1;
    }
    if (!ok) {
        free(g);
        return -1;
    }
    if (rgl_funcs_load(&rgl, err, n) != 0) {
        rgl_destroy(g);
        return -1;
    }
    /* draws need a complete framebuffer even with the rasteriser off, and
       a surfaceless context has none: a 1 x 1 one until a frame binds its own */
    rgl.GenRenderbuffers(1, &g->rb);
    rgl.BindRenderbuffer(GL_RENDERBUFFER, g->rb);
    rgl.RenderbufferStorage(GL_RENDERBUFFER, GL_RGBA8, 1, 1);
    rgl.GenFramebuffers(1, &g->fbo);
    rgl.BindFramebuffer(GL_FRAMEBUFFER, g->fbo);
    rgl.FramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, g->rb);
    s = (const char *)rgl.GetString(GL_RENDERER);
    snprintf(g->renderer, sizeof g->renderer, "%s", s ? s : "(null)");
    s = (const char *)rgl.GetString(GL_VERSION);
    snprintf(g->version, sizeof g->version, "%s", s ? s : "(null)");
    s = eglQueryString(g->dpy, EGL_VENDOR);
    snprintf(g->vendor, sizeof g->vendor, "%s (EGL platform: %s)", s ? s : "(null)", platform);
    *out = g;
    return 0;
}

void rgl_destroy(rgl_context *g) {
    if (!g) return;
    if (g->ctx != EGL_NO_CONTEXT) {
        if (g->fbo) rgl.DeleteFramebuffers(1, &g->fbo);
        if (g->rb) rgl.DeleteRenderbuffers(1, &g->rb);
        eglMakeCurrent(g->dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
        eglDestroyContext(g->dpy, g->ctx);
    }
    if (g->dpy != EGL_NO_DISPLAY) eglTerminate(g->dpy);
    free(g);
}

const char *rgl_renderer(const rgl_context *g) { return g->renderer; }
GLuint rgl_default_framebuffer(const rgl_context *g) { return g->fbo; }
const char *rgl_version(const rgl_context *g) { return g->version; }
const char *rgl_egl_vendor(const rgl_context *g) { return g->vendor; }

/* ---- programs ---------------------------------------------------------------- */

GLuint rgl_program(const char *const *vs_parts, int vs_count, const char *const *fs_parts, int fs_count,
                   const char *const *varyings, int varying_count, char *err, size_t n) {
    GLuint prog = rgl.CreateProgram(), sh[2] = {0, 0};
    GLint ok = 0;
    int i;
    for (i = 0; i < 2; ++i) {
        const char *const *parts = i ? fs_parts : vs_parts;
        int count = i ? fs_count : vs_count;
        if (!count) continue;
        sh[i] = rgl.CreateShader(i ? GL_FRAGMENT_SHADER : GL_VERTEX_SHADER);
        rgl.ShaderSource(sh[i], count, parts, NULL);
        rgl.CompileShader(sh[i]);
        rgl.GetShaderiv(sh[i], GL_COMPILE_STATUS, &ok);
        if (!ok) {
            char log[1024] = "";
            rgl.GetShaderInfoLog(sh[i], (GLsizei)sizeof log, NULL, log);
            snprintf(err, n, "%s shader compile failed: %s", i ? "fragment" : "vertex", log);
            rgl.DeleteShader(sh[i]);
            if (i && sh[0]) rgl.DeleteShader(sh[0]);
            rgl.DeleteProgram(prog);
            return 0;
        }
        rgl.AttachShader(prog, sh[i]);
    }
    if (varying_count) rgl.TransformFeedbackVaryings(prog, varying_count, varyings, GL_INTERLEAVED_ATTRIBS);
    rgl.LinkProgram(prog);
    for (i = 0; i < 2; ++i)
        if (sh[i]) rgl.DeleteShader(sh[i]);
    rgl.GetProgramiv(prog, GL_LINK_STATUS, &ok);
    if (!ok) {
        char log[1024] = "";
        rgl.GetProgramInfoLog(prog, (GLsizei)sizeof log, NULL, log);
        snprintf(err, n, "program link failed: %s", log);
        rgl.DeleteProgram(prog);
        return 0;
    }
    return prog;
}

GLuint rgl_buffer_texture(const float *data, long long floats, GLuint *buffer, char *err, size_t n) {
    GLint max_texels = 0;
    GLuint tex = 0;
    rgl.GetIntegerv(GL_MAX_TEXTURE_BUFFER_SIZE, &max_texels);
    if (floats / 4 > (long long)max_texels) {
        snprintf(err, n, "camera data of %lld texels over GL_MAX_TEXTURE_BUFFER_SIZE (%d)", floats / 4, max_texels);
        return 0;
    }
    rgl.GenBuffers(1, buffer);
    rgl.BindBuffer(GL_TEXTURE_BUFFER, *buffer);
    rgl.BufferData(GL_TEXTURE_BUFFER, (GLsizeiptr)(floats * (long long)sizeof(float)), data, GL_STATIC_DRAW);
    rgl.GenTextures(1, &tex);
    rgl.BindTexture(GL_TEXTURE_BUFFER, tex);
    rgl.TexBuffer(GL_TEXTURE_BUFFER, GL_RGBA32F, *buffer);
    return tex;
}

double rgl_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* ---- fixtures ---------------------------------------------------------------- */

/* The fixtures' world: a unit sphere at the origin (and a bowl, the inside
   of a sphere of radius 2) in the box [-4, 4]^3, seen from one eye. Errors
   are relative to the box's diagonal. */
#define RGL_MAXD(a, b) ((a) > (b) ? (a) : (b))
#define RGL_BOX 4.0f
#define RGL_SCENE_SIZE (2.0 * 1.7320508 * RGL_BOX)

typedef struct rgl_rng { uint64_t s; } rgl_rng;
static double rgl__rand(rgl_rng *r) {
    r->s = r->s * 6364136223846793005ULL + 1442695040888963407ULL;
    return (double)(r->s >> 11) * (1.0 / 9007199254740992.0);
}
static double rgl__range(rgl_rng *r, double lo, double hi) { return lo + (hi - lo) * rgl__rand(r); }

static refl_vec3 rgl__box_point(rgl_rng *r) {
    return refl_v3((float)rgl__range(r, -RGL_BOX, RGL_BOX), (float)rgl__range(r, -RGL_BOX, RGL_BOX),
                   (float)rgl__range(r, -RGL_BOX, RGL_BOX));
}

/* The desired view of the SBC fixtures. */
typedef struct rgl_view {
    refl_vec3 eye, fwd, right, up;
    float tan_half, aspect;
    int width, height;
    refl_mat4 vp;
} rgl_view;

static rgl_view rgl__view(refl_vec3 eye, refl_vec3 target, float fovy_deg, int w, int h) {
    rgl_view v;
    float fovy = fovy_deg * 3.14159265f / 180.0f;
    v.eye = eye;
    v.fwd = refl_v3_normalize(refl_v3_sub(target, eye));
    v.right = refl_v3_normalize(refl_v3_cross(v.fwd, refl_v3(0, 1, 0)));
    v.up = refl_v3_cross(v.right, v.fwd);
    v.tan_half = tanf(0.5f * fovy);
    v.aspect = (float)w / (float)h;
    v.width = w;
    v.height = h;
    v.vp = refl_mat4_mul(refl_mat4_perspective(fovy, v.aspect, 0.05f, 50.0f), refl_mat4_look_at(eye, target, refl_v3(0, 1, 0)));
    return v;
}

static refl_vec3 rgl__view_dir(const rgl_view *v, double px, double py) {
    float x = (float)((2.0 * px / v->width - 1.0) * v->tan_half * v->aspect);
    float y = (float)((1.0 - 2.0 * py / v->height) * v->tan_half);
    return refl_v3_normalize(refl_v3_add(v->fwd, refl_v3_add(refl_v3_scale(v->right, x), refl_v3_scale(v->up, y))));
}

/* A ray map of a sphere (centre 0, radius, seen from outside; inside when
   `inside`: the bowl) over the view's pixels; *valid marks hits. */
static void rgl__sphere_map(const rgl_view *v, refl_vec3 centre, float radius, int inside, refl_sbc_ray *rays,
                            uint8_t *valid) {
    refl_vec3 box_lo = refl_v3(-RGL_BOX, -RGL_BOX, -RGL_BOX), box_hi = refl_v3(RGL_BOX, RGL_BOX, RGL_BOX);
    int x, y;
    for (y = 0; y < v->height; ++y) {
        for (x = 0; x < v->width; ++x) {
            refl_vec3 d = rgl__view_dir(v, x + 0.5, y + 0.5), o = refl_v3_sub(v->eye, centre), p, nrm, r;
            float b = refl_v3_dot(o, d), c = refl_v3_dot(o, o) - radius * radius, disc = b * b - c, t, t_exit;
            int i = y * v->width + x;
            valid[i] = 0;
            memset(&rays[i], 0, sizeof rays[i]);
            if (disc < 0.0f) continue;
            t = inside ? -b + sqrtf(disc) : -b - sqrtf(disc);
            if (!(t > 0.0f)) continue;
            p = refl_v3_add(o, refl_v3_scale(d, t));
            nrm = refl_v3_scale(p, (inside ? -1.0f : 1.0f) / radius);
            /* the bowl: only its back half (facing the eye) */
            if (inside && p.z > 0.0f) continue;
            p = refl_v3_add(p, centre);
            r = refl_v3_normalize(refl_v3_reflect(d, nrm));
            rays[i].tail = p;
            rays[i].first = p;
            refl_ray_box(p, r, box_lo, box_hi, NULL, &t_exit); /* where the reflected ray leaves the box */
            rays[i].head = refl_v3_add(p, refl_v3_scale(r, t_exit));
            valid[i] = 1;
        }
    }
}

/* ---- validation -------------------------------------------------------------- */

static const char rgl__vs_head[] =
    "#version 330 core\n"
    "layout(location = 0) in vec4 a_p;\n"
    "uniform samplerBuffer u_data;\n"
    "uniform int u_base;\n"
    "out vec4 v_o0;\n"
    "out vec4 v_o1;\n";

static const char *const rgl__vs_main[RGL_CAMERAS] = {
    "void main() {\n"
    "    float cd;\n"
    "    v_o0 = refl_mirror_project(u_data, u_base, a_p.xyz, cd);\n"
    "    v_o1 = vec4(cd, 0.0, 0.0, 0.0);\n"
    "    gl_Position = vec4(0.0);\n"
    "}\n",
    "void main() {\n"
    "    vec4 pr[3];\n"
    "    int cam = int(a_p.w), n = refl_c3rc_project(u_data, u_base, cam, a_p.xyz, pr);\n"
    "    v_o0 = n > 0 ? pr[0] : vec4(0.0);\n"
    "    v_o1 = vec4(n > 0 ? refl_c3rc_image(u_data, u_base, cam, pr[0]) : vec3(0.0), float(n));\n"
    "    gl_Position = vec4(0.0);\n"
    "}\n",
    NULL, NULL,
    "void main() {\n"
    "    int f;\n"
    "    v_o0 = refl_graphcam_project(u_data, u_base, a_p.xyz, f);\n"
    "    v_o1 = vec4(float(f), 0.0, 0.0, 0.0);\n"
    "    gl_Position = vec4(0.0);\n"
    "}\n",
    "void main() {\n"
    "    vec3 f;\n"
    "    float d;\n"
    "    bool ok = refl_sbc_morph_project(u_data, u_base, a_p.xyz, f, d);\n"
    "    v_o0 = vec4(f, d);\n"
    "    v_o1 = vec4(ok ? 1.0 : 0.0, 0.0, 0.0, 0.0);\n"
    "    gl_Position = vec4(0.0);\n"
    "}\n",
    "void main() {\n"
    "    ivec4 t;\n"
    "    vec4 w;\n"
    "    refl_lem_shell_lookup(u_data, u_base, int(a_p.w), a_p.xyz, a_p.xyz - vec3(0.5, 0.25, -0.75), t, w);\n"
    "    v_o0 = vec4(t);\n"
    "    v_o1 = w;\n"
    "    gl_Position = vec4(0.0);\n"
    "}\n",
    "void main() {\n"
    "    v_o0 = refl_spoc_project(u_data, u_base, a_p.xyz);\n"
    "    v_o1 = vec4(0.0);\n"
    "    gl_Position = vec4(0.0);\n"
    "}\n",
    "void main() {\n" /* the morph grid per sheet: the point's sheet in a_p.w */
    "    vec3 f;\n"
    "    float d;\n"
    "    bool across;\n"
    "    bool ok = refl_sbc_morph_project_sheet(u_data, u_base, a_p.xyz, int(a_p.w), f, d, across);\n"
    "    v_o0 = vec4(f, d);\n"
    "    v_o1 = vec4(ok ? 1.0 : 0.0, across ? 1.0 : 0.0, 0.0, 0.0);\n"
    "    gl_Position = vec4(0.0);\n"
    "}\n"};

static const char rgl__vs_main_sbc[] =
    "void main() {\n"
    "    vec3 f;\n"
    "    float z;\n"
    "    int k;\n"
    "    bool ok = refl_sbc_project(u_data, u_base, a_p.xyz, f, z, k);\n"
    "    v_o0 = vec4(f, z);\n"
    "    v_o1 = vec4(ok ? 1.0 : 0.0, float(k), 0.0, 0.0);\n"
    "    gl_Position = vec4(0.0);\n"
    "}\n";

/* One fixture's cameras, packed, and the C side of its projection. */
typedef struct rgl_fixture {
    refl_gl_camera kind;
    float *packed;
    long long floats;
    /* mirror */
    refl_mat4 vp, mirrored;     /* mirrored: vp times the reflection, what PLANAR draws with */
    double n[3], d;
    /* c3rc */
    refl_c3rc *cams;
    int cam_count;
    /* sbc */
    refl_sbc *sbc;
    refl_sbc_ray *rays;
    uint8_t *valid;
    int map_w, map_h;
    /* graph camera */
    refl_graphcam *graph;
    /* SBC morph grid: the default scene's teapot, one eye and piece; the
       test points' box and the scene size errors are relative to */
    refl_scene *scene;
    refl_sbc_morph *morph;
    refl_vec3 eye, lo, hi;
    int piece;
    int sheets;              /* the per-sheet fixture: the piece's sheets (each point carries its own) */
    double size;
    /* LAYERED_EM's shells (one of each kind): exit rays from the test point p
       along p - RGL_LEM_AIM, on the layer the point carries */
    refl_lem_shell shells[4];
    /* spoc */
    refl_spoc spoc;
} rgl_fixture;

#define RGL_LEM_AIM refl_v3(0.5f, 0.25f, -0.75f)

static void rgl__fixture_free(rgl_fixture *f) {
    free(f->packed);
    free(f->cams);
    refl_sbc_destroy(f->sbc);
    free(f->rays);
    free(f->valid);
    free(f->graph);
    refl_sbc_morph_destroy(f->morph);
    refl_scene_destroy(f->scene);
    memset(f, 0, sizeof *f);
}

static int rgl__pack(rgl_fixture *f, char *err, size_t n) {
    long long need = f->kind == REFL_GL_MIRROR ? refl_gl_pack_mirror(f->vp, refl_v3((float)f->n[0], (float)f->n[1], (float)f->n[2]), (float)f->d, NULL, 0)
                     : f->kind == REFL_GL_C3RC ? refl_gl_pack_c3rc(f->cams, f->cam_count, NULL, 0)
                     : f->kind == REFL_GL_GRAPHCAM ? refl_gl_pack_graphcam(f->graph, NULL, 0)
                     : f->kind == REFL_GL_SBC_MORPH ? refl_gl_pack_sbc_morph(f->morph, f->eye, f->piece, NULL, 0)
                     : f->kind == REFL_GL_LEM_SHELL ? refl_gl_pack_lem_shells(f->shells, NULL, 4, NULL, 0)
                     : f->kind == REFL_GL_SPOC ? refl_gl_pack_spoc(&f->spoc, NULL, 0)
                                               : refl_gl_pack_sbc(f->sbc, NULL, 0);
    if (need <= 0) return rgl__fail(err, n, "packer refused the fixture");
    f->packed = (float *)malloc((size_t)need * sizeof(float));
    if (!f->packed) return rgl__fail(err, n, "out of memory");
    f->floats = need;
    if (f->kind == REFL_GL_MIRROR)
        refl_gl_pack_mirror(f->vp, refl_v3((float)f->n[0], (float)f->n[1], (float)f->n[2]), (float)f->d, f->packed, need);
    else if (f->kind == REFL_GL_C3RC)
        refl_gl_pack_c3rc(f->cams, f->cam_count, f->packed, need);
    else if (f->kind == REFL_GL_GRAPHCAM)
        refl_gl_pack_graphcam(f->graph, f->packed, need);
    else if (f->kind == REFL_GL_SBC_MORPH)
        refl_gl_pack_sbc_morph(f->morph, f->eye, f->piece, f->packed, need);
    else if (f->kind == REFL_GL_LEM_SHELL)
        refl_gl_pack_lem_shells(f->shells, NULL, 4, f->packed, need);
    else if (f->kind == REFL_GL_SPOC)
        refl_gl_pack_spoc(&f->spoc, f->packed, need);
    else
        refl_gl_pack_sbc(f->sbc, f->packed, need);
    return 0;
}

static int rgl__fixture(int which, rgl_fixture *f, char *note, size_t note_n, char *err, size_t n) {
    rgl_view v = rgl__view(refl_v3(0.4f, 0.9f, 3.5f), refl_v3(0, 0, 0), 35.0f, 160, 120);
    memset(f, 0, sizeof *f);
    if (which == 0) {
        double len;
        f->kind = REFL_GL_MIRROR;
        f->vp = v.vp;
        f->n[0] = 0.1; f->n[1] = 1.0; f->n[2] = 0.2;
        len = sqrt(f->n[0] * f->n[0] + f->n[1] * f->n[1] + f->n[2] * f->n[2]);
        f->n[0] /= len; f->n[1] /= len; f->n[2] /= len;
        f->d = -0.5;
        {
            /* vp * R, R = I - 2 n n^T, plus 2 d n */
            refl_mat4 r = refl_mat4_identity();
            int a, b;
            for (b = 0; b < 3; ++b) {
                for (a = 0; a < 3; ++a) r.m[b * 4 + a] = (float)((a == b) - 2.0 * f->n[a] * f->n[b]);
                r.m[12 + b] = (float)(2.0 * f->d * f->n[b]);
            }
            f->mirrored = refl_mat4_mul(f->vp, r);
        }
        snprintf(note, note_n, "one mirror plane, the view at 160x120");
    } else if (which == 1) {
        /* a latitude-longitude unit sphere's triangles facing the eye, with
           the eye's rays reflected at their vertices */
        const int stacks = 8, slices = 16;
        int i, j, k;
        f->kind = REFL_GL_C3RC;
        f->cams = (refl_c3rc *)calloc((size_t)(2 * stacks * slices), sizeof *f->cams);
        if (!f->cams) return rgl__fail(err, n, "out of memory");
        for (i = 0; i < stacks; ++i) {
            for (j = 0; j < slices; ++j) {
                refl_vec3 q[4], tri[3], dir[3];
                for (k = 0; k < 4; ++k) {
                    double th = 3.14159265358979 * (i + (k >> 1)) / stacks, ph = 2.0 * 3.14159265358979 * (j + (k & 1)) / slices;
                    q[k] = refl_v3((float)(sin(th) * cos(ph)), (float)cos(th), (float)(sin(th) * sin(ph)));
                }
                for (k = 0; k < 2; ++k) {
                    int c;
                    tri[0] = q[0]; tri[1] = k ? q[3] : q[1]; tri[2] = k ? q[2] : q[3];
                    if (refl_v3_length(refl_v3_cross(refl_v3_sub(tri[1], tri[0]), refl_v3_sub(tri[2], tri[0]))) < 1e-4f) continue;
                    for (c = 0; c < 3; ++c) dir[c] = refl_v3_reflect(refl_v3_normalize(refl_v3_sub(tri[c], v.eye)), tri[c]);
                    if (refl_v3_dot(refl_v3_sub(v.eye, tri[0]), tri[0]) <= 0.0f) continue; /* faces away */
                    if (refl_c3rc_init(&f->cams[f->cam_count], tri, dir) == REFL_OK) f->cam_count++;
                }
            }
        }
        snprintf(note, note_n, "%d C3RCs of a unit sphere's triangles", f->cam_count);
    } else if (which == 6) {
        /* a shell about an off-centre point; rays from inside and outside it */
        f->kind = REFL_GL_LEM_SHELL;
        /* a sphere, a cylinder and a box about off-centre points (the
           cylinder tilted off the vertical, the box turned), and a quad:
           rays from inside and outside them */
        refl_vec3 ax = refl_v3_normalize(refl_v3(0.8f, 0.0f, 0.6f)), ay = refl_v3_normalize(refl_v3(0.1f, 1.0f, 0.0f));
        refl_vec3 az = refl_v3_normalize(refl_v3_cross(ax, ay));
        int k;
        ay = refl_v3_cross(az, ax);
        for (k = 0; k < 4; ++k) {
            refl_lem_shell *sh = &f->shells[k];
            sh->kind = REFL_LEM_SHELL_SPHERE + k;
            sh->face_size = 32;
            sh->center = refl_v3(0.3f, -0.2f, 0.1f);
            sh->radius = 2.5f;
            sh->axis[0] = k ? ax : refl_v3(1, 0, 0);
            sh->axis[1] = k ? ay : refl_v3(0, 1, 0);
            sh->axis[2] = k ? az : refl_v3(0, 0, 1);
            sh->extent[0] = 2.5f, sh->extent[1] = k == 2 ? 2.2f : 2.5f, sh->extent[2] = k == 2 ? 2.8f : 2.5f;
        }
        f->shells[3].center = refl_v3(-0.5f, 0.4f, -2.5f);
        f->shells[3].extent[0] = f->shells[3].extent[1] = 8.0f;
        snprintf(note, note_n, "a sphere, a tilted cylinder, a turned box and a quad, 6 x 32^2 texels each; rays from points of [-4, 4]^3 (80%% in [-2, 2]^3)");
    } else if (which == 5 || which == 8) {
        /* 5: the default scene's teapot in a one-cell grid beside the view
           (tests/reflect/test_sbc_morph.c's), the eye inside the cell; 8:
           the concave bowl's, about the scene's eye, per sheet (its rays
           fold: three sheets) */
        refl_sbc_morph_desc md;
        refl_sbc_morph_stats st;
        refl_vec3 c, lo, hi;
        int k;
        f->kind = REFL_GL_SBC_MORPH;
        if (refl_scene_builtin(which == 8 ? "concave" : "default", NULL, &f->scene) != REFL_OK)
            return rgl__fail(err, n, "no built-in scene");
        memset(&md, 0, sizeof md);
        md.nodes[0] = md.nodes[1] = md.nodes[2] = 2;
        md.region_lo = which == 8 ? refl_v3(-0.5f, 3.0f, 5.5f) : refl_v3(-1.0f, 3.8f, 7.4f);
        md.region_hi = which == 8 ? refl_v3(0.5f, 4.0f, 6.5f) : refl_v3(1.0f, 5.3f, 9.4f);
        md.face_size = which == 8 ? 32 : 64;
        if (refl_sbc_morph_build(f->scene, 1, &md, &f->morph) != REFL_OK) return rgl__fail(err, n, "refl_sbc_morph_build failed");
        refl_mesh_bounds(f->scene->meshes[f->scene->objects[1].mesh], &lo, &hi);
        f->lo = refl_v3(1e30f, 1e30f, 1e30f);
        f->hi = refl_v3(-1e30f, -1e30f, -1e30f);
        for (k = 0; k < 8; ++k) { /* the teapot's world box, grown by its size */
            refl_vec3 q = refl_mat4_point(f->scene->objects[1].transform,
                                          refl_v3(k & 1 ? hi.x : lo.x, k & 2 ? hi.y : lo.y, k & 4 ? hi.z : lo.z));
            f->lo = refl_v3(fminf(f->lo.x, q.x), fminf(f->lo.y, q.y), fminf(f->lo.z, q.z));
            f->hi = refl_v3(fmaxf(f->hi.x, q.x), fmaxf(f->hi.y, q.y), fmaxf(f->hi.z, q.z));
        }
        f->size = refl_v3_length(refl_v3_sub(f->hi, f->lo));
        c = refl_v3_scale(refl_v3_add(f->lo, f->hi), 0.5f);
        f->lo = refl_v3_sub(f->lo, refl_v3(1.0f, 1.0f, 1.0f));
        f->hi = refl_v3_add(f->hi, refl_v3(1.0f, 1.0f, 1.0f));
        f->size = refl_v3_length(refl_v3_sub(f->hi, f->lo));
        f->eye = which == 8 ? refl_v3(0.1f, 3.5f, 6.0f) : refl_v3(0.3f, 4.5f, 8.9f);
        f->piece = refl_sbc_morph_piece_at(f->morph, f->eye, refl_v3_sub(c, f->eye));
        if (f->piece < 0) return rgl__fail(err, n, "the eye sees no piece of the reflector");
        refl_sbc_morph_get_stats(f->morph, &st);
        if (which == 8) f->sheets = refl_sbc_morph_sheets(f->morph, f->eye, f->piece);
        if (rgl__pack(f, err, n) != 0) return -1;
        snprintf(note, note_n, "%s, one grid cell of %d nodes, %d pieces, %d SBCs, face %d; piece %d, %.0f texels",
                 which == 8 ? "the concave bowl" : "the default scene's teapot", st.nodes_built, st.pieces, st.sbcs,
                 md.face_size, f->piece, (double)f->floats / 4.0);
        if (which == 8) snprintf(note + strlen(note), note_n - strlen(note), "; per sheet, %d sheets", f->sheets);
        return 0;
    } else if (which == 4) {
        f->kind = REFL_GL_GRAPHCAM;
        f->graph = (refl_graphcam *)malloc(sizeof *f->graph);
        if (!f->graph) return rgl__fail(err, n, "out of memory");
        if (refl_graphcam_maze(f->graph, 960, 588) != REFL_OK) return rgl__fail(err, n, "refl_graphcam_maze failed");
        snprintf(note, note_n, "the maze's graph camera, %d frusta at 960x588", f->graph->count);
    } else if (which == 7) {
        /* a unit sphere seen from the view's eye, pushed with strength 1 */
        f->kind = REFL_GL_SPOC;
        if (refl_spoc_init(&f->spoc, v.eye, refl_v3(0, 0, 0), 1.0f, 1.0f, 1.0f, 512) != REFL_OK)
            return rgl__fail(err, n, "refl_spoc_init failed");
        snprintf(note, note_n, "a unit sphere's SPOC at 512x512, strength 1, baseline 1");
    } else {
        refl_sbc_desc desc;
        refl_sbc_stats st;
        int inside = which == 3;
        refl_result r;
        if (inside) v = rgl__view(refl_v3(0.2f, 0.3f, 0.0f), refl_v3(0, 0, -3), 60.0f, 160, 120);
        f->kind = REFL_GL_SBC;
        f->map_w = v.width;
        f->map_h = v.height;
        f->rays = (refl_sbc_ray *)calloc((size_t)v.width * v.height, sizeof *f->rays);
        f->valid = (uint8_t *)calloc((size_t)v.width * v.height, 1);
        if (!f->rays || !f->valid) return rgl__fail(err, n, "out of memory");
        /* the bowl: a sphere of radius 8 about (0, 0, 5), its back wall at z = -3,
           the eye inside its focal length (rays diverge, strongly bent) */
        rgl__sphere_map(&v, refl_v3(0, 0, inside ? 5.0f : 0.0f), inside ? 8.0f : 1.0f, inside, f->rays, f->valid);
        memset(&desc, 0, sizeof desc);
        desc.error_px = 0.5f;
        desc.view_proj = v.vp;
        desc.width = v.width;
        desc.height = v.height;
        r = refl_sbc_build(f->rays, f->valid, v.width, v.height, &desc, &f->sbc);
        if (r != REFL_OK) {
            snprintf(err, n, "refl_sbc_build: %s", refl_result_string(r));
            return -1;
        }
        refl_sbc_get_stats(f->sbc, &st);
        if (rgl__pack(f, err, n) != 0) return -1;
        /* indexed ray-list leaves: (cell starts' offset - indexes' offset) / 6 (docs/gl.md) */
        snprintf(note, note_n, "%s, %dx%d ray map, %d pinhole and %d ray-list leaves (%d indexed)",
                 inside ? "concave bowl" : "sphere", v.width, v.height, st.pinhole_leaves, st.ray_leaves,
                 (int)(f->packed[8] - f->packed[7]) / REFL_GL_SBC_INDEX_TEXELS);
        return 0;
    }
    return rgl__pack(f, err, n);
}

/* The morph grid's C projection of p: in sheet `sheet` when the fixture
   has sheets (*across then as refl_sbc_morph_project_sheet's), else one
   image per node. */
static int rgl__morph_project(const rgl_fixture *f, refl_vec3 p, int sheet, refl_vec3 *first, float *dist, int *across) {
    *across = 0;
    if (f->sheets) return refl_sbc_morph_project_sheet(f->morph, f->eye, f->piece, sheet, p, first, dist, across);
    return refl_sbc_morph_project(f->morph, f->eye, f->piece, p, first, dist, NULL);
}

/* The test points of a fixture: 4 floats each (xyz, and the C3RC camera
   or the morph grid's sheet). */
static void rgl__points(const rgl_fixture *f, long long count, float *pts) {
    rgl_rng r = {0x5eed1234abcdULL};
    long long i;
    int nvalid = 0, *valid_list = NULL, k;
    if (f->kind == REFL_GL_SBC) {
        valid_list = (int *)malloc((size_t)f->map_w * f->map_h * sizeof(int));
        for (k = 0; valid_list && k < f->map_w * f->map_h; ++k)
            if (f->valid[k]) valid_list[nvalid++] = k;
    }
    for (i = 0; i < count; ++i) {
        refl_vec3 p = rgl__box_point(&r);
        float cam = 0.0f;
        int in_volume = rgl__rand(&r) < 0.8;
        if (f->kind == REFL_GL_C3RC) {
            int c = (int)(rgl__rand(&r) * f->cam_count);
            cam = (float)c;
            if (in_volume) {
                double a = rgl__rand(&r), b = rgl__rand(&r), t = rgl__range(&r, 0.0, 6.0);
                const refl_c3rc *cc = &f->cams[c];
                if (a + b > 1.0) { a = 1.0 - a; b = 1.0 - b; }
                p = refl_v3_add(refl_v3_scale(refl_v3_add(cc->v[0], refl_v3_scale(cc->d[0], (float)t)), (float)(1.0 - a - b)),
                                refl_v3_add(refl_v3_scale(refl_v3_add(cc->v[1], refl_v3_scale(cc->d[1], (float)t)), (float)a),
                                            refl_v3_scale(refl_v3_add(cc->v[2], refl_v3_scale(cc->d[2], (float)t)), (float)b)));
            }
        } else if (f->kind == REFL_GL_GRAPHCAM) {
            refl_vec3 lo, hi;
            refl_graphcam_bounds(f->graph, &lo, &hi);
            if (in_volume)
                p = refl_v3((float)rgl__range(&r, lo.x, hi.x), (float)rgl__range(&r, lo.y, hi.y),
                            (float)rgl__range(&r, lo.z, hi.z));
        } else if (f->kind == REFL_GL_LEM_SHELL) {
            if (in_volume) p = refl_v3_scale(p, 0.5f); /* [-2, 2]^3: mostly inside the shell */
            cam = (float)(int)(rgl__rand(&r) * 4); /* the layer */
        } else if (f->kind == REFL_GL_SBC_MORPH) {
            /* in the teapot's box, grown; "in the volume": drawn until the C
               projects it (at most 64 tries) */
            int tries, sheet = f->sheets ? (int)(rgl__rand(&r) * f->sheets) : 0, across;
            for (tries = 0; tries < (in_volume ? 64 : 1); ++tries) {
                refl_vec3 q;
                float dd;
                p = refl_v3((float)rgl__range(&r, f->lo.x, f->hi.x), (float)rgl__range(&r, f->lo.y, f->hi.y),
                            (float)rgl__range(&r, f->lo.z, f->hi.z));
                if (rgl__morph_project(f, p, sheet, &q, &dd, &across)) break;
            }
            cam = (float)sheet;
        } else if (f->kind == REFL_GL_SPOC && in_volume) {
            /* in the bounding sphere */
            do p = refl_v3((float)rgl__range(&r, -1.0, 1.0), (float)rgl__range(&r, -1.0, 1.0), (float)rgl__range(&r, -1.0, 1.0));
            while (refl_v3_dot(p, p) > 1.0f);
            p = refl_v3_add(p, f->spoc.center);
        } else if (f->kind == REFL_GL_SBC && in_volume && nvalid) {
            const refl_sbc_ray *ray = &f->rays[valid_list[(int)(rgl__rand(&r) * nvalid)]];
            double s = rgl__range(&r, 0.0, 1.0);
            p = refl_v3_add(ray->tail, refl_v3_scale(refl_v3_sub(ray->head, ray->tail), (float)s));
            p = refl_v3_add(p, refl_v3((float)rgl__range(&r, -1e-3, 1e-3), (float)rgl__range(&r, -1e-3, 1e-3),
                                       (float)rgl__range(&r, -1e-3, 1e-3)));
        }
        pts[4 * i + 0] = p.x;
        pts[4 * i + 1] = p.y;
        pts[4 * i + 2] = p.z;
        pts[4 * i + 3] = cam;
    }
    free(valid_list);
}

static int rgl__cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double rgl__dist3(const double *a, const float *b) {
    double dx = a[0] - b[0], dy = a[1] - b[1], dz = a[2] - b[2];
    return sqrt(dx * dx + dy * dy + dz * dz);
}

/* The C projection of point i against the GL's result (8 floats):
   -1 disagree, 0 neither projects, 1 agree with *err. */
static int rgl__compare(const rgl_fixture *f, const float *p, const float *gl, double *err, int *leaf) {
    refl_vec3 pv = refl_v3(p[0], p[1], p[2]);
    *leaf = 0;
    if (f->kind == REFL_GL_MIRROR) {
        double s = f->n[0] * p[0] + f->n[1] * p[1] + f->n[2] * p[2] - f->d, q[4], clip[4], len = 0.0, e = 0.0;
        int r, c;
        for (c = 0; c < 3; ++c) q[c] = p[c] - 2.0 * s * f->n[c];
        q[3] = 1.0;
        for (r = 0; r < 4; ++r) {
            clip[r] = 0.0;
            for (c = 0; c < 4; ++c) clip[r] += (double)f->vp.m[c * 4 + r] * q[c];
            len += clip[r] * clip[r];
            e += (clip[r] - gl[r]) * (clip[r] - gl[r]);
        }
        *err = RGL_MAXD(sqrt(e / len), fabs(s - gl[4]) / RGL_SCENE_SIZE);
        return 1;
    }
    if (f->kind == REFL_GL_GRAPHCAM) {
        /* the frustum, then the image point and gd, relative to the image */
        float c[3];
        int fc = -1, ok = refl_graphcam_project(f->graph, pv, c, &fc), fg = (int)gl[4];
        if (fc != fg) return -1;
        if (!ok || !(gl[3] > 0.0f)) return ok ? -1 : 0;
        *err = RGL_MAXD(RGL_MAXD(fabs(c[0] - (gl[0] / gl[3] + 1.0) * 0.5 * f->graph->width) / f->graph->width,
                                 fabs(c[1] - (1.0 - gl[1] / gl[3]) * 0.5 * f->graph->height) / f->graph->height),
                        fabs(c[2] - (gl[2] / gl[3] + 1.0) * 0.5));
        return 1;
    }
    if (f->kind == REFL_GL_LEM_SHELL) {
        /* the same four texels, their weights within float rounding */
        uint32_t tex[4];
        float w[4];
        int ok = refl_lem_shell_lookup(&f->shells[(int)p[3]], pv, refl_v3_sub(pv, RGL_LEM_AIM), tex, w), k;
        double e = 0.0;
        if (ok != (gl[0] >= 0.0f)) return -1;
        if (!ok) return 0;
        for (k = 0; k < 4; ++k) {
            if ((float)tex[k] != gl[k]) return -1;
            e = RGL_MAXD(e, fabs(w[k] - gl[4 + k]));
        }
        *err = e;
        return 1;
    }
    if (f->kind == REFL_GL_SBC_MORPH) {
        refl_vec3 first = {0.0f, 0.0f, 0.0f};
        float dd = 0.0f;
        int across, ok = rgl__morph_project(f, pv, (int)p[3], &first, &dd, &across);
        double fd[3] = {first.x, first.y, first.z};
        if (ok != (gl[4] > 0.5f) || (ok && across != (gl[5] > 0.5f))) return -1;
        if (!ok) return 0;
        *err = RGL_MAXD(rgl__dist3(fd, gl), fabs(dd - gl[3])) / f->size;
        return 1;
    }
    if (f->kind == REFL_GL_SPOC) {
        /* the image point relative to the image (or to itself, far off it:
           points near the eye plane), and gd relative to its range (or to
           itself) */
        float c[3];
        int ok = refl_spoc_project(&f->spoc, pv, c);
        double scale = RGL_MAXD(f->spoc.size, RGL_MAXD(fabs(c[0]), fabs(c[1])));
        if (ok != (gl[3] > 0.5f)) return -1;
        if (!ok) return 0;
        *err = RGL_MAXD(RGL_MAXD(fabs(c[0] - gl[0]), fabs(c[1] - gl[1])) / scale,
                        fabs(c[2] - gl[2]) / RGL_MAXD(1.0, fabs(c[2])));
        return 1;
    }
    if (f->kind == REFL_GL_C3RC) {
        refl_c3rc_projection pr[3];
        const refl_c3rc *cam = &f->cams[(int)p[3]];
        int nc = refl_c3rc_project(cam, pv, pr), ng = (int)gl[7], k;
        double img[3];
        if (nc != ng) return -1;
        if (!nc) return 0;
        for (k = 0; k < 3; ++k) {
            const float *v0 = &cam->v[0].x, *v1 = &cam->v[1].x, *v2 = &cam->v[2].x;
            img[k] = pr[0].a * (double)v0[k] + pr[0].b * (double)v1[k] + pr[0].c * (double)v2[k];
        }
        *err = RGL_MAXD(rgl__dist3(img, gl + 4), fabs(pr[0].t - gl[3])) / RGL_SCENE_SIZE;
        return 1;
    } else {
        refl_vec3 first;
        float z;
        int ok = refl_sbc_project(f->sbc, pv, &first, &z);
        double fd[3] = {first.x, first.y, first.z};
        if (ok != (gl[4] > 0.5f)) return -1;
        if (!ok) return 0;
        *leaf = (int)gl[5];
        *err = RGL_MAXD(rgl__dist3(fd, gl), fabs(z - gl[3])) / RGL_SCENE_SIZE;
        return 1;
    }
}

/* The C projection of the points alone, on this thread: seconds. */
static double rgl__c_seconds(const rgl_fixture *f, const float *pts, long long count) {
    volatile float sink = 0.0f;
    double t = rgl_now();
    long long i;
    for (i = 0; i < count; ++i) {
        refl_vec3 p = refl_v3(pts[4 * i], pts[4 * i + 1], pts[4 * i + 2]);
        if (f->kind == REFL_GL_MIRROR) {
            refl_vec3 q = refl_mat4_point(f->mirrored, p);
            sink += q.x;
        } else if (f->kind == REFL_GL_C3RC) {
            refl_c3rc_projection pr[3];
            sink += (float)refl_c3rc_project(&f->cams[(int)pts[4 * i + 3]], p, pr);
        } else if (f->kind == REFL_GL_GRAPHCAM) {
            float c[3];
            sink += (float)refl_graphcam_project(f->graph, p, c, NULL);
        } else if (f->kind == REFL_GL_SBC_MORPH) {
            refl_vec3 q;
            float dd;
            int across;
            sink += (float)rgl__morph_project(f, p, (int)pts[4 * i + 3], &q, &dd, &across);
        } else if (f->kind == REFL_GL_LEM_SHELL) {
            uint32_t tex[4];
            float w[4];
            sink += (float)refl_lem_shell_lookup(&f->shells[(int)pts[4 * i + 3]], p, refl_v3_sub(p, RGL_LEM_AIM), tex, w);
        } else if (f->kind == REFL_GL_SPOC) {
            float c[3];
            sink += (float)refl_spoc_project(&f->spoc, p, c);
        } else {
            refl_vec3 first;
            float z;
            sink += (float)refl_sbc_project(f->sbc, p, &first, &z);
        }
    }
    (void)sink;
    return rgl_now() - t;
}

int rgl_validate(rgl_context *g, int which, long long points, int repeats, rgl_validation *out, char *err, size_t n) {
    static const char *const names[RGL_CAMERAS] = {"mirror", "c3rc", "sbc-convex", "sbc-concave", "graphcam",
                                                   "sbc-morph", "lem-shell", "spoc", "sbc-morph-sheets"};
    static const char *const varyings[2] = {"v_o0", "v_o1"};
    rgl_fixture f;
    float *pts = NULL, *res = NULL;
    double *errs = NULL;
    GLuint prog = 0, tex = 0, data_buf = 0, vbo = 0, tfb = 0, vao = 0;
    long long i, agree = 0;
    int rep, rc = -1;
    (void)g;
    memset(out, 0, sizeof *out);
    if (which < 0 || which >= RGL_CAMERAS || points < 1) return rgl__fail(err, n, "bad fixture or point count");
    out->camera = names[which];
    if (rgl__fixture(which, &f, out->note, sizeof out->note, err, n) != 0) goto done;
    pts = (float *)malloc((size_t)points * 4 * sizeof(float));
    res = (float *)malloc((size_t)points * 8 * sizeof(float));
    errs = (double *)malloc((size_t)points * sizeof(double));
    if (!pts || !res || !errs) {
        rgl__fail(err, n, "out of memory");
        goto done;
    }
    rgl__points(&f, points, pts);
    {
        const char *vs[4];
        vs[0] = rgl__vs_head;
        vs[1] = refl_gl_glsl(f.kind == REFL_GL_SBC_MORPH ? REFL_GL_SBC : f.kind); /* the morph grid's nodes are SBCs */
        vs[2] = f.kind == REFL_GL_SBC_MORPH ? refl_gl_glsl(REFL_GL_SBC_MORPH) : "";
        vs[3] = f.kind == REFL_GL_SBC ? rgl__vs_main_sbc : rgl__vs_main[which];
        prog = rgl_program(vs, 4, NULL, 0, varyings, 2, err, n);
        if (!prog) goto done;
    }
    tex = rgl_buffer_texture(f.packed, f.floats, &data_buf, err, n);
    if (!tex) goto done;
    rgl.GenVertexArrays(1, &vao);
    rgl.BindVertexArray(vao);
    rgl.GenBuffers(1, &vbo);
    rgl.BindBuffer(GL_ARRAY_BUFFER, vbo);
    rgl.BufferData(GL_ARRAY_BUFFER, (GLsizeiptr)(points * 4 * (long long)sizeof(float)), pts, GL_STATIC_DRAW);
    rgl.EnableVertexAttribArray(0);
    rgl.VertexAttribPointer(0, 4, GL_FLOAT, GL_FALSE, 16, (const void *)0);
    rgl.GenBuffers(1, &tfb);
    rgl.BindBuffer(GL_TRANSFORM_FEEDBACK_BUFFER, tfb);
    rgl.BufferData(GL_TRANSFORM_FEEDBACK_BUFFER, (GLsizeiptr)(points * 8 * (long long)sizeof(float)), NULL, GL_STREAM_READ);
    rgl.BindBufferBase(GL_TRANSFORM_FEEDBACK_BUFFER, 0, tfb);
    rgl.UseProgram(prog);
    rgl.ActiveTexture(GL_TEXTURE0);
    rgl.BindTexture(GL_TEXTURE_BUFFER, tex);
    rgl.Uniform1i(rgl.GetUniformLocation(prog, "u_data"), 0);
    rgl.Uniform1i(rgl.GetUniformLocation(prog, "u_base"), 0);
    rgl.Enable(GL_RASTERIZER_DISCARD);
    out->gl_seconds = 1e30;
    for (rep = 0; rep < (repeats < 1 ? 1 : repeats); ++rep) {
        double t;
        rgl.Finish();
        t = rgl_now();
        rgl.BeginTransformFeedback(GL_POINTS);
        rgl.DrawArrays(GL_POINTS, 0, (GLsizei)points);
        rgl.EndTransformFeedback();
        rgl.Finish();
        t = rgl_now() - t;
        if (t < out->gl_seconds) out->gl_seconds = t;
    }
    rgl.Disable(GL_RASTERIZER_DISCARD);
    rgl.GetBufferSubData(GL_TRANSFORM_FEEDBACK_BUFFER, 0, (GLsizeiptr)(points * 8 * (long long)sizeof(float)), res);
    {
        GLenum e = rgl.GetError();
        if (e != GL_NO_ERROR) {
            snprintf(err, n, "GL error 0x%x during the transform-feedback pass", (unsigned)e);
            goto done;
        }
    }
    out->cpu_seconds = rgl__c_seconds(&f, pts, points);
    for (i = 0; i < points; ++i) {
        double e = 0.0;
        int leaf, c = rgl__compare(&f, pts + 4 * i, res + 8 * i, &e, &leaf);
        if (c < 0) {
            out->disagree++;
        } else if (c > 0) {
            errs[agree++] = e;
            if (f.kind == REFL_GL_SBC) {
                if (leaf == 1) out->pinhole_points++;
                else out->raylist_points++;
            }
        }
    }
    out->points = points;
    out->projected = agree;
    if (agree) {
        qsort(errs, (size_t)agree, sizeof *errs, rgl__cmp_double);
        out->max_rel = errs[agree - 1];
        out->p999_rel = errs[(long long)(0.999 * (double)(agree - 1))];
    }
    rc = 0;
done:
    if (tfb) rgl.DeleteBuffers(1, &tfb);
    if (vbo) rgl.DeleteBuffers(1, &vbo);
    if (data_buf) rgl.DeleteBuffers(1, &data_buf);
    if (tex) rgl.DeleteTextures(1, &tex);
    if (vao) rgl.DeleteVertexArrays(1, &vao);
    if (prog) rgl.DeleteProgram(prog);
    free(pts);
    free(res);
    free(errs);
    rgl__fixture_free(&f);
    return rc;
}

int rgl_validation_ok(const rgl_validation *v) {
    return (double)v->disagree <= RGL_MAX_DISAGREE * (double)v->points && v->p999_rel <= RGL_MAX_P999 &&
           v->max_rel <= RGL_MAX_REL;
}
