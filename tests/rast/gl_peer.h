/* gl_peer.h - a headless OpenGL reference renderer (Mesa llvmpipe through
   EGL) for the conformance test and the benchmark. Header-only, everything
   static inline. Link with -lEGL -lOpenGL (GLVND) or -lEGL -lGL.

   What it gives you:
     - a desktop OpenGL 3.3 core context on the EGL surfaceless platform
       (EGL_MESA_platform_surfaceless; falls back to EGL_EXT_platform_device
       and then to EGL_DEFAULT_DISPLAY), made current without any surface;
     - an FBO of W x H with an RGBA8 colour renderbuffer and a
       DEPTH32F_STENCIL8 renderbuffer (float depth, exact 8-bit stencil);
     - one vertex layout, the same as the rast.h tests use: 8 floats per
       vertex, clip-space x y z w then r g b a; a program that passes the
       position through, writes gl_PointSize from a uniform and interpolates
       the colour (smooth, or flat from the last vertex like GL's default
       provoking vertex);
     - read-backs that flip rows so that row 0 is the TOP row, as rast.h
       images are.

   Core profile on purpose: points are then always rasterised as point
   sprites (squares of side `size` centred on the vertex, fragment centres
   inside, ties by the fill rule) - GL 3.x's rule for points - and not with
   the legacy GL 2.1 "basic point rasterization" (llvmpipe's legacy_points).

   Every failure returns nonzero and leaves a reason in peer->err; nothing
   aborts, so callers can skip cleanly when there is no EGL or no llvmpipe.
   The caller sets any GL state (depth, stencil, blend, cull) itself with
   ordinary GL calls while the context is current.

   Environment: before the display is created, gl_peer_init sets
   LIBGL_ALWAYS_SOFTWARE=1 and GALLIUM_DRIVER=llvmpipe (overriding the
   caller's environment: the reference must be llvmpipe), and refuses any
   renderer whose GL_RENDERER does not contain "llvmpipe". llvmpipe reads LP_NUM_THREADS when its screen is created,
   i.e. in gl_peer_init: set it before that (once per process). */
#ifndef GL_PEER_H_INCLUDED
#define GL_PEER_H_INCLUDED

#ifndef GL_GLEXT_PROTOTYPES
#define GL_GLEXT_PROTOTYPES 1
#endif
#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <GL/gl.h>
#include <GL/glext.h>

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../../tools/name_in_list.h"

/* Mesa's EGL/GL stack keeps (and at eglTerminate drops) a few small
   allocations that LeakSanitizer reports as leaks from an unloaded module,
   which no suppression can name. Under ASan, allocations made while the
   peer is set up and torn down are exempted from leak checking; nothing
   of rast.h's runs in between. */
#if defined(__SANITIZE_ADDRESS__)
#define GL_PEER__LSAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define GL_PEER__LSAN 1
#endif
#endif
#ifdef GL_PEER__LSAN
#include <sanitizer/lsan_interface.h>
#define GL_PEER__LSAN_OFF() __lsan_disable()
#define GL_PEER__LSAN_ON() __lsan_enable()
#else
#define GL_PEER__LSAN_OFF() ((void)0)
#define GL_PEER__LSAN_ON() ((void)0)
#endif

#ifndef EGL_PLATFORM_SURFACELESS_MESA
#define EGL_PLATFORM_SURFACELESS_MESA 0x31DD
#endif
#ifndef EGL_PLATFORM_DEVICE_EXT
#define EGL_PLATFORM_DEVICE_EXT 0x313F
#endif

enum { GL_PEER_FLOATS_PER_VERTEX = 8 };

typedef struct gl_peer {
    int width, height;
    EGLDisplay dpy;
    EGLContext ctx;
    GLuint fbo, color_rb, ds_rb;
    GLuint prog_smooth, prog_flat, prog; /* prog: the one in use */
    GLint loc_point_size_smooth, loc_point_size_flat;
    GLuint vao, vbo, ibo;
    size_t vbo_bytes, ibo_bytes;
    float point_size;
    char renderer[160];
    char version[160];
    char err[512];
} gl_peer;

static inline int gl_peer__fail(gl_peer *p, const char *what) {
    snprintf(p->err, sizeof p->err, "%s", what);
    return -1;
}

