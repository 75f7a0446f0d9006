/* The median of repeated timings, for the benchmarks' C programs (the values are sorted in place). */
#ifndef BENCHMARK_MEDIAN_H
#define BENCHMARK_MEDIAN_H

#include <stdlib.h>

static int compare_doubles(const void *a, const void *b)
{
    const double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double median(double *values, int n)
{
    qsort(values, (size_t)n, sizeof(double), compare_doubles);
    return values[n / 2];
}

#endif
