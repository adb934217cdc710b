/* test_gdsr.c: gdsr's features (Eq. 2-5), the decoder's rotation
 * equivariance, the hyper-net's WIRE field, training lowering its loss and
 * bit-exact resume, the untrained model being upsampling, the regularisers
 * (values against crease eval, gradients against finite differences). */
#include "crease/eval.h"
#include "crease/gdsr.h"
#include "crease/losses.h"
#include "crease/mesh_io.h"
#include "crease/nn_optim.h"
#include "crease/primitives.h"
#include "gdsr_fixture.h"
#include "methods/gdsr/gdsr_internal.h"
#include "nn_gradcheck.h"
#include "test.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Two triangles (0,1,2), (0,2,3) on a unit square in the XZ plane. */
static cr_mesh *quad(void) {
    cr_mesh *m = NULL;
    cr_error err = {0};
    if (cr_mesh_create(4, 2, 0, &m, &err) != CR_OK) return NULL;
    const float p[12] = {0, 0, 0, 1, 0, 0, 1, 0, 1, 0, 0, 1};
    const int32_t t[6] = {0, 2, 1, 0, 3, 2};
    memcpy(m->pos, p, sizeof p);
    memcpy(m->tri, t, sizeof t);
    return m;
}

CR_TEST(gdsr, graph_and_features_on_a_hand_made_quad) {
    cr_error err = {0};
    cr_mesh *m = quad();
    CR_REQUIRE(m);
    cr_gdsr_graph g;
    CR_CHECK_OK(cr_gdsr_graph_build(m, &g, &err), &err);
    CR_CHECK(g.ne[0] == 10); /* 5 edges, both ways */
    CR_CHECK(g.ne[1] == 2);  /* 1 and 3 are two apart */
    CR_CHECK((g.rcv[1][0] == 1 && g.snd[1][0] == 3) || (g.rcv[1][0] == 3 && g.snd[1][0] == 1));
    float c[12], c1[12], c2[12], bp[12], dprev[12];
    for (int i = 0; i < 12; i++) {
        c2[i] = m->pos[i];
        c1[i] = m->pos[i] + (i % 3 == 0 ? 0.01f : 0.0f);            /* +1 cm in x */
        c[i] = m->pos[i] + (i % 3 == 0 ? 0.03f : 0.0f);             /* +2 cm more */
        bp[i] = c[i] + (i % 3 == 1 ? (i < 3 ? -0.01f : -0.5f) : 0); /* vertex 0 near */
        dprev[i] = i == 5 ? 0.002f : 0.0f;
    }
    cr_gdsr_frame_in in = {.c = c, .c_prev = c1, .c_prev2 = c2, .d_prev = dprev, .body_point = bp};
    float node[4 * CR_GDSR_NODE_FEATURES], e0[10 * CR_GDSR_EDGE_FEATURES],
        e1[2 * CR_GDSR_EDGE_FEATURES];
    cr_gdsr_features(m, &g, &in, 0.015f, node, e0, e1);
    const float *n0 = node, *n1 = node + CR_GDSR_NODE_FEATURES;
    CR_CHECK_NEAR(n0[1], 1.0f, 1e-5);             /* normal +Y (triangles wound for +Y) */
    CR_CHECK_NEAR(n0[3], 2.0f, 1e-4);             /* velocity 2 cm per frame */
    CR_CHECK_NEAR(n0[6], 1.0f, 1e-4);             /* acceleration 1 cm per frame^2 */
    CR_CHECK_NEAR(n0[10], -0.01f / 0.015f, 1e-4); /* body vector / sigma_b */
    CR_CHECK_NEAR(n0[12], 0.01f / 0.015f, 1e-4);  /* its length */
    CR_CHECK_NEAR(n1[10], 0.0f, 0);               /* 0.5 m away: no interaction */
    CR_CHECK_NEAR(n1[12], 0.0f, 0);
    CR_CHECK_NEAR(n1[15], 0.2f, 1e-5); /* d_{t-1} of vertex 1 along z, cm */
    CR_CHECK_NEAR(n0[16], 1.0f, 1e-4); /* no C^ yet: C_{t-1} - C_{t-2}, 1 cm */
    for (int64_t e = 0; e < g.ne[0]; e++) {
        const float *f = e0 + CR_GDSR_EDGE_FEATURES * e;
        int32_t i = g.rcv[0][e], j = g.snd[0][e];
        float dx = m->pos[3 * j] - m->pos[3 * i], dz = m->pos[3 * j + 2] - m->pos[3 * i + 2];
        CR_CHECK_NEAR(f[3], 10.0f * sqrtf(dx * dx + dz * dz), 1e-4);
        CR_CHECK_NEAR(f[7], f[3], 1e-4); /* rigid translation: same current length */
    }
    CR_CHECK_NEAR(e1[3], 10.0f * sqrtf(2.0f), 1e-4);
    cr_gdsr_graph_free(&g);
    cr_mesh_destroy(m);
}

CR_TEST(gdsr, decoder_is_rotation_equivariant) {
    cr_error err = {0};
    cr_mesh *m = NULL;
    CR_REQUIRE(cr_prim_plane(4, 4, 1, 1, &m, &err) == CR_OK);
    cr_gdsr_model_def def = gdsr_tiny_def();
    cr_gdsr_model *mo = NULL;
    CR_REQUIRE(cr_gdsr_model_create(&def, &mo, &err) == CR_OK);
    cr_rng rng = cr_rng_make(3, 0);
    /* the last layer starts at zero; give it weights */
    cr_nn_fill_uniform(mo->dec->layer[1].weight, &rng, -0.5f, 0.5f);
    cr_nn_fill_uniform(mo->dec->layer[1].bias, &rng, -0.5f, 0.5f);
    cr_nn_ctx *ctx = NULL;
    cr_nn_ctx_def cd = cr_nn_ctx_default_def();
    CR_REQUIRE(cr_nn_ctx_create(&cd, &ctx, &err) == CR_OK);
    int V = m->nv;
    float *c = malloc((size_t)V * 3 * sizeof(float)), *cr = malloc((size_t)V * 3 * sizeof(float));
    float *fe = malloc((size_t)V * 8 * sizeof(float)), *d0 = malloc((size_t)V * 3 * sizeof(float));
    for (int i = 0; i < V; i++) {
        c[3 * i] = m->pos[3 * i];
        c[3 * i + 1] = 0.1f * sinf(5.0f * m->pos[3 * i] + 3.0f * m->pos[3 * i + 2]);
        c[3 * i + 2] = m->pos[3 * i + 2];
    }
    for (int i = 0; i < V * 8; i++)
        fe[i] = 2.0f * cr_rng_uniformf(&rng) - 1.0f;
    /* rotation by 0.7 rad about (1,2,3)/|.| */
    float ax[3] = {1, 2, 3}, l = sqrtf(14.0f), a = 0.7f, R[9];
    for (int k = 0; k < 3; k++)
        ax[k] /= l;
    float cs = cosf(a), sn = sinf(a);
    for (int r = 0; r < 3; r++)
        for (int q = 0; q < 3; q++)
            R[3 * r + q] = (r == q ? cs : 0) + (1 - cs) * ax[r] * ax[q];
    R[1] -= sn * ax[2], R[2] += sn * ax[1], R[3] += sn * ax[2];
    R[5] -= sn * ax[0], R[6] -= sn * ax[1], R[7] += sn * ax[0];
    for (int i = 0; i < V; i++)
        for (int r = 0; r < 3; r++)
            cr[3 * i + r] = R[3 * r] * c[3 * i] + R[3 * r + 1] * c[3 * i + 1] +
                            R[3 * r + 2] * c[3 * i + 2] + (r == 0 ? 0.3f : 0.0f);
    cr_tensor *f = cr_nn_from(ctx, 2, (int64_t[]){V, 8}, fe);
    cr_tensor *d = cr_gdsr_decode(ctx, mo, m, f, c);
    CR_REQUIRE(d);
    memcpy(d0, d->data, (size_t)V * 3 * sizeof(float));
    cr_tensor *dr = cr_gdsr_decode(ctx, mo, m, f, cr);
    CR_REQUIRE(dr);
    double maxd = 0, maxerr = 0;
    for (int i = 0; i < V; i++)
        for (int r = 0; r < 3; r++) {
            double want =
                R[3 * r] * d0[3 * i] + R[3 * r + 1] * d0[3 * i + 1] + R[3 * r + 2] * d0[3 * i + 2];
            maxerr = fmax(maxerr, fabs(want - dr->data[3 * i + r]));
            maxd = fmax(maxd, fabs(want));
        }
    CR_CHECK(maxd > 0.01);                 /* the output is not trivially zero */
    CR_CHECK(maxerr < 1e-5 * maxd + 1e-6); /* and rotates with the input */
    free(c);
    free(cr);
    free(fe);
    free(d0);
    cr_nn_ctx_destroy(ctx);
    cr_gdsr_model_destroy(mo);
    cr_mesh_destroy(m);
}

