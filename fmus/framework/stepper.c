/* The integration of a communication step: from the FMU's state at t to t + H, with the solver the
 * user chose.
 * Finiteness is checked once per communication step; only when that check fails is the step
 * redone with a check after every substep, to stop at the last good one. */
#include <math.h>
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

static Status finish(Instance *inst, double t, double H_done, double t_reached)
{
    model_advance_inputs(inst->s.real, inst->s.input_derivative, H_done);
    inst->s.slopes_set = 0; /* slopes hold for one step; kept for the output rates at its end */
    inst->s.time = t_reached;
    inst->s.last_successful_time = t_reached;
    inst->outputs_valid = 0;
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
    model_derivatives(&inst->constants, t, x, u, real + N_STATES);
    return model_outputs(&inst->constants, t, real + N_STATES, real) && first_non_finite(real, N_REAL) < 0;
}

/* The importer's look at an accepted internal step: the instance shows the step's time, states and
 * outputs while report_step runs, and its own state afterwards. */
static void report_internal_step(Instance *inst, double t, const double *real)
{
    double before[N_REAL];
    const double time = inst->s.time;
    const int32_t machine_state = inst->s.machine_state;
    const int outputs_valid = inst->outputs_valid;
    memcpy(before, inst->s.real, sizeof before);
    memcpy(inst->s.real, real, sizeof before);
    inst->s.time = t;
    inst->outputs_valid = 1;
    inst->s.machine_state = MS_INTERMEDIATE;
    inst->report_step(inst, t);
    memcpy(inst->s.real, before, sizeof before);
    inst->s.time = time;
    inst->s.machine_state = machine_state;
    inst->outputs_valid = outputs_valid;
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

static Status fail(Instance *inst, const char *function, double t, double t_good, const char *method, double h,
                   int unconverged)
{
    finish(inst, t, t_good - t, t_good);
    if (unconverged)
        log_discard(inst, "%s: %s with h = %g: Newton's iteration did not converge (%d iterations at most, scaled "
                    "correction below %g) in the substep after t = %.17g; stopped there (last successful time "
                    "%.17g): take a smaller h", function, method, h, NEWTON_MAX_ITERATIONS, NEWTON_TOLERANCE, t_good,
                    t_good);
    else
        log_discard(inst, "%s: %s with h = %g: the state would become non-finite or singular in the substep "
                    "after t = %.17g; stopped there (last successful time %.17g)", function, method, h, t_good,
                    t_good);
    return STATUS_DISCARD;
}

/* The work of a call, into the counters. */
static void count_work(IntegratorMemory *memory, const RightHandSide *f)
{
    memory->n_rhs += f->evaluations;
    memory->n_jacobians += f->jacobians;
    memory->n_iterations += f->iterations;
}

/* J = df/dx at (t, x) with inputs u (NULL: zero), a column per state from the model's exact
 * directional derivative. */
static void jacobian_at(void *context, double t, const double *x, const double *u, double *J)
{
    const Instance *inst = (const Instance *)context;
    double real[N_REAL], change[N_REAL], dx[STATE_SLOTS], ddx[STATE_SLOTS];
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
    int32_t departing; /* constraints the step leaves: their crossings are the method's error (departing_constraints) */
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
    constraint_indicators(&e->inst->constants, e->inst->s.active_constraints, t, x, inputs_at(e->f, t, u), z);
}

/* x = the method's step of theta from (t, x0), with the integrator memory `memory` left as it was. */
static void trial_step(const EventStepper *e, const IntegratorMemory *memory, const double *x0, double t,
                       double theta, double *x)
{
    IntegratorMemory scratch = *memory;
    memcpy(x, x0, STATE_SLOTS * sizeof(double));
    if (e->adaptive) {
        adaptive_pass(e->f, e->solver, &scratch, x, t, t + theta, e->h, e->tol, 0);
    } else {
        scratch.ab_count = 0;
        integrate_fixed(e->f, e->solver, &scratch, x, t, theta, 0, 1, 0);
    }
}

static int crossed(const EventStepper *e, int k, double before, double after)
{
    return !(e->departing >> k & 1) && indicator_crossed(&e->inst->constants, k, before, after);
}

/* The indicators at the start of a step from (t, x), and the constraints it departs from. */
static void start_of_step(EventStepper *e, double t, const double *x, double *z)
{
    double u[INPUT_SLOTS];
    indicators_at(e, t, x, z);
    e->departing = departing_constraints(&e->inst->constants, e->inst->s.active_constraints, t, x,
                                         inputs_at(e->f, t, u));
}

/* The first event in (t, t + span] from x0 (indicators z0 there), whose step of span crossed; leaves the
 * state at the event in x and returns the event's offset from t. */
static double locate_event(const EventStepper *e, const IntegratorMemory *memory, const double *x0, double t,
                           double span, const double *z0, double *x)
{
    double z[N_CONSTRAINTS], zt[N_CONSTRAINTS], xt[STATE_SLOTS], xhi[STATE_SLOTS];
    double lo = 0.0, hi = span, zlo, zhi;
    int k, j, round, round_k, iteration, side = 0;
    trial_step(e, memory, x0, t, span, xhi);
    indicators_at(e, t + span, xhi, z);
    /* the indicator that crossed first by linear interpolation */
    k = -1;
    for (j = 0; j < N_CONSTRAINTS; j++)
        if (crossed(e, j, z0[j], z[j]) &&
            (k < 0 || z0[j] / (z0[j] - z[j]) < z0[k] / (z0[k] - z[k])))
            k = j;
    for (round = 0; round <= N_CONSTRAINTS && k >= 0; round++) {
        zlo = z0[k];
        zhi = z[k];
        lo = 0.0;
        /* A rigid gap that starts touching (just after an impact) and returns within the step: from a point
         * where it is open. */
        if (!e->inst->constants.law[k].compliant && !(zlo > 0.0)) {
            double theta = hi;
            int found = 0;
            for (j = 0; j < 40 && !found; j++) {
                theta *= 0.5;
                trial_step(e, memory, x0, t, theta, xt);
                indicators_at(e, t + theta, xt, zt);
                if (zt[k] > 0.0) {
                    lo = theta;
                    zlo = zt[k];
                    found = 1;
                }
            }
            if (!found) { /* touching all along: the event is at the start */
                memcpy(x, x0, STATE_SLOTS * sizeof(double));
                return 0.0;
            }
        }
        for (iteration = 0; iteration < 200 && hi - lo > 4.0 * DBL_EPSILON * (fabs(t) + span); iteration++) {
            double theta = hi - zhi * (hi - lo) / (zhi - zlo);
            if (!(theta > lo && theta < hi)) theta = 0.5 * (lo + hi);
            trial_step(e, memory, x0, t, theta, xt);
            indicators_at(e, t + theta, xt, zt);
            if (e->inst->constants.law[k].compliant ? (zt[k] > -GAP_ROUNDING) != (z0[k] > -GAP_ROUNDING) : zt[k] <= 0.0) {
                hi = theta;
                zhi = zt[k];
                memcpy(xhi, xt, sizeof xhi);
                if (side == 1) zlo *= 0.5; /* Illinois: the retained end's value halved */
                side = 1;
            } else {
                lo = theta;
                zlo = zt[k];
                if (side == -1) zhi *= 0.5;
                side = -1;
            }
        }
        /* another indicator that crossed before this one's zero: locate that one within [t, t + hi] */
        indicators_at(e, t + hi, xhi, z);
        for (j = 0, round_k = k, k = -1; j < N_CONSTRAINTS && k < 0; j++)
            if (j != round_k && crossed(e, j, z0[j], z[j])) k = j;
    }
    memcpy(x, xhi, STATE_SLOTS * sizeof(double));
    return hi;
}

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
    double hs;
    e.inst = inst;
    e.f = f;
    e.solver = solver;
    e.h = s->real[VR_h];
    e.tol = s->real[VR_tol];
    e.adaptive = solver == SOLVER_RKF45 || ((solver == SOLVER_GBS || solver == SOLVER_TAYLOR) && e.tol > 0.0);
    n = (int64_t)fmax(1.0, ceil(H / e.h - 1e-9));
    hs = H / (double)n;
    if (!e.adaptive) {
        /* each substep, and at most an event's location per substep */
        const double work = 2.0 * evaluations_needed(solver, 0, (double)n, f) + (double)n;
        if (work > MAX_EVALUATIONS_PER_CALL) {
            log_error(inst, "%s: communicationStepSize = %g with %s at h = %g needs %.0f right-hand-side "
                      "evaluations with its event checks (allowed at most %.0f per call): raise h or shorten the "
                      "step", function, H, solver_name(solver), e.h, work, MAX_EVALUATIONS_PER_CALL);
            return STATUS_ERROR;
        }
        if (memory->ab_count > 0 && fabs(hs - memory->ab_step) > 1e-10 * hs) memory->ab_count = 0;
        memory->ab_step = hs;
    }
    for (i = 0; i < n; i++) {
        double ta = t + (double)i * hs;
        const double tb = i + 1 == n ? t_end : t + (double)(i + 1) * hs;
        double x0[STATE_SLOTS];
        IntegratorMemory m0 = *memory;
        uint64_t events_seen = memory->n_events;
        int32_t active_seen = s->active_constraints;
        int any, k, stalls = 0;
        memcpy(x0, x, sizeof x0);
        start_of_step(&e, ta, x, z0);
        if (e.adaptive) {
            if (adaptive_pass(f, solver, memory, x, ta, tb, e.h, e.tol, 0) < tb) {
                memcpy(x, x0, sizeof x0);
                count_work(memory, f);
                return fail(inst, function, t, ta, solver_name(solver), e.h, 0);
            }
        } else {
            integrate_fixed(f, solver, memory, x, t, hs, i, 1, 0);
        }
        if (!model_state_ok(c, x)) {
            memcpy(x, x0, sizeof x0);
            *memory = m0;
            count_work(memory, f);
            return fail(inst, function, t, ta, solver_name(solver), e.h, f->unconverged);
        }
        indicators_at(&e, tb, x, z1);
        for (any = 0, k = 0; k < N_CONSTRAINTS; k++) any |= crossed(&e, k, z0[k], z1[k]);
        while (any) {
            const double theta = locate_event(&e, &m0, x0, ta, tb - ta, z0, x);
            double located[STATE_SLOTS];
            const int32_t active_before = s->active_constraints;
            ta += theta;
            *memory = m0;
            memory->ab_count = 0;
            memcpy(located, x, sizeof located);
            if (!leave_boundary(c, s->active_constraints, e.departing, ta, x) ||
                !handle_event(c, &s->active_constraints, ta, x, inputs_at(f, ta, u), &memory->n_events) ||
                !model_state_ok(c, x)) {
                memcpy(x, located, sizeof located); /* the state the event was found in, as it was */
                s->active_constraints = active_before;
                memory->n_events = m0.n_events;
                count_work(memory, f);
                finish(inst, t, ta - t, ta);
                log_discard(inst, "%s: the constraints at t = %.17g are dependent (an impact or a contact force has no "
                            "unique solution); stopped there (last successful time %.17g)", function, ta, ta);
                return STATUS_DISCARD;
            }
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
            start_of_step(&e, ta, x, z0);
            if (inst->return_at_events && ta > t && ta < t_end && memory->n_events > events_before) { /* FMI 3.0 */
                count_work(memory, f);
                f->checks++;
                if (!evaluate_at(inst, ta, x, checked)) return fail(inst, function, t, ta, solver_name(solver), e.h, 0);
                return finish_with(inst, t, ta - t, checked, f->inputs_vary);
            }
            any = 0;
            if (tb - ta > 4.0 * DBL_EPSILON * fabs(tb)) {
                trial_step(&e, &m0, x0, ta, tb - ta, x);
                indicators_at(&e, tb, x, z1);
                for (k = 0; k < N_CONSTRAINTS; k++) any |= crossed(&e, k, z0[k], z1[k]);
            } else {
                memcpy(z1, z0, sizeof z1);
            }
        }
        if (!leave_boundary(c, s->active_constraints, e.departing, tb, x) ||
            !project_constraints(c, s->active_constraints, tb, x)) {
            count_work(memory, f);
            return fail(inst, function, t, ta, solver_name(solver), e.h, 0);
        }
        if (inst->report_step && inst->s.machine_state == MS_STEP_COMPLETE) state_acceptable(inst, tb, x);
    }
    count_work(memory, f);
    f->checks++;
    if (!evaluate_at(inst, t_end, x, checked)) return fail(inst, function, t, t_end, solver_name(solver), e.h, 0);
    return finish_with(inst, t, H, checked, f->inputs_vary);
}
#endif

