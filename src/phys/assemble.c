/* assemble.c: value, gradient and block-sparse Hessian of a sum of energy
 * terms, in parallel and deterministically (see crease/phys_assemble.h).
 *
 * Creation builds, for every term of two or more vertices per element:
 *   - the block pattern: the pairs of vertices sharing an element, sorted and
 *     de-duplicated per block column, plus every diagonal block;
 *   - a slot map (nelem, nvert^2): for local pair (a, b) of an element, the
 *     block that receives H[a][b] when idx[a] <= idx[b], else -1 (the pair
 *     (b, a) delivers it, transposed by symmetry);
 *   - a greedy colouring in element order (Jones & Plassmann style first fit):
 *     an element takes the smallest colour none of its vertex-neighbours
 *     already holds. On regular cloth meshes triangles need about 7-13
 *     colours and hinges about 20-30.
 * Terms of one vertex per element touch only diagonal blocks and are not
 * planned: with elem == NULL (element e is vertex e) they run in parallel,
 * otherwise serially in element order, since their elements may repeat a
 * vertex and may change between evaluations (contact sets).
 *
 * Left out: symbolic re-analysis when elements change (the pattern is fixed),
 * block sizes other than 3.
 */
#include "crease/phys_assemble.h"

#include <stdlib.h>
#include <string.h>

/* Smallest chunk worth a thread, in elements. Every colour ends in a
 * barrier; on a busy machine a barrier waits for a descheduled thread, a
 * scheduler quantum of several milliseconds, so a colour is split only when
 * each part holds several milliseconds of kernels (a hinge or triangle costs
 * 1-10 us, a vertex term well under 1 us). With 512 a 4k-vertex cloth spent
 * 5 s per frame in assembly on two threads while another process used one of
 * the two cores, against 0.1 s on one thread. */
#define COLOUR_GRAIN 4096
#define VERTEX_GRAIN 32768

typedef struct term_plan {
    int32_t nelem;
    int nvert;
    const int32_t *elem;
    int ncolour;
    int32_t *colour_off; /* (ncolour+1) offsets into order */
    int32_t *order;      /* (nelem) elements grouped by colour, ascending within a colour */
    int32_t *slot;       /* (nelem, nvert^2) block of local pair (a,b), or -1 */
} term_plan;

struct cr_assembly {
    int32_t nv;
    int nterms;
    term_plan *plan; /* (nterms) */
    cr_hessian h;
    int64_t *diag; /* (V) block index of (v,v) */
    double *evals; /* (max nelem) per-element values of the term being summed */
    int32_t max_elem;
};

/* ------------------------------------------------------------- pattern -- */

static int cmp_i32(const void *a, const void *b) {
    int32_t x = *(const int32_t *)a, y = *(const int32_t *)b;
    return (x > y) - (x < y);
}

/* Block rows of every column: off-diagonal partners (row < col) collected from
 * the planned terms, sorted, unique, then the diagonal last. */
