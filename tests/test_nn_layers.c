/* test_nn_layers.c: the layers of nn_layers.h.
 *
 * Gradients are checked by central differences (nn_gradcheck: step h = 1e-3,
 * tolerance 1e-2 relative, or absolute below 1, unless a check says
 * otherwise) with respect to inputs and parameters. Values are checked
 * against double-precision brute force written here independently: the MLP
 * forward, its Jacobian by central differences of that forward (h = 1e-5),
 * eq. 4 of the drape paper for the grid encoding, the serial scatter for the
 * grid's gradient, complex arithmetic for WIRE. Parameter counts are the drape
 * paper's Table 1 models (sec. 4.1).
 */
#include "crease/nn_layers.h"
#include "nn/cpu/cpu.h"
#include "nn_gradcheck.h"
#include "test.h"

#include <complex.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

static cr_nn_ctx *make_ctx(void) {
    cr_nn_ctx_def d = cr_nn_ctx_default_def();
    d.arena_bytes = (size_t)32 << 20;
    cr_nn_ctx *ctx = NULL;
    cr_error err = {0};
    CR_CHECK_OK(cr_nn_ctx_create(&d, &ctx, &err), &err);
    return ctx;
}

static void fill_rand(float *a, int64_t n, cr_rng *r, float lo, float hi) {
    for (int64_t i = 0; i < n; i++)
        a[i] = lo + (hi - lo) * cr_rng_uniformf(r);
}

static cr_mlp_def mlp_def(int nlayers, const int *widths, cr_act act) {
    cr_mlp_def d = cr_mlp_default_def();
    d.nlayers = nlayers;
    memcpy(d.widths, widths, (size_t)(nlayers + 1) * sizeof(int));
    d.act = act;
    return d;
}

/* ------------------------------------------------------- parameter counts -- */

CR_TEST(nn_layers, drape_table1_parameter_counts) {
    cr_error err = {0};
    cr_rng rng = cr_rng_make(1, 0);
    cr_mlp_def base = mlp_def(4, (int[]){2, 152, 152, 152, 3}, CR_ACT_RELU);
    cr_mlp_def pe = mlp_def(4, (int[]){18, 148, 148, 148, 3}, CR_ACT_RELU);
    cr_mlp_def head = mlp_def(4, (int[]){6, 64, 64, 64, 3}, CR_ACT_RELU);
    cr_grid_encoding_def gd = cr_grid_encoding_default_def();
    CR_CHECK(cr_mlp_param_count(&base) == 47427);
    CR_CHECK(cr_fourier_encoding_dim(2, 4) == 18);
    CR_CHECK(cr_mlp_param_count(&pe) == 47363);
    CR_CHECK(cr_grid_encoding_out_dim(&gd) == 6);
    CR_CHECK(cr_grid_encoding_param_count(&gd) == 101 * 101 * 3 + 51 * 51 * 3);
    CR_CHECK(cr_mlp_param_count(&head) == 8963);
    CR_CHECK(cr_grid_encoding_param_count(&gd) + cr_mlp_param_count(&head) == 47369);

    /* The stores agree with the formulas, and the grid's level shapes are the paper's. */
    cr_nn_params *P = NULL;
    cr_mlp *m = NULL;
    cr_grid_encoding *g = NULL;
    CR_CHECK_OK(cr_nn_params_create(&P, &err), &err);
    CR_CHECK_OK(cr_grid_encoding_create(&gd, P, "grid", &rng, &g, &err), &err);
    CR_CHECK_OK(cr_mlp_create(&head, P, "mlp", &rng, &m, &err), &err);
    CR_CHECK(cr_nn_params_numel(P) == 47369);
    cr_tensor *l1 = cr_nn_params_find(P, "grid.level1");
    CR_REQUIRE(l1 && cr_nn_params_find(P, "mlp.3.bias"));
    CR_CHECK(l1->shape[0] == 51 && l1->shape[1] == 51 && l1->shape[2] == 3);
    CR_CHECK(cr_nn_params_find(P, "mlp.0.weight")->shape[0] == 64);
    CR_CHECK(cr_nn_params_find(P, "mlp.0.weight")->shape[1] == 6);
    cr_mlp_destroy(m);
    cr_grid_encoding_destroy(g);
    cr_nn_params_destroy(P);
}

/* ----------------------------------------------------------------- init -- */

CR_TEST(nn_layers, init_bounds_and_determinism) {
    cr_error err = {0};
    cr_nn_params *P = NULL;
    CR_CHECK_OK(cr_nn_params_create(&P, &err), &err);
    cr_tensor *w;
    CR_REQUIRE(cr_nn_params_add(P, "w", 2, (int64_t[]){200, 100}, &w, &err) == CR_OK);
    struct {
        int kind;
        double bound;
    } cases[] = {{0, sqrt(6.0 / 300.0)},
                 {1, sqrt(2.0) * sqrt(3.0 / 100.0)},
                 {2, 1.0 / 100.0},
                 {3, sqrt(6.0 / 100.0) / 30.0}};
    for (int c = 0; c < 4; c++) {
        cr_rng rng = cr_rng_make(7, 0);
        switch (cases[c].kind) {
        case 0:
            cr_init_glorot_uniform(w, &rng, 1.0f);
            break;
        case 1:
            cr_init_kaiming_uniform(w, &rng, sqrtf(2.0f));
            break;
        case 2:
            cr_init_siren(w, &rng, 1, 30.0f);
            break;
        default:
            cr_init_siren(w, &rng, 0, 30.0f);
            break;
        }
        double mx = 0.0, var = 0.0;
        for (int64_t i = 0; i < w->numel; i++) {
            mx = fmax(mx, fabs(w->data[i]));
            var += (double)w->data[i] * w->data[i];
        }
        var /= (double)w->numel;
        double b = cases[c].bound;
        CR_CHECK(mx <= b * (1 + 1e-6) && mx > 0.99 * b);
        CR_CHECK_NEAR(var, b * b / 3.0, 0.03 * b * b / 3.0); /* U(-b,b) variance */
    }
    cr_rng rng = cr_rng_make(7, 0);
    cr_init_kaiming_normal(w, &rng, sqrtf(2.0f));
    double var = 0.0;
    for (int64_t i = 0; i < w->numel; i++)
        var += (double)w->data[i] * w->data[i];
    CR_CHECK_NEAR(var / (double)w->numel, 2.0 / 100.0, 0.03 * 2.0 / 100.0);
    CR_CHECK_NEAR(cr_init_gain(CR_ACT_LEAKY_RELU, 1.0f), 1.0, 1e-6);
    cr_nn_params_destroy(P);

    /* Same seed, same MLP; another seed, another. */
    cr_mlp_def d = mlp_def(3, (int[]){2, 16, 16, 3}, CR_ACT_SIN);
    float *first[3] = {NULL, NULL, NULL};
    int64_t n = 0;
    uint64_t seeds[3] = {5, 5, 6};
    cr_nn_params *Ps[3] = {NULL, NULL, NULL};
    for (int k = 0; k < 3; k++) {
        cr_rng r = cr_rng_make(seeds[k], 0);
        cr_mlp *m = NULL;
        CR_CHECK_OK(cr_nn_params_create(&Ps[k], &err), &err);
        CR_CHECK_OK(cr_mlp_create(&d, Ps[k], "net", &r, &m, &err), &err);
        first[k] = cr_nn_params_data(Ps[k], &n);
        cr_mlp_destroy(m);
    }
    CR_CHECK(memcmp(first[0], first[1], (size_t)n * sizeof(float)) == 0);
    CR_CHECK(memcmp(first[0], first[2], (size_t)n * sizeof(float)) != 0);
    for (int k = 0; k < 3; k++)
        cr_nn_params_destroy(Ps[k]);
}

/* --------------------------------------------------------- linear, MLP -- */

static cr_tensor *build_mlp(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    return cr_mlp_forward(ctx, user, in[0]);
}

