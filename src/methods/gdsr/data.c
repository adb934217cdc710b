/* data.c: gdsr's data (a low/high garment pair, its correspondence, clips
 * from a `crease dataset` folder), the low mesh's 1-ring / 2-ring graph and
 * the node and edge features of Eq. 2-5. */
#include "gdsr_internal.h"

#include "crease/dataset.h"

#include "crease/garment.h"
#include "crease/mesh_io.h"
#include "crease/npz.h"
#include "crease/topology.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void cr_gdsr_data_free(cr_gdsr_data *d) {
    if (!d) return;
    cr_mesh_destroy(d->low);
    cr_mesh_destroy(d->high);
    cr_mesh_destroy(d->body);
    free(d->face);
    free(d->bary);
    free(d->coarse_face);
    free(d->coarse_bary);
    free(d->layer);
    for (int i = 0; i < d->nclips; i++) {
        free(d->clip[i].low);
        free(d->clip[i].high);
        free(d->clip[i].body);
    }
    memset(d, 0, sizeof *d);
}

/* C*'s operator: each low vertex's point on the high mesh through the UVs
 * (Eq. 1's correspondence the other way round), so at rest C* is the low
 * rest mesh. (The high vertex nearest each low vertex, used before, was up
 * to half a high edge off: S[C*] then had 28x the strain of S[C] on the
 * held-out walk, and the coarse L1 pulled C^ toward it; docs/gdsr.md.) */
static cr_status coarse_operator(cr_gdsr_data *d, cr_error *err) {
    int32_t nl = d->low->nv;
    d->layer = malloc((size_t)nl * sizeof(int32_t));
    if (!d->layer) return CR_FAIL(err, CR_ERR_MEMORY, "gdsr: out of memory");
    d->nlayers = cr_gdsr_mesh_layers(d->low, d->layer);
    d->coarse_face = malloc((size_t)nl * sizeof(int32_t));
    d->coarse_bary = malloc((size_t)nl * 3 * sizeof(float));
    if (!d->coarse_face || !d->coarse_bary)
        return CR_FAIL(err, CR_ERR_MEMORY, "gdsr: out of memory");
    return cr_garment_correspondence(d->high, d->low, d->coarse_face, d->coarse_bary, err);
}

void cr_gdsr_coarse_target(const cr_gdsr_data *d, const float *high_pos, float *out) {
    cr_garment_apply_correspondence(d->high, high_pos, d->coarse_face, d->coarse_bary, d->low->nv,
                                    out);
}

void cr_gdsr_upsample(const cr_gdsr_data *d, const float *low_pos, float *out) {
    cr_garment_apply_correspondence(d->low, low_pos, d->face, d->bary, d->high->nv, out);
}

/* want_frames > 0: exactly that many samples; < 0: at least -want_frames, the
 * first of them kept (a motion file's posed body runs past the simulated
 * frames). */
static cr_status read_pc2(const char *path, int32_t nv, int32_t want_frames, float **out,
                          int32_t *nframes, cr_error *err) {
    cr_pc2 pc = {0};
    CR_TRY(cr_pc2_read(path, &pc, err));
    if (pc.nv != nv) {
        int32_t got = pc.nv;
        cr_pc2_free(&pc);
        return CR_FAIL(err, CR_ERR_SHAPE, "%s: %d points per sample, the mesh has %d", path, got,
                       nv);
    }
    if ((want_frames > 0 && pc.nframes != want_frames) ||
        (want_frames < 0 && pc.nframes < -want_frames)) {
        int32_t got = pc.nframes;
        cr_pc2_free(&pc);
        return CR_FAIL(err, CR_ERR_SHAPE, "%s: %d samples, expected %s%d", path, got,
                       want_frames < 0 ? "at least " : "", abs(want_frames));
    }
    if (want_frames < 0) pc.nframes = -want_frames;
    *out = pc.frames;
    *nframes = pc.nframes;
    return CR_OK;
}

