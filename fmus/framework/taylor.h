/* Taylor arithmetic for the Taylor method: coefficient k of a series from coefficients 0 ... k of
 * its operands (each series an array of TAYLOR_SLOTS coefficients, w(t + s) = sum_k w[k] s^k). The
 * generated model_taylor strings these together; see harness/objects/taylor_code.py for the rules. */
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
static inline uint64_t taylor_charge(int order)
{
    return (uint64_t)order * (uint64_t)(order + 1) / 2;
}

/* (a b)_k */
static inline double taylor_product(const double *a, const double *b, int k)
{
    double sum = 0.0;
    int j;
    for (j = 0; j <= k; j++) sum += a[j] * b[k - j];
    return sum;
}

/* (a^2)_k, each cross term once */
static inline double taylor_square(const double *a, int k)
{
    double sum = 0.0;
    int j;
    for (j = 0; j < (k + 1) / 2; j++) sum += a[j] * a[k - j];
    sum *= 2.0;
    if (!(k & 1)) sum += a[k / 2] * a[k / 2];
    return sum;
}

/* w = a / b given a_k: w_k = (a_k - sum_{j=1..k} b_j w_(k-j)) / b_0 */
static inline double taylor_quotient(double a_k, const double *b, const double *w, int k)
{
    double sum = a_k;
    int j;
    for (j = 1; j <= k; j++) sum -= b[j] * w[k - j];
    return sum / b[0];
}

/* sum_{j=1..k} m_j a_(k-j): the part of (m a)_k that coefficients below k of a give */
static inline double taylor_shifted(const double *m, const double *a, int k)
{
    double sum = 0.0;
    int j;
    for (j = 1; j <= k; j++) sum += m[j] * a[k - j];
    return sum;
}

/* w = sqrt(a), k >= 1: w_k = (a_k - sum_{j=1..k-1} w_j w_(k-j)) / (2 w_0) */
static inline double taylor_sqrt(const double *a, const double *w, int k)
{
    double sum = a[k];
    int j;
    for (j = 1; j < k; j++) sum -= w[j] * w[k - j];
    return sum / (2.0 * w[0]);
}

/* w = a^r, k >= 1: k a_0 w_k = sum_{j=0..k-1} (r (k - j) - j) a_(k-j) w_j */
static inline double taylor_power(const double *a, double r, const double *w, int k)
{
    double sum = 0.0;
    int j;
    for (j = 0; j < k; j++) sum += (r * (k - j) - j) * a[k - j] * w[j];
    return sum / (k * a[0]);
}

/* w' = g a', k >= 1: w_k = (1/k) sum_{j=1..k} j a_j g_(k-j) (sin and cos, exp, atan, ...) */
static inline double taylor_chain(const double *a, const double *g, int k)
{
    double sum = 0.0;
    int j;
    for (j = 1; j <= k; j++) sum += j * a[j] * g[k - j];
    return sum / k;
}

/* s = sin(a) and c = cos(a) (sign -1; sinh and cosh: sign 1), k >= 1: taylor_chain for both in one pass over
 * d_j = j a_j (d_k set here, d_1 ... d_(k-1) by the calls before); inverse_k = 1 / k. Each sum in two halves (odd
 * and even j), so that four additions run side by side instead of waiting on one another. */
static inline void taylor_sincos(const double *a, double *d, double *s, double *c, double sign, double inverse_k,
                                 int k)
{
    double odd_s = 0.0, odd_c = 0.0, even_s = 0.0, even_c = 0.0;
    int j;
    d[k] = k * a[k];
    for (j = 1; j < k; j += 2) {
        odd_s += d[j] * c[k - j];
        odd_c += d[j] * s[k - j];
        even_s += d[j + 1] * c[k - j - 1];
        even_c += d[j + 1] * s[k - j - 1];
    }
    if (j == k) {
        odd_s += d[k] * c[0];
        odd_c += d[k] * s[0];
    }
    s[k] = (odd_s + even_s) * inverse_k;
    c[k] = sign * ((odd_c + even_c) * inverse_k);
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
