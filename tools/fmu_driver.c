/* A minimal Co-Simulation importer, compiled for every platform the FMUs carry binaries for, so that
 * each binary runs where it was built for (Windows DLLs under Wine, aarch64 under qemu-user) and its
 * numbers can be compared with the x86_64 Linux binary's.
 *
 *   fmu_driver LIBRARY VERSION TOKEN STOP STEP OUTPUTS [real:VR=VALUE | int:VR=VALUE]...
 *   fmu_driver --jobs < JOBS      one such argument list per line of JOBS, run one after the other
 *                                 (one process: under Wine or qemu its start costs more than a run)
 *
 * VERSION is 2 or 3, OUTPUTS a comma-separated list of Real value references. Prints one line per
 * communication point: the time and the outputs as the 16 hexadecimal digits of their IEEE 754 bits
 * (exact, and the same text from every C runtime's printf), then the status of the run. Exit code 0 when every call returned OK, 1 otherwise, 2 for bad arguments. */
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef _WIN32
#include <windows.h>
typedef HMODULE Library;
static Library open_library(const char *path) { return LoadLibraryA(path); }
static void *symbol(Library library, const char *name) { return (void *)GetProcAddress(library, name); }
#else
#include <dlfcn.h>
typedef void *Library;
static Library open_library(const char *path) { return dlopen(path, RTLD_NOW | RTLD_LOCAL); }
static void *symbol(Library library, const char *name) { return dlsym(library, name); }
#endif

#define MAX_OUTPUTS 256

/* The few FMI types and signatures the driver calls (FMI 2.0 and 3.0 Co-Simulation). */
typedef void *Component;
typedef struct {
    void (*logger)(void *, const char *, int, const char *, const char *, ...);
    void *(*allocate)(size_t, size_t);
    void (*release)(void *);
    void (*step_finished)(void *, int);
    void *environment;
} Fmi2Callbacks;
typedef Component (*Fmi2Instantiate)(const char *, int, const char *, const char *, const Fmi2Callbacks *, int, int);
typedef int (*Fmi2Setup)(Component, int, double, double, int, double);
typedef int (*Fmi2Call)(Component);
typedef int (*Fmi2SetReal)(Component, const unsigned int *, size_t, const double *);
typedef int (*Fmi2SetInteger)(Component, const unsigned int *, size_t, const int *);
typedef int (*Fmi2DoStep)(Component, double, double, int);
typedef void (*FreeInstance)(Component);
typedef void (*Fmi3Logger)(void *, int, const char *, const char *);
typedef Component (*Fmi3Instantiate)(const char *, const char *, const char *, int, int, int, int, const unsigned int *,
                                     size_t, void *, Fmi3Logger, void *);
typedef int (*Fmi3EnterInitialization)(Component, int, double, double, int, double);
typedef int (*Fmi3SetFloat64)(Component, const unsigned int *, size_t, const double *, size_t);
typedef int (*Fmi3SetInt64)(Component, const unsigned int *, size_t, const int64_t *, size_t);
typedef int (*Fmi3DoStep)(Component, double, double, int, int *, int *, int *, double *);
typedef int (*Fmi2GetReal)(Component, const unsigned int *, size_t, double *);
typedef int (*Fmi3GetFloat64)(Component, const unsigned int *, size_t, double *, size_t);

static void logger2(void *environment, const char *name, int status, const char *category, const char *message, ...)
{
    (void)environment, (void)category;
    fprintf(stderr, "%s [%d]: %s\n", name, status, message);
}

static void logger3(void *environment, int status, const char *category, const char *message)
{
    (void)environment, (void)category;
    fprintf(stderr, "[%d]: %s\n", status, message);
}

static void print_bits(double value)
{
    static const char digits[] = "0123456789abcdef";
    char text[17];
    uint64_t bits;
    int i;
    memcpy(&bits, &value, sizeof bits);
    for (i = 15; i >= 0; i--, bits >>= 4) text[i] = digits[bits & 15u];
    text[16] = '\0';
    fputs(text, stdout);
}

static void *found(Library library, const char *name)
{
    void *address = symbol(library, name);
    if (!address) {
        fprintf(stderr, "fmu_driver: the library exports no %s\n", name);
        exit(2);
    }
    return address;
}

