/* Prints the integrators' coefficients as JSON, straight from the data the FMUs are built with. */
#include <stdio.h>

#include "integrators.h"

static void print_tableau(const ButcherTableau *t, int last)
{
    int i, j;
    printf("  \"%s\": {\"stages\": %d, \"order\": %d, \"c\": [", t->name, t->stages, t->order);
    for (i = 0; i < t->stages; i++) printf("%s%.17g", i ? ", " : "", t->c[i]);
    printf("], \"a\": [");
    for (i = 0; i < t->stages; i++) {
        printf("%s[", i ? ", " : "");
        for (j = 0; j < t->stages; j++) printf("%s%.17g", j ? ", " : "", t->a[i][j]);
        printf("]");
    }
    printf("], \"b\": [");
    for (i = 0; i < t->stages; i++) printf("%s%.17g", i ? ", " : "", t->b[i]);
    printf("], \"e\": [");
    for (i = 0; i < t->stages; i++) printf("%s%.17g", i ? ", " : "", t->e[i]);
    printf("], \"implicit\": %s, \"d\": [", t->implicit ? "true" : "false");
    for (i = 0; i < t->stages && t->implicit; i++) printf("%s%.17g", i ? ", " : "", t->d[i]);
    printf("]}%s\n", last ? "" : ",");
}

static void print_adams_bashforth(const AdamsBashforth *ab, int last)
{
    int j;
    printf("  \"%s\": {\"steps\": %d, \"starter\": \"%s\", \"beta\": [", ab->name, ab->steps, ab->starter->name);
    for (j = 0; j < ab->steps; j++) printf("%s%.17g", j ? ", " : "", ab->beta[j]);
    printf("]");
    if (ab->corrected) {
        printf(", \"moulton\": [");
        for (j = 0; j < ab->steps; j++) printf("%s%.17g", j ? ", " : "", ab->moulton[j]);
        printf("]");
    }
    printf("}%s\n", last ? "" : ",");
}

int main(void)
{
    int solver;
    printf("{\n");
    for (solver = 1; solver <= SOLVER_COUNT; solver++) {
        const ButcherTableau *t = tableau_of(solver);
        if (t)
            print_tableau(t, solver == SOLVER_COUNT);
        else if (solver == SOLVER_GBS)
            printf("  \"%s\": {\"extrapolation\": true, \"columns\": %d}%s\n", solver_name(solver), GBS_MAX_COLUMNS,
                   solver == SOLVER_COUNT ? "" : ",");
        else if (solver == SOLVER_TAYLOR)
            printf("  \"%s\": {\"taylor\": true}%s\n", solver_name(solver), solver == SOLVER_COUNT ? "" : ",");
        else if (solver == SOLVER_STORMER_VERLET)
            printf("  \"%s\": {\"partitioned\": true, \"order\": 2}%s\n", solver_name(solver),
                   solver == SOLVER_COUNT ? "" : ",");
        else
            print_adams_bashforth(adams_bashforth_of(solver), solver == SOLVER_COUNT);
    }
    printf("}\n");
    return 0;
}
