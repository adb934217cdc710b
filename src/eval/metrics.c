/* metrics.c: cr_eval_run, every paper's metric of a predicted garment
 * sequence against a reference one, frame by frame, and their summaries.
 *
 * T frames, V vertices, F triangles, H interior hinges (cr_topology order),
 * Vb body vertices, S the normal maps' side in pixels.
 *
 * Energies (BEN, STE, SHE, GE, IE) are sums of the phys/ kernels
 * (phys_energies.h) over their elements, with the def's material, never
 * copies of them. Geometry (distances, angles, w_u and w_v, normals) comes
 * from geom/. Formulas, sources and the reconstructions of epnet's lost
 * equations: docs/eval.md.
 *
 * Leaves out: the epnet "Segmented Maximum Analysis" beyond its reading as
 * the top share of hinges by peak plastic bending (docs/eval.md says why);
 * self-intersection counts; metrics across different meshes (both sequences
 * animate the same mesh).
 */
#include "crease/eval.h"
#include "eval_internal.h"

#include "crease/bvh.h"
#include "crease/diffgeo.h"
#include "crease/phys_energies.h"
#include "crease/topology.h"
#include "crease/uvlookup.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define EVAL_DEF_COOKIE 0x4556414cu /* "EVAL" */

/* Farther than this from the body counts as outside without an exact distance, m. */
static const float BODY_QUERY_M = 10.0f;
static const double RAD2DEG = 180.0 / M_PI;

static const struct {
    const char *name, *source;
} METRICS[CR_EVAL_METRIC_COUNT] = {
    [CR_EVAL_MED] = {"med_m", "epnet"},
    [CR_EVAL_E_DIST_CM] = {"e_dist_cm", "swingar"},
    [CR_EVAL_CD] = {"cd_m2", "epnet"},
    [CR_EVAL_CHAMFER] = {"chamfer_m", "drape"},
    [CR_EVAL_BE] = {"be_rad", "epnet"},
    [CR_EVAL_BED] = {"bed_rad", "epnet"},
    [CR_EVAL_PE] = {"pe_rad", "epnet"},
    [CR_EVAL_BEN] = {"ben_j", "epnet"},
    [CR_EVAL_STE] = {"ste_j", "epnet"},
    [CR_EVAL_SHE] = {"she_j", "epnet"},
    [CR_EVAL_GE] = {"ge_j", "epnet"},
    [CR_EVAL_IE] = {"ie_j", "epnet"},
    [CR_EVAL_COL] = {"col_m", "epnet"},
    [CR_EVAL_COL_MAX] = {"col_max_m", "epnet"},
    [CR_EVAL_COLLISION_RATIO] = {"collision_ratio", "swingar"},
    [CR_EVAL_COL_FACE_MAX] = {"col_face_max_m", "crease"},
    [CR_EVAL_E_U] = {"e_u", "gdsr"},
    [CR_EVAL_E_V] = {"e_v", "gdsr"},
    [CR_EVAL_E_UV] = {"e_uv", "gdsr"},
    [CR_EVAL_SSIM] = {"ssim", "gdsr"},
    [CR_EVAL_NORMAL_ANGLE] = {"normal_angle_deg", "gdsr"},
    [CR_EVAL_E_NORM] = {"e_norm_deg", "swingar"},
    [CR_EVAL_JITTER] = {"jitter_m", "crease"},
    [CR_EVAL_JITTER_REF] = {"jitter_ref_m", "crease"},
    [CR_EVAL_H_RMS] = {"h_rms", "drape"},
    [CR_EVAL_BED_RING] = {"bed_ring_rad", "crease"},
    [CR_EVAL_PE_RING] = {"pe_ring_rad", "crease"},
    [CR_EVAL_BED_SORTED] = {"bed_sorted_rad", "crease"},
    [CR_EVAL_PE_SORTED] = {"pe_sorted_rad", "crease"},
    [CR_EVAL_PE_RB0] = {"pe_rb0_rad", "crease"},
    [CR_EVAL_PE_RING_RB0] = {"pe_ring_rb0_rad", "crease"},
    [CR_EVAL_FOLD_SHARE] = {"fold_share", "crease"},
    [CR_EVAL_FOLD_SHARE_REF] = {"fold_share_ref", "crease"},
};

const char *cr_eval_metric_name(cr_eval_metric m) {
    return m >= 0 && m < CR_EVAL_METRIC_COUNT ? METRICS[m].name : "unknown";
}

const char *cr_eval_metric_source(cr_eval_metric m) {
    return m >= 0 && m < CR_EVAL_METRIC_COUNT ? METRICS[m].source : "unknown";
}

int cr_eval_metric_higher_is_better(cr_eval_metric m) {
    return m == CR_EVAL_SSIM;
}

int cr_eval_metric_is_error(cr_eval_metric m) {
    switch (m) {
    case CR_EVAL_MED:
    case CR_EVAL_E_DIST_CM:
    case CR_EVAL_CD:
    case CR_EVAL_CHAMFER:
    case CR_EVAL_BE:
    case CR_EVAL_BED:
    case CR_EVAL_PE:
    case CR_EVAL_SSIM:
    case CR_EVAL_NORMAL_ANGLE:
    case CR_EVAL_E_NORM:
    case CR_EVAL_BED_RING:
    case CR_EVAL_PE_RING:
    case CR_EVAL_BED_SORTED:
    case CR_EVAL_PE_SORTED:
        return 1;
    default:
        return 0;
    }
}

double cr_eval_removed(const cr_eval_result *pred, const cr_eval_result *base, cr_eval_metric m) {
    if (!cr_eval_metric_is_error(m) || m < 0 || m >= CR_EVAL_METRIC_COUNT) return NAN;
    double p = pred->summary[m].mean, b = base->summary[m].mean;
    if (m == CR_EVAL_SSIM) p = 1.0 - p, b = 1.0 - b;
    if (!isfinite(p) || !isfinite(b) || b == 0.0) return NAN;
    return 1.0 - p / b;
}

