/* smpl_model.c: SMPL-family body models from .npz into a cr_body_model.
 *
 * Reads v_template (V,3), shapedirs (V,3,B), J_regressor (J,V) dense,
 * weights (V,J), kintree_table (2,J) and f (F,3) in any dtype npz.h reads
 * (SMPL's own files mix float64, uint32 and int64; the root's parent is
 * usually stored as 4294967295). The shaped rest mesh is
 *   v = v_template + shapedirs[:, :, :nbetas] . betas        (Loper et al., eq. 2)
 * and the rest joints J_regressor . v (eq. 5), accumulated in double. The
 * first 22 joints must have SMPL's parents (true of SMPL, SMPL+H, SMPL-X);
 * every later joint's skinning weight goes to its nearest ancestor among
 * them, so SMPL's hands merge into the wrists and SMPL-X's jaw and eyes
 * into the head. Each vertex keeps its four largest merged weights,
 * renormalised to sum to 1. The model is then moved so its lowest vertex
 * is on y = 0 and its pelvis over x = z = 0 (SMPL's template floats around
 * the origin; crease's bodies stand on the ground).
 *
 * Leaves out pose blend shapes (posedirs), SMPL-X expression and hand
 * PCA components, and sparse (scipy) regressors: a J_regressor pickled as
 * a sparse matrix must be converted with .toarray() before saving.
 *
 * Reference: Loper, Mahmood, Romero, Pons-Moll, Black 2015, "SMPL: A
 * Skinned Multi-Person Linear Model" (eqs. 2-5).
 */
#include "body/motion_internal.h"
#include "crease/body.h"
#include "crease/mesh.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { MAX_MODEL_JOINTS = 1024, SKIN_SLOTS = 4 };
static const double NEGATIVE_WEIGHT_TOL = 1e-4; /* float noise in converted weight tables */

void cr_smpl_free(cr_body_model *b) {
    if (!b) return;
    cr_mesh_destroy(b->rest);
    free(b->skin_joint);
    free(b->skin_weight);
    memset(b, 0, sizeof *b);
}

static cr_status get_shaped(const cr_npz *z, const char *source, const char *key, cr_npy_as as,
                            int ndim, const int64_t *want, cr_npy *out, cr_error *err) {
    cr_status st = cr_npz_get(z, key, as, out, err);
    if (st == CR_ERR_UNSUPPORTED && strcmp(key, "J_regressor") == 0) {
        char why[sizeof err->msg];
        snprintf(why, sizeof why, "%s", err ? err->msg : "unsupported dtype");
        return CR_FAIL(err, st, "%s (J_regressor must be a dense array: save it with .toarray())",
                       why);
    }
    if (st != CR_OK) return st;
    int ok = out->ndim == ndim;
    for (int k = 0; k < ndim && ok; k++)
        ok = want[k] < 0 ? out->shape[k] >= 1 : out->shape[k] == want[k];
    if (ok) return CR_OK;
    char got[160], exp[160];
    int n = 0, e = 0;
    for (int k = 0; k < out->ndim && n < 120; k++)
        n += snprintf(got + n, sizeof got - (size_t)n, k ? ", %lld" : "%lld",
                      (long long)out->shape[k]);
    got[n] = 0;
    for (int k = 0; k < ndim && e < 120; k++)
        e += want[k] < 0 ? snprintf(exp + e, sizeof exp - (size_t)e, k ? ", n" : "n")
                         : snprintf(exp + e, sizeof exp - (size_t)e, k ? ", %lld" : "%lld",
                                    (long long)want[k]);
    exp[e] = 0;
    cr_npy_free(out);
    return CR_FAIL(err, CR_ERR_SHAPE, "%s: %s: shape (%s), expected (%s)", source, key, got, exp);
}

