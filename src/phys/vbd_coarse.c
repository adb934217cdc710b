/* vbd_coarse.c: a coarse-level correction for vertex block descent.
 *
 * Why: a Gauss-Seidel sweep moves a vertex against its neighbours, so it
 * removes the rough part of the error quickly and the smooth part (a whole
 * region stretched or displaced together) hardly at all. On cloth the
 * membrane block of a vertex is about 4e5 times its inertia m/h^2 at
 * 1/30 s, so thirty sweeps leave an impact's stretch in place, and the next
 * substep's guess carries it on (docs/physics.md, "What bench-peers did not
 * show"). A two-level method (smoothed-aggregation multigrid's coarse
 * step, here unsmoothed) removes what the sweeps cannot:
 *
 *   P     (3V x 6M): over M aggregates, each a vertex and its free
 *         neighbours up to `rings` rings in the Hessian's pattern, built
 *         greedily in vertex order once (pinned vertices in none), each
 *         aggregate's rigid motions: u_i = t_a + w_a x (x_i - c_a), c_a its
 *         centroid at the iterate. Translations alone (piecewise constant P)
 *         removed the impact's stretch but not the slow swing of a cloth
 *         folding over a sphere, a smooth rotation; smoothed-aggregation
 *         multigrid for elasticity keeps the rigid motions in its coarse
 *         space for the same reason (Vanek, Mandel & Brezina 1996);
 *   solve (P^T H P) c = -P^T g with H, g the objective's Hessian (the
 *         energies' projected element Hessians, the same as Newton's) and
 *         gradient at the iterate, a sparse Cholesky of 2M 3x3 block rows
 *         (node 2a the translation t_a, 2a+1 the rotation w_a), each rotation
 *         block's diagonal raised by 1e-6 of itself and 1e-12 of its trace
 *         (a one-vertex or collinear aggregate has a rotation that moves
 *         nothing, so a singular block; a flat one's in-plane rotation is
 *         some 1e5 times stiffer than its out-of-plane ones, so the shift is
 *         per axis);
 *   step  x += alpha P c, alpha by an Armijo search in vbd.c (the step is a
 *         descent direction whenever P^T H P is positive definite).
 *
 * The coarse matrix is summed from the fine blocks through a map made once
 * per assembly pattern (self-contact rebuilds the assembly when its pairs
 * change; the map follows s->assembly_builds). Its symbolic analysis is
 * done with the map; each correction pays one full evaluation with the
 * Hessian, the sum, one numeric factorisation and one solve.
 */
#include <stdlib.h>
#include <string.h>

#include "crease/phys_solve.h"
#include "phys/vbd_internal.h"

/* How a fine block adds to its coarse block. */
enum { ADD_BLOCK = 0, ADD_TRANSPOSE = 1, ADD_BOTH = 2 };

struct cr_vbd_coarse {
    int32_t nv, nagg;
    int32_t *agg;             /* (V) each vertex's aggregate, -1 when pinned */
    int64_t builds;           /* s->assembly_builds the map was made for (-1: none yet) */
    cr_hessian hc;            /* (2M nodes) P^T H P, upper block triangle */
    int64_t *slot;            /* (fine B) aggregate-level block of each fine block, -1: none */
    uint8_t *how;             /* (fine B) ADD_* */
    int64_t nqblock;          /* aggregate-level blocks (pairs of aggregates a <= b that touch) */
    int32_t *qrow, *qcol;     /* (nqblock) their aggregates */
    int64_t *qbase0, *qbase1; /* (nqblock) their first coarse block in column 2b, 2b+1 */
    cr_cholesky *chol;
    double *gc;       /* (2M,3) -P^T g, then the coarse solution (t_a, w_a) */
    double *centre;   /* (M,3) the aggregates' centroids at the iterate, m */
    int32_t *size;    /* (M) their vertices */
    double *arm;      /* (V,3) each vertex from its aggregate's centroid at the last
                         factorisation, m: the rotations' basis until the next */
    double rot_shift; /* the rotation blocks' relative shift (1e-6) */
    int factored;     /* 1: chol holds a positive definite P^T H P */
};

void cr_vbd_coarse_destroy(cr_vbd_coarse *c) {
    if (!c) return;
    free(c->agg), free(c->slot), free(c->how), free(c->gc);
    free(c->qrow), free(c->qcol), free(c->qbase0), free(c->qbase1);
    free(c->centre), free(c->size), free(c->arm);
    free(c->hc.col_off), free(c->hc.row), free(c->hc.col), free(c->hc.val);
    cr_cholesky_destroy(c->chol);
    free(c);
}

