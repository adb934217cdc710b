/* io_ply.c: PLY (Stanford polygon file) reader and writer.
 *
 * Reads ascii, binary_little_endian and binary_big_endian files: positions
 * (x y z of any numeric type), optional normals (nx ny nz) and per-vertex
 * UVs (s t, u v, texture_u texture_v or texture_s texture_t) from element
 * "vertex", polygons from the list vertex_indices / vertex_index of element
 * "face" (fan-triangulated). Every other element and property is read past
 * and dropped, lists included. Before anything is allocated, the counts the
 * header declares are checked against the bytes that follow it (each item
 * needs at least its fixed-size part in binary, two bytes per value in
 * ascii), so a forged header cannot make the reader allocate beyond a small
 * multiple of the file. Data after the last element is refused: it means the
 * header and the body disagree. With UVs, vertices split at seams are welded
 * back (see crease/mesh_io.h).
 *
 * Writes binary little endian or ascii: float x y z [nx ny nz] [s t], faces
 * "list uchar int vertex_indices", vertices split at UV seams.
 *
 * Reference: Greg Turk, "The PLY Polygon File Format" (1994),
 * paulbourke.net/dataformats/ply.
 */
#include "crease/mesh_io.h"
#include "geom/io_text.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef enum ptype { T_NONE, T_I8, T_U8, T_I16, T_U16, T_I32, T_U32, T_F32, T_F64 } ptype;

static const int type_size[] = {0, 1, 1, 2, 2, 4, 4, 4, 8};

static const struct {
    const char *name;
    ptype type;
} type_names[] = {
    {"char", T_I8},   {"int8", T_I8},     {"uchar", T_U8},   {"uint8", T_U8},
    {"short", T_I16}, {"int16", T_I16},   {"ushort", T_U16}, {"uint16", T_U16},
    {"int", T_I32},   {"int32", T_I32},   {"uint", T_U32},   {"uint32", T_U32},
    {"float", T_F32}, {"float32", T_F32}, {"double", T_F64}, {"float64", T_F64},
};

/* What a property feeds. U/V pairs are matched by name below. */
enum { R_SKIP = -1, R_X, R_Y, R_Z, R_NX, R_NY, R_NZ, R_U, R_V, R_INDICES };

typedef struct ply_prop {
    char name[64];
    ptype type;       /* scalar type, or list item type */
    ptype count_type; /* list count type, T_NONE for scalars */
    int role;
} ply_prop;

typedef struct ply_elem {
    char name[64];
    int64_t count;
    int64_t line; /* header line that declared it */
    ply_prop *props;
    int nprops, cap;
} ply_elem;

enum { FMT_ASCII, FMT_LE, FMT_BE };

typedef struct ply_reader {
    const unsigned char *data;
    size_t len;
    const char *source;
    int format;
    io_text t;  /* header, then the ascii body */
    size_t off; /* binary cursor (byte offset in data) */
    ply_elem *elems;
    int nelems, cap_elems;
    int vertex_elem, face_elem;
    int has_normal, has_uv;
    int64_t nv;
    float *pos, *normal, *uv; /* (V,3), (V,3), (V,2) */
    int32_t *tri;             /* (ntri,3) */
    int64_t ntri, cap_tri;
} ply_reader;

static int is_int_type(ptype t) {
    return t >= T_I8 && t <= T_U32;
}

static int token_is(const char *b, const char *e, const char *s) {
    size_t n = strlen(s);
    return (size_t)(e - b) == n && memcmp(b, s, n) == 0;
}

/* ---------------------------------------------------------------- header -- */

static cr_status header_fail(ply_reader *r, cr_status st, const char *what, cr_error *err) {
    return CR_FAIL(err, st, "%s:%lld: %s", r->source, (long long)r->t.line, what);
}

static cr_status parse_type(ply_reader *r, const char *b, const char *e, ptype *out,
                            cr_error *err) {
    for (size_t i = 0; i < sizeof type_names / sizeof type_names[0]; i++)
        if (token_is(b, e, type_names[i].name)) {
            *out = type_names[i].type;
            return CR_OK;
        }
    char snip[48];
    cr_io_text_snippet(b, e, snip, sizeof snip);
    return CR_FAIL(err, CR_ERR_PARSE,
                   "%s:%lld: unknown property type '%s' (expected char, uchar, short, ushort, "
                   "int, uint, float, double or their sized names)",
                   r->source, (long long)r->t.line, snip);
}

