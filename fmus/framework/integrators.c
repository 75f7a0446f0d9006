/* The coefficients of every method of thesis chapter 4. Corrections against the printed thesis:
 * rk3 (4.38): k3 = f(x + h, y - h k1 + 2 h k2); Kutta-Nystrom (4.36): a21 = 1/3, a52 = +10/9,
 * a62 = +12/25; Adams-Bashforth 6 (4.43): the last term -475 f(k-5) restored. A test checks every
 * tableau against the Runge-Kutta order conditions and every Adams-Bashforth set against exactness
 * on polynomials. */
#include "integrators.h"

/* the coefficients laid out as their tables are, not as the formatter would */
/* clang-format off */
INTERNAL_DATA const ButcherTableau TABLEAU_EULER = {"euler", 1, 1, {0}, {{0}}, {1}, {0}, 0, {0}};

INTERNAL_DATA const ButcherTableau TABLEAU_MIDPOINT = {"midpoint", 2, 2, {0, 0.5}, {{0}, {0.5}}, {0, 1}, {0}, 0, {0}};

INTERNAL_DATA const ButcherTableau TABLEAU_HEUN = {"heun", 2, 2, {0, 1}, {{0}, {1}}, {0.5, 0.5}, {0}, 0, {0}};

INTERNAL_DATA const ButcherTableau TABLEAU_RK3 = {
    "rk3", 3, 3, {0, 0.5, 1}, {{0}, {0.5}, {-1, 2}}, {1.0 / 6, 4.0 / 6, 1.0 / 6}, {0}, 0, {0}};

INTERNAL_DATA const ButcherTableau TABLEAU_RK4 = {
    "rk4", 4, 4, {0, 0.5, 0.5, 1}, {{0}, {0.5}, {0, 0.5}, {0, 0, 1}},
    {1.0 / 6, 1.0 / 3, 1.0 / 3, 1.0 / 6}, {0}, 0, {0}};

INTERNAL_DATA const ButcherTableau TABLEAU_NYSTROM5 = {
    "nystrom5", 6, 5, {0, 1.0 / 3, 2.0 / 5, 1, 2.0 / 3, 4.0 / 5},
    {{0},
     {1.0 / 3},
     {4.0 / 25, 6.0 / 25},
     {1.0 / 4, -3, 15.0 / 4},
     {2.0 / 27, 10.0 / 9, -50.0 / 81, 8.0 / 81},
     {2.0 / 25, 12.0 / 25, 2.0 / 15, 8.0 / 75}},
    {23.0 / 192, 0, 125.0 / 192, 0, -81.0 / 192, 125.0 / 192}, {0}, 0, {0}};

/* Fehlberg 4(5): the 4th-order solution is propagated, the 5th-order one only estimates the error. */
INTERNAL_DATA const ButcherTableau TABLEAU_RKF45 = {
    "rkf45", 6, 4, {0, 1.0 / 4, 3.0 / 8, 12.0 / 13, 1, 1.0 / 2},
    {{0},
     {1.0 / 4},
     {3.0 / 32, 9.0 / 32},
     {1932.0 / 2197, -7200.0 / 2197, 7296.0 / 2197},
     {439.0 / 216, -8, 3680.0 / 513, -845.0 / 4104},
     {-8.0 / 27, 2, -3544.0 / 2565, 1859.0 / 4104, -11.0 / 40}},
    {25.0 / 216, 0, 1408.0 / 2565, 2197.0 / 4104, -1.0 / 5, 0},
    {16.0 / 135 - 25.0 / 216, 0, 6656.0 / 12825 - 1408.0 / 2565, 28561.0 / 56430 - 2197.0 / 4104,
     -9.0 / 50 + 1.0 / 5, 2.0 / 55}, 0, {0}};

/* Gauss-Legendre collocation: implicit midpoint (1 stage, order 2) and 2 stages (order 4), both
 * symmetric. With r = sqrt(3): c = 1/2 -+ r/6, A = [[1/4, 1/4 - r/6], [1/4 + r/6, 1/4]], b = (1/2, 1/2),
 * and d = b^T A^-1 = (-r, r). */
#define SQRT3 1.7320508075688772
INTERNAL_DATA const ButcherTableau TABLEAU_IMPLICIT_MIDPOINT = {"implicit_midpoint", 1, 2, {0.5}, {{0.5}}, {1}, {0}, 1, {2}};
INTERNAL_DATA const ButcherTableau TABLEAU_GAUSS_LEGENDRE4 = {
    "gauss_legendre4", 2, 4, {0.5 - SQRT3 / 6, 0.5 + SQRT3 / 6},
    {{0.25, 0.25 - SQRT3 / 6}, {0.25 + SQRT3 / 6, 0.25}}, {0.5, 0.5}, {0}, 1, {-SQRT3, SQRT3}};

/* The trapezoid rule (thesis 4.9), x1 = x0 + h/2 (f(t0, x0) + f(t1, x1)), as the 2-stage Lobatto IIIA
 * method: its first stage is explicit (f at the step's start, evaluated once) and its last row of A
 * is b, so that x1 = x0 + Z_2 (A is singular: no b^T A^-1). */
INTERNAL_DATA const ButcherTableau TABLEAU_TRAPEZOID = {
    "trapezoid", 2, 2, {0.0, 1.0}, {{0.0, 0.0}, {0.5, 0.5}}, {0.5, 0.5}, {0}, 1, {0.0, 1.0}};

INTERNAL_DATA const AdamsBashforth AB2 = {"ab2", 2, {3.0 / 2, -1.0 / 2}, &TABLEAU_RK4, 0, {0}, &TABLEAU_EULER};
INTERNAL_DATA const AdamsBashforth AB3 = {"ab3", 3, {23.0 / 12, -16.0 / 12, 5.0 / 12}, &TABLEAU_RK4, 0, {0}, &TABLEAU_MIDPOINT};
INTERNAL_DATA const AdamsBashforth AB4 = {"ab4", 4, {55.0 / 24, -59.0 / 24, 37.0 / 24, -9.0 / 24}, &TABLEAU_RK4, 0, {0}, &TABLEAU_RK3};
INTERNAL_DATA const AdamsBashforth AB5 = {
    "ab5", 5, {1901.0 / 720, -2774.0 / 720, 2616.0 / 720, -1274.0 / 720, 251.0 / 720}, &TABLEAU_RK4, 0, {0}, &TABLEAU_RK4};
#define AB6_BETA {4277.0 / 1440, -7923.0 / 1440, 9982.0 / 1440, -7298.0 / 1440, 2877.0 / 1440, -475.0 / 1440}
INTERNAL_DATA const AdamsBashforth AB6 = {"ab6", 6, AB6_BETA, &TABLEAU_NYSTROM5, 0, {0}, &TABLEAU_NYSTROM5};

/* Adams-Bashforth-Moulton, PECE (thesis 4.2, predictor-corrector): the k-step Adams-Bashforth
 * predictor, f at the prediction, the (k-1)-step Adams-Moulton corrector of the same order k; the
 * next step's f(k) is taken at the corrected point. Two evaluations per step. abm5 starts with
 * nystrom5, not ab5's rk4: its error constant is 8 times smaller than ab5's, and an order-4 start
 * would dominate it over a short run. */
INTERNAL_DATA const AdamsBashforth ABM2 = {"abm2", 2, {3.0 / 2, -1.0 / 2}, &TABLEAU_RK4, 1, {1.0 / 2, 1.0 / 2}, &TABLEAU_EULER};
INTERNAL_DATA const AdamsBashforth ABM3 = {"abm3", 3, {23.0 / 12, -16.0 / 12, 5.0 / 12}, &TABLEAU_RK4, 1,
                             {5.0 / 12, 8.0 / 12, -1.0 / 12}, &TABLEAU_MIDPOINT};
INTERNAL_DATA const AdamsBashforth ABM4 = {"abm4", 4, {55.0 / 24, -59.0 / 24, 37.0 / 24, -9.0 / 24}, &TABLEAU_RK4, 1,
                             {9.0 / 24, 19.0 / 24, -5.0 / 24, 1.0 / 24}, &TABLEAU_RK3};