static cr_status build_pattern(cr_assembly *a, const cr_energy_term *terms, cr_error *err) {
    int32_t nv = a->nv;
    int64_t *count = cr_calloc((size_t)nv + 1, sizeof(int64_t), err);
    if (!count) return err ? err->status : CR_ERR_MEMORY;
    int32_t idx[CR_ENERGY_MAX_VERTS];
    for (int t = 0; t < a->nterms; t++) {
        if (terms[t].nvert < 2) continue;
        for (int32_t e = 0; e < terms[t].nelem; e++) {
            cr_energy_term_vertices(&terms[t], e, idx);
            for (int p = 0; p < terms[t].nvert; p++)
                for (int q = 0; q < terms[t].nvert; q++)
                    if (idx[p] < idx[q]) count[idx[q] + 1]++;
        }
    }
    for (int32_t v = 0; v < nv; v++)
        count[v + 1] += count[v];
    int64_t total = count[nv];
    int32_t *rows = cr_malloc((size_t)(total > 0 ? total : 1) * sizeof(int32_t), err);
    int64_t *fill = cr_malloc((size_t)nv * sizeof(int64_t), err);
    if (!rows || !fill) {
        free(count), free(rows), free(fill);
        return err ? err->status : CR_ERR_MEMORY;
    }
    memcpy(fill, count, (size_t)nv * sizeof(int64_t));
    for (int t = 0; t < a->nterms; t++) {
        if (terms[t].nvert < 2) continue;
        for (int32_t e = 0; e < terms[t].nelem; e++) {
            cr_energy_term_vertices(&terms[t], e, idx);
            for (int p = 0; p < terms[t].nvert; p++)
                for (int q = 0; q < terms[t].nvert; q++)
                    if (idx[p] < idx[q]) rows[fill[idx[q]]++] = idx[p];
        }
    }
    /* Unique rows per column, counted first so the final arrays are exact. */
    int64_t nblock = 0;
    for (int32_t j = 0; j < nv; j++) {
        int32_t *r = rows + count[j];
        int64_t n = count[j + 1] - count[j], u = 0;
        qsort(r, (size_t)n, sizeof(int32_t), cmp_i32);
        for (int64_t i = 0; i < n; i++)
            if (i == 0 || r[i] != r[i - 1]) r[u++] = r[i];
        fill[j] = u; /* unique count */
        nblock += u + 1;
    }
    cr_hessian *h = &a->h;
    h->nv = nv;
    h->nblock = nblock;
    h->col_off = cr_malloc(((size_t)nv + 1) * sizeof(int64_t), err);
    h->row = cr_malloc((size_t)nblock * sizeof(int32_t), err);
    h->val = cr_calloc((size_t)nblock * 9, sizeof(double), err);
    a->diag = cr_malloc((size_t)(nv > 0 ? nv : 1) * sizeof(int64_t), err);
    if (!h->col_off || !h->row || !h->val || !a->diag) {
        free(count), free(rows), free(fill);
        return err ? err->status : CR_ERR_MEMORY;
    }
    int64_t k = 0;
    for (int32_t j = 0; j < nv; j++) {
        h->col_off[j] = k;
        memcpy(h->row + k, rows + count[j], (size_t)fill[j] * sizeof(int32_t));
        k += fill[j];
        a->diag[j] = k;
        h->row[k++] = j;
    }
    h->col_off[nv] = k;
    /* The same blocks by row: counting sort on the row index, stable, so
     * columns ascend within each row. */
    h->row_off = cr_calloc((size_t)nv + 1, sizeof(int64_t), err);
    h->row_blk = cr_malloc((size_t)nblock * sizeof(int64_t), err);
    h->col = cr_malloc((size_t)nblock * sizeof(int32_t), err);
    if (!h->row_off || !h->row_blk || !h->col) {
        free(count), free(rows), free(fill);
        return err ? err->status : CR_ERR_MEMORY;
    }
    for (int32_t j = 0; j < nv; j++)
        for (int64_t b = h->col_off[j]; b < h->col_off[j + 1]; b++)
            h->col[b] = j;
    for (int64_t b = 0; b < nblock; b++)
        h->row_off[h->row[b] + 1]++;
    for (int32_t v = 0; v < nv; v++)
        h->row_off[v + 1] += h->row_off[v];
    memcpy(fill, h->row_off, (size_t)nv * sizeof(int64_t));
    for (int64_t b = 0; b < nblock; b++)
        h->row_blk[fill[h->row[b]]++] = b;
    free(count), free(rows), free(fill);
    return CR_OK;
}

static int64_t find_block(const cr_hessian *h, int32_t i, int32_t j) {
    const int32_t *r = h->row + h->col_off[j];
    int64_t lo = 0, hi = h->col_off[j + 1] - h->col_off[j] - 1;
    while (lo <= hi) {
        int64_t mid = (lo + hi) / 2;
        if (r[mid] == i) return h->col_off[j] + mid;
        if (r[mid] < i)
            lo = mid + 1;
        else
            hi = mid - 1;
    }
    return -1;
}

/* ----------------------------------------------------------- colouring -- */

