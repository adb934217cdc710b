/* garment_user.c: a garment the user brings (OBJ, PLY or glb with UVs),
 * checked like the procedural ones and fitted to the body's rest pose.
 *
 * Checks, in order, each naming the file: a valid mesh, an oriented
 * 2-manifold (boundaries allowed), UVs not degenerate where there are any
 * (at most 1% of faces with zero UV area), a size that reads as metres
 * (bounding box diagonal 0.1 to 4; a larger one says which unit it may be
 * in), lying on the body (at least half the vertices within 0.3 m of it,
 * and none more than 0.1 m below its soles or above its crown),
 * and normals facing away from the body (area-weighted agreement with the
 * body's outward normal at the closest point).
 *
 * Fitting: with D the displacement from the file's positions, repeat
 * max_rounds times: push every vertex closer than the clearance out along
 * the body's signed-distance gradient (D += (c - d) n), then smooth D by
 * relax_iterations Jacobi steps of the uniform Laplacian, so the cloth
 * around a pushed vertex moves with it and keeps its folds instead of
 * getting dents; stop early once no vertex is closer than 0.98 c. A last
 * exact push leaves every vertex at least c out.
 *
 * Panels are the UV charts: faces joined through edges whose two corners
 * share UV indices on both sides. uv_scale_m is estimated as
 * sqrt(3-D area / UV area) over the whole garment.
 *
 * Without UVs (research garments often have none) the garment is accepted
 * for what needs none: the simulator's membrane takes its rest shape from
 * the 3-D rest triangles (as every garment's does in `simulate`, `dataset`,
 * epnet and swingar); panels are then the mesh's connected pieces
 * ("piece_0", ...) and uv_scale_m is 0. What needs UVs (drape's chart,
 * gdsr's normal maps) refuses it, naming itself.
 *
 * Seams: vertices at bit-identical positions are welded first (an exporter
 * that writes one vertex per UV or per panel), unless that makes the mesh
 * non-manifold. Panels are compared by UV values, not indices, so one `vt`
 * per face corner reads as the charts it draws.
 *
 * Left out: other repairs (flipping windings, welding seams that are near but
 * not exactly on each other), and collisions of the garment with itself.
 */
#include "garment_internal.h"

#include "crease/diffgeo.h"
#include "crease/mesh_io.h"
#include "crease/topology.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define USER_DEF_COOKIE 0x47555352u
/* A vertex this close to the body counts as on it, m. */
#define NEAR_BODY_M 0.3f
/* How far past the body's lowest and highest point a garment may reach, m
 * (a hem on the floor, a hood over the crown). */
#define BODY_SPAN_MARGIN_M 0.1f

cr_garment_user_def cr_garment_user_default_def(void) {
    cr_garment_user_def d = {0};
    d.clearance_m = 0.01f;
    d.relax_iterations = 10;
    d.max_rounds = 20;
    d.cookie = USER_DEF_COOKIE;
    return d;
}

static cr_status check_user_def(const cr_garment_user_def *d, cr_error *err) {
    CR_ASSERT(d->cookie == USER_DEF_COOKIE);
    if (!(d->clearance_m >= 0.005f && d->clearance_m <= 0.1f))
        return CR_FAIL(err, CR_ERR_INVALID, "garment: clearance_m = %g (need 0.005 to 0.1)",
                       (double)d->clearance_m);
    if (d->relax_iterations < 0 || d->relax_iterations > 200)
        return CR_FAIL(err, CR_ERR_INVALID, "garment: relax_iterations = %d (need 0 to 200)",
                       d->relax_iterations);
    if (d->max_rounds < 1 || d->max_rounds > 100)
        return CR_FAIL(err, CR_ERR_INVALID, "garment: max_rounds = %d (need 1 to 100)",
                       d->max_rounds);
    return CR_OK;
}

static double uv_area2(const cr_mesh *m, int32_t f) {
    const float *a = &m->uv[2 * (size_t)m->tri_uv[3 * f]],
                *b = &m->uv[2 * (size_t)m->tri_uv[3 * f + 1]],
                *c = &m->uv[2 * (size_t)m->tri_uv[3 * f + 2]];
    return (double)(b[0] - a[0]) * (c[1] - a[1]) - (double)(b[1] - a[1]) * (c[0] - a[0]);
}

