/* mlp_fused.c: a whole MLP as one op, run by blocks of rows.
 *
 * The layer-by-layer path (cr_nn_linear_act per layer) runs every layer over
 * the whole batch: a parallel region per GEMM and per activation pass, and
 * each layer's activations and gradients make a round trip to memory. With
 * 64-wide layers over thousands of rows those round trips and the regions'
 * wake-ups, not the multiply-adds, set the step's time, and a second thread
 * gained little (docs/nn.md, "The whole MLP by blocks of rows"). Here:
 *
 *   forward   one parallel region over blocks of BR rows; a block goes
 *             through every layer (GEMM, bias and activation) while it is in
 *             cache. The hidden layers' outputs are kept for backward only
 *             when something needs a gradient.
 *   backward  one parallel region over a fixed number of row chunks; a chunk
 *             walks its blocks from the last layer to the first: dz = dy
 *             act'(y) with the bias's column sums, dW += dz^T x into the
 *             chunk's own partial gradient, dx = dz W for the layer below.
 *             The partials are then added in chunk order, so the sums do not
 *             depend on the thread count (the chunks are fixed by the shape).
 *
 * The kernels are the CPU backend's own (the engine's GEMM, bias +
 * activation, activation gradient + bias sums), called directly from inside
 * the region, where they run on the calling thread (cr_parallel_for does not
 * nest); cr_nn_mlp_fused_usable keeps the op to the CPU backend. Used by cr_mlp_forward
 * for an MLP of fusable activations without layer norm or residual links on
 * the CPU backend; every other MLP takes the layer-by-layer path.
 * Off by default (CREASE_NN_MLP=fused or cr_nn_mlp_fused_set(1) turns it
 * on): since the layer path keeps each thread on its own rows and splits the
 * weights gradient by chunks of rows (cr_parallel_for, cpu_gemm.c), it is
 * within 5 % of this op on the drape's MLP shape, and this op's extra code
 * path is not worth a default (docs/nn.md, "Static chunks").
 * Leaves out: recomputing the forward in backward instead of keeping it
 * (checkpointing), a GPU version.
 */
#include "nn/mlp_fused.h"

#include "nn/cpu/cpu.h"
#include "nn/tape.h"

#include <stdlib.h>
#include <string.h>

enum {
    FUSED_BLOCK_FLOATS = 32768, /* a block's widest activation, floats: 128 KB, in L2 */
    FUSED_BLOCK_MIN = 32,
    FUSED_BLOCK_MAX = 512,
    FUSED_CHUNKS = 16,              /* row chunks at most: the partial gradients' count */
    FUSED_PARTIAL_FLOATS = 1 << 22, /* the partial gradients together at most (16 MB), so a
                                       wide MLP takes fewer chunks */
};

typedef struct mlp_fused {
    cr_fused_op op;
    int nl;
    int width[CR_MLP_MAX_LAYERS + 1];
    cr_op act[CR_MLP_MAX_LAYERS];
    float p[CR_MLP_MAX_LAYERS];
    int64_t rows, block_rows, nblocks;
    float *hidden[CR_MLP_MAX_LAYERS]; /* (rows, width[l+1]) outputs of layers 0..nl-2, or NULL */
} mlp_fused;

/* C = A op B (+ C) on the calling thread, by the engine's own GEMM whatever
 * cr_nn_cpu_gemm would pick: OpenBLAS called from inside the region takes
 * other paths than outside it (and on one thread than on several), which
 * made the bits depend on the thread count; the own GEMM sums each element
 * in one order whatever the product's height. The reference loop is the
 * fallback when the own GEMM cannot get its packing memory. */
static void block_gemm(int ta, int64_t M, int64_t N, int64_t K, const float *A, int64_t lda,
                       const float *B, int64_t ldb, float beta, float *C, int64_t ldc) {
    if (cr_nn_cpu_gemm_own(cr_nn_cpu_simd(), ta, 0, M, N, K, 1.0f, A, lda, B, ldb, beta, C, ldc) !=
        0)
        cr_nn_cpu_gemm_naive(ta, 0, M, N, K, 1.0f, A, lda, B, ldb, beta, C, ldc);
}

/* The first block of chunk c of `chunks` (the chunk's end: that of c + 1). */
static int64_t chunk_first_block(const mlp_fused *m, int64_t c, int64_t chunks) {
    return m->nblocks * c / chunks;
}

/* Rows of block blk: block_rows but for the last, partial one. */
static int64_t block_height(const mlp_fused *m, int64_t blk) {
    const int64_t left = m->rows - blk * m->block_rows;
    return left < m->block_rows ? left : m->block_rows;
}

static int max_width(const mlp_fused *m) {
    int w = 0;
    for (int l = 0; l <= m->nl; l++)
        w = m->width[l] > w ? m->width[l] : w;
    return w;
}

