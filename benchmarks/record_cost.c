/* What a recorded point costs against the internal step it holds, where the communication step is the
 * internal step (a user recording every step):
 *
 *   record_cost LIBRARY GUID SOLVER_VR SOLVER H_VR H OUTPUTS MODE N [LIBRARY3]
 *
 * LIBRARY is an FMI 2.0 Co-Simulation binary, SOLVER the value given to the Integer variable SOLVER_VR,
 * H the value of the Real variable H_VR (the internal step), OUTPUTS a comma-separated list of the Real
 * value references recorded at each point. MODE:
 *   steps   N internal steps inside one fmi2DoStep (the steps' own cost)
 *   record  N points through the harness's C recorder (harness/fmi/native/record_loop.c): per point one
 *           fmi2DoStep of H and one fmi2GetReal of OUTPUTS
 *   reported N internal steps inside one fmi3DoStep of LIBRARY3 (the object's FMI 3.0 binary), each reported
 *           through the intermediate-update callback, which reads OUTPUTS with fmi3GetFloat64 into a row
 *   both    steps and record (and reported where LIBRARY3 is given), interleaved repeats, medians as JSON
 *           (nanoseconds per step, per point and per reported step)
 * The FMU's entry and exit work (state checks, outputs, getters) and the recorder's loop are what a
 * point costs more than a step; a reported step costs the check, the outputs and the getter of each step. */
#define _POSIX_C_SOURCE 200809L
#include <dlfcn.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "fmi2_api.h"
#include "median.h"
#include "record_loop.h"

#define MAX_OUTPUTS 64
#define ROUNDS 9

typedef fmi2Component (*Instantiate)(fmi2String, fmi2Type, fmi2String, fmi2String, const fmi2CallbackFunctions *,
                                     fmi2Boolean, fmi2Boolean);
typedef fmi2Status (*SetInteger)(fmi2Component, const fmi2ValueReference[], size_t, const fmi2Integer[]);
typedef fmi2Status (*Call)(fmi2Component);
typedef void (*FreeInstance)(fmi2Component);

/* FMI 3.0's calls for the reported mode, in plain C types */
typedef void (*IntermediateUpdate3)(void *, double, bool, bool, bool, bool, bool *, double *);
typedef void *(*Instantiate3)(const char *, const char *, const char *, bool, bool, bool, bool, const unsigned *,
                              size_t, void *, void (*)(void *, int, const char *, const char *), IntermediateUpdate3);
typedef int (*SetInt64)(void *, const unsigned *, size_t, const long long *, size_t);
typedef int (*EnterInitialization3)(void *, bool, double, double, bool, double);
typedef int (*Call3)(void *);

typedef struct {
    void *library;
    void *library3; /* the FMI 3.0 binary, NULL where not given */
    const char *guid;
    unsigned solver_vr, h_vr, outputs[MAX_OUTPUTS];
    int solver, n_outputs;
    double h;
} Setting;

static void logger(fmi2ComponentEnvironment environment, fmi2String name, fmi2Status status, fmi2String category,
                   fmi2String message, ...)
{
    (void)environment, (void)category;
    fprintf(stderr, "%s [%d]: %s\n", name, status, message);
}

static void *found(void *library, const char *name)
{
    void *address = dlsym(library, name);
    if (!address) {
        fprintf(stderr, "record_cost: the library exports no %s\n", name);
        exit(2);
    }
    return address;
}

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

/* An instance at t = 0 with the setting's method and step, its calls in the recorder's shape. */
static FmiCalls initialized(const Setting *s)
{
    static const fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};
    FmiCalls calls;
    fmi2Component c = ((Instantiate)found(s->library, "fmi2Instantiate"))("record_cost", fmi2CoSimulation, s->guid, "",
                                                                          &callbacks, 0, 0);
    if (!c || ((SetInteger)found(s->library, "fmi2SetInteger"))(c, &s->solver_vr, 1, &s->solver) ||
        ((SetReal2)found(s->library, "fmi2SetReal"))(c, &s->h_vr, 1, &s->h) ||
        ((Call)found(s->library, "fmi2EnterInitializationMode"))(c) ||
        ((Call)found(s->library, "fmi2ExitInitializationMode"))(c)) {
        fprintf(stderr, "record_cost: the FMU's set-up failed\n");
        exit(2);
    }
    memset(&calls, 0, sizeof calls);
    calls.component = c;
    calls.get_float = found(s->library, "fmi2GetReal");
    calls.do_step = found(s->library, "fmi2DoStep");
    return calls;
}

