/* io_glb.c: glTF 2.0 binary (.glb) reader and writer, static and animated.
 *
 * Reader: the subset crease writes and most exporters produce for one
 * object: a single mesh with a single triangle primitive; POSITION (float
 * VEC3), optional NORMAL (float VEC3), TEXCOORD_0 (float, or normalised
 * unsigned byte/short, VEC2) and _CREASE_UV (float VEC2, see below); indices
 * of unsigned byte, short or int, or none. Every accessor is checked against
 * its buffer view, every view against the buffer, the buffer against the BIN
 * chunk and the chunks against the file, in 64-bit arithmetic, before any
 * element is read. Node transforms, skins, sparse accessors, external
 * buffers and multi-mesh files are not read (the last three are refused
 * rather than misread); morph targets only by cr_glb_read_sequence, which
 * adds each target's POSITION to the base and maps the file's seam copies
 * onto the welded vertices (the weld's own first-appearance order, rebuilt
 * with a hash of the position bits).
 *
 * Writer: POSITION with min/max, NORMAL when present, TEXCOORD_0 and
 * _CREASE_UV when the mesh has UVs, u32 indices, vertices split at UV seams.
 * glTF's UV origin is the top left (v down) where OBJ's is the bottom left,
 * so TEXCOORD_0 holds (u, 1 - v). That flip is not invertible in float for
 * v < 0.5, so the exact crease UVs go along as the application-specific
 * attribute _CREASE_UV; the reader takes them only when flipping them gives
 * TEXCOORD_0 bit for bit, i.e. when no other tool has edited the UVs.
 *
 * Sequences: one morph target per frame holding the displacement from the
 * base positions (plus normal displacements when the base has normals), and
 * an animation whose weights channel is one-hot at t = i / fps, LINEAR, so
 * the player reproduces each frame exactly at its time. Targets are streamed
 * to the file frame by frame; only their min/max are computed beforehand.
 *
 * Reference: The Khronos glTF 2.0 Specification (registry.khronos.org/glTF),
 * sections 3.6 (buffers, accessors), 3.7.2.2 (morph targets), 3.11
 * (animations), 4.4 (GLB container).
 */
#include "crease/diffgeo.h"
#include "crease/mesh_io.h"
#include "geom/glb_internal.h"
#include "geom/io_text.h"

#include <cjson/cJSON.h>
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

const cJSON *cr_glb_json_at(const cJSON *arr, uint64_t i) {
    return cJSON_IsArray(arr) && i < (uint64_t)cJSON_GetArraySize(arr)
               ? cJSON_GetArrayItem(arr, (int)i)
               : NULL;
}

/* obj[key] as an integer in [0, max]; `dflt` when absent and not `required`.
 * *out is 0 on failure, so no caller ever holds an unset value. */
cr_status cr_glb_json_uint(const glb_in *g, const cJSON *obj, const char *where, const char *key,
                           int required, uint64_t dflt, uint64_t max, uint64_t *out,
                           cr_error *err) {
    *out = 0;
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(obj, key);
    if (!v && !required) {
        *out = dflt;
        return CR_OK;
    }
    if (!cJSON_IsNumber(v) || v->valuedouble < 0 || v->valuedouble > (double)max ||
        v->valuedouble != floor(v->valuedouble))
        return CR_FAIL(err, CR_ERR_PARSE, "%s: %s.%s: expected an integer in [0, %llu]", g->source,
                       where, key, (unsigned long long)max);
    *out = (uint64_t)v->valuedouble;
    return CR_OK;
}

static int type_components(const char *type) {
    static const struct {
        const char *name;
        int n;
    } types[] = {{"SCALAR", 1}, {"VEC2", 2}, {"VEC3", 3}, {"VEC4", 4},
                 {"MAT2", 4},   {"MAT3", 9}, {"MAT4", 16}};
    for (size_t i = 0; type && i < sizeof types / sizeof types[0]; i++)
        if (strcmp(type, types[i].name) == 0) return types[i].n;
    return 0;
}

static int ctype_size(int ctype) {
    switch (ctype) {
    case CT_I8:
    case CT_U8:
        return 1;
    case CT_I16:
    case CT_U16:
        return 2;
    case CT_U32:
    case CT_F32:
        return 4;
    default:
        return 0;
    }
}

cr_status cr_glb_accessor(const glb_in *g, uint64_t index, glb_acc *out, cr_error *err) {
    char where[64], vwhere[64];
    snprintf(where, sizeof where, "accessors[%llu]", (unsigned long long)index);
    const cJSON *acc =
        cr_glb_json_at(cJSON_GetObjectItemCaseSensitive(g->root, "accessors"), index);
    if (!cJSON_IsObject(acc))
        return CR_FAIL(err, CR_ERR_RANGE, "%s: %s does not exist", g->source, where);
    if (cJSON_GetObjectItemCaseSensitive(acc, "sparse"))
        return CR_FAIL(err, CR_ERR_UNSUPPORTED, "%s: %s is sparse (not supported)", g->source,
                       where);
    uint64_t view_i, off, count, ctype;
    if (!cJSON_GetObjectItemCaseSensitive(acc, "bufferView"))
        return CR_FAIL(err, CR_ERR_UNSUPPORTED, "%s: %s has no bufferView (not supported)",
                       g->source, where);
    CR_TRY(cr_glb_json_uint(g, acc, where, "bufferView", 1, 0, INT32_MAX, &view_i, err));
    CR_TRY(cr_glb_json_uint(g, acc, where, "byteOffset", 0, 0, UINT32_MAX, &off, err));
    CR_TRY(cr_glb_json_uint(g, acc, where, "count", 1, 0, UINT32_MAX, &count, err));
    CR_TRY(cr_glb_json_uint(g, acc, where, "componentType", 1, 0, 65535, &ctype, err));
    const cJSON *type = cJSON_GetObjectItemCaseSensitive(acc, "type");
    int ncomp = type_components(cJSON_GetStringValue(type));
    int csize = ctype_size((int)ctype);
    if (!ncomp || !csize || count == 0)
        return CR_FAIL(err, CR_ERR_PARSE,
                       "%s: %s: expected a known type and componentType and count >= 1", g->source,
                       where);
    snprintf(vwhere, sizeof vwhere, "bufferViews[%llu]", (unsigned long long)view_i);
    const cJSON *view =
        cr_glb_json_at(cJSON_GetObjectItemCaseSensitive(g->root, "bufferViews"), view_i);
    if (!cJSON_IsObject(view))
        return CR_FAIL(err, CR_ERR_RANGE, "%s: %s refers to %s, which does not exist", g->source,
                       where, vwhere);
    uint64_t buf, voff, vlen, vstride;
    CR_TRY(cr_glb_json_uint(g, view, vwhere, "buffer", 1, 0, INT32_MAX, &buf, err));
    CR_TRY(cr_glb_json_uint(g, view, vwhere, "byteOffset", 0, 0, UINT32_MAX, &voff, err));
    CR_TRY(cr_glb_json_uint(g, view, vwhere, "byteLength", 1, 0, UINT32_MAX, &vlen, err));
    CR_TRY(cr_glb_json_uint(g, view, vwhere, "byteStride", 0, 0, 252, &vstride, err));
    if (buf != 0 || !g->bin)
        return CR_FAIL(err, CR_ERR_UNSUPPORTED,
                       "%s: %s: expected buffer 0 stored in the GLB BIN chunk", g->source, vwhere);
    if (voff + vlen > g->buf_len)
        return CR_FAIL(err, CR_ERR_RANGE,
                       "%s: %s: bytes [%llu, %llu) lie outside the %llu-byte buffer", g->source,
                       vwhere, (unsigned long long)voff, (unsigned long long)(voff + vlen),
                       (unsigned long long)g->buf_len);
    uint64_t elem = (uint64_t)csize * (uint64_t)ncomp;
    uint64_t stride = vstride ? vstride : elem;
    if (stride < elem)
        return CR_FAIL(err, CR_ERR_PARSE,
                       "%s: %s: byteStride %llu is smaller than an element "
                       "(%llu bytes)",
                       g->source, vwhere, (unsigned long long)stride, (unsigned long long)elem);
    uint64_t last = off + stride * (count - 1) + elem; /* < 2^41: no overflow */
    if (last > vlen)
        return CR_FAIL(err, CR_ERR_RANGE,
                       "%s: %s: %llu elements from byte %llu need %llu bytes, but %s holds %llu",
                       g->source, where, (unsigned long long)count, (unsigned long long)off,
                       (unsigned long long)last, vwhere, (unsigned long long)vlen);
    out->count = (int64_t)count;
    out->ctype = (int)ctype;
    out->ncomp = ncomp;
    out->base = g->bin + voff + off;
    out->stride = stride;
    return CR_OK;
}

