/* test_epnet.c: epnet (paper 004): the plastic rule against Eq. 4-5 on
 * hand-made strain sequences, the hinge graph of a known mesh, a tiny E-Net
 * lowering its physics loss, P-Net fitting a known RB field, P-Net's RB in
 * the rule's bounded form, the reference keeping creases, a pinned
 * waistband, bit-exact resume, the checkpoint set and P-Net's replay. */
#include "test.h"

#include "nn_gradcheck.h"

#include "crease/epnet.h"
#include "crease/losses.h"
#include "crease/mesh.h"
#include "crease/motion.h"
#include "crease/npz.h"
#include "crease/topology.h"
#include "methods/epnet/epnet_internal.h"

#include <malloc.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

CR_TEST(epnet, plastic_rule_matches_eq4_5) {
    /* one hinge, rest angle 0.1, yield 0.5, gain 1, no sigmoid: strain
     * rises to 0.9 (d = 0.8 over the yield by 0.3), holds, then falls */
    const float theta[6] = {0.3f, 0.9f, 0.9f, 1.0f, 0.2f, -0.9f};
    const float bar[1] = {0.1f};
    float rb[6];
    int64_t n = cr_epnet_plastic_rollout(theta, bar, NULL, 6, 1, 0.5, 1.0, 0.0, rb);
    /* t0: d=0.2 -> 0; t1: d=0.8 -> rb 0.3; t2: d=0.5 -> stays; t3: d=0.6 -> 0.4;
     * t4: d=-0.3 -> stays; t5: d=-1.4 -> rb = 0.4 - 0.9 = -0.5 */
    const float want[6] = {0, 0.3f, 0.3f, 0.4f, 0.4f, -0.5f};
    for (int t = 0; t < 6; t++)
        CR_CHECK_NEAR(rb[t], want[t], 1e-6);
    CR_CHECK(n == 3);
    /* the sigmoid gate (sharpness 50): at 0.3 over the yield s = 1/(1+e^-15) */
    cr_epnet_plastic_rollout(theta, bar, NULL, 2, 1, 0.5, 1.0, 50.0, rb);
    CR_CHECK_NEAR(rb[1], 0.3 / (1.0 + exp(-15.0)), 1e-6);
    /* gain 0.5 halves the first step; two hinges run independently */
    const float th2[4] = {0.8f, 0.0f, 0.8f, -0.9f};
    float rb2[4];
    cr_epnet_plastic_rollout(th2, NULL, NULL, 2, 2, 0.5, 0.5, 0.0, rb2);
    CR_CHECK_NEAR(rb2[0], 0.15, 1e-6); /* hinge 0, t0 */
    CR_CHECK_NEAR(rb2[1], 0.0, 1e-6);  /* hinge 1, t0 */
    CR_CHECK_NEAR(rb2[2], 0.15 + 0.5 * (0.65 - 0.5), 1e-6);
    CR_CHECK_NEAR(rb2[3], -0.5 * 0.4, 1e-6);
}

CR_TEST(epnet, hinge_graph_of_a_known_mesh) {
    /* a 3 x 3 vertex grid, 8 triangles (diagonals from (i,j) to (i+1,j+1)):
     * 16 edges, 8 interior hinges; every vertex of a 2 x 2 grid is shared
     * by the centre vertex's hinges, so the centre's four edges' hinges are
     * all neighbours of each other */
    cr_mesh *m = NULL;
    cr_error err;
    CR_REQUIRE(cr_mesh_create(9, 8, 0, &m, &err) == CR_OK);
    for (int j = 0; j < 3; j++)
        for (int i = 0; i < 3; i++) {
            float *p = m->pos + 3 * (3 * j + i);
            p[0] = (float)i, p[1] = 0, p[2] = (float)j;
        }
    int f = 0;
    for (int j = 0; j < 2; j++)
        for (int i = 0; i < 2; i++) {
            const int a = 3 * j + i, b = a + 1, c = a + 4, d = a + 3;
            int32_t *t = m->tri + 3 * f;
            t[0] = a, t[1] = c, t[2] = b, f++;
            t = m->tri + 3 * f;
            t[0] = a, t[1] = d, t[2] = c, f++;
        }
    cr_topology *t = NULL;
    CR_REQUIRE(cr_topology_build(m, &t, &err) == CR_OK);
    CR_CHECK(t->nh == 8);
    int32_t *s = NULL, *r = NULL;
    int64_t ne = 0;
    CR_REQUIRE(cr_epnet_hinge_graph(t, &s, &r, &ne, &err) == CR_OK);
    /* brute force: hinges a != b sharing a vertex */
    int64_t want = 0;
    for (int a = 0; a < t->nh; a++)
        for (int b = 0; b < t->nh; b++) {
            if (a == b) continue;
            int share = 0;
            for (int i = 0; i < 4; i++)
                for (int k = 0; k < 4; k++)
                    share |= t->hinge[4 * a + i] == t->hinge[4 * b + k];
            want += share;
        }
    CR_CHECK(ne == want);
    CR_CHECK(ne > 0 && ne % 2 == 0);
    for (int64_t e = 0; e < ne; e++) {
        CR_CHECK(s[e] != r[e]);
        if (e > 0) CR_CHECK(r[e] > r[e - 1] || (r[e] == r[e - 1] && s[e] > s[e - 1]));
        /* symmetric: (r, s) is an edge too */
        int found = 0;
        for (int64_t k = 0; k < ne; k++)
            found |= s[k] == r[e] && r[k] == s[e];
        CR_CHECK(found);
    }
    free(s), free(r);
    cr_topology_destroy(t);
    cr_mesh_destroy(m);
}

static cr_epnet_def tiny_def(void) {
    cr_epnet_def d = cr_epnet_default_def();
    d.garment_vertices = 500;
    d.frames = 12;
    d.static_widths[0] = 16, d.nstatic = 1;
    d.dynamic_width = 8, d.gru_hidden = 8, d.rb_widths[0] = 8;
    d.decoder_width = 32, d.decoder_layers = 1;
    d.pnet_latent = 8;
    return d;
}

/* both inertia forms: gradients through the three frames, and the
 * implicit-Euler form with frames t-1, t-2 held fixed */
CR_TEST(epnet, tiny_enet_lowers_its_physics_loss) {
    for (int detach = 0; detach < 2; detach++) {
        cr_error err;
        cr_epnet_def d = tiny_def();
        d.experimental.inertia_detach = detach;
        cr_epnet *m = NULL;
        CR_REQUIRE(cr_epnet_create(&d, &m, &err) == CR_OK);
        cr_epnet_seq *s = NULL;
        CR_REQUIRE(cr_epnet_seq_create(m, "squat", NULL, 12, 0, &s, &err) == CR_OK);
        cr_epnet_losses l0, l;
        CR_REQUIRE(cr_epnet_enet_step(m, s, NULL, 0, &l0, &err) == CR_OK);
        for (int i = 0; i < CR_TEST_SIZE(60, 6); i++)
            CR_REQUIRE(cr_epnet_enet_step(m, s, NULL, 1, &l, &err) == CR_OK);
        CR_REQUIRE(cr_epnet_enet_step(m, s, NULL, 0, &l, &err) == CR_OK);
        fprintf(stderr, "  inertia_detach %d: enet loss %.5g -> %.5g J/frame\n", detach, l0.total,
                l.total);
        for (int k = 0; k < CR_EPNET_NTERMS; k++)
            fprintf(stderr, "    %s %.5g -> %.5g\n", cr_epnet_term_names[k], l0.term[k], l.term[k]);
        CR_CHECK(isfinite(l.total));
        /* the elastic energy of the skinned template (stretch + shear + bending)
         * falls at least fivefold, and the total (gravity included) falls: after
         * 60 steps, so in a full run only */
        const double el0 = l0.term[0] + l0.term[1] + l0.term[2];
        const double el = l.term[0] + l.term[1] + l.term[2];
        if (!cr_test_quick()) {
            CR_CHECK(el < 0.2 * el0);
            CR_CHECK(l.total < l0.total);
            /* and it stays (nearly) outside the body: the penalty starts at eps + the
             * chord sag of each vertex's edges (losses.h), 1.6-1.9 % of el0 here (0.2 %
             * when it started at eps) */
            CR_CHECK(l.term[4] < 0.03 * el0);
        }
        cr_epnet_seq_destroy(s);
        cr_epnet_destroy(m);
    }
}

