/* The integration of a communication step: from the FMU's state at t to t + H, with the solver the
 * user chose.
 * Finiteness is checked once per communication step; only when that check fails is the step
 * redone with a check after every substep, to stop at the last good one. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "integrators.h"


/* Forgets the Adams-Bashforth history and the adaptive methods' step and column proposals: after a reset, or when solver,
 * h or tol change. */
void restart_integrator(Instance *inst)
{
    inst->s.integrator.ab_count = 0;
    inst->s.integrator.ab_head = 0;
    inst->s.integrator.ab_step = 0.0;
    inst->s.integrator.step_proposal = 0.0;
    inst->s.integrator.gbs_columns = 0;
    inst->s.integrator.gbs_rejected = 0;
    inst->s.integrator.ab_restarted = 0;
}

/* Input slopes drive a step only when set for it: those left from the last step (kept so that the
 * output derivatives at its end follow them) give way to held inputs. */
static void take_slopes(SimState *s)
{
    if (!s->slopes_set) memset(s->input_derivative, 0, sizeof s->input_derivative);
}

#if N_STATES == 0

Status step_to(Instance *inst, const char *function, double t, double H)
{
    double before[N_REAL];
    take_slopes(&inst->s);
    memcpy(before, inst->s.real, sizeof before);
    model_advance_inputs(inst->s.real, inst->s.input_derivative, H);
    /* The outputs belong to the end of the step; a singular or overflowing end keeps the step from
     * happening. */
    if (!model_outputs(&inst->constants, t + H, NULL, inst->s.real) || first_non_finite(inst->s.real, N_REAL) >= 0) {
        memcpy(inst->s.real, before, sizeof before);
        inst->outputs_valid = 0;
        log_discard(inst, "%s: singular configuration or non-finite outputs at t = %.17g; "
                    "last successful time %.17g", function, t + H, t);
        inst->s.last_successful_time = t;
        return STATUS_DISCARD;
    }
    inst->s.slopes_set = 0;
    inst->s.time = t + H;
    inst->s.last_successful_time = t + H;
    inst->outputs_valid = 1;
    return STATUS_OK;
}

#else

/* ceil(q), without a library call where q fits an integer (most calls take one or a few substeps). */
static double round_up(double q)
{
    if (q > -1e15 && q < 1e15) {
        const double whole = (double)(int64_t)q; /* q rounded toward zero */
        return whole < q ? whole + 1.0 : whole;
    }
    return ceil(q);
}

static Status finish(Instance *inst, double t, double H_done, double t_reached)
{
    model_advance_inputs(inst->s.real, inst->s.input_derivative, H_done);
    inst->s.slopes_set = 0; /* slopes hold for one step; kept for the output rates at its end */
    inst->s.time = t_reached;
    inst->s.last_successful_time = t_reached;
    inst->outputs_valid = 0;
    inst->derivatives_current = 0;
    (void)t;
    return STATUS_OK;
}

/* Fills real (a copy of the variables with the states x) with the inputs at t (moved along their
 * slopes from the step's start), the derivatives and the outputs; returns whether x is a state to
 * continue from: finite and regular, with finite inputs, derivatives and outputs (an input whose slope
 * overflows it within the step fails the step, also for methods that never evaluate at its end). Costs
 * a right-hand side and the outputs, so it runs once per communication step, or per substep only when
 * redoing a failed step. */
static int evaluate_at(const Instance *inst, double t, const double *x, double *real)
{
    double u[INPUT_SLOTS];
    int i;
    if (!model_state_ok(&inst->constants, x)) return 0;
    memcpy(real, inst->s.real, N_REAL * sizeof(double));
    memcpy(real, x, N_STATES * sizeof(double));
    gather_inputs(inst, u);
    for (i = 0; i < N_INPUTS; i++) u[i] += (t - inst->s.time) * inst->s.input_derivative[i];
    scatter_inputs(real, u);
    return model_evaluate(&inst->constants, t, u, real) && all_finite(real, N_REAL);
}

/* The importer's look at an accepted internal step whose time, states and outputs s.real holds: the instance
 * shows the step's time while report_step runs, and its own time and machine state afterwards. */
static void report_in_place(Instance *inst, double t)
{
    const double time = inst->s.time;
    const int32_t machine_state = inst->s.machine_state;
    const int outputs_valid = inst->outputs_valid;
    inst->s.time = t;
    inst->outputs_valid = 1;
    inst->s.machine_state = MS_INTERMEDIATE;
    caller_float_control_begin(inst);
    inst->report_step(inst, t);
    caller_float_control_end(inst);
    inst->s.time = time;
    inst->s.machine_state = machine_state;
    inst->outputs_valid = outputs_valid;
}

/* The same for a step evaluated into real: shown in s.real while report_step runs, the instance's own values
 * afterwards. */
static void report_internal_step(Instance *inst, double t, const double *real)
{
    double before[N_REAL];
    memcpy(before, inst->s.real, sizeof before);
    memcpy(inst->s.real, real, sizeof before);
    report_in_place(inst, t);
    memcpy(inst->s.real, before, sizeof before);
}

int first_non_finite_at(const Instance *inst, double t, const double *x)
{
    double real[N_REAL];
    if (!model_state_ok(&inst->constants, x) || evaluate_at(inst, t, x, real)) return -1;
    return first_non_finite(real, N_REAL);
}

int state_acceptable(void *context, double t, const double *x)
{
    Instance *inst = (Instance *)context;
    double real[N_REAL];
    if (!evaluate_at(inst, t, x, real)) return 0;
    if (inst->report_step && inst->s.machine_state == MS_STEP_COMPLETE) report_internal_step(inst, t, real);
    return 1;
}

/* Ends a successful step. When the inputs did not vary, the outputs the end-of-step check computed
 * are those of the new state and inputs: they become the cached outputs instead of being computed
 * again when the master reads them. */
static Status finish_with(Instance *inst, double t, double H, const double *checked, int inputs_vary)
{
    const Status status = finish(inst, t, H, t + H);
    if (!inputs_vary) {
        memcpy(inst->s.real, checked, N_REAL * sizeof(double));
        inst->outputs_valid = 1;
    }
    return status;
}

/* The check of a fixed-step call's end state x = s.real at t. Where the inputs held it evaluates into the
 * instance itself, as the method evaluates f (the inputs it held, none where all are zero): the outputs need no
 * copy, and the derivatives serve as the next call's first evaluation. A failure leaves garbage there, which the
 * failure's finish forgets. */
#if defined(__GNUC__)
__attribute__((always_inline)) /* in step_to's every call: a call of its own costs it more than the check's set-up */
#endif
static inline int end_state_good(Instance *inst, const RightHandSide *f, double t, double *checked)
{
    double *real = inst->s.real;
    if (f->inputs_vary) return evaluate_at(inst, t, real, checked);
    return model_state_ok(&inst->constants, real) &&
           model_evaluate(&inst->constants, t, f->forces ? f->u0 : NULL, real) && computed_finite(real);
}

/* Whether a reporting pass takes its substeps one at a time (report_substeps): the methods whose substep starts from
 * its slope and depends on nothing else of the substeps before it in the call (the Adams methods' history lives in
 * the integrator memory), so that one at a time they give what the pass in one loop gives. */
static int reports_one_at_a_time(int solver)
{
    return (steps_from_slope(solver) && solver != SOLVER_STORMER_VERLET) || adams_bashforth_of(solver) != NULL;
}

/* Substeps first ... first + count - 1 of hs from t, reported with the inputs held: each a pass of its own,
 * checked as a call's end is (end_state_good: into the instance, as the method evaluates f) at the time the next
 * one starts (t_end for the last), reported from there without a copy, the next starting from that check's
 * derivatives as a call starts from its predecessor's. The substeps done; a refused one leaves x and the memory as
 * they were before it, the refused state in f. */
