/* crease/nn_layers.h: neural network layers on the tensor engine (nn.h):
 * weight initialisers, activations, Linear, MLP, the MLP's input Jacobian as
 * a differentiable tensor, Fourier positional encoding, the multi-resolution
 * grid encoding over UV (a fused op), WIRE complex Gabor layers and a
 * hyper-network that generates per-group MLP weights.
 *
 *   cr_mlp_def def = cr_mlp_default_def();
 *   def.nlayers = 4;                               // 2-152-152-152-3
 *   memcpy(def.widths, (int[]){2, 152, 152, 152, 3}, 5 * sizeof(int));
 *   def.act = CR_ACT_RELU;
 *   cr_mlp *mlp = NULL;
 *   CR_TRY(cr_mlp_create(&def, params, "mlp", &rng, &mlp, err));
 *   ... per step:  cr_tensor *y = cr_mlp_forward(ctx, mlp, x);   // (N,2) -> (N,3)
 *
 * Layers own no memory beyond their small struct: weights live in a
 * cr_nn_params store under "<prefix>.<...>" names (PyTorch's layout and
 * naming, so safetensors checkpoints map one to one onto torch modules);
 * every forward takes its tensors from the step arena and fails through the
 * context like any op (NULL out, error recorded on the context).
 *
 * Shapes: N points (rows), IN/OUT features, G groups, M rows of a grouped
 * evaluation, L grid levels, F features per grid node, K frequencies.
 */
#ifndef CREASE_NN_LAYERS_H
#define CREASE_NN_LAYERS_H

#include "crease/nn.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---------------------------------------------------------- activations -- */

typedef enum cr_act {
    CR_ACT_NONE = 0, /* identity */
    CR_ACT_RELU,
    CR_ACT_LEAKY_RELU, /* param: negative-side slope */
    CR_ACT_TANH,
    CR_ACT_SIGMOID,
    CR_ACT_SOFTPLUS, /* param: beta, log(1 + exp(beta z)) / beta */
    CR_ACT_SIN,      /* param: omega, sin(omega z) (SIREN, Sitzmann et al. 2020) */
    CR_ACT_COUNT
} cr_act;

const char *cr_act_name(cr_act act); /* "relu", "sin", ... */
/* act(z), same shape. */
cr_tensor *cr_act_forward(cr_nn_ctx *ctx, cr_act act, float param, cr_tensor *z);
/* act'(z) as a differentiable tensor (ones for CR_ACT_NONE; relu is
 * leaky_relu_deriv with slope 0, a step whose own gradient is zero). */
cr_tensor *cr_act_deriv(cr_nn_ctx *ctx, cr_act act, float param, cr_tensor *z);

/* --------------------------------------------------------------- init -- */

/* Initialisers fill t->data from a seeded generator (same seed, same
 * numbers). fan_in is the last axis, fan_out the rest: a (OUT,IN) weight. */
typedef enum cr_init {
    CR_INIT_AUTO = 0, /* MLP: chosen from the activation (see cr_mlp_def.init) */
    CR_INIT_ZERO,
    CR_INIT_GLOROT_UNIFORM,  /* U(+-gain sqrt(6/(in+out))), Glorot & Bengio 2010 */
    CR_INIT_KAIMING_UNIFORM, /* U(+-gain sqrt(3/in)), He et al. 2015 */
    CR_INIT_KAIMING_NORMAL,  /* N(0, gain/sqrt(in)) */
    CR_INIT_SIREN_FIRST,     /* U(+-1/in), SIREN's first layer */
    CR_INIT_SIREN,           /* U(+-sqrt(6/in)/omega), SIREN's (and WIRE's) later layers */
    CR_INIT_TORCH            /* torch.nn.Linear's default: U(+-1/sqrt(in)) */
} cr_init;

