/* Cost of one internal RK4 step inside fmi2DoStep against textbook RK4 loops in plain C.
 *
 *   bench_<Model> FMU.so fmu STEPS        the FMU: STEPS internal steps in one fmi2DoStep
 *   bench_<Model> FMU.so generated STEPS  textbook RK4 over the generated model_derivatives
 *   bench_<Model> FMU.so bare STEPS       textbook RK4 over the hand-written right-hand side
 *   bench_<Model> FMU.so check N          hand-written against generated derivatives at N random
 *                                         states and parameters; exit 1 beyond 1e-12
 *   bench_<Model> FMU.so both STEPS       the check, then time ratios from interleaved repeats (JSON)
 *
 * The FMU runs all STEPS internal steps inside one fmi2DoStep, so the cost per step is the
 * integrator engine's, not the FMI call's. The generated right-hand side is linked from the same
 * physics.h the FMU is built from; the hand-written ones (handwritten_rhs.h) exist for the three
 * thesis pendulums only: for any other model, bare and check are refused and both times the FMU
 * against the generated loop alone. No force acts in any of the loops. */
#define _POSIX_C_SOURCE 200809L
#include <dlfcn.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define MODEL_DESCRIPTION_TABLES
#include "fmi2_api.h"
#include "framework.h"
#include "handwritten_rhs.h"
#include "median.h"

#define STEP 1e-3
#define CHECK_LIMIT 1e-12

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

/* A value the compiler cannot see through: parameters come at run time, as in the FMU, and are
 * not folded into the loops as constants. */
static double at_run_time(double value)
{
    volatile double v = value;
    return v;
}

/* The variables at their start values, as the FMU has them after instantiation. */
static void start_values(double *real, int32_t *integer)
{
    int i;
    for (i = 0; i < N_REAL; i++) real[i] = at_run_time(REAL_VARIABLES[i].start);
    for (i = 0; i < N_INTEGER; i++) integer[i] = (int32_t)INTEGER_VARIABLES[i].start;
}