CR_TEST(gdsr, hyper_wire_field_reproduces_a_per_triangle_function) {
    cr_error err = {0};
    cr_mesh *m = NULL;
    CR_REQUIRE(cr_prim_plane(3, 3, 1, 1, &m, &err) == CR_OK); /* 8 triangles */
    cr_gdsr_model_def def = gdsr_tiny_def();
    def.wire_layers = 3;
    cr_gdsr_model *mo = NULL;
    CR_REQUIRE(cr_gdsr_model_create(&def, &mo, &err) == CR_OK);
    cr_nn_ctx *ctx = NULL;
    cr_nn_ctx_def cd = cr_nn_ctx_default_def();
    CR_REQUIRE(cr_nn_ctx_create(&cd, &ctx, &err) == CR_OK);
    /* per-vertex features fixed; 6x6 barycentric samples per triangle */
    int F = m->nf, S = 21, M = F * S;
    float *h = malloc((size_t)m->nv * 8 * sizeof(float)), *bary = malloc((size_t)M * 3 * 4);
    float *target = malloc((size_t)M * 3 * 4);
    int32_t *face = malloc((size_t)M * 4);
    cr_rng rng = cr_rng_make(5, 0);
    for (int i = 0; i < m->nv * 8; i++)
        h[i] = 2.0f * cr_rng_uniformf(&rng) - 1.0f;
    int k = 0;
    for (int f = 0; f < F; f++)
        for (int a = 0; a <= 5; a++)
            for (int b = 0; a + b <= 5; b++, k++) {
                float u = a / 5.0f, v = b / 5.0f;
                face[k] = f;
                bary[3 * k] = 1 - u - v, bary[3 * k + 1] = u, bary[3 * k + 2] = v;
                /* a different smooth function per triangle, in cm-ish units */
                float s = (float)(f + 1) / F;
                target[3 * k] = 0.5f * s * sinf(3.0f * u) - 0.3f * v;
                target[3 * k + 1] = 0.4f * (u * v) * (1 - s);
                target[3 * k + 2] = 0.2f * s * cosf(2.0f * v);
            }
    cr_optim_def od = cr_optim_default_def(CR_OPTIM_ADAM);
    od.lr.base = 3e-3f;
    cr_optim *opt = NULL;
    CR_REQUIRE(cr_optim_create(&od, mo->params, &opt, &err) == CR_OK);
    double first = 0, last = 0, var = 0;
    for (int i = 0; i < M * 3; i++)
        var += target[i] * target[i];
    var /= M * 3;
    for (int it = 0; it < 300; it++) {
        cr_nn_ctx_reset(ctx);
        cr_tensor *ht = cr_nn_from(ctx, 2, (int64_t[]){m->nv, 8}, h);
        cr_tensor *y = cr_gdsr_hyper(ctx, mo, m, ht, M, face, bary);
        cr_tensor *t = cr_nn_from(ctx, 2, (int64_t[]){M, 3}, target);
        cr_tensor *loss = cr_nn_mean(ctx, cr_nn_square(ctx, cr_nn_sub(ctx, y, t)));
        cr_nn_params_zero_grad(mo->params);
        CR_REQUIRE(cr_nn_backward(ctx, loss, &err) == CR_OK);
        CR_REQUIRE(cr_optim_step(opt, &err) == CR_OK);
        if (it == 0) first = loss->data[0];
        last = loss->data[0];
    }
    CR_CHECK(first > 0.5 * var); /* starts near zero output */
    CR_CHECK(last < 0.05 * var); /* ends within 5 % of the target's energy */
    free(h);
    free(bary);
    free(target);
    free(face);
    cr_optim_destroy(opt);
    cr_nn_ctx_destroy(ctx);
    cr_gdsr_model_destroy(mo);
    cr_mesh_destroy(m);
}

CR_TEST(gdsr, tiny_model_lowers_its_loss) {
    cr_gdsr_data d;
    CR_REQUIRE(gdsr_tiny_data(&d));
    cr_error err = {0};
    cr_gdsr_train_def def = cr_gdsr_train_default_def();
    def.model = gdsr_tiny_def();
    def.model.out_scale = 1.0f; /* 48 steps: the unscaled outputs' fast pace */
    def.epochs = 8;
    def.lr = 3e-3f;
    def.noise_m = 0.0005f;
    def.quiet = 1;
    /* the paper's coarse terms (off by default), so they are met in training */
    def.experimental.w_coarse_normal = 0.01f, def.experimental.w_coarse_bend = 0.001f;
    def.experimental.w_coarse_strain = 0.01f, def.experimental.w_coarse_smooth = 100.0f;
    char dir[1024];
    snprintf(dir, sizeof dir, "%s/gdsr_tiny", cr_test_tmpdir());
    def.out_dir = dir;
    cr_gdsr_train_result r;
    CR_CHECK_OK(cr_gdsr_train(&def, &d, &r, &err), &err);
    CR_CHECK(r.epochs == 8);
    CR_CHECK(r.last_loss < 0.7 * r.first_loss);
    CR_CHECK(
        r.last_term[CR_GDSR_TERM_COARSE_NORMAL] > 0 && r.last_term[CR_GDSR_TERM_COARSE_BEND] > 0 &&
        r.last_term[CR_GDSR_TERM_COARSE_STRAIN] > 0 && r.last_term[CR_GDSR_TERM_COARSE_SMOOTH] > 0);
    /* the model file loads and rolls out; outside the body after handling */
    char path[1100];
    snprintf(path, sizeof path, "%s/model.safetensors", dir);
    cr_gdsr_model *m = NULL;
    CR_CHECK_OK(cr_gdsr_model_load(path, &m, &err), &err);
    if (m) {
        cr_gdsr_rollout_result ro;
        CR_CHECK_OK(cr_gdsr_rollout(m, &d, 0, 0.002f, CR_GDSR_RELAX_DEFAULT, 0, &ro, &err), &err);
        CR_CHECK(ro.inside_after == 0);
        cr_gdsr_rollout_free(&ro);
    }
    cr_gdsr_model_destroy(m);
    cr_gdsr_data_free(&d);
}

static int files_equal(const char *a, const char *b) {
    char *x = NULL, *y = NULL;
    size_t nx = 0, ny = 0;
    cr_error err = {0};
    int eq = cr_file_read_all(a, &x, &nx, &err) == CR_OK &&
             cr_file_read_all(b, &y, &ny, &err) == CR_OK && nx == ny && memcmp(x, y, nx) == 0;
    free(x);
    free(y);
    return eq;
}

CR_TEST(gdsr, resume_is_bit_exact) {
    cr_gdsr_data d;
    CR_REQUIRE(gdsr_tiny_data(&d));
    cr_error err = {0};
    cr_gdsr_train_def def = cr_gdsr_train_default_def();
    def.model = gdsr_tiny_def();
    def.lr = 3e-3f;
    def.quiet = 1;
    def.checkpoint_every = 1;
    char a[1024], b[1024], pa[1100], pb[1100];
    snprintf(a, sizeof a, "%s/gdsr_resume_a", cr_test_tmpdir());
    snprintf(b, sizeof b, "%s/gdsr_resume_b", cr_test_tmpdir());
    cr_gdsr_train_result r;
    def.epochs = 4;
    def.out_dir = a;
    CR_CHECK_OK(cr_gdsr_train(&def, &d, &r, &err), &err);
    def.out_dir = b;
    def.epochs = 2;
    CR_CHECK_OK(cr_gdsr_train(&def, &d, &r, &err), &err);
    def.epochs = 4;
    def.resume = 1;
    CR_CHECK_OK(cr_gdsr_train(&def, &d, &r, &err), &err);
    CR_CHECK(r.resumed_from == 2 && r.epochs == 4);
    snprintf(pa, sizeof pa, "%s/model.safetensors", a);
    snprintf(pb, sizeof pb, "%s/model.safetensors", b);
    CR_CHECK(files_equal(pa, pb));
    cr_gdsr_data_free(&d);
}

CR_TEST(gdsr, untrained_model_is_upsampling) {
    cr_gdsr_data d;
    CR_REQUIRE(gdsr_tiny_data(&d));
    cr_error err = {0};
    cr_gdsr_model *m = NULL;
    cr_gdsr_model_def def = gdsr_tiny_def();
    CR_CHECK_OK(cr_gdsr_model_create(&def, &m, &err), &err);
    cr_gdsr_rollout_result r;
    CR_CHECK_OK(cr_gdsr_rollout(m, &d, 0, 0.002f, CR_GDSR_RELAX_DEFAULT, 0, &r, &err), &err);
    double worst = 0;
    for (int64_t i = 0; i < (int64_t)r.nframes * r.nv_high * 3; i++)
        worst = fmax(worst, fabs((double)r.gdsr_raw[i] - r.upsampled[i]));
    CR_CHECK(worst < 1e-6); /* E and A's last layers start at zero */
    cr_gdsr_rollout_free(&r);
    cr_gdsr_model_destroy(m);
    cr_gdsr_data_free(&d);
}

/* The 9x9 sheet of gdsr_tiny_data, deformed: stretched, sheared and waved. */
/* gdsr_tiny_data and the regularisers on its high mesh (on_low: its low one). */
static int tiny_reg(cr_gdsr_data *d, int on_low, gdsr_reg *reg) {
    cr_error err = {0};
    if (!gdsr_tiny_data(d)) return 0;
    if (cr_gdsr_reg_create(on_low ? d->low : d->high, reg, &err) == CR_OK) return 1;
    cr_gdsr_data_free(d);
    return 0;
}

static void deform(const cr_mesh *hi, float *x, float amp) {
    for (int32_t i = 0; i < hi->nv; i++) {
        const float *p = hi->pos + 3 * i;
        x[3 * i] = 1.1f * p[0] + 0.05f * p[2];
        x[3 * i + 1] = p[1] + amp * sinf(9 * p[0]) * cosf(7 * p[2]);
        x[3 * i + 2] = 0.95f * p[2];
    }
}

