/* The test binaries' main: Criterion's, plus a list of tests to leave out
   read from the file RAST_TEST_SKIP_FILE names (one "suite/test" a line;
   lines not starting with a lower-case letter ignored). The sanitized run
   of `make test` leaves out tests/sanitized_skip.txt's this way: Criterion's
   --filter matches every test name against every alternative of its
   pattern, and with the list's 66 alternatives that alone took minutes. */
#include <criterion/criterion.h>
#include <criterion/internal/ordered-set.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int listed(char *const *names, int count, const char *suite, const char *test) {
    size_t sl = strlen(suite);
    int i;
    for (i = 0; i < count; ++i)
        if (!strncmp(names[i], suite, sl) && names[i][sl] == '/' && !strcmp(names[i] + sl + 1, test)) return 1;
    return 0;
}

/* Marks the listed tests disabled (Criterion reports them skipped); a file
   that cannot be read is an error, so a wrong path never runs everything. */
static int skip_listed(struct criterion_test_set *set, const char *path) {
    char line[512], *names[1024];
    int count = 0, i;
    FILE *f = fopen(path, "r");
    if (!f) {
        fprintf(stderr, "RAST_TEST_SKIP_FILE: cannot read %s\n", path);
        return 0;
    }
    while (count < 1024 && fgets(line, sizeof line, f)) {
        line[strcspn(line, "\r\n")] = '\0';
        size_t n = strlen(line) + 1;
        if (!(line[0] >= 'a' && line[0] <= 'z')) continue;
        if (!(names[count] = (char *)malloc(n))) break;
        memcpy(names[count++], line, n);
    }
    fclose(f);
    FOREACH_SET(struct criterion_suite_set *s, set->suites) {
        FOREACH_SET(struct criterion_test *t, s->tests) {
            if (t->data && listed(names, count, s->suite.name, t->name)) t->data->disabled = true;
        }
    }
    for (i = 0; i < count; ++i) free(names[i]);
    return 1;
}

int main(int argc, char *argv[]) {
    struct criterion_test_set *tests = criterion_initialize();
    const char *skip = getenv("RAST_TEST_SKIP_FILE");
    int ok = 1;
    if (criterion_handle_args(argc, argv, true)) ok = (!skip || skip_listed(tests, skip)) && criterion_run_all_tests(tests);
    criterion_finalize(tests);
    return !ok;
}
