/* test_losses.c: physics energies as tape losses (crease/losses.h).
 *
 * For every energy: the op's gradient against central differences of its
 * own float32 forward (tests/nn_gradcheck.h; step and tolerance per test,
 * weights scaled so the largest gradient entry is about 10 and the check's
 * absolute floor of 1e-2 cannot hide an error), the op's value against
 * cr_assembly_eval on the same state (1e-6 relative, per term and item), the
 * same bits with 1 and 2 threads, and the errors of bad shapes and indices.
 */
#include "test.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "crease/bvh.h"
#include "crease/losses.h"
#include "crease/phys_assemble.h"
#include "crease/phys_energies.h"
#include "crease/primitives.h"
#include "crease/topology.h"
#include "nn_gradcheck.h"

/* B batch items, V vertices, H hinges. */

/* ------------------------------------------------------------ fixture -- */

typedef struct cloth {
    cr_mesh *m;
    cr_topology *topo;
    cr_material mat;
    cr_membrane *mem;
    cr_bending *bend;
    cr_gravity *grav;
    cr_pin *pin;
    int32_t V;
} cloth;

/* An n x n sheet of `size` m in the XZ plane with UV rest, bending with its
 * (flat) rest angles, gravity and a pin on two corners. */
static int cloth_make(cloth *c, int n, float size, cr_membrane_model model) {
    cr_error err;
    memset(c, 0, sizeof *c);
    CR_CHECK_OK(cr_material_preset("cotton", &c->mat, &err), &err);
    c->mat.membrane = model;
    c->mat.bending = 1e-2; /* stiffer than cloth, so bending gradients are not all rounding */
    const double g[3] = {0.0, -9.81, 0.0};
    CR_CHECK_OK(cr_prim_plane(n, n, size, size, &c->m, &err), &err);
    if (!c->m) return 0;
    c->V = c->m->nv;
    CR_CHECK_OK(cr_topology_build(c->m, &c->topo, &err), &err);
    CR_CHECK_OK(cr_membrane_create(c->m, 1, size, &c->mat, &c->mem, &err), &err);
    if (!c->topo || !c->mem) return 0;
    CR_CHECK_OK(cr_bending_create(c->m, c->topo, &c->mat, 0, &c->bend, &err), &err);
    CR_CHECK_OK(cr_gravity_create(c->m, &c->mat, g, &c->grav, &err), &err);
    const int32_t pins[2] = {0, n - 1};
    CR_CHECK_OK(cr_pin_create(c->V, pins, 2, 50.0, &c->pin, &err), &err);
    if (!c->bend || !c->grav || !c->pin) return 0;
    const double targets[6] = {c->m->pos[0],           0.05, c->m->pos[2],
                               c->m->pos[3 * (n - 1)], 0.05, c->m->pos[3 * (n - 1) + 2]};
    cr_pin_set_targets(c->pin, targets);
    return 1;
}

static void cloth_destroy(cloth *c) {
    cr_pin_destroy(c->pin);
    cr_gravity_destroy(c->grav);
    cr_bending_destroy(c->bend);
    cr_membrane_destroy(c->mem);
    cr_topology_destroy(c->topo);
    cr_mesh_destroy(c->m);
}

/* B states (B,V,3): the rest sheet stretched by a factor per item and
 * perturbed by `noise` m (seeded). */
static float *states(const cloth *c, int B, double noise, uint64_t seed) {
    float *x = malloc(sizeof(float) * 3 * (size_t)B * (size_t)c->V);
    cr_rng r = cr_rng_make(seed, 0);
    for (int b = 0; b < B; b++)
        for (int64_t i = 0; i < 3 * (int64_t)c->V; i++)
            x[3 * (int64_t)c->V * b + i] =
                (float)((1.0 + 0.05 * b) * c->m->pos[i] + noise * cr_rng_normal(&r));
    return x;
}

/* ------------------------------------------------- gradient checking -- */

typedef struct plain_job {
    cr_energy_term t;
    int per_element;
} plain_job;

static cr_tensor *build_plain(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    const plain_job *j = user;
    return j->per_element ? cr_loss_energy_per_element(ctx, &j->t, in[0])
                          : cr_loss_energy(ctx, &j->t, in[0]);
}

/* The smallest over the inputs that require grad of their largest |dE/dinput|
 * (one backward of sum(E)): the checks scale the weight by 10 over it, so
 * every input's gradient reaches about 10 or more. */
static double op_grad_max(nn_gradcheck_fn fn, void *user, int nin, nn_gradcheck_input *in) {
    cr_nn_ctx *ctx = nn_gradcheck_ctx((size_t)64 << 20);
    cr_error err;
    cr_tensor *t[4];
    for (int k = 0; k < nin; k++) {
        t[k] = cr_nn_wrap(ctx, in[k].ndim, in[k].shape, in[k].data);
        t[k]->requires_grad = (uint8_t)in[k].requires_grad;
    }
    cr_tensor *y = fn(ctx, t, user);
    CR_CHECK_OK(cr_nn_backward(ctx, cr_nn_sum(ctx, y), &err), &err);
    double least = INFINITY;
    for (int k = 0; k < nin; k++) {
        if (!in[k].requires_grad || !t[k]->grad) continue;
        double m = 0.0;
        for (int64_t i = 0; i < t[k]->numel; i++)
            m = fmax(m, fabs(t[k]->grad[i]));
        least = fmin(least, m);
    }
    cr_nn_ctx_destroy(ctx);
    return isfinite(least) ? least : 0.0;
}