static cr_tensor *build_linear(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    return cr_linear_forward(ctx, user, in[0]);
}

CR_TEST(nn_layers, linear_gradcheck) {
    cr_error err = {0};
    cr_rng rng = cr_rng_make(3, 0);
    cr_nn_params *P = NULL;
    CR_CHECK_OK(cr_nn_params_create(&P, &err), &err);
    cr_linear_def ld = cr_linear_default_def();
    ld.in = 4;
    ld.out = 3;
    cr_linear lin;
    CR_CHECK_OK(cr_linear_create(&ld, P, "fc", &rng, &lin, &err), &err);
    fill_rand(lin.bias->data, 3, &rng, -1, 1);
    float x[5 * 4];
    fill_rand(x, 20, &rng, -1, 1);
    nn_gradcheck_input in[1] = {{2, {5, 4}, x, 1}};
    nn_gradcheck_def gd = nn_gradcheck_default_def();
    gd.name = "linear";
    CR_CHECK(nn_gradcheck(&gd, 1, in, P, build_linear, &lin, NULL) == 0);
    cr_nn_params_destroy(P);
}

/* The MLP in double, straight from its definition. x (IN), y (OUT). */
static void mlp_ref(const cr_mlp *m, const double *x, double *y) {
    const cr_mlp_def *d = &m->def;
    double h[64], z[64];
    for (int k = 0; k < d->widths[0]; k++)
        h[k] = x[k];
    for (int i = 0; i < d->nlayers; i++) {
        int in = d->widths[i], out = d->widths[i + 1];
        const float *W = m->layer[i].weight->data, *b = m->layer[i].bias->data;
        for (int o = 0; o < out; o++) {
            z[o] = b[o];
            for (int k = 0; k < in; k++)
                z[o] += (double)W[o * in + k] * h[k];
        }
        if (m->ln_weight[i]) {
            double mean = 0, var = 0;
            for (int o = 0; o < out; o++)
                mean += z[o] / out;
            for (int o = 0; o < out; o++)
                var += (z[o] - mean) * (z[o] - mean) / out;
            for (int o = 0; o < out; o++)
                z[o] = (z[o] - mean) / sqrt(var + d->ln_eps) * m->ln_weight[i]->data[o] +
                       m->ln_bias[i]->data[o];
        }
        float p;
        cr_act act = cr_mlp_layer_act(d, i, &p);
        for (int o = 0; o < out; o++) {
            double v = z[o], a = v;
            switch (act) {
            case CR_ACT_RELU:
                a = v > 0 ? v : 0;
                break;
            case CR_ACT_LEAKY_RELU:
                a = v > 0 ? v : p * v;
                break;
            case CR_ACT_TANH:
                a = tanh(v);
                break;
            case CR_ACT_SIGMOID:
                a = 1 / (1 + exp(-v));
                break;
            case CR_ACT_SOFTPLUS:
                a = log1p(exp(p * v)) / p;
                break;
            case CR_ACT_SIN:
                a = sin(p * v);
                break;
            default:
                break;
            }
            z[o] = cr_mlp_layer_residual(d, i) ? h[o] + a : a;
        }
        for (int o = 0; o < out; o++)
            h[o] = z[o];
    }
    for (int o = 0; o < d->widths[d->nlayers]; o++)
        y[o] = h[o];
}

typedef struct mlp_case {
    const char *name;
    cr_act act;
    int layer_norm, residual;
} mlp_case;

static const mlp_case mlp_cases[] = {
    {"relu", CR_ACT_RELU, 0, 0},
    {"leaky_relu", CR_ACT_LEAKY_RELU, 0, 0},
    {"tanh", CR_ACT_TANH, 0, 0},
    {"sigmoid", CR_ACT_SIGMOID, 0, 0},
    {"softplus", CR_ACT_SOFTPLUS, 0, 0},
    {"sin", CR_ACT_SIN, 0, 0},
    {"none", CR_ACT_NONE, 0, 0},
    {"tanh+ln+res", CR_ACT_TANH, 1, 1},
    {"softplus+res", CR_ACT_SOFTPLUS, 0, 1},
    {"leaky+ln", CR_ACT_LEAKY_RELU, 1, 0},
};
enum { NCASES = sizeof mlp_cases / sizeof mlp_cases[0] };

/* A 3-6-6-6-2 MLP of one case, with random biases and layer-norm affines so
 * every parameter matters. */
static cr_mlp *case_mlp(const mlp_case *c, cr_nn_params *P, cr_rng *rng) {
    cr_mlp_def d = mlp_def(4, (int[]){3, 6, 6, 6, 2}, c->act);
    d.layer_norm = c->layer_norm;
    d.residual = c->residual;
    d.leaky_slope = 0.1f;
    d.softplus_beta = 2.0f;
    cr_mlp *m = NULL;
    cr_error err = {0};
    CR_CHECK_OK(cr_mlp_create(&d, P, "m", rng, &m, &err), &err);
    if (!m) return NULL;
    for (int i = 0; i < cr_nn_params_count(P); i++) {
        const char *name;
        cr_tensor *t = cr_nn_params_at(P, i, &name);
        if (strstr(name, "bias")) fill_rand(t->data, t->numel, rng, -0.5f, 0.5f);
        if (strstr(name, "ln.weight")) fill_rand(t->data, t->numel, rng, 0.5f, 1.5f);
    }
    return m;
}

CR_TEST(nn_layers, mlp_matches_reference_and_gradcheck) {
    for (int c = 0; c < NCASES; c++) {
        cr_error err = {0};
        cr_rng rng = cr_rng_make(11 + c, 0);
        cr_nn_params *P = NULL;
        CR_CHECK_OK(cr_nn_params_create(&P, &err), &err);
        cr_mlp *m = case_mlp(&mlp_cases[c], P, &rng);
        CR_REQUIRE(m);
        CR_CHECK(cr_nn_params_numel(P) == cr_mlp_param_count(&m->def));
        float x[4 * 3];
        fill_rand(x, 12, &rng, -1, 1);
        cr_nn_ctx *ctx = make_ctx();
        cr_tensor *y = cr_mlp_forward(ctx, m, cr_nn_from(ctx, 2, (int64_t[]){4, 3}, x));
        CR_REQUIRE(y && y->shape[0] == 4 && y->shape[1] == 2);
        for (int n = 0; n < 4; n++) {
            double xd[3] = {x[3 * n], x[3 * n + 1], x[3 * n + 2]}, yd[2];
            mlp_ref(m, xd, yd);
            for (int o = 0; o < 2; o++)
                CR_CHECK_NEAR(y->data[2 * n + o], yd[o], 1e-5);
        }
        cr_nn_ctx_destroy(ctx);
        nn_gradcheck_input in[1] = {{2, {4, 3}, x, 1}};
        nn_gradcheck_def gd = nn_gradcheck_default_def();
        gd.name = mlp_cases[c].name;
        CR_CHECK(nn_gradcheck(&gd, 1, in, P, build_mlp, m, NULL) == 0);
        cr_mlp_destroy(m);
        cr_nn_params_destroy(P);
    }
}

/* ----------------------------------------------------------- Jacobian -- */

static cr_tensor *build_jac_sq(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    return cr_nn_square(ctx, cr_mlp_input_jacobian(ctx, user, in[0], NULL));
}

