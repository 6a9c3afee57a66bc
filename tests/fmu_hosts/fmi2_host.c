/*
 * fmi2_host.c -- a plain C FMI 2.0 co-simulation master for the tests.
 *
 * No Python anywhere: it dlopens the FMU's binary and drives one instance
 *
 *   fmi2Instantiate, fmi2SetupExperiment, fmi2SetReal (parameters),
 *   fmi2EnterInitializationMode, fmi2ExitInitializationMode,
 *   then per communication point k:  fmi2SetReal(u_k), fmi2GetReal(y_k), fmi2DoStep(t_k, h),
 *   fmi2Terminate, fmi2FreeInstance.
 *
 * Usage:
 *   fmi2_host LIBRARY GUID RESOURCE_URI STEP NSTEPS INPUT_FILE IN_VRS OUT_VRS [VR=VALUE ...] [@K]
 *
 *   IN_VRS, OUT_VRS   comma-separated value references, or "-" for none
 *   INPUT_FILE        NSTEPS lines of len(IN_VRS) numbers, or "-" when IN_VRS is "-"
 *   VR=VALUE          Real parameters set before initialisation
 *   @K                checkpoint: before communication point K the state is saved (fmi2GetFMUstate) and
 *                     serialised to bytes (fmi2SerializeFMUstate, the live state freed); after the run it is
 *                     deserialised, set (fmi2SetFMUstate) and points K … NSTEPS-1 are run again, their lines
 *                     prefixed with "R "
 *
 * With FMI2_HOST_REJECT_NULL set in the environment the logger aborts the process when called with a NULL
 * instance name, category or message, as a host building C++ strings from them does (OMSimulator).
 *
 * Prints one line per communication point with the outputs (%.17g) on
 * stdout; the FMU's log messages go to stderr, and so does the state of
 * PYTHONHOME / PYTHONPATH right after fmi2Instantiate.  Exit status: 0 success,
 * 1 usage, 2 the library or a symbol cannot be loaded, 3 an FMI call
 * returned an error (the function and status are printed on stderr).
 */
#include <stdarg.h>

#include "host_util.h"

typedef void *fmi2Component;
typedef void *fmi2ComponentEnvironment;
typedef unsigned int fmi2ValueReference;
typedef double fmi2Real;
typedef int fmi2Boolean;
typedef const char *fmi2String;
typedef enum { fmi2OK, fmi2Warning, fmi2Discard, fmi2Error, fmi2Fatal, fmi2Pending } fmi2Status;
typedef enum { fmi2ModelExchange, fmi2CoSimulation } fmi2Type;

typedef struct {
    void (*logger)(fmi2ComponentEnvironment, fmi2String, fmi2Status, fmi2String, fmi2String, ...);
    void *(*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void *);
    void (*stepFinished)(fmi2ComponentEnvironment, fmi2Status);
    fmi2ComponentEnvironment componentEnvironment;
} fmi2CallbackFunctions;

typedef fmi2Component (*InstantiateFn)(fmi2String, fmi2Type, fmi2String, fmi2String,
                                       const fmi2CallbackFunctions *, fmi2Boolean, fmi2Boolean);
typedef void (*FreeInstanceFn)(fmi2Component);
typedef fmi2Status (*SetupExperimentFn)(fmi2Component, fmi2Boolean, fmi2Real, fmi2Real, fmi2Boolean, fmi2Real);
typedef fmi2Status (*ComponentFn)(fmi2Component);
typedef fmi2Status (*SetRealFn)(fmi2Component, const fmi2ValueReference[], size_t, const fmi2Real[]);
typedef fmi2Status (*GetRealFn)(fmi2Component, const fmi2ValueReference[], size_t, fmi2Real[]);
typedef fmi2Status (*DoStepFn)(fmi2Component, fmi2Real, fmi2Real, fmi2Boolean);
typedef void *fmi2FMUstate;
typedef fmi2Status (*GetStateFn)(fmi2Component, fmi2FMUstate *);
typedef fmi2Status (*SetStateFn)(fmi2Component, fmi2FMUstate);
typedef fmi2Status (*FreeStateFn)(fmi2Component, fmi2FMUstate *);
typedef fmi2Status (*StateSizeFn)(fmi2Component, fmi2FMUstate, size_t *);
typedef fmi2Status (*SerializeFn)(fmi2Component, fmi2FMUstate, char[], size_t);
typedef fmi2Status (*DeSerializeFn)(fmi2Component, const char[], size_t, fmi2FMUstate *);