/* The attribute accessor `name` of the primitive, or found = 0. */
static cr_status get_attribute(const glb_in *g, const cJSON *attrs, const char *name, glb_acc *out,
                               int *found, cr_error *err) {
    *found = 0;
    if (!cJSON_GetObjectItemCaseSensitive(attrs, name)) return CR_OK;
    char where[64];
    snprintf(where, sizeof where, "meshes[0].primitives[0].attributes");
    uint64_t i;
    CR_TRY(cr_glb_json_uint(g, attrs, where, name, 1, 0, INT32_MAX, &i, err));
    CR_TRY(cr_glb_accessor(g, i, out, err));
    *found = 1;
    return CR_OK;
}

static cr_status expect_float(const glb_in *g, const glb_acc *a, const char *name, int ncomp,
                              int64_t count, cr_error *err) {
    if (a->ctype != CT_F32 || a->ncomp != ncomp)
        return CR_FAIL(err, CR_ERR_UNSUPPORTED, "%s: %s: expected float VEC%d", g->source, name,
                       ncomp);
    if (count >= 0 && a->count != count)
        return CR_FAIL(err, CR_ERR_PARSE, "%s: %s has %lld elements, POSITION has %lld", g->source,
                       name, (long long)a->count, (long long)count);
    return CR_OK;
}

/* Float components of a float accessor into out (count, ncomp), refusing non-finite. */
cr_status cr_glb_read_floats(const glb_in *g, const glb_acc *a, const char *name, float *out,
                             cr_error *err) {
    for (int64_t i = 0; i < a->count; i++)
        for (int k = 0; k < a->ncomp; k++) {
            float x = io_f32(io_le32(a->base + (uint64_t)i * a->stride + 4 * (uint64_t)k));
            if (!isfinite(x))
                return CR_FAIL(err, CR_ERR_NAN, "%s: %s element %lld is not finite", g->source,
                               name, (long long)i);
            out[i * a->ncomp + k] = x;
        }
    return CR_OK;
}

static cr_status read_texcoord(const glb_in *g, const glb_acc *a, int64_t nv, float *uv,
                               cr_error *err) {
    if (a->ncomp != 2 || !(a->ctype == CT_F32 || a->ctype == CT_U8 || a->ctype == CT_U16))
        return CR_FAIL(err, CR_ERR_UNSUPPORTED,
                       "%s: TEXCOORD_0: expected VEC2 of float or normalised unsigned byte/short",
                       g->source);
    if (a->count != nv)
        return CR_FAIL(err, CR_ERR_PARSE, "%s: TEXCOORD_0 has %lld elements, POSITION has %lld",
                       g->source, (long long)a->count, (long long)nv);
    if (a->ctype == CT_F32) return cr_glb_read_floats(g, a, "TEXCOORD_0", uv, err);
    int size = ctype_size(a->ctype);
    double scale = a->ctype == CT_U8 ? 255.0 : 65535.0;
    for (int64_t i = 0; i < nv; i++)
        for (int k = 0; k < 2; k++)
            uv[2 * i + k] =
                (float)(io_load(a->base + (uint64_t)i * a->stride + (uint64_t)(k * size), size, 0) /
                        scale);
    return CR_OK;
}

static cr_status read_indices(const glb_in *g, const cJSON *prim, int64_t nv, int32_t **tri,
                              int64_t *ntri, cr_error *err) {
    int64_t n;
    glb_acc a = {0};
    int indexed = cJSON_GetObjectItemCaseSensitive(prim, "indices") != NULL;
    if (indexed) {
        uint64_t i;
        CR_TRY(cr_glb_json_uint(g, prim, "meshes[0].primitives[0]", "indices", 1, 0, INT32_MAX, &i,
                                err));
        CR_TRY(cr_glb_accessor(g, i, &a, err));
        if (a.ncomp != 1 || !(a.ctype == CT_U8 || a.ctype == CT_U16 || a.ctype == CT_U32))
            return CR_FAIL(err, CR_ERR_PARSE,
                           "%s: indices: expected SCALAR unsigned byte, short or int", g->source);
        n = a.count;
    } else {
        n = nv;
    }
    if (n % 3 != 0)
        return CR_FAIL(err, CR_ERR_PARSE, "%s: %s: %lld indices, expected a multiple of 3",
                       g->source, indexed ? "indices" : "POSITION", (long long)n);
    if (n / 3 > INT32_MAX)
        return CR_FAIL(err, CR_ERR_RANGE, "%s: more than %d triangles", g->source, INT32_MAX);
    *tri = cr_malloc((size_t)n * sizeof(int32_t), err);
    if (!*tri) return CR_ERR_MEMORY;
    int size = indexed ? ctype_size(a.ctype) : 0;
    for (int64_t c = 0; c < n; c++) {
        uint64_t v = indexed ? io_load(a.base + (uint64_t)c * a.stride, size, 0) : (uint64_t)c;
        if (v >= (uint64_t)nv) {
            free(*tri);
            *tri = NULL;
            return CR_FAIL(err, CR_ERR_RANGE,
                           "%s: indices element %lld is %llu, but POSITION has %lld vertices",
                           g->source, (long long)c, (unsigned long long)v, (long long)nv);
        }
        (*tri)[c] = (int32_t)v;
    }
    *ntri = n / 3;
    return CR_OK;
}