/* ------------------------------------------------------------ forward -- */

typedef struct fwd_job {
    const mlp_fused *m;
    const float *x;
    float *y;
    const float *wt[CR_MLP_MAX_LAYERS], *b[CR_MLP_MAX_LAYERS]; /* W^T (in, out): read in place */
    float *scratch;                                            /* (chunks, 2, block_rows, widest) */
    int64_t chunks;
} fwd_job;

/* Chunks [begin, end): their blocks through every layer. */
static void forward_chunks(void *arg, int64_t begin, int64_t end) {
    const fwd_job *j = arg;
    const mlp_fused *m = j->m;
    const int64_t one = m->block_rows * max_width(m);
    for (int64_t c = begin; c < end; c++) {
        float *tmp[2] = {j->scratch + 2 * c * one, j->scratch + (2 * c + 1) * one};
        const int64_t b1 = chunk_first_block(m, c + 1, j->chunks);
        for (int64_t blk = chunk_first_block(m, c, j->chunks); blk < b1; blk++) {
            const int64_t r0 = blk * m->block_rows, rr = block_height(m, blk);
            const float *h = j->x + r0 * m->width[0];
            for (int l = 0; l < m->nl; l++) {
                const int in = m->width[l], out = m->width[l + 1];
                float *z = l == m->nl - 1 ? j->y + r0 * out
                           : m->hidden[l] ? m->hidden[l] + r0 * out
                                          : tmp[l % 2];
                block_gemm(0, rr, out, in, h, in, j->wt[l], out, 0.0f, z, out);
                cr_nn_cpu_bias_act_forward(m->act[l], m->p[l], j->b[l], z, rr, out);
                h = z;
            }
        }
    }
}

static int64_t chunk_count(const mlp_fused *m) {
    return m->nblocks < FUSED_CHUNKS ? m->nblocks : FUSED_CHUNKS;
}

static cr_status fused_forward(const cr_fused_op *op, cr_nn_ctx *ctx, cr_tensor *const *in, int nin,
                               cr_tensor *const *out, int nout, void **stash, cr_error *err) {
    (void)nin, (void)nout, (void)stash;
    mlp_fused *m = op->user;
    fwd_job j = {.m = m, .x = in[0]->data, .y = out[0]->data, .chunks = chunk_count(m)};
    if (j.chunks == 0) return CR_OK; /* no rows */
    int keep = in[0]->requires_grad;
    for (int l = 0; l < m->nl; l++) {
        const cr_tensor *w = in[1 + 2 * l], *b = in[2 + 2 * l];
        const int64_t nout_l = m->width[l + 1], nin_l = m->width[l];
        float *wt = cr_nn_scratch(ctx, "mlp", (size_t)(nout_l * nin_l) * sizeof(float));
        if (!wt) return CR_FAIL(err, CR_ERR_MEMORY, "mlp: no arena for the weights' transpose");
        for (int64_t o = 0; o < nout_l; o++)
            for (int64_t i = 0; i < nin_l; i++)
                wt[i * nout_l + o] = w->data[o * nin_l + i];
        j.wt[l] = wt;
        j.b[l] = b ? b->data : NULL;
        keep |= w->requires_grad || (b && b->requires_grad);
    }
    keep &= cr_nn_ctx_grad_enabled(ctx);
    for (int l = 0; l < m->nl - 1; l++) {
        m->hidden[l] = NULL;
        if (!keep) continue;
        m->hidden[l] =
            cr_nn_scratch(ctx, "mlp", (size_t)(m->rows * m->width[l + 1]) * sizeof(float));
        if (!m->hidden[l]) return CR_FAIL(err, CR_ERR_MEMORY, "mlp: no arena for the activations");
    }
    j.scratch = cr_nn_scratch(
        ctx, "mlp", (size_t)(j.chunks * 2 * m->block_rows * max_width(m)) * sizeof(float));
    if (!j.scratch) return CR_FAIL(err, CR_ERR_MEMORY, "mlp: no arena for the blocks' scratch");
    cr_parallel_for(j.chunks, 1, forward_chunks, &j);
    return CR_OK;
}

/* ----------------------------------------------------------- backward -- */

typedef struct bwd_job {
    const mlp_fused *m;
    const float *x, *y_out, *dy; /* the input, the op's output and its gradient */
    float *dx;                   /* x's grad or NULL */
    const float *w[CR_MLP_MAX_LAYERS];
    int64_t off_w[CR_MLP_MAX_LAYERS], off_b[CR_MLP_MAX_LAYERS]; /* in a partial, or -1 */
    int64_t nparts;  /* floats of one chunk's partial gradient */
    float *partials; /* (chunks, nparts), each zeroed by its chunk */
    float *scratch;  /* (chunks, 3, block_rows, widest) */
    int64_t chunks;
} bwd_job;