void cr_eval_admit(const cr_eval_def *def, const cr_eval_result *twin, int twin_tested,
                   cr_eval_admission *out) {
    memset(out, 0, sizeof *out);
    out->twin_pe_ring_rad = twin->summary[CR_EVAL_PE_RING].mean;
    out->rb0_pe_ring_rad = twin->summary[CR_EVAL_PE_RING_RB0].mean;
    out->plastic_bending_rad = twin->nframes > 0 && twin->frames
                                   ? cr_eval_value(twin, twin->nframes - 1, CR_EVAL_PE_RB0)
                                   : NAN;
    out->defined = isfinite(out->plastic_bending_rad);
    out->twin_tested = twin_tested && out->defined;
    if (!out->defined) {
        snprintf(out->reason, sizeof out->reason,
                 "no plastic rest angles for the reference: plasticity is not measured");
        return;
    }
    if (out->plastic_bending_rad < def->admit_plastic_bending) {
        snprintf(out->reason, sizeof out->reason,
                 "the reference's mean |plastic bending| at the last frame is %.4g rad, below "
                 "%.4g: too little plasticity to measure",
                 out->plastic_bending_rad, (double)def->admit_plastic_bending);
        return;
    }
    if (out->twin_tested &&
        !(out->twin_pe_ring_rad <= def->admit_twin_ratio * out->rb0_pe_ring_rad)) {
        snprintf(out->reason, sizeof out->reason,
                 "the twin's tolerant PE %.4g rad is above %.2f x that of RB = 0 (%.4g): the "
                 "reference's plasticity is chaotic here",
                 out->twin_pe_ring_rad, (double)def->admit_twin_ratio, out->rb0_pe_ring_rad);
        return;
    }
    out->admitted = 1;
    snprintf(out->reason, sizeof out->reason,
             out->twin_tested ? "admitted"
                              : "admitted on plastic bending alone (no twin: its tolerant PE "
                                "was not tested)");
}

cr_eval_def cr_eval_default_def(void) {
    cr_eval_def d;
    memset(&d, 0, sizeof d);
    d.fps = 30.0f;
    d.gravity[1] = -9.81;
    cr_error err = {0};
    cr_status st = cr_material_preset("cotton", &d.material, &err);
    CR_ASSERT(st == CR_OK);
    d.uv_scale = 1.0f;
    d.bending_rest_from_mesh = 1;
    d.bed_fraction = 0.1f;
    d.ssim_side = 256;
    d.ring = 1;
    d.fold_threshold = 0.1f;
    d.resolve_edges = 3.0f;
    d.band_every = 1;
    d.admit_plastic_bending = 0.02f;
    d.admit_twin_ratio = 0.7f;
    d.cookie = EVAL_DEF_COOKIE;
    return d;
}

/* ------------------------------------------------------------- helpers -- */

static inline double norm3(const double a[3]) {
    return sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
}

/* Angle between two vectors, rad, accurate near 0 and pi; 0 when either is zero. */
static double angle3(const float *a, const float *b) {
    double c[3] = {(double)a[1] * b[2] - (double)a[2] * b[1],
                   (double)a[2] * b[0] - (double)a[0] * b[2],
                   (double)a[0] * b[1] - (double)a[1] * b[0]};
    double d = (double)a[0] * b[0] + (double)a[1] * b[1] + (double)a[2] * b[2];
    double s = norm3(c);
    return s == 0.0 && d == 0.0 ? 0.0 : atan2(s, d);
}

/* Sum of a term's element values at positions x (V,3) double, times its weight. */
static double term_sum(const cr_energy_term *t, const double *x) {
    double s = 0.0, xe[3 * CR_ENERGY_MAX_VERTS];
    int32_t idx[CR_ENERGY_MAX_VERTS];
    for (int32_t e = 0; e < t->nelem; e++) {
        cr_energy_term_vertices(t, e, idx);
        for (int k = 0; k < t->nvert; k++)
            for (int d = 0; d < 3; d++)
                xe[3 * k + d] = x[3 * (int64_t)idx[k] + d];
        s += t->kernel(t->data, e, xe, NULL, NULL);
    }
    return s * t->weight;
}

/* theta difference wrapped to [-pi, pi]. */
static double angle_diff(double a, double b) {
    return remainder(a - b, 2.0 * M_PI);
}

int32_t cr_eval_top_hinges(const double *score, int32_t nh, float fraction, int32_t *sel) {
    if (nh <= 0) return 0;
    int32_t k = (int32_t)ceil((double)fraction * nh - 1e-4); /* 0.1f * 10 is 1.0000000149 */
    if (k < 1) k = 1;
    if (k > nh) k = nh;
    /* partial selection sort: k is a tenth of H, H a few ten thousand at most */
    uint8_t *taken = calloc((size_t)nh, 1);
    for (int32_t j = 0; j < k; j++) {
        int32_t best = -1;
        for (int32_t h = 0; h < nh; h++)
            if ((!taken || !taken[h]) && (best < 0 || score[h] > score[best])) best = h;
        sel[j] = best;
        if (taken)
            taken[best] = 1;
        else
            break; /* out of memory: the single best hinge */
    }
    if (!taken) k = 1;
    free(taken);
    return k;
}

/* ------------------------------------------------------------ context -- */

typedef struct eval_ctx {
    const cr_eval_def *def;
    const cr_eval_input *in;
    int32_t V, F, H, T;
    cr_topology *topo;
    cr_membrane *membrane;
    cr_bending *bending;
    cr_gravity *gravity;
    cr_inertia *inertia;
    cr_energy_term stretch_t, shear_t, bending_t, gravity_t, inertia_t;
    cr_mesh *mp, *mr;          /* working meshes at P_t and R_t */
    cr_bvh *bp, *br, *body;    /* over P_t, R_t, the body at frame t */
    double *xp, *xpred;        /* (V,3) P_t, 2 P_{t-1} - P_{t-2} */
    double *theta_p, *theta_r; /* (H) rad */
    double *rest_mesh;         /* (H) rest angles without plasticity, rad */
    int32_t *bed;              /* (nbed) hinges */
    int32_t *bed_pred;         /* (nbed) the prediction's own, for the tolerant BED */
    int32_t nbed;
    int32_t *ring_off, *ring_idx;       /* each hinge's neighbourhood (cr_eval_hinge_rings) */
    double *bend_p, *bend_r;            /* (H) theta - theta0 of P, R */
    double *rb_p, *rb_r, *zero;         /* (H) rest - theta0 of P, R; zeros */
    double *sort_scratch;               /* (2H) */
    double *dminv;                      /* (F,2,2) inverse rest edge matrix of each triangle */
    float *np, *nr, *fnp, *fnr, *farea; /* (V,3), (V,3), (F,3), (F,3), (F) */
    float *dist, *dist2;                /* (V) scratch */
    float *centroid, *fdist;            /* (F,3), (F) scratch */
    /* normal maps */
    int S;
    int32_t *pix_face;    /* (S*S) face under the pixel, -1 outside the chart */
    double *pix_bary;     /* (S*S,3) */
    uint8_t *mask;        /* (S*S) */
    float *img_p, *img_r; /* (S*S,3) */
} eval_ctx;