CR_TEST(nn_layers, jacobian_matches_differences_and_backpropagates) {
    for (int c = 0; c < NCASES; c++) {
        cr_error err = {0};
        cr_rng rng = cr_rng_make(40 + c, 0);
        cr_nn_params *P = NULL;
        CR_CHECK_OK(cr_nn_params_create(&P, &err), &err);
        cr_mlp *m = case_mlp(&mlp_cases[c], P, &rng);
        CR_REQUIRE(m);
        float x[5 * 3];
        fill_rand(x, 15, &rng, -1, 1);
        cr_nn_ctx *ctx = make_ctx();
        cr_tensor *y = NULL;
        cr_tensor *J = cr_mlp_input_jacobian(ctx, m, cr_nn_from(ctx, 2, (int64_t[]){5, 3}, x), &y);
        CR_CHECK_OK(cr_nn_ctx_error(ctx, &err), &err);
        CR_REQUIRE(J && y && J->ndim == 3 && J->shape[0] == 5 && J->shape[1] == 3 &&
                   J->shape[2] == 2);
        double maxerr = 0.0;
        for (int n = 0; n < 5; n++) {
            double yd[2];
            double xd[3] = {x[3 * n], x[3 * n + 1], x[3 * n + 2]};
            mlp_ref(m, xd, yd);
            for (int o = 0; o < 2; o++)
                CR_CHECK_NEAR(y->data[2 * n + o], yd[o], 1e-5);
            for (int i = 0; i < 3; i++) {
                double xp[3], xm[3], yp[2], ym[2], h = 1e-5;
                memcpy(xp, xd, sizeof xd);
                memcpy(xm, xd, sizeof xd);
                xp[i] += h;
                xm[i] -= h;
                mlp_ref(m, xp, yp);
                mlp_ref(m, xm, ym);
                for (int o = 0; o < 2; o++) {
                    double fd = (yp[o] - ym[o]) / (2 * h), got = J->data[(n * 3 + i) * 2 + o];
                    maxerr = fmax(maxerr, fabs(got - fd) / fmax(1.0, fabs(fd)));
                }
            }
        }
        if (maxerr > 1e-4)
            fprintf(stderr, "    jacobian %s: max error %g\n", mlp_cases[c].name, maxerr);
        CR_CHECK(maxerr <= 1e-4);
        cr_nn_ctx_destroy(ctx);

        /* A loss on J^2 reaches the weights and x through the tape. */
        nn_gradcheck_input in[1] = {{2, {5, 3}, x, 1}};
        nn_gradcheck_def gd = nn_gradcheck_default_def();
        gd.name = mlp_cases[c].name;
        CR_CHECK(nn_gradcheck(&gd, 1, in, P, build_jac_sq, m, NULL) == 0);
        cr_mlp_destroy(m);
        cr_nn_params_destroy(P);
    }
}

/* Eikonal loss of a scalar softplus field: mean((|grad f| - 1)^2). */
static cr_tensor *build_eikonal(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    cr_tensor *J = cr_mlp_input_jacobian(ctx, user, in[0], NULL); /* (N,3,1) */
    cr_tensor *g = cr_nn_reshape(ctx, J, 2, (int64_t[]){-1, 3});
    return cr_nn_mean(ctx,
                      cr_nn_square(ctx, cr_nn_add_scalar(ctx, cr_nn_norm(ctx, g, 1e-12f), -1)));
}

CR_TEST(nn_layers, eikonal_loss_gradcheck) {
    cr_error err = {0};
    cr_rng rng = cr_rng_make(77, 0);
    cr_nn_params *P = NULL;
    CR_CHECK_OK(cr_nn_params_create(&P, &err), &err);
    cr_mlp_def d = mlp_def(3, (int[]){3, 8, 8, 1}, CR_ACT_SOFTPLUS);
    d.softplus_beta = 10.0f;
    cr_mlp *m = NULL;
    CR_CHECK_OK(cr_mlp_create(&d, P, "sdf", &rng, &m, &err), &err);
    CR_REQUIRE(m);
    float x[6 * 3];
    fill_rand(x, 18, &rng, -1, 1);
    nn_gradcheck_input in[1] = {{2, {6, 3}, x, 1}};
    nn_gradcheck_def gd = nn_gradcheck_default_def();
    gd.name = "eikonal";
    gd.step = 1e-3;
    gd.tol = 1e-2;
    nn_gradcheck_result res;
    CR_CHECK(nn_gradcheck(&gd, 1, in, P, build_eikonal, m, &res) == 0);
    CR_CHECK(res.checked > 100);
    cr_mlp_destroy(m);
    cr_nn_params_destroy(P);
}

/* ---------------------------------------------------------- encodings -- */

static cr_tensor *build_fourier(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    (void)user;
    return cr_fourier_encoding_forward(ctx, in[0], 3);
}

CR_TEST(nn_layers, fourier_encoding_layout_and_gradcheck) {
    float x[3 * 2] = {0.1f, -0.7f, 0.25f, 0.5f, 0.9f, 0.0f};
    cr_nn_ctx *ctx = make_ctx();
    cr_tensor *y = cr_fourier_encoding_forward(ctx, cr_nn_from(ctx, 2, (int64_t[]){3, 2}, x), 4);
    CR_REQUIRE(y && y->shape[0] == 3 && y->shape[1] == 18);
    for (int n = 0; n < 3; n++) {
        const float *r = y->data + n * 18;
        for (int d = 0; d < 2; d++) {
            double v = x[2 * n + d];
            CR_CHECK(r[d] == x[2 * n + d]);
            for (int k = 0; k < 4; k++) {
                double a = ldexp(M_PI, k) * v;
                CR_CHECK_NEAR(r[2 + k * 4 + d], sin(a), 5e-6);
                CR_CHECK_NEAR(r[2 + k * 4 + 2 + d], cos(a), 5e-6);
            }
        }
    }
    cr_nn_ctx_destroy(ctx);
    nn_gradcheck_input in[1] = {{2, {3, 2}, x, 1}};
    nn_gradcheck_def gd = nn_gradcheck_default_def();
    gd.name = "fourier";
    CR_CHECK(nn_gradcheck(&gd, 1, in, NULL, build_fourier, NULL, NULL) == 0);
}

static double grid_node(const cr_grid_encoding *g, int l, double ix, double iy, int f) {
    int64_t s = g->cells[l] + 1;
    return g->level[l]->data[((int64_t)iy * s + (int64_t)ix) * g->def.features + f];
}

/* Eq. 4 of the drape paper, literally, in double (x, y in grid units). */
static void grid_ref(const cr_grid_encoding *g, double u, double v, double *out) {
    int F = g->def.features;
    for (int l = 0; l < g->def.levels; l++) {
        int r = g->cells[l];
        double x = fmin(fmax(u, 0), 1) * r, y = fmin(fmax(v, 0), 1) * r;
        double x1 = fmin(floor(x), r - 1), y1 = fmin(floor(y), r - 1), x2 = x1 + 1, y2 = y1 + 1;
        double alpha = 1.0 / ((x2 - x1) * (y2 - y1));
        double vx0 = x2 - x, vx1 = x - x1, vy0 = y2 - y, vy1 = y - y1;
        for (int f = 0; f < F; f++) {
            double m00 = grid_node(g, l, x1, y1, f), m01 = grid_node(g, l, x1, y2, f);
            double m10 = grid_node(g, l, x2, y1, f), m11 = grid_node(g, l, x2, y2, f);
            out[l * F + f] =
                alpha * (vx0 * (m00 * vy0 + m01 * vy1) + vx1 * (m10 * vy0 + m11 * vy1));
        }
    }
}

static cr_grid_encoding *make_grid_interp(int res, int levels, int F, cr_grid_interp interp,
                                          const char *prefix, cr_nn_params *P, cr_rng *rng) {
    cr_grid_encoding_def d = cr_grid_encoding_default_def();
    d.interp = interp;
    d.resolution = res;
    d.levels = levels;
    d.features = F;
    d.init_range = 1.0f; /* O(1) features, so gradients are O(1) too */
    cr_grid_encoding *g = NULL;
    cr_error err = {0};
    CR_CHECK_OK(cr_grid_encoding_create(&d, P, prefix, rng, &g, &err), &err);
    return g;
}

static cr_grid_encoding *make_grid(int res, int levels, int F, const char *prefix, cr_nn_params *P,
                                   cr_rng *rng) {
    return make_grid_interp(res, levels, F, CR_GRID_BILINEAR, prefix, P, rng);
}