static inline GLuint gl_peer__shader(gl_peer *p, GLenum type, const char *src) {
    GLuint s = glCreateShader(type);
    GLint ok = 0;
    glShaderSource(s, 1, &src, NULL);
    glCompileShader(s);
    glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
    if (!ok) {
        char log[400];
        log[0] = '\0';
        glGetShaderInfoLog(s, (GLsizei)sizeof log, NULL, log);
        snprintf(p->err, sizeof p->err, "shader compile failed: %s", log);
        glDeleteShader(s);
        return 0;
    }
    return s;
}

static inline GLuint gl_peer__program(gl_peer *p, int flat) {
    static const char *vs_smooth =
        "#version 330 core\n"
        "layout(location = 0) in vec4 a_pos;\n"
        "layout(location = 1) in vec4 a_col;\n"
        "uniform float u_point_size;\n"
        "smooth out vec4 v_col;\n"
        "void main() { gl_Position = a_pos; gl_PointSize = u_point_size; v_col = a_col; }\n";
    static const char *fs_smooth =
        "#version 330 core\n"
        "smooth in vec4 v_col;\n"
        "layout(location = 0) out vec4 o_col;\n"
        "void main() { o_col = v_col; }\n";
    static const char *vs_flat =
        "#version 330 core\n"
        "layout(location = 0) in vec4 a_pos;\n"
        "layout(location = 1) in vec4 a_col;\n"
        "uniform float u_point_size;\n"
        "flat out vec4 v_col;\n"
        "void main() { gl_Position = a_pos; gl_PointSize = u_point_size; v_col = a_col; }\n";
    static const char *fs_flat =
        "#version 330 core\n"
        "flat in vec4 v_col;\n"
        "layout(location = 0) out vec4 o_col;\n"
        "void main() { o_col = v_col; }\n";
    GLuint vs = gl_peer__shader(p, GL_VERTEX_SHADER, flat ? vs_flat : vs_smooth);
    GLuint fs = vs ? gl_peer__shader(p, GL_FRAGMENT_SHADER, flat ? fs_flat : fs_smooth) : 0;
    GLuint prog;
    GLint ok = 0;
    if (!vs || !fs) {
        if (vs) glDeleteShader(vs);
        return 0;
    }
    prog = glCreateProgram();
    glAttachShader(prog, vs);
    glAttachShader(prog, fs);
    glLinkProgram(prog);
    glDeleteShader(vs);
    glDeleteShader(fs);
    glGetProgramiv(prog, GL_LINK_STATUS, &ok);
    if (!ok) {
        char log[400];
        log[0] = '\0';
        glGetProgramInfoLog(prog, (GLsizei)sizeof log, NULL, log);
        snprintf(p->err, sizeof p->err, "program link failed: %s", log);
        glDeleteProgram(prog);
        return 0;
    }
    return prog;
}

static inline EGLDisplay gl_peer__display(gl_peer *p) {
    const char *cext = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
    PFNEGLGETPLATFORMDISPLAYEXTPROC get_platform_display =
        (PFNEGLGETPLATFORMDISPLAYEXTPROC)eglGetProcAddress("eglGetPlatformDisplayEXT");
    EGLDisplay dpy = EGL_NO_DISPLAY;
    if (get_platform_display && name_in_list(cext, "EGL_MESA_platform_surfaceless", ' '))
        dpy = get_platform_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, NULL);
    if (dpy == EGL_NO_DISPLAY && get_platform_display &&
        name_in_list(cext, "EGL_EXT_platform_device", ' ')) {
        PFNEGLQUERYDEVICESEXTPROC query_devices =
            (PFNEGLQUERYDEVICESEXTPROC)eglGetProcAddress("eglQueryDevicesEXT");
        EGLDeviceEXT devs[8];
        EGLint n = 0, i;
        if (query_devices && query_devices(8, devs, &n)) {
            for (i = 0; i < n && dpy == EGL_NO_DISPLAY; i++)
                dpy = get_platform_display(EGL_PLATFORM_DEVICE_EXT, devs[i], NULL);
        }
    }
    if (dpy == EGL_NO_DISPLAY) dpy = eglGetDisplay(EGL_DEFAULT_DISPLAY);
    if (dpy == EGL_NO_DISPLAY)
        snprintf(p->err, sizeof p->err,
                 "no EGL display (client extensions: %s)", cext ? cext : "(none)");
    return dpy;
}

