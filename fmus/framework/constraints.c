/* Constraints: Lagrange's equations of the first kind on top of an object's free motion.
 *
 * M a = f + Q + sum_i lambda_i G_i^T with G_i = dg_i/dq. Compliant constraints add their force law while
 * they overlap; the active rigid ones (bilateral always, unilateral while resting or taut) impose
 * g'' = G a + gamma = 0, which gives their forces from (G M^-1 G^T) lambda = -gamma - G a_free. Impacts
 * make the velocities jump by M^-1 G^T P (Newton's restitution); the positions never jump. The object's
 * physics.c gives g, G, g' and gamma (model_constraints) and M (model_mass); the factorizations here
 * are numeric, of matrices no larger than the object's coordinates and constraints. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "framework.h"
#include "integrators.h"

#if N_CONSTRAINTS > 0

#define NQ N_COORDINATES
#define NC N_CONSTRAINTS

typedef struct {
    double g[NC], G[NC][NQ], rate[NC], gamma[NC];
} Geometry;

static void geometry_at(const ModelConst *c, double t, const double *x, Geometry *geo)
{
    model_constraints(c, t, x, geo->g, &geo->G[0][0], geo->rate, geo->gamma);
}

/* Cholesky factor L (lower, in place) of the symmetric n x n matrix A; 0 where A is not positive definite. */
static int cholesky(double *A, int n)
{
    int i, j, k;
    for (j = 0; j < n; j++) {
        double d = A[j * n + j];
        for (k = 0; k < j; k++) d -= A[j * n + k] * A[j * n + k];
        if (!(d > 0.0)) return 0;
        A[j * n + j] = sqrt(d);
        for (i = j + 1; i < n; i++) {
            double s = A[i * n + j];
            for (k = 0; k < j; k++) s -= A[i * n + k] * A[j * n + k];
            A[i * n + j] = s / A[j * n + j];
        }
    }
    return 1;
}

/* b = (L L^T)^-1 b */
static void cholesky_solve(const double *L, int n, double *b)
{
    int i, k;
    for (i = 0; i < n; i++) {
        for (k = 0; k < i; k++) b[i] -= L[i * n + k] * b[k];
        b[i] /= L[i * n + i];
    }
    for (i = n - 1; i >= 0; i--) {
        for (k = i + 1; k < n; k++) b[i] -= L[k * n + i] * b[k];
        b[i] /= L[i * n + i];
    }
}

static double dot(const double *a, const double *b)
{
    double s = 0.0;
    int j;
    for (j = 0; j < NQ; j++) s += a[j] * b[j];
    return s;
}

/* The rigid constraints that act in `active`, bilateral ones always: their indices, their count. */
static int acting(const ModelConst *c, int32_t active, int *set)
{
    int i, m = 0;
    for (i = 0; i < NC; i++)
        if (!c->law[i].compliant && (c->law[i].bilateral || (active >> i & 1))) set[m++] = i;
    return m;
}

static double compliant_force(const ConstraintLaw *law, double g, double rate)
{
    double force;
    if (!(g < 0.0)) return 0.0;
    force = law->stiffness * pow(-g, law->exponent) * (1.0 + law->damping * -rate);
    return force > 0.0 ? force : 0.0; /* never pulling */
}

#if N_COMPLIANT > 0
/* A compliant contact that pushes at (t, x): its force's change with the gap and with the gap's rate, its gradient
 * G and M^-1 G^T (the accelerations a unit force gives), G M^-1 G^T (its inverse effective mass). */
typedef struct {
    int index;
    double dF_dg, dF_drate, gradient[NQ], response[NQ], inverse_mass;
} Stiffness;

/* The compliant contacts that push at (t, x), into s; how many (0 also where the mass matrix is not positive
 * definite). With a horizon (peak >= 0), each contact that overlaps or closes within it (at its present rate), at
 * the depth where it will stop: where the kinetic energy of its approach, mu g'^2 / 2 with mu = 1 / (G M^-1 G^T), is
 * stored as k depth^(p+1) / (p+1) (its damping left out, which only shortens that). */
