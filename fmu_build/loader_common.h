/*
 * loader_common.h -- what the FMU's entry libraries share (loader.c for FMI 2.0, loader3.c for FMI 3.0): finding
 * or loading the build interpreter's libpython, loading pythonfmu's library from the loader's own directory,
 * setting PYTHONHOME/PYTHONPATH for the moment Python starts, releasing pythonfmu's interpreter state once, and
 * the host's logging switch.  Header-only: each loader is one C file compiled with this header (and its
 * loader_config.h) by fmu_build/loader.py; see loader.c's header comment for why each step is there.
 *
 * Before including it, a loader includes loader_config.h (EBB_PYTHON, EBB_LIBPYTHON, EBB_PYTHONHOME,
 * EBB_PYTHONPATH, EBB_INNER_LIB, EBB_GUID).
 */
#ifndef EBB_LOADER_COMMON_H
#define EBB_LOADER_COMMON_H

#include <errno.h>
#include <dlfcn.h>
#include <pthread.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define EXPORT __attribute__((visibility("default")))

/* The statuses both standards share: OK 0, warning 1, discard 2, error 3, fatal 4. */
enum { EBB_OK = 0, EBB_WARNING = 1, EBB_DISCARD = 2, EBB_ERROR = 3, EBB_FATAL = 4 };

/* Process-wide loader state: the inner library is loaded once per process. */
static pthread_once_t g_once = PTHREAD_ONCE_INIT;
static pthread_mutex_t g_env_lock = PTHREAD_MUTEX_INITIALIZER;
static void *g_inner = NULL;
static int g_loaded_libpython = 0;
static int (*g_py_is_initialized)(void) = NULL; /* set when this loader loaded libpython */
static void (*g_inner_finalize)(void) = NULL;   /* pythonfmu's finalizePythonInterpreter */
static char g_error[2048] = "";

static inline void own_directory(char *buf, size_t size)
{
    Dl_info info;
    buf[0] = '\0';
    if (dladdr((void *)&own_directory, &info) && info.dli_fname) {
        snprintf(buf, size, "%s", info.dli_fname);
        char *slash = strrchr(buf, '/');
        if (slash) {
            *slash = '\0';
        } else {
            snprintf(buf, size, ".");
        }
    }
}

/* pythonfmu's interpreter state is released once, before its static destructors run (loader.c explains). */
static inline void finalize_inner(void)
{
    if (g_inner && g_inner_finalize) {
        g_inner_finalize();
        g_inner_finalize = NULL;
    }
}

static void finalize_inner_at_exit(void) { finalize_inner(); }

/* Resolve the inner library's `symbol` into g_api.field, or note what is missing in g_error and return. */
#define RESOLVE(field, symbol)                                                         \
    do {                                                                               \
        *(void **)(&g_api.field) = dlsym(g_inner, symbol);                             \
        if (!g_api.field) {                                                            \
            snprintf(g_error, sizeof g_error, "%s: missing symbol %s", EBB_INNER_LIB, symbol); \
            return;                                                                    \
        }                                                                              \
    } while (0)

/* The build interpreter and its site-packages must still be where the build found them: otherwise
 * name what is missing (not the first module Python fails to import). Returns 0 when all is there. */
static inline int check_build_python(void)
{
    const char *missing = NULL;
    char entry[4096];
    if (access(EBB_PYTHON, X_OK) != 0) missing = EBB_PYTHON;
    for (const char *p = EBB_PYTHONPATH; !missing && *p;) {
        size_t n = strcspn(p, ":");
        if (n > 0 && n < sizeof entry) {
            memcpy(entry, p, n);
            entry[n] = '\0';
            if (access(entry, R_OK | X_OK) != 0) missing = entry;
        }
        p += n + (p[n] == ':');
    }
    if (!missing) return 0;
    snprintf(g_error, sizeof g_error,
             "the Python this FMU was built with is gone (%s: %s); the FMU runs on %s with numpy, scipy "
             "and numba installed: restore that environment or rebuild the FMU", missing, strerror(errno),
             EBB_PYTHON);
    return 1;
}

/* Python's C API in the process (the host's, or the build interpreter's libpython loaded RTLD_GLOBAL), then
 * pythonfmu's library from this loader's directory into g_inner.  Returns 0, or 1 with the reason in g_error. */