/* Nearest ancestor of each model joint among the 22 body joints. */
static cr_status read_kintree(const cr_npz *z, const char *source, int64_t J, int *merged,
                              cr_error *err) {
    cr_npy kt;
    int64_t want[2] = {2, J};
    CR_TRY(get_shaped(z, source, "kintree_table", CR_NPY_AS_F64, 2, want, &kt, err));
    cr_status st = CR_OK;
    for (int64_t k = 0; k < J && st == CR_OK; k++) {
        double parent = kt.f64[k], id = kt.f64[J + k];
        if (id != (double)k)
            st = CR_FAIL(err, CR_ERR_PARSE,
                         "%s: kintree_table: column %lld names joint %g (joints must be listed "
                         "in order)",
                         source, (long long)k, id);
        else if (k == 0)
            merged[0] = 0;
        else if (!(parent >= 0 && parent < (double)k && parent == floor(parent)))
            st = CR_FAIL(err, CR_ERR_PARSE,
                         "%s: kintree_table: joint %lld has parent %g (expected an earlier joint)",
                         source, (long long)k, parent);
        else if (k < CR_NJOINTS && (int)parent != cr_joint_parent[k])
            st = CR_FAIL(err, CR_ERR_PARSE,
                         "%s: kintree_table: joint %lld (%s) has parent %g, SMPL's is %d (not an "
                         "SMPL-family model?)",
                         source, (long long)k, cr_joint_name[k], parent, cr_joint_parent[k]);
        else
            merged[k] = k < CR_NJOINTS ? (int)k : merged[(int)parent];
    }
    cr_npy_free(&kt);
    return st;
}

cr_status cr_body_top_weights_(const float *w, int64_t J, const int *merged, int64_t v,
                               const char *source, int32_t *idx, float *wt, cr_error *err) {
    double acc[CR_NJOINTS] = {0};
    for (int64_t k = 0; k < J; k++) {
        if (w[k] < -NEGATIVE_WEIGHT_TOL)
            return CR_FAIL(err, CR_ERR_RANGE, "%s: weights[%lld, %lld] = %g is negative", source,
                           (long long)v, (long long)k, (double)w[k]);
        acc[merged[k]] += w[k] > 0 ? w[k] : 0;
    }
    double sum = 0;
    for (int s = 0; s < SKIN_SLOTS; s++) {
        int best = 0;
        for (int j = 1; j < CR_NJOINTS; j++)
            if (acc[j] > acc[best]) best = j;
        idx[s] = best;
        wt[s] = (float)acc[best];
        sum += acc[best];
        acc[best] = -1;
    }
    if (!(sum > 1e-8))
        return CR_FAIL(err, CR_ERR_RANGE, "%s: vertex %lld has no skinning weight", source,
                       (long long)v);
    for (int s = 0; s < SKIN_SLOTS; s++) {
        wt[s] = (float)(wt[s] / sum);
        if (wt[s] == 0) idx[s] = 0;
    }
    return CR_OK;
}

void cr_body_stand_shift_(const double *pos, int64_t V, const double pelvis[3], double shift[3]) {
    double lowest = INFINITY;
    for (int64_t i = 0; i < V; i++)
        lowest = fmin(lowest, pos[i * 3 + 1]);
    shift[0] = -pelvis[0], shift[1] = -lowest, shift[2] = -pelvis[2];
}

