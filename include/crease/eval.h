/* crease/eval.h: how close a predicted garment sequence is to a reference
 * one, by every metric the project's four papers report.
 *
 *   cr_eval_def def = cr_eval_default_def();
 *   def.fps = 30.0f;
 *   cr_eval_input in = {.garment = rest, .nframes = T, .pred = pred, .ref = ref,
 *                       .body_mesh = body, .body = body_frames, .body_nframes = T};
 *   cr_eval_result res = {0};
 *   cr_status st = cr_eval_run(&def, &in, &res, &err);
 *   printf("MED %g m\n", res.summary[CR_EVAL_MED].mean);
 *   cr_eval_result_free(&res);
 *
 * Both sequences animate one mesh (the garment's rest mesh: its triangles,
 * UVs and rest shape); frame t of the prediction is compared with frame t
 * of the reference. Per frame the metrics below are computed (NAN where a
 * metric is undefined: inertia and jitter need three frames, collision
 * needs a body, SSIM needs UVs, PE needs rest angles); each gets a summary
 * over the frames where it is defined: mean, max, min and the worst frame.
 *
 *   key                 paper      what, per frame t (P prediction, R reference)
 *   med_m               epnet      mean_i |P_i - R_i|, m
 *   e_dist_cm           swingar    the same in cm
 *   cd_m2               epnet      mean_i min_j |P_i - R_j|^2 + mean_j min_i |R_j - P_i|^2, m^2
 *   chamfer_m           drape      (mean dist(P_i, surface R) + mean dist(R_j, surface P)) / 2, m
 *   be_rad              epnet      mean over hinges |theta_P - theta_R|, rad
 *   bed_rad             epnet      the same over the top 10 % hinges by peak plastic bending of R
 *   pe_rad              epnet      mean over hinges |rest_P - rest_R| (rest_P = 0 when not given)
 *   ben_j               epnet      mean per hinge k_e/2 (theta_P - rest_P)^2, J
 *   ste_j, she_j        epnet      membrane stretch and shear energy of P (phys kernels), J
 *   ge_j                epnet      gravitational energy -sum m_i g . P_i, J
 *   ie_j                epnet      sum m_i/(2h^2) |P_t - 2P_{t-1} + P_{t-2}|^2, J (h = 1/fps)
 *   col_m, col_max_m    epnet      mean_i max(0, -sd_body(P_i)); the deepest, m
 *   collision_ratio     swingar    share of P's vertices inside the body (sd < 0)
 *   col_face_max_m      crease     the deepest face centroid of P inside the body, m: what a
 *                                  renderer shows as skin through the cloth where every
 *                                  vertex is outside (coarse faces over a curved body)
 *   e_u, e_v, e_uv      gdsr B     mean over triangles (|w_u|-1)^2, (|w_v|-1)^2, (w_u.w_v)^2
 *   ssim                gdsr C     SSIM of P's and R's normal maps rendered over UV
 *   normal_angle_deg    gdsr       mean angle between P's and R's vertex normals, degrees
 *   e_norm_deg          swingar    mean angle between P's and R's face normals, degrees
 *   jitter_m, jitter_ref_m  -      mean_i |X_t - 2X_{t-1} + X_{t-2}| of P (of R), m
 *   h_rms               drape      area-weighted RMS of P's signed mean curvature, 1/m
 *
 * Fold measures that do not care where exactly each fold lies (a fold one
 * hinge away from the reference's is not an error), with b_h = theta_h -
 * theta0_h a hinge's bending from the rest mesh and RB_h = rest_h - theta0_h
 * its plastic bending, N(h) the hinges within `ring` rings of h (h itself
 * included; ring 1: the hinges sharing a vertex with h, a hinge's vertices
 * being its edge's ends and the two opposite ones; each further ring grows h's
 * vertices by a ring):
 *   bed_ring_rad        crease     BED with each selected hinge's best match in N(h),
 *                                  symmetrised: the mean of mean_{h in S} min_{h' in N(h)}
 *                                  |b_h'(P) - b_h(R)| and the same with P and R swapped
 *                                  and S the prediction's own top share
 *   pe_ring_rad         crease     PE the same way, symmetrised: the mean of P matched
 *                                  to R and R matched to P
 *   bed_sorted_rad      crease     location-free: the top share (bed_fraction) of |b(P)|
 *                                  sorted, against the same of |b(R)|: mean |difference|
 *   pe_sorted_rad       crease     the same of |RB|
 *   pe_rb0_rad          crease     PE of RB = 0 (mean |RB(R)|: the reference's plastic
 *                                  bending), the zero-plasticity floor PE is judged by
 *   pe_ring_rb0_rad     crease     pe_ring_rad of RB = 0
 *   fold_share          crease     share of P's hinges with |b| > fold_threshold
 *   fold_share_ref      crease     the same of R
 *
 * Formulas, their sources and the reconstructions of equations the papers
 * lost: docs/eval.md. Energies come from phys/ kernels (phys_energies.h) on
 * the material in the def, never from copies.
 *
 * Also here, for the methods: the drape paper's surface measures (Chamfer
 * distance between two surfaces, signed mean curvature, its spectrum), SSIM
 * of two images, and a small line-plot and text renderer for report PNGs;
 * and `crease eval` as one call over files (cr_eval_files_run).
 *
 * Thread safety: calls share no state. The library prints nothing.
 */
