/* normals.c: face normals and areas, area- and angle-weighted vertex normals.
 * Angle weighting gives the pseudo-normal that makes inside/outside tests
 * exact at vertices (Baerentzen & Aanaes, IEEE TVCG 2005). */
#include "base/vec3.h"
#include "crease/diffgeo.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

float cr_triangle_normal(const float a[3], const float b[3], const float c[3], float n[3]) {
    double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    double e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    double x = e1[1] * e2[2] - e1[2] * e2[1];
    double y = e1[2] * e2[0] - e1[0] * e2[2];
    double z = e1[0] * e2[1] - e1[1] * e2[0];
    double len = sqrt(x * x + y * y + z * z);
    if (len > 0) {
        n[0] = (float)(x / len), n[1] = (float)(y / len), n[2] = (float)(z / len);
    } else {
        n[0] = n[1] = n[2] = 0.0f;
    }
    return (float)len;
}

void cr_mesh_face_normals(const cr_mesh *m, float *normals, float *areas) {
    for (int32_t f = 0; f < m->nf; f++) {
        const int32_t *t = &m->tri[3 * f];
        float n[3];
        float twice_area =
            cr_triangle_normal(&m->pos[3 * t[0]], &m->pos[3 * t[1]], &m->pos[3 * t[2]], n);
        if (normals) memcpy(&normals[3 * f], n, sizeof n);
        if (areas) areas[f] = 0.5f * twice_area;
    }
}

/* atan2 keeps the angle accurate near 0 and pi, where acos of a dot product is not. */
double cr_triangle_corner_angle(const float a[3], const float b[3], const float c[3]) {
    float u[3], v[3];
    sub3f(b, a, u);
    sub3f(c, a, v);
    double cx = (double)u[1] * v[2] - (double)u[2] * v[1];
    double cy = (double)u[2] * v[0] - (double)u[0] * v[2];
    double cz = (double)u[0] * v[1] - (double)u[1] * v[0];
    double dot = (double)u[0] * v[0] + (double)u[1] * v[1] + (double)u[2] * v[2];
    return atan2(sqrt(cx * cx + cy * cy + cz * cz), dot);
}

void cr_mesh_vertex_normals(const cr_mesh *m, cr_normal_weight weight, float *normals) {
    double *acc = calloc((size_t)m->nv * 3, sizeof(double));
    CR_ASSERT(acc || m->nv == 0);
    for (int32_t f = 0; f < m->nf; f++) {
        const int32_t *t = &m->tri[3 * f];
        float n[3];
        float twice_area =
            cr_triangle_normal(&m->pos[3 * t[0]], &m->pos[3 * t[1]], &m->pos[3 * t[2]], n);
        for (int k = 0; k < 3; k++) {
            double w =
                weight == CR_NORMAL_AREA
                    ? 0.5 * twice_area
                    : cr_triangle_corner_angle(&m->pos[3 * t[k]], &m->pos[3 * t[(k + 1) % 3]],
                                               &m->pos[3 * t[(k + 2) % 3]]);
            for (int d = 0; d < 3; d++)
                acc[3 * (size_t)t[k] + d] += w * n[d];
        }
    }
    for (int32_t v = 0; v < m->nv; v++) {
        double *a = &acc[3 * (size_t)v];
        double len = sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
        for (int d = 0; d < 3; d++)
            normals[3 * (size_t)v + d] = len > 0 ? (float)(a[d] / len) : 0.0f;
    }
    free(acc);
}

cr_status cr_mesh_compute_normals(cr_mesh *m, cr_error *err) {
    if (!m->normal) {
        m->normal = cr_malloc((size_t)m->nv * 3 * sizeof(float), err);
        if (!m->normal) return CR_ERR_MEMORY;
    }
    cr_mesh_vertex_normals(m, CR_NORMAL_AREA, m->normal);
    return CR_OK;
}