INTERNAL_DATA const AdamsBashforth ABM5 = {
    "abm5", 5, {1901.0 / 720, -2774.0 / 720, 2616.0 / 720, -1274.0 / 720, 251.0 / 720}, &TABLEAU_NYSTROM5, 1,
    {251.0 / 720, 646.0 / 720, -264.0 / 720, 106.0 / 720, -19.0 / 720}, &TABLEAU_RK4};
INTERNAL_DATA const AdamsBashforth ABM6 = {"abm6", 6, AB6_BETA, &TABLEAU_NYSTROM5, 1,
                             {475.0 / 1440, 1427.0 / 1440, -798.0 / 1440, 482.0 / 1440, -173.0 / 1440, 27.0 / 1440}, &TABLEAU_NYSTROM5};
/* clang-format on */

#if N_STATES > 0

#include <math.h>
#include <string.h>

#if defined(__GNUC__)
#define ENGINE_INLINE static inline __attribute__((always_inline))
#else
#define ENGINE_INLINE static inline
#endif
/* The stage and state loops have a handful of iterations known at compile time: unrolled, the
 * coefficients become constants and the zeros disappear. */
#if defined(__GNUC__) && !defined(__clang__)
#define UNROLL _Pragma("GCC unroll 8")
#elif defined(__clang__)
#define UNROLL _Pragma("unroll")
#else
#define UNROLL
#endif

/* The right-hand side as one loop sees it: copied into a local so that the compiler keeps it in
 * registers across the calls into the model (evaluations are counted per step by the loops). */
typedef struct {
    const ModelConst *model;
    const double *u0, *du;
    double t0;
} Evaluator;

/* How the inputs enter a loop. The fixed-step loops are compiled once per mode with the mode a
 * constant, so each stage inlines one copy of the model: without force terms for FORCES_NONE, and
 * the compiler's pairing of sin and cos of one angle reaches every stage. */
enum { FORCES_NONE, FORCES_HELD, FORCES_VARY };

static int forces_mode(const RightHandSide *f)
{
    return f->inputs_vary ? FORCES_VARY : f->forces ? FORCES_HELD : FORCES_NONE;
}

ENGINE_INLINE Evaluator evaluator_of(const RightHandSide *f)
{
    Evaluator e;
    e.model = f->model;
    e.u0 = f->u0;
    e.du = f->du;
    e.t0 = f->t0;
    return e;
}

ENGINE_INLINE void evaluate(const Evaluator *f, int mode, double t, const double *x, double *dx)
{
    if (mode == FORCES_VARY) {
        double u[INPUT_SLOTS];
        int i;
        for (i = 0; i < N_INPUTS; i++) u[i] = f->u0[i] + (t - f->t0) * f->du[i];
        model_equations(f->model, t, x, u, dx);
    } else if (mode == FORCES_HELD) {
        model_equations(f->model, t, x, f->u0, dx);
    } else {
        model_equations(f->model, t, x, NULL, dx); /* the force terms vanish when inlined */
    }
}

/* A tableau's weights and nodes times the step h, computed once per loop: a stage then multiplies each k
 * once (h a_sj times k_j, not h times a_sj k_j). */
typedef struct {
    double a[RK_MAX_STAGES][RK_MAX_STAGES], b[RK_MAX_STAGES], e[RK_MAX_STAGES], c[RK_MAX_STAGES];
} StepWeights;

ENGINE_INLINE StepWeights step_weights(const ButcherTableau *tab, double h)
{
    StepWeights w;
    int s, j;
    UNROLL for (s = 0; s < tab->stages; s++)
    {
        w.c[s] = tab->c[s] * h;
        w.b[s] = tab->b[s] * h;
        w.e[s] = tab->e[s] * h;
        UNROLL for (j = 0; j < s; j++) w.a[s][j] = tab->a[s][j] * h;
    }
    return w;
}

/* sum_j (h w_j) k[j][i] over the tableau's nonzero weights w, the k of equal weights added before their one
 * product (rk4: h/6 (k1 + k4) + h/3 (k2 + k3)). The tableau is a constant where this is inlined: the compiler
 * settles every comparison, drops the zeros, and no 0.0 + w k remains (IEEE rules forbid removing it). */
ENGINE_INLINE double weighted_sum(const double *w, const double *scaled, int count, double (*k)[STATE_SLOTS], int i)
{
    double sum = 0.0;
    int j, l, started = 0;
    UNROLL for (j = 0; j < count; j++)
    {
        int leads = w[j] != 0.0; /* the first of its weight */
        UNROLL for (l = 0; l < j; l++) leads = leads && w[l] != w[j];
        if (leads) {
            double group = k[j][i];
            UNROLL for (l = j + 1; l < count; l++) if (w[l] == w[j]) group += k[l][i];
            sum = started ? sum + scaled[j] * group : scaled[j] * group;
            started = 1;
        }
    }
    return sum;
}

/* One explicit Runge-Kutta step of tableau tab (w: its weights times h), in place on x; f0 = f(t, x) is given
 * so that the Adams-Bashforth start can keep it. err (optional) receives h * sum(e_j k_j). */
ENGINE_INLINE void runge_kutta_step(const Evaluator *f, int mode, const ButcherTableau *tab, const StepWeights *w,
                                    double t, double *x, const double *f0, double *err)
{
    double k[RK_MAX_STAGES][STATE_SLOTS];
    double y[STATE_SLOTS];
    int s, i;
    UNROLL for (i = 0; i < N_STATES; i++) k[0][i] = f0[i];
    UNROLL for (s = 1; s < tab->stages; s++)
    {
        UNROLL for (i = 0; i < N_STATES; i++) y[i] = x[i] + weighted_sum(tab->a[s], w->a[s], s, k, i);
        evaluate(f, mode, t + w->c[s], y, k[s]);
    }
    if (err) {
        UNROLL for (i = 0; i < N_STATES; i++) err[i] = weighted_sum(tab->e, w->e, tab->stages, k, i);
    }
    UNROLL for (i = 0; i < N_STATES; i++) x[i] += weighted_sum(tab->b, w->b, tab->stages, k, i);
}

/* One step of h, its weights scaled here (a step that is not one of a loop's equal steps). */
ENGINE_INLINE void runge_kutta_step_of(const Evaluator *f, int mode, const ButcherTableau *tab, double t, double h,
                                       double *x, const double *f0, double *err)
{
    const StepWeights w = step_weights(tab, h);
    runge_kutta_step(f, mode, tab, &w, t, x, f0, err);
}

/* A state refused: kept for the message of a step that stops on it. */
static int remember_refused(RightHandSide *f, const double *x)
{
    memcpy(f->refused, x, sizeof f->refused);
    f->refused_known = 1;
    return 0;
}

/* model_state_ok, remembering a refused state. */
ENGINE_INLINE int regular(RightHandSide *f, const double *x)
{
    return model_state_ok(f->model, x) || remember_refused(f, x);
}

/* f->acceptable, remembering a refused state. */
ENGINE_INLINE int acceptable(RightHandSide *f, double t, const double *x)
{
    return f->acceptable(f->context, t, x) || remember_refused(f, x);
}

/* A checking pass's test of a substep's result: whether it is rejected (x is then back at saved). */
ENGINE_INLINE int rejected(RightHandSide *f, double t, double *x, const double *saved)
{
    f->checks++;
    if (acceptable(f, t, x)) return 0;
    memcpy(x, saved, STATE_SLOTS * sizeof(double));
    return 1;
}

/* The loop steps a local copy of x: no store through x can then alias the model's constants, which the
 * compiler keeps out of the loop. Each substep's first stage is evaluated at the end of the substep before it, the
 * first one's before the loop, where the previous call's end check may give it: the loop's body stays one copy. */
