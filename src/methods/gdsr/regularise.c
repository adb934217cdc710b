/* regularise.c: gdsr's physics and smoothness terms (sec. 4.5, Eq. 15-19
 * and 21-23): Baraff-Witkin stretch and shear, bending toward the
 * reference's dihedral angles, the L1 of the uniform Laplacian of the error,
 * the strain against the reference's, and the squared Laplacian of the
 * corrected coarse garment (Eq. 15's smoothing). Built once per mesh: the
 * high one for the output, the low one for C^. The membrane and bending go
 * through the generic loss op (losses.h) on phys/ kernels, with unit
 * stiffnesses and weights that turn their sums into means (docs/gdsr.md). */
#include "gdsr_internal.h"

#include "crease/losses.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void cr_gdsr_reg_free(gdsr_reg *r) {
    if (!r) return;
    cr_membrane_destroy(r->membrane);
    cr_bending_destroy(r->bending);
    cr_topology_destroy(r->topo);
    free(r->lap_snd);
    free(r->lap_rcv);
    free(r->lap_inv_deg);
    free(r->theta_ref);
    free(r->xd);
    for (int k = 0; k < 3; k++) {
        free(r->corner[k]);
        free(r->cu[k]);
        free(r->cv[k]);
    }
    free(r->strain_ref);
    memset(r, 0, sizeof *r);
}

cr_status cr_gdsr_reg_create(const cr_mesh *high, gdsr_reg *r, cr_error *err) {
    memset(r, 0, sizeof *r);
    cr_material mat;
    CR_TRY(cr_material_preset("cotton", &mat, err));
    mat.membrane = CR_MEMBRANE_BARAFF_WITKIN;
    mat.bw_stretch = 1.0;
    mat.bw_shear = 1.0;
    mat.bending = 1.0;
    cr_status st;
    if ((st = cr_membrane_create(high, 0, 1.0f, &mat, &r->membrane, err)) != CR_OK) goto fail;
    if ((st = cr_topology_build(high, &r->topo, err)) != CR_OK) goto fail;
    if ((st = cr_bending_create(high, r->topo, &mat, 1, &r->bending, err)) != CR_OK) goto fail;
    double area = 0;
    const double *a = cr_membrane_rest_areas(r->membrane);
    for (int32_t f = 0; f < high->nf; f++)
        area += a[f];
    /* sum A0 k/2 s^2 -> area-weighted mean of s^2 */
    r->membrane_norm = area > 0 ? 2.0 / area : 0.0;
    int32_t H = cr_bending_count(r->bending);
    r->bending_norm = H > 0 ? 1.0 / H : 0.0;
    /* the uniform Laplacian's directed edges: every 1-ring neighbour j of i */
    const cr_topology *tp = r->topo;
    int64_t n = tp->vv_off[high->nv];
    r->lap_snd = malloc(((size_t)n + 1) * sizeof(int32_t));
    r->lap_rcv = malloc(((size_t)n + 1) * sizeof(int32_t));
    r->lap_inv_deg = calloc((size_t)high->nv + 1, sizeof(float));
    r->theta_ref = malloc(((size_t)H + 1) * sizeof(float));
    r->xd = malloc((size_t)high->nv * 3 * sizeof(double));
    if (!r->lap_snd || !r->lap_rcv || !r->lap_inv_deg || !r->theta_ref || !r->xd) {
        st = CR_FAIL(err, CR_ERR_MEMORY, "gdsr: out of memory");
        goto fail;
    }
    for (int32_t i = 0; i < high->nv; i++)
        for (int32_t k = tp->vv_off[i]; k < tp->vv_off[i + 1]; k++)
            r->lap_snd[k] = tp->vv[k], r->lap_rcv[k] = i;
    r->lap_n = n;
    for (int64_t e = 0; e < n; e++)
        r->lap_inv_deg[r->lap_rcv[e]] += 1.0f;
    for (int32_t i = 0; i < high->nv; i++)
        r->lap_inv_deg[i] = r->lap_inv_deg[i] > 0 ? 1.0f / r->lap_inv_deg[i] : 0.0f;
    r->nv = high->nv;
    /* w_u, w_v as fixed combinations of the corners (phys/membrane.h's c_ij) */
    r->nf = high->nf;
    int ok = (r->strain_ref = malloc((size_t)high->nf * 3 * sizeof(float))) != NULL;
    for (int k = 0; k < 3; k++) {
        ok &= (r->corner[k] = cr_gdsr_tri_column(high, k)) != NULL;
        ok &= (r->cu[k] = malloc(((size_t)high->nf + 1) * sizeof(float))) != NULL;
        ok &= (r->cv[k] = malloc(((size_t)high->nf + 1) * sizeof(float))) != NULL;
    }
    if (!ok) {
        st = CR_FAIL(err, CR_ERR_MEMORY, "gdsr: out of memory");
        goto fail;
    }
    const double *D = cr_membrane_rest_dminv(r->membrane);
    for (int32_t f = 0; f < high->nf; f++) {
        const double *d = D + 4 * (int64_t)f;
        r->cu[1][f] = (float)d[0], r->cv[1][f] = (float)d[1];
        r->cu[2][f] = (float)d[2], r->cv[2][f] = (float)d[3];
        r->cu[0][f] = (float)-(d[0] + d[2]), r->cv[0][f] = (float)-(d[1] + d[3]);
    }
    return CR_OK;
fail:
    cr_gdsr_reg_free(r);
    return st;
}