/* The dataset's low and high garment entries of garment on body, and its body. */
static cr_status find_pair(const cr_dataset_manifest *man, const char *garment, const char *body,
                           const cr_dataset_garment_entry **low,
                           const cr_dataset_garment_entry **high, const cr_dataset_body_entry **b,
                           cr_error *err) {
    *b = cr_dataset_find_body(man, body);
    *low = cr_dataset_find_garment(man, garment, body, "low");
    *high = cr_dataset_find_garment(man, garment, body, "high");
    if (!*b) return CR_FAIL(err, CR_ERR_IO, "%s/manifest.json: no body %s", man->dir, body);
    if (!*low || !*high || !(*low)->high_from_low)
        return CR_FAIL(err, CR_ERR_IO,
                       "%s/manifest.json: no low and high %s on body %s (gdsr needs `crease "
                       "dataset --res low,high`)",
                       man->dir, garment, body);
    return CR_OK;
}

int cr_gdsr_dataset_motions(const char *dir, const char *garment, const char *body,
                            const char *const *skip, int nskip, char (*names)[64], int max,
                            cr_error *err) {
    cr_dataset_manifest man;
    if (cr_dataset_read(dir, &man, err) != CR_OK) return -1;
    int n = 0;
    for (int32_t i = 0; i < man.nmotions; i++) {
        const char *m = man.motions[i].name;
        const cr_dataset_sequence_entry *lo =
            cr_dataset_find_sequence(&man, garment, "low", body, m);
        const cr_dataset_sequence_entry *hi =
            cr_dataset_find_sequence(&man, garment, "high", body, m);
        int skipped = 0;
        for (int k = 0; k < nskip; k++)
            skipped |= strcmp(skip[k], m) == 0;
        if (skipped || !lo || !hi || !lo->done || !hi->done) continue;
        if (n == max) {
            cr_dataset_manifest_free(&man);
            CR_FAIL(err, CR_ERR_RANGE, "%s: more than %d motions of %s on %s", dir, max, garment,
                    body);
            return -1;
        }
        snprintf(names[n++], 64, "%s", m);
    }
    cr_dataset_manifest_free(&man);
    if (n == 0)
        CR_FAIL(err, CR_ERR_INVALID,
                "%s/manifest.json: no motion with a done low and high %s on %s", dir, garment,
                body);
    return n ? n : -1;
}

