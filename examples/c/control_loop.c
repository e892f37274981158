/*
 * A controller's loop on a graybox model, in the controller's own process (no service): load
 * a model file, step it 1000 times with gbx_predict_ws in a workspace of its own, warn on
 * stderr when the loop takes the model far from its training data, and check the first steps
 * against a rollout the service recorded.
 *
 * Usage: control_loop MODEL.gbx [RECORD.txt]
 * Without a record the loop starts at rest (x = 0) with the inputs at zero and prints where
 * it ends. RECORD.txt holds whitespace-separated numbers: n m steps, then x0 (2n), the inputs
 * (steps × m) and the service's states x0 … x_steps ((steps + 1) × 2n), each in shortest
 * round-trip form. The first `steps` states must match bit for bit; the loop then goes on to
 * 1000 steps with the inputs held at zero, and every state must stay finite.
 *
 * Build (README, "In your controller's process"): cargo build --release -p graybox-c, then
 * cc -O2 -I capi/include examples/c/control_loop.c -Ltarget/release -lgraybox_c -lm
 *    -Wl,-rpath,$PWD/target/release -o control_loop
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "graybox.h"

#define LOOP_STEPS 1000

/* z is the largest |z-score| of a step's state and input under the model's training data.
 * Past about 4 standard deviations the model answers about states it never saw: its networks
 * saturate there, so its outputs stay finite but mean little (README: "above ~4, treat the
 * outputs with doubt"). */
#define Z_DOUBT 4.0

static double *read_doubles(FILE *f, size_t count) {
    double *out = malloc(count * sizeof(double) + 1);
    for (size_t i = 0; out && i < count; i++) {
        if (fscanf(f, "%lf", &out[i]) != 1) {
            free(out);
            return NULL;
        }
    }
    return out;
}

int main(int argc, char **argv) {
    if (argc != 2 && argc != 3) {
        fprintf(stderr, "usage: %s MODEL.gbx [RECORD.txt]\n", argv[0]);
        return 2;
    }
    if (gbx_abi_version() != GBX_ABI_VERSION) {
        fprintf(stderr, "libgraybox_c is ABI %u, this program was built for %u\n",
                gbx_abi_version(), GBX_ABI_VERSION);
        return 1;
    }
    GbxModel *model = NULL;
    GbxWorkspace *ws = NULL;
    /* The loop's scratch, made once for one state per call: the steps allocate nothing. */
    if (gbx_model_load(argv[1], &model) != GBX_STATUS_OK ||
        gbx_workspace_new(model, 1, &ws) != GBX_STATUS_OK) {
        fprintf(stderr, "load: %s\n", gbx_last_error());
        return 1;
    }
    if (gbx_model_warning(model)) {
        fprintf(stderr, "warning: %s: %s\n", argv[1], gbx_model_warning(model));
    }
    /* A state is [q, v]: nq configuration values, nv velocities. */
    size_t m = gbx_model_m(model), nx = gbx_model_nq(model) + gbx_model_nv(model), steps = 0;
    double *x0 = calloc(nx, sizeof(double)), *inputs = NULL, *expected = NULL;
    gbx_model_neutral(model, x0);
    if (argc == 3) {
        size_t rnx, rm;
        FILE *f = fopen(argv[2], "r");
        if (!f || fscanf(f, "%zu %zu %zu", &rnx, &rm, &steps) != 3 || rnx != nx || rm != m) {
            fprintf(stderr, "%s: not a record of this model\n", argv[2]);
            return 1;
        }
        free(x0);
        x0 = read_doubles(f, nx);
        inputs = read_doubles(f, steps * m);
        expected = read_doubles(f, (steps + 1) * nx);
        fclose(f);
        if (!x0 || !inputs || !expected) {
            fprintf(stderr, "%s: too few numbers\n", argv[2]);
            return 1;
        }
    }

    double x[64], next[64], u[64] = {0};
    if (nx > 64 || m > 64) {
        fprintf(stderr, "this example holds states of at most 64 values and 64 inputs\n");
        return 1;
    }
    memcpy(x, x0, nx * sizeof(double));
    int mismatches = 0;
    double z, z_max = 0.0;
    size_t z_max_step = 0, z_first_step = 0;
    int far = 0;
    for (size_t t = 0; t < LOOP_STEPS; t++) {
        if (t < steps) {
            memcpy(u, inputs + t * m, m * sizeof(double));
        } else {
            memset(u, 0, m * sizeof(double));
        }
        if (gbx_predict_ws(model, ws, x, u, 1, next, NULL, &z, NULL) != GBX_STATUS_OK) {
            fprintf(stderr, "step %zu: %s\n", t, gbx_last_error());
            return 1;
        }
        if (z > Z_DOUBT && !far) {
            far = 1;
            z_first_step = t;
            fprintf(stderr,
                    "warning: step %zu: z = %.3g > %g: the state or input is far outside the "
                    "model's training data; treat its answers with doubt\n",
                    t, z, Z_DOUBT);
        }
        if (z > z_max) {
            z_max = z;
            z_max_step = t;
        }
        for (size_t i = 0; i < nx; i++) {
            if (t < steps && memcmp(&next[i], &expected[(t + 1) * nx + i], sizeof(double))) {
                fprintf(stderr, "step %zu, x[%zu]: %.17g, the service's %.17g\n", t + 1, i,
                        next[i], expected[(t + 1) * nx + i]);
                mismatches++;
            }
            if (!isfinite(next[i])) {
                fprintf(stderr, "step %zu: x[%zu] is not finite\n", t + 1, i);
                return 1;
            }
        }
        memcpy(x, next, nx * sizeof(double));
    }
    free(x0);
    free(inputs);
    free(expected);
    if (far) {
        fprintf(stderr, "warning: z went above %g at step %zu and reached %.3g at step %zu\n",
                Z_DOUBT, z_first_step, z_max, z_max_step);
    }
    if (mismatches) {
        return 1;
    }
    if (steps > 0) {
        printf("%d steps; the first %zu equal the service's rollout bit for bit\n", LOOP_STEPS,
               steps);
    } else {
        printf("%d steps of %g s from rest; q ends at", LOOP_STEPS, gbx_model_dt(model));
        for (size_t i = 0; i < gbx_model_nq(model); i++) {
            printf(" %.6g", x[i]);
        }
        printf("\n");
    }
    gbx_workspace_free(ws);
    gbx_model_free(model);
    return 0;
}