static cr_status plan_term(cr_assembly *a, const cr_energy_term *t, term_plan *p, cr_error *err) {
    int32_t nv = a->nv, ne = t->nelem;
    int nvert = t->nvert, nn = nvert * nvert;
    p->nelem = ne, p->nvert = nvert, p->elem = t->elem;
    p->slot = cr_malloc((size_t)(ne > 0 ? ne : 1) * nn * sizeof(int32_t), err);
    p->order = cr_malloc((size_t)(ne > 0 ? ne : 1) * sizeof(int32_t), err);
    int32_t *colour = cr_malloc((size_t)(ne > 0 ? ne : 1) * sizeof(int32_t), err);
    int32_t *voff = cr_calloc((size_t)nv + 1, sizeof(int32_t), err);
    int32_t *vel = cr_malloc((size_t)(ne > 0 ? ne : 1) * nvert * sizeof(int32_t), err);
    cr_status st = CR_OK;
    int32_t *forbid = NULL;
    if (!p->slot || !p->order || !colour || !voff || !vel) goto oom;

    int32_t idx[CR_ENERGY_MAX_VERTS];
    for (int32_t e = 0; e < ne; e++) {
        cr_energy_term_vertices(t, e, idx);
        for (int i = 0; i < nvert; i++)
            for (int j = 0; j < nvert; j++)
                p->slot[(int64_t)e * nn + i * nvert + j] =
                    idx[i] <= idx[j] ? (int32_t)find_block(&a->h, idx[i], idx[j]) : -1;
        for (int i = 0; i < nvert; i++)
            voff[idx[i] + 1]++;
    }
    int32_t maxdeg = 0;
    for (int32_t v = 0; v < nv; v++) {
        if (voff[v + 1] > maxdeg) maxdeg = voff[v + 1];
        voff[v + 1] += voff[v];
    }
    /* vertex -> elements, ascending (a vertex repeated in an element lists it
     * twice); voff[v] serves as v's fill cursor, then is shifted back. */
    for (int32_t e = 0; e < ne; e++) {
        cr_energy_term_vertices(t, e, idx);
        for (int i = 0; i < nvert; i++)
            vel[voff[idx[i]]++] = e;
    }
    for (int32_t v = nv; v > 0; v--)
        voff[v] = voff[v - 1];
    voff[0] = 0;

    int32_t bound = maxdeg * nvert + 1; /* no element has more neighbours than this */
    forbid = cr_malloc((size_t)bound * sizeof(int32_t), err);
    if (!forbid) goto oom;
    for (int32_t c = 0; c < bound; c++)
        forbid[c] = -1;
    int ncolour = 0;
    for (int32_t e = 0; e < ne; e++)
        colour[e] = -1;
    for (int32_t e = 0; e < ne; e++) {
        cr_energy_term_vertices(t, e, idx);
        for (int i = 0; i < nvert; i++)
            for (int32_t k = voff[idx[i]]; k < voff[idx[i] + 1]; k++)
                if (colour[vel[k]] >= 0) forbid[colour[vel[k]]] = e;
        int32_t c = 0;
        while (forbid[c] == e)
            c++;
        colour[e] = c;
        if (c + 1 > ncolour) ncolour = c + 1;
    }
    p->ncolour = ncolour;
    p->colour_off = cr_calloc((size_t)ncolour + 1, sizeof(int32_t), err);
    if (!p->colour_off) goto oom;
    for (int32_t e = 0; e < ne; e++)
        p->colour_off[colour[e] + 1]++;
    for (int c = 0; c < ncolour; c++)
        p->colour_off[c + 1] += p->colour_off[c];
    memcpy(forbid, p->colour_off, (size_t)ncolour * sizeof(int32_t)); /* fill cursors */
    for (int32_t e = 0; e < ne; e++)
        p->order[forbid[colour[e]]++] = e;
    goto done;
oom:
    st = err ? err->status : CR_ERR_MEMORY;
done:
    free(colour), free(voff), free(vel), free(forbid);
    return st;
}

/* ---------------------------------------------------------------- create -- */

void cr_assembly_destroy(cr_assembly *a) {
    if (!a) return;
    if (a->plan)
        for (int t = 0; t < a->nterms; t++) {
            free(a->plan[t].colour_off);
            free(a->plan[t].order);
            free(a->plan[t].slot);
        }
    free(a->plan);
    free(a->h.col_off), free(a->h.row), free(a->h.val), free(a->h.row_off), free(a->h.row_blk),
        free(a->h.col);
    free(a->diag), free(a->evals);
    free(a);
}