ENGINE_INLINE int64_t runge_kutta_steps(RightHandSide *f, int mode, const ButcherTableau *tab, double *x, double t0,
                                        double hs, int64_t first, int64_t n, int check_each)
{
    const Evaluator e = evaluator_of(f);
    const StepWeights w = step_weights(tab, hs);
    double state[STATE_SLOTS], f0[STATE_SLOTS], saved[STATE_SLOTS];
    int64_t i = first, evaluated = n;
    memcpy(state, x, sizeof state);
    if (n > 0) {
        if (first == 0 && f->start_slope)
            memcpy(f0, f->start_slope, sizeof f0);
        else
            evaluate(&e, mode, t0 + (double)first * hs, state, f0);
        for (;;) {
            const double t = t0 + (double)i * hs;
            if (check_each) memcpy(saved, state, sizeof saved);
            runge_kutta_step(&e, mode, tab, &w, t, state, f0, NULL);
            if (check_each && rejected(f, t + hs, state, saved)) {
                evaluated = i - first + 1;
                break;
            }
            if (++i == first + n) break;
            evaluate(&e, mode, t0 + (double)i * hs, state, f0);
        }
    }
    memcpy(x, state, sizeof state);
    f->evaluations += (uint64_t)evaluated * (uint64_t)tab->stages;
    return i - first;
}

/* Compiled apart for check_each: the loop that does not check calls nothing unknown, so the model's constants stay
 * out of it. */
ENGINE_INLINE int64_t runge_kutta_loop(RightHandSide *f, int mode, const ButcherTableau *tab, double *x, double t0,
                                       double hs, int64_t first, int64_t n, int check_each)
{
    if (check_each) return runge_kutta_steps(f, mode, tab, x, t0, hs, first, n, 1);
    return runge_kutta_steps(f, mode, tab, x, t0, hs, first, n, 0);
}

/* Adams-Bashforth: x(k+1) = x(k) + h sum beta_j f(k-j). Until enough history exists the starter
 * Runge-Kutta method steps (the restarter after an event), and its first stage, f(k), goes into the history all the
 * same. f(k) enters the ring given as f0 (NULL: evaluated here). */
ENGINE_INLINE void adams_bashforth_slope(RightHandSide *f, const Evaluator *e, int mode, IntegratorMemory *m,
                                         const double *x, double t, const double *f0)
{
    double *newest;
    m->ab_head = m->ab_head + 1 == AB_MAX_STEPS ? 0 : m->ab_head + 1; /* no division: the ring's next slot */
    newest = m->ab_history[m->ab_head];
    if (f0)
        memcpy(newest, f0, N_STATES * sizeof(double));
    else
        evaluate(e, mode, t, x, newest);
    f->evaluations++;
    if (m->ab_count < AB_MAX_STEPS) m->ab_count++;
}

/* The step from (t, x) once f(k) is the ring's newest entry. */
ENGINE_INLINE void adams_bashforth_substep(RightHandSide *f, const Evaluator *e, int mode, const AdamsBashforth *ab,
                                           IntegratorMemory *m, double *x, double t, double hs)
{
    double *newest = m->ab_history[m->ab_head];
    int j, q;
    if (m->ab_count < ab->steps) {
        /* a call per tableau: on a tableau chosen at run time gcc -O2 -Wall cannot see that every stage
         * summed was set, and warns */
        const int restarting = m->ab_restarted;
        if (m->ab_count + 1 == ab->steps) m->ab_restarted = 0; /* the history is whole after this step */
        if (restarting) {
            runge_kutta_step_of(e, mode, ab->restarter, t, hs, x, newest, NULL);
            f->evaluations += (uint64_t)(ab->restarter->stages - 1);
        } else {
            runge_kutta_step_of(e, mode, ab->starter, t, hs, x, newest, NULL);
            f->evaluations += (uint64_t)(ab->starter->stages - 1);
        }
    } else {
        /* the past slopes f(k - j), their ring positions found once per step rather than once per state */
        const double *past[AB_MAX_STEPS];
        UNROLL for (j = 0; j < ab->steps; j++) past[j] =
            m->ab_history[m->ab_head >= j ? m->ab_head - j : m->ab_head - j + AB_MAX_STEPS];
        if (!ab->corrected) {
            UNROLL for (q = 0; q < N_STATES; q++)
            {
                double sum = ab->beta[0] * newest[q];
                UNROLL for (j = 1; j < ab->steps; j++) sum += ab->beta[j] * past[j][q];
                x[q] += hs * sum;
            }
        } else { /* predict, evaluate, correct */
            double predicted[STATE_SLOTS], f_predicted[STATE_SLOTS];
            UNROLL for (q = 0; q < N_STATES; q++)
            {
                double sum = ab->beta[0] * newest[q];
                UNROLL for (j = 1; j < ab->steps; j++) sum += ab->beta[j] * past[j][q];
                predicted[q] = x[q] + hs * sum;
            }
            evaluate(e, mode, t + hs, predicted, f_predicted);
            f->evaluations++;
            UNROLL for (q = 0; q < N_STATES; q++)
            {
                double sum = ab->moulton[0] * f_predicted[q] + ab->moulton[1] * newest[q];
                UNROLL for (j = 1; j + 1 < ab->steps; j++) sum += ab->moulton[j + 1] * past[j][q];
                x[q] += hs * sum;
            }
        }
    }
}

/* The substeps, each one's f(k) taken at the end of the one before (as in runge_kutta_steps). A checking pass saves
 * x and the memory before f(k) enters the ring, so that a rejected substep leaves both as they were. */
ENGINE_INLINE int64_t adams_bashforth_loop(RightHandSide *f, int mode, const AdamsBashforth *ab, IntegratorMemory *m,
                                           double *x, double t0, double hs, int64_t first, int64_t n, int check_each)
{
    const Evaluator e = evaluator_of(f);
    double saved[STATE_SLOTS] = {0}; /* set before use where check_each; gcc cannot see that */
    IntegratorMemory saved_memory;
    int64_t i = first;
    if (n <= 0) return 0;
    if (check_each) {
        memcpy(saved, x, sizeof saved);
        saved_memory = *m;
    }
    adams_bashforth_slope(f, &e, mode, m, x, t0 + (double)first * hs, first == 0 ? f->start_slope : NULL);
    for (;;) {
        const double t = t0 + (double)i * hs;
        adams_bashforth_substep(f, &e, mode, ab, m, x, t, hs);
        if (check_each && rejected(f, t + hs, x, saved)) {
            *m = saved_memory;
            return i - first;
        }
        if (++i == first + n) return n;
        if (check_each) {
            memcpy(saved, x, sizeof saved);
            saved_memory = *m;
        }
        adams_bashforth_slope(f, &e, mode, m, x, t0 + (double)i * hs, NULL);
    }
}

/* Dense LU factorization with partial pivoting, in place (row-major n x n); 0 when singular. */
static int lu_factor(double *a, int n, int *pivot)
{
    int i, j, k;
    for (k = 0; k < n; k++) {
        int best = k;
        for (i = k + 1; i < n; i++)
            if (fabs(a[i * n + k]) > fabs(a[best * n + k])) best = i;
        pivot[k] = best;
        if (!(a[best * n + k] != 0.0) || !isfinite(a[best * n + k])) return 0;
        if (best != k)
            for (j = 0; j < n; j++) {
                const double swap = a[k * n + j];
                a[k * n + j] = a[best * n + j];
                a[best * n + j] = swap;
            }
        for (i = k + 1; i < n; i++) {
            const double factor = a[i * n + k] / a[k * n + k];
            a[i * n + k] = factor;
            for (j = k + 1; j < n; j++) a[i * n + j] -= factor * a[k * n + j];
        }
    }
    return 1;
}

static void lu_solve(const double *a, int n, const int *pivot, double *b)
{
    int i, j;
    for (i = 0; i < n; i++) {
        const double swap = b[i];
        b[i] = b[pivot[i]];
        b[pivot[i]] = swap;
        for (j = 0; j < i; j++) b[i] -= a[i * n + j] * b[j];
    }
    for (i = n - 1; i >= 0; i--) {
        for (j = i + 1; j < n; j++) b[i] -= a[i * n + j] * b[j];
        b[i] /= a[i * n + i];
    }
}

/* A stage whose row of A is zero (the trapezoid rule's first): f at the step's start, no unknown. */
static int explicit_stage(const ButcherTableau *tab, int i)
{
    int j;
    for (j = 0; j < tab->stages; j++)
        if (tab->a[i][j] != 0.0) return 0;
    return 1;
}