static int64_t check_plain(const char *name, cr_energy_term t, int B, float *x, int32_t V,
                           int per_element, double step, double tol) {
    plain_job j = {t, per_element};
    nn_gradcheck_input in = nn_gradcheck_in(3, (int64_t[]){B, V, 3}, x);
    const double gmax = op_grad_max(build_plain, &j, 1, &in);
    CR_CHECK(gmax > 0.0);
    if (gmax > 0.0) j.t.weight = 10.0 / gmax;
    nn_gradcheck_def def = nn_gradcheck_default_def();
    def.name = name;
    def.step = step;
    def.tol = tol;
    def.arena_bytes = (size_t)32 << 20;
    nn_gradcheck_result res;
    const int64_t failed = nn_gradcheck(&def, 1, &in, NULL, build_plain, &j, &res);
    if (failed || getenv("CR_LOSSES_VERBOSE"))
        fprintf(stderr, "%s: %lld of %lld failed, max err %.3g\n", name, (long long)res.failed,
                (long long)res.checked, res.max_err);
    return failed;
}

CR_TEST(losses, gradient_plain_terms) {
    for (int model = 0; model < 2; model++) {
        cloth c;
        CR_REQUIRE(cloth_make(&c, 4, 0.3f, model ? CR_MEMBRANE_BARAFF_WITKIN : CR_MEMBRANE_STVK));
        float *x = states(&c, 2, 0.01, 7);
        const char *names[3][2] = {
            {"stvk", "baraff_witkin"}, {"stvk stretch", "bw stretch"}, {"stvk shear", "bw shear"}};
        for (int part = 0; part < 3; part++) {
            cr_energy_term t;
            cr_membrane_term_part(c.mem, (cr_membrane_part)part, &t);
            CR_CHECK(check_plain(names[part][model], t, 2, x, c.V, 0, 1e-3, 3e-3) == 0);
            CR_CHECK(check_plain(names[part][model], t, 2, x, c.V, 1, 1e-3, 3e-3) == 0);
        }
        cr_energy_term t;
        cr_bending_term(c.bend, &t);
        CR_CHECK(check_plain("bending", t, 2, x, c.V, 0, 1e-3, 3e-3) == 0);
        cr_gravity_term(c.grav, &t);
        CR_CHECK(check_plain("gravity", t, 2, x, c.V, 0, 1e-3, 3e-3) == 0);
        cr_pin_term(c.pin, &t);
        CR_CHECK(check_plain("pin", t, 2, x, c.V, 1, 1e-3, 3e-3) == 0);
        free(x);
        cloth_destroy(&c);
    }
}

/* ----------------------------------------------- value = simulator's -- */

/* The op's (B) values against cr_assembly_eval of the one term per item. */
static void check_value(const char *name, const cr_energy_term *t, int B, const float *x,
                        int32_t V) {
    cr_error err;
    cr_assembly *a = NULL;
    CR_CHECK_OK(cr_assembly_create(t, 1, V, &a, &err), &err);
    cr_nn_ctx *ctx = nn_gradcheck_ctx((size_t)32 << 20);
    CR_REQUIRE(a && ctx);
    cr_tensor *xt = cr_nn_from(ctx, 3, (int64_t[]){B, V, 3}, x);
    cr_tensor *e = cr_loss_energy(ctx, t, xt);
    CR_CHECK_OK(cr_nn_ctx_error(ctx, &err), &err);
    CR_REQUIRE(e && e->numel == B);
    double *xd = malloc(sizeof(double) * 3 * (size_t)V);
    for (int b = 0; b < B; b++) {
        for (int64_t i = 0; i < 3 * (int64_t)V; i++)
            xd[i] = x[3 * (int64_t)V * b + i];
        double tv = 0.0;
        const double total = cr_assembly_eval(a, t, xd, NULL, 0, &tv);
        CR_CHECK_NEAR(tv, total, 0.0);
        if (!(fabs(e->data[b] - tv) <= 1e-6 * fabs(tv)))
            cr_test_fail_here(__FILE__, __LINE__, "%s item %d: op %.9g, assembly %.9g", name, b,
                              (double)e->data[b], tv);
        CR_CHECK(tv != 0.0);
    }
    free(xd);
    cr_nn_ctx_destroy(ctx);
    cr_assembly_destroy(a);
}

CR_TEST(losses, value_equals_assembly) {
    for (int model = 0; model < 2; model++) {
        cloth c;
        CR_REQUIRE(cloth_make(&c, 6, 0.5f, model ? CR_MEMBRANE_BARAFF_WITKIN : CR_MEMBRANE_STVK));
        float *x = states(&c, 3, 0.02, 11);
        cr_energy_term t;
        for (int part = 0; part < 3; part++) {
            cr_membrane_term_part(c.mem, (cr_membrane_part)part, &t);
            t.weight = 0.5;
            check_value(t.name, &t, 3, x, c.V);
        }
        cr_bending_term(c.bend, &t);
        check_value("bending", &t, 3, x, c.V);
        cr_gravity_term(c.grav, &t);
        check_value("gravity", &t, 3, x, c.V);
        cr_pin_term(c.pin, &t);
        check_value("pin", &t, 3, x, c.V);
        free(x);
        cloth_destroy(&c);
    }
}

