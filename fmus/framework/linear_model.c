/* Normal modes of an object's linear model and its closed-form step (see linear_model.h). */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "framework.h"

#if HAS_LINEAR_MODEL

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

/* Cholesky M = L L' in place (lower triangle of L); returns the failing pivot + 1, or 0. */
static int cholesky(double L[LM_N][LM_N], double *bad_pivot)
{
    int i, j, k;
    for (j = 0; j < LM_N; j++) {
        double s = L[j][j];
        for (k = 0; k < j; k++) s -= L[j][k] * L[j][k];
        if (!(s > 0.0)) {
            *bad_pivot = s;
            return j + 1;
        }
        L[j][j] = sqrt(s);
        for (i = j + 1; i < LM_N; i++) {
            double t = L[i][j];
            for (k = 0; k < j; k++) t -= L[i][k] * L[j][k];
            L[i][j] = t / L[j][j];
        }
        for (i = 0; i < j; i++) L[i][j] = 0.0;
    }
    return 0;
}

/* Solves L y = b in place (L lower triangular). */
static void forward(const double L[LM_N][LM_N], double *b)
{
    int i, k;
    for (i = 0; i < LM_N; i++) {
        for (k = 0; k < i; k++) b[i] -= L[i][k] * b[k];
        b[i] /= L[i][i];
    }
}

/* Solves L' y = b in place. */
static void backward(const double L[LM_N][LM_N], double *b)
{
    int i, k;
    for (i = LM_N - 1; i >= 0; i--) {
        for (k = i + 1; k < LM_N; k++) b[i] -= L[k][i] * b[k];
        b[i] /= L[i][i];
    }
}

/* Cyclic Jacobi: A = V diag(w) V' for symmetric A (destroyed). Converges quadratically; the sweep
 * limit only bounds the work for pathological input. */
