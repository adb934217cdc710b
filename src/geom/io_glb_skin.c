/* io_glb_skin.c: skinned, animated characters in glTF 2.0 binary (.glb), as
 * game engines and DCC tools take them: a skeleton of joint nodes, a skin
 * (JOINTS_0, WEIGHTS_0, inverse bind matrices) and one animation of the
 * joints' rotations and the root's translation.
 *
 * Writer (cr_glb_write_skinned): node 0 is the mesh (its transform is
 * ignored by skinning, as the specification says), nodes 1..J the joints,
 * joint j's translation its rest offset from its parent (the root's its rest
 * position), so the file's rest pose is the bind pose and each inverse bind
 * matrix is a translation by minus the joint's rest position. Keys at
 * t = i / fps, LINEAR (glTF slerps rotations). JOINTS_0 as unsigned short,
 * WEIGHTS_0 renormalised in float (validators check the sum), vertices split
 * at UV seams like every crease glb. A garment may go beside the body, on
 * the same timeline: its own node and mesh, one morph target a frame and a
 * weights channel one-hot at each frame's time (as cr_glb_write_sequence
 * writes one). The BIN chunk is built in memory.
 *
 * Evaluation (cr_glb_skin_frames, for cr_glb_read_sequence): the node that
 * draws meshes[0] with a skin; animations[0]'s translation, rotation and
 * scale channels (LINEAR or STEP; CUBICSPLINE refused) sampled at
 * t = t0 + i / fps over the channels' whole time range; nodes' local TRS or
 * matrix, composed from the scene's roots; each vertex moved by the
 * weighted sum of its joints' world transform times their inverse bind
 * matrix. Any joint names and hierarchy are read; the frame count is capped
 * so a file cannot ask for more memory than it plausibly describes. A
 * character (cr_glb_read_character) gets its joints through the same
 * frames: world positions and world rotations relative to the rest's
 * (cr_glb_skin_anim), every node above them composed in.
 *
 * Reference: The Khronos glTF 2.0 Specification, sections 3.5 (nodes and
 * hierarchy), 3.7.3 (skins), 3.11 (animations, interpolation).
 */
#include "crease/mesh_io.h"
#include "geom/glb_internal.h"
#include "geom/io_text.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Frames a skinned file may ask for, and frames times vertices. */
#define MAX_SKIN_FRAMES 100000
#define MAX_SKIN_VALUES ((int64_t)1 << 27)
/* Nesting of the node tree followed before a file counts as cyclic. */
#define MAX_NODE_DEPTH 256

/* ================================================================ writer == */

/* The BIN chunk under construction. */
typedef struct bin_buf {
    unsigned char *d;
    size_t len, cap;
    int oom;
} bin_buf;

static void bin_put(bin_buf *b, const void *data, size_t n) {
    if (b->oom) return;
    size_t need = b->len + ((n + 3) & ~(size_t)3);
    if (need > b->cap) {
        size_t cap = b->cap ? b->cap : 1 << 16;
        while (cap < need)
            cap *= 2;
        unsigned char *d = realloc(b->d, cap);
        if (!d) {
            b->oom = 1;
            return;
        }
        b->d = d, b->cap = cap;
    }
    memcpy(b->d + b->len, data, n);
    memset(b->d + b->len + n, 0, need - b->len - n);
    b->len = need;
}

/* One accessor of `count` elements of `type` over a new view holding `data`
 * (little-endian floats or u16/u32, as the host writes them: crease builds
 * only for little-endian machines, io_text.h). min/max for float data when
 * `minmax`. Returns the accessor's index. */
static int put_accessor(glb_out *g, bin_buf *b, const void *data, int64_t count, const char *type,
                        int ncomp, int ctype, int target, int minmax) {
    const int size = ctype == CT_U16 ? 2 : 4;
    const size_t bytes = (size_t)count * (size_t)ncomp * (size_t)size;
    cJSON *view = cr_glb_add(g, g->views, NULL, cJSON_CreateObject());
    cr_glb_add_num(g, view, "buffer", 0);
    cr_glb_add_num(g, view, "byteOffset", (double)b->len);
    cr_glb_add_num(g, view, "byteLength", (double)bytes);
    if (target) cr_glb_add_num(g, view, "target", target);
    bin_put(b, data, bytes);
    cJSON *acc = cr_glb_add(g, g->accessors, NULL, cJSON_CreateObject());
    cr_glb_add_num(g, acc, "bufferView", g->nviews++);
    cr_glb_add_num(g, acc, "componentType", ctype);
    cr_glb_add_num(g, acc, "count", (double)count);
    cr_glb_add(g, acc, "type", cJSON_CreateString(type));
    if (minmax) cr_glb_add_minmax(g, acc, data, count, ncomp);
    return g->naccessors++;
}

static cr_status check_skin(const char *path, const cr_mesh *m, const cr_glb_skin *s,
                            const cr_glb_skin_motion *a, cr_error *err) {
    CR_TRY(cr_mesh_validate(m, path, err));
    if (m->nf == 0) return CR_FAIL(err, CR_ERR_TOPOLOGY, "%s: mesh has no faces", path);
    if (s->njoints < 1 || s->njoints > CR_GLB_MAX_JOINTS)
        return CR_FAIL(err, CR_ERR_INVALID, "%s: %d joints (1 to %d)", path, s->njoints,
                       CR_GLB_MAX_JOINTS);
    for (int32_t j = 0; j < s->njoints; j++)
        if (s->parent[j] >= j || s->parent[j] < -1)
            return CR_FAIL(err, CR_ERR_INVALID,
                           "%s: joint %d (%s): parent %d must come before it (or be -1)", path, j,
                           s->joint_name[j], s->parent[j]);
    for (int64_t i = 0; i < 4 * (int64_t)m->nv; i++) {
        if (s->skin_joint[i] < 0 || s->skin_joint[i] >= s->njoints ||
            !(s->skin_weight[i] >= 0.0f && s->skin_weight[i] <= 1.0f))
            return CR_FAIL(err, CR_ERR_INVALID,
                           "%s: vertex %lld: joint %d or weight %g out of range", path,
                           (long long)(i / 4), s->skin_joint[i], (double)s->skin_weight[i]);
    }
    if (a->nframes < 1 || !(isfinite(a->fps) && a->fps > 0.0f))
        return CR_FAIL(err, CR_ERR_INVALID, "%s: %d frames at %g fps (need >= 1 and > 0)", path,
                       a->nframes, (double)a->fps);
    for (int64_t i = 0; i < (int64_t)a->nframes * s->njoints * 4; i++)
        if (!isfinite(a->rotation[i]))
            return CR_FAIL(err, CR_ERR_NAN, "%s: frame %lld: a joint rotation is not finite", path,
                           (long long)(i / (4 * s->njoints)));
    for (int64_t i = 0; i < 3 * (int64_t)a->nframes; i++)
        if (!isfinite(a->translation[i]))
            return CR_FAIL(err, CR_ERR_NAN, "%s: frame %lld: the root translation is not finite",
                           path, (long long)(i / 3));
    return CR_OK;
}

/* The vertex data, split at seams: POSITION, NORMAL, TEXCOORD_0, JOINTS_0,
 * WEIGHTS_0 and the indices into the primitive's attributes. */