/* The two parts of each membrane sum to the whole, per element. */
CR_TEST(losses, membrane_parts_sum_to_whole) {
    for (int model = 0; model < 2; model++) {
        cloth c;
        CR_REQUIRE(cloth_make(&c, 5, 0.4f, model ? CR_MEMBRANE_BARAFF_WITKIN : CR_MEMBRANE_STVK));
        float *x = states(&c, 2, 0.02, 5);
        cr_nn_ctx *ctx = nn_gradcheck_ctx((size_t)16 << 20);
        cr_tensor *xt = cr_nn_from(ctx, 3, (int64_t[]){2, c.V, 3}, x);
        cr_energy_term t[3];
        cr_tensor *e[3];
        for (int p = 0; p < 3; p++) {
            cr_membrane_term_part(c.mem, (cr_membrane_part)p, &t[p]);
            e[p] = cr_loss_energy_per_element(ctx, &t[p], xt);
            CR_REQUIRE(e[p] && e[p]->ndim == 2 && e[p]->shape[0] == 2 && e[p]->shape[1] == c.m->nf);
        }
        double smax = 0.0, shmax = 0.0;
        for (int64_t k = 0; k < e[0]->numel; k++) {
            CR_CHECK_NEAR(e[1]->data[k] + e[2]->data[k], e[0]->data[k],
                          1e-6 * fabs(e[0]->data[k]) + 1e-12);
            smax = fmax(smax, e[1]->data[k]), shmax = fmax(shmax, e[2]->data[k]);
        }
        CR_CHECK(smax > 0.0 && shmax > 0.0); /* both parts present in this state */
        cr_nn_ctx_destroy(ctx);
        free(x);
        cloth_destroy(&c);
    }
}

/* ------------------------------------------------------ determinism -- */

/* Values and gradients of membrane, bending and bending with rest angles
 * (B,H) that require grad, on a 40 x 40 sheet (several parallel chunks per
 * loop), under a thread count: copied out for comparison. val (3B), grad
 * (B,V,3), rgrad (B,H). */
static void run_threads(const cloth *c, const float *x, int B, int threads, float *val, float *grad,
                        float *rgrad) {
    cr_error err;
    cr_set_thread_count(threads);
    cr_nn_ctx *ctx = nn_gradcheck_ctx((size_t)64 << 20);
    const int32_t H = cr_bending_count(c->bend);
    cr_tensor *xt = cr_nn_from(ctx, 3, (int64_t[]){B, c->V, 3}, x);
    cr_tensor *rt = cr_nn_zeros(ctx, 2, (int64_t[]){B, H});
    cr_rng r = cr_rng_make(77, 0);
    for (int64_t k = 0; k < rt->numel; k++)
        rt->data[k] = (float)(0.5 * cr_rng_uniform(&r) - 0.25);
    xt->requires_grad = rt->requires_grad = 1;
    cr_energy_term t[2];
    cr_membrane_term(c->mem, &t[0]);
    cr_bending_term(c->bend, &t[1]);
    cr_tensor *e[3] = {cr_loss_energy(ctx, &t[0], xt), cr_loss_energy(ctx, &t[1], xt),
                       cr_loss_bending(ctx, c->bend, 1.0, xt, rt)};
    cr_tensor *loss = cr_loss_weighted_sum(ctx, e, (float[]){1.0f, 100.0f, 50.0f}, 3, NULL);
    CR_CHECK_OK(cr_nn_backward(ctx, loss, &err), &err);
    if (e[0] && e[1] && e[2] && xt->grad && rt->grad) {
        for (int q = 0; q < 3; q++)
            memcpy(val + q * B, e[q]->data, sizeof(float) * (size_t)B);
        memcpy(grad, xt->grad, sizeof(float) * 3 * (size_t)B * (size_t)c->V);
        memcpy(rgrad, rt->grad, sizeof(float) * (size_t)B * (size_t)H);
    }
    cr_nn_ctx_destroy(ctx);
}

CR_TEST(losses, same_bits_any_thread_count) {
    cloth c;
    CR_REQUIRE(cloth_make(&c, 40, 1.0f, CR_MEMBRANE_STVK));
    const int B = 2;
    float *x = states(&c, B, 0.01, 3);
    const size_t ng = 3 * (size_t)B * (size_t)c.V, nr = (size_t)B * cr_bending_count(c.bend);
    float v1[6] = {0}, v2[6] = {1};
    float *g1 = calloc(ng, sizeof(float)), *g2 = calloc(ng, sizeof(float));
    float *r1 = calloc(nr, sizeof(float)), *r2 = calloc(nr, sizeof(float));
    const int before = cr_thread_count();
    run_threads(&c, x, B, 1, v1, g1, r1);
    run_threads(&c, x, B, 2, v2, g2, r2);
    cr_set_thread_count(before);
    CR_CHECK(memcmp(v1, v2, sizeof v1) == 0);
    CR_CHECK(memcmp(g1, g2, sizeof(float) * ng) == 0);
    CR_CHECK(memcmp(r1, r2, sizeof(float) * nr) == 0);
    double gm = 0.0, rm = 0.0;
    for (size_t i = 0; i < ng; i++)
        gm = fmax(gm, fabs(g1[i]));
    for (size_t i = 0; i < nr; i++)
        rm = fmax(rm, fabs(r1[i]));
    CR_CHECK(gm > 0.0 && rm > 0.0);
    free(g1), free(g2), free(r1), free(r2), free(x);
    cloth_destroy(&c);
}

/* ------------------------------------------------------------ errors -- */

static void expect_error(cr_nn_ctx *ctx, cr_tensor *y, cr_status want, const char *needle) {
    cr_error err;
    const cr_status st = cr_nn_ctx_error(ctx, &err);
    CR_CHECK(y == NULL);
    CR_CHECK(st == want);
    if (st != CR_OK && !strstr(err.msg, needle))
        cr_test_fail_here(__FILE__, __LINE__, "message '%s' lacks '%s'", err.msg, needle);
    cr_nn_ctx_reset(ctx);
}

