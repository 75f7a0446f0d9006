/* Spring: massless linear spring-damper between the points a and b (a coupling element; not in
 * the thesis). With d = b - a, r = |d|, e = d / r:
 *   Fa = (k (r - l0) + c (v_b - v_a) . e) e,  Fb = -Fa,  E_pot = k/2 (r - l0)^2.
 * For l0 = 0 this is k d + c ((v_b - v_a) . e) e, defined at r = 0 (the damping term vanishes there);
 * for l0 > 0, r = 0 is singular. In Co-Simulation the outputs belong to the end of each step: the
 * positions move with the velocity inputs (and their derivatives, where set) over the step. */
#include <math.h>

#include "framework.h"

/* Positions of INPUT_VRS: a_x a_y a_vx a_vy b_x b_y b_vx b_vy. */
enum { IN_AX, IN_AY, IN_AVX, IN_AVY, IN_BX, IN_BY, IN_BVX, IN_BVY };

int model_prepare(const double *real, const int32_t *integer, ModelConst *c, char *message, size_t size)
{
    (void)integer, (void)message, (void)size;
    c->k = real[VR_k];
    c->c = real[VR_c];
    c->l0 = real[VR_l0];
    return 0;
}

int model_outputs(const ModelConst *c, double t, const double *dx, double *real)
{
    const double dx_ = real[VR_b_x] - real[VR_a_x], dy = real[VR_b_y] - real[VR_a_y];
    const double dvx = real[VR_b_vx] - real[VR_a_vx], dvy = real[VR_b_vy] - real[VR_a_vy];
    const double r = hypot(dx_, dy);
    double fx = 0.0, fy = 0.0;
    int ok = 1;
    (void)dx;
    if (r > 0.0) {
        const double ex = dx_ / r, ey = dy / r;
        const double magnitude = c->k * (r - c->l0) + c->c * (dvx * ex + dvy * ey);
        fx = magnitude * ex;
        fy = magnitude * ey;
    } else if (c->l0 > 0.0) {
        ok = 0; /* the direction of the pre-stressed spring is undefined */
    }
    real[VR_Fa_x] = fx;
    real[VR_Fa_y] = fy;
    real[VR_Fb_x] = -fx;
    real[VR_Fb_y] = -fy;
    real[VR_E_pot] = 0.5 * c->k * (r - c->l0) * (r - c->l0);
    return ok;
}

/* The change of the outputs along a change (dpx, dpy) of b - a and (dwx, dwy) of v_b - v_a: the
 * time rates for (dp, dw) = (v_b - v_a, their slopes), a directional derivative for a seed. */
static void output_change(const ModelConst *c, const double *real, double dpx, double dpy, double dwx, double dwy,
                          double *change)
{
    const double px = real[VR_b_x] - real[VR_a_x], py = real[VR_b_y] - real[VR_a_y];
    const double wx = real[VR_b_vx] - real[VR_a_vx], wy = real[VR_b_vy] - real[VR_a_vy];
    const double r = hypot(px, py);
    double fx = 0.0, fy = 0.0, energy = 0.0;
    if (r > 0.0) {
        const double ex = px / r, ey = py / r;
        const double dr = dpx * ex + dpy * ey;
        const double dex = (dpx - dr * ex) / r, dey = (dpy - dr * ey) / r;
        const double s = wx * ex + wy * ey, ds = dwx * ex + dwy * ey + wx * dex + wy * dey;
        const double magnitude = c->k * (r - c->l0) + c->c * s;
        const double dmagnitude = c->k * dr + c->c * ds;
        fx = dmagnitude * ex + magnitude * dex;
        fy = dmagnitude * ey + magnitude * dey;
        energy = c->k * (r - c->l0) * dr;
    } else if (c->l0 == 0.0) {
        fx = c->k * dpx; /* Fa = k d near r = 0 */
        fy = c->k * dpy;
    }
    change[VR_Fa_x] = fx;
    change[VR_Fa_y] = fy;
    change[VR_Fb_x] = -fx;
    change[VR_Fb_y] = -fy;
    change[VR_E_pot] = energy;
}

void model_output_rates(const ModelConst *c, double t, const double *real, const double *dx, const double *du,
                        double *rate)
{
    (void)t, (void)dx;
    output_change(c, real, real[VR_b_vx] - real[VR_a_vx], real[VR_b_vy] - real[VR_a_vy], du[IN_BVX] - du[IN_AVX],
                  du[IN_BVY] - du[IN_AVY], rate);
}

void model_directional(const ModelConst *c, double t, const double *real, const double *dx, const double *seed_x,
                       const double *seed_u, double *ddx, double *change)
{
    (void)t, (void)dx, (void)seed_x, (void)ddx;
    output_change(c, real, seed_u[IN_BX] - seed_u[IN_AX], seed_u[IN_BY] - seed_u[IN_AY],
                  seed_u[IN_BVX] - seed_u[IN_AVX], seed_u[IN_BVY] - seed_u[IN_AVY], change);
}

void model_advance_inputs(double *real, const double *du, double H)
{
    /* A position moves with its velocity input: p + v H + dv H^2 / 2; a velocity with its slope. */
    real[VR_a_x] += real[VR_a_vx] * H + 0.5 * du[IN_AVX] * H * H;
    real[VR_a_y] += real[VR_a_vy] * H + 0.5 * du[IN_AVY] * H * H;
    real[VR_b_x] += real[VR_b_vx] * H + 0.5 * du[IN_BVX] * H * H;
    real[VR_b_y] += real[VR_b_vy] * H + 0.5 * du[IN_BVY] * H * H;
    real[VR_a_vx] += du[IN_AVX] * H;
    real[VR_a_vy] += du[IN_AVY] * H;
    real[VR_b_vx] += du[IN_BVX] * H;
    real[VR_b_vy] += du[IN_BVY] * H;
}
