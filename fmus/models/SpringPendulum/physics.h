#ifndef PHYSICS_H
#define PHYSICS_H

typedef struct {
    double g, d, m, D, l0, anchor_x, anchor_y;
    double D_over_m, inv_m;
} ModelConst;

#endif