CR_TEST(losses, bad_shapes_are_context_errors) {
    cloth c;
    CR_REQUIRE(cloth_make(&c, 4, 0.3f, CR_MEMBRANE_STVK));
    cr_nn_ctx *ctx = nn_gradcheck_ctx((size_t)16 << 20);
    cr_energy_term mem, grav;
    cr_membrane_term(c.mem, &mem);
    cr_gravity_term(c.grav, &grav);
    /* (V,2) */
    cr_tensor *x = cr_nn_zeros(ctx, 2, (int64_t[]){c.V, 2});
    expect_error(ctx, cr_loss_energy(ctx, &mem, x), CR_ERR_SHAPE, "loss_energy(membrane)");
    /* (B,V,3) with fewer vertices than the mesh: an index out of range */
    x = cr_nn_zeros(ctx, 3, (int64_t[]){2, c.V - 1, 3});
    expect_error(ctx, cr_loss_energy(ctx, &mem, x), CR_ERR_RANGE, "loss_energy(membrane)");
    /* a per-vertex term on the wrong vertex count */
    x = cr_nn_zeros(ctx, 2, (int64_t[]){c.V + 1, 3});
    expect_error(ctx, cr_loss_energy(ctx, &grav, x), CR_ERR_SHAPE, "loss_energy(gravity)");
    /* 4-D */
    x = cr_nn_zeros(ctx, 4, (int64_t[]){1, 2, c.V, 3});
    expect_error(ctx, cr_loss_energy(ctx, &grav, x), CR_ERR_SHAPE, "(B,V,3)");
    /* (V,3) works and gives (1); per element (nelem) */
    x = cr_nn_zeros(ctx, 2, (int64_t[]){c.V, 3});
    cr_tensor *e = cr_loss_energy(ctx, &mem, x), *pe = cr_loss_energy_per_element(ctx, &mem, x);
    CR_REQUIRE(e && pe);
    CR_CHECK(e->ndim == 1 && e->shape[0] == 1);
    CR_CHECK(pe->ndim == 1 && pe->shape[0] == c.m->nf);
    cr_nn_ctx_destroy(ctx);
    cloth_destroy(&c);
}

/* The weighted sum and its per-term reports. */
CR_TEST(losses, weighted_sum) {
    cr_nn_ctx *ctx = nn_gradcheck_ctx((size_t)1 << 20);
    cr_error err;
    cr_tensor *a = cr_nn_from(ctx, 1, (int64_t[]){2}, (float[]){1.0f, 2.0f});
    cr_tensor *b = cr_nn_from(ctx, 1, (int64_t[]){3}, (float[]){0.5f, 0.25f, 0.25f});
    a->requires_grad = b->requires_grad = 1;
    cr_tensor *w[2];
    cr_tensor *s = cr_loss_weighted_sum(ctx, (cr_tensor *[]){a, b}, (float[]){2.0f, -4.0f}, 2, w);
    CR_REQUIRE(s && w[0] && w[1]);
    CR_CHECK_NEAR(s->data[0], 2.0, 1e-6);
    CR_CHECK_NEAR(w[0]->data[0], 6.0, 1e-6);
    CR_CHECK_NEAR(w[1]->data[0], -4.0, 1e-6);
    CR_CHECK_OK(cr_nn_backward(ctx, s, &err), &err);
    CR_CHECK_NEAR(a->grad[1], 2.0, 0.0);
    CR_CHECK_NEAR(b->grad[2], -4.0, 0.0);
    cr_nn_ctx_destroy(ctx);
}

/* ------------------------------------------------- per-item variants -- */

/* Every per-item job starts with its weight, which the check rescales. */
typedef struct item_job {
    double weight;
    const cloth *c;
    const double *mass;
    double h;
    cr_loss_collider *col;
    const cr_material *mat;
} item_job;

static cr_tensor *build_bending(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    const item_job *j = user;
    return cr_loss_bending(ctx, j->c->bend, j->weight, in[0], in[1]);
}

static cr_tensor *build_residual(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    const item_job *j = user;
    return cr_loss_hinge_residual(ctx, j->c->bend, j->weight, in[0], in[1]);
}

static cr_tensor *build_inertia(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    const item_job *j = user;
    return cr_loss_inertia(ctx, j->mass, j->c->V, j->h, j->weight, in[0], in[1], in[2]);
}

/* in[1] is the body (B,V_b,3); the check perturbs it too, so it is given as
 * a constant input (requires_grad 0). */
static cr_tensor *build_collision(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    const item_job *j = user;
    return cr_loss_collision(ctx, j->col, j->mat, j->weight, in[0], in[1]);
}

static int64_t check_items(const char *name, nn_gradcheck_fn fn, item_job *j, int nin,
                           nn_gradcheck_input *in, double step, double tol) {
    j->weight = 1.0;
    const double gmax = op_grad_max(fn, j, nin, in);
    CR_CHECK(gmax > 0.0);
    if (gmax > 0.0) j->weight = 10.0 / gmax;
    nn_gradcheck_def def = nn_gradcheck_default_def();
    def.name = name;
    def.step = step;
    def.tol = tol;
    def.arena_bytes = (size_t)32 << 20;
    nn_gradcheck_result res;
    const int64_t failed = nn_gradcheck(&def, nin, in, NULL, fn, j, &res);
    if (failed || getenv("CR_LOSSES_VERBOSE"))
        fprintf(stderr, "%s: %lld of %lld failed, max err %.3g\n", name, (long long)res.failed,
                (long long)res.checked, res.max_err);
    return failed;
}