static void prepare_generated(const double *real, const int32_t *integer, ModelConst *c)
{
    char message[256];
#if N_CONSTRAINTS > 0
    static const int32_t none_active = 0; /* the loops here locate no events: the free motion */
#endif
    if (model_prepare(real, integer, c, message, sizeof message)) {
        fprintf(stderr, "%s\n", message);
        exit(2);
    }
#if N_CONSTRAINTS > 0
    c->active = &none_active;
#endif
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

/* The textbook RK4 loop, written out once per right-hand side (a macro rather than a function
 * pointer, so that each right-hand side is inlined as it would be in a program of its own). The
 * stage times matter for a driven (rheonomic) model: t_n = n h, t_n + h/2, t_n + h. */
#define TEXTBOOK_RK4(RHS, steps, x) \
    do { \
        double y_[N_STATES], k1_[N_STATES], k2_[N_STATES], k3_[N_STATES], k4_[N_STATES]; \
        const double h_ = STEP; \
        long n_; \
        int i_; \
        for (n_ = 0; n_ < (steps); n_++) { \
            const double t_ = (double)n_ * h_; \
            RHS(t_, x, k1_); \
            for (i_ = 0; i_ < N_STATES; i_++) y_[i_] = x[i_] + 0.5 * h_ * k1_[i_]; \
            RHS(t_ + 0.5 * h_, y_, k2_); \
            for (i_ = 0; i_ < N_STATES; i_++) y_[i_] = x[i_] + 0.5 * h_ * k2_[i_]; \
            RHS(t_ + 0.5 * h_, y_, k3_); \
            for (i_ = 0; i_ < N_STATES; i_++) y_[i_] = x[i_] + h_ * k3_[i_]; \
            RHS(t_ + h_, y_, k4_); \
            for (i_ = 0; i_ < N_STATES; i_++) x[i_] += h_ / 6.0 * (k1_[i_] + 2.0 * k2_[i_] + 2.0 * k3_[i_] + k4_[i_]); \
        } \
    } while (0)

static double run_generated(long steps, double *result)
{
    double real[N_REAL], x[N_STATES];
    int32_t integer[INTEGER_SLOTS];
    ModelConst c;
    double t0, t1;
    start_values(real, integer);
    prepare_generated(real, integer, &c);
    memcpy(x, real, sizeof x);
    t0 = now();
#define GENERATED_RHS(time, state, dx) model_derivatives(&c, time, state, NULL, dx)
    TEXTBOOK_RK4(GENERATED_RHS, steps, x);
#undef GENERATED_RHS
    t1 = now();
    *result = x[0];
    return t1 - t0;
}

#ifdef HAVE_HANDWRITTEN_RHS
static double run_bare(long steps, double *result)
{
    double real[N_REAL], x[N_STATES];
    int32_t integer[INTEGER_SLOTS];
    HandConst c;
    double t0, t1;
    start_values(real, integer);
    hand_prepare(real, &c);
    memcpy(x, real, sizeof x);
    t0 = now();
#define HAND_RHS(time, state, dx) ((void)(time), hand_rhs(&c, state, dx)) /* the thesis pendulums: autonomous */
    TEXTBOOK_RK4(HAND_RHS, steps, x);
#undef HAND_RHS
    t1 = now();
    *result = x[0];
    return t1 - t0;
}

/* xorshift64*: a fixed, reproducible sequence of uniform numbers in [0, 1). */
static double uniform(uint64_t *s)
{
    *s ^= *s >> 12;
    *s ^= *s << 25;
    *s ^= *s >> 27;
    return (double)((*s * 0x2545F4914F6CDD1DULL) >> 11) * 0x1.0p-53;
}

/* Largest difference of hand-written and generated derivatives over n random states, each with its
 * own parameters (every parameter its default times 0.5 ... 2, the damping d in [0, 1], so that
 * the damping convention is compared too). Normwise relative, max |hand - generated| / max
 * |generated| per state: an acceleration that nearly cancels (terms of 100, sum of 0.1) carries the
 * rounding of its terms, which a componentwise ratio would blow up. */
static double check_against_generated(long n)
{
    uint64_t seed = 0x9E3779B97F4A7C15ULL;
    double worst = 0.0;
    long trial;
    int i;
    for (trial = 0; trial < n; trial++) {
        double real[N_REAL], x[N_STATES], generated[N_STATES], hand[N_STATES];
        int32_t integer[INTEGER_SLOTS];
        ModelConst gc;
        HandConst hc;
        start_values(real, integer);
        for (i = N_STATES; i < N_REAL; i++)
            if (REAL_VARIABLES[i].causality == CAUSALITY_PARAMETER && i != VR_h && i != VR_tol)
                real[i] *= 0.5 + 1.5 * uniform(&seed);
        real[VR_d] = uniform(&seed);
        for (i = 0; i < N_STATES; i++) x[i] = HAND_SAMPLE_RANGE[i] * (2.0 * uniform(&seed) - 1.0);
        prepare_generated(real, integer, &gc);
        hand_prepare(real, &hc);
        model_derivatives(&gc, 0.0, x, NULL, generated);
        hand_rhs(&hc, x, hand);
        {
            double difference = 0.0, scale = 0.0;
            for (i = 0; i < N_STATES; i++) {
                const double e = fabs(hand[i] - generated[i]);
                if (!(e <= difference)) difference = e; /* NaN on either side wins */
                if (fabs(generated[i]) > scale) scale = fabs(generated[i]);
            }
            difference /= scale;
            if (!(difference <= worst)) worst = difference;
        }
    }
    return worst;
}
#endif

/* Interleaved repeats of every loop, so that machine noise hits all alike; medians as JSON. */
static void time_all(const Api *api, long steps)
{
    enum { ROUNDS = 9 };
    double fmu[ROUNDS], generated[ROUNDS], to_generated[ROUNDS], result;
    int r;
#ifdef HAVE_HANDWRITTEN_RHS
    double bare[ROUNDS], to_bare[ROUNDS];
    const double worst = check_against_generated(1000);
    if (!(worst <= CHECK_LIMIT)) {
        fprintf(stderr, "hand-written and generated derivatives differ by %.3g (> %g)\n", worst, CHECK_LIMIT);
        exit(1);
    }
#endif
    for (r = 0; r < ROUNDS; r++) {
        fmu[r] = run_fmu(api, steps, &result);
        generated[r] = run_generated(steps, &result);
        to_generated[r] = fmu[r] / generated[r];
#ifdef HAVE_HANDWRITTEN_RHS
        bare[r] = run_bare(steps, &result);
        to_bare[r] = fmu[r] / bare[r];
#endif
    }
    printf("{\"model\": \"%s\", \"steps\": %ld, \"fmu_ns_per_step\": %.2f, \"generated_ns_per_step\": %.2f, "
           "\"fmu_to_generated\": %.4f",
           MODEL_IDENTIFIER_STRING, steps, 1e9 * median(fmu, ROUNDS) / steps, 1e9 * median(generated, ROUNDS) / steps,
           median(to_generated, ROUNDS));
#ifdef HAVE_HANDWRITTEN_RHS
    printf(", \"bare_ns_per_step\": %.2f, \"fmu_to_bare\": %.4f, \"rhs_difference\": %.3g",
           1e9 * median(bare, ROUNDS) / steps, median(to_bare, ROUNDS), worst);
#endif
    printf("}\n");
}

int main(int argc, char **argv)
{
    Api api;
    void *lib;
    long steps;
    double result;
    const char *mode;
    if (argc != 4) {
        fprintf(stderr, "usage: %s FMU_LIBRARY {fmu|generated|bare|check|both} STEPS\n", argv[0]);
        return 2;
    }
    mode = argv[2];
    steps = atol(argv[3]);
#ifndef HAVE_HANDWRITTEN_RHS
    if (strcmp(mode, "bare") == 0 || strcmp(mode, "check") == 0) {
        fprintf(stderr, "%s has no hand-written right-hand side (only the three thesis pendulums have one)\n",
                MODEL_IDENTIFIER_STRING);
        return 3;
    }
#endif
    if (strcmp(mode, "generated") == 0) {
        run_generated(steps, &result);
        printf("%.17g\n", result);
        return 0;
    }
#ifdef HAVE_HANDWRITTEN_RHS
    if (strcmp(mode, "bare") == 0) {
        run_bare(steps, &result);
        printf("%.17g\n", result);
        return 0;
    }
    if (strcmp(mode, "check") == 0) {
        const double worst = check_against_generated(steps);
        printf("%s: hand-written against generated derivatives at %ld random states: largest relative difference "
               "%.3g\n",
               MODEL_IDENTIFIER_STRING, steps, worst);
        return worst <= CHECK_LIMIT ? 0 : 1;
    }
#endif
    if (strcmp(mode, "fmu") != 0 && strcmp(mode, "both") != 0) {
        fprintf(stderr, "unknown mode %s: expected fmu, generated, bare, check or both\n", mode);
        return 2;
    }
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
    if (strcmp(mode, "fmu") == 0) {
        run_fmu(&api, steps, &result);
        printf("%.17g\n", result);
    } else {
        time_all(&api, steps);
    }
    dlclose(lib);
    return 0;
}