cr_status cr_gdsr_data_load(const char *dir, const char *garment, const char *body,
                            const char *const *motions, int nmotions, cr_gdsr_data *out,
                            cr_error *err) {
    memset(out, 0, sizeof *out);
    if (nmotions < 0 || nmotions > CR_GDSR_MAX_CLIPS)
        return CR_FAIL(err, CR_ERR_INVALID, "gdsr: %d motions, need 0..%d", nmotions,
                       CR_GDSR_MAX_CLIPS);
    cr_dataset_manifest man;
    CR_TRY(cr_dataset_read(dir, &man, err));
    const cr_dataset_garment_entry *lo = NULL, *hi = NULL;
    const cr_dataset_body_entry *be = NULL;
    char path[CR_SCENE_PATH + 64];
    cr_status st = find_pair(&man, garment, body, &lo, &hi, &be, err);
    if (st != CR_OK) goto fail;
    if ((st = cr_dataset_path(&man, lo->mesh, path, sizeof path, err)) != CR_OK ||
        (st = cr_mesh_read(path, &out->low, err)) != CR_OK)
        goto fail;
    if ((st = cr_dataset_path(&man, hi->mesh, path, sizeof path, err)) != CR_OK ||
        (st = cr_mesh_read(path, &out->high, err)) != CR_OK)
        goto fail;
    if ((st = cr_dataset_path(&man, be->rest, path, sizeof path, err)) != CR_OK ||
        (st = cr_mesh_read(path, &out->body, err)) != CR_OK)
        goto fail;
    if ((st = cr_dataset_path(&man, lo->high_from_low, path, sizeof path, err)) != CR_OK) goto fail;
    {
        cr_npz *z = NULL;
        if ((st = cr_npz_open(path, &z, err)) != CR_OK) goto fail;
        cr_npy f = {0}, b = {0};
        st = cr_npz_get(z, "face", CR_NPY_AS_I32, &f, err);
        if (st == CR_OK) st = cr_npz_get(z, "bary", CR_NPY_AS_F32, &b, err);
        cr_npz_close(z);
        if (st == CR_OK && (f.count != out->high->nv || b.count != 3 * (int64_t)out->high->nv))
            st = CR_FAIL(err, CR_ERR_SHAPE, "%s: face/bary do not match the high mesh's %d", path,
                         out->high->nv);
        if (st != CR_OK) {
            cr_npy_free(&f);
            cr_npy_free(&b);
            goto fail;
        }
        out->face = f.i32;
        out->bary = b.f32;
        for (int32_t k = 0; k < out->high->nv; k++)
            if (out->face[k] < 0 || out->face[k] >= out->low->nf) {
                st = CR_FAIL(err, CR_ERR_SHAPE, "%s: face[%d] = %d out of range", path, k,
                             out->face[k]);
                goto fail;
            }
    }
    if ((st = coarse_operator(out, err)) != CR_OK) goto fail;
    for (int i = 0; i < nmotions; i++) {
        cr_gdsr_clip *c = &out->clip[i];
        out->nclips = i + 1;
        snprintf(c->motion, sizeof c->motion, "%s", motions[i]);
        int32_t T = 0, T2 = 0;
        const cr_dataset_sequence_entry *ql =
            cr_dataset_find_sequence(&man, garment, "low", body, motions[i]);
        const cr_dataset_sequence_entry *qh =
            cr_dataset_find_sequence(&man, garment, "high", body, motions[i]);
        if (!ql || !ql->done) {
            st = CR_FAIL(err, CR_ERR_IO, "%s/manifest.json: no finished low %s on %s doing %s", dir,
                         garment, body, motions[i]);
            goto fail;
        }
        if ((st = cr_dataset_path(&man, ql->garment_pc2, path, sizeof path, err)) != CR_OK ||
            (st = read_pc2(path, out->low->nv, 0, &c->low, &T, err)) != CR_OK)
            goto fail;
        /* no finished high sequence (a low-only roll-out input): clip.high stays NULL */
        if (qh && qh->done &&
            ((st = cr_dataset_path(&man, qh->garment_pc2, path, sizeof path, err)) != CR_OK ||
             (st = read_pc2(path, out->high->nv, T, &c->high, &T2, err)) != CR_OK))
            goto fail;
        if ((st = cr_dataset_path(&man, ql->body_pc2, path, sizeof path, err)) != CR_OK ||
            (st = read_pc2(path, out->body->nv, -T, &c->body, &T2, err)) != CR_OK)
            goto fail;
        c->nframes = T;
    }
    cr_dataset_manifest_free(&man);
    return CR_OK;
fail:
    cr_dataset_manifest_free(&man);
    cr_gdsr_data_free(out);
    return st;
}

cr_status cr_gdsr_data_from_arrays(const cr_mesh *low, const cr_mesh *high, const cr_mesh *body,
                                   int32_t nframes, const float *low_frames,
                                   const float *high_frames, const float *body_frames,
                                   cr_gdsr_data *out, cr_error *err) {
    memset(out, 0, sizeof *out);
    cr_status st;
    if ((st = cr_mesh_clone(low, &out->low, err)) != CR_OK) goto fail;
    if ((st = cr_mesh_clone(high, &out->high, err)) != CR_OK) goto fail;
    if ((st = cr_mesh_clone(body, &out->body, err)) != CR_OK) goto fail;
    out->face = malloc((size_t)high->nv * sizeof(int32_t));
    out->bary = malloc((size_t)high->nv * 3 * sizeof(float));
    if (!out->face || !out->bary) {
        st = CR_FAIL(err, CR_ERR_MEMORY, "gdsr: out of memory");
        goto fail;
    }
    if ((st = cr_garment_correspondence(low, high, out->face, out->bary, err)) != CR_OK) goto fail;
    if ((st = coarse_operator(out, err)) != CR_OK) goto fail;
    out->nclips = 1;
    cr_gdsr_clip *c = &out->clip[0];
    snprintf(c->motion, sizeof c->motion, "arrays");
    c->nframes = nframes;
    size_t nl = (size_t)nframes * low->nv * 3, nh = (size_t)nframes * high->nv * 3,
           nb = (size_t)nframes * body->nv * 3;
    c->low = malloc(nl * sizeof(float));
    c->high = malloc(nh * sizeof(float));
    c->body = malloc(nb * sizeof(float));
    if (!c->low || !c->high || !c->body) {
        st = CR_FAIL(err, CR_ERR_MEMORY, "gdsr: out of memory");
        goto fail;
    }
    memcpy(c->low, low_frames, nl * sizeof(float));
    memcpy(c->high, high_frames, nh * sizeof(float));
    memcpy(c->body, body_frames, nb * sizeof(float));
    return CR_OK;
fail:
    cr_gdsr_data_free(out);
    return st;
}