static void ctx_free(eval_ctx *c) {
    cr_topology_destroy(c->topo);
    cr_membrane_destroy(c->membrane);
    cr_bending_destroy(c->bending);
    cr_gravity_destroy(c->gravity);
    cr_inertia_destroy(c->inertia);
    cr_mesh_destroy(c->mp), cr_mesh_destroy(c->mr);
    cr_bvh_destroy(c->bp), cr_bvh_destroy(c->br), cr_bvh_destroy(c->body);
    free(c->xp), free(c->xpred), free(c->theta_p), free(c->theta_r), free(c->rest_mesh);
    free(c->bed), free(c->bed_pred), free(c->ring_off), free(c->ring_idx), free(c->bend_p),
        free(c->bend_r);
    free(c->rb_p), free(c->rb_r), free(c->zero), free(c->sort_scratch);
    free(c->dminv), free(c->np), free(c->nr), free(c->fnp), free(c->fnr);
    free(c->farea), free(c->dist), free(c->dist2), free(c->centroid), free(c->fdist),
        free(c->pix_face), free(c->pix_bary);
    free(c->mask), free(c->img_p), free(c->img_r);
}

static const float *frame_of(const float *seq, int32_t nv, int32_t t) {
    return seq + (int64_t)t * nv * 3;
}

static cr_status check_finite(const float *seq, int32_t nv, int32_t nframes, const char *name,
                              cr_error *err) {
    for (int32_t t = 0; t < nframes; t++)
        for (int32_t i = 0; i < nv; i++)
            for (int d = 0; d < 3; d++)
                if (!isfinite(seq[((int64_t)t * nv + i) * 3 + d]))
                    return CR_FAIL(err, CR_ERR_NAN,
                                   "%s: non-finite position at frame %d, vertex %d", name, t, i);
    return CR_OK;
}

/* Rest shape of each triangle in 2-D (UVs times uv_scale, or the rest triangle
 * laid flat with u along its first edge) and the inverse of its edge matrix. */
static cr_status rest_frames(eval_ctx *c, cr_error *err) {
    const cr_mesh *g = c->in->garment;
    int from_uv = c->def->membrane_rest_from_uv && cr_mesh_has_uv(g);
    c->dminv = cr_malloc((size_t)c->F * 4 * sizeof(double) + 1, err);
    if (!c->dminv) return CR_ERR_MEMORY;
    for (int32_t f = 0; f < c->F; f++) {
        const int32_t *t = &g->tri[3 * (int64_t)f];
        double e1[2], e2[2];
        if (from_uv) {
            const int32_t *tu = &g->tri_uv[3 * (int64_t)f];
            const float *a = &g->uv[2 * (int64_t)tu[0]], *b = &g->uv[2 * (int64_t)tu[1]],
                        *q = &g->uv[2 * (int64_t)tu[2]];
            double s = c->def->uv_scale;
            e1[0] = s * ((double)b[0] - a[0]), e1[1] = s * ((double)b[1] - a[1]);
            e2[0] = s * ((double)q[0] - a[0]), e2[1] = s * ((double)q[1] - a[1]);
        } else {
            const float *a = &g->pos[3 * (int64_t)t[0]], *b = &g->pos[3 * (int64_t)t[1]],
                        *q = &g->pos[3 * (int64_t)t[2]];
            double u[3], v[3];
            for (int d = 0; d < 3; d++)
                u[d] = (double)b[d] - a[d], v[d] = (double)q[d] - a[d];
            double lu = norm3(u),
                   proj = lu > 0.0 ? (u[0] * v[0] + u[1] * v[1] + u[2] * v[2]) / lu : 0.0;
            double lv2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2] - proj * proj;
            e1[0] = lu, e1[1] = 0.0;
            e2[0] = proj, e2[1] = sqrt(lv2 > 0.0 ? lv2 : 0.0);
        }
        double det = e1[0] * e2[1] - e2[0] * e1[1];
        if (!(fabs(det) > 1e-20))
            return CR_FAIL(err, CR_ERR_TOPOLOGY, "garment: triangle %d has a degenerate rest shape",
                           f);
        double *m = &c->dminv[4 * (int64_t)f]; /* row-major inverse of [e1 e2] (columns) */
        m[0] = e2[1] / det, m[1] = -e2[0] / det;
        m[2] = -e1[1] / det, m[3] = e1[0] / det;
    }
    return CR_OK;
}

/* Pixels of the normal maps: face and barycentrics over the UV bounds. */
static cr_status normal_map_setup(eval_ctx *c, cr_error *err) {
    const cr_mesh *g = c->in->garment;
    if (!cr_mesh_has_uv(g)) return CR_OK;
    int S = c->S = c->def->ssim_side;
    size_t n = (size_t)S * S;
    c->pix_face = cr_malloc(n * sizeof(int32_t), err);
    c->pix_bary = cr_malloc(n * 3 * sizeof(double), err);
    c->mask = cr_calloc(n, 1, err);
    c->img_p = cr_calloc(n * 3, sizeof(float), err);
    c->img_r = cr_calloc(n * 3, sizeof(float), err);
    if (!c->pix_face || !c->pix_bary || !c->mask || !c->img_p || !c->img_r) return CR_ERR_MEMORY;
    CR_TRY(cr_eval_uv_raster(g, S, c->pix_face, c->pix_bary, NULL, err));
    for (size_t k = 0; k < n; k++)
        c->mask[k] = c->pix_face[k] >= 0;
    return CR_OK;
}

