/* mesh.c: creation, cloning, validation and simple whole-mesh edits of cr_mesh. */
#include "crease/mesh.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

cr_status cr_mesh_create(int32_t nv, int32_t nf, int32_t nuv, cr_mesh **out, cr_error *err) {
    *out = NULL;
    if (nv < 0 || nf < 0 || nuv < 0)
        return CR_FAIL(err, CR_ERR_INVALID, "mesh: negative size (V=%d, F=%d, U=%d)", nv, nf, nuv);
    cr_mesh *m = cr_calloc(1, sizeof *m, err);
    if (!m) return CR_ERR_MEMORY;
    m->nv = nv, m->nf = nf, m->nuv = nuv;
    m->pos = cr_calloc((size_t)nv * 3, sizeof(float), err);
    m->tri = cr_calloc((size_t)nf * 3, sizeof(int32_t), err);
    if (nuv > 0) {
        m->uv = cr_calloc((size_t)nuv * 2, sizeof(float), err);
        m->tri_uv = cr_calloc((size_t)nf * 3, sizeof(int32_t), err);
    }
    if (!m->pos || !m->tri || (nuv > 0 && (!m->uv || !m->tri_uv))) {
        cr_mesh_destroy(m);
        return CR_ERR_MEMORY;
    }
    *out = m;
    return CR_OK;
}

void cr_mesh_destroy(cr_mesh *m) {
    if (!m) return;
    free(m->pos);
    free(m->tri);
    free(m->uv);
    free(m->tri_uv);
    free(m->normal);
    for (int32_t i = 0; i < m->nattr; i++)
        free(m->attr[i].data);
    free(m->attr);
    free(m);
}

static void *dup_array(const void *src, size_t bytes, cr_error *err, int *failed) {
    if (!src) return NULL;
    void *p = cr_malloc(bytes, err);
    if (!p) {
        *failed = 1;
        return NULL;
    }
    memcpy(p, src, bytes);
    return p;
}

cr_status cr_mesh_clone(const cr_mesh *m, cr_mesh **out, cr_error *err) {
    *out = NULL;
    cr_mesh *c = cr_calloc(1, sizeof *c, err);
    if (!c) return CR_ERR_MEMORY;
    int failed = 0;
    c->nv = m->nv, c->nf = m->nf, c->nuv = m->nuv;
    c->pos = dup_array(m->pos, (size_t)m->nv * 3 * sizeof(float), err, &failed);
    c->tri = dup_array(m->tri, (size_t)m->nf * 3 * sizeof(int32_t), err, &failed);
    c->uv = dup_array(m->uv, (size_t)m->nuv * 2 * sizeof(float), err, &failed);
    c->tri_uv = dup_array(m->tri_uv, (size_t)m->nf * 3 * sizeof(int32_t), err, &failed);
    c->normal = dup_array(m->normal, (size_t)m->nv * 3 * sizeof(float), err, &failed);
    if (m->nattr > 0) {
        c->attr = cr_calloc((size_t)m->nattr, sizeof *c->attr, err);
        if (!c->attr) failed = 1;
        for (int32_t i = 0; c->attr && i < m->nattr; i++) {
            c->attr[i] = m->attr[i];
            c->attr[i].data = dup_array(
                m->attr[i].data, (size_t)m->nv * m->attr[i].dim * sizeof(float), err, &failed);
            c->nattr = i + 1;
        }
    }
    if (failed) {
        cr_mesh_destroy(c);
        return CR_ERR_MEMORY;
    }
    *out = c;
    return CR_OK;
}

const cr_mesh_attr *cr_mesh_find_attr(const cr_mesh *m, const char *name) {
    for (int32_t i = 0; i < m->nattr; i++)
        if (strcmp(m->attr[i].name, name) == 0) return &m->attr[i];
    return NULL;
}

cr_status cr_mesh_add_attr(cr_mesh *m, const char *name, int32_t dim, float **out, cr_error *err) {
    *out = NULL;
    if (strlen(name) >= CR_MESH_ATTR_NAME_MAX || dim <= 0)
        return CR_FAIL(err, CR_ERR_INVALID, "mesh attribute '%s': bad name or dim %d", name, dim);
    const cr_mesh_attr *found = cr_mesh_find_attr(m, name);
    if (found) {
        if (found->dim != dim)
            return CR_FAIL(err, CR_ERR_SHAPE, "mesh attribute '%s': has dim %d, asked for %d", name,
                           found->dim, dim);
        *out = found->data;
        return CR_OK;
    }
    cr_mesh_attr *grown = realloc(m->attr, (size_t)(m->nattr + 1) * sizeof *grown);
    if (!grown) return CR_FAIL(err, CR_ERR_MEMORY, "mesh attribute '%s': out of memory", name);
    m->attr = grown;
    float *data = cr_calloc((size_t)m->nv * dim, sizeof(float), err);
    if (!data) return CR_ERR_MEMORY;
    cr_mesh_attr *a = &m->attr[m->nattr++];
    memset(a, 0, sizeof *a);
    snprintf(a->name, sizeof a->name, "%s", name);
    a->dim = dim;
    a->data = data;
    *out = data;
    return CR_OK;
}