static void release(const Setting *s, FmiCalls *calls)
{
    ((FreeInstance)found(s->library, "fmi2FreeInstance"))(calls->component);
}

/* Seconds of n internal steps in one fmi2DoStep. */
static double run_steps(const Setting *s, long n)
{
    FmiCalls calls = initialized(s);
    double start, seconds;
    start = now();
    if (fmi_do_step(&calls, 0.0, (double)n * s->h) != STATUS_OK) {
        fprintf(stderr, "record_cost: fmi2DoStep failed\n");
        exit(2);
    }
    seconds = now() - start;
    release(s, &calls);
    return seconds;
}

/* The reported mode's recorder: each accepted internal step's outputs into the next row. */
typedef struct {
    FmiCalls calls;
    const unsigned *outputs;
    int n_outputs, failed;
    double *rows;
    long row, capacity;
} Reporter;

static void report_row(void *environment, double t, bool set_requested, bool get_allowed, bool step_finished,
                       bool can_return_early, bool *early_return_requested, double *early_return_time)
{
    Reporter *r = environment;
    (void)t, (void)set_requested, (void)can_return_early, (void)early_return_time;
    *early_return_requested = false;
    if (!get_allowed || !step_finished) return;
    if (r->row == r->capacity) { /* more steps reported than taken */
        r->failed = 1;
        return;
    }
    r->failed |= fmi_get_floats(&r->calls, r->outputs, r->n_outputs, r->rows + r->row++ * r->n_outputs) != STATUS_OK;
}

static void logger3(void *environment, int status, const char *category, const char *message)
{
    (void)environment, (void)category;
    fprintf(stderr, "[%d]: %s\n", status, message);
}

/* Seconds of n internal steps inside one fmi3DoStep, each reported and its outputs read. */
static double run_reported(const Setting *s, long n)
{
    Reporter r;
    const long long solver = s->solver;
    double start, seconds, last = 0.0;
    void *c;
    memset(&r, 0, sizeof r);
    r.outputs = s->outputs;
    r.n_outputs = s->n_outputs;
    r.capacity = n;
    r.rows = malloc((size_t)(n + 1) * (size_t)s->n_outputs * sizeof *r.rows);
    c = ((Instantiate3)found(s->library3, "fmi3InstantiateCoSimulation"))(
        "record_cost", s->guid, "", false, false, false, false, NULL, 0, &r, logger3, report_row);
    if (!r.rows || !c || ((SetInt64)found(s->library3, "fmi3SetInt64"))(c, &s->solver_vr, 1, &solver, 1) ||
        ((SetFloat3)found(s->library3, "fmi3SetFloat64"))(c, &s->h_vr, 1, &s->h, 1) ||
        ((EnterInitialization3)found(s->library3, "fmi3EnterInitializationMode"))(c, false, 0.0, 0.0, false, 0.0) ||
        ((Call3)found(s->library3, "fmi3ExitInitializationMode"))(c)) {
        fprintf(stderr, "record_cost: the FMI 3.0 FMU's set-up failed\n");
        exit(2);
    }
    r.calls.component = c;
    r.calls.fmi3 = 1;
    r.calls.get_float = found(s->library3, "fmi3GetFloat64");
    r.calls.do_step = found(s->library3, "fmi3DoStep");
    r.calls.last_time = &last;
    start = now();
    if (fmi_do_step(&r.calls, 0.0, (double)n * s->h) != STATUS_OK || r.failed || r.row != n) {
        fprintf(stderr, "record_cost: fmi3DoStep reported %ld of %ld steps\n", r.row, n);
        exit(2);
    }
    seconds = now() - start;
    ((void (*)(void *))found(s->library3, "fmi3FreeInstance"))(c);
    free(r.rows);
    return seconds;
}