static cr_status put_mesh(glb_out *g, bin_buf *b, const cr_mesh *m, const cr_mesh_seams *s,
                          const cr_glb_skin *sk, cJSON *prim, cr_error *err) {
    const int64_t n = s->nv;
    float *f = cr_malloc((size_t)n * 4 * sizeof(float), err);
    uint16_t *jt = cr_malloc((size_t)n * 4 * sizeof(uint16_t), err);
    if (!f || !jt) {
        free(f), free(jt);
        return CR_ERR_MEMORY;
    }
    cJSON *attrs = cr_glb_add(g, prim, "attributes", cJSON_CreateObject());
    for (int64_t i = 0; i < n; i++)
        memcpy(f + 3 * i, m->pos + 3 * (int64_t)s->src[i], 3 * sizeof(float));
    cr_glb_add_num(g, attrs, "POSITION",
                   put_accessor(g, b, f, n, "VEC3", 3, CT_F32, TARGET_ARRAY, 1));
    if (m->normal) {
        for (int64_t i = 0; i < n; i++)
            memcpy(f + 3 * i, m->normal + 3 * (int64_t)s->src[i], 3 * sizeof(float));
        cr_glb_add_num(g, attrs, "NORMAL",
                       put_accessor(g, b, f, n, "VEC3", 3, CT_F32, TARGET_ARRAY, 0));
    }
    if (s->uv) {
        for (int64_t i = 0; i < n; i++)
            f[2 * i] = s->uv[2 * i], f[2 * i + 1] = (float)(1.0 - (double)s->uv[2 * i + 1]);
        cr_glb_add_num(g, attrs, "TEXCOORD_0",
                       put_accessor(g, b, f, n, "VEC2", 2, CT_F32, TARGET_ARRAY, 0));
    }
    for (int64_t i = 0; sk && i < n; i++) {
        const int64_t v = s->src[i];
        double sum = 0.0;
        for (int k = 0; k < 4; k++)
            sum += sk->skin_weight[4 * v + k];
        for (int k = 0; k < 4; k++) {
            const float w = sum > 0.0 ? (float)(sk->skin_weight[4 * v + k] / sum) : k == 0;
            f[4 * i + k] = w;
            jt[4 * i + k] = w > 0.0f ? (uint16_t)sk->skin_joint[4 * v + k] : 0;
        }
    }
    if (sk) {
        cr_glb_add_num(g, attrs, "JOINTS_0",
                       put_accessor(g, b, jt, n, "VEC4", 4, CT_U16, TARGET_ARRAY, 0));
        cr_glb_add_num(g, attrs, "WEIGHTS_0",
                       put_accessor(g, b, f, n, "VEC4", 4, CT_F32, TARGET_ARRAY, 0));
    }
    cr_glb_add_num(
        g, prim, "indices",
        put_accessor(g, b, s->tri, 3 * (int64_t)m->nf, "SCALAR", 1, CT_U32, TARGET_ELEMENTS, 0));
    cr_glb_add_num(g, prim, "mode", MODE_TRIANGLES);
    free(f), free(jt);
    return CR_OK;
}

/* Joint nodes 1..J, the skin and the animation. */
static cr_status put_skeleton(glb_out *g, bin_buf *b, const cr_glb_skin *s,
                              const cr_glb_skin_motion *a, cJSON *nodes, int *times_out,
                              cr_error *err) {
    const int32_t J = s->njoints, T = a->nframes;
    float *buf = cr_malloc((size_t)(16 * J > 4 * T ? 16 * J : 4 * T) * sizeof(float), err);
    if (!buf) return CR_ERR_MEMORY;
    for (int32_t j = 0; j < J; j++) {
        cJSON *node = cr_glb_add(g, nodes, NULL, cJSON_CreateObject());
        cr_glb_add(g, node, "name", cJSON_CreateString(s->joint_name[j]));
        const int32_t p = s->parent[j];
        float t[3];
        for (int k = 0; k < 3; k++)
            t[k] = s->rest_joint[3 * j + k] - (p >= 0 ? s->rest_joint[3 * p + k] : 0.0f);
        cr_glb_add(g, node, "translation", cr_glb_float_array(t, 3));
        cJSON *children = NULL;
        for (int32_t c = j + 1; c < J; c++)
            if (s->parent[c] == j) {
                if (!children) children = cr_glb_add(g, node, "children", cJSON_CreateArray());
                cr_glb_add_num(g, children, NULL, 1 + c);
            }
    }
    /* Inverse bind matrices, column-major: a translation by minus the rest position. */
    for (int32_t j = 0; j < J; j++) {
        float *mtx = buf + 16 * j;
        memset(mtx, 0, 16 * sizeof(float));
        mtx[0] = mtx[5] = mtx[10] = mtx[15] = 1.0f;
        for (int k = 0; k < 3; k++)
            mtx[12 + k] = -s->rest_joint[3 * j + k];
    }
    cJSON *skin = cr_glb_add(g, cr_glb_add(g, g->root, "skins", cJSON_CreateArray()), NULL,
                             cJSON_CreateObject());
    cr_glb_add_num(g, skin, "inverseBindMatrices",
                   put_accessor(g, b, buf, J, "MAT4", 16, CT_F32, 0, 0));
    cJSON *joints = cr_glb_add(g, skin, "joints", cJSON_CreateArray());
    for (int32_t j = 0; j < J; j++)
        cr_glb_add_num(g, joints, NULL, 1 + j);
    cr_glb_add_num(g, skin, "skeleton", 1);

    cJSON *anim = cr_glb_add(g, cr_glb_add(g, g->root, "animations", cJSON_CreateArray()), NULL,
                             cJSON_CreateObject());
    cr_glb_add(g, anim, "name", cJSON_CreateString("motion"));
    cJSON *samplers = cr_glb_add(g, anim, "samplers", cJSON_CreateArray());
    cJSON *channels = cr_glb_add(g, anim, "channels", cJSON_CreateArray());
    for (int32_t i = 0; i < T; i++)
        buf[i] = (float)((double)i / a->fps);
    const int times = put_accessor(g, b, buf, T, "SCALAR", 1, CT_F32, 0, 1);
    *times_out = times;
    int nsamplers = 0;
    for (int32_t j = -1; j < J; j++) { /* -1: the root's translation */
        if (j < 0) {
            for (int32_t i = 0; i < T; i++)
                for (int k = 0; k < 3; k++)
                    buf[3 * i + k] = s->rest_joint[k] + a->translation[3 * i + k];
        } else {
            for (int32_t i = 0; i < T; i++) {
                const float *q = a->rotation + 4 * ((int64_t)i * J + j);
                double n = sqrt((double)q[0] * q[0] + (double)q[1] * q[1] + (double)q[2] * q[2] +
                                (double)q[3] * q[3]);
                for (int k = 0; k < 4; k++)
                    buf[4 * i + k] = n > 0.0 ? (float)(q[k] / n) : k == 3;
            }
        }
        cJSON *smp = cr_glb_add(g, samplers, NULL, cJSON_CreateObject());
        cr_glb_add_num(g, smp, "input", times);
        cr_glb_add_num(g, smp, "output",
                       j < 0 ? put_accessor(g, b, buf, T, "VEC3", 3, CT_F32, 0, 0)
                             : put_accessor(g, b, buf, T, "VEC4", 4, CT_F32, 0, 0));
        cr_glb_add(g, smp, "interpolation", cJSON_CreateString("LINEAR"));
        cJSON *ch = cr_glb_add(g, channels, NULL, cJSON_CreateObject());
        cr_glb_add_num(g, ch, "sampler", nsamplers++);
        cJSON *target = cr_glb_add(g, ch, "target", cJSON_CreateObject());
        cr_glb_add_num(g, target, "node", 1 + (j < 0 ? 0 : j));
        cr_glb_add(g, target, "path", cJSON_CreateString(j < 0 ? "translation" : "rotation"));
    }
    free(buf);
    return CR_OK;
}

/* The cloth beside the body: mesh 1 on node 1 + J, one morph target a frame
 * (displacements from its rest, split at seams), and a weights channel in
 * the body's animation, one-hot at each frame's time (accessor `times`). */