/* One step of an implicit (collocation) method, in place on x. Simplified Newton: the Jacobian at the
 * step's start, I - h (A (x) J) factored once, the stage increments Z starting from the previous
 * step's (which differ by O(h^2)), or from zero for a loop's first step; Z keeps the solution for the
 * next step (a guess extrapolated from f through the previous step's start was better at small steps
 * and far off at large ones, where it kept the trapezoid rule from converging). An explicit first stage
 * (the trapezoid rule's) is f at the step's start, evaluated once. Returns 0 (x unchanged) when the
 * Jacobian is not finite or, setting f->unconverged, when the iteration does not converge. */
/* Newton's iteration for the stage increments Z of an implicit step from (t, x) on the Jacobian J; F holds the
 * explicit first stage, where the method has one. Returns whether it converged. */
static int newton_solve(RightHandSide *f, const Evaluator *e, int mode, const ButcherTableau *tab, double t, double h,
                        const double *x, const double *J, double (*F)[STATE_SLOTS], double (*Z)[STATE_SLOTS])
{
    enum { DIM = IMPLICIT_MAX_STAGES * STATE_SLOTS };
    const int s = tab->stages, dim = s * N_STATES;
    const int explicit_first = explicit_stage(tab, 0);
    double newton[DIM * DIM], r[DIM], y[STATE_SLOTS];
    double previous = INFINITY;
    int pivot[DIM], i, j, p, q, iteration;
    if (first_non_finite(J, N_STATES * N_STATES) >= 0) return 0;
    for (i = 0; i < s; i++)
        for (p = 0; p < N_STATES; p++)
            for (j = 0; j < s; j++)
                for (q = 0; q < N_STATES; q++)
                    newton[(i * N_STATES + p) * dim + j * N_STATES + q] =
                        (i == j && p == q ? 1.0 : 0.0) - h * tab->a[i][j] * J[p * N_STATES + q];
    if (!lu_factor(newton, dim, pivot)) return 0;
    for (iteration = 1; iteration <= NEWTON_MAX_ITERATIONS; iteration++) {
        double norm = 0.0;
        for (i = 0; i < s; i++) {
            if (i == 0 && explicit_first) continue; /* its Z stays zero: F is known */
            for (p = 0; p < N_STATES; p++) y[p] = x[p] + Z[i][p];
            evaluate(e, mode, t + tab->c[i] * h, y, F[i]);
            f->evaluations++;
        }
        f->iterations++;
        for (i = 0; i < s; i++)
            for (p = 0; p < N_STATES; p++) {
                double sum = 0.0;
                for (j = 0; j < s; j++) sum += tab->a[i][j] * F[j][p];
                r[i * N_STATES + p] = h * sum - Z[i][p];
            }
        lu_solve(newton, dim, pivot, r);
        for (i = 0; i < s; i++)
            for (p = 0; p < N_STATES; p++) {
                const double scaled = fabs(r[i * N_STATES + p]) / (1.0 + fabs(x[p]));
                Z[i][p] += r[i * N_STATES + p];
                if (!(scaled <= norm) && !isnan(norm)) norm = scaled; /* a NaN stays */
            }
        if (norm <= NEWTON_TOLERANCE) return 1;
        if (!(norm < previous)) return norm <= NEWTON_PLATEAU; /* no longer shrinking: rounding, or diverging */
        /* Contracting by rate = norm / previous per iteration, the corrections still to come add up to
         * about norm rate / (1 - rate): small enough, the iteration has converged. */
        if (previous < INFINITY && norm * norm / (previous - norm) <= NEWTON_TOLERANCE) return 1;
        previous = norm;
    }
    return 0;
}

static int implicit_step(RightHandSide *f, const Evaluator *e, int mode, const ButcherTableau *tab, double t, double h,
                         double *x, double (*Z)[STATE_SLOTS])
{
    const int s = tab->stages;
    double J[STATE_SLOTS * STATE_SLOTS], slope[STATE_SLOTS], end_slope[STATE_SLOTS];
    double F[IMPLICIT_MAX_STAGES][STATE_SLOTS], y[STATE_SLOTS], u[INPUT_SLOTS];
    int i, p;
    if (mode == FORCES_VARY)
        for (i = 0; i < N_INPUTS; i++) u[i] = e->u0[i] + (t - e->t0) * e->du[i];
    else if (mode == FORCES_HELD)
        for (i = 0; i < N_INPUTS; i++) u[i] = e->u0[i];
    if (f->kept_jacobian && f->kept_jacobian->valid && t == f->kept_jacobian->t &&
        memcmp(x, f->kept_jacobian->x, N_STATES * sizeof(double)) == 0) {
        memcpy(J, f->kept_jacobian->J, sizeof J);
        memcpy(slope, f->kept_jacobian->slope, sizeof slope);
    } else {
        f->jacobian(f->context, t, x, mode == FORCES_NONE ? NULL : u, J, slope);
        f->jacobians++;
        f->evaluations++; /* the Jacobian's columns need f(t, x) itself once */
        if (f->kept_jacobian) {
            f->kept_jacobian->valid = 1;
            f->kept_jacobian->t = t;
            memcpy(f->kept_jacobian->x, x, N_STATES * sizeof(double));
            memcpy(f->kept_jacobian->J, J, sizeof J);
            memcpy(f->kept_jacobian->slope, slope, sizeof slope);
        }
    }
    if (first_non_finite(J, N_STATES * N_STATES) >= 0) return 0;
    if (explicit_stage(tab, 0)) {
        evaluate(e, mode, t, x, F[0]);
        f->evaluations++;
    }
    if (!newton_solve(f, e, mode, tab, t, h, x, J, F, Z)) {
        /* Once more on the Jacobian at the step's end as Euler predicts it: a step into a stiff contact (Hertz's
         * force grows from zero stiffness at the onset) needs the stiffness there, which the start lacks. */
        for (p = 0; p < N_STATES; p++) y[p] = x[p] + h * slope[p];
        f->jacobian(f->context, t + h, y, mode == FORCES_NONE ? NULL : u, J, end_slope);
        f->jacobians++;
        f->evaluations++;
        memset(Z, 0, (size_t)s * sizeof Z[0]);
        if (!newton_solve(f, e, mode, tab, t, h, x, J, F, Z)) {
            f->unconverged = 1;
            return 0;
        }
    }
    for (p = 0; p < N_STATES; p++) {
        double sum = tab->d[0] * Z[0][p];
        for (i = 1; i < s; i++) sum += tab->d[i] * Z[i][p];
        x[p] += sum;
    }
    return 1;
}

static int64_t implicit_loop(RightHandSide *f, int mode, const ButcherTableau *tab, double *x, double t0, double hs,
                             int64_t first, int64_t n, int check_each)
{
    const Evaluator e = evaluator_of(f);
    double saved[STATE_SLOTS], Z[IMPLICIT_MAX_STAGES][STATE_SLOTS];
    int64_t i;
    memset(Z, 0, sizeof Z);
    for (i = first; i < first + n; i++) {
        const double t = t0 + (double)i * hs;
        memcpy(saved, x, sizeof saved);
        if (!implicit_step(f, &e, mode, tab, t, hs, x, Z)) return i - first;
        if (check_each && rejected(f, t + hs, x, saved)) return i - first;
    }
    return n;
}

#if SPLIT_ACCELERATIONS /* only the models whose accelerations split off the damping use them */
/* The accelerations a(t, q) of a model whose accelerations are a(t, q) - d v (SPLIT_ACCELERATIONS):
 * the right-hand side at zero velocities, in g[N_COORDINATES ...]. */
ENGINE_INLINE void accelerations(const Evaluator *e, int mode, double t, const double *x, double *g)
{
    double y[STATE_SLOTS];
    int j;
    UNROLL for (j = 0; j < N_COORDINATES; j++)
    {
        y[j] = x[j];
        y[N_COORDINATES + j] = 0.0;
    }
    evaluate(e, mode, t, y, g);
}

/* Stormer-Verlet for q' = v, v' = a(t, q) - d v in its symmetric form for velocity-dependent forces:
 * v+ = v + h/2 (a(t, q) - d v+), q1 = q + h v+, v1 = v+ + h/2 (a(t + h, q1) - d v+). Without damping
 * it is the symplectic velocity Verlet; a(t + h, q1) starts the next step. */
