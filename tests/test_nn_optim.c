/* test_nn_optim.c: optimisers against hand-written reference loops (in
 * double), convergence on a quadratic and on Rosenbrock, schedules at chosen
 * steps, gradient clipping, and the NaN guard. */
#include "crease/nn_optim.h"
#include "test.h"

#include <stdlib.h>
#include <string.h>

/* The toy: two parameters, "w" (2) and "b" (1), three scalars x_i pulled by
 * f = sum_i c_i (x_i - t_i)^2 / 2, so g_i = c_i (x_i - t_i). */
enum { TOY_N = 3 };
static const double TOY_C[TOY_N] = {2.0, 4.0, 0.5};
static const double TOY_T[TOY_N] = {3.0, -1.0, 0.25};
static const double TOY_X0[TOY_N] = {1.0, -2.0, 0.5};

typedef struct toy {
    cr_nn_params *p;
    cr_tensor *w, *b;
} toy;

static void toy_make(toy *t) {
    cr_error err;
    t->p = NULL;
    CR_CHECK_OK(cr_nn_params_create(&t->p, &err), &err);
    CR_CHECK_OK(cr_nn_params_add(t->p, "w", 1, (int64_t[]){2}, &t->w, &err), &err);
    CR_CHECK_OK(cr_nn_params_add(t->p, "b", 1, (int64_t[]){1}, &t->b, &err), &err);
    t->w->data[0] = (float)TOY_X0[0];
    t->w->data[1] = (float)TOY_X0[1];
    t->b->data[0] = (float)TOY_X0[2];
}

static float *toy_x(toy *t, int i) {
    return i < 2 ? &t->w->data[i] : &t->b->data[0];
}

static void toy_grads(toy *t) {
    cr_nn_params_zero_grad(t->p);
    for (int i = 0; i < TOY_N; i++) {
        float g = (float)(TOY_C[i] * ((double)*toy_x(t, i) - TOY_T[i]));
        if (i < 2)
            t->w->grad[i] = g;
        else
            t->b->grad[0] = g;
    }
}

/* Three steps of the optimiser against the reference update written out in
 * double, exactly as torch.optim documents it. */
static void check_three_steps(const cr_optim_def *def) {
    toy t;
    toy_make(&t);
    cr_error err;
    cr_optim *o = NULL;
    CR_CHECK_OK(cr_optim_create(def, t.p, &o, &err), &err);
    CR_REQUIRE(o);
    double x[TOY_N], m[TOY_N] = {0}, v[TOY_N] = {0};
    for (int i = 0; i < TOY_N; i++)
        x[i] = TOY_X0[i];
    double lr = def->lr.base, wd = def->weight_decay;
    for (int step = 1; step <= 3; step++) {
        toy_grads(&t);
        CR_CHECK_OK(cr_optim_step(o, &err), &err);
        for (int i = 0; i < TOY_N; i++) {
            double g = TOY_C[i] * (x[i] - TOY_T[i]);
            if (def->kind == CR_OPTIM_SGD) {
                g += wd * x[i];
                if (def->momentum > 0) {
                    m[i] = step == 1 ? g : def->momentum * m[i] + (1 - def->dampening) * g;
                    g = def->nesterov ? g + def->momentum * m[i] : m[i];
                }
                x[i] -= lr * g;
            } else {
                if (def->kind == CR_OPTIM_ADAMW)
                    x[i] *= 1 - lr * wd;
                else
                    g += wd * x[i];
                m[i] = def->beta1 * m[i] + (1 - def->beta1) * g;
                v[i] = def->beta2 * v[i] + (1 - def->beta2) * g * g;
                double mhat = m[i] / (1 - pow(def->beta1, step));
                double vhat = v[i] / (1 - pow(def->beta2, step));
                x[i] -= lr * mhat / (sqrt(vhat) + def->eps);
            }
            CR_CHECK_NEAR(*toy_x(&t, i), x[i], 2e-6);
        }
    }
    CR_CHECK(cr_optim_step_count(o) == 3);
    cr_optim_destroy(o);
    cr_nn_params_destroy(t.p);
}