cr_status cr_eval_uv_raster(const cr_mesh *m, int side, int32_t *face, double *bary,
                            int64_t *inside, cr_error *err) {
    if (!cr_mesh_has_uv(m)) return CR_FAIL(err, CR_ERR_INVALID, "uv raster: the mesh has no UVs");
    if (side < 1) return CR_FAIL(err, CR_ERR_INVALID, "uv raster: side %d < 1", side);
    cr_uv_lookup *lk = NULL;
    CR_TRY(cr_uv_lookup_build(m, 0, &lk, err));
    float lo[2], hi[2];
    cr_uv_lookup_bounds(lk, lo, hi);
    int64_t in = 0;
    for (int i = 0; i < side; i++)
        for (int j = 0; j < side; j++) {
            size_t k = (size_t)i * side + j;
            float u = lo[0] + (hi[0] - lo[0]) * (j + 0.5f) / side;
            float v = hi[1] - (hi[1] - lo[1]) * (i + 0.5f) / side; /* row 0 at the top */
            if (cr_uv_lookup_find(lk, u, v, &face[k], &bary[3 * k]))
                in++;
            else
                face[k] = -1;
        }
    cr_uv_lookup_destroy(lk);
    if (inside) *inside = in;
    return CR_OK;
}

/* Normal map of per-vertex normals n (V,3) into img (S*S,3), values (n + 1)/2. */
static void normal_map(const eval_ctx *c, const float *n, float *img) {
    const cr_mesh *g = c->in->garment;
    for (size_t k = 0; k < (size_t)c->S * c->S; k++) {
        float *o = &img[3 * k];
        if (c->pix_face[k] < 0) {
            o[0] = o[1] = o[2] = 0.0f;
            continue;
        }
        const int32_t *t = &g->tri[3 * (int64_t)c->pix_face[k]];
        const double *b = &c->pix_bary[3 * k];
        double m[3] = {0, 0, 0};
        for (int q = 0; q < 3; q++)
            for (int d = 0; d < 3; d++)
                m[d] += b[q] * n[3 * (int64_t)t[q] + d];
        double l = norm3(m);
        for (int d = 0; d < 3; d++)
            o[d] = (float)(0.5 * ((l > 0.0 ? m[d] / l : 0.0) + 1.0));
    }
}

static cr_status ctx_create(eval_ctx *c, cr_error *err) {
    const cr_eval_input *in = c->in;
    const cr_mesh *g = in->garment;
    c->V = g->nv, c->F = g->nf, c->T = in->nframes;
    CR_TRY(cr_topology_build(g, &c->topo, err));
    CR_TRY(cr_membrane_create(g, c->def->membrane_rest_from_uv, c->def->uv_scale, &c->def->material,
                              &c->membrane, err));
    CR_TRY(cr_bending_create(g, c->topo, &c->def->material, c->def->bending_rest_from_mesh,
                             &c->bending, err));
    CR_TRY(cr_gravity_create(g, &c->def->material, c->def->gravity, &c->gravity, err));
    CR_TRY(cr_inertia_create(cr_gravity_masses(c->gravity), c->V, &c->inertia, err));
    cr_membrane_term_part(c->membrane, CR_MEMBRANE_STRETCH, &c->stretch_t);
    cr_membrane_term_part(c->membrane, CR_MEMBRANE_SHEAR, &c->shear_t);
    cr_bending_term(c->bending, &c->bending_t);
    cr_gravity_term(c->gravity, &c->gravity_t);
    cr_inertia_term(c->inertia, &c->inertia_t);
    c->H = cr_bending_count(c->bending);
    if (in->rest_nhinges > 0 && in->rest_nhinges != c->H)
        return CR_FAIL(err, CR_ERR_SHAPE, "eval: the rest angles have %d hinges, the garment %d",
                       in->rest_nhinges, c->H);
    size_t v3 = (size_t)c->V * 3, h = (size_t)c->H + 1;
    c->xp = cr_malloc(v3 * sizeof(double), err);
    c->xpred = cr_malloc(v3 * sizeof(double), err);
    c->theta_p = cr_malloc(h * sizeof(double), err);
    c->theta_r = cr_malloc(h * sizeof(double), err);
    c->rest_mesh = cr_malloc(h * sizeof(double), err);
    c->bed = cr_malloc(h * sizeof(int32_t), err);
    c->bed_pred = cr_malloc(h * sizeof(int32_t), err);
    c->bend_p = cr_malloc(h * sizeof(double), err);
    c->bend_r = cr_malloc(h * sizeof(double), err);
    c->rb_p = cr_malloc(h * sizeof(double), err);
    c->rb_r = cr_malloc(h * sizeof(double), err);
    c->zero = cr_calloc(h, sizeof(double), err);
    c->sort_scratch = cr_malloc(2 * h * sizeof(double), err);
    if (!c->bend_p || !c->bend_r || !c->rb_p || !c->rb_r || !c->zero || !c->sort_scratch ||
        !c->bed_pred)
        return CR_ERR_MEMORY;
    CR_TRY(cr_eval_hinge_rings(c->topo, c->def->ring, &c->ring_off, &c->ring_idx, err));
    c->np = cr_malloc(v3 * sizeof(float), err);
    c->nr = cr_malloc(v3 * sizeof(float), err);
    c->fnp = cr_malloc((size_t)c->F * 3 * sizeof(float), err);
    c->fnr = cr_malloc((size_t)c->F * 3 * sizeof(float), err);
    c->farea = cr_malloc((size_t)c->F * sizeof(float), err);
    c->dist = cr_malloc((size_t)c->V * sizeof(float), err);
    c->dist2 = cr_malloc((size_t)c->V * sizeof(float), err);
    c->centroid = cr_malloc((size_t)c->F * 3 * sizeof(float), err);
    c->fdist = cr_malloc((size_t)c->F * sizeof(float), err);
    if (!c->xp || !c->xpred || !c->theta_p || !c->theta_r || !c->rest_mesh || !c->bed || !c->np ||
        !c->nr || !c->fnp || !c->fnr || !c->farea || !c->dist || !c->dist2 || !c->centroid ||
        !c->fdist)
        return CR_ERR_MEMORY;
    memcpy(c->rest_mesh, cr_bending_rest_angles(c->bending), (size_t)c->H * sizeof(double));
    CR_TRY(cr_mesh_clone(g, &c->mp, err));
    CR_TRY(cr_mesh_clone(g, &c->mr, err));
    CR_TRY(cr_bvh_build(frame_of(in->pred, c->V, 0), c->V, g->tri, c->F, &c->bp, err));
    CR_TRY(cr_bvh_build(frame_of(in->ref, c->V, 0), c->V, g->tri, c->F, &c->br, err));
    if (in->body_mesh) {
        const cr_mesh *b = in->body_mesh;
        const float *pos = in->body ? in->body : b->pos;
        CR_TRY(cr_bvh_build(pos, b->nv, b->tri, b->nf, &c->body, err));
    }
    CR_TRY(rest_frames(c, err));
    return normal_map_setup(c, err);
}

