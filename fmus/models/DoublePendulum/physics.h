#ifndef PHYSICS_H
#define PHYSICS_H

typedef struct {
    double g, d, m1, m2, J1, J2, s1, s2, l1, l2, anchor_x, anchor_y;
    double M11, M22; /* constant entries of the mass matrix */
    double B;        /* m2 l1 s2: the coupling, M12 = B cos(phi1 - phi2) */
    double G1, G2;   /* gravity torques per sine: (m1 s1 + m2 l1) g, m2 s2 g */
} ModelConst;

#endif
