/* garment_outfit.c: garments worn over each other merged into one garment
 * (an outfit of two or more layers, one connected component each), with the
 * layers' rest clearance checked and, where needed, the outer one moved out.
 *
 * UVs: every template packs its charts into [0,1]^2 with its own
 * uv_scale_m, so two layers' charts overlap in UV. The outfit gives layer k
 * the strip u in [k/n, (k+1)/n) of one layout, each chart scaled by
 * uv_scale_k / S with one S = OUTFIT_UV_ROOM * n * max_k uv_scale_k, so uv * S
 * is still metres along the cloth and the strips are a tenth of their width
 * apart: a correspondence found through UV (gdsr Eq. 1) then never maps a
 * vertex of one layer onto a face of another, and every resolution of one
 * outfit shares the layout (the transform depends on the templates only).
 *
 * Clearance: for each layer, the vertices of the layers inside it whose
 * closest point on it lies inside one of its faces (where they overlap; a
 * closest point on its rim means the vertex is past an opening) must be at
 * least CR_GARMENT_OUTFIT_MIN_GAP behind it (signed distance against its
 * outward normals), and no edge of either may cross a face of the other. A
 * layer that fails is moved out along its vertex normals by 1 mm steps.
 */
#include "garment_internal.h"

#include "crease/bvh.h"
#include "crease/diffgeo.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Strip width over the widest layer's charts: 10 % of room between strips. */
#define OUTFIT_UV_ROOM 1.1f
#define OUTFIT_STEP_M 0.001f

/* Inner vertices (pos, n of them) in front of `outer` where they overlap:
 * closer than min_gap behind its surface, with the closest point inside a
 * face and within 5 cm (farther apart the layers do not overlap there). */
static int64_t count_in_front(const cr_bvh *outer, const float *pos, int32_t n, float min_gap) {
    int64_t bad = 0;
    for (int32_t v = 0; v < n; v++) {
        float d = 0.0f;
        cr_bvh_hit h;
        if (!cr_bvh_signed_distance(outer, pos + 3 * (int64_t)v, 0.05f, &d, NULL, &h)) continue;
        if (h.feature == CR_BVH_FACE && d > -min_gap) bad++;
    }
    return bad;
}

/* Is layer `outer` (positions pos) clear of inner layer `inner`? -1 on error. */
static int layer_clear(const cr_mesh *inner, const cr_mesh *outer, const float *pos,
                       cr_error *err) {
    cr_mesh view = *outer;
    view.pos = (float *)pos;
    int64_t c = cr_garment_count_crossings(inner, &view, err);
    if (c < 0) return -1;
    if (c > 0) return 0;
    cr_bvh *b = NULL;
    if (cr_bvh_build(pos, outer->nv, outer->tri, outer->nf, &b, err) != CR_OK) return -1;
    int64_t bad = count_in_front(b, inner->pos, inner->nv, CR_GARMENT_OUTFIT_MIN_GAP);
    cr_bvh_destroy(b);
    return bad == 0;
}