cr_status cr_mesh_validate(const cr_mesh *m, const char *source, cr_error *err) {
    for (int64_t i = 0; i < (int64_t)m->nv * 3; i++)
        if (!isfinite(m->pos[i]))
            return CR_FAIL(err, CR_ERR_NAN, "%s: vertex %lld has a non-finite coordinate", source,
                           (long long)(i / 3));
    for (int64_t i = 0; i < (int64_t)m->nf * 3; i++)
        if (m->tri[i] < 0 || m->tri[i] >= m->nv)
            return CR_FAIL(err, CR_ERR_RANGE, "%s: face %lld uses vertex %d, mesh has %d", source,
                           (long long)(i / 3), m->tri[i], m->nv);
    if (cr_mesh_has_uv(m)) {
        for (int64_t i = 0; i < (int64_t)m->nuv * 2; i++)
            if (!isfinite(m->uv[i]))
                return CR_FAIL(err, CR_ERR_NAN, "%s: UV %lld is not finite", source,
                               (long long)(i / 2));
        for (int64_t i = 0; i < (int64_t)m->nf * 3; i++)
            if (m->tri_uv[i] < 0 || m->tri_uv[i] >= m->nuv)
                return CR_FAIL(err, CR_ERR_RANGE, "%s: face %lld uses UV %d, mesh has %d", source,
                               (long long)(i / 3), m->tri_uv[i], m->nuv);
    }
    return CR_OK;
}

void cr_mesh_bounds(const cr_mesh *m, float lo[3], float hi[3]) {
    for (int k = 0; k < 3; k++)
        lo[k] = hi[k] = m->nv > 0 ? m->pos[k] : 0.0f;
    for (int32_t i = 1; i < m->nv; i++)
        for (int k = 0; k < 3; k++) {
            float x = m->pos[3 * i + k];
            if (x < lo[k]) lo[k] = x;
            if (x > hi[k]) hi[k] = x;
        }
}

double cr_mesh_diagonal(const cr_mesh *m) {
    float lo[3], hi[3];
    cr_mesh_bounds(m, lo, hi);
    double d2 = 0.0;
    for (int k = 0; k < 3; k++)
        d2 += ((double)hi[k] - lo[k]) * ((double)hi[k] - lo[k]);
    return sqrt(d2);
}

void cr_mesh_transform(cr_mesh *m, float scale, const float translate[3]) {
    for (int32_t i = 0; i < m->nv; i++)
        for (int k = 0; k < 3; k++)
            m->pos[3 * i + k] = scale * m->pos[3 * i + k] + translate[k];
}

static int grow(void **p, size_t bytes) {
    void *q = realloc(*p, bytes ? bytes : 1);
    if (!q) return 0;
    *p = q;
    return 1;
}

cr_status cr_mesh_append(cr_mesh *a, const cr_mesh *b, cr_error *err) {
    int uv = cr_mesh_has_uv(a) && cr_mesh_has_uv(b);
    int32_t nv = a->nv + b->nv, nf = a->nf + b->nf, nuv = uv ? a->nuv + b->nuv : 0;
    if (!grow((void **)&a->pos, (size_t)nv * 3 * sizeof(float)) ||
        !grow((void **)&a->tri, (size_t)nf * 3 * sizeof(int32_t)) ||
        (uv && (!grow((void **)&a->uv, (size_t)nuv * 2 * sizeof(float)) ||
                !grow((void **)&a->tri_uv, (size_t)nf * 3 * sizeof(int32_t)))))
        return CR_FAIL(err, CR_ERR_MEMORY, "mesh append: out of memory");
    memcpy(a->pos + 3 * (size_t)a->nv, b->pos, (size_t)b->nv * 3 * sizeof(float));
    for (int64_t i = 0; i < (int64_t)b->nf * 3; i++)
        a->tri[3 * (int64_t)a->nf + i] = b->tri[i] + a->nv;
    if (uv) {
        memcpy(a->uv + 2 * (size_t)a->nuv, b->uv, (size_t)b->nuv * 2 * sizeof(float));
        for (int64_t i = 0; i < (int64_t)b->nf * 3; i++)
            a->tri_uv[3 * (int64_t)a->nf + i] = b->tri_uv[i] + a->nuv;
    } else {
        free(a->uv);
        free(a->tri_uv);
        a->uv = NULL, a->tri_uv = NULL;
    }
    free(a->normal);
    a->normal = NULL;
    for (int32_t i = 0; i < a->nattr; i++)
        free(a->attr[i].data);
    free(a->attr);
    a->attr = NULL, a->nattr = 0;
    a->nv = nv, a->nf = nf, a->nuv = nuv;
    return CR_OK;
}
