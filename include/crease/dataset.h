/* crease/dataset.h: garment sequences simulated on moving bodies by the
 * reference simulator, written as a self-describing dataset that the
 * training commands read.
 *
 *   cr_dataset_def def = cr_dataset_default_def();
 *   def.out_dir = "data";
 *   def.garments = (const char *[]){"tshirt", "dress"}, def.ngarments = 2;
 *   ... motions, bodies, resolutions ...
 *   cr_dataset_result r;
 *   CR_TRY(cr_dataset_generate(&def, &r, err));
 *
 * Every combination garment x motion x body x resolution is one sequence.
 * Layout under out_dir (paths in manifest.json are relative to it):
 *   manifest.json                              what was asked and every sequence's state
 *   bodies/<body>/rest.obj                     the mannequin (A-pose rest)
 *   bodies/<body>/skin.npz                     joints (22,3), skin_joint (V,4), skin_weight (V,4)
 *   bodies/<body>/<motion>.pc2                 the posed body, frames + 1 samples
 *   motions/<motion>.npz                       the motion (crease's motion .npz)
 *   garments/<body>/<garment>_<res>.obj        rest garment with UVs (<garment>: the
 *                                              variant's label, e.g. dress_seed3)
 *   garments/<body>/<garment>_<res>_skin.npz   skin_joint (V,4), skin_weight (V,4), panel (F)
 *   garments/<body>/<garment>_high_from_low.npz  face (Vh), bary (Vh,3): gdsr Eq. 1
 *   sequences/<garment>_<res>_<body>_<motion>/garment.pc2   frames + 1 samples
 *   sequences/<...>/frames.jsonl               the simulator's per-frame log
 *   sequences/<...>/result.json                written last: status, figures
 *
 * Resumable: a sequence whose result.json says "done" is skipped; a failed
 * one is tried again. Sequences run in parallel (each simulator on one
 * thread); one that fails (divergence, bad input) is recorded with its
 * reason and the others go on. Every file is written atomically.
 *
 * Garments start in the body's rest pose, where every motion starts (clips
 * by construction, files by their ease-in: body sample 0 is the rest
 * pose). The
 * waistband of a skirt or of trousers (its highest boundary loop) is pinned
 * and carried by the body through the garment's own skinning weights: with
 * no self-collision and penalty friction, a skirt would otherwise slide
 * down the legs.
 */
#ifndef CREASE_DATASET_H
#define CREASE_DATASET_H

#include "crease/base.h"
#include "crease/motion.h"
#include "crease/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

#define CR_DATASET_MAX_ITEMS 64

typedef struct cr_dataset_def {
    const char *out_dir;
    const char *const *garments; /* garment variants: a type ("dress") or a variant spec
                                    (cr_garment_variant_parse: "dress:seed=3",
                                    "tshirt:length=0.8:sleeve=1.2"); files and ids use the
                                    variant's label ("dress_seed3") */
    int ngarments;
    const char *const *motions; /* clip names (motion.h) or motion files (.npz, .bvh) */
    int nmotions;
    const char *const *bodies; /* mannequin presets: slim, normal, heavy */
    int nbodies;
    const char *const *res; /* "low", "high" */
    int nres;
    int32_t low_vertices;     /* default 2000 */
    int32_t high_vertices;    /* default 8000 */
    int32_t frames;           /* simulated frames per sequence (default 150) */
    float fps;                /* default 30 */
    const char *material;     /* preset name (default "cotton") */
    int plastic;              /* 1: plastic bending (epnet's ground truth) */
    double max_collider_step; /* m: frames where the body moves further run more substeps
                                 (cr_sim_def.max_collider_step; default 0.15: the run and
                                 jump clips get 2-3, the others 1) */
    int solver;               /* cr_sim_solver (default 0: CR_SIM_SOLVER_NEWTON) */
    int self_contact;         /* cloth self-contact: 1 on, 0 off, -1 (default) cr_sim_def's */
    float self_thickness;     /* its thickness, m; 0 (default): cr_sim_def's */
    uint64_t seed;            /* recorded in the manifest (the simulator has no randomness) */
    cr_scene_twin twin;       /* a twin dataset: every sequence re-run with this tiny
                                 perturbation (recorded in the manifest; default none) */
    uint32_t mesh_only_res;   /* bit r set: res[r]'s garments (and the low/high correspondence)
                                 are made but its sequences are not simulated (gdsr run's
                                 low-only input with its high pair); default 0 */
    int quiet;                /* 1: no progress bar */
    /* Motion files (clips are made at fps and start at the rest pose): read
     * with motion_import, then made ready by cr_motion_prepare with
     * motion_prepare (frames used, a calibration frame dropped, resampled to
     * fps (its own fps field is ignored), grounded on the default mannequin's
     * feet, eased in from the rest pose over 1 s). Set by the default def. */
    cr_motion_import_def motion_import;
    cr_motion_prepare_def motion_prepare;
    uint32_t cookie;
} cr_dataset_def;