CR_TEST(gdsr, regularisers_are_eval_strains_and_vanish_at_the_reference) {
    cr_gdsr_data d;
    gdsr_reg reg;
    CR_REQUIRE(tiny_reg(&d, 0, &reg));
    cr_error err = {0};
    const cr_mesh *hi = d.high;
    float *x = malloc((size_t)hi->nv * 3 * sizeof(float));
    float *ref = malloc((size_t)hi->nv * 3 * sizeof(float));
    deform(hi, x, 0.01f);
    /* stretch and shear against crease eval's e_u + e_v and e_uv (equal
     * triangle areas: the area-weighted mean is the plain one) */
    cr_eval_def ed = cr_eval_default_def();
    ed.ssim_side = 16;
    cr_eval_input in = {.garment = hi, .nframes = 1, .pred = x, .ref = x};
    cr_eval_result er = {0};
    CR_CHECK_OK(cr_eval_run(&ed, &in, &er, &err), &err);
    cr_nn_ctx_def cd = cr_nn_ctx_default_def();
    cd.arena_bytes = (size_t)16 << 20;
    cr_nn_ctx *ctx = NULL;
    CR_REQUIRE(cr_nn_ctx_create(&cd, &ctx, &err) == CR_OK);
    cr_tensor *t[4];
    cr_tensor *X = cr_nn_from(ctx, 2, (int64_t[]){hi->nv, 3}, x);
    cr_gdsr_reg_terms(ctx, &reg, X, x, &t[0], &t[1], &t[2], &t[3]);
    double eu = er.summary[CR_EVAL_E_U].mean + er.summary[CR_EVAL_E_V].mean;
    double euv = er.summary[CR_EVAL_E_UV].mean;
    CR_CHECK(eu > 1e-3 && euv > 1e-4);
    CR_CHECK_NEAR(t[0]->data[0], eu, 1e-3 * eu);
    CR_CHECK_NEAR(t[1]->data[0], euv, 1e-3 * euv);
    CR_CHECK(t[2]->data[0] < 1e-12f && t[3]->data[0] == 0.0f); /* x is the reference */
    /* one vertex moved by delta: the Laplacian's L1 is delta (1 + sum 1/deg_j) / 3V */
    memcpy(ref, x, (size_t)hi->nv * 3 * sizeof(float));
    int32_t k = hi->nv / 2;
    const float delta = 0.01f;
    x[3 * k + 1] += delta;
    double want = delta;
    for (int32_t a = reg.topo->vv_off[k]; a < reg.topo->vv_off[k + 1]; a++) {
        int32_t j = reg.topo->vv[a];
        want += delta / (reg.topo->vv_off[j + 1] - reg.topo->vv_off[j]);
    }
    want /= 3.0 * hi->nv;
    cr_nn_ctx_reset(ctx);
    X = cr_nn_from(ctx, 2, (int64_t[]){hi->nv, 3}, x);
    cr_gdsr_reg_terms(ctx, &reg, X, ref, &t[0], &t[1], &t[2], &t[3]);
    CR_CHECK_NEAR(t[3]->data[0], want, 1e-4 * want);
    CR_CHECK(t[2]->data[0] > 0); /* the moved vertex bends its hinges */
    cr_nn_ctx_destroy(ctx);
    cr_eval_result_free(&er);
    free(x);
    free(ref);
    cr_gdsr_reg_free(&reg);
    cr_gdsr_data_free(&d);
}

typedef struct reg_check {
    gdsr_reg *reg;
    const float *ref;
    float scale[4];
} reg_check;

static cr_tensor *build_reg(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    reg_check *c = user;
    cr_tensor *t[4];
    cr_gdsr_reg_terms(ctx, c->reg, in[0], c->ref, &t[0], &t[1], &t[2], &t[3]);
    return cr_loss_weighted_sum(ctx, t, c->scale, 4, NULL);
}

CR_TEST(gdsr, regulariser_gradients_match_finite_differences) {
    cr_gdsr_data d;
    gdsr_reg reg;
    CR_REQUIRE(tiny_reg(&d, 0, &reg));
    const cr_mesh *hi = d.high;
    int64_t n = (int64_t)hi->nv * 3;
    float *x = malloc((size_t)n * sizeof(float)), *ref = malloc((size_t)n * sizeof(float));
    deform(hi, ref, 0.01f);
    /* x = ref + noise of 2 cm: the Laplacian's |.| stays clear of its kink */
    nn_gradcheck_fill(x, n, -0.02f, 0.02f, 0.005f, 5);
    for (int64_t i = 0; i < n; i++)
        x[i] += ref[i];
    /* scales that make each term's gradient of order one */
    reg_check c = {.reg = &reg, .ref = ref, .scale = {30.0f, 30.0f, 30.0f, 3.0f * hi->nv}};
    for (int k = 0; k < 4; k++) {
        reg_check one = c;
        for (int j = 0; j < 4; j++)
            one.scale[j] = j == k ? c.scale[j] : 0.0f;
        nn_gradcheck_input gin = nn_gradcheck_in(2, (int64_t[]){hi->nv, 3}, x);
        nn_gradcheck_def gd = nn_gradcheck_default_def();
        const char *names[4] = {"stretch", "shear", "bend", "laplacian"};
        gd.name = names[k];
        gd.step = 2e-4;
        gd.max_elems = 60;
        gd.arena_bytes = (size_t)32 << 20;
        nn_gradcheck_result res;
        CR_CHECK(nn_gradcheck(&gd, 1, &gin, NULL, build_reg, &one, &res) == 0);
        CR_CHECK(res.checked == 60);
    }
    free(x);
    free(ref);
    cr_gdsr_reg_free(&reg);
    cr_gdsr_data_free(&d);
}

/* The largest |d(f)/d(x)| of a scalar built by fn: the gradient checks below
 * are only worth something when it is of order one (the checker's tolerance
 * is absolute below 1). */
static float max_grad(nn_gradcheck_fn fn, void *user, float *x, int64_t nv) {
    cr_nn_ctx *ctx = nn_gradcheck_ctx((size_t)32 << 20);
    if (!ctx) return -1.0f;
    cr_tensor *X = cr_nn_from(ctx, 2, (int64_t[]){nv, 3}, x);
    X->requires_grad = 1;
    cr_tensor *in[1] = {X};
    cr_error err = {0};
    float g = -1.0f;
    if (cr_nn_backward(ctx, fn(ctx, in, user), &err) == CR_OK && X->grad) {
        g = 0.0f;
        for (int64_t i = 0; i < nv * 3; i++)
            g = fmaxf(g, fabsf(X->grad[i]));
    }
    cr_nn_ctx_destroy(ctx);
    return g;
}

/* Eq. 16-18's strain L1: zero at the reference, 0.2 for the rest sheet
 * scaled by 1.1 in its plane against itself at rest (|w_u| = |w_v| = 1.1,
 * w_u . w_v = 0), and its gradient against central differences. */
typedef struct strain_check {
    gdsr_reg *reg;
    const float *ref;
    float scale;
} strain_check;

static cr_tensor *build_strain(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    strain_check *c = user;
    return cr_nn_mul_scalar(ctx, cr_gdsr_reg_strain_l1(ctx, c->reg, in[0], c->ref), c->scale);
}

CR_TEST(gdsr, strain_l1_is_zero_at_the_reference_and_its_gradient_matches_fd) {
    cr_gdsr_data d;
    gdsr_reg reg;
    CR_REQUIRE(tiny_reg(&d, 0, &reg));
    const cr_mesh *hi = d.high;
    int64_t n = (int64_t)hi->nv * 3;
    float *x = malloc((size_t)n * sizeof(float)), *ref = malloc((size_t)n * sizeof(float));
    cr_nn_ctx *ctx = nn_gradcheck_ctx((size_t)16 << 20);
    CR_REQUIRE(ctx != NULL);
    deform(hi, ref, 0.01f);
    cr_tensor *l =
        cr_gdsr_reg_strain_l1(ctx, &reg, cr_nn_from(ctx, 2, (int64_t[]){hi->nv, 3}, ref), ref);
    CR_CHECK(fabsf(l->data[0]) < 1e-6f);
    for (int64_t i = 0; i < n; i++)
        x[i] = 1.1f * hi->pos[i];
    cr_nn_ctx_reset(ctx);
    l = cr_gdsr_reg_strain_l1(ctx, &reg, cr_nn_from(ctx, 2, (int64_t[]){hi->nv, 3}, x), hi->pos);
    CR_CHECK_NEAR(l->data[0], 0.2, 1e-5);
    /* x = ref stretched by 1.3 and 1.2 and sheared by 0.3 in its plane, plus
     * 1 mm of noise: every term stays clear of |.|'s kink */
    nn_gradcheck_fill(x, n, -0.001f, 0.001f, 0.0f, 11);
    for (int32_t i = 0; i < hi->nv; i++) {
        const float *r = ref + 3 * i;
        x[3 * i] += 1.3f * r[0] + 0.3f * r[2];
        x[3 * i + 1] += r[1];
        x[3 * i + 2] += 1.2f * r[2];
    }
    strain_check c = {.reg = &reg, .ref = ref, .scale = 3.0f};
    float g = max_grad(build_strain, &c, x, hi->nv);
    CR_CHECK(g > 0.5f && g < 50.0f);
    nn_gradcheck_input gin = nn_gradcheck_in(2, (int64_t[]){hi->nv, 3}, x);
    nn_gradcheck_def gd = nn_gradcheck_default_def();
    gd.name = "strain_l1";
    gd.step = 2e-4;
    gd.max_elems = 60;
    gd.arena_bytes = (size_t)32 << 20;
    nn_gradcheck_result res;
    CR_CHECK(nn_gradcheck(&gd, 1, &gin, NULL, build_strain, &c, &res) == 0);
    CR_CHECK(res.checked == 60);
    cr_nn_ctx_destroy(ctx);
    free(x);
    free(ref);
    cr_gdsr_reg_free(&reg);
    cr_gdsr_data_free(&d);
}

/* Eq. 15's smoothing on C^: the mean over (V,3) of the squared uniform
 * Laplacian of x itself, against the same sum over the 1-rings written out
 * here; blind to a translation, four times as large at twice the size; its
 * gradient against central differences. */
typedef struct smooth_check {
    gdsr_reg *reg;
    float scale;
} smooth_check;

static cr_tensor *build_smooth(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    smooth_check *c = user;
    return cr_nn_mul_scalar(ctx, cr_gdsr_reg_smooth(ctx, c->reg, in[0]), c->scale);
}

static double smooth_of(cr_nn_ctx *ctx, gdsr_reg *reg, const float *x, int32_t nv) {
    cr_nn_ctx_reset(ctx);
    return cr_gdsr_reg_smooth(ctx, reg, cr_nn_from(ctx, 2, (int64_t[]){nv, 3}, x))->data[0];
}