cr_status cr_garment_outfit(const cr_garment *const *layers, int32_t n, cr_garment **out,
                            float *offset_m, cr_error *err) {
    *out = NULL;
    if (n < 2 || n > CR_GARMENT_OUTFIT_MAX_LAYERS)
        return CR_FAIL(err, CR_ERR_INVALID, "garment outfit: %d layers, need 2 to %d", n,
                       CR_GARMENT_OUTFIT_MAX_LAYERS);
    int64_t nv = 0, nf = 0, nuv = 0;
    int32_t npanels = 0;
    float smax = 0.0f;
    for (int32_t k = 0; k < n; k++) {
        const cr_mesh *m = layers[k]->mesh;
        if (!cr_mesh_has_uv(m) || !m->normal)
            return CR_FAIL(err, CR_ERR_INVALID,
                           "garment outfit: layer %d (%s) has no UVs or no normals", k,
                           cr_garment_type_name(layers[k]->type));
        nv += m->nv, nf += m->nf, nuv += m->nuv, npanels += layers[k]->npanels;
        smax = fmaxf(smax, layers[k]->uv_scale_m);
        if (offset_m) offset_m[k] = 0.0f;
    }
    if (npanels > CR_GARMENT_MAX_PANELS)
        return CR_FAIL(err, CR_ERR_INVALID, "garment outfit: %d panels in all, at most %d", npanels,
                       CR_GARMENT_MAX_PANELS);
    if (nv > INT32_MAX / 4 || nf > INT32_MAX / 4)
        return CR_FAIL(err, CR_ERR_INVALID, "garment outfit: too large");
    cr_mesh *m = NULL;
    CR_TRY(cr_mesh_create((int32_t)nv, (int32_t)nf, (int32_t)nuv, &m, err));
    cr_garment *g = cr_calloc(1, sizeof *g, err);
    float *moved = cr_malloc(sizeof(float) * 3 * (size_t)nv, err);
    cr_status st = g && moved ? CR_OK : CR_ERR_MEMORY;
    if (st == CR_OK) {
        g->mesh = m, m = NULL;
        g->skin_joint = cr_malloc(sizeof(int32_t) * 4 * (size_t)nv, err);
        g->skin_weight = cr_malloc(sizeof(float) * 4 * (size_t)nv, err);
        g->panel = cr_malloc(sizeof(int32_t) * (size_t)nf, err);
        if (!g->skin_joint || !g->skin_weight || !g->panel) st = CR_ERR_MEMORY;
    }
    const float S = OUTFIT_UV_ROOM * (float)n * smax;
    int32_t v0 = 0, f0 = 0, u0 = 0;
    for (int32_t k = 0; k < n && st == CR_OK; k++) {
        const cr_garment *l = layers[k];
        const cr_mesh *src = l->mesh;
        cr_mesh *dst = g->mesh;
        /* Moved out until clear of every layer inside it. */
        float *pos = moved + 3 * (int64_t)v0;
        memcpy(pos, src->pos, sizeof(float) * 3 * (size_t)src->nv);
        int clear = 0;
        for (int step = 0; step <= CR_GARMENT_OUTFIT_MAX_STEPS && st == CR_OK; step++) {
            float off = OUTFIT_STEP_M * (float)step;
            for (int32_t v = 0; v < src->nv; v++)
                for (int c = 0; c < 3; c++)
                    pos[3 * v + c] = src->pos[3 * v + c] + off * src->normal[3 * v + c];
            /* against the inner layers as placed in the outfit (moved out too) */
            clear = 1;
            for (int32_t j = 0, w0 = 0; j < k && clear == 1; w0 += layers[j]->mesh->nv, j++) {
                cr_mesh view = *layers[j]->mesh;
                view.pos = moved + 3 * (int64_t)w0;
                clear = layer_clear(&view, src, pos, err);
            }
            if (clear < 0) st = err ? err->status : CR_ERR_MEMORY;
            if (clear == 1) {
                if (offset_m) offset_m[k] = off;
                break;
            }
        }
        if (st == CR_OK && clear != 1)
            st = CR_FAIL(err, CR_ERR_TOPOLOGY,
                         "garment outfit: layer %d (%s) still crosses or lies inside a layer "
                         "under it after moving it %g m out",
                         k, cr_garment_type_name(l->type),
                         (double)(OUTFIT_STEP_M * CR_GARMENT_OUTFIT_MAX_STEPS));
        if (st != CR_OK) break;
        memcpy(dst->pos + 3 * (int64_t)v0, pos, sizeof(float) * 3 * (size_t)src->nv);
        for (int32_t f = 0; f < src->nf; f++)
            for (int c = 0; c < 3; c++) {
                dst->tri[3 * (int64_t)(f0 + f) + c] = src->tri[3 * f + c] + v0;
                dst->tri_uv[3 * (int64_t)(f0 + f) + c] = src->tri_uv[3 * f + c] + u0;
            }
        const float s = l->uv_scale_m / S, du = (float)k / (float)n;
        for (int32_t u = 0; u < src->nuv; u++) {
            dst->uv[2 * (int64_t)(u0 + u)] = du + s * src->uv[2 * u];
            dst->uv[2 * (int64_t)(u0 + u) + 1] = s * src->uv[2 * u + 1];
        }
        memcpy(g->skin_joint + 4 * (int64_t)v0, l->skin_joint, sizeof(int32_t) * 4 * src->nv);
        memcpy(g->skin_weight + 4 * (int64_t)v0, l->skin_weight, sizeof(float) * 4 * src->nv);
        for (int32_t f = 0; f < src->nf; f++)
            g->panel[f0 + f] = l->panel[f] + g->npanels;
        for (int32_t p = 0; p < l->npanels; p++) {
            /* A long layer name is cut to fit; using the return value keeps
               -Wformat-truncation quiet at every optimisation level. */
            const int written = snprintf(g->panel_name[g->npanels + p], sizeof g->panel_name[0],
                                         "%d_%.20s", k, l->panel_name[p]);
            if (written < 0) g->panel_name[g->npanels + p][0] = '\0';
        }
        g->npanels += l->npanels;
        v0 += src->nv, f0 += src->nf, u0 += src->nuv;
    }
    if (st == CR_OK) st = cr_mesh_compute_normals(g->mesh, err);
    free(moved);
    cr_mesh_destroy(m);
    if (st != CR_OK) {
        cr_garment_destroy(g);
        return st;
    }
    g->type = layers[0]->type;
    g->uv_scale_m = S;
    g->clearance_m = layers[0]->clearance_m;
    *out = g;
    return CR_OK;
}