#if defined(__GNUC__)
__attribute__((noinline)) /* kept out of step_to, whose calls without reports it would slow */
#endif
static int64_t report_substeps(Instance *inst, RightHandSide *f, int solver, IntegratorMemory *memory, double *x,
                               double t, double hs, int64_t first, int64_t count, double t_end)
{
    const int reuse = rounding_to_nearest(inst);
    int64_t k;
    for (k = first; k < first + count; k++) {
        const double t_k = t + (double)k * hs, t_next = k + 1 == first + count ? t_end : t + (double)(k + 1) * hs;
        double saved[STATE_SLOTS];
        IntegratorMemory saved_memory = *memory;
        memcpy(saved, x, sizeof saved);
        if (k > first) f->start_slope = reuse ? inst->s.real + N_STATES : NULL; /* checked at t_k */
        else if (first > 0) f->start_slope = NULL;
        f->checks++;
        if (integrate_fixed(f, solver, memory, x, t_k, hs, 0, 1, 0) != 1 || !end_state_good(inst, f, t_next, NULL)) {
            memcpy(f->refused, x, sizeof f->refused);
            f->refused_known = 1;
            memcpy(x, saved, sizeof saved);
            *memory = saved_memory;
            return k - first;
        }
        if (inst->s.machine_state == MS_STEP_COMPLETE) report_in_place(inst, t_next);
    }
    return count;
}

/* Why a state was refused, for a message: the requirement it breaks or the variable it makes non-finite
 * ("" when neither is found). */
static void refusal_reason(const Instance *inst, double t, const double *refused, char *text, size_t size)
{
    char reason[1024];
    int k;
    text[0] = '\0';
    if (!refused) return;
    k = first_non_finite(refused, N_STATES);
    if (k >= 0)
        snprintf(text, size, " (%s would not be finite)", real_variable_name(k));
    else if (model_explain_singularity(&inst->constants, t, refused, reason, sizeof reason))
        snprintf(text, size, " (%s)", reason);
    else if ((k = first_non_finite_at(inst, t, refused)) >= 0)
        snprintf(text, size, " (%s would not be finite)", real_variable_name(k));
}

static Status fail(Instance *inst, const char *function, double t, double t_good, const char *method, double h,
                   int unconverged, const double *refused)
{
    char reason[1100];
    refusal_reason(inst, t_good, refused, reason, sizeof reason);
    finish(inst, t, t_good - t, t_good);
    if (unconverged)
        log_discard(inst, "%s: %s with h = %g: Newton's iteration did not converge (%d iterations at most, scaled "
                    "correction below %g) in the substep after t = %.17g; stopped there (last successful time "
                    "%.17g): take a smaller h", function, method, h, NEWTON_MAX_ITERATIONS, NEWTON_TOLERANCE, t_good,
                    t_good);
    else
        log_discard(inst, "%s: %s with h = %g: the state would become non-finite or singular in the substep "
                    "after t = %.17g%s; stopped there (last successful time %.17g)", function, method, h, t_good,
                    reason, t_good);
    return STATUS_DISCARD;
}

/* Whether the method picks its own steps (at most h long) to meet tol. */
static int adaptive_method(int solver, double tol)
{
    return solver == SOLVER_RKF45 || ((solver == SOLVER_GBS || solver == SOLVER_TAYLOR) && tol > 0.0);
}

/* A method that stopped short of its step (out of budget, or an adaptive step underflowed) at `reached`: the
 * call ends there, with the reason. */
static Status stopped_short(Instance *inst, const char *function, const RightHandSide *f, int solver, double t,
                            double reached)
{
    const char *method = solver_name(solver);
    const double tol = inst->s.real[VR_tol];
    char reason[1100];
    refusal_reason(inst, reached, f->refused_known ? f->refused : NULL, reason, sizeof reason);
    finish(inst, t, reached - t, reached);
    if (f->out_of_budget && !adaptive_method(solver, tol)) /* a fixed-step method's checks for contacts inside */
        log_discard(inst, "%s: %s at h = %g used its %.0f right-hand-side evaluations allowed per call, with the "
                    "checks for contacts inside its steps, at t = %.17g; stopped at the last successful time %.17g "
                    "(take shorter communication steps)", function, method, inst->s.real[VR_h],
                    MAX_EVALUATIONS_PER_CALL, reached, reached);
    else if (f->out_of_budget)
        log_discard(inst, "%s: %s with tol = %g used its %.0f right-hand-side evaluations "
                    "allowed per call at t = %.17g; stopped at the last successful time %.17g (take shorter "
                    "communication steps or a larger tol)", function, method, tol, MAX_EVALUATIONS_PER_CALL,
                    reached, reached);
    else if (f->unconverged)
        log_discard(inst, "%s: %s with h = %g: Newton's iteration did not converge (%d iterations at most, scaled "
                    "correction below %g) in a trial step locating an event after t = %.17g; stopped at the last "
                    "successful time %.17g: take a smaller h", function, method, inst->s.real[VR_h], NEWTON_MAX_ITERATIONS,
                    NEWTON_TOLERANCE, reached, reached);
    else if (solver == SOLVER_TAYLOR)
        log_discard(inst, "%s: taylor of order %d with tol = %g: the step its coefficients allow "
                    "underflowed at t = %.17g%s (tol is out of reach at this order in double precision, or "
                    "the state is non-finite or singular there: take a larger tol or a higher "
                    "taylor_order); stopped at the last successful time %.17g", function,
                    inst->s.integer[INT_taylor_order], tol, reached, reason, reached);
    else
        log_discard(inst, "%s: %s with tol = %g: the step size underflowed at t = %.17g%s (the "
                    "state is non-finite, singular or too stiff there); stopped at the last successful "
                    "time %.17g", function, method, tol, reached, reason, reached);
    return STATUS_DISCARD;
}

/* The work of a call, into the counters. */
static void count_work(IntegratorMemory *memory, const RightHandSide *f)
{
    memory->n_rhs += f->evaluations;
    memory->n_jacobians += f->jacobians;
    memory->n_iterations += f->iterations;
}

/* J = df/dx and dx = f at (t, x) with inputs u (NULL: zero), a column of J per state from the model's exact
 * directional derivative. */
static void jacobian_at(void *context, double t, const double *x, const double *u, double *J, double *dx)
{
    const Instance *inst = (const Instance *)context;
    double real[N_REAL], change[N_REAL], ddx[STATE_SLOTS];
    double seed[STATE_SLOTS] = {0}, seed_u[INPUT_SLOTS] = {0}, zero[INPUT_SLOTS] = {0};
    int i, j;
    memcpy(real, inst->s.real, sizeof real);
    memcpy(real, x, N_STATES * sizeof(double));
    scatter_inputs(real, u ? u : zero);
    model_equations(&inst->constants, t, x, u, dx);
    for (j = 0; j < N_STATES; j++) {
        seed[j] = 1.0;
        model_directional(&inst->constants, t, real, dx, seed, seed_u, ddx, change);
        seed[j] = 0.0;
        for (i = 0; i < N_STATES; i++) J[i * N_STATES + j] = ddx[i];
    }
#if N_CONSTRAINTS > 0 && N_COMPLIANT > 0
    compliant_jacobian(&inst->constants, t, x, J); /* the free equations' J lacks the contacts' stiffness */
#endif
}

/* The adaptive methods: rkf45, gbs, and taylor with tol > 0. */
static double adaptive_pass(RightHandSide *f, int solver, IntegratorMemory *memory, double *x, double t, double t_end,
                            double h, double tol, int check_each)
{
    if (solver == SOLVER_TAYLOR) return integrate_taylor(f, memory, x, t, t_end, tol, check_each);
    if (solver == SOLVER_GBS) return integrate_extrapolation(f, memory, x, t, t_end, h, tol, check_each);
    return integrate_adaptive(f, memory, x, t, t_end, h, tol, check_each);
}

#if N_CONSTRAINTS > 0
#include <float.h>

