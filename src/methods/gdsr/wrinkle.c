/* wrinkle.c: gdsr's patch normal-map loss (sec. 4.5, Eq. 20) with a fixed
 * filter bank in place of the pre-trained VGG (no weights here). The normal
 * map over the UV chart is built on the tape from a raster computed once
 * (crease eval's, cr_eval_uv_raster): per texel a barycentric mix of the
 * vertex normals. Its responses to oriented first differences (odd, edge-like)
 * and second differences (even, ridge-like) along rows, columns and both
 * diagonals at steps of 1, 2 and 4 texels stand for VGG's multi-layer
 * features; as in Eq. 20 they are compared by L1, summed over the scales
 * (layers). Eq. 24: the mean over random square patches of the map (8 a
 * step by default), or the whole chart as one patch (docs/gdsr.md).
 * Energy mode compares per patch each response's RMS over the patch
 * instead of the responses texel by texel: how strong the folds of each
 * orientation and scale are there, not where their crests lie, as VGG's
 * deeper features tolerate a shift within their receptive field. */
#include "gdsr_internal.h"

#include "crease/eval.h"

#include <stdlib.h>
#include <string.h>

static const int STEP[CR_GDSR_WRINKLE_SCALES] = {1, 2, 4};
static const int DIR[4][2] = {{0, 1}, {1, 0}, {1, 1}, {1, -1}}; /* (row, column) */

void cr_gdsr_wrinkle_free(gdsr_wrinkle *w) {
    if (!w) return;
    for (int k = 0; k < 3; k++) {
        free(w->corner[k]);
        free(w->tex_v[k]);
        free(w->tex_b[k]);
    }
    for (int s = 0; s < CR_GDSR_WRINKLE_SCALES; s++) {
        for (int k = 0; k < CR_GDSR_WRINKLE_TAPS; k++)
            free(w->tap[s][k]);
        free(w->valid_px[s]);
    }
    free(w->tex_px);
    free(w->scratch);
    memset(w, 0, sizeof *w);
}

cr_status cr_gdsr_wrinkle_create(const cr_mesh *high, int side, gdsr_wrinkle *w, cr_error *err) {
    memset(w, 0, sizeof *w);
    if (side < 8 || side > 2048)
        return CR_FAIL(err, CR_ERR_INVALID, "gdsr wrinkle: map side %d outside 8..2048", side);
    size_t n = (size_t)side * side;
    int32_t *face = malloc(n * sizeof(int32_t)), *id = malloc(n * sizeof(int32_t));
    double *bary = malloc(n * 3 * sizeof(double));
    cr_status st = CR_OK;
    if (!face || !id || !bary) {
        st = CR_FAIL(err, CR_ERR_MEMORY, "gdsr: out of memory");
        goto done;
    }
    if ((st = cr_eval_uv_raster(high, side, face, bary, &w->ntex, err)) != CR_OK) goto done;
    w->nv = high->nv, w->nf = high->nf, w->side = side;
    int ok = 1;
    for (int k = 0; k < 3; k++) {
        ok &= (w->corner[k] = cr_gdsr_tri_column(high, k)) != NULL;
        ok &= (w->tex_v[k] = malloc(((size_t)w->ntex + 1) * sizeof(int32_t))) != NULL;
        ok &= (w->tex_b[k] = malloc(((size_t)w->ntex + 1) * sizeof(float))) != NULL;
    }
    for (int s = 0; s < CR_GDSR_WRINKLE_SCALES; s++) {
        for (int k = 0; k < CR_GDSR_WRINKLE_TAPS; k++)
            ok &= (w->tap[s][k] = malloc(((size_t)w->ntex + 1) * sizeof(int32_t))) != NULL;
        ok &= (w->valid_px[s] = malloc(((size_t)w->ntex + 1) * sizeof(int32_t))) != NULL;
    }
    ok &= (w->tex_px = malloc(((size_t)w->ntex + 1) * sizeof(int32_t))) != NULL;
    ok &= (w->scratch = malloc(((size_t)w->ntex + 1) * sizeof(int32_t))) != NULL;
    if (!ok) {
        st = CR_FAIL(err, CR_ERR_MEMORY, "gdsr: out of memory");
        goto done;
    }
    int64_t t = 0;
    for (size_t p = 0; p < n; p++) {
        id[p] = face[p] >= 0 ? (int32_t)t : -1;
        if (face[p] < 0) continue;
        for (int k = 0; k < 3; k++) {
            w->tex_v[k][t] = high->tri[3 * (int64_t)face[p] + k];
            w->tex_b[k][t] = (float)bary[3 * p + k];
        }
        w->tex_px[t] = (int32_t)p;
        t++;
    }
    for (int s = 0; s < CR_GDSR_WRINKLE_SCALES; s++) {
        int64_t m = 0;
        for (int i = 0; i < side; i++)
            for (int j = 0; j < side; j++) {
                int32_t nb[CR_GDSR_WRINKLE_TAPS];
                nb[0] = id[(size_t)i * side + j];
                int in = nb[0] >= 0;
                for (int d = 0; d < 4 && in; d++)
                    for (int sg = 0; sg < 2 && in; sg++) {
                        int a = i + (sg ? -1 : 1) * STEP[s] * DIR[d][0];
                        int b = j + (sg ? -1 : 1) * STEP[s] * DIR[d][1];
                        in = a >= 0 && a < side && b >= 0 && b < side;
                        nb[2 * d + 1 + sg] = in ? id[(size_t)a * side + b] : -1;
                        in = in && nb[2 * d + 1 + sg] >= 0;
                    }
                if (!in) continue;
                for (int k = 0; k < CR_GDSR_WRINKLE_TAPS; k++)
                    w->tap[s][k][m] = nb[k];
                w->valid_px[s][m] = i * side + j;
                m++;
            }
        w->nvalid[s] = m;
    }
done:
    free(face);
    free(id);
    free(bary);
    if (st != CR_OK) cr_gdsr_wrinkle_free(w);
    return st;
}