static int compliant_stiffness(const ModelConst *c, double t, const double *x, double peak, Stiffness *s)
{
    Geometry geo;
    double L[NQ * NQ];
    int i, n = 0, factored = 0;
    geometry_at(c, t, x, &geo);
    for (i = 0; i < NC; i++) {
        const ConstraintLaw *law = &c->law[i];
        double depth;
        if (!law->compliant) continue;
        if (peak >= 0.0 ? !(geo.g[i] < 0.0 || (geo.rate[i] < 0.0 && geo.g[i] < CONTACT_GAP - geo.rate[i] * peak))
                        : compliant_force(law, geo.g[i], geo.rate[i]) <= 0.0)
            continue;
        if (!factored) {
            model_mass(c, t, x, L);
            if (!cholesky(L, NQ)) return 0;
            factored = 1;
        }
        memcpy(s[n].gradient, geo.G[i], sizeof s[n].gradient);
        memcpy(s[n].response, geo.G[i], sizeof s[n].response);
        cholesky_solve(L, NQ, s[n].response);
        s[n].inverse_mass = dot(geo.G[i], s[n].response);
        depth = geo.g[i] < 0.0 ? -geo.g[i] : 0.0; /* F = k depth^p (1 - damping g'), depth = -g */
        if (peak >= 0.0 && geo.rate[i] < 0.0)
            depth = pow(pow(depth, law->exponent + 1.0) + (law->exponent + 1.0) * geo.rate[i] * geo.rate[i] /
                                                              (2.0 * law->stiffness * s[n].inverse_mass),
                        1.0 / (law->exponent + 1.0));
        s[n].index = i;
        s[n].dF_dg = -law->stiffness * law->exponent * pow(depth, law->exponent - 1.0) *
                     (peak >= 0.0 ? 1.0 : 1.0 - law->damping * geo.rate[i]);
        s[n].dF_drate = -law->stiffness * pow(depth, law->exponent) * law->damping;
        n++;
    }
    return n;
}

#if N_STATES != 2 * NQ
#error "an object with constraints has its coordinates and their velocities as states"
#endif
void compliant_jacobian(const ModelConst *c, double t, const double *x, double *J)
{
    Stiffness s[NC];
    const int n = compliant_stiffness(c, t, x, -1.0, s);
    int k, a, b;
    for (k = 0; k < n; k++)
        for (a = 0; a < NQ; a++)
            for (b = 0; b < NQ; b++) {
                J[(NQ + a) * N_STATES + b] += s[k].response[a] * s[k].dF_dg * s[k].gradient[b];
                J[(NQ + a) * N_STATES + NQ + b] += s[k].response[a] * s[k].dF_drate * s[k].gradient[b];
            }
}

int compliant_frequency(const ModelConst *c, double t, const double *x, double horizon, double *omega)
{
    Stiffness s[NC];
    const int n = compliant_stiffness(c, t, x, horizon, s);
    double sum = 0.0, largest = 0.0;
    int k, stiffest = -1;
    for (k = 0; k < n; k++) {
        const double squared = -s[k].dF_dg * s[k].inverse_mass;
        sum += squared;
        if (squared > largest) {
            largest = squared;
            stiffest = s[k].index;
        }
    }
    *omega = sqrt(sum);
    return stiffest;
}
#endif

/* Solves (G_S M^-1 G_S^T) P = r for the constraints in set (m of them, L the factor of M) and leaves
 * M^-1 G_S^T P in dv; 0 where the constraints are dependent. */
static int constrained_response(const double *L, const Geometry *geo, const int *set, int m, double *r, double *dv)
{
    double Y[NC][NQ], W[NC * NC];
    int p, q, j;
    if (m > NC) return 0; /* never (a set of the NC constraints): tells the compiler W's bound */
    for (p = 0; p < m; p++) {
        memcpy(Y[p], geo->G[set[p]], sizeof Y[p]);
        cholesky_solve(L, NQ, Y[p]);
    }
    for (p = 0; p < m; p++)
        for (q = 0; q < m; q++) W[p * m + q] = dot(geo->G[set[p]], Y[q]);
    if (!cholesky(W, m)) return 0;
    cholesky_solve(W, m, r);
    for (j = 0; j < NQ; j++) {
        dv[j] = 0.0;
        for (p = 0; p < m; p++) dv[j] += Y[p][j] * r[p];
    }
    return 1;
}