ENGINE_INLINE void verlet_step(const Evaluator *e, int mode, double damping, double t, double h, double *x, double *g)
{
    const double shrink = 1.0 / (1.0 + 0.5 * h * damping);
    double v_half[STATE_SLOTS];
    int j;
    UNROLL for (j = 0; j < N_COORDINATES; j++)
    {
        v_half[j] = (x[N_COORDINATES + j] + 0.5 * h * g[N_COORDINATES + j]) * shrink;
        x[j] += h * v_half[j];
    }
    accelerations(e, mode, t + h, x, g);
    UNROLL for (j = 0; j < N_COORDINATES; j++) x[N_COORDINATES + j] =
        v_half[j] + 0.5 * h * (g[N_COORDINATES + j] - damping * v_half[j]);
}

ENGINE_INLINE int64_t stormer_verlet_loop(RightHandSide *f, int mode, double *x, double t0, double hs, int64_t first,
                                          int64_t n, int check_each)
{
    const Evaluator e = evaluator_of(f);
    const double damping = f->model->d;
    double g[STATE_SLOTS], saved[STATE_SLOTS];
    int64_t i;
    accelerations(&e, mode, t0 + (double)first * hs, x, g);
    f->evaluations++;
    for (i = first; i < first + n; i++) {
        const double t = t0 + (double)i * hs;
        if (check_each) memcpy(saved, x, sizeof saved);
        verlet_step(&e, mode, damping, t, hs, x, g); /* g: the accelerations at the step's start, then at its end */
        f->evaluations++;
        if (check_each && rejected(f, t + hs, x, saved)) return i - first;
    }
    return n;
}
#endif

double oscillation_growth(int solver, const RightHandSide *f, double y)
{
    double coefficient[TAYLOR_MAX_TERMS], re = 0.0, im = 0.0, power = 1.0;
    const ButcherTableau *tableau = tableau_of(solver);
    int n = 0, k;
    coefficient[0] = 1.0;
    if (solver == SOLVER_STORMER_VERLET) { /* its eigenvalues on the oscillation: l + 1/l = 2 - y^2 */
        const double w = y * y - 2.0;
        return y <= 2.0 ? 1.0 : 0.5 * (w + sqrt(w * w - 4.0));
    }
    if (solver == SOLVER_TAYLOR) { /* the series to its order: sum z^k / k! */
        n = f->taylor_order < TAYLOR_MAX_TERMS - 1 ? f->taylor_order : TAYLOR_MAX_TERMS - 1;
        for (k = 1; k <= n; k++) coefficient[k] = coefficient[k - 1] / k;
    } else if (tableau && !tableau->implicit) { /* R(z) = 1 + sum_k z^k b^T A^(k-1) 1 */
        double v[RK_MAX_STAGES], w[RK_MAX_STAGES];
        int i, j;
        n = tableau->stages;
        for (i = 0; i < n; i++) v[i] = 1.0;
        for (k = 1; k <= n; k++) {
            coefficient[k] = 0.0;
            for (i = 0; i < n; i++) coefficient[k] += tableau->b[i] * v[i];
            for (i = 0; i < n; i++)
                for (w[i] = 0.0, j = 0; j < n; j++) w[i] += tableau->a[i][j] * v[j];
            memcpy(v, w, sizeof v);
        }
    } else {
        return 0.0;
    }
    for (k = 0; k <= n; k++, power *= y) { /* i^k cycles through 1, i, -1, -i */
        const double term = coefficient[k] * power;
        if (k % 4 == 0)
            re += term;
        else if (k % 4 == 1)
            im += term;
        else if (k % 4 == 2)
            re -= term;
        else
            im -= term;
    }
    return isfinite(re) && isfinite(im) ? hypot(re, im) : INFINITY;
}

/* The switches over the methods expand the lists the methods table generates (model_description.h): a method of an
 * engine with coefficients appears here by its entry in harness/fmi/methods.py and its coefficients above. */
#define RETURN_COEFFICIENTS(solver, coefficients) \
    case solver: return &coefficients;

const ButcherTableau *tableau_of(int solver)
{
    switch (solver) {
        EXPLICIT_METHODS(RETURN_COEFFICIENTS)
        EMBEDDED_METHODS(RETURN_COEFFICIENTS)
        IMPLICIT_METHODS(RETURN_COEFFICIENTS)
    default: return NULL;
    }
}

const AdamsBashforth *adams_bashforth_of(int solver)
{
    switch (solver) {
        ADAMS_METHODS(RETURN_COEFFICIENTS)
    default: return NULL;
    }
}

const char *solver_name(int solver)
{
    const ButcherTableau *tab = tableau_of(solver);
    const AdamsBashforth *ab = adams_bashforth_of(solver);
    if (solver == SOLVER_STORMER_VERLET) return "stormer_verlet";
    if (solver == SOLVER_TAYLOR) return "taylor";
    if (solver == SOLVER_GBS) return "gbs";
    return tab ? tab->name : ab ? ab->name : "unknown solver";
}

/* Right-hand sides to fill rows 1 ... k, f at the step's start included: 1 + sum (n_i - 1) = 1 + k^2. */
static uint64_t gbs_work(int k) { return 1 + (uint64_t)k * (uint64_t)k; }

double evaluations_needed(int solver, int history, double substeps, const RightHandSide *f)
{
    const ButcherTableau *tab = tableau_of(solver);
    const AdamsBashforth *ab = adams_bashforth_of(solver);
    double starts;
    if (solver == SOLVER_STORMER_VERLET) return substeps + ceil(substeps / CHECK_BLOCK); /* one per block start */
    if (solver == SOLVER_TAYLOR) return substeps * (double)taylor_charge(f->taylor_order);
    if (solver == SOLVER_GBS) return substeps * (double)gbs_work(f->gbs_columns);
    if (tab && tab->implicit) return substeps * (tab->stages * NEWTON_MAX_ITERATIONS + 1 + N_STATES);
    if (tab || !ab) return substeps * (tab ? tab->stages : 1);
    /* substep i starts with a Runge-Kutta step while history + i + 1 < steps (adams_bashforth_loop) */
    starts = (double)(ab->steps - 1 - history);
    if (starts < 0.0) starts = 0.0;
    if (starts > substeps) starts = substeps;
    /* a corrected step evaluates twice; a starting step as its Runge-Kutta method */
    return substeps * (ab->corrected ? 2 : 1) + starts * (ab->starter->stages - 1 - ab->corrected);
}

/* The adaptive methods' floor: a step below it at time t has underflowed (t + h barely differs from t, or
 * the state is singular or too stiff there). */
static double smallest_step(double t) { return 1e-14 * (fabs(t) > 1.0 ? fabs(t) : 1.0); }

/* ---- The Taylor method (thesis 4.10-4.13): x(t + s) = sum_{k=0..p} x_k s^k, the coefficients x_k from
 * the object's generated recurrences (model_taylor), summed by Horner's rule; a step counts
 * taylor_charge(p) evaluations. */

static double (*taylor_coefficients(RightHandSide *f, int mode, double t, const double *x)) [TAYLOR_SLOTS] {
    double (*series)[TAYLOR_SLOTS] = f->taylor_series;
    double u[INPUT_SLOTS];
    int i;
    /* the inputs are the call's (f), so the point alone decides the series */
    if (f->taylor_cached && t == f->taylor_at_t && memcmp(x, f->taylor_at, N_STATES * sizeof(double)) == 0)
        return series;
    f->taylor_cached = 0;
    for (i = 0; i < N_STATES; i++) series[i][0] = x[i];
    for (i = 0; i < N_INPUTS; i++) u[i] = f->u0[i] + (mode == FORCES_VARY ? (t - f->t0) * f->du[i] : 0.0);
    f->evaluations += taylor_charge(f->taylor_order);
    if (!model_taylor(f->model, t, mode == FORCES_NONE ? NULL : u, mode == FORCES_VARY ? f->du : NULL, f->taylor_order,
                      series, f->taylor_work))
        return NULL;
    memcpy(f->taylor_at, x, N_STATES * sizeof(double));
    f->taylor_at_t = t;
    f->taylor_cached = 1;
    return series;
}