static cr_status smpl_from_npz(const cr_npz *z, const char *source, const float *betas, int nbetas,
                               cr_body_model *out, cr_error *err) {
    memset(out, 0, sizeof *out);
    if (nbetas < 0 || (nbetas > 0 && !betas))
        return CR_FAIL(err, CR_ERR_INVALID, "%s: %d betas given", source, nbetas);
    for (int b = 0; b < nbetas; b++)
        if (!isfinite(betas[b]))
            return CR_FAIL(err, CR_ERR_NAN, "%s: betas[%d] is not finite", source, b);
    cr_npy tmpl = {0}, dirs = {0}, reg = {0}, weights = {0}, faces = {0};
    int64_t any = -1;
    int64_t want_t[2] = {any, 3};
    CR_TRY(get_shaped(z, source, "v_template", CR_NPY_AS_F32, 2, want_t, &tmpl, err));
    int64_t V = tmpl.shape[0];
    int64_t want_f[2] = {any, 3}, want_r[2] = {any, V}, want_d[3] = {V, 3, any};
    int *merged = NULL;
    double *shaped = NULL;
    cr_status st = V <= INT32_MAX
                       ? CR_OK
                       : CR_FAIL(err, CR_ERR_RANGE, "%s: %lld vertices", source, (long long)V);
    if (st == CR_OK) st = get_shaped(z, source, "J_regressor", CR_NPY_AS_F32, 2, want_r, &reg, err);
    int64_t J = reg.shape[0];
    if (st == CR_OK && (J < CR_NJOINTS || J > MAX_MODEL_JOINTS))
        st = CR_FAIL(err, CR_ERR_SHAPE, "%s: J_regressor has %lld joints, expected 22 to %d",
                     source, (long long)J, MAX_MODEL_JOINTS);
    int64_t want_w[2] = {V, J};
    if (st == CR_OK) st = get_shaped(z, source, "weights", CR_NPY_AS_F32, 2, want_w, &weights, err);
    if (st == CR_OK) st = get_shaped(z, source, "f", CR_NPY_AS_I32, 2, want_f, &faces, err);
    if (st == CR_OK && faces.shape[0] > INT32_MAX)
        st = CR_FAIL(err, CR_ERR_RANGE, "%s: %lld faces", source, (long long)faces.shape[0]);
    if (st == CR_OK && (nbetas > 0 || cr_npz_has(z, "shapedirs")))
        st = get_shaped(z, source, "shapedirs", CR_NPY_AS_F32, 3, want_d, &dirs, err);
    if (st == CR_OK && nbetas > (dirs.f32 ? dirs.shape[2] : 0))
        st = CR_FAIL(err, CR_ERR_SHAPE, "%s: %d betas given, the model has %lld shape components",
                     source, nbetas, (long long)(dirs.f32 ? dirs.shape[2] : 0));
    if (st == CR_OK) {
        merged = cr_malloc((size_t)J * sizeof *merged, err);
        shaped = cr_malloc((size_t)V * 3 * sizeof *shaped, err);
        if (!merged || !shaped) st = CR_ERR_MEMORY;
    }
    if (st == CR_OK) st = read_kintree(z, source, J, merged, err);
    for (int64_t i = 0; st == CR_OK && i < faces.count; i++)
        if (faces.i32[i] < 0 || faces.i32[i] >= V)
            st = CR_FAIL(err, CR_ERR_RANGE, "%s: f[%lld, %lld] = %d, expected 0 to %lld", source,
                         (long long)(i / 3), (long long)(i % 3), faces.i32[i], (long long)V - 1);
    if (st == CR_OK) {
        int64_t B = dirs.f32 ? dirs.shape[2] : 0;
        for (int64_t i = 0; i < V * 3; i++) {
            double v = tmpl.f32[i];
            for (int b = 0; b < nbetas; b++)
                v += (double)dirs.f32[i * B + b] * betas[b];
            shaped[i] = v;
        }
        for (int j = 0; j < CR_NJOINTS; j++)
            for (int k = 0; k < 3; k++) {
                double acc = 0;
                for (int64_t i = 0; i < V; i++)
                    acc += (double)reg.f32[j * V + i] * shaped[i * 3 + k];
                out->joints[j * 3 + k] = (float)acc;
            }
        const double pelvis[3] = {out->joints[0], out->joints[1], out->joints[2]};
        double shift[3];
        cr_body_stand_shift_(shaped, V, pelvis, shift);
        for (int j = 0; j < CR_NJOINTS; j++)
            for (int k = 0; k < 3; k++)
                out->joints[j * 3 + k] = (float)(out->joints[j * 3 + k] + shift[k]);
        st = cr_mesh_create((int32_t)V, (int32_t)faces.shape[0], 0, &out->rest, err);
        if (st == CR_OK) {
            for (int64_t i = 0; i < V * 3; i++)
                out->rest->pos[i] = (float)(shaped[i] + shift[i % 3]);
            memcpy(out->rest->tri, faces.i32, (size_t)faces.count * sizeof(int32_t));
            out->skin_joint = cr_malloc((size_t)V * SKIN_SLOTS * sizeof(int32_t), err);
            out->skin_weight = cr_malloc((size_t)V * SKIN_SLOTS * sizeof(float), err);
            if (!out->skin_joint || !out->skin_weight) st = CR_ERR_MEMORY;
        }
        for (int64_t i = 0; st == CR_OK && i < V; i++)
            st = cr_body_top_weights_(weights.f32 + i * J, J, merged, i, source,
                                      out->skin_joint + i * SKIN_SLOTS,
                                      out->skin_weight + i * SKIN_SLOTS, err);
    }
    free(merged);
    free(shaped);
    cr_npy_free(&tmpl);
    cr_npy_free(&dirs);
    cr_npy_free(&reg);
    cr_npy_free(&weights);
    cr_npy_free(&faces);
    if (st != CR_OK) cr_smpl_free(out);
    return st;
}