CR_TEST(gdsr, coarse_smoothing_is_the_mean_squared_laplacian) {
    cr_gdsr_data d;
    gdsr_reg reg;
    CR_REQUIRE(tiny_reg(&d, 1, &reg));
    cr_error err = {0};
    const cr_mesh *lo = d.low;
    cr_topology *tp = NULL;
    CR_REQUIRE(cr_topology_build(lo, &tp, &err) == CR_OK);
    int64_t n = (int64_t)lo->nv * 3;
    float *x = malloc((size_t)n * sizeof(float)), *y = malloc((size_t)n * sizeof(float));
    CR_REQUIRE(x && y);
    deform(lo, x, 0.03f);
    double want = 0;
    for (int32_t i = 0; i < lo->nv; i++) {
        int32_t deg = tp->vv_off[i + 1] - tp->vv_off[i];
        for (int c = 0; c < 3; c++) {
            double m = 0;
            for (int32_t k = tp->vv_off[i]; k < tp->vv_off[i + 1]; k++)
                m += x[3 * tp->vv[k] + c];
            double l = deg ? m / deg - x[3 * i + c] : 0.0;
            want += l * l;
        }
    }
    want /= (double)n;
    cr_nn_ctx *ctx = nn_gradcheck_ctx((size_t)16 << 20);
    CR_REQUIRE(ctx != NULL);
    double got = smooth_of(ctx, &reg, x, lo->nv);
    CR_CHECK(want > 1e-7);
    CR_CHECK_NEAR(got, want, 1e-5 * want);
    for (int64_t i = 0; i < n; i++)
        y[i] = x[i] + (i % 3 == 1 ? 0.7f : -0.2f);
    CR_CHECK_NEAR(smooth_of(ctx, &reg, y, lo->nv), want, 1e-3 * want);
    for (int64_t i = 0; i < n; i++)
        y[i] = 2.0f * x[i];
    CR_CHECK_NEAR(smooth_of(ctx, &reg, y, lo->nv), 4.0 * want, 1e-5 * want);
    smooth_check c = {.reg = &reg, .scale = 1.0f / (float)sqrt(want)};
    float g = max_grad(build_smooth, &c, x, lo->nv);
    CR_CHECK(g > 0.05f && g < 50.0f);
    nn_gradcheck_input gin = nn_gradcheck_in(2, (int64_t[]){lo->nv, 3}, x);
    nn_gradcheck_def gd = nn_gradcheck_default_def();
    gd.name = "coarse_smooth";
    gd.step = 2e-4;
    gd.arena_bytes = (size_t)32 << 20;
    nn_gradcheck_result res;
    CR_CHECK(nn_gradcheck(&gd, 1, &gin, NULL, build_smooth, &c, &res) == 0);
    CR_CHECK(res.checked == n);
    cr_nn_ctx_destroy(ctx);
    cr_topology_destroy(tp);
    free(x);
    free(y);
    cr_gdsr_reg_free(&reg);
    cr_gdsr_data_free(&d);
}

typedef struct wrinkle_check {
    gdsr_wrinkle *w;
    const float *ref;
    float scale;
    const gdsr_patch *patches;
    int npatches, energy;
} wrinkle_check;

static cr_tensor *build_wrinkle(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    wrinkle_check *c = user;
    return cr_nn_mul_scalar(
        ctx, cr_gdsr_wrinkle_loss(ctx, c->w, in[0], c->ref, c->patches, c->npatches, c->energy),
        c->scale);
}

/* x = c->ref plus a small random field (seeded); the loss's largest
 * gradient entry in (gmin, 50), then its gradient against central
 * differences on 60 entries. */
static void wrinkle_gradcheck(const char *name, wrinkle_check *c, float *x, int32_t nv,
                              uint64_t seed, float gmin) {
    int64_t n = (int64_t)nv * 3;
    nn_gradcheck_fill(x, n, -0.01f, 0.01f, 0.002f, seed);
    for (int64_t i = 0; i < n; i++)
        x[i] += c->ref[i];
    float g = max_grad(build_wrinkle, c, x, nv);
    CR_CHECK(g > gmin && g < 50.0f);
    nn_gradcheck_input gin = nn_gradcheck_in(2, (int64_t[]){nv, 3}, x);
    nn_gradcheck_def gd = nn_gradcheck_default_def();
    gd.name = name;
    gd.step = 1e-4;
    gd.max_elems = 60;
    gd.arena_bytes = (size_t)32 << 20;
    nn_gradcheck_result res;
    CR_CHECK(nn_gradcheck(&gd, 1, &gin, NULL, build_wrinkle, c, &res) == 0);
    CR_CHECK(res.checked == 60);
}

/* The wrinkle loss (Eq. 20, filter bank): the flat sheet's map is its
 * normal everywhere; zero at the reference; a ripple the reference has and
 * x lacks costs more than half of it; the gradient against central
 * differences. */
CR_TEST(gdsr, wrinkle_loss_sees_ripples_and_its_gradient_matches_fd) {
    cr_gdsr_data d;
    CR_REQUIRE(gdsr_tiny_data(&d));
    cr_error err = {0};
    const cr_mesh *hi = d.high;
    gdsr_wrinkle w;
    CR_CHECK(cr_gdsr_wrinkle_create(hi, 4, &w, &err) == CR_ERR_INVALID); /* side < 8 */
    CR_REQUIRE(cr_gdsr_wrinkle_create(hi, 16, &w, &err) == CR_OK);
    CR_CHECK(w.ntex == 16 * 16); /* the plane's UVs fill their bounds */
    CR_CHECK(w.nvalid[0] == 14 * 14 && w.nvalid[1] == 12 * 12 && w.nvalid[2] == 8 * 8);
    int64_t n = (int64_t)hi->nv * 3;
    float *x = malloc((size_t)n * sizeof(float)), *ref = malloc((size_t)n * sizeof(float));
    cr_nn_ctx *ctx = nn_gradcheck_ctx((size_t)16 << 20);
    CR_REQUIRE(ctx != NULL);
    cr_tensor *tn =
        cr_gdsr_wrinkle_normals(ctx, &w, cr_nn_from(ctx, 2, (int64_t[]){hi->nv, 3}, hi->pos));
    float m0 = 1.0f;
    for (int64_t t = 0; t < w.ntex; t++)
        m0 = fminf(m0, fabsf(tn->data[3 * t + 1])); /* plane in x-z: normal along y */
    CR_CHECK(m0 > 0.9999f);
    deform(hi, ref, 0.01f);
    cr_nn_ctx_reset(ctx);
    cr_tensor *l = cr_gdsr_wrinkle_loss(ctx, &w, cr_nn_from(ctx, 2, (int64_t[]){hi->nv, 3}, ref),
                                        ref, NULL, 0, 0);
    CR_CHECK(l->data[0] == 0.0f);
    deform(hi, x, 0.0f); /* the same stretch and shear, no ripple */
    cr_nn_ctx_reset(ctx);
    float flat = cr_gdsr_wrinkle_loss(ctx, &w, cr_nn_from(ctx, 2, (int64_t[]){hi->nv, 3}, x), ref,
                                      NULL, 0, 0)
                     ->data[0];
    deform(hi, x, 0.005f); /* half the ripple */
    cr_nn_ctx_reset(ctx);
    float half = cr_gdsr_wrinkle_loss(ctx, &w, cr_nn_from(ctx, 2, (int64_t[]){hi->nv, 3}, x), ref,
                                      NULL, 0, 0)
                     ->data[0];
    CR_CHECK(flat > 0.01f && half > 0.3f * flat && half < 0.7f * flat);
    wrinkle_check c = {.w = &w, .ref = ref, .scale = 5.0f};
    wrinkle_gradcheck("wrinkle", &c, x, hi->nv, 12, 0.5f);
    cr_nn_ctx_destroy(ctx);
    free(x);
    free(ref);
    cr_gdsr_wrinkle_free(&w);
    cr_gdsr_data_free(&d);
}

/* Energy mode (--wrinkle-energy): zero at the reference; the ripple with
 * its crests and troughs swapped (x's height minus the ripple) costs next
 * to nothing, where the texel-by-texel form charges it twice the flat
 * sheet's cost; the flat sheet costs; over two patches the gradient
 * against central differences. */
CR_TEST(gdsr, wrinkle_energy_ignores_where_the_crests_lie) {
    cr_gdsr_data d;
    CR_REQUIRE(gdsr_tiny_data(&d));
    cr_error err = {0};
    const cr_mesh *hi = d.high;
    gdsr_wrinkle w;
    CR_REQUIRE(cr_gdsr_wrinkle_create(hi, 16, &w, &err) == CR_OK);
    int64_t n = (int64_t)hi->nv * 3;
    float *x = malloc((size_t)n * sizeof(float)), *ref = malloc((size_t)n * sizeof(float));
    cr_nn_ctx *ctx = nn_gradcheck_ctx((size_t)16 << 20);
    CR_REQUIRE(ctx && x && ref);
    deform(hi, ref, 0.01f);
    float loss[2][3]; /* [energy][reference, flat, swapped] */
    for (int e = 0; e < 2; e++)
        for (int k = 0; k < 3; k++) {
            deform(hi, x, k == 1 ? 0.0f : k == 2 ? -0.01f : 0.01f);
            cr_nn_ctx_reset(ctx);
            loss[e][k] =
                cr_gdsr_wrinkle_loss(ctx, &w, cr_nn_from(ctx, 2, (int64_t[]){hi->nv, 3}, x), ref,
                                     NULL, 0, e)
                    ->data[0];
        }
    printf("  texel by texel: flat %.4g, swapped %.4g; energy: flat %.4g, swapped %.4g\n",
           loss[0][1], loss[0][2], loss[1][1], loss[1][2]);
    CR_CHECK(loss[1][0] == 0.0f && loss[0][0] == 0.0f);
    CR_CHECK(loss[0][2] > 1.5f * loss[0][1]); /* the phase costs texel by texel */
    CR_CHECK(loss[1][1] > 0.005f && loss[1][2] < 0.05f * loss[1][1]);
    gdsr_patch p[2];
    cr_rng r = cr_rng_make(3, 0);
    cr_gdsr_wrinkle_draw_patches(&w, 2, 8, &r, p);
    wrinkle_check c = {
        .w = &w, .ref = ref, .scale = 5.0f, .patches = p, .npatches = 2, .energy = 1};
    wrinkle_gradcheck("wrinkle energy", &c, x, hi->nv, 14, 0.05f);
    cr_nn_ctx_destroy(ctx);
    free(x);
    free(ref);
    cr_gdsr_wrinkle_free(&w);
    cr_gdsr_data_free(&d);
}