cr_tensor *cr_gdsr_wrinkle_normals(cr_nn_ctx *ctx, const gdsr_wrinkle *w, cr_tensor *x) {
    cr_tensor *p[3];
    for (int k = 0; k < 3; k++)
        p[k] = cr_nn_gather_rows(ctx, x, w->corner[k], w->nf);
    /* |cross| = twice the area: the sum over a vertex's triangles is area-weighted */
    cr_tensor *fn = cr_nn_cross(ctx, cr_nn_sub(ctx, p[1], p[0]), cr_nn_sub(ctx, p[2], p[0]));
    cr_tensor *vn = NULL, *tn = NULL;
    for (int k = 0; k < 3; k++) {
        cr_tensor *s = cr_nn_scatter_add_rows(ctx, fn, w->corner[k], w->nv);
        vn = vn ? cr_nn_add(ctx, vn, s) : s;
    }
    vn = cr_nn_normalize(ctx, vn, 1e-12f);
    for (int k = 0; k < 3; k++) {
        cr_tensor *b = cr_nn_from(ctx, 2, (int64_t[]){w->ntex, 1}, w->tex_b[k]);
        cr_tensor *q = cr_nn_mul(ctx, cr_nn_gather_rows(ctx, vn, w->tex_v[k], w->ntex), b);
        tn = tn ? cr_nn_add(ctx, tn, q) : q;
    }
    return cr_nn_normalize(ctx, tn, 1e-12f);
}

/* The responses (nvalid, 24) of texel normals tn at scale s: per direction
 * the odd n+ - n- and the even n+ + n- - 2 n, three channels each. */
static cr_tensor *responses(cr_nn_ctx *ctx, const gdsr_wrinkle *w, cr_tensor *tn, int s) {
    int64_t m = w->nvalid[s];
    cr_tensor *c2 = cr_nn_mul_scalar(ctx, cr_nn_gather_rows(ctx, tn, w->tap[s][0], m), 2.0f);
    cr_tensor *r[8];
    for (int d = 0; d < 4; d++) {
        cr_tensor *a = cr_nn_gather_rows(ctx, tn, w->tap[s][2 * d + 1], m);
        cr_tensor *b = cr_nn_gather_rows(ctx, tn, w->tap[s][2 * d + 2], m);
        r[2 * d] = cr_nn_sub(ctx, a, b);
        r[2 * d + 1] = cr_nn_sub(ctx, cr_nn_add(ctx, a, b), c2);
    }
    return cr_nn_concat(ctx, 8, r, 1);
}