static cr_status check_uvs_and_size(const cr_mesh *m, const char *src, cr_error *err) {
    int32_t flat = 0;
    for (int32_t f = 0; f < m->nf && cr_mesh_has_uv(m); f++)
        flat += uv_area2(m, f) == 0.0;
    if ((int64_t)flat * 100 > m->nf)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "%s: %d of %d faces have zero UV area; the UV layout is degenerate", src,
                       flat, m->nf);
    float lo[3], hi[3];
    cr_mesh_bounds(m, lo, hi);
    double diag = cr_mesh_diagonal(m);
    if (diag > 4.0)
        return CR_FAIL(
            err, CR_ERR_INVALID,
            "%s: the garment is %.4g units across (bounding box %.4g x %.4g x %.4g); "
            "expected metres (0.1 to 4)%s",
            src, diag, (double)(hi[0] - lo[0]), (double)(hi[1] - lo[1]), (double)(hi[2] - lo[2]),
            diag <= 400.0
                ? ": centimetres? scale it by 0.01 (crease convert IN OUT --scale 0.01)"
                : ": millimetres? scale it by 0.001 (crease convert IN OUT --scale 0.001)");
    if (diag < 0.1)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "%s: the garment is only %.4g units across; expected metres (0.1 to 4)", src,
                       diag);
    return CR_OK;
}

/* Share near the body and orientation, from distances d (V) and the
 * outward normals at the face centroids. */
static cr_status check_placement(const cr_mesh *m, const char *src, const gbody *body,
                                 cr_error *err) {
    const cr_bvh *bvh = body->bvh;
    const float body_lo_y = body->lo[1], body_hi_y = body->hi[1];
    float span_lo = INFINITY, span_hi = -INFINITY;
    for (int32_t v = 0; v < m->nv; v++)
        span_lo = fminf(span_lo, m->pos[3 * (size_t)v + 1]),
        span_hi = fmaxf(span_hi, m->pos[3 * (size_t)v + 1]);
    float *d = cr_malloc((size_t)m->nv * sizeof(float), err);
    float *cen = cr_malloc((size_t)m->nf * 3 * sizeof(float), err);
    float *nb = cr_malloc((size_t)m->nf * 3 * sizeof(float), err);
    float *fd = cr_malloc((size_t)m->nf * sizeof(float), err);
    float *fn = cr_malloc((size_t)m->nf * 3 * sizeof(float), err);
    float *area = cr_malloc((size_t)m->nf * sizeof(float), err);
    cr_status st = d && cen && nb && fd && fn && area ? CR_OK : CR_ERR_MEMORY;
    if (st == CR_OK) {
        cr_bvh_signed_distance_batch(bvh, m->pos, m->nv, INFINITY, d, NULL, NULL);
        int32_t near = 0;
        for (int32_t v = 0; v < m->nv; v++)
            near += fabsf(d[v]) < NEAR_BODY_M;
        if ((int64_t)near * 2 < m->nv)
            st = CR_FAIL(err, CR_ERR_INVALID,
                         "%s: only %d of %d vertices lie within %g m of the body; place the "
                         "garment on the body's rest pose (+Y up, facing +Z, soles at y = 0; a "
                         "Z-up file: crease convert IN OUT --z-up)",
                         src, near, m->nv, (double)NEAR_BODY_M);
    }
    if (st == CR_OK) {
        /* Near the body is not enough: a shirt 1.15 m low (SMPL's pelvis at the
         * origin) lies on the shins and through the floor. */
        int32_t below = 0, above = 0;
        for (int32_t v = 0; v < m->nv; v++) {
            float y = m->pos[3 * (size_t)v + 1];
            below += y < body_lo_y - BODY_SPAN_MARGIN_M;
            above += y > body_hi_y + BODY_SPAN_MARGIN_M;
        }
        if (below + above > 0)
            st = CR_FAIL(err, CR_ERR_INVALID,
                         "%s: %d of %d vertices lie %s the body (it spans y = %.2f to %.2f m; "
                         "the garment %.2f to %.2f m); place the garment on the body's rest "
                         "pose (+Y up, soles at y = 0; a garment made on SMPL's pelvis at the "
                         "origin needs lifting by the pelvis height)",
                         src, below + above, m->nv,
                         below && above ? "below and above"
                         : below        ? "below"
                                        : "above",
                         (double)body_lo_y, (double)body_hi_y, (double)span_lo, (double)span_hi);
    }
    if (st == CR_OK) {
        for (int32_t f = 0; f < m->nf; f++)
            for (int k = 0; k < 3; k++)
                cen[3 * f + k] = (m->pos[3 * (size_t)m->tri[3 * f] + k] +
                                  m->pos[3 * (size_t)m->tri[3 * f + 1] + k] +
                                  m->pos[3 * (size_t)m->tri[3 * f + 2] + k]) /
                                 3.0f;
        cr_bvh_signed_distance_batch(bvh, cen, m->nf, INFINITY, fd, nb, NULL);
        cr_mesh_face_normals(m, fn, area);
        double agree = 0.0, total = 0.0;
        for (int32_t f = 0; f < m->nf; f++) {
            agree += area[f] * (fn[3 * f] * nb[3 * f] + fn[3 * f + 1] * nb[3 * f + 1] +
                                fn[3 * f + 2] * nb[3 * f + 2]);
            total += area[f];
        }
        if (!(agree > 0.0))
            st = CR_FAIL(err, CR_ERR_TOPOLOGY,
                         "%s: the face normals point into the body (%.0f%% of the area against "
                         "its outward normal); reverse the faces' winding",
                         src, total > 0 ? 50.0 * (1.0 - agree / total) : 100.0);
    }
    free(d), free(cen), free(nb), free(fd), free(fn), free(area);
    return st;
}

