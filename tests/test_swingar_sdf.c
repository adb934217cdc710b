/* test_swingar_sdf.c: SwinGar's neural collision removal (paper 002, sec.
 * III-D): the SDF network fitted to a sphere is an SDF (unit gradient, right
 * sign), the eq. 8-9 loss differentiates correctly through the input
 * gradient, eq. 10 clears an analytic sphere without touching free vertices,
 * the BVH source does the same on a mesh, and training resumes bit-exactly. */
#include "methods/swingar/sdf.h"

#include "crease/bvh.h"
#include "crease/nn_optim.h"
#include "crease/primitives.h"
#include "nn_gradcheck.h"
#include "test.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { SPHERE_BATCH = 256, SPHERE_STEPS = 800 };
static const float SPHERE_R = 0.3f; /* the fitted sphere, m (the init is 0.5) */

static float vlen(const float *v) {
    return sqrtf(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
}

/* Half the batch on the sphere, a quarter near it, a quarter in the box. */
static void sphere_batch(cr_rng *rng, float *x, float *s, float *n) {
    for (int i = 0; i < SPHERE_BATCH; i++) {
        float *p = &x[3 * i];
        if (i < 3 * SPHERE_BATCH / 4) {
            float v[3] = {(float)cr_rng_normal(rng), (float)cr_rng_normal(rng),
                          (float)cr_rng_normal(rng)};
            float l = vlen(v), r = SPHERE_R;
            if (i >= SPHERE_BATCH / 2) r += 0.05f * (float)cr_rng_normal(rng);
            for (int k = 0; k < 3; k++)
                p[k] = r * v[k] / l;
        } else {
            for (int k = 0; k < 3; k++)
                p[k] = -0.6f + 1.2f * cr_rng_uniformf(rng);
        }
        float l = vlen(p);
        s[i] = l - SPHERE_R;
        for (int k = 0; k < 3; k++)
            n[3 * i + k] = p[k] / l;
    }
}

static cr_swingar_sdf *fit_sphere(int steps) {
    cr_error err = {0};
    cr_swingar_sdf_def d = cr_swingar_sdf_default_def();
    d.width = 32;
    d.cond_dim = 0;
    cr_swingar_sdf *net = NULL;
    CR_CHECK_OK(cr_swingar_sdf_create(&d, &net, &err), &err);
    if (!net) return NULL;
    cr_optim_def od = cr_optim_default_def(CR_OPTIM_ADAM);
    od.lr.kind = CR_LR_COSINE;
    od.lr.base = 2e-3f;
    od.lr.final = 1e-5f;
    od.lr.total_steps = steps > 0 ? steps : 1;
    cr_optim *opt = NULL;
    CR_CHECK_OK(cr_optim_create(&od, cr_swingar_sdf_params(net), &opt, &err), &err);
    cr_nn_ctx_def cd = cr_nn_ctx_default_def();
    cd.arena_bytes = (size_t)64 << 20;
    cr_nn_ctx *ctx = NULL;
    CR_CHECK_OK(cr_nn_ctx_create(&cd, &ctx, &err), &err);
    cr_rng rng = cr_rng_make(7, 0);
    float x[3 * SPHERE_BATCH], s[SPHERE_BATCH], n[3 * SPHERE_BATCH];
    /* the tangents of this small net, (256,3,32), sit just above the engine's
     * parallel threshold, where waking OpenMP threads costs more than the
     * work: on a loaded machine 800 steps took minutes instead of seconds */
    int threads = cr_thread_count();
    cr_set_thread_count(1);
    for (int it = 0; ctx && opt && it < steps; it++) {
        sphere_batch(&rng, x, s, n);
        cr_nn_ctx_reset(ctx);
        cr_tensor *xt = cr_nn_wrap(ctx, 2, (int64_t[]){SPHERE_BATCH, 3}, x);
        cr_tensor *st = cr_nn_wrap(ctx, 2, (int64_t[]){SPHERE_BATCH, 1}, s);
        cr_tensor *nt = cr_nn_wrap(ctx, 2, (int64_t[]){SPHERE_BATCH, 3}, n);
        cr_tensor *loss = cr_swingar_sdf_loss(ctx, net, xt, NULL, NULL, st, nt, 0.15f, NULL);
        cr_nn_params_zero_grad(cr_swingar_sdf_params(net));
        CR_CHECK_OK(cr_nn_backward(ctx, loss, &err), &err);
        CR_CHECK_OK(cr_optim_step(opt, &err), &err);
    }
    cr_set_thread_count(threads);
    cr_nn_ctx_destroy(ctx);
    cr_optim_destroy(opt);
    return net;
}

/* Worst |grad| deviation from 1 and sign errors at shells around the sphere
 * (clear of the centre, where the SDF has its kink, and of the surface). */
static void sphere_check(cr_swingar_sdf *net, double *max_dev, int *wrong_sign) {
    enum { N = 600 };
    float x[3 * N], s[N], g[3 * N], want[N];
    cr_rng rng = cr_rng_make(99, 1);
    for (int i = 0; i < N; i++) {
        float v[3] = {(float)cr_rng_normal(&rng), (float)cr_rng_normal(&rng),
                      (float)cr_rng_normal(&rng)};
        float l = vlen(v), r = 0.15f + 0.35f * (float)i / (N - 1);
        if (fabsf(r - SPHERE_R) < 0.02f) r += 0.04f;
        for (int k = 0; k < 3; k++)
            x[3 * i + k] = r * v[k] / l;
        want[i] = r - SPHERE_R;
    }
    cr_error err = {0};
    CR_CHECK_OK(cr_swingar_sdf_eval(net, x, N, NULL, s, g, &err), &err);
    *max_dev = 0;
    *wrong_sign = 0;
    for (int i = 0; i < N; i++) {
        double dev = fabs(vlen(&g[3 * i]) - 1.0);
        *max_dev = dev > *max_dev ? dev : *max_dev;
        if ((s[i] < 0) != (want[i] < 0)) (*wrong_sign)++;
    }
}

CR_TEST(swingar_sdf, sphere_fit_is_an_sdf) {
    /* the untrained net is a sphere of radius 0.5, so the shell between 0.3
     * and 0.5 has the wrong sign: the check can fail */
    cr_swingar_sdf *net0 = fit_sphere(0);
    double dev0;
    int wrong0;
    sphere_check(net0, &dev0, &wrong0);
    CR_CHECK(wrong0 > 100);
    cr_swingar_sdf_destroy(net0);

    cr_swingar_sdf *net = fit_sphere(SPHERE_STEPS);
    CR_REQUIRE(net);
    double dev;
    int wrong;
    sphere_check(net, &dev, &wrong);
    printf("  sphere fit: max | |grad S| - 1 | = %.4f, wrong signs %d / 600\n", dev, wrong);
    CR_CHECK(dev < 0.05);
    CR_CHECK(wrong == 0);
    /* the gradient the eval reports is the one the loss trains: compare with
     * central differences of S */
    float p[3] = {0.21f, -0.17f, 0.12f}, g[3], s0;
    cr_error err = {0};
    CR_CHECK_OK(cr_swingar_sdf_eval(net, p, 1, NULL, &s0, g, &err), &err);
    for (int k = 0; k < 3; k++) {
        float a[3] = {p[0], p[1], p[2]}, b[3] = {p[0], p[1], p[2]}, sa, sb;
        a[k] += 1e-3f, b[k] -= 1e-3f;
        cr_swingar_sdf_eval(net, a, 1, NULL, &sa, NULL, &err);
        cr_swingar_sdf_eval(net, b, 1, NULL, &sb, NULL, &err);
        CR_CHECK_NEAR(g[k], (sa - sb) / (a[k] - b[k]), 2e-2);
    }
    cr_swingar_sdf_destroy(net);
}

/* ----------------------------------------------------- loss gradients -- */

typedef struct loss_case {
    cr_swingar_sdf *net;
    int32_t row[6];
} loss_case;

/* in: x (6,3), cond (2,3), s (6,1), n (6,3), and for an articulated net the
 * joint frames (2,264), constants appended to the conditioning rows */
static cr_tensor *build_loss(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    loss_case *lc = user;
    cr_tensor *c = in[1];
    if (cr_swingar_sdf_get_def(lc->net)->articulated)
        c = cr_nn_concat(ctx, 2, (cr_tensor *const[]){in[1], in[4]}, 1);
    return cr_swingar_sdf_loss(ctx, lc->net, in[0], c, lc->row, in[2], in[3], 0.15f, NULL);
}

/* Two joint-frame records of random poses about random joints. */
static void random_frames(float *fr, uint64_t seed) {
    float joints[3 * CR_NJOINTS], pose[3 * CR_NJOINTS], rec[CR_SWINGAR_SDF_COND_MAX];
    for (int q = 0; q < 2; q++) {
        nn_gradcheck_fill(joints, 3 * CR_NJOINTS, -0.5f, 0.5f, 0.0f, seed + 2 * (uint64_t)q);
        nn_gradcheck_fill(pose, 3 * CR_NJOINTS, -0.6f, 0.6f, 0.0f, seed + 2 * (uint64_t)q + 1);
        cr_swingar_sdf_condition(NULL, joints, pose, rec);
        memcpy(&fr[q * CR_SWINGAR_SDF_FRAME_DIM], &rec[CR_SWINGAR_SDF_COND_DIM],
               CR_SWINGAR_SDF_FRAME_DIM * sizeof(float));
    }
}

static void check_loss_gradients(int articulated) {
    /* small, smooth (beta 10) net so central differences resolve the
     * second derivatives the normal and eikonal terms bring in */
    cr_swingar_sdf_def d = cr_swingar_sdf_default_def();
    d.width = 6;
    d.cond_dim = 3;
    d.articulated = articulated;
    d.softplus_beta = 10.0f;
    d.scale = 0.8f;
    d.center[1] = 0.1f;
    cr_error err = {0};
    loss_case lc = {.row = {0, 1, 1, 0, 1, 0}};
    CR_CHECK_OK(cr_swingar_sdf_create(&d, &lc.net, &err), &err);
    CR_REQUIRE(lc.net);
    /* the fusion block of the body branch starts at zero; give it values so
     * every path carries gradient */
    cr_tensor *wq = cr_nn_params_find(cr_swingar_sdf_params(lc.net), "fuse.0.weight_q");
    CR_REQUIRE(wq);
    cr_rng rng = cr_rng_make(3, 0);
    cr_nn_fill_uniform(wq, &rng, -0.5f, 0.5f);
    float x[18], c[6], s[6], n[18];
    nn_gradcheck_fill(x, 18, -0.6f, 0.6f, 0.0f, 11);
    nn_gradcheck_fill(c, 6, -0.5f, 0.5f, 0.0f, 12);
    nn_gradcheck_fill(s, 6, -3.0f, 3.0f, 0.0f, 13); /* far from S: |S - s| stays off its kink */
    nn_gradcheck_fill(n, 18, -1.0f, 1.0f, 0.0f, 14);
    float fr[2 * CR_SWINGAR_SDF_FRAME_DIM];
    random_frames(fr, 21);
    nn_gradcheck_input in[5] = {{2, {6, 3}, x, 1},
                                {2, {2, 3}, c, 1},
                                {2, {6, 1}, s, 1},
                                {2, {6, 3}, n, 1},
                                {2, {2, CR_SWINGAR_SDF_FRAME_DIM}, fr, 0}};
    nn_gradcheck_def gd = nn_gradcheck_default_def();
    gd.name = articulated ? "swingar sdf loss, articulated" : "swingar sdf loss";
    gd.seed = 5;
    nn_gradcheck_result r;
    CR_CHECK(nn_gradcheck(&gd, articulated ? 5 : 4, in, cr_swingar_sdf_params(lc.net), build_loss,
                          &lc, &r) == 0);
    CR_CHECK(r.checked > (articulated ? 300 : 100));
    cr_swingar_sdf_destroy(lc.net);
}

CR_TEST(swingar_sdf, loss_gradients_match_finite_differences) {
    check_loss_gradients(0);
}

CR_TEST(swingar_sdf, articulated_loss_gradients_match_finite_differences) {
    check_loss_gradients(1);
    check_loss_gradients(2);
}

/* An articulated net sees a point through the joints' rest frames: turning
 * the whole body (joint 0 only) about the root turns the field with it, and
 * the evaluated gradient is the derivative of S. */
static void check_follows_joints(int articulated) {
    cr_swingar_sdf_def d = cr_swingar_sdf_default_def();
    d.width = 16;
    d.articulated = articulated;
    d.center[1] = 1.0f;
    cr_error err = {0};
    cr_swingar_sdf *net = NULL;
    CR_CHECK_OK(cr_swingar_sdf_create(&d, &net, &err), &err);
    CR_REQUIRE(net);
    /* every weight random, the body branch's fusion block included */
    cr_rng rng = cr_rng_make(9, 0);
    int64_t np;
    float *w = cr_nn_params_data(cr_swingar_sdf_params(net), &np);
    for (int64_t i = 0; i < np; i++)
        w[i] += 0.2f * (float)cr_rng_normal(&rng);
    float joints[3 * CR_NJOINTS], pose[3 * CR_NJOINTS] = {0.3f, -0.8f, 0.2f};
    nn_gradcheck_fill(joints, 3 * CR_NJOINTS, -0.4f, 0.4f, 0.0f, 4);
    const float *root = joints;
    float c_rest[CR_SWINGAR_SDF_COND_MAX], c_turn[CR_SWINGAR_SDF_COND_MAX];
    cr_swingar_sdf_condition(NULL, joints, NULL, c_rest);
    cr_swingar_sdf_condition(NULL, joints, pose, c_turn);
    /* the body branch sees the pose too; give both the same c so only the
     * frames differ */
    memcpy(c_turn, c_rest, CR_SWINGAR_SDF_COND_DIM * sizeof(float));
    float rot[9];
    cr_body_rodrigues(pose, rot);
    double worst = 0, worst_g = 0;
    for (int i = 0; i < 20; i++) {
        float u[3], x[3], su, sx, g[3];
        for (int k = 0; k < 3; k++)
            u[k] = root[k] + 0.5f * (float)cr_rng_normal(&rng);
        for (int r = 0; r < 3; r++) /* x = root + R (u - root) */
            x[r] = root[r] + rot[3 * r] * (u[0] - root[0]) + rot[3 * r + 1] * (u[1] - root[1]) +
                   rot[3 * r + 2] * (u[2] - root[2]);
        CR_CHECK_OK(cr_swingar_sdf_eval(net, u, 1, c_rest, &su, NULL, &err), &err);
        CR_CHECK_OK(cr_swingar_sdf_eval(net, x, 1, c_turn, &sx, g, &err), &err);
        worst = fmax(worst, fabs((double)su - sx));
        for (int k = 0; k < 3; k++) {
            float a[3] = {x[0], x[1], x[2]}, b[3] = {x[0], x[1], x[2]}, sa, sb;
            a[k] += 1e-3f, b[k] -= 1e-3f;
            cr_swingar_sdf_eval(net, a, 1, c_turn, &sa, NULL, &err);
            cr_swingar_sdf_eval(net, b, 1, c_turn, &sb, NULL, &err);
            double fd = (sa - sb) / (a[k] - b[k]);
            worst_g = fmax(worst_g, fabs(fd - g[k]) / fmax(1.0, fabs(fd)));
        }
    }
    CR_CHECK(worst < 1e-4);
    CR_CHECK(worst_g < 2e-2);
    /* not a field that ignores the pose: the same point reads differently */
    float p0[3] = {0.3f, 1.2f, 0.1f}, s0, s1;
    cr_swingar_sdf_eval(net, p0, 1, c_rest, &s0, NULL, &err);
    cr_swingar_sdf_eval(net, p0, 1, c_turn, &s1, NULL, &err);
    CR_CHECK(fabs((double)s0 - s1) > 1e-3);
    cr_swingar_sdf_destroy(net);
}

CR_TEST(swingar_sdf, articulated_field_follows_the_joints) {
    check_follows_joints(1);
    check_follows_joints(2);
}

/* --------------------------------------------------- collision removal -- */

typedef struct sphere_sdf {
    float r;
    float gain; /* S = gain (|x| - r); 0 reads as 1 */
    int calls;
} sphere_sdf;

static cr_status sphere_eval(void *user, const float *x, int64_t n, float *s, float *grad,
                             cr_error *err) {
    (void)err;
    sphere_sdf *u = user;
    u->calls++;
    for (int64_t i = 0; i < n; i++) {
        float l = vlen(&x[3 * i]);
        s[i] = (u->gain > 0 ? u->gain : 1.0f) * (l - u->r);
        if (grad)
            for (int k = 0; k < 3; k++)
                grad[3 * i + k] = 2.0f * x[3 * i + k]; /* any length: it is normalised */
    }
    return CR_OK;
}

CR_TEST(swingar_sdf, removal_clears_an_analytic_sphere) {
    cr_error err = {0};
    cr_mesh *m = NULL;
    CR_CHECK_OK(cr_prim_icosphere(1.0f, 3, &m, &err), &err);
    CR_REQUIRE(m);
    cr_topology *topo = NULL;
    CR_CHECK_OK(cr_topology_build(m, &topo, &err), &err);
    CR_REQUIRE(topo);
    const float r = 0.5f, out_r = 0.51f;
    /* a "garment" at 1 cm outside the sphere with a dent reaching up to 4 cm inside */
    int64_t nv = m->nv, inside = 0;
    float *pos = malloc((size_t)nv * 3 * sizeof(float));
    float *before = malloc((size_t)nv * 3 * sizeof(float));
    CR_REQUIRE(pos && before);
    for (int64_t i = 0; i < nv; i++) {
        const float *p = &m->pos[3 * i];
        float dent = p[1] > 0.7f ? (p[1] - 0.7f) / 0.3f : 0.0f;
        float rad = out_r - 0.05f * dent;
        for (int k = 0; k < 3; k++)
            pos[3 * i + k] = rad * p[k];
        inside += rad < r;
    }
    memcpy(before, pos, (size_t)nv * 3 * sizeof(float));
    sphere_sdf u = {.r = r};
    cr_swingar_sdf_source src = {.eval = sphere_eval, .user = &u};
    cr_swingar_collide_def cd = cr_swingar_collide_default_def();
    cr_swingar_collide_stats stats;
    CR_CHECK_OK(cr_swingar_collision_remove(&cd, pos, topo, &src, &stats, &err), &err);
    CR_CHECK(stats.colliding == inside && inside > 5);
    int64_t still_inside = 0, moved_outside = 0;
    double max_out = 0;
    for (int64_t i = 0; i < nv; i++) {
        float l = vlen(&pos[3 * i]);
        if (l < r - 1e-6f) still_inside++;
        int was_in = vlen(&before[3 * i]) < r;
        if (!was_in && memcmp(&pos[3 * i], &before[3 * i], 3 * sizeof(float)) != 0) moved_outside++;
        /* a collided vertex lands no farther out than its free neighbours */
        if (was_in && l - r > max_out) max_out = l - r;
    }
    CR_CHECK(still_inside == 0);
    CR_CHECK(moved_outside == 0);
    CR_CHECK(max_out <= out_r - r + 1e-5);
    CR_CHECK(stats.mean_delta_m > 0);

    /* one vertex pushed in, all its neighbours 1 cm out: delta is their
     * common |S| whatever the weights, so it lands back at 1 cm */
    for (int64_t i = 0; i < nv; i++)
        for (int k = 0; k < 3; k++)
            pos[3 * i + k] = out_r * m->pos[3 * i + k];
    for (int k = 0; k < 3; k++)
        pos[k] = 0.45f * m->pos[k];
    CR_CHECK_OK(cr_swingar_collision_remove(&cd, pos, topo, &src, &stats, &err), &err);
    CR_CHECK(stats.colliding == 1);
    CR_CHECK_NEAR(vlen(pos), out_r, 1e-5);
    /* without the neighbour term it stops on the surface */
    for (int k = 0; k < 3; k++)
        pos[k] = 0.45f * m->pos[k];
    cd.delta_weight = 0;
    CR_CHECK_OK(cr_swingar_collision_remove(&cd, pos, topo, &src, &stats, &err), &err);
    CR_CHECK_NEAR(vlen(pos), r, 1e-5);
    /* a field that reads half the distance: each pass halves the depth, and
     * passes stop once nothing collides */
    u.gain = 0.5f;
    for (int passes = 1; passes <= 4; passes *= 2) {
        for (int k = 0; k < 3; k++)
            pos[k] = 0.45f * m->pos[k];
        cd.passes = passes;
        CR_CHECK_OK(cr_swingar_collision_remove(&cd, pos, topo, &src, &stats, &err), &err);
        CR_CHECK_NEAR(vlen(pos), r - 0.05f / (float)(1 << passes), 1e-5);
    }
    u.gain = 1.0f, cd.passes = 5, cd.delta_weight = 1, u.calls = 0;
    for (int k = 0; k < 3; k++)
        pos[k] = 0.45f * m->pos[k];
    CR_CHECK_OK(cr_swingar_collision_remove(&cd, pos, topo, &src, &stats, &err), &err);
    CR_CHECK(u.calls == 3); /* pass 1: S, gradient; pass 2: S, nothing inside, stop */
    CR_CHECK_NEAR(vlen(pos), out_r, 1e-5);
    /* with an offset of 2 cm the free garment at 1 cm counts as colliding:
     * every vertex ends 2 cm out */
    for (int64_t i = 0; i < nv; i++)
        for (int k = 0; k < 3; k++)
            pos[3 * i + k] = out_r * m->pos[3 * i + k];
    cd.passes = 1, cd.offset = 0.02f;
    CR_CHECK_OK(cr_swingar_collision_remove(&cd, pos, topo, &src, &stats, &err), &err);
    CR_CHECK(stats.colliding == nv);
    for (int64_t i = 0; i < nv; i += 7)
        CR_CHECK_NEAR(vlen(&pos[3 * i]), r + 0.02f, 1e-5);
    free(pos), free(before);
    cr_topology_destroy(topo);
    cr_mesh_destroy(m);
}

CR_TEST(swingar_sdf, bvh_source_removes_collisions_on_a_mesh) {
    cr_error err = {0};
    cr_mesh *body = NULL, *cloth = NULL;
    CR_CHECK_OK(cr_prim_icosphere(0.5f, 4, &body, &err), &err);
    CR_CHECK_OK(cr_prim_icosphere(0.48f, 2, &cloth, &err), &err); /* wholly inside */
    CR_REQUIRE(body && cloth);
    cr_bvh *bvh = NULL;
    CR_CHECK_OK(cr_bvh_build(body->pos, body->nv, body->tri, body->nf, &bvh, &err), &err);
    cr_topology *topo = NULL;
    CR_CHECK_OK(cr_topology_build(cloth, &topo, &err), &err);
    CR_REQUIRE(bvh && topo);
    cr_swingar_sdf_bvh_source bu;
    cr_swingar_sdf_source src;
    cr_swingar_sdf_source_bvh(bvh, INFINITY, &bu, &src);
    cr_swingar_collide_def cd = cr_swingar_collide_default_def();
    cr_swingar_collide_stats stats;
    CR_CHECK_OK(cr_swingar_collision_remove(&cd, cloth->pos, topo, &src, &stats, &err), &err);
    CR_CHECK(stats.colliding == cloth->nv);
    CR_CHECK(stats.mean_delta_m == 0); /* no free neighbours anywhere */
    int64_t inside = 0;
    for (int32_t i = 0; i < cloth->nv; i++) {
        float d;
        cr_bvh_signed_distance(bvh, &cloth->pos[3 * (int64_t)i], INFINITY, &d, NULL, NULL);
        inside += d < -1e-6f;
    }
    CR_CHECK(inside == 0);
    cr_bvh_destroy(bvh);
    cr_topology_destroy(topo);
    cr_mesh_destroy(body), cr_mesh_destroy(cloth);
}

/* ------------------------------------------------------------ training -- */

static cr_swingar_sdf_train_def tiny_train(const char *ckpt, int64_t stop_at, int articulated) {
    cr_swingar_sdf_train_def d = cr_swingar_sdf_train_default_def();
    d.model.width = 16;
    d.model.articulated = articulated;
    d.motions = "walk";
    d.shapes = "normal";
    d.body_resolution = 60;
    d.clip_frames = 6;
    d.frame_stride = 3;
    d.samples_surface = 200;
    d.samples_near = 200;
    d.samples_space = 50;
    d.steps = 8;
    d.stop_at = stop_at;
    d.batch = 64;
    d.checkpoint = ckpt;
    d.checkpoint_every = 3;
    d.resume = ckpt != NULL;
    d.quiet = 1;
    return d;
}

static void check_resume(int articulated) {
    char ckpt[1024], ckpt_b[1024], saved[1024];
    snprintf(ckpt, sizeof ckpt, "%s/swingar_sdf_resume%d.safetensors", cr_test_tmpdir(),
             articulated);
    snprintf(ckpt_b, sizeof ckpt_b, "%s/swingar_sdf_straight%d.safetensors", cr_test_tmpdir(),
             articulated);
    snprintf(saved, sizeof saved, "%s/swingar_sdf_model%d.safetensors", cr_test_tmpdir(),
             articulated);
    remove(ckpt), remove(ckpt_b);
    cr_error err = {0};
    cr_swingar_sdf_train_result ra, rb;
    cr_swingar_sdf *a = NULL, *b = NULL, *c = NULL;
    cr_swingar_sdf_train_def da = tiny_train(ckpt_b, 0, articulated);
    CR_CHECK_OK(cr_swingar_sdf_train(&da, &a, &ra, &err), &err);
    cr_swingar_sdf_train_def d1 =
        tiny_train(ckpt, 5, articulated); /* stops after a checkpoint at 3 */
    CR_CHECK_OK(cr_swingar_sdf_train(&d1, &b, &rb, &err), &err);
    CR_REQUIRE(a && b);
    CR_CHECK(rb.steps == 5);
    cr_swingar_sdf_destroy(b);
    b = NULL;
    cr_swingar_sdf_train_def d2 = tiny_train(ckpt, 0, articulated);
    CR_CHECK_OK(cr_swingar_sdf_train(&d2, &b, &rb, &err), &err);
    CR_REQUIRE(b);
    CR_CHECK(rb.resumed_from == 5 && rb.steps == 8 && ra.steps == 8);
    CR_CHECK(ra.poses == 2 && ra.samples == 2 * 450);
    CR_CHECK(isfinite(ra.loss) && ra.loss > 0);
    int64_t na, nb;
    float *pa = cr_nn_params_data(cr_swingar_sdf_params(a), &na);
    float *pb = cr_nn_params_data(cr_swingar_sdf_params(b), &nb);
    CR_CHECK(na == nb && memcmp(pa, pb, (size_t)na * sizeof(float)) == 0);
    CR_CHECK(ra.loss == rb.loss);
    /* a saved model (or the checkpoint itself) loads back to the same field */
    CR_CHECK_OK(cr_swingar_sdf_save(a, saved, &err), &err);
    CR_CHECK_OK(cr_swingar_sdf_load(saved, &c, &err), &err);
    CR_REQUIRE(c);
    float x[6] = {0.1f, 1.0f, 0.05f, 0.3f, 1.4f, -0.2f}, cond[CR_SWINGAR_SDF_COND_MAX];
    cr_swingar_sdf_condition(NULL, NULL, NULL, cond);
    float sa[2], sc[2];
    CR_CHECK_OK(cr_swingar_sdf_eval(a, x, 2, cond, sa, NULL, &err), &err);
    CR_CHECK_OK(cr_swingar_sdf_eval(c, x, 2, cond, sc, NULL, &err), &err);
    CR_CHECK(memcmp(sa, sc, sizeof sa) == 0);
    cr_swingar_sdf_destroy(c);
    c = NULL;
    CR_CHECK_OK(cr_swingar_sdf_load(ckpt, &c, &err), &err);
    cr_swingar_sdf_destroy(a), cr_swingar_sdf_destroy(b), cr_swingar_sdf_destroy(c);
}

CR_TEST(swingar_sdf, resume_is_bit_exact) {
    check_resume(0);
    check_resume(2); /* the articulated input, its frames in the conditioning rows */
}