/* Steps with events: each substep is taken, then the event indicators are compared at its ends. Where
 * one crossed, the event time is found on the method's own step map (one step from the substep's start
 * over theta, solved for the indicator's zero by the Illinois variant of regula falsi), so that the
 * state at the event has the method's order; the event is resolved there (impacts, activations,
 * releases), and the rest of the substep is taken from it. Adams-Bashforth methods take their
 * Runge-Kutta starter for these partial steps and restart their history after an event. */
typedef struct {
    Instance *inst;
    RightHandSide *f;
    int solver, adaptive;
    double h, tol;
    /* the step's start, and the constraints it departs from (constraint_departs), decided where they cross */
    const double *x_start;
    double t_start;
    int32_t departing, decided;
    int short_of; /* a trial step of an adaptive method stopped short: the call stops */
    /* An Adams method's history after the step that crossed (its newest entry f at the step's start), while
     * its event is located; NULL otherwise */
    const IntegratorMemory *history;
    double hs;
    /* f at the step's start (t_start, x_start) where known: a method of steps_from_slope takes its trial steps from
     * it, and the step's interpolant its accelerations there */
    int slope_known;
    double slope[STATE_SLOTS];
} EventStepper;

static const double *inputs_at(const RightHandSide *f, double t, double *u)
{
    int i;
    for (i = 0; i < N_INPUTS; i++) u[i] = f->u0[i] + (t - f->t0) * f->du[i];
    return f->forces ? u : NULL;
}

static void indicators_at(const EventStepper *e, double t, const double *x, double *z)
{
    double u[INPUT_SLOTS];
    /* a resting or taut constraint's indicator is its force: an evaluation */
    e->f->evaluations += (uint64_t)constraint_indicators(&e->inst->constants, e->inst->s.active_constraints, t, x,
                                                         inputs_at(e->f, t, u), z);
}

/* f at the step's start, evaluated at the first need only. */
static const double *start_slope(EventStepper *e)
{
    if (!e->slope_known) {
        slope_at(e->f, e->solver, e->t_start, e->x_start, e->slope);
        e->slope_known = 1;
    }
    return e->slope;
}

/* w_j = the integral from 0 to sigma of the polynomial that is 1 at nodes[j] and 0 at the other nodes (in units of
 * the step): an Adams method's weights over a fraction sigma of its step. */
static void adams_fraction(const double *nodes, int n, double sigma, double *w)
{
    int j, i, m;
    for (j = 0; j < n; j++) {
        double poly[AB_MAX_STEPS + 1] = {1.0}, scale = 1.0, power = sigma, integral = 0.0;
        int degree = 0;
        for (i = 0; i < n; i++) {
            if (i == j) continue;
            for (m = degree + 1; m >= 1; m--) poly[m] = poly[m - 1] - nodes[i] * poly[m]; /* times (u - node i) */
            poly[0] *= -nodes[i];
            degree++;
            scale *= nodes[j] - nodes[i];
        }
        for (m = 0; m <= degree; m++, power *= sigma) integral += poly[m] * power / (m + 1);
        w[j] = integral / scale;
    }
}

/* An Adams method's step over theta (at most its step hs) from (t, x0), on its own polynomials from the history e->history
 * (newest first: f at t, t - hs, ...): Adams-Bashforth's x0 + hs sum_j beta_j(sigma) f_j, sigma = theta / hs, then for
 * the predictor-corrector methods Adams-Moulton's on the predicted point's f (one evaluation). At theta = hs these
 * are the method's own steps; inside, their error is of the method's order. */
static void adams_trial_step(EventStepper *e, const double *x0, double t, double theta, double *x)
{
    const AdamsBashforth *ab = adams_bashforth_of(e->solver);
    const IntegratorMemory *m = e->history;
    const double sigma = theta / e->hs;
    /* nodes set to 0 first: gcc cannot see that the loops below fill what adams_fraction reads */
    double nodes[AB_MAX_STEPS] = {0}, w[AB_MAX_STEPS], slope[STATE_SLOTS], u[INPUT_SLOTS];
    int j, q;
    for (j = 0; j < ab->steps; j++) nodes[j] = -j;
    adams_fraction(nodes, ab->steps, sigma, w);
    for (q = 0; q < N_STATES; q++) {
        double sum = 0.0;
        for (j = 0; j < ab->steps; j++) sum += w[j] * m->ab_history[(m->ab_head - j + AB_MAX_STEPS) % AB_MAX_STEPS][q];
        x[q] = x0[q] + e->hs * sum;
    }
    if (!ab->corrected) return;
    model_equations(&e->inst->constants, t + theta, x, inputs_at(e->f, t + theta, u), slope);
    e->f->evaluations++;
    nodes[0] = sigma; /* the predicted point, then the history's newest ab->steps - 1 */
    for (j = 1; j < ab->steps; j++) nodes[j] = 1 - j;
    adams_fraction(nodes, ab->steps, sigma, w);
    for (q = 0; q < N_STATES; q++) {
        double sum = w[0] * slope[q];
        for (j = 1; j < ab->steps; j++)
            sum += w[j] * m->ab_history[(m->ab_head - (j - 1) + AB_MAX_STEPS) % AB_MAX_STEPS][q];
        x[q] = x0[q] + e->hs * sum;
    }
}

/* x = the method's step of theta from (t, x0), with the integrator memory `memory` left as it was. An adaptive
 * method that stops short (out of budget, its step underflowed) sets e->short_of. */
static void trial_step(EventStepper *e, const IntegratorMemory *memory, const double *x0, double t,
                       double theta, double *x)
{
    IntegratorMemory scratch = *memory;
    memcpy(x, x0, STATE_SLOTS * sizeof(double));
    if (e->history && theta <= e->hs) { /* inside an Adams step: on its own polynomials, from its history */
        adams_trial_step(e, x0, t, theta, x);
        return;
    }
    if (e->adaptive) {
        if (adaptive_pass(e->f, e->solver, &scratch, x, t, t + theta, e->h, e->tol, 0) < t + theta) e->short_of = 1;
    } else if (steps_from_slope(e->solver) && x0 == e->x_start && t == e->t_start) {
        step_from_slope(e->f, e->solver, &scratch, x, t, theta, start_slope(e));
    } else {
        scratch.ab_count = 0;
        if (integrate_fixed(e->f, e->solver, &scratch, x, t, theta, 0, 1, 0) < 1) e->short_of = 1; /* Newton failed */
    }
}

static int crossed(EventStepper *e, int k, double before, double after)
{
    const int32_t bit = (int32_t)1 << k;
    if (!indicator_crossed(&e->inst->constants, k, before, after)) return 0;
    if (!(e->decided & bit)) { /* a touching constraint the motion leaves: its crossing is the method's error */
        double u[INPUT_SLOTS];
        e->decided |= bit;
        if (before <= CONTACT_GAP && constraint_departs(&e->inst->constants, e->inst->s.active_constraints, k,
                                                        e->t_start, e->x_start, inputs_at(e->f, e->t_start, u)))
            e->departing |= bit;
    }
    return !(e->departing & bit);
}

/* Whether a rigid constraint acts (bilateral, or resting or taut): the steps' ends are projected onto it. */
static int rigid_acting(const ModelConst *c, int32_t active)
{
    int i;
    for (i = 0; i < N_CONSTRAINTS; i++)
        if (!c->law[i].compliant && (c->law[i].bilateral || (active >> i & 1))) return 1;
    return 0;
}

/* A step from (t, x0): its start for the departing constraints, and the indicators there (z, or those the last
 * step ended with where nothing moved the state since: `reuse`). */
static void start_of_step(EventStepper *e, double t, const double *x0, double *z, const double *reuse)
{
    e->x_start = x0;
    e->t_start = t;
    e->slope_known = 0;
    e->departing = e->decided = 0;
    if (reuse)
        memcpy(z, reuse, N_CONSTRAINTS * sizeof(double));
    else
        indicators_at(e, t, x0, z);
}