int32_t cr_vbd_coarse_count(const cr_vbd_coarse *c) {
    return c->nagg;
}

void cr_vbd_coarse_set_rotation_shift(cr_vbd_coarse *c, double shift) {
    c->rot_shift = shift;
}

const int32_t *cr_vbd_coarse_aggregates(const cr_vbd_coarse *c) {
    return c->agg;
}

/* The aggregates: each free vertex not yet taken, in vertex order, starts
 * one and takes the free untaken vertices within `rings` rings of it
 * (breadth first over the pattern's off-diagonal blocks, both ways). */
static cr_status build_aggregates(const cr_sim *s, cr_vbd_coarse *c, int rings, cr_error *err) {
    const cr_hessian *h = cr_assembly_hessian(s->assembly);
    const int32_t nv = s->nv;
    cr_status st = CR_OK;
    int64_t *off = cr_calloc((size_t)nv + 1, sizeof *off, err);
    int32_t *nb = NULL, *queue = NULL, *depth = NULL;
    if (!off) return err ? err->status : CR_ERR_MEMORY;
    for (int64_t k = 0; k < h->nblock; k++)
        if (h->row[k] != h->col[k]) off[h->row[k] + 1]++, off[h->col[k] + 1]++;
    for (int32_t i = 0; i < nv; i++)
        off[i + 1] += off[i];
    nb = cr_malloc((size_t)(off[nv] > 0 ? off[nv] : 1) * sizeof *nb, err);
    queue = cr_malloc((size_t)nv * sizeof *queue, err);
    depth = cr_malloc((size_t)nv * sizeof *depth, err);
    if (!nb || !queue || !depth) {
        st = err ? err->status : CR_ERR_MEMORY;
        goto done;
    }
    {
        int64_t *fill = cr_malloc((size_t)nv * sizeof *fill, err);
        if (!fill) {
            st = err ? err->status : CR_ERR_MEMORY;
            goto done;
        }
        memcpy(fill, off, (size_t)nv * sizeof *fill);
        for (int64_t k = 0; k < h->nblock; k++) {
            int32_t a = h->row[k], b = h->col[k];
            if (a == b) continue;
            nb[fill[a]++] = b;
            nb[fill[b]++] = a;
        }
        free(fill);
    }
    for (int32_t i = 0; i < nv; i++)
        c->agg[i] = -1;
    c->nagg = 0;
    for (int32_t seed = 0; seed < nv; seed++) {
        if (s->pinned[seed] || c->agg[seed] >= 0) continue;
        int32_t head = 0, tail = 0, id = c->nagg++;
        c->agg[seed] = id, depth[seed] = 0, queue[tail++] = seed;
        while (head < tail) {
            int32_t i = queue[head++];
            if (depth[i] >= rings) continue;
            for (int64_t k = off[i]; k < off[i + 1]; k++) {
                int32_t j = nb[k];
                if (s->pinned[j] || c->agg[j] >= 0) continue;
                c->agg[j] = id, depth[j] = depth[i] + 1, queue[tail++] = j;
            }
        }
    }
done:
    free(off), free(nb), free(queue), free(depth);
    return st;
}

cr_status cr_vbd_coarse_create(const cr_sim *s, int rings, cr_vbd_coarse **out, cr_error *err) {
    *out = NULL;
    if (rings < 1)
        return CR_FAIL(err, CR_ERR_INVALID, "vbd coarse correction: rings must be >= 1, got %d",
                       rings);
    cr_vbd_coarse *c = cr_calloc(1, sizeof *c, err);
    if (!c) return err ? err->status : CR_ERR_MEMORY;
    c->nv = s->nv;
    c->builds = -1;
    c->rot_shift = 1e-6;
    c->agg = cr_malloc((size_t)s->nv * sizeof *c->agg, err);
    cr_status st =
        c->agg ? build_aggregates(s, c, rings, err) : (err ? err->status : CR_ERR_MEMORY);
    if (st == CR_OK && c->nagg > 0) {
        c->gc = cr_malloc((size_t)c->nagg * 6 * sizeof *c->gc, err);
        c->centre = cr_malloc((size_t)c->nagg * 3 * sizeof *c->centre, err);
        c->size = cr_calloc((size_t)c->nagg, sizeof *c->size, err);
        c->arm = cr_malloc((size_t)s->nv * 3 * sizeof *c->arm, err);
        if (!c->gc || !c->centre || !c->size || !c->arm)
            st = err ? err->status : CR_ERR_MEMORY;
        else
            for (int32_t i = 0; i < s->nv; i++)
                if (c->agg[i] >= 0) c->size[c->agg[i]]++;
    }
    if (st != CR_OK) {
        cr_vbd_coarse_destroy(c);
        return st;
    }
    *out = c;
    return CR_OK;
}

