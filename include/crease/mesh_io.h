/* crease/mesh_io.h: reading and writing meshes and point caches.
 *
 *   format                     read                       write
 *   OBJ (.obj)                 cr_obj_read[_mem]          cr_obj_write
 *   PLY (.ply)                 cr_ply_read[_mem]          cr_ply_write (binary LE or ASCII)
 *   glTF 2.0 binary (.glb)     cr_glb_read[_mem]          cr_glb_write, cr_glb_write_sequence
 *   PC2 point cache (.pc2)     cr_pc2_read[_mem]          cr_pc2_write
 *   by extension               cr_mesh_read               cr_mesh_write
 *
 * Readers take a path, or bytes in memory with a `source` name used in
 * messages. Every reader checks the whole input (truncation, non-finite
 * numbers, indices out of range, counts the file cannot hold, non-text bytes
 * in a text format) and fails with a message that starts "<source>:<line>: "
 * for text formats and "<source>: " plus a byte offset or the name of the
 * element for binary ones, saying what was expected. Declared counts are
 * checked against the bytes actually present before anything is allocated,
 * so memory stays a small multiple of the input size. A mesh without faces
 * is refused ("no faces", CR_ERR_TOPOLOGY). The result passes
 * cr_mesh_validate.
 *
 * UVs and seams. crease keeps UVs per corner (cr_mesh.tri_uv), as OBJ does;
 * PLY and glTF store one UV per vertex. So the PLY and glb writers split
 * each vertex into one copy per distinct UV it meets (cr_mesh_split_seams:
 * original vertices first, in order, seam copies after), and the PLY and glb
 * readers, when the file has UVs, weld vertices with bit-identical positions
 * back into one (cr_mesh_weld), keeping each corner's UV. A round trip
 * OBJ -> PLY -> glb -> OBJ therefore keeps the vertex count, the vertex order,
 * the positions and the per-corner UVs bit for bit. The price: two distinct
 * vertices at exactly the same position in a PLY or glb file with UVs come
 * back as one. Files without UVs are never welded; the OBJ reader never welds.
 *
 * Conventions. UVs are in OBJ's convention (v up) everywhere in crease. glTF
 * puts v down, so the glb writer stores TEXCOORD_0 = (u, 1 - v); because
 * 1 - (1 - v) loses low bits in float for v < 0.5 it also stores the exact
 * UVs as the application attribute _CREASE_UV, which the reader uses when
 * it agrees with TEXCOORD_0 (so a file whose UVs another tool edited is read
 * from TEXCOORD_0). Floats are printed with %.9g, which reads back exactly.
 * Numbers are parsed in the C locale's format (decimal point '.').
 *
 * Left out: OBJ materials, groups, lines, free-form geometry and '\' line
 * continuation (skipped or refused, never misread); PLY colours and other
 * properties (skipped); glTF node transforms, skins, sparse accessors,
 * external buffers, files with several meshes or primitives (refused), and
 * morph targets in cr_glb_read (the base mesh is read; cr_glb_read_sequence
 * reads them).
 *
 * Ownership: meshes returned through `out` belong to the caller
 * (cr_mesh_destroy); cr_pc2.frames belongs to the cr_pc2 (cr_pc2_free).
 * Writers go through cr_atomic_open/commit, so a failure leaves no file.
 * Every function is reentrant.
 */
#ifndef CREASE_MESH_IO_H
#define CREASE_MESH_IO_H

#include "crease/mesh.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ------------------------------------------------------------- dispatch -- */

/* Read or write by the path's extension: obj, ply (written binary little
 * endian), glb. Any other extension: CR_ERR_UNSUPPORTED naming it. */
cr_status cr_mesh_read(const char *path, cr_mesh **out, cr_error *err);
cr_status cr_mesh_write(const char *path, const cr_mesh *m, cr_error *err);

/* ------------------------------------------------------------------ OBJ -- */