/* The state at offset theta in [0, span] on the quintic Hermite interpolant of a step from x0 to x1 whose
 * accelerations at its ends are a0 and a1: positions to O(span^6), velocities (the interpolant's derivative) to
 * O(span^5). Costs no evaluation of the equations, so events are found on it first. */
static void interpolate(const double *x0, const double *a0, const double *x1, const double *a1, double span,
                        double theta, double *x)
{
    const double s = theta / span, s2 = s * s, s3 = s2 * s, s4 = s3 * s, s5 = s4 * s, h2 = span * span;
    const double b[6] = {1.0 - 10.0 * s3 + 15.0 * s4 - 6.0 * s5, s - 6.0 * s3 + 8.0 * s4 - 3.0 * s5,
                         0.5 * (s2 - 3.0 * s3 + 3.0 * s4 - s5), 10.0 * s3 - 15.0 * s4 + 6.0 * s5,
                         -4.0 * s3 + 7.0 * s4 - 3.0 * s5, 0.5 * (s3 - 2.0 * s4 + s5)};
    const double d[6] = {-30.0 * s2 + 60.0 * s3 - 30.0 * s4, 1.0 - 18.0 * s2 + 32.0 * s3 - 15.0 * s4,
                         0.5 * (2.0 * s - 9.0 * s2 + 12.0 * s3 - 5.0 * s4), 30.0 * s2 - 60.0 * s3 + 30.0 * s4,
                         -12.0 * s2 + 28.0 * s3 - 15.0 * s4, 0.5 * (3.0 * s2 - 8.0 * s3 + 5.0 * s4)};
    int j;
    for (j = 0; j < N_COORDINATES; j++) {
        const double q0 = x0[j], v0 = x0[N_COORDINATES + j], q1 = x1[j], v1 = x1[N_COORDINATES + j];
        x[j] = b[0] * q0 + b[1] * span * v0 + b[2] * h2 * a0[j] + b[3] * q1 + b[4] * span * v1 + b[5] * h2 * a1[j];
        x[N_COORDINATES + j] = (d[0] * q0 + d[1] * span * v0 + d[2] * h2 * a0[j] + d[3] * q1 + d[4] * span * v1 +
                                d[5] * h2 * a1[j]) / span;
    }
}

/* The accelerations at (t, x), counted as an evaluation. */
static void accelerations_at(const EventStepper *e, double t, const double *x, double *a)
{
    double dx[N_STATES], u[INPUT_SLOTS];
    model_equations(&e->inst->constants, t, x, inputs_at(e->f, t, u), dx);
    e->f->evaluations++;
    memcpy(a, dx + N_COORDINATES, N_COORDINATES * sizeof(double));
}

/* Whether indicator k at `value` lies on the far side of its event from where the step began (z0): the side a
 * located event must end on, so that handling it sees the contact or the release. */
static int past(const EventStepper *e, int k, double value, double start)
{
    return e->inst->constants.law[k].compliant ? (value > -GAP_ROUNDING) != (start > -GAP_ROUNDING) : value <= 0.0;
}

/* Indicator k's zero in [lo, hi] on the interpolant (Illinois), from zlo (not past) to zhi (past). */
static double zero_on_interpolant(const EventStepper *e, int k, double t, double span, const double *x0,
                                  const double *a0, const double *x1, const double *a1, double z0k, double lo,
                                  double zlo, double hi, double zhi)
{
    double xt[STATE_SLOTS], zt[N_CONSTRAINTS];
    int iteration, side = 0;
    for (iteration = 0; iteration < 100 && hi - lo > 4.0 * DBL_EPSILON * (fabs(t) + span); iteration++) {
        double theta = hi - zhi * (hi - lo) / (zhi - zlo);
        if (!(theta > lo && theta < hi)) theta = 0.5 * (lo + hi);
        interpolate(x0, a0, x1, a1, span, theta, xt);
        indicators_at(e, t + theta, xt, zt);
        if (past(e, k, zt[k], z0k)) {
            hi = theta;
            zhi = zt[k];
            if (side == 1) zlo *= 0.5; /* Illinois: the retained end's value halved */
            side = 1;
        } else {
            lo = theta;
            zlo = zt[k];
            if (side == -1) zhi *= 0.5;
            side = -1;
        }
    }
    return hi;
}

/* The first event in (t, t + span] of the step from x0 (indicators z0) to x1, whose indicators crossed: found on
 * the step's interpolant, then on the method's own step map (so that every method keeps its order through
 * impacts) by a Newton step or two from there. Leaves the state at the event in x (past it by at most the
 * indicator's rounding) and returns the event's offset from t. Typically costs two evaluations and one or two
 * trial steps. */
static double locate_event(EventStepper *e, const IntegratorMemory *memory, const double *x0, double t,
                           double span, const double *z0, const double *x1, double *x)
{
    double a0[N_COORDINATES], a1[N_COORDINATES], z1[N_CONSTRAINTS], zt[N_CONSTRAINTS], xt[STATE_SLOTS];
    double first = span, lo, hi, zlo, zhi, theta;
    int k = -1, j, trial;
    if (e->history) /* f at the step's start is the history's newest entry */
        memcpy(a0, e->history->ab_history[e->history->ab_head] + N_COORDINATES, sizeof a0);
    else if (!e->adaptive && steps_from_slope(e->solver) && x0 == e->x_start && t == e->t_start)
        slope_accelerations(e->f, e->solver, start_slope(e), x0, a0);
    else if (e->f->kept_jacobian && e->f->kept_jacobian->valid && t == e->f->kept_jacobian->t &&
             memcmp(x0, e->f->kept_jacobian->x, N_STATES * sizeof(double)) == 0) /* an implicit step's start */
        memcpy(a0, e->f->kept_jacobian->slope + N_COORDINATES, sizeof a0);
    else
        accelerations_at(e, t, x0, a0);
    accelerations_at(e, t + span, x1, a1);
    indicators_at(e, t + span, x1, z1);
    for (j = 0; j < N_CONSTRAINTS; j++) {
        double start = 0.0, zstart = z0[j], found;
        if (!crossed(e, j, z0[j], z1[j])) continue;
        if (!e->inst->constants.law[j].compliant && !(zstart > 0.0)) {
            /* a rigid gap that starts touching (just after an impact) and returns within the step: from a point
             * where it is open */
            double probe = span;
            int open = 0, halving;
            for (halving = 0; halving < 60 && !open; halving++) {
                probe *= 0.5;
                interpolate(x0, a0, x1, a1, span, probe, xt);
                indicators_at(e, t + probe, xt, zt);
                if (zt[j] > 0.0) {
                    start = probe;
                    zstart = zt[j];
                    open = 1;
                }
            }
            if (!open) { /* touching all along: the event is at the start */
                memcpy(x, x0, STATE_SLOTS * sizeof(double));
                return 0.0;
            }
        }
        found = zero_on_interpolant(e, j, t, span, x0, a0, x1, a1, z0[j], start, zstart, span, z1[j]);
        if (k < 0 || found < first) {
            k = j;
            first = found;
        }
    }
    if (k < 0) { /* no crossing after all (rounding): the step's end */
        memcpy(x, x1, STATE_SLOTS * sizeof(double));
        return span;
    }
    /* onto the step map: Newton steps, kept inside a bracket [lo, hi] whose hi end is past the event, with the slope
     * of the interpolant bent through the last trial (the step map and the interpolant agree at the step's ends, so
     * their difference goes as theta (span - theta) times a smooth function, taken constant from the last trial: the
     * bent curve's slope is the step map's to a higher order than the interpolant's, and a few trials reach the
     * event). Each Newton step aims at half the tolerance past the event, so that it lands past it. A compliant
     * contact's onset and end (Hertz's delta^1.5, whose higher derivatives are unbounded there) keep the
     * interpolant's own slope and, where a trial falls short, a step twice as far: in a row of touching balls the
     * located times decide which contact opens first, and the Windows binaries (another libm) agree with Linux's
     * to 1e-11 this way. */
    {
        const int compliant = e->inst->constants.law[k].compliant;
        const double tolerance = 1e-14 * fmax(1.0, fabs(z0[k]));
        const double aim = compliant ? 0.0 : -0.5 * tolerance;
        double bend[STATE_SLOTS] = {0.0};
        lo = 0.0;
        hi = span;
        zlo = z0[k];
        zhi = z1[k];
        memcpy(x, x1, STATE_SLOTS * sizeof(double));
        theta = first;
        for (trial = 0; trial < 60 && hi - lo > 4.0 * DBL_EPSILON * (fabs(t) + span); trial++) {
            double slope, zp[N_CONSTRAINTS], zm[N_CONSTRAINTS], xp[STATE_SLOTS], xm[STATE_SLOTS], next, width;
            const double delta = 1e-6 * span, up = fmin(theta + delta, span), down = fmax(theta - delta, 0.0);
            int q;
            trial_step(e, memory, x0, t, theta, xt);
            indicators_at(e, t + theta, xt, zt);
            if (past(e, k, zt[k], z0[k])) {
                hi = theta;
                zhi = zt[k];
                memcpy(x, xt, STATE_SLOTS * sizeof(double));
                if (fabs(zt[k]) <= tolerance) break;
            } else {
                lo = theta;
                zlo = zt[k];
            }
            width = theta * (span - theta);
            if (width > 0.0 && !compliant) { /* the bend that takes the interpolant through this trial */
                interpolate(x0, a0, x1, a1, span, theta, xp);
                for (q = 0; q < N_STATES; q++) bend[q] = (xt[q] - xp[q]) / width;
            }
            interpolate(x0, a0, x1, a1, span, up, xp);
            interpolate(x0, a0, x1, a1, span, down, xm);
            for (q = 0; q < N_STATES; q++) {
                xp[q] += up * (span - up) * bend[q];
                xm[q] += down * (span - down) * bend[q];
            }
            indicators_at(e, t + up, xp, zp);
            indicators_at(e, t + down, xm, zm);
            slope = (zp[k] - zm[k]) / (up - down);
            next = theta - (zt[k] - aim) / slope;
            if (compliant && !past(e, k, zt[k], z0[k])) /* to land past the event: a little beyond the zero */
                next += fmax(fabs(zt[k] / slope), 4.0 * DBL_EPSILON * (fabs(t) + span));
            if (!(next > lo && next < hi) || !isfinite(next)) next = hi - zhi * (hi - lo) / (zhi - zlo);
            if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
            if (e->adaptive && t + next <= t + lo) { /* far from t = 0 a correction can be below the time's rounding */
                next = nextafter(t + lo, INFINITY) - t;
                if (!(t + next < t + hi)) break;
            }
            theta = next;
        }
    }
    return hi;
}