/* ------------------------------------------------------------ graph -- */

void cr_gdsr_graph_free(cr_gdsr_graph *g) {
    if (!g) return;
    for (int s = 0; s < 3; s++) {
        free(g->snd[s]);
        free(g->rcv[s]);
    }
    memset(g, 0, sizeof *g);
}

static int cmp_i32(const void *a, const void *b) {
    int32_t x = *(const int32_t *)a, y = *(const int32_t *)b;
    return (x > y) - (x < y);
}

cr_status cr_gdsr_graph_build(const cr_mesh *low, cr_gdsr_graph *out, cr_error *err) {
    memset(out, 0, sizeof *out);
    cr_topology *t = NULL;
    CR_TRY(cr_topology_build(low, &t, err));
    int32_t nv = low->nv;
    out->nv = nv;
    /* adjacency lists (CSR) */
    int32_t *deg = calloc((size_t)nv + 1, sizeof(int32_t));
    int32_t *adj = malloc((size_t)2 * t->ne * sizeof(int32_t));
    int32_t *fill = calloc((size_t)nv, sizeof(int32_t));
    int32_t *mark = malloc((size_t)nv * sizeof(int32_t));
    int32_t *tmp = malloc((size_t)nv * sizeof(int32_t));
    cr_status st = CR_OK;
    if (!deg || !adj || !fill || !mark || !tmp) {
        st = CR_FAIL(err, CR_ERR_MEMORY, "gdsr: out of memory");
        goto done;
    }
    for (int32_t e = 0; e < t->ne; e++) {
        deg[t->edge[2 * e] + 1]++;
        deg[t->edge[2 * e + 1] + 1]++;
    }
    for (int32_t i = 0; i < nv; i++)
        deg[i + 1] += deg[i];
    for (int32_t e = 0; e < t->ne; e++) {
        int32_t a = t->edge[2 * e], b = t->edge[2 * e + 1];
        adj[deg[a] + fill[a]++] = b;
        adj[deg[b] + fill[b]++] = a;
    }
    for (int32_t i = 0; i < nv; i++)
        qsort(adj + deg[i], (size_t)(deg[i + 1] - deg[i]), 4, cmp_i32);
    /* 1-ring: both directions of every edge */
    out->ne[0] = 2 * (int64_t)t->ne;
    out->snd[0] = malloc((size_t)out->ne[0] * sizeof(int32_t));
    out->rcv[0] = malloc((size_t)out->ne[0] * sizeof(int32_t));
    if (!out->snd[0] || !out->rcv[0]) {
        st = CR_FAIL(err, CR_ERR_MEMORY, "gdsr: out of memory");
        goto done;
    }
    int64_t k = 0;
    for (int32_t i = 0; i < nv; i++)
        for (int32_t a = deg[i]; a < deg[i + 1]; a++) {
            out->rcv[0][k] = i;
            out->snd[0][k] = adj[a];
            k++;
        }
    /* 2-ring: vertices at distance exactly 2, counted then filled */
    for (int pass = 0; pass < 2; pass++) {
        int64_t n2 = 0;
        for (int32_t i = 0; i < nv; i++)
            mark[i] = -1;
        for (int32_t i = 0; i < nv; i++) {
            mark[i] = i;
            for (int32_t a = deg[i]; a < deg[i + 1]; a++)
                mark[adj[a]] = i;
            int32_t nt = 0;
            for (int32_t a = deg[i]; a < deg[i + 1]; a++) {
                int32_t j = adj[a];
                for (int32_t b = deg[j]; b < deg[j + 1]; b++) {
                    int32_t q = adj[b];
                    if (mark[q] == i) continue;
                    mark[q] = i;
                    tmp[nt++] = q;
                }
            }
            qsort(tmp, (size_t)nt, 4, cmp_i32);
            for (int32_t a = 0; a < nt; a++) {
                if (pass == 1) {
                    out->rcv[1][n2] = i;
                    out->snd[1][n2] = tmp[a];
                }
                n2++;
            }
        }
        if (pass == 0) {
            out->ne[1] = n2;
            out->snd[1] = malloc((size_t)(n2 > 0 ? n2 : 1) * sizeof(int32_t));
            out->rcv[1] = malloc((size_t)(n2 > 0 ? n2 : 1) * sizeof(int32_t));
            if (!out->snd[1] || !out->rcv[1]) {
                st = CR_FAIL(err, CR_ERR_MEMORY, "gdsr: out of memory");
                goto done;
            }
        }
    }
done:
    free(deg);
    free(adj);
    free(fill);
    free(mark);
    free(tmp);
    cr_topology_destroy(t);
    if (st != CR_OK) cr_gdsr_graph_free(out);
    return st;
}

