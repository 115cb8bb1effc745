/* reflect_gl_funcs.h - the GL entry points the GL host uses, loaded
   through eglGetProcAddress (EGL 1.5 and EGL_KHR_get_all_proc_addresses
   return core functions too), so the host links libEGL alone and runs
   wherever a vendor's EGL is installed (no libGL, no X11 libraries).
   Include after <GL/gl.h>; rgl (tools/reflect_gl.c) holds them once a
   context is current. */
#ifndef REFLECT_GL_FUNCS_H
#define REFLECT_GL_FUNCS_H

#include <stdio.h>

typedef char GLchar_rgl;
typedef ptrdiff_t GLsizeiptr_rgl;
typedef ptrdiff_t GLintptr_rgl;

#define RGL_FUNCS(X) \
    X(const GLubyte *, GetString, (GLenum)) \
    X(GLenum, GetError, (void)) \
    X(void, GetIntegerv, (GLenum, GLint *)) \
    X(void, Enable, (GLenum)) \
    X(void, Disable, (GLenum)) \
    X(void, Finish, (void)) \
    X(void, Viewport, (GLint, GLint, GLsizei, GLsizei)) \
    X(void, Scissor, (GLint, GLint, GLsizei, GLsizei)) \
    X(void, ClearColor, (GLfloat, GLfloat, GLfloat, GLfloat)) \
    X(void, ClearDepth, (GLdouble)) \
    X(void, ClearStencil, (GLint)) \
    X(void, Clear, (GLbitfield)) \
    X(void, DepthFunc, (GLenum)) \
    X(void, DepthMask, (GLboolean)) \
    X(void, StencilFunc, (GLenum, GLint, GLuint)) \
    X(void, StencilOp, (GLenum, GLenum, GLenum)) \
    X(void, StencilMask, (GLuint)) \
    X(void, ColorMask, (GLboolean, GLboolean, GLboolean, GLboolean)) \
    X(void, ReadPixels, (GLint, GLint, GLsizei, GLsizei, GLenum, GLenum, void *)) \
    X(void, PixelStorei, (GLenum, GLint)) \
    X(void, DrawArrays, (GLenum, GLint, GLsizei)) \
    X(void, DrawArraysInstanced, (GLenum, GLint, GLsizei, GLsizei)) \
    X(void, DrawBuffers, (GLsizei, const GLenum *)) \
    X(void, ReadBuffer, (GLenum)) \
    X(void, DrawElements, (GLenum, GLsizei, GLenum, const void *)) \
    X(GLuint, CreateShader, (GLenum)) \
    X(void, ShaderSource, (GLuint, GLsizei, const GLchar_rgl *const *, const GLint *)) \
    X(void, CompileShader, (GLuint)) \
    X(void, GetShaderiv, (GLuint, GLenum, GLint *)) \
    X(void, GetShaderInfoLog, (GLuint, GLsizei, GLsizei *, GLchar_rgl *)) \
    X(void, DeleteShader, (GLuint)) \
    X(GLuint, CreateProgram, (void)) \
    X(void, AttachShader, (GLuint, GLuint)) \
    X(void, TransformFeedbackVaryings, (GLuint, GLsizei, const GLchar_rgl *const *, GLenum)) \
    X(void, LinkProgram, (GLuint)) \
    X(void, GetProgramiv, (GLuint, GLenum, GLint *)) \
    X(void, GetProgramInfoLog, (GLuint, GLsizei, GLsizei *, GLchar_rgl *)) \
    X(void, DeleteProgram, (GLuint)) \
    X(void, UseProgram, (GLuint)) \
    X(GLint, GetUniformLocation, (GLuint, const GLchar_rgl *)) \
    X(void, Uniform1i, (GLint, GLint)) \
    X(void, Uniform1f, (GLint, GLfloat)) \
    X(void, Uniform3f, (GLint, GLfloat, GLfloat, GLfloat)) \
    X(void, Uniform4f, (GLint, GLfloat, GLfloat, GLfloat, GLfloat)) \
    X(void, Uniform4fv, (GLint, GLsizei, const GLfloat *)) \
    X(void, UniformMatrix4fv, (GLint, GLsizei, GLboolean, const GLfloat *)) \
    X(void, GenBuffers, (GLsizei, GLuint *)) \
    X(void, BindBuffer, (GLenum, GLuint)) \
    X(void, BufferData, (GLenum, GLsizeiptr_rgl, const void *, GLenum)) \
    X(void, GetBufferSubData, (GLenum, GLintptr_rgl, GLsizeiptr_rgl, void *)) \
    X(void, DeleteBuffers, (GLsizei, const GLuint *)) \
    X(void, BindBufferBase, (GLenum, GLuint, GLuint)) \
    X(void, GenTextures, (GLsizei, GLuint *)) \
    X(void, BindTexture, (GLenum, GLuint)) \
    X(void, TexBuffer, (GLenum, GLenum, GLuint)) \
    X(void, TexImage2D, (GLenum, GLint, GLint, GLsizei, GLsizei, GLint, GLenum, GLenum, const void *)) \
    X(void, TexParameteri, (GLenum, GLenum, GLint)) \
    X(void, DeleteTextures, (GLsizei, const GLuint *)) \
    X(void, ActiveTexture, (GLenum)) \
    X(void, GenVertexArrays, (GLsizei, GLuint *)) \
    X(void, BindVertexArray, (GLuint)) \
    X(void, DeleteVertexArrays, (GLsizei, const GLuint *)) \
    X(void, EnableVertexAttribArray, (GLuint)) \
    X(void, VertexAttribPointer, (GLuint, GLint, GLenum, GLboolean, GLsizei, const void *)) \
    X(void, BeginTransformFeedback, (GLenum)) \
    X(void, EndTransformFeedback, (void)) \
    X(void, GenFramebuffers, (GLsizei, GLuint *)) \
    X(void, BindFramebuffer, (GLenum, GLuint)) \
    X(void, DeleteFramebuffers, (GLsizei, const GLuint *)) \
    X(void, FramebufferRenderbuffer, (GLenum, GLenum, GLenum, GLuint)) \
    X(GLenum, CheckFramebufferStatus, (GLenum)) \
    X(void, GenRenderbuffers, (GLsizei, GLuint *)) \
    X(void, BindRenderbuffer, (GLenum, GLuint)) \
    X(void, RenderbufferStorage, (GLenum, GLenum, GLsizei, GLsizei)) \
    X(void, DeleteRenderbuffers, (GLsizei, const GLuint *))

