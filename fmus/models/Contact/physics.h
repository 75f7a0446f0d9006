#ifndef PHYSICS_H
#define PHYSICS_H

typedef struct {
    double k, exponent, c, reach; /* reach = R_a + R_b: the centres' distance at touch */
} ModelConst;

#endif