/* One axis's weights at fraction f in double, from the textbook forms rather
 * than the kernel's coefficients: the B-spline by its blending functions and
 * the partition of unity. Returns the stencil size (its first node is cell - 1
 * for 4). */
static int ref_axis(cr_grid_interp m, double f, double *w) {
    if (m == CR_GRID_BILINEAR) {
        w[0] = 1 - f, w[1] = f;
        return 2;
    }
    w[0] = (1 - f) * (1 - f) * (1 - f) / 6, w[3] = f * f * f / 6;
    w[1] = (3 * f * f * f - 6 * f * f + 4) / 6, w[2] = 1 - w[0] - w[1] - w[3];
    return 4;
}

/* A point's stencil on level l in double: n x n nodes (clamped) and weights. */
static int ref_stencil(const cr_grid_encoding *g, int l, double u, double v, int64_t *node,
                       double *w) {
    int r = g->cells[l], s = r + 1;
    double x = fmin(fmax(u, 0), 1) * r, y = fmin(fmax(v, 0), 1) * r;
    int i = (int)fmin(floor(x), r - 1), j = (int)fmin(floor(y), r - 1);
    double wx[4], wy[4];
    int n = ref_axis(g->def.interp, x - i, wx);
    ref_axis(g->def.interp, y - j, wy);
    int off = n == 4 ? -1 : 0;
    for (int b = 0; b < n; b++)
        for (int a = 0; a < n; a++) {
            int ia = i + off + a, jb = j + off + b;
            ia = ia < 0 ? 0 : ia > r ? r : ia;
            jb = jb < 0 ? 0 : jb > r ? r : jb;
            node[b * n + a] = (int64_t)jb * s + ia;
            w[b * n + a] = wx[a] * wy[b];
        }
    return n * n;
}

/* Any interpolation's features in double from ref_stencil. */
static void grid_ref_interp(const cr_grid_encoding *g, double u, double v, double *out) {
    int F = g->def.features;
    for (int l = 0; l < g->def.levels; l++) {
        int64_t node[16];
        double w[16];
        int k = ref_stencil(g, l, u, v, node, w);
        for (int f = 0; f < F; f++) {
            double sum = 0;
            for (int c = 0; c < k; c++)
                sum += w[c] * g->level[l]->data[node[c] * F + f];
            out[l * F + f] = sum;
        }
    }
}

CR_TEST(nn_layers, grid_encoding_values) {
    cr_error err = {0};
    cr_rng rng = cr_rng_make(21, 0);
    cr_nn_params *P = NULL;
    CR_CHECK_OK(cr_nn_params_create(&P, &err), &err);
    cr_grid_encoding *g = make_grid(64, 3, 3, "a", P, &rng);   /* cells 64, 32, 16 */
    cr_grid_encoding *gp = make_grid(100, 2, 3, "b", P, &rng); /* the paper's 101 + 51 nodes */
    CR_REQUIRE(g && gp);
    cr_nn_ctx *ctx = make_ctx();
    /* Node positions: exactly the node's features on every level they hit
     * (iu/64 is exact in float). Plus the corners u,v = 1. */
    enum { NN = 65 * 65 };
    float *uv = malloc(NN * 2 * sizeof(float));
    for (int iv = 0; iv <= 64; iv++)
        for (int iu = 0; iu <= 64; iu++) {
            uv[2 * (iv * 65 + iu)] = (float)iu / 64.0f;
            uv[2 * (iv * 65 + iu) + 1] = (float)iv / 64.0f;
        }
    cr_tensor *y = cr_grid_encoding_forward(ctx, g, cr_nn_from(ctx, 2, (int64_t[]){NN, 2}, uv));
    CR_REQUIRE(y && y->shape[0] == NN && y->shape[1] == 9);
    int64_t bad = 0;
    for (int iv = 0; iv <= 64; iv++)
        for (int iu = 0; iu <= 64; iu++)
            for (int l = 0; l < 3; l++) {
                int step = 1 << l, s = g->cells[l] + 1;
                if (iu % step || iv % step) continue;
                const float *node = g->level[l]->data + ((iv / step) * s + iu / step) * 3;
                for (int f = 0; f < 3; f++)
                    bad += y->data[(iv * 65 + iu) * 9 + l * 3 + f] != node[f];
            }
    CR_CHECK(bad == 0);
    /* Random points (some outside [0,1], clamped) against eq. 4 on both grids. */
    enum { NR = 3000 };
    fill_rand(uv, NR * 2, &rng, -0.05f, 1.05f);
    cr_grid_encoding *gs[2] = {g, gp};
    for (int k = 0; k < 2; k++) {
        cr_tensor *yr =
            cr_grid_encoding_forward(ctx, gs[k], cr_nn_from(ctx, 2, (int64_t[]){NR, 2}, uv));
        CR_REQUIRE(yr);
        int D = cr_grid_encoding_out_dim(&gs[k]->def);
        double maxerr = 0, ref[CR_GRID_MAX_LEVELS * 3];
        for (int n = 0; n < NR; n++) {
            grid_ref(gs[k], uv[2 * n], uv[2 * n + 1], ref);
            for (int j = 0; j < D; j++)
                maxerr = fmax(maxerr, fabs(yr->data[n * D + j] - ref[j]));
        }
        CR_CHECK(maxerr < 1e-5);
    }
    /* Paper grid: node (37, 12) of level 0 to float precision (37/100 is inexact). */
    float p[2] = {0.37f, 0.12f};
    cr_tensor *yp = cr_grid_encoding_forward(ctx, gp, cr_nn_from(ctx, 2, (int64_t[]){1, 2}, p));
    CR_REQUIRE(yp);
    for (int f = 0; f < 3; f++)
        CR_CHECK_NEAR(yp->data[f], gp->level[0]->data[(12 * 101 + 37) * 3 + f], 1e-6);
    /* Bad input: NaN and a wrong shape fail on the context. */
    cr_nn_ctx_reset(ctx);
    float nan_uv[2] = {0.5f, NAN};
    CR_CHECK(!cr_grid_encoding_forward(ctx, g, cr_nn_from(ctx, 2, (int64_t[]){1, 2}, nan_uv)));
    CR_CHECK(cr_nn_ctx_error(ctx, &err) == CR_ERR_NAN);
    cr_nn_ctx_reset(ctx);
    CR_CHECK(!cr_grid_encoding_forward(ctx, g, cr_nn_from(ctx, 2, (int64_t[]){2, 1}, p)));
    CR_CHECK(cr_nn_ctx_error(ctx, &err) == CR_ERR_SHAPE);
    free(uv);
    cr_nn_ctx_destroy(ctx);
    cr_grid_encoding_destroy(g);
    cr_grid_encoding_destroy(gp);
    cr_nn_params_destroy(P);
}

static cr_tensor *build_grid(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    return cr_grid_encoding_forward(ctx, user, in[0]);
}