int constraint_forces(const ModelConst *c, int32_t active, double t, const double *x, double *dx, double *lambda)
{
    Geometry geo;
    double L[NQ * NQ], a[NQ], force[NC];
    int set[NC], i, j, p, m, compliant = 0;
    m = acting(c, active, set);
    if (m == 0 && N_COMPLIANT == 0) { /* free motion: no geometry needed */
        if (lambda)
            for (i = 0; i < NC; i++) lambda[i] = 0.0;
        return 1;
    }
    geometry_at(c, t, x, &geo);
    for (i = 0; i < NC; i++) {
        force[i] = c->law[i].compliant ? compliant_force(&c->law[i], geo.g[i], geo.rate[i]) : 0.0;
        if (force[i] != 0.0) compliant = 1;
    }
    if (lambda) memcpy(lambda, force, sizeof force);
    if (!compliant && m == 0) return 1;
    model_mass(c, t, x, L);
    if (!cholesky(L, NQ)) return 0;
    for (j = 0; j < NQ; j++) a[j] = dx[NQ + j];
    if (compliant) {
        double y[NQ] = {0};
        for (i = 0; i < NC; i++)
            for (j = 0; j < NQ; j++) y[j] += geo.G[i][j] * force[i];
        cholesky_solve(L, NQ, y);
        for (j = 0; j < NQ; j++) a[j] += y[j];
    }
    if (m > 0) {
        double r[NC], da[NQ];
        for (p = 0; p < m; p++) r[p] = -geo.gamma[set[p]] - dot(geo.G[set[p]], a);
        if (!constrained_response(L, &geo, set, m, r, da)) return 0;
        for (j = 0; j < NQ; j++) a[j] += da[j];
        if (lambda)
            for (p = 0; p < m; p++) lambda[set[p]] = r[p];
    }
    for (j = 0; j < NQ; j++) dx[NQ + j] = a[j];
    return 1;
}

int constrain_motion(const ModelConst *c, double t, const double *x, double *dx, double *lambda)
{
    int i;
    if (constraint_forces(c, *c->active, t, x, dx, lambda)) return 1;
    for (i = 0; i < N_STATES; i++) dx[i] = NAN; /* dependent constraints or a singular mass matrix */
    return 0;
}

/* The forces lambda at (t, x) with inputs u (NULL: none) and the constraints `active`. */
static int forces_at(const ModelConst *c, int32_t active, double t, const double *x, const double *u, double *lambda)
{
    double dx[N_STATES];
    model_free_equations(c, t, x, u, dx);
    return constraint_forces(c, active, t, x, dx, lambda);
}

/* Whether constraint i (rigid, unilateral, touching at rest, not in `active`) would be pushed: its gap closes
 * under the motion it leaves free faster than REST_ACCELERATION, and its force with `active` pushes. A pair
 * that touches with no force between them (balls of a cradle at rest) stays open. */
static int would_rest(const ModelConst *c, int32_t active, int i, double t, const double *x, const double *u)
{
    Geometry geo;
    double dx[N_STATES], free[N_STATES], lambda[NC];
    model_free_equations(c, t, x, u, free);
    memcpy(dx, free, sizeof dx);
    if (!constraint_forces(c, active, t, x, dx, NULL)) return 0;
    geometry_at(c, t, x, &geo);
    return geo.gamma[i] + dot(geo.G[i], dx + NQ) < -REST_ACCELERATION &&
           constraint_forces(c, active | (int32_t)1 << i, t, x, free, lambda) && lambda[i] > 0.0;
}

/* The indicators from the gaps g and the forces lambda (NULL: none computed, 0 for the resting ones). */
static void indicators_from(const ModelConst *c, int32_t active, const double *g, const double *lambda, double *z)
{
    int i;
    for (i = 0; i < NC; i++) {
        if (c->law[i].bilateral)
            z[i] = 1.0;
        else if (!c->law[i].compliant && (active >> i & 1))
            z[i] = lambda ? lambda[i] : 0.0;
        else
            z[i] = g[i];
    }
}

/* A gap's event lies just past contact (as in Co-Simulation), so that the state an impact leaves behind is not
 * taken for the next event, and touching without overlap (a Hertz cradle at rest) is no contact. */
static void past_contact(const ModelConst *c, int32_t active, double *z)
{
    int i;
    for (i = 0; i < NC; i++)
        if (c->law[i].compliant || (!c->law[i].bilateral && !(active >> i & 1))) z[i] += GAP_ROUNDING;
}