CR_TEST(gdsr, lambda_schedule_is_the_papers) {
    cr_gdsr_train_def def = cr_gdsr_train_default_def();
    float c, w;
    cr_gdsr_lambdas(&def, 37, &c, &w);
    CR_CHECK(c == 1.0f && w == 1.0f); /* default: constant */
    def.lambda_c0 = 1.9f, def.lambda_w0 = 0.1f;
    const int ep[5] = {0, 9, 10, 45, 50};
    const float wc[5] = {1.9f, 1.9f, 1.7f, 1.1f, 1.0f}, ww[5] = {0.1f, 0.1f, 0.3f, 0.9f, 1.0f};
    for (int k = 0; k < 5; k++) {
        cr_gdsr_lambdas(&def, ep[k], &c, &w);
        CR_CHECK_NEAR(c, wc[k], 1e-5);
        CR_CHECK_NEAR(w, ww[k], 1e-5);
    }
    cr_gdsr_lambdas(&def, 500, &c, &w);
    CR_CHECK(c == 1.0f && w == 1.0f);
}

/* C* of the high rest mesh is the low rest mesh, also where no high vertex
 * sits on a low one (a 5x5 sheet over an 8x8 one; the nearest high vertex,
 * the operator before, was up to half a high cell off). */
CR_TEST(gdsr, coarse_target_of_the_rest_is_the_low_rest) {
    cr_error err = {0};
    cr_mesh *lo = NULL, *hi = NULL, *body = NULL;
    CR_REQUIRE(cr_prim_plane(5, 5, 0.4f, 0.4f, &lo, &err) == CR_OK);
    CR_REQUIRE(cr_prim_plane(8, 8, 0.4f, 0.4f, &hi, &err) == CR_OK);
    CR_REQUIRE(cr_prim_icosphere(0.05f, 1, &body, &err) == CR_OK);
    cr_gdsr_data d;
    CR_REQUIRE(cr_gdsr_data_from_arrays(lo, hi, body, 1, lo->pos, hi->pos, body->pos, &d, &err) ==
               CR_OK);
    float *c = malloc((size_t)lo->nv * 3 * sizeof(float));
    cr_gdsr_coarse_target(&d, hi->pos, c);
    float worst = 0.0f;
    for (int64_t i = 0; i < (int64_t)lo->nv * 3; i++)
        worst = fmaxf(worst, fabsf(c[i] - lo->pos[i]));
    CR_CHECK(worst < 1e-5f);
    free(c);
    cr_gdsr_data_free(&d);
    cr_mesh_destroy(lo);
    cr_mesh_destroy(hi);
    cr_mesh_destroy(body);
}

/* Sum over the sheet's edges of (|e| / |e_rest| - 1)^2. */
static double edge_strain(const cr_topology *t, const float *x, const float *rest) {
    double s = 0.0;
    for (int32_t e = 0; e < t->ne; e++) {
        const int32_t a = t->edge[2 * e], b = t->edge[2 * e + 1];
        double l = 0.0, l0 = 0.0;
        for (int k = 0; k < 3; k++) {
            double d = (double)x[3 * a + k] - x[3 * b + k],
                   d0 = (double)rest[3 * a + k] - rest[3 * b + k];
            l += d * d, l0 += d0 * d0;
        }
        s += (sqrt(l / l0) - 1.0) * (sqrt(l / l0) - 1.0);
    }
    return s;
}

/* A 20 cm sheet with a ball poking 1 cm through its middle: the per-vertex
 * push (0 steps) and the spread one (8) both leave every vertex outside;
 * the spread one strains the edges less and leaves the far corner alone.
 * Skipping the queries the first push's distances rule out changes nothing. */
CR_TEST(gdsr, collision_relax_keeps_outside_and_lowers_strain) {
    cr_error err = {0};
    cr_mesh *sheet = NULL, *ball = NULL;
    cr_topology *t = NULL;
    cr_bvh *b = NULL;
    CR_REQUIRE(cr_prim_plane(31, 31, 0.2f, 0.2f, &sheet, &err) == CR_OK);
    CR_REQUIRE(cr_prim_icosphere(0.03f, 3, &ball, &err) == CR_OK);
    for (int32_t i = 0; i < ball->nv; i++)
        ball->pos[3 * i + 1] -= 0.02f;
    CR_REQUIRE(cr_bvh_build(ball->pos, ball->nv, ball->tri, ball->nf, &b, &err) == CR_OK);
    CR_REQUIRE(cr_topology_build(sheet, &t, &err) == CR_OK);
    int32_t n = sheet->nv;
    float *x = malloc((size_t)n * 3 * sizeof(float)), *sd = malloc((size_t)n * sizeof(float));
    float *nrm = malloc((size_t)n * 3 * sizeof(float)), *d = malloc((size_t)n * 9 * sizeof(float));
    float *lb = malloc((size_t)n * sizeof(float)), *all = malloc((size_t)n * 3 * sizeof(float));
    int32_t *idx = malloc((size_t)n * sizeof(int32_t));
    uint8_t *moved = malloc((size_t)n);
    cr_gdsr_relax_scratch s = {.sd = sd,
                               .nrm = nrm,
                               .d = d,
                               .dn = d + 3 * n,
                               .x0 = d + 6 * n,
                               .lb = NULL,
                               .idx = idx,
                               .moved = moved};
    double strain[2];
    for (int pass = 0; pass < 2; pass++) {
        s.lb = NULL; /* every vertex in doubt queried */
        memcpy(all, sheet->pos, (size_t)n * 3 * sizeof(float));
        cr_gdsr_relax_push(b, t, sheet->pos, all, 0.001f, pass ? 8 : 0, &s);
        s.lb = lb;
        memcpy(x, sheet->pos, (size_t)n * 3 * sizeof(float));
        cr_gdsr_relax_push(b, t, sheet->pos, x, 0.001f, pass ? 8 : 0, &s);
        CR_CHECK(memcmp(x, all, (size_t)n * 3 * sizeof(float)) == 0);
        cr_bvh_signed_distance_batch(b, x, n, 1.0f, sd, NULL, NULL);
        int32_t inside = 0;
        for (int32_t i = 0; i < n; i++)
            inside += sd[i] < 0.0f;
        CR_CHECK(inside == 0);
        CR_CHECK(x[1] == sheet->pos[1]); /* vertex 0, the corner, 14 cm from the ball */
        strain[pass] = edge_strain(t, x, sheet->pos);
    }
    printf("  edge strain: push %.4g, spread %.4g\n", strain[0], strain[1]);
    CR_CHECK(strain[0] > 0.0);
    CR_CHECK(strain[1] < 0.5 * strain[0]);
    free(x), free(sd), free(nrm), free(d), free(lb), free(all), free(idx), free(moved);
    cr_bvh_destroy(b);
    cr_topology_destroy(t);
    cr_mesh_destroy(sheet);
    cr_mesh_destroy(ball);
}

/* gdsr run --simulate's input: one low-resolution sequence made by the
 * dataset machinery, with the high mesh and Eq. 1 but no high run. */
CR_TEST(gdsr, simulate_makes_a_low_only_input_with_its_pair) {
    cr_error err = {0};
    char dir[1024];
    snprintf(dir, sizeof dir, "%s/gdsr_sim", cr_test_tmpdir());
    cr_gdsr_sim_def sd = cr_gdsr_sim_default_def();
    sd.out_dir = dir, sd.motion = "walk", sd.frames = 3, sd.quiet = 1;
    sd.low_vertices = 500, sd.high_vertices = 1000;
    cr_gdsr_data d;
    cr_gdsr_sim_result r;
    CR_CHECK_OK(cr_gdsr_simulate(&sd, &d, &r, &err), &err);
    CR_CHECK(!strcmp(r.garment, "tshirt") && !strcmp(r.motion, "walk"));
    CR_CHECK(d.nclips == 1 && d.clip[0].nframes == 4); /* frames + 1 samples */
    CR_CHECK(d.clip[0].low && d.clip[0].body && !d.clip[0].high);
    CR_CHECK(r.low_vertices == d.low->nv && d.high->nv > d.low->nv);
    /* the garment moved with the body */
    int64_t last = (int64_t)3 * d.low->nv * 3;
    double moved = 0;
    for (int32_t i = 0; i < 3 * d.low->nv; i++)
        moved = fmax(moved, fabs(d.clip[0].low[last + i] - d.clip[0].low[i]));
    CR_CHECK(moved > 1e-4);
    char path[1100];
    snprintf(path, sizeof path, "%s/sequences/tshirt_high_normal_walk", dir);
    FILE *f = fopen(path, "r"); /* not simulated */
    CR_CHECK(!f);
    if (f) fclose(f);
    cr_gdsr_data_free(&d);
    sd.motion = "no_such_clip";
    CR_CHECK(cr_gdsr_simulate(&sd, &d, &r, &err) != CR_OK);
}

/* A PNG's width from its IHDR chunk (bytes 16-19, big-endian); 0 if unreadable. */
static int png_width(const char *path) {
    unsigned char h[24];
    FILE *f = fopen(path, "rb");
    size_t n = f ? fread(h, 1, sizeof h, f) : 0;
    if (f) fclose(f);
    return n == sizeof h ? (h[16] << 24) | (h[17] << 16) | (h[18] << 8) | h[19] : 0;
}

/* gdsr run's glb (animated, or the last frame past the cap) and its
 * side-by-side pictures (four panels with a reference, three without). */