static float *random_angles(int64_t n, double amp, uint64_t seed) {
    float *r = malloc(sizeof(float) * (size_t)n);
    cr_rng g = cr_rng_make(seed, 1);
    for (int64_t i = 0; i < n; i++)
        r[i] = (float)(amp * (2.0 * cr_rng_uniform(&g) - 1.0));
    return r;
}

/* Hinge residuals: the values are the hinges' angles minus the rest, wrapped
 * (checked against cr_bending_angles, including a rest past pi), and the
 * gradients to x and to the rest match central differences. */
CR_TEST(losses, hinge_residual_values_and_gradients) {
    cloth c;
    CR_REQUIRE(cloth_make(&c, 4, 0.3f, CR_MEMBRANE_STVK));
    const int B = 2;
    const int32_t H = cr_bending_count(c.bend), V = c.V;
    float *x = states(&c, B, 0.01, 29), *rest = random_angles((int64_t)B * H, 0.4, 5);
    rest[3] += (float)(2.0 * M_PI); /* wraps back to the same residual */
    cr_nn_ctx *ctx = nn_gradcheck_ctx((size_t)8 << 20);
    cr_tensor *xt = cr_nn_wrap(ctx, 3, (int64_t[]){B, V, 3}, x);
    cr_tensor *rt = cr_nn_wrap(ctx, 2, (int64_t[]){B, H}, rest);
    cr_tensor *r = cr_loss_hinge_residual(ctx, c.bend, 2.0, xt, rt);
    cr_tensor *own = cr_loss_hinge_residual(ctx, c.bend, 1.0, xt, NULL);
    CR_REQUIRE(r && own && r->ndim == 2 && r->shape[0] == B && r->shape[1] == H);
    double *xd = malloc(sizeof(double) * 3 * (size_t)V), *th = malloc(sizeof(double) * (size_t)H);
    const double *rest0 = cr_bending_rest_angles(c.bend);
    double worst = 0, worst_own = 0, biggest = 0;
    for (int b = 0; b < B; b++) {
        for (int64_t i = 0; i < 3 * (int64_t)V; i++)
            xd[i] = x[3 * (int64_t)V * b + i];
        cr_bending_angles(c.bend, xd, th);
        for (int32_t h = 0; h < H; h++) {
            double want = th[h] - rest[(int64_t)b * H + h];
            want = remainder(want, 2.0 * M_PI);
            worst = fmax(worst, fabs(r->data[(int64_t)b * H + h] - 2.0 * want));
            worst_own = fmax(worst_own, fabs(own->data[(int64_t)b * H + h] - (th[h] - rest0[h])));
            biggest = fmax(biggest, fabs(want));
        }
    }
    CR_CHECK(worst < 1e-5 && worst_own < 1e-5);
    CR_CHECK(biggest > 0.1); /* the residuals are not all near zero */
    free(xd), free(th);
    cr_nn_ctx_destroy(ctx);
    item_job j = {.c = &c};
    nn_gradcheck_input in[2] = {nn_gradcheck_in(3, (int64_t[]){B, V, 3}, x),
                                nn_gradcheck_in(2, (int64_t[]){B, H}, rest)};
    for (int which = 0; which < 2; which++) {
        in[0].requires_grad = which == 0, in[1].requires_grad = which == 1;
        CR_CHECK(check_items(which ? "residual d/d(rest)" : "residual d/dx", build_residual, &j, 2,
                             in, 1e-3, 3e-3) == 0);
    }
    free(x), free(rest);
    cloth_destroy(&c);
}

CR_TEST(losses, gradient_bending_rest_per_item) {
    cloth c;
    CR_REQUIRE(cloth_make(&c, 4, 0.3f, CR_MEMBRANE_STVK));
    const int B = 3;
    const int32_t H = cr_bending_count(c.bend);
    float *x = states(&c, B, 0.01, 17), *rest = random_angles((int64_t)B * H, 0.4, 3);
    item_job j = {.c = &c};
    nn_gradcheck_input in[2] = {nn_gradcheck_in(3, (int64_t[]){B, c.V, 3}, x),
                                nn_gradcheck_in(2, (int64_t[]){B, H}, rest)};
    /* d/dx and d/d(rest) apart: each scaled to its own magnitude (dE/dx is
     * about 1/edge length times dE/d(rest)) */
    for (int which = 0; which < 2; which++) {
        in[0].requires_grad = which == 0, in[1].requires_grad = which == 1;
        CR_CHECK(check_items(which ? "bending d/d(rest (B,H))" : "bending d/dx, rest (B,H)",
                             build_bending, &j, 2, in, 1e-3, 3e-3) == 0);
    }
    in[0].requires_grad = 1;
    in[1] = nn_gradcheck_in(1, (int64_t[]){H}, rest); /* one set shared by the items */
    CR_CHECK(check_items("bending rest (H), both", build_bending, &j, 2, in, 1e-3, 1e-2) == 0);
    in[0].requires_grad = 0;
    CR_CHECK(check_items("bending d/d(rest (H))", build_bending, &j, 2, in, 1e-3, 3e-3) == 0);
    free(x), free(rest);
    cloth_destroy(&c);
}