/* ------------------------------------------------ the paired terms -- */

typedef struct paired_job {
    cr_epnet *m;
    double scale;    /* the check's output scale (gradients of order 10) */
    const float *rb; /* (T,H) for the whole-step check */
    const cr_epnet_seq *s;
} paired_job;

/* The paired terms of given positions: in[0] x_RB (1,V,3), in[1] x_0 (1,V,3), in[2] RB (1,H). */
static cr_tensor *build_paired(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    const paired_job *j = user;
    cr_tensor *z = NULL, *r = NULL;
    cr_epnet_paired_terms_(ctx, j->m->bending, in[0], in[1], in[2], &z, &r);
    return cr_nn_mul_scalar(
        ctx, cr_nn_add(ctx, cr_nn_mul_scalar(ctx, z, 2.0f), cr_nn_mul_scalar(ctx, r, 5.0f)),
        (float)j->scale);
}

/* The whole E-Net loss of the step on the checker's tape (E-Net's parameters
 * are checked): the model's context swapped for the checker's while it runs. */
static cr_tensor *build_step_loss(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    (void)in;
    const paired_job *j = user;
    cr_nn_ctx *own = j->m->ctx;
    j->m->ctx = ctx;
    cr_tensor *loss = cr_epnet_enet_loss_(j->m, j->s, j->rb, NULL);
    j->m->ctx = own;
    return cr_nn_mul_scalar(ctx, loss, (float)j->scale);
}

/* The largest |dL/d(input or parameter)| of a build at scale 1, to scale the check by. */
static double grad_max(nn_gradcheck_fn fn, paired_job *j, int nin, nn_gradcheck_input *in,
                       cr_nn_params *params, size_t arena) {
    cr_nn_ctx *ctx = nn_gradcheck_ctx(arena);
    cr_error err;
    cr_tensor *w[4];
    j->scale = 1.0;
    for (int i = 0; i < nin; i++) {
        w[i] = cr_nn_wrap(ctx, in[i].ndim, in[i].shape, in[i].data);
        w[i]->requires_grad = (uint8_t)in[i].requires_grad;
    }
    if (params) cr_nn_params_zero_grad(params);
    cr_tensor *y = fn(ctx, w, j);
    double g = 0;
    if (y && cr_nn_backward(ctx, y, &err) == CR_OK) {
        for (int i = 0; i < nin; i++)
            for (int64_t k = 0; in[i].requires_grad && k < w[i]->numel; k++)
                g = fmax(g, fabs(w[i]->grad[k]));
        for (int k = 0; params && k < cr_nn_params_count(params); k++) {
            const cr_tensor *p = cr_nn_params_at(params, k, NULL);
            for (int64_t e = 0; p->grad && e < p->numel; e++)
                g = fmax(g, fabs(p->grad[e]));
        }
    }
    cr_nn_ctx_destroy(ctx);
    return g;
}

/* The paired terms (the authors' zero-rest consistency and rest response):
 * their values against angles measured by hand, and their gradients to both
 * passes' positions and, through a tiny E-Net's whole training loss with
 * only these terms on, to every E-Net parameter, against central
 * differences (step 3e-4 m on positions, 1e-3 on weights; tolerance 1e-2 of
 * the larger of 1 and the difference, on gradients scaled to about 10). */
CR_TEST(epnet, paired_terms_gradients_match_central_differences) {
    cr_error err;
    cr_epnet_def d = tiny_def();
    cr_epnet *m = NULL;
    CR_REQUIRE(cr_epnet_create(&d, &m, &err) == CR_OK);
    const int32_t V = cr_epnet_garment(m)->nv, H = cr_epnet_hinge_count(m);
    const float *bar = cr_epnet_rest_angles(m);
    float *xr = malloc(sizeof(float) * 3 * (size_t)V), *x0 = malloc(sizeof(float) * 3 * (size_t)V);
    float *rb = malloc(sizeof(float) * (size_t)H), *th = malloc(sizeof(float) * (size_t)H),
          *th0 = malloc(sizeof(float) * (size_t)H);
    CR_REQUIRE(xr && x0 && rb && th && th0);
    /* the rest garment moved by up to 4 mm (edges about 4 cm: angles of 0.1-0.3 rad) */
    nn_gradcheck_fill(xr, 3 * (int64_t)V, -0.004f, 0.004f, 0.0f, 11);
    nn_gradcheck_fill(x0, 3 * (int64_t)V, -0.004f, 0.004f, 0.0f, 12);
    nn_gradcheck_fill(rb, H, -0.3f, 0.3f, 0.0f, 13);
    for (int32_t i = 0; i < 3 * V; i++)
        xr[i] += cr_epnet_garment(m)->pos[i], x0[i] += cr_epnet_garment(m)->pos[i];
    cr_epnet_angles(m, xr, 1, th), cr_epnet_angles(m, x0, 1, th0);
    double zero = 0, resp = 0;
    for (int32_t h = 0; h < H; h++) {
        const double r0 = remainder((double)th0[h] - bar[h], 2 * M_PI);
        const double rr = remainder((double)th[h] - bar[h], 2 * M_PI);
        zero += r0 * r0 / H, resp += (rr - r0 - rb[h]) * (rr - r0 - rb[h]) / H;
    }
    cr_nn_ctx *ctx = nn_gradcheck_ctx((size_t)16 << 20);
    cr_tensor *z = NULL, *r = NULL;
    cr_epnet_paired_terms_(ctx, m->bending, cr_nn_wrap(ctx, 3, (int64_t[]){1, V, 3}, xr),
                           cr_nn_wrap(ctx, 3, (int64_t[]){1, V, 3}, x0),
                           cr_nn_wrap(ctx, 2, (int64_t[]){1, H}, rb), &z, &r);
    CR_REQUIRE(z && r);
    fprintf(stderr, "  paired terms: zero rest %.5g (by hand %.5g), rest response %.5g (%.5g)\n",
            z->data[0], zero, r->data[0], resp);
    CR_CHECK(zero > 1e-3 && resp > 1e-3);
    CR_CHECK_NEAR(z->data[0], zero, 1e-5 * zero + 1e-7);
    CR_CHECK_NEAR(r->data[0], resp, 1e-5 * resp + 1e-7);
    cr_nn_ctx_destroy(ctx);
    paired_job j = {.m = m};
    nn_gradcheck_input in[3] = {nn_gradcheck_in(3, (int64_t[]){1, V, 3}, xr),
                                nn_gradcheck_in(3, (int64_t[]){1, V, 3}, x0),
                                nn_gradcheck_in(2, (int64_t[]){1, H}, rb)};
    in[2].requires_grad = 0;
    for (int which = 0; which < 2; which++) {
        in[0].requires_grad = which == 0, in[1].requires_grad = which == 1;
        const double g = grad_max(build_paired, &j, 3, in, NULL, (size_t)16 << 20);
        CR_CHECK(g > 0);
        j.scale = 10.0 / g;
        nn_gradcheck_def gd = nn_gradcheck_default_def();
        gd.name = which ? "paired d/d(x_0)" : "paired d/d(x_RB)";
        gd.max_elems = CR_TEST_SIZE(300, 40);
        gd.step = 3e-4; /* m */
        nn_gradcheck_result res;
        CR_CHECK(nn_gradcheck(&gd, 3, in, NULL, build_paired, &j, &res) == 0);
        fprintf(stderr, "  %s: %lld checked, max err %.3g\n", gd.name, (long long)res.checked,
                res.max_err);
    }
    /* through the network: only the paired terms weighted, an RB that moves */
    cr_epnet_destroy(m);
    d.w_stretch = d.w_shear = d.w_bending = d.w_gravity = d.w_collision = d.w_inertia = 0;
    d.w_pin = 0;
    CR_REQUIRE(cr_epnet_create(&d, &m, &err) == CR_OK);
    cr_epnet_seq *s = NULL;
    CR_REQUIRE(cr_epnet_seq_create(m, "squat", NULL, 6, 0, &s, &err) == CR_OK);
    const int32_t T = cr_epnet_seq_frames(s);
    float *rbt = malloc(sizeof(float) * (size_t)T * H);
    CR_REQUIRE(rbt);
    nn_gradcheck_fill(rbt, (int64_t)T * H, -0.3f, 0.3f, 0.0f, 14);
    /* biases start at zero and frame 0's velocities are zero, so some ReLUs sit on
     * their kink exactly: move every bias off zero first */
    for (int k = 0; k < cr_nn_params_count(m->pe); k++) {
        const char *name = NULL;
        cr_tensor *p = cr_nn_params_at(m->pe, k, &name);
        if (strstr(name, "bias")) nn_gradcheck_fill(p->data, p->numel, -0.1f, 0.1f, 0.02f, 20 + k);
    }
    j = (paired_job){.m = m, .rb = rbt, .s = s};
    const double g = grad_max(build_step_loss, &j, 0, NULL, m->pe, (size_t)64 << 20);
    CR_CHECK(g > 0);
    j.scale = 10.0 / g;
    nn_gradcheck_def gd = nn_gradcheck_default_def();
    gd.name = "paired terms d/d(E-Net parameters)";
    gd.max_elems = CR_TEST_SIZE(12, 3);
    gd.arena_bytes = (size_t)64 << 20;
    nn_gradcheck_result res;
    CR_CHECK(nn_gradcheck(&gd, 0, NULL, m->pe, build_step_loss, &j, &res) == 0);
    fprintf(stderr, "  %s: %lld checked, max err %.3g\n", gd.name, (long long)res.checked,
            res.max_err);
    cr_epnet_losses l;
    CR_REQUIRE(cr_epnet_enet_step(m, s, rbt, 0, &l, &err) == CR_OK);
    CR_CHECK(l.term[7] > 0 && l.term[8] > 0);
    CR_CHECK_NEAR(l.total, l.term[7] + l.term[8], 1e-6 * l.total);
    free(rbt);
    cr_epnet_seq_destroy(s);
    free(xr), free(x0), free(rb), free(th), free(th0);
    cr_epnet_destroy(m);
}

