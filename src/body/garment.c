/* garment.c: the garment API: defs, templates and instances, layers, the
 * quality report, and the checks every garment passes.
 *
 * A template (cr_garment_template) holds what does not depend on the
 * resolution: the field, the cut surface with its panels (garment_shapes.c),
 * and a reference remesh of REF_VERTICES vertices flattened into the UV
 * layout (garment_uv.c). An instance remeshes the cut surface at the wanted
 * vertex count (cr_garment_remesh.c), pushes any vertex closer to the body than
 * CR_GARMENT_MIN_CLEARANCE out to it, takes its UVs from the reference, and
 * its skinning weights from the body (garment_skin.c). Every instance of one
 * template therefore shares one UV layout and one uv_scale_m.
 *
 * Layers: each layer is its own level set of the same blurred distance
 * field, sampled on grids aligned to one lattice, so a vest at a larger
 * clearance than a shirt is a nested level set and cannot cross it (up to
 * the chords of both meshes, which the gap of CR_GARMENT_LAYER_GAP covers);
 * create_layers checks that with an exact edge-face crossing test.
 *
 * Left out: garments from 2-D sewing patterns.
 */
#include "garment_internal.h"

#include "crease/diffgeo.h"
#include "crease/topology.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define GARMENT_DEF_COOKIE 0x47524d54u
/* Vertices of the reference mesh the UV layout is flattened on: enough for
 * smooth charts, cheap to flatten. */
#define REF_VERTICES 2500
/* Every vertex ends at least this far out of the body, m (the 5 mm
 * plus a margin for float rounding in later distance queries). */
#define MIN_CLEARANCE_M 0.0052f

static const char *const type_names[CR_GARMENT_TYPE_COUNT] = {
    "tshirt", "longsleeve", "skirt", "dress", "trousers", "vest", "jumpsuit", "user"};

const char *cr_garment_type_name(cr_garment_type type) {
    return type >= 0 && type < CR_GARMENT_TYPE_COUNT ? type_names[type] : "unknown";
}

cr_status cr_garment_type_parse(const char *name, cr_garment_type *out, cr_error *err) {
    for (int t = 0; t < CR_GARMENT_USER; t++)
        if (strcmp(name, type_names[t]) == 0) {
            *out = (cr_garment_type)t;
            return CR_OK;
        }
    return CR_FAIL(err, CR_ERR_INVALID,
                   "garment: unknown type '%s' (tshirt, longsleeve, skirt, dress, trousers, vest, "
                   "jumpsuit)",
                   name);
}

cr_garment_def cr_garment_default_def(cr_garment_type type) {
    CR_ASSERT(type >= 0 && type < CR_GARMENT_USER);
    cr_garment_def d = {0};
    d.type = type;
    d.target_vertices = 8000;
    d.clearance_m =
        type == CR_GARMENT_VEST ? 0.02f
        : type == CR_GARMENT_TROUSERS || type == CR_GARMENT_SKIRT || type == CR_GARMENT_JUMPSUIT
            ? 0.015f
            : 0.01f;
    d.flare_deg = type == CR_GARMENT_DRESS ? 15.0f : 12.0f;
    d.length_scale = 1.0f;
    d.grid_m = 0.01f;
    d.remesh_iterations = 8;
    d.sleeve_scale = 1.0f;
    d.neck_m = 0.0f;
    d.cookie = GARMENT_DEF_COOKIE;
    return d;
}

static cr_status check_def(const cr_garment_def *d, cr_error *err) {
    CR_ASSERT(d->cookie == GARMENT_DEF_COOKIE);
    if (!(d->type >= 0 && d->type < CR_GARMENT_USER))
        return CR_FAIL(err, CR_ERR_INVALID, "garment: type %d has no procedural template",
                       (int)d->type);
    struct {
        const char *name;
        double v, lo, hi;
    } f[] = {{"target_vertices", d->target_vertices, 500, 100000},
             {"grid_m", d->grid_m, 0.004, 0.03},
             {"remesh_iterations", d->remesh_iterations, 1, 50}};
    for (size_t i = 0; i < sizeof f / sizeof f[0]; i++)
        if (!cr_garment_in_range(f[i].v, f[i].lo, f[i].hi))
            return CR_FAIL(err, CR_ERR_INVALID, "garment: %s = %g (need %g to %g)", f[i].name,
                           f[i].v, f[i].lo, f[i].hi);
    return cr_garment_params_check(d, err);
}

void cr_garment_destroy(cr_garment *g) {
    if (!g) return;
    cr_mesh_destroy(g->mesh);
    free(g->skin_joint);
    free(g->skin_weight);
    free(g->panel);
    free(g);
}