static int run(int argc, char **argv)
{
    unsigned int outputs[MAX_OUTPUTS];
    double values[MAX_OUTPUTS];
    size_t n_outputs = 0;
    Library library;
    Component c;
    int version, status = 0, i;
    double stop, step, t = 0.0;
    long k, n_steps;
    char *cursor;
    if (argc < 7) {
        fprintf(stderr, "usage: fmu_driver LIBRARY VERSION TOKEN STOP STEP OUTPUTS [real:VR=VALUE|int:VR=VALUE]...\n");
        return 2;
    }
    version = atoi(argv[2]);
    stop = strtod(argv[4], NULL);
    step = strtod(argv[5], NULL);
    for (cursor = argv[6]; *cursor && n_outputs < MAX_OUTPUTS; cursor += *cursor == ',') {
        outputs[n_outputs++] = (unsigned int)strtoul(cursor, &cursor, 10);
    }
    library = open_library(argv[1]);
    if (!library || (version != 2 && version != 3) || !(step > 0.0)) {
        fprintf(stderr, "fmu_driver: cannot load %s as FMI %d, or STEP is not positive\n", argv[1], version);
        return 2;
    }
    if (version == 2) {
        static Fmi2Callbacks callbacks = {logger2, calloc, free, NULL, NULL};
        c = ((Fmi2Instantiate)found(library, "fmi2Instantiate"))("driver", 1, argv[3], "", &callbacks, 0, 0);
        if (!c) return 1;
        status |= ((Fmi2Setup)found(library, "fmi2SetupExperiment"))(c, 0, 0.0, 0.0, 0, 0.0);
    } else {
        c = ((Fmi3Instantiate)found(library, "fmi3InstantiateCoSimulation"))("driver", argv[3], "", 0, 0, 0, 0, NULL, 0,
                                                                             NULL, logger3, NULL);
        if (!c) return 1;
    }
    for (i = 7; i < argc; i++) { /* start values, before initialization */
        const int is_real = strncmp(argv[i], "real:", 5) == 0;
        unsigned int vr = (unsigned int)strtoul(argv[i] + (is_real ? 5 : 4), &cursor, 10);
        if (*cursor != '=') return 2;
        if (is_real) {
            const double value = strtod(cursor + 1, NULL);
            status |= version == 2 ? ((Fmi2SetReal)found(library, "fmi2SetReal"))(c, &vr, 1, &value)
                                   : ((Fmi3SetFloat64)found(library, "fmi3SetFloat64"))(c, &vr, 1, &value, 1);
        } else {
            const int64_t value = strtoll(cursor + 1, NULL, 10);
            const int narrow = (int)value;
            status |= version == 2 ? ((Fmi2SetInteger)found(library, "fmi2SetInteger"))(c, &vr, 1, &narrow)
                                   : ((Fmi3SetInt64)found(library, "fmi3SetInt64"))(c, &vr, 1, &value, 1);
        }
    }
    if (version == 2) {
        status |= ((Fmi2Call)found(library, "fmi2EnterInitializationMode"))(c);
        status |= ((Fmi2Call)found(library, "fmi2ExitInitializationMode"))(c);
    } else {
        status |= ((Fmi3EnterInitialization)found(library, "fmi3EnterInitializationMode"))(c, 0, 0.0, 0.0, 0, 0.0);
        status |= ((Fmi2Call)found(library, "fmi3ExitInitializationMode"))(c);
    }
    n_steps = (long)(stop / step + 0.5);
    for (k = 0; k <= n_steps && status == 0; k++) {
        size_t j;
        if (k > 0) {
            const double t_next = (double)k * step; /* from the index: no accumulated rounding */
            if (version == 2) {
                status |= ((Fmi2DoStep)found(library, "fmi2DoStep"))(c, t, t_next - t, 1);
            } else {
                int event = 0, terminate = 0, early = 0;
                double reached = 0.0;
                status |= ((Fmi3DoStep)found(library, "fmi3DoStep"))(c, t, t_next - t, 1, &event, &terminate, &early,
                                                                     &reached);
            }
            t = t_next;
        }
        status |= version == 2
                      ? ((Fmi2GetReal)found(library, "fmi2GetReal"))(c, outputs, n_outputs, values)
                      : ((Fmi3GetFloat64)found(library, "fmi3GetFloat64"))(c, outputs, n_outputs, values, n_outputs);
        print_bits(t);
        for (j = 0; j < n_outputs; j++) {
            putchar(' ');
            print_bits(values[j]);
        }
        putchar('\n');
    }
    printf("status %d\n", status);
    ((FreeInstance)found(library, version == 2 ? "fmi2FreeInstance" : "fmi3FreeInstance"))(c);
    return status == 0 ? 0 : 1;
}

int main(int argc, char **argv)
{
    static char line[1 << 16];
    char *arguments[MAX_OUTPUTS];
    int worst = 0;
    if (argc != 2 || strcmp(argv[1], "--jobs") != 0) return run(argc, argv);
    while (fgets(line, sizeof line, stdin)) {
        int n = 1, result;
        char *token;
        arguments[0] = argv[0];
        for (token = strtok(line, " \t\r\n"); token && n < MAX_OUTPUTS; token = strtok(NULL, " \t\r\n"))
            arguments[n++] = token;
        if (n == 1) continue;
        result = run(n, arguments);
        fflush(stdout);
        if (result > worst) worst = result;
    }
    return worst;
}