static cr_status copy_name(ply_reader *r, const char *b, const char *e, char out[64],
                           cr_error *err) {
    if (e - b >= 64) return header_fail(r, CR_ERR_PARSE, "name longer than 63 bytes", err);
    memcpy(out, b, (size_t)(e - b));
    out[e - b] = 0;
    return CR_OK;
}

static cr_status parse_element(ply_reader *r, cr_error *err) {
    const char *b, *e;
    if (r->nelems == r->cap_elems) {
        int cap = r->cap_elems ? 2 * r->cap_elems : 8;
        ply_elem *g = realloc(r->elems, (size_t)cap * sizeof *g);
        if (!g) return CR_FAIL(err, CR_ERR_MEMORY, "%s: out of memory", r->source);
        r->elems = g, r->cap_elems = cap;
    }
    ply_elem *el = &r->elems[r->nelems];
    memset(el, 0, sizeof *el);
    r->nelems++;
    el->line = r->t.line;
    if (!cr_io_text_token(&r->t, &b, &e))
        return header_fail(r, CR_ERR_PARSE, "expected 'element <name> <count>'", err);
    CR_TRY(copy_name(r, b, e, el->name, err));
    if (!cr_io_text_token(&r->t, &b, &e))
        return header_fail(r, CR_ERR_PARSE, "expected 'element <name> <count>'", err);
    CR_TRY(cr_io_text_int(&r->t, b, e, "an element count", &el->count, err));
    if (el->count < 0) return header_fail(r, CR_ERR_RANGE, "negative element count", err);
    if (cr_io_text_token(&r->t, &b, &e))
        return header_fail(r, CR_ERR_PARSE, "expected 'element <name> <count>', got more", err);
    return CR_OK;
}

static cr_status parse_property(ply_reader *r, cr_error *err) {
    const char *b, *e;
    if (r->nelems == 0) return header_fail(r, CR_ERR_PARSE, "'property' before any 'element'", err);
    ply_elem *el = &r->elems[r->nelems - 1];
    if (el->nprops == el->cap) {
        int cap = el->cap ? 2 * el->cap : 8;
        ply_prop *g = realloc(el->props, (size_t)cap * sizeof *g);
        if (!g) return CR_FAIL(err, CR_ERR_MEMORY, "%s: out of memory", r->source);
        el->props = g, el->cap = cap;
    }
    ply_prop *p = &el->props[el->nprops];
    memset(p, 0, sizeof *p);
    p->role = R_SKIP;
    const char *usage = "expected 'property <type> <name>' or 'property list <count type> "
                        "<item type> <name>'";
    if (!cr_io_text_token(&r->t, &b, &e)) return header_fail(r, CR_ERR_PARSE, usage, err);
    if (token_is(b, e, "list")) {
        if (!cr_io_text_token(&r->t, &b, &e)) return header_fail(r, CR_ERR_PARSE, usage, err);
        CR_TRY(parse_type(r, b, e, &p->count_type, err));
        if (!is_int_type(p->count_type))
            return header_fail(r, CR_ERR_PARSE, "list count type must be an integer type", err);
        if (!cr_io_text_token(&r->t, &b, &e)) return header_fail(r, CR_ERR_PARSE, usage, err);
    }
    CR_TRY(parse_type(r, b, e, &p->type, err));
    if (!cr_io_text_token(&r->t, &b, &e)) return header_fail(r, CR_ERR_PARSE, usage, err);
    CR_TRY(copy_name(r, b, e, p->name, err));
    if (cr_io_text_token(&r->t, &b, &e)) return header_fail(r, CR_ERR_PARSE, usage, err);
    el->nprops++;
    return CR_OK;
}

static int find_prop(const ply_elem *el, const char *name) {
    for (int i = 0; i < el->nprops; i++)
        if (strcmp(el->props[i].name, name) == 0) return i;
    return -1;
}

