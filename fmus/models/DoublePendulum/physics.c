/* DoublePendulum (thesis 5.2, with the printed errors of 5.35 and B.2 corrected): two rigid links,
 * q = (phi1, phi2) from the downward vertical.
 *   r1 = s1 (sin phi1, -cos phi1),  r2 = l1 (sin phi1, -cos phi1) + s2 (sin phi2, -cos phi2)
 *   T = m1/2 |r1'|^2 + J1/2 w1^2 + m2/2 |r2'|^2 + J2/2 w2^2,  U = m1 g r1_y + m2 g r2_y
 * Lagrange gives M(q) q'' = rhs with
 *   M = [[J1 + m1 s1^2 + m2 l1^2, B cos D], [B cos D, J2 + m2 s2^2]],  B = m2 l1 s2,  D = phi1 - phi2
 *   rhs1 = Q1 - B sin D w2^2 - (m1 s1 + m2 l1) g sin phi1
 *   rhs2 = Q2 + B sin D w1^2 - m2 s2 g sin phi2
 * solved by Cramer's rule, det = M11 M22 - M12^2 > 0 (guaranteed by J_i + m_i s_i^2 > 0).
 * The force F acts on the tip of link 2: Q1 = l1 (F_x cos phi1 + F_y sin phi1),
 * Q2 = l2 (F_x cos phi2 + F_y sin phi2). Damping: each angular acceleration gets -d w_i. */
#include <math.h>
#include <stdio.h>

#include "framework.h"

void model_prepare(const double *real, const int32_t *integer, ModelConst *c)
{
    (void)integer;
    c->g = real[VR_g];
    c->d = real[VR_d];
    c->m1 = real[VR_m1];
    c->m2 = real[VR_m2];
    c->J1 = real[VR_J1];
    c->J2 = real[VR_J2];
    c->s1 = real[VR_s1];
    c->s2 = real[VR_s2];
    c->l1 = real[VR_l1];
    c->l2 = real[VR_l2];
    c->anchor_x = real[VR_anchor_x];
    c->anchor_y = real[VR_anchor_y];
    c->M11 = c->J1 + c->m1 * c->s1 * c->s1 + c->m2 * c->l1 * c->l1;
    c->M22 = c->J2 + c->m2 * c->s2 * c->s2;
    c->B = c->m2 * c->l1 * c->s2;
    c->G1 = (c->m1 * c->s1 + c->m2 * c->l1) * c->g;
    c->G2 = c->m2 * c->s2 * c->g;
}

int model_check_parameters(const double *real, char *message, size_t size)
{
    const double I1 = real[VR_J1] + real[VR_m1] * real[VR_s1] * real[VR_s1];
    const double I2 = real[VR_J2] + real[VR_m2] * real[VR_s2] * real[VR_s2];
    if (!(I1 > 0)) {
        snprintf(message, size, "J1 + m1 s1^2 = %g must be > 0 (J1 = %g, m1 = %g, s1 = %g): the mass matrix would "
                 "be singular", I1, real[VR_J1], real[VR_m1], real[VR_s1]);
        return 1;
    }
    if (!(I2 > 0)) {
        snprintf(message, size, "J2 + m2 s2^2 = %g must be > 0 (J2 = %g, m2 = %g, s2 = %g): the mass matrix would "
                 "be singular", I2, real[VR_J2], real[VR_m2], real[VR_s2]);
        return 1;
    }
    return 0;
}

void model_derivatives(const ModelConst *c, const double *x, const double *u, double *dx)
{
    const double w1 = x[2], w2 = x[3];
    const double sn1 = sin(x[0]), cs1 = cos(x[0]), sn2 = sin(x[1]), cs2 = cos(x[1]);
    const double sD = sn1 * cs2 - cs1 * sn2, cD = cs1 * cs2 + sn1 * sn2;
    const double M12 = c->B * cD;
    const double rhs1 = c->l1 * (u[0] * cs1 + u[1] * sn1) - c->B * sD * w2 * w2 - c->G1 * sn1;
    const double rhs2 = c->l2 * (u[0] * cs2 + u[1] * sn2) + c->B * sD * w1 * w1 - c->G2 * sn2;
    const double inv_det = 1.0 / (c->M11 * c->M22 - M12 * M12);
    dx[0] = w1;
    dx[1] = w2;
    dx[2] = (c->M22 * rhs1 - M12 * rhs2) * inv_det - c->d * w1;
    dx[3] = (c->M11 * rhs2 - M12 * rhs1) * inv_det - c->d * w2;
}