CR_TEST(losses, gradient_inertia_three_states) {
    cloth c;
    CR_REQUIRE(cloth_make(&c, 4, 0.3f, CR_MEMBRANE_STVK));
    const int B = 2;
    float *x0 = states(&c, B, 0.02, 1), *x1 = states(&c, B, 0.02, 2), *x2 = states(&c, B, 0.02, 3);
    item_job j = {.c = &c, .mass = cr_gravity_masses(c.grav), .h = 1.0 / 30.0};
    const int64_t sh[3] = {B, c.V, 3};
    nn_gradcheck_input in[3] = {nn_gradcheck_in(3, sh, x0), nn_gradcheck_in(3, sh, x1),
                                nn_gradcheck_in(3, sh, x2)};
    CR_CHECK(check_items("inertia", build_inertia, &j, 3, in, 1e-3, 3e-3) == 0);
    free(x0), free(x1), free(x2);
    cloth_destroy(&c);
}

/* A body: an icosphere of radius 0.2 m at the origin, moved per item, and a
 * sheet of n x n vertices 0.1 m wide over its north pole whose heights
 * scatter through the contact band (inside, within eps, outside). */
typedef struct contact {
    cr_mesh *sphere;
    float *body; /* (B,V_b,3) */
    cr_loss_collider *col;
} contact;

static int contact_make(contact *k, int B) {
    cr_error err;
    memset(k, 0, sizeof *k);
    CR_CHECK_OK(cr_prim_icosphere(0.2f, 2, &k->sphere, &err), &err);
    if (!k->sphere) return 0;
    const int32_t Vb = k->sphere->nv;
    k->body = malloc(sizeof(float) * 3 * (size_t)B * (size_t)Vb);
    for (int b = 0; b < B; b++)
        for (int32_t i = 0; i < Vb; i++)
            for (int d = 0; d < 3; d++)
                k->body[3 * ((int64_t)Vb * b + i) + d] =
                    k->sphere->pos[3 * i + d] + (d == 0   ? 0.01f * b
                                                 : d == 1 ? 0.004f * b
                                                          : 0.0f);
    CR_CHECK_OK(
        cr_loss_collider_create(k->sphere->pos, Vb, k->sphere->tri, k->sphere->nf, &k->col, &err),
        &err);
    return k->col != NULL;
}

static void contact_destroy(contact *k) {
    cr_loss_collider_destroy(k->col);
    free(k->body);
    cr_mesh_destroy(k->sphere);
}

static float *sheet_over_pole(const cloth *c, int B, uint64_t seed) {
    float *x = malloc(sizeof(float) * 3 * (size_t)B * (size_t)c->V);
    cr_rng r = cr_rng_make(seed, 2);
    for (int b = 0; b < B; b++)
        for (int32_t i = 0; i < c->V; i++) {
            float *p = x + 3 * ((int64_t)c->V * b + i);
            /* off the pole, so no vertex sits on the distance's kinks
               (the medial axis under the pole vertex) */
            p[0] = c->m->pos[3 * i] + 0.013f + 0.01f * b;
            p[2] = c->m->pos[3 * i + 2] + 0.007f;
            /* the sphere's surface height here, plus -8..+15 mm */
            const double r2 = (double)p[0] * p[0] + (double)p[2] * p[2];
            p[1] = (float)(sqrt(0.04 - r2) + 0.004 * b - 0.008 + 0.023 * cr_rng_uniform(&r));
        }
    return x;
}

CR_TEST(losses, gradient_collision_per_item_body) {
    cloth c;
    contact k;
    CR_REQUIRE(cloth_make(&c, 5, 0.1f, CR_MEMBRANE_STVK));
    const int B = 2;
    CR_REQUIRE(contact_make(&k, B));
    cr_material mat = c.mat;
    mat.collision_thickness = 0.01; /* wide enough for the step */
    float *x = sheet_over_pole(&c, B, 9);
    item_job j = {.c = &c, .col = k.col, .mat = &mat};
    nn_gradcheck_input in[2] = {
        nn_gradcheck_in(3, (int64_t[]){B, c.V, 3}, x),
        {.ndim = 3, .shape = {B, k.sphere->nv, 3}, .data = k.body, .requires_grad = 0}};
    CR_CHECK(check_items("collision", build_collision, &j, 2, in, 2e-4, 3e-3) == 0);
    free(x);
    contact_destroy(&k);
    cloth_destroy(&c);
}

/* With the cloth's edges the penalty starts at eps + the chord sag: a coarse
 * sphere (42 vertices) 1 mm outside a fine one. The value is k max(m_i - d_i,
 * 0)^3 summed, m_i = eps + the largest sag of vertex i's edges with the exact
 * sphere's normals (the fine sphere's smooth normals are within its facets'
 * error of them: 1 %); without edges, k (eps - 1 mm)^3 per vertex. The
 * gradient pushes every vertex outward, as the true distance's sign says
 * (the sag put a vertex's taken distance below 0 while it lay outside, and
 * a sign from that pulled it in). A garment of another vertex count is
 * refused. */