int constraint_indicators(const ModelConst *c, int32_t active, double t, const double *x, const double *u, double *z)
{
    double g[NC], lambda[NC];
    const int resting = (active & RIGID_UNILATERAL_BITS) != 0;
    if (!resting && N_BILATERAL == 0 && N_COMPLIANT == 0) { /* free flight among rigid contacts: the gaps themselves */
        model_gaps(c, t, x, z);
        return 0;
    }
    model_gaps(c, t, x, g);
    indicators_from(c, active, g, resting && forces_at(c, active, t, x, u, lambda) ? lambda : NULL, z);
    return resting;
}

void event_indicators(const ModelConst *c, int32_t active, double t, const double *x, const double *u, double *z)
{
    constraint_indicators(c, active, t, x, u, z);
    past_contact(c, active, z);
}

int indicator_crossed(const ModelConst *c, int i, double before, double after)
{
    if (c->law[i].compliant) return (before > -GAP_ROUNDING) != (after > -GAP_ROUNDING);
    return after < -GAP_ROUNDING;
}

/* Velocities jump so that the rates of the rigid constraints acting in `active` become zero and that of
 * constraint `hit` (-1: none) becomes `target`. */
static int impulse(const ModelConst *c, int32_t active, double t, double *x, int hit, double target)
{
    Geometry geo;
    double L[NQ * NQ], r[NC], dv[NQ];
    int set[NC], m, p, j;
    m = acting(c, active, set);
    if (hit >= 0) set[m++] = hit;
    if (m == 0) return 1;
    geometry_at(c, t, x, &geo);
    for (p = 0; p < m; p++) r[p] = (set[p] == hit ? target : 0.0) - geo.rate[set[p]];
    model_mass(c, t, x, L);
    if (!cholesky(L, NQ) || !constrained_response(L, &geo, set, m, r, dv)) return 0;
    for (j = 0; j < NQ; j++) x[NQ + j] += dv[j];
    return 1;
}

static int resolve_events(const ModelConst *c, int32_t *active, double t, double *x, const double *u, uint64_t *events)
{
    Geometry geo;
    double lambda[NC];
    int32_t struck = 0; /* the constraints that received an impulse: their activation is the same event */
    int sweep, i, changed;
    /* impacts, one contact at a time in the file's order, until none approaches */
    for (sweep = 0; sweep < MAX_SWEEPS; sweep++) {
        int hit = -1;
        geometry_at(c, t, x, &geo);
        for (i = 0; i < NC && hit < 0; i++)
            if (!c->law[i].compliant && !c->law[i].bilateral && !(*active >> i & 1) && geo.g[i] <= CONTACT_GAP &&
                geo.rate[i] < -GAP_ROUNDING)
                hit = i;
        if (hit < 0) break;
        {
            const double rebound = -c->law[hit].restitution * geo.rate[hit];
            if (!impulse(c, *active, t, x, hit, rebound >= REST_SPEED ? rebound : 0.0)) return 0;
            (*events)++;
            struck |= (int32_t)1 << hit;
        }
    }
    /* activations where a touching constraint at rest would push, releases where an active one would pull */
    for (sweep = 0; sweep < MAX_SWEEPS; sweep++) {
        changed = 0;
        geometry_at(c, t, x, &geo);
        for (i = 0; i < NC && !changed; i++) {
            const int32_t bit = (int32_t)1 << i;
            if (c->law[i].compliant || c->law[i].bilateral || (*active & bit)) continue;
            if (geo.g[i] <= CONTACT_GAP && fabs(geo.rate[i]) < REST_SPEED && would_rest(c, *active, i, t, x, u)) {
                *active |= bit;
                if (!impulse(c, *active, t, x, -1, 0.0)) return 0; /* its rate to zero with the others */
                if (!(struck & bit)) (*events)++;
                changed = 1;
            }
        }
        if (!changed && forces_at(c, *active, t, x, u, lambda))
            for (i = 0; i < NC && !changed; i++)
                if (!c->law[i].compliant && !c->law[i].bilateral && (*active >> i & 1) && lambda[i] <= 0.0) {
                    *active &= ~((int32_t)1 << i);
                    (*events)++;
                    changed = 1;
                }
        if (!changed) return 1;
    }
    return 1;
}

