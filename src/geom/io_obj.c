/* io_obj.c: Wavefront OBJ reader and writer.
 *
 * Reads v, vt, vn and f (v, v/vt, v//vn, v/vt/vn, negative = relative
 * indices), fan-triangulating polygons; skips groups, materials, smoothing,
 * lines, points and the free-form statements; refuses anything else, so a
 * binary or foreign file is not half-read. One pass, arrays grown by
 * doubling: memory stays within a small multiple of the file size. Indices
 * must refer to elements defined above the face, which lets every range
 * error name its line. '#' starts a comment anywhere on a line; a leading
 * UTF-8 byte-order mark is skipped. '\' line continuation is not supported.
 *
 * Writes v, vt, vn with %.9g (float round trip is exact) and f v/vt/vn.
 *
 * Reference: Wavefront "Object Files (.obj)", Appendix B1 of the Advanced
 * Visualizer manual (paulbourke.net/dataformats/obj).
 */
#include "crease/mesh_io.h"
#include "geom/io_text.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Statements we accept and skip: grouping, display, materials and the
 * free-form geometry we do not read. */
static const char *const skipped[] = {
    "g",     "o",      "s",     "usemtl",   "mtllib",   "l",          "p",
    "vp",    "cstype", "deg",   "bmat",     "step",     "curv",       "curv2",
    "surf",  "parm",   "trim",  "hole",     "scrv",     "sp",         "end",
    "con",   "mg",     "lod",   "usemap",   "maplib",   "shadow_obj", "trace_obj",
    "ctech", "stech",  "bevel", "c_interp", "d_interp", "call",       "csh",
};

typedef struct obj_state {
    io_text t;
    float *v, *vt, *vn; /* (nv,3), (nvt,2), (nvn,3) */
    int64_t nv, nvt, nvn, cap_v, cap_vt, cap_vn;
    int32_t *tv, *tt, *tn; /* (ntri,3) vertex, uv and normal indices per corner */
    int64_t ntri, cap_tri;
    int32_t *corner; /* (ncorner,3) scratch for one polygon: v, vt, vn (-1 absent) */
    int64_t cap_corner;
    int face_vt;          /* -1 before the first face, then 0 or 1 */
    int64_t face_vt_line; /* line of the face that fixed face_vt */
    int all_vn;           /* every face so far had vn on every corner */
} obj_state;

/* Make room for `need` elements of `elem` bytes in *p (capacity *cap). */
static cr_status reserve(void **p, int64_t *cap, int64_t need, size_t elem, cr_error *err) {
    if (need <= *cap) return CR_OK;
    int64_t c = *cap ? *cap : 64;
    while (c < need)
        c *= 2;
    void *q = realloc(*p, (size_t)c * elem);
    if (!q) return CR_FAIL(err, CR_ERR_MEMORY, "obj: out of memory (%lld elements)", (long long)c);
    *p = q;
    *cap = c;
    return CR_OK;
}

static int is_keyword(const char *b, const char *e, const char *kw) {
    size_t n = strlen(kw);
    return (size_t)(e - b) == n && memcmp(b, kw, n) == 0;
}

/* Parse between `lo` and `hi` float values of a v/vt/vn line into out. */
static cr_status parse_floats(obj_state *s, const char *stmt, int lo, int hi, float *out,
                              cr_error *err) {
    const char *b, *e;
    int n = 0;
    float extra;
    while (cr_io_text_token(&s->t, &b, &e)) {
        if (n >= hi)
            return CR_FAIL(err, CR_ERR_PARSE, "%s:%lld: '%s' takes at most %d numbers", s->t.source,
                           (long long)s->t.line, stmt, hi);
        CR_TRY(cr_io_text_float(&s->t, b, e, "a coordinate", n < 3 ? &out[n] : &extra, err));
        n++;
    }
    if (n < lo)
        return CR_FAIL(err, CR_ERR_PARSE, "%s:%lld: '%s' needs at least %d numbers, got %d",
                       s->t.source, (long long)s->t.line, stmt, lo, n);
    for (int k = n; k < 3; k++)
        out[k] = 0.0f;
    return CR_OK;
}