static inline void gl_peer__destroy(gl_peer *p) {
    if (p->ctx != EGL_NO_CONTEXT && p->ctx != NULL) {
        if (p->vbo) glDeleteBuffers(1, &p->vbo);
        if (p->ibo) glDeleteBuffers(1, &p->ibo);
        if (p->vao) glDeleteVertexArrays(1, &p->vao);
        if (p->prog_smooth) glDeleteProgram(p->prog_smooth);
        if (p->prog_flat) glDeleteProgram(p->prog_flat);
        if (p->fbo) glDeleteFramebuffers(1, &p->fbo);
        if (p->color_rb) glDeleteRenderbuffers(1, &p->color_rb);
        if (p->ds_rb) glDeleteRenderbuffers(1, &p->ds_rb);
        eglMakeCurrent(p->dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
        eglDestroyContext(p->dpy, p->ctx);
    }
    if (p->dpy != EGL_NO_DISPLAY && p->dpy != NULL) eglTerminate(p->dpy);
    p->ctx = EGL_NO_CONTEXT;
    p->dpy = EGL_NO_DISPLAY;
    p->vbo = p->ibo = p->vao = p->prog = p->prog_smooth = p->prog_flat = 0;
    p->fbo = p->color_rb = p->ds_rb = 0;
}

/* 0 on success; else nonzero with the reason in p->err (p is then cleaned). */
static inline int gl_peer__init(gl_peer *p, int width, int height) {
    EGLint major = 0, minor = 0, nconf = 0;
    EGLConfig conf = NULL;
    static const EGLint conf_attrs_pbuf[] = {
        EGL_SURFACE_TYPE, EGL_PBUFFER_BIT, EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE
    };
    static const EGLint conf_attrs_any[] = {
        EGL_SURFACE_TYPE, 0, EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE
    };
    static const EGLint ctx_attrs[] = {
        EGL_CONTEXT_MAJOR_VERSION, 3, EGL_CONTEXT_MINOR_VERSION, 3,
        EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
        EGL_NONE
    };
    const char *s;
    GLenum status;

    memset(p, 0, sizeof *p);
    p->dpy = EGL_NO_DISPLAY;
    p->ctx = EGL_NO_CONTEXT;
    p->width = width;
    p->height = height;
    p->point_size = 1.0f;
    if (width <= 0 || height <= 0) return gl_peer__fail(p, "bad size");

    setenv("LIBGL_ALWAYS_SOFTWARE", "1", 1);
    setenv("GALLIUM_DRIVER", "llvmpipe", 1);

    p->dpy = gl_peer__display(p);
    if (p->dpy == EGL_NO_DISPLAY) return -1;
    if (!eglInitialize(p->dpy, &major, &minor)) {
        snprintf(p->err, sizeof p->err, "eglInitialize failed (0x%x)", (unsigned)eglGetError());
        p->dpy = EGL_NO_DISPLAY;
        return -1;
    }
    if (!eglBindAPI(EGL_OPENGL_API)) {
        gl_peer__destroy(p);
        return gl_peer__fail(p, "eglBindAPI(EGL_OPENGL_API) failed: no desktop GL through EGL");
    }
    if (!eglChooseConfig(p->dpy, conf_attrs_pbuf, &conf, 1, &nconf) || nconf < 1) {
        nconf = 0;
        if (!eglChooseConfig(p->dpy, conf_attrs_any, &conf, 1, &nconf) || nconf < 1) {
            gl_peer__destroy(p);
            return gl_peer__fail(p, "eglChooseConfig found no desktop-GL config");
        }
    }
    p->ctx = eglCreateContext(p->dpy, conf, EGL_NO_CONTEXT, ctx_attrs);
    if (p->ctx == EGL_NO_CONTEXT) {
        snprintf(p->err, sizeof p->err, "eglCreateContext(GL 3.3 core) failed (0x%x)",
                 (unsigned)eglGetError());
        p->ctx = EGL_NO_CONTEXT;
        {
            char keep[512];
            memcpy(keep, p->err, sizeof keep);
            gl_peer__destroy(p);
            memcpy(p->err, keep, sizeof keep);
        }
        return -1;
    }
    if (!eglMakeCurrent(p->dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, p->ctx)) {
        snprintf(p->err, sizeof p->err,
                 "eglMakeCurrent without surface failed (0x%x): no EGL_KHR_surfaceless_context?",
                 (unsigned)eglGetError());
        {
            char keep[512];
            memcpy(keep, p->err, sizeof keep);
            eglDestroyContext(p->dpy, p->ctx);
            p->ctx = EGL_NO_CONTEXT;
            gl_peer__destroy(p);
            memcpy(p->err, keep, sizeof keep);
        }
        return -1;
    }
    s = (const char *)glGetString(GL_RENDERER);
    snprintf(p->renderer, sizeof p->renderer, "%s", s ? s : "(null)");
    s = (const char *)glGetString(GL_VERSION);
    snprintf(p->version, sizeof p->version, "%s", s ? s : "(null)");
    if (!strstr(p->renderer, "llvmpipe")) {
        char keep[512];
        snprintf(keep, sizeof keep, "GL_RENDERER is \"%s\", not llvmpipe", p->renderer);
        gl_peer__destroy(p);
        memcpy(p->err, keep, sizeof keep);
        return -1;
    }

    glGenRenderbuffers(1, &p->color_rb);
    glBindRenderbuffer(GL_RENDERBUFFER, p->color_rb);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_RGBA8, width, height);
    glGenRenderbuffers(1, &p->ds_rb);
    glBindRenderbuffer(GL_RENDERBUFFER, p->ds_rb);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH32F_STENCIL8, width, height);
    glGenFramebuffers(1, &p->fbo);
    glBindFramebuffer(GL_FRAMEBUFFER, p->fbo);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, p->color_rb);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_STENCIL_ATTACHMENT, GL_RENDERBUFFER, p->ds_rb);
    status = glCheckFramebufferStatus(GL_FRAMEBUFFER);
    if (status != GL_FRAMEBUFFER_COMPLETE) {
        char keep[512];
        snprintf(keep, sizeof keep, "FBO incomplete (0x%x)", (unsigned)status);
        gl_peer__destroy(p);
        memcpy(p->err, keep, sizeof keep);
        return -1;
    }
    glDrawBuffer(GL_COLOR_ATTACHMENT0);
    glReadBuffer(GL_COLOR_ATTACHMENT0);

    p->prog_smooth = gl_peer__program(p, 0);
    p->prog_flat = p->prog_smooth ? gl_peer__program(p, 1) : 0;
    if (!p->prog_smooth || !p->prog_flat) {
        char keep[512];
        memcpy(keep, p->err, sizeof keep);
        gl_peer__destroy(p);
        memcpy(p->err, keep, sizeof keep);
        return -1;
    }
    p->loc_point_size_smooth = glGetUniformLocation(p->prog_smooth, "u_point_size");
    p->loc_point_size_flat = glGetUniformLocation(p->prog_flat, "u_point_size");
    glUseProgram(p->prog_flat);
    glUniform1f(p->loc_point_size_flat, 1.0f);
    glUseProgram(p->prog_smooth);
    glUniform1f(p->loc_point_size_smooth, 1.0f);
    p->prog = p->prog_smooth;

    glGenVertexArrays(1, &p->vao);
    glBindVertexArray(p->vao);
    glGenBuffers(1, &p->vbo);
    glGenBuffers(1, &p->ibo);
    glBindBuffer(GL_ARRAY_BUFFER, p->vbo);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, p->ibo);
    glEnableVertexAttribArray(0);
    glEnableVertexAttribArray(1);
    glVertexAttribPointer(0, 4, GL_FLOAT, GL_FALSE, GL_PEER_FLOATS_PER_VERTEX * 4, (const void *)0);
    glVertexAttribPointer(1, 4, GL_FLOAT, GL_FALSE, GL_PEER_FLOATS_PER_VERTEX * 4, (const void *)16);

    /* GL 3.3 core defaults otherwise: viewport = FBO size is set here since
       the context had no surface when it was first made current. */
    glViewport(0, 0, width, height);
    glEnable(GL_PROGRAM_POINT_SIZE);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    if (glGetError() != GL_NO_ERROR) {
        gl_peer__destroy(p);
        return gl_peer__fail(p, "GL error while setting up the FBO, program or buffers");
    }
    return 0;
}

