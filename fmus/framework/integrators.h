/* Integrators as data: Butcher tableaux and Adams-Bashforth coefficients (thesis chapter 4, with
 * its printed errors corrected), driven by one explicit Runge-Kutta engine and one Adams-Bashforth
 * engine. Independent of the FMI layer: the engines see only a right-hand side. */
#ifndef INTEGRATORS_H
#define INTEGRATORS_H

#include <stdint.h>

#include "framework.h"

#define RK_MAX_STAGES 6
#define AB_MAX_COEFFICIENTS 6

typedef struct {
    const char *name;
    int stages;
    int order;
    double c[RK_MAX_STAGES];
    double a[RK_MAX_STAGES][RK_MAX_STAGES];
    double b[RK_MAX_STAGES];
    /* Embedded error weights (b of the higher-order partner minus b); all zero without a partner. */
    double e[RK_MAX_STAGES];
    /* Implicit methods (a full A): solved for the stage increments Z_i = h sum_j a_ij f(t + c_j h, x + Z_j)
     * by Newton's method, then x += sum_i d_i Z_i with d = b^T A^-1 (no evaluation after the solve). */
    int implicit;
    double d[RK_MAX_STAGES];
} ButcherTableau;

typedef struct {
    const char *name;
    int steps;
    double beta[AB_MAX_COEFFICIENTS]; /* weights of f(k), f(k-1), ..., f(k-steps+1) */
    const ButcherTableau *starter; /* Runge-Kutta method of order >= steps - 1 for the first steps */
    /* Adams-Moulton corrector of the same order (PECE), or none (all zero): weights of the
     * predicted f(k+1), then f(k), ..., f(k-steps+2) */
    int corrected;
    double moulton[AB_MAX_COEFFICIENTS];
    /* Runge-Kutta method of order steps - 1 for the first steps after an event: the least order that keeps the
     * method's (each of its steps' local error is of order h^steps), with the fewest stages. The history starts
     * again at every impact, where the run's start is paid once, so there the start's cost counts and not its
     * error constant. */
    const ButcherTableau *restarter;
} AdamsBashforth;

/* Newton's iteration of the implicit methods: at most this many iterations per step. With c_k the
 * largest scaled correction max |dZ_i| / (1 + |x_i|) of iteration k: converged when c_k, or the
 * corrections still to come estimated from the contraction rate, c_k^2 / (c_(k-1) - c_k), are below
 * NEWTON_TOLERANCE, or when c_k stops shrinking below NEWTON_PLATEAU (rounding reached); not converged
 * otherwise (the step is discarded). 20 iterations: the trapezoid rule's unknown stage lies at the
 * step's end, twice as far from the Jacobian's point as the midpoint rule's, and on the fast double
 * pendulum at h = 0.01 its iteration contracts by only 0.08 per iteration (13 needed). */
#define NEWTON_MAX_ITERATIONS 20
#define NEWTON_TOLERANCE 1e-15
#define NEWTON_PLATEAU 1e-10
#define IMPLICIT_MAX_STAGES 2

/* Substeps between two checks of the state in a fixed-step pass: a failure costs at most this many
 * substeps redone, and the checks cost one evaluation per block. */
#define CHECK_BLOCK 256

/* The methods' coefficients, declared from the lists the methods table generates (model_description.h: an object
 * with states has them). */
#ifdef EXPLICIT_METHODS
#define DECLARE_TABLEAU(solver, table) INTERNAL_DATA_DECLARATION const ButcherTableau table;
#define DECLARE_ADAMS(solver, coefficients) INTERNAL_DATA_DECLARATION const AdamsBashforth coefficients;
EXPLICIT_METHODS(DECLARE_TABLEAU)
EMBEDDED_METHODS(DECLARE_TABLEAU)
IMPLICIT_METHODS(DECLARE_TABLEAU)
ADAMS_METHODS(DECLARE_ADAMS)
#endif

/* A Jacobian kept with the point it was taken at: the implicit methods' trial steps from one point (locating an event
 * inside a step) take it again instead of computing it again. Valid while the constraints acting stay the same. */
typedef struct {
    int valid;
    double t, x[STATE_SLOTS], J[STATE_SLOTS * STATE_SLOTS], slope[STATE_SLOTS]; /* slope: f(t, x) */
} KeptJacobian;

/* The right-hand side as the engines see it: the model, and inputs that vary linearly over the
 * communication step, u(t) = u0 + (t - t0) du. Counts its evaluations. */
typedef struct {
    const ModelConst *model;
    double u0[INPUT_SLOTS];
    double du[INPUT_SLOTS];
    double t0;
    int inputs_vary;
    int forces; /* some input is not zero or varies: the model computes its force terms */
    uint64_t evaluations;
    uint64_t checks; /* calls of acceptable: each evaluates the right-hand side and the outputs once */
    uint64_t budget; /* rkf45 stops before a step that would take evaluations plus checks past this */
    uint64_t jacobians, iterations; /* the implicit methods' Jacobians and Newton iterations */
    int unconverged; /* set when an implicit method stopped because Newton's iteration did not converge */
    int out_of_budget; /* set when an adaptive method stopped at the budget */
    int taylor_order;
    double (*taylor_work)[TAYLOR_SLOTS];
    /* The last series computed (STATE_SLOTS of them) and where: a trial step from the same point (locating an
     * event inside the step that crossed it) sums it again instead of computing it again. */
    double (*taylor_series)[TAYLOR_SLOTS];
    double taylor_at[STATE_SLOTS], taylor_at_t;
    int taylor_cached;
    int gbs_columns; /* gbs: its column with the fixed step (tol = 0), its highest with tol > 0 */
    int single_step; /* rkf45, gbs: return after one accepted step (event checks at each of them) */
    /* f(t0, x) at the call's start where the previous call's end check left it (NULL: not known): the fixed-step
     * methods that start a substep from its slope take it as their first substep's first evaluation, which counts
     * as an evaluation all the same (the check it came from never counted). */
    const double *start_slope;
    /* J (N_STATES x N_STATES, row-major, J[i][j] = df_i/dx_j) and slope = f(t, x) at (t, x) with inputs u (NULL: all
     * zero). */
    void (*jacobian)(void *context, double t, const double *x, const double *u, double *J, double *slope);
    KeptJacobian *kept_jacobian; /* NULL: none kept */
    /* Whether a state is good enough to continue from (finite, not singular, finite outputs);
     * called only in checking passes, never in the hot loop. */
    int (*acceptable)(void *context, double t, const double *x);
    void *context;
    /* The last state refused as non-finite or singular, for the message of a step that stops on it. */
    double refused[STATE_SLOTS];
    int refused_known;
} RightHandSide;