/* The paired terms make E-Net read RB: a tiny E-Net trained on the squat
 * with a fixed RB field (0.3 rad of either sign on every fifth hinge) for 60
 * steps, once with the authors' paired weights (2, 5) and once without,
 * then the RB it realises at the last frame (cr_epnet_rb_realised: its
 * angles given that RB against its own at RB = 0, along RB). */
CR_TEST(epnet, paired_terms_make_enet_realise_more_rb) {
    cr_error err;
    double realised[2] = {0, 0};
    const int steps = CR_TEST_SIZE(60, 4);
    for (int paired = 0; paired < 2; paired++) {
        cr_epnet_def d = tiny_def();
        if (!paired) d.w_zero_rest = d.w_rest_response = 0;
        cr_epnet *m = NULL;
        CR_REQUIRE(cr_epnet_create(&d, &m, &err) == CR_OK);
        cr_epnet_seq *s = NULL;
        CR_REQUIRE(cr_epnet_seq_create(m, "squat", NULL, 12, 0, &s, &err) == CR_OK);
        const int32_t T = cr_epnet_seq_frames(s), H = cr_epnet_hinge_count(m);
        float *rb = malloc(sizeof(float) * (size_t)T * H), *th = malloc(sizeof(float) * T * H),
              *th0 = malloc(sizeof(float) * (size_t)T * H);
        CR_REQUIRE(rb && th && th0);
        for (int32_t t = 0; t < T; t++)
            for (int32_t h = 0; h < H; h++)
                rb[(size_t)t * H + h] = h % 5 ? 0.0f : (h % 10 ? 0.3f : -0.3f);
        cr_epnet_losses l0, l;
        CR_REQUIRE(cr_epnet_enet_step(m, s, rb, 0, &l0, &err) == CR_OK);
        for (int i = 0; i < steps; i++)
            CR_REQUIRE(cr_epnet_enet_step(m, s, rb, 1, &l, &err) == CR_OK);
        cr_nn_ctx_reset(m->ctx);
        cr_nn_ctx_set_grad_enabled(m->ctx, 0);
        cr_tensor *x = cr_epnet_enet_forward_(m, s, rb);
        CR_REQUIRE(x);
        cr_epnet_angles(m, x->data, T, th);
        cr_nn_ctx_reset(m->ctx);
        x = cr_epnet_enet_forward_(m, s, NULL);
        CR_REQUIRE(x);
        cr_epnet_angles(m, x->data, T, th0);
        realised[paired] = cr_epnet_rb_realised(th + (size_t)(T - 1) * H, th0 + (size_t)(T - 1) * H,
                                                rb + (size_t)(T - 2) * H, H, 0.05);
        fprintf(stderr,
                "  paired %d: RB realised %.3f; zero rest %.4g -> %.4g, rest response %.4g -> "
                "%.4g\n",
                paired, realised[paired], l0.term[7], l.term[7], l0.term[8], l.term[8]);
        free(rb), free(th), free(th0);
        cr_epnet_seq_destroy(s);
        cr_epnet_destroy(m);
    }
    if (!cr_test_quick()) {
        CR_CHECK(realised[1] > 0.3);
        CR_CHECK(realised[1] > 3.0 * fabs(realised[0]));
    }
}

/* P-Net's task as the authors set it: from the proxy's angles (here a strain
 * ramp past the yield on a third of the hinges) to the converged RB (Eq. 4-5
 * on the same ramp 0.1 rad higher, as if E-Net realised RB), fitted with
 * L1, noisy teacher forcing (0.05 rad) and inactive hinges down-weighted;
 * judged as inference runs it, through the ratchet without any teacher: the
 * RB error on the ramp's hinges (frames 4 on, once 3 of 5 have driven) falls
 * at least threefold in 30 steps (measured 0.1 -> 0.0008 rad). */
CR_TEST(epnet, pnet_learns_the_converged_rb_from_the_proxy) {
    cr_error err;
    cr_epnet_def d = tiny_def();
    d.pnet_lr = 3e-2f;
    d.pnet_frames = 2;
    cr_epnet *m = NULL;
    CR_REQUIRE(cr_epnet_create(&d, &m, &err) == CR_OK);
    CR_CHECK(d.pnet_rb_noise == 0.05 && d.pnet_inactive_weight == 0.03);
    cr_epnet_seq *s = NULL;
    CR_REQUIRE(cr_epnet_seq_create(m, "squat", NULL, 12, 0, &s, &err) == CR_OK);
    const int32_t T = 12, H = cr_epnet_hinge_count(m), V = cr_epnet_garment(m)->nv;
    float *pos = malloc(sizeof(float) * 3 * (size_t)T * V),
          *theta = malloc(sizeof(float) * (size_t)T * H);
    float *rb = malloc(sizeof(float) * (size_t)T * H), *R = malloc(sizeof(float) * (size_t)T * H);
    CR_REQUIRE(pos && theta && rb && R);
    const float *bar = cr_epnet_rest_angles(m);
    for (int32_t t = 0; t < T; t++) {
        for (int32_t v = 0; v < 3 * V; v++)
            pos[(size_t)t * V * 3 + v] = cr_epnet_garment(m)->pos[v];
        for (int32_t h = 0; h < H; h++)
            theta[(size_t)t * H + h] = bar[h] + (h % 3 == 0 ? 0.6f + 0.08f * t + 0.1f : 0.0f);
    }
    cr_epnet_plastic_rollout(theta, bar, NULL, T, H, 0.52, 1.0, 50.0, rb);
    for (int32_t t = 0; t < T; t++)
        for (int32_t h = 0; h < H; h += 3)
            theta[(size_t)t * H + h] -= 0.1f;
    const cr_epnet_ratchet_def rd = cr_epnet_ratchet_default_def();
    double e[2];
    double l0 = 0, l = 0;
    /* the noise makes the fall uneven: 12 steps 2x, 30 steps 130x, 40 steps 13x */
    const int steps = CR_TEST_SIZE(30, 4);
    for (int k = 0; k < 2; k++) {
        if (k == 1) {
            CR_REQUIRE(cr_epnet_pnet_fit(m, s, pos, theta, rb, 1, &l0, &err) == CR_OK);
            double t0 = cr_time_now();
            CR_REQUIRE(cr_epnet_pnet_fit(m, s, pos, theta, rb, steps, &l, &err) == CR_OK);
            fprintf(stderr, "  pnet: %.3f s per step; fit L1 %.3g -> %.3g rad\n",
                    (cr_time_now() - t0) / steps, l0, l);
        }
        CR_REQUIRE(cr_epnet_pnet_proxy_(m, pos, theta, T, &rd, R, &err) == CR_OK);
        e[k] = 0;
        for (int32_t t = 4; t < T; t++)
            for (int32_t h = 0; h < H; h += 3)
                e[k] += fabs(R[(size_t)t * H + h] - rb[(size_t)t * H + h]) / ((T - 4) * (H / 3));
    }
    fprintf(stderr, "  P-Net through the ratchet: mean |RB - converged RB| %.3g -> %.3g rad\n",
            e[0], e[1]);
    CR_CHECK(e[0] > 0.05);
    if (!cr_test_quick()) CR_CHECK(e[1] < e[0] / 3);
    free(pos), free(theta), free(rb), free(R);
    cr_epnet_seq_destroy(s);
    cr_epnet_destroy(m);
}