static void symmetric_eigen(double A[LM_N][LM_N], double *w, double V[LM_N][LM_N])
{
    int i, j, k, sweep;
    for (i = 0; i < LM_N; i++)
        for (j = 0; j < LM_N; j++) V[i][j] = i == j ? 1.0 : 0.0;
    for (sweep = 0; sweep < 60; sweep++) {
        double off = 0.0, scale = 0.0;
        for (i = 0; i < LM_N; i++)
            for (j = 0; j < LM_N; j++) {
                if (i != j) off += A[i][j] * A[i][j];
                scale += A[i][j] * A[i][j];
            }
        if (off <= 1e-32 * scale) break;
        for (i = 0; i < LM_N - 1; i++)
            for (j = i + 1; j < LM_N; j++) {
                double theta, t, cs, sn;
                if (A[i][j] == 0.0) continue;
                theta = (A[j][j] - A[i][i]) / (2.0 * A[i][j]);
                t = (theta >= 0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
                cs = 1.0 / sqrt(t * t + 1.0);
                sn = t * cs;
                for (k = 0; k < LM_N; k++) { /* A <- A J */
                    const double aki = A[k][i], akj = A[k][j];
                    A[k][i] = cs * aki - sn * akj;
                    A[k][j] = sn * aki + cs * akj;
                }
                for (k = 0; k < LM_N; k++) { /* A <- J' A */
                    const double aik = A[i][k], ajk = A[j][k];
                    A[i][k] = cs * aik - sn * ajk;
                    A[j][k] = sn * aik + cs * ajk;
                }
                for (k = 0; k < LM_N; k++) {
                    const double vki = V[k][i], vkj = V[k][j];
                    V[k][i] = cs * vki - sn * vkj;
                    V[k][j] = sn * vki + cs * vkj;
                }
            }
    }
    for (i = 0; i < LM_N; i++) w[i] = A[i][i];
}

int linear_model_prepare(LinearModel *lm, const double *M0, const double *K0, const double *B0, const double *rest,
                         double U0, char *message, size_t size)
{
    double L[LM_N][LM_N], C[LM_N][LM_N], V[LM_N][LM_N], column[LM_N], bad = 0.0, largest = 0.0;
    int i, j, k, failed;
    memset(lm, 0, sizeof *lm);
    lm->U0 = U0;
    for (i = 0; i < LM_N; i++) {
        lm->rest[i] = rest[i];
        for (j = 0; j < LM_N; j++) {
            lm->M0[i][j] = L[i][j] = M0[i * LM_N + j];
            lm->K0[i][j] = K0[i * LM_N + j];
        }
    }
    failed = cholesky(L, &bad);
    if (failed) {
        snprintf(message, size, "model = linear: the mass matrix at rest is not positive definite (pivot %d = %g)",
                 failed, bad);
        return 1;
    }
    /* C = L^-1 K0 L^-T, symmetric; its eigenvectors Q give the modes L^-T Q, mass-normalized. */
    for (j = 0; j < LM_N; j++) {
        for (i = 0; i < LM_N; i++) column[i] = lm->K0[i][j];
        forward(L, column);
        for (i = 0; i < LM_N; i++) C[i][j] = column[i];
    }
    for (i = 0; i < LM_N; i++) {
        for (j = 0; j < LM_N; j++) column[j] = C[i][j];
        forward(L, column);
        for (j = 0; j < LM_N; j++) C[i][j] = column[j];
    }
    for (i = 0; i < LM_N; i++)
        for (j = 0; j < i; j++) C[i][j] = C[j][i] = 0.5 * (C[i][j] + C[j][i]);
    symmetric_eigen(C, lm->omega2, V);
    for (i = 0; i < LM_N; i++)
        if (fabs(lm->omega2[i]) > largest) largest = fabs(lm->omega2[i]);
    for (i = 0; i < LM_N; i++) {
        if (lm->omega2[i] < -1e-12 * (largest > 1.0 ? largest : 1.0)) {
            snprintf(message, size,
                     "model = linear: the rest state is unstable for these parameters (a normal mode "
                     "has omega^2 = %g < 0)",
                     lm->omega2[i]);
            return 1;
        }
        if (lm->omega2[i] < 0.0) lm->omega2[i] = 0.0;
    }
    for (j = 0; j < LM_N; j++) {
        for (i = 0; i < LM_N; i++) column[i] = V[i][j];
        backward(L, column);
        for (i = 0; i < LM_N; i++) lm->modes[i][j] = column[i];
    }
    /* modes' M0 = Q' L' */
    for (i = 0; i < LM_N; i++)
        for (j = 0; j < LM_N; j++) {
            double s = 0.0;
            for (k = 0; k < LM_N; k++) s += lm->modes[k][i] * lm->M0[k][j];
            lm->to_modal[i][j] = s;
        }
    for (i = 0; i < LM_N; i++)
        for (j = 0; j < N_FORCE_INPUTS; j++) {
            double s = 0.0;
            for (k = 0; k < LM_N; k++) s += lm->modes[k][i] * B0[k * N_FORCE_INPUTS + j];
            lm->modal_force[i][j] = s;
        }
    /* M0^-1 K0 and M0^-1 B0, column by column */
    for (j = 0; j < LM_N; j++) {
        for (i = 0; i < LM_N; i++) column[i] = lm->K0[i][j];
        forward(L, column);
        backward(L, column);
        for (i = 0; i < LM_N; i++) lm->stiffness[i][j] = column[i];
    }
    for (j = 0; j < N_FORCE_INPUTS; j++) {
        for (i = 0; i < LM_N; i++) column[i] = B0[i * N_FORCE_INPUTS + j];
        forward(L, column);
        backward(L, column);
        for (i = 0; i < LM_N; i++) lm->input_gain[i][j] = column[i];
    }
    return 0;
}

void linear_model_derivatives(const LinearModel *lm, double d, const double *x, const double *u, double *dx)
{
    int i, j;
    for (i = 0; i < LM_N; i++) {
        double a = -d * x[LM_N + i];
        for (j = 0; j < LM_N; j++) a -= lm->stiffness[i][j] * (x[j] - lm->rest[j]);
        if (u)
            for (j = 0; j < N_FORCE_INPUTS; j++) a += lm->input_gain[i][j] * u[j];
        dx[i] = x[LM_N + i];
        dx[LM_N + i] = a;
    }
}

void linear_model_step(const LinearModel *lm, double d, double H, const double *u, double *x)
{
    double eta[LM_N], rate[LM_N];
    int i, j;
    for (i = 0; i < LM_N; i++) {
        double e = 0.0, r = 0.0, g = 0.0, k, kdot, K;
        for (j = 0; j < LM_N; j++) {
            e += lm->to_modal[i][j] * (x[j] - lm->rest[j]);
            r += lm->to_modal[i][j] * x[LM_N + j];
        }
        if (u)
            for (j = 0; j < N_FORCE_INPUTS; j++) g += lm->modal_force[i][j] * u[j];
        oscillator_kernels(d, lm->omega2[i], H, &k, &kdot, &K);
        eta[i] = e * (kdot + d * k) + r * k + g * K;
        rate[i] = -lm->omega2[i] * k * e + r * kdot + g * k;
    }
    for (i = 0; i < LM_N; i++) {
        double q = 0.0, v = 0.0;
        for (j = 0; j < LM_N; j++) {
            q += lm->modes[i][j] * eta[j];
            v += lm->modes[i][j] * rate[j];
        }
        x[i] = lm->rest[i] + q;
        x[LM_N + i] = v;
    }
}

void linear_model_energies(const LinearModel *lm, const double *real, const double *dx, double *E_kin, double *E_pot,
                           double *rate_kin, double *rate_pot)
{
    double kin = 0.0, pot = 0.0, dkin = 0.0, dpot = 0.0;
    int i, j;
    for (i = 0; i < LM_N; i++)
        for (j = 0; j < LM_N; j++) {
            const double v_i = real[LM_N + i], v_j = real[LM_N + j];
            const double q_i = real[i] - lm->rest[i], q_j = real[j] - lm->rest[j];
            kin += 0.5 * v_i * lm->M0[i][j] * v_j;
            pot += 0.5 * q_i * lm->K0[i][j] * q_j;
            if (dx) {
                dkin += v_i * lm->M0[i][j] * dx[LM_N + j];
                dpot += q_i * lm->K0[i][j] * v_j;
            }
        }
    if (E_kin) *E_kin = kin;
    if (E_pot) *E_pot = lm->U0 + pot;
    if (rate_kin) *rate_kin = dkin;
    if (rate_pot) *rate_pot = dpot;
}

void linear_model_directional(const LinearModel *lm, double d, const double *real, const double *seed_x,
                              const double *seed_u, double *ddx, double *E_kin, double *E_pot)
{
    double kin = 0.0, pot = 0.0;
    int i, j;
    for (i = 0; i < LM_N; i++) {
        double a = -d * seed_x[LM_N + i];
        for (j = 0; j < LM_N; j++) {
            a -= lm->stiffness[i][j] * seed_x[j];
            kin += real[LM_N + i] * lm->M0[i][j] * seed_x[LM_N + j];
            pot += (real[i] - lm->rest[i]) * lm->K0[i][j] * seed_x[j];
        }
        for (j = 0; j < N_FORCE_INPUTS; j++) a += lm->input_gain[i][j] * seed_u[j];
        ddx[i] = seed_x[LM_N + i];
        ddx[LM_N + i] = a;
    }
    *E_kin = kin;
    *E_pot = pot;
}

#endif