cr_status cr_garment_finish(const gbody *body, cr_garment_type type, cr_mesh *mesh, int32_t *panel,
                            int32_t npanels, char (*names)[24], float uv_scale_m, float clearance,
                            int loose, cr_garment **out, cr_error *err) {
    *out = NULL;
    cr_garment *g = cr_calloc(1, sizeof *g, err);
    if (!g) {
        cr_mesh_destroy(mesh);
        free(panel);
        return CR_ERR_MEMORY;
    }
    g->type = type, g->mesh = mesh, g->panel = panel, g->npanels = npanels;
    g->uv_scale_m = uv_scale_m, g->clearance_m = clearance;
    memcpy(g->panel_name, names, (size_t)npanels * sizeof g->panel_name[0]);
    g->skin_joint = cr_malloc((size_t)mesh->nv * 4 * sizeof(int32_t), err);
    g->skin_weight = cr_malloc((size_t)mesh->nv * 4 * sizeof(float), err);
    cr_status st = g->skin_joint && g->skin_weight ? CR_OK : CR_ERR_MEMORY;
    if (st == CR_OK) st = cr_mesh_compute_normals(mesh, err);
    if (st == CR_OK)
        st = cr_garment_skin_transfer(body, mesh, loose, clearance, g->skin_joint, g->skin_weight,
                                      err);
    if (st != CR_OK) {
        cr_garment_destroy(g);
        return st;
    }
    *out = g;
    return CR_OK;
}

/* ----------------------------------------------------------- templates -- */

struct cr_garment_template {
    cr_garment_def def;
    gbase base;
    cr_mesh *ref;       /* reference remesh carrying the UV layout */
    int32_t *ref_panel; /* (F_ref) */
    float uv_scale_m;
    int32_t body_nv, body_nf; /* the body it was fitted to */
};

void cr_garment_template_destroy(cr_garment_template *t) {
    if (!t) return;
    cr_gbase_free(&t->base);
    cr_mesh_destroy(t->ref);
    free(t->ref_panel);
    free(t);
}

cr_status cr_garment_template_create(const cr_garment_def *def, const cr_body_model *body,
                                     cr_garment_template **out, cr_error *err) {
    *out = NULL;
    CR_TRY(check_def(def, err));
    cr_garment_template *t = cr_calloc(1, sizeof *t, err);
    if (!t) return CR_ERR_MEMORY;
    t->def = *def;
    t->body_nv = body->rest->nv, t->body_nf = body->rest->nf;
    gbody gb;
    cr_status st = cr_gbody_init(&gb, body, err);
    if (st == CR_OK) {
        st = cr_garment_build_base(def, &gb, &t->base, err);
        cr_gbody_free(&gb);
    }
    gremesh_out ro = {0};
    if (st == CR_OK)
        st = cr_garment_remesh(&t->base.field, t->base.mesh, t->base.panel, NULL, NULL,
                               REF_VERTICES, def->remesh_iterations, &ro, err);
    if (st == CR_OK) {
        t->ref = ro.mesh, t->ref_panel = ro.panel;
        st = cr_garment_uv_layout(t->ref, t->ref_panel, t->base.npanels, &t->uv_scale_m, err);
    }
    if (st != CR_OK) {
        cr_garment_template_destroy(t);
        return st;
    }
    *out = t;
    return CR_OK;
}

cr_status cr_garment_template_instantiate(const cr_garment_template *t, int32_t target_vertices,
                                          const cr_body_model *body, cr_garment **out,
                                          cr_error *err) {
    *out = NULL;
    if (!(target_vertices >= 500 && target_vertices <= 100000))
        return CR_FAIL(err, CR_ERR_INVALID, "garment: target_vertices = %d (need 500 to 100000)",
                       target_vertices);
    if (body->rest->nv != t->body_nv || body->rest->nf != t->body_nf)
        return CR_FAIL(err, CR_ERR_SHAPE,
                       "garment: the template was fitted to a body of %d vertices and %d faces, "
                       "not this one (%d, %d)",
                       t->body_nv, t->body_nf, body->rest->nv, body->rest->nf);
    gbody gb;
    CR_TRY(cr_gbody_init(&gb, body, err));
    gremesh_out ro = {0};
    /* The reference is already a good mesh of the surface: half the rounds do. */
    int32_t rounds = t->def.remesh_iterations / 2 > 3 ? t->def.remesh_iterations / 2 : 3;
    cr_status st = cr_garment_remesh(&t->base.field, t->base.mesh, t->base.panel, t->ref,
                                     t->ref_panel, target_vertices, rounds, &ro, err);
    if (st == CR_OK) {
        cr_garment_push_out(&gb, ro.mesh->pos, ro.mesh->nv, MIN_CLEARANCE_M);
        st = cr_garment_uv_transfer(t->ref, t->ref_panel, t->base.npanels, &t->base.field, ro.mesh,
                                    ro.panel, err);
    }
    if (st == CR_OK) {
        char names[CR_GARMENT_MAX_PANELS][24];
        memcpy(names, t->base.panel_name, sizeof names);
        st = cr_garment_finish(&gb, t->def.type, ro.mesh, ro.panel, t->base.npanels, names,
                               t->uv_scale_m, t->def.clearance_m, t->base.loose, out, err);
        ro.mesh = NULL, ro.panel = NULL; /* taken over, also on failure */
    }
    cr_mesh_destroy(ro.mesh);
    free(ro.panel);
    cr_gbody_free(&gb);
    return st;
}