cr_status cr_assembly_create(const cr_energy_term *terms, int nterms, int32_t nv, cr_assembly **out,
                             cr_error *err) {
    *out = NULL;
    if (nv < 1)
        return CR_FAIL(err, CR_ERR_INVALID, "assembly: need at least one vertex, got %d", nv);
    if (nterms < 0 || (nterms > 0 && !terms))
        return CR_FAIL(err, CR_ERR_INVALID, "assembly: bad term list (%d terms)", nterms);
    int32_t max_elem = nv; /* per-vertex terms without an element list: at most V */
    for (int t = 0; t < nterms; t++) {
        const cr_energy_term *term = &terms[t];
        const char *name = term->name ? term->name : "?";
        if (term->nvert < 1 || term->nvert > CR_ENERGY_MAX_VERTS)
            return CR_FAIL(err, CR_ERR_INVALID, "assembly: term %d (%s): nvert %d not in 1..%d", t,
                           name, term->nvert, CR_ENERGY_MAX_VERTS);
        if (term->nelem < 0 || !term->kernel || (!term->elem && term->nvert > 1))
            return CR_FAIL(err, CR_ERR_INVALID,
                           "assembly: term %d (%s): %d elements, kernel %s, elem %s", t, name,
                           term->nelem, term->kernel ? "set" : "NULL", term->elem ? "set" : "NULL");
        if (!term->elem && term->nelem > nv)
            return CR_FAIL(err, CR_ERR_RANGE,
                           "assembly: term %d (%s): %d per-vertex elements > %d vertices", t, name,
                           term->nelem, nv);
        if (term->elem)
            for (int64_t i = 0; i < (int64_t)term->nelem * term->nvert; i++)
                if (term->elem[i] < 0 || term->elem[i] >= nv)
                    return CR_FAIL(
                        err, CR_ERR_RANGE,
                        "assembly: term %d (%s): element %lld uses vertex %d, not in [0, %d)", t,
                        name, (long long)(i / term->nvert), term->elem[i], nv);
        if (term->nelem > max_elem && (term->nvert > 1 || !term->elem)) max_elem = term->nelem;
    }
    cr_assembly *a = cr_calloc(1, sizeof(cr_assembly), err);
    if (!a) return err ? err->status : CR_ERR_MEMORY;
    a->nv = nv;
    a->nterms = nterms;
    a->max_elem = max_elem;
    a->plan = cr_calloc((size_t)(nterms > 0 ? nterms : 1), sizeof(term_plan), err);
    a->evals = cr_malloc((size_t)max_elem * sizeof(double), err);
    cr_status st = (a->plan && a->evals) ? CR_OK : (err ? err->status : CR_ERR_MEMORY);
    if (st == CR_OK) st = build_pattern(a, terms, err);
    if (st == CR_OK && a->h.nblock >= INT32_MAX)
        st = CR_FAIL(err, CR_ERR_RANGE, "assembly: %lld Hessian blocks exceed 32-bit slots",
                     (long long)a->h.nblock);
    for (int t = 0; st == CR_OK && t < nterms; t++) {
        a->plan[t].nvert = terms[t].nvert;
        if (terms[t].nvert > 1) st = plan_term(a, &terms[t], &a->plan[t], err);
    }
    if (st != CR_OK) {
        cr_assembly_destroy(a);
        return st;
    }
    *out = a;
    return CR_OK;
}

const cr_hessian *cr_assembly_hessian(const cr_assembly *a) {
    return &a->h;
}

int cr_assembly_colour_count(const cr_assembly *a, int t) {
    CR_ASSERT(t >= 0 && t < a->nterms);
    return a->plan[t].nvert > 1 ? a->plan[t].ncolour : 1;
}

/* ------------------------------------------------------------------ eval -- */

typedef struct eval_ctx {
    const cr_energy_term *t;
    const int32_t *elems; /* elements to visit (a colour's slice of order), or NULL: 0..n */
    const int32_t *slot;  /* the term's slot map, NULL for per-vertex terms */
    const int64_t *diag;
    const double *x;
    double *grad;
    double *hval;   /* NULL: no Hessian */
    double *evals;  /* (nelem) per-element values, or one running sum */
    int accumulate; /* 1: add every value to evals[0] (serial use only) */
} eval_ctx;

static void eval_range(void *vctx, int64_t begin, int64_t end) {
    const eval_ctx *c = vctx;
    const cr_energy_term *t = c->t;
    int nvert = t->nvert, n = 3 * nvert;
    double w = t->weight;
    int32_t idx[CR_ENERGY_MAX_VERTS];
    double xe[3 * CR_ENERGY_MAX_VERTS], g[3 * CR_ENERGY_MAX_VERTS];
    double H[9 * CR_ENERGY_MAX_VERTS * CR_ENERGY_MAX_VERTS];
    for (int64_t i = begin; i < end; i++) {
        int32_t e = c->elems ? c->elems[i] : (int32_t)i;
        cr_energy_term_vertices(t, e, idx);
        for (int k = 0; k < nvert; k++)
            memcpy(xe + 3 * k, c->x + 3 * (int64_t)idx[k], 3 * sizeof(double));
        double v = w * t->kernel(t->data, e, xe, c->grad ? g : NULL, c->hval ? H : NULL);
        if (c->accumulate)
            *c->evals += v;
        else
            c->evals[e] = v;
        if (c->grad)
            for (int k = 0; k < nvert; k++)
                for (int d = 0; d < 3; d++)
                    c->grad[3 * (int64_t)idx[k] + d] += w * g[3 * k + d];
        if (!c->hval) continue;
        for (int p = 0; p < nvert; p++)
            for (int q = 0; q < nvert; q++) {
                int64_t s =
                    c->slot ? c->slot[(int64_t)e * nvert * nvert + p * nvert + q] : c->diag[idx[p]];
                if (s < 0) continue;
                double *blk = c->hval + 9 * s;
                for (int r = 0; r < 3; r++)
                    for (int col = 0; col < 3; col++)
                        blk[3 * r + col] += w * H[(3 * p + r) * n + 3 * q + col];
            }
    }
}