/* UVs in crease's convention: the exact copy from _CREASE_UV when flipping
 * it gives TEXCOORD_0 bit for bit everywhere, else TEXCOORD_0 flipped back. */
static void unflip_uvs(float *uv, const float *exact, int64_t nv) {
    int agree = exact != NULL;
    for (int64_t i = 0; agree && i < nv; i++)
        agree = io_f32_bits(exact[2 * i]) == io_f32_bits(uv[2 * i]) &&
                io_f32_bits((float)(1.0 - (double)exact[2 * i + 1])) == io_f32_bits(uv[2 * i + 1]);
    if (agree) {
        memcpy(uv, exact, (size_t)nv * 2 * sizeof(float));
        return;
    }
    for (int64_t i = 0; i < nv; i++)
        uv[2 * i + 1] = (float)(1.0 - (double)uv[2 * i + 1]);
}

/* Split the container into the parsed JSON and the BIN chunk. */
cr_status cr_glb_open_container(glb_in *g, const unsigned char *d, size_t len, cr_error *err) {
    if (len < 20)
        return CR_FAIL(err, CR_ERR_PARSE,
                       "%s: %zu bytes, expected a 12-byte GLB header and a "
                       "JSON chunk",
                       g->source, len);
    if (io_le32(d) != GLB_MAGIC)
        return CR_FAIL(err, CR_ERR_PARSE, "%s: byte 0: expected magic 'glTF' (not a glb file)",
                       g->source);
    if (io_le32(d + 4) != 2)
        return CR_FAIL(err, CR_ERR_UNSUPPORTED, "%s: byte 4: glb version %u, expected 2", g->source,
                       io_le32(d + 4));
    if (io_le32(d + 8) != len)
        return CR_FAIL(err, CR_ERR_PARSE, "%s: byte 8: header says %u bytes, the file has %zu",
                       g->source, io_le32(d + 8), len);
    uint64_t jlen = io_le32(d + 12);
    if (io_le32(d + 16) != GLB_CHUNK_JSON || 20 + jlen > len)
        return CR_FAIL(err, CR_ERR_PARSE,
                       "%s: byte 12: expected a JSON chunk of at most %zu bytes, got type 0x%08x "
                       "length %llu",
                       g->source, len - 20, io_le32(d + 16), (unsigned long long)jlen);
    const char *json = (const char *)d + 20, *end = NULL;
    g->root = cJSON_ParseWithLengthOpts(json, (size_t)jlen, &end, 0);
    if (!g->root)
        return CR_FAIL(err, CR_ERR_PARSE, "%s: byte %lld: expected valid JSON in the JSON chunk",
                       g->source, (long long)(20 + (end && end >= json ? end - json : 0)));
    uint64_t at = 20 + jlen;
    if (at + 8 <= len) {
        uint64_t blen = io_le32(d + at);
        if (io_le32(d + at + 4) != GLB_CHUNK_BIN || at + 8 + blen > len)
            return CR_FAIL(err, CR_ERR_PARSE,
                           "%s: byte %llu: expected a BIN chunk of at most %llu bytes", g->source,
                           (unsigned long long)at, (unsigned long long)(len - at - 8));
        g->bin = d + at + 8;
        g->bin_len = blen;
    }
    const cJSON *buffer = cr_glb_json_at(cJSON_GetObjectItemCaseSensitive(g->root, "buffers"), 0);
    if (buffer) {
        if (cJSON_GetObjectItemCaseSensitive(buffer, "uri"))
            return CR_FAIL(err, CR_ERR_UNSUPPORTED,
                           "%s: buffers[0] is external (uri); expected "
                           "the GLB BIN chunk",
                           g->source);
        CR_TRY(cr_glb_json_uint(g, buffer, "buffers[0]", "byteLength", 1, 0, g->bin_len,
                                &g->buf_len, err));
    }
    return CR_OK;
}

/* The one primitive: meshes[0].primitives[0], refusing what we would misread. */
static cr_status get_primitive(const glb_in *g, const cJSON **out, cr_error *err) {
    const cJSON *asset = cJSON_GetObjectItemCaseSensitive(g->root, "asset");
    const char *version = cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(asset, "version"));
    if (!version || strncmp(version, "2.", 2) != 0)
        return CR_FAIL(err, CR_ERR_UNSUPPORTED, "%s: asset.version: expected \"2.x\"", g->source);
    const cJSON *meshes = cJSON_GetObjectItemCaseSensitive(g->root, "meshes");
    if (!cJSON_IsArray(meshes) || cJSON_GetArraySize(meshes) != 1)
        return CR_FAIL(err, CR_ERR_UNSUPPORTED, "%s: meshes: expected exactly one mesh, got %d",
                       g->source, cJSON_IsArray(meshes) ? cJSON_GetArraySize(meshes) : 0);
    const cJSON *prims = cJSON_GetObjectItemCaseSensitive(cr_glb_json_at(meshes, 0), "primitives");
    if (!cJSON_IsArray(prims) || cJSON_GetArraySize(prims) != 1)
        return CR_FAIL(err, CR_ERR_UNSUPPORTED,
                       "%s: meshes[0].primitives: expected exactly one primitive", g->source);
    const cJSON *prim = cr_glb_json_at(prims, 0);
    uint64_t mode;
    CR_TRY(cr_glb_json_uint(g, prim, "meshes[0].primitives[0]", "mode", 0, MODE_TRIANGLES, 6, &mode,
                            err));
    if (mode != MODE_TRIANGLES)
        return CR_FAIL(err, CR_ERR_UNSUPPORTED,
                       "%s: meshes[0].primitives[0].mode is %llu, expected 4 (triangles)",
                       g->source, (unsigned long long)mode);
    *out = prim;
    return CR_OK;
}