#ifndef CREASE_EVAL_H
#define CREASE_EVAL_H

#include "crease/mesh.h"
#include "crease/phys_material.h"
#include "crease/render.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ------------------------------------------------------------- metrics -- */

typedef enum cr_eval_metric {
    CR_EVAL_MED = 0,
    CR_EVAL_E_DIST_CM,
    CR_EVAL_CD,
    CR_EVAL_CHAMFER,
    CR_EVAL_BE,
    CR_EVAL_BED,
    CR_EVAL_PE,
    CR_EVAL_BEN,
    CR_EVAL_STE,
    CR_EVAL_SHE,
    CR_EVAL_GE,
    CR_EVAL_IE,
    CR_EVAL_COL,
    CR_EVAL_COL_MAX,
    CR_EVAL_COLLISION_RATIO,
    CR_EVAL_COL_FACE_MAX,
    CR_EVAL_E_U,
    CR_EVAL_E_V,
    CR_EVAL_E_UV,
    CR_EVAL_SSIM,
    CR_EVAL_NORMAL_ANGLE,
    CR_EVAL_E_NORM,
    CR_EVAL_JITTER,
    CR_EVAL_JITTER_REF,
    CR_EVAL_H_RMS,
    /* fold measures a chaotic reference can be held to (docs/eval.md, "Folds") */
    CR_EVAL_BED_RING,
    CR_EVAL_PE_RING,
    CR_EVAL_BED_SORTED,
    CR_EVAL_PE_SORTED,
    CR_EVAL_PE_RB0,
    CR_EVAL_PE_RING_RB0,
    CR_EVAL_FOLD_SHARE,
    CR_EVAL_FOLD_SHARE_REF,
    CR_EVAL_METRIC_COUNT
} cr_eval_metric;

/* JSON key ("med_m", ...) and the paper it comes from ("epnet", ...). */
const char *cr_eval_metric_name(cr_eval_metric m);
const char *cr_eval_metric_source(cr_eval_metric m);
/* 1 when a larger value is better (only SSIM); the worst frame is then the minimum. */
int cr_eval_metric_higher_is_better(cr_eval_metric m);