CR_TEST(losses, collision_with_edges_holds_the_faces) {
    cr_error err;
    const float R = 0.3f;
    cr_mesh *body = NULL, *g = NULL;
    CR_CHECK_OK(cr_prim_icosphere(R, 4, &body, &err), &err);
    CR_CHECK_OK(cr_prim_icosphere(R + 0.001f, 1, &g, &err), &err);
    CR_REQUIRE(body && g);
    cr_topology *topo = NULL;
    CR_CHECK_OK(cr_topology_build(g, &topo, &err), &err);
    CR_REQUIRE(topo);
    cr_material mat;
    CR_CHECK_OK(cr_material_preset("cotton", &mat, &err), &err);
    const double k = mat.collision_stiffness, eps = mat.collision_thickness;
    const int32_t V = g->nv;
    double want_plain = 0.0, want = 0.0;
    double *m = malloc(sizeof(double) * (size_t)V);
    for (int32_t i = 0; i < V; i++)
        m[i] = eps;
    for (int32_t e = 0; e < topo->ne; e++) {
        const int32_t a = topo->edge[2 * e], b = topo->edge[2 * e + 1];
        double xa[3], xb[3], na[3], nb[3];
        for (int d = 0; d < 3; d++)
            xa[d] = g->pos[3 * a + d], xb[d] = g->pos[3 * b + d];
        for (int d = 0; d < 3; d++)
            na[d] = xa[d] / (R + 0.001), nb[d] = xb[d] / (R + 0.001);
        const double sag = cr_collision_chord_sag(xa, na, xb, nb);
        m[a] = fmax(m[a], eps + sag), m[b] = fmax(m[b], eps + sag);
    }
    cr_bvh *bvh = NULL;
    CR_CHECK_OK(cr_bvh_build(body->pos, body->nv, body->tri, body->nf, &bvh, &err), &err);
    CR_REQUIRE(bvh);
    for (int32_t i = 0; i < V; i++) {
        float d;
        cr_bvh_signed_distance(bvh, g->pos + 3 * i, INFINITY, &d, NULL, NULL);
        want_plain += k * pow(fmax(eps - d, 0.0), 3);
        want += k * pow(fmax(m[i] - d, 0.0), 3);
    }
    cr_bvh_destroy(bvh);
    cr_loss_collider *col = NULL;
    CR_CHECK_OK(cr_loss_collider_create(body->pos, body->nv, body->tri, body->nf, &col, &err),
                &err);
    CR_REQUIRE(col);
    cr_nn_ctx *ctx = nn_gradcheck_ctx((size_t)16 << 20);
    cr_tensor *x = cr_nn_from(ctx, 2, (int64_t[]){V, 3}, g->pos);
    cr_tensor *plain = cr_loss_collision(ctx, col, &mat, 1.0, x, NULL);
    CR_CHECK_OK(cr_loss_collider_set_edges(col, topo->edge, topo->ne, V, &err), &err);
    x->requires_grad = 1;
    cr_tensor *held = cr_loss_collision(ctx, col, &mat, 1.0, x, NULL);
    CR_CHECK_OK(cr_nn_backward(ctx, held, &err), &err);
    CR_REQUIRE(plain && held && x->grad);
    printf("    42 vertices 1 mm out: penalty %.4g J without the edges (want %.4g), %.4g J with "
           "them (want %.4g)\n",
           (double)plain->data[0], want_plain, (double)held->data[0], want);
    CR_CHECK(fabs(plain->data[0] - want_plain) <= 1e-4 * want_plain);
    CR_CHECK(fabs(held->data[0] - want) <= 0.01 * want);
    CR_CHECK(want > 100.0 * want_plain);
    int outward = 1;
    for (int32_t i = 0; i < V; i++) {
        const float *gi = x->grad + 3 * i, *p = g->pos + 3 * i;
        outward &= gi[0] * p[0] + gi[1] * p[1] + gi[2] * p[2] < 0.0f;
    }
    CR_CHECK(outward);
    cr_tensor *x2 = cr_nn_from(ctx, 2, (int64_t[]){V - 1, 3}, g->pos);
    CR_CHECK(cr_loss_collision(ctx, col, &mat, 1.0, x2, NULL) == NULL);
    CR_CHECK(cr_nn_ctx_error(ctx, &err) == CR_ERR_SHAPE && strstr(err.msg, "edges are over 42"));
    cr_nn_ctx_destroy(ctx);
    cr_loss_collider_destroy(col);
    free(m);
    cr_topology_destroy(topo);
    cr_mesh_destroy(g), cr_mesh_destroy(body);
}

