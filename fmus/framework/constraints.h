/* Constraints of an object (Lagrange's equations of the first kind): the law of each, as its object
 * file declares it. Included by the physics.h of an object with constraints, before its ModelConst. */
#ifndef CONSTRAINTS_H
#define CONSTRAINTS_H

typedef struct {
    int bilateral; /* g = 0 always: pushes and pulls */
    int compliant; /* a force law instead of impulses */
    double restitution; /* rigid unilateral: the gap's rate after an impact is -restitution times the rate before */
    double stiffness, exponent, damping; /* compliant: F = k delta^exponent (1 + damping d(delta)/dt), delta = -g */
} ConstraintLaw;

/* A rebound slower than this (gap units per second) ends at rest: the constraint turns active where its
 * force pushes, else the object leaves with zero normal speed, so contact sequences end after finitely
 * many events. */
#define REST_SPEED 1e-3
/* A touching constraint turns active only where the motion it leaves free would close it faster than this (gap
 * units per second squared) and its force would push: touching without force stays open. */
#define REST_ACCELERATION 1e-6
/* Gaps within this of zero (gap units) touch: simultaneous impacts and activations take them in. */
#define CONTACT_GAP 1e-9
/* A rigid constraint's start must hold to this (SI units), bilateral ones also in their rate. */
#define START_GAP_TOLERANCE 1e-12
/* A gap below -GAP_ROUNDING (or a force below zero) is an event; above it, rounding. */
#define GAP_ROUNDING 1e-13
/* Sweeps of impulses over the contacts at one event (simultaneous impacts), and events per call. */
#define MAX_SWEEPS (16 * N_CONSTRAINTS + 16)
#define MAX_EVENTS_PER_CALL 100000

#endif
