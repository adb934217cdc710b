/* bench_epnet_pnet.c: P-Net alone, fed the plastic reference's own angles
 * (docs/epnet.md, "P-Net on the reference's angles"). Table 1's PE mixes two
 * errors: E-Net bending other hinges than the reference does, and P-Net
 * turning angles into RB. Here E-Net is out: P-Net replays the reference
 * simulation's positions, and its RB is scored against the reference's
 * plastic rest by crease eval's PE, beside RB = 0 (the baseline's PE) and the
 * plastic rule of Eq. 4-5 on the same angles (P-Net before training). On the
 * model's own garment and on garments P-Net never saw (its graph network
 * runs on any hinge graph: the paper's Table 3, unseen topology).
 *
 *   bench_epnet_pnet EPNET_DIR [motion,motion,...] [garment,garment,...] [hold] [friction]
 *
 * garments: unseen ones, after the model's own (default longsleeve,dress);
 * friction: the reference's Coulomb friction (default 0, the loss's physics).
 */
#include "crease/epnet.h"
#include "crease/eval.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int fail(const cr_error *e) {
    fprintf(stderr, "bench_epnet_pnet: %s\n", e->msg);
    return 1;
}

/* crease eval's PE of rest angles (T,H), relative to the rest mesh's, against
 * the reference's (absolute); the positions are the reference's own. */
static double plastic_error(const cr_epnet *m, const cr_epnet_seq *s, const float *ref,
                            const float *ref_rest, const float *rb, int32_t T, cr_error *err) {
    const int32_t H = cr_epnet_hinge_count(m);
    const float *bar = cr_epnet_rest_angles(m);
    float *abs_rb = malloc(sizeof(float) * (size_t)T * H);
    if (!abs_rb) return NAN;
    for (int32_t t = 0; t < T; t++)
        for (int32_t h = 0; h < H; h++)
            abs_rb[(size_t)t * H + h] = bar[h] + (rb ? rb[(size_t)t * H + h] : 0.0f);
    cr_eval_def ed = cr_eval_default_def();
    cr_epnet_material(&ed.material);
    cr_eval_input in = {.garment = cr_epnet_garment(m),
                        .nframes = T,
                        .pred = ref,
                        .ref = ref,
                        .body_mesh = cr_epnet_seq_body_mesh(s),
                        .body = cr_epnet_seq_body(s),
                        .body_nframes = T,
                        .ref_rest = ref_rest,
                        .ref_rest_nframes = T,
                        .pred_rest = abs_rb,
                        .pred_rest_nframes = T,
                        .rest_nhinges = H};
    cr_eval_result r;
    double pe = NAN;
    if (cr_eval_run(&ed, &in, &r, err) == CR_OK) {
        pe = r.summary[CR_EVAL_PE].mean;
        cr_eval_result_free(&r);
    }
    free(abs_rb);
    return pe;
}

int main(int argc, char **argv) {
    if (argc < 2) {
        fprintf(stderr, "usage: bench_epnet_pnet EPNET_DIR [motions] [garments] [hold] "
                        "[friction]\n");
        return 2;
    }
    char mbuf[512], gbuf[256];
    snprintf(mbuf, sizeof mbuf, "%s", argc > 2 ? argv[2] : "raise_arms,bend");
    snprintf(gbuf, sizeof gbuf, "%s", argc > 3 ? argv[3] : "longsleeve,dress");
    const int hold = argc > 4 ? atoi(argv[4]) : 30;
    const double friction = argc > 5 ? atof(argv[5]) : 0.0;
    const char *motions[16], *garments[9] = {NULL};
    int nm = 0, ng = 1; /* garments[0]: the model's own */
    for (char *t = strtok(mbuf, ","); t && nm < 16; t = strtok(NULL, ","))
        motions[nm++] = t;
    for (char *t = strtok(gbuf, ","); t && ng < 9; t = strtok(NULL, ","))
        garments[ng++] = t;
    cr_error err;
    printf(
        "| garment | motion | hinges | reference: plastic rest past 0.3 / 0.1 rad | PE rad, RB = 0 "
        "(baseline) | PE rad, Eq. 4-5 on the reference's angles | PE rad, P-Net on the "
        "reference's angles | P-Net against RB = 0 |\n");
    printf("|---|---|---|---|---|---|---|---|\n");
    for (int gi = 0; gi < ng; gi++) {
        cr_epnet *m = NULL;
        if (gi == 0 ? cr_epnet_open(argv[1], &m, &err)
                    : cr_epnet_open_pnet(argv[1], garments[gi], 0, &m, &err))
            return fail(&err);
        const cr_epnet_def *d = cr_epnet_get_def(m);
        const int32_t V = cr_epnet_garment(m)->nv, H = cr_epnet_hinge_count(m);
        const float *bar = cr_epnet_rest_angles(m);
        for (int mi = 0; mi < nm; mi++) {
            cr_epnet_seq *s = NULL;
            if (cr_epnet_seq_create(m, motions[mi], NULL, 0, hold, &s, &err) != CR_OK)
                return fail(&err);
            const int32_t T = cr_epnet_seq_frames(s);
            float *ref = malloc(sizeof(float) * 3 * (size_t)T * V);
            float *rest = malloc(sizeof(float) * (size_t)T * H),
                  *th = malloc(sizeof(float) * (size_t)T * H);
            float *rule = malloc(sizeof(float) * (size_t)T * H),
                  *rb = malloc(sizeof(float) * (size_t)T * H);
            if (!ref || !rest || !th || !rule || !rb) return 1;
            if (cr_epnet_reference_friction(m, s, 1, friction, ref, rest, &err) != CR_OK)
                return fail(&err);
            const float *last = rest + (size_t)(T - 1) * H; /* relative to bar */
            double past3 = 0, past1 = 0;
            for (int32_t h = 0; h < H; h++)
                past3 += fabsf(last[h]) > 0.3f, past1 += fabsf(last[h]) > 0.1f;
            for (int64_t i = 0; i < (int64_t)T * H; i++)
                rest[i] += bar[i % H];
            cr_epnet_angles(m, ref, T, th);
            cr_epnet_plastic_rollout(th, bar, NULL, T, H, d->material.yield_angle,
                                     d->material.plastic_gain, d->sharpness, rule);
            if (cr_epnet_pnet_replay(m, ref, T, rb, &err) != CR_OK) return fail(&err);
            const double pe0 = plastic_error(m, s, ref, rest, NULL, T, &err);
            const double per = plastic_error(m, s, ref, rest, rule, T, &err);
            const double pep = plastic_error(m, s, ref, rest, rb, T, &err);
            if (!isfinite(pe0) || !isfinite(per) || !isfinite(pep)) return fail(&err);
            printf("| %s%s | %s | %d | %.3f / %.3f | %.4g | %.4g | %.4g | %+.0f %% |\n", d->garment,
                   gi == 0 ? " (trained)" : " (unseen)", motions[mi], H, past3 / H, past1 / H, pe0,
                   per, pep, 100.0 * (pep / pe0 - 1.0));
            fflush(stdout);
            free(ref), free(rest), free(th), free(rule), free(rb);
            cr_epnet_seq_destroy(s);
        }
        cr_epnet_destroy(m);
    }
    return 0;
}