static cr_status put_cloth(glb_out *g, bin_buf *b, const cr_glb_cloth *c, int32_t T, int times,
                           int32_t node, cJSON *nodes, cr_error *err) {
    cr_mesh_seams s;
    CR_TRY(cr_mesh_split_seams(c->rest, &s, err));
    float *d = cr_malloc((size_t)s.nv * 3 * sizeof(float), err);
    float *w = cr_calloc((size_t)T * (size_t)T, sizeof(float), err);
    cr_status st = d && w ? CR_OK : CR_ERR_MEMORY;
    cJSON *mesh = cr_glb_add(g, cJSON_GetObjectItemCaseSensitive(g->root, "meshes"), NULL,
                             cJSON_CreateObject());
    cr_glb_add(g, mesh, "name", cJSON_CreateString("garment"));
    cJSON *prim = cr_glb_add(g, cr_glb_add(g, mesh, "primitives", cJSON_CreateArray()), NULL,
                             cJSON_CreateObject());
    if (st == CR_OK) st = put_mesh(g, b, c->rest, &s, NULL, prim, err);
    cJSON *targets = cr_glb_add(g, prim, "targets", cJSON_CreateArray());
    cr_glb_add_frame_names(g, mesh, T);
    const int64_t nv = c->rest->nv;
    for (int32_t t = 0; st == CR_OK && t < T; t++) {
        const float *x = c->frames + (int64_t)t * nv * 3;
        for (int64_t i = 0; i < s.nv; i++)
            for (int k = 0; k < 3; k++)
                d[3 * i + k] =
                    x[3 * (int64_t)s.src[i] + k] - c->rest->pos[3 * (int64_t)s.src[i] + k];
        cJSON *target = cr_glb_add(g, targets, NULL, cJSON_CreateObject());
        cr_glb_add_num(g, target, "POSITION",
                       put_accessor(g, b, d, s.nv, "VEC3", 3, CT_F32, TARGET_ARRAY, 1));
        w[(int64_t)t * T + t] = 1.0f;
    }
    if (st == CR_OK) {
        cJSON *gn = cr_glb_add(g, nodes, NULL, cJSON_CreateObject());
        cr_glb_add(g, gn, "name", cJSON_CreateString("garment"));
        cr_glb_add_num(g, gn, "mesh", 1);
        cJSON *anim =
            cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(g->root, "animations"), 0);
        cJSON *samplers = cJSON_GetObjectItemCaseSensitive(anim, "samplers");
        cJSON *smp = cr_glb_add(g, samplers, NULL, cJSON_CreateObject());
        cr_glb_add_num(g, smp, "input", times);
        cr_glb_add_num(g, smp, "output",
                       put_accessor(g, b, w, (int64_t)T * T, "SCALAR", 1, CT_F32, 0, 0));
        cr_glb_add(g, smp, "interpolation", cJSON_CreateString("LINEAR"));
        cJSON *ch = cr_glb_add(g, cJSON_GetObjectItemCaseSensitive(anim, "channels"), NULL,
                               cJSON_CreateObject());
        cr_glb_add_num(g, ch, "sampler", cJSON_GetArraySize(samplers) - 1);
        cJSON *target = cr_glb_add(g, ch, "target", cJSON_CreateObject());
        cr_glb_add_num(g, target, "node", node);
        cr_glb_add(g, target, "path", cJSON_CreateString("weights"));
    }
    free(d), free(w);
    cr_mesh_seams_free(&s);
    return st;
}

static cr_status write_file(const char *path, const char *json, const bin_buf *b, cr_error *err) {
    cr_atomic_file f;
    CR_TRY(cr_glb_begin_file(path, json, b->len, &f, err));
    if (fwrite(b->d, 1, b->len, f.fp) != b->len) {
        cr_atomic_abort(&f);
        return CR_FAIL(err, CR_ERR_IO, "%s: write failed", path);
    }
    return cr_atomic_commit(&f, err);
}

cr_status cr_glb_write_skinned(const char *path, const cr_mesh *rest, const cr_glb_skin *skin,
                               const cr_glb_skin_motion *motion, const cr_glb_cloth *cloth,
                               cr_error *err) {
    CR_TRY(check_skin(path, rest, skin, motion, err));
    if (cloth) {
        CR_TRY(cr_mesh_validate(cloth->rest, path, err));
        for (int64_t i = 0; i < (int64_t)motion->nframes * cloth->rest->nv * 3; i++)
            if (!isfinite(cloth->frames[i]))
                return CR_FAIL(err, CR_ERR_NAN, "%s: garment frame %lld vertex %lld is not finite",
                               path, (long long)(i / (3 * (int64_t)cloth->rest->nv)),
                               (long long)(i / 3 % cloth->rest->nv));
    }
    cr_mesh_seams s;
    CR_TRY(cr_mesh_split_seams(rest, &s, err));
    glb_out g = {0};
    bin_buf b = {0};
    g.root = cJSON_CreateObject();
    g.views = cJSON_CreateArray();
    g.accessors = cJSON_CreateArray();
    cr_status st = g.root && g.views && g.accessors ? CR_OK : CR_ERR_MEMORY;
    if (st == CR_OK) {
        cJSON *asset = cr_glb_add(&g, g.root, "asset", cJSON_CreateObject());
        cr_glb_add(&g, asset, "version", cJSON_CreateString("2.0"));
        cr_glb_add(&g, asset, "generator", cJSON_CreateString("crease"));
        cr_glb_add_num(&g, g.root, "scene", 0);
        cJSON *scene = cr_glb_add(&g, cr_glb_add(&g, g.root, "scenes", cJSON_CreateArray()), NULL,
                                  cJSON_CreateObject());
        cJSON *roots = cr_glb_add(&g, scene, "nodes", cJSON_CreateArray());
        cr_glb_add_num(&g, roots, NULL, 0);
        for (int32_t j = 0; j < skin->njoints; j++)
            if (skin->parent[j] < 0) cr_glb_add_num(&g, roots, NULL, 1 + j);
        if (cloth) cr_glb_add_num(&g, roots, NULL, 1 + skin->njoints);
        cJSON *nodes = cr_glb_add(&g, g.root, "nodes", cJSON_CreateArray());
        cJSON *node = cr_glb_add(&g, nodes, NULL, cJSON_CreateObject());
        cr_glb_add(&g, node, "name", cJSON_CreateString("body"));
        cr_glb_add_num(&g, node, "mesh", 0);
        cr_glb_add_num(&g, node, "skin", 0);
        cJSON *mesh = cr_glb_add(&g, cr_glb_add(&g, g.root, "meshes", cJSON_CreateArray()), NULL,
                                 cJSON_CreateObject());
        cr_glb_add(&g, mesh, "name", cJSON_CreateString("body"));
        cJSON *prim = cr_glb_add(&g, cr_glb_add(&g, mesh, "primitives", cJSON_CreateArray()), NULL,
                                 cJSON_CreateObject());
        st = put_mesh(&g, &b, rest, &s, skin, prim, err);
        int times = 0;
        if (st == CR_OK) st = put_skeleton(&g, &b, skin, motion, nodes, &times, err);
        if (st == CR_OK && cloth)
            st = put_cloth(&g, &b, cloth, motion->nframes, times, 1 + skin->njoints, nodes, err);
    }
    char *json = NULL;
    if (st == CR_OK) {
        cJSON *buffer = cr_glb_add(&g, cr_glb_add(&g, g.root, "buffers", cJSON_CreateArray()), NULL,
                                   cJSON_CreateObject());
        cr_glb_add_num(&g, buffer, "byteLength", (double)b.len);
        cr_glb_add(&g, g.root, "bufferViews", g.views);
        cr_glb_add(&g, g.root, "accessors", g.accessors);
        g.views = g.accessors = NULL; /* the root owns them now */
        json = g.oom || b.oom ? NULL : cJSON_PrintUnformatted(g.root);
        if (!json) st = CR_FAIL(err, CR_ERR_MEMORY, "%s: out of memory building the file", path);
    }
    if (st == CR_OK) st = write_file(path, json, &b, err);
    cJSON_free(json);
    cJSON_Delete(g.root);
    cJSON_Delete(g.views);
    cJSON_Delete(g.accessors);
    free(b.d);
    cr_mesh_seams_free(&s);
    return st;
}

