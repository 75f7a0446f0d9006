/* Contact: a massless compliant contact between two bodies of radii R_a and R_b centred at the points a
 * and b (a coupling element, beside the Spring). With d = b - a, r = |d|, e = d / r, w = v_b - v_a:
 *   gap = r - R_a - R_b,  gap_rate = w . e,  delta = -gap (the overlap),
 *   F = k delta^n (1 + c d(delta)/dt) while delta > 0, never below 0 (Hertz; Hunt and Crossley),
 *   Fa = -F e,  Fb = F e,  E_pot = k delta^(n + 1) / (n + 1), the integral of the elastic part over the overlap.
 * The same law as a compliant constraint in an object file, so a scene of FMUs joined by Contacts has the
 * single object's equations. Centres at one point (r = 0) leave the direction undefined: a singular
 * configuration (fmi2Discard). In Co-Simulation the outputs belong to the end of each step, the centres
 * moved with their velocity inputs (and their derivatives, where set) over the step. */
#include <math.h>
#include <stdio.h>

#include "framework.h"
#include "constraints.h" /* GAP_ROUNDING: the same event rule as a compliant constraint */

/* Positions of INPUT_VRS: a's position and velocity, then b's. */
enum { IN_A = 0, IN_AV = 3, IN_B = 6, IN_BV = 9 };

int model_prepare(const double *real, const int32_t *integer, ModelConst *c, char *message, size_t size)
{
    (void)integer;
    /* Two points never overlap: the gap |b - a| cannot become negative, and the contact would never act */
    if (!(real[VR_R_a] + real[VR_R_b] > 0.0)) {
        snprintf(message, size,
                 "the radii R_a = %g and R_b = %g make the bodies points, which never touch (allowed: "
                 "R_a + R_b > 0)",
                 real[VR_R_a], real[VR_R_b]);
        return 1;
    }
    c->k = real[VR_k];
    c->exponent = real[VR_exponent];
    c->c = real[VR_c];
    c->reach = real[VR_R_a] + real[VR_R_b];
    return 0;
}

/* The geometry at real[]: d = b - a, w = v_b - v_a, r = |d|. */
typedef struct {
    double d[3], w[3], r;
} Geometry;

static Geometry geometry(const double *real)
{
    static const unsigned a[3] = {VR_a_x, VR_a_y, VR_a_z}, b[3] = {VR_b_x, VR_b_y, VR_b_z};
    static const unsigned va[3] = {VR_a_vx, VR_a_vy, VR_a_vz}, vb[3] = {VR_b_vx, VR_b_vy, VR_b_vz};
    Geometry g;
    int i;
    for (i = 0; i < 3; i++) {
        g.d[i] = real[b[i]] - real[a[i]];
        g.w[i] = real[vb[i]] - real[va[i]];
    }
    /* hypot twice: no overflow or underflow of the squares for centres far apart or nearly together */
    g.r = hypot(hypot(g.d[0], g.d[1]), g.d[2]);
    return g;
}

static double dot3(const double *p, const double *q) { return p[0] * q[0] + p[1] * q[1] + p[2] * q[2]; }

/* The force's magnitude F >= 0 for an overlap delta and its rate, with dF/d(delta) and dF/d(rate) where they
 * are asked for. */
static double force(const ModelConst *c, double delta, double delta_rate, double *by_delta, double *by_rate)
{
    double elastic, magnitude;
    if (by_delta) *by_delta = 0.0;
    if (by_rate) *by_rate = 0.0;
    if (!(delta > 0.0)) return 0.0;
    elastic = c->k * pow(delta, c->exponent);
    magnitude = elastic * (1.0 + c->c * delta_rate);
    if (!(magnitude > 0.0)) return 0.0; /* never pulling: the damping cannot hold the bodies together */
    if (by_delta) *by_delta = c->k * c->exponent * pow(delta, c->exponent - 1.0) * (1.0 + c->c * delta_rate);
    if (by_rate) *by_rate = elastic * c->c;
    return magnitude;
}

