/* SpringPendulum (thesis 5.3, "Federpendel", with the sign of (5.65)/(5.73) corrected): mass m on a
 * linear spring of stiffness D and natural length l0; q = (phi, eps), r = l0 + eps.
 *   position = anchor + r (sin phi, -cos phi)
 *   T = m/2 (eps'^2 + r^2 phi'^2),  U = D/2 eps^2 - m g r cos(phi)
 *   Q_phi = r (F_x cos phi + F_y sin phi),  Q_eps = F_x sin phi - F_y cos phi
 *   phi'' = -(g sin phi + 2 eps' phi') / r + (F_x cos phi + F_y sin phi) / (m r) - d phi'
 *   eps'' = r phi'^2 - (D/m) eps + g cos phi + (F_x sin phi - F_y cos phi) / m - d eps'
 * r <= 0 (the mass at or through the anchor) is a singular configuration. */
#include <math.h>

#include "framework.h"

void model_prepare(const double *real, const int32_t *integer, ModelConst *c)
{
    (void)integer;
    c->g = real[VR_g];
    c->d = real[VR_d];
    c->m = real[VR_m];
    c->D = real[VR_D];
    c->l0 = real[VR_l0];
    c->anchor_x = real[VR_anchor_x];
    c->anchor_y = real[VR_anchor_y];
    c->D_over_m = c->D / c->m;
    c->inv_m = 1.0 / c->m;
}

int model_check_parameters(const double *real, char *message, size_t size)
{
    (void)real, (void)message, (void)size;
    return 0;
}

void model_derivatives(const ModelConst *c, const double *x, const double *u, double *dx)
{
    const double phi = x[0], eps = x[1], omega = x[2], v = x[3];
    const double r = c->l0 + eps, s = sin(phi), co = cos(phi);
    if (!(r > 0.0)) {
        /* The mass at or through the anchor: the equations are undefined. NaN reaches the state, so the
         * once-per-step check catches even a pass through r <= 0 that ends with r > 0 again. */
        dx[0] = dx[1] = dx[2] = dx[3] = NAN;
        return;
    }
    dx[0] = omega;
    dx[1] = v;
    dx[2] = (-(c->g * s + 2.0 * v * omega) + (u[0] * co + u[1] * s) * c->inv_m) / r - c->d * omega;
    dx[3] = r * omega * omega - c->D_over_m * eps + c->g * co + (u[0] * s - u[1] * co) * c->inv_m - c->d * v;
}

int model_state_ok(const ModelConst *c, const double *x)
{
    return isfinite(x[0]) && isfinite(x[1]) && isfinite(x[2]) && isfinite(x[3]) && c->l0 + x[1] > 0.0;
}

int model_closed_form_step(const ModelConst *c, double H, const double *u, double *x)
{
    (void)c, (void)H, (void)u, (void)x;
    return 0;
}

int model_outputs(const ModelConst *c, const double *dx, double *real)
{
    const double phi = real[VR_phi], eps = real[VR_eps], omega = real[VR_omega], v = real[VR_v_eps];
    const double r = c->l0 + eps, s = sin(phi), co = cos(phi);
    (void)dx;
    real[VR_x] = c->anchor_x + r * s;
    real[VR_y] = c->anchor_y - r * co;
    real[VR_v_x] = v * s + r * omega * co;
    real[VR_v_y] = -v * co + r * omega * s;
    real[VR_E_kin] = 0.5 * c->m * (v * v + r * r * omega * omega);
    real[VR_E_pot] = 0.5 * c->D * eps * eps - c->m * c->g * r * co;
    real[VR_E] = real[VR_E_kin] + real[VR_E_pot];
    return 1;
}

void model_output_rates(const ModelConst *c, const double *real, const double *dx, const double *du, double *rate)
{
    const double phi = real[VR_phi], eps = real[VR_eps], omega = real[VR_omega], v = real[VR_v_eps];
    const double alpha = dx[2], a_eps = dx[3];
    const double r = c->l0 + eps, s = sin(phi), co = cos(phi);
    (void)du;
    rate[VR_x] = v * s + r * omega * co;
    rate[VR_y] = -v * co + r * omega * s;
    rate[VR_v_x] = a_eps * s + 2.0 * v * omega * co + r * alpha * co - r * omega * omega * s;
    rate[VR_v_y] = -a_eps * co + 2.0 * v * omega * s + r * alpha * s + r * omega * omega * co;
    rate[VR_E_kin] = c->m * (v * a_eps + r * v * omega * omega + r * r * omega * alpha);
    rate[VR_E_pot] = c->D * eps * v - c->m * c->g * (v * co - r * s * omega);
    rate[VR_E] = rate[VR_E_kin] + rate[VR_E_pot];
}

void model_advance_inputs(double *real, const double *du, double H) { advance_inputs_linearly(real, du, H); }