typedef struct cr_eval_def {
    float fps;                   /* frames per second of both sequences, for IE (default 30) */
    double gravity[3];           /* m/s^2, for GE (default 0, -9.81, 0: Y up) */
    cr_material material;        /* for BEN, STE, SHE, GE, IE (default the "cotton" preset,
                                    crease simulate's default) */
    int membrane_rest_from_uv;   /* 1: rest shape of the membrane and of w_u, w_v from the
                                    garment's UVs times uv_scale; 0 (default): the rest mesh's
                                    triangles laid flat, u along each triangle's first edge */
    float uv_scale;              /* m per UV unit (default 1) */
    int bending_rest_from_mesh;  /* 1 (default, as crease simulate): BEN's and BED's rest angles
                                    are the rest mesh's dihedral angles when none are given */
    float bed_fraction;          /* share of hinges BED keeps, (0, 1] (default 0.1) */
    int ssim_side;               /* normal maps are ssim_side^2 pixels over the UV bounds,
                                    16..2048 (default 256) */
    int ring;                    /* rings of the tolerant measures' neighbourhood, 1..8
                                    (default 1) */
    float fold_threshold;        /* rad: a hinge bent past it counts as folded (fold share,
                                    retention; default 0.1) */
    float resolve_edges;         /* a curvature band is resolved when its central wavelength
                                    spans at least this many mean rest edges (default 3) */
    int band_every;              /* band power over frames: every n-th frame (default 1) */
    float admit_plastic_bending; /* admission: the reference's mean |RB| at the last frame
                                    must reach this, rad (default 0.02) */
    float admit_twin_ratio;      /* and the twin's pe_ring_rad be at most this times that of
                                    RB = 0 (default 0.7) */
    uint32_t cookie;             /* set by cr_eval_default_def */
} cr_eval_def;

cr_eval_def cr_eval_default_def(void);

typedef struct cr_eval_input {
    const cr_mesh *garment;   /* rest mesh (borrowed): V vertices, triangles, optional UVs */
    int32_t nframes;          /* T >= 1 */
    const float *pred;        /* (T,V,3) predicted positions, m, finite */
    const float *ref;         /* (T,V,3) reference positions, m, finite */
    const cr_mesh *body_mesh; /* optional closed body (collider) mesh, Vb vertices */
    const float *body;        /* optional (Tb,Vb,3) body positions per frame; NULL: body_mesh
                                 stays where it is. Frame t uses body frame min(t, Tb - 1) */
    int32_t body_nframes;     /* Tb */
    /* Plastic rest angles per hinge (hinge order of cr_topology_build on the garment), rad:
     * (Tr,H) with Tr == T (per frame) or Tr == 1 (constant); NULL when the sequence has none. */
    const float *ref_rest;
    int32_t ref_rest_nframes;
    const float *pred_rest;
    int32_t pred_rest_nframes;
    int32_t rest_nhinges; /* H the rest-angle arrays were made for; 0: not checked */
    /* Names for messages (file names, say); NULL: "prediction", "reference", "body". */
    const char *pred_name, *ref_name, *body_name;
} cr_eval_input;

typedef struct cr_eval_summary {
    double mean, max, min; /* over the frames where the metric is defined; NAN when none */
    int32_t worst_frame;   /* the max (the min for SSIM); -1 when undefined everywhere */
    int32_t count;         /* frames where it is defined */
} cr_eval_summary;

enum { CR_EVAL_H_BANDS = 5 };
/* Wavelength bands of the mean-curvature spectrum, m: band b holds
 * wavelengths in [edges[b+1], edges[b]) (the last reaches the sampling limit). */
extern const double cr_eval_h_band_edges_m[CR_EVAL_H_BANDS + 1];