CR_TEST(nn_optim, sgd_matches_reference) {
    cr_optim_def d = cr_optim_default_def(CR_OPTIM_SGD);
    d.lr.base = 0.1f;
    check_three_steps(&d); /* plain */
    d.momentum = 0.9f;
    d.weight_decay = 0.05f;
    check_three_steps(&d); /* heavy ball + L2 */
    d.dampening = 0.3f;
    check_three_steps(&d);
    d.dampening = 0.0f;
    d.nesterov = 1;
    check_three_steps(&d);
}

CR_TEST(nn_optim, adam_matches_reference) {
    cr_optim_def d = cr_optim_default_def(CR_OPTIM_ADAM);
    d.lr.base = 0.1f;
    check_three_steps(&d);
    d.weight_decay = 0.1f; /* L2 through the gradient */
    d.beta1 = 0.8f;
    d.beta2 = 0.95f;
    check_three_steps(&d);
}

CR_TEST(nn_optim, adamw_matches_reference) {
    cr_optim_def d = cr_optim_default_def(CR_OPTIM_ADAMW);
    CR_CHECK(d.weight_decay == 0.01f); /* torch's default */
    d.lr.base = 0.1f;
    d.weight_decay = 0.2f;
    check_three_steps(&d);
}

/* AdamW's decay is decoupled: with zero gradients the parameters shrink by
 * exactly (1 - lr wd) per step while Adam's L2 term moves them by ~lr. */
CR_TEST(nn_optim, adamw_decay_is_decoupled) {
    toy t;
    toy_make(&t);
    cr_error err;
    cr_optim_def d = cr_optim_default_def(CR_OPTIM_ADAMW);
    d.lr.base = 0.01f;
    d.weight_decay = 0.5f;
    cr_optim *o = NULL;
    CR_CHECK_OK(cr_optim_create(&d, t.p, &o, &err), &err);
    CR_REQUIRE(o);
    cr_nn_params_zero_grad(t.p);
    CR_CHECK_OK(cr_optim_step(o, &err), &err);
    CR_CHECK_NEAR(t.w->data[0], 1.0 * (1 - 0.005), 1e-7);
    CR_CHECK_NEAR(t.w->data[1], -2.0 * (1 - 0.005), 1e-7);
    cr_optim_destroy(o);
    cr_nn_params_destroy(t.p);
}

CR_TEST(nn_optim, adam_minimises_quadratic_and_rosenbrock) {
    cr_error err;
    /* ill-conditioned quadratic: curvatures 1e-2 .. 1e2 */
    toy t;
    toy_make(&t);
    cr_optim_def d = cr_optim_default_def(CR_OPTIM_ADAM);
    d.lr.base = 0.05f;
    d.lr.kind = CR_LR_COSINE;
    d.lr.final = 1e-4f;
    d.lr.total_steps = 2000;
    cr_optim *o = NULL;
    CR_CHECK_OK(cr_optim_create(&d, t.p, &o, &err), &err);
    CR_REQUIRE(o);
    for (int s = 0; s < 2000; s++) {
        toy_grads(&t);
        CR_CHECK_OK(cr_optim_step(o, &err), &err);
    }
    for (int i = 0; i < TOY_N; i++)
        CR_CHECK_NEAR(*toy_x(&t, i), TOY_T[i], 1e-4);
    cr_optim_destroy(o);
    cr_nn_params_destroy(t.p);

    /* Rosenbrock f = (1 - x)^2 + 100 (y - x^2)^2 from (-1.5, 2), minimum at (1, 1) */
    cr_nn_params *p = NULL;
    cr_tensor *xy;
    CR_CHECK_OK(cr_nn_params_create(&p, &err), &err);
    CR_CHECK_OK(cr_nn_params_add(p, "xy", 1, (int64_t[]){2}, &xy, &err), &err);
    xy->data[0] = -1.5f;
    xy->data[1] = 2.0f;
    d = cr_optim_default_def(CR_OPTIM_ADAM);
    d.lr.base = 0.02f;
    d.lr.kind = CR_LR_COSINE;
    d.lr.final = 1e-5f;
    d.lr.total_steps = 8000;
    CR_CHECK_OK(cr_optim_create(&d, p, &o, &err), &err);
    CR_REQUIRE(o);
    for (int s = 0; s < 8000; s++) {
        double x = xy->data[0], y = xy->data[1];
        xy->grad[0] = (float)(-2 * (1 - x) - 400 * x * (y - x * x));
        xy->grad[1] = (float)(200 * (y - x * x));
        CR_CHECK_OK(cr_optim_step(o, &err), &err);
    }
    CR_CHECK_NEAR(xy->data[0], 1.0, 1e-3);
    CR_CHECK_NEAR(xy->data[1], 1.0, 2e-3);
    cr_optim_destroy(o);
    cr_nn_params_destroy(p);
}

