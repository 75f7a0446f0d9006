/* The coupled-pendulums scene (spring, left, right; Jacobi, inputs held) as a plain C loop of fmi2
 * calls: the floor any master in any language can reach with these FMUs.
 *
 *   coupled_native PENDULUM.so PENDULUM_GUID SPRING.so SPRING_GUID STEPS H VR... [record RECORDED...]
 *
 * VR: the value references (from the model descriptions) of, in this order:
 *   pendulum x y v_x v_y F_x F_y phi anchor_x h, spring a_x a_y a_vx a_vy b_x b_y b_vx b_vy Fa_x Fa_y Fb_x Fb_y k l0
 * With `record`, the loop makes the calls a master makes that records every output: per unit and
 * step one get of all its float outputs and one of its integer outputs, each written into a row of
 * a preallocated table. RECORDED is, in this order: the count and value references of the
 * pendulum's float outputs, the positions of x y v_x v_y among them, the count and value
 * references of its integer outputs, and the count and value references of the spring's float
 * outputs with the positions of Fa_x Fa_y Fb_x Fb_y among them.
 * Prints the seconds per macro step and the left bob's final x. */
#define _POSIX_C_SOURCE 200809L
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "fmi2_api.h"

typedef struct {
    fmi2Component c;
    void (*free_instance)(fmi2Component);
    fmi2Status (*set_real)(fmi2Component, const fmi2ValueReference[], size_t, const fmi2Real[]);
    fmi2Status (*get_real)(fmi2Component, const fmi2ValueReference[], size_t, fmi2Real[]);
    fmi2Status (*do_step)(fmi2Component, fmi2Real, fmi2Real, fmi2Boolean);
} Unit;

static void logger(fmi2ComponentEnvironment e, fmi2String n, fmi2Status s, fmi2String c, fmi2String m, ...)
{
    (void)e, (void)s, (void)c;
    fprintf(stderr, "%s: %s\n", n, m);
}

static Unit open_unit(const char *path, const char *guid, const char *name)
{
    static const fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};
    Unit u;
    void *lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    fmi2Component (*instantiate)(fmi2String, fmi2Type, fmi2String, fmi2String, const fmi2CallbackFunctions *,
                                 fmi2Boolean, fmi2Boolean);
    if (!lib) {
        fprintf(stderr, "%s\n", dlerror());
        exit(2);
    }
    *(void **)&instantiate = dlsym(lib, "fmi2Instantiate");
    *(void **)&u.set_real = dlsym(lib, "fmi2SetReal");
    *(void **)&u.get_real = dlsym(lib, "fmi2GetReal");
    *(void **)&u.do_step = dlsym(lib, "fmi2DoStep");
    *(void **)&u.free_instance = dlsym(lib, "fmi2FreeInstance");
    u.c = instantiate(name, fmi2CoSimulation, guid, "", &callbacks, fmi2False, fmi2False);
    if (!u.c) exit(2);
    return u;
}

#define MAX_RECORDED 64

typedef struct {
    int n_real, n_int, n_spring;
    fmi2ValueReference real[MAX_RECORDED], ints[MAX_RECORDED], spring[MAX_RECORDED];
    int bob[4], force[4];
} Recorded;

static int read_list(char **argv, int at, int argc, fmi2ValueReference *vrs, int *n)
{
    int i;
    if (at >= argc || (*n = atoi(argv[at])) < 0 || *n > MAX_RECORDED || at + 1 + *n > argc) {
        fprintf(stderr, "record: bad list at argument %d\n", at);
        exit(2);
    }
    for (i = 0; i < *n; i++) vrs[i] = (fmi2ValueReference)atoi(argv[at + 1 + i]);
    return at + 1 + *n;
}

static int read_positions(char **argv, int at, int argc, int *positions, int n_max)
{
    int i;
    for (i = 0; i < 4; i++) {
        if (at + i >= argc || (positions[i] = atoi(argv[at + i])) < 0 || positions[i] >= n_max) {
            fprintf(stderr, "record: bad position at argument %d\n", at + i);
            exit(2);
        }
    }
    return at + 4;
}

static void initialize(const char *path, fmi2Component c)
{
    void *lib = dlopen(path, RTLD_NOW | RTLD_LOCAL | RTLD_NOLOAD);
    fmi2Status (*enter)(fmi2Component), (*leave)(fmi2Component);
    *(void **)&enter = dlsym(lib, "fmi2EnterInitializationMode");
    *(void **)&leave = dlsym(lib, "fmi2ExitInitializationMode");
    if (enter(c) || leave(c)) exit(2);
}