static void taylor_sum(double (*series)[TAYLOR_SLOTS], int order, double s, double *x)
{
    int i, k;
    for (i = 0; i < N_STATES; i++) {
        double sum = series[i][order];
        for (k = order - 1; k >= 0; k--) sum = sum * s + series[i][k];
        x[i] = sum;
    }
}

static int64_t taylor_loop(RightHandSide *f, int mode, double *x, double t0, double hs, int64_t first, int64_t n,
                           int check_each)
{
    double (*series)[TAYLOR_SLOTS], saved[STATE_SLOTS];
    int64_t i;
    for (i = first; i < first + n; i++) {
        const double t = t0 + (double)i * hs;
        memcpy(saved, x, sizeof saved);
        if (!(series = taylor_coefficients(f, mode, t, x))) return i - first;
        taylor_sum(series, f->taylor_order, hs, x);
        if (check_each && rejected(f, t + hs, x, saved)) return i - first;
    }
    return n;
}

/* With tol > 0 the step comes from the last coefficients, after Jorba and Zou: s = exp(-0.7 / (p - 1))
 * (tol (1 + |x|_inf))^(1/p) R, with the radius of convergence estimated as R = min |x_j|_inf^(-1/j) over
 * j = p - 3 ... p (and j >= 1); no step is rejected. Jorba and Zou take (tol / |x_j|)^(1/j) over the last
 * two; but a pendulum released from rest at 90 degrees has only every fourth power in its series, so
 * that at orders divisible by 4 the last two coefficients are rounding noise and promised steps of
 * seconds. A noisy coefficient only raises its own radius estimate; the minimum takes a true one. Only
 * with all four zero (rest, or a polynomial of low degree) is the step unbounded. Stops early
 * (returning the time reached) when the work bound is reached, when the step underflows, or when a
 * result is not acceptable. */
double integrate_taylor(RightHandSide *f, IntegratorMemory *memory, double *x, double t0, double t_end, double tol,
                        int check_each)
{
    const int mode = forces_mode(f), order = f->taylor_order;
    const double safety = exp(-0.7 / (order - 1));
    double (*series)[TAYLOR_SLOTS], y[STATE_SLOTS];
    double t = t0;
    int i;
    while (t < t_end) {
        const double remaining = t_end - t;
        double size = 0.0, exponent = INFINITY, h, step;
        int j;
        if (f->evaluations + f->checks + taylor_charge(order) > f->budget) {
            f->out_of_budget = 1;
            break;
        }
        if (!(series = taylor_coefficients(f, mode, t, x))) break;
        /* comparisons rather than fmax, which is a call unless non-finite numbers are ruled out */
        for (i = 0; i < N_STATES; i++) size = fabs(x[i]) > size ? fabs(x[i]) : size;
        /* min_j |x_j|^(-1/j) (tol (1 + size))^(1/p) as the exponential of a sum of logarithms: five logs
         * and one exp cost half of the five powers they replace, a fifth of an order-16 pendulum's step */
        for (j = order; j >= 1 && j >= order - 3; j--) {
            double largest = 0.0;
            for (i = 0; i < N_STATES; i++) largest = fabs(series[i][j]) > largest ? fabs(series[i][j]) : largest;
            if (largest > 0.0) {
                const double candidate = -log(largest) / j;
                exponent = candidate < exponent ? candidate : exponent;
            }
        }
        h = safety * exp(exponent + log(tol * (1.0 + size)) / order);
        if (!(h >= smallest_step(t))) break; /* underflowed, or the coefficients are not finite */
        step = h >= remaining ? remaining : h;
        taylor_sum(series, order, step, y);
        if (!regular(f, y)) break;
        if (check_each) {
            f->checks++;
            if (!acceptable(f, t + step, y)) break;
        }
        memcpy(x, y, sizeof y);
        t = step == remaining ? t_end : t + step;
        memory->n_steps++;
        if (f->single_step) break; /* events are compared at each step */
    }
    return t < t_end ? t : t_end;
}

/* ---- Gragg-Bulirsch-Stoer extrapolation (thesis 4.2: Richardson extrapolation). Row k of the table
 * (k = 1 ... GBS_MAX_COLUMNS) starts from Gragg's modified midpoint rule with n_k = 2k substeps of H / n_k,
 * whose error expands in even powers of the substep; the Aitken-Neville scheme in h^2 fills the row,
 * T(k, j+1) = T(k, j) + (T(k, j) - T(k-1, j)) / ((n_k / n_(k-j))^2 - 1), and T(k, k), of order 2k, is the
 * result. Its error is estimated by T(k, k) - T(k, k-1). Order and step control after Hairer, Norsett and
 * Wanner (Solving ODEs I, II.9): each step aims at a column `target`, computes up to target + 1 and takes
 * the first column from target - 1 on whose error passes; it gives up early when the error cannot pass by
 * target + 1; the next target is the column that costs least per unit of time (A_k / H_k). */

/* The first step's target column from tol alone (Hairer, Norsett and Wanner's ODEX). */
static int gbs_start_column(double tol)
{
    const int k = (int)(-log10(tol + 1e-40) * 0.6 + 1.5);
    return k < 2 ? 2 : k > GBS_MAX_COLUMNS - 1 ? GBS_MAX_COLUMNS - 1 : k;
}

/* x + H from (t, x) with f0 = f(t, x) by n substeps of the modified midpoint rule: z1 = x + h f0,
 * z(m+1) = z(m-1) + 2 h f(z(m)); n - 1 evaluations. */
ENGINE_INLINE void modified_midpoint(const Evaluator *e, int mode, double t, double H, int n, const double *x,
                                     const double *f0, double *y)
{
    const double h = H / n;
    double previous[STATE_SLOTS], slope[STATE_SLOTS];
    int m, i;
    UNROLL for (i = 0; i < N_STATES; i++)
    {
        previous[i] = x[i];
        y[i] = x[i] + h * f0[i];
    }
    for (m = 1; m < n; m++) {
        evaluate(e, mode, t + m * h, y, slope);
        UNROLL for (i = 0; i < N_STATES; i++)
        {
            const double next = previous[i] + 2.0 * h * slope[i];
            previous[i] = y[i];
            y[i] = next;
        }
    }
}

/* Row k of the table in place: table[0 ... k-2] hold row k - 1 on entry, table[0 ... k-1] row k on return,
 * from its first entry `first`. */
static void extrapolate_row(double (*table)[STATE_SLOTS], int k, const double *first)
{
    int i, j;
    for (i = 0; i < N_STATES; i++) {
        double below = first[i]; /* T(k, j) */
        for (j = 1; j < k; j++) {
            const double ratio = (double)k / (double)(k - j);
            const double next = below + (below - table[j - 1][i]) / (ratio * ratio - 1.0);
            table[j - 1][i] = below;
            below = next;
        }
        table[k - 1][i] = below;
    }
}

/* The step column k's error estimate asks for: H / fac with fac = (err / 0.65)^(1/(2k-1)) / 0.94, fac within
 * [m / 4, 1 / m] for m = 0.02^(1/(2k-1)) (ODEX's safety factors and bounds); a non-finite error cuts most. */
static double gbs_step_for(int k, double H, double err)
{
    const double exponent = 1.0 / (2 * k - 1), least = pow(0.02, exponent);
    double fac = pow(err / 0.65, exponent) / 0.94;
    if (!(fac <= 4.0 / least)) fac = 4.0 / least; /* also NaN */
    if (fac < least) fac = least;
    return H / fac;
}

/* Fills row k of the table for the step H from (t, x), f0 = f(t, x): 2k - 1 evaluations. */
ENGINE_INLINE void gbs_row(const Evaluator *e, int mode, double t, double H, int k, const double *x, const double *f0,
                           double (*table)[STATE_SLOTS])
{
    double first[STATE_SLOTS];
    modified_midpoint(e, mode, t, H, 2 * k, x, f0, first);
    extrapolate_row(table, k, first);
}

