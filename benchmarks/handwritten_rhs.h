/* Hand-written right-hand sides of the three thesis pendulums, without force terms, as the yardstick
 * for the generated ones: what a careful person writes from T and U by hand. Parameter-only
 * constants are computed once in hand_prepare, each angle costs one sin and one cos, the double
 * pendulum's 2x2 mass matrix is solved in closed form. The damping is the thesis's: each
 * acceleration gets -d times its own velocity.
 *
 * The build defines HANDWRITTEN_<Model> for the model it compiles; the model's generated
 * model_description.h (value references VR_*) must be included first. Each model provides
 *   HandConst                                the constants,
 *   hand_prepare(real, c)                    from the variables' values (real[VR_*]),
 *   hand_rhs(c, x, dx)                       dx = f(x), x = (q, v) in the FMU's state order,
 *   HAND_SAMPLE_RANGE[N_STATES]              half-widths of the random states of the check
 * and HAVE_HANDWRITTEN_RHS. Any other model gets none of these. */
#ifndef HANDWRITTEN_RHS_H
#define HANDWRITTEN_RHS_H

#include <math.h>

#define HAND_PI 3.14159265358979323846

#if defined(HANDWRITTEN_SimplePendulum)
#define HAVE_HANDWRITTEN_RHS 1

/* T = m/2 L^2 omega^2, U = -m g L cos(phi): m L^2 phi'' = -m g L sin(phi), so m drops out. */
typedef struct {
    double g_over_L, d;
} HandConst;

static void hand_prepare(const double *real, HandConst *c)
{
    c->g_over_L = real[VR_g] / real[VR_L];
    c->d = real[VR_d];
}

static inline void hand_rhs(const HandConst *c, const double *x, double *dx)
{
    const double phi = x[0], omega = x[1];
    dx[0] = omega;
    dx[1] = -c->g_over_L * sin(phi) - c->d * omega;
}

static const double HAND_SAMPLE_RANGE[2] = {HAND_PI, 6.0};

#elif defined(HANDWRITTEN_DoublePendulum)
#define HAVE_HANDWRITTEN_RHS 1

/* T = I1/2 w1^2 + m2/2 (l1^2 w1^2 + 2 l1 s2 w1 w2 cos(phi1 - phi2) + s2^2 w2^2) + J2/2 w2^2 with
 * I1 = J1 + m1 s1^2, U = -(m1 s1 + m2 l1) g cos(phi1) - m2 s2 g cos(phi2). Lagrange, D = phi1 - phi2:
 *   [M11       B cos D] [w1']   [-B sin D w2^2 - G1 sin phi1]
 *   [B cos D   M22    ] [w2'] = [ B sin D w1^2 - G2 sin phi2]
 * M11 = I1 + m2 l1^2, M22 = J2 + m2 s2^2, B = m2 l1 s2, G1 = (m1 s1 + m2 l1) g, G2 = m2 s2 g; by
 * Cramer's rule. The determinant M11 M22 - B^2 cos^2 D >= I1 M22 + m2 l1^2 J2 is positive for
 * every state once the parameters make M positive definite, so it is not checked per call. */
typedef struct {
    double M11, M22, B, G1, G2, d;
    double M11M22, B2; /* the determinant's constant parts */
} HandConst;

static void hand_prepare(const double *real, HandConst *c)
{
    const double m1 = real[VR_m1], m2 = real[VR_m2], J1 = real[VR_J1], J2 = real[VR_J2];
    const double s1 = real[VR_s1], s2 = real[VR_s2], l1 = real[VR_l1], g = real[VR_g];
    c->M11 = J1 + m1 * s1 * s1 + m2 * l1 * l1;
    c->M22 = J2 + m2 * s2 * s2;
    c->B = m2 * l1 * s2;
    c->G1 = (m1 * s1 + m2 * l1) * g;
    c->G2 = m2 * s2 * g;
    c->d = real[VR_d];
    c->M11M22 = c->M11 * c->M22;
    c->B2 = c->B * c->B;
}

static inline void hand_rhs(const HandConst *c, const double *x, double *dx)
{
    const double w1 = x[2], w2 = x[3];
    const double sn1 = sin(x[0]), cs1 = cos(x[0]), sn2 = sin(x[1]), cs2 = cos(x[1]);
    /* sin and cos of phi1 - phi2 from those of the angles, not from two more calls */
    const double sD = sn1 * cs2 - cs1 * sn2, cD = cs1 * cs2 + sn1 * sn2;
    const double M12 = c->B * cD, BsD = c->B * sD;
    const double r1 = -BsD * w2 * w2 - c->G1 * sn1;
    const double r2 = BsD * w1 * w1 - c->G2 * sn2;
    const double inv_det = 1.0 / (c->M11M22 - c->B2 * cD * cD);
    dx[0] = w1;
    dx[1] = w2;
    dx[2] = (c->M22 * r1 - M12 * r2) * inv_det - c->d * w1;
    dx[3] = (c->M11 * r2 - M12 * r1) * inv_det - c->d * w2;
}

static const double HAND_SAMPLE_RANGE[4] = {HAND_PI, HAND_PI, 8.0, 8.0};

#elif defined(HANDWRITTEN_SpringPendulum)
#define HAVE_HANDWRITTEN_RHS 1

/* r = l0 + eps, T = m/2 (eps'^2 + r^2 phi'^2), U = D/2 eps^2 - m g r cos(phi):
 *   phi'' = -(g sin(phi) + 2 eps' phi') / r,   eps'' = r phi'^2 - (D/m) eps + g cos(phi).
 * r <= 0 (the mass at or through the anchor) is singular: NaN, as the FMU gives there. */
typedef struct {
    double l0, g, D_over_m, d;
} HandConst;

static void hand_prepare(const double *real, HandConst *c)
{
    c->l0 = real[VR_l0];
    c->g = real[VR_g];
    c->D_over_m = real[VR_D] / real[VR_m];
    c->d = real[VR_d];
}

static inline void hand_rhs(const HandConst *c, const double *x, double *dx)
{
    const double phi = x[0], eps = x[1], omega = x[2], v = x[3];
    const double r = c->l0 + eps, sn = sin(phi), cs = cos(phi);
    if (!(r > 0.0)) {
        dx[0] = dx[1] = dx[2] = dx[3] = NAN;
        return;
    }
    dx[0] = omega;
    dx[1] = v;
    dx[2] = -(c->g * sn + 2.0 * v * omega) / r - c->d * omega;
    dx[3] = r * omega * omega - c->D_over_m * eps + c->g * cs - c->d * v;
}

/* |eps| <= 0.4 m: r stays positive for every l0 the check draws (at least half the default 1 m) */
static const double HAND_SAMPLE_RANGE[4] = {HAND_PI, 0.4, 6.0, 3.0};

#endif

#endif