static inline int gl_peer_init(gl_peer *p, int width, int height) {
    int r;
    GL_PEER__LSAN_OFF();
    r = gl_peer__init(p, width, height);
    GL_PEER__LSAN_ON();
    return r;
}

static inline void gl_peer_destroy(gl_peer *p) {
    GL_PEER__LSAN_OFF();
    gl_peer__destroy(p);
    GL_PEER__LSAN_ON();
}

/* Smooth (perspective-correct) or flat (last vertex) colour. */
static inline void gl_peer_shading(gl_peer *p, int flat) {
    p->prog = flat ? p->prog_flat : p->prog_smooth;
    glUseProgram(p->prog);
    glUniform1f(flat ? p->loc_point_size_flat : p->loc_point_size_smooth, p->point_size);
}

static inline void gl_peer_point_size(gl_peer *p, float size) {
    p->point_size = size;
    glUniform1f(p->prog == p->prog_flat ? p->loc_point_size_flat : p->loc_point_size_smooth, size);
}

/* Uploads vertices (8 floats each) and optional 32-bit indices into the
   peer's buffers; later gl_peer_draw calls use them. */
static inline void gl_peer_upload(gl_peer *p, const float *vertices, int vertex_count,
                                  const uint32_t *indices, int index_count) {
    size_t vb = (size_t)vertex_count * GL_PEER_FLOATS_PER_VERTEX * sizeof(float);
    size_t ib = indices ? (size_t)index_count * sizeof(uint32_t) : 0;
    glBindBuffer(GL_ARRAY_BUFFER, p->vbo);
    glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)vb, vertices, GL_STATIC_DRAW);
    p->vbo_bytes = vb;
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, p->ibo);
    glBufferData(GL_ELEMENT_ARRAY_BUFFER, (GLsizeiptr)ib, ib ? indices : NULL, GL_STATIC_DRAW);
    p->ibo_bytes = ib;
}

