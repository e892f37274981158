/*
 * The C library's latency as a controller sees it: gbx_predict and gbx_linearize of one state,
 * timed call by call with the monotonic clock after a warm-up, as JSON lines (median, 99th
 * percentile, mean in microseconds). `graybox-lab bench infer --model F --c-library LIB`
 * builds and runs it beside the Rust in-process and gRPC figures of the same model and state.
 *
 * Usage: latency MODEL.gbx CALLS < STATE, where STATE holds x (2n numbers) then u (m).
 */
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "graybox.h"

static double now_us(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec * 1e6 + (double)t.tv_nsec * 1e-3;
}

static int by_value(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static void report(const char *bench, double *us, size_t calls) {
    double sum = 0.0;
    for (size_t i = 0; i < calls; i++) sum += us[i];
    qsort(us, calls, sizeof(double), by_value);
    printf("{\"bench\":\"%s\",\"calls\":%zu,\"p50_us\":%.4f,\"p99_us\":%.4f,\"mean_us\":%.4f}\n",
           bench, calls, us[(size_t)((double)(calls - 1) * 0.5 + 0.5)],
           us[(size_t)((double)(calls - 1) * 0.99 + 0.5)], sum / (double)calls);
}

int main(int argc, char **argv) {
    if (argc != 3) {
        fprintf(stderr, "usage: %s MODEL.gbx CALLS < STATE\n", argv[0]);
        return 2;
    }
    GbxModel *model = NULL;
    if (gbx_model_load(argv[1], &model) != GBX_STATUS_OK) {
        fprintf(stderr, "load: %s\n", gbx_last_error());
        return 1;
    }
    /* A state is nq + nv values; A is 2nv × 2nv and B 2nv × m (the tangent space). */
    size_t nv = gbx_model_nv(model), m = gbx_model_m(model), nx = gbx_model_nq(model) + nv;
    size_t calls = strtoul(argv[2], NULL, 10);
    double *x = malloc(nx * sizeof(double)), *u = malloc((m + 1) * sizeof(double));
    double *next = malloc(nx * sizeof(double)), *a = malloc(4 * nv * nv * sizeof(double));
    double *b = malloc((2 * nv * m + 1) * sizeof(double)), *us = malloc((calls + 1) * sizeof(double));
    for (size_t i = 0; i < nx + m; i++) {
        if (scanf("%lf", i < nx ? &x[i] : &u[i - nx]) != 1) {
            fprintf(stderr, "the state needs %zu numbers on stdin\n", nx + m);
            return 2;
        }
    }
    for (int which = 0; which < 2; which++) {
        /* A tenth of the calls warm up the caches and the library's block lists. */
        for (size_t i = 0; i < calls + calls / 10; i++) {
            double t = now_us();
            GbxStatus s = which == 0 ? gbx_predict(model, x, u, 1, next, NULL)
                                     : gbx_linearize(model, x, u, 1, a, b);
            double dt = now_us() - t;
            if (s != GBX_STATUS_OK) {
                fprintf(stderr, "call: %s\n", gbx_last_error());
                return 1;
            }
            if (i >= calls / 10) us[i - calls / 10] = dt;
        }
        report(which == 0 ? "c_predict_1" : "c_linearize_1", us, calls);
    }
    gbx_model_free(model);
    free(x), free(u), free(next), free(a), free(b), free(us);
    return 0;
}