int model_outputs(const ModelConst *c, double t, const double *dx, double *real)
{
    const Geometry g = geometry(real);
    const double gap = g.r - c->reach, delta = -gap;
    double e[3] = {0.0, 0.0, 0.0}, rate = 0.0, magnitude;
    int i;
    (void)t, (void)dx;
    if (g.r > 0.0) {
        for (i = 0; i < 3; i++) e[i] = g.d[i] / g.r;
        rate = dot3(g.w, e);
    }
    magnitude = force(c, delta, -rate, NULL, NULL);
    real[VR_Fa_x] = -magnitude * e[0];
    real[VR_Fa_y] = -magnitude * e[1];
    real[VR_Fa_z] = -magnitude * e[2];
    real[VR_Fb_x] = magnitude * e[0];
    real[VR_Fb_y] = magnitude * e[1];
    real[VR_Fb_z] = magnitude * e[2];
    real[VR_gap] = gap;
    real[VR_gap_rate] = rate;
    real[VR_E_pot] = delta > 0.0 ? c->k * pow(delta, c->exponent + 1.0) / (c->exponent + 1.0) : 0.0;
    real[VR_contact_indicator] = gap + GAP_ROUNDING;
    return g.r > 0.0; /* centres at one point: no direction to push along */
}

/* The change of the outputs at the geometry `at` along a change dp of b - a and dw of v_b - v_a: the time rates for
 * (dp, dw) = (v_b - v_a, the velocities' slopes), a directional derivative for a seed. */
static void output_change(const ModelConst *c, const Geometry *at, const double *dp, const double *dw, double *change)
{
    const Geometry g = *at;
    double e[3], de[3], dr, rate, drate, magnitude, by_delta, by_rate, dmagnitude;
    int i;
    if (!(g.r > 0.0)) { /* undefined there (model_outputs refuses the point): no change to report */
        for (i = VR_Fa_x; i <= VR_contact_indicator; i++) change[i] = 0.0;
        return;
    }
    for (i = 0; i < 3; i++) e[i] = g.d[i] / g.r;
    dr = dot3(dp, e);
    for (i = 0; i < 3; i++) de[i] = (dp[i] - dr * e[i]) / g.r;
    rate = dot3(g.w, e);
    drate = dot3(dw, e) + dot3(g.w, de);
    magnitude = force(c, c->reach - g.r, -rate, &by_delta, &by_rate);
    dmagnitude = -by_delta * dr - by_rate * drate;
    for (i = 0; i < 3; i++) {
        change[VR_Fb_x + i] = dmagnitude * e[i] + magnitude * de[i];
        change[VR_Fa_x + i] = -change[VR_Fb_x + i];
    }
    change[VR_gap] = dr;
    change[VR_gap_rate] = drate;
    change[VR_E_pot] = g.r < c->reach ? -c->k * pow(c->reach - g.r, c->exponent) * dr : 0.0;
    change[VR_contact_indicator] = dr;
}

void model_output_rates(const ModelConst *c, double t, const double *real, const double *dx, const double *du,
                        double *rate)
{
    const Geometry g = geometry(real);
    const double slope[3] = {du[IN_BV] - du[IN_AV], du[IN_BV + 1] - du[IN_AV + 1], du[IN_BV + 2] - du[IN_AV + 2]};
    (void)t, (void)dx;
    output_change(c, &g, g.w, slope, rate);
}

void model_directional(const ModelConst *c, double t, const double *real, const double *dx, const double *seed_x,
                       const double *seed_u, double *ddx, double *change)
{
    const Geometry g = geometry(real);
    double dp[3], dw[3];
    int i;
    (void)t, (void)dx, (void)seed_x, (void)ddx;
    for (i = 0; i < 3; i++) {
        dp[i] = seed_u[IN_B + i] - seed_u[IN_A + i];
        dw[i] = seed_u[IN_BV + i] - seed_u[IN_AV + i];
    }
    output_change(c, &g, dp, dw, change);
}

void model_event_indicators(const ModelConst *c, double t, const double *real, double *z)
{
    (void)t;
    z[0] = geometry(real).r - c->reach + GAP_ROUNDING;
}

void model_advance_inputs(double *real, const double *du, double H)
{
    /* A centre moves with its velocity input: p + v H + dv H^2 / 2; a velocity with its slope. */
    static const unsigned p[6] = {VR_a_x, VR_a_y, VR_a_z, VR_b_x, VR_b_y, VR_b_z};
    static const unsigned v[6] = {VR_a_vx, VR_a_vy, VR_a_vz, VR_b_vx, VR_b_vy, VR_b_vz};
    static const int slope[6] = {IN_AV, IN_AV + 1, IN_AV + 2, IN_BV, IN_BV + 1, IN_BV + 2};
    int i;
    for (i = 0; i < 6; i++) {
        real[p[i]] += real[v[i]] * H + 0.5 * du[slope[i]] * H * H;
        real[v[i]] += du[slope[i]] * H;
    }
}