/* P-Net's phase stops once its validation loss (P-Net through the ratchet on
 * the validation clip's proxy, against that clip's target) has not improved
 * for def.pnet_patience epochs, and ends with the best epoch's weights: the
 * same weights as a run without validation stopped at that epoch (validation
 * draws no random numbers). A P-Net rate of 0.3 makes the loss bounce. */
CR_TEST(epnet, pnet_early_stopping_keeps_the_best_validation_weights) {
    cr_error err = {0};
    char a[64], b[64], path[128];
    snprintf(a, sizeof a, "/tmp/epnet_test_es_a_%d", (int)getpid());
    snprintf(b, sizeof b, "/tmp/epnet_test_es_b_%d", (int)getpid());
    const char *motions[1] = {"squat"};
    cr_epnet_def d = tiny_def();
    d.material.yield_angle = 0.05; /* so RB moves */
    d.frames = 6, d.motions = motions, d.nmotions = 1, d.quiet = 1;
    d.cycles = 1, d.enet_epochs = 1, d.pnet_epochs = CR_TEST_SIZE(12, 6), d.pnet_frames = 1;
    d.pnet_lr = 0.3f, d.pnet_patience = 2, d.pnet_val_motion = "squat";
    d.out_dir = a;
    cr_epnet_train_report r;
    CR_REQUIRE(cr_epnet_train(&d, &r, &err) == CR_OK);
    /* the validation losses of the phase, from progress.jsonl */
    snprintf(path, sizeof path, "%s/progress.jsonl", a);
    FILE *f = fopen(path, "r");
    CR_REQUIRE(f);
    double val[64];
    int n = 0;
    char line[1024];
    while (n < 64 && fgets(line, sizeof line, f)) {
        const char *v = strstr(line, "\"val_l1_rad\": ");
        if (v) val[n++] = atof(v + 14);
    }
    fclose(f);
    int best = 0;
    for (int i = 1; i < n; i++)
        if (val[i] < val[best]) best = i;
    fprintf(stderr, "  %d P-Net epochs of %d, best %d (val %.4g rad), last val %.4g\n", n,
            d.pnet_epochs, best, val[best], val[n - 1]);
    CR_CHECK(n >= 1 && n <= d.pnet_epochs);
    CR_CHECK(n == d.pnet_epochs || n == best + 1 + d.pnet_patience); /* stopped at patience */
    CR_CHECK(isfinite(r.pnet_val_loss) && fabs(r.pnet_val_loss - val[n - 1]) < 1e-5 * val[n - 1]);
    /* the same run without validation, stopped at the best epoch */
    d.pnet_val_motion = NULL, d.pnet_epochs = best + 1, d.out_dir = b;
    CR_REQUIRE(cr_epnet_train(&d, &r, &err) == CR_OK);
    CR_CHECK(isnan(r.pnet_val_loss));
    cr_epnet *ma = NULL, *mb = NULL;
    CR_REQUIRE(cr_epnet_open(a, &ma, &err) == CR_OK && cr_epnet_open(b, &mb, &err) == CR_OK);
    int64_t na = 0, nb = 0;
    const float *pa = cr_nn_params_data(ma->pp, &na), *pb = cr_nn_params_data(mb->pp, &nb);
    CR_CHECK(na == nb && na > 0 && memcmp(pa, pb, sizeof(float) * (size_t)na) == 0);
    cr_epnet_destroy(ma), cr_epnet_destroy(mb);
    char cmd[200];
    snprintf(cmd, sizeof cmd, "rm -rf %s %s", a, b);
    CR_CHECK(system(cmd) == 0);
}

/* P-Net's increment is Eq. 4-5 on a corrected strain: at the start (zero
 * correction) the rollout's RB is the plastic rule on the rollout's own
 * angles, and whatever P-Net learns, |theta - theta_bar - RB| never exceeds
 * the yield plus the correction's bound (0.2 rad) after a frame's update. */
CR_TEST(epnet, pnet_rb_follows_the_rule_and_stays_bounded) {
    cr_error err;
    cr_epnet_def d = tiny_def();
    d.material.yield_angle = 0.05; /* so the squat's angles pass it */
    d.pnet_lr = 0.1f;
    d.pnet_frames = 2;
    cr_epnet *m = NULL;
    CR_REQUIRE(cr_epnet_create(&d, &m, &err) == CR_OK);
    cr_epnet_seq *s = NULL;
    CR_REQUIRE(cr_epnet_seq_create(m, "squat", NULL, 12, CR_TEST_SIZE(20, 4), &s, &err) == CR_OK);
    const int32_t T = cr_epnet_seq_frames(s), H = cr_epnet_hinge_count(m),
                  V = cr_epnet_garment(m)->nv;
    float *pos = malloc(sizeof(float) * 3 * (size_t)T * V),
          *theta = malloc(sizeof(float) * (size_t)T * H);
    float *rb = malloc(sizeof(float) * (size_t)T * H),
          *want = malloc(sizeof(float) * (size_t)T * H);
    CR_REQUIRE(pos && theta && rb && want);
    CR_REQUIRE(cr_epnet_rollout(m, s, 1, pos, theta, rb, &err) == CR_OK);
    const float *bar = cr_epnet_rest_angles(m);
    cr_epnet_plastic_rollout(theta, bar, NULL, T, H, 0.05, 1.0, 50.0, want);
    double maxdiff = 0, maxrb = 0;
    for (int64_t i = 0; i < (int64_t)T * H; i++) {
        maxdiff = fmax(maxdiff, fabs(rb[i] - want[i]));
        maxrb = fmax(maxrb, fabs(rb[i]));
    }
    fprintf(stderr, "  rule: max |RB| %.3g rad, max |RB - Eq. 4-5| %.3g\n", maxrb, maxdiff);
    CR_CHECK(maxrb > 0.01);
    CR_CHECK(maxdiff < 1e-4);
    /* push P-Net hard towards absurd targets (5 rad a frame), then roll out */
    for (int64_t i = 0; i < (int64_t)T * H; i++)
        want[i] = 5.0f * (float)(i / H + 1);
    CR_REQUIRE(cr_epnet_pnet_fit(m, s, pos, theta, want, 10, NULL, &err) == CR_OK);
    CR_REQUIRE(cr_epnet_rollout(m, s, 1, pos, theta, rb, &err) == CR_OK);
    double worst = 0;
    maxrb = 0;
    for (int32_t t = 0; t < T; t++)
        for (int32_t h = 0; h < H; h++) {
            const size_t i = (size_t)t * H + h;
            worst = fmax(worst, fabs(theta[i] - bar[h] - rb[i]));
            maxrb = fmax(maxrb, fabs(rb[i]));
        }
    fprintf(stderr, "  pushed: max |RB| %.3g rad, max |theta - bar - RB| %.3g\n", maxrb, worst);
    CR_CHECK(worst <= 0.05 + 0.2 + 1e-4);
    CR_CHECK(maxrb < 3.5);
    free(pos), free(theta), free(rb), free(want);
    cr_epnet_seq_destroy(s);
    cr_epnet_destroy(m);
}

/* The proxy's ratchet, one frame at a time (cr_epnet_ratchet_step): hand
 * cases of the drive rule and the cut-off, then 400 frames of random strains
 * and increments on 64 hinges against a direct reading of the rule (each
 * frame's drive kept in an array, the last five counted): the same RB bit
 * for bit, and no hinge's |RB| ever shrinks. */