int main(int argc, char **argv)
{
    Unit left, right, spring;
    fmi2ValueReference p_out[4], p_in[2], p_phi, p_anchor, p_h, s_in[8], s_out[4], s_k, s_l0;
    double left_out[4], right_out[4], spring_in[8], spring_out[4], force[2], value;
    long steps, k;
    double H, t0, t1;
    struct timespec ts;
    int i;
    Recorded rec = {0};
    int recording = argc > 30;
    double *table = NULL, *row;
    long row_length = 0;
    fmi2Status (*get_integer[3])(fmi2Component, const fmi2ValueReference[], size_t, fmi2Integer[]);
    if (argc < 7 + 9 + 14 || (recording && strcmp(argv[30], "record") != 0)) {
        fprintf(stderr, "usage: see the comment at the top of coupled_native.c\n");
        return 2;
    }
    steps = atol(argv[5]);
    H = atof(argv[6]);
    for (i = 0; i < 4; i++) p_out[i] = (fmi2ValueReference)atoi(argv[7 + i]);
    for (i = 0; i < 2; i++) p_in[i] = (fmi2ValueReference)atoi(argv[11 + i]);
    p_phi = (fmi2ValueReference)atoi(argv[13]);
    p_anchor = (fmi2ValueReference)atoi(argv[14]);
    p_h = (fmi2ValueReference)atoi(argv[15]);
    for (i = 0; i < 8; i++) s_in[i] = (fmi2ValueReference)atoi(argv[16 + i]);
    for (i = 0; i < 4; i++) s_out[i] = (fmi2ValueReference)atoi(argv[24 + i]);
    s_k = (fmi2ValueReference)atoi(argv[28]);
    s_l0 = (fmi2ValueReference)atoi(argv[29]);

    if (recording) {
        int at = read_list(argv, 31, argc, rec.real, &rec.n_real);
        at = read_positions(argv, at, argc, rec.bob, rec.n_real);
        at = read_list(argv, at, argc, rec.ints, &rec.n_int);
        at = read_list(argv, at, argc, rec.spring, &rec.n_spring);
        at = read_positions(argv, at, argc, rec.force, rec.n_spring);
        if (at != argc) {
            fprintf(stderr, "record: %d arguments left over\n", argc - at);
            return 2;
        }
        row_length = 1 + rec.n_spring + 2 * (rec.n_real + rec.n_int);
        table = malloc(sizeof(double) * row_length * (steps + 1));
        if (!table) return 2;
    }
    spring = open_unit(argv[3], argv[4], "spring");
    left = open_unit(argv[1], argv[2], "left");
    right = open_unit(argv[1], argv[2], "right");
    value = 0.5;
    left.set_real(left.c, &p_phi, 1, &value);
    value = 0.0;
    right.set_real(right.c, &p_phi, 1, &value);
    value = 1.5;
    right.set_real(right.c, &p_anchor, 1, &value);
    value = 0.001;
    left.set_real(left.c, &p_h, 1, &value);
    right.set_real(right.c, &p_h, 1, &value);
    value = 10.0;
    spring.set_real(spring.c, &s_k, 1, &value);
    value = 1.5;
    spring.set_real(spring.c, &s_l0, 1, &value);
    initialize(argv[3], spring.c);
    initialize(argv[1], left.c);
    initialize(argv[1], right.c);
    left.get_real(left.c, p_out, 4, left_out);
    right.get_real(right.c, p_out, 4, right_out);
    spring.get_real(spring.c, s_out, 4, spring_out);
    {
        void *lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL | RTLD_NOLOAD);
        *(void **)&get_integer[1] = dlsym(lib, "fmi2GetInteger");
        get_integer[2] = get_integer[1];
    }

    clock_gettime(CLOCK_MONOTONIC, &ts);
    t0 = ts.tv_sec + 1e-9 * ts.tv_nsec;
    for (k = 0; k < steps; k++) {
        const double t = k * H;
        for (i = 0; i < 4; i++) {
            spring_in[i] = left_out[i];
            spring_in[4 + i] = right_out[i];
        }
        spring.set_real(spring.c, s_in, 8, spring_in);
        left.set_real(left.c, p_in, 2, spring_out);
        force[0] = spring_out[2];
        force[1] = spring_out[3];
        right.set_real(right.c, p_in, 2, force);
        if (spring.do_step(spring.c, t, H, 1) || left.do_step(left.c, t, H, 1) || right.do_step(right.c, t, H, 1)) {
            fprintf(stderr, "fmi2DoStep failed at t = %g\n", t);
            return 1;
        }
        if (recording) {
            Unit *units[3] = {&spring, &left, &right};
            double *bob[2] = {left_out, right_out};
            fmi2Integer ints[MAX_RECORDED];
            int u, column = 1;
            row = table + (k + 1) * row_length;
            row[0] = t + H;
            units[0]->get_real(units[0]->c, rec.spring, rec.n_spring, row + column);
            for (i = 0; i < 4; i++) spring_out[i] = row[column + rec.force[i]];
            column += rec.n_spring;
            for (u = 1; u < 3; u++) {
                units[u]->get_real(units[u]->c, rec.real, rec.n_real, row + column);
                for (i = 0; i < 4; i++) bob[u - 1][i] = row[column + rec.bob[i]];
                column += rec.n_real;
            }
            for (u = 1; u < 3; u++) {
                get_integer[u](units[u]->c, rec.ints, rec.n_int, ints);
                for (i = 0; i < rec.n_int; i++) row[column++] = ints[i];
            }
        } else {
            spring.get_real(spring.c, s_out, 4, spring_out);
            left.get_real(left.c, p_out, 4, left_out);
            right.get_real(right.c, p_out, 4, right_out);
        }
    }
    clock_gettime(CLOCK_MONOTONIC, &ts);
    t1 = ts.tv_sec + 1e-9 * ts.tv_nsec;
    printf("%.9g %.17g\n", (t1 - t0) / steps, left_out[0]);
    free(table);
    spring.free_instance(spring.c);
    left.free_instance(left.c);
    right.free_instance(right.c);
    return 0;
}