CR_TEST(nn_layers, grid_encoding_gradients) {
    cr_error err = {0};
    cr_rng rng = cr_rng_make(22, 0);
    cr_nn_params *P = NULL;
    CR_CHECK_OK(cr_nn_params_create(&P, &err), &err);
    cr_grid_encoding *g = make_grid(8, 3, 2, "g", P, &rng); /* cells 8, 4, 2 */
    CR_REQUIRE(g);
    /* Points inside the finest cells, away from every level's cell borders
     * (the uv gradient jumps there), plus one clamped point per axis. */
    enum { N = 12 };
    float uv[N * 2];
    for (int k = 0; k < 2 * N; k++)
        uv[k] = ((float)cr_rng_below(&rng, 8) + 0.3f + 0.4f * cr_rng_uniformf(&rng)) / 8.0f;
    uv[0] = -0.2f;
    uv[3] = 1.3f;
    nn_gradcheck_input in[1] = {{2, {N, 2}, uv, 1}};
    nn_gradcheck_def gd = nn_gradcheck_default_def();
    gd.name = "grid_encoding";
    nn_gradcheck_result res;
    CR_CHECK(nn_gradcheck(&gd, 1, in, P, build_grid, g, &res) == 0);
    CR_CHECK(res.checked == 2 * N + cr_grid_encoding_param_count(&g->def));
    cr_grid_encoding_destroy(g);
    cr_nn_params_destroy(P);

    /* Many points: the sorted gather equals the naive serial scatter, and is
     * bitwise the same on one thread and on all; so does a batch of 8,000
     * (scattered on the 101 x 101 level, gathered on the 51 x 51 one) and one
     * of 4,096 (scattered on both); for every interpolation, the cubics
     * (which gather only above twice 4 points per node) on 90,000, 30,000
     * and 4,096. */
    for (int m = 0; m < CR_GRID_INTERP_COUNT; m++) {
        CR_CHECK_OK(cr_nn_params_create(&P, &err), &err);
        g = make_grid_interp(100, 2, 3, (cr_grid_interp)m, "g", P, &rng);
        CR_REQUIRE(g);
        const int cubic = m == CR_GRID_BSPLINE;
        const int sizes[2][3] = {{20000, 8000, 4096}, {90000, 30000, 4096}};
        for (int si = 0; si < 3; si++) {
            const int M = sizes[cubic][si];
            float *pts = malloc((size_t)M * 2 * sizeof(float)),
                  *wts = malloc((size_t)M * 6 * sizeof(float));
            fill_rand(pts, M * 2, &rng, 0, 1);
            fill_rand(wts, M * 6, &rng, -1, 1);
            int64_t np;
            float *grads[2];
            for (int pass = 0; pass < 2; pass++) {
                int threads = cr_thread_count();
                if (pass == 1) cr_set_thread_count(1);
                cr_nn_ctx *ctx = make_ctx();
                cr_nn_params_zero_grad(P);
                cr_tensor *y =
                    cr_grid_encoding_forward(ctx, g, cr_nn_from(ctx, 2, (int64_t[]){M, 2}, pts));
                cr_tensor *L =
                    cr_nn_sum(ctx, cr_nn_mul(ctx, y, cr_nn_from(ctx, 2, (int64_t[]){M, 6}, wts)));
                CR_CHECK_OK(cr_nn_backward(ctx, L, &err), &err);
                float *gr = cr_nn_params_grad(P, &np);
                grads[pass] = malloc((size_t)np * sizeof(float));
                memcpy(grads[pass], gr, (size_t)np * sizeof(float));
                cr_nn_ctx_destroy(ctx);
                if (pass == 1) cr_set_thread_count(threads);
            }
            CR_CHECK(memcmp(grads[0], grads[1], (size_t)np * sizeof(float)) == 0);
            double maxerr = 0.0;
            for (int l = 0; l < 2; l++) {
                int s = g->cells[l] + 1;
                double *ref = calloc((size_t)s * s * 3, sizeof(double));
                for (int n = 0; n < M; n++) {
                    int64_t nodes[16];
                    double w[16];
                    int k = ref_stencil(g, l, pts[2 * n], pts[2 * n + 1], nodes, w);
                    for (int c = 0; c < k; c++)
                        for (int f = 0; f < 3; f++)
                            ref[nodes[c] * 3 + f] += w[c] * wts[n * 6 + l * 3 + f];
                }
                const float *got = grads[0] + (g->level[l]->data - cr_nn_params_data(P, NULL));
                for (int64_t k = 0; k < (int64_t)s * s * 3; k++)
                    maxerr = fmax(maxerr, fabs(got[k] - ref[k]) / fmax(1.0, fabs(ref[k])));
                free(ref);
            }
            if (maxerr >= 1e-5)
                printf("    %s, %d points: max error %g\n", cr_grid_interp_name((cr_grid_interp)m),
                       M, maxerr);
            CR_CHECK(maxerr < 1e-5);
            free(grads[0]);
            free(grads[1]);
            free(pts);
            free(wts);
        }
        cr_grid_encoding_destroy(g);
        cr_nn_params_destroy(P);
    }
}

/* The B-spline against its textbook form (it averages (G[i-1] + 4 G[i] +
 * G[i+1]) / 6 per axis at the nodes, which the reference covers). */
CR_TEST(nn_layers, grid_encoding_interpolation_values) {
    cr_error err = {0};
    cr_rng rng = cr_rng_make(23, 0);
    CR_CHECK(strcmp(cr_grid_interp_name(CR_GRID_BSPLINE), "bspline") == 0);
    cr_grid_interp parsed;
    CR_CHECK(cr_grid_interp_parse("bspline", &parsed, &err) == CR_OK && parsed == CR_GRID_BSPLINE);
    CR_CHECK(cr_grid_interp_parse("cubic", &parsed, &err) == CR_ERR_INVALID);
    enum { NR = 3000 };
    float uv[NR * 2];
    fill_rand(uv, NR * 2, &rng, -0.05f, 1.05f);
    for (int m = CR_GRID_BSPLINE; m < CR_GRID_INTERP_COUNT; m++) {
        cr_nn_params *P = NULL;
        CR_CHECK_OK(cr_nn_params_create(&P, &err), &err);
        cr_grid_encoding *g = make_grid_interp(64, 3, 3, (cr_grid_interp)m, "a", P, &rng);
        CR_REQUIRE(g);
        cr_nn_ctx *ctx = make_ctx();
        cr_tensor *y = cr_grid_encoding_forward(ctx, g, cr_nn_from(ctx, 2, (int64_t[]){NR, 2}, uv));
        CR_REQUIRE(y);
        double maxerr = 0, ref[9];
        for (int n = 0; n < NR; n++) {
            grid_ref_interp(g, uv[2 * n], uv[2 * n + 1], ref);
            for (int j = 0; j < 9; j++)
                maxerr = fmax(maxerr, fabs(y->data[n * 9 + j] - ref[j]));
        }
        CR_CHECK(maxerr < 1e-5);
        cr_nn_ctx_destroy(ctx);
        cr_grid_encoding_destroy(g);
        cr_nn_params_destroy(P);
    }
}

/* Central differences for every interpolation on both backward paths: a
 * few points (every level scatters) and enough that every level sorts and
 * gathers. Border cells are among the
 * points, so the cubics' clamped node indices are checked too. */
CR_TEST(nn_layers, grid_encoding_interpolation_gradients) {
    cr_error err = {0};
    cr_rng rng = cr_rng_make(24, 0);
    /* the finest level has 9 x 9 nodes: bilinear gathers above 162 points,
     * the 4 x 4 stencils above 648 */
    const int counts[2] = {12, 700};
    for (int m = 0; m < CR_GRID_INTERP_COUNT; m++)
        for (int c = 0; c < 2; c++) {
            cr_nn_params *P = NULL;
            CR_CHECK_OK(cr_nn_params_create(&P, &err), &err);
            cr_grid_encoding *g = make_grid_interp(8, 3, 2, (cr_grid_interp)m, "g", P, &rng);
            CR_REQUIRE(g);
            int N = counts[c];
            float *uv = malloc((size_t)N * 2 * sizeof(float));
            /* away from the finest cell borders (bilinear's uv gradient
             * jumps there; the cubics' second derivatives), one point
             * clamped per axis */
            for (int k = 0; k < 2 * N; k++)
                uv[k] = ((float)cr_rng_below(&rng, 8) + 0.3f + 0.4f * cr_rng_uniformf(&rng)) / 8.0f;
            uv[0] = -0.2f;
            uv[3] = 1.3f;
            nn_gradcheck_input in[1] = {{2, {N, 2}, uv, 1}};
            nn_gradcheck_def gd = nn_gradcheck_default_def();
            char name[64];
            snprintf(name, sizeof name, "grid_encoding %s, %d points",
                     cr_grid_interp_name((cr_grid_interp)m), N);
            gd.name = name;
            nn_gradcheck_result res;
            CR_CHECK(nn_gradcheck(&gd, 1, in, P, build_grid, g, &res) == 0);
            CR_CHECK(res.checked == 2 * N + cr_grid_encoding_param_count(&g->def));
            free(uv);
            cr_grid_encoding_destroy(g);
            cr_nn_params_destroy(P);
        }
}

