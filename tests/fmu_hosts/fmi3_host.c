/*
 * fmi3_host.c -- a plain C FMI 3.0 co-simulation master for the tests, written against the standard's headers
 * (fmi3FunctionTypes.h, as fmpy ships them: compiled with -I pointing there).
 *
 * No Python anywhere: it dlopens the FMU's binary and drives one instance
 *
 *   fmi3InstantiateCoSimulation, fmi3SetFloat64 (parameters), fmi3EnterInitializationMode,
 *   fmi3ExitInitializationMode, then per communication point k:  fmi3SetFloat64(u_k), one fmi3GetFloat64 of every
 *   output (arrays included, nValues their total), fmi3DoStep(t_k, h); at the end the directional derivatives
 *   of every output element in every input and the adjoint of an all-ones seed; fmi3Terminate,
 *   fmi3FreeInstance.
 *
 * Usage:
 *   fmi3_host LIBRARY TOKEN RESOURCE_PATH STEP NSTEPS INPUT_FILE IN_VRS OUT_VRS [VR=VALUE ...] [@K]
 *
 *   IN_VRS            comma-separated value references of scalar inputs, or "-" for none
 *   OUT_VRS           comma-separated value references of outputs, an array's as VRxN (N its elements)
 *   INPUT_FILE        NSTEPS lines of len(IN_VRS) numbers
 *   VR=VALUE          Float64 parameters set before initialisation
 *   @K                checkpoint: before point K the state is saved and serialised (the live state freed); after
 *                     the run it is deserialised, set, and points K … NSTEPS-1 run again (lines prefixed "R ")
 *
 * Prints one line per communication point with the output elements (%.17g), then "J" and one line per input
 * (the directional derivatives of every output element), then "A" and the adjoint sensitivities (one per
 * input).  The FMU's log messages go to stderr.  Exit status: 0 success, 1 usage, 2 the library or a symbol
 * cannot be loaded, 3 an FMI call returned an error.
 */
#include "fmi3FunctionTypes.h"
#include "host_util.h"

static void log_message(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category, fmi3String message)
{
    (void)env;
    fprintf(stderr, "status=%d category=%s: %s\n", (int)status, category ? category : "", message ? message : "");
}