/* Give the vertex and face properties their roles; refuse what we cannot read. */
static cr_status assign_roles(ply_reader *r, cr_error *err) {
    r->vertex_elem = r->face_elem = -1;
    for (int i = 0; i < r->nelems; i++) {
        if (strcmp(r->elems[i].name, "vertex") == 0 && r->vertex_elem < 0) r->vertex_elem = i;
        if (strcmp(r->elems[i].name, "face") == 0 && r->face_elem < 0) r->face_elem = i;
    }
    if (r->vertex_elem < 0)
        return CR_FAIL(err, CR_ERR_PARSE, "%s: header has no element 'vertex'", r->source);
    ply_elem *ve = &r->elems[r->vertex_elem];
    if (ve->count > INT32_MAX)
        return CR_FAIL(err, CR_ERR_RANGE, "%s:%lld: %lld vertices exceed 32-bit indices", r->source,
                       (long long)ve->line, (long long)ve->count);
    r->nv = ve->count;
    static const char *const xyz[6] = {"x", "y", "z", "nx", "ny", "nz"};
    int idx[6];
    for (int k = 0; k < 6; k++)
        idx[k] = find_prop(ve, xyz[k]);
    for (int k = 0; k < 3; k++)
        if (idx[k] < 0)
            return CR_FAIL(err, CR_ERR_PARSE, "%s:%lld: element 'vertex' has no property '%s'",
                           r->source, (long long)ve->line, xyz[k]);
    r->has_normal = idx[3] >= 0 && idx[4] >= 0 && idx[5] >= 0;
    static const char *const uv_names[4][2] = {
        {"s", "t"}, {"u", "v"}, {"texture_u", "texture_v"}, {"texture_s", "texture_t"}};
    int iu = -1, iv = -1;
    for (int k = 0; k < 4 && iu < 0; k++) {
        int a = find_prop(ve, uv_names[k][0]), b = find_prop(ve, uv_names[k][1]);
        if (a >= 0 && b >= 0) iu = a, iv = b;
    }
    r->has_uv = iu >= 0;
    for (int k = 0; k < 6; k++)
        if (idx[k] >= 0 && (k < 3 || r->has_normal)) ve->props[idx[k]].role = R_X + k;
    if (r->has_uv) ve->props[iu].role = R_U, ve->props[iv].role = R_V;
    for (int i = 0; i < ve->nprops; i++)
        if (ve->props[i].role != R_SKIP && ve->props[i].count_type != T_NONE)
            return CR_FAIL(err, CR_ERR_PARSE,
                           "%s:%lld: vertex property '%s' is a list, expected a "
                           "number",
                           r->source, (long long)ve->line, ve->props[i].name);
    if (r->face_elem < 0 || r->elems[r->face_elem].count == 0)
        return CR_FAIL(err, CR_ERR_TOPOLOGY, "%s:%lld: no faces (expected element 'face')",
                       r->source,
                       (long long)(r->face_elem < 0 ? r->t.line : r->elems[r->face_elem].line));
    ply_elem *fe = &r->elems[r->face_elem];
    int li = find_prop(fe, "vertex_indices");
    if (li < 0) li = find_prop(fe, "vertex_index");
    if (li < 0 || fe->props[li].count_type == T_NONE || !is_int_type(fe->props[li].type))
        return CR_FAIL(err, CR_ERR_PARSE,
                       "%s:%lld: element 'face' needs an integer list property vertex_indices "
                       "(or vertex_index)",
                       r->source, (long long)fe->line);
    fe->props[li].role = R_INDICES;
    return CR_OK;
}

/* Refuse counts the body cannot hold before allocating for them. */
static cr_status check_counts(ply_reader *r, cr_error *err) {
    size_t body = r->format == FMT_ASCII ? (size_t)(r->t.p - (const char *)r->data) : r->off;
    /* ascii: the last value of the file may lack its trailing separator */
    uint64_t avail = r->len - body + (r->format == FMT_ASCII);
    for (int i = 0; i < r->nelems; i++) {
        const ply_elem *el = &r->elems[i];
        uint64_t per = 0;
        for (int k = 0; k < el->nprops; k++) {
            const ply_prop *p = &el->props[k];
            ptype fixed = p->count_type != T_NONE ? p->count_type : p->type;
            per += r->format == FMT_ASCII ? 2 : (uint64_t)type_size[fixed];
        }
        if (per > 0 && (uint64_t)el->count > avail / per)
            return CR_FAIL(err, CR_ERR_PARSE,
                           "%s:%lld: element '%s' declares %lld items, needing at least %llu "
                           "bytes each, but only %llu bytes are left after the header",
                           r->source, (long long)el->line, el->name, (long long)el->count,
                           (unsigned long long)per, (unsigned long long)(r->len - body));
        avail -= per * (uint64_t)el->count;
    }
    return CR_OK;
}