CR_TEST(gdsr, glb_and_pictures_of_a_rollout) {
    cr_gdsr_data d;
    CR_REQUIRE(gdsr_tiny_data(&d));
    cr_error err = {0};
    const cr_gdsr_clip *cl = &d.clip[0];
    int32_t T = cl->nframes, nh = d.high->nv;
    float *up = malloc((size_t)T * nh * 3 * sizeof(float));
    CR_REQUIRE(up);
    for (int32_t t = 0; t < T; t++)
        cr_gdsr_upsample(&d, cl->low + (int64_t)t * d.low->nv * 3, up + (int64_t)t * nh * 3);
    /* the reference stands in for gdsr's output */
    cr_gdsr_rollout_result r = {.nframes = T, .nv_high = nh, .gdsr = cl->high, .upsampled = up};
    char path[1100], npath[1100];
    int animated = -1;
    snprintf(path, sizeof path, "%s/gdsr_out.glb", cr_test_tmpdir());
    CR_CHECK_OK(cr_gdsr_write_glb(d.high, r.gdsr, T, 30.0f, T, path, &animated, &err), &err);
    CR_CHECK(animated == 1);
    cr_mesh *rest = NULL;
    float *frames = NULL, fps = 0;
    int32_t nf = 0;
    CR_CHECK_OK(cr_glb_read_sequence(path, &rest, &frames, &nf, &fps, &err), &err);
    CR_CHECK(nf == T && rest && rest->nv == nh);
    if (nf == T && rest && rest->nv == nh) {
        float worst = 0;
        for (int64_t i = 0; i < (int64_t)T * nh * 3; i++)
            worst = fmaxf(worst, fabsf(frames[i] - cl->high[i]));
        CR_CHECK(worst < 1e-5f);
        CR_CHECK_NEAR(fps, 30.0f, 1e-3);
    }
    free(frames);
    cr_mesh_destroy(rest);
    rest = NULL;
    CR_CHECK_OK(cr_gdsr_write_glb(d.high, r.gdsr, T, 30.0f, T - 1, path, &animated, &err), &err);
    CR_CHECK(animated == 0);
    CR_CHECK_OK(cr_glb_read(path, &rest, &err), &err);
    if (rest && rest->nv == nh) /* the last frame */
        CR_CHECK_NEAR(rest->pos[4], cl->high[(int64_t)(T - 1) * nh * 3 + 4], 1e-6);
    cr_mesh_destroy(rest);
    snprintf(path, sizeof path, "%s/gdsr_compare.png", cr_test_tmpdir());
    snprintf(npath, sizeof npath, "%s/gdsr_compare_normals.png", cr_test_tmpdir());
    CR_CHECK_OK(cr_gdsr_render_compare(&d, 0, &r, T - 1, 64, path, npath, &err), &err);
    CR_CHECK(png_width(path) == 4 * 64 + 3 * 4 && png_width(npath) == 4 * 64 + 3 * 4);
    float *high = d.clip[0].high;
    d.clip[0].high = NULL; /* no reference: three panels */
    CR_CHECK_OK(cr_gdsr_render_compare(&d, 0, &r, 1, 64, path, NULL, &err), &err);
    CR_CHECK(png_width(path) == 3 * 64 + 2 * 4);
    CR_CHECK(cr_gdsr_render_compare(&d, 0, &r, T, 64, path, NULL, &err) == CR_ERR_RANGE);
    d.clip[0].high = high;
    free(up);
    cr_gdsr_data_free(&d);
}

/* Two layers by hand: the quad (vertices 0-3, y = 0) and a copy (4-7)
 * moved so that 4 is 1.5 cm above 0, 5 is 2.5 cm above 1, 6 is 1.41 cm from
 * 2 and 7 is far: with sigma_l = 2 cm the layer edges are 0-4 and 2-6, both
 * ways, never a pair of one layer. */
CR_TEST(gdsr, layer_edges_on_a_hand_made_two_layer_configuration) {
    cr_error err = {0};
    cr_mesh *a = quad(), *b = quad();
    CR_REQUIRE(a && b);
    CR_REQUIRE(cr_mesh_append(a, b, &err) == CR_OK);
    CR_REQUIRE(a->nv == 8 && a->nf == 4);
    int32_t layer[8];
    CR_CHECK(cr_gdsr_mesh_layers(a, layer) == 2);
    for (int i = 0; i < 8; i++)
        CR_CHECK(layer[i] == (i >= 4));
    float c[24];
    memcpy(c, a->pos, sizeof c);
    c[3 * 4 + 1] = 0.015f;                          /* above 0 */
    c[3 * 5 + 1] = 0.025f;                          /* above 1, too far */
    c[3 * 6 + 0] = 1.01f, c[3 * 6 + 1] = 0.01f;     /* beside 2 */
    c[3 * 7 + 0] = c[3 * 7 + 1] = c[3 * 7 + 2] = 5; /* far */
    cr_gdsr_graph g;
    CR_CHECK_OK(cr_gdsr_graph_build(a, &g, &err), &err);
    CR_CHECK(g.ne[2] == 0);
    CR_CHECK_OK(cr_gdsr_layer_edges(&g, layer, c, 0.02f, &err), &err);
    const int32_t want[4][2] = {{0, 4}, {2, 6}, {4, 0}, {6, 2}}; /* receiver, sender */
    CR_CHECK(g.ne[2] == 4);
    for (int e = 0; e < 4 && g.ne[2] == 4; e++)
        CR_CHECK(g.rcv[2][e] == want[e][0] && g.snd[2][e] == want[e][1]);
    float f[4 * CR_GDSR_EDGE_FEATURES];
    if (g.ne[2] == 4) {
        cr_gdsr_layer_edge_features(&g, c, 0.02f, f);
        const float *f0 = f, *f1 = f + CR_GDSR_EDGE_FEATURES; /* 4 -> 0 and 6 -> 2, dm */
        CR_CHECK(f0[0] == 0 && f0[1] == 0 && f0[2] == 0);
        CR_CHECK_NEAR(f0[3], 0.2f, 1e-6);  /* sigma_l where the rest length was */
        CR_CHECK_NEAR(f0[5], 0.15f, 1e-6); /* c_4 - c_0 */
        CR_CHECK_NEAR(f0[4], 0.0f, 1e-6);
        CR_CHECK_NEAR(f0[7], 0.15f, 1e-6);
        CR_CHECK_NEAR(f1[4], 0.1f, 1e-5);
        CR_CHECK_NEAR(f1[5], 0.1f, 1e-5);
        CR_CHECK_NEAR(f1[7], 0.141421f, 1e-5);
        CR_CHECK_NEAR(f[2 * CR_GDSR_EDGE_FEATURES + 5], -0.15f, 1e-6); /* 0 -> 4: reversed */
    }
    /* a radius past the quad's 1 m edges: still no pair of one layer */
    CR_CHECK_OK(cr_gdsr_layer_edges(&g, layer, c, 1.2f, &err), &err);
    CR_CHECK(g.ne[2] > 4);
    for (int64_t e = 0; e < g.ne[2]; e++)
        CR_CHECK(layer[g.rcv[2][e]] != layer[g.snd[2][e]]);
    /* one layer: none */
    int32_t one[8] = {0};
    CR_CHECK_OK(cr_gdsr_layer_edges(&g, one, c, 1.2f, &err), &err);
    CR_CHECK(g.ne[2] == 0);
    cr_gdsr_graph_free(&g);
    cr_mesh_destroy(a);
    cr_mesh_destroy(b);
}

/* The grid finds exactly the pairs a brute-force search finds. */
CR_TEST(gdsr, layer_edges_match_brute_force) {
    cr_error err = {0};
    enum { N = 400 };
    cr_rng rng = cr_rng_make(3, 0);
    float c[3 * N];
    int32_t layer[N];
    for (int i = 0; i < N; i++) {
        layer[i] = i % 3;
        for (int k = 0; k < 3; k++)
            c[3 * i + k] = 0.1f * (float)cr_rng_uniform(&rng);
    }
    cr_gdsr_graph g = {.nv = N};
    CR_CHECK_OK(cr_gdsr_layer_edges(&g, layer, c, 0.02f, &err), &err);
    int64_t want = 0;
    for (int i = 0; i < N; i++)
        for (int l = 0; l < N; l++) {
            float d2 = 0;
            for (int k = 0; k < 3; k++)
                d2 += (c[3 * l + k] - c[3 * i + k]) * (c[3 * l + k] - c[3 * i + k]);
            want += layer[i] != layer[l] && d2 < 0.02f * 0.02f;
        }
    printf("  %lld layer edges\n", (long long)want);
    CR_CHECK(want > 100);
    CR_CHECK(g.ne[2] == want);
    cr_gdsr_graph_free(&g);
}

/* compare.png's panels colour an outfit by layer: the two sheets of
 * gdsr_two_layer_data seen from above show the upper one's tan and, where it does
 * not cover the lower one (they are offset 1 cm in height only, so seen at
 * an angle the lower sheet's edge shows), blue; a single sheet is all blue. */
CR_TEST(gdsr, compare_pictures_colour_each_layer) {
    cr_gdsr_data d;
    CR_REQUIRE(gdsr_two_layer_data(&d));
    cr_error err = {0};
    cr_render_def rd = cr_render_default_def();
    rd.width = rd.height = 96;
    rd.pitch_deg = 10.0f;
    int counts[2][2] = {{0}}; /* [two layers, one][tan, blue] */
    for (int one = 0; one < 2; one++) {
        cr_mesh *m = NULL;
        CR_REQUIRE(cr_mesh_clone(d.high, &m, &err) == CR_OK);
        if (one) m->nf /= 2; /* the first sheet's faces only */
        cr_image img = {0};
        CR_CHECK_OK(cr_gdsr_render_layers(&rd, m, &img, &err), &err);
        for (int64_t i = 0; img.rgb && i < (int64_t)img.width * img.height; i++) {
            const int r = img.rgb[3 * i], b = img.rgb[3 * i + 2];
            counts[one][0] += r > b + 40;
            counts[one][1] += b > r + 40;
        }
        cr_image_free(&img);
        cr_mesh_destroy(m);
    }
    printf("  two layers: %d tan, %d blue pixels; one: %d tan, %d blue\n", counts[0][0],
           counts[0][1], counts[1][0], counts[1][1]);
    CR_CHECK(counts[0][0] > 100 && counts[0][1] > 20);
    CR_CHECK(counts[1][0] == 0 && counts[1][1] > 100);
    cr_gdsr_data_free(&d);
}