CR_TEST(epnet, ratchet_never_shrinks_and_gates_on_the_drive_rule) {
    cr_epnet_ratchet_def d = cr_epnet_ratchet_default_def();
    cr_error err;
    CR_CHECK_OK(cr_epnet_ratchet_check(&d, &err), &err);
    cr_epnet_ratchet_def bad = d;
    bad.drive_frames = 6;
    CR_CHECK(cr_epnet_ratchet_check(&bad, &err) == CR_ERR_INVALID);
    /* one hinge, strain 0.2 rad, increment 0.01: driven from the first frame, so it
     * moves on the third (3 of the last 5) and not before */
    float rb[1] = {0}, strain[1] = {0.2f}, delta[1] = {0.01f};
    uint32_t hist[1] = {0};
    CR_CHECK(cr_epnet_ratchet_step(&d, strain, delta, 1, hist, rb) == 0 && rb[0] == 0);
    CR_CHECK(cr_epnet_ratchet_step(&d, strain, delta, 1, hist, rb) == 0 && rb[0] == 0);
    CR_CHECK(cr_epnet_ratchet_step(&d, strain, delta, 1, hist, rb) == 1);
    CR_CHECK_NEAR(rb[0], 0.01, 1e-7);
    /* an increment under 0.005 rad is dropped */
    delta[0] = 0.004f;
    CR_CHECK(cr_epnet_ratchet_step(&d, strain, delta, 1, hist, rb) == 0);
    CR_CHECK_NEAR(rb[0], 0.01, 1e-7);
    /* not driven now (strain within 0.05 of RB): nothing, even with 4 of 5 driven */
    strain[0] = 0.03f, delta[0] = 0.1f;
    CR_CHECK(cr_epnet_ratchet_step(&d, strain, delta, 1, hist, rb) == 0);
    /* the ratchet: an increment back towards zero keeps |RB|, one past zero flips
     * the sign at the larger size, and c = 0 keeps RB */
    rb[0] = 0.3f, hist[0] = 0x1f, strain[0] = -0.5f;
    delta[0] = -0.1f;
    cr_epnet_ratchet_step(&d, strain, delta, 1, hist, rb);
    CR_CHECK_NEAR(rb[0], 0.3, 1e-7);
    delta[0] = -0.3f;
    cr_epnet_ratchet_step(&d, strain, delta, 1, hist, rb);
    CR_CHECK_NEAR(rb[0], 0.3, 1e-7);
    delta[0] = -0.7f;
    cr_epnet_ratchet_step(&d, strain, delta, 1, hist, rb);
    CR_CHECK_NEAR(rb[0], -0.4, 1e-6);
    delta[0] = 0.2f;
    cr_epnet_ratchet_step(&d, strain, delta, 1, hist, rb);
    CR_CHECK_NEAR(rb[0], -0.4, 1e-6);
    /* random frames against the rule read directly */
    enum { NH = 64, NT = 400 };
    static uint8_t driven[NT][NH];
    float r[NH] = {0}, want[NH] = {0}, st[NH], dl[NH];
    uint32_t h2[NH] = {0};
    cr_rng g = cr_rng_make(7, 3);
    int moved = 0, gated = 0, shrunk = 0, differ = 0;
    for (int t = 0; t < NT; t++) {
        for (int h = 0; h < NH; h++) {
            st[h] = (float)(0.4 * (2 * cr_rng_uniform(&g) - 1)) * (h % 4 == 0 ? 0.1f : 1.0f);
            dl[h] = (float)(0.05 * (2 * cr_rng_uniform(&g) - 1));
        }
        for (int h = 0; h < NH; h++) {
            driven[t][h] = fabs(remainder((double)st[h] - want[h], 2 * M_PI)) > 0.05;
            int n = 0;
            for (int k = t; k >= 0 && k > t - 5; k--)
                n += driven[k][h];
            const float before = want[h];
            if (driven[t][h] && n >= 3 && fabs(dl[h]) >= 0.005) {
                const double c = (double)want[h] + dl[h];
                const double sg = c > 0 ? 1 : c < 0 ? -1 : (want[h] >= 0 ? 1 : -1);
                want[h] = (float)(sg * fmax(fabs((double)want[h]), fabs(c)));
            } else if (fabs(dl[h]) >= 0.005) {
                gated++;
            }
            moved += want[h] != before;
        }
        float prev[NH];
        memcpy(prev, r, sizeof r);
        cr_epnet_ratchet_step(&d, st, dl, NH, h2, r);
        for (int h = 0; h < NH; h++) {
            shrunk += fabsf(r[h]) < fabsf(prev[h]);
            differ += r[h] != want[h];
        }
    }
    fprintf(stderr, "  ratchet: %d moves, %d increments gated off, %d shrunk, %d differ\n", moved,
            gated, shrunk, differ);
    CR_CHECK(moved > 100 && gated > 100);
    CR_CHECK(shrunk == 0 && differ == 0);
}

/* The proxy inference cannot run away: an untrained model (P-Net is then
 * Eq. 4-5 on the proxy's angles) at a yield of 0.05 rad, a 12-frame squat
 * and a long hold. |RB| stays below the rule's bound, the largest
 * |theta_proxy - theta_bar| + 0.2 rad per hinge (untrained, without P-Net's
 * correction: that strain less the yield), never shrinks, and stops moving
 * once the hold has settled (150 frames; the closed loop's fold path grew
 * without end there). */
CR_TEST(epnet, proxy_inference_cannot_run_away) {
    cr_error err;
    cr_epnet_def d = tiny_def();
    d.material.yield_angle = 0.05;
    cr_epnet *m = NULL;
    CR_REQUIRE(cr_epnet_create(&d, &m, &err) == CR_OK);
    const int hold = CR_TEST_SIZE(150, 30);
    cr_epnet_seq *s = NULL;
    CR_REQUIRE(cr_epnet_seq_create(m, "squat", NULL, 12, hold, &s, &err) == CR_OK);
    const int32_t T = cr_epnet_seq_frames(s), H = cr_epnet_hinge_count(m),
                  V = cr_epnet_garment(m)->nv;
    float *th0 = malloc(sizeof(float) * (size_t)T * H), *th = malloc(sizeof(float) * T * H);
    float *rb = malloc(sizeof(float) * (size_t)T * H), *pos = malloc(sizeof(float) * 3 * T * V);
    CR_REQUIRE(th0 && th && rb && pos);
    cr_epnet_infer_def zero = cr_epnet_infer_default_def();
    zero.mode = CR_EPNET_ZERO_RB;
    CR_REQUIRE(cr_epnet_infer(m, s, &zero, NULL, th0, NULL, &err) == CR_OK);
    cr_epnet_infer_def pd = cr_epnet_infer_default_def();
    CR_CHECK(pd.mode == CR_EPNET_PROXY);
    CR_REQUIRE(cr_epnet_infer(m, s, &pd, pos, th, rb, &err) == CR_OK);
    const float *bar = cr_epnet_rest_angles(m);
    double worst = -INFINITY, tight = -INFINITY, maxrb = 0, late = 0;
    int finite = 1;
    for (int32_t h = 0; h < H; h++) {
        double bound = 0, strain = 0, prev = 0;
        for (int32_t t = 0; t < T; t++) {
            const size_t i = (size_t)t * H + h;
            strain = fmax(strain, fabs((double)th0[i] - bar[h]));
            bound = strain + 0.2;
            worst = fmax(worst, fabs(rb[i]) - bound);
            tight = fmax(tight, fabs(rb[i]) - fmax(strain - 0.05, 0)); /* untrained */
            CR_CHECK(fabs(rb[i]) >= prev);                             /* the ratchet */
            prev = fabs(rb[i]);
            maxrb = fmax(maxrb, fabs(rb[i]));
            finite &= isfinite(th[i]);
            if (t >= 12 + 20) late = fmax(late, fabs(rb[i] - rb[(size_t)(12 + 20) * H + h]));
        }
    }
    fprintf(stderr,
            "  proxy, %d frames: max |RB| %.3g rad, largest |RB| - bound %.3g (- strain + yield "
            "%.3g), RB moved %.3g after frame 32\n",
            T, maxrb, worst, tight, late);
    CR_CHECK(finite);
    CR_CHECK(maxrb > 0.01);
    CR_CHECK(worst <= 1e-5 && tight <= 1e-5);
    CR_CHECK(late < 1e-6);
    /* frame t's E-Net is given RB of frame t-1: frame 0's is the proxy's own */
    CR_CHECK(memcmp(th, th0, sizeof(float) * (size_t)H) == 0);
    free(th0), free(th), free(rb), free(pos);
    cr_epnet_seq_destroy(s);
    cr_epnet_destroy(m);
}

