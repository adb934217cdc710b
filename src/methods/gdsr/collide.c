/* collide.c: gdsr's collision handling (sec. 4.6, Eq. 26-27) on the high
 * garment: the per-vertex push out of the body, and a relaxation that
 * spreads each push over the pushed vertex's neighbourhood.
 *
 * A push of height h on one vertex stretches its one-ring's edges by about
 * (h / l)^2 / 2 (l the edge length); the same push spread as a smooth bump
 * of radius R = n l stretches each edge by (h / R)^2 / 2, so the strain
 * energy falls by about (l / R)^2. The relaxation smooths the displacement
 * D = x - raw by Jacobi steps of the uniform Laplacian on the vertices that
 * moved and their one-ring, then pushes out again whatever the smoothing
 * lowered back under the margin: each iteration spreads D by one ring while
 * the pushed vertices stay outside.
 *
 * Leaves out: cotangent weights; a tangential-only or strain-limiting
 * projection (the smoothed D has a tangential part too).
 */
#include "gdsr_internal.h"

#include <math.h>
#include <string.h>

int64_t cr_gdsr_push_out(const cr_bvh *b, float *x, int64_t n, float eps, float *sd, float *nrm,
                         float *push) {
    cr_bvh_signed_distance_batch(b, x, n, 0.2f, sd, nrm, NULL);
    int64_t inside = 0;
    for (int64_t i = 0; i < n; i++) {
        if (sd[i] < 0) inside++;
        if (sd[i] < eps) {
            float s = eps - sd[i];
            for (int k = 0; k < 3; k++) {
                x[3 * i + k] += s * nrm[3 * i + k];
                if (push) push[3 * i + k] = s * nrm[3 * i + k];
            }
        } else if (push) {
            push[3 * i] = push[3 * i + 1] = push[3 * i + 2] = 0.0f;
        }
    }
    return inside;
}

void cr_gdsr_relax_push(const cr_bvh *b, const cr_topology *t, const float *raw, float *x,
                        float eps, int iters, float *sd, float *nrm, float *d, float *dn,
                        uint8_t *moved) {
    int32_t n = t->nv;
    cr_gdsr_push_out(b, x, n, eps, sd, nrm, NULL);
    for (int it = 0; it < iters; it++) {
        for (int64_t i = 0; i < 3 * (int64_t)n; i++)
            d[i] = x[i] - raw[i];
        for (int32_t i = 0; i < n; i++)
            moved[i] = d[3 * i] != 0.0f || d[3 * i + 1] != 0.0f || d[3 * i + 2] != 0.0f;
        /* smooth on the moved vertices and their one-ring (moved[i] |= 2) */
        for (int32_t i = 0; i < n; i++) {
            int32_t b0 = t->vv_off[i], b1 = t->vv_off[i + 1];
            int near = moved[i] & 1;
            for (int32_t e = b0; !near && e < b1; e++)
                near = moved[t->vv[e]] & 1;
            if (!near || b1 == b0) continue;
            float s[3] = {0, 0, 0};
            for (int32_t e = b0; e < b1; e++)
                for (int k = 0; k < 3; k++)
                    s[k] += d[3 * (int64_t)t->vv[e] + k];
            for (int k = 0; k < 3; k++)
                dn[3 * (int64_t)i + k] = 0.5f * d[3 * (int64_t)i + k] + 0.5f * s[k] / (b1 - b0);
            moved[i] |= 2;
        }
        /* only the smoothed vertices moved: push those (gathered into d) */
        int64_t c = 0;
        for (int32_t i = 0; i < n; i++)
            if (moved[i] & 2) {
                for (int k = 0; k < 3; k++)
                    d[3 * c + k] = raw[3 * (int64_t)i + k] + dn[3 * (int64_t)i + k];
                c++;
            }
        cr_gdsr_push_out(b, d, c, eps, sd, nrm, NULL);
        c = 0;
        for (int32_t i = 0; i < n; i++)
            if (moved[i] & 2) {
                memcpy(&x[3 * (int64_t)i], &d[3 * c], 3 * sizeof(float));
                c++;
            }
    }
    cr_gdsr_push_out(b, x, n, eps, sd, nrm, NULL); /* concave spots: once more */
}