/* One index of a face corner: 1-based, or negative relative to `count`. */
static cr_status resolve_index(obj_state *s, const char *b, const char *e, int64_t count,
                               const char *kind, int32_t *out, cr_error *err) {
    int64_t idx;
    CR_TRY(cr_io_text_int(&s->t, b, e, kind, &idx, err));
    if (idx == 0)
        return CR_FAIL(err, CR_ERR_RANGE, "%s:%lld: %s index 0 is invalid (OBJ indices start at 1)",
                       s->t.source, (long long)s->t.line, kind);
    int64_t r = idx > 0 ? idx - 1 : count + idx;
    if (r < 0 || r >= count)
        return CR_FAIL(err, CR_ERR_RANGE,
                       "%s:%lld: %s index %lld is out of range: %lld defined above this line",
                       s->t.source, (long long)s->t.line, kind, (long long)idx, (long long)count);
    *out = (int32_t)r; /* counts stay below INT32_MAX */
    return CR_OK;
}

/* "a", "a/b", "a//c" or "a/b/c" into c[0..2] (-1 where absent). */
static cr_status parse_corner(obj_state *s, const char *b, const char *e, int32_t c[3],
                              cr_error *err) {
    const char *part[3], *pend[3];
    int np = 0;
    const char *q = b;
    for (;;) {
        const char *slash = memchr(q, '/', (size_t)(e - q));
        const char *pe = slash ? slash : e;
        if (np == 3) {
            char snip[48];
            cr_io_text_snippet(b, e, snip, sizeof snip);
            return CR_FAIL(err, CR_ERR_PARSE,
                           "%s:%lld: expected v, v/vt, v//vn or v/vt/vn, got '%s'", s->t.source,
                           (long long)s->t.line, snip);
        }
        part[np] = q, pend[np] = pe, np++;
        if (!slash) break;
        q = slash + 1;
    }
    static const char *const kinds[3] = {"vertex", "texture coordinate", "normal"};
    const int64_t counts[3] = {s->nv, s->nvt, s->nvn};
    for (int k = 0; k < 3; k++) {
        c[k] = -1;
        if (k >= np || (k > 0 && part[k] == pend[k])) continue;
        CR_TRY(resolve_index(s, part[k], pend[k], counts[k], kinds[k], &c[k], err));
    }
    return CR_OK;
}

static cr_status parse_face(obj_state *s, cr_error *err) {
    const char *b, *e;
    int64_t n = 0;
    while (cr_io_text_token(&s->t, &b, &e)) {
        CR_TRY(reserve((void **)&s->corner, &s->cap_corner, n + 1, 3 * sizeof(int32_t), err));
        CR_TRY(parse_corner(s, b, e, &s->corner[3 * n], err));
        n++;
    }
    if (n < 3)
        return CR_FAIL(err, CR_ERR_PARSE, "%s:%lld: face has %lld vertices, expected at least 3",
                       s->t.source, (long long)s->t.line, (long long)n);
    int has_vt = s->corner[1] >= 0, has_vn = 1;
    for (int64_t i = 0; i < n; i++) {
        if ((s->corner[3 * i + 1] >= 0) != has_vt)
            return CR_FAIL(err, CR_ERR_PARSE,
                           "%s:%lld: some corners of this face have texture coordinates and "
                           "some do not",
                           s->t.source, (long long)s->t.line);
        has_vn &= s->corner[3 * i + 2] >= 0;
    }
    if (s->face_vt < 0) {
        s->face_vt = has_vt;
        s->face_vt_line = s->t.line;
    } else if (s->face_vt != has_vt)
        return CR_FAIL(err, CR_ERR_PARSE,
                       "%s:%lld: face %s texture coordinates but the face on line %lld %s; "
                       "expected all faces with vt or all without",
                       s->t.source, (long long)s->t.line, has_vt ? "has" : "lacks",
                       (long long)s->face_vt_line, s->face_vt ? "has them" : "does not");
    if (!has_vn && s->all_vn) {
        s->all_vn = 0;
        free(s->tn);
        s->tn = NULL;
    }
    if (s->ntri + (n - 2) > INT32_MAX)
        return CR_FAIL(err, CR_ERR_RANGE, "%s:%lld: more than %d triangles", s->t.source,
                       (long long)s->t.line, INT32_MAX);
    /* The three index arrays share one capacity; tt and tn exist only while
     * faces have vt and vn, which keeps memory near 6 bytes per file byte. */
    int64_t need = s->ntri + n - 2, cap = s->cap_tri;
    CR_TRY(reserve((void **)&s->tv, &cap, need, 3 * sizeof(int32_t), err));
    if (s->face_vt) {
        cap = s->cap_tri;
        CR_TRY(reserve((void **)&s->tt, &cap, need, 3 * sizeof(int32_t), err));
    }
    if (s->all_vn) {
        cap = s->cap_tri;
        CR_TRY(reserve((void **)&s->tn, &cap, need, 3 * sizeof(int32_t), err));
    }
    s->cap_tri = cap;
    /* Fan triangulation (0, k, k+1), which keeps the polygon's winding. */
    for (int64_t k = 1; k + 1 < n; k++) {
        const int64_t idx[3] = {0, k, k + 1};
        for (int j = 0; j < 3; j++) {
            const int32_t *c = &s->corner[3 * idx[j]];
            s->tv[3 * s->ntri + j] = c[0];
            if (s->face_vt) s->tt[3 * s->ntri + j] = c[1];
            if (s->all_vn) s->tn[3 * s->ntri + j] = c[2];
        }
        s->ntri++;
    }
    return CR_OK;
}