/* The runtime steps a motion frame by frame and gives cr_epnet_infer's
 * positions and RB on the whole sequence (and, without a warm-up, the RB of
 * P-Net run over E-Net's own zero-RB rollout, and that rollout's positions):
 * the proxy (with and without a warm-up) and zero RB, on a squat with a hold, at a yield low enough
 * that RB moves; a reset starts over; the heap does not grow while stepping. */
CR_TEST(epnet, runtime_steps_equal_the_inference) {
    cr_error err = {0};
    cr_epnet_def d = tiny_def();
    d.material.yield_angle = 0.05;
    cr_epnet *m = NULL;
    CR_REQUIRE(cr_epnet_create(&d, &m, &err) == CR_OK);
    const int frames = 12, hold = 4;
    cr_epnet_seq *s = NULL;
    CR_REQUIRE(cr_epnet_seq_create(m, "squat", NULL, frames, hold, &s, &err) == CR_OK);
    cr_motion *mo = NULL;
    cr_motion_resolve_def rd = cr_motion_resolve_default_def();
    rd.clip_frames = frames, rd.max_frames = frames, rd.fps = d.fps;
    CR_REQUIRE(cr_motion_resolve("squat", &rd, &mo, NULL, &err) == CR_OK);
    const int32_t T = cr_epnet_seq_frames(s), H = cr_epnet_hinge_count(m),
                  V = cr_epnet_garment(m)->nv;
    CR_REQUIRE(T == frames + hold && mo->nframes == frames);
    float *pos = malloc(sizeof(float) * 3 * (size_t)T * V), *rb = malloc(sizeof(float) * T * H);
    float *x = malloc(sizeof(float) * 3 * (size_t)V);
    CR_REQUIRE(pos && rb && x);
    /* the passes one after the other, as the proxy inference was first built:
     * E-Net's rollout at RB = 0, then P-Net through the ratchet over it */
    float *ppos = malloc(sizeof(float) * 3 * (size_t)T * V), *pth = malloc(sizeof(float) * T * H);
    float *R = malloc(sizeof(float) * (size_t)T * H);
    CR_REQUIRE(ppos && pth && R);
    CR_REQUIRE(cr_epnet_rollout(m, s, 0, ppos, pth, NULL, &err) == CR_OK);
    cr_epnet_ratchet_def rd0 = cr_epnet_ratchet_default_def();
    CR_REQUIRE(cr_epnet_pnet_proxy_(m, ppos, pth, T, &rd0, R, &err) == CR_OK);
    const cr_epnet_inference modes[3] = {CR_EPNET_PROXY, CR_EPNET_PROXY, CR_EPNET_ZERO_RB};
    const int warmups[3] = {0, 3, 0};
    for (int k = 0; k < 3; k++) {
        cr_epnet_infer_def inf = cr_epnet_infer_default_def();
        inf.mode = modes[k], inf.warmup = warmups[k];
        CR_REQUIRE(cr_epnet_infer(m, s, &inf, pos, NULL, rb, &err) == CR_OK);
        cr_epnet_runtime *rt = NULL;
        CR_CHECK_OK(cr_epnet_runtime_create(m, NULL, &inf, &rt, &err), &err);
        CR_REQUIRE(rt);
        CR_CHECK(cr_epnet_runtime_vertices(rt) == V);
        double dx = 0, drb = 0, maxrb = 0;
        size_t held = 0;
        for (int rep = 0; rep < 2; rep++) {
            cr_epnet_runtime_reset(rt);
            for (int32_t t = 0; t < T; t++) {
                const int32_t f = t < frames ? t : frames - 1;
#ifdef __GLIBC__
                if (rep == 1 && t == 1) held = mallinfo2().uordblks;
#endif
                CR_CHECK_OK(cr_epnet_runtime_step(rt, mo->poses + (size_t)f * CR_NJOINTS * 3,
                                                  mo->trans + 3 * f, x, &err),
                            &err);
                for (int64_t i = 0; i < 3 * (int64_t)V; i++)
                    dx = fmax(dx, fabs(x[i] - pos[(size_t)t * V * 3 + i]));
                const float *r = cr_epnet_runtime_rb(rt);
                for (int32_t h = 0; h < H; h++) {
                    drb = fmax(drb, fabs(r[h] - rb[(size_t)t * H + h]));
                    if (k == 0) drb = fmax(drb, fabs(r[h] - R[(size_t)t * H + h]));
                    maxrb = fmax(maxrb, fabs(r[h]));
                }
                if (k == 2) /* zero RB: E-Net's own rollout */
                    for (int64_t i = 0; i < 3 * (int64_t)V; i++)
                        dx = fmax(dx, fabs(x[i] - ppos[(size_t)t * V * 3 + i]));
            }
        }
        size_t now = held;
#ifdef __GLIBC__
        now = mallinfo2().uordblks;
#endif
        fprintf(stderr,
                "  runtime, %s, warm-up %d: max |x - infer| %.2e m, |RB - infer| %.2e rad (max "
                "|RB| %.3f), heap %zu -> %zu bytes\n",
                modes[k] == CR_EPNET_PROXY ? "proxy" : "zero RB", warmups[k], dx, drb, maxrb, held,
                now);
        CR_CHECK(dx < 1e-5 && drb < 1e-6);
        CR_CHECK(modes[k] == CR_EPNET_ZERO_RB ? maxrb == 0 : maxrb > 0.01);
        CR_CHECK(now == held);
        cr_epnet_runtime_destroy(rt);
    }
    cr_epnet_infer_def cl = cr_epnet_infer_default_def();
    cl.mode = CR_EPNET_CLOSED_LOOP;
    cr_epnet_runtime *rt = NULL;
    CR_CHECK(cr_epnet_runtime_create(m, NULL, &cl, &rt, &err) == CR_ERR_UNSUPPORTED && !rt);
    free(pos), free(rb), free(x), free(ppos), free(pth), free(R);
    cr_motion_destroy(mo);
    cr_epnet_seq_destroy(s);
    cr_epnet_destroy(m);
}

/* Persistence on the simulator side: raise the arms and lower them (4 s at
 * 10 fps), hold 1 s; count the hinges whose angle stays more than 0.3 rad
 * off the rest mesh's after the return. Run without friction, as the
 * E-Net's loss is: with friction the shirt sticks and slips, and where it
 * comes to rest depends on the last bits of the arithmetic (the elastic
 * share measured 13.9-19.9 % across OpenBLAS's kernels, the plastic one
 * 16.2-20.3 %, so neither ordering held). Frictionless, measured on the
 * Prescott, Sandybridge, Haswell and SkylakeX kernels: elastic 3.8-4.0 %,
 * plastic 6.9 %, its rest angles moved past 0.1 rad on 18.2-18.5 %. */
CR_TEST(epnet, reference_keeps_more_creases_than_the_elastic_one) {
    cr_error err;
    cr_epnet_def d = tiny_def();
    d.fps = 10;
    d.material.yield_angle = 0.1;
    cr_epnet *m = NULL;
    CR_REQUIRE(cr_epnet_create(&d, &m, &err) == CR_OK);
    cr_epnet_seq *s = NULL;
    CR_REQUIRE(cr_epnet_seq_create(m, "raise_arms", NULL, 40, 10, &s, &err) == CR_OK);
    const int32_t T = cr_epnet_seq_frames(s), H = cr_epnet_hinge_count(m),
                  V = cr_epnet_garment(m)->nv;
    float *pos = malloc(sizeof(float) * 3 * (size_t)T * V),
          *theta = malloc(sizeof(float) * (size_t)T * H);
    float *rest = malloc(sizeof(float) * (size_t)T * H);
    CR_REQUIRE(pos && theta && rest);
    const float *bar = cr_epnet_rest_angles(m);
    double share[2], moved = 0;
    for (int plastic = 0; plastic < 2; plastic++) {
        CR_REQUIRE(cr_epnet_reference_friction(m, s, plastic, 0.0, pos, rest, &err) == CR_OK);
        cr_epnet_angles(m, pos, T, theta);
        share[plastic] = cr_epnet_fold_share(theta, bar, T - 1, H, 0.3);
        if (plastic)
            for (int32_t h = 0; h < H; h++)
                moved += fabs(rest[(size_t)(T - 1) * H + h]) > 0.1 ? 1.0 / H : 0.0;
    }
    fprintf(stderr,
            "  folded past 0.3 rad after the return: plastic %.3f, elastic %.3f; plastic rest "
            "moved past 0.1 rad: %.3f\n",
            share[1], share[0], moved);
    CR_CHECK(share[1] > 0.05);
    CR_CHECK(share[1] > 1.4 * share[0]);
    CR_CHECK(moved > 0.1);
    free(pos), free(theta), free(rest);
    cr_epnet_seq_destroy(s);
    cr_epnet_destroy(m);
}