/* ============================================================ evaluation == */

/* 4x4 column-major matrices in double. */
static void mat_mul(const double *a, const double *b, double *out) {
    double r[16];
    for (int c = 0; c < 4; c++)
        for (int row = 0; row < 4; row++) {
            double s = 0.0;
            for (int k = 0; k < 4; k++)
                s += a[4 * k + row] * b[4 * c + k];
            r[4 * c + row] = s;
        }
    memcpy(out, r, sizeof r);
}

/* T R S as a column-major matrix; q = x, y, z, w (normalised here). */
static void trs_matrix(const double *t, const double *q, const double *s, double *m) {
    double n = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    double x = n > 0 ? q[0] / n : 0, y = n > 0 ? q[1] / n : 0, z = n > 0 ? q[2] / n : 0,
           w = n > 0 ? q[3] / n : 1;
    double R[9] = {1 - 2 * (y * y + z * z), 2 * (x * y + z * w),     2 * (x * z - y * w),
                   2 * (x * y - z * w),     1 - 2 * (x * x + z * z), 2 * (y * z + x * w),
                   2 * (x * z + y * w),     2 * (y * z - x * w),     1 - 2 * (x * x + y * y)};
    for (int c = 0; c < 3; c++) {
        for (int r = 0; r < 3; r++)
            m[4 * c + r] = R[3 * c + r] * s[c];
        m[4 * c + 3] = 0.0;
    }
    m[12] = t[0], m[13] = t[1], m[14] = t[2], m[15] = 1.0;
}

/* One node's rest transform: matrix, or T, R, S (defaults 0, identity, 1). */
typedef struct node_trs {
    double t[3], r[4], s[3];
    double matrix[16];
    int has_matrix;
    int parent; /* -1 for a root */
    int depth;  /* ancestors above it */
} node_trs;

static cr_status read_vec(const glb_in *g, const cJSON *node, const char *key, int n, double *out,
                          int64_t index, cr_error *err) {
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(node, key);
    if (!v) return CR_OK;
    if (!cJSON_IsArray(v) || cJSON_GetArraySize(v) != n)
        return CR_FAIL(err, CR_ERR_PARSE, "%s: nodes[%lld].%s: expected %d numbers", g->source,
                       (long long)index, key, n);
    for (int k = 0; k < n; k++) {
        const cJSON *e = cJSON_GetArrayItem(v, k);
        if (!cJSON_IsNumber(e) || !isfinite(e->valuedouble))
            return CR_FAIL(err, CR_ERR_PARSE, "%s: nodes[%lld].%s[%d]: expected a finite number",
                           g->source, (long long)index, key, k);
        out[k] = e->valuedouble;
    }
    return CR_OK;
}

/* The nodes' rest transforms and parents into nt (n), and order (n) the
 * nodes with every parent before its children. */
static cr_status read_nodes(const glb_in *g, const cJSON *nodes, node_trs *nt, int64_t n,
                            int32_t *order, cr_error *err) {
    for (int64_t i = 0; i < n; i++) {
        node_trs *p = &nt[i];
        memset(p, 0, sizeof *p);
        p->r[3] = 1.0, p->s[0] = p->s[1] = p->s[2] = 1.0, p->parent = -1;
    }
    for (int64_t i = 0; i < n; i++) {
        const cJSON *node = cr_glb_json_at(nodes, (uint64_t)i);
        node_trs *p = &nt[i];
        CR_TRY(read_vec(g, node, "translation", 3, p->t, i, err));
        CR_TRY(read_vec(g, node, "rotation", 4, p->r, i, err));
        CR_TRY(read_vec(g, node, "scale", 3, p->s, i, err));
        if (cJSON_GetObjectItemCaseSensitive(node, "matrix")) {
            CR_TRY(read_vec(g, node, "matrix", 16, p->matrix, i, err));
            p->has_matrix = 1;
        }
        const cJSON *ch = cJSON_GetObjectItemCaseSensitive(node, "children");
        for (int k = 0; cJSON_IsArray(ch) && k < cJSON_GetArraySize(ch); k++) {
            const cJSON *c = cJSON_GetArrayItem(ch, k);
            if (!cJSON_IsNumber(c) || c->valuedouble < 0 || c->valuedouble >= (double)n ||
                c->valuedouble != floor(c->valuedouble) ||
                nt[(int64_t)c->valuedouble].parent >= 0 || (int64_t)c->valuedouble == i)
                return CR_FAIL(err, CR_ERR_PARSE,
                               "%s: nodes[%lld].children[%d]: not a node, or a node with two "
                               "parents",
                               g->source, (long long)i, k);
            nt[(int64_t)c->valuedouble].parent = (int)i;
        }
    }
    int64_t count[MAX_NODE_DEPTH + 2] = {0}; /* nodes per depth, then where each depth starts */
    for (int64_t i = 0; i < n; i++) {        /* a cycle has no root: its walk never ends */
        int depth = 0;
        for (int p = nt[i].parent; p >= 0; p = nt[p].parent)
            if (++depth > MAX_NODE_DEPTH)
                return CR_FAIL(err, CR_ERR_PARSE,
                               "%s: nodes[%lld]: the hierarchy is cyclic or "
                               "deeper than %d",
                               g->source, (long long)i, MAX_NODE_DEPTH);
        nt[i].depth = depth;
        count[depth + 1]++;
    }
    for (int d = 1; d <= MAX_NODE_DEPTH + 1; d++)
        count[d] += count[d - 1];
    for (int64_t i = 0; i < n; i++) /* by depth: parents first */
        order[count[nt[i].depth]++] = (int32_t)i;
    return CR_OK;
}

/* One animation channel: a node's path, keys and values. */
typedef struct channel {
    int node, path; /* path: 0 translation, 1 rotation, 2 scale */
    int step;       /* STEP interpolation */
    int64_t nkeys;
    float *time, *value; /* (K), (K, 3 or 4) */
} channel;

static cr_status read_channel(const glb_in *g, const cJSON *anim, const cJSON *ch, int64_t nnodes,
                              channel *out, int *used, cr_error *err) {
    *used = 0;
    const cJSON *target = cJSON_GetObjectItemCaseSensitive(ch, "target");
    const char *path = cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(target, "path"));
    int kind = !path                          ? -1
               : !strcmp(path, "translation") ? 0
               : !strcmp(path, "rotation")    ? 1
               : !strcmp(path, "scale")       ? 2
                                              : -1;
    if (kind < 0 || !cJSON_GetObjectItemCaseSensitive(target, "node")) return CR_OK; /* weights */
    uint64_t node, si, in, outi;
    CR_TRY(cr_glb_json_uint(g, target, "animations[0].channels[].target", "node", 1, 0,
                            (uint64_t)nnodes - 1, &node, err));
    CR_TRY(
        cr_glb_json_uint(g, ch, "animations[0].channels[]", "sampler", 1, 0, INT32_MAX, &si, err));
    const cJSON *smp = cr_glb_json_at(cJSON_GetObjectItemCaseSensitive(anim, "samplers"), si);
    if (!smp)
        return CR_FAIL(err, CR_ERR_PARSE, "%s: animations[0].samplers[%llu] does not exist",
                       g->source, (unsigned long long)si);
    const char *interp =
        cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(smp, "interpolation"));
    if (interp && strcmp(interp, "LINEAR") && strcmp(interp, "STEP"))
        return CR_FAIL(err, CR_ERR_UNSUPPORTED,
                       "%s: animations[0].samplers[%llu]: %s interpolation (LINEAR and STEP are "
                       "read)",
                       g->source, (unsigned long long)si, interp);
    CR_TRY(
        cr_glb_json_uint(g, smp, "animations[0].samplers[]", "input", 1, 0, INT32_MAX, &in, err));
    CR_TRY(cr_glb_json_uint(g, smp, "animations[0].samplers[]", "output", 1, 0, INT32_MAX, &outi,
                            err));
    glb_acc ta, va;
    CR_TRY(cr_glb_accessor(g, in, &ta, err));
    CR_TRY(cr_glb_accessor(g, outi, &va, err));
    const int nc = kind == 1 ? 4 : 3;
    if (ta.ctype != CT_F32 || ta.ncomp != 1 || va.ctype != CT_F32 || va.ncomp != nc ||
        va.count != ta.count || ta.count < 1)
        return CR_FAIL(err, CR_ERR_UNSUPPORTED,
                       "%s: animations[0].samplers[%llu]: expected float keys and float VEC%d "
                       "values of the same count",
                       g->source, (unsigned long long)si, nc);
    out->node = (int)node, out->path = kind, out->nkeys = ta.count;
    out->step = interp && !strcmp(interp, "STEP");
    *used = 1; /* the caller frees what is allocated from here on */
    out->time = cr_malloc((size_t)ta.count * sizeof(float), err);
    out->value = cr_malloc((size_t)ta.count * (size_t)nc * sizeof(float), err);
    if (!out->time || !out->value) return CR_ERR_MEMORY;
    CR_TRY(cr_glb_read_floats(g, &ta, "animation keys", out->time, err));
    for (int64_t k = 1; k < ta.count; k++)
        if (!(out->time[k] > out->time[k - 1]))
            return CR_FAIL(err, CR_ERR_PARSE,
                           "%s: animations[0].samplers[%llu]: key times must increase", g->source,
                           (unsigned long long)si);
    return cr_glb_read_floats(g, &va, "animation values", out->value, err);
}