/* A contact that closes and opens again between two comparisons (a ball through another within one long step)
 * changes no indicator's sign. An open contact's gap that approaches at the step's start and recedes at its end
 * may dip inside: below the tangents at the two ends, where they meet, lies the least value a convex gap can take
 * (a V for balls that pass through each other, a parabola for a near miss). Where that lies past contact, the step
 * is tried up to that point; a crossing there is an event like any other, and without one the side on which the
 * gap still approaches and recedes is searched the same way. Returns the offset of the first crossing found (x1
 * and z1 then the trial's state and indicators), or 0 where there is none. Costs the gaps' rates at the step's
 * ends (r0 those at its start where known, else NULL), which it leaves in r1 for the next step, and a trial step
 * with the gaps' rates per point tried. */
#define DIP_TRIALS 8
static double dip_within(EventStepper *e, const IntegratorMemory *memory, const double *x0, double t, double span,
                         const double *z0, const double *r0, double *x1, double *z1, double *r1)
{
    const ModelConst *c = &e->inst->constants;
    const int32_t active = e->inst->s.active_constraints;
    double g0[N_CONSTRAINTS], start[N_CONSTRAINTS], g1[N_CONSTRAINTS], best = 0.0;
    double found_x[STATE_SLOTS] = {0.0}, found_z[N_CONSTRAINTS] = {0.0};
    int k, j;
    if (r0)
        memcpy(start, r0, sizeof start); /* r0 may be r1, which the end's rates overwrite */
    else
        model_gap_rates(c, t, x0, g0, start);
    model_gap_rates(c, t + span, x1, g1, r1);
    for (k = 0; k < N_CONSTRAINTS; k++) {
        double a = 0.0, ga = z0[k], ra = start[k], b = span, gb = z1[k], rb = r1[k];
        int trial;
        if (c->law[k].bilateral || (active >> k & 1) || !(ga > 0.0) || !(gb > 0.0)) continue;
        for (trial = 0; trial < DIP_TRIALS && ra < 0.0 && rb > 0.0 && (best == 0.0 || a < best); trial++) {
            const double meet = (gb - ga + ra * a - rb * b) / (ra - rb);
            double xt[STATE_SLOTS], zt[N_CONSTRAINTS], gt[N_CONSTRAINTS], rt[N_CONSTRAINTS];
            int any = 0;
            if (!(meet > a && meet < b) || !(ga + ra * (meet - a) < -GAP_ROUNDING)) break;
            /* a fixed-step method's trials stay within the call's bound (an adaptive one's pass checks its own) */
            if (!e->adaptive &&
                e->f->evaluations + e->f->checks + (uint64_t)evaluations_needed(e->solver, 0, 1.0, e->f) > e->f->budget) {
                e->f->out_of_budget = 1;
                e->short_of = 1;
                return 0.0;
            }
            trial_step(e, memory, x0, t, meet, xt);
            if (e->short_of) return 0.0;
            indicators_at(e, t + meet, xt, zt);
            for (j = 0; j < N_CONSTRAINTS; j++) any |= crossed(e, j, z0[j], zt[j]);
            if (any) {
                best = meet;
                memcpy(found_x, xt, sizeof found_x);
                memcpy(found_z, zt, sizeof found_z);
                break;
            }
            model_gap_rates(c, t + meet, xt, gt, rt);
            if (rt[k] < 0.0) { /* still approaching there: the dip, if any, lies after */
                a = meet;
                ga = gt[k];
                ra = rt[k];
            } else {
                b = meet;
                gb = gt[k];
                rb = rt[k];
            }
        }
    }
    if (best > 0.0) {
        memcpy(x1, found_x, sizeof found_x);
        memcpy(z1, found_z, sizeof found_z);
    }
    return best;
}

/* The history an Adams step that crossed (not its starter's) takes its trial steps from, on its polynomial; NULL
 * for the other methods. */
static const IntegratorMemory *adams_history(const EventStepper *e, const IntegratorMemory *memory)
{
    const AdamsBashforth *ab = e->adaptive ? NULL : adams_bashforth_of(e->solver);
    return ab && memory->ab_count >= ab->steps ? memory : NULL;
}

/* A method stopped short inside a substep with events: the state and the integrator memory go back to where they
 * were at ta (x0, m0), and the call ends there. */
static Status stopped_at(Instance *inst, const char *function, RightHandSide *f, int solver, double t, double ta,
                         double *x, const double *x0, IntegratorMemory *memory, const IntegratorMemory *m0)
{
    memcpy(x, x0, STATE_SLOTS * sizeof(double));
    *memory = *m0;
    count_work(memory, f);
    return stopped_short(inst, function, f, solver, t, ta);
}

#if N_COMPLIANT > 0
/* How much an oscillation grows over one period at y = h omega with `solver` (over one step where a step is longer). */
static double period_growth(const EventStepper *e, double y)
{
    const double growth = oscillation_growth(e->solver, e->f, y);
    return growth > 0.0 ? pow(growth, fmax(1.0, 6.283185307179586 / y)) : 0.0;
}