/* Mean vertex distance between frames a and b (V,3), m. */
static double mean_distance(const float *a, const float *b, int32_t V) {
    double d = 0;
    for (int32_t v = 0; v < V; v++) {
        const float *p = a + 3 * v, *q = b + 3 * v;
        d += sqrt((p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) +
                  (p[2] - q[2]) * (p[2] - q[2])) /
             V;
    }
    return d;
}

/* The loss has no friction, so a skirt's waistband must be pinned: without
 * pins the frictionless reference's skirt falls off the body, with the top
 * 1 cm pinned to the skinning it stays on (the last frame's distance to the
 * fresh E-Net, which is the skinned skirt within millimetres); the pinning
 * term is zero without pins and positive (the fresh E-Net is not exactly the
 * skinning) with. */
CR_TEST(epnet, pinned_waistband_holds_the_skirt_up) {
    cr_error err;
    double drop[2], pin_loss[2];
    for (int pinned = 0; pinned < 2; pinned++) {
        cr_epnet_def d = tiny_def();
        d.garment = "skirt";
        d.fps = 10;
        d.pin_top = pinned ? 0.01 : 0;
        cr_epnet *m = NULL;
        CR_REQUIRE(cr_epnet_create(&d, &m, &err) == CR_OK);
        cr_epnet_seq *s = NULL;
        CR_REQUIRE(cr_epnet_seq_create(m, "squat", NULL, 10, 0, &s, &err) == CR_OK);
        const int32_t T = cr_epnet_seq_frames(s), V = cr_epnet_garment(m)->nv;
        float *pos = malloc(sizeof(float) * 3 * (size_t)T * V),
              *net = malloc(sizeof(float) * 3 * (size_t)T * V);
        CR_REQUIRE(pos && net);
        CR_REQUIRE(cr_epnet_reference_friction(m, s, 1, 0.0, pos, NULL, &err) == CR_OK);
        CR_REQUIRE(cr_epnet_rollout(m, s, 0, net, NULL, NULL, &err) == CR_OK);
        const size_t last = (size_t)(T - 1) * V * 3;
        drop[pinned] = mean_distance(pos + last, net + last, V);
        cr_epnet_losses l;
        CR_REQUIRE(cr_epnet_enet_step(m, s, NULL, 0, &l, &err) == CR_OK);
        pin_loss[pinned] = l.term[6];
        free(pos), free(net);
        cr_epnet_seq_destroy(s);
        cr_epnet_destroy(m);
    }
    fprintf(stderr,
            "  skirt after 1 s of squat, mean distance to the skinned one: unpinned %.3f m, "
            "pinned %.3f m\n",
            drop[0], drop[1]);
    CR_CHECK(drop[0] > 0.3);
    CR_CHECK(drop[1] < 0.15 && drop[1] < 0.1 * drop[0]); /* measured 0.089 vs 2.76 */
    CR_CHECK(pin_loss[0] == 0);
    CR_CHECK(pin_loss[1] > 0);
}

static int files_equal(const char *a, const char *b) {
    FILE *fa = fopen(a, "rb"), *fb = fopen(b, "rb");
    int eq = fa && fb;
    while (eq) {
        int ca = fgetc(fa), cb = fgetc(fb);
        if (ca != cb) eq = 0;
        if (ca == EOF) break;
    }
    if (fa) fclose(fa);
    if (fb) fclose(fb);
    return eq;
}

CR_TEST(epnet, resume_is_bit_exact) {
    cr_error err;
    char a[64], b[64];
    snprintf(a, sizeof a, "/tmp/epnet_test_a_%d", (int)getpid());
    snprintf(b, sizeof b, "/tmp/epnet_test_b_%d", (int)getpid());
    const char *motions[2] = {"squat", "twist"};
    cr_epnet_def d = tiny_def();
    d.frames = CR_TEST_SIZE(12, 6);
    d.pnet_frames = 2; /* the frames drawn come from the resumed generator all the same */
    d.motions = motions, d.nmotions = 2;
    d.cycles = 2, d.enet_epochs = 2, d.pnet_epochs = 2, d.quiet = 1;
    d.out_dir = a;
    cr_epnet_train_report r;
    CR_REQUIRE(cr_epnet_train(&d, &r, &err) == CR_OK);
    CR_CHECK(r.cycles_done == 2);
    /* b: stop after the first cycle, then resume to two */
    d.out_dir = b, d.cycles = 1;
    CR_REQUIRE(cr_epnet_train(&d, &r, &err) == CR_OK);
    d.cycles = 2, d.resume = 1;
    CR_REQUIRE(cr_epnet_train(&d, &r, &err) == CR_OK);
    char pa[128], pb[128];
    snprintf(pa, sizeof pa, "%s/enet.safetensors", a),
        snprintf(pb, sizeof pb, "%s/enet.safetensors", b);
    CR_CHECK(files_equal(pa, pb));
    snprintf(pa, sizeof pa, "%s/pnet.safetensors", a),
        snprintf(pb, sizeof pb, "%s/pnet.safetensors", b);
    CR_CHECK(files_equal(pa, pb));
    snprintf(pa, sizeof pa, "%s/rb_train.npy", a), snprintf(pb, sizeof pb, "%s/rb_train.npy", b);
    CR_CHECK(files_equal(pa, pb));
    char cmd[200];
    snprintf(cmd, sizeof cmd, "rm -rf %s %s", a, b);
    CR_CHECK(system(cmd) == 0);
}

static void copy_file(const char *from, const char *to) {
    FILE *a = fopen(from, "rb"), *b = fopen(to, "wb");
    CR_REQUIRE(a && b);
    for (int c; (c = fgetc(a)) != EOF;)
        fputc(c, b);
    fclose(a), fclose(b);
}

/* The checkpoint (model.json, both networks, the RB) is committed as one set:
 * a run refused before training, or killed before a set's commit, leaves the
 * folder as it was; a kill after the commit is finished at the next load; a
 * resume with other options, or a model.json with a misspelt key, is refused
 * naming the key. */