typedef struct coarse_key {
    int32_t col, row; /* aggregates, row <= col */
    int64_t fine;     /* the fine block */
} coarse_key;

static int key_order(const void *pa, const void *pb) {
    const coarse_key *a = pa, *b = pb;
    if (a->col != b->col) return a->col < b->col ? -1 : 1;
    if (a->row != b->row) return a->row < b->row ? -1 : 1;
    return (a->fine > b->fine) - (a->fine < b->fine);
}

static void free_map(cr_vbd_coarse *c) {
    free(c->slot), free(c->how), free(c->qrow), free(c->qcol), free(c->qbase0), free(c->qbase1);
    c->slot = NULL, c->how = NULL, c->qrow = c->qcol = NULL, c->qbase0 = c->qbase1 = NULL;
    free(c->hc.col_off), free(c->hc.row), free(c->hc.col), free(c->hc.val);
    memset(&c->hc, 0, sizeof c->hc);
    cr_cholesky_destroy(c->chol);
    c->chol = NULL;
}

/* The coarse pattern and the fine-to-coarse map for the assembly's current
 * pattern, and the Cholesky analysis of it. Aggregates a < b that touch
 * give the four coarse blocks (2a+p, 2b+q); an aggregate with itself the
 * three of the upper triangle. */
static cr_status build_map(const cr_sim *s, cr_vbd_coarse *c, cr_error *err) {
    const cr_hessian *h = cr_assembly_hessian(s->assembly);
    const int32_t m = c->nagg;
    const size_t nb = (size_t)(h->nblock > 0 ? h->nblock : 1);
    cr_status st = CR_OK;
    free_map(c);
    c->slot = cr_malloc(nb * sizeof *c->slot, err);
    c->how = cr_malloc(nb, err);
    coarse_key *keys = cr_malloc(nb * sizeof *keys, err);
    c->hc.col_off = cr_calloc(2 * (size_t)m + 1, sizeof *c->hc.col_off, err);
    if (!c->slot || !c->how || !keys || !c->hc.col_off) goto oom;
    int64_t nk = 0;
    for (int64_t k = 0; k < h->nblock; k++) {
        int32_t a = c->agg[h->row[k]], b = c->agg[h->col[k]];
        c->slot[k] = -1;
        if (a < 0 || b < 0) continue;
        c->how[k] = a == b ? (h->row[k] == h->col[k] ? ADD_BLOCK : ADD_BOTH)
                           : (a < b ? ADD_BLOCK : ADD_TRANSPOSE);
        keys[nk++] = (coarse_key){a < b ? b : a, a < b ? a : b, k};
    }
    qsort(keys, (size_t)nk, sizeof *keys, key_order);
    int64_t nq = 0;
    for (int64_t q = 0; q < nk; q++)
        if (q == 0 || keys[q].col != keys[q - 1].col || keys[q].row != keys[q - 1].row) nq++;
    const size_t nqs = (size_t)(nq > 0 ? nq : 1);
    c->nqblock = nq;
    c->qrow = cr_malloc(nqs * sizeof *c->qrow, err);
    c->qcol = cr_malloc(nqs * sizeof *c->qcol, err);
    c->qbase0 = cr_malloc(nqs * sizeof *c->qbase0, err);
    c->qbase1 = cr_malloc(nqs * sizeof *c->qbase1, err);
    if (!c->qrow || !c->qcol || !c->qbase0 || !c->qbase1) goto oom;
    int64_t b = -1;
    for (int64_t q = 0; q < nk; q++) {
        if (q == 0 || keys[q].col != keys[q - 1].col || keys[q].row != keys[q - 1].row) {
            b++;
            c->qrow[b] = keys[q].row, c->qcol[b] = keys[q].col;
            /* Column 2 col holds rows 2 row and 2 row + 1 (only 2 row on the
             * diagonal); column 2 col + 1 holds both. */
            c->hc.col_off[2 * keys[q].col + 1] += keys[q].row == keys[q].col ? 1 : 2;
            c->hc.col_off[2 * keys[q].col + 2] += 2;
        }
        c->slot[keys[q].fine] = b;
    }
    for (int32_t j = 0; j < 2 * m; j++)
        c->hc.col_off[j + 1] += c->hc.col_off[j];
    const int64_t nblock = c->hc.col_off[2 * m];
    const size_t ncb = (size_t)(nblock > 0 ? nblock : 1);
    c->hc.nv = 2 * m;
    c->hc.nblock = nblock;
    c->hc.row = cr_malloc(ncb * sizeof *c->hc.row, err);
    c->hc.col = cr_malloc(ncb * sizeof *c->hc.col, err);
    c->hc.val = cr_malloc(ncb * 9 * sizeof *c->hc.val, err);
    if (!c->hc.row || !c->hc.col || !c->hc.val) goto oom;
    {
        /* Aggregate-level blocks come by column, rows ascending, so filling
         * each coarse column in that order keeps its rows ascending and its
         * diagonal last. */
        int64_t *fill = cr_malloc(2 * (size_t)m * sizeof *fill, err);
        if (!fill) goto oom;
        memcpy(fill, c->hc.col_off, 2 * (size_t)m * sizeof *fill);
        for (int64_t q = 0; q < nq; q++) {
            const int32_t ra = c->qrow[q], ca = c->qcol[q];
            const int32_t j0 = 2 * ca, j1 = 2 * ca + 1;
            c->qbase0[q] = fill[j0];
            c->hc.row[fill[j0]] = 2 * ra, c->hc.col[fill[j0]++] = j0;
            if (ra != ca) c->hc.row[fill[j0]] = 2 * ra + 1, c->hc.col[fill[j0]++] = j0;
            c->qbase1[q] = fill[j1];
            c->hc.row[fill[j1]] = 2 * ra, c->hc.col[fill[j1]++] = j1;
            c->hc.row[fill[j1]] = 2 * ra + 1, c->hc.col[fill[j1]++] = j1;
        }
        free(fill);
    }
    st = cr_cholesky_create(&c->hc, NULL, &c->chol, err);
    if (st == CR_OK) c->builds = s->assembly_builds;
    free(keys);
    return st;
oom:
    free(keys);
    return err && err->status != CR_OK ? err->status : CR_ERR_MEMORY;
}