/* The channel's value at time t into v (3 or 4; rotations slerped). */
static void sample(const channel *c, double t, double *v) {
    const int nc = c->path == 1 ? 4 : 3;
    int64_t k = 0;
    while (k + 1 < c->nkeys && c->time[k + 1] <= t)
        k++;
    const float *a = c->value + nc * k;
    if (c->step || k + 1 >= c->nkeys || t <= c->time[0]) {
        for (int i = 0; i < nc; i++)
            v[i] = a[i];
        return;
    }
    const float *b = c->value + nc * (k + 1);
    const double u = (t - c->time[k]) / ((double)c->time[k + 1] - c->time[k]);
    if (nc == 3) {
        for (int i = 0; i < 3; i++)
            v[i] = a[i] + u * (b[i] - a[i]);
        return;
    }
    double d = 0.0, bb[4];
    for (int i = 0; i < 4; i++)
        d += (double)a[i] * b[i];
    for (int i = 0; i < 4; i++)
        bb[i] = d < 0 ? -b[i] : b[i];
    d = fabs(d);
    double wa = 1.0 - u, wb = u;
    if (d < 0.9995) {
        double th = acos(d), sn = sin(th);
        wa = sin((1.0 - u) * th) / sn, wb = sin(u * th) / sn;
    }
    for (int i = 0; i < 4; i++)
        v[i] = wa * a[i] + wb * bb[i];
}

/* A skinned primitive ready to evaluate: the node tree, the skin's joints
 * and inverse bind matrices, and each vertex's four joints and weights. */
typedef struct skin_eval {
    int64_t nn, J, nraw;
    node_trs *nt;    /* (nn) rest transforms */
    double *world;   /* (nn,16) scratch: world matrices */
    int32_t *order;  /* (nn) parents first */
    double *jm;      /* (J,16) scratch: skinning matrices */
    float *ibm;      /* (J,16) */
    int32_t *jnode;  /* (J) each joint's node */
    int32_t *vj;     /* (nraw,4) */
    float *vw;       /* (nraw,4) */
    uint64_t skin_i; /* the skin's index, for messages */
    const cJSON *skin;
} skin_eval;

static void skin_eval_free(skin_eval *e) {
    free(e->nt), free(e->world), free(e->order), free(e->jm), free(e->ibm), free(e->jnode),
        free(e->vj), free(e->vw);
    memset(e, 0, sizeof *e);
}

static cr_status skin_open(const glb_in *g, const cJSON *prim, int64_t nraw, skin_eval *e,
                           cr_error *err) {
    memset(e, 0, sizeof *e);
    const cJSON *nodes = cJSON_GetObjectItemCaseSensitive(g->root, "nodes");
    const int64_t nn = cJSON_IsArray(nodes) ? cJSON_GetArraySize(nodes) : 0;
    int64_t mesh_node = -1;
    for (int64_t i = 0; i < nn && mesh_node < 0; i++) {
        const cJSON *node = cr_glb_json_at(nodes, (uint64_t)i);
        const cJSON *mi = cJSON_GetObjectItemCaseSensitive(node, "mesh");
        if (cJSON_IsNumber(mi) && mi->valuedouble == 0 &&
            cJSON_GetObjectItemCaseSensitive(node, "skin"))
            mesh_node = i;
    }
    if (mesh_node < 0)
        return CR_FAIL(err, CR_ERR_PARSE, "%s: no node draws the skinned mesh", g->source);
    uint64_t skin_i;
    CR_TRY(cr_glb_json_uint(g, cr_glb_json_at(nodes, (uint64_t)mesh_node), "nodes[]", "skin", 1, 0,
                            INT32_MAX, &skin_i, err));
    const cJSON *skin = cr_glb_json_at(cJSON_GetObjectItemCaseSensitive(g->root, "skins"), skin_i);
    const cJSON *joints = cJSON_GetObjectItemCaseSensitive(skin, "joints");
    const int64_t J = cJSON_IsArray(joints) ? cJSON_GetArraySize(joints) : 0;
    if (J < 1 || J > CR_GLB_MAX_JOINTS)
        return CR_FAIL(err, CR_ERR_PARSE, "%s: skins[%llu].joints: expected 1 to %d joints",
                       g->source, (unsigned long long)skin_i, CR_GLB_MAX_JOINTS);
    const cJSON *attrs = cJSON_GetObjectItemCaseSensitive(prim, "attributes");
    uint64_t ji, wi;
    CR_TRY(cr_glb_json_uint(g, attrs, "attributes", "JOINTS_0", 1, 0, INT32_MAX, &ji, err));
    CR_TRY(cr_glb_json_uint(g, attrs, "attributes", "WEIGHTS_0", 1, 0, INT32_MAX, &wi, err));
    glb_acc ja, wa;
    CR_TRY(cr_glb_accessor(g, ji, &ja, err));
    CR_TRY(cr_glb_accessor(g, wi, &wa, err));
    if (ja.ncomp != 4 || (ja.ctype != CT_U8 && ja.ctype != CT_U16) || ja.count != nraw ||
        wa.ncomp != 4 || wa.ctype != CT_F32 || wa.count != nraw)
        return CR_FAIL(err, CR_ERR_UNSUPPORTED,
                       "%s: JOINTS_0 (u8/u16 VEC4) and WEIGHTS_0 (float VEC4) of %lld vertices "
                       "expected",
                       g->source, (long long)nraw);
    const size_t nn1 = (size_t)(nn > 0 ? nn : 1);
    e->nn = nn, e->J = J, e->nraw = nraw, e->skin_i = skin_i, e->skin = skin;
    e->nt = cr_malloc(nn1 * sizeof *e->nt, err);
    e->world = cr_malloc(nn1 * 16 * sizeof(double), err);
    e->order = cr_malloc(nn1 * sizeof(int32_t), err);
    e->jm = cr_malloc((size_t)J * 16 * sizeof(double), err);
    e->ibm = cr_malloc((size_t)J * 16 * sizeof(float), err);
    e->jnode = cr_malloc((size_t)J * sizeof(int32_t), err);
    e->vj = cr_malloc((size_t)nraw * 4 * sizeof(int32_t), err);
    e->vw = cr_malloc((size_t)nraw * 4 * sizeof(float), err);
    cr_status st = e->nt && e->world && e->order && e->jm && e->ibm && e->jnode && e->vj && e->vw
                       ? CR_OK
                       : CR_ERR_MEMORY;
    if (st == CR_OK) st = read_nodes(g, nodes, e->nt, nn, e->order, err);
    for (int64_t j = 0; st == CR_OK && j < J; j++) {
        const cJSON *c = cJSON_GetArrayItem(joints, (int)j);
        if (!cJSON_IsNumber(c) || c->valuedouble < 0 || c->valuedouble >= (double)nn ||
            c->valuedouble != floor(c->valuedouble))
            st = CR_FAIL(err, CR_ERR_PARSE, "%s: skins[%llu].joints[%lld]: not a node", g->source,
                         (unsigned long long)skin_i, (long long)j);
        else
            e->jnode[j] = (int32_t)c->valuedouble;
    }
    if (st == CR_OK) {
        uint64_t bi;
        if (cJSON_GetObjectItemCaseSensitive(skin, "inverseBindMatrices")) {
            glb_acc ba;
            st = cr_glb_json_uint(g, skin, "skins[]", "inverseBindMatrices", 1, 0, INT32_MAX, &bi,
                                  err);
            if (st == CR_OK) st = cr_glb_accessor(g, bi, &ba, err);
            if (st == CR_OK && (ba.ctype != CT_F32 || ba.ncomp != 16 || ba.count != J))
                st = CR_FAIL(err, CR_ERR_PARSE, "%s: inverseBindMatrices: expected %lld float MAT4",
                             g->source, (long long)J);
            if (st == CR_OK) st = cr_glb_read_floats(g, &ba, "inverseBindMatrices", e->ibm, err);
        } else {
            for (int64_t j = 0; j < J; j++)
                for (int k = 0; k < 16; k++)
                    e->ibm[16 * j + k] = k % 5 == 0;
        }
    }
    for (int64_t i = 0; st == CR_OK && i < nraw; i++)
        for (int k = 0; k < 4; k++) {
            const unsigned char *p = ja.base + (uint64_t)i * ja.stride;
            e->vj[4 * i + k] = ja.ctype == CT_U8 ? p[k] : (int32_t)io_load(p + 2 * k, 2, 0);
            e->vw[4 * i + k] = io_f32(io_le32(wa.base + (uint64_t)i * wa.stride + 4 * (uint64_t)k));
            if (e->vj[4 * i + k] >= J || !isfinite(e->vw[4 * i + k]))
                st = CR_FAIL(err, CR_ERR_PARSE, "%s: vertex %lld: joint %d of %lld, or weight %g",
                             g->source, (long long)i, e->vj[4 * i + k], (long long)J,
                             (double)e->vw[4 * i + k]);
        }
    if (st != CR_OK) skin_eval_free(e);
    return st;
}