cr_dataset_def cr_dataset_default_def(void);

typedef struct cr_dataset_result {
    int32_t sequences; /* combinations asked for */
    int32_t done;      /* simulated by this call */
    int32_t skipped;   /* already done by an earlier call */
    int32_t failed;
    double seconds;
    int32_t ngarments;
    /* Per garment type asked for: the largest share of its vertices inside
     * the body on any stored frame of any of its sequences, 0..1 (measured
     * by a signed-distance query of its own), and the same for the solver's
     * substeps before the simulator projects vertices out. */
    double max_inside_share[CR_DATASET_MAX_ITEMS];
    double max_inside_share_solver[CR_DATASET_MAX_ITEMS];
    /* Per garment: crossing (intersecting) triangle pairs of the garment with
     * itself (cr_bvh_self_intersections), the most on any stored frame of a
     * sequence that did not fail, and the most on the garment as built (its
     * rest state, frame 0: seams that touch at rest count there, not as the
     * simulation's); -1 where nothing was counted (every sequence failed). */
    int64_t max_crossings[CR_DATASET_MAX_ITEMS];
    int64_t rest_crossings[CR_DATASET_MAX_ITEMS];
    /* Per garment: its failed sequences, and the seconds of all its
     * sequences (this call's, and those of the sequences skipped as done, as
     * their result.json recorded them): not deterministic, so kept out of
     * the manifest, which is the same bytes for every run of one def. */
    int32_t failed_by_garment[CR_DATASET_MAX_ITEMS];
    double seconds_by_garment[CR_DATASET_MAX_ITEMS];
} cr_dataset_result;

/* Generate (or complete) the dataset. CR_ERR_INVALID naming a bad field or
 * an unknown garment, body or resolution; CR_ERR_IO for the output folder.
 * Sequences that fail do not fail the call: they are counted in `failed`. */
cr_status cr_dataset_generate(const cr_dataset_def *def, cr_dataset_result *out, cr_error *err);

/* A motion's name in the dataset's files: the clip's name ("walk"), or a
 * file's base name without its extension ("dance" for "mocap/dance.bvh"),
 * a character's with its joint map's as cr_dataset_body_label gives them. */
void cr_dataset_motion_label(const char *spec, char *out, size_t size);

/* A body spec's name in the dataset's files: a preset's own ("slim"), or an
 * SMPL-family file's base name ("basicModel_f" for
 * "models/basicModel_f.npz"), followed by its betas when given, '.' as 'p',
 * '-' as 'm' and separators as '_' ("basicModel_f_b1p5_m0p5" for ":1.5,-0.5"
 * or ":1.5:-0.5"), or a character's base name and its joint map's ("hero_bones"
 * for "chars/hero.glb:maps/bones.txt"). */
void cr_dataset_body_label(const char *spec, char *out, size_t size);

/* 1 when a garment spec names a mesh file (.obj, .ply or .glb): a garment from
 * another tool, fitted to each body as given, UVs not needed. */