/* 3x3 row-major products. */
static void mul3(const double *a, const double *b, double *out) {
    for (int r = 0; r < 3; r++)
        for (int l = 0; l < 3; l++)
            out[3 * r + l] = a[3 * r] * b[l] + a[3 * r + 1] * b[3 + l] + a[3 * r + 2] * b[6 + l];
}

static void transpose3(const double *a, double *out) {
    for (int r = 0; r < 3; r++)
        for (int l = 0; l < 3; l++)
            out[3 * l + r] = a[3 * r + l];
}

static void add3(double *dst, const double *a) {
    for (int k = 0; k < 9; k++)
        dst[k] += a[k];
}

/* S_i = -[r_i]x, the map from an aggregate's rotation w to vertex i's
 * motion w x r_i (r_i = x_i - c_a at the factorisation). */
static void rotation_map(const cr_vbd_coarse *c, int32_t i, double *S) {
    const double *r = c->arm + 3 * (int64_t)i;
    const double rx = r[0], ry = r[1], rz = r[2];
    const double m[9] = {0.0, rz, -ry, -rz, 0.0, rx, ry, -rx, 0.0};
    memcpy(S, m, sizeof m);
}

/* Fine block H (rows of vertex i, columns of j) into the aggregate-level
 * block whose four coarse blocks are b00 (t_a, t_b), b01 (t_a, w_b), b10
 * (w_a, t_b; NULL on an aggregate's own block, whose lower part is not
 * stored) and b11 (w_a, w_b): [I; S_i^T] H [I, S_j]. */
static void add_fine(const double *H, const double *Si, const double *Sj, double *b00, double *b01,
                     double *b10, double *b11) {
    double SiT[9], HSj[9], SiTH[9], SiTHSj[9];
    transpose3(Si, SiT);
    mul3(H, Sj, HSj);
    mul3(SiT, H, SiTH);
    mul3(SiTH, Sj, SiTHSj);
    add3(b00, H);
    add3(b01, HSj);
    if (b10) add3(b10, SiTH);
    add3(b11, SiTHSj);
}