CR_TEST(epnet, checkpoint_set_commits_whole_and_resume_keeps_the_model) {
    cr_error err = {0};
    char dir[64], path[128], next[140];
    snprintf(dir, sizeof dir, "/tmp/epnet_test_set_%d", (int)getpid());
    const char *motions[1] = {"squat"};
    cr_epnet_def d = tiny_def();
    d.frames = 6, d.motions = motions, d.nmotions = 1;
    d.cycles = 1, d.enet_epochs = 1, d.pnet_epochs = 1, d.pnet_frames = 2, d.quiet = 1;
    d.out_dir = dir;
    CR_REQUIRE(cr_epnet_train(&d, NULL, &err) == CR_OK);
    snprintf(path, sizeof path, "%s/model.json", dir);
    char keep[140];
    snprintf(keep, sizeof keep, "%s/model.keep", dir);
    copy_file(path, keep);
    /* a fresh run refused on its motion leaves model.json as it was */
    const char *bad[1] = {"no_such_clip"};
    cr_epnet_def e = d;
    e.garment_vertices = 600, e.motions = bad;
    CR_CHECK(cr_epnet_train(&e, NULL, &err) != CR_OK);
    CR_CHECK(files_equal(path, keep));
    /* a resume with another yield angle is refused, naming it */
    e = d;
    e.material.yield_angle = 0.3, e.resume = 1;
    CR_CHECK(cr_epnet_train(&e, NULL, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "yield") != NULL);
    CR_CHECK(files_equal(path, keep));
    /* killed before a commit: the half-written set is dropped at the next load */
    snprintf(next, sizeof next, "%s/enet.safetensors.next", dir);
    FILE *f = fopen(next, "wb");
    CR_REQUIRE(f);
    fputs("half a checkpoint", f), fclose(f);
    cr_epnet *m = NULL;
    CR_CHECK_OK(cr_epnet_open(dir, &m, &err), &err);
    cr_epnet_destroy(m), m = NULL;
    CR_CHECK(access(next, F_OK) != 0);
    /* killed after the commit: the renames are finished at the next load */
    snprintf(path, sizeof path, "%s/pnet.safetensors", dir);
    snprintf(next, sizeof next, "%s/pnet.safetensors.next", dir);
    copy_file(path, next);
    snprintf(path, sizeof path, "%s/commit.json", dir);
    f = fopen(path, "wb");
    CR_REQUIRE(f);
    fputs("{\"position\": 0}\n", f), fclose(f);
    CR_CHECK_OK(cr_epnet_open(dir, &m, &err), &err);
    cr_epnet_destroy(m), m = NULL;
    CR_CHECK(access(next, F_OK) != 0 && access(path, F_OK) != 0);
    /* a misspelt key in model.json */
    snprintf(path, sizeof path, "%s/model.json", dir);
    f = fopen(path, "wb");
    CR_REQUIRE(f);
    fputs("{\"garment\": \"tshirt\", \"garment_vertices\": 500, \"yeild\": 0.3}\n", f), fclose(f);
    CR_CHECK(cr_epnet_open(dir, &m, &err) == CR_ERR_PARSE);
    CR_CHECK(strstr(err.msg, "unknown key 'yeild'") != NULL && strstr(err.msg, "model.json"));
    char cmd[100];
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    CR_CHECK(system(cmd) == 0);
}

/* P-Net replayed on given positions: at initialisation (zero decoder) it is
 * the plastic rule on their angles; a trained P-Net opened on its own garment
 * through cr_epnet_open_pnet replays bit for bit as the whole model does, and
 * on another garment (another hinge graph) it runs, moving RB only where the
 * angles pass the yield and never past the rule's bound. */
CR_TEST(epnet, pnet_replay_is_the_rule_and_runs_on_another_garment) {
    cr_error err = {0};
    char dir[64];
    snprintf(dir, sizeof dir, "/tmp/epnet_test_replay_%d", (int)getpid());
    const char *motions[1] = {"squat"};
    cr_epnet_def d = tiny_def();
    d.material.yield_angle = 0.05; /* so the squat's angles pass it */
    d.frames = 6, d.motions = motions, d.nmotions = 1;
    d.cycles = 1, d.enet_epochs = 1, d.pnet_epochs = 2, d.pnet_frames = 2, d.quiet = 1;
    d.pnet_lr = 0.1f;
    /* fresh: the replay is Eq. 4-5 on the positions' angles */
    cr_epnet *m = NULL;
    CR_REQUIRE(cr_epnet_create(&d, &m, &err) == CR_OK);
    cr_epnet_seq *s = NULL;
    CR_REQUIRE(cr_epnet_seq_create(m, "squat", NULL, 12, 4, &s, &err) == CR_OK);
    const int32_t T = cr_epnet_seq_frames(s), H = cr_epnet_hinge_count(m),
                  V = cr_epnet_garment(m)->nv;
    float *pos = malloc(sizeof(float) * 3 * (size_t)T * V), *th = malloc(sizeof(float) * T * H);
    float *rb = malloc(sizeof(float) * (size_t)T * H), *want = malloc(sizeof(float) * T * H);
    CR_REQUIRE(pos && th && rb && want);
    CR_REQUIRE(cr_epnet_rollout(m, s, 0, pos, NULL, NULL, &err) == CR_OK);
    CR_CHECK_OK(cr_epnet_pnet_replay(m, pos, T, rb, &err), &err);
    cr_epnet_angles(m, pos, T, th);
    cr_epnet_plastic_rollout(th, cr_epnet_rest_angles(m), NULL, T, H, 0.05, 1.0, 50.0, want);
    double diff = 0, most = 0;
    for (int64_t i = 0; i < (int64_t)T * H; i++)
        diff = fmax(diff, fabs(rb[i] - want[i])), most = fmax(most, fabs(want[i]));
    fprintf(stderr, "  fresh P-Net against the rule: max |RB| %.3g, max diff %.3g rad\n", most,
            diff);
    CR_CHECK(most > 0.01);
    CR_CHECK(diff < 1e-4);
    cr_epnet_destroy(m), m = NULL;
    /* trained, then opened whole and as a P-Net on the same garment */
    d.out_dir = dir;
    CR_REQUIRE(cr_epnet_train(&d, NULL, &err) == CR_OK);
    cr_epnet *whole = NULL, *alone = NULL;
    CR_REQUIRE(cr_epnet_open(dir, &whole, &err) == CR_OK);
    CR_CHECK_OK(cr_epnet_open_pnet(dir, "tshirt", 0, &alone, &err), &err);
    CR_CHECK_OK(cr_epnet_pnet_replay(whole, pos, T, rb, &err), &err);
    CR_CHECK_OK(cr_epnet_pnet_replay(alone, pos, T, want, &err), &err);
    CR_CHECK(memcmp(rb, want, sizeof(float) * (size_t)T * H) == 0);
    cr_epnet_destroy(whole), cr_epnet_destroy(alone);
    /* on a dress: another mesh, another hinge graph */
    cr_epnet *dress = NULL;
    CR_CHECK_OK(cr_epnet_open_pnet(dir, "dress", 0, &dress, &err), &err);
    if (dress) {
        cr_epnet_seq *sd = NULL;
        CR_REQUIRE(cr_epnet_seq_create(dress, "squat", NULL, 12, 4, &sd, &err) == CR_OK);
        const int32_t Hd = cr_epnet_hinge_count(dress), Vd = cr_epnet_garment(dress)->nv;
        CR_CHECK(Hd != H);
        float *pd = malloc(sizeof(float) * 3 * (size_t)T * Vd),
              *rd = malloc(sizeof(float) * (size_t)T * Hd),
              *td = malloc(sizeof(float) * (size_t)T * Hd);
        CR_REQUIRE(pd && rd && td);
        CR_REQUIRE(cr_epnet_rollout(dress, sd, 0, pd, td, NULL, &err) == CR_OK);
        CR_CHECK_OK(cr_epnet_pnet_replay(dress, pd, T, rd, &err), &err);
        const float *bar = cr_epnet_rest_angles(dress);
        double moved = 0, worst = 0;
        for (int32_t t = 0; t < T; t++)
            for (int32_t h = 0; h < Hd; h++) {
                const size_t i = (size_t)t * Hd + h;
                CR_CHECK(isfinite(rd[i]));
                moved = fmax(moved, fabs(rd[i]));
                worst = fmax(worst, fabs(td[i] - bar[h] - rd[i]));
            }
        fprintf(stderr, "  dress: %d hinges, max |RB| %.3g, max |theta - bar - RB| %.3g rad\n", Hd,
                moved, worst);
        CR_CHECK(moved > 0.01);
        CR_CHECK(worst <= 0.05 + 0.2 + 1e-4);
        free(pd), free(rd), free(td);
        cr_epnet_seq_destroy(sd);
        cr_epnet_destroy(dress);
    }
    /* a baseline has no P-Net to lend */
    char path[128];
    snprintf(path, sizeof path, "%s/model.json", dir);
    char *txt = NULL;
    CR_REQUIRE(cr_file_read_all(path, &txt, NULL, &err) == CR_OK);
    char *at = strstr(txt, "\"baseline\": 0");
    CR_REQUIRE(at);
    at[12] = '1';
    FILE *f = fopen(path, "wb");
    CR_REQUIRE(f);
    fputs(txt, f), fclose(f), free(txt);
    CR_CHECK(cr_epnet_open_pnet(dir, "dress", 0, &dress, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "baseline") != NULL);
    free(pos), free(th), free(rb), free(want);
    cr_epnet_seq_destroy(s);
    char cmd[100];
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    CR_CHECK(system(cmd) == 0);
}