int cr_dataset_garment_is_file(const char *spec);

/* A garment spec's name in the dataset's files: the variant's label
 * ("dress_seed3"), or an outfit's ("tshirt+vest": its parts' labels joined
 * by '+'). CR_ERR_INVALID naming a bad spec. */
cr_status cr_dataset_garment_label(const char *spec, char *out, size_t size, cr_error *err);

/* ------------------------------------------------------------ reading -- */

/* A dataset as its manifest.json describes it: the one reader of what
 * cr_dataset_generate writes, for every command that reads a dataset. Paths
 * are relative to the dataset folder (cr_dataset_path joins them); strings
 * are owned by the manifest and live until cr_dataset_manifest_free. */
typedef struct cr_dataset_body_entry {
    const char *name, *rest, *skin; /* label (cr_dataset_body_label); its rest mesh and skin.npz */
} cr_dataset_body_entry;

typedef struct cr_dataset_garment_entry {
    const char *type, *label, *body, *res; /* label: the variant's ("dress_seed3"), or the type */
    const char *mesh, *skin;
    const char *high_from_low; /* NULL unless the dataset has both resolutions */
} cr_dataset_garment_entry;

typedef struct cr_dataset_motion_entry {
    const char *name, *path; /* the motion .npz */
    int32_t frames;
} cr_dataset_motion_entry;

typedef struct cr_dataset_sequence_entry {
    const char *id, *garment, *res, *body, *motion; /* garment: the label */
    const char *garment_pc2, *body_pc2, *status;
    int done; /* status "done" */
} cr_dataset_sequence_entry;

typedef struct cr_dataset_manifest {
    char dir[CR_SCENE_PATH]; /* the dataset folder */
    int32_t frames, low_vertices, high_vertices;
    float fps;
    int plastic;
    const char *material;
    cr_dataset_body_entry *bodies;
    cr_dataset_garment_entry *garments;
    cr_dataset_motion_entry *motions;
    cr_dataset_sequence_entry *sequences;
    int32_t nbodies, ngarments, nmotions, nsequences;
    void *json; /* the parsed manifest the strings point into (owned) */
} cr_dataset_manifest;

/* Read dir/manifest.json. CR_ERR_IO naming it when missing, CR_ERR_PARSE
 * naming it and the entry when it is not a crease dataset's. */
cr_status cr_dataset_read(const char *dir, cr_dataset_manifest *out, cr_error *err);
/* The same from a manifest's text (len bytes) for the folder dir; what
 * cr_dataset_read parses after reading the file (and what its fuzz target
 * drives). */
cr_status cr_dataset_parse(const char *text, size_t len, const char *dir, cr_dataset_manifest *out,
                           cr_error *err);
/* Free and zero; a zeroed manifest is a no-op. */
void cr_dataset_manifest_free(cr_dataset_manifest *m);
/* m->dir / rel into out (size bytes); CR_ERR_RANGE when it does not fit. */
cr_status cr_dataset_path(const cr_dataset_manifest *m, const char *rel, char *out, size_t size,
                          cr_error *err);
/* The entries by name; NULL when absent. A garment by its label (or type), body
 * and resolution; a sequence by its garment label, resolution, body and motion,
 * whatever its status; by id (NULL: the first done one). */
const cr_dataset_body_entry *cr_dataset_find_body(const cr_dataset_manifest *m, const char *name);
const cr_dataset_garment_entry *cr_dataset_find_garment(const cr_dataset_manifest *m,
                                                        const char *label, const char *body,
                                                        const char *res);
const cr_dataset_sequence_entry *cr_dataset_find_sequence(const cr_dataset_manifest *m,
                                                          const char *garment, const char *res,
                                                          const char *body, const char *motion);
const cr_dataset_sequence_entry *cr_dataset_find_id(const cr_dataset_manifest *m, const char *id);

#ifdef __cplusplus
}
#endif
#endif
