/* SimplePendulum (thesis 5.1): point mass m at distance L from the anchor, q = phi.
 *   T = m/2 L^2 omega^2,  U = -m g L cos(phi),  r = anchor + L (sin phi, -cos phi)
 *   Lagrange with Q = F . dr/dphi = L (F_x cos phi + F_y sin phi):
 *   phi'' = -(g/L) sin(phi) - d omega + (F_x cos phi + F_y sin phi) / (m L)
 * Model "linear" (the thesis's small-angle mode): phi'' = -(g/L) phi - d omega + F_x / (m L),
 * solved in closed form over each communication step with F_x held at its mid-step value. */
#include <math.h>

#include "framework.h"

void model_prepare(const double *real, const int32_t *integer, ModelConst *c)
{
    c->g = real[VR_g];
    c->d = real[VR_d];
    c->L = real[VR_L];
    c->m = real[VR_m];
    c->anchor_x = real[VR_anchor_x];
    c->anchor_y = real[VR_anchor_y];
    c->g_over_L = c->g / c->L;
    c->inv_mL = 1.0 / (c->m * c->L);
    c->linear = integer[INT_model] == MODEL_LINEAR;
}

int model_check_parameters(const double *real, char *message, size_t size)
{
    (void)real, (void)message, (void)size;
    return 0; /* every constraint is a range of one parameter, checked from the XML */
}

void model_derivatives(const ModelConst *c, const double *x, const double *u, double *dx)
{
    const double phi = x[0], omega = x[1];
    dx[0] = omega;
    if (c->linear)
        dx[1] = -c->g_over_L * phi - c->d * omega + u[0] * c->inv_mL;
    else
        dx[1] = -c->g_over_L * sin(phi) - c->d * omega + (u[0] * cos(phi) + u[1] * sin(phi)) * c->inv_mL;
}

int model_state_ok(const ModelConst *c, const double *x)
{
    (void)c;
    return isfinite(x[0]) && isfinite(x[1]);
}

/* Kernels of y'' + d y' + w2 y = 0 over time t: the impulse response k (k(0) = 0, k'(0) = 1), its
 * derivative kdot, and its integral K = int_0^t k, the response to a unit constant force. Written
 * to stay accurate through under-, critically and over-damped cases and w2 -> 0. */
static void oscillator_kernels(double d, double w2, double t, double *k, double *kdot, double *K)
{
    const double a = -0.5 * d;
    const double disc = 0.25 * d * d - w2; /* > 0: over-damped */
    const double mu = sqrt(fabs(disc));
    const double z = mu * t;
    if (z < 0.1) {
        /* cos/cosh and sin/sinh(z)/z by series: the sign of disc picks the branch smoothly. */
        const double s = disc >= 0 ? 1.0 : -1.0, z2 = s * z * z;
        const double C = 1 + z2 / 2 * (1 + z2 / 12 * (1 + z2 / 30 * (1 + z2 / 56)));
        const double S = t * (1 + z2 / 6 * (1 + z2 / 20 * (1 + z2 / 42 * (1 + z2 / 72))));
        const double e = exp(a * t);
        *k = e * S;
        *kdot = e * (C + a * S);
    } else if (disc < 0) {
        const double e = exp(a * t);
        *k = e * sin(z) / mu;
        *kdot = e * (cos(z) + a * sin(z) / mu);
    } else {
        const double l2 = a - mu, l1 = w2 / l2; /* l1 = a + mu without cancellation */
        const double e1 = exp(l1 * t), e2 = exp(l2 * t);
        *k = (e1 - e2) / (2 * mu);
        *kdot = (l1 * e1 - l2 * e2) / (2 * mu);
    }
    if (w2 * t * t >= 0.01) {
        *K = (1 - *kdot - d * *k) / w2; /* from K'' + d K' + w2 K = 1 */
    } else if (d * t > 2) {
        /* Strongly over-damped, almost no restoring force: K = (t phi1(l1 t) - t phi1(l2 t)) / (l1 - l2). */
        const double l2 = a - mu, l1 = w2 / l2;
        const double p1 = l1 * t != 0 ? expm1(l1 * t) / (l1 * t) : 1.0;
        const double p2 = expm1(l2 * t) / (l2 * t);
        *K = t * (p1 - p2) / (2 * mu);
    } else {
        /* Power series of K: K'' = 1 - d K' - w2 K with K(0) = K'(0) = 0. */
        double c_prev = 0.0, c = 0.5, sum = 0.0, power = t * t;
        int n;
        for (n = 2; n < 80; n++) {
            const double term = c * power, c_next = (-d * n * c - w2 * c_prev) / ((n + 1) * n);
            sum += term;
            if (n > 4 && fabs(term) < 1e-18 * fabs(sum)) break;
            c_prev = c;
            c = c_next;
            power *= t;
        }
        *K = sum;
    }
}

int model_closed_form_step(const ModelConst *c, double H, const double *u, double *x)
{
    double k, kdot, K;
    const double phi = x[0], omega = x[1], force = u[0] * c->inv_mL;
    if (!c->linear) return 0;
    oscillator_kernels(c->d, c->g_over_L, H, &k, &kdot, &K);
    x[0] = phi * (kdot + c->d * k) + omega * k + force * K;
    x[1] = -c->g_over_L * k * phi + omega * kdot + force * k;
    return 1;
}

int model_outputs(const ModelConst *c, const double *dx, double *real)
{
    const double phi = real[VR_phi], omega = real[VR_omega];
    const double s = sin(phi), co = cos(phi), mL2 = c->m * c->L * c->L;
    (void)dx;
    real[VR_x] = c->anchor_x + c->L * s;
    real[VR_y] = c->anchor_y - c->L * co;
    real[VR_v_x] = c->L * omega * co;
    real[VR_v_y] = c->L * omega * s;
    real[VR_E_kin] = 0.5 * mL2 * omega * omega;
    /* The linear model conserves the quadratic approximation of -m g L cos(phi). */
    real[VR_E_pot] = c->linear ? c->m * c->g * c->L * (0.5 * phi * phi - 1.0) : -c->m * c->g * c->L * co;
    real[VR_E] = real[VR_E_kin] + real[VR_E_pot];
    return 1;
}

void model_output_rates(const ModelConst *c, const double *real, const double *dx, const double *du, double *rate)
{
    const double phi = real[VR_phi], omega = real[VR_omega], alpha = dx[1];
    const double s = sin(phi), co = cos(phi), mL2 = c->m * c->L * c->L;
    (void)du;
    rate[VR_x] = c->L * omega * co;
    rate[VR_y] = c->L * omega * s;
    rate[VR_v_x] = c->L * (alpha * co - omega * omega * s);
    rate[VR_v_y] = c->L * (alpha * s + omega * omega * co);
    rate[VR_E_kin] = mL2 * omega * alpha;
    rate[VR_E_pot] = c->m * c->g * c->L * (c->linear ? phi : s) * omega;
    rate[VR_E] = rate[VR_E_kin] + rate[VR_E_pot];
}

void model_advance_inputs(double *real, const double *du, double H) { advance_inputs_linearly(real, du, H); }