void cr_init_zero(cr_tensor *t);
void cr_init_glorot_uniform(cr_tensor *w, cr_rng *rng, float gain);
void cr_init_kaiming_uniform(cr_tensor *w, cr_rng *rng, float gain);
void cr_init_kaiming_normal(cr_tensor *w, cr_rng *rng, float gain);
/* first: U(+-1/in); else U(+-sqrt(6/in)/omega). */
void cr_init_siren(cr_tensor *w, cr_rng *rng, int first, float omega);
/* PyTorch's torch.nn.init.calculate_gain: relu sqrt(2), leaky_relu
 * sqrt(2/(1+slope^2)), tanh 5/3, others 1; softplus is given relu's sqrt(2)
 * since it is a smoothed relu. */
float cr_init_gain(cr_act act, float param);

/* ------------------------------------------------------------- linear -- */

typedef struct cr_linear_def {
    int in, out;     /* features, >= 1 */
    int bias;        /* 1: add "<prefix>.bias" (default 1) */
    cr_init init;    /* weights (default CR_INIT_GLOROT_UNIFORM; AUTO means the same here) */
    float gain;      /* glorot and kaiming gain (default 1) */
    float omega;     /* CR_INIT_SIREN frequency (default 30, SIREN's omega_0) */
    uint32_t cookie; /* set by cr_linear_default_def; a hand-zeroed def is a bug */
} cr_linear_def;

/* Borrowed pointers into the store (valid until it is destroyed). */
typedef struct cr_linear {
    cr_tensor *weight; /* (OUT,IN) "<prefix>.weight" */
    cr_tensor *bias;   /* (OUT) "<prefix>.bias", or NULL */
    int in, out;
} cr_linear;

cr_linear_def cr_linear_default_def(void);
/* Adds the parameters and initialises them. Biases start at zero, except
 * under CR_INIT_TORCH, CR_INIT_SIREN_FIRST and CR_INIT_SIREN, which keep
 * PyTorch's U(+-1/sqrt(in)) bias as the reference SIREN and WIRE code do. */
cr_status cr_linear_create(const cr_linear_def *def, cr_nn_params *params, const char *prefix,
                           cr_rng *rng, cr_linear *out, cr_error *err);
/* x (...,IN) -> (...,OUT). */
cr_tensor *cr_linear_forward(cr_nn_ctx *ctx, const cr_linear *lin, cr_tensor *x);

/* ---------------------------------------------------------------- MLP -- */

enum { CR_MLP_MAX_LAYERS = 16 };

typedef struct cr_mlp_def {
    int nlayers;                       /* linear layers, 1..CR_MLP_MAX_LAYERS (default 0: set it) */
    int widths[CR_MLP_MAX_LAYERS + 1]; /* widths[0] inputs, widths[nlayers] outputs, all >= 1 */
    cr_act act;                        /* after every hidden layer (default CR_ACT_RELU) */
    float leaky_slope;                 /* CR_ACT_LEAKY_RELU (default 0.01) */
    float softplus_beta;               /* CR_ACT_SOFTPLUS (default 1; SDF nets use 100) */
    float first_omega;                 /* CR_ACT_SIN: omega of the first layer (default 30) */
    float hidden_omega;                /* CR_ACT_SIN: omega of later layers (default 30) */
    cr_act out_act;                    /* after the last layer (default CR_ACT_NONE); its param
                                          is the same field as for `act` */
    int layer_norm;                    /* 1: linear -> layer norm -> act on hidden layers */
    float ln_eps;                      /* layer-norm epsilon (default 1e-5, PyTorch's) */
    int residual;                      /* 1: h + act(...) on hidden->hidden layers of equal width */
    /* AUTO: sin nets get SIREN_FIRST then SIREN; otherwise a layer followed by
     * relu, leaky_relu or softplus gets Kaiming uniform, any other Glorot
     * uniform, with cr_init_gain of that activation. Explicit kinds apply to
     * every layer (CR_INIT_SIREN: SIREN_FIRST on layer 0). */
    cr_init init;
    uint32_t cookie; /* set by cr_mlp_default_def */
} cr_mlp_def;