static cr_status read_mesh(const glb_in *g, cr_mesh **out, cr_error *err) {
    const cJSON *prim = NULL;
    CR_TRY(get_primitive(g, &prim, err));
    const cJSON *attrs = cJSON_GetObjectItemCaseSensitive(prim, "attributes");
    glb_acc pa, na, ta, xa;
    int has_p, has_n, has_t, has_x;
    CR_TRY(get_attribute(g, attrs, "POSITION", &pa, &has_p, err));
    if (!has_p)
        return CR_FAIL(err, CR_ERR_PARSE, "%s: meshes[0].primitives[0] has no POSITION", g->source);
    CR_TRY(expect_float(g, &pa, "POSITION", 3, -1, err));
    if (pa.count > INT32_MAX)
        return CR_FAIL(err, CR_ERR_RANGE, "%s: POSITION: %lld vertices exceed 32-bit indices",
                       g->source, (long long)pa.count);
    int64_t nv = pa.count;
    CR_TRY(get_attribute(g, attrs, "NORMAL", &na, &has_n, err));
    if (has_n) CR_TRY(expect_float(g, &na, "NORMAL", 3, nv, err));
    CR_TRY(get_attribute(g, attrs, "TEXCOORD_0", &ta, &has_t, err));
    CR_TRY(get_attribute(g, attrs, "_CREASE_UV", &xa, &has_x, err));
    if (has_t && has_x) CR_TRY(expect_float(g, &xa, "_CREASE_UV", 2, nv, err));

    int32_t *tri = NULL;
    int64_t ntri = 0;
    CR_TRY(read_indices(g, prim, nv, &tri, &ntri, err));
    cr_mesh *m;
    cr_status st = cr_mesh_create((int32_t)nv, 0, has_t ? (int32_t)nv : 0, &m, err);
    if (st != CR_OK) {
        free(tri);
        return st;
    }
    free(m->tri);
    m->tri = tri;
    m->nf = (int32_t)ntri;
    if (has_t) {
        free(m->tri_uv);
        m->tri_uv = cr_malloc((size_t)ntri * 3 * sizeof(int32_t), err);
        if (!m->tri_uv)
            st = CR_ERR_MEMORY;
        else
            memcpy(m->tri_uv, tri, (size_t)ntri * 3 * sizeof(int32_t));
    }
    if (st == CR_OK) st = cr_glb_read_floats(g, &pa, "POSITION", m->pos, err);
    if (st == CR_OK && has_n) {
        m->normal = cr_malloc((size_t)nv * 3 * sizeof(float), err);
        st = m->normal ? cr_glb_read_floats(g, &na, "NORMAL", m->normal, err) : CR_ERR_MEMORY;
    }
    if (st == CR_OK && has_t) st = read_texcoord(g, &ta, nv, m->uv, err);
    if (st == CR_OK && has_t) {
        float *exact = has_x ? cr_malloc((size_t)nv * 2 * sizeof(float), err) : NULL;
        if (has_x && !exact) st = CR_ERR_MEMORY;
        if (st == CR_OK && has_x) st = cr_glb_read_floats(g, &xa, "_CREASE_UV", exact, err);
        if (st == CR_OK) unflip_uvs(m->uv, exact, nv);
        free(exact);
    }
    if (st == CR_OK) st = cr_mesh_validate(m, g->source, err);
    if (st == CR_OK && has_t) st = cr_mesh_weld(m, err);
    if (st != CR_OK) {
        cr_mesh_destroy(m);
        return st;
    }
    *out = m;
    return CR_OK;
}

cr_status cr_glb_read_mem(const void *data, size_t len, const char *source, cr_mesh **out,
                          cr_error *err) {
    *out = NULL;
    glb_in g = {.source = source};
    cr_status st = cr_glb_open_container(&g, data, len, err);
    if (st == CR_OK) st = read_mesh(&g, out, err);
    cJSON_Delete(g.root);
    return st;
}

cr_status cr_glb_read(const char *path, cr_mesh **out, cr_error *err) {
    *out = NULL;
    char *buf;
    size_t len;
    CR_TRY(cr_file_read_all(path, &buf, &len, err));
    cr_status st = cr_glb_read_mem(buf, len, path, out, err);
    free(buf);
    return st;
}

/* ================================================================ writer == */

cJSON *cr_glb_add(glb_out *g, cJSON *parent, const char *key, cJSON *item) {
    int ok = item &&
             (key ? cJSON_AddItemToObject(parent, key, item) : cJSON_AddItemToArray(parent, item));
    if (!ok) {
        cJSON_Delete(item);
        g->oom = 1;
        return NULL;
    }
    return item;
}

void cr_glb_add_num(glb_out *g, cJSON *obj, const char *key, double v) {
    cr_glb_add(g, obj, key, cJSON_CreateNumber(v));
}

/* A float as a JSON number that parses back to exactly this float's double
 * value: validators compare accessor min/max with the data that way, and
 * cJSON's own printing accepts 15 digits that only come close. */
cJSON *cr_glb_float_array(const float *x, int n) {
    cJSON *arr = cJSON_CreateArray();
    for (int i = 0; arr && i < n; i++) {
        char buf[32];
        snprintf(buf, sizeof buf, "%.9g", x[i]);
        if (strtod(buf, NULL) != (double)x[i]) snprintf(buf, sizeof buf, "%.17g", x[i]);
        if (!cJSON_AddItemToArray(arr, cJSON_CreateRaw(buf))) {
            cJSON_Delete(arr);
            return NULL;
        }
    }
    return arr;
}

void cr_glb_add_minmax(glb_out *g, cJSON *acc, const float *x, int64_t n, int ncomp) {
    float lo[16], hi[16];
    for (int k = 0; k < ncomp; k++)
        lo[k] = hi[k] = x[k];
    for (int64_t i = 1; i < n; i++)
        for (int k = 0; k < ncomp; k++) {
            lo[k] = fminf(lo[k], x[i * ncomp + k]);
            hi[k] = fmaxf(hi[k], x[i * ncomp + k]);
        }
    cr_glb_add(g, acc, "min", cr_glb_float_array(lo, ncomp));
    cr_glb_add(g, acc, "max", cr_glb_float_array(hi, ncomp));
}

/* What one pass over the file's binary pieces needs. The same code plans
 * (fp == NULL: registers views and accessors, computes min/max) and writes
 * (fp set: streams the bytes), so layout and data cannot drift apart. */
typedef struct glb_job {
    const cr_mesh *m;
    const cr_mesh_seams *s;
    const float *frames; /* (T,V,3) or NULL for a static mesh */
    int32_t nframes;
    float fps;
    glb_out *g;
    FILE *fp;
    float *buf;     /* (V',3) scratch */
    float *nrm;     /* (V,3) scratch for frame normals */
    cJSON *targets; /* plan pass: primitive.targets */
    int acc_pos, acc_nrm, acc_tex, acc_xuv, acc_idx, acc_time, acc_weight;
} glb_job;

/* One piece: `n` elements of `ncomp` float (or u32 when `u32`) components,
 * from `data`, or (weights) generated row by row. Returns the accessor index
 * in the plan pass. */