/* v, vt, vn and f in every index form (v, v/vt, v//vn, v/vt/vn), negative
 * (relative) indices, polygons fan-triangulated (i0, ik, ik+1). Indices must
 * refer to elements defined above the face. Faces must all have vt or all
 * lack it. When every face has vn, mesh->normal is the normalised mean of
 * the vn each vertex is given; otherwise it stays NULL. g, o, s, usemtl,
 * mtllib, l, p, comments and the free-form statements are skipped; an
 * unknown statement is an error. Extra numbers on v lines (w, or vertex
 * colours) are checked and dropped. CRLF line ends are fine. */
cr_status cr_obj_read(const char *path, cr_mesh **out, cr_error *err);
cr_status cr_obj_read_mem(const void *data, size_t len, const char *source, cr_mesh **out,
                          cr_error *err);
/* v, vt (when the mesh has UVs), vn (when it has normals), f v[/vt][/vn]. */
cr_status cr_obj_write(const char *path, const cr_mesh *m, cr_error *err);

/* ------------------------------------------------------------------ PLY -- */

/* ascii, binary_little_endian and binary_big_endian. Element "vertex" with
 * x y z of any numeric type, optional nx ny nz and optional UVs named s t,
 * u v, texture_u texture_v or texture_s texture_t; element "face" with a
 * list property vertex_indices or vertex_index (any count and index types),
 * polygons fan-triangulated. Other elements and properties (lists
 * included) are skipped. Bytes or values after the last declared element
 * are refused. Welds at UV seams (see the top of this file). */
cr_status cr_ply_read(const char *path, cr_mesh **out, cr_error *err);
cr_status cr_ply_read_mem(const void *data, size_t len, const char *source, cr_mesh **out,
                          cr_error *err);

typedef enum cr_ply_format {
    CR_PLY_BINARY = 0, /* binary_little_endian */
    CR_PLY_ASCII
} cr_ply_format;

/* float x y z [nx ny nz] [s t] per vertex (split at UV seams), faces as
 * "list uchar int vertex_indices". */
cr_status cr_ply_write(const char *path, const cr_mesh *m, cr_ply_format format, cr_error *err);

/* ------------------------------------------------------------------ glb -- */

/* glTF 2.0 binary: one mesh with one triangle primitive; POSITION (float
 * VEC3), optional NORMAL (float VEC3), TEXCOORD_0 (float or normalised
 * u8/u16 VEC2) and _CREASE_UV; indices u8, u16 or u32, or none (then every
 * three vertices make a triangle). Every accessor and buffer view is checked against the
 * binary chunk. Welds at UV seams (see the top of this file). */
cr_status cr_glb_read(const char *path, cr_mesh **out, cr_error *err);
cr_status cr_glb_read_mem(const void *data, size_t len, const char *source, cr_mesh **out,
                          cr_error *err);

/* One mesh: POSITION with min/max, NORMAL if the mesh has normals,
 * TEXCOORD_0 and _CREASE_UV if it has UVs (split at seams), u32 indices. */
cr_status cr_glb_write(const char *path, const cr_mesh *m, cr_error *err);

/* A mesh sequence as morph-target animation, which Blender and three.js
 * play: the base mesh is `rest`; frame i is morph target i holding
 * frames[i] - rest positions (split at seams like the base); one animation
 * channel drives the mesh weights, one-hot at time i / fps, with LINEAR
 * interpolation (so playback between frames blends positions linearly).
 * When `rest` has normals, each frame's area-weighted vertex normals are
 * stored as NORMAL target displacements too. The weights output grows as
 * T^2 floats; the file must stay under 4 GiB.
 *   frames: (T,V,3) positions, m, V = rest->nv, T = nframes >= 1; fps > 0. */
cr_status cr_glb_write_sequence(const char *path, const cr_mesh *rest, const float *frames,
                                int32_t nframes, float fps, cr_error *err);