static cr_status parse_line(obj_state *s, cr_error *err) {
    const char *b, *e;
    const char *hash = memchr(s->t.cur, '#', (size_t)(s->t.le - s->t.cur));
    if (hash) s->t.le = hash; /* a comment runs from '#' to the end of the line */
    if (!cr_io_text_token(&s->t, &b, &e)) return CR_OK;
    if (is_keyword(b, e, "v")) {
        if (s->nv >= INT32_MAX)
            return CR_FAIL(err, CR_ERR_RANGE, "%s:%lld: more than %d vertices", s->t.source,
                           (long long)s->t.line, INT32_MAX);
        CR_TRY(reserve((void **)&s->v, &s->cap_v, s->nv + 1, 3 * sizeof(float), err));
        CR_TRY(parse_floats(s, "v", 3, 7, &s->v[3 * s->nv], err));
        s->nv++;
    } else if (is_keyword(b, e, "vt")) {
        if (s->nvt >= INT32_MAX)
            return CR_FAIL(err, CR_ERR_RANGE, "%s:%lld: more than %d texture coordinates",
                           s->t.source, (long long)s->t.line, INT32_MAX);
        float uvw[3];
        CR_TRY(reserve((void **)&s->vt, &s->cap_vt, s->nvt + 1, 2 * sizeof(float), err));
        CR_TRY(parse_floats(s, "vt", 1, 3, uvw, err));
        s->vt[2 * s->nvt] = uvw[0], s->vt[2 * s->nvt + 1] = uvw[1];
        s->nvt++;
    } else if (is_keyword(b, e, "vn")) {
        if (s->nvn >= INT32_MAX)
            return CR_FAIL(err, CR_ERR_RANGE, "%s:%lld: more than %d normals", s->t.source,
                           (long long)s->t.line, INT32_MAX);
        CR_TRY(reserve((void **)&s->vn, &s->cap_vn, s->nvn + 1, 3 * sizeof(float), err));
        CR_TRY(parse_floats(s, "vn", 3, 3, &s->vn[3 * s->nvn], err));
        s->nvn++;
    } else if (is_keyword(b, e, "f")) {
        CR_TRY(parse_face(s, err));
    } else {
        for (size_t i = 0; i < sizeof skipped / sizeof skipped[0]; i++)
            if (is_keyword(b, e, skipped[i])) return CR_OK;
        char snip[48];
        cr_io_text_snippet(b, e, snip, sizeof snip);
        return CR_FAIL(err, CR_ERR_PARSE,
                       "%s:%lld: unknown statement '%s' (expected v, vt, vn, f, g, o, s, usemtl, "
                       "mtllib or a comment)",
                       s->t.source, (long long)s->t.line, snip);
    }
    return CR_OK;
}

/* Per-vertex normal: the normalised mean of the vn its corners give it. */
static cr_status average_normals(const obj_state *s, cr_mesh *m, cr_error *err) {
    double *sum = cr_calloc((size_t)m->nv * 3, sizeof(double), err);
    m->normal = cr_calloc((size_t)m->nv * 3, sizeof(float), err);
    if (!sum || !m->normal) {
        free(sum);
        return CR_ERR_MEMORY;
    }
    for (int64_t c = 0; c < 3 * s->ntri; c++)
        for (int k = 0; k < 3; k++)
            sum[3 * (int64_t)m->tri[c] + k] += s->vn[3 * (int64_t)s->tn[c] + k];
    for (int64_t i = 0; i < m->nv; i++) {
        double *n = &sum[3 * i];
        double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        /* Opposite or zero vn leave no direction: the normal stays zero. */
        for (int k = 0; len > 0 && k < 3; k++)
            m->normal[3 * i + k] = (float)(n[k] / len);
    }
    free(sum);
    return CR_OK;
}