#define RGL_MEMBER(ret, name, args) ret (*name) args;
typedef struct rgl_funcs {
    RGL_FUNCS(RGL_MEMBER)
} rgl_funcs;
#undef RGL_MEMBER

extern rgl_funcs rgl;

/* Loads every entry point (a context must be current); 0 on success, else
   nonzero naming the first one missing. */
static inline int rgl_funcs_load(rgl_funcs *f, char *err, size_t n) {
#define RGL_LOAD(ret, name, args) \
    *(void **)(&f->name) = (void *)eglGetProcAddress("gl" #name); \
    if (!f->name) { snprintf(err, n, "eglGetProcAddress(\"gl%s\") found nothing", #name); return -1; }
    RGL_FUNCS(RGL_LOAD)
#undef RGL_LOAD
    return 0;
}

/* Shared by the host's modules (tools/reflect_gl.c). */
GLuint rgl_program(const char *const *vs_parts, int vs_count, const char *const *fs_parts, int fs_count,
                   const char *const *varyings, int varying_count, char *err, size_t n);
GLuint rgl_buffer_texture(const float *data, long long floats, GLuint *buffer, char *err, size_t n);
double rgl_now(void);
struct rgl_context;
GLuint rgl_default_framebuffer(const struct rgl_context *g); /* the context's 1 x 1 framebuffer */

#endif
