/* cli_options.h - option parsing shared by the `reflect` command's
   subcommands (tools/reflect.c, reflect_path.c, reflect_bench.c,
   reflect_bench_auto.c, reflect_gl_bench.c): an option whose value is one
   of a few names, and a value option given twice, refused in one way. */
#ifndef CLI_OPTIONS_H
#define CLI_OPTIONS_H

#include <stdio.h>
#include <string.h>

/* One accepted name of an option and what it stands for; a list ends with
   a NULL name. */
typedef struct cli_choice {
    const char *name;
    int value;
} cli_choice;

/* The value that v names among choices into *out, and 1; when v names
   none, "COMMAND: OPTION: expected a, b or c, got V" on stderr and 0. */
static inline int parse_choice(const char *command, const char *option, const char *v, const cli_choice *choices,
                               int *out) {
    int i, n;
    for (n = 0; choices[n].name; ++n)
        if (!strcmp(choices[n].name, v)) {
            *out = choices[n].value;
            return 1;
        }
    fprintf(stderr, "%s: %s: expected ", command, option);
    for (i = 0; i < n; ++i) fprintf(stderr, "%s%s", i == 0 ? "" : i == n - 1 ? " or " : ", ", choices[i].name);
    fprintf(stderr, ", got %s\n", v);
    return 0;
}

/* A second value of an option would silently replace the first. 1 when
   option a, one of value_options (NULL-ended, at most 64), was given
   before: "COMMAND: OPTION: given twice" on stderr; else 0, a recorded in
   *given (0 before the first option). An option not in the list is never
   refused. */
static inline int cli_given_twice(const char *command, const char *const *value_options, const char *a,
                                  unsigned long long *given) {
    int k;
    for (k = 0; k < 64 && value_options[k]; ++k)
        if (!strcmp(value_options[k], a)) {
            if (*given >> k & 1) {
                fprintf(stderr, "%s: %s: given twice\n", command, a);
                return 1;
            }
            *given |= 1ull << k;
            return 0;
        }
    return 0;
}

#endif
