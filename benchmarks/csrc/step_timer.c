/*
 * step_timer.c -- the cost of one co-simulation step of an FMU as a C master pays it, FMI 2.0 or 3.0.
 *
 * dlopens the FMU's binary, instantiates co-simulation, and per repeat initialises, then times NSTEPS steps of
 *   set the input, get the outputs, do one step of STEP seconds
 * (fmi2SetReal / fmi2GetReal / fmi2DoStep, or fmi3SetFloat64 / fmi3GetFloat64 / fmi3DoStep), then resets.  One
 * untimed repeat first.  Written against the standards' headers (as fmpy ships them: -I there).
 *
 * Usage:  step_timer 2|3 LIBRARY TOKEN STEP NSTEPS REPEATS IN_VR OUT_VR[,OUT_VR...]
 * Prints the mean ns per step of each timed repeat on one line.  Exit status 0, 1 usage, 2 loading, 3 an FMI
 * error.
 */
#define _POSIX_C_SOURCE 199309L
#include <dlfcn.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "fmi2FunctionTypes.h"
#include "fmi3FunctionTypes.h"

static void *symbol(void *lib, const char *name)
{
    void *p = dlsym(lib, name);
    if (!p) {
        fprintf(stderr, "missing symbol %s\n", name);
        exit(2);
    }
    return p;
}

static void logger2(fmi2ComponentEnvironment e, fmi2String n, fmi2Status s, fmi2String c, fmi2String m, ...)
{
    (void)e; (void)n; (void)s; (void)c;
    fprintf(stderr, "%s\n", m);
}

static void logger3(fmi3InstanceEnvironment e, fmi3Status s, fmi3String c, fmi3String m)
{
    (void)e; (void)s; (void)c;
    fprintf(stderr, "%s\n", m);
}

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

int main(int argc, char **argv)
{
    if (argc != 9) {
        fprintf(stderr, "usage: %s 2|3 LIBRARY TOKEN STEP NSTEPS REPEATS IN_VR OUT_VRS\n", argv[0]);
        return 1;
    }
    const int version = atoi(argv[1]);
    const double step = strtod(argv[4], NULL);
    const long nsteps = strtol(argv[5], NULL, 10);
    const int repeats = atoi(argv[6]);
    unsigned in_vr = (unsigned)strtoul(argv[7], NULL, 10), out_vr[64];
    size_t n_out = 0;
    for (char *p = argv[8]; *p && n_out < 64; p += (*p == ',')) out_vr[n_out++] = (unsigned)strtoul(p, &p, 10);
    void *lib = dlopen(argv[2], RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        fprintf(stderr, "cannot load %s: %s\n", argv[2], dlerror());
        return 2;
    }
    double y[64], u;
    if (version == 2) {
        fmi2CallbackFunctions cb = {logger2, calloc, free, NULL, NULL};
        fmi2Component c = ((fmi2InstantiateTYPE *)symbol(lib, "fmi2Instantiate"))("t", fmi2CoSimulation, argv[3],
                                                                                 "", &cb, fmi2False, fmi2False);
        fmi2SetRealTYPE *set = (fmi2SetRealTYPE *)symbol(lib, "fmi2SetReal");
        fmi2GetRealTYPE *get = (fmi2GetRealTYPE *)symbol(lib, "fmi2GetReal");
        fmi2DoStepTYPE *doStep = (fmi2DoStepTYPE *)symbol(lib, "fmi2DoStep");
        if (!c) return 3;
        for (int rep = 0; rep <= repeats; ++rep) {
            ((fmi2SetupExperimentTYPE *)symbol(lib, "fmi2SetupExperiment"))(c, fmi2False, 0.0, 0.0, fmi2False, 0.0);
            ((fmi2EnterInitializationModeTYPE *)symbol(lib, "fmi2EnterInitializationMode"))(c);
            if (((fmi2ExitInitializationModeTYPE *)symbol(lib, "fmi2ExitInitializationMode"))(c) > fmi2Warning)
                return 3;
            const double start = now();
            for (long k = 0; k < nsteps; ++k) {
                u = sin(0.01 * (double)k);
                set(c, &in_vr, 1, &u);
                get(c, out_vr, n_out, y);
                if (doStep(c, (double)k * step, step, fmi2True) > fmi2Warning) return 3;
            }
            const double elapsed = now() - start;
            if (rep > 0) printf(rep > 1 ? " %.3f" : "%.3f", elapsed / (double)nsteps * 1e9);
            ((fmi2ResetTYPE *)symbol(lib, "fmi2Reset"))(c);
        }
        ((fmi2FreeInstanceTYPE *)symbol(lib, "fmi2FreeInstance"))(c);
    } else {
        fmi3Instance c = ((fmi3InstantiateCoSimulationTYPE *)symbol(lib, "fmi3InstantiateCoSimulation"))(
            "t", argv[3], "", fmi3False, fmi3False, fmi3False, fmi3False, NULL, 0, NULL, logger3, NULL);
        fmi3SetFloat64TYPE *set = (fmi3SetFloat64TYPE *)symbol(lib, "fmi3SetFloat64");
        fmi3GetFloat64TYPE *get = (fmi3GetFloat64TYPE *)symbol(lib, "fmi3GetFloat64");
        fmi3DoStepTYPE *doStep = (fmi3DoStepTYPE *)symbol(lib, "fmi3DoStep");
        fmi3Boolean event, stop, early;
        fmi3Float64 last;
        if (!c) return 3;
        for (int rep = 0; rep <= repeats; ++rep) {
            ((fmi3EnterInitializationModeTYPE *)symbol(lib, "fmi3EnterInitializationMode"))(c, fmi3False, 0.0, 0.0,
                                                                                           fmi3False, 0.0);
            if (((fmi3ExitInitializationModeTYPE *)symbol(lib, "fmi3ExitInitializationMode"))(c) > fmi3Warning)
                return 3;
            const double start = now();
            for (long k = 0; k < nsteps; ++k) {
                u = sin(0.01 * (double)k);
                set(c, &in_vr, 1, &u, 1);
                get(c, out_vr, n_out, y, n_out);
                if (doStep(c, (double)k * step, step, fmi3True, &event, &stop, &early, &last) > fmi3Warning)
                    return 3;
            }
            const double elapsed = now() - start;
            if (rep > 0) printf(rep > 1 ? " %.3f" : "%.3f", elapsed / (double)nsteps * 1e9);
            ((fmi3ResetTYPE *)symbol(lib, "fmi3Reset"))(c);
        }
        ((fmi3FreeInstanceTYPE *)symbol(lib, "fmi3FreeInstance"))(c);
    }
    printf("\n");
    return 0;
}