static cr_status parse_header(ply_reader *r, cr_error *err) {
    int got;
    const char *b, *e;
    CR_TRY(cr_io_text_next_line(&r->t, &got, err));
    if (!got || !cr_io_text_token(&r->t, &b, &e) || !token_is(b, e, "ply") ||
        cr_io_text_token(&r->t, &b, &e))
        return CR_FAIL(err, CR_ERR_PARSE, "%s:1: expected 'ply' (not a PLY file)", r->source);
    int have_format = 0;
    for (;;) {
        CR_TRY(cr_io_text_next_line(&r->t, &got, err));
        if (!got)
            return CR_FAIL(err, CR_ERR_PARSE, "%s:%lld: header ends without 'end_header'",
                           r->source, (long long)r->t.line);
        if (!cr_io_text_token(&r->t, &b, &e)) continue;
        if (token_is(b, e, "comment") || token_is(b, e, "obj_info")) continue;
        if (token_is(b, e, "end_header")) break;
        if (token_is(b, e, "format")) {
            if (!cr_io_text_token(&r->t, &b, &e))
                return header_fail(r, CR_ERR_PARSE, "expected 'format <type> 1.0'", err);
            if (token_is(b, e, "ascii"))
                r->format = FMT_ASCII;
            else if (token_is(b, e, "binary_little_endian"))
                r->format = FMT_LE;
            else if (token_is(b, e, "binary_big_endian"))
                r->format = FMT_BE;
            else {
                char snip[48];
                cr_io_text_snippet(b, e, snip, sizeof snip);
                return CR_FAIL(err, CR_ERR_UNSUPPORTED,
                               "%s:%lld: unknown PLY format '%s' (expected ascii, "
                               "binary_little_endian or binary_big_endian)",
                               r->source, (long long)r->t.line, snip);
            }
            have_format = 1;
        } else if (token_is(b, e, "element")) {
            CR_TRY(parse_element(r, err));
        } else if (token_is(b, e, "property")) {
            CR_TRY(parse_property(r, err));
        } else {
            char snip[48];
            cr_io_text_snippet(b, e, snip, sizeof snip);
            return CR_FAIL(err, CR_ERR_PARSE,
                           "%s:%lld: unknown header keyword '%s' (expected format, element, "
                           "property, comment or end_header)",
                           r->source, (long long)r->t.line, snip);
        }
    }
    if (!have_format) return header_fail(r, CR_ERR_PARSE, "header has no 'format' line", err);
    r->off = (size_t)(r->t.p - (const char *)r->data);
    CR_TRY(assign_roles(r, err));
    return check_counts(r, err);
}

/* ------------------------------------------------------------------ body -- */

/* Where a value sits, for messages: "<source>:<line>: " (ascii) or
 * "<source>: byte <offset> " (binary), then the element and item. */
static void where_at(const ply_reader *r, const ply_elem *el, int64_t item, size_t off, char *out,
                     size_t cap) {
    if (r->format == FMT_ASCII)
        snprintf(out, cap, "%s:%lld: %s %lld", r->source, (long long)r->t.line, el->name,
                 (long long)item);
    else
        snprintf(out, cap, "%s: byte %zu (%s %lld)", r->source, off, el->name, (long long)item);
}

static void where(const ply_reader *r, const ply_elem *el, int64_t item, char *out, size_t cap) {
    where_at(r, el, item, r->off, out, cap);
}

static const int64_t int_lo[] = {0, INT8_MIN, 0, INT16_MIN, 0, INT32_MIN, 0};
static const int64_t int_hi[] = {0,          INT8_MAX,  UINT8_MAX, INT16_MAX,
                                 UINT16_MAX, INT32_MAX, UINT32_MAX};