cr_status cr_smpl_read_mem(const void *data, size_t len, const char *source, const float *betas,
                           int nbetas, cr_body_model *out, cr_error *err) {
    memset(out, 0, sizeof *out);
    cr_npz *z = NULL;
    CR_TRY(cr_npz_open_mem(data, len, source, &z, err));
    cr_status st = smpl_from_npz(z, source, betas, nbetas, out, err);
    cr_npz_close(z);
    return st;
}

cr_status cr_smpl_load(const char *path, const float *betas, int nbetas, cr_body_model *out,
                       cr_error *err) {
    memset(out, 0, sizeof *out);
    cr_npz *z = NULL;
    CR_TRY(cr_npz_open(path, &z, err));
    cr_status st = smpl_from_npz(z, path, betas, nbetas, out, err);
    cr_npz_close(z);
    return st;
}

cr_status cr_body_resolve(const char *spec, cr_body_model **out, cr_error *err) {
    *out = NULL;
    char path[1024];
    const char *tail = NULL;
    int file = cr_spec_split(spec, ".glb", path, sizeof path, &tail);
    if (file > 0) return cr_body_from_character(path, tail, out, err); /* tail: its joint map */
    if (file == 0) file = cr_spec_split(spec, ".npz", path, sizeof path, &tail);
    if (file < 0) return CR_FAIL(err, CR_ERR_INVALID, "body: path too long: %s", spec);
    if (file == 0) {
        cr_mannequin_def md = cr_mannequin_default_def();
        CR_TRY(cr_mannequin_preset(spec ? spec : "normal", &md, err));
        return cr_mannequin_create(&md, out, err);
    }
    float betas[CR_BODY_MAX_BETAS];
    int nbetas = 0;
    for (const char *p = tail; p && *p; nbetas++) {
        char *end = NULL;
        double v = strtod(p, &end);
        if (end == p || !isfinite(v) || nbetas == CR_BODY_MAX_BETAS ||
            (*end && *end != ',' && *end != ':'))
            return CR_FAIL(err, CR_ERR_INVALID,
                           "body %s: shape coefficient %d: expected up to %d numbers after ':', "
                           "separated by ',' or ':'",
                           spec, nbetas + 1, CR_BODY_MAX_BETAS);
        betas[nbetas] = (float)v;
        p = *end ? end + 1 : end;
    }
    cr_body_model *b = cr_calloc(1, sizeof *b, err);
    if (!b) return CR_ERR_MEMORY;
    cr_status st = cr_smpl_load(path, betas, nbetas, b, err);
    if (st != CR_OK) {
        free(b);
        return st;
    }
    *out = b;
    return CR_OK;
}