typedef struct cr_eval_result {
    int32_t nframes, nv; /* T, V */
    int32_t nhinges;     /* H */
    int32_t nbed_hinges; /* hinges BED averages over */
    int bed_from_rest;   /* 1: BED's hinges chosen by the reference's rest angles; 0: by its
                            bending |theta_R - rest| (no rest angles given) */
    double *frames;      /* (T, CR_EVAL_METRIC_COUNT), NAN where undefined; owned */
    cr_eval_summary summary[CR_EVAL_METRIC_COUNT];
    int32_t worst_frame;                  /* frame of the largest MED */
    float *vertex_error;                  /* (V) |P_i - R_i| at worst_frame, m; owned */
    int has_spectrum;                     /* 1 when the garment has UVs: the bands below are set */
    double h_band_pred[CR_EVAL_H_BANDS];  /* spectrum shares of P at the last frame */
    double h_band_ref[CR_EVAL_H_BANDS];   /* of R at the last frame */
    double h_power_pred[CR_EVAL_H_BANDS]; /* each band's power of P, (1/m)^2 (below) */
    double h_power_ref[CR_EVAL_H_BANDS];  /* of R */
    /* Fold retention (fold_share at the last frame over its peak over the run): 1 for
     * folds that stay, 0 for folds that spring back; NAN when no hinge ever folded. */
    double retention_pred, retention_ref;
    int32_t ring;              /* def.ring */
    double fold_threshold_rad; /* def.fold_threshold */
    /* Curvature band power averaged over frames (every def.band_every-th), with UVs: */
    int has_band_power;
    double mean_edge_m;                      /* the rest mesh's mean edge length */
    int band_resolved[CR_EVAL_H_BANDS];      /* 1: the band's central wavelength spans at
                                                least def.resolve_edges mean edges */
    double band_power_pred[CR_EVAL_H_BANDS]; /* (1/m)^2, mean over the frames */
    double band_power_ref[CR_EVAL_H_BANDS];
    int32_t band_frames; /* frames averaged */
    /* Hem swing: the hem (the boundary loop lowest at rest) in the body's frame (its
     * best rigid fit to its first frame; the world frame without a body): RMS of each hem
     * vertex's displacement about its own mean over the frames, m, and the dominant
     * frequency of that motion, Hz. has_hem 0 when the garment has no boundary or there
     * are fewer than 4 frames. */
    int has_hem;
    int hem_in_body_frame;
    int32_t hem_vertices;
    double hem_amplitude_pred_m, hem_amplitude_ref_m;
    double hem_frequency_pred_hz, hem_frequency_ref_hz;
} cr_eval_result;

/* Compute every metric. Refuses (CR_ERR_INVALID / CR_ERR_SHAPE / CR_ERR_NAN,
 * naming the input and the frame/vertex) a def not made by its default, an
 * empty or non-manifold garment, non-finite positions, rest angles of the
 * wrong shape, a body without its mesh. On failure `out` is left empty. */
cr_status cr_eval_run(const cr_eval_def *def, const cr_eval_input *in, cr_eval_result *out,
                      cr_error *err);
/* Free the result's arrays and zero it; NULL and zeroed results are fine. */
void cr_eval_result_free(cr_eval_result *r);
/* The metric's value at frame t. */
static inline double cr_eval_value(const cr_eval_result *r, int32_t t, cr_eval_metric m) {
    return r->frames[(int64_t)t * CR_EVAL_METRIC_COUNT + m];
}

/* 1 when the metric is an error against the reference (lower is better, 0 for the
 * reference itself; SSIM's error is 1 - SSIM): the metrics a baseline's share removed
 * is defined for. Energies, jitter, curvature RMS and fold shares are not. */
int cr_eval_metric_is_error(cr_eval_metric m);

/* The share of a baseline's error that a prediction removes, both scored against
 * the same reference: 1 - err(pred) / err(base), with err the metric's mean (1 -
 * SSIM for SSIM). 1: all of it; 0: none; negative: worse than the baseline. NAN
 * where the metric is not an error (cr_eval_metric_is_error), undefined in
 * either, or the baseline's error is 0. */
double cr_eval_removed(const cr_eval_result *pred, const cr_eval_result *base, cr_eval_metric m);

/* Admission of a plasticity case (docs/eval.md, "The twin"): the reference's mean
 * |plastic bending| at the last frame is at least def.admit_plastic_bending, and the
 * twin (the reference re-simulated with a tiny perturbation, scored as a prediction
 * with its own rest angles) has a tolerant PE at most def.admit_twin_ratio times that
 * of RB = 0. `twin` is the twin's result (or any result against the reference when no
 * twin was run: then only the first condition is tested and `reason` says so). */