/* World matrices of every node posed by cur (nn), parents first. */
static void node_worlds(skin_eval *e, const node_trs *cur) {
    for (int64_t k = 0; k < e->nn; k++) { /* world = parent's world x local, parents first */
        const int64_t i = e->order[k];
        double *w = &e->world[16 * i];
        if (cur[i].has_matrix)
            memcpy(w, cur[i].matrix, 16 * sizeof(double));
        else
            trs_matrix(cur[i].t, cur[i].r, cur[i].s, w);
        if (cur[i].parent >= 0) mat_mul(&e->world[16 * (int64_t)cur[i].parent], w, w);
    }
}

/* node_worlds, and the skin's matrices: each joint's world times its inverse bind matrix. */
static void skin_matrices(skin_eval *e, const node_trs *cur) {
    node_worlds(e, cur);
    for (int64_t j = 0; j < e->J; j++) {
        double b[16];
        for (int k = 0; k < 16; k++)
            b[k] = e->ibm[16 * j + k];
        mat_mul(&e->world[16 * (int64_t)e->jnode[j]], b, &e->jm[16 * j]);
    }
}

/* Linear blend skinning: dst (n,3) = sum_k w_k M_{j_k} x over each vertex's
 * four joints (vj, vw (n,4)), jm (J,16) column-major. */
static void blend(const float *x, int64_t n, const int32_t *vj, const float *vw, const double *jm,
                  float *dst) {
    for (int64_t i = 0; i < n; i++) {
        const float *v = x + 3 * i;
        double p[3] = {0, 0, 0};
        for (int k = 0; k < 4; k++) {
            const double w = vw[4 * i + k];
            if (w == 0.0) continue;
            const double *m = &jm[16 * (int64_t)vj[4 * i + k]];
            for (int r = 0; r < 3; r++)
                p[r] += w * (m[r] * v[0] + m[4 + r] * v[1] + m[8 + r] * v[2] + m[12 + r]);
        }
        for (int r = 0; r < 3; r++)
            dst[3 * i + r] = (float)p[r];
    }
}

/* animations[0]'s node channels, to be sampled frame by frame. */
typedef struct anim_clip {
    channel *ch;
    int used;    /* channels read (weights channels are skipped) */
    double t0;   /* the first key's time, s (0 without channels) */
    double rate; /* frames a second: the first channel's key spacing (crease writes one key a
                    frame), 30 without two keys */
    int64_t T;   /* frames over the channels' time range; 1 without an animation */
} anim_clip;

static void anim_clip_free(anim_clip *a) {
    for (int c = 0; a->ch && c < a->used; c++)
        free(a->ch[c].time), free(a->ch[c].value);
    free(a->ch);
    memset(a, 0, sizeof *a);
}

/* Read the channels of nodes among nn; per_frame: values a frame costs (`what`: "vertices",
 * "joints"), for the cap on what a file may ask for. */
static cr_status anim_clip_open(const glb_in *g, int64_t nn, int64_t per_frame, const char *what,
                                anim_clip *a, cr_error *err) {
    memset(a, 0, sizeof *a);
    a->rate = 30.0, a->T = 1;
    const cJSON *anim = cr_glb_json_at(cJSON_GetObjectItemCaseSensitive(g->root, "animations"), 0);
    const cJSON *chs = cJSON_GetObjectItemCaseSensitive(anim, "channels");
    const int nch = cJSON_IsArray(chs) ? cJSON_GetArraySize(chs) : 0;
    if (!(a->ch = cr_calloc((size_t)(nch > 0 ? nch : 1), sizeof *a->ch, err))) return CR_ERR_MEMORY;
    double t0 = INFINITY, t1 = -INFINITY;
    cr_status st = CR_OK;
    for (int c = 0; st == CR_OK && c < nch; c++) {
        int ok = 0;
        st = read_channel(g, anim, cJSON_GetArrayItem(chs, c), nn, &a->ch[a->used], &ok, err);
        if (st == CR_OK && ok)
            t0 = fmin(t0, a->ch[a->used].time[0]),
            t1 = fmax(t1, a->ch[a->used].time[a->ch[a->used].nkeys - 1]);
        a->used += ok; /* what it allocated is freed by anim_clip_free either way */
    }
    for (int c = 0; c < a->used && st == CR_OK; c++)
        if (a->ch[c].nkeys >= 2) {
            a->rate = cr_glb_key_rate(a->ch[c].time[0], a->ch[c].time[1]);
            break;
        }
    if (st == CR_OK && a->used > 0 && t1 > t0) {
        const double nf = floor((t1 - t0) * a->rate + 1e-6) + 1.0;
        if (!(nf <= MAX_SKIN_FRAMES) || nf * (double)per_frame > (double)MAX_SKIN_VALUES)
            st = CR_FAIL(err, CR_ERR_RANGE,
                         "%s: the animation asks for %.0f frames of %lld %s (at most %d "
                         "frames, %lld values)",
                         g->source, nf, (long long)per_frame, what, MAX_SKIN_FRAMES,
                         (long long)MAX_SKIN_VALUES);
        a->T = (int64_t)nf, a->t0 = t0;
    }
    if (st != CR_OK) anim_clip_free(a);
    return st;
}