static void log_message(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status,
                        fmi2String category, fmi2String message, ...)
{
    (void)env;
    if ((!name || !category || !message) && getenv("FMI2_HOST_REJECT_NULL")) {
        /* as a host that builds C++ strings from them does (OMSimulator: std::logic_error, then abort) */
        fprintf(stderr, "logger called with a NULL %s\n", !name ? "instance name" : !category ? "category" : "message");
        abort();
    }
    va_list args;
    va_start(args, message);
    fprintf(stderr, "[%s] status=%d category=%s: ", name ? name : "", (int)status, category ? category : "");
    vfprintf(stderr, message, args);
    fputc('\n', stderr);
    va_end(args);
}

int main(int argc, char **argv)
{
    if (argc < 9) {
        fprintf(stderr, "usage: %s LIBRARY GUID RESOURCE_URI STEP NSTEPS INPUT_FILE IN_VRS OUT_VRS [VR=VALUE ...]\n",
                argv[0]);
        return 1;
    }
    const char *library = argv[1], *guid = argv[2], *resources = argv[3];
    double step = strtod(argv[4], NULL);
    long nsteps = strtol(argv[5], NULL, 10);
    const char *input_file = argv[6];
    fmi2ValueReference *in_vrs, *out_vrs;
    size_t *in_sizes, *out_sizes, n_in_values, n_out_values;    /* (FMI 2.0 has no arrays: sizes 1) */
    size_t n_in = parse_vrs(argv[7], &in_vrs, &in_sizes, &n_in_values);
    size_t n_out = parse_vrs(argv[8], &out_vrs, &out_sizes, &n_out_values);

    void *lib = dlopen(library, RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        fprintf(stderr, "cannot load %s: %s\n", library, dlerror());
        return 2;
    }
    InstantiateFn instantiate = (InstantiateFn)symbol(lib, "fmi2Instantiate");
    FreeInstanceFn freeInstance = (FreeInstanceFn)symbol(lib, "fmi2FreeInstance");
    SetupExperimentFn setupExperiment = (SetupExperimentFn)symbol(lib, "fmi2SetupExperiment");
    ComponentFn enterInit = (ComponentFn)symbol(lib, "fmi2EnterInitializationMode");
    ComponentFn exitInit = (ComponentFn)symbol(lib, "fmi2ExitInitializationMode");
    ComponentFn terminate = (ComponentFn)symbol(lib, "fmi2Terminate");
    SetRealFn setReal = (SetRealFn)symbol(lib, "fmi2SetReal");
    GetRealFn getReal = (GetRealFn)symbol(lib, "fmi2GetReal");
    DoStepFn doStep = (DoStepFn)symbol(lib, "fmi2DoStep");

    fmi2CallbackFunctions callbacks = {log_message, calloc, free, NULL, NULL};
    fmi2Component c = instantiate("c_host", fmi2CoSimulation, guid, resources, &callbacks, 0, 0);
    if (!c) {
        fprintf(stderr, "fmi2Instantiate failed\n");
        return 3;
    }
    /* the FMU's loader may set these while Python starts, but must give them back */
    fprintf(stderr, "after fmi2Instantiate: PYTHONHOME=%s PYTHONPATH=%s\n",
            getenv("PYTHONHOME") ? getenv("PYTHONHOME") : "(unset)",
            getenv("PYTHONPATH") ? getenv("PYTHONPATH") : "(unset)");
    CHECK(setupExperiment(c, 0, 0.0, 0.0, 0, 0.0), "fmi2SetupExperiment");
    long checkpoint;
    unsigned *vrs = calloc((size_t)argc, sizeof *vrs);
    double *values = calloc((size_t)argc, sizeof *values);
    const int n_params = parse_params(argc, argv, 9, vrs, values, &checkpoint);
    if (n_params < 0) {
        freeInstance(c);
        return 1;
    }
    for (int i = 0; i < n_params; ++i) CHECK(setReal(c, vrs + i, 1, values + i), "fmi2SetReal");
    free(vrs);
    free(values);
    CHECK(enterInit(c), "fmi2EnterInitializationMode");
    CHECK(exitInit(c), "fmi2ExitInitializationMode");

    FILE *in = NULL;
    if (n_in > 0) {
        in = fopen(input_file, "r");
        if (!in) {
            fprintf(stderr, "cannot open %s\n", input_file);
            freeInstance(c);
            return 1;
        }
    }
    fmi2Real *u = calloc(n_in * (size_t)nsteps + 1, sizeof *u);   /* every input, for a replay */
    fmi2Real *y = calloc(n_out + 1, sizeof *y);
    char *saved = NULL;
    size_t saved_size = 0;
    double t = 0.0;
    for (long k = 0; k < nsteps; ++k) {
        fmi2Real *uk = u + (size_t)k * n_in;
        for (size_t i = 0; i < n_in; ++i) {
            if (fscanf(in, "%lf", &uk[i]) != 1) {
                fprintf(stderr, "input file: not enough values at step %ld\n", k);
                freeInstance(c);
                return 1;
            }
        }
        if (k == checkpoint) {
            fmi2FMUstate state = NULL;
            CHECK(((GetStateFn)symbol(lib, "fmi2GetFMUstate"))(c, &state), "fmi2GetFMUstate");
            CHECK(((StateSizeFn)symbol(lib, "fmi2SerializedFMUstateSize"))(c, state, &saved_size),
                  "fmi2SerializedFMUstateSize");
            saved = malloc(saved_size);
            CHECK(((SerializeFn)symbol(lib, "fmi2SerializeFMUstate"))(c, state, saved, saved_size),
                  "fmi2SerializeFMUstate");
            CHECK(((FreeStateFn)symbol(lib, "fmi2FreeFMUstate"))(c, &state), "fmi2FreeFMUstate");
        }
        if (n_in) CHECK(setReal(c, in_vrs, n_in, uk), "fmi2SetReal");
        if (n_out) CHECK(getReal(c, out_vrs, n_out, y), "fmi2GetReal");
        print_row("", y, n_out);
        CHECK(doStep(c, t, step, 1), "fmi2DoStep");
        t = (double)(k + 1) * step;
    }
    if (saved) {                                  /* the replay from the deserialised checkpoint */
        fmi2FMUstate state = NULL;
        CHECK(((DeSerializeFn)symbol(lib, "fmi2DeSerializeFMUstate"))(c, saved, saved_size, &state),
              "fmi2DeSerializeFMUstate");
        CHECK(((SetStateFn)symbol(lib, "fmi2SetFMUstate"))(c, state), "fmi2SetFMUstate");
        CHECK(((FreeStateFn)symbol(lib, "fmi2FreeFMUstate"))(c, &state), "fmi2FreeFMUstate");
        for (long k = checkpoint; k < nsteps; ++k) {
            t = (double)k * step;
            if (n_in) CHECK(setReal(c, in_vrs, n_in, u + (size_t)k * n_in), "fmi2SetReal");
            if (n_out) CHECK(getReal(c, out_vrs, n_out, y), "fmi2GetReal");
            print_row("R ", y, n_out);
            CHECK(doStep(c, t, step, 1), "fmi2DoStep");
        }
        free(saved);
    }
    if (in) fclose(in);
    CHECK(terminate(c), "fmi2Terminate");
    freeInstance(c);
    free(u);
    free(y);
    free(in_vrs);
    free(in_sizes);
    free(out_vrs);
    free(out_sizes);
    fflush(stdout);
    return 0;
}
