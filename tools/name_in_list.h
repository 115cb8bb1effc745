/* name_in_list.h - whether a name is one of the words of a list separated
   by one character (EGL's space-separated extension strings, a command
   line's comma-separated choices). Shared by the GL host (tools/reflect_gl.c,
   reflect_gl_bench.c) and the rasteriser tests' GL peer
   (tests/rast/gl_peer.h). */
#ifndef NAME_IN_LIST_H
#define NAME_IN_LIST_H

#include <string.h>

/* 1 when name appears in list as a whole word between separators sep (or
   the list's ends); 0 otherwise, and for a NULL list. */
static inline int name_in_list(const char *list, const char *name, char sep) {
    size_t n = strlen(name);
    const char *s = list;
    if (!list || !n) return 0;
    while ((s = strstr(s, name)) != NULL) {
        if ((s == list || s[-1] == sep) && (s[n] == sep || s[n] == '\0')) return 1;
        s += n;
    }
    return 0;
}

#endif