/* Read such a sequence back: `rest` is the base mesh as cr_glb_read gives it
 * (welded at seams), frames (T,V,3) positions, m, over its V vertices (base
 * plus morph target i; a seam copy lands on its welded vertex), T the number
 * of morph targets, or 1 (the base) for a file without them. A skinned mesh
 * (JOINTS_0, WEIGHTS_0 and a node with a skin; any skeleton) is posed by
 * animations[0] instead, sampled at its key spacing over its time range
 * (cr_glb_write_skinned's files, or a rigged character from another tool;
 * LINEAR and STEP keys). *fps is
 * 1 / (t1 - t0) of the first animation sampler, or 0 when the file has no
 * animation of two keys or more. Targets must not share bytes: the frames
 * never take more memory than the file's BIN chunk. The caller frees *frames
 * and destroys *rest; on failure both are NULL. */
cr_status cr_glb_read_sequence(const char *path, cr_mesh **rest, float **frames, int32_t *nframes,
                               float *fps, cr_error *err);
cr_status cr_glb_read_sequence_mem(const void *data, size_t len, const char *source, cr_mesh **rest,
                                   float **frames, int32_t *nframes, float *fps, cr_error *err);

/* A skinned, animated character (src/geom/io_glb_skin.c), as game engines
 * and Blender import it: a skeleton of J joint nodes, the mesh's linear blend
 * skin over them and one animation. */
enum { CR_GLB_MAX_JOINTS = 1024 };

typedef struct cr_glb_skin {
    int32_t njoints;               /* J, 1..CR_GLB_MAX_JOINTS */
    const char *const *joint_name; /* (J) node names */
    const int32_t *parent;         /* (J) parent joint, earlier in the list, or -1 for a root */
    const float *rest_joint;       /* (J,3) joint positions in the rest (bind) pose, m */
    const int32_t *skin_joint;     /* (V,4) joints of each vertex */
    const float *skin_weight;      /* (V,4) their weights, >= 0 (renormalised when written) */
} cr_glb_skin;

typedef struct cr_glb_skin_motion {
    int32_t nframes;          /* T >= 1 */
    float fps;                /* > 0 */
    const float *rotation;    /* (T,J,4) each joint's rotation relative to its parent's frame
                                 in the rest pose, unit quaternion x, y, z, w */
    const float *translation; /* (T,3) the root's displacement from its rest position, m */
} cr_glb_skin_motion;

/* A garment's frames on the character's timeline. */
typedef struct cr_glb_cloth {
    const cr_mesh *rest; /* its mesh (faces, UVs, rest positions) */
    const float *frames; /* (T,Vg,3) positions, m, T = the motion's frames */
} cr_glb_cloth;

/* Write `rest` skinned to the skeleton, posed by `motion`: joint nodes with
 * their rest offsets, inverse bind matrices (the rest pose is the bind pose),
 * JOINTS_0 / WEIGHTS_0, one LINEAR animation of the joints' rotations and the
 * root's translation with keys at i / fps. With `cloth` (may be NULL), the
 * garment too, as a second mesh with one morph target a frame driven by the
 * same animation: one file that plays body and garment together. Without it,
 * cr_glb_read_sequence reads the file back as frames. Atomic. */
cr_status cr_glb_write_skinned(const char *path, const cr_mesh *rest, const cr_glb_skin *skin,
                               const cr_glb_skin_motion *motion, const cr_glb_cloth *cloth,
                               cr_error *err);

/* A skeleton's own animation, joint by joint in the world. */
typedef struct cr_glb_skin_anim {
    int32_t nframes;       /* T >= 1: the animation's time range at its key rate (1: the rest) */
    float fps;             /* the first channel's key rate (30 without two keys) */
    int animated;          /* 0: the file has no animation of its nodes (one frame, the rest) */
    const float *rotation; /* (T,J,4) each joint's world rotation from its rest world rotation
                              (R_t R_rest^-1, scale taken out), x, y, z, w, the file's frame */
    const float *position; /* (T,J,3) each joint's world position, m, the file's frame */
} cr_glb_skin_anim;

/* A rigged character read from a .glb, to be posed by another motion than
 * its own (cr_motion_retarget_bvh) or to drive a body by its own
 * (cr_motion_import of the .glb): the skinned mesh at the rest pose its
 * nodes hold (their translation, rotation and scale without animation;
 * for crease's files and most exports the bind pose), welded like
 * cr_glb_read; its skeleton with the joints ordered parents first, each
 * named by its node ("joint_K" for an unnamed one), its parent the nearest
 * ancestor node that is a joint, rest_joint its world position; the skin per
 * vertex of `rest`; its joints through animations[0]. Owned; free with cr_glb_character_destroy. */
