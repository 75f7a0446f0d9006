/* Cost of one internal RK4 step inside fmi2DoStep against a bare C loop of the same right-hand side.
 *
 *   bench_<Model> FMU.so both STEPS    time ratio, FMU / bare, interleaved repeats in one run
 *   bench_<Model> FMU.so fmu STEPS     only the FMU path   (for instruction counts under callgrind)
 *   bench_<Model> FMU.so bare STEPS    only the bare loop
 *
 * The bare loop is textbook RK4 calling the model's model_derivatives, linked from the same
 * physics.c the FMU is built from. The FMU runs all STEPS internal steps inside one fmi2DoStep,
 * so the cost per step is the integrator engine's, not the FMI call's. */
#define _POSIX_C_SOURCE 200809L
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define MODEL_DESCRIPTION_TABLES
#include "framework.h"

#define STEP 1e-3

typedef struct {
    fmi2Component (*instantiate)(fmi2String, fmi2Type, fmi2String, fmi2String, const fmi2CallbackFunctions *,
                                 fmi2Boolean, fmi2Boolean);
    fmi2Status (*set_integer)(fmi2Component, const fmi2ValueReference[], size_t, const fmi2Integer[]);
    fmi2Status (*set_real)(fmi2Component, const fmi2ValueReference[], size_t, const fmi2Real[]);
    fmi2Status (*get_real)(fmi2Component, const fmi2ValueReference[], size_t, fmi2Real[]);
    fmi2Status (*enter_init)(fmi2Component);
    fmi2Status (*exit_init)(fmi2Component);
    fmi2Status (*do_step)(fmi2Component, fmi2Real, fmi2Real, fmi2Boolean);
    void (*free_instance)(fmi2Component);
} Api;

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                   fmi2String message, ...)
{
    (void)env, (void)status, (void)category;
    fprintf(stderr, "%s: %s\n", name, message);
}

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

static void *symbol(void *lib, const char *name)
{
    void *p = dlsym(lib, name);
    if (!p) {
        fprintf(stderr, "missing symbol %s\n", name);
        exit(2);
    }
    return p;
}

/* Returns the seconds spent in fmi2DoStep; the final first state goes to *result. */
static double run_fmu(const Api *api, long steps, double *result)
{
    static const fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};
    const fmi2ValueReference solver_vr = VR_solver, h_vr = VR_h, x0_vr = 0;
    const fmi2Integer rk4 = SOLVER_RK4;
    const fmi2Real h = STEP;
    fmi2Component c = api->instantiate("bench", fmi2CoSimulation, MODEL_GUID, "", &callbacks, fmi2False, fmi2False);
    double t0, t1;
    if (!c || api->set_integer(c, &solver_vr, 1, &rk4) || api->set_real(c, &h_vr, 1, &h) || api->enter_init(c) ||
        api->exit_init(c)) {
        fprintf(stderr, "FMU setup failed\n");
        exit(2);
    }
    t0 = now();
    if (api->do_step(c, 0.0, steps * STEP, fmi2True) != fmi2OK) {
        fprintf(stderr, "fmi2DoStep failed\n");
        exit(2);
    }
    t1 = now();
    api->get_real(c, &x0_vr, 1, result);
    api->free_instance(c);
    return t1 - t0;
}

static double run_bare(long steps, double *result)
{
    double real[N_REAL], x[N_STATES], y[N_STATES], k1[N_STATES], k2[N_STATES], k3[N_STATES], k4[N_STATES];
    int32_t integer[INTEGER_SLOTS];
    ModelConst c;
    const double h = STEP;
    double t0, t1;
    long n;
    int i;
    for (i = 0; i < N_REAL; i++) real[i] = REAL_VARIABLES[i].start;
    for (i = 0; i < N_INTEGER; i++) integer[i] = (int32_t)INTEGER_VARIABLES[i].start;
    {
        char message[256];
        if (model_prepare(real, integer, &c, message, sizeof message)) {
            fprintf(stderr, "%s\n", message);
            exit(2);
        }
    }
    for (i = 0; i < N_STATES; i++) x[i] = real[i];
    t0 = now();
    for (n = 0; n < steps; n++) {
        model_derivatives(&c, 0.0, x, NULL, k1);
        for (i = 0; i < N_STATES; i++) y[i] = x[i] + 0.5 * h * k1[i];
        model_derivatives(&c, 0.0, y, NULL, k2);
        for (i = 0; i < N_STATES; i++) y[i] = x[i] + 0.5 * h * k2[i];
        model_derivatives(&c, 0.0, y, NULL, k3);
        for (i = 0; i < N_STATES; i++) y[i] = x[i] + h * k3[i];
        model_derivatives(&c, 0.0, y, NULL, k4);
        for (i = 0; i < N_STATES; i++) x[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
    }
    t1 = now();
    *result = x[0];
    return t1 - t0;
}

static int compare(const void *a, const void *b)
{
    const double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

int main(int argc, char **argv)
{
    Api api;
    void *lib;
    long steps;
    double fmu_result, bare_result;
    if (argc != 4) {
        fprintf(stderr, "usage: %s FMU_LIBRARY {both|fmu|bare} STEPS\n", argv[0]);
        return 2;
    }
    steps = atol(argv[3]);
    lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        fprintf(stderr, "cannot load %s: %s\n", argv[1], dlerror());
        return 2;
    }
    *(void **)&api.instantiate = symbol(lib, "fmi2Instantiate");
    *(void **)&api.set_integer = symbol(lib, "fmi2SetInteger");
    *(void **)&api.set_real = symbol(lib, "fmi2SetReal");
    *(void **)&api.get_real = symbol(lib, "fmi2GetReal");
    *(void **)&api.enter_init = symbol(lib, "fmi2EnterInitializationMode");
    *(void **)&api.exit_init = symbol(lib, "fmi2ExitInitializationMode");
    *(void **)&api.do_step = symbol(lib, "fmi2DoStep");
    *(void **)&api.free_instance = symbol(lib, "fmi2FreeInstance");

    if (strcmp(argv[2], "fmu") == 0) {
        run_fmu(&api, steps, &fmu_result);
        printf("%.17g\n", fmu_result);
    } else if (strcmp(argv[2], "bare") == 0) {
        run_bare(steps, &bare_result);
        printf("%.17g\n", bare_result);
    } else {
        enum { ROUNDS = 9 };
        double ratios[ROUNDS], fmu_times[ROUNDS], bare_times[ROUNDS];
        int r;
        for (r = 0; r < ROUNDS; r++) { /* alternate, so that machine noise hits both alike */
            fmu_times[r] = run_fmu(&api, steps, &fmu_result);
            bare_times[r] = run_bare(steps, &bare_result);
            ratios[r] = fmu_times[r] / bare_times[r];
        }
        qsort(ratios, ROUNDS, sizeof(double), compare);
        qsort(fmu_times, ROUNDS, sizeof(double), compare);
        qsort(bare_times, ROUNDS, sizeof(double), compare);
        printf("{\"model\": \"%s\", \"steps\": %ld, \"fmu_ns_per_step\": %.2f, \"bare_ns_per_step\": %.2f, "
               "\"median_ratio\": %.4f, \"same_result\": %s}\n",
               MODEL_IDENTIFIER_STRING, steps, 1e9 * fmu_times[ROUNDS / 2] / steps,
               1e9 * bare_times[ROUNDS / 2] / steps, ratios[ROUNDS / 2],
               fmu_result == bare_result ? "true" : "false");
    }
    dlclose(lib);
    return 0;
}