typedef struct cr_mlp {
    cr_mlp_def def;
    cr_linear layer[CR_MLP_MAX_LAYERS];      /* "<prefix>.<i>.weight" / ".bias" */
    cr_tensor *ln_weight[CR_MLP_MAX_LAYERS]; /* (C) "<prefix>.<i>.ln.weight" (ones) or NULL */
    cr_tensor *ln_bias[CR_MLP_MAX_LAYERS];   /* (C) "<prefix>.<i>.ln.bias" (zeros) or NULL */
} cr_mlp;

cr_mlp_def cr_mlp_default_def(void);
/* CR_ERR_INVALID names the bad field (layer count, a width, a parameter). */
cr_status cr_mlp_def_validate(const cr_mlp_def *def, cr_error *err);
/* prefix "" gives names "0.weight", ... (a top-level torch.nn.Sequential). */
cr_status cr_mlp_create(const cr_mlp_def *def, cr_nn_params *params, const char *prefix,
                        cr_rng *rng, cr_mlp **out, cr_error *err);
void cr_mlp_destroy(cr_mlp *mlp); /* NULL is a no-op; the parameters stay in the store */
/* x (...,IN) -> (...,OUT). */
cr_tensor *cr_mlp_forward(cr_nn_ctx *ctx, const cr_mlp *mlp, cr_tensor *x);
/* Floats the MLP adds to a store (weights, biases, layer-norm affines). */
int64_t cr_mlp_param_count(const cr_mlp_def *def);
/* The activation after linear layer i (act for hidden layers, out_act for
 * the last) and its parameter. */
cr_act cr_mlp_layer_act(const cr_mlp_def *def, int i, float *param);
/* 1 when layer i is a hidden->hidden layer of equal width under def.residual. */
int cr_mlp_layer_residual(const cr_mlp_def *def, int i);

/* Input Jacobian of an MLP, built only from differentiable ops (forward-mode
 * propagation J_{l+1} = diag(act'(z_l)) W_l J_l, through layer norm and
 * residual connections too), so a loss on J (eikonal (|grad f| - 1)^2, a
 * stretch term on tangents) backpropagates to the weights and to x.
 *
 * Returns J (N,IN,OUT) with J[n][i][o] = d y[n][o] / d x[n][i]: row i is the
 * derivative of the output along input axis i (for a UV -> 3-D map, the two
 * tangent vectors dp/du and dp/dv; for a scalar field, the gradient as
 * (N,IN,1)). This is the transpose of the (OUT,IN) convention because the
 * chain then runs as row-wise linear ops with no transpose op. x (...,IN) is
 * taken as N = numel/IN rows; *y_out (may be NULL) gets the forward value
 * (N,OUT). relu and leaky_relu are accepted: J is then exact almost
 * everywhere and piecewise constant in x, so a loss on J reaches the weights
 * but carries no signal about the activation pattern. */
cr_tensor *cr_mlp_input_jacobian(cr_nn_ctx *ctx, const cr_mlp *mlp, cr_tensor *x,
                                 cr_tensor **y_out);

/* ----------------------------------------------------------- encodings -- */

/* Fourier positional encoding (NeRF's, Mildenhall et al. 2020): x (...,D) ->
 * (..., D + 2 D K), ordered [x, sin(pi x), cos(pi x), sin(2 pi x), cos(2 pi x),
 * ..., sin(2^(K-1) pi x), cos(2^(K-1) pi x)], each block D wide. The drape
 * paper's PE model: D = 2, K = 4 -> 18 features. Built from ops. K in
 * 0..30 (K = 0 returns x itself). */
cr_tensor *cr_fourier_encoding_forward(cr_nn_ctx *ctx, cr_tensor *x, int nfreq);
int64_t cr_fourier_encoding_dim(int64_t in_dim, int nfreq);

enum { CR_GRID_MAX_LEVELS = 8, CR_GRID_MAX_FEATURES = 64 };