static int piece(glb_job *j, const void *data, int64_t n, int ncomp, int u32, int minmax,
                 int target, cr_status *st, cr_error *err) {
    uint64_t bytes = 4 * (uint64_t)n * (uint64_t)ncomp;
    if (j->fp) {
        int ok = u32 ? cr_io_write_i32le(j->fp, data, (size_t)(n * ncomp))
                     : cr_io_write_f32le(j->fp, data, (size_t)(n * ncomp));
        if (!ok) *st = CR_FAIL(err, CR_ERR_IO, "glb: write failed");
        return -1;
    }
    glb_out *g = j->g;
    cJSON *view = cr_glb_add(g, g->views, NULL, cJSON_CreateObject());
    cr_glb_add_num(g, view, "buffer", 0);
    cr_glb_add_num(g, view, "byteOffset", (double)g->bin_len);
    cr_glb_add_num(g, view, "byteLength", (double)bytes);
    if (target) cr_glb_add_num(g, view, "target", target);
    g->bin_len += bytes;
    cJSON *acc = cr_glb_add(g, g->accessors, NULL, cJSON_CreateObject());
    cr_glb_add_num(g, acc, "bufferView", g->nviews++);
    cr_glb_add_num(g, acc, "componentType", u32 ? CT_U32 : CT_F32);
    cr_glb_add_num(g, acc, "count", (double)n);
    static const char *const types[] = {"", "SCALAR", "VEC2", "VEC3"};
    cr_glb_add(g, acc, "type", cJSON_CreateString(types[ncomp]));
    if (minmax && data) cr_glb_add_minmax(g, acc, data, n, ncomp);
    return g->naccessors++;
}

/* out[s] = a[src[s]] - b[src[s]] (b may be NULL) over split vertices, (V',3). */
static cr_status gather3(const glb_job *j, const float *a, const float *b, float *out,
                         cr_error *err) {
    for (int64_t s = 0; s < j->s->nv; s++) {
        int64_t v = j->s->src[s];
        for (int k = 0; k < 3; k++) {
            float x = b ? a[3 * v + k] - b[3 * v + k] : a[3 * v + k];
            if (!isfinite(x))
                return CR_FAIL(err, CR_ERR_RANGE,
                               "glb: vertex %lld: displacement overflows a "
                               "float",
                               (long long)v);
            out[3 * s + k] = x;
        }
    }
    return CR_OK;
}

static cr_status emit_targets(glb_job *j, cr_error *err) {
    const cr_mesh *m = j->m;
    int64_t nv = j->s->nv;
    cr_status st = CR_OK;
    for (int32_t t = 0; t < j->nframes && st == CR_OK; t++) {
        const float *frame = j->frames + (size_t)t * (size_t)m->nv * 3;
        cJSON *target = j->fp ? NULL : cr_glb_add(j->g, j->targets, NULL, cJSON_CreateObject());
        CR_TRY(gather3(j, frame, m->pos, j->buf, err));
        int a = piece(j, j->buf, nv, 3, 0, 1, TARGET_ARRAY, &st, err);
        if (target) cr_glb_add_num(j->g, target, "POSITION", a);
        if (!m->normal || st != CR_OK) continue;
        cr_mesh view = *m;
        view.pos = (float *)frame;
        cr_mesh_vertex_normals(&view, CR_NORMAL_AREA, j->nrm);
        CR_TRY(gather3(j, j->nrm, m->normal, j->buf, err));
        a = piece(j, j->buf, nv, 3, 0, 0, TARGET_ARRAY, &st, err);
        if (target) cr_glb_add_num(j->g, target, "NORMAL", a);
    }
    if (st != CR_OK) return st;
    /* Animation: key i at t = i / fps with weights one-hot on target i. */
    float *times = cr_malloc((size_t)j->nframes * sizeof(float), err);
    if (!times) return CR_ERR_MEMORY;
    for (int32_t t = 0; t < j->nframes; t++)
        times[t] = (float)((double)t / j->fps);
    j->acc_time = piece(j, times, j->nframes, 1, 0, 1, 0, &st, err);
    free(times);
    int64_t T = j->nframes;
    if (!j->fp) {
        j->acc_weight = piece(j, NULL, T * T, 1, 0, 0, 0, &st, err);
        return st;
    }
    float *row = cr_calloc((size_t)T, sizeof(float), err);
    if (!row) return CR_ERR_MEMORY;
    for (int64_t t = 0; t < T && st == CR_OK; t++) {
        row[t] = 1.0f;
        piece(j, row, T, 1, 0, 0, 0, &st, err);
        row[t] = 0.0f;
    }
    free(row);
    return st;
}

static cr_status emit_all(glb_job *j, cr_error *err) {
    const cr_mesh *m = j->m;
    const cr_mesh_seams *s = j->s;
    cr_status st = CR_OK;
    CR_TRY(gather3(j, m->pos, NULL, j->buf, err));
    j->acc_pos = piece(j, j->buf, s->nv, 3, 0, 1, TARGET_ARRAY, &st, err);
    if (m->normal && st == CR_OK) {
        CR_TRY(gather3(j, m->normal, NULL, j->buf, err));
        j->acc_nrm = piece(j, j->buf, s->nv, 3, 0, 0, TARGET_ARRAY, &st, err);
    }
    if (s->uv && st == CR_OK) {
        /* TEXCOORD_0 = (u, 1 - v), rounded once from the exact double. */
        for (int64_t i = 0; i < s->nv; i++) {
            j->buf[2 * i] = s->uv[2 * i];
            j->buf[2 * i + 1] = (float)(1.0 - (double)s->uv[2 * i + 1]);
        }
        j->acc_tex = piece(j, j->buf, s->nv, 2, 0, 0, TARGET_ARRAY, &st, err);
        if (st == CR_OK) j->acc_xuv = piece(j, s->uv, s->nv, 2, 0, 0, TARGET_ARRAY, &st, err);
    }
    if (st == CR_OK)
        j->acc_idx = piece(j, s->tri, 3 * (int64_t)m->nf, 1, 1, 0, TARGET_ELEMENTS, &st, err);
    if (st == CR_OK && j->frames) st = emit_targets(j, err);
    return st;
}

void cr_glb_add_frame_names(glb_out *g, cJSON *mesh, int32_t nframes) {
    /* Static viewers show frame 0; Blender names shape keys from targetNames. */
    cJSON *weights = cr_glb_add(g, mesh, "weights", cJSON_CreateArray());
    cJSON *names = cr_glb_add(g, cr_glb_add(g, mesh, "extras", cJSON_CreateObject()), "targetNames",
                              cJSON_CreateArray());
    for (int32_t t = 0; t < nframes; t++) {
        char name[32];
        snprintf(name, sizeof name, "frame_%04d", t);
        cr_glb_add_num(g, weights, NULL, t == 0);
        cr_glb_add(g, names, NULL, cJSON_CreateString(name));
    }
}