typedef struct cr_eval_admission {
    int defined;                /* 0: the reference has no rest angles (no plasticity) */
    int admitted;               /* 1: the case counts for the plasticity metrics */
    int twin_tested;            /* 1: the second condition was tested */
    double plastic_bending_rad; /* the reference's mean |RB| at the last frame */
    double twin_pe_ring_rad;    /* the twin's tolerant PE, mean over frames */
    double rb0_pe_ring_rad;     /* tolerant PE of RB = 0, mean over frames */
    char reason[200];           /* why not, or "admitted" */
} cr_eval_admission;

void cr_eval_admit(const cr_eval_def *def, const cr_eval_result *twin, int twin_tested,
                   cr_eval_admission *out);

/* ------------------------------------------------------------- reports -- */

/* What cr_eval_write_report wrote. */
typedef struct cr_eval_report {
    char frames_jsonl[1100]; /* DIR/frames.jsonl: {"frame": t, "<metric>": value or null, ...} */
    char summary_json[1100]; /* DIR/summary.json: cr_eval_summary_json's object */
    char plots_dir[1100];    /* DIR/plots: <metric>.png, each metric over the frames */
    char heatmap_png[1100];  /* DIR/heatmap.png: |P_i - R_i| on P at the worst frame */
    char vertex_error_npy[1100]; /* DIR/vertex_error.npy: (T,V) float32 |P_i - R_i|, m */
    int nplots;
} cr_eval_report;

/* The summary as one JSON object (text, caller frees with free()): frames,
 * vertices, hinges, bed_hinges, bed_from_rest, worst_frame, "metrics": {key:
 * {mean, max, min, worst_frame, count, source}} (null where undefined),
 * with UVs "spectrum": {band_edges_m, pred, ref} (the last frame) and
 * "band_power": {band_edges_m, mean_edge_m, resolved, pred, ref, ratio, frames}
 * (over frames), "folds": {ring, threshold_rad, retention_pred, retention_ref}
 * and, when defined, "hem": {vertices, frame, amplitude_pred_m, amplitude_ref_m,
 * amplitude_ratio, frequency_pred_hz, frequency_ref_hz}. NULL when out of memory. */
char *cr_eval_summary_json(const cr_eval_result *r);

/* One case scored several ways against one reference, side by side: the
 * prediction of each seed (models trained alike but for their seed), the twin
 * (the reference re-simulated with a tiny perturbation: the floor), a
 * baseline (the skinned garment, the upsampled low simulation, the zero-RB
 * network), and the admission of a plasticity case. */
typedef struct cr_eval_table {
    const cr_eval_result *preds; /* (npreds) >= 1 */
    int npreds;
    const cr_eval_result *twin;         /* may be NULL */
    const cr_eval_result *baseline;     /* may be NULL */
    const cr_eval_admission *admission; /* may be NULL */
} cr_eval_table;

/* The mean and spread (sample standard deviation, NAN for fewer than two) of v[0..n),
 * non-finite values skipped: what the table reports over seeds. */
void cr_eval_mean_spread(const double *v, int n, double *mean, double *spread);

/* The table as JSON (text, caller frees with free()): "seeds": {n, "metrics":
 * {key: {mean, spread, min, max}}} over the predictions (spread: the sample
 * standard deviation, null for one seed), "retention" and "hem_amplitude_m" and
 * "band_power" the same way; "twin" and "baseline": {key: mean}; "removed":
 * {key: {mean, spread}} the share of the baseline's error each seed removes
 * (cr_eval_removed) and "twin_removed": {key: value} the twin's; "admission".
 * Objects whose row is missing are left out. NULL when out of memory. */
char *cr_eval_table_json(const cr_eval_table *t);

/* The same as a Markdown table (text, caller frees with free()): a row per
 * prediction mean (with its spread over seeds), the twin and the baseline, a
 * row of the share of the baseline's error removed, for the metrics defined
 * in the first prediction. */