/* The rest angles of a sequence at frame t, or NULL. */
static const float *rest_at(const float *rest, int32_t nframes, int32_t H, int32_t t) {
    if (!rest) return NULL;
    return rest + (int64_t)(nframes == 1 ? 0 : t) * H;
}

/* The top share of hinges of one sequence (seq, (T,V,3)) by peak |rest -
 * rest_mesh| (plastic bending) when its rest angles are given, else by peak
 * |theta - rest_mesh| over the frames, into sel; returns how many. */
static int32_t top_hinges_of(eval_ctx *c, const float *seq, const float *rest, int32_t rest_nframes,
                             double *score, int32_t *sel) {
    memset(score, 0, (size_t)c->H * sizeof(double));
    for (int32_t t = 0; t < c->T; t++) {
        const float *rr = rest_at(rest, rest_nframes, c->H, t);
        if (!rr) {
            const float *X = frame_of(seq, c->V, t);
            for (int64_t k = 0; k < 3 * (int64_t)c->V; k++)
                c->xp[k] = X[k];
            cr_bending_angles(c->bending, c->xp, c->theta_r);
        }
        for (int32_t h = 0; h < c->H; h++) {
            double b = fabs(angle_diff(rr ? rr[h] : c->theta_r[h], c->rest_mesh[h]));
            if (b > score[h]) score[h] = b;
        }
        if (rr && rest_nframes == 1) break;
    }
    return cr_eval_top_hinges(score, c->H, c->def->bed_fraction, sel);
}

/* BED's hinges, chosen by the reference (by its plastic bending when its rest
 * angles are given), and the prediction's own for the tolerant BED's other
 * half (by its plastic bending when both have rest angles). */
static cr_status select_bed(eval_ctx *c, cr_eval_result *out, cr_error *err) {
    double *score = cr_calloc((size_t)c->H + 1, sizeof(double), err);
    if (!score) return CR_ERR_MEMORY;
    const cr_eval_input *in = c->in;
    out->bed_from_rest = in->ref_rest != NULL;
    c->nbed = out->nbed_hinges =
        top_hinges_of(c, in->ref, in->ref_rest, in->ref_rest_nframes, score, c->bed);
    const int by_rest = in->ref_rest && in->pred_rest;
    top_hinges_of(c, in->pred, by_rest ? in->pred_rest : NULL, in->pred_rest_nframes, score,
                  c->bed_pred);
    free(score);
    return CR_OK;
}

/* ------------------------------------------------------------ per frame -- */