static void backward_chunks(void *arg, int64_t begin, int64_t end) {
    const bwd_job *j = arg;
    const mlp_fused *m = j->m;
    const int64_t one = m->block_rows * max_width(m);
    for (int64_t c = begin; c < end; c++) {
        float *dz = j->scratch + 3 * c * one, *dh[2] = {dz + one, dz + 2 * one};
        float *part = j->partials + c * j->nparts;
        memset(part, 0, (size_t)j->nparts * sizeof(float));
        const int64_t b1 = chunk_first_block(m, c + 1, j->chunks);
        for (int64_t blk = chunk_first_block(m, c, j->chunks); blk < b1; blk++) {
            const int64_t r0 = blk * m->block_rows, rr = block_height(m, blk);
            const float *g = j->dy + r0 * m->width[m->nl]; /* dL/d(layer l's output) */
            for (int l = m->nl - 1; l >= 0; l--) {
                const int in = m->width[l], out = m->width[l + 1];
                const float *y = (l == m->nl - 1 ? j->y_out : m->hidden[l]) + r0 * out;
                const float *h = l == 0 ? j->x + r0 * in : m->hidden[l - 1] + r0 * in;
                float *db = j->off_b[l] >= 0 ? part + j->off_b[l] : NULL;
                const float *gz = g;
                if (m->act[l] != CR_OP_NONE) {
                    cr_nn_cpu_act_bias_backward(m->act[l], m->p[l], y, g, rr, out, dz, db);
                    gz = dz;
                } else if (db) {
                    cr_nn_cpu_act_bias_backward(CR_OP_NONE, 0.0f, g, g, rr, out, NULL, db);
                }
                if (j->off_w[l] >= 0)
                    block_gemm(1, out, in, rr, gz, out, h, in, 1.0f, part + j->off_w[l], in);
                if (l > 0) {
                    float *next = dh[l % 2];
                    block_gemm(0, rr, in, out, gz, out, j->w[l], in, 0.0f, next, in);
                    g = next;
                } else if (j->dx) {
                    block_gemm(0, rr, in, out, gz, out, j->w[0], in, 1.0f, j->dx + r0 * in, in);
                }
            }
        }
    }
}

/* The gradients the partials add to: grad[k] takes partial floats
 * [off[k], off[k] + n[k]) of every chunk; off increases with k. */
typedef struct sum_job {
    const bwd_job *j;
    int count;
    float *grad[2 * CR_MLP_MAX_LAYERS];
    int64_t off[2 * CR_MLP_MAX_LAYERS], n[2 * CR_MLP_MAX_LAYERS];
} sum_job;

/* Partial floats [begin, end): each added, chunk by chunk in order, to its
 * gradient element (one region for every tensor of the MLP). */
static void sum_partials(void *arg, int64_t begin, int64_t end) {
    const sum_job *s = arg;
    const bwd_job *j = s->j;
    for (int k = 0; k < s->count; k++) {
        const int64_t lo = begin > s->off[k] ? begin : s->off[k];
        const int64_t hi = end < s->off[k] + s->n[k] ? end : s->off[k] + s->n[k];
        for (int64_t i = lo; i < hi; i++) {
            double acc = 0.0;
            for (int64_t c = 0; c < j->chunks; c++)
                acc += j->partials[c * j->nparts + i];
            s->grad[k][i - s->off[k]] += (float)acc;
        }
    }
}