char *cr_eval_table_text(const cr_eval_table *t);

/* Write the report of r into dir (created): the per-frame JSON lines, the
 * summary, a plot of each metric defined somewhere, the per-vertex error of
 * every frame (vertex_error.npy, for `crease view --color-by`), and the heat map (the
 * prediction at r->worst_frame with the body there, when in has one, in
 * grey; a colour bar in metres underneath). in is the input r came from.
 * Every file goes through cr_atomic_open/commit (PNGs through
 * cr_image_write_png, which does the same). */
cr_status cr_eval_write_report(const cr_eval_result *r, const cr_eval_input *in, const char *dir,
                               cr_eval_report *out, cr_error *err);

/* `crease eval` as one call (src/eval/files.c): the files read and checked
 * (vertex and frame counts; a sequence more than 5 times larger or smaller
 * than its rest mesh is refused as a unit mix-up), every row scored
 * (cr_eval_run) and reported (cr_eval_write_report: the first prediction's
 * in out_dir, the other seeds' in out_dir/seed<k>/, out_dir/twin/,
 * out_dir/baseline/), the admission, and the table of every row
 * (out_dir/table.md, table.json). Paths are PC2 sequences, meshes (.obj,
 * .ply, .glb) and float .npy rest angles, rad, (T,H) or (H). */
typedef struct cr_eval_files_def {
    cr_eval_def eval;        /* the metrics (cr_eval_default_def) */
    const char *const *pred; /* (npred >= 1) predictions, one per seed */
    int npred;
    const char *const *pred_rest; /* (npred_rest: 0, 1 for all, or npred) their rest angles */
    int npred_rest;
    const char *ref;                      /* the reference (required) */
    const char *garment;                  /* the rest mesh every sequence animates (required) */
    const char *body;                     /* body positions per frame, or NULL (needs body_mesh) */
    const char *body_mesh;                /* the body mesh (alone: a static body), or NULL */
    const char *rest;                     /* the reference's rest angles, or NULL */
    const char *twin, *twin_rest;         /* the twin and its rest angles (admission), or NULL */
    const char *baseline, *baseline_rest; /* a baseline and its rest angles, or NULL */
    const char *out_dir;                  /* required */
    uint32_t cookie;                      /* set by cr_eval_files_default_def */
} cr_eval_files_def;
cr_eval_files_def cr_eval_files_default_def(void);

typedef struct cr_eval_files_result {
    cr_eval_result first;        /* the first prediction's result */
    cr_eval_report report;       /* its report, out_dir's own */
    cr_eval_admission admission; /* of the twin when it has rest angles, else of first */
    char *table_json;            /* cr_eval_table_json's text (owned) */
    char *table_text;            /* cr_eval_table_text's (owned) */
} cr_eval_files_result;

/* Progress ("eval: scoring ...") and warnings through cr_log. On failure out is
 * left empty. */
cr_status cr_eval_files_run(const cr_eval_files_def *def, cr_eval_files_result *out, cr_error *err);
void cr_eval_files_result_free(cr_eval_files_result *r); /* NULL is a no-op */

/* The BED hinge selection alone: the k = max(1, ceil(fraction H)) hinges of
 * largest score, score (H) any non-negative value (ties: lower index
 * first), written to sel (k); returns k. */
int32_t cr_eval_top_hinges(const double *score, int32_t nh, float fraction, int32_t *sel);

/* ----------------------------------------------------- surface measures -- */

/* Symmetric Chamfer distance between two surfaces: the mean of both
 * directions' mean closest-point distance (vertex to the other's triangles), m. */
cr_status cr_eval_chamfer_surface(const cr_mesh *a, const cr_mesh *b, double *out, cr_error *err);

/* Signed mean curvature per vertex, H (V): (L x)_i . n_i / (2 A_i) with the
 * cotangent Laplacian and mixed Voronoi areas: 1/R on a sphere with outward
 * normals; 0 on the boundary. */