/* Per-item values against the simulator's terms set up for each item. */
CR_TEST(losses, per_item_values_equal_assembly) {
    cr_error err;
    cloth c;
    contact k;
    CR_REQUIRE(cloth_make(&c, 5, 0.1f, CR_MEMBRANE_STVK));
    const int B = 2;
    CR_REQUIRE(contact_make(&k, B));
    const int32_t V = c.V, H = cr_bending_count(c.bend);
    float *x = sheet_over_pole(&c, B, 4), *xp = states(&c, B, 0.01, 5),
          *xpp = states(&c, B, 0.01, 6), *rest = random_angles((int64_t)B * H, 0.4, 8);
    const double h = 1.0 / 30.0;
    cr_nn_ctx *ctx = nn_gradcheck_ctx((size_t)16 << 20);
    const int64_t sh[3] = {B, V, 3};
    cr_tensor *xt = cr_nn_from(ctx, 3, sh, x), *xpt = cr_nn_from(ctx, 3, sh, xp),
              *xppt = cr_nn_from(ctx, 3, sh, xpp);
    cr_tensor *rt = cr_nn_from(ctx, 2, (int64_t[]){B, H}, rest);
    cr_tensor *bt = cr_nn_from(ctx, 3, (int64_t[]){B, k.sphere->nv, 3}, k.body);
    cr_tensor *eb = cr_loss_bending(ctx, c.bend, 2.0, xt, rt);
    cr_tensor *ei = cr_loss_inertia(ctx, cr_gravity_masses(c.grav), V, h, 2.0, xt, xpt, xppt);
    cr_tensor *ec = cr_loss_collision(ctx, k.col, &c.mat, 2.0, xt, bt);
    CR_CHECK_OK(cr_nn_ctx_error(ctx, &err), &err);
    CR_REQUIRE(eb && ei && ec);

    cr_inertia *in = NULL;
    cr_collision *col = NULL;
    CR_CHECK_OK(cr_inertia_create(cr_gravity_masses(c.grav), V, &in, &err), &err);
    CR_CHECK_OK(cr_collision_create(V, &c.mat, &col, &err), &err);
    CR_REQUIRE(in && col);
    cr_energy_term t[3];
    cr_bending_term(c.bend, &t[0]);
    cr_inertia_term(in, &t[1]);
    cr_collision_term(col, &t[2]);
    for (int q = 0; q < 3; q++)
        t[q].weight = 2.0;
    cr_assembly *a = NULL;
    CR_CHECK_OK(cr_assembly_create(t, 3, V, &a, &err), &err);
    CR_REQUIRE(a);
    double *xd = malloc(sizeof(double) * 3 * (size_t)V),
           *pred = malloc(sizeof(double) * 3 * (size_t)V);
    float *dist = malloc(sizeof(float) * (size_t)V), *nrm = malloc(sizeof(float) * 3 * (size_t)V);
    double *rest_b = cr_bending_rest_angles(c.bend);
    double saved_rest0 = rest_b[0];
    for (int b = 0; b < B; b++) {
        const int64_t o = 3 * (int64_t)V * b;
        for (int64_t i = 0; i < 3 * (int64_t)V; i++) {
            xd[i] = x[o + i];
            pred[i] = 2.0 * xp[o + i] - xpp[o + i];
        }
        for (int32_t e = 0; e < H; e++)
            rest_b[e] = rest[(int64_t)H * b + e];
        cr_inertia_set(in, pred, h);
        cr_bvh *bvh = NULL;
        CR_CHECK_OK(cr_bvh_build(k.body + 3 * (int64_t)k.sphere->nv * b, k.sphere->nv,
                                 k.sphere->tri, k.sphere->nf, &bvh, &err),
                    &err);
        CR_REQUIRE(bvh);
        cr_bvh_signed_distance_batch(bvh, x + o, V, INFINITY, dist, nrm, NULL);
        cr_bvh_destroy(bvh);
        cr_collision_update(col, xd, dist, nrm);
        double tv[3];
        cr_assembly_eval(a, t, xd, NULL, 0, tv);
        const float op[3] = {eb->data[b], ei->data[b], ec->data[b]};
        for (int q = 0; q < 3; q++) {
            CR_CHECK(tv[q] > 0.0);
            if (!(fabs(op[q] - tv[q]) <= 1e-6 * fabs(tv[q])))
                cr_test_fail_here(__FILE__, __LINE__, "%s item %d: op %.9g, assembly %.9g",
                                  t[q].name, b, (double)op[q], tv[q]);
        }
    }
    rest_b[0] = saved_rest0;
    free(xd), free(pred), free(dist), free(nrm);
    cr_assembly_destroy(a);
    cr_collision_destroy(col);
    cr_inertia_destroy(in);
    cr_nn_ctx_destroy(ctx);
    free(x), free(xp), free(xpp), free(rest);
    contact_destroy(&k);
    cloth_destroy(&c);
}

CR_TEST(losses, per_item_bad_shapes) {
    cloth c;
    contact k;
    CR_REQUIRE(cloth_make(&c, 4, 0.3f, CR_MEMBRANE_STVK));
    CR_REQUIRE(contact_make(&k, 2));
    cr_nn_ctx *ctx = nn_gradcheck_ctx((size_t)16 << 20);
    const int32_t V = c.V, H = cr_bending_count(c.bend);
    cr_tensor *x = cr_nn_zeros(ctx, 3, (int64_t[]){2, V, 3});
    cr_tensor *r = cr_nn_zeros(ctx, 2, (int64_t[]){3, H});
    expect_error(ctx, cr_loss_bending(ctx, c.bend, 1.0, x, r), CR_ERR_SHAPE,
                 "loss_energy(bending)");
    x = cr_nn_zeros(ctx, 3, (int64_t[]){2, V, 3});
    cr_tensor *y = cr_nn_zeros(ctx, 3, (int64_t[]){1, V, 3});
    expect_error(ctx, cr_loss_inertia(ctx, cr_gravity_masses(c.grav), V, 0.1, 1.0, x, x, y),
                 CR_ERR_SHAPE, "loss_energy(inertia)");
    x = cr_nn_zeros(ctx, 3, (int64_t[]){2, V, 3});
    expect_error(ctx, cr_loss_inertia(ctx, cr_gravity_masses(c.grav), V - 1, 0.1, 1.0, x, x, x),
                 CR_ERR_SHAPE, "loss_energy(inertia)");
    x = cr_nn_zeros(ctx, 3, (int64_t[]){2, V, 3});
    expect_error(ctx, cr_loss_inertia(ctx, cr_gravity_masses(c.grav), V, 0.0, 1.0, x, x, x),
                 CR_ERR_INVALID, "step h");
    x = cr_nn_zeros(ctx, 3, (int64_t[]){2, V, 3});
    cr_tensor *body = cr_nn_zeros(ctx, 3, (int64_t[]){3, k.sphere->nv, 3});
    expect_error(ctx, cr_loss_collision(ctx, k.col, &c.mat, 1.0, x, body), CR_ERR_SHAPE,
                 "loss_energy(collision): body");
    x = cr_nn_full(ctx, 3, (int64_t[]){2, V, 3}, NAN);
    expect_error(ctx, cr_loss_collision(ctx, k.col, &c.mat, 1.0, x, NULL), CR_ERR_NAN,
                 "not finite");
    cr_nn_ctx_destroy(ctx);
    contact_destroy(&k);
    cloth_destroy(&c);
}