/* The positions onto g = 0 for the rigid constraints acting in `active` (Newton's iteration along M^-1 G^T). */
static int project_positions(const ModelConst *c, int32_t active, double t, double *x)
{
    Geometry geo;
    double L[NQ * NQ], r[NC], dq[NQ];
    int set[NC], m, p, j, iteration;
    m = acting(c, active, set);
    if (m == 0) return 1;
    for (iteration = 0; iteration < 3; iteration++) {
        double largest = 0.0;
        geometry_at(c, t, x, &geo);
        for (p = 0; p < m; p++) {
            r[p] = -geo.g[set[p]];
            if (fabs(r[p]) > largest) largest = fabs(r[p]);
        }
        if (largest <= GAP_ROUNDING * 1e-3) break;
        model_mass(c, t, x, L);
        if (!cholesky(L, NQ) || !constrained_response(L, &geo, set, m, r, dq)) return 0;
        for (j = 0; j < NQ; j++) x[j] += dq[j];
    }
    return 1;
}

int project_constraints(const ModelConst *c, int32_t active, double t, double *x)
{
    if (N_BILATERAL == 0 && !(active & RIGID_UNILATERAL_BITS)) return 1; /* free flight: every step's end comes here */
    /* positions onto g = 0, then velocities onto g' = 0 */
    return project_positions(c, active, t, x) && impulse(c, active, t, x, -1, 0.0);
}

int constraint_departs(const ModelConst *c, int32_t active, int i, double t, const double *x, const double *u)
{
    Geometry geo;
    if (c->law[i].compliant || c->law[i].bilateral || (active >> i & 1)) return 0;
    geometry_at(c, t, x, &geo);
    /* however fast it opens: a low-order step can dip across the boundary it leaves (Euler's straight line off a
     * string's circle dips by h^2 v^2 / 2L) for several steps, until the opening outruns the dip */
    return geo.g[i] <= CONTACT_GAP && geo.rate[i] >= -GAP_ROUNDING && !would_rest(c, active, i, t, x, u);
}

int free_motion_refused(int solver, int32_t active, const char *when, double t, char *message, size_t size)
{
    char at[48] = "";
    int i;
    if (!FREE_MOTION_ONLY(solver) || !(active & RIGID_UNILATERAL_BITS)) return 0;
    for (i = 0; !(active >> i & 1); i++) continue;
    if (isfinite(t)) snprintf(at, sizeof at, " t = %.17g", t);
    snprintf(message, size,
             "constraint %s acts %s%s (resting or taut), and %s integrates free motion only (the free "
             "equations' %s, without the constraint's force): take another method for this object",
             CONSTRAINT_NAMES[i], when, at, solver_name(solver),
             solver == SOLVER_TAYLOR ? "Taylor series" : "split a(q) - d v");
    return 1;
}

int leave_boundary(const ModelConst *c, int32_t active, int32_t departing, double t, double *x)
{
    Geometry geo;
    int32_t outside = 0, approaching = 0;
    int i;
    if (!departing) return 1; /* every step's end comes here: no geometry where nothing departs */
    geometry_at(c, t, x, &geo);
    for (i = 0; i < NC; i++)
        if ((departing >> i & 1) && geo.g[i] < 0.0) outside |= (int32_t)1 << i;
    if (!outside) return 1;
    if (!project_positions(c, active | outside, t, x)) return 0;
    geometry_at(c, t, x, &geo);
    for (i = 0; i < NC; i++)
        if ((outside >> i & 1) && geo.rate[i] < 0.0) approaching |= (int32_t)1 << i;
    return impulse(c, active | approaching, t, x, -1, 0.0);
}

/* A compliant constraint's bit records whether it overlaps; each change is an onset or an end: an event. */
static void track_overlaps(const ModelConst *c, int32_t *active, double t, const double *x, uint64_t *events)
{
    Geometry geo;
    int i;
    geometry_at(c, t, x, &geo);
    for (i = 0; i < NC; i++) {
        const int32_t bit = (int32_t)1 << i;
        if (c->law[i].compliant && ((*active & bit) != 0) != (geo.g[i] <= -GAP_ROUNDING)) {
            *active ^= bit;
            if (events) (*events)++;
        }
    }
}

int handle_event(const ModelConst *c, int32_t *active, double t, double *x, const double *u, uint64_t *events)
{
    /* onto the constraints that held up to the event first: a constraint released there leaves from g = 0, not
     * from the drift of the step that reached it (which would read as a new crossing at once) */
    if (!project_constraints(c, *active, t, x) || !resolve_events(c, active, t, x, u, events) ||
        !project_constraints(c, *active, t, x))
        return 0;
    track_overlaps(c, active, t, x, events);
    return 1;
}