int model_state_ok(const ModelConst *c, const double *x)
{
    (void)c;
    return isfinite(x[0]) && isfinite(x[1]) && isfinite(x[2]) && isfinite(x[3]);
}

int model_closed_form_step(const ModelConst *c, double H, const double *u, double *x)
{
    (void)c, (void)H, (void)u, (void)x;
    return 0;
}

int model_outputs(const ModelConst *c, const double *dx, double *real)
{
    const double w1 = real[VR_omega1], w2 = real[VR_omega2];
    const double sn1 = sin(real[VR_phi1]), cs1 = cos(real[VR_phi1]);
    const double sn2 = sin(real[VR_phi2]), cs2 = cos(real[VR_phi2]);
    const double M12 = c->B * (cs1 * cs2 + sn1 * sn2);
    (void)dx;
    real[VR_x1] = c->anchor_x + c->l1 * sn1;
    real[VR_y1] = c->anchor_y - c->l1 * cs1;
    real[VR_x2] = real[VR_x1] + c->l2 * sn2;
    real[VR_y2] = real[VR_y1] - c->l2 * cs2;
    real[VR_v_x] = c->l1 * w1 * cs1 + c->l2 * w2 * cs2;
    real[VR_v_y] = c->l1 * w1 * sn1 + c->l2 * w2 * sn2;
    real[VR_E_kin] = 0.5 * (c->M11 * w1 * w1 + 2.0 * M12 * w1 * w2 + c->M22 * w2 * w2);
    real[VR_E_pot] = -c->G1 * cs1 - c->G2 * cs2;
    real[VR_E] = real[VR_E_kin] + real[VR_E_pot];
    return 1;
}

void model_output_rates(const ModelConst *c, const double *real, const double *dx, const double *du, double *rate)
{
    const double w1 = real[VR_omega1], w2 = real[VR_omega2], a1 = dx[2], a2 = dx[3];
    const double sn1 = sin(real[VR_phi1]), cs1 = cos(real[VR_phi1]);
    const double sn2 = sin(real[VR_phi2]), cs2 = cos(real[VR_phi2]);
    const double sD = sn1 * cs2 - cs1 * sn2, cD = cs1 * cs2 + sn1 * sn2, M12 = c->B * cD;
    (void)du;
    rate[VR_x1] = c->l1 * w1 * cs1;
    rate[VR_y1] = c->l1 * w1 * sn1;
    rate[VR_x2] = rate[VR_x1] + c->l2 * w2 * cs2;
    rate[VR_y2] = rate[VR_y1] + c->l2 * w2 * sn2;
    rate[VR_v_x] = c->l1 * (a1 * cs1 - w1 * w1 * sn1) + c->l2 * (a2 * cs2 - w2 * w2 * sn2);
    rate[VR_v_y] = c->l1 * (a1 * sn1 + w1 * w1 * cs1) + c->l2 * (a2 * sn2 + w2 * w2 * cs2);
    /* d/dt (w'M w / 2) = w'M a + w'(dM/dt)w / 2, dM12/dt = -B sin D (w1 - w2) */
    rate[VR_E_kin] = w1 * (c->M11 * a1 + M12 * a2) + w2 * (M12 * a1 + c->M22 * a2) - c->B * sD * (w1 - w2) * w1 * w2;
    rate[VR_E_pot] = c->G1 * sn1 * w1 + c->G2 * sn2 * w2;
    rate[VR_E] = rate[VR_E_kin] + rate[VR_E_pot];
}

void model_advance_inputs(double *real, const double *du, double H) { advance_inputs_linearly(real, du, H); }