/* Across a cell boundary the smooth interpolations are continuous in value
 * and in their uv derivative (the tape's, a random mix of the features);
 * bilinear's derivative jumps there, which is what makes the facets. The
 * boundary 3/8 is one of the finest level only (cells 8, 4, 2), 1/2 one of
 * every level. */
CR_TEST(nn_layers, grid_encoding_continuity) {
    cr_error err = {0};
    cr_rng rng = cr_rng_make(25, 0);
    const float d = 1e-5f; /* either side of the boundary, UV */
    for (int m = 0; m < CR_GRID_INTERP_COUNT; m++)
        for (int c = 0; c < 4; c++) {
            int axis = c & 1;
            float at = c < 2 ? 0.375f : 0.5f;
            cr_nn_params *P = NULL;
            CR_CHECK_OK(cr_nn_params_create(&P, &err), &err);
            cr_grid_encoding *g = make_grid_interp(8, 3, 3, (cr_grid_interp)m, "g", P, &rng);
            CR_REQUIRE(g);
            float uv[4] = {at - d, 0.3f, at + d, 0.3f}; /* (2,2) */
            if (axis == 1) uv[0] = uv[2] = 0.7f, uv[1] = at - d, uv[3] = at + d;
            float mix[18];
            fill_rand(mix, 9, &rng, -1, 1);
            memcpy(mix + 9, mix, 9 * sizeof(float));
            cr_nn_ctx *ctx = make_ctx();
            cr_tensor *u = cr_nn_from(ctx, 2, (int64_t[]){2, 2}, uv);
            u->requires_grad = 1;
            cr_tensor *y = cr_grid_encoding_forward(ctx, g, u);
            cr_tensor *L =
                cr_nn_sum(ctx, cr_nn_mul(ctx, y, cr_nn_from(ctx, 2, (int64_t[]){2, 9}, mix)));
            CR_CHECK_OK(cr_nn_backward(ctx, L, &err), &err);
            /* the mixed value on either side, and its uv derivative */
            double v0 = 0, v1 = 0;
            for (int j = 0; j < 9; j++)
                v0 += mix[j] * y->data[j], v1 += mix[j] * y->data[9 + j];
            double d0 = u->grad[axis], d1 = u->grad[2 + axis];
            double scale = fmax(1.0, fmax(fabs(d0), fabs(d1)));
            double value_jump = fabs(v1 - v0), slope_jump = fabs(d1 - d0);
            if (getenv("CREASE_TEST_VERBOSE"))
                printf("    %s at %g along axis %d: value jump %.3g, slope %.4g | %.4g\n",
                       cr_grid_interp_name((cr_grid_interp)m), at, axis, value_jump, d0, d1);
            CR_CHECK(value_jump < 3 * d * scale + 1e-5); /* the slope times 2d, no step */
            if (m == CR_GRID_BILINEAR)
                CR_CHECK(slope_jump > 0.1 * scale); /* the kink the others remove */
            else /* C1: what is left is the second derivative (~ r^2) times 2d */
                CR_CHECK(slope_jump < 1e-2 * scale);
            cr_nn_ctx_destroy(ctx);
            cr_grid_encoding_destroy(g);
            cr_nn_params_destroy(P);
        }
}

/* --------------------------------------------------------------- WIRE -- */

typedef struct wire_args {
    float omega0, s0;
    int real_input;
} wire_args;

/* Both parts as one (2,...) tensor so the checker sees both outputs. */
static cr_tensor *build_wire(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    const wire_args *a = user;
    cr_tensor *re, *im;
    cr_wire_activation(ctx, in[0], a->real_input ? NULL : in[1], a->omega0, a->s0, &re, &im);
    cr_tensor *parts[2] = {re, im};
    return cr_nn_concat(ctx, 2, parts, 0);
}

CR_TEST(nn_layers, wire_activation_values_and_gradcheck) {
    cr_rng rng = cr_rng_make(31, 0);
    enum { N = 40 };
    float re[N], im[N];
    fill_rand(re, N, &rng, -0.15f, 0.15f);
    fill_rand(im, N, &rng, -0.15f, 0.15f);
    wire_args cases[3] = {{CR_WIRE_OMEGA0, CR_WIRE_S0, 0}, {5.0f, 10.0f, 0}, {20.0f, 10.0f, 1}};
    for (int c = 0; c < 3; c++) {
        cr_nn_ctx *ctx = make_ctx();
        cr_tensor *a = cr_nn_from(ctx, 2, (int64_t[]){N / 4, 4}, re);
        cr_tensor *b = cases[c].real_input ? NULL : cr_nn_from(ctx, 2, (int64_t[]){N / 4, 4}, im);
        cr_tensor *ore = NULL, *oim = NULL;
        cr_wire_activation(ctx, a, b, cases[c].omega0, cases[c].s0, &ore, &oim);
        CR_REQUIRE(ore && oim && ore->shape[0] == N / 4 && oim->shape[1] == 4);
        for (int k = 0; k < N; k++) {
            double complex z = re[k] + I * (cases[c].real_input ? 0.0 : im[k]);
            double sz = cabs(cases[c].s0 * z);
            double complex w = cexp(I * cases[c].omega0 * z) * exp(-sz * sz);
            CR_CHECK_NEAR(ore->data[k], creal(w), 1e-5);
            CR_CHECK_NEAR(oim->data[k], cimag(w), 1e-5);
        }
        cr_nn_ctx_destroy(ctx);
        nn_gradcheck_input in[2] = {{2, {N / 4, 4}, re, 1}, {2, {N / 4, 4}, im, 1}};
        nn_gradcheck_def gd = nn_gradcheck_default_def();
        gd.name = "wire";
        gd.step = 1e-4; /* derivatives reach omega0 s0-scaled curvature ~ 1e3 */
        CR_CHECK(nn_gradcheck(&gd, cases[c].real_input ? 1 : 2, in, NULL, build_wire, &cases[c],
                              NULL) == 0);
    }
}

/* cr_wire_hyper_infer (cpu_wire.c) against the networks computed in double
 * with complex arithmetic, on every SIMD level the machine has: widths 16
 * (AVX-512's register path), 5 and 20 (the portable one, with and without
 * whole vectors), 2 to 5 layers, one and three outputs, points sharing rows.
 * Arguments past the vector sincos's range (omega0 1e5, on real inputs, where
 * the activation's modulus is at most 1) give outputs within the bound. */
static double complex wire_ref(double complex z, double omega0, double s0) {
    double sz = cabs(s0 * z);
    return cexp(I * omega0 * z) * exp(-sz * sz);
}