/* How a level's features are interpolated between its nodes, per axis (the
 * 2-D weight of a node is the product of its u and v weights; f is the
 * point's fraction of its cell, i its cell):
 *   BILINEAR     nodes i, i+1, weights 1-f, f: C0, the derivative jumps at
 *                every cell boundary (the paper's eq. 4)
 *   BSPLINE      nodes i-1..i+2, the uniform cubic B-spline (approximates
 *                the nodes: (G[i-1] + 4 G[i] + G[i+1]) / 6 at node i): C2
 * (Smoothstep, Instant-NGP's, and Catmull-Rom were measured on the drape and
 * not adopted: docs/drape.md, "Grid interpolation".)
 * The 4 x 4 stencils clamp node indices to the grid (node -1 reads node 0,
 * node r+1 node r), so the border cells extrapolate a constant node. */
typedef enum cr_grid_interp {
    CR_GRID_BILINEAR = 0,
    CR_GRID_BSPLINE,
    CR_GRID_INTERP_COUNT
} cr_grid_interp;

/* "bilinear", "bspline"; "?" out of range. */
const char *cr_grid_interp_name(cr_grid_interp interp);
/* CR_ERR_INVALID listing the names for anything else. */
cr_status cr_grid_interp_parse(const char *name, cr_grid_interp *out, cr_error *err);

/* Multi-resolution grid encoding over UV (drape paper, sec. 3.1, eq. 4-5).
 * Level l has r_l = floor(resolution / 2^l) cells per side, so (r_l + 1)^2
 * nodes of F features: resolution 100 with 2 levels gives the paper's
 * 101x101x3 and 51x51x3 grids (38,406 floats). */
typedef struct cr_grid_encoding_def {
    int levels; /* L, 1..CR_GRID_MAX_LEVELS, with floor(resolution / 2^(L-1)) >= 1 (default 2) */
    int resolution;        /* cells per side of the finest level (default 100) */
    int features;          /* F per node, 1..CR_GRID_MAX_FEATURES (default 3) */
    float init_range;      /* nodes start U(-r, r) (default 1e-4, Instant-NGP's) */
    cr_grid_interp interp; /* default CR_GRID_BILINEAR (the paper's) */
    uint32_t cookie;       /* set by cr_grid_encoding_default_def */
} cr_grid_encoding_def;

typedef struct cr_grid_encoding {
    cr_grid_encoding_def def;
    int cells[CR_GRID_MAX_LEVELS];        /* r_l */
    cr_tensor *level[CR_GRID_MAX_LEVELS]; /* (r_l+1, r_l+1, F) "<prefix>.level<l>", [iv][iu][f] */
    cr_fused_op op;                       /* the fused op (user = this struct) */
} cr_grid_encoding;

cr_grid_encoding_def cr_grid_encoding_default_def(void);
cr_status cr_grid_encoding_create(const cr_grid_encoding_def *def, cr_nn_params *params,
                                  const char *prefix, cr_rng *rng, cr_grid_encoding **out,
                                  cr_error *err);
void cr_grid_encoding_destroy(cr_grid_encoding *g); /* NULL is a no-op */
/* uv (N,2) in [0,1]^2 -> (N, L F): level 0 (finest) first, F features each,
 * interpolated by def.interp from the nodes around the cell holding (u,v)
 * (node (iu,iv) sits at (iu/r, iv/r)). One fused node; backward adds into
 * the level grids (a deterministic gather per node after a counting sort of
 * the points by cell, so it is race-free and independent of the thread
 * count) and into uv (the interpolant's derivative: for bilinear piecewise
 * linear and discontinuous across cells, continuous for the others). u and
 * v are clamped to [0,1] (their gradient is zero where clamping acted);
 * non-finite uv fail with CR_ERR_NAN. */
cr_tensor *cr_grid_encoding_forward(cr_nn_ctx *ctx, const cr_grid_encoding *g, cr_tensor *uv);
int64_t cr_grid_encoding_param_count(const cr_grid_encoding_def *def);
int cr_grid_encoding_out_dim(const cr_grid_encoding_def *def); /* L F */