static cr_status eval_frame(eval_ctx *c, int32_t t, double *m, cr_error *err) {
    const cr_eval_input *in = c->in;
    const cr_mesh *g = in->garment;
    const int32_t V = c->V, F = c->F, H = c->H;
    const float *P = frame_of(in->pred, V, t), *R = frame_of(in->ref, V, t);
    for (int k = 0; k < CR_EVAL_METRIC_COUNT; k++)
        m[k] = NAN;

    /* distances */
    double s = 0.0;
    for (int32_t i = 0; i < V; i++) {
        double d[3] = {(double)P[3 * i] - R[3 * i], (double)P[3 * i + 1] - R[3 * i + 1],
                       (double)P[3 * i + 2] - R[3 * i + 2]};
        s += norm3(d);
    }
    m[CR_EVAL_MED] = s / V;
    m[CR_EVAL_E_DIST_CM] = 100.0 * m[CR_EVAL_MED];
    CR_TRY(cr_bvh_refit(c->bp, P, err));
    CR_TRY(cr_bvh_refit(c->br, R, err));
    cr_bvh_nearest_vertex_batch(c->br, P, V, INFINITY, NULL, c->dist);
    cr_bvh_nearest_vertex_batch(c->bp, R, V, INFINITY, NULL, c->dist2);
    double cd_a = 0.0, cd_b = 0.0;
    for (int32_t i = 0; i < V; i++)
        cd_a += (double)c->dist[i] * c->dist[i], cd_b += (double)c->dist2[i] * c->dist2[i];
    m[CR_EVAL_CD] = cd_a / V + cd_b / V;
    cr_bvh_closest_batch(c->br, P, V, INFINITY, NULL, NULL, NULL, c->dist);
    cr_bvh_closest_batch(c->bp, R, V, INFINITY, NULL, NULL, NULL, c->dist2);
    double ch_a = 0.0, ch_b = 0.0;
    for (int32_t i = 0; i < V; i++)
        ch_a += c->dist[i], ch_b += c->dist2[i];
    m[CR_EVAL_CHAMFER] = 0.5 * (ch_a / V + ch_b / V);

    /* bending */
    for (int64_t k = 0; k < 3 * (int64_t)V; k++)
        c->xp[k] = R[k];
    cr_bending_angles(c->bending, c->xp, c->theta_r);
    for (int64_t k = 0; k < 3 * (int64_t)V; k++)
        c->xp[k] = P[k];
    cr_bending_angles(c->bending, c->xp, c->theta_p);
    if (H > 0) {
        double be = 0.0, bed = 0.0;
        for (int32_t h = 0; h < H; h++)
            be += fabs(angle_diff(c->theta_p[h], c->theta_r[h]));
        for (int32_t j = 0; j < c->nbed; j++)
            bed += fabs(angle_diff(c->theta_p[c->bed[j]], c->theta_r[c->bed[j]]));
        m[CR_EVAL_BE] = be / H;
        m[CR_EVAL_BED] = bed / c->nbed;
        for (int32_t h = 0; h < H; h++) {
            c->bend_p[h] = angle_diff(c->theta_p[h], c->rest_mesh[h]);
            c->bend_r[h] = angle_diff(c->theta_r[h], c->rest_mesh[h]);
        }
        /* symmetrised: the reference's folds found in the prediction, and the prediction's
           in the reference (one-sided, folding everywhere would score best) */
        m[CR_EVAL_BED_RING] = 0.5 * (cr_eval_ring_match(c->bend_p, c->bend_r, c->bed, c->nbed,
                                                        c->ring_off, c->ring_idx) +
                                     cr_eval_ring_match(c->bend_r, c->bend_p, c->bed_pred, c->nbed,
                                                        c->ring_off, c->ring_idx));
        m[CR_EVAL_BED_SORTED] =
            cr_eval_sorted_top(c->bend_p, c->bend_r, H, c->nbed, c->sort_scratch);
        m[CR_EVAL_FOLD_SHARE] = cr_eval_fold_share(c->bend_p, H, c->def->fold_threshold);
        m[CR_EVAL_FOLD_SHARE_REF] = cr_eval_fold_share(c->bend_r, H, c->def->fold_threshold);
        const float *rp = rest_at(in->pred_rest, in->pred_rest_nframes, H, t);
        const float *rr = rest_at(in->ref_rest, in->ref_rest_nframes, H, t);
        if (rr) {
            double pe = 0.0;
            for (int32_t h = 0; h < H; h++) {
                pe += fabs(angle_diff(rp ? rp[h] : c->rest_mesh[h], rr[h]));
                c->rb_p[h] = rp ? angle_diff(rp[h], c->rest_mesh[h]) : 0.0;
                c->rb_r[h] = angle_diff(rr[h], c->rest_mesh[h]);
            }
            m[CR_EVAL_PE] = pe / H;
            const int32_t *o = c->ring_off, *q = c->ring_idx;
            m[CR_EVAL_PE_RING] = 0.5 * (cr_eval_ring_match(c->rb_p, c->rb_r, NULL, H, o, q) +
                                        cr_eval_ring_match(c->rb_r, c->rb_p, NULL, H, o, q));
            m[CR_EVAL_PE_SORTED] =
                cr_eval_sorted_top(c->rb_p, c->rb_r, H, c->nbed, c->sort_scratch);
            double rb0 = 0.0;
            for (int32_t h = 0; h < H; h++)
                rb0 += fabs(c->rb_r[h]);
            m[CR_EVAL_PE_RB0] = rb0 / H;
            /* RB = 0 matched to R within the rings is PE_RB0 itself (every |0 - RB_R(h)|) */
            m[CR_EVAL_PE_RING_RB0] =
                0.5 * (m[CR_EVAL_PE_RB0] + cr_eval_ring_match(c->rb_r, c->zero, NULL, H, o, q));
        }
        double *rest = cr_bending_rest_angles(c->bending);
        for (int32_t h = 0; h < H; h++)
            rest[h] = rp ? rp[h] : c->rest_mesh[h];
        m[CR_EVAL_BEN] = term_sum(&c->bending_t, c->xp) / H;
    }

    /* energies of the prediction */
    m[CR_EVAL_STE] = term_sum(&c->stretch_t, c->xp);
    m[CR_EVAL_SHE] = term_sum(&c->shear_t, c->xp);
    m[CR_EVAL_GE] = term_sum(&c->gravity_t, c->xp);
    if (t >= 2) {
        const float *P1 = frame_of(in->pred, V, t - 1), *P2 = frame_of(in->pred, V, t - 2);
        const float *R1 = frame_of(in->ref, V, t - 1), *R2 = frame_of(in->ref, V, t - 2);
        double jp = 0.0, jr = 0.0;
        for (int32_t i = 0; i < V; i++) {
            double ap[3], ar[3];
            for (int d = 0; d < 3; d++) {
                int64_t k = 3 * (int64_t)i + d;
                c->xpred[k] = 2.0 * P1[k] - P2[k];
                ap[d] = (double)P[k] - c->xpred[k];
                ar[d] = (double)R[k] - (2.0 * R1[k] - R2[k]);
            }
            jp += norm3(ap), jr += norm3(ar);
        }
        m[CR_EVAL_JITTER] = jp / V;
        m[CR_EVAL_JITTER_REF] = jr / V;
        cr_inertia_set(c->inertia, c->xpred, 1.0 / c->def->fps);
        m[CR_EVAL_IE] = term_sum(&c->inertia_t, c->xp);
    }

    /* collisions with the body */
    if (c->body) {
        const cr_mesh *b = in->body_mesh;
        if (in->body && t > 0) {
            int32_t tb = t < in->body_nframes ? t : in->body_nframes - 1;
            CR_TRY(cr_bvh_refit(c->body, frame_of(in->body, b->nv, tb), err));
        }
        cr_bvh_signed_distance_batch(c->body, P, V, BODY_QUERY_M, c->dist, NULL, NULL);
        double pen = 0.0, deepest = 0.0;
        int64_t inside = 0;
        for (int32_t i = 0; i < V; i++)
            if (c->dist[i] < 0.0f) {
                pen += -c->dist[i], inside++;
                if (-c->dist[i] > deepest) deepest = -c->dist[i];
            }
        m[CR_EVAL_COL] = pen / V;
        m[CR_EVAL_COL_MAX] = deepest;
        m[CR_EVAL_COLLISION_RATIO] = (double)inside / V;
        for (int32_t f = 0; f < F; f++) {
            const int32_t *tri = &g->tri[3 * (int64_t)f];
            for (int d = 0; d < 3; d++)
                c->centroid[3 * (int64_t)f + d] =
                    (P[3 * tri[0] + d] + P[3 * tri[1] + d] + P[3 * tri[2] + d]) / 3.0f;
        }
        cr_bvh_signed_distance_batch(c->body, c->centroid, F, BODY_QUERY_M, c->fdist, NULL, NULL);
        double face_deepest = 0.0;
        for (int32_t f = 0; f < F; f++)
            if (-c->fdist[f] > face_deepest) face_deepest = -c->fdist[f];
        m[CR_EVAL_COL_FACE_MAX] = face_deepest;
    }

    /* w_u, w_v of every triangle (gdsr App. B) */
    double eu = 0.0, ev = 0.0, euv = 0.0;
    for (int32_t f = 0; f < F; f++) {
        const int32_t *tri = &g->tri[3 * (int64_t)f];
        const double *mi = &c->dminv[4 * (int64_t)f];
        double wu[3], wv[3];
        for (int d = 0; d < 3; d++) {
            double a = (double)P[3 * tri[1] + d] - P[3 * tri[0] + d];
            double b = (double)P[3 * tri[2] + d] - P[3 * tri[0] + d];
            wu[d] = a * mi[0] + b * mi[2];
            wv[d] = a * mi[1] + b * mi[3];
        }
        double lu = norm3(wu) - 1.0, lv = norm3(wv) - 1.0;
        double dot = wu[0] * wv[0] + wu[1] * wv[1] + wu[2] * wv[2];
        eu += lu * lu, ev += lv * lv, euv += dot * dot;
    }
    m[CR_EVAL_E_U] = eu / F, m[CR_EVAL_E_V] = ev / F, m[CR_EVAL_E_UV] = euv / F;

    /* normals */
    memcpy(c->mp->pos, P, (size_t)V * 3 * sizeof(float));
    memcpy(c->mr->pos, R, (size_t)V * 3 * sizeof(float));
    cr_mesh_vertex_normals(c->mp, CR_NORMAL_AREA, c->np);
    cr_mesh_vertex_normals(c->mr, CR_NORMAL_AREA, c->nr);
    double na = 0.0;
    for (int32_t i = 0; i < V; i++)
        na += angle3(&c->np[3 * i], &c->nr[3 * i]);
    m[CR_EVAL_NORMAL_ANGLE] = RAD2DEG * na / V;
    cr_mesh_face_normals(c->mp, c->fnp, c->farea);
    cr_mesh_face_normals(c->mr, c->fnr, c->farea);
    double fa = 0.0;
    for (int32_t f = 0; f < F; f++)
        fa += angle3(&c->fnp[3 * f], &c->fnr[3 * f]);
    m[CR_EVAL_E_NORM] = RAD2DEG * fa / F;
    if (c->S > 0) {
        normal_map(c, c->np, c->img_p);
        normal_map(c, c->nr, c->img_r);
        CR_TRY(
            cr_eval_ssim(c->img_p, c->img_r, c->mask, c->S, c->S, 3, 1.0f, &m[CR_EVAL_SSIM], err));
    }

    /* curvature */
    float *Hc = c->dist, *area = c->dist2;
    CR_TRY(cr_eval_mean_curvature(c->mp, Hc, err));
    cr_mesh_vertex_areas(c->mp, CR_AREA_MIXED_VORONOI, area);
    double hs = 0.0, as = 0.0;
    for (int32_t i = 0; i < V; i++)
        hs += (double)area[i] * Hc[i] * Hc[i], as += area[i];
    m[CR_EVAL_H_RMS] = as > 0.0 ? sqrt(hs / as) : 0.0;
    return CR_OK;
}