/* Seams an exporter left open: vertices at bit-identical positions (one per
 * UV, or one per panel) would let the panels fall apart in the simulator.
 * Welded into *out (NULL when there is nothing to weld, or when welding would
 * make the mesh non-manifold: then they are kept apart, with a warning). */
static cr_status weld_seams(const cr_mesh *mesh, const char *src, cr_mesh **out, cr_error *err) {
    *out = NULL;
    cr_mesh *w = NULL;
    CR_TRY(cr_mesh_clone(mesh, &w, err));
    cr_status st = cr_mesh_weld(w, err);
    const int32_t merged = w ? mesh->nv - w->nv : 0;
    if (st != CR_OK || merged == 0) {
        cr_mesh_destroy(w);
        return st;
    }
    cr_topology *t = NULL;
    cr_error why = {0};
    if (cr_topology_build(w, &t, &why) == CR_OK &&
        cr_topology_require_manifold(t, src, &why) == CR_OK) {
        cr_log(CR_LOG_WARN, "%s: welded %d vertices that sat exactly on others (open seams)", src,
               merged);
        *out = w;
    } else {
        cr_log(CR_LOG_WARN,
               "%s: %d vertices sit exactly on others (open seams?), left apart: welding them "
               "would make the mesh non-manifold",
               src, merged);
        cr_mesh_destroy(w);
    }
    cr_topology_destroy(t);
    return CR_OK;
}