typedef struct cr_glb_character {
    cr_mesh *rest;
    cr_glb_skin skin;
    cr_glb_skin_anim anim; /* its own animation, animations[0], sampled as cr_glb_read_sequence
                              samples it */
} cr_glb_character;

/* Fails naming the file when it has no skin (JOINTS_0, WEIGHTS_0 and a node
 * drawing the mesh with a skin). */
cr_status cr_glb_read_character(const char *path, cr_glb_character **out, cr_error *err);
cr_status cr_glb_read_character_mem(const void *data, size_t len, const char *source,
                                    cr_glb_character **out, cr_error *err);
void cr_glb_character_destroy(cr_glb_character *c);

/* The character posed by m (cr_glb_skin_motion's convention: rotations
 * relative to the parent with world-aligned rest frames, the roots
 * displaced by m->translation): *frames (T,V,3), m, over rest's V
 * vertices, by the same linear blend skinning cr_glb_read_sequence uses.
 * The caller frees *frames. */
cr_status cr_glb_character_pose(const cr_glb_character *c, const cr_glb_skin_motion *m,
                                float **frames, cr_error *err);

/* ------------------------------------------------------------------ PC2 -- */

/* PC2 point cache (Blender, 3ds Max): "POINTCACHE2\0", int32 version 1,
 * int32 points, float start frame, float sample rate, int32 samples, then
 * float32 x y z per point per sample, all little endian. Vertex order is the
 * mesh's own. */
typedef struct cr_pc2 {
    int32_t nv;        /* V: points per sample */
    int32_t nframes;   /* T: samples */
    float start_frame; /* frame number of the first sample */
    float sample_rate; /* frames between samples */
    float *frames;     /* (T,V,3) positions, m; owned */
} cr_pc2;

/* On failure `out` is left empty (frames NULL). */
cr_status cr_pc2_read(const char *path, cr_pc2 *out, cr_error *err);
cr_status cr_pc2_read_mem(const void *data, size_t len, const char *source, cr_pc2 *out,
                          cr_error *err);
/* frames: (T,V,3) positions, m, T = nframes >= 1, V = nv >= 1, all finite. */
cr_status cr_pc2_write(const char *path, const float *frames, int32_t nv, int32_t nframes,
                       float start_frame, float sample_rate, cr_error *err);
/* Free frames and zero the struct; NULL is a no-op. */
void cr_pc2_free(cr_pc2 *p);

/* ------------------------------------------------------ seams and welds -- */

/* A mesh laid out with one UV per vertex, as PLY and glTF need it. Vertex i
 * < V keeps its index (with the first UV a face gives it, or (0,0) when no
 * face uses it); each further distinct UV (compared bit for bit) at a vertex
 * adds a copy at index >= V, in the order faces meet them. Without UVs the
 * split is the identity. */
typedef struct cr_mesh_seams {
    int32_t nv;   /* V': vertices after the split, V <= V' <= V + 3F */
    int32_t *src; /* (V') the mesh vertex each split vertex copies */
    float *uv;    /* (V',2) the UV of each split vertex; NULL without UVs */
    int32_t *tri; /* (F,3) triangles over split vertices */
} cr_mesh_seams;

/* `m` must be valid (cr_mesh_validate); `out` is freed with cr_mesh_seams_free. */
cr_status cr_mesh_split_seams(const cr_mesh *m, cr_mesh_seams *out, cr_error *err);
void cr_mesh_seams_free(cr_mesh_seams *s);

/* Merge vertices whose positions are bit-identical into the first of them
 * (order of first appearance kept); triangles are renumbered, UVs and their
 * per-corner indices are untouched, normals and attributes are those of the
 * first copy. `m` must be valid. O(V) expected time, 4 V to 8 V bytes of scratch. */
cr_status cr_mesh_weld(cr_mesh *m, cr_error *err);

#ifdef __cplusplus
}
#endif
#endif
