/* The linear model of an object: the quadratic approximation of T and U about its rest state,
 *   M0 a + K0 (q - rest) = B0 F - d M0 v,
 * solved in closed form over a communication step through its normal modes (forces held). The
 * object's physics.h defines N_COORDINATES, N_FORCE_INPUTS and HAS_LINEAR_MODEL before including
 * this header. */
#ifndef LINEAR_MODEL_H
#define LINEAR_MODEL_H

#include <stddef.h>

#if HAS_LINEAR_MODEL
#define LM_N N_COORDINATES
#define LM_F (N_FORCE_INPUTS > 0 ? N_FORCE_INPUTS : 1)

typedef struct {
    double rest[LM_N];
    double M0[LM_N][LM_N], K0[LM_N][LM_N];
    double U0; /* U at rest */
    double omega2[LM_N]; /* squared modal angular frequencies, >= 0 */
    double modes[LM_N][LM_N]; /* columns: mode shapes, normalized to modes' M0 modes = 1 */
    double to_modal[LM_N][LM_N]; /* modes' M0: modal coordinates from q - rest */
    double modal_force[LM_N][LM_F]; /* modes' B0: modal force per input */
    double stiffness[LM_N][LM_N]; /* M0^-1 K0 */
    double input_gain[LM_N][LM_F]; /* M0^-1 B0 */
} LinearModel;

/* Factorizes and decomposes; returns 0, or 1 with a message when M0 is not positive definite or the
 * rest state is unstable (a negative stiffness eigenvalue). M0, K0 are n x n row-major, B0 n x F. */
INTERNAL int linear_model_prepare(LinearModel *lm, const double *M0, const double *K0, const double *B0,
                                  const double *rest, double U0, char *message, size_t size);
/* dx = (v, a) of the linear model at x = (q, v); u == NULL means no force. */
INTERNAL void linear_model_derivatives(const LinearModel *lm, double d, const double *x, const double *u, double *dx);
/* x advanced by H in closed form with the inputs u held (u == NULL: none). */
INTERNAL void linear_model_step(const LinearModel *lm, double d, double H, const double *u, double *x);
/* The linear model's energies at real[] = (q, v, ...) and their rates (dx = (v, a)); NULL skips one. */
INTERNAL void linear_model_energies(const LinearModel *lm, const double *real, const double *dx, double *E_kin,
                                    double *E_pot, double *rate_kin, double *rate_pot);
/* The linear model's Jacobian times a seed (seed_x over (q, v), seed_u over the inputs) at
 * real[] = (q, v, ...): the change ddx of (v, a) and of the energies. */
INTERNAL void linear_model_directional(const LinearModel *lm, double d, const double *real, const double *seed_x,
                                       const double *seed_u, double *ddx, double *E_kin, double *E_pot);
#endif

#endif