/* x = T(k, k) of column k = f->gbs_columns for the step h from (t, x), f0 = f(t, x): gbs_work(k) - 1 evaluations. */
ENGINE_INLINE void gbs_step(const RightHandSide *f, const Evaluator *e, int mode, double t, double h, double *x,
                            const double *f0)
{
    double table[GBS_MAX_COLUMNS][STATE_SLOTS];
    int k;
    for (k = 1; k <= f->gbs_columns; k++) gbs_row(e, mode, t, h, k, x, f0, table);
    memcpy(x, table[f->gbs_columns - 1], STATE_SLOTS * sizeof(double));
}

/* gbs with the fixed step hs (tol = 0): T(k, k) of column k = f->gbs_columns each step, of order 2k. */
static int64_t extrapolation_loop(RightHandSide *f, int mode, double *x, double t0, double hs, int64_t first, int64_t n,
                                  int check_each)
{
    const Evaluator e = evaluator_of(f);
    const int columns = f->gbs_columns;
    double f0[STATE_SLOTS], saved[STATE_SLOTS];
    int64_t i;
    for (i = first; i < first + n; i++) {
        const double t = t0 + (double)i * hs;
        memcpy(saved, x, sizeof saved);
        if (i == 0 && f->start_slope) /* a test per step is nothing beside a step's many evaluations */
            memcpy(f0, f->start_slope, N_STATES * sizeof(double));
        else
            evaluate(&e, mode, t, x, f0);
        gbs_step(f, &e, mode, t, hs, x, f0);
        f->evaluations += gbs_work(columns);
        if (check_each && rejected(f, t + hs, x, saved)) return i - first;
    }
    return n;
}

#define EXPLICIT_LOOP(solver, tableau) \
    case solver: return runge_kutta_loop(f, mode, &tableau, x, t0, hs, first, n, check_each);
#define ADAMS_LOOP(solver, coefficients) \
    case solver: return adams_bashforth_loop(f, mode, &coefficients, memory, x, t0, hs, first, n, check_each);
#define IMPLICIT_LOOP(solver, tableau) \
    case solver: return implicit_loop(f, mode, &tableau, x, t0, hs, first, n, check_each);

/* One case per method, each with a constant tableau, so that each loop is compiled for its own
 * coefficients (and, inlined per forces mode, for its inputs). Returns -1 for an unknown solver. */
ENGINE_INLINE int64_t fixed_loop(RightHandSide *f, int mode, int solver, IntegratorMemory *memory, double *x, double t0,
                                 double hs, int64_t first, int64_t n, int check_each)
{
    switch (solver) {
        EXPLICIT_METHODS(EXPLICIT_LOOP)
        ADAMS_METHODS(ADAMS_LOOP)
        IMPLICIT_METHODS(IMPLICIT_LOOP)
    case SOLVER_TAYLOR: return taylor_loop(f, mode, x, t0, hs, first, n, check_each);
    case SOLVER_GBS: return extrapolation_loop(f, mode, x, t0, hs, first, n, check_each);
#if SPLIT_ACCELERATIONS
    case SOLVER_STORMER_VERLET: return stormer_verlet_loop(f, mode, x, t0, hs, first, n, check_each);
#endif
    default: return -1;
    }
}

int64_t integrate_fixed(RightHandSide *f, int solver, IntegratorMemory *memory, double *x, double t0, double hs,
                        int64_t first, int64_t n, int check_each)
{
    int64_t done;
    switch (forces_mode(f)) {
    case FORCES_NONE: done = fixed_loop(f, FORCES_NONE, solver, memory, x, t0, hs, first, n, check_each); break;
    case FORCES_HELD: done = fixed_loop(f, FORCES_HELD, solver, memory, x, t0, hs, first, n, check_each); break;
    default: done = fixed_loop(f, FORCES_VARY, solver, memory, x, t0, hs, first, n, check_each); break;
    }
    if (done < 0) return 0;
    memory->n_steps += (uint64_t)done;
    return done;
}

#define IS_METHOD(solver, coefficients) \
    case solver: return 1;

/* Whether the method is an explicit Runge-Kutta tableau's. */
static int explicit_method(int solver)
{
    switch (solver) {
        EXPLICIT_METHODS(IS_METHOD)
    default: return 0;
    }
}

int steps_from_slope(int solver)
{
    return solver == SOLVER_GBS || explicit_method(solver) || (SPLIT_ACCELERATIONS && solver == SOLVER_STORMER_VERLET);
}

ENGINE_INLINE void mode_slope(const Evaluator *e, int mode, int solver, double t, const double *x, double *dx)
{
#if SPLIT_ACCELERATIONS
    if (solver == SOLVER_STORMER_VERLET) {
        accelerations(e, mode, t, x, dx);
        return;
    }
#endif
    evaluate(e, mode, t, x, dx);
}

void slope_at(RightHandSide *f, int solver, double t, const double *x, double *dx)
{
    const Evaluator e = evaluator_of(f);
    switch (forces_mode(f)) {
    case FORCES_NONE: mode_slope(&e, FORCES_NONE, solver, t, x, dx); break;
    case FORCES_HELD: mode_slope(&e, FORCES_HELD, solver, t, x, dx); break;
    default: mode_slope(&e, FORCES_VARY, solver, t, x, dx); break;
    }
    f->evaluations++;
}

void slope_accelerations(const RightHandSide *f, int solver, const double *slope, const double *x, double *a)
{
    int j;
    for (j = 0; j < N_COORDINATES; j++)
        a[j] = slope[N_COORDINATES + j] - (solver == SOLVER_STORMER_VERLET ? f->model->d * x[N_COORDINATES + j] : 0.0);
}

#define EXPLICIT_STEP(solver, tableau) \
    case solver: runge_kutta_step_of(e, mode, &tableau, t, h, x, f0, NULL); break;

/* One step of steps_from_slope's methods with f0 given, for a constant forces mode. */
ENGINE_INLINE void slope_step(RightHandSide *f, const Evaluator *e, int mode, int solver, double t, double h, double *x,
                              const double *f0)
{
#if SPLIT_ACCELERATIONS
    if (solver == SOLVER_STORMER_VERLET) {
        double g[STATE_SLOTS];
        memcpy(g, f0, sizeof g);
        verlet_step(e, mode, f->model->d, t, h, x, g);
        f->evaluations++;
        return;
    }
#endif
    if (solver == SOLVER_GBS) {
        gbs_step(f, e, mode, t, h, x, f0);
        f->evaluations += gbs_work(f->gbs_columns) - 1;
    } else { /* each with its constant tableau, as fixed_loop has them */
        const ButcherTableau *tab = tableau_of(solver);
        switch (solver) {
            EXPLICIT_METHODS(EXPLICIT_STEP)
        default: break;
        }
        f->evaluations += (uint64_t)(tab->stages - 1);
    }
}

void step_from_slope(RightHandSide *f, int solver, IntegratorMemory *memory, double *x, double t, double h,
                     const double *f0)
{
    const Evaluator e = evaluator_of(f);
    switch (forces_mode(f)) {
    case FORCES_NONE: slope_step(f, &e, FORCES_NONE, solver, t, h, x, f0); break;
    case FORCES_HELD: slope_step(f, &e, FORCES_HELD, solver, t, h, x, f0); break;
    default: slope_step(f, &e, FORCES_VARY, solver, t, h, x, f0); break;
    }
    memory->n_steps++;
}

/* The start of an adaptive step that may take `work` evaluations: 0 (setting f->out_of_budget) when they
 * would pass the work bound per call; else f0 = f(t, x), evaluated unless a rejected attempt from the same
 * point left it. */
ENGINE_INLINE int adaptive_step_start(RightHandSide *f, const Evaluator *e, int mode, double t, const double *x,
                                      double *f0, int *have_f0, uint64_t work)
{
    if (f->evaluations + f->checks + work > f->budget) {
        f->out_of_budget = 1;
        return 0;
    }
    if (!*have_f0) {
        evaluate(e, mode, t, x, f0);
        f->evaluations++;
        *have_f0 = 1;
    }
    return 1;
}

/* The error test of the adaptive methods: the RMS over the states of (a_i - b_i) / (tol (1 + |x_i|)), b NULL
 * for zero; 1 or less passes. */