/* ---------------------------------------------------------------- run -- */

static cr_status validate(const cr_eval_def *def, const cr_eval_input *in, cr_error *err) {
    CR_ASSERT(def && def->cookie == EVAL_DEF_COOKIE);
    const char *pn = in->pred_name ? in->pred_name : "prediction";
    const char *rn = in->ref_name ? in->ref_name : "reference";
    const char *bn = in->body_name ? in->body_name : "body";
    if (!(def->fps > 0.0f) || !isfinite(def->fps))
        return CR_FAIL(err, CR_ERR_INVALID, "eval: fps must be positive, got %g", (double)def->fps);
    if (!(def->bed_fraction > 0.0f && def->bed_fraction <= 1.0f))
        return CR_FAIL(err, CR_ERR_INVALID, "eval: bed_fraction must be in (0, 1], got %g",
                       (double)def->bed_fraction);
    if (def->ssim_side < 16 || def->ssim_side > 2048)
        return CR_FAIL(err, CR_ERR_INVALID, "eval: ssim_side must be in 16..2048, got %d",
                       def->ssim_side);
    if (def->ring < 1 || def->ring > 8)
        return CR_FAIL(err, CR_ERR_INVALID, "eval: ring must be in 1..8, got %d", def->ring);
    if (!(def->fold_threshold > 0.0f && def->fold_threshold < (float)M_PI))
        return CR_FAIL(err, CR_ERR_INVALID, "eval: fold_threshold must be in (0, pi) rad, got %g",
                       (double)def->fold_threshold);
    if (!(def->resolve_edges > 0.0f) || !isfinite(def->resolve_edges))
        return CR_FAIL(err, CR_ERR_INVALID, "eval: resolve_edges must be positive, got %g",
                       (double)def->resolve_edges);
    if (def->band_every < 1)
        return CR_FAIL(err, CR_ERR_INVALID, "eval: band_every must be >= 1, got %d",
                       def->band_every);
    if (!(def->admit_plastic_bending >= 0.0f) || !(def->admit_twin_ratio > 0.0f))
        return CR_FAIL(err, CR_ERR_INVALID,
                       "eval: admit_plastic_bending must be >= 0 and admit_twin_ratio > 0, got "
                       "%g and %g",
                       (double)def->admit_plastic_bending, (double)def->admit_twin_ratio);
    CR_TRY(cr_material_validate(&def->material, err));
    if (!in->garment || in->garment->nv < 1 || in->garment->nf < 1)
        return CR_FAIL(err, CR_ERR_INVALID, "eval: the garment mesh is missing or empty");
    if (in->nframes < 1 || !in->pred || !in->ref)
        return CR_FAIL(err, CR_ERR_INVALID, "eval: %s and %s need at least one frame", pn, rn);
    CR_TRY(check_finite(in->pred, in->garment->nv, in->nframes, pn, err));
    CR_TRY(check_finite(in->ref, in->garment->nv, in->nframes, rn, err));
    if (in->body && !in->body_mesh)
        return CR_FAIL(err, CR_ERR_INVALID, "eval: %s positions need the body mesh", bn);
    if (in->body_mesh) {
        if (in->body && in->body_nframes < 1)
            return CR_FAIL(err, CR_ERR_INVALID, "eval: %s has no frames", bn);
        if (in->body) CR_TRY(check_finite(in->body, in->body_mesh->nv, in->body_nframes, bn, err));
    }
    const int32_t rn_[2] = {in->ref_rest_nframes, in->pred_rest_nframes};
    const float *rs[2] = {in->ref_rest, in->pred_rest};
    for (int k = 0; k < 2; k++)
        if (rs[k] && rn_[k] != 1 && rn_[k] != in->nframes)
            return CR_FAIL(err, CR_ERR_SHAPE,
                           "eval: %s rest angles have %d frames, expected 1 or %d", k ? pn : rn,
                           rn_[k], in->nframes);
    return CR_OK;
}