/* Everything in the JSON besides views and accessors, after the plan pass. */
static void build_document(glb_job *j) {
    glb_out *g = j->g;
    cJSON *root = g->root;
    cJSON *asset = cr_glb_add(g, root, "asset", cJSON_CreateObject());
    cr_glb_add(g, asset, "version", cJSON_CreateString("2.0"));
    cr_glb_add(g, asset, "generator", cJSON_CreateString("crease"));
    cr_glb_add_num(g, root, "scene", 0);
    cJSON *scene = cr_glb_add(g, cr_glb_add(g, root, "scenes", cJSON_CreateArray()), NULL,
                              cJSON_CreateObject());
    cr_glb_add_num(g, cr_glb_add(g, scene, "nodes", cJSON_CreateArray()), NULL, 0);
    cJSON *node = cr_glb_add(g, cr_glb_add(g, root, "nodes", cJSON_CreateArray()), NULL,
                             cJSON_CreateObject());
    cr_glb_add(g, node, "name", cJSON_CreateString("crease"));
    cr_glb_add_num(g, node, "mesh", 0);
    cJSON *mesh = cr_glb_add(g, cr_glb_add(g, root, "meshes", cJSON_CreateArray()), NULL,
                             cJSON_CreateObject());
    cJSON *prim = cr_glb_add(g, cr_glb_add(g, mesh, "primitives", cJSON_CreateArray()), NULL,
                             cJSON_CreateObject());
    cJSON *attrs = cr_glb_add(g, prim, "attributes", cJSON_CreateObject());
    cr_glb_add_num(g, attrs, "POSITION", j->acc_pos);
    if (j->m->normal) cr_glb_add_num(g, attrs, "NORMAL", j->acc_nrm);
    if (j->s->uv) {
        cr_glb_add_num(g, attrs, "TEXCOORD_0", j->acc_tex);
        cr_glb_add_num(g, attrs, "_CREASE_UV", j->acc_xuv);
    }
    cr_glb_add_num(g, prim, "indices", j->acc_idx);
    cr_glb_add_num(g, prim, "mode", MODE_TRIANGLES);
    if (j->frames) {
        cr_glb_add(g, prim, "targets", j->targets);
        cr_glb_add_frame_names(g, mesh, j->nframes);
        cJSON *anim = cr_glb_add(g, cr_glb_add(g, root, "animations", cJSON_CreateArray()), NULL,
                                 cJSON_CreateObject());
        cr_glb_add(g, anim, "name", cJSON_CreateString("sequence"));
        cJSON *sampler = cr_glb_add(g, cr_glb_add(g, anim, "samplers", cJSON_CreateArray()), NULL,
                                    cJSON_CreateObject());
        cr_glb_add_num(g, sampler, "input", j->acc_time);
        cr_glb_add_num(g, sampler, "output", j->acc_weight);
        cr_glb_add(g, sampler, "interpolation", cJSON_CreateString("LINEAR"));
        cJSON *channel = cr_glb_add(g, cr_glb_add(g, anim, "channels", cJSON_CreateArray()), NULL,
                                    cJSON_CreateObject());
        cr_glb_add_num(g, channel, "sampler", 0);
        cJSON *target = cr_glb_add(g, channel, "target", cJSON_CreateObject());
        cr_glb_add_num(g, target, "node", 0);
        cr_glb_add(g, target, "path", cJSON_CreateString("weights"));
    }
    cJSON *buffer = cr_glb_add(g, cr_glb_add(g, root, "buffers", cJSON_CreateArray()), NULL,
                               cJSON_CreateObject());
    cr_glb_add_num(g, buffer, "byteLength", (double)g->bin_len);
    cr_glb_add(g, root, "bufferViews", g->views);
    cr_glb_add(g, root, "accessors", g->accessors);
}

cr_status cr_glb_begin_file(const char *path, const char *json, uint64_t bin_len, cr_atomic_file *f,
                            cr_error *err) {
    uint64_t jlen = strlen(json), jpad = (jlen + 3) & ~(uint64_t)3;
    uint64_t total = 12 + 8 + jpad + 8 + bin_len;
    if (total > UINT32_MAX)
        return CR_FAIL(err, CR_ERR_RANGE, "%s: %llu bytes exceed the 4 GiB glb limit", path,
                       (unsigned long long)total);
    CR_TRY(cr_atomic_open(f, path, err));
    unsigned char head[20];
    io_put_le32(head, GLB_MAGIC);
    io_put_le32(head + 4, 2);
    io_put_le32(head + 8, (uint32_t)total);
    io_put_le32(head + 12, (uint32_t)jpad);
    io_put_le32(head + 16, GLB_CHUNK_JSON);
    int ok = fwrite(head, 1, 20, f->fp) == 20 && fwrite(json, 1, jlen, f->fp) == jlen;
    for (uint64_t i = jlen; i < jpad && ok; i++)
        ok = fputc(' ', f->fp) != EOF;
    io_put_le32(head, (uint32_t)bin_len);
    io_put_le32(head + 4, GLB_CHUNK_BIN);
    ok = ok && fwrite(head, 1, 8, f->fp) == 8;
    if (ok) return CR_OK;
    cr_atomic_abort(f);
    return CR_FAIL(err, CR_ERR_IO, "%s: write failed", path);
}

static cr_status write_container(const char *path, glb_job *j, const char *json, cr_error *err) {
    cr_atomic_file f;
    CR_TRY(cr_glb_begin_file(path, json, j->g->bin_len, &f, err));
    j->fp = f.fp;
    cr_status st = emit_all(j, err);
    if (st != CR_OK) {
        cr_atomic_abort(&f);
        return st;
    }
    return cr_atomic_commit(&f, err);
}

static cr_status write_glb(const char *path, const cr_mesh *m, const float *frames, int32_t nframes,
                           float fps, cr_error *err) {
    CR_TRY(cr_mesh_validate(m, path, err));
    if (m->nf == 0) return CR_FAIL(err, CR_ERR_TOPOLOGY, "%s: mesh has no faces", path);
    cr_mesh_seams s;
    CR_TRY(cr_mesh_split_seams(m, &s, err));
    glb_out g = {0};
    glb_job j = {.m = m, .s = &s, .frames = frames, .nframes = nframes, .fps = fps, .g = &g};
    g.root = cJSON_CreateObject();
    g.views = cJSON_CreateArray();
    g.accessors = cJSON_CreateArray();
    j.targets = frames ? cJSON_CreateArray() : NULL;
    j.buf = cr_malloc((size_t)s.nv * 3 * sizeof(float), err);
    j.nrm = frames && m->normal ? cr_malloc((size_t)m->nv * 3 * sizeof(float), err) : NULL;
    cr_status st = CR_OK;
    if (!g.root || !g.views || !g.accessors || (frames && !j.targets) || !j.buf ||
        (frames && m->normal && !j.nrm))
        st = CR_FAIL(err, CR_ERR_MEMORY, "%s: out of memory", path);
    if (st == CR_OK) st = emit_all(&j, err);
    char *json = NULL;
    if (st == CR_OK) {
        /* build_document moves views, accessors and targets into the root */
        build_document(&j);
        g.views = g.accessors = j.targets = NULL;
        json = g.oom ? NULL : cJSON_PrintUnformatted(g.root);
        if (!json) st = CR_FAIL(err, CR_ERR_MEMORY, "%s: out of memory building the JSON", path);
    }
    if (st == CR_OK) st = write_container(path, &j, json, err);
    cJSON_free(json);
    cJSON_Delete(g.root);
    cJSON_Delete(g.views);
    cJSON_Delete(g.accessors);
    cJSON_Delete(j.targets);
    free(j.buf), free(j.nrm);
    cr_mesh_seams_free(&s);
    return st;
}

