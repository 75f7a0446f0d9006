#ifndef PHYSICS_H
#define PHYSICS_H

typedef struct {
    double k, c, l0;
} ModelConst;

#endif