CR_TEST(nn_layers, wire_hyper_infer_matches_a_double_reference) {
    const struct {
        int width, layers, out;
        float omega0;
    } cases[] = {{16, 5, 3, 5.0f}, {16, 2, 1, 20.0f}, {5, 4, 3, 5.0f},
                 {20, 3, 3, 5.0f}, {16, 2, 3, 1e5f},  {5, 2, 3, 1e5f}};
    enum { G = 7, M = 40 };
    const int prev = cr_nn_cpu_simd();
    double worst = 0;
    for (int level = NN_SIMD_SCALAR; level <= cr_nn_cpu_simd_max(); level++) {
        cr_nn_cpu_set_simd(level);
        for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
            const int w = cases[c].width, L = cases[c].layers, out = cases[c].out;
            const float omega0 = cases[c].omega0, s0 = 10.0f;
            const int64_t P = 3 * w + (L - 2) * (2 * w * w + 2 * w) + 2 * out * w + 2 * out + 1;
            cr_rng rng = cr_rng_make(41 + (uint64_t)c, 0);
            float *theta = malloc(sizeof(float) * (size_t)(G * P)), x[3 * M], y[3 * M];
            int32_t group[M];
            CR_REQUIRE(theta);
            fill_rand(theta, G * P, &rng, -0.2f, 0.2f);
            fill_rand(x, 3 * M, &rng, 0.0f, 1.0f);
            for (int m = 0; m < M; m++)
                group[m] = (int32_t)((m / 2) % G);
            cr_nn_ctx *ctx = make_ctx();
            cr_error err = {0};
            CR_CHECK_OK(cr_wire_hyper_infer(ctx, theta, G, P, group, x + 1, 3, M, w, L, out, omega0,
                                            s0, y, &err),
                        &err);
            for (int m = 0; m < M; m++) {
                const float *t = theta + group[m] * P;
                const double u = x[3 * m + 1], v = x[3 * m + 2];
                double complex z[32], yz[32];
                double bound[32]; /* |y_o| at most its weights' and bias's moduli summed */
                for (int o = 0; o < w; o++)
                    z[o] = wire_ref(t[2 * o] * u + t[2 * o + 1] * v + t[2 * w + o], omega0, s0);
                t += 3 * w;
                for (int l = 1; l < L; l++) {
                    const int no = l == L - 1 ? out : w;
                    const float *Wr = t, *Wi = t + no * w, *br = Wi + no * w, *bi = br + no;
                    for (int o = 0; o < no; o++) {
                        yz[o] = br[o] + I * bi[o];
                        bound[o] = fabs(br[o]);
                        for (int k = 0; k < w; k++) {
                            yz[o] += z[k] * (Wr[o * w + k] + I * Wi[o * w + k]);
                            bound[o] += fabs(Wr[o * w + k]) + fabs(Wi[o * w + k]);
                        }
                    }
                    for (int o = 0; o < no; o++)
                        z[o] = l == L - 1 ? yz[o] : wire_ref(yz[o], omega0, s0);
                    t += 2 * no * w + 2 * no;
                }
                for (int o = 0; o < out; o++) {
                    if (omega0 > 1e4f) {
                        CR_CHECK(isfinite(y[m * out + o]) &&
                                 fabs(y[m * out + o]) <= bound[o] + 1e-5);
                        continue;
                    }
                    double d = fabs(y[m * out + o] - creal(z[o]));
                    worst = fmax(worst, d);
                    CR_CHECK(d < 2e-6 + 1e-5 * fabs(creal(z[o])));
                }
            }
            cr_nn_ctx_destroy(ctx);
            free(theta);
        }
    }
    cr_nn_cpu_set_simd(prev);
    printf("  worst difference %.3g over %d SIMD levels\n", worst, cr_nn_cpu_simd_max() + 1);
}

static cr_tensor *build_complex_linear(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    (void)user;
    cr_tensor *yr, *yi;
    cr_complex_linear(ctx, in[0], in[1], in[2], in[3], in[4], in[5], &yr, &yi);
    cr_tensor *parts[2] = {yr, yi};
    return cr_nn_concat(ctx, 2, parts, 0);
}

CR_TEST(nn_layers, complex_linear_values_and_gradcheck) {
    cr_rng rng = cr_rng_make(32, 0);
    float xr[3 * 4], xi[3 * 4], wr[2 * 4], wi[2 * 4], br[2], bi[2];
    float *arrs[6] = {xr, xi, wr, wi, br, bi};
    int sizes[6] = {12, 12, 8, 8, 2, 2};
    for (int k = 0; k < 6; k++)
        fill_rand(arrs[k], sizes[k], &rng, -1, 1);
    cr_nn_ctx *ctx = make_ctx();
    cr_tensor *yr, *yi;
    cr_complex_linear(
        ctx, cr_nn_from(ctx, 2, (int64_t[]){3, 4}, xr), cr_nn_from(ctx, 2, (int64_t[]){3, 4}, xi),
        cr_nn_from(ctx, 2, (int64_t[]){2, 4}, wr), cr_nn_from(ctx, 2, (int64_t[]){2, 4}, wi),
        cr_nn_from(ctx, 1, (int64_t[]){2}, br), cr_nn_from(ctx, 1, (int64_t[]){2}, bi), &yr, &yi);
    CR_REQUIRE(yr && yi);
    for (int n = 0; n < 3; n++)
        for (int o = 0; o < 2; o++) {
            double complex s = br[o] + I * bi[o];
            for (int k = 0; k < 4; k++)
                s += (xr[n * 4 + k] + I * xi[n * 4 + k]) * (wr[o * 4 + k] + I * wi[o * 4 + k]);
            CR_CHECK_NEAR(yr->data[n * 2 + o], creal(s), 1e-5);
            CR_CHECK_NEAR(yi->data[n * 2 + o], cimag(s), 1e-5);
        }
    cr_nn_ctx_destroy(ctx);
    nn_gradcheck_input in[6] = {{2, {3, 4}, xr, 1}, {2, {3, 4}, xi, 1}, {2, {2, 4}, wr, 1},
                                {2, {2, 4}, wi, 1}, {1, {2}, br, 1},    {1, {2}, bi, 1}};
    nn_gradcheck_def gd = nn_gradcheck_default_def();
    gd.name = "complex_linear";
    CR_CHECK(nn_gradcheck(&gd, 6, in, NULL, build_complex_linear, NULL, NULL) == 0);
}

static cr_tensor *build_wire_mlp(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    return cr_wire_mlp_forward(ctx, user, in[0]);
}

CR_TEST(nn_layers, wire_mlp_gradcheck) {
    cr_error err = {0};
    cr_rng rng = cr_rng_make(33, 0);
    cr_nn_params *P = NULL;
    CR_CHECK_OK(cr_nn_params_create(&P, &err), &err);
    cr_wire_mlp_def d = cr_wire_mlp_default_def();
    d.nlayers = 3;
    memcpy(d.widths, (int[]){3, 6, 6, 2}, 4 * sizeof(int));
    d.omega0 = 5.0f; /* GDSR's */
    d.s0 = 2.0f;     /* a gentler envelope so that every weight gets an O(1) gradient */
    cr_wire_mlp *m = NULL;
    CR_CHECK_OK(cr_wire_mlp_create(&d, P, "wire", &rng, &m, &err), &err);
    CR_REQUIRE(m);
    CR_CHECK(cr_nn_params_numel(P) == cr_wire_mlp_param_count(&d));
    CR_CHECK(cr_wire_mlp_param_count(&d) == (3 * 6 + 6) + 2 * (6 * 6 + 6) + 2 * (6 * 2 + 2));
    CR_CHECK(cr_nn_params_find(P, "wire.2.weight_im") && cr_nn_params_find(P, "wire.0.bias"));
    float x[4 * 3];
    fill_rand(x, 12, &rng, -0.5f, 0.5f);
    nn_gradcheck_input in[1] = {{2, {4, 3}, x, 1}};
    nn_gradcheck_def gd = nn_gradcheck_default_def();
    gd.name = "wire_mlp";
    CR_CHECK(nn_gradcheck(&gd, 1, in, P, build_wire_mlp, m, NULL) == 0);
    cr_wire_mlp_destroy(m);
    cr_nn_params_destroy(P);
}

/* -------------------------------------------------------- hyper-network -- */

static const int32_t hyper_groups[7] = {2, 0, 1, 2, 2, 0, 1};

static cr_tensor *build_hyper(cr_nn_ctx *ctx, cr_tensor *const *in, void *user) {
    return cr_hyper_forward(ctx, user, in[0], in[1], hyper_groups, NULL);
}