cr_status cr_vbd_coarse_factor(cr_sim *s, cr_vbd_coarse *c, int *ok, cr_error *err) {
    *ok = 0;
    c->factored = 0;
    if (c->nagg == 0) return CR_OK;
    if (c->builds != s->assembly_builds) CR_TRY(build_map(s, c, err));
    const cr_hessian *h = cr_assembly_hessian(s->assembly);
    const double *x = s->x;
    double t = cr_time_now();
    /* The rotations' arms from the aggregates' centroids at the iterate. */
    memset(c->centre, 0, (size_t)c->nagg * 3 * sizeof *c->centre);
    for (int32_t i = 0; i < s->nv; i++)
        if (c->agg[i] >= 0)
            for (int d = 0; d < 3; d++)
                c->centre[3 * c->agg[i] + d] += x[3 * (int64_t)i + d] / c->size[c->agg[i]];
    for (int32_t i = 0; i < s->nv; i++)
        for (int d = 0; d < 3; d++)
            c->arm[3 * (int64_t)i + d] =
                c->agg[i] >= 0 ? x[3 * (int64_t)i + d] - c->centre[3 * c->agg[i] + d] : 0.0;
    memset(c->hc.val, 0, (size_t)c->hc.nblock * 9 * sizeof *c->hc.val);
    for (int64_t k = 0; k < h->nblock; k++) {
        const int64_t q = c->slot[k];
        if (q < 0) continue;
        const int diagonal = c->qrow[q] == c->qcol[q];
        double *b00 = c->hc.val + 9 * c->qbase0[q];
        double *b10 = diagonal ? NULL : b00 + 9;
        double *b01 = c->hc.val + 9 * c->qbase1[q], *b11 = b01 + 9;
        const double *f = h->val + 9 * k;
        double Si[9], Sj[9], fT[9];
        rotation_map(c, h->row[k], Si);
        rotation_map(c, h->col[k], Sj);
        if (c->how[k] == ADD_TRANSPOSE || c->how[k] == ADD_BOTH) transpose3(f, fT);
        if (c->how[k] != ADD_TRANSPOSE) add_fine(f, Si, Sj, b00, b01, b10, b11);
        /* Block (j, i) of the symmetric matrix is f^T. */
        if (c->how[k] != ADD_BLOCK) add_fine(fT, Sj, Si, b00, b01, b10, b11);
    }
    for (int64_t q = 0; q < c->nqblock; q++) {
        if (c->qrow[q] != c->qcol[q]) continue;
        const double *tt = c->hc.val + 9 * c->qbase0[q];
        double *rr = c->hc.val + 9 * (c->qbase1[q] + 1);
        const double trr = rr[0] + rr[4] + rr[8];
        const double floor = trr > 0.0 ? 1e-6 * trr : (tt[0] + tt[4] + tt[8]) / 3.0;
        for (int d = 0; d < 3; d++)
            rr[4 * d] += c->rot_shift * (rr[4 * d] + floor);
    }
    s->rep->seconds_assembly += cr_time_now() - t;
    t = cr_time_now();
    cr_error local = {0};
    cr_status st = cr_cholesky_factor(c->chol, &c->hc, NULL, &local);
    s->rep->seconds_factor += cr_time_now() - t;
    s->rep->factorisations++;
    /* A coarse matrix still indefinite after the shifts: no correction
     * until the next factorisation (the sweeps go on); NaN is an error. */
    if (st == CR_ERR_DIVERGED) return CR_OK;
    if (st != CR_OK) return CR_FAIL(err, st, "vbd coarse correction: %s", local.msg);
    c->factored = 1;
    *ok = 1;
    return CR_OK;
}

cr_status cr_vbd_coarse_direction(cr_sim *s, cr_vbd_coarse *c, const double *grad, double *dir,
                                  int *ok, cr_error *err) {
    *ok = 0;
    memset(dir, 0, (size_t)s->nv * 3 * sizeof *dir);
    if (!c->factored) return CR_OK;
    double t = cr_time_now();
    memset(c->gc, 0, (size_t)c->nagg * 6 * sizeof *c->gc);
    for (int32_t i = 0; i < s->nv; i++) {
        const int32_t a = c->agg[i];
        if (a < 0) continue;
        const double *g = grad + 3 * (int64_t)i;
        double S[9];
        rotation_map(c, i, S);
        for (int d = 0; d < 3; d++) {
            c->gc[6 * a + d] -= g[d];
            /* (S^T g)_d = sum_r S[r][d] g_r */
            c->gc[6 * a + 3 + d] -= S[d] * g[0] + S[3 + d] * g[1] + S[6 + d] * g[2];
        }
    }
    CR_TRY(cr_cholesky_solve(c->chol, c->gc, c->gc, err));
    for (int32_t i = 0; i < s->nv; i++) {
        const int32_t a = c->agg[i];
        if (a < 0) continue;
        double S[9];
        rotation_map(c, i, S);
        const double *tr = c->gc + 6 * a, *w = tr + 3;
        for (int d = 0; d < 3; d++)
            dir[3 * (int64_t)i + d] =
                tr[d] + S[3 * d] * w[0] + S[3 * d + 1] * w[1] + S[3 * d + 2] * w[2];
    }
    s->rep->seconds_solve += cr_time_now() - t;
    *ok = 1;
    return CR_OK;
}