int start_constraints(const ModelConst *c, int32_t *active, double t, double *x, const double *u, char *message,
                      size_t size)
{
    Geometry geo;
    int i;
    geometry_at(c, t, x, &geo);
    *active = 0;
    for (i = 0; i < NC; i++) {
        const double tolerance = START_GAP_TOLERANCE;
        if (c->law[i].compliant) continue;
        if (!isfinite(geo.g[i]) || geo.g[i] < -tolerance ||
            (c->law[i].bilateral && (fabs(geo.g[i]) > tolerance || fabs(geo.rate[i]) > tolerance))) {
            snprintf(message, size,
                     "the start values violate constraint %s (gap = %g, its rate = %g; allowed: gap "
                     ">= %g%s)",
                     CONSTRAINT_NAMES[i], geo.g[i], geo.rate[i], -tolerance,
                     c->law[i].bilateral ? ", and both within 1e-12 for a bilateral constraint" : "");
            return 0;
        }
    }
    track_overlaps(c, active, t, x, NULL); /* a compliant contact overlapping from the start: no event */
    /* a constraint touching at rest begins active where its force pushes: no event */
    for (i = 0; i < NC; i++) {
        const int32_t bit = (int32_t)1 << i;
        if (c->law[i].compliant || c->law[i].bilateral) continue;
        if (fabs(geo.g[i]) <= START_GAP_TOLERANCE && fabs(geo.rate[i]) <= START_GAP_TOLERANCE &&
            would_rest(c, *active, i, t, x, u))
            *active |= bit;
    }
    return 1;
}

int constraint_outputs(const ModelConst *c, double t, const double *u, double *real)
{
    Geometry geo;
    double lambda[NC], z[NC];
    int i;
    geometry_at(c, t, real, &geo);
    if (!forces_at(c, *c->active, t, real, u, lambda)) return 0;
    indicators_from(c, *c->active, geo.g, lambda, z);
    past_contact(c, *c->active, z);
    for (i = 0; i < NC; i++) {
        real[CONSTRAINT_GAP_VRS[i]] = geo.g[i];
        /* a unilateral constraint never pulls: a resting one's force within rounding of its release (the indicator
         * above keeps its sign for the event) is no pull */
        real[CONSTRAINT_FORCE_VRS[i]] = c->law[i].bilateral || lambda[i] > 0.0 ? lambda[i] : 0.0;
        real[CONSTRAINT_INDICATOR_VRS[i]] = z[i];
        if (c->law[i].compliant && geo.g[i] < 0.0) { /* the energy the overlap stores */
            const double stored =
                c->law[i].stiffness * pow(-geo.g[i], c->law[i].exponent + 1.0) / (c->law[i].exponent + 1.0);
            real[VR_E_pot] += stored;
            real[VR_E] += stored;
        }
    }
    return 1;
}

void constraint_output_rates(const ModelConst *c, double t, const double *real, const double *dx, const double *u,
                             double *rate)
{
    Geometry geo;
    double ahead[N_STATES], behind[N_STATES], lambda_ahead[NC], lambda_behind[NC];
    /* the forces' rates by a central difference along the motion: lambda is not a closed form */
    const double dt = 1e-6;
    int i, j;
    geometry_at(c, t, real, &geo);
    for (j = 0; j < N_STATES; j++) {
        ahead[j] = real[j] + dt * dx[j];
        behind[j] = real[j] - dt * dx[j];
    }
    if (!forces_at(c, *c->active, t + dt, ahead, u, lambda_ahead) ||
        !forces_at(c, *c->active, t - dt, behind, u, lambda_behind))
        for (i = 0; i < NC; i++) lambda_ahead[i] = lambda_behind[i] = 0.0;
    for (i = 0; i < NC; i++) {
        rate[CONSTRAINT_GAP_VRS[i]] = geo.rate[i];
        rate[CONSTRAINT_FORCE_VRS[i]] = (lambda_ahead[i] - lambda_behind[i]) / (2.0 * dt);
        if (c->law[i].compliant && geo.g[i] < 0.0) {
            const double power = -c->law[i].stiffness * pow(-geo.g[i], c->law[i].exponent) * geo.rate[i];
            rate[VR_E_pot] += power;
            rate[VR_E] += power;
        }
    }
}

#endif