static cr_hyper_def hyper_def(void) {
    cr_hyper_def d = cr_hyper_default_def();
    d.generator = mlp_def(2, (int[]){4, 8, 0}, CR_ACT_TANH);
    d.target = mlp_def(3, (int[]){2, 5, 5, 1}, CR_ACT_TANH);
    return d;
}

CR_TEST(nn_layers, hyper_network_values_and_gradcheck) {
    cr_error err = {0};
    cr_rng rng = cr_rng_make(51, 0);
    cr_nn_params *P = NULL;
    CR_CHECK_OK(cr_nn_params_create(&P, &err), &err);
    cr_hyper_def d = hyper_def();
    d.head_scale = 1.0f; /* O(1) generated weights, so all gradients are O(1) */
    cr_hyper *hn = NULL;
    CR_CHECK_OK(cr_hyper_create(&d, P, "hyper", &rng, &hn, &err), &err);
    CR_REQUIRE(hn);
    CR_CHECK(hn->nparams == 2 * 5 + 5 + 5 * 5 + 5 + 5 + 1);
    CR_CHECK(cr_nn_params_find(P, "hyper.gen.1.weight")->shape[0] == hn->nparams);
    float h[3 * 4], x[7 * 2];
    fill_rand(h, 12, &rng, -1, 1);
    fill_rand(x, 14, &rng, -1, 1);

    /* Values: each row through its own group's target, by hand from theta. */
    cr_nn_ctx *ctx = make_ctx();
    cr_tensor *theta = NULL;
    cr_tensor *y = cr_hyper_forward(ctx, hn, cr_nn_from(ctx, 2, (int64_t[]){3, 4}, h),
                                    cr_nn_from(ctx, 2, (int64_t[]){7, 2}, x), hyper_groups, &theta);
    CR_REQUIRE(y && theta && y->shape[0] == 7 && y->shape[1] == 1);
    for (int m = 0; m < 7; m++) {
        const float *t = theta->data + hyper_groups[m] * hn->nparams;
        double a[8] = {x[2 * m], x[2 * m + 1]}, z[8];
        const int *w = d.target.widths;
        for (int l = 0; l < 3; l++) {
            for (int o = 0; o < w[l + 1]; o++) {
                z[o] = t[w[l] * w[l + 1] + o];
                for (int k = 0; k < w[l]; k++)
                    z[o] += t[o * w[l] + k] * a[k];
            }
            for (int o = 0; o < w[l + 1]; o++)
                a[o] = l < 2 ? tanh(z[o]) : z[o];
            t += w[l] * w[l + 1] + w[l + 1];
        }
        CR_CHECK_NEAR(y->data[m], a[0], 1e-5);
    }
    /* Wrong theta width and a bad group id fail on the context. */
    cr_nn_ctx_reset(ctx);
    cr_tensor *bad = cr_nn_zeros(ctx, 2, (int64_t[]){3, hn->nparams + 1});
    CR_CHECK(!cr_hyper_eval_target(ctx, &d.target, bad, cr_nn_from(ctx, 2, (int64_t[]){7, 2}, x),
                                   hyper_groups));
    CR_CHECK(cr_nn_ctx_error(ctx, &err) == CR_ERR_SHAPE);
    cr_nn_ctx_reset(ctx);
    int32_t oob[7] = {0, 1, 2, 3, 0, 0, 0};
    CR_CHECK(!cr_hyper_forward(ctx, hn, cr_nn_from(ctx, 2, (int64_t[]){3, 4}, h),
                               cr_nn_from(ctx, 2, (int64_t[]){7, 2}, x), oob, NULL));
    CR_CHECK(cr_nn_ctx_error(ctx, &err) == CR_ERR_RANGE);
    cr_nn_ctx_destroy(ctx);

    nn_gradcheck_input in[2] = {{2, {3, 4}, h, 1}, {2, {7, 2}, x, 1}};
    nn_gradcheck_def gd = nn_gradcheck_default_def();
    gd.name = "hyper";
    CR_CHECK(nn_gradcheck(&gd, 2, in, P, build_hyper, hn, NULL) == 0);
    cr_hyper_destroy(hn);
    cr_nn_params_destroy(P);
}

CR_TEST(nn_layers, hyper_head_starts_at_a_target_init) {
    cr_error err = {0};
    cr_rng rng = cr_rng_make(52, 0);
    cr_nn_params *P = NULL;
    CR_CHECK_OK(cr_nn_params_create(&P, &err), &err);
    cr_hyper_def d = hyper_def();
    cr_hyper *hn = NULL;
    CR_CHECK_OK(cr_hyper_create(&d, P, "", &rng, &hn, &err), &err);
    CR_REQUIRE(hn);
    /* Head bias = a Kaiming/Glorot target init: the first target weight block
     * is within its Glorot bound (tanh gain 5/3) and not all zero; the head's
     * weights are the generator's own init scaled by 0.01. */
    const cr_linear *head = &hn->generator->layer[1];
    double gb = 5.0 / 3.0 * sqrt(6.0 / (2 + 5)), mx = 0, mw = 0;
    for (int k = 0; k < 10; k++)
        mx = fmax(mx, fabs(head->bias->data[k]));
    for (int64_t k = 0; k < head->weight->numel; k++)
        mw = fmax(mw, fabs(head->weight->data[k]));
    CR_CHECK(mx > 0.3 * gb && mx <= gb);
    double hb = 0.01 * sqrt(6.0 / (8 + 51)); /* Glorot, gain 1: the head has no activation */
    CR_CHECK(mw > 0.5 * hb && mw <= hb * 1.0001);
    CR_CHECK(cr_nn_params_find(P, "gen.0.weight") != NULL);
    cr_hyper_destroy(hn);
    cr_nn_params_destroy(P);
}

/* --------------------------------------------------------------- errors -- */

CR_TEST(nn_layers, bad_definitions_are_refused) {
    cr_error err = {0};
    cr_rng rng = cr_rng_make(1, 0);
    cr_nn_params *P = NULL;
    CR_CHECK_OK(cr_nn_params_create(&P, &err), &err);
    cr_mlp *m = NULL;
    cr_mlp_def d = cr_mlp_default_def();
    CR_CHECK(cr_mlp_create(&d, P, "m", &rng, &m, &err) == CR_ERR_INVALID && !m);
    CR_CHECK(strstr(err.msg, "nlayers") != NULL);
    d = mlp_def(2, (int[]){3, 0, 1}, CR_ACT_RELU);
    CR_CHECK(cr_mlp_create(&d, P, "m", &rng, &m, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "widths[1]") != NULL);
    cr_grid_encoding_def gd = cr_grid_encoding_default_def();
    gd.resolution = 3;
    gd.levels = 3; /* 3 >> 2 = 0 cells */
    cr_grid_encoding *g = NULL;
    CR_CHECK(cr_grid_encoding_create(&gd, P, "g", &rng, &g, &err) == CR_ERR_INVALID && !g);
    cr_hyper_def hd = hyper_def();
    hd.target.layer_norm = 1;
    cr_hyper *hn = NULL;
    CR_CHECK(cr_hyper_create(&hd, P, "h", &rng, &hn, &err) == CR_ERR_INVALID && !hn);

    /* A Jacobian of an input of the wrong width fails on the context. */
    d = mlp_def(2, (int[]){3, 4, 1}, CR_ACT_TANH);
    CR_CHECK_OK(cr_mlp_create(&d, P, "ok", &rng, &m, &err), &err);
    cr_nn_ctx *ctx = make_ctx();
    CR_CHECK(!cr_mlp_input_jacobian(ctx, m, cr_nn_zeros(ctx, 2, (int64_t[]){5, 2}), NULL));
    CR_CHECK(cr_nn_ctx_error(ctx, &err) == CR_ERR_SHAPE);
    cr_nn_ctx_destroy(ctx);
    cr_mlp_destroy(m);
    cr_nn_params_destroy(P);
}