/* --------------------------------------------------------- features -- */

static void vertex_normals(const cr_mesh *m, const float *pos, float *n) {
    memset(n, 0, (size_t)m->nv * 3 * sizeof(float));
    for (int32_t f = 0; f < m->nf; f++) {
        const int32_t *t = m->tri + 3 * f;
        const float *a = pos + 3 * t[0], *b = pos + 3 * t[1], *c = pos + 3 * t[2];
        float u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        float v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        float x[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2],
                      u[0] * v[1] - u[1] * v[0]};
        for (int k = 0; k < 3; k++)
            for (int j = 0; j < 3; j++)
                n[3 * t[k] + j] += x[j];
    }
    for (int32_t i = 0; i < m->nv; i++) {
        float *p = n + 3 * i;
        float l = sqrtf(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
        if (l > 0)
            for (int j = 0; j < 3; j++)
                p[j] /= l;
    }
}

void cr_gdsr_features(const cr_mesh *low, const cr_gdsr_graph *g, const cr_gdsr_frame_in *in,
                      float sigma_b, float *node, float *edge0, float *edge1) {
    float *nrm = malloc((size_t)low->nv * 3 * sizeof(float));
    cr_gdsr_features_(low, g, in, sigma_b, nrm, node, edge0, edge1);
    free(nrm);
}

