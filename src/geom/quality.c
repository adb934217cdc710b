/* quality.c: triangle quality as the smallest interior angle per face, and a
 * summary over the mesh (minimum, mean, 1st percentile, share above 20 deg).
 *
 * The minimum angle is the measure Delaunay refinement bounds (Shewchuk,
 * "Delaunay refinement algorithms for triangular mesh generation", 2002):
 * 20 degrees is the usual guarantee of Ruppert/Chew-style remeshers, hence
 * the threshold in the summary. Left out: aspect ratios, radius ratios, and
 * the maximum angle (which bounds interpolation error rather than conditioning).
 */
#include "crease/diffgeo.h"

#include <math.h>
#include <stdlib.h>

static const double RAD_TO_DEG = 57.29577951308232;
static const double QUALITY_GOOD_DEG = 20.0; /* Ruppert/Chew guarantee, see above */

void cr_mesh_face_min_angles(const cr_mesh *m, float *deg) {
    for (int32_t f = 0; f < m->nf; f++) {
        const int32_t *t = &m->tri[3 * f];
        const float *p[3] = {&m->pos[3 * (size_t)t[0]], &m->pos[3 * (size_t)t[1]],
                             &m->pos[3 * (size_t)t[2]]};
        double lo = INFINITY;
        for (int k = 0; k < 3; k++) {
            double a = cr_triangle_corner_angle(p[k], p[(k + 1) % 3], p[(k + 2) % 3]);
            if (a < lo) lo = a;
        }
        deg[f] = (float)(lo * RAD_TO_DEG);
    }
}

static int cmp_float(const void *pa, const void *pb) {
    float a = *(const float *)pa, b = *(const float *)pb;
    return (a > b) - (a < b);
}

cr_status cr_mesh_quality_stats(const cr_mesh *m, cr_quality_stats *out, cr_error *err) {
    *out = (cr_quality_stats){0};
    if (m->nf == 0) return CR_OK;
    float *deg = cr_malloc((size_t)m->nf * sizeof(float), err);
    if (!deg) return CR_ERR_MEMORY;
    cr_mesh_face_min_angles(m, deg);
    qsort(deg, (size_t)m->nf, sizeof(float), cmp_float);
    double sum = 0.0;
    int64_t good = 0;
    for (int32_t f = 0; f < m->nf; f++) {
        sum += deg[f];
        good += deg[f] > QUALITY_GOOD_DEG;
    }
    /* Nearest rank: the smallest value with at least 1% of faces at or below it. */
    int64_t rank = (int64_t)ceil(0.01 * m->nf);
    out->nf = m->nf;
    out->min_deg = deg[0];
    out->mean_deg = (float)(sum / m->nf);
    out->p01_deg = deg[rank > 0 ? rank - 1 : 0];
    out->frac_above_20 = (float)((double)good / m->nf);
    free(deg);
    return CR_OK;
}