cr_status cr_glb_write(const char *path, const cr_mesh *m, cr_error *err) {
    return write_glb(path, m, NULL, 0, 0.0f, err);
}

cr_status cr_glb_write_sequence(const char *path, const cr_mesh *rest, const float *frames,
                                int32_t nframes, float fps, cr_error *err) {
    if (!frames || nframes < 1)
        return CR_FAIL(err, CR_ERR_INVALID, "%s: expected at least one frame, got %d", path,
                       nframes);
    if (!(isfinite(fps) && fps > 0))
        return CR_FAIL(err, CR_ERR_INVALID, "%s: fps must be positive, got %g", path, fps);
    for (int64_t i = 0; i < (int64_t)nframes * rest->nv * 3; i++)
        if (!isfinite(frames[i]))
            return CR_FAIL(err, CR_ERR_NAN, "%s: frame %lld vertex %lld is not finite", path,
                           (long long)(i / (3 * (int64_t)rest->nv)), (long long)(i / 3 % rest->nv));
    return write_glb(path, rest, frames, nframes, fps, err);
}

/* ======================================================= sequence reader == */

/* Hash of a position's bits, for mapping file vertices onto welded ones. */
static uint64_t pos_hash(const float *p) {
    uint32_t b[3];
    memcpy(b, p, sizeof b);
    uint64_t h = 1469598103934665603ull;
    for (int k = 0; k < 3; k++)
        h = (h ^ b[k]) * 1099511628211ull;
    return h;
}

/* map[j] = the vertex of `m` (welded, V) with the bits of file vertex j (V'
 * positions raw). Weld keeps first appearances in order, so first
 * appearances here are numbered 0, 1, ... in the same way. */
static cr_status weld_map(const float *raw, int64_t nraw, const cr_mesh *m, int32_t *map,
                          const char *source, cr_error *err) {
    uint64_t cap = 16;
    while (cap < 2 * (uint64_t)nraw)
        cap *= 2;
    int32_t *slot = cr_malloc(cap * sizeof(int32_t), err);
    if (!slot) return CR_ERR_MEMORY;
    for (uint64_t s = 0; s < cap; s++)
        slot[s] = -1;
    int32_t next = 0;
    for (int64_t j = 0; j < nraw; j++) {
        const float *p = raw + 3 * j;
        uint64_t s = pos_hash(p) & (cap - 1);
        while (slot[s] >= 0 && memcmp(raw + 3 * (int64_t)slot[s], p, 3 * sizeof(float)) != 0)
            s = (s + 1) & (cap - 1);
        if (slot[s] < 0) {
            slot[s] = (int32_t)j;
            map[j] = next++;
        } else {
            map[j] = map[slot[s]];
        }
    }
    free(slot);
    if (next != m->nv)
        return CR_FAIL(err, CR_ERR_PARSE,
                       "%s: %d distinct base positions but the welded mesh has %d vertices", source,
                       next, m->nv);
    return CR_OK;
}

/* The frame rate of animations[0]: 1 / (t1 - t0) of its first sampler's input. */
double cr_glb_key_rate(float t0, float t1) {
    /* The writer stores i / fps in float: 1 / (t1 - t0) of 30 fps reads 29.999998. */
    double fps = 1.0 / ((double)t1 - (double)t0), whole = round(fps);
    return fabs(fps - whole) < 1e-4 * whole ? whole : fps;
}

static float read_fps(const glb_in *g) {
    const cJSON *anim = cr_glb_json_at(cJSON_GetObjectItemCaseSensitive(g->root, "animations"), 0);
    const cJSON *smp = cr_glb_json_at(cJSON_GetObjectItemCaseSensitive(anim, "samplers"), 0);
    const cJSON *in = cJSON_GetObjectItemCaseSensitive(smp, "input");
    glb_acc a;
    cr_error ignored = {0};
    if (!cJSON_IsNumber(in) || in->valuedouble < 0 ||
        cr_glb_accessor(g, (uint64_t)in->valuedouble, &a, &ignored) != CR_OK || a.ctype != CT_F32 ||
        a.ncomp != 1 || a.count < 2)
        return 0.0f;
    float t0 = io_f32(io_le32(a.base)), t1 = io_f32(io_le32(a.base + a.stride));
    if (!(isfinite(t1 - t0) && t1 > t0)) return 0.0f;
    return (float)cr_glb_key_rate(t0, t1);
}