/* Draws `count` vertices (or indices, when indices were uploaded) from
   `first` with the uploaded buffers. */
static inline void gl_peer_draw(gl_peer *p, GLenum mode, int first, int count) {
    GL_PEER__LSAN_OFF(); /* shader variants are compiled lazily, at draws */
    if (p->ibo_bytes)
        glDrawElements(mode, count, GL_UNSIGNED_INT, (const void *)((size_t)first * sizeof(uint32_t)));
    else
        glDrawArrays(mode, first, count);
    GL_PEER__LSAN_ON();
}

/* Upload + draw in one go, without indices. */
static inline void gl_peer_draw_vertices(gl_peer *p, GLenum mode, const float *vertices,
                                         int vertex_count) {
    gl_peer_upload(p, vertices, vertex_count, NULL, 0);
    gl_peer_draw(p, mode, 0, vertex_count);
}

static inline void gl_peer_finish(gl_peer *p) {
    (void)p;
    glFinish();
}

static inline void gl_peer__flip(void *data, int row_bytes, int height) {
    unsigned char *d = (unsigned char *)data, tmp[256];
    int y;
    for (y = 0; y < height / 2; y++) {
        unsigned char *a = d + (size_t)y * (size_t)row_bytes;
        unsigned char *b = d + (size_t)(height - 1 - y) * (size_t)row_bytes;
        int off = 0;
        while (off < row_bytes) {
            int n = row_bytes - off < (int)sizeof tmp ? row_bytes - off : (int)sizeof tmp;
            memcpy(tmp, a + off, (size_t)n);
            memcpy(a + off, b + off, (size_t)n);
            memcpy(b + off, tmp, (size_t)n);
            off += n;
        }
    }
}

/* Read-backs: tightly packed, row 0 = the top row. */
static inline void gl_peer_read_rgba8(gl_peer *p, uint8_t *rgba) {
    glReadPixels(0, 0, p->width, p->height, GL_RGBA, GL_UNSIGNED_BYTE, rgba);
    gl_peer__flip(rgba, p->width * 4, p->height);
}

static inline void gl_peer_read_depth(gl_peer *p, float *depth) {
    glReadPixels(0, 0, p->width, p->height, GL_DEPTH_COMPONENT, GL_FLOAT, depth);
    gl_peer__flip(depth, p->width * (int)sizeof(float), p->height);
}

static inline void gl_peer_read_stencil(gl_peer *p, uint8_t *stencil) {
    glReadPixels(0, 0, p->width, p->height, GL_STENCIL_INDEX, GL_UNSIGNED_BYTE, stencil);
    gl_peer__flip(stencil, p->width, p->height);
}

/* Nonzero when GL recorded an error since the last call (it is cleared). */
static inline GLenum gl_peer_error(void) {
    GLenum e = glGetError(), first = e;
    while (e != GL_NO_ERROR) e = glGetError();
    return first;
}

#endif /* GL_PEER_H_INCLUDED */
