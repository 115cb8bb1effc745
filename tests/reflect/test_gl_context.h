/* The GL tests' context (tools/reflect_gl.h): created, or the test skipped
   saying why where no EGL device exists (GL_PEER_REQUIRED=1 turns the skip
   into a failure, as for the rasteriser's GL peer). Mesa keeps (and at
   eglTerminate drops) allocations that LeakSanitizer reports from an
   unloaded module: GL work runs between LSAN_OFF and LSAN_ON. Include after
   <criterion/criterion.h>, "../../reflect.h" and "../../tools/reflect_gl.h". */
#ifndef TEST_GL_CONTEXT_H
#define TEST_GL_CONTEXT_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#if defined(__SANITIZE_ADDRESS__)
#include <sanitizer/lsan_interface.h>
#define LSAN_OFF() __lsan_disable()
#define LSAN_ON() __lsan_enable()
#else
#define LSAN_OFF() ((void)0)
#define LSAN_ON() ((void)0)
#endif

static inline rgl_context *tu_gl_context(const char *test) {
    rgl_context *g = NULL;
    char err[1024];
    int r;
    LSAN_OFF();
    r = rgl_create(&g, err, sizeof err);
    LSAN_ON();
    if (r != 0) {
        const char *req = getenv("GL_PEER_REQUIRED");
        fprintf(stderr, "%s: no EGL device: %s\n", test, err);
        if (req && *req && strcmp(req, "0") != 0) cr_assert_fail("no EGL device: %s (GL_PEER_REQUIRED is set)", err);
        cr_skip_test("no EGL device: %s", err);
    }
    return g;
}

#endif