/* cur (nn) = the nodes' rest transforms with the channels' values at frame f. */
static void anim_clip_pose(const anim_clip *a, const node_trs *rest, int64_t nn, int64_t f,
                           node_trs *cur) {
    const double t = a->t0 + (double)f / a->rate;
    memcpy(cur, rest, (size_t)nn * sizeof *cur);
    for (int c = 0; c < a->used; c++) {
        double v[4];
        sample(&a->ch[c], t, v);
        node_trs *p = &cur[a->ch[c].node];
        memcpy(a->ch[c].path == 0   ? p->t
               : a->ch[c].path == 1 ? p->r
                                    : p->s,
               v, (a->ch[c].path == 1 ? 4 : 3) * sizeof(double));
        p->has_matrix = 0; /* an animated node is TRS (glTF 3.11) */
    }
}

cr_status cr_glb_skin_frames(const glb_in *g, const cJSON *prim, const float *raw, int64_t nraw,
                             float **frames, int32_t *nframes, float *fps, cr_error *err) {
    *frames = NULL, *nframes = 0;
    skin_eval e;
    CR_TRY(skin_open(g, prim, nraw, &e, err));
    const int64_t nn = e.nn;
    anim_clip a;
    cr_status st = anim_clip_open(g, nn, nraw, "vertices", &a, err);
    const int64_t T = a.T;
    float *out = NULL;
    if (st == CR_OK && !(out = cr_malloc((size_t)T * (size_t)nraw * 3 * sizeof(float), err)))
        st = CR_ERR_MEMORY;
    node_trs *cur = st == CR_OK ? cr_malloc((size_t)(nn > 0 ? nn : 1) * sizeof *cur, err) : NULL;
    if (st == CR_OK && !cur) st = CR_ERR_MEMORY;
    for (int64_t f = 0; st == CR_OK && f < T; f++) {
        anim_clip_pose(&a, e.nt, nn, f, cur);
        skin_matrices(&e, cur);
        blend(raw, nraw, e.vj, e.vw, e.jm, out + f * nraw * 3);
    }
    const double rate = a.rate;
    free(cur);
    anim_clip_free(&a);
    skin_eval_free(&e);
    if (st != CR_OK) {
        free(out);
        return st;
    }
    *frames = out;
    *nframes = (int32_t)T;
    *fps = (float)rate;
    return CR_OK;
}

/* ============================================================ characters == */

void cr_glb_character_destroy(cr_glb_character *c) {
    if (!c) return;
    if (c->skin.joint_name)
        for (int32_t j = 0; j < c->skin.njoints; j++)
            free((void *)c->skin.joint_name[j]);
    free((void *)c->skin.joint_name), free((void *)c->skin.parent);
    free((void *)c->skin.rest_joint), free((void *)c->skin.skin_joint);
    free((void *)c->skin.skin_weight);
    free((void *)c->anim.rotation), free((void *)c->anim.position);
    cr_mesh_destroy(c->rest);
    free(c);
}

/* The rotation of a column-major 4x4 with its columns' scale taken out (3x3 column-major). */
static void mat_rotation(const double *m, double *r) {
    for (int c = 0; c < 3; c++) {
        const double n =
            sqrt(m[4 * c] * m[4 * c] + m[4 * c + 1] * m[4 * c + 1] + m[4 * c + 2] * m[4 * c + 2]);
        for (int k = 0; k < 3; k++)
            r[3 * c + k] = n > 0.0 ? m[4 * c + k] / n : (double)(c == k);
    }
}

/* The unit quaternion (x, y, z, w) of a 3x3 column-major rotation (Shepperd's method). */
static void rotation_quat(const double *r, float *q) {
#define R(row, col) r[3 * (col) + (row)]
    const double tr = R(0, 0) + R(1, 1) + R(2, 2);
    double x, y, z, w;
    if (tr > 0.0) {
        const double s = 2.0 * sqrt(tr + 1.0);
        w = 0.25 * s, x = (R(2, 1) - R(1, 2)) / s, y = (R(0, 2) - R(2, 0)) / s,
        z = (R(1, 0) - R(0, 1)) / s;
    } else if (R(0, 0) > R(1, 1) && R(0, 0) > R(2, 2)) {
        const double s = 2.0 * sqrt(1.0 + R(0, 0) - R(1, 1) - R(2, 2));
        w = (R(2, 1) - R(1, 2)) / s, x = 0.25 * s, y = (R(0, 1) + R(1, 0)) / s,
        z = (R(0, 2) + R(2, 0)) / s;
    } else if (R(1, 1) > R(2, 2)) {
        const double s = 2.0 * sqrt(1.0 + R(1, 1) - R(0, 0) - R(2, 2));
        w = (R(0, 2) - R(2, 0)) / s, x = (R(0, 1) + R(1, 0)) / s, y = 0.25 * s,
        z = (R(1, 2) + R(2, 1)) / s;
    } else {
        const double s = 2.0 * sqrt(1.0 + R(2, 2) - R(0, 0) - R(1, 1));
        w = (R(1, 0) - R(0, 1)) / s, x = (R(0, 2) + R(2, 0)) / s, y = (R(1, 2) + R(2, 1)) / s,
        z = 0.25 * s;
    }
#undef R
    const double n = sqrt(x * x + y * y + z * z + w * w);
    q[0] = (float)(x / n), q[1] = (float)(y / n), q[2] = (float)(z / n), q[3] = (float)(w / n);
}

/* The skeleton's own animation into c->anim: e posed at each frame of animations[0], each
 * joint's (order: new -> skin) world position and world rotation from its rest's. */
static cr_status joint_anim(const glb_in *g, skin_eval *e, const int32_t *order,
                            cr_glb_character *c, cr_error *err) {
    const int64_t J = e->J, nn = e->nn;
    anim_clip a;
    CR_TRY(anim_clip_open(g, nn, 7 * J, "joint values", &a, err)); /* 4 + 3 floats a joint */
    const int64_t T = a.T;
    float *rot = cr_malloc((size_t)T * (size_t)J * 4 * sizeof(float), err);
    float *pos = cr_malloc((size_t)T * (size_t)J * 3 * sizeof(float), err);
    double *rest = cr_malloc((size_t)J * 9 * sizeof(double), err);
    node_trs *cur = cr_malloc((size_t)(nn > 0 ? nn : 1) * sizeof *cur, err);
    cr_status st = rot && pos && rest && cur ? CR_OK : CR_ERR_MEMORY;
    if (st == CR_OK) {
        node_worlds(e, e->nt);
        for (int64_t i = 0; i < J; i++)
            mat_rotation(&e->world[16 * (int64_t)e->jnode[order[i]]], &rest[9 * i]);
    }
    for (int64_t f = 0; st == CR_OK && f < T; f++) {
        anim_clip_pose(&a, e->nt, nn, f, cur);
        node_worlds(e, cur);
        for (int64_t i = 0; i < J; i++) {
            const double *w = &e->world[16 * (int64_t)e->jnode[order[i]]], *b = &rest[9 * i];
            double r[9], rel[9]; /* rel = R_f R_rest^T */
            mat_rotation(w, r);
            for (int col = 0; col < 3; col++)
                for (int row = 0; row < 3; row++)
                    rel[3 * col + row] =
                        r[row] * b[col] + r[3 + row] * b[3 + col] + r[6 + row] * b[6 + col];
            rotation_quat(rel, rot + 4 * (f * J + i));
            for (int k = 0; k < 3; k++)
                pos[3 * (f * J + i) + k] = (float)w[12 + k];
        }
    }
    if (st == CR_OK)
        c->anim = (cr_glb_skin_anim){(int32_t)T, (float)a.rate, a.used > 0, rot, pos};
    else
        free(rot), free(pos);
    free(rest), free(cur);
    anim_clip_free(&a);
    return st;
}