/* ---------------------------------------------------------------- WIRE -- */

/* WIRE (Saragadam et al., CVPR 2023): complex Gabor wavelet activation
 *   wire(z) = exp(j omega0 z) exp(-|s0 z|^2),  z = re + j im,
 * i.e. exp(-omega0 im - s0^2 (re^2 + im^2)) (cos(omega0 re) + j sin(omega0 re)).
 * Complex tensors are carried as (re, im) pairs of real tensors. The WIRE
 * paper's defaults are omega0 = 20, s0 = 10; GDSR uses omega0 = 5, s0 = 10. */
#define CR_WIRE_OMEGA0 20.0f
#define CR_WIRE_S0 10.0f

/* One fused node with a hand-written backward. im may be NULL (real input,
 * the first layer). Returns *out_re (NULL on error); out_im may be NULL. */
cr_tensor *cr_wire_activation(cr_nn_ctx *ctx, cr_tensor *re, cr_tensor *im, float omega0, float s0,
                              cr_tensor **out_re, cr_tensor **out_im);
/* (x_re + j x_im)(W_re + j W_im)^T + (b_re + j b_im): x (...,IN), W (OUT,IN),
 * b (OUT). x_im NULL means real input; b_re, b_im may be NULL. Returns *y_re. */
cr_tensor *cr_complex_linear(cr_nn_ctx *ctx, cr_tensor *x_re, cr_tensor *x_im, cr_tensor *w_re,
                             cr_tensor *w_im, cr_tensor *b_re, cr_tensor *b_im, cr_tensor **y_re,
                             cr_tensor **y_im);

/* WIRE networks whose parameters are rows of theta (G,P), as a hyper-network
 * makes them (gdsr's fields), evaluated point by point with the context's
 * gradient off: point m runs row group[m]'s network at its two inputs
 * x[m ldx], x[m ldx + 1] and writes the real part of the last layer to
 * y (M,out). A row holds, in order: the real first layer's weight (width,2)
 * row-major and bias (width); then for each later layer the weight's real
 * and imaginary parts (o,width) row-major and the bias's (o), o = width but
 * `out` for the last; WIRE after every layer but the last. So P is at least
 * 3 width + (layers - 2)(2 width^2 + 2 width) + 2 out width + 2 out. layers
 * 2..CR_MLP_MAX_LAYERS, width 1..CR_WIRE_MAX_WIDTH, out >= 1. One fused kernel a point;
 * 16-wide networks in registers on AVX-512 (cpu_wire.c). Returns
 * CR_ERR_INVALID on a bad size or a group outside [0,G). */
enum { CR_WIRE_MAX_WIDTH = 256 }; /* cr_wire_hyper_infer's widest network */
cr_status cr_wire_hyper_infer(cr_nn_ctx *ctx, const float *theta, int64_t G, int64_t P,
                              const int32_t *group, const float *x, int64_t ldx, int64_t M,
                              int width, int layers, int out, float omega0, float s0, float *y,
                              cr_error *err);

/* A WIRE network as in the WIRE reference code: a real first linear layer,
 * WIRE after every hidden layer, complex later layers, and the real part of
 * the last (complex, unactivated) layer as the output. */
typedef struct cr_wire_mlp_def {
    int nlayers;                       /* 2..CR_MLP_MAX_LAYERS (default 0: set it) */
    int widths[CR_MLP_MAX_LAYERS + 1]; /* widths[0] inputs ... widths[nlayers] outputs */
    float omega0;                      /* default CR_WIRE_OMEGA0 */
    float s0;                          /* default CR_WIRE_S0 */
    uint32_t cookie;                   /* set by cr_wire_mlp_default_def */
} cr_wire_mlp_def;

