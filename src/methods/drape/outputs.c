/* outputs.c: the drape method's surface as a mesh at any resolution (the
 * representation is continuous), its penetration into the object, its grid
 * facets (the second differences across the grid encoding's cell
 * boundaries against those inside cells, docs/drape.md "Smooth cloth"), and
 * the picture of cloth over object.
 *
 * Leaves out: writing the object (`crease primitive` makes it), turntables
 * (`crease render --turntable` on drape.obj).
 */
#include "drape_internal.h"

#include "crease/primitives.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* V output vertices. */

cr_status cr_drape_surface_mesh(cr_nn_ctx *ctx, cr_drape_model *m, const drape_scene *s, int res,
                                cr_mesh **out, cr_error *err) {
    *out = NULL;
    cr_mesh *mesh = NULL;
    if (s->square)
        CR_TRY(cr_prim_plane(res, res, 1.0f, 1.0f, &mesh, err)); /* one UV per vertex */
    else
        CR_TRY(cr_mesh_clone(s->rest, &mesh, err));
    int64_t nv = mesh->nv;
    float *uv = cr_malloc((size_t)nv * 2 * sizeof(float), err);
    float *p0 = cr_malloc((size_t)nv * 3 * sizeof(float), err);
    cr_status st = uv && p0 ? CR_OK : CR_ERR_MEMORY;
    if (st == CR_OK) {
        for (int64_t c = 3 * (int64_t)mesh->nf - 1; c >= 0; c--) /* first UV of each vertex */
            memcpy(&uv[2 * (int64_t)mesh->tri[c]], &mesh->uv[2 * (int64_t)mesh->tri_uv[c]],
                   2 * sizeof(float));
        if (s->square)
            cr_drape_model_rest(m, uv, nv, p0, NULL);
        else
            memcpy(p0, s->rest->pos, (size_t)nv * 3 * sizeof(float));
        st = cr_drape_model_eval(ctx, m, uv, p0, nv, mesh->pos, err);
    }
    for (int64_t i = 0; st == CR_OK && i < 3 * nv; i++)
        if (!isfinite(mesh->pos[i]))
            st = CR_FAIL(err, CR_ERR_DIVERGED,
                         "drape: the learned surface is not finite at "
                         "vertex %lld",
                         (long long)(i / 3));
    free(uv), free(p0);
    if (st != CR_OK) {
        cr_mesh_destroy(mesh);
        return st;
    }
    *out = mesh;
    return CR_OK;
}

double cr_drape_max_penetration(const cr_bvh *object, const cr_mesh *surface) {
    float *d = malloc((size_t)surface->nv * sizeof(float) + 1);
    if (!d) return NAN;
    cr_bvh_signed_distance_batch(object, surface->pos, surface->nv, INFINITY, d, NULL, NULL);
    double deepest = 0.0;
    for (int32_t i = 0; i < surface->nv; i++)
        deepest = fmax(deepest, -(double)d[i]);
    free(d);
    return deepest;
}

/* Does the open interval ((k-1)/(n-1), (k+1)/(n-1)) hold a boundary
 * c/cells, 0 < c < cells? In integers: (k-1) cells < c (n-1) < (k+1) cells. */
static int span_crosses(int k, int n, int cells) {
    int64_t lo = (int64_t)(k - 1) * cells, hi = (int64_t)(k + 1) * cells, m = n - 1;
    int64_t c = lo / m + 1; /* the first boundary index above lo / m */
    return c < cells && c * m < hi;
}

/* Second-difference norm of pos at vertices a, b, c (index of the vertex). */
static double second_difference(const float *pos, int64_t a, int64_t b, int64_t c) {
    double s = 0.0;
    for (int k = 0; k < 3; k++) {
        double d = (double)pos[3 * a + k] - 2.0 * pos[3 * b + k] + pos[3 * c + k];
        s += d * d;
    }
    return sqrt(s);
}

double cr_drape_facet_ratio(const float *pos, int nu, int nv, int cells) {
    CR_ASSERT(pos && nu >= 1 && nv >= 1 && cells >= 1);
    double sum[2] = {0.0, 0.0}; /* [crossing] */
    int64_t count[2] = {0, 0};
    for (int iv = 0; iv < nv; iv++) /* along rows: spans in u */
        for (int iu = 1; iu + 1 < nu; iu++) {
            int x = span_crosses(iu, nu, cells);
            int64_t b = (int64_t)iv * nu + iu;
            sum[x] += second_difference(pos, b - 1, b, b + 1);
            count[x]++;
        }
    for (int iu = 0; iu < nu; iu++) /* along columns: spans in v */
        for (int iv = 1; iv + 1 < nv; iv++) {
            int x = span_crosses(iv, nv, cells);
            int64_t b = (int64_t)iv * nu + iu;
            sum[x] += second_difference(pos, b - nu, b, b + nu);
            count[x]++;
        }
    if (count[0] == 0 || count[1] == 0 || !(sum[0] > 0.0)) return NAN;
    return (sum[1] / (double)count[1]) / (sum[0] / (double)count[0]);
}

cr_status cr_drape_render(const cr_mesh *surface, const cr_mesh *object, int size, cr_image *img,
                          cr_error *err) {
    cr_render_object objs[2] = {
        {.mesh = surface, .color = {0.33f, 0.52f, 0.80f}}, /* cloth blue, as `crease render` */
        {.mesh = object, .color = {0.72f, 0.72f, 0.70f}},
    };
    cr_render_def def = cr_render_default_def();
    def.width = def.height = size;
    def.pitch_deg = 25.0f; /* a little more from above than the default: folds read better */
    return cr_render_scene(&def, objs, 2, img, err);
}