double cr_assembly_eval(cr_assembly *a, const cr_energy_term *terms, const double *x, double *grad,
                        int want_hessian, double *term_values) {
    if (grad) memset(grad, 0, (size_t)a->nv * 3 * sizeof(double));
    if (want_hessian) memset(a->h.val, 0, (size_t)a->h.nblock * 9 * sizeof(double));
    double total = 0.0;
    for (int t = 0; t < a->nterms; t++) {
        const cr_energy_term *term = &terms[t];
        const term_plan *p = &a->plan[t];
        double sum = 0.0;
        if (term->weight != 0.0 && term->nelem > 0) {
            eval_ctx c = {term,     NULL, NULL, a->diag, x, grad, want_hessian ? a->h.val : NULL,
                          a->evals, 0};
            if (term->nvert > 1) {
                /* Same elements as at creation: the slots and colours depend on them. */
                CR_ASSERT(term->nvert == p->nvert && term->nelem == p->nelem &&
                          term->elem == p->elem);
                c.slot = p->slot;
                if (!grad && !want_hessian) {
                    /* Values alone write only their own slot: no colours needed,
                     * one parallel region (VBD's per-sweep objective). */
                    c.elems = p->order;
                    cr_parallel_for(p->colour_off[p->ncolour], COLOUR_GRAIN, eval_range, &c);
                } else
                    for (int col = 0; col < p->ncolour; col++) {
                        c.elems = p->order + p->colour_off[col];
                        cr_parallel_for(p->colour_off[col + 1] - p->colour_off[col], COLOUR_GRAIN,
                                        eval_range, &c);
                    }
            } else if (term->elem) {
                /* May repeat a vertex and change between calls: serial, in order. */
                c.evals = &sum;
                c.accumulate = 1;
                eval_range(&c, 0, term->nelem);
            } else {
                CR_ASSERT(term->nelem <= a->nv);
                cr_parallel_for(term->nelem, VERTEX_GRAIN, eval_range, &c);
            }
            if (c.evals == a->evals)
                for (int32_t e = 0; e < term->nelem; e++)
                    sum += a->evals[e];
        }
        if (term_values) term_values[t] = sum;
        total += sum;
    }
    return total;
}

/* -------------------------------------------------------------- multiply -- */

typedef struct multiply_ctx {
    const cr_hessian *h;
    const double *x;
    double *y;
} multiply_ctx;

/* Row v of A x: the stored blocks of row v (columns >= v) times x, plus the
 * transposes of column v's blocks above the diagonal. */
static void multiply_range(void *vctx, int64_t begin, int64_t end) {
    const multiply_ctx *c = vctx;
    const cr_hessian *h = c->h;
    for (int64_t v = begin; v < end; v++) {
        double acc[3] = {0, 0, 0};
        for (int64_t q = h->row_off[v]; q < h->row_off[v + 1]; q++) {
            int64_t k = h->row_blk[q];
            const double *b = h->val + 9 * k;
            int64_t j = h->col[k];
            const double *xj = c->x + 3 * j;
            for (int r = 0; r < 3; r++)
                acc[r] += b[3 * r] * xj[0] + b[3 * r + 1] * xj[1] + b[3 * r + 2] * xj[2];
        }
        for (int64_t k = h->col_off[v]; k < h->col_off[v + 1] - 1; k++) {
            const double *b = h->val + 9 * k, *xi = c->x + 3 * (int64_t)h->row[k];
            for (int col = 0; col < 3; col++)
                acc[col] += b[col] * xi[0] + b[3 + col] * xi[1] + b[6 + col] * xi[2];
        }
        memcpy(c->y + 3 * v, acc, sizeof acc);
    }
}

void cr_hessian_multiply(const cr_hessian *h, const double *x, double *y) {
    multiply_ctx c = {h, x, y};
    cr_parallel_for(h->nv, 2048, multiply_range, &c);
}
