/* bench_losses.c: cost of the physics losses on the tape (losses.h):
 * forward + backward of the generic energy op over an n x n sheet (membrane
 * triangles, hinges, vertices), B states at once. Prints medians, in ms and
 * in ns per element and batch item; docs/losses.md quotes them.
 *
 *   bench_losses [n] [B] [reps]      (default 100 4 9)
 */
#include "crease/losses.h"
#include "crease/phys_energies.h"
#include "crease/primitives.h"

#include "bench_stats.h"

#include <stdio.h>
#include <stdlib.h>

int main(int argc, char **argv) {
    const int n = argc > 1 ? atoi(argv[1]) : 100, B = argc > 2 ? atoi(argv[2]) : 4;
    const int reps = argc > 3 ? atoi(argv[3]) : 9;
    if (n < 2 || B < 1 || reps < 1 || reps > 1000) {
        fprintf(stderr, "usage: bench_losses [n >= 2] [B >= 1] [reps 1..1000]\n");
        return 2;
    }
    cr_error err = {0};
    cr_material mat;
    cr_mesh *m = NULL;
    cr_topology *topo = NULL;
    cr_membrane *mem = NULL;
    cr_bending *bend = NULL;
    cr_gravity *grav = NULL;
    const double g[3] = {0.0, -9.81, 0.0};
    if (cr_material_preset("cotton", &mat, &err) || cr_prim_plane(n, n, 1.0f, 1.0f, &m, &err) ||
        cr_topology_build(m, &topo, &err) || cr_membrane_create(m, 1, 1.0f, &mat, &mem, &err) ||
        cr_bending_create(m, topo, &mat, 0, &bend, &err) ||
        cr_gravity_create(m, &mat, g, &grav, &err)) {
        fprintf(stderr, "bench_losses: %s\n", err.msg);
        return 1;
    }
    const int32_t V = m->nv;
    float *x = malloc(sizeof(float) * 3 * (size_t)B * (size_t)V);
    cr_rng r = cr_rng_make(21, 0);
    for (int b = 0; b < B; b++)
        for (int64_t i = 0; i < 3 * (int64_t)V; i++)
            x[3 * (int64_t)V * b + i] =
                (float)((1.0 + 0.05 * b) * m->pos[i] + 0.002 * cr_rng_normal(&r));
    cr_nn_ctx *ctx = NULL;
    cr_nn_ctx_def def = cr_nn_ctx_default_def();
    def.arena_bytes = (size_t)512 << 20;
    if (!x || cr_nn_ctx_create(&def, &ctx, &err)) {
        fprintf(stderr, "bench_losses: %s\n", x ? err.msg : "out of memory");
        return 1;
    }
    cr_energy_term t[3];
    cr_membrane_term(mem, &t[0]);
    cr_bending_term(bend, &t[1]);
    cr_gravity_term(grav, &t[2]);
    printf(
        "bench_losses: %d x %d sheet, %d vertices, %d triangles, %d hinges, B = %d, %d threads\n",
        n, n, V, m->nf, cr_bending_count(bend), B, cr_thread_count());
    for (int q = 0; q < 3; q++) {
        double tf[1000], tb[1000];
        for (int k = 0; k < reps; k++) {
            cr_nn_ctx_reset(ctx);
            cr_tensor *xt = cr_nn_wrap(ctx, 3, (int64_t[]){B, V, 3}, x);
            xt->requires_grad = 1;
            const double t0 = cr_time_now();
            cr_tensor *loss = cr_nn_sum(ctx, cr_loss_energy(ctx, &t[q], xt));
            const double t1 = cr_time_now();
            if (!loss || cr_nn_backward(ctx, loss, &err)) {
                cr_nn_ctx_error(ctx, &err);
                fprintf(stderr, "bench_losses: %s\n", err.msg);
                return 1;
            }
            tb[k] = cr_time_now() - t1, tf[k] = t1 - t0;
        }
        const double f = bench_median(tf, reps), b = bench_median(tb, reps);
        printf("  %-9s forward %8.2f ms  backward %8.2f ms  %6.0f ns per element and item\n",
               t[q].name, 1e3 * f, 1e3 * b, 1e9 * (f + b) / ((double)B * t[q].nelem));
    }
    printf("  arena peak %.1f MiB\n", cr_nn_ctx_arena_peak(ctx) / 1048576.0);
    cr_nn_ctx_destroy(ctx);
    free(x);
    cr_gravity_destroy(grav);
    cr_bending_destroy(bend);
    cr_membrane_destroy(mem);
    cr_topology_destroy(topo);
    cr_mesh_destroy(m);
    return 0;
}