/* Eq. 27 on a hand-made configuration: the two sheets' outer one (1 cm
 * above) pushed 1.2 cm down, 2 mm through the inner one: every outer coarse
 * vertex and every outer high vertex (every other one 3 mm lower still, as
 * a wrinkle residual) ends sigma above the inner sheet, the
 * inner one does not move; at its rest 1 cm nothing moves; moved 1 m aside
 * (beyond gamma) it is not a collision. */
static void layer_collisions_push_the_outer_layer_out_by(int surface) {
    cr_gdsr_data d;
    CR_REQUIRE(gdsr_two_layer_data(&d));
    const int32_t nl = d.low->nv, nh = d.high->nv;
    float *c = malloc(sizeof(float) * 3 * (size_t)nl), *x = malloc(sizeof(float) * 3 * (size_t)nh);
    float *c0 = malloc(sizeof(float) * 3 * (size_t)nl);
    cr_error err = {0};
    const float sig = CR_GDSR_LAYER_SIGMA, gam = CR_GDSR_LAYER_GAMMA;
    for (int pass = 0; pass < 3; pass++) {
        memcpy(c, d.low->pos, sizeof(float) * 3 * (size_t)nl);
        for (int32_t i = 0; i < nl; i++)
            if (d.layer[i] == 1) {
                if (pass == 0) c[3 * i + 1] -= 0.012f;
                if (pass == 2) c[3 * i + 1] -= 0.012f, c[3 * i] += 1.0f;
            }
        memcpy(c0, c, sizeof(float) * 3 * (size_t)nl);
        cr_gdsr_upsample(&d, c, x);
        int32_t dipped = 0; /* a residual: every other outer high vertex 3 mm lower */
        for (int32_t v = 0; pass == 0 && v < nh; v += 2)
            if (d.layer[d.low->tri[3 * d.face[v]]] == 1) x[3 * v + 1] -= 0.003f, dipped++;
        int64_t fine = -1;
        int64_t n = cr_gdsr_layer_push(&d, c, x, sig, gam, surface, &fine, &err);
        printf("  %s rule, pass %d: %lld coarse and %lld high vertices pushed\n",
               surface ? "surface" : "vertex", pass, (long long)n, (long long)fine);
        int32_t outer_low = 0, outer_high = 0, inner_moved = 0, low_short = 0, high_short = 0;
        for (int32_t i = 0; i < nl; i++) {
            if (d.layer[i] == 0) {
                inner_moved += memcmp(c + 3 * i, c0 + 3 * i, 3 * sizeof(float)) != 0;
                continue;
            }
            outer_low++;
            low_short += c[3 * i + 1] < sig - 1e-5f; /* the inner sheet lies at y = 0 */
        }
        for (int32_t v = 0; v < nh; v++) {
            int32_t lay = d.layer[d.low->tri[3 * d.face[v]]];
            if (lay != 1) continue;
            outer_high++;
            high_short += x[3 * v + 1] < sig - 1e-5f;
        }
        CR_CHECK(inner_moved == 0);
        if (pass == 0) {
            /* the coarse push lifts the high sheet to sigma; the dipped ones
             * need Eq. 27's own push */
            CR_CHECK(n == outer_low && fine == dipped && dipped > 0 && outer_high > 2 * dipped - 2);
            CR_CHECK(low_short == 0 && high_short == 0);
        } else {
            CR_CHECK(n == 0 && fine == 0);
            CR_CHECK(memcmp(c, c0, sizeof(float) * 3 * (size_t)nl) == 0);
        }
    }
    /* a single layer: nothing to do */
    int32_t nlay = d.nlayers;
    d.nlayers = 1;
    CR_CHECK(cr_gdsr_layer_push(&d, c, x, sig, gam, surface, NULL, &err) == 0);
    d.nlayers = nlay;
    free(c), free(x), free(c0);
    cr_gdsr_data_free(&d);
}

CR_TEST(gdsr, layer_collisions_push_the_outer_layer_out) {
    layer_collisions_push_the_outer_layer_out_by(0);
    layer_collisions_push_the_outer_layer_out_by(1);
}

/* Where the two rules of Eq. 27 differ: the outer sheet 2 cm aside and 3 mm
 * above the inner one (closer than sigma). Over the inner sheet both push
 * its vertices out to sigma; the outer sheet's last column, 2 cm past the
 * inner sheet's open edge, is within gamma of the inner edge's vertices, so
 * the nearest-vertex rule pushes it too, and the surface rule, whose closest
 * point for it lies on that open edge, leaves it. */
CR_TEST(gdsr, layer_surface_rule_skips_past_the_open_edge) {
    cr_gdsr_data d;
    CR_REQUIRE(gdsr_two_layer_data(&d));
    const int32_t nl = d.low->nv, nh = d.high->nv;
    float *c = malloc(sizeof(float) * 3 * (size_t)nl), *x = malloc(sizeof(float) * 3 * (size_t)nh);
    CR_REQUIRE(c && x);
    cr_error err = {0};
    int64_t pushed[2];
    int32_t outer = 0, past = 0;
    for (int surface = 0; surface < 2; surface++) {
        memcpy(c, d.low->pos, sizeof(float) * 3 * (size_t)nl);
        for (int32_t i = 0; i < nl; i++)
            if (d.layer[i] == 1) c[3 * i] += 0.02f, c[3 * i + 1] -= 0.007f;
        cr_gdsr_upsample(&d, c, x);
        pushed[surface] = cr_gdsr_layer_push(&d, c, x, CR_GDSR_LAYER_SIGMA, CR_GDSR_LAYER_GAMMA,
                                             surface, NULL, &err);
        outer = past = 0;
        int32_t short_over = 0, moved_past = 0;
        for (int32_t i = 0; i < nl; i++) {
            if (d.layer[i] != 1) continue;
            outer++;
            const int is_past = c[3 * i] > 0.2f + 1e-4f; /* the inner sheet ends at x = 0.2 */
            past += is_past;
            if (!is_past) short_over += c[3 * i + 1] < CR_GDSR_LAYER_SIGMA - 1e-5f;
            if (is_past) moved_past += fabsf(c[3 * i + 1] - 0.003f) > 1e-6f;
        }
        printf("  %s rule: %lld of %d outer vertices pushed, %d of them past the edge\n",
               surface ? "surface" : "vertex", (long long)pushed[surface], outer, past);
        CR_CHECK(short_over == 0); /* over the inner sheet: out to sigma either way */
        if (surface) CR_CHECK(moved_past == 0);
    }
    CR_CHECK(past == 5 && outer == 25);
    CR_CHECK(pushed[0] == outer && pushed[1] == outer - past);
    /* the layers' crossings: none at rest 1 cm apart, every outer edge over the inner
       sheet's interior when the outer sheet tilts through it */
    CR_CHECK(cr_gdsr_layer_crossings(&d, d.high->pos, &err) == 0);
    memcpy(x, d.high->pos, sizeof(float) * 3 * (size_t)nh);
    for (int32_t v = 0; v < nh; v++)
        if (d.layer[d.low->tri[3 * d.face[v]]] == 1) x[3 * v + 1] -= 0.01f + 0.1f * x[3 * v];
    int64_t crossings = cr_gdsr_layer_crossings(&d, x, &err);
    printf("  tilted through: %lld crossings\n", (long long)crossings);
    CR_CHECK(crossings > 0);
    free(c), free(x);
    cr_gdsr_data_free(&d);
}

/* On an outfit, training turns the layer edges on (auto): H gets a third
 * edge set, the layer edges change the trained model's output and reach
 * their encoder's weights through the gradient, and the model rolls out;
 * off, the same model is smaller. */