CR_TEST(nn_optim, schedules) {
    cr_lr_schedule s = cr_lr_default_schedule();
    cr_error err;
    CR_CHECK_OK(cr_lr_check(&s, &err), &err);
    CR_CHECK(cr_lr_at(&s, 0) == 1e-3f && cr_lr_at(&s, 123456) == 1e-3f);

    s.kind = CR_LR_STEP; /* halve every 100 */
    s.base = 0.8f;
    s.step_every = 100;
    CR_CHECK(cr_lr_at(&s, 0) == 0.8f && cr_lr_at(&s, 99) == 0.8f);
    CR_CHECK(cr_lr_at(&s, 100) == 0.4f && cr_lr_at(&s, 250) == 0.2f);
    CR_CHECK(cr_lr_at(&s, 1000) == (float)(0.8 / 1024));
    s.gamma = 0.1f;
    CR_CHECK_NEAR(cr_lr_at(&s, 200), 0.8 * 0.01, 1e-9);

    s = cr_lr_default_schedule();
    s.kind = CR_LR_COSINE;
    s.base = 1.0f;
    s.final = 0.1f;
    s.total_steps = 100;
    CR_CHECK(cr_lr_at(&s, 0) == 1.0f);
    CR_CHECK_NEAR(cr_lr_at(&s, 50), 0.55, 1e-7);
    CR_CHECK_NEAR(cr_lr_at(&s, 25), 0.1 + 0.9 * 0.5 * (1 + cos(M_PI / 4)), 1e-7);
    CR_CHECK(cr_lr_at(&s, 100) == 0.1f && cr_lr_at(&s, 5000) == 0.1f);

    s.warmup_steps = 10; /* linear ramp, then the cosine starts over */
    CR_CHECK_NEAR(cr_lr_at(&s, 0), 0.1, 1e-8);
    CR_CHECK_NEAR(cr_lr_at(&s, 4), 0.5, 1e-8);
    CR_CHECK(cr_lr_at(&s, 9) == 1.0f && cr_lr_at(&s, 10) == 1.0f);
    CR_CHECK_NEAR(cr_lr_at(&s, 60), 0.55, 1e-7);
    CR_CHECK(cr_lr_at(&s, 110) == 0.1f);

    s.final = 2.0f; /* above base */
    CR_CHECK(cr_lr_check(&s, &err) == CR_ERR_INVALID && strstr(err.msg, "final"));
    s = cr_lr_default_schedule();
    s.kind = CR_LR_STEP;
    s.gamma = 0.0f;
    CR_CHECK(cr_lr_check(&s, &err) == CR_ERR_INVALID && strstr(err.msg, "gamma"));
}

/* The optimiser evaluates its schedule at its own step count: SGD on a unit
 * gradient moves each parameter by exactly lr(t) per step. */
