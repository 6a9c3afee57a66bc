/*
 * host_util.h -- what the tests' plain C masters (fmi2_host.c, fmi3_host.c) share: resolving a symbol, parsing
 * value references, checking a call's status, printing a row.  Header-only (each master is one C file).
 */
#ifndef HOST_UTIL_H
#define HOST_UTIL_H

#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* the symbol, or exit status 2 naming it */
static void *symbol(void *lib, const char *name)
{
    void *p = dlsym(lib, name);
    if (!p) {
        fprintf(stderr, "missing symbol %s: %s\n", name, dlerror());
        exit(2);
    }
    return p;
}

/* comma-separated value references ("-": none), an array's written VRxN (N its elements); returns how many
 * references, their element counts in *sizes and the total in *total */
static size_t parse_vrs(const char *text, unsigned **out, size_t **sizes, size_t *total)
{
    *out = NULL;
    *sizes = NULL;
    *total = 0;
    if (strcmp(text, "-") == 0) return 0;
    size_t n = 1;
    for (const char *p = text; *p; ++p) n += (*p == ',');
    *out = calloc(n, sizeof **out);
    *sizes = calloc(n, sizeof **sizes);
    const char *p = text;
    for (size_t i = 0; i < n; ++i) {
        char *end;
        (*out)[i] = (unsigned)strtoul(p, &end, 10);
        (*sizes)[i] = 1;
        if (*end == 'x') (*sizes)[i] = (size_t)strtoul(end + 1, &end, 10);
        *total += (*sizes)[i];
        p = end + (*end == ',');
    }
    return n;
}

/* a call's status (both standards: 0 OK, 1 warning, 2 discard, 3 error, 4 fatal): above a warning, name the
 * function, free the instance c unless fatal, and return exit status 3 */
#define CHECK(call, name)                                                   \
    do {                                                                    \
        int s_ = (int)(call);                                               \
        if (s_ > 1) {                                                       \
            fprintf(stderr, "%s failed with status %d\n", name, s_);        \
            if (s_ < 4) freeInstance(c);                                    \
            return 3;                                                       \
        }                                                                   \
    } while (0)

/* the trailing arguments from argv[first]: VR=VALUE (a parameter, into vrs[i], values[i]; returns how many) and
 * @K (the checkpoint, into *checkpoint, -1 without one); -1 and a message for anything else */
static int parse_params(int argc, char **argv, int first, unsigned *vrs, double *values, long *checkpoint)
{
    int n = 0;
    *checkpoint = -1;
    for (int i = first; i < argc; ++i) {
        if (argv[i][0] == '@') {
            *checkpoint = strtol(argv[i] + 1, NULL, 10);
            continue;
        }
        char *eq = strchr(argv[i], '=');
        if (!eq) {
            fprintf(stderr, "bad parameter argument %s\n", argv[i]);
            return -1;
        }
        vrs[n] = (unsigned)strtoul(argv[i], NULL, 10);
        values[n++] = strtod(eq + 1, NULL);
    }
    return n;
}

static void print_row(const char *prefix, const double *y, size_t n)
{
    fputs(prefix, stdout);
    for (size_t i = 0; i < n; ++i) printf(i ? " %.17g" : "%.17g", y[i]);
    printf("\n");
}

#endif
