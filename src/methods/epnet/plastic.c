/* plastic.c: epnet's perfect-plastic rule (paper 004, Eq. 4-5) over a
 * sequence of hinge angles, the hinge graph P-Net passes messages on, and
 * the fold measure of the persistence test.
 *
 * The sigmoid gate s(sharpness (|d| - yield)) is the authors' smoothing of
 * the max (their code, sharpness 50); phys/plasticity.c's CR_PLASTIC_SMOOTH
 * is the same rule per substep in the simulator. */
#include "crease/epnet.h"

#include <math.h>
#include <stdlib.h>

int64_t cr_epnet_plastic_rollout(const float *theta, const float *theta_bar, const float *rb0,
                                 int32_t nframes, int32_t nh, double yield, double gain,
                                 double sharpness, float *rb) {
    int64_t updates = 0;
    for (int32_t h = 0; h < nh; h++) {
        double r = rb0 ? rb0[h] : 0.0;
        const double bar = theta_bar ? theta_bar[h] : 0.0;
        for (int32_t t = 0; t < nframes; t++) {
            const double d = theta[(size_t)t * nh + h] - bar - r; /* Eq. 4 */
            const double over = fabs(d) - yield;
            if (over > 0) {
                const double gate = sharpness > 0 ? 1.0 / (1.0 + exp(-sharpness * over)) : 1.0;
                r += gain * (d > 0 ? 1.0 : -1.0) * gate * over; /* Eq. 5 */
                updates++;
            }
            rb[(size_t)t * nh + h] = (float)r;
        }
    }
    return updates;
}

/* Hinges around each vertex as a CSR, then the union of the four vertices'
 * lists per hinge (sorted, without the hinge itself). */
static int cmp_i32(const void *a, const void *b) {
    const int32_t x = *(const int32_t *)a, y = *(const int32_t *)b;
    return (x > y) - (x < y);
}

cr_status cr_epnet_hinge_graph(const cr_topology *t, int32_t **senders, int32_t **receivers,
                               int64_t *nedges, cr_error *err) {
    *senders = *receivers = NULL;
    *nedges = 0;
    const int32_t nh = t->nh, nv = t->nv;
    int32_t *start = calloc((size_t)nv + 1, sizeof *start);
    int32_t *list = malloc(sizeof(int32_t) * 4 * (size_t)(nh > 0 ? nh : 1));
    int32_t *fill = calloc((size_t)nv, sizeof *fill);
    if (!start || !list || !fill) {
        free(start), free(list), free(fill);
        return CR_FAIL(err, CR_ERR_MEMORY, "epnet hinge graph: out of memory for %d hinges", nh);
    }
    for (int32_t h = 0; h < nh; h++)
        for (int k = 0; k < 4; k++)
            start[t->hinge[4 * h + k] + 1]++;
    for (int32_t v = 0; v < nv; v++)
        start[v + 1] += start[v];
    for (int32_t h = 0; h < nh; h++)
        for (int k = 0; k < 4; k++) {
            const int32_t v = t->hinge[4 * h + k];
            list[start[v] + fill[v]++] = h;
        }
    free(fill);
    /* count then fill, with a per-hinge scratch of neighbours */
    int64_t cap = 0;
    for (int32_t h = 0; h < nh; h++)
        for (int k = 0; k < 4; k++) {
            const int32_t v = t->hinge[4 * h + k];
            cap += start[v + 1] - start[v];
        }
    int32_t *s = malloc(sizeof(int32_t) * (size_t)(cap > 0 ? cap : 1));
    int32_t *r = malloc(sizeof(int32_t) * (size_t)(cap > 0 ? cap : 1));
    int32_t *scratch = malloc(sizeof(int32_t) * (size_t)(cap > 0 ? cap : 1));
    if (!s || !r || !scratch) {
        free(start), free(list), free(s), free(r), free(scratch);
        return CR_FAIL(err, CR_ERR_MEMORY, "epnet hinge graph: out of memory for %lld edges",
                       (long long)cap);
    }
    int64_t ne = 0;
    for (int32_t h = 0; h < nh; h++) {
        int32_t n = 0;
        for (int k = 0; k < 4; k++) {
            const int32_t v = t->hinge[4 * h + k];
            for (int32_t i = start[v]; i < start[v + 1]; i++)
                if (list[i] != h) scratch[n++] = list[i];
        }
        qsort(scratch, (size_t)n, sizeof *scratch, cmp_i32);
        for (int32_t i = 0; i < n; i++) {
            if (i > 0 && scratch[i] == scratch[i - 1]) continue;
            s[ne] = scratch[i], r[ne] = h, ne++;
        }
    }
    free(start), free(list), free(scratch);
    *senders = s, *receivers = r, *nedges = ne;
    return CR_OK;
}

double cr_epnet_fold_share(const float *theta, const float *theta_bar, int32_t t, int32_t nh,
                           double thresh) {
    if (nh <= 0) return 0.0;
    int32_t n = 0;
    for (int32_t h = 0; h < nh; h++) {
        const double d = theta[(size_t)t * nh + h] - (theta_bar ? theta_bar[h] : 0.0f);
        if (fabs(d) > thresh) n++;
    }
    return (double)n / nh;
}

double cr_epnet_rb_realised(const float *theta, const float *theta0, const float *rb, int32_t nh,
                            double thresh) {
    double along = 0, total = 0;
    for (int32_t i = 0; i < nh; i++) {
        if (!(fabs(rb[i]) > thresh)) continue;
        along += (rb[i] > 0 ? 1.0 : -1.0) * ((double)theta[i] - theta0[i]);
        total += fabs(rb[i]);
    }
    return total > 0 ? along / total : NAN;
}