/* A fixed step of an explicit method must follow the compliant contacts' oscillation: where h omega lies beyond the
 * method's stability there, every step multiplies it (rk4: for h omega > 2.83) and energy appears from nothing. A
 * step from x at t (a step's start, or an onset) is refused where the oscillation the contacts that overlap or close
 * within it will reach would grow more than 2-fold per period: writes why into message and returns 1. */
static int too_stiff(const EventStepper *e, double t, const double *x, char *message, size_t size)
{
    double omega, low = 0.0, high, growth;
    int k, contact;
    if (!(oscillation_growth(e->solver, e->f, 1.0) > 0.0)) return 0; /* a method this does not cover */
    contact = compliant_frequency(&e->inst->constants, t, x, e->hs, &omega);
    if (contact < 0 || !(omega > 0.0)) return 0;
    high = e->hs * omega;
    growth = period_growth(e, high);
    if (!(growth > 2.0)) return 0;
    for (k = 0; k < 60; k++) { /* the largest h omega within 2-fold */
        const double middle = 0.5 * (low + high);
        if (period_growth(e, middle) > 2.0) high = middle;
        else low = middle;
    }
    snprintf(message, size, "the compliant contact %s at t = %.17g is too stiff for %s at h = %g: its oscillation from there "
             "(angular frequency up to %g rad/s at full compression) grows %.3g-fold per period, where h at most %.3g keeps it within "
             "2-fold (or take an implicit or an adaptive method)", CONSTRAINT_NAMES[contact], t,
             solver_name(e->solver), e->hs, omega, growth, low / omega);
    return 1;
}

/* A fixed step from x at ta, which the contacts it meets make too stiff for h (too_stiff): the call ends at ta. */
static int stiffness_refused(Instance *inst, const char *function, const EventStepper *e, RightHandSide *f, double t,
                             double ta, const double *x)
{
    char message[600];
    if (e->adaptive || !too_stiff(e, ta, x, message, sizeof message)) return 0;
    count_work(&inst->s.integrator, f);
    finish(inst, t, ta - t, ta);
    log_discard(inst, "%s: %s; stopped there (last successful time %.17g)", function, message, ta);
    return 1;
}
#endif

static Status step_with_events(Instance *inst, const char *function, RightHandSide *f, int solver, double t, double H)
{
    SimState *s = &inst->s;
    IntegratorMemory *memory = &s->integrator;
    const ModelConst *c = &inst->constants;
    EventStepper e;
    double *x = s->real;
    double z0[N_CONSTRAINTS], z1[N_CONSTRAINTS], checked[N_REAL], u[INPUT_SLOTS];
    const double t_end = t + H;
    const uint64_t events_before = memory->n_events;
    int64_t n, i;
    int reuse, rates_known = 0;
    KeptJacobian kept; /* the implicit methods' Jacobian at a step's start, for the trial steps from there */
    double hs, reached, rates[N_CONSTRAINTS] = {0.0}; /* the gaps' rates where the last step ended (adaptive methods) */
    double x_call[STATE_SLOTS]; /* the call's start, with m_call and active_call */
    const IntegratorMemory m_call = *memory;
    const int32_t active_call = s->active_constraints;
    e.inst = inst;
    e.f = f;
    e.solver = solver;
    e.h = s->real[VR_h];
    e.tol = s->real[VR_tol];
    e.short_of = 0;
    e.history = NULL;
    kept.valid = 0;
    f->kept_jacobian = &kept;
    memcpy(x_call, x, sizeof x_call);
    e.adaptive = adaptive_method(solver, e.tol);
    {
        char message[512];
        if (free_motion_refused(solver, s->active_constraints, "at", t, message, sizeof message)) {
            log_discard(inst, "%s: %s; nothing was done (last successful time %.17g)", function, message, t);
            return STATUS_DISCARD;
        }
    }
    n = (int64_t)fmax(1.0, ceil(H / e.h - 1e-9));
    hs = H / (double)n;
    e.hs = hs;
    if (!e.adaptive) {
        /* each substep, and at most an event's location per substep */
        const double work = 2.0 * evaluations_needed(solver, 0, (double)n, f) + (double)n;
        if (work > MAX_EVALUATIONS_PER_CALL) {
            log_error(inst, "%s: communicationStepSize = %g with %s at h = %g needs %.0f right-hand-side "
                      "evaluations with its event checks (allowed at most %.0f per call): raise h or shorten the "
                      "step", function, H, solver_name(solver), e.h, work, MAX_EVALUATIONS_PER_CALL);
            return STATUS_ERROR;
        }
        if (memory->ab_count > 0 && fabs(hs - memory->ab_step) > 1e-10 * hs) memory->ab_count = memory->ab_restarted = 0;
        memory->ab_step = hs;
    }
    /* An adaptive method's indicators are compared at each of its own steps (at most h long): a gap that closes
     * and opens again between two comparisons (a ball through another) is missed, so h bounds the time between
     * them. */
    for (i = 0, reuse = 0, reached = t; e.adaptive ? reached < t_end : i < n; i++) {
        double ta = e.adaptive ? reached : t + (double)i * hs;
        /* an adaptive method's substep ends where its one step does, at most h on */
        double tb = e.adaptive ? (ta + 1.001 * e.h >= t_end ? t_end : ta + e.h)
                               : i + 1 == n ? t_end : t + (double)(i + 1) * hs;
        double x0[STATE_SLOTS];
        IntegratorMemory m0 = *memory;
        uint64_t events_seen = memory->n_events;
        int32_t active_seen = s->active_constraints;
        int any, k, stalls = 0, remainder = 0;
        double step_end; /* a fixed-step method's step ends here, whatever it finds inside */
        memcpy(x0, x, sizeof x0);
        start_of_step(&e, ta, x0, z0, reuse ? z1 : NULL);
#if N_COMPLIANT > 0
        if (stiffness_refused(inst, function, &e, f, t, ta, x)) return STATUS_DISCARD; /* the contacts it meets */
#endif
        if (e.adaptive) {
            f->single_step = 1;
            tb = adaptive_pass(f, solver, memory, x, ta, tb, e.h, e.tol, 0);
            f->single_step = 0;
            if (!(tb > ta)) { /* no step accepted: out of budget, or the step fell below the resolution of time */
                return stopped_at(inst, function, f, solver, t, ta, x, x0, memory, &m0);
            }
        } else if (steps_from_slope(solver)) { /* its f at the start stays for the event's trial steps */
            step_from_slope(f, solver, memory, x, ta, hs, start_slope(&e));
        } else if (integrate_fixed(f, solver, memory, x, t, hs, i, 1, 0) < 1) { /* Newton's iteration failed */
            memcpy(x, x0, sizeof x0);
            *memory = m0;
            count_work(memory, f);
            return fail(inst, function, t, ta, solver_name(solver), e.h, f->unconverged, NULL);
        }
        if (!model_state_ok(c, x)) {
            memcpy(x, x0, sizeof x0);
            *memory = m0;
            count_work(memory, f);
            return fail(inst, function, t, ta, solver_name(solver), e.h, f->unconverged, f->refused_known ? f->refused : NULL);
        }
        indicators_at(&e, tb, x, z1);
        step_end = tb;
        for (any = 0, k = 0; k < N_CONSTRAINTS; k++) any |= crossed(&e, k, z0[k], z1[k]);
        if (!any) { /* a contact may close and open again inside the step */
            double dip;
            e.history = adams_history(&e, memory);
            dip = dip_within(&e, &m0, x0, ta, tb - ta, z0, reuse && rates_known ? rates : NULL, x, z1, rates);
            e.history = NULL;
            rates_known = dip == 0.0;
            if (e.short_of) return stopped_at(inst, function, f, solver, t, ta, x, x0, memory, &m0);
            if (dip > 0.0) {
                tb = ta + dip;
                any = 1;
            }
        } else {
            rates_known = 0; /* an event moves the state from where its rates were */
        }
        while (any) {
            double located[STATE_SLOTS], theta;
            const int32_t active_before = s->active_constraints;
            memcpy(located, x, sizeof located); /* the step's end, past the event */
            e.history = adams_history(&e, memory);
            theta = locate_event(&e, &m0, x0, ta, tb - ta, z0, located, x);
            e.history = NULL;
            if (!e.adaptive) tb = step_end; /* a dip was searched up to where the tangents met: the rest goes on */
            if (e.short_of) { /* a trial step stopped short: the event is not located; back to the step's start */
                return stopped_at(inst, function, f, solver, t, ta, x, x0, memory, &m0);
            }
            ta += theta;
            *memory = m0;
            memory->ab_count = 0;
            memory->ab_restarted = 1;
            if (!e.adaptive && theta > 0.0) memory->n_steps++; /* the step onto the event */
            memcpy(located, x, sizeof located);
            kept.valid = 0; /* the constraints acting may change */
            if (!leave_boundary(c, s->active_constraints, e.departing, ta, x) ||
                !handle_event(c, &s->active_constraints, ta, x, inputs_at(f, ta, u), &memory->n_events) ||
                !model_state_ok(c, x)) {
                memcpy(x, located, sizeof located); /* the state the event was found in, as it was */
                s->active_constraints = active_before;
                memory->n_events = m0.n_events;
                count_work(memory, f);
                {
                    double good = ta;
                    if (!evaluate_at(inst, ta, x, checked)) { /* its outputs overflow: back to the call's start */
                        memcpy(x, x_call, sizeof x_call);
                        *memory = m_call;
                        s->active_constraints = active_call;
                        good = t;
                    }
                    finish(inst, t, good - t, good);
                    log_discard(inst, "%s: the constraints at t = %.17g are dependent (an impact or a contact force has "
                                "no unique solution); stopped at the last successful time %.17g", function, ta, good);
                }
                return STATUS_DISCARD;
            }
            {
                char message[512];
                if (free_motion_refused(solver, s->active_constraints, "from", ta, message, sizeof message)) {
                    count_work(memory, f);
                    finish(inst, t, ta - t, ta);
                    log_discard(inst, "%s: %s; stopped there (last successful time %.17g)", function, message, ta);
                    return STATUS_DISCARD;
                }
            }
#if N_COMPLIANT > 0
            if (stiffness_refused(inst, function, &e, f, t, ta, x)) return STATUS_DISCARD; /* the contact begun */
#endif
            /* events found again and again where they change nothing: stop rather than spin */
            stalls = memory->n_events == events_seen && s->active_constraints == active_seen ? stalls + 1 : 0;
            events_seen = memory->n_events;
            active_seen = s->active_constraints;
            if (stalls > 2) {
                count_work(memory, f);
                finish(inst, t, ta - t, ta);
                log_discard(inst, "%s: an event at t = %.17g recurs at once after it was handled (the state cannot leave "
                            "the constraint's boundary with %s at h = %g); stopped there (last successful time %.17g)",
                            function, ta, solver_name(solver), e.h, ta);
                return STATUS_DISCARD;
            }
            if (memory->n_events - events_before > MAX_EVENTS_PER_CALL) {
                count_work(memory, f);
                finish(inst, t, ta - t, ta);
                log_discard(inst, "%s: %d events within this step, the most one call handles; stopped at t = %.17g "
                            "(last successful time %.17g): take a shorter communication step", function,
                            MAX_EVENTS_PER_CALL, ta, ta);
                return STATUS_DISCARD;
            }
            memcpy(x0, x, sizeof x0);
            m0 = *memory;
            start_of_step(&e, ta, x0, z0, NULL);
            if (inst->return_at_events && ta > t && ta < t_end && memory->n_events > events_before) { /* FMI 3.0 */
                count_work(memory, f);
                f->checks++;
                if (!evaluate_at(inst, ta, x, checked)) return fail(inst, function, t, ta, solver_name(solver), e.h, 0, x);
                return finish_with(inst, t, ta - t, checked, f->inputs_vary);
            }
            any = 0;
            remainder = 0;
            if (tb - ta > 4.0 * DBL_EPSILON * fabs(tb)) {
                remainder = !e.adaptive;
                trial_step(&e, &m0, x0, ta, tb - ta, x);
                if (e.short_of) { /* the rest of the step stopped short: the call ends at the event */
                    return stopped_at(inst, function, f, solver, t, ta, x, x0, memory, &m0);
                }
                indicators_at(&e, tb, x, z1);
                for (k = 0; k < N_CONSTRAINTS; k++) any |= crossed(&e, k, z0[k], z1[k]);
            } else {
                memcpy(z1, z0, sizeof z1);
            }
        }
        memory->n_steps += (uint64_t)remainder; /* the rest of a step that had an event */
        if (!leave_boundary(c, s->active_constraints, e.departing, tb, x) ||
            !project_constraints(c, s->active_constraints, tb, x)) {
            count_work(memory, f);
            return fail(inst, function, t, ta, solver_name(solver), e.h, 0, NULL);
        }
        /* the next step starts with the indicators this one ended with, unless a projection moved the state */
        reuse = !e.departing && !rigid_acting(c, s->active_constraints);
        reached = tb;
        if (inst->report_step && inst->s.machine_state == MS_STEP_COMPLETE) state_acceptable(inst, tb, x);
    }
    count_work(memory, f);
    f->checks++;
    if (!evaluate_at(inst, t_end, x, checked)) { /* the call's start is its last good point: back there */
        double refused[STATE_SLOTS];
        memcpy(refused, x, sizeof refused);
        memcpy(x, x_call, sizeof x_call);
        *memory = m_call;
        s->active_constraints = active_call;
        return fail(inst, function, t, t, solver_name(solver), e.h, 0, refused);
    }
    return finish_with(inst, t, H, checked, f->inputs_vary);
}
#endif

