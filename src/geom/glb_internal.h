/* glb_internal.h: what io_glb.c (meshes and morph-target sequences) shares
 * with io_glb_skin.c (skinned, animated characters): the container, checked
 * accessors and the JSON writer's helpers. Private to src/geom. */
#ifndef CREASE_GEOM_GLB_INTERNAL_H
#define CREASE_GEOM_GLB_INTERNAL_H

#include "crease/base.h"
#include "crease/mesh_io.h"

#include <cjson/cJSON.h>
#include <stdint.h>

enum {
    GLB_MAGIC = 0x46546c67,      /* "glTF" */
    GLB_CHUNK_JSON = 0x4e4f534a, /* "JSON" */
    GLB_CHUNK_BIN = 0x004e4942,  /* "BIN\0" */
    CT_I8 = 5120,
    CT_U8 = 5121,
    CT_I16 = 5122,
    CT_U16 = 5123,
    CT_U32 = 5125,
    CT_F32 = 5126,
    TARGET_ARRAY = 34962,
    TARGET_ELEMENTS = 34963,
    MODE_TRIANGLES = 4
};

typedef struct glb_in {
    const char *source;
    cJSON *root;
    const unsigned char *bin; /* BIN chunk payload, NULL when absent */
    uint64_t bin_len;
    uint64_t buf_len; /* buffers[0].byteLength, <= bin_len */
} glb_in;

/* A checked accessor: element i is at base + i * stride. */
typedef struct glb_acc {
    int64_t count;
    int ctype, ncomp;
    const unsigned char *base;
    uint64_t stride;
} glb_acc;

/* The element i of a JSON array, or NULL. */
const cJSON *cr_glb_json_at(const cJSON *arr, uint64_t i);
/* obj[key] as an integer in [0, max]; `dflt` when absent and not `required`;
 * *out is 0 on failure. `where` names obj in messages. */
cr_status cr_glb_json_uint(const glb_in *g, const cJSON *obj, const char *where, const char *key,
                           int required, uint64_t dflt, uint64_t max, uint64_t *out, cr_error *err);
/* accessors[index], checked against its view, the buffer and the BIN chunk. */
cr_status cr_glb_accessor(const glb_in *g, uint64_t index, glb_acc *out, cr_error *err);
/* A float accessor's components into out (count, ncomp), refusing non-finite. */
cr_status cr_glb_read_floats(const glb_in *g, const glb_acc *a, const char *name, float *out,
                             cr_error *err);
/* Frames per second of keys at t0 < t1, 1 / (t1 - t0), the nearest whole
 * number when within 1e-4 of it (keys stored as i / fps in float). */
double cr_glb_key_rate(float t0, float t1);
/* Split a .glb's bytes into the parsed JSON (g->root, the caller deletes it)
 * and the BIN chunk. */
cr_status cr_glb_open_container(glb_in *g, const unsigned char *d, size_t len, cr_error *err);

/* The JSON under construction and the running BIN length. Every cJSON call
 * can fail on memory; `oom` collects that so the code reads straight. */
typedef struct glb_out {
    cJSON *root, *views, *accessors;
    int nviews, naccessors;
    uint64_t bin_len;
    int oom;
} glb_out;

/* Add item to parent (under key, or appended when key is NULL); NULL and
 * g->oom set when memory ran out. */
cJSON *cr_glb_add(glb_out *g, cJSON *parent, const char *key, cJSON *item);
void cr_glb_add_num(glb_out *g, cJSON *obj, const char *key, double v);
/* Open `path` atomically and write the GLB header, the JSON chunk (padded
 * with spaces) and the header of a BIN chunk of bin_len bytes; the caller
 * writes the bytes and commits f (on failure f is aborted). */
cr_status cr_glb_begin_file(const char *path, const char *json, uint64_t bin_len, cr_atomic_file *f,
                            cr_error *err);
/* An accessor's "min" and "max" over x (n, ncomp <= 16) floats. */
void cr_glb_add_minmax(glb_out *g, cJSON *acc, const float *x, int64_t n, int ncomp);
/* A morph-target sequence's mesh fields: "weights" one-hot on frame 0 (what
 * static viewers show) and "extras.targetNames" frame_0000, ... (Blender's
 * shape-key names). */
void cr_glb_add_frame_names(glb_out *g, cJSON *mesh, int32_t nframes);
/* Floats as JSON numbers that parse back to exactly these floats. */
cJSON *cr_glb_float_array(const float *x, int n);

/* The frames of meshes[0]'s skinned primitive `prim` under animations[0]
 * (io_glb_skin.c): raw (V',3) the file's positions, frames (T,V',3) out,
 * sampled at the first channel's key spacing over the animation's time range
 * (*fps that rate; one frame at the rest pose without an animation). */
cr_status cr_glb_skin_frames(const glb_in *g, const cJSON *prim, const float *raw, int64_t nraw,
                             float **frames, int32_t *nframes, float *fps, cr_error *err);

/* A skinned primitive's skeleton and skin at its nodes' rest pose into c
 * (io_glb_skin.c): joints ordered parents first (the nearest ancestor node
 * that is a joint is the parent), named by their nodes, rest_joint their
 * world positions; raw (nraw,3) the file's positions, weld (nraw) the
 * welded vertex of each, c->rest (already read, welded) gets the rest-posed
 * positions and c->skin the skin per welded vertex. */
cr_status cr_glb_skin_rest(const glb_in *g, const cJSON *prim, const float *raw, int64_t nraw,
                           const int32_t *weld, cr_glb_character *c, cr_error *err);

#endif