/* One value of type `type` as a double (integers up to 32 bits are exact); 0 on failure. */
static cr_status read_value(ply_reader *r, const ply_elem *el, int64_t item, ptype type,
                            const char *what, double *out, cr_error *err) {
    char at[160];
    *out = 0;
    if (r->format == FMT_ASCII) {
        const char *b, *e;
        int got;
        CR_TRY(cr_io_text_token_any(&r->t, &b, &e, &got, err));
        if (!got) {
            where(r, el, item, at, sizeof at);
            return CR_FAIL(err, CR_ERR_PARSE, "%s: file ends here, expected %s", at, what);
        }
        if (!is_int_type(type)) return cr_io_text_double(&r->t, b, e, what, out, err);
        int64_t v;
        CR_TRY(cr_io_text_int(&r->t, b, e, what, &v, err));
        if (v < int_lo[type] || v > int_hi[type]) {
            where(r, el, item, at, sizeof at);
            return CR_FAIL(err, CR_ERR_RANGE, "%s: %s %lld does not fit its declared type", at,
                           what, (long long)v);
        }
        *out = (double)v;
        return CR_OK;
    }
    int size = type_size[type];
    if (r->len - r->off < (size_t)size) {
        where(r, el, item, at, sizeof at);
        return CR_FAIL(err, CR_ERR_PARSE, "%s: file ends, expected %d more bytes for %s", at, size,
                       what);
    }
    uint64_t u = io_load(r->data + r->off, size, r->format == FMT_BE);
    switch (type) {
    case T_I8:
        *out = (double)(int8_t)u;
        break;
    case T_I16:
        *out = (double)(int16_t)u;
        break;
    case T_I32:
        *out = (double)(int32_t)u;
        break;
    case T_F32:
        *out = (double)io_f32((uint32_t)u);
        break;
    case T_F64:
        *out = io_f64(u);
        break;
    default:
        *out = (double)u;
        break;
    }
    r->off += (size_t)size;
    return CR_OK;
}

static cr_status read_list_count(ply_reader *r, const ply_elem *el, int64_t item, const ply_prop *p,
                                 int64_t *n, cr_error *err) {
    *n = 0;
    double v;
    CR_TRY(read_value(r, el, item, p->count_type, "a list length", &v, err));
    if (v < 0) {
        char at[160];
        where(r, el, item, at, sizeof at);
        return CR_FAIL(err, CR_ERR_RANGE, "%s: negative list length %.0f", at, v);
    }
    *n = (int64_t)v;
    return CR_OK;
}

static cr_status store_vertex_value(ply_reader *r, const ply_elem *el, int64_t i, const ply_prop *p,
                                    double v, cr_error *err) {
    int role = p->role;
    /* Binary values arrive unchecked; ascii ones were refused if not finite. */
    if (!isfinite(v) || fabs(v) > FLT_MAX) {
        char at[160];
        where_at(r, el, i, r->off - (size_t)type_size[p->type], at, sizeof at);
        return CR_FAIL(err, CR_ERR_NAN, "%s: %s = %g, expected a finite float", at, p->name, v);
    }
    if (role <= R_Z)
        r->pos[3 * i + role] = (float)v;
    else if (role <= R_NZ)
        r->normal[3 * i + role - R_NX] = (float)v;
    else
        r->uv[2 * i + role - R_U] = (float)v;
    return CR_OK;
}

static cr_status read_face(ply_reader *r, const ply_elem *el, int64_t i, const ply_prop *p,
                           cr_error *err) {
    char at[160];
    int64_t n;
    CR_TRY(read_list_count(r, el, i, p, &n, err));
    if (n < 3) {
        where(r, el, i, at, sizeof at);
        return CR_FAIL(err, CR_ERR_PARSE, "%s: face has %lld vertices, expected at least 3", at,
                       (long long)n);
    }
    int64_t first = 0, prev = 0;
    for (int64_t k = 0; k < n; k++) {
        double v;
        CR_TRY(read_value(r, el, i, p->type, "a vertex index", &v, err));
        if (v < 0 || v >= (double)r->nv) {
            where(r, el, i, at, sizeof at);
            return CR_FAIL(err, CR_ERR_RANGE,
                           "%s: vertex index %.0f is out of range (the file has %lld vertices)", at,
                           v, (long long)r->nv);
        }
        int64_t idx = (int64_t)v;
        if (k == 0) first = idx;
        if (k >= 2) {
            /* fan triangulation (0, k-1, k) keeps the polygon's winding */
            if (r->ntri >= INT32_MAX)
                return CR_FAIL(err, CR_ERR_RANGE, "%s: more than %d triangles", r->source,
                               INT32_MAX);
            if (r->ntri == r->cap_tri) {
                int64_t cap = r->cap_tri ? 2 * r->cap_tri : 1024;
                int32_t *g = realloc(r->tri, (size_t)cap * 3 * sizeof(int32_t));
                if (!g) return CR_FAIL(err, CR_ERR_MEMORY, "%s: out of memory", r->source);
                r->tri = g, r->cap_tri = cap;
            }
            int32_t *t = &r->tri[3 * r->ntri++];
            t[0] = (int32_t)first, t[1] = (int32_t)prev, t[2] = (int32_t)idx;
        }
        prev = idx;
    }
    return CR_OK;
}