static void state_free(obj_state *s) {
    free(s->v), free(s->vt), free(s->vn);
    free(s->tv), free(s->tt), free(s->tn);
    free(s->corner);
}

cr_status cr_obj_read_mem(const void *data, size_t len, const char *source, cr_mesh **out,
                          cr_error *err) {
    *out = NULL;
    obj_state s;
    memset(&s, 0, sizeof s);
    cr_io_text_init(&s.t, data, len, source);
    s.face_vt = -1;
    s.all_vn = 1;
    cr_status st = CR_OK;
    for (;;) {
        int got;
        st = cr_io_text_next_line(&s.t, &got, err);
        if (st != CR_OK || !got) break;
        st = parse_line(&s, err);
        if (st != CR_OK) break;
    }
    if (st == CR_OK && s.ntri == 0)
        st = CR_FAIL(err, CR_ERR_TOPOLOGY, "%s:%lld: no faces (expected 'f' lines)", source,
                     (long long)(s.t.line > 0 ? s.t.line : 1));
    cr_mesh *m = NULL;
    if (st == CR_OK) st = cr_mesh_create(0, 0, 0, &m, err);
    if (st == CR_OK) {
        /* Hand the grown arrays over to the mesh rather than copying them. */
        free(m->pos), free(m->tri);
        m->nv = (int32_t)s.nv, m->nf = (int32_t)s.ntri;
        m->pos = s.v, m->tri = s.tv;
        s.v = NULL, s.tv = NULL;
        if (s.face_vt == 1) {
            m->nuv = (int32_t)s.nvt;
            m->uv = s.vt, m->tri_uv = s.tt;
            s.vt = NULL, s.tt = NULL;
        }
        if (s.all_vn) st = average_normals(&s, m, err);
    }
    if (st == CR_OK) st = cr_mesh_validate(m, source, err);
    state_free(&s);
    if (st != CR_OK) {
        cr_mesh_destroy(m);
        return st;
    }
    *out = m;
    return CR_OK;
}

cr_status cr_obj_read(const char *path, cr_mesh **out, cr_error *err) {
    *out = NULL;
    char *buf;
    size_t len;
    CR_TRY(cr_file_read_all(path, &buf, &len, err));
    cr_status st = cr_obj_read_mem(buf, len, path, out, err);
    free(buf);
    return st;
}

cr_status cr_obj_write(const char *path, const cr_mesh *m, cr_error *err) {
    CR_TRY(cr_mesh_validate(m, path, err));
    if (m->nf == 0) return CR_FAIL(err, CR_ERR_TOPOLOGY, "%s: mesh has no faces", path);
    cr_atomic_file f;
    CR_TRY(cr_atomic_open(&f, path, err));
    FILE *fp = f.fp;
    int uv = cr_mesh_has_uv(m), nrm = m->normal != NULL;
    fprintf(fp, "# crease: %d vertices, %d triangles\n", m->nv, m->nf);
    for (int64_t i = 0; i < m->nv; i++) {
        const float *p = &m->pos[3 * i];
        fprintf(fp, "v %.9g %.9g %.9g\n", p[0], p[1], p[2]);
    }
    for (int64_t i = 0; uv && i < m->nuv; i++)
        fprintf(fp, "vt %.9g %.9g\n", m->uv[2 * i], m->uv[2 * i + 1]);
    for (int64_t i = 0; nrm && i < m->nv; i++) {
        const float *n = &m->normal[3 * i];
        fprintf(fp, "vn %.9g %.9g %.9g\n", n[0], n[1], n[2]);
    }
    for (int64_t i = 0; i < m->nf && !ferror(fp); i++) {
        fputc('f', fp);
        for (int k = 0; k < 3; k++) {
            long long v = m->tri[3 * i + k] + 1LL;
            if (uv && nrm)
                fprintf(fp, " %lld/%d/%lld", v, m->tri_uv[3 * i + k] + 1, v);
            else if (uv)
                fprintf(fp, " %lld/%d", v, m->tri_uv[3 * i + k] + 1);
            else if (nrm)
                fprintf(fp, " %lld//%lld", v, v);
            else
                fprintf(fp, " %lld", v);
        }
        fputc('\n', fp);
    }
    return cr_atomic_commit(&f, err);
}
