/* Taylor arithmetic for the Taylor method (each series an array of TAYLOR_SLOTS coefficients, w(t + s) =
 * sum_k w[k] s^k): the generated model_taylor writes its convolutions out itself (harness/objects/
 * taylor_code.py); here are the rare operations it calls (powers, logarithms) and the mass matrix's
 * factorization and solve. */
#ifndef TAYLOR_H
#define TAYLOR_H

#include <stdint.h>

/* The highest order comes with the generated physics.h (from harness.fmi.methods.TAYLOR_ORDERS). */
#ifndef TAYLOR_MAX_ORDER /* a model without states (the hand-written Spring) has no Taylor method */
#define TAYLOR_MAX_ORDER 1
#endif
#define TAYLOR_SLOTS (TAYLOR_MAX_ORDER + 1)

/* The evaluations a step of order p counts (in n_rhs and against the bound per call): coefficient k
 * costs about k + 1 multiply-adds per operation of the equations where an evaluation costs one, so
 * p (p + 1) / 2 in all; an over-count for the simple pendulum, whose sine dominates its evaluation, and
 * about twice the five-link chain's cost. */
static inline uint64_t taylor_charge(int order) { return (uint64_t)order * (uint64_t)(order + 1) / 2; }

/* w = a^r, k >= 1: k a_0 w_k = sum_{j=0..k-1} (r (k - j) - j) a_(k-j) w_j */
static inline double taylor_power(const double *a, double r, const double *w, int k)
{
    double sum = 0.0;
    int j;
    for (j = 0; j < k; j++) sum += (r * (k - j) - j) * a[k - j] * w[j];
    return sum / (k * a[0]);
}

/* w = log(a), k >= 1: w_k = (a_k - (1/k) sum_{j=1..k-1} j w_j a_(k-j)) / a_0 */
static inline double taylor_log(const double *a, const double *w, int k)
{
    double sum = 0.0;
    int j;
    for (j = 1; j < k; j++) sum += j * w[j] * a[k - j];
    return (a[k] - sum / k) / a[0];
}

/* LDL^T of the symmetric n x n matrix m (row-major) in place: L below the diagonal, D on it.
 * 0 when a pivot is not positive (M not positive definite here). */
static inline int taylor_factor(double *m, int n)
{
    int i, j, k;
    for (j = 0; j < n; j++) {
        double pivot = m[j * n + j];
        for (k = 0; k < j; k++) pivot -= m[j * n + k] * m[j * n + k] * m[k * n + k];
        if (!(pivot > 0.0)) return 0;
        m[j * n + j] = pivot;
        for (i = j + 1; i < n; i++) {
            double entry = m[i * n + j];
            for (k = 0; k < j; k++) entry -= m[i * n + k] * m[j * n + k] * m[k * n + k];
            m[i * n + j] = entry / pivot;
        }
    }
    return 1;
}

/* Solves M a = r in place with taylor_factor's LDL^T. */
static inline void taylor_solve(const double *m, int n, double *r)
{
    int i, k;
    for (i = 0; i < n; i++)
        for (k = 0; k < i; k++) r[i] -= m[i * n + k] * r[k];
    for (i = 0; i < n; i++) r[i] /= m[i * n + i];
    for (i = n - 1; i >= 0; i--)
        for (k = i + 1; k < n; k++) r[i] -= m[k * n + i] * r[k];
}

#endif