static double scaled_error(const double *x, const double *a, const double *b, double tol)
{
    double norm = 0.0;
    int i;
    for (i = 0; i < N_STATES; i++) {
        const double scaled = (b ? a[i] - b[i] : a[i]) / (tol * (1.0 + fabs(x[i])));
        norm += scaled * scaled;
    }
    return sqrt(norm / N_STATES);
}

/* An embedded method's pass, for its constant tableau (inlined per method, as fixed_loop's). */
ENGINE_INLINE double embedded_pass(RightHandSide *f, const ButcherTableau *tableau, IntegratorMemory *memory, double *x,
                                   double t0, double t_end, double h_initial, double tol, int check_each)
{
    const Evaluator e = evaluator_of(f);
    const int mode = forces_mode(f);
    double h = memory->step_proposal > 0.0 ? memory->step_proposal : h_initial;
    double t = t0;
    double f0[STATE_SLOTS] = {0}, y[STATE_SLOTS], err[STATE_SLOTS];
    int have_f0 = 0, rejected_before = 0;
    while (t < t_end) {
        const double remaining = t_end - t;
        const int last = h >= remaining;
        const double step = last ? remaining : h;
        double norm, factor;
        int accept;
        if (!adaptive_step_start(f, &e, mode, t, x, f0, &have_f0, (uint64_t)tableau->stages)) break;
        memcpy(y, x, sizeof y);
        runge_kutta_step_of(&e, mode, tableau, t, step, y, f0, err);
        f->evaluations += (uint64_t)(tableau->stages - 1);
        norm = scaled_error(x, err, NULL, tol);
        accept = norm <= 1.0 && regular(f, y);
        if (accept && check_each) {
            f->checks++;
            accept = acceptable(f, t + step, y);
        }
        /* An error estimate of order p (rkf45: 4): the step scales with 0.8 norm^(-1/(p + 1)), kept within
         * [0.2, 5]; the safety factor 0.8 (rather than 0.9) halves the rejections on the pendulums at the same total
         * cost. */
        factor = norm > 0.0 ? 0.8 * pow(norm, -1.0 / (tableau->order + 1)) : 5.0;
        if (!(factor >= 0.2)) factor = 0.2; /* also catches NaN */
        if (factor > 5.0) factor = 5.0;
        if (accept) {
            memcpy(x, y, sizeof y);
            t = last ? t_end : t + step;
            have_f0 = 0;
            memory->n_steps++;
            /* No growth right after a rejection: that would invite the next one. */
            if (rejected_before && factor > 1.0) factor = 1.0;
            rejected_before = 0;
            /* A step cut short to land on t_end says nothing about the proposal. */
            if (!last || step >= h) h = step * factor;
            if (f->single_step) break;
        } else {
            memory->n_rejected++;
            rejected_before = 1;
            /* Rejected for a singular or non-finite result (also a NaN error norm, which the formula
             * above would turn into growth): cut hard, so that the step underflows if it persists. */
            if (!(norm > 1.0)) factor = 0.25;
            h = step * factor;
            if (h < smallest_step(t)) break;
        }
    }
    memory->step_proposal = h;
    return t < t_end ? t : t_end;
}

#define EMBEDDED_PASS(solver, tableau) \
    case solver: return embedded_pass(f, &tableau, memory, x, t0, t_end, h_initial, tol, check_each);

double integrate_adaptive(RightHandSide *f, int solver, IntegratorMemory *memory, double *x, double t0, double t_end,
                          double h_initial, double tol, int check_each)
{
    switch (solver) {
        EMBEDDED_METHODS(EMBEDDED_PASS)
    default: return t0;
    }
}

double integrate_extrapolation(RightHandSide *f, IntegratorMemory *memory, double *x, double t0, double t_end,
                               double h_initial, double tol, int check_each)
{
    const Evaluator e = evaluator_of(f);
    const int mode = forces_mode(f);
    /* the target stays below the highest column, so that one more can decide a step (unless that is 2) */
    const int highest = f->gbs_columns, cap = highest > 2 ? highest - 1 : 2;
    double table[GBS_MAX_COLUMNS][STATE_SLOTS], f0[STATE_SLOTS] = {0};
    double step_for[GBS_MAX_COLUMNS + 1], work_for[GBS_MAX_COLUMNS + 1];
    double H = memory->step_proposal > 0.0 ? memory->step_proposal : h_initial;
    double t = t0;
    int target = memory->gbs_columns ? memory->gbs_columns : gbs_start_column(tol);
    int rejected_before = memory->gbs_rejected, have_f0 = 0;
    if (target > cap) target = cap;
    while (t < t_end) {
        const double remaining = t_end - t;
        const int last = H >= remaining;
        const double step = last ? remaining : H;
        const int top = target + 1 < highest ? target + 1 : highest;
        double previous = 0.0; /* the error of the column below */
        int k, accepted = 0, failed = 0, next;
        if (!adaptive_step_start(f, &e, mode, t, x, f0, &have_f0, gbs_work(top))) break;
        for (k = 1; k <= top; k++) {
            double err;
            gbs_row(&e, mode, t, step, k, x, f0, table);
            f->evaluations += (uint64_t)(2 * k - 1);
            if (k == 1) continue;
            err = scaled_error(x, table[k - 1], table[k - 2], tol);
            step_for[k] = gbs_step_for(k, step, err);
            work_for[k] = (double)gbs_work(k) / step_for[k];
            if (err != err) { /* a row went non-finite */
                failed = 1;
                break;
            }
            /* a step cut short to land on t_end takes the first column that passes: the control's target is
             * for the full step */
            if ((k >= target - 1 || (last && step < H)) && err <= 1.0) {
                accepted = 1;
                break;
            }
            /* Hopeless: at the target, the column above cannot pass. Its error is foreseen from the rate of
             * the last two (err^2 / err_(k-1)), or, with one, from Hairer, Norsett and Wanner's model
             * (err / (n_(k+1) / n_1)^2). Their test one column earlier, against the model alone, gave up on
             * steps the pendulum's fast convergence would have passed, and the lower column's step that
             * followed set off runs of rejections. */
            if (k == target && k < top && err * (k > 2 ? err / previous : 1.0 / ((k + 1) * (k + 1))) > 1.0) break;
            previous = err;
        }
        if (k > top) k = top;
        if (accepted &&
            (!regular(f, table[k - 1]) || (check_each && (f->checks++, !acceptable(f, t + step, table[k - 1]))))) {
            accepted = 0;
            failed = 1;
        }
        /* the next target: one column down if that is clearly cheaper per unit of time; one up after an
         * accepted step if the column reached was clearly cheaper than the one below it */
        next = k;
        if (k > 2 && work_for[k - 1] < 0.8 * work_for[k])
            next = k - 1;
        else if (accepted && !rejected_before && k + 1 <= cap && (k == 2 || work_for[k] < 0.9 * work_for[k - 1]))
            next = k + 1;
        if (next > cap) next = cap;
        if (next < 2) next = 2;
        if (accepted) {
            /* a column above the one computed: its step from the work ratio */
            const double proposal =
                next > k ? step_for[k] * (double)gbs_work(next) / (double)gbs_work(k) : step_for[next];
            memcpy(x, table[k - 1], STATE_SLOTS * sizeof(double));
            t = last ? t_end : t + step;
            have_f0 = 0;
            memory->n_steps++;
            /* a step cut short to land on t_end says nothing about the proposals: the step and column
             * chosen for the full step stay */
            if (last && step < H) {
                rejected_before = 0;
                break;
            }
            H = rejected_before && proposal > step ? step : proposal; /* no growth right after a rejection */
            rejected_before = 0;
            if (f->single_step) {
                target = next;
                break;
            }
        } else {
            memory->n_rejected++;
            rejected_before = 1;
            if (failed) { /* a singular or non-finite result: cut hard, so that the step underflows if it persists */
                H = 0.25 * step;
                next = target;
            } else {
                if (next > target) next = target;
                H = step_for[next];
            }
            if (H < smallest_step(t)) {
                target = next;
                break;
            }
        }
        target = next;
    }
    memory->step_proposal = H;
    memory->gbs_columns = target;
    memory->gbs_rejected = rejected_before;
    return t < t_end ? t : t_end;
}

#endif /* N_STATES > 0 */