Status step_to(Instance *inst, const char *function, double t, double H)
{
    SimState *s = &inst->s;
    IntegratorMemory *memory = &s->integrator;
    const int solver = s->integer[INT_solver];
    const double h = s->real[VR_h];
    const char *method = solver_name(solver);
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
    for (i = 0; i < N_INPUTS; i++) {
        f.du[i] = s->input_derivative[i];
        if (f.du[i] != 0.0) f.inputs_vary = 1;
        if (f.u0[i] != 0.0) f.forces = 1;
    }
    if (f.inputs_vary) f.forces = 1;
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
    if (solver == SOLVER_TAYLOR && !inst->taylor_work) {
        inst->taylor_work = (double (*)[TAYLOR_SLOTS])inst->allocate(TAYLOR_SERIES, sizeof *inst->taylor_work);
        if (!inst->taylor_work) {
            log_error(inst, "%s: out of memory for the Taylor method's %d work series of %d coefficients", function,
                      TAYLOR_SERIES, TAYLOR_SLOTS);
            return STATUS_ERROR;
        }
    }
    f.taylor_work = inst->taylor_work;
    f.acceptable = state_acceptable;
    f.jacobian = jacobian_at;
    f.context = inst;

    {
        double u_mid[INPUT_SLOTS], closed[STATE_SLOTS];
        for (i = 0; i < N_INPUTS; i++) u_mid[i] = f.u0[i] + 0.5 * H * f.du[i];
        memcpy(closed, x, sizeof closed);
        if (model_closed_form_step(&inst->constants, H, u_mid, closed)) {
            if (!evaluate_at(inst, t + H, closed, checked)) return fail(inst, function, t, t, "closed form", H, 0);
            memcpy(x, closed, sizeof closed);
            memory->n_steps++;
            return finish_with(inst, t, H, checked, f.inputs_vary);
        }
    }

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
#if N_CONSTRAINTS > 0
    return step_with_events(inst, function, &f, solver, t, H);
#endif
    if (solver == SOLVER_RKF45 || ((solver == SOLVER_GBS || solver == SOLVER_TAYLOR) && s->real[VR_tol] > 0.0)) {
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
        if (reached < t_end) {
            finish(inst, t, reached - t, reached);
            if (f.out_of_budget)
                log_discard(inst, "%s: %s with tol = %g used its %.0f right-hand-side evaluations "
                            "allowed per call at t = %.17g; stopped at the last successful time %.17g (take shorter "
                            "communication steps or a larger tol)", function, method, s->real[VR_tol],
                            MAX_EVALUATIONS_PER_CALL, reached, reached);
            else if (solver == SOLVER_TAYLOR)
                log_discard(inst, "%s: taylor of order %d with tol = %g: the step its coefficients allow "
                            "underflowed at t = %.17g (tol is out of reach at this order in double precision, or "
                            "the state is non-finite or singular there: take a larger tol or a higher "
                            "taylor_order); stopped at the last successful time %.17g", function,
                            s->integer[INT_taylor_order], s->real[VR_tol], reached, reached);
            else
                log_discard(inst, "%s: %s with tol = %g: the step size underflowed at t = %.17g (the "
                            "state is non-finite, singular or too stiff there); stopped at the last successful "
                            "time %.17g", function, method, s->real[VR_tol], reached, reached);
            return STATUS_DISCARD;
        }
        return finish(inst, t, H, t_end);
    } else {
        const double substeps = ceil(H / h - 1e-9);
        const double planned = substeps < 1.0 ? 1.0 : substeps;
        int64_t n, first;
        double hs = H / planned;
        /* the Adams-Bashforth history survives only if the substep stays the same (below) */
        const int history = memory->ab_count > 0 && fabs(hs - memory->ab_step) <= 1e-10 * hs ? memory->ab_count : 0;
        /* The work of the whole call, the state checks included: the method's evaluations, one check
         * per block (or per substep when reporting), and the redo of one failing block with a check
         * after each of its substeps. */
        const double redone = fmin(planned, (double)CHECK_BLOCK);
        const double work = evaluations_needed(solver, history, planned, &f) +
                            (reporting ? planned : ceil(planned / CHECK_BLOCK) + evaluations_needed(solver, 0, redone, &f) +
                                                   redone);
        if (work > MAX_EVALUATIONS_PER_CALL) {
            log_error(inst, "%s: communicationStepSize = %g with %s at h = %g needs %.0f right-hand-side "
                      "evaluations, its state checks included (allowed at most %.0f per call): raise h or shorten the "
                      "step", function, H, method, h, work, MAX_EVALUATIONS_PER_CALL);
            return STATUS_ERROR;
        }
        n = substeps < 1.0 ? 1 : (int64_t)substeps;
        hs = H / (double)n;
        /* Adams-Bashforth history is only valid for the substep it was taken with. */
        if (memory->ab_count > 0 && fabs(hs - memory->ab_step) > 1e-10 * hs) memory->ab_count = 0;
        memory->ab_step = hs;
        /* Blocks of CHECK_BLOCK substeps, each checked at its end: a failure is redone, checking every
         * substep, from the last good block only. */
        for (first = 0; first < n; first += CHECK_BLOCK) {
            const int64_t count = n - first < CHECK_BLOCK ? n - first : CHECK_BLOCK;
            const double t_block_end = first + count == n ? t + H : t + (double)(first + count) * hs;
            double x_block[STATE_SLOTS];
            IntegratorMemory memory_block = *memory;
            int64_t done;
            memcpy(x_block, x, sizeof x_block);
            done = integrate_fixed(&f, solver, memory, x, t, hs, first, count, reporting);
            if (done == count) {
                f.checks++;
                if (evaluate_at(inst, t_block_end, x, checked)) continue;
            }
            if (!reporting) { /* the reporting pass checked every substep already: x is the last good one */
                f.unconverged = 0; /* the checking pass finds the first failure again, whatever it is */
                memcpy(x, x_block, sizeof x_block);
                *memory = memory_block;
                done = integrate_fixed(&f, solver, memory, x, t, hs, first, count, 1);
            }
            count_work(memory, &f);
            memory->ab_count = 0;
            return fail(inst, function, t, first + done == n ? t + H : t + (double)(first + done) * hs, method, h,
                        f.unconverged);
        }
        count_work(memory, &f);
        return finish_with(inst, t, H, checked, f.inputs_vary);
    }
}

#endif