cr_status cr_garment_create(const cr_garment_def *def, const cr_body_model *body, cr_garment **out,
                            cr_error *err) {
    *out = NULL;
    cr_garment_template *t = NULL;
    CR_TRY(cr_garment_template_create(def, body, &t, err));
    cr_status st = cr_garment_template_instantiate(t, def->target_vertices, body, out, err);
    cr_garment_template_destroy(t);
    return st;
}

/* -------------------------------------------------------------- layers -- */

int64_t cr_garment_count_crossings(const cr_mesh *a, const cr_mesh *b, cr_error *err) {
    int64_t n = 0;
    for (int pass = 0; pass < 2; pass++) {
        const cr_mesh *e = pass ? b : a, *f = pass ? a : b;
        cr_bvh *bvh = NULL;
        cr_topology *t = NULL;
        if (cr_bvh_build(f->pos, f->nv, f->tri, f->nf, &bvh, err) != CR_OK) return -1;
        if (cr_topology_build(e, &t, err) != CR_OK) {
            cr_bvh_destroy(bvh);
            return -1;
        }
        for (int32_t k = 0; k < t->ne; k++) {
            const float *p = &e->pos[3 * (size_t)t->edge[2 * k]],
                        *q = &e->pos[3 * (size_t)t->edge[2 * k + 1]];
            float dir[3] = {q[0] - p[0], q[1] - p[1], q[2] - p[2]};
            cr_bvh_ray_hit h;
            n += cr_bvh_raycast(bvh, p, dir, 1.0f, &h);
        }
        cr_topology_destroy(t);
        cr_bvh_destroy(bvh);
    }
    return n;
}

cr_status cr_garment_create_layers(const cr_garment_def *defs, int32_t n, const cr_body_model *body,
                                   cr_garment **out, cr_error *err) {
    for (int32_t i = 0; i < n; i++)
        out[i] = NULL;
    for (int32_t i = 1; i < n; i++)
        if (!(defs[i].clearance_m >= defs[i - 1].clearance_m + CR_GARMENT_LAYER_GAP - 1e-6f))
            return CR_FAIL(err, CR_ERR_INVALID,
                           "garment layers: layer %d (%s, clearance %g m) must clear layer %d "
                           "(%s, %g m) by at least %g m",
                           i, cr_garment_type_name(defs[i].type), (double)defs[i].clearance_m,
                           i - 1, cr_garment_type_name(defs[i - 1].type),
                           (double)defs[i - 1].clearance_m, (double)CR_GARMENT_LAYER_GAP);
    cr_status st = CR_OK;
    for (int32_t i = 0; i < n && st == CR_OK; i++) {
        if (defs[i].grid_m != defs[0].grid_m)
            st = CR_FAIL(err, CR_ERR_INVALID,
                         "garment layers: layer %d has grid_m %g m, layer 0 %g m; layers share "
                         "one grid",
                         i, (double)defs[i].grid_m, (double)defs[0].grid_m);
        if (st == CR_OK) st = cr_garment_create(&defs[i], body, &out[i], err);
        for (int32_t j = 0; j < i && st == CR_OK; j++) {
            int64_t c = cr_garment_count_crossings(out[j]->mesh, out[i]->mesh, err);
            if (c < 0)
                st = err ? err->status : CR_ERR_MEMORY;
            else if (c > 0)
                st = CR_FAIL(err, CR_ERR_TOPOLOGY,
                             "garment layers: layer %d (%s) crosses layer %d (%s) at %lld edges", i,
                             cr_garment_type_name(defs[i].type), j,
                             cr_garment_type_name(defs[j].type), (long long)c);
        }
    }
    if (st != CR_OK)
        for (int32_t i = 0; i < n; i++) {
            cr_garment_destroy(out[i]);
            out[i] = NULL;
        }
    return st;
}

/* ------------------------------------------------------------- quality -- */