int main(int argc, char **argv)
{
    if (argc < 9) {
        fprintf(stderr, "usage: %s LIBRARY TOKEN RESOURCE_PATH STEP NSTEPS INPUT_FILE IN_VRS OUT_VRS [VR=VALUE ...]"
                " [@K]\n", argv[0]);
        return 1;
    }
    const char *library = argv[1], *token = argv[2], *resources = argv[3];
    double step = strtod(argv[4], NULL);
    long nsteps = strtol(argv[5], NULL, 10);
    const char *input_file = argv[6];
    fmi3ValueReference *in_vrs, *out_vrs;
    size_t *in_sizes, *out_sizes, n_in_values, n_out_values;
    size_t n_in = parse_vrs(argv[7], &in_vrs, &in_sizes, &n_in_values);
    size_t n_out = parse_vrs(argv[8], &out_vrs, &out_sizes, &n_out_values);

    void *lib = dlopen(library, RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        fprintf(stderr, "cannot load %s: %s\n", library, dlerror());
        return 2;
    }
    fmi3InstantiateCoSimulationTYPE *instantiate = (fmi3InstantiateCoSimulationTYPE *)symbol(
        lib, "fmi3InstantiateCoSimulation");
    fmi3FreeInstanceTYPE *freeInstance = (fmi3FreeInstanceTYPE *)symbol(lib, "fmi3FreeInstance");
    fmi3EnterInitializationModeTYPE *enterInit = (fmi3EnterInitializationModeTYPE *)symbol(
        lib, "fmi3EnterInitializationMode");
    fmi3ExitInitializationModeTYPE *exitInit = (fmi3ExitInitializationModeTYPE *)symbol(
        lib, "fmi3ExitInitializationMode");
    fmi3TerminateTYPE *terminate = (fmi3TerminateTYPE *)symbol(lib, "fmi3Terminate");
    fmi3SetFloat64TYPE *setFloat64 = (fmi3SetFloat64TYPE *)symbol(lib, "fmi3SetFloat64");
    fmi3GetFloat64TYPE *getFloat64 = (fmi3GetFloat64TYPE *)symbol(lib, "fmi3GetFloat64");
    fmi3DoStepTYPE *doStep = (fmi3DoStepTYPE *)symbol(lib, "fmi3DoStep");

    fmi3Instance c = instantiate("c_host3", token, resources, fmi3False, fmi3False, fmi3False, fmi3False, NULL, 0,
                                 NULL, log_message, NULL);
    if (!c) {
        fprintf(stderr, "fmi3InstantiateCoSimulation failed\n");
        return 3;
    }
    long checkpoint;
    unsigned *vrs = calloc((size_t)argc, sizeof *vrs);
    double *values = calloc((size_t)argc, sizeof *values);
    const int n_params = parse_params(argc, argv, 9, vrs, values, &checkpoint);
    if (n_params < 0) {
        freeInstance(c);
        return 1;
    }
    for (int i = 0; i < n_params; ++i) CHECK(setFloat64(c, vrs + i, 1, values + i, 1), "fmi3SetFloat64");
    free(vrs);
    free(values);
    CHECK(enterInit(c, fmi3False, 0.0, 0.0, fmi3False, 0.0), "fmi3EnterInitializationMode");
    CHECK(exitInit(c), "fmi3ExitInitializationMode");

    FILE *in = NULL;
    if (n_in > 0 && !(in = fopen(input_file, "r"))) {
        fprintf(stderr, "cannot open %s\n", input_file);
        freeInstance(c);
        return 1;
    }
    fmi3Float64 *u = calloc(n_in_values * (size_t)nsteps + 1, sizeof *u);   /* every input, for a replay */
    fmi3Float64 *y = calloc(n_out_values + 1, sizeof *y);
    fmi3Byte *saved = NULL;
    size_t saved_size = 0;
    fmi3Boolean event, stop, early;
    fmi3Float64 last;
    for (long k = 0; k < nsteps; ++k) {
        fmi3Float64 *uk = u + (size_t)k * n_in_values;
        for (size_t i = 0; i < n_in_values; ++i) {
            if (fscanf(in, "%lf", &uk[i]) != 1) {
                fprintf(stderr, "input file: not enough values at step %ld\n", k);
                freeInstance(c);
                return 1;
            }
        }
        if (k == checkpoint) {
            fmi3FMUState state = NULL;
            CHECK(((fmi3GetFMUStateTYPE *)symbol(lib, "fmi3GetFMUState"))(c, &state), "fmi3GetFMUState");
            CHECK(((fmi3SerializedFMUStateSizeTYPE *)symbol(lib, "fmi3SerializedFMUStateSize"))(c, state, &saved_size),
                  "fmi3SerializedFMUStateSize");
            saved = malloc(saved_size);
            CHECK(((fmi3SerializeFMUStateTYPE *)symbol(lib, "fmi3SerializeFMUState"))(c, state, saved, saved_size),
                  "fmi3SerializeFMUState");
            CHECK(((fmi3FreeFMUStateTYPE *)symbol(lib, "fmi3FreeFMUState"))(c, &state), "fmi3FreeFMUState");
        }
        if (n_in) CHECK(setFloat64(c, in_vrs, n_in, uk, n_in_values), "fmi3SetFloat64");
        if (n_out) CHECK(getFloat64(c, out_vrs, n_out, y, n_out_values), "fmi3GetFloat64");
        print_row("", y, n_out_values);
        CHECK(doStep(c, (double)k * step, step, fmi3True, &event, &stop, &early, &last), "fmi3DoStep");
    }
    if (saved) {                                  /* the replay from the deserialised checkpoint */
        fmi3FMUState state = NULL;
        CHECK(((fmi3DeserializeFMUStateTYPE *)symbol(lib, "fmi3DeserializeFMUState"))(c, saved, saved_size, &state),
              "fmi3DeserializeFMUState");
        CHECK(((fmi3SetFMUStateTYPE *)symbol(lib, "fmi3SetFMUState"))(c, state), "fmi3SetFMUState");
        CHECK(((fmi3FreeFMUStateTYPE *)symbol(lib, "fmi3FreeFMUState"))(c, &state), "fmi3FreeFMUState");
        for (long k = checkpoint; k < nsteps; ++k) {
            if (n_in) CHECK(setFloat64(c, in_vrs, n_in, u + (size_t)k * n_in_values, n_in_values), "fmi3SetFloat64");
            if (n_out) CHECK(getFloat64(c, out_vrs, n_out, y, n_out_values), "fmi3GetFloat64");
            print_row("R ", y, n_out_values);
            CHECK(doStep(c, (double)k * step, step, fmi3True, &event, &stop, &early, &last), "fmi3DoStep");
        }
        free(saved);
    }
    if (n_in && n_out) {                          /* derivatives at the last point */
        fmi3GetDirectionalDerivativeTYPE *directional = (fmi3GetDirectionalDerivativeTYPE *)symbol(
            lib, "fmi3GetDirectionalDerivative");
        fmi3GetAdjointDerivativeTYPE *adjoint = (fmi3GetAdjointDerivativeTYPE *)symbol(
            lib, "fmi3GetAdjointDerivative");
        fmi3Float64 one = 1.0, *ones = calloc(n_out_values, sizeof *ones), *sens = calloc(n_in_values, sizeof *sens);
        for (size_t i = 0; i < n_out_values; ++i) ones[i] = 1.0;
        printf("J\n");
        for (size_t j = 0; j < n_in; ++j) {
            CHECK(directional(c, out_vrs, n_out, &in_vrs[j], 1, &one, 1, y, n_out_values),
                  "fmi3GetDirectionalDerivative");
            print_row("", y, n_out_values);
        }
        CHECK(adjoint(c, out_vrs, n_out, in_vrs, n_in, ones, n_out_values, sens, n_in_values),
              "fmi3GetAdjointDerivative");
        print_row("A ", sens, n_in_values);
        free(ones);
        free(sens);
    }
    if (in) fclose(in);
    CHECK(terminate(c), "fmi3Terminate");
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