/* Seconds of n recorded points after the first, one internal step each. */
static double run_record(const Setting *s, long n)
{
    RecordUnit unit;
    double *grid = malloc((size_t)(n + 1) * sizeof *grid), *rows = malloc((size_t)(n + 1) * MAX_OUTPUTS * sizeof *rows);
    double start, seconds;
    long i, done;
    int where;
    if (!grid || !rows) {
        fprintf(stderr, "record_cost: out of memory for %ld points\n", n);
        exit(2);
    }
    for (i = 0; i <= n; i++) grid[i] = (double)i * s->h;
    memset(&unit, 0, sizeof unit);
    unit.calls = initialized(s);
    unit.n_real = s->n_outputs;
    unit.real_vrs = s->outputs;
    unit.reals = (char *)rows;
    unit.real_stride = (long)(s->n_outputs * sizeof *rows);
    if (record_rows(&unit, grid, 0, 1, &done, &where) != STATUS_OK) exit(2); /* the start's row */
    start = now();
    if (record_rows(&unit, grid, 1, n + 1, &done, &where) != STATUS_OK) {
        fprintf(stderr, "record_cost: the recorder stopped at point %ld\n", done);
        exit(2);
    }
    seconds = now() - start;
    release(s, &unit.calls);
    free(grid);
    free(rows);
    return seconds;
}

int main(int argc, char **argv)
{
    Setting s;
    const char *mode;
    char *cursor;
    long n;
    if (argc != 10 && argc != 11) {
        fprintf(stderr,
                "usage: record_cost LIBRARY GUID SOLVER_VR SOLVER H_VR H OUTPUTS {steps|record|reported|both} N "
                "[LIBRARY3]\n");
        return 2;
    }
    memset(&s, 0, sizeof s);
    s.library = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (!s.library) {
        fprintf(stderr, "record_cost: cannot load %s: %s\n", argv[1], dlerror());
        return 2;
    }
    if (argc == 11 && !(s.library3 = dlopen(argv[10], RTLD_NOW | RTLD_LOCAL))) {
        fprintf(stderr, "record_cost: cannot load %s: %s\n", argv[10], dlerror());
        return 2;
    }
    s.guid = argv[2];
    s.solver_vr = (unsigned)strtoul(argv[3], NULL, 10);
    s.solver = atoi(argv[4]);
    s.h_vr = (unsigned)strtoul(argv[5], NULL, 10);
    s.h = strtod(argv[6], NULL);
    for (cursor = argv[7]; *cursor && s.n_outputs < MAX_OUTPUTS; cursor += *cursor == ',')
        s.outputs[s.n_outputs++] = (unsigned)strtoul(cursor, &cursor, 10);
    mode = argv[8];
    n = atol(argv[9]);
    if (!(s.h > 0.0) || n < 1) {
        fprintf(stderr, "record_cost: H and N must be positive\n");
        return 2;
    }
    if (strcmp(mode, "steps") == 0) {
        run_steps(&s, n);
    } else if (strcmp(mode, "record") == 0) {
        run_record(&s, n);
    } else if (strcmp(mode, "reported") == 0 && s.library3) {
        run_reported(&s, n);
    } else if (strcmp(mode, "both") == 0) {
        double steps[ROUNDS], points[ROUNDS], ratio[ROUNDS], reported[ROUNDS], reported_ratio[ROUNDS];
        int r;
        for (r = 0; r < ROUNDS; r++) { /* interleaved: the machine's noise falls on all alike */
            steps[r] = run_steps(&s, n);
            points[r] = run_record(&s, n);
            ratio[r] = points[r] / steps[r];
            reported[r] = s.library3 ? run_reported(&s, n) : 0.0;
            reported_ratio[r] = reported[r] / steps[r];
        }
        printf("{\"ns_per_step\": %.2f, \"ns_per_point\": %.2f, \"point_to_step\": %.3f",
               1e9 * median(steps, ROUNDS) / (double)n, 1e9 * median(points, ROUNDS) / (double)n,
               median(ratio, ROUNDS));
        if (s.library3)
            printf(", \"ns_per_reported\": %.2f, \"reported_to_step\": %.3f",
                   1e9 * median(reported, ROUNDS) / (double)n, median(reported_ratio, ROUNDS));
        printf("}\n");
    } else {
        fprintf(stderr, "record_cost: unknown mode %s: expected steps, record, both or (with LIBRARY3) reported\n",
                mode);
        return 2;
    }
    if (s.library3) dlclose(s.library3);
    dlclose(s.library);
    return 0;
}