#if N_STATES > 0 /* the engines: a model without states has none */
/* Fixed-step integration with solver (a SOLVER_* value that is not rkf45): substeps first ...
 * first + n - 1 of hs from t0, substep i starting at t0 + i hs. With check_each, stops before the
 * first substep whose result is not acceptable and leaves x, memory at the last good substep.
 * Returns the number of substeps completed. */
INTERNAL int64_t integrate_fixed(RightHandSide *f, int solver, IntegratorMemory *memory, double *x, double t0,
                                 double hs, int64_t first, int64_t n, int check_each);

/* Whether a fixed step of `solver` starts from one evaluation at its start (its slope: f(t, x) for the explicit
 * Runge-Kutta methods and gbs, the accelerations a(t, q) for Stormer-Verlet): the event stepper evaluates it once
 * per start and takes the trial steps that locate an event inside the step from it, instead of evaluating it again
 * for each. */
INTERNAL int steps_from_slope(int solver);
/* The slope of `solver` at (t, x) into dx, counted as an evaluation. */
INTERNAL void slope_at(RightHandSide *f, int solver, double t, const double *x, double *dx);
/* The accelerations of the motion at x from the slope there. */
INTERNAL void slope_accelerations(const RightHandSide *f, int solver, const double *slope, const double *x, double *a);
/* One fixed step of h from (t, x) with its slope f0 at the start given, for a solver of steps_from_slope: the same
 * arithmetic as integrate_fixed's step, less the evaluation of f0. */
INTERNAL void step_from_slope(RightHandSide *f, int solver, IntegratorMemory *memory, double *x, double t, double h,
                              const double *f0);

/* An embedded Runge-Kutta method (rkf45: Fehlberg 4(5)) with step-size control from t0 to t_end; starts from
 * memory->step_proposal (or h_initial) and leaves its next proposal there. A step whose result fails model_state_ok
 * (or, with check_each, is not acceptable) is rejected like one with too large an error. Returns the time reached:
 * t_end on success, earlier when the step size underflowed (x is then the last accepted state). */
INTERNAL double integrate_adaptive(RightHandSide *f, int solver, IntegratorMemory *memory, double *x, double t0,
                                   double t_end, double h_initial, double tol, int check_each);

/* The Taylor method of order f->taylor_order from t0 to t_end with the step chosen from its last four
 * coefficients for tol (after Jorba and Zou, who take two); no step is rejected. Returns the time reached: t_end on
 * success, earlier at the work bound (f->out_of_budget), where the step underflows, or before a
 * result that is not acceptable. */
INTERNAL double integrate_taylor(RightHandSide *f, IntegratorMemory *memory, double *x, double t0, double t_end,
                                 double tol, int check_each);

/* Gragg-Bulirsch-Stoer extrapolation from t0 to t_end, order (column 2 ... f->gbs_columns) and step chosen
 * for tol; starts from
 * memory->step_proposal (or h_initial) and memory->gbs_columns (or a column from tol) and leaves its next
 * proposals there. A step whose result fails model_state_ok (or, with check_each, is not acceptable) is
 * rejected and cut to a quarter. Returns the time reached: t_end on success, earlier at the work bound
 * (f->out_of_budget) or where the step size underflowed (x is then the last accepted state). */
INTERNAL double integrate_extrapolation(RightHandSide *f, IntegratorMemory *memory, double *x, double t0, double t_end,
                                        double h_initial, double tol, int check_each);

/* The growth per fixed step of `solver` on an undamped oscillation with h omega = y: |R(i y)| of its stability
 * function, for the explicit Runge-Kutta methods (from the tableau), the Taylor method (its order from f) and
 * Stormer-Verlet; 0 for the others (the implicit methods, stable there; the Adams methods and gbs, not covered). */
#define TAYLOR_MAX_TERMS 64
INTERNAL double oscillation_growth(int solver, const RightHandSide *f, double y);
/* The tableau or coefficient set of a solver (NULL where it is the other kind). */
INTERNAL const ButcherTableau *tableau_of(int solver);
INTERNAL const AdamsBashforth *adams_bashforth_of(int solver);
INTERNAL const char *solver_name(int solver);
/* Right-hand-side evaluations a fixed-step solver makes in `substeps` steps: its stages per step,
 * or for Adams-Bashforth one per step plus its Runge-Kutta start where `history` (the points it
 * keeps) is too short; for the implicit methods the most their iterations can take, each Jacobian
 * counted as one evaluation (f at the step's start) and one per state (its columns); for the Taylor
 * method taylor_charge(f->taylor_order) per step; for gbs with its fixed step 1 + k^2 (k = f->gbs_columns). */
INTERNAL double evaluations_needed(int solver, int history, double substeps, const RightHandSide *f);
#endif

#endif