/* Push-and-relax rounds, then the last exact push (see the file comment). */
static cr_status fit(const gbody *body, cr_mesh *m, const cr_garment_user_def *def, cr_error *err) {
    cr_topology *t = NULL;
    CR_TRY(cr_topology_build(m, &t, err));
    const size_t n3 = (size_t)m->nv * 3;
    float *x0 = cr_malloc(n3 * sizeof(float), err);
    float *D = cr_calloc(n3, sizeof(float), err);
    float *next = cr_malloc(n3 * sizeof(float), err);
    float *d = cr_malloc((size_t)m->nv * sizeof(float), err);
    float *nrm = cr_malloc(n3 * sizeof(float), err);
    cr_status st = x0 && D && next && d && nrm ? CR_OK : CR_ERR_MEMORY;
    const float c = def->clearance_m;
    if (st == CR_OK) memcpy(x0, m->pos, n3 * sizeof(float));
    for (int round = 0; st == CR_OK && round < def->max_rounds; round++) {
        cr_bvh_signed_distance_batch(body->bvh, m->pos, m->nv, INFINITY, d, nrm, NULL);
        int32_t close = 0;
        for (int32_t v = 0; v < m->nv; v++) {
            if (d[v] >= c) continue;
            close += d[v] < 0.98f * c;
            for (int k = 0; k < 3; k++)
                D[3 * v + k] += (c - d[v]) * nrm[3 * v + k];
        }
        if (close == 0) break;
        for (int it = 0; it < def->relax_iterations; it++) {
            for (int32_t v = 0; v < m->nv; v++) {
                int32_t cnt = t->vv_off[v + 1] - t->vv_off[v];
                for (int k = 0; k < 3; k++) {
                    float s = 0.0f;
                    for (int32_t q = t->vv_off[v]; q < t->vv_off[v + 1]; q++)
                        s += D[3 * (size_t)t->vv[q] + k];
                    next[3 * v + k] =
                        cnt ? 0.5f * D[3 * v + k] + 0.5f * s / (float)cnt : D[3 * v + k];
                }
            }
            memcpy(D, next, n3 * sizeof(float));
        }
        for (size_t i = 0; i < n3; i++)
            m->pos[i] = x0[i] + D[i];
    }
    if (st == CR_OK) cr_garment_push_out(body, m->pos, m->nv, c);
    cr_topology_destroy(t);
    free(x0), free(D), free(next), free(d), free(nrm);
    return st;
}

/* Two UV indices name one point: the same index, or bit-identical values (an
 * exporter that writes one `vt` per face corner). */
static int same_uv(const cr_mesh *m, int32_t a, int32_t b) {
    return a == b || (a >= 0 && b >= 0 && m->uv[2 * (size_t)a] == m->uv[2 * (size_t)b] &&
                      m->uv[2 * (size_t)a + 1] == m->uv[2 * (size_t)b + 1]);
}

/* Panels = UV charts (union of faces across edges whose UV corners match),
 * or without UVs the connected pieces (faces joined through shared edges). */
static cr_status uv_charts(const cr_mesh *m, const cr_topology *t, const char *src, int32_t *panel,
                           int32_t *npanels, cr_error *err) {
    int32_t *parent = cr_malloc((size_t)m->nf * sizeof(int32_t), err);
    int32_t *id = cr_malloc((size_t)m->nf * sizeof(int32_t), err);
    if (!parent || !id) {
        free(parent), free(id);
        return CR_ERR_MEMORY;
    }
    const int has_uv = cr_mesh_has_uv(m);
    for (int32_t f = 0; f < m->nf; f++)
        parent[f] = f, id[f] = -1;
    for (int32_t f = 0; f < m->nf; f++)
        for (int k = 0; k < 3; k++) {
            int32_t g = t->face_face[3 * f + k];
            if (g < 0) continue;
            if (has_uv) { /* the corners of the shared edge in g, matched by vertex */
                int32_t a = m->tri[3 * f + k], b = m->tri[3 * f + (k + 1) % 3], ua = -1, ub = -1;
                for (int j = 0; j < 3; j++) {
                    if (m->tri[3 * g + j] == a) ua = m->tri_uv[3 * g + j];
                    if (m->tri[3 * g + j] == b) ub = m->tri_uv[3 * g + j];
                }
                if (!same_uv(m, ua, m->tri_uv[3 * f + k]) ||
                    !same_uv(m, ub, m->tri_uv[3 * f + (k + 1) % 3]))
                    continue;
            }
            int32_t x = f, y = g;
            while (parent[x] != x)
                x = parent[x] = parent[parent[x]];
            while (parent[y] != y)
                y = parent[y] = parent[parent[y]];
            if (x != y) parent[x > y ? x : y] = x > y ? y : x;
        }
    int32_t n = 0;
    cr_status st = CR_OK;
    for (int32_t f = 0; f < m->nf && st == CR_OK; f++) {
        int32_t r = f;
        while (parent[r] != r)
            r = parent[r];
        if (id[r] < 0) id[r] = n++;
        panel[f] = id[r];
        if (n > CR_GARMENT_MAX_PANELS)
            st = CR_FAIL(err, CR_ERR_INVALID, "%s: more than %d %s (panels)", src,
                         CR_GARMENT_MAX_PANELS, has_uv ? "UV charts" : "separate pieces (no UVs)");
    }
    *npanels = n;
    free(parent), free(id);
    return st;
}