void cr_gdsr_features_(const cr_mesh *low, const cr_gdsr_graph *g, const cr_gdsr_frame_in *in,
                       float sigma_b, float *nrm, float *node, float *edge0, float *edge1) {
    int32_t nv = low->nv;
    const int F = CR_GDSR_NODE_FEATURES;
    if (nrm) vertex_normals(low, in->c, nrm);
    for (int32_t i = 0; i < nv; i++) {
        float *o = node + (int64_t)F * i;
        const float *x = in->c + 3 * i, *x1 = in->c_prev + 3 * i, *x2 = in->c_prev2 + 3 * i;
        for (int k = 0; k < 3; k++) {
            o[k] = nrm ? nrm[3 * i + k] : 0.0f;
            o[3 + k] = 100.0f * (x[k] - x1[k]);
            o[6 + k] = 100.0f * (x[k] - 2.0f * x1[k] + x2[k]);
        }
        const float *bp = in->body_point + 3 * i;
        float b[3] = {bp[0] - x[0], bp[1] - x[1], bp[2] - x[2]};
        float bl = sqrtf(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
        int near = bl < sigma_b;
        for (int k = 0; k < 3; k++)
            o[9 + k] = near ? b[k] / sigma_b : 0.0f;
        o[12] = near ? bl / sigma_b : 0.0f;
        const float *h1 = in->chat_prev ? in->chat_prev + 3 * i : x1;
        const float *h2 = in->chat_prev2 ? in->chat_prev2 + 3 * i : x2;
        for (int k = 0; k < 3; k++) {
            o[13 + k] = in->d_prev ? 100.0f * in->d_prev[3 * i + k] : 0.0f;
            o[16 + k] = 100.0f * (h1[k] - h2[k]);
        }
    }
    float *edges[2] = {edge0, edge1};
    for (int s = 0; s < 2; s++) {
        if (!edges[s]) continue;
        for (int64_t e = 0; e < g->ne[s]; e++) {
            int32_t i = g->rcv[s][e], j = g->snd[s][e];
            float *o = edges[s] + (int64_t)CR_GDSR_EDGE_FEATURES * e;
            float r2 = 0, c2 = 0;
            for (int k = 0; k < 3; k++) {
                float r = 10.0f * (low->pos[3 * j + k] - low->pos[3 * i + k]);
                float c = 10.0f * (in->c[3 * j + k] - in->c[3 * i + k]);
                o[k] = r;
                o[4 + k] = c;
                r2 += r * r;
                c2 += c * c;
            }
            o[3] = sqrtf(r2);
            o[7] = sqrtf(c2);
        }
    }
}

/* ------------------------------------------------------ layer edges -- */

static int32_t find_root(int32_t *parent, int32_t i) {
    while (parent[i] != i) {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    return i;
}

int32_t cr_gdsr_mesh_layers(const cr_mesh *m, int32_t *layer) {
    int32_t nv = m->nv;
    /* union-find over the triangles' corners, in layer[] itself */
    for (int32_t i = 0; i < nv; i++)
        layer[i] = i;
    for (int32_t f = 0; f < m->nf; f++)
        for (int k = 1; k < 3; k++) {
            int32_t a = find_root(layer, m->tri[3 * f]), b = find_root(layer, m->tri[3 * f + k]);
            if (a != b) layer[a > b ? a : b] = a < b ? a : b; /* the lower root wins */
        }
    /* each vertex to its root, the component's lowest vertex (so below or at it) */
    for (int32_t i = 0; i < nv; i++)
        layer[i] = find_root(layer, i);
    /* number the roots in order, as -(id + 1) while the roots are still read */
    int32_t n = 0;
    for (int32_t i = 0; i < nv; i++)
        layer[i] = layer[i] == i ? -(++n) : layer[layer[i]];
    for (int32_t i = 0; i < nv; i++)
        layer[i] = -layer[i] - 1;
    return n;
}

typedef struct cell_item {
    int64_t key;
    int32_t v;
} cell_item;

static int cmp_cell(const void *a, const void *b) {
    const cell_item *x = a, *y = b;
    if (x->key != y->key) return (x->key > y->key) - (x->key < y->key);
    return (x->v > y->v) - (x->v < y->v);
}

enum { CELL_BITS = 21 }; /* cells per axis < 2^21: 42 km at 2 cm */

static int64_t cell_key(int64_t x, int64_t y, int64_t z) {
    return (x << (2 * CELL_BITS)) | (y << CELL_BITS) | z;
}

static cr_status push_edge(cr_gdsr_graph *g, int32_t rcv, int32_t snd, cr_error *err) {
    if (g->ne[2] == g->cap2) {
        int64_t cap = g->cap2 ? 2 * g->cap2 : 1024;
        int32_t *r = realloc(g->rcv[2], (size_t)cap * sizeof(int32_t));
        if (r) g->rcv[2] = r;
        int32_t *s = r ? realloc(g->snd[2], (size_t)cap * sizeof(int32_t)) : NULL;
        if (s) g->snd[2] = s;
        if (!r || !s) return CR_FAIL(err, CR_ERR_MEMORY, "gdsr: out of memory (layer edges)");
        g->cap2 = cap;
    }
    g->rcv[2][g->ne[2]] = rcv;
    g->snd[2][g->ne[2]] = snd;
    g->ne[2]++;
    return CR_OK;
}

cr_status cr_gdsr_layer_edges(cr_gdsr_graph *g, const int32_t *layer, const float *c, float sigma_l,
                              cr_error *err) {
    g->ne[2] = 0;
    int32_t nv = g->nv;
    int multi = 0;
    for (int32_t i = 1; layer && i < nv && !multi; i++)
        multi = layer[i] != layer[0];
    if (!multi) return CR_OK;
    if (!(sigma_l > 0))
        return CR_FAIL(err, CR_ERR_INVALID, "gdsr layer edges: sigma_l = %g m", (double)sigma_l);
    float lo[3] = {c[0], c[1], c[2]};
    for (int32_t i = 0; i < nv; i++)
        for (int k = 0; k < 3; k++) {
            if (!isfinite(c[3 * i + k]))
                return CR_FAIL(err, CR_ERR_NAN, "gdsr layer edges: vertex %d is not finite", i);
            lo[k] = fminf(lo[k], c[3 * i + k]);
        }
    cell_item *it = malloc((size_t)nv * sizeof(cell_item));
    int32_t(*cell)[3] = malloc((size_t)nv * sizeof *cell);
    int32_t *tmp = malloc((size_t)nv * sizeof(int32_t));
    cr_status st = it && cell && tmp ? CR_OK : CR_FAIL(err, CR_ERR_MEMORY, "gdsr: out of memory");
    for (int32_t i = 0; i < nv && st == CR_OK; i++) {
        for (int k = 0; k < 3; k++) {
            double q = floor(((double)c[3 * i + k] - lo[k]) / sigma_l) + 1; /* >= 1: room below */
            if (q >= (double)((1 << CELL_BITS) - 1))
                st = CR_FAIL(err, CR_ERR_RANGE,
                             "gdsr layer edges: the garment spans more than %d cells of %g m",
                             (1 << CELL_BITS) - 2, (double)sigma_l);
            cell[i][k] = (int32_t)q;
        }
        it[i] = (cell_item){cell_key(cell[i][0], cell[i][1], cell[i][2]), i};
    }
    if (st == CR_OK) qsort(it, (size_t)nv, sizeof *it, cmp_cell);
    const float s2 = sigma_l * sigma_l;
    for (int32_t i = 0; i < nv && st == CR_OK; i++) {
        int32_t nt = 0;
        for (int dx = -1; dx <= 1; dx++)
            for (int dy = -1; dy <= 1; dy++)
                for (int dz = -1; dz <= 1; dz++) {
                    int64_t key = cell_key(cell[i][0] + dx, cell[i][1] + dy, cell[i][2] + dz);
                    /* the first item of the cell (lower bound) */
                    int32_t a = 0, b = nv;
                    while (a < b) {
                        int32_t mid = a + (b - a) / 2;
                        if (it[mid].key < key)
                            a = mid + 1;
                        else
                            b = mid;
                    }
                    for (; a < nv && it[a].key == key; a++) {
                        int32_t l = it[a].v;
                        if (layer[l] == layer[i]) continue;
                        float d2 = 0;
                        for (int k = 0; k < 3; k++) {
                            float e = c[3 * l + k] - c[3 * i + k];
                            d2 += e * e;
                        }
                        if (d2 < s2) tmp[nt++] = l;
                    }
                }
        qsort(tmp, (size_t)nt, sizeof(int32_t), cmp_i32);
        for (int32_t a = 0; a < nt && st == CR_OK; a++)
            st = push_edge(g, i, tmp[a], err);
    }
    free(it);
    free(cell);
    free(tmp);
    if (st != CR_OK) g->ne[2] = 0;
    return st;
}

void cr_gdsr_layer_edge_features(const cr_gdsr_graph *g, const float *c, float sigma_l,
                                 float *edge2) {
    for (int64_t e = 0; e < g->ne[2]; e++) {
        int32_t i = g->rcv[2][e], l = g->snd[2][e];
        float *o = edge2 + (int64_t)CR_GDSR_EDGE_FEATURES * e;
        float c2 = 0;
        for (int k = 0; k < 3; k++) {
            float d = 10.0f * (c[3 * l + k] - c[3 * i + k]);
            o[k] = 0.0f;
            o[4 + k] = d;
            c2 += d * d;
        }
        o[3] = 10.0f * sigma_l;
        o[7] = sqrtf(c2);
    }
}

cr_status cr_gdsr_frame_features_(const cr_gdsr_data *d, const cr_gdsr_model_def *md,
                                  cr_gdsr_graph *g, const cr_gdsr_frame_in *in, float *nrm,
                                  float *node, float *e0, float *e1, float **e2, int64_t *e2cap,
                                  cr_error *err) {
    cr_gdsr_features_(d->low, g, in, md->sigma_b, nrm, node, e0, e1);
    g->ne[2] = 0;
    if (!md->layer_edges || d->nlayers < 2) return CR_OK;
    CR_TRY(cr_gdsr_layer_edges(g, d->layer, in->c, md->sigma_l, err));
    if (g->ne[2] > *e2cap) {
        float *p = realloc(*e2, (size_t)g->ne[2] * CR_GDSR_EDGE_FEATURES * sizeof(float));
        if (!p) return CR_FAIL(err, CR_ERR_MEMORY, "gdsr: out of memory (layer edges)");
        *e2 = p, *e2cap = g->ne[2];
    }
    cr_gdsr_layer_edge_features(g, in->c, md->sigma_l, *e2);
    return CR_OK;
}