static cr_status read_body(ply_reader *r, cr_error *err) {
    for (int ei = 0; ei < r->nelems; ei++) {
        const ply_elem *el = &r->elems[ei];
        if (el->nprops == 0) continue;
        int is_vertex = ei == r->vertex_elem, is_face = ei == r->face_elem;
        for (int64_t i = 0; i < el->count; i++) {
            for (int k = 0; k < el->nprops; k++) {
                const ply_prop *p = &el->props[k];
                double v;
                if (is_face && p->role == R_INDICES) {
                    CR_TRY(read_face(r, el, i, p, err));
                } else if (p->count_type != T_NONE) {
                    int64_t n;
                    CR_TRY(read_list_count(r, el, i, p, &n, err));
                    for (int64_t j = 0; j < n; j++)
                        CR_TRY(read_value(r, el, i, p->type, "a list item", &v, err));
                } else {
                    CR_TRY(read_value(r, el, i, p->type, p->name, &v, err));
                    if (is_vertex && p->role != R_SKIP)
                        CR_TRY(store_vertex_value(r, el, i, p, v, err));
                }
            }
        }
    }
    if (r->format == FMT_ASCII) {
        const char *b, *e;
        int got;
        CR_TRY(cr_io_text_token_any(&r->t, &b, &e, &got, err));
        if (got)
            return CR_FAIL(err, CR_ERR_PARSE,
                           "%s:%lld: data after the last element (the header declares fewer "
                           "items)",
                           r->source, (long long)r->t.line);
    } else if (r->off != r->len) {
        return CR_FAIL(err, CR_ERR_PARSE,
                       "%s: byte %zu: %zu bytes after the last element (the header declares "
                       "fewer items)",
                       r->source, r->off, r->len - r->off);
    }
    return CR_OK;
}

static void reader_free(ply_reader *r) {
    for (int i = 0; i < r->nelems; i++)
        free(r->elems[i].props);
    free(r->elems);
    free(r->pos), free(r->normal), free(r->uv), free(r->tri);
}

/* Hand the arrays to a mesh: per-vertex UVs become per-corner through tri_uv = tri. */
static cr_status build_mesh(ply_reader *r, cr_mesh **out, cr_error *err) {
    cr_mesh *m;
    CR_TRY(cr_mesh_create(0, 0, 0, &m, err));
    free(m->pos), free(m->tri);
    m->nv = (int32_t)r->nv, m->nf = (int32_t)r->ntri;
    m->pos = r->pos, m->tri = r->tri, m->normal = r->normal;
    r->pos = r->normal = NULL, r->tri = NULL;
    if (r->has_uv) {
        m->nuv = m->nv;
        m->uv = r->uv;
        r->uv = NULL;
        m->tri_uv = cr_malloc((size_t)m->nf * 3 * sizeof(int32_t), err);
        if (!m->tri_uv) {
            cr_mesh_destroy(m);
            return CR_ERR_MEMORY;
        }
        memcpy(m->tri_uv, m->tri, (size_t)m->nf * 3 * sizeof(int32_t));
    }
    cr_status st = cr_mesh_validate(m, r->source, err);
    if (st == CR_OK && r->has_uv) st = cr_mesh_weld(m, err);
    if (st != CR_OK) {
        cr_mesh_destroy(m);
        return st;
    }
    *out = m;
    return CR_OK;
}

