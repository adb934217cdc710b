/* io_dispatch.c: mesh read/write by file extension, and the UV seam split and
 * position weld that let per-corner UVs pass through the formats that store
 * one UV per vertex (PLY, glTF) and come back unchanged.
 *
 * Split: each vertex gets one copy per distinct UV its corners use (compared
 * bit for bit), originals first in their own order, extra copies appended.
 * Weld: vertices with bit-identical positions merge into the first one; a
 * hash table on the position bits makes it linear in V. Together they are
 * inverses on any mesh without two distinct vertices at the same position.
 */
#include "crease/mesh_io.h"

#include <stdlib.h>
#include <string.h>

cr_status cr_mesh_read(const char *path, cr_mesh **out, cr_error *err) {
    *out = NULL;
    char ext[16];
    cr_path_ext(path, ext, sizeof ext);
    if (strcmp(ext, "obj") == 0) return cr_obj_read(path, out, err);
    if (strcmp(ext, "ply") == 0) return cr_ply_read(path, out, err);
    if (strcmp(ext, "glb") == 0) return cr_glb_read(path, out, err);
    return CR_FAIL(err, CR_ERR_UNSUPPORTED,
                   "%s: cannot read meshes with extension '.%s' (expected .obj, .ply or .glb)",
                   path, ext);
}

cr_status cr_mesh_write(const char *path, const cr_mesh *m, cr_error *err) {
    char ext[16];
    cr_path_ext(path, ext, sizeof ext);
    if (strcmp(ext, "obj") == 0) return cr_obj_write(path, m, err);
    if (strcmp(ext, "ply") == 0) return cr_ply_write(path, m, CR_PLY_BINARY, err);
    if (strcmp(ext, "glb") == 0) return cr_glb_write(path, m, err);
    return CR_FAIL(err, CR_ERR_UNSUPPORTED,
                   "%s: cannot write meshes with extension '.%s' (expected .obj, .ply or .glb)",
                   path, ext);
}

/* ----------------------------------------------------------------- split -- */

void cr_mesh_seams_free(cr_mesh_seams *s) {
    if (!s) return;
    free(s->src);
    free(s->uv);
    free(s->tri);
    memset(s, 0, sizeof *s);
}

cr_status cr_mesh_split_seams(const cr_mesh *m, cr_mesh_seams *out, cr_error *err) {
    memset(out, 0, sizeof *out);
    int uv = cr_mesh_has_uv(m);
    int64_t nc = 3 * (int64_t)m->nf;     /* corners */
    int64_t cap = m->nv + (uv ? nc : 0); /* at most one new vertex per corner */
    out->src = cr_malloc((size_t)cap * sizeof(int32_t), err);
    out->tri = cr_malloc((size_t)nc * sizeof(int32_t), err);
    if (!out->src || !out->tri) {
        cr_mesh_seams_free(out);
        return CR_ERR_MEMORY;
    }
    for (int32_t i = 0; i < m->nv; i++)
        out->src[i] = i;
    out->nv = m->nv;
    if (!uv) {
        memcpy(out->tri, m->tri, (size_t)nc * sizeof(int32_t));
        return CR_OK;
    }
    out->uv = cr_calloc((size_t)cap * 2, sizeof(float), err);
    int32_t *next = cr_malloc((size_t)cap * sizeof(int32_t), err); /* chain of copies */
    unsigned char *used = cr_calloc((size_t)m->nv, 1, err);
    if (!out->uv || !next || !used) {
        free(next), free(used);
        cr_mesh_seams_free(out);
        return CR_ERR_MEMORY;
    }
    int64_t n = m->nv;
    for (int64_t c = 0; c < nc; c++) {
        int32_t v = m->tri[c];
        const float *t = &m->uv[2 * (int64_t)m->tri_uv[c]];
        if (!used[v]) {
            used[v] = 1;
            memcpy(&out->uv[2 * (int64_t)v], t, 2 * sizeof(float));
            next[v] = -1;
            out->tri[c] = v;
            continue;
        }
        int32_t s = v;
        while (memcmp(&out->uv[2 * (int64_t)s], t, 2 * sizeof(float)) != 0 && next[s] >= 0)
            s = next[s];
        if (memcmp(&out->uv[2 * (int64_t)s], t, 2 * sizeof(float)) != 0) {
            next[s] = (int32_t)n;
            next[n] = -1;
            out->src[n] = v;
            memcpy(&out->uv[2 * n], t, 2 * sizeof(float));
            s = (int32_t)n++;
        }
        out->tri[c] = s;
    }
    free(next), free(used);
    if (n > INT32_MAX) {
        cr_mesh_seams_free(out);
        return CR_FAIL(err, CR_ERR_RANGE, "seam split: %lld vertices exceed 32-bit indices",
                       (long long)n);
    }
    out->nv = (int32_t)n;
    return CR_OK;
}

/* ------------------------------------------------------------------ weld -- */

static uint64_t hash_position(const float *p) {
    uint32_t w[3];
    memcpy(w, p, sizeof w);
    uint64_t h = ((uint64_t)w[0] << 32 | w[1]) ^ ((uint64_t)w[2] * 0x9e3779b97f4a7c15ull);
    /* splitmix64 finaliser: every input bit reaches the low (table) bits */
    h ^= h >> 30;
    h *= 0xbf58476d1ce4e5b9ull;
    h ^= h >> 27;
    h *= 0x94d049bb133111ebull;
    return h ^ (h >> 31);
}

/* Keep rows i with map[i] new (the first copy) in place: rows only move down. */
static void compact_rows(float *a, int32_t dim, const int32_t *map, int32_t nv) {
    int32_t k = 0;
    for (int32_t i = 0; i < nv; i++)
        if (map[i] == k) {
            memmove(&a[(int64_t)k * dim], &a[(int64_t)i * dim], (size_t)dim * sizeof(float));
            k++;
        }
}

cr_status cr_mesh_weld(cr_mesh *m, cr_error *err) {
    if (m->nv == 0) return CR_OK;
    size_t cap = 1;
    while (cap < 2 * (size_t)m->nv)
        cap *= 2;
    int32_t *table = cr_malloc(cap * sizeof(int32_t), err);
    int32_t *map = cr_malloc((size_t)m->nv * sizeof(int32_t), err);
    if (!table || !map) {
        free(table), free(map);
        return CR_ERR_MEMORY;
    }
    memset(table, 0xff, cap * sizeof(int32_t));
    int32_t nnew = 0;
    for (int32_t i = 0; i < m->nv; i++) {
        const float *p = &m->pos[3 * (int64_t)i];
        size_t h = (size_t)hash_position(p) & (cap - 1);
        while (table[h] >= 0 && memcmp(&m->pos[3 * (int64_t)table[h]], p, 3 * sizeof(float)) != 0)
            h = (h + 1) & (cap - 1);
        if (table[h] >= 0) {
            map[i] = map[table[h]];
        } else {
            table[h] = i;
            map[i] = nnew++;
        }
    }
    free(table);
    if (nnew < m->nv) {
        compact_rows(m->pos, 3, map, m->nv);
        if (m->normal) compact_rows(m->normal, 3, map, m->nv);
        for (int32_t a = 0; a < m->nattr; a++)
            compact_rows(m->attr[a].data, m->attr[a].dim, map, m->nv);
        for (int64_t c = 0; c < 3 * (int64_t)m->nf; c++)
            m->tri[c] = map[m->tri[c]];
        m->nv = nnew;
    }
    free(map);
    return CR_OK;
}
