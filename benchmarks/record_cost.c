/* What a recorded point costs against the internal step it holds, where the communication step is the
 * internal step (a user recording every step):
 *
 *   record_cost LIBRARY GUID SOLVER_VR SOLVER H_VR H OUTPUTS MODE N
 *
 * LIBRARY is an FMI 2.0 Co-Simulation binary, SOLVER the value given to the Integer variable SOLVER_VR,
 * H the value of the Real variable H_VR (the internal step), OUTPUTS a comma-separated list of the Real
 * value references recorded at each point. MODE:
 *   steps   N internal steps inside one fmi2DoStep (the steps' own cost)
 *   record  N points through the harness's C recorder (harness/fmi/native/record_loop.c): per point one
 *           fmi2DoStep of H and one fmi2GetReal of OUTPUTS
 *   both    both, interleaved repeats, medians as JSON (nanoseconds per step and per point)
 * The FMU's entry and exit work (state checks, outputs, getters) and the recorder's loop are what the
 * second costs more than the first. */
#define _POSIX_C_SOURCE 200809L
#include <dlfcn.h>
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

typedef struct {
    void *library;
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
    fmi2Component c =
        ((Instantiate)found(s->library, "fmi2Instantiate"))("record_cost", fmi2CoSimulation, s->guid, "", &callbacks, 0, 0);
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
    if (fmi_do_step(&calls, 0.0, (double)n * s->h) != FMI_OK) {
        fprintf(stderr, "record_cost: fmi2DoStep failed\n");
        exit(2);
    }
    seconds = now() - start;
    release(s, &calls);
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
    if (record_rows(&unit, grid, 0, 1, &done, &where) != FMI_OK) exit(2); /* the start's row */
    start = now();
    if (record_rows(&unit, grid, 1, n + 1, &done, &where) != FMI_OK) {
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
    if (argc != 10) {
        fprintf(stderr, "usage: record_cost LIBRARY GUID SOLVER_VR SOLVER H_VR H OUTPUTS {steps|record|both} N\n");
        return 2;
    }
    memset(&s, 0, sizeof s);
    s.library = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (!s.library) {
        fprintf(stderr, "record_cost: cannot load %s: %s\n", argv[1], dlerror());
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
    } else if (strcmp(mode, "both") == 0) {
        double steps[ROUNDS], points[ROUNDS], ratio[ROUNDS];
        int r;
        for (r = 0; r < ROUNDS; r++) { /* interleaved: the machine's noise falls on both alike */
            steps[r] = run_steps(&s, n);
            points[r] = run_record(&s, n);
            ratio[r] = points[r] / steps[r];
        }
        printf("{\"ns_per_step\": %.2f, \"ns_per_point\": %.2f, \"point_to_step\": %.3f}\n",
               1e9 * median(steps, ROUNDS) / (double)n, 1e9 * median(points, ROUNDS) / (double)n,
               median(ratio, ROUNDS));
    } else {
        fprintf(stderr, "record_cost: unknown mode %s: expected steps, record or both\n", mode);
        return 2;
    }
    dlclose(s.library);
    return 0;
}