cr_status cr_ply_read_mem(const void *data, size_t len, const char *source, cr_mesh **out,
                          cr_error *err) {
    *out = NULL;
    ply_reader r;
    memset(&r, 0, sizeof r);
    r.data = data, r.len = len, r.source = source;
    cr_io_text_init(&r.t, data, len, source);
    cr_status st = parse_header(&r, err);
    if (st == CR_OK) {
        size_t nv = (size_t)r.nv;
        r.pos = cr_malloc(nv * 3 * sizeof(float), err);
        if (r.has_normal) r.normal = cr_malloc(nv * 3 * sizeof(float), err);
        if (r.has_uv) r.uv = cr_malloc(nv * 2 * sizeof(float), err);
        if (!r.pos || (r.has_normal && !r.normal) || (r.has_uv && !r.uv)) st = CR_ERR_MEMORY;
    }
    if (st == CR_OK) st = read_body(&r, err);
    if (st == CR_OK) st = build_mesh(&r, out, err);
    reader_free(&r);
    return st;
}

cr_status cr_ply_read(const char *path, cr_mesh **out, cr_error *err) {
    *out = NULL;
    char *buf;
    size_t len;
    CR_TRY(cr_file_read_all(path, &buf, &len, err));
    cr_status st = cr_ply_read_mem(buf, len, path, out, err);
    free(buf);
    return st;
}

/* ---------------------------------------------------------------- writer -- */

static void write_header(FILE *fp, const cr_mesh *m, const cr_mesh_seams *s, int ascii) {
    fprintf(fp, "ply\nformat %s 1.0\ncomment crease\n", ascii ? "ascii" : "binary_little_endian");
    fprintf(fp, "element vertex %d\nproperty float x\nproperty float y\nproperty float z\n", s->nv);
    if (m->normal) fprintf(fp, "property float nx\nproperty float ny\nproperty float nz\n");
    if (s->uv) fprintf(fp, "property float s\nproperty float t\n");
    fprintf(fp, "element face %d\nproperty list uchar int vertex_indices\nend_header\n", m->nf);
}

cr_status cr_ply_write(const char *path, const cr_mesh *m, cr_ply_format format, cr_error *err) {
    CR_TRY(cr_mesh_validate(m, path, err));
    if (m->nf == 0) return CR_FAIL(err, CR_ERR_TOPOLOGY, "%s: mesh has no faces", path);
    if (format != CR_PLY_BINARY && format != CR_PLY_ASCII)
        return CR_FAIL(err, CR_ERR_INVALID, "%s: unknown PLY format %d", path, (int)format);
    cr_mesh_seams s;
    CR_TRY(cr_mesh_split_seams(m, &s, err));
    cr_atomic_file f;
    cr_status st = cr_atomic_open(&f, path, err);
    if (st != CR_OK) {
        cr_mesh_seams_free(&s);
        return st;
    }
    FILE *fp = f.fp;
    int ascii = format == CR_PLY_ASCII;
    write_header(fp, m, &s, ascii);
    int ok = 1;
    for (int64_t i = 0; i < s.nv && ok; i++) {
        float row[8];
        int n = 0;
        int64_t v = s.src[i];
        for (int k = 0; k < 3; k++)
            row[n++] = m->pos[3 * v + k];
        for (int k = 0; m->normal && k < 3; k++)
            row[n++] = m->normal[3 * v + k];
        for (int k = 0; s.uv && k < 2; k++)
            row[n++] = s.uv[2 * i + k];
        if (ascii) {
            for (int k = 0; k < n; k++)
                fprintf(fp, k ? " %.9g" : "%.9g", row[k]);
            ok = fputc('\n', fp) != EOF;
        } else {
            ok = cr_io_write_f32le(fp, row, (size_t)n);
        }
    }
    for (int64_t i = 0; i < m->nf && ok; i++) {
        const int32_t *t = &s.tri[3 * i];
        if (ascii) {
            ok = fprintf(fp, "3 %d %d %d\n", t[0], t[1], t[2]) > 0;
        } else {
            unsigned char three = 3;
            ok = fwrite(&three, 1, 1, fp) == 1 && cr_io_write_i32le(fp, t, 3);
        }
    }
    cr_mesh_seams_free(&s);
    if (!ok) {
        cr_atomic_abort(&f);
        return CR_FAIL(err, CR_ERR_IO, "%s: write failed", path);
    }
    return cr_atomic_commit(&f, err);
}