/* fold_share at the last frame over its peak over the run. */
static void retention(cr_eval_result *out) {
    const cr_eval_metric key[2] = {CR_EVAL_FOLD_SHARE, CR_EVAL_FOLD_SHARE_REF};
    double *dst[2] = {&out->retention_pred, &out->retention_ref};
    for (int s = 0; s < 2; s++) {
        double peak = out->summary[key[s]].max;
        double last = cr_eval_value(out, out->nframes - 1, key[s]);
        *dst[s] = peak > 0.0 && isfinite(last) ? last / peak : NAN;
    }
}

/* The wavelength a band stands for: the geometric mean of its edges, the open
 * ends taken at twice the longest edge (> 16 cm: 32 cm) and half the
 * shortest (< 2 cm: 1 cm). */
static double band_wavelength(int b) {
    double hi = cr_eval_h_band_edges_m[b], lo = cr_eval_h_band_edges_m[b + 1];
    if (!isfinite(hi)) hi = 2.0 * lo;
    if (!(lo > 0.0)) lo = 0.5 * hi;
    return sqrt(hi * lo);
}

/* Curvature band power of P and R averaged over every band_every-th frame. */
static cr_status band_power(eval_ctx *c, cr_eval_result *out, cr_error *err) {
    const int32_t V = c->V;
    double band[CR_EVAL_H_BANDS], power[CR_EVAL_H_BANDS], rms;
    memset(out->band_power_pred, 0, sizeof out->band_power_pred);
    memset(out->band_power_ref, 0, sizeof out->band_power_ref);
    int32_t n = 0;
    for (int32_t t = 0; t < c->T; t += c->def->band_every, n++)
        for (int s = 0; s < 2; s++) {
            memcpy(c->mp->pos, frame_of(s ? c->in->ref : c->in->pred, V, t),
                   (size_t)V * 3 * sizeof(float));
            CR_TRY(cr_eval_curvature_spectrum(c->mp, &rms, band, power, err));
            double *acc = s ? out->band_power_ref : out->band_power_pred;
            for (int b = 0; b < CR_EVAL_H_BANDS; b++)
                acc[b] += power[b];
        }
    out->band_frames = n;
    out->mean_edge_m = cr_eval_mean_edge(c->in->garment, c->topo);
    for (int b = 0; b < CR_EVAL_H_BANDS; b++) {
        out->band_power_pred[b] /= n, out->band_power_ref[b] /= n;
        out->band_resolved[b] =
            band_wavelength(b) >= (double)c->def->resolve_edges * out->mean_edge_m;
    }
    out->has_band_power = 1;
    return CR_OK;
}

cr_status cr_eval_run(const cr_eval_def *def, const cr_eval_input *in, cr_eval_result *out,
                      cr_error *err) {
    memset(out, 0, sizeof *out);
    CR_TRY(validate(def, in, err));
    eval_ctx c = {.def = def, .in = in};
    cr_status st = ctx_create(&c, err);
    const int32_t T = in->nframes, V = in->garment->nv;
    out->nframes = T, out->nv = V, out->nhinges = c.H;
    out->ring = def->ring, out->fold_threshold_rad = def->fold_threshold;
    out->frames =
        st == CR_OK ? cr_malloc((size_t)T * CR_EVAL_METRIC_COUNT * sizeof(double), err) : NULL;
    out->vertex_error = st == CR_OK ? cr_malloc((size_t)V * sizeof(float), err) : NULL;
    if (st == CR_OK && (!out->frames || !out->vertex_error)) st = CR_ERR_MEMORY;
    if (st == CR_OK && c.H > 0) st = select_bed(&c, out, err);
    for (int32_t t = 0; st == CR_OK && t < T; t++)
        st = eval_frame(&c, t, &out->frames[(int64_t)t * CR_EVAL_METRIC_COUNT], err);
    if (st == CR_OK) {
        for (int k = 0; k < CR_EVAL_METRIC_COUNT; k++) {
            cr_eval_summary *s = &out->summary[k];
            double sum = 0.0;
            s->mean = s->max = s->min = NAN;
            s->worst_frame = -1;
            int hib = cr_eval_metric_higher_is_better((cr_eval_metric)k);
            for (int32_t t = 0; t < T; t++) {
                double v = cr_eval_value(out, t, (cr_eval_metric)k);
                if (!isfinite(v)) continue;
                if (!s->count || v > s->max) s->max = v;
                if (!s->count || v < s->min) s->min = v;
                if (!s->count || (hib ? v < cr_eval_value(out, s->worst_frame, (cr_eval_metric)k)
                                      : v > cr_eval_value(out, s->worst_frame, (cr_eval_metric)k)))
                    s->worst_frame = t;
                sum += v, s->count++;
            }
            if (s->count) s->mean = sum / s->count;
        }
        int32_t w = out->summary[CR_EVAL_MED].worst_frame;
        out->worst_frame = w < 0 ? 0 : w;
        const float *P = frame_of(in->pred, V, out->worst_frame);
        const float *R = frame_of(in->ref, V, out->worst_frame);
        for (int32_t i = 0; i < V; i++) {
            double d[3] = {(double)P[3 * i] - R[3 * i], (double)P[3 * i + 1] - R[3 * i + 1],
                           (double)P[3 * i + 2] - R[3 * i + 2]};
            out->vertex_error[i] = (float)norm3(d);
        }
    }
    if (st == CR_OK && cr_mesh_has_uv(in->garment)) {
        double rms;
        memcpy(c.mp->pos, frame_of(in->pred, V, T - 1), (size_t)V * 3 * sizeof(float));
        memcpy(c.mr->pos, frame_of(in->ref, V, T - 1), (size_t)V * 3 * sizeof(float));
        st = cr_eval_curvature_spectrum(c.mp, &rms, out->h_band_pred, out->h_power_pred, err);
        if (st == CR_OK)
            st = cr_eval_curvature_spectrum(c.mr, &rms, out->h_band_ref, out->h_power_ref, err);
        out->has_spectrum = st == CR_OK;
    }
    if (st == CR_OK) retention(out);
    if (st == CR_OK && cr_mesh_has_uv(in->garment)) st = band_power(&c, out, err);
    if (st == CR_OK) st = cr_eval_hem_swing(def, in, c.topo, out, err);
    ctx_free(&c);
    if (st != CR_OK) cr_eval_result_free(out);
    return st;
}

void cr_eval_result_free(cr_eval_result *r) {
    if (!r) return;
    free(r->frames);
    free(r->vertex_error);
    memset(r, 0, sizeof *r);
}