typedef struct cr_wire_mlp {
    cr_wire_mlp_def def;
    cr_linear first; /* "<prefix>.0.weight" / ".bias" */
    cr_tensor *w_re[CR_MLP_MAX_LAYERS],
        *w_im[CR_MLP_MAX_LAYERS]; /* (OUT,IN) ".<i>.weight_re/_im" */
    cr_tensor *b_re[CR_MLP_MAX_LAYERS], *b_im[CR_MLP_MAX_LAYERS]; /* (OUT) ".<i>.bias_re/_im" */
} cr_wire_mlp;

cr_wire_mlp_def cr_wire_mlp_default_def(void);
/* Every weight and bias part starts U(+-1/sqrt(in)) (PyTorch's default,
 * which the WIRE reference keeps). */
cr_status cr_wire_mlp_create(const cr_wire_mlp_def *def, cr_nn_params *params, const char *prefix,
                             cr_rng *rng, cr_wire_mlp **out, cr_error *err);
void cr_wire_mlp_destroy(cr_wire_mlp *m); /* NULL is a no-op */
/* x (N,IN) -> real part of the output (N,OUT). */
cr_tensor *cr_wire_mlp_forward(cr_nn_ctx *ctx, const cr_wire_mlp *m, cr_tensor *x);
/* Real floats in the store (a complex weight counts twice). */
int64_t cr_wire_mlp_param_count(const cr_wire_mlp_def *def);

/* ------------------------------------------------------ hyper-network -- */

/* A generator MLP maps per-group features h (G,D) to the flat parameters
 * theta (G,P) of a small target MLP, which is then evaluated on each group's
 * own points. theta's layout per group follows the target's layers in order:
 * weight (OUT,IN) row-major, then bias (OUT), i.e. the order and layout of
 * cr_mlp's parameters, so P = cr_mlp_param_count(&target). Real layers only:
 * a method that wants WIRE target layers slices theta itself and uses
 * cr_complex_linear / cr_wire_activation per group.
 * Reference: Ha et al., HyperNetworks, 2016; the head initialisation follows
 * the SIREN code's hyper_weight_init (Sitzmann et al. 2020). */
typedef struct cr_hyper_def {
    /* widths[0] = D; widths[nlayers] is overwritten with P at create. */
    cr_mlp_def generator;
    /* The per-group MLP; layer_norm and residual must be off. */
    cr_mlp_def target;
    /* The generator's last layer starts with weights scaled by head_scale
     * (default 0.01) and with a bias holding one initialisation of the target
     * (its own init rule), so every group starts near a well-initialised
     * target network. */
    float head_scale;
    uint32_t cookie; /* set by cr_hyper_default_def */
} cr_hyper_def;

typedef struct cr_hyper {
    cr_hyper_def def;  /* generator.widths[nlayers] = P */
    cr_mlp *generator; /* "<prefix>.gen.<i>.weight", ... */
    int64_t nparams;   /* P */
} cr_hyper;

cr_hyper_def cr_hyper_default_def(void);
cr_status cr_hyper_create(const cr_hyper_def *def, cr_nn_params *params, const char *prefix,
                          cr_rng *rng, cr_hyper **out, cr_error *err);
void cr_hyper_destroy(cr_hyper *hn); /* NULL is a no-op */
/* h (G,D), x (M,IN), group (M) int32 in [0,G) (host, copied) -> y (M,OUT):
 * y[m] = target_{theta[group[m]]}(x[m]). Gradients reach the generator's
 * parameters, h and x. *theta_out (may be NULL) gets theta (G,P). */
cr_tensor *cr_hyper_forward(cr_nn_ctx *ctx, const cr_hyper *hn, cr_tensor *h, cr_tensor *x,
                            const int32_t *group, cr_tensor **theta_out);
/* The target half alone, for parameters made any other way: theta (G,P)
 * laid out as above, x (M,IN), group (M) -> (M,OUT). Uses
 * cr_nn_matmul_grouped per layer and gathers each row's bias. */
cr_tensor *cr_hyper_eval_target(cr_nn_ctx *ctx, const cr_mlp_def *target, cr_tensor *theta,
                                cr_tensor *x, const int32_t *group);

#ifdef __cplusplus
}
#endif
#endif