cr_status cr_garment_measure(const cr_garment *g, const cr_body_model *body,
                             cr_garment_quality *out, cr_error *err) {
    memset(out, 0, sizeof *out);
    const cr_mesh *m = g->mesh;
    out->vertices = m->nv, out->faces = m->nf, out->panels = g->npanels;
    cr_quality_stats q;
    CR_TRY(cr_mesh_quality_stats(m, &q, err));
    out->share_min_angle_above_20deg = q.frac_above_20;
    out->min_angle_deg = q.min_deg;
    cr_topology *t = NULL;
    CR_TRY(cr_topology_build(m, &t, err));
    out->manifold = cr_topology_require_manifold(t, "garment", NULL) == CR_OK;
    out->boundary_loops = t->nloop;
    cr_topology_destroy(t);
    for (int32_t v = 0; v < m->nv; v++) {
        double s = 0.0;
        for (int k = 0; k < 4; k++) {
            s += g->skin_weight[4 * v + k];
            out->bad_joints +=
                !(g->skin_joint[4 * v + k] >= 0 && g->skin_joint[4 * v + k] < CR_NJOINTS);
        }
        out->max_weight_sum_error = fmaxf(out->max_weight_sum_error, (float)fabs(s - 1.0));
    }
    cr_bvh *bvh = NULL;
    CR_TRY(
        cr_bvh_build(body->rest->pos, body->rest->nv, body->rest->tri, body->rest->nf, &bvh, err));
    size_t n = (size_t)(m->nv > m->nf ? m->nv : m->nf);
    float *d = cr_malloc(n * sizeof(float), err);
    float *nrm = cr_malloc(n * 3 * sizeof(float), err);
    float *cen = cr_malloc((size_t)m->nf * 3 * sizeof(float), err);
    float *fn = cr_malloc((size_t)m->nf * 3 * sizeof(float), err);
    float *area = cr_malloc((size_t)m->nf * sizeof(float), err);
    cr_status st = d && nrm && cen && fn && area ? CR_OK : CR_ERR_MEMORY;
    if (st == CR_OK) {
        cr_bvh_signed_distance_batch(bvh, m->pos, m->nv, INFINITY, d, NULL, NULL);
        out->min_clearance_m = INFINITY;
        for (int32_t v = 0; v < m->nv; v++)
            out->min_clearance_m = fminf(out->min_clearance_m, d[v]);
        for (int32_t f = 0; f < m->nf; f++)
            for (int k = 0; k < 3; k++)
                cen[3 * f + k] = (m->pos[3 * (size_t)m->tri[3 * f] + k] +
                                  m->pos[3 * (size_t)m->tri[3 * f + 1] + k] +
                                  m->pos[3 * (size_t)m->tri[3 * f + 2] + k]) /
                                 3.0f;
        cr_bvh_signed_distance_batch(bvh, cen, m->nf, INFINITY, d, nrm, NULL);
        cr_mesh_face_normals(m, fn, area);
        int64_t outward = 0;
        for (int32_t f = 0; f < m->nf; f++)
            outward += fn[3 * f] * nrm[3 * f] + fn[3 * f + 1] * nrm[3 * f + 1] +
                           fn[3 * f + 2] * nrm[3 * f + 2] >
                       0.0f;
        out->share_outward = m->nf ? (float)((double)outward / m->nf) : 0.0f;
        /* Per panel: UV area * uv_scale^2 against 3-D area. */
        double a3[CR_GARMENT_MAX_PANELS] = {0}, a2[CR_GARMENT_MAX_PANELS] = {0};
        for (int32_t f = 0; f < m->nf && cr_mesh_has_uv(m); f++) {
            const float *u0 = &m->uv[2 * (size_t)m->tri_uv[3 * f]];
            const float *u1 = &m->uv[2 * (size_t)m->tri_uv[3 * f + 1]];
            const float *u2 = &m->uv[2 * (size_t)m->tri_uv[3 * f + 2]];
            int32_t p = g->panel[f];
            out->uv_flipped +=
                (u1[0] - u0[0]) * (u2[1] - u0[1]) - (u1[1] - u0[1]) * (u2[0] - u0[0]) <= 0.0f;
            a3[p] += area[f];
            a2[p] += 0.5 * fabs((double)(u1[0] - u0[0]) * (u2[1] - u0[1]) -
                                (double)(u1[1] - u0[1]) * (u2[0] - u0[0]));
        }
        double s2 = (double)g->uv_scale_m * g->uv_scale_m;
        for (int32_t p = 0; p < g->npanels && cr_mesh_has_uv(m); p++)
            if (a3[p] > 0.0)
                out->uv_area_error =
                    fmaxf(out->uv_area_error, (float)fabs(a2[p] * s2 / a3[p] - 1.0));
    }
    free(d), free(nrm), free(cen), free(fn), free(area);
    cr_bvh_destroy(bvh);
    return st;
}