static cr_status fused_backward(const cr_fused_op *op, cr_nn_ctx *ctx, cr_tensor *const *in,
                                int nin, cr_tensor *const *out, int nout, void *stash,
                                cr_error *err) {
    (void)nin, (void)nout, (void)stash;
    mlp_fused *m = op->user;
    bwd_job j = {.m = m,
                 .x = in[0]->data,
                 .y_out = out[0]->data,
                 .dy = out[0]->grad,
                 .dx = nn_gout(in[0]),
                 .chunks = chunk_count(m)};
    if (j.chunks == 0) return CR_OK; /* no rows */
    for (int l = 0; l < m->nl; l++) {
        const cr_tensor *w = in[1 + 2 * l], *b = in[2 + 2 * l];
        j.w[l] = w->data;
        j.off_w[l] = j.off_b[l] = -1;
        if (nn_gout(w)) j.off_w[l] = j.nparts, j.nparts += w->numel;
        if (nn_gout(b)) j.off_b[l] = j.nparts, j.nparts += b->numel;
    }
    for (int l = 0; l < m->nl - 1; l++)
        if (!m->hidden[l])
            return CR_FAIL(err, CR_ERR_INVALID, "mlp: backward without the forward's activations");
    if (j.nparts > 0 && j.chunks * j.nparts > FUSED_PARTIAL_FLOATS) /* by the shape alone */
        j.chunks = FUSED_PARTIAL_FLOATS / j.nparts > 1 ? FUSED_PARTIAL_FLOATS / j.nparts : 1;
    j.scratch = cr_nn_scratch(
        ctx, "mlp", (size_t)(j.chunks * 3 * m->block_rows * max_width(m)) * sizeof(float));
    if (!j.scratch) return CR_FAIL(err, CR_ERR_MEMORY, "mlp: no arena for the blocks' scratch");
    j.partials = cr_nn_scratch(ctx, "mlp", (size_t)(j.chunks * j.nparts) * sizeof(float) + 1);
    if (!j.partials) return CR_FAIL(err, CR_ERR_MEMORY, "mlp: no arena for the partial gradients");
    cr_parallel_for(j.chunks, 1, backward_chunks, &j);
    sum_job s = {.j = &j};
    for (int l = 0; l < m->nl; l++)
        for (int k = 0; k < 2; k++) {
            const int64_t off = k == 0 ? j.off_w[l] : j.off_b[l];
            if (off < 0) continue;
            const cr_tensor *t = in[1 + 2 * l + k];
            s.grad[s.count] = t->grad, s.off[s.count] = off, s.n[s.count] = t->numel;
            s.count++;
        }
    cr_parallel_for(j.nparts, 4096, sum_partials, &s);
    return CR_OK;
}

/* ---------------------------------------------------------------- op -- */

static int fused_choice = -1; /* -1: not read yet */

int cr_nn_mlp_fused_enabled(void) {
    if (fused_choice < 0) {
        const char *env = getenv("CREASE_NN_MLP");
        fused_choice = env && strcmp(env, "fused") == 0;
    }
    return fused_choice;
}

int cr_nn_mlp_fused_set(int on) {
    int prev = cr_nn_mlp_fused_enabled();
    fused_choice = on != 0;
    return prev;
}

int cr_nn_mlp_fused_usable(const cr_nn_ctx *ctx) {
    return strcmp(ctx->be->name, "cpu") == 0;
}

cr_tensor *cr_nn_mlp_fused(cr_nn_ctx *ctx, cr_tensor *x, int nl, cr_tensor *const *w,
                           cr_tensor *const *b, const cr_op *act, const float *p) {
    CR_ASSERT(nl >= 1 && nl <= CR_MLP_MAX_LAYERS);
    if (!x || cr_nn_ctx_error(ctx, NULL) != CR_OK) return NULL;
    mlp_fused *m = cr_nn_alloc(ctx, "mlp", sizeof *m);
    cr_tensor **in = cr_nn_alloc(ctx, "mlp", (size_t)(1 + 2 * nl) * sizeof *in);
    if (!m || !in) return NULL;
    memset(m, 0, sizeof *m);
    m->op = (cr_fused_op){
        .name = "mlp", .forward = fused_forward, .backward = fused_backward, .user = m};
    m->nl = nl;
    int64_t rows, cols;
    cr_nn_rows_cols(x, &rows, &cols);
    m->width[0] = (int)cols;
    in[0] = x;
    for (int l = 0; l < nl; l++) {
        if (!w[l] || w[l]->ndim != 2 || w[l]->shape[1] != m->width[l] ||
            (b[l] && (b[l]->ndim != 1 || b[l]->shape[0] != w[l]->shape[0]))) {
            char sx[64], sw[64];
            NN_FAIL(ctx, CR_ERR_SHAPE, "mlp: layer %d's weight %s does not take %d inputs (x %s)",
                    l, w[l] ? cr_nn_shape_str(w[l], sw, sizeof sw) : "(none)", m->width[l],
                    cr_nn_shape_str(x, sx, sizeof sx));
            return NULL;
        }
        m->width[l + 1] = (int)w[l]->shape[0];
        m->act[l] = act[l];
        m->p[l] = p[l];
        in[1 + 2 * l] = w[l];
        in[2 + 2 * l] = b[l];
    }
    m->rows = rows;
    int64_t br = FUSED_BLOCK_FLOATS / max_width(m);
    br = br < FUSED_BLOCK_MIN ? FUSED_BLOCK_MIN : br > FUSED_BLOCK_MAX ? FUSED_BLOCK_MAX : br;
    m->block_rows = br / 16 * 16;
    m->nblocks = (rows + m->block_rows - 1) / m->block_rows;
    cr_nn_shape shape = {.ndim = x->ndim};
    for (int i = 0; i < x->ndim; i++)
        shape.d[i] = x->shape[i];
    shape.d[x->ndim - 1] = m->width[nl];
    return cr_nn_fused(ctx, &m->op, 1 + 2 * nl, in, 1, &shape, NULL);
}
