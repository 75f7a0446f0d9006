#ifndef PHYSICS_H
#define PHYSICS_H

/* Constants derived once from the parameters, so that the right-hand side only multiplies. */
typedef struct {
    double g, d, L, m, anchor_x, anchor_y;
    double g_over_L; /* omega0^2 */
    double inv_mL;   /* force to angular acceleration: Q / (m L^2) = (F . dr/dphi) / (m L^2) */
    int linear;
} ModelConst;

#endif