void cr_gdsr_wrinkle_draw_patches(const gdsr_wrinkle *w, int n, int side, cr_rng *rng,
                                  gdsr_patch *out) {
    if (side > w->side) side = w->side;
    if (side < 1) side = 1;
    for (int k = 0; k < n; k++) {
        int32_t px = w->ntex > 0 ? w->tex_px[cr_rng_below(rng, (uint32_t)w->ntex)] : 0;
        int32_t r = px / w->side - side / 2, c = px % w->side - side / 2;
        r = r < 0 ? 0 : r > w->side - side ? w->side - side : r;
        c = c < 0 ? 0 : c > w->side - side ? w->side - side : c;
        out[k] = (gdsr_patch){r, c, side};
    }
}

/* Per response channel, the RMS over the rows of r (rows, 24) -> (24). */
static cr_tensor *channel_rms(cr_nn_ctx *ctx, cr_tensor *r) {
    return cr_nn_sqrt(
        ctx, cr_nn_add_scalar(ctx, cr_nn_mean_axis(ctx, cr_nn_square(ctx, r), 0, 0), 1e-8f));
}

/* Energy mode's term over the rows `rows` (m; NULL: all) of the responses. */
static cr_tensor *energy_term(cr_nn_ctx *ctx, cr_tensor *rx, cr_tensor *rr, const int32_t *rows,
                              int64_t m) {
    if (rows) {
        rx = cr_nn_gather_rows(ctx, rx, rows, m);
        rr = cr_nn_gather_rows(ctx, rr, rows, m);
    }
    return cr_nn_mean(ctx,
                      cr_nn_abs(ctx, cr_nn_sub(ctx, channel_rms(ctx, rx), channel_rms(ctx, rr))));
}

cr_tensor *cr_gdsr_wrinkle_loss(cr_nn_ctx *ctx, const gdsr_wrinkle *w, cr_tensor *x,
                                const float *ref, const gdsr_patch *patches, int npatches,
                                int energy) {
    cr_tensor *tx = cr_gdsr_wrinkle_normals(ctx, w, x);
    cr_tensor *tr = cr_gdsr_wrinkle_normals(ctx, w, cr_nn_from(ctx, 2, (int64_t[]){w->nv, 3}, ref));
    if (!patches) npatches = 0;
    cr_tensor *loss = NULL;
    for (int s = 0; s < CR_GDSR_WRINKLE_SCALES; s++) {
        if (w->nvalid[s] < 1) continue;
        cr_tensor *rx = responses(ctx, w, tx, s), *rr = cr_nn_detach(ctx, responses(ctx, w, tr, s));
        cr_tensor *e = energy ? NULL : cr_nn_abs(ctx, cr_nn_sub(ctx, rx, rr));
        if (npatches == 0) {
            cr_tensor *l = energy ? energy_term(ctx, rx, rr, NULL, 0) : cr_nn_mean(ctx, e);
            loss = loss ? cr_nn_add(ctx, loss, l) : l;
            continue;
        }
        for (int p = 0; p < npatches; p++) {
            /* this patch's texels at this scale (gather_rows copies the indices) */
            const gdsr_patch *q = patches + p;
            int64_t m = 0;
            for (int64_t v = 0; v < w->nvalid[s]; v++) {
                int32_t r = w->valid_px[s][v] / w->side, c = w->valid_px[s][v] % w->side;
                if (r >= q->r0 && r < q->r0 + q->side && c >= q->c0 && c < q->c0 + q->side)
                    w->scratch[m++] = (int32_t)v;
            }
            if (m == 0) continue;
            cr_tensor *l =
                cr_nn_mul_scalar(ctx,
                                 energy ? energy_term(ctx, rx, rr, w->scratch, m)
                                        : cr_nn_mean(ctx, cr_nn_gather_rows(ctx, e, w->scratch, m)),
                                 1.0f / npatches);
            loss = loss ? cr_nn_add(ctx, loss, l) : l;
        }
    }
    return loss ? loss : cr_nn_mul_scalar(ctx, cr_nn_sum(ctx, x), 0.0f);
}