cr_status cr_eval_mean_curvature(const cr_mesh *m, float *H, cr_error *err);

/* Metres per UV unit of a mesh with UVs: sqrt(3-D area / UV area); 1 without UV area. */
float cr_eval_chart_scale(const cr_mesh *m);

/* The mean-curvature field's area-weighted RMS (1/m) and spectrum: H
 * resampled over the UV chart on a 256x256 grid, mean removed, 2-D DFT
 * power binned by wavelength (UV frequency scaled by cr_eval_chart_scale),
 * as shares of the total (band). power (may be NULL) gets each band's power
 * in (1/m)^2: its part of the resampled field's mean square over the chart's
 * pixels (Parseval), so the bands sum to that mean square. Shares compare
 * shapes of spectra; powers compare amounts: a surface with half the folds of
 * another has a lower power in their band but can have a higher share in
 * every other band. Needs UVs (CR_ERR_INVALID). */
cr_status cr_eval_curvature_spectrum(const cr_mesh *m, double *h_rms, double band[CR_EVAL_H_BANDS],
                                     double power[CR_EVAL_H_BANDS], cr_error *err);

/* The pixels of the normal maps SSIM compares: side x side over m's UV
 * bounds, row 0 at the top (highest v); per pixel the triangle under its
 * centre (face (side^2), -1 outside the chart) and its barycentrics (bary
 * (side^2,3)). *inside (may be NULL) gets the count of pixels on the chart.
 * CR_ERR_INVALID without UVs. */
cr_status cr_eval_uv_raster(const cr_mesh *m, int side, int32_t *face, double *bary,
                            int64_t *inside, cr_error *err);

/* ---------------------------------------------------------------- SSIM -- */

/* Mean SSIM (Wang, Bovik, Sheikh, Simoncelli 2004) of two images a, b (H,W,C)
 * with values in [0, range]: 11x11 Gaussian window of sigma 1.5, C1 =
 * (0.01 range)^2, C2 = (0.03 range)^2, borders replicated; averaged over the
 * channels and over the pixels where mask (H,W) is non-zero (all pixels
 * when mask is NULL). 1 for identical images. */
cr_status cr_eval_ssim(const float *a, const float *b, const uint8_t *mask, int width, int height,
                       int channels, float range, double *out, cr_error *err);

/* --------------------------------------------------------------- plots -- */

/* A 5x7 bitmap font for report labels: lower-case letters (upper case is
 * drawn as lower), digits and " .-+:%/()_=,|"; other characters draw as a
 * box. scale >= 1 multiplies each glyph pixel. */
void cr_plot_text(cr_image *img, int x, int y, int scale, const char *text, const uint8_t rgb[3]);
int cr_plot_text_width(const char *text, int scale); /* pixels */

/* One line series: n points (x[i], y[i]); non-finite y (or y <= 0 on a log
 * panel) breaks the line. */
typedef struct cr_plot_series {
    const char *name; /* legend entry, NULL for none */
    const double *x, *y;
    int n;
    uint8_t rgb[3];
} cr_plot_series;

typedef struct cr_plot_panel {
    const cr_plot_series *series;
    int nseries;
    int log_y; /* 1: log10 axis with a tick per decade */
} cr_plot_panel;

/* Panels stacked top to bottom sharing the x range (the series' own),
 * white background, grey grid, tick labels (x labels under the last panel
 * only), a legend per panel at its upper right, x_label centred at the
 * bottom and title (may be NULL) at the top left. width, height pixels. */
cr_status cr_plot_lines(const cr_plot_panel *panels, int npanels, const char *x_label,
                        const char *title, int width, int height, cr_image *out, cr_error *err);

/* A horizontal colour bar (viridis from lo to hi) with its end and middle
 * values printed underneath, drawn into img at (x, y), w x h pixels. */
void cr_plot_colorbar(cr_image *img, int x, int y, int w, int h, double lo, double hi,
                      const char *unit);

#ifdef __cplusplus
}
#endif
#endif