cr_status cr_garment_fit_user(const cr_mesh *mesh, const char *source,
                              const cr_garment_user_def *def, const cr_body_model *body,
                              cr_garment **out, cr_error *err) {
    *out = NULL;
    CR_TRY(check_user_def(def, err));
    CR_TRY(cr_mesh_validate(mesh, source, err));
    if (mesh->nf == 0) return CR_FAIL(err, CR_ERR_TOPOLOGY, "%s: no faces", source);
    cr_mesh *welded = NULL;
    CR_TRY(weld_seams(mesh, source, &welded, err));
    if (welded) mesh = welded;
    cr_topology *t = NULL;
    cr_status tst = cr_topology_build(mesh, &t, err);
    if (tst != CR_OK) {
        cr_mesh_destroy(welded);
        return tst;
    }
    cr_status st = cr_topology_require_manifold(t, source, err);
    if (st == CR_OK) st = check_uvs_and_size(mesh, source, err);
    gbody gb = {0};
    if (st == CR_OK) st = cr_gbody_init(&gb, body, err);
    if (st == CR_OK) st = check_placement(mesh, source, &gb, err);
    cr_mesh *m = NULL;
    int32_t *panel = NULL, npanels = 0;
    if (st == CR_OK) st = cr_mesh_clone(mesh, &m, err);
    if (st == CR_OK) {
        panel = cr_malloc((size_t)m->nf * sizeof(int32_t), err);
        st = panel ? uv_charts(m, t, source, panel, &npanels, err) : CR_ERR_MEMORY;
    }
    if (st == CR_OK) st = fit(&gb, m, def, err);
    if (st == CR_OK) {
        const int has_uv = cr_mesh_has_uv(m);
        double a3 = 0.0, a2 = 0.0;
        for (int32_t f = 0; f < m->nf && has_uv; f++) {
            float n[3];
            a3 += 0.5 * cr_triangle_normal(&m->pos[3 * (size_t)m->tri[3 * f]],
                                           &m->pos[3 * (size_t)m->tri[3 * f + 1]],
                                           &m->pos[3 * (size_t)m->tri[3 * f + 2]], n);
            a2 += 0.5 * fabs(uv_area2(m, f));
        }
        if (!has_uv)
            cr_log(CR_LOG_INFO,
                   "%s: no UVs: the membrane's rest shape is the fitted 3-D mesh (StVK is "
                   "isotropic; Baraff-Witkin's warp runs along each triangle's first edge); %d "
                   "piece(s); drape and gdsr, which work in UV space, refuse it",
                   source, npanels);
        char names[CR_GARMENT_MAX_PANELS][24];
        for (int32_t p = 0; p < npanels; p++)
            snprintf(names[p], sizeof names[p], has_uv ? "chart_%d" : "piece_%d", p);
        st = cr_garment_finish(&gb, CR_GARMENT_USER, m, panel, npanels, names,
                               has_uv ? (float)sqrt(a3 / a2) : 0.0f, def->clearance_m, 0, out, err);
        m = NULL, panel = NULL; /* taken over */
    }
    cr_mesh_destroy(m);
    free(panel);
    cr_gbody_free(&gb);
    cr_topology_destroy(t);
    cr_mesh_destroy(welded);
    return st;
}

cr_status cr_garment_load_user(const char *path, const cr_garment_user_def *def,
                               const cr_body_model *body, cr_garment **out, cr_error *err) {
    *out = NULL;
    cr_mesh *m = NULL;
    CR_TRY(cr_mesh_read(path, &m, err));
    cr_status st = cr_garment_fit_user(m, path, def, body, out, err);
    cr_mesh_destroy(m);
    return st;
}