/* mean_j x_j - x_i over the 1-ring of each vertex: (V,3). */
static cr_tensor *laplacian(cr_nn_ctx *ctx, const gdsr_reg *r, cr_tensor *x) {
    cr_tensor *s = cr_nn_scatter_add_rows(ctx, cr_nn_gather_rows(ctx, x, r->lap_snd, r->lap_n),
                                          r->lap_rcv, r->nv);
    s = cr_nn_mul(ctx, s, cr_nn_from(ctx, 2, (int64_t[]){r->nv, 1}, r->lap_inv_deg));
    return cr_nn_sub(ctx, s, x);
}

cr_tensor *cr_gdsr_reg_bend(cr_nn_ctx *ctx, gdsr_reg *r, cr_tensor *x, const float *ref) {
    /* the reference's dihedral angles as this frame's rest angles */
    int32_t H = cr_bending_count(r->bending);
    for (int64_t i = 0; i < (int64_t)r->nv * 3; i++)
        r->xd[i] = ref[i];
    double *th = malloc(((size_t)H + 1) * sizeof(double));
    if (!th) return NULL;
    cr_bending_angles(r->bending, r->xd, th);
    for (int32_t h = 0; h < H; h++)
        r->theta_ref[h] = (float)th[h];
    free(th);
    cr_tensor *rest = cr_nn_from(ctx, 1, (int64_t[]){H}, r->theta_ref);
    return cr_loss_bending(ctx, r->bending, r->bending_norm, x, rest);
}

void cr_gdsr_reg_terms(cr_nn_ctx *ctx, gdsr_reg *r, cr_tensor *x, const float *ref,
                       cr_tensor **stretch, cr_tensor **shear, cr_tensor **bend, cr_tensor **lap) {
    cr_energy_term t;
    cr_membrane_term_part(r->membrane, CR_MEMBRANE_STRETCH, &t);
    t.weight = r->membrane_norm;
    *stretch = cr_loss_energy(ctx, &t, x);
    cr_membrane_term_part(r->membrane, CR_MEMBRANE_SHEAR, &t);
    t.weight = r->membrane_norm;
    *shear = cr_loss_energy(ctx, &t, x);
    *bend = cr_gdsr_reg_bend(ctx, r, x, ref);
    cr_tensor *e = cr_nn_sub(ctx, x, cr_nn_from(ctx, 2, (int64_t[]){r->nv, 3}, ref));
    *lap = cr_nn_mean(ctx, cr_nn_abs(ctx, laplacian(ctx, r, e)));
}

cr_tensor *cr_gdsr_reg_smooth(cr_nn_ctx *ctx, const gdsr_reg *r, cr_tensor *x) {
    cr_tensor *l = laplacian(ctx, r, x);
    return cr_nn_mean(ctx, cr_nn_mul(ctx, l, l));
}

/* w_u and w_v (F,3) of positions x (V,3). */
static void strain_w(cr_nn_ctx *ctx, const gdsr_reg *r, cr_tensor *x, cr_tensor **wu,
                     cr_tensor **wv) {
    *wu = *wv = NULL;
    for (int k = 0; k < 3; k++) {
        cr_tensor *p = cr_nn_gather_rows(ctx, x, r->corner[k], r->nf);
        cr_tensor *a = cr_nn_mul(ctx, p, cr_nn_from(ctx, 2, (int64_t[]){r->nf, 1}, r->cu[k]));
        cr_tensor *b = cr_nn_mul(ctx, p, cr_nn_from(ctx, 2, (int64_t[]){r->nf, 1}, r->cv[k]));
        *wu = *wu ? cr_nn_add(ctx, *wu, a) : a;
        *wv = *wv ? cr_nn_add(ctx, *wv, b) : b;
    }
}

cr_tensor *cr_gdsr_reg_strain_l1(cr_nn_ctx *ctx, gdsr_reg *r, cr_tensor *x, const float *ref) {
    /* the reference's |w_u|, |w_v|, w_u . w_v, in double on the host */
    for (int32_t f = 0; f < r->nf; f++) {
        double u[3] = {0, 0, 0}, v[3] = {0, 0, 0};
        for (int k = 0; k < 3; k++)
            for (int d = 0; d < 3; d++) {
                double p = ref[3 * (int64_t)r->corner[k][f] + d];
                u[d] += r->cu[k][f] * p, v[d] += r->cv[k][f] * p;
            }
        float *o = r->strain_ref + 3 * (int64_t)f;
        o[0] = (float)sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
        o[1] = (float)sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
        o[2] = (float)(u[0] * v[0] + u[1] * v[1] + u[2] * v[2]);
    }
    cr_tensor *wu, *wv;
    strain_w(ctx, r, x, &wu, &wv);
    cr_tensor *s[3] = {cr_nn_norm(ctx, wu, 1e-12f), cr_nn_norm(ctx, wv, 1e-12f),
                       cr_nn_dot(ctx, wu, wv)};
    cr_tensor *m = cr_nn_concat(ctx, 3, s, 1); /* (F,3) */
    cr_tensor *e = cr_nn_sub(ctx, m, cr_nn_from(ctx, 2, (int64_t[]){r->nf, 3}, r->strain_ref));
    /* the mean over (F,3) is a third of the sum of the three per-triangle means */
    return cr_nn_mul_scalar(ctx, cr_nn_mean(ctx, cr_nn_abs(ctx, e)), 3.0f);
}
