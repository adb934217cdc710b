/* gdsr_fixture.c: the small gdsr cases the gdsr tests share (test_gdsr.c,
 * test_gdsr_runtime.c). */
#include "gdsr_fixture.h"

#include "crease/primitives.h"

#include <math.h>
#include <stdlib.h>

cr_gdsr_model_def gdsr_tiny_def(void) {
    cr_gdsr_model_def d = cr_gdsr_model_default_def();
    d.latent = 16;
    d.steps = 2;
    d.decoder_features = 8;
    d.hyper_features = 8;
    d.gen_hidden = 16;
    d.wire_width = 8;
    d.wire_layers = 3;
    return d;
}

/* A tiny pair: a 5x5 and a 9x9 sheet sharing UVs, waving; the high one has
 * a ripple the low one cannot hold. The body is a small sphere below. */
int gdsr_tiny_data(cr_gdsr_data *d) {
    cr_error err = {0};
    cr_mesh *lo = NULL, *hi = NULL, *body = NULL;
    if (cr_prim_plane(5, 5, 0.4f, 0.4f, &lo, &err) != CR_OK) return 0;
    if (cr_prim_plane(9, 9, 0.4f, 0.4f, &hi, &err) != CR_OK) return 0;
    if (cr_prim_icosphere(0.05f, 1, &body, &err) != CR_OK) return 0;
    int T = 8;
    float *L = malloc((size_t)T * lo->nv * 12), *H = malloc((size_t)T * hi->nv * 12);
    float *B = malloc((size_t)T * body->nv * 12);
    for (int t = 0; t < T; t++) {
        float ph = 0.4f * t;
        for (int i = 0; i < lo->nv; i++) {
            const float *p = lo->pos + 3 * i;
            float *o = L + ((size_t)t * lo->nv + i) * 3;
            o[0] = p[0], o[2] = p[2], o[1] = 0.03f * sinf(6 * p[0] + ph);
        }
        for (int i = 0; i < hi->nv; i++) {
            const float *p = hi->pos + 3 * i;
            float *o = H + ((size_t)t * hi->nv + i) * 3;
            o[0] = p[0], o[2] = p[2];
            o[1] = 0.03f * sinf(6 * p[0] + ph) + 0.004f * sinf(40 * p[2]) * cosf(ph);
        }
        for (int i = 0; i < body->nv; i++) {
            float *o = B + ((size_t)t * body->nv + i) * 3;
            o[0] = body->pos[3 * i], o[1] = body->pos[3 * i + 1] - 0.2f,
            o[2] = body->pos[3 * i + 2];
        }
    }
    cr_status st = cr_gdsr_data_from_arrays(lo, hi, body, T, L, H, B, d, &err);
    free(L);
    free(H);
    free(B);
    cr_mesh_destroy(lo);
    cr_mesh_destroy(hi);
    cr_mesh_destroy(body);
    return st == CR_OK;
}

/* Two 40 cm sheets 1 cm apart (their UVs side by side), rippling: an outfit
 * of two layers. */
int gdsr_two_layer_data(cr_gdsr_data *d) {
    cr_error err = {0};
    cr_mesh *lo = NULL, *hi = NULL, *lo2 = NULL, *hi2 = NULL, *body = NULL;
    if (cr_prim_plane(5, 5, 0.4f, 0.4f, &lo, &err) != CR_OK) return 0;
    if (cr_prim_plane(9, 9, 0.4f, 0.4f, &hi, &err) != CR_OK) return 0;
    if (cr_mesh_clone(lo, &lo2, &err) != CR_OK || cr_mesh_clone(hi, &hi2, &err) != CR_OK) return 0;
    cr_mesh *two[2][2] = {{lo, lo2}, {hi, hi2}};
    for (int r = 0; r < 2; r++) {
        cr_mesh *b = two[r][1];
        for (int32_t i = 0; i < b->nv; i++)
            b->pos[3 * i + 1] += 0.01f;
        for (int32_t i = 0; i < b->nuv; i++)
            b->uv[2 * i] += 2.0f;
        if (cr_mesh_append(two[r][0], b, &err) != CR_OK) return 0;
    }
    if (cr_prim_icosphere(0.05f, 1, &body, &err) != CR_OK) return 0;
    int T = 6;
    float *L = malloc((size_t)T * lo->nv * 12), *H = malloc((size_t)T * hi->nv * 12);
    float *B = malloc((size_t)T * body->nv * 12);
    for (int t = 0; t < T; t++) {
        float ph = 0.4f * t;
        const cr_mesh *ms[2] = {lo, hi};
        float *out[2] = {L, H};
        for (int r = 0; r < 2; r++)
            for (int32_t i = 0; i < ms[r]->nv; i++) {
                const float *p = ms[r]->pos + 3 * i;
                float *o = out[r] + ((size_t)t * ms[r]->nv + i) * 3;
                o[0] = p[0], o[2] = p[2];
                o[1] = p[1] + 0.02f * sinf(6 * p[0] + ph) + (r ? 0.003f * sinf(40 * p[2]) : 0);
            }
        for (int32_t i = 0; i < body->nv * 3; i++)
            B[(size_t)t * body->nv * 3 + i] = body->pos[i] - (i % 3 == 1 ? 0.3f : 0);
    }
    cr_status st = cr_gdsr_data_from_arrays(lo, hi, body, T, L, H, B, d, &err);
    free(L), free(H), free(B);
    cr_mesh_destroy(lo), cr_mesh_destroy(hi), cr_mesh_destroy(lo2), cr_mesh_destroy(hi2);
    cr_mesh_destroy(body);
    return st == CR_OK;
}