Status step_to(Instance *inst, const char *function, double t, double H)
{
    SimState *s = &inst->s;
    IntegratorMemory *memory = &s->integrator;
    const int solver = s->integer[INT_solver];
    const double h = s->real[VR_h];
    /* Reporting internal steps checks each of them as it is taken, so that no report shows a state
     * that a failed step would take back. */
    const int reporting = inst->report_step != NULL;
    double *x = s->real; /* the states lead the Real variables */
    RightHandSide f;
    double checked[N_REAL];
    int i;

    take_slopes(s);
    f.model = &inst->constants;
    gather_inputs(inst, f.u0);
    f.inputs_vary = 0;
    f.forces = 0;
    for (i = 0; i < N_INPUTS; i++) { /* no branch per input */
        f.du[i] = s->input_derivative[i];
        f.inputs_vary |= f.du[i] != 0.0;
        f.forces |= f.u0[i] != 0.0;
    }
    f.forces |= f.inputs_vary;
    f.t0 = t;
    f.evaluations = 0;
    f.checks = 0;
    f.budget = (uint64_t)MAX_EVALUATIONS_PER_CALL - 1; /* one check of the end state stays in the budget */
    f.jacobians = 0;
    f.iterations = 0;
    f.unconverged = 0;
    f.out_of_budget = 0;
    f.taylor_order = s->integer[INT_taylor_order];
    f.gbs_columns = s->integer[INT_gbs_columns];
    f.single_step = 0;
    if (solver == SOLVER_TAYLOR && !inst->taylor_work) {
        inst->taylor_work =
            (double (*)[TAYLOR_SLOTS])inst->allocate(TAYLOR_SERIES + STATE_SLOTS, sizeof *inst->taylor_work);
        if (!inst->taylor_work) {
            log_error(inst, "%s: out of memory for the Taylor method's %d work series of %d coefficients", function,
                      TAYLOR_SERIES + STATE_SLOTS, TAYLOR_SLOTS);
            return STATUS_ERROR;
        }
    }
    f.taylor_work = inst->taylor_work;
    f.taylor_series = inst->taylor_work ? inst->taylor_work + TAYLOR_SERIES : NULL;
    f.taylor_cached = 0;
    f.acceptable = state_acceptable;
    f.jacobian = jacobian_at;
    f.kept_jacobian = NULL;
    f.refused_known = 0;
    f.context = inst;
    f.start_slope = NULL;

    /* the method's settings are checked also where a closed form (model = linear) takes the step */
    if (solver == SOLVER_RKF45 && !(s->real[VR_tol] > 0.0)) {
        log_error(inst, "%s: rkf45 needs a tolerance: variable tol = 0 is out of its range (0, 1] for rkf45 (tol = 0 "
                  "means a fixed step only for taylor and gbs)", function);
        return STATUS_ERROR;
    }
    if (solver == SOLVER_GBS && s->real[VR_tol] > 0.0 && s->real[VR_tol] < GBS_SMALLEST_TOL) {
        log_error(inst, "%s: gbs with tol = %g: out of reach in double precision (its columns agree to rounding "
                  "first); allowed for gbs: 0 (fixed step h) or [%g, 1]", function, s->real[VR_tol], GBS_SMALLEST_TOL);
        return STATUS_ERROR;
    }
#if HAS_LINEAR_MODEL
    if (inst->constants.linear) { /* only model = linear has a closed form */
        double u_mid[INPUT_SLOTS], closed[STATE_SLOTS];
        for (i = 0; i < N_INPUTS; i++) u_mid[i] = f.u0[i] + 0.5 * H * f.du[i];
        memcpy(closed, x, sizeof closed);
        if (model_closed_form_step(&inst->constants, H, u_mid, closed)) {
            if (!evaluate_at(inst, t + H, closed, checked)) return fail(inst, function, t, t, "closed form", H, 0, closed);
            memcpy(x, closed, sizeof closed);
            memory->n_steps++;
            return finish_with(inst, t, H, checked, f.inputs_vary);
        }
    }
#endif

#if N_CONSTRAINTS > 0
    return step_with_events(inst, function, &f, solver, t, H);
#endif
    if (adaptive_method(solver, s->real[VR_tol])) {
        const double t_end = t + H;
        double x_start[STATE_SLOTS];
        IntegratorMemory memory_start = *memory;
        double reached;
        memcpy(x_start, x, sizeof x_start);
        reached = adaptive_pass(&f, solver, memory, x, t, t_end, h, s->real[VR_tol], reporting);
        f.checks++;
        if (reporting) {
            if (reached == t_end && evaluate_at(inst, reached, x, checked)) {
                count_work(memory, &f);
                return finish_with(inst, t, H, checked, f.inputs_vary);
            }
        } else if (!evaluate_at(inst, reached, x, checked)) { /* outputs overflowed although the state stayed finite: redo, checking */
            memcpy(x, x_start, sizeof x_start);
            *memory = memory_start;
            /* the checking pass runs on what is left of the budget */
            reached = adaptive_pass(&f, solver, memory, x, t, t_end, h, s->real[VR_tol], 1);
        } else if (reached == t_end) {
            count_work(memory, &f);
            return finish_with(inst, t, H, checked, f.inputs_vary);
        }
        count_work(memory, &f);
        if (reached < t_end) return stopped_short(inst, function, &f, solver, t, reached);
        return finish(inst, t, H, t_end);
    } else {
        const double substeps = round_up(H / h - 1e-9);
        const double planned = substeps < 1.0 ? 1.0 : substeps;
        int64_t n, first;
        double hs = H / planned;
        /* The work of the whole call, the state checks included: the method's evaluations, one check per block
         * (or per substep when reporting), and the redo of one failing block with a check after each of its
         * substeps. At most twice the dearest substep's work plus two checks per substep: only a call near the
         * bound is counted exactly. */
        if (!(inst->substep_work > 0.0)) inst->substep_work = evaluations_needed(solver, 0, 1.0, &f);
        if (planned * (2.0 * inst->substep_work + 2.0) > MAX_EVALUATIONS_PER_CALL) {
            /* the Adams-Bashforth history survives only if the substep stays the same (below) */
            const int history = memory->ab_count > 0 && fabs(hs - memory->ab_step) <= 1e-10 * hs ? memory->ab_count : 0;
            const double redone = fmin(planned, (double)CHECK_BLOCK);
            const double work = evaluations_needed(solver, history, planned, &f) +
                                (reporting ? planned
                                           : ceil(planned / CHECK_BLOCK) + evaluations_needed(solver, 0, redone, &f) +
                                                 redone);
            if (work > MAX_EVALUATIONS_PER_CALL) {
                log_error(inst, "%s: communicationStepSize = %g with %s at h = %g needs %.0f right-hand-side "
                          "evaluations, its state checks included (allowed at most %.0f per call): raise h or shorten "
                          "the step", function, H, solver_name(solver), h, work, MAX_EVALUATIONS_PER_CALL);
                return STATUS_ERROR;
            }
        }
        n = substeps < 1.0 ? 1 : (int64_t)substeps;
        hs = H / (double)n;
        /* Adams-Bashforth history is only valid for the substep it was taken with. */
        if (memory->ab_count > 0 && fabs(hs - memory->ab_step) > 1e-10 * hs) memory->ab_count = memory->ab_restarted = 0;
        memory->ab_step = hs;
        /* The last call's end check evaluated f where this call starts, with these inputs: its derivatives are the
         * first substep's first evaluation (bit for bit: the same function of the same numbers, rounded to nearest;
         * in another mode the compiler's rewrites, exact only to nearest, may round the two apart). */
        if (inst->outputs_valid && inst->derivatives_current && t == s->time && !f.inputs_vary &&
            rounding_to_nearest(inst)
#if HAS_LINEAR_MODEL
            && !inst->constants.linear
#endif
        )
            f.start_slope = s->real + N_STATES;
        /* Blocks of CHECK_BLOCK substeps, each checked at its end: a failure is redone, checking every
         * substep, from the last good block only. */
        for (first = 0; first < n; first += CHECK_BLOCK) {
            const int64_t count = n - first < CHECK_BLOCK ? n - first : CHECK_BLOCK;
            const int last = first + count == n;
            const double t_block_end = last ? t + H : t + (double)(first + count) * hs;
            double x_block[STATE_SLOTS];
            IntegratorMemory memory_block = *memory;
            int64_t done;
            memcpy(x_block, x, sizeof x_block);
            if (reporting && !f.inputs_vary && reports_one_at_a_time(solver)) {
                done = report_substeps(inst, &f, solver, memory, x, t, hs, first, count, t_block_end);
                if (done == count) continue; /* every substep checked in place, the last at t_block_end */
            } else {
                done = integrate_fixed(&f, solver, memory, x, t, hs, first, count, reporting);
            }
            if (done == count) {
                f.checks++;
                if (last ? end_state_good(inst, &f, t_block_end, checked) : evaluate_at(inst, t_block_end, x, checked))
                    continue;
            }
            f.start_slope = NULL; /* the end check may have overwritten it */
            if (!reporting) { /* the reporting pass checked every substep already: x is the last good one */
                f.unconverged = 0; /* the checking pass finds the first failure again, whatever it is */
                memcpy(x, x_block, sizeof x_block);
                *memory = memory_block;
                done = integrate_fixed(&f, solver, memory, x, t, hs, first, count, 1);
            }
            count_work(memory, &f);
            memory->ab_count = memory->ab_restarted = 0;
            return fail(inst, function, t, first + done == n ? t + H : t + (double)(first + done) * hs,
                        solver_name(solver), h,
                        f.unconverged, f.refused_known ? f.refused : NULL);
        }
        count_work(memory, &f);
        if (f.inputs_vary) return finish_with(inst, t, H, checked, 1);
        {   /* the end check left the outputs and the derivatives in place */
            const Status status = finish(inst, t, H, t + H);
            inst->outputs_valid = 1;
            inst->derivatives_current = rounding_to_nearest(inst);
            return status;
        }
    }
}

#endif