static cr_status read_sequence(const glb_in *g, cr_mesh *m, float **frames, int32_t *nframes,
                               float *skin_fps_out, cr_error *err) {
    const cJSON *prim = NULL;
    CR_TRY(get_primitive(g, &prim, err));
    glb_acc pa;
    int has_p;
    CR_TRY(get_attribute(g, cJSON_GetObjectItemCaseSensitive(prim, "attributes"), "POSITION", &pa,
                         &has_p, err));
    const cJSON *targets = cJSON_GetObjectItemCaseSensitive(prim, "targets");
    int64_t nt = cJSON_IsArray(targets) ? cJSON_GetArraySize(targets) : 0;
    int64_t nraw = pa.count, nv = m->nv;
    /* Targets that share bytes could ask for T x V floats from a small file: a crease
     * sequence stores every target whole, so the output never outgrows the BIN chunk. */
    if ((uint64_t)nt * (uint64_t)nraw * 12 > g->bin_len)
        return CR_FAIL(err, CR_ERR_RANGE,
                       "%s: %lld targets of %lld vertices need more than the %llu-byte BIN chunk",
                       g->source, (long long)nt, (long long)nraw, (unsigned long long)g->bin_len);
    float *raw = cr_malloc((size_t)nraw * 3 * sizeof(float), err);
    float *dis = cr_malloc((size_t)nraw * 3 * sizeof(float), err);
    int32_t *map = cr_malloc((size_t)nraw * sizeof(int32_t), err);
    cr_status st = raw && dis && map ? CR_OK : CR_ERR_MEMORY;
    if (st == CR_OK) st = cr_glb_read_floats(g, &pa, "POSITION", raw, err);
    if (st == CR_OK) st = weld_map(raw, nraw, m, map, g->source, err);
    /* A skinned mesh without morph targets: posed by its animation. */
    const cJSON *attrs = cJSON_GetObjectItemCaseSensitive(prim, "attributes");
    float *posed = NULL, skin_fps = 0.0f;
    int32_t nposed = 0;
    if (st == CR_OK && nt == 0 && cJSON_GetObjectItemCaseSensitive(attrs, "JOINTS_0") &&
        cJSON_GetObjectItemCaseSensitive(g->root, "skins"))
        st = cr_glb_skin_frames(g, prim, raw, nraw, &posed, &nposed, &skin_fps, err);
    const int64_t T = posed ? nposed : nt > 0 ? nt : 1;
    float *out = st == CR_OK ? cr_malloc((size_t)T * (size_t)nv * 3 * sizeof(float), err) : NULL;
    if (st == CR_OK && !out) st = CR_ERR_MEMORY;
    for (int64_t t = 0; st == CR_OK && t < T; t++) {
        char name[64];
        snprintf(name, sizeof name, "targets[%lld].POSITION", (long long)t);
        memset(dis, 0, (size_t)nraw * 3 * sizeof(float));
        if (nt > 0) {
            glb_acc ta;
            int has_t;
            st = get_attribute(g, cr_glb_json_at(targets, (uint64_t)t), "POSITION", &ta, &has_t,
                               err);
            if (st == CR_OK && !has_t)
                st = CR_FAIL(err, CR_ERR_PARSE, "%s: %s is missing", g->source, name);
            if (st == CR_OK) st = expect_float(g, &ta, name, 3, nraw, err);
            if (st == CR_OK) st = cr_glb_read_floats(g, &ta, name, dis, err);
        }
        /* Seam copies land on their welded vertex with the same value as the original. */
        const float *base = posed ? posed + t * nraw * 3 : raw;
        for (int64_t j = 0; st == CR_OK && j < nraw; j++)
            for (int k = 0; k < 3; k++)
                out[(t * nv + map[j]) * 3 + k] = base[3 * j + k] + dis[3 * j + k];
    }
    if (posed) *skin_fps_out = skin_fps;
    free(posed);
    free(raw);
    free(dis);
    free(map);
    if (st != CR_OK) {
        free(out);
        return st;
    }
    *frames = out;
    *nframes = (int32_t)T;
    return CR_OK;
}

cr_status cr_glb_read_sequence(const char *path, cr_mesh **rest, float **frames, int32_t *nframes,
                               float *fps, cr_error *err) {
    *rest = NULL;
    *frames = NULL;
    *nframes = 0;
    *fps = 0.0f;
    char *buf;
    size_t len;
    CR_TRY(cr_file_read_all(path, &buf, &len, err));
    cr_status st = cr_glb_read_sequence_mem(buf, len, path, rest, frames, nframes, fps, err);
    free(buf);
    return st;
}

cr_status cr_glb_read_sequence_mem(const void *data, size_t len, const char *source, cr_mesh **rest,
                                   float **frames, int32_t *nframes, float *fps, cr_error *err) {
    *rest = NULL;
    *frames = NULL;
    *nframes = 0;
    *fps = 0.0f;
    glb_in g = {.source = source};
    cr_status st = cr_glb_open_container(&g, data, len, err);
    if (st == CR_OK) st = read_mesh(&g, rest, err);
    float skin_fps = 0.0f;
    if (st == CR_OK) st = read_sequence(&g, *rest, frames, nframes, &skin_fps, err);
    if (st == CR_OK) *fps = skin_fps > 0.0f ? skin_fps : read_fps(&g);
    if (st != CR_OK) {
        cr_mesh_destroy(*rest);
        *rest = NULL;
    }
    cJSON_Delete(g.root);
    return st;
}

/* ------------------------------------------------------------ characters -- */

cr_status cr_glb_read_character_mem(const void *data, size_t len, const char *source,
                                    cr_glb_character **out, cr_error *err) {
    *out = NULL;
    glb_in g = {.source = source};
    cr_glb_character *c = cr_calloc(1, sizeof *c, err);
    if (!c) return CR_ERR_MEMORY;
    float *raw = NULL;
    int32_t *weld = NULL;
    const cJSON *prim = NULL;
    glb_acc pa;
    int has_p = 0;
    cr_status st = cr_glb_open_container(&g, data, len, err);
    if (st == CR_OK) st = read_mesh(&g, &c->rest, err);
    if (st == CR_OK) st = get_primitive(&g, &prim, err);
    if (st == CR_OK)
        st = get_attribute(&g, cJSON_GetObjectItemCaseSensitive(prim, "attributes"), "POSITION",
                           &pa, &has_p, err);
    const cJSON *attrs = prim ? cJSON_GetObjectItemCaseSensitive(prim, "attributes") : NULL;
    if (st == CR_OK && (!cJSON_GetObjectItemCaseSensitive(attrs, "JOINTS_0") ||
                        !cJSON_GetObjectItemCaseSensitive(attrs, "WEIGHTS_0") ||
                        !cJSON_GetObjectItemCaseSensitive(g.root, "skins")))
        st = CR_FAIL(err, CR_ERR_UNSUPPORTED,
                     "%s: the mesh has no skin (JOINTS_0, WEIGHTS_0 and a skins entry): a "
                     "character must be rigged to follow a motion",
                     source);
    if (st == CR_OK) {
        raw = cr_malloc((size_t)pa.count * 3 * sizeof(float), err);
        weld = cr_malloc((size_t)pa.count * sizeof(int32_t), err);
        if (!raw || !weld) st = CR_ERR_MEMORY;
    }
    if (st == CR_OK) st = cr_glb_read_floats(&g, &pa, "POSITION", raw, err);
    if (st == CR_OK) st = weld_map(raw, pa.count, c->rest, weld, source, err);
    if (st == CR_OK) st = cr_glb_skin_rest(&g, prim, raw, pa.count, weld, c, err);
    free(raw), free(weld);
    cJSON_Delete(g.root);
    if (st != CR_OK) {
        cr_glb_character_destroy(c);
        return st;
    }
    *out = c;
    return CR_OK;
}

cr_status cr_glb_read_character(const char *path, cr_glb_character **out, cr_error *err) {
    *out = NULL;
    char *buf;
    size_t len;
    CR_TRY(cr_file_read_all(path, &buf, &len, err));
    cr_status st = cr_glb_read_character_mem(buf, len, path, out, err);
    free(buf);
    return st;
}