cr_status cr_glb_skin_rest(const glb_in *g, const cJSON *prim, const float *raw, int64_t nraw,
                           const int32_t *weld, cr_glb_character *c, cr_error *err) {
    skin_eval e;
    CR_TRY(skin_open(g, prim, nraw, &e, err));
    const int64_t J = e.J, nv = c->rest->nv;
    const cJSON *nodes = cJSON_GetObjectItemCaseSensitive(g->root, "nodes");
    int32_t *jidx = cr_malloc((size_t)(e.nn > 0 ? e.nn : 1) * sizeof(int32_t), err);
    int32_t *par = cr_malloc((size_t)J * sizeof(int32_t), err); /* skin order */
    int32_t *depth = cr_calloc((size_t)J, sizeof(int32_t), err);
    int32_t *order = cr_malloc((size_t)J * sizeof(int32_t), err); /* new -> skin */
    int32_t *inv = cr_malloc((size_t)J * sizeof(int32_t), err);   /* skin -> new */
    float *posed = cr_malloc((size_t)nraw * 3 * sizeof(float), err);
    char **names = cr_calloc((size_t)J, sizeof(char *), err);
    int32_t *parent = cr_malloc((size_t)J * sizeof(int32_t), err);
    float *rest_joint = cr_malloc((size_t)J * 3 * sizeof(float), err);
    int32_t *sj = cr_malloc((size_t)nv * 4 * sizeof(int32_t), err);
    float *sw = cr_malloc((size_t)nv * 4 * sizeof(float), err);
    cr_status st =
        jidx && par && depth && order && inv && posed && names && parent && rest_joint && sj && sw
            ? CR_OK
            : CR_ERR_MEMORY;
    c->skin = (cr_glb_skin){(int32_t)J, (const char *const *)names, parent, rest_joint, sj, sw};
    if (st != CR_OK) {
        free(names), free(parent), free(rest_joint), free(sj), free(sw);
        memset(&c->skin, 0, sizeof c->skin);
    }
    for (int64_t i = 0; st == CR_OK && i < e.nn; i++)
        jidx[i] = -1;
    for (int64_t j = 0; st == CR_OK && j < J; j++) {
        if (jidx[e.jnode[j]] >= 0)
            st = CR_FAIL(err, CR_ERR_PARSE, "%s: skins[%llu]: node %d is listed twice", g->source,
                         (unsigned long long)e.skin_i, e.jnode[j]);
        else
            jidx[e.jnode[j]] = (int32_t)j;
    }
    for (int64_t j = 0; st == CR_OK && j < J; j++) {
        int p = e.nt[e.jnode[j]].parent;
        while (p >= 0 && jidx[p] < 0)
            p = e.nt[p].parent;
        par[j] = p >= 0 ? jidx[p] : -1;
    }
    for (int64_t j = 0; st == CR_OK && j < J; j++) /* the node tree is acyclic (read_nodes) */
        for (int32_t p = par[j]; p >= 0; p = par[p])
            depth[j]++;
    if (st == CR_OK) { /* parents first: by depth, then the skin's order */
        int64_t k = 0;
        for (int32_t d = 0; k < J; d++)
            for (int64_t j = 0; j < J; j++)
                if (depth[j] == d) order[k++] = (int32_t)j;
        for (int64_t i = 0; i < J; i++)
            inv[order[i]] = (int32_t)i;
        skin_matrices(&e, e.nt); /* the nodes' rest */
        blend(raw, nraw, e.vj, e.vw, e.jm, posed);
    }
    for (int64_t i = 0; st == CR_OK && i < J; i++) {
        const int32_t j = order[i];
        const char *nm = cJSON_GetStringValue(
            cJSON_GetObjectItemCaseSensitive(cr_glb_json_at(nodes, (uint64_t)e.jnode[j]), "name"));
        char dflt[32];
        snprintf(dflt, sizeof dflt, "joint_%d", (int)j);
        if (!nm) nm = dflt;
        if (!(names[i] = cr_malloc(strlen(nm) + 1, err))) {
            st = CR_ERR_MEMORY;
            break;
        }
        memcpy(names[i], nm, strlen(nm) + 1);
        parent[i] = par[j] >= 0 ? inv[par[j]] : -1;
        for (int k = 0; k < 3; k++)
            rest_joint[3 * i + k] = (float)e.world[16 * (int64_t)e.jnode[j] + 12 + k];
    }
    for (int64_t r = nraw - 1; st == CR_OK && r >= 0; r--) { /* the first copy of each wins */
        const int64_t v = weld[r];
        double sum = 0.0;
        for (int k = 0; k < 3; k++)
            c->rest->pos[3 * v + k] = posed[3 * r + k];
        for (int k = 0; k < 4; k++) {
            sj[4 * v + k] = inv[e.vj[4 * r + k]];
            sw[4 * v + k] = e.vw[4 * r + k] > 0.0f ? e.vw[4 * r + k] : 0.0f;
            sum += sw[4 * v + k];
        }
        if (!(sum > 0.0))
            st = CR_FAIL(err, CR_ERR_PARSE, "%s: vertex %lld has no skin weight", g->source,
                         (long long)r);
        for (int k = 0; k < 4 && st == CR_OK; k++)
            sw[4 * v + k] = (float)(sw[4 * v + k] / sum);
    }
    if (st == CR_OK) st = joint_anim(g, &e, order, c, err);
    free(jidx), free(par), free(depth), free(order), free(inv), free(posed);
    skin_eval_free(&e);
    return st;
}

cr_status cr_glb_character_pose(const cr_glb_character *c, const cr_glb_skin_motion *m,
                                float **frames, cr_error *err) {
    *frames = NULL;
    const cr_glb_skin *s = &c->skin;
    const int64_t J = s->njoints, nv = c->rest->nv, T = m->nframes;
    if (T < 1 || T * nv > MAX_SKIN_VALUES)
        return CR_FAIL(err, CR_ERR_RANGE, "character: %lld frames of %lld vertices", (long long)T,
                       (long long)nv);
    double *world = cr_malloc((size_t)J * 16 * sizeof(double), err);
    double *jm = cr_malloc((size_t)J * 16 * sizeof(double), err);
    float *out = cr_malloc((size_t)T * (size_t)nv * 3 * sizeof(float), err);
    if (!world || !jm || !out) {
        free(world), free(jm), free(out);
        return CR_ERR_MEMORY;
    }
    static const double one[3] = {1, 1, 1};
    for (int64_t f = 0; f < T; f++) {
        for (int64_t j = 0; j < J; j++) { /* world-aligned rest frames, as the writer's files */
            const int32_t p = s->parent[j];
            double t[3], q[4], local[16];
            for (int k = 0; k < 3; k++)
                t[k] = s->rest_joint[3 * j + k] - (p >= 0 ? s->rest_joint[3 * p + k] : 0.0f) +
                       (p >= 0 ? 0.0 : m->translation[3 * f + k]);
            for (int k = 0; k < 4; k++)
                q[k] = m->rotation[4 * (f * J + j) + k];
            trs_matrix(t, q, one, local);
            if (p >= 0)
                mat_mul(&world[16 * p], local, &world[16 * j]);
            else
                memcpy(&world[16 * j], local, sizeof local);
            double ib[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
            for (int k = 0; k < 3; k++)
                ib[12 + k] = -s->rest_joint[3 * j + k];
            mat_mul(&world[16 * j], ib, &jm[16 * j]);
        }
        blend(c->rest->pos, nv, s->skin_joint, s->skin_weight, jm, out + f * nv * 3);
    }
    free(world), free(jm);
    *frames = out;
    return CR_OK;
}