CR_TEST(nn_optim, optimiser_follows_schedule) {
    toy t;
    toy_make(&t);
    cr_error err;
    cr_optim_def d = cr_optim_default_def(CR_OPTIM_SGD);
    d.lr.kind = CR_LR_STEP;
    d.lr.base = 0.25f;
    d.lr.step_every = 2;
    d.lr.warmup_steps = 2;
    cr_optim *o = NULL;
    CR_CHECK_OK(cr_optim_create(&d, t.p, &o, &err), &err);
    CR_REQUIRE(o);
    const float expect[6] = {0.125f, 0.25f, 0.25f, 0.25f, 0.125f, 0.125f};
    for (int s = 0; s < 6; s++) {
        CR_CHECK(cr_optim_lr(o) == expect[s]);
        float before = t.b->data[0];
        cr_nn_params_zero_grad(t.p);
        t.b->grad[0] = 1.0f;
        CR_CHECK_OK(cr_optim_step(o, &err), &err);
        CR_CHECK_NEAR(before - t.b->data[0], expect[s], 1e-7);
    }
    cr_optim_destroy(o);
    cr_nn_params_destroy(t.p);
}

CR_TEST(nn_optim, clip_grad_norm) {
    toy t;
    toy_make(&t);
    cr_error err;
    cr_nn_params_zero_grad(t.p);
    t.w->grad[0] = 3.0f;
    t.w->grad[1] = 0.0f;
    t.b->grad[0] = -4.0f;
    float norm = 0;
    CR_CHECK_OK(cr_clip_grad_norm(t.p, 10.0f, &norm, &err), &err); /* below: untouched */
    CR_CHECK(norm == 5.0f && t.w->grad[0] == 3.0f && t.b->grad[0] == -4.0f);
    CR_CHECK_OK(cr_clip_grad_norm(t.p, 1.0f, &norm, &err), &err);
    CR_CHECK(norm == 5.0f);
    CR_CHECK_NEAR(t.w->grad[0], 0.6, 1e-7);
    CR_CHECK_NEAR(t.b->grad[0], -0.8, 1e-7);
    CR_CHECK_OK(cr_clip_grad_norm(t.p, 1.0f, &norm, &err), &err);
    CR_CHECK_NEAR(norm, 1.0, 1e-6);
    /* a frozen parameter is neither counted nor scaled */
    t.b->requires_grad = 0;
    t.b->grad[0] = 100.0f;
    t.w->grad[0] = 6.0f;
    t.w->grad[1] = 8.0f;
    CR_CHECK_OK(cr_clip_grad_norm(t.p, 5.0f, &norm, &err), &err);
    CR_CHECK(norm == 10.0f && t.b->grad[0] == 100.0f);
    CR_CHECK_NEAR(t.w->grad[0], 3.0, 1e-6);
    CR_CHECK(cr_clip_grad_norm(t.p, 0.0f, &norm, &err) == CR_ERR_INVALID);
    t.w->grad[1] = INFINITY;
    CR_CHECK(cr_clip_grad_norm(t.p, 1.0f, &norm, &err) == CR_ERR_NAN);
    CR_CHECK(strstr(err.msg, "'w'") != NULL && t.w->grad[0] == 3.0f);
    cr_nn_params_destroy(t.p);
}