CR_TEST(gdsr, two_layer_outfit_trains_with_layer_edges) {
    cr_gdsr_data d;
    CR_REQUIRE(gdsr_two_layer_data(&d));
    CR_CHECK(d.nlayers == 2);
    cr_error err = {0};
    cr_gdsr_train_def def = cr_gdsr_train_default_def();
    def.model = gdsr_tiny_def();
    def.model.out_scale = 1.0f;
    def.epochs = 2;
    def.lr = 3e-3f;
    def.quiet = 1;
    char dir[1024], path[1100];
    snprintf(dir, sizeof dir, "%s/gdsr_layers", cr_test_tmpdir());
    def.out_dir = dir;
    cr_gdsr_train_result on, off;
    CR_CHECK_OK(cr_gdsr_train(&def, &d, &on, &err), &err);
    snprintf(path, sizeof path, "%s/model.safetensors", dir);
    cr_gdsr_model *m = NULL;
    CR_CHECK_OK(cr_gdsr_model_load(path, &m, &err), &err);
    if (m) {
        CR_CHECK(cr_gdsr_model_get_def(m)->layer_edges == 1);
        cr_tensor *w = cr_nn_params_find(cr_gdsr_model_params(m), "H.encoder.edge2.0.weight");
        CR_CHECK(w != NULL);
        /* frame 2's layer edges reach the output and their encoder's gradient */
        int32_t nl = d.low->nv;
        const float *c = d.clip[0].low + 2 * 3 * nl;
        cr_gdsr_graph g;
        CR_CHECK_OK(cr_gdsr_graph_build(d.low, &g, &err), &err);
        CR_CHECK_OK(cr_gdsr_layer_edges(&g, d.layer, c, 0.02f, &err), &err);
        printf("  %lld layer edges at frame 2\n", (long long)g.ne[2]);
        CR_CHECK(g.ne[2] >= 2 * 25); /* each vertex and the one 1 cm above it, at least */
        float *node = malloc((size_t)nl * CR_GDSR_NODE_FEATURES * sizeof(float));
        float *e0 = malloc((size_t)g.ne[0] * CR_GDSR_EDGE_FEATURES * sizeof(float));
        float *e1 = malloc((size_t)g.ne[1] * CR_GDSR_EDGE_FEATURES * sizeof(float));
        float *e2 = malloc((size_t)(g.ne[2] + 1) * CR_GDSR_EDGE_FEATURES * sizeof(float));
        float *far = malloc((size_t)nl * 3 * sizeof(float));
        for (int32_t i = 0; i < 3 * nl; i++)
            far[i] = c[i] + 1.0f; /* the body out of reach */
        cr_gdsr_frame_in in = {
            .c = c, .c_prev = c - 3 * nl, .c_prev2 = c - 6 * nl, .body_point = far};
        cr_gdsr_features(d.low, &g, &in, 0.015f, node, e0, e1);
        cr_gdsr_layer_edge_features(&g, c, 0.02f, e2);
        cr_nn_ctx_def cd = cr_nn_ctx_default_def();
        cr_nn_ctx *ctx = NULL;
        CR_CHECK_OK(cr_nn_ctx_create(&cd, &ctx, &err), &err);
        cr_tensor *chat = NULL;
        cr_tensor *x1 = cr_gdsr_forward(ctx, m, &d, &g, node, e0, e1, e2, c, &chat);
        cr_tensor *x2 = cr_gdsr_forward(ctx, m, &d, &g, node, e0, e1, NULL, c, &chat);
        CR_REQUIRE(x1 && x2);
        double diff = 0;
        for (int64_t i = 0; i < x1->numel; i++)
            diff = fmax(diff, fabs(x1->data[i] - x2->data[i]));
        CR_CHECK(diff > 1e-6);
        cr_nn_params_zero_grad(cr_gdsr_model_params(m));
        CR_CHECK_OK(cr_nn_backward(ctx, cr_nn_sum(ctx, x1), &err), &err);
        double gmax = 0;
        for (int64_t i = 0; w && w->grad && i < w->numel; i++)
            gmax = fmax(gmax, fabs(w->grad[i]));
        CR_CHECK(gmax > 0);
        cr_nn_ctx_destroy(ctx);
        free(node), free(e0), free(e1), free(e2), free(far);
        cr_gdsr_graph_free(&g);
        cr_gdsr_rollout_result ro;
        CR_CHECK_OK(cr_gdsr_rollout(m, &d, 0, 0.002f, 0, 0, &ro, &err), &err);
        cr_gdsr_rollout_free(&ro);
    }
    cr_gdsr_model_destroy(m);
    def.model.layer_edges = 0;
    snprintf(dir, sizeof dir, "%s/gdsr_layers_off", cr_test_tmpdir());
    CR_CHECK_OK(cr_gdsr_train(&def, &d, &off, &err), &err);
    CR_CHECK(off.params < on.params);
    cr_gdsr_data_free(&d);
}

/* Eq. 24's patches: drawn inside the map around chart texels, the same for
 * the same stream; one patch over the whole map is the whole-chart loss; a
 * ripple on one side of the sheet costs in a patch there and nothing in a
 * patch on the other side; the gradient through two patches against
 * central differences. */
CR_TEST(gdsr, wrinkle_patches_crop_the_map) {
    cr_gdsr_data d;
    CR_REQUIRE(gdsr_tiny_data(&d));
    cr_error err = {0};
    const cr_mesh *hi = d.high;
    gdsr_wrinkle w;
    CR_REQUIRE(cr_gdsr_wrinkle_create(hi, 32, &w, &err) == CR_OK);
    gdsr_patch p[8], q[8];
    cr_rng r1 = cr_rng_make(5, 0), r2 = cr_rng_make(5, 0);
    cr_gdsr_wrinkle_draw_patches(&w, 8, 12, &r1, p);
    cr_gdsr_wrinkle_draw_patches(&w, 8, 12, &r2, q);
    int distinct = 0;
    for (int k = 0; k < 8; k++) {
        CR_CHECK(p[k].side == 12 && p[k].r0 >= 0 && p[k].c0 >= 0 && p[k].r0 + 12 <= 32 &&
                 p[k].c0 + 12 <= 32);
        CR_CHECK(p[k].r0 == q[k].r0 && p[k].c0 == q[k].c0);
        distinct += k > 0 && (p[k].r0 != p[0].r0 || p[k].c0 != p[0].c0);
    }
    CR_CHECK(distinct > 0);
    cr_gdsr_wrinkle_draw_patches(&w, 1, 64, &r1, q); /* larger than the map: the map */
    CR_CHECK(q[0].side == 32 && q[0].r0 == 0 && q[0].c0 == 0);
    int64_t n = (int64_t)hi->nv * 3;
    float *x = malloc((size_t)n * sizeof(float)), *ref = malloc((size_t)n * sizeof(float));
    cr_nn_ctx *ctx = nn_gradcheck_ctx((size_t)16 << 20);
    CR_REQUIRE(ctx && x && ref);
    deform(hi, ref, 0.01f);
    deform(hi, x, 0.0f);
    cr_tensor *X = cr_nn_from(ctx, 2, (int64_t[]){hi->nv, 3}, x);
    float whole = cr_gdsr_wrinkle_loss(ctx, &w, X, ref, NULL, 0, 0)->data[0];
    float one = cr_gdsr_wrinkle_loss(ctx, &w, X, ref, q, 1, 0)->data[0];
    CR_CHECK_NEAR(one, whole, 1e-6 * whole);
    /* the ripple only where x < -0.1 m: the flat x against it */
    memcpy(x, hi->pos, (size_t)n * sizeof(float));
    memcpy(ref, hi->pos, (size_t)n * sizeof(float));
    for (int32_t i = 0; i < hi->nv; i++)
        if (hi->pos[3 * i] < -0.1f) ref[3 * i + 1] += 0.01f * sinf(60 * hi->pos[3 * i + 2]);
    const gdsr_patch side[2] = {{12, 0, 8}, {12, 24, 8}}; /* the map's two edges */
    float l[2];
    for (int k = 0; k < 2; k++) {
        cr_nn_ctx_reset(ctx);
        X = cr_nn_from(ctx, 2, (int64_t[]){hi->nv, 3}, x);
        l[k] = cr_gdsr_wrinkle_loss(ctx, &w, X, ref, side + k, 1, 0)->data[0];
    }
    printf("  patch losses at the two edges: %.4g, %.4g\n", l[0], l[1]);
    CR_CHECK(fmaxf(l[0], l[1]) > 0.01f && fminf(l[0], l[1]) == 0.0f);
    /* gradient through two patches */
    deform(hi, ref, 0.01f);
    wrinkle_check c = {.w = &w, .ref = ref, .scale = 5.0f, .patches = p, .npatches = 2};
    wrinkle_gradcheck("wrinkle patches", &c, x, hi->nv, 13, 0.2f);
    cr_nn_ctx_destroy(ctx);
    free(x);
    free(ref);
    cr_gdsr_wrinkle_free(&w);
    cr_gdsr_data_free(&d);
}

/* Mean distance (m) of a roll-out's raw output and of its upsampling to the
 * reference, frames 2.., through training's validation sums. */
static void rollout_distances(cr_gdsr_model *m, const cr_gdsr_data *d, double *med,
                              double *med_up) {
    cr_error err = {0};
    double s = 0, su = 0;
    int64_t n = 0;
    *med = *med_up = NAN;
    if (cr_gdsr_validate(m, d, 0, &s, &su, &n, &err) == CR_OK && n > 0)
        *med = s / n, *med_up = su / n;
}

/* One model on two garments of different meshes and layer counts (the
 * rippled sheet and the two-layer pair): it trains, switches the layer edges
 * on for the outfit, and ends closer to the reference than upsampling on
 * both. */
CR_TEST(gdsr, one_model_trains_on_two_garments) {
    cr_gdsr_data a, b;
    CR_REQUIRE(gdsr_tiny_data(&a));
    CR_REQUIRE(gdsr_two_layer_data(&b));
    cr_error err = {0};
    cr_gdsr_train_def def = cr_gdsr_train_default_def();
    def.model = gdsr_tiny_def();
    def.epochs = CR_TEST_SIZE(30, 3);
    def.w_stretch = def.w_shear = 1.0f;
    def.lr = 3e-3f;
    def.noise_m = 0.0005f;
    def.quiet = 1;
    char dir[1024], path[1100];
    snprintf(dir, sizeof dir, "%s/gdsr_two_garments", cr_test_tmpdir());
    def.out_dir = dir;
    const cr_gdsr_data *both[2] = {&a, &b};
    cr_gdsr_train_result r;
    CR_CHECK_OK(cr_gdsr_train_many(&def, both, 2, &r, &err), &err);
    printf("  loss %.4g -> %.4g over %d epochs\n", r.first_loss, r.last_loss, r.epochs);
    CR_CHECK(r.epochs == def.epochs && r.last_loss < r.first_loss);
    snprintf(path, sizeof path, "%s/model.safetensors", dir);
    cr_gdsr_model *m = NULL;
    CR_CHECK_OK(cr_gdsr_model_load(path, &m, &err), &err);
    if (m) {
        CR_CHECK(cr_gdsr_model_get_def(m)->layer_edges == 1); /* auto: the outfit has two */
        for (int k = 0; k < 2; k++) {
            double med, med_up;
            rollout_distances(m, both[k], &med, &med_up);
            printf("  garment %d: MED %.5f m, upsampling %.5f m\n", k + 1, med, med_up);
            if (!cr_test_quick()) CR_CHECK(med < med_up);
        }
    }
    cr_gdsr_model_destroy(m);
    /* refused: no garment, and a garment with too few clips for val_clips */
    CR_CHECK(cr_gdsr_train_many(&def, both, 0, &r, &err) == CR_ERR_INVALID);
    def.val_clips = 1;
    CR_CHECK(cr_gdsr_train_many(&def, both, 2, &r, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "garment 1") != NULL);
    cr_gdsr_data_free(&a);
    cr_gdsr_data_free(&b);
}