static inline int load_python_and_inner(void)
{
    if (!dlsym(RTLD_DEFAULT, "Py_IsInitialized")) {
        /* No Python in the process: bring the build interpreter's. */
        if (check_build_python()) return 1;
        void *libpython = dlopen(EBB_LIBPYTHON, RTLD_NOW | RTLD_GLOBAL);
        if (!libpython) {
            snprintf(g_error, sizeof g_error, "cannot load the Python runtime this FMU was built with (%s): %s",
                     EBB_LIBPYTHON, dlerror());
            return 1;
        }
        *(void **)(&g_py_is_initialized) = dlsym(libpython, "Py_IsInitialized");
        if (!g_py_is_initialized) {
            snprintf(g_error, sizeof g_error, "%s: missing symbol Py_IsInitialized", EBB_LIBPYTHON);
            return 1;
        }
        g_loaded_libpython = 1;
    }
    char path[4096];
    own_directory(path, sizeof path);
    size_t used = strlen(path);
    snprintf(path + used, sizeof path - used, "/%s", EBB_INNER_LIB);
    g_inner = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!g_inner) {
        snprintf(g_error, sizeof g_error, "cannot load %s: %s", path, dlerror());
        return 1;
    }
    return 0;
}

/* After the inner library's functions are resolved: release its state at exit, and pin this loader when it
 * brought Python (the interpreter must outlive any reload of the FMU, numpy cannot be initialised twice). */
static inline void keep_inner(void)
{
    *(void **)(&g_inner_finalize) = dlsym(g_inner, "finalizePythonInterpreter");
    if (g_inner_finalize) atexit(finalize_inner_at_exit);
    if (g_loaded_libpython) {
        Dl_info self;
        if (dladdr((void *)&own_directory, &self) && self.dli_fname) {
            dlopen(self.dli_fname, RTLD_NOW | RTLD_NOLOAD | RTLD_NODELETE);
        }
    }
}

/* Before the inner instantiate call: when this loader brought Python and it may start now, set PYTHONHOME and
 * PYTHONPATH (those the host has not set) under g_env_lock.  Returns which were set (for end_python_start). */
static inline int begin_python_start(void)
{
    int set = 0;
    if (!g_py_is_initialized) return 0;
    pthread_mutex_lock(&g_env_lock);
    if (!g_py_is_initialized()) {
        if (!getenv("PYTHONHOME")) {
            setenv("PYTHONHOME", EBB_PYTHONHOME, 1);
            set |= 1;
        }
        if (!getenv("PYTHONPATH")) {
            setenv("PYTHONPATH", EBB_PYTHONPATH, 1);
            set |= 2;
        }
    }
    return set;
}

/* After the inner instantiate call: the host's environment as it was. */
static inline void end_python_start(int set)
{
    if (!g_py_is_initialized) return;
    if (set & 1) unsetenv("PYTHONHOME");
    if (set & 2) unsetenv("PYTHONPATH");
    pthread_mutex_unlock(&g_env_lock);
}

__attribute__((destructor)) static void unload_inner(void)
{
    /* In a Python host, unload pythonfmu's library with us (as a master would
     * without the loader).  An interpreter this loader started stays loaded:
     * pythonfmu finalises it at process exit. */
    if (g_inner && !g_loaded_libpython) {
        finalize_inner();
        dlclose(g_inner);
        g_inner = NULL;
    }
}

/* ---- the host's logging switch ------------------------------------------------------------------------------ */

typedef struct {
    int on;               /* debug logging enabled by the host */
    size_t n_categories;  /* 0: every category */
    char **categories;
    int worst;            /* worst status logged by the slave during the current call */
} LogSwitch;

static inline void log_switch_clear(LogSwitch *s)
{
    for (size_t i = 0; i < s->n_categories; ++i) free(s->categories[i]);
    free(s->categories);
    s->categories = NULL;
    s->n_categories = 0;
}

/* The host's fmiXSetDebugLogging; returns EBB_OK, or EBB_ERROR when out of memory. */
static inline int log_switch_set(LogSwitch *s, int on, size_t n, const char *const categories[])
{
    log_switch_clear(s);
    s->on = on;
    if (n > 0 && categories) {
        s->categories = calloc(n, sizeof(char *));
        if (!s->categories) return EBB_ERROR;
        for (size_t i = 0; i < n; ++i) s->categories[i] = strdup(categories[i] ? categories[i] : "");
        s->n_categories = n;
    }
    return EBB_OK;
}

/* Note a message's status; whether it reaches the host: errors always, others when the host enabled debug
 * logging (and named the category, if it named any). */
static inline int log_switch_passes(LogSwitch *s, int status, const char *category)
{
    if (status > s->worst) s->worst = status;
    if (status >= EBB_ERROR) return 1;
    if (!s->on) return 0;
    if (s->n_categories == 0) return 1;
    if (!category) return 0;
    for (size_t i = 0; i < s->n_categories; ++i) {
        if (strcmp(s->categories[i], category) == 0) return 1;
    }
    return 0;
}

/* The status a call returns: at least the worst the slave logged during it (capped at error; a logged discard
 * is not a failed call). */
static inline int log_switch_settle(const LogSwitch *s, int status)
{
    int logged = s->worst > EBB_ERROR ? EBB_ERROR : s->worst;
    if (logged == EBB_DISCARD) logged = EBB_WARNING;
    return status < logged ? logged : status;
}

#endif