/* A NaN gradient fails the step naming the parameter, and changes nothing. */
CR_TEST(nn_optim, nan_gradient_leaves_state_unchanged) {
    toy t;
    toy_make(&t);
    cr_error err;
    cr_optim_def d = cr_optim_default_def(CR_OPTIM_ADAMW);
    d.lr.base = 0.1f;
    cr_optim *o = NULL;
    CR_CHECK_OK(cr_optim_create(&d, t.p, &o, &err), &err);
    CR_REQUIRE(o);
    toy_grads(&t);
    CR_CHECK_OK(cr_optim_step(o, &err), &err); /* moments are non-zero now */
    int64_t n;
    float *data = cr_nn_params_data(t.p, &n);
    float *before = malloc((size_t)n * 3 * sizeof(float));
    CR_REQUIRE(before);
    memcpy(before, data, (size_t)n * sizeof(float));
    memcpy(before + n, cr_optim_state(o, 0, NULL), (size_t)n * sizeof(float));
    memcpy(before + 2 * n, cr_optim_state(o, 1, NULL), (size_t)n * sizeof(float));
    toy_grads(&t);
    t.b->grad[0] = NAN;
    CR_CHECK(cr_optim_step(o, &err) == CR_ERR_NAN);
    CR_CHECK(strstr(err.msg, "'b'") != NULL && strstr(err.msg, "NaN") != NULL);
    CR_CHECK(memcmp(before, data, (size_t)n * sizeof(float)) == 0);
    CR_CHECK(memcmp(before + n, cr_optim_state(o, 0, NULL), (size_t)n * sizeof(float)) == 0);
    CR_CHECK(memcmp(before + 2 * n, cr_optim_state(o, 1, NULL), (size_t)n * sizeof(float)) == 0);
    CR_CHECK(cr_optim_step_count(o) == 1);
    t.b->grad[0] = 0.0f;
    t.w->grad[1] = -INFINITY;
    CR_CHECK(cr_optim_step(o, &err) == CR_ERR_NAN);
    CR_CHECK(strstr(err.msg, "'w'") && strstr(err.msg, "infinite") && strstr(err.msg, "element 1"));
    free(before);
    cr_optim_destroy(o);
    cr_nn_params_destroy(t.p);
}

CR_TEST(nn_optim, frozen_parameters_are_skipped) {
    toy t;
    toy_make(&t);
    cr_error err;
    cr_optim_def d = cr_optim_default_def(CR_OPTIM_ADAMW);
    d.weight_decay = 0.5f;
    cr_optim *o = NULL;
    CR_CHECK_OK(cr_optim_create(&d, t.p, &o, &err), &err);
    CR_REQUIRE(o);
    t.w->requires_grad = 0;
    toy_grads(&t);
    t.w->grad[0] = NAN; /* frozen: not even checked */
    CR_CHECK_OK(cr_optim_step(o, &err), &err);
    CR_CHECK(t.w->data[0] == 1.0f && t.w->data[1] == -2.0f);
    CR_CHECK(t.b->data[0] != 0.5f);
    cr_optim_destroy(o);
    cr_nn_params_destroy(t.p);
}

CR_TEST(nn_optim, bad_definitions_and_late_parameters) {
    toy t;
    toy_make(&t);
    cr_error err;
    cr_optim *o = NULL;
    cr_optim_def d = cr_optim_default_def(CR_OPTIM_ADAM);
    d.beta2 = 1.0f;
    CR_CHECK(cr_optim_create(&d, t.p, &o, &err) == CR_ERR_INVALID && !o);
    CR_CHECK(strstr(err.msg, "beta2") != NULL);
    d = cr_optim_default_def(CR_OPTIM_SGD);
    d.nesterov = 1; /* without momentum */
    CR_CHECK(cr_optim_create(&d, t.p, &o, &err) == CR_ERR_INVALID);
    d = cr_optim_default_def(CR_OPTIM_SGD);
    d.lr.base = -1.0f;
    CR_CHECK(cr_optim_create(&d, t.p, &o, &err) == CR_ERR_INVALID && strstr(err.msg, "base"));
    d = cr_optim_default_def(CR_OPTIM_SGD);
    d.momentum = 0.5f;
    CR_CHECK_OK(cr_optim_create(&d, t.p, &o, &err), &err);
    CR_REQUIRE(o);
    CR_CHECK(cr_optim_state_count(o) == 1);
    cr_tensor *late;
    CR_CHECK_OK(cr_nn_params_add(t.p, "late", 1, (int64_t[]){4096}, &late, &err), &err);
    CR_CHECK(cr_optim_step(o, &err) == CR_ERR_INVALID && strstr(err.msg, "added"));
    cr_optim_destroy(o);
    cr_nn_params_destroy(t.p);
}
