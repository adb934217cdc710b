/* crease/drape.h: quasi-static cloth draping with an implicit neural surface
 * and spatially adaptive sampling of local structures (Shu, Azevedo,
 * Solenthaler & Gross, "Spatially Adaptive Cloth Regression with Implicit
 * Neural Representations"; ../shared/papers/000; docs/drape.md).
 *
 * The cloth is a map from its UV chart to 3-D (eq. 2, 6, 14):
 *
 *     p(u,v) = p0(u,v) + MLP(GE(u,v))
 *
 * p0 the rest position under (u,v) through the UV lookup of the rest mesh
 * (eq. 15-17), GE the multi-resolution grid encoding (levels 101x101x3 and
 * 51x51x3 by default, cubic B-spline between nodes where the paper has
 * bilinear cells), MLP 6-64-64-64-3 with softplus units (47,369
 * parameters in all). Training minimises, with Adam (gradient norm clipped
 * against contact spikes), the weighted sum of four terms evaluated on
 * "local structures" (sec. 3.3): around a sample point, an equilateral
 * triangle ABC whose centroid is the point plus the three equilateral
 * triangles on its edges (apexes D, E, F opposite A, B, C), side `side` in
 * UV (paper: 0.001), rotated by a fresh random angle in [0, 2 pi/3) each
 * epoch:
 *
 *     strain     eq. 19   sum over the 9 edges of ((|e'| - |e|) / |e|)^2, |e| from p0 (eq. 17)
 *     bend       eq. 22   sum over the 3 face pairs (ABC with BCD, CAE, ABF) of |n1 - n2|^2
 *     gravity    eq. 24   m g h, h the mean height (+Y) of the six vertices
 *     collision  eq. 26   sum over the six vertices of min(d . n - eps, 0)^2, d from the
 *                         nearest object vertex, n its normal (or, as an option, the
 *                         signed distance to the object surface from the BVH)
 *
 * Sample points come from the adaptive sampler (drape_sampling.h, sec. 3.2,
 * Algorithm 1): half from the PDF of the weighted loss on a UV grid, half
 * uniform, Lloyd-relaxed together.
 *
 * Variants (the paper's Fig. 1 and 8-10), all trained by the same loop:
 *   mesh          direct optimisation of a 128x128 vertex grid (49,152 floats) with losses on
 *                 the mesh's edges, hinges and vertices
 *   inr-mesh      the INR queried at those grid vertices, same mesh losses
 *   inr-uniform   the INR on local structures, uniformly sampled (mu = 0)
 *   inr-adaptive  the INR on local structures, adaptively sampled (the default)
 * The mesh losses are rescaled so that on a smooth surface they estimate the
 * same energy per area as the structure losses (docs/drape.md gives the
 * factors), so the four variants minimise one energy.
 *
 * Convergence, the same for every variant: every `eval_every` epochs the
 * current surface is scored on a fixed dense set of local structures
 * (eval_res x eval_res centres, fixed rotations); the run has converged when
 * the lowest energy so far fell by less than `converge_tol` times its
 * decrease since the first evaluation over the last `converge_window` epochs.
 *
 * World: metres, Y up, gravity along -Y. Scenes (Table 4): ball (sphere
 * r 0.3 m), torus (0.3 / 0.1 m), prism (side 0.4 m, length 0.8 m, ridge up),
 * table (a 0.4 m box), or any object mesh; a square 1 m cloth laid flat
 * 5 cm above the object, or any cloth mesh with a UV chart.
 *
 * A pin holds the chart centre's horizontal position (the energy has no
 * friction, so a drape over a ball would otherwise slide off in time).
 *
 * Leaves out: self-collision, friction, dynamics (the method is
 * quasi-static), seams between UV panels (a cloth with several panels is
 * allowed, but nothing ties the panels together).
 */
#ifndef CREASE_DRAPE_H
#define CREASE_DRAPE_H

#include "crease/bvh.h"
#include "crease/eval.h"
#include "crease/mesh.h"
#include "crease/nn.h"
#include "crease/nn_layers.h"
#include "crease/phys_energies.h"
#include "crease/uvlookup.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ------------------------------------------------------------- choices -- */

typedef enum cr_drape_variant {
    CR_DRAPE_MESH = 0,
    CR_DRAPE_INR_MESH,
    CR_DRAPE_INR_UNIFORM,
    CR_DRAPE_INR_ADAPTIVE,
    CR_DRAPE_VARIANT_COUNT
} cr_drape_variant;

/* "mesh", "inr-mesh", "inr-uniform", "inr-adaptive". */
const char *cr_drape_variant_name(cr_drape_variant v);
/* CR_ERR_INVALID naming the accepted names when `name` is none of them. */
cr_status cr_drape_variant_parse(const char *name, cr_drape_variant *out, cr_error *err);

typedef enum cr_drape_scene {
    CR_DRAPE_BALL = 0,
    CR_DRAPE_TORUS,
    CR_DRAPE_PRISM,
    CR_DRAPE_TABLE,
    CR_DRAPE_OBJECT, /* a user mesh, cr_drape_def.object_path */
    CR_DRAPE_SCENE_COUNT
} cr_drape_scene;

/* "ball", "torus", "prism", "table", "object". */
const char *cr_drape_scene_name(cr_drape_scene s);
/* Accepts the four named scenes (not "object": that is --object FILE). */
cr_status cr_drape_scene_parse(const char *name, cr_drape_scene *out, cr_error *err);

/* cr_drape_collision_mode (CR_DRAPE_COLLIDE_VERTEX, _SDF): phys_energies.h, with the
 * collision energy. */

/* Loss weights (Table 4). */
typedef struct cr_drape_weights {
    float strain;    /* w_Strain (paper 0.005) */
    float bend;      /* w_Bend (paper 0.0005) */
    float gravity;   /* w_Gravity (paper 2) */
    float collision; /* w_Collision (paper 1e7 ball, table; 1e6 torus, prism) */
} cr_drape_weights;

/* The four terms, weighted, and their sum (J up to the loss's scale). */
typedef struct cr_drape_terms {
    double strain, bend, gravity, collision, total;
} cr_drape_terms;

/* ------------------------------------------------------------ the run -- */

typedef struct cr_drape_def {
    cr_drape_scene scene;
    const char *object_path; /* CR_DRAPE_OBJECT: the object mesh (OBJ, PLY, glb) */
    const char *cloth_path; /* NULL: the square cloth; else a rest cloth mesh with UVs in [0,1]^2 */
    cr_drape_variant variant;

    /* scene */
    float cloth_size; /* m, side of the square cloth; 0 (the default): from the object,
                         cr_drape_cloth_placement */
    float gap;        /* m, drop height of the square cloth above the object's top; < 0 (the
                         default): from the cloth's size */
    int mesh_res;     /* vertices per side of the mesh variants' grid (default 128) */

    /* losses */
    cr_drape_weights w;                /* Table 4 for the scene */
    float point_mass;                  /* kg, m(p) of eq. 24 per structure or vertex (default 1e-4,
                                          docs/drape.md) */
    float gravity;                     /* m/s^2 (default 9.81) */
    float collision_eps;               /* m, eps of eq. 26 (default 0.002) */
    cr_drape_collision_mode collision; /* default CR_DRAPE_COLLIDE_VERTEX */
    float side;                        /* structure side in UV (default 0.001) */
    float pin; /* holds the chart centre's horizontal position: pin * (structures
                  or vertices) * |dx, dz|^2, standing in for the friction that
                  keeps a real cloth from sliding off (default 1; 0: free) */

    /* model (INR variants) */
    int grid_levels;     /* default 2 */
    int grid_resolution; /* cells per side of the finest level (default 100: 101x101 nodes) */
    int grid_features;   /* default 3 */
    cr_grid_interp grid_interp; /* between the grid's nodes (nn_layers.h; default
                                   CR_GRID_BSPLINE, docs/drape.md "Smooth cloth") */
    int mlp_hidden;             /* hidden width (default 64) */
    int mlp_layers;             /* linear layers (default 4: 6-64-64-64-3) */
    float softplus_beta;        /* hidden activation softplus(beta z)/beta (default 10); 0: ReLU */

    /* training */
    float lr;          /* Adam learning rate at the first epoch (default 0.0005) */
    float lr_final;    /* at the last epoch, cosine from lr; < 0: no cosine (default -1) */
    int settle_epochs; /* without a cosine: the last this many epochs (at most half the
                          run) go at lr / 10, so contacts settle out of the eps band
                          (default 250; 0: constant lr throughout); with
                          stop_at_converged, the epochs after convergence */
    float beta2;       /* Adam's second-moment decay (default 0.999) */
    float clip;        /* gradient-norm clip, times the running mean of recent norms (default 3;
                          0: off) */
    int epochs;        /* cap on epochs, >= 1 (default 15000) */
    int samples;       /* N structures per epoch (default 1024) */

    /* sampler (structure variants) */
    int pdf_grid;         /* PDF cells per side (default 32) */
    float pdf_gamma;      /* eq. 7 blend (default 0.9) */
    float mu;             /* adaptive share of the samples (default 0.5; inr-uniform: 0) */
    int lloyd_iterations; /* default 2 */
    int pdf_every;        /* epochs between PDF updates (default 5) */
    float pdf_collision;  /* the collision term's weight in the PDF's per-cell loss, times
                             its training weight (default 1; gravity's is always 0) */

    /* convergence */
    int eval_res;          /* fixed structures per side (default 128) */
    int eval_every;        /* epochs between evaluations (default 50) */
    int converge_window;   /* epochs (default 2000) */
    float converge_tol;    /* default 0.01 */
    int stop_at_converged; /* 1 (default): stop there, after settle_epochs at lr / 10;
                              0: train to `epochs` */

    uint64_t seed; /* initialisation, sampling, rotations (default 1) */

    /* outputs */
    const char *out_dir;  /* NULL: write nothing */
    int out_res;          /* output surface vertices per side (default 256) */
    int render_size;      /* PNG side, px (default 1024) */
    int checkpoint_every; /* epochs between checkpoints (default 250; 0: only at the end) */
    int resume;           /* 1: continue from out_dir/checkpoint.safetensors when present */
    int quiet;            /* 1: no progress bar */
    /* Called after every evaluation on the fixed structures, the start's
     * included (NULL: none): the epoch, the training seconds so far and the
     * weighted terms, as loss.jsonl has them. For live plots and benchmarks
     * that need the whole curve without an out_dir; a resumed run calls it
     * only for the evaluations it makes. */
    void (*on_eval)(void *user, int epoch, double seconds, const cr_drape_terms *terms);
    void *on_eval_user;
    uint32_t cookie; /* set by cr_drape_default_def */
} cr_drape_def;

/* The def's fields by group, as cr_config_key tables: their ranges (what
 * cr_drape_def_validate checks, with the few a field's meaning narrows) and the
 * options of `crease drape` with their help; n gets the group's length. */
typedef enum cr_drape_key_group {
    CR_DRAPE_KEYS_SCENE,
    CR_DRAPE_KEYS_TRAINING,
    CR_DRAPE_KEYS_LOSSES,
    CR_DRAPE_KEYS_MODEL,
    CR_DRAPE_KEYS_SAMPLER,
    CR_DRAPE_KEYS_CONVERGENCE,
    CR_DRAPE_KEYS_OUTPUTS,
    CR_DRAPE_KEY_GROUPS
} cr_drape_key_group;
const cr_config_key *cr_drape_def_keys(cr_drape_key_group g, int *n);

/* Defaults for `scene` with Table 4's weights (collision 1e6 for torus and
 * prism, 1e7 otherwise) and variant inr-adaptive. */
cr_drape_def cr_drape_default_def(cr_drape_scene scene);
/* CR_ERR_INVALID naming the field for anything out of range or not finite. */
cr_status cr_drape_def_validate(const cr_drape_def *def, cr_error *err);

typedef struct cr_drape_result {
    int64_t params;           /* free variables (network parameters or 3 x vertices) */
    int epochs;               /* epochs trained in all, resumed ones included */
    int resumed_from;         /* epoch the run resumed from (0: fresh) */
    double seconds;           /* training wall time (sampling included, evaluation excluded), s */
    double eval_seconds;      /* time spent on the convergence evaluation, s */
    int converged_epoch;      /* first epoch meeting the criterion; -1 if never */
    double converged_seconds; /* training time to that epoch; -1 if never */
    cr_drape_terms terms;     /* last evaluation on the fixed structures */
    cr_drape_terms initial;   /* first evaluation (the flat start of a fresh run) */
    double max_penetration_m; /* deepest output vertex inside the object (signed distance) */
    double facet_ratio;       /* cr_drape_facet_ratio of the output surface against the finest
                                 grid level's cells (the mesh variants: the vertex grid's);
                                 NaN on a user's cloth (no output grid) */
    double cloth_size_m;      /* side of the square cloth used, m (0: a user's cloth) */
    double drop_height_m;     /* its height above the object's top at the start, m */
    char obj_path[1024], glb_path[1024], png_path[1024], loss_png[1024], log_path[1024],
        sampler_png[1024], checkpoint_path[1024]; /* written files; "" when not written */
} cr_drape_result;

/* The square cloth's side and drop height for def on an object whose
 * bounding box is lo..hi (Y up). Given values win. Otherwise the side is 1 m
 * on the built-in scenes (Table 4's cloth; the ball's 0.6 m diameter is 3/5
 * of it) and 5/3 of the object's larger horizontal extent on a user's object,
 * so a sphere of any size is covered as the ball is; the drop height is 5 %
 * of the side (the ball's 5 cm). */
void cr_drape_cloth_placement(const cr_drape_def *def, const float lo[3], const float hi[3],
                              float *size, float *drop_height);

/* Train, evaluate and (with out_dir) write: drape.obj and drape.glb (the
 * surface at out_res), drape.png (cloth over object), loss.jsonl (one line
 * per evaluation: epoch, seconds, each weighted term on the fixed structures,
 * and the last training batch's), loss.png (those terms over epochs),
 * sampler.png (the INR variants: the PDF and the last sample points) and
 * checkpoint.safetensors (resumable). When
 * `surface` is not NULL it receives the output surface (caller destroys). */
cr_status cr_drape_run(const cr_drape_def *def, cr_drape_result *out, cr_mesh **surface,
                       cr_error *err);

/* All four variants on def's scene, each into out_dir/<variant>/, and
 * out_dir/compare.png with their renders side by side (mesh, inr-mesh,
 * inr-uniform, inr-adaptive, left to right, named underneath). `results`
 * (CR_DRAPE_VARIANT_COUNT, may be NULL) receives each run's result. */
cr_status cr_drape_compare(const cr_drape_def *def, cr_drape_result *results, char *png_path,
                           size_t png_cap, cr_error *err);

/* ---------------------------------------------------------- fidelity -- */

/* Wavelength bands of the mean-curvature spectrum: eval.h's
 * (cr_eval_h_band_edges_m, m). */
enum { CR_DRAPE_H_BANDS = CR_EVAL_H_BANDS };

typedef struct cr_drape_fidelity {
    double chamfer_m;         /* symmetric Chamfer distance to the reference (the mean of both
                                 directions' mean closest-point distances), m; NAN without one */
    double max_penetration_m; /* deepest vertex inside the object (signed distance), m; NaN
                                 for an open object (no inside) */
    double h_rms;             /* area-weighted RMS of the signed mean curvature, 1/m */
    double h_band[CR_DRAPE_H_BANDS]; /* share of the mean curvature's spatial power per band */
} cr_drape_fidelity;

/* Compare a draped surface with a reference drape of the same scene (may be
 * NULL) and the object. The spectrum: signed mean curvature per vertex
 * (cotangent Laplacian . vertex normal / 2 mixed area; boundary vertices 0),
 * resampled over the UV chart on a 256x256 grid, mean removed, 2-D DFT
 * power binned by wavelength (UV frequency scaled by the chart's metres per
 * UV unit). Wrinkles show as power in the short-wavelength bands. Both
 * meshes need UVs (CR_ERR_INVALID otherwise). */
cr_status cr_drape_fidelity_measure(const cr_mesh *surface, const cr_mesh *reference,
                                    const cr_mesh *object, cr_drape_fidelity *out, cr_error *err);

/* Grid facets of a surface sampled on a regular grid: pos (NV,NU,3), row iv
 * at v = iv / (NV-1), column iu at u = iu / (NU-1), over a UV chart cut
 * into `cells` x `cells` cells (the grid encoding's finest level). Along
 * every row and every column, each span of three vertices gives the norm
 * of its second difference |p[k-1] - 2 p[k] + p[k+1]|; the result is the
 * mean over the spans whose open UV interval holds a cell boundary divided
 * by the mean over those that hold none. About 1 on a smooth surface; a
 * surface with creases of its slope at the cell boundaries (bilinear
 * cells) gives more, as each crease adds to the second difference of the
 * spans across it only. NaN when either set of spans is empty or the
 * non-crossing mean is 0 (a plane). */
double cr_drape_facet_ratio(const float *pos, int nu, int nv, int cells);

/* ------------------------------------------------------------ scenes -- */

/* The scene's object, Y up, finely tessellated for the nearest-vertex
 * collision (about 25,000 vertices, as in Table 4): ball, torus, prism (a
 * subdivided prism), table (a subdivided box); CR_DRAPE_OBJECT reads `path`
 * (CR_ERR_INVALID when NULL, CR_ERR_TOPOLOGY naming the first vertex no face
 * uses). The caller destroys *out. */
cr_status cr_drape_scene_object(cr_drape_scene scene, const char *path, cr_mesh **out,
                                cr_error *err);

/* ---------------------------------------------------- local structures -- */

enum {
    CR_DRAPE_STRUCT_VERTS = 6, /* A, B, C, D, E, F */
    CR_DRAPE_STRUCT_EDGES = 9, /* AB BC CA BD DC CE EA AF FB */
    CR_DRAPE_STRUCT_HINGES = 3 /* (B,C,A,D) (C,A,B,E) (A,B,C,F) */
};

/* Local vertex indices of each structure's edges (9,2) and face pairs (3,4)
 * in the hinge layout of topology.h: face A = (x0,x1,x2), face B = (x1,x0,x3). */
extern const int32_t cr_drape_struct_edges[CR_DRAPE_STRUCT_EDGES][2];
extern const int32_t cr_drape_struct_hinges[CR_DRAPE_STRUCT_HINGES][4];

/* UVs of n structures: centre (N,2), angle theta (N) in radians, side s ->
 * uv (N,6,2). A, B, C lie at angles theta + pi/2, + 7pi/6, + 11pi/6 at
 * distance s/sqrt(3) from the centre (counter-clockwise); D = B + C - A,
 * E = C + A - B, F = A + B - C. Every vertex lies within 2s/sqrt(3) of the centre. */
void cr_drape_structures(const float *centre, const float *theta, int64_t n, float side, float *uv);

/* The four losses are energies of phys/ (phys_energies.h: cr_drape_strain,
 * cr_drape_bend, cr_drape_gravity, cr_drape_collision), on the tape through
 * cr_loss_energy (losses.h). */

/* ------------------------------------------------------------- model -- */

/* The learned surface: the INR (grid encoding + MLP over p0) or, for the
 * mesh variant, the free vertex grid (queried between vertices by
 * barycentric interpolation). */
typedef struct cr_drape_model cr_drape_model;

/* `rest` is the rest cloth with UVs (borrowed for the model's life); the
 * mesh variant makes a grid of def->mesh_res vertices per side over rest's
 * UV chart. CR_ERR_INVALID when rest has no UVs. */
cr_status cr_drape_model_create(const cr_drape_def *def, const cr_mesh *rest, cr_drape_model **out,
                                cr_error *err);
void cr_drape_model_destroy(cr_drape_model *m); /* NULL is a no-op */
int64_t cr_drape_model_param_count(const cr_drape_model *m);
/* Rest positions p0 (N,3) under uv (N,2); returns how many points lie on the
 * chart (others get p0 = 0 and valid[i] = 0; `valid` may be NULL). */
int64_t cr_drape_model_rest(const cr_drape_model *m, const float *uv, int64_t n, float *p0,
                            uint8_t *valid);
/* Positions at uv (N,2) given their rest positions p0 (N,3): a differentiable
 * (N,3) tensor in ctx (the parameters get gradients). */
cr_tensor *cr_drape_model_forward(cr_nn_ctx *ctx, cr_drape_model *m, const float *uv,
                                  const float *p0, int64_t n);
/* The free variables, for checkpoints and tests: the INR's grid levels
 * ("grid.level<l>") and MLP ("mlp.<i>.weight", ".bias"), or the mesh
 * variant's vertex positions ("vertices", (V,3), m). Owned by the model. */
cr_nn_params *cr_drape_model_params(cr_drape_model *m);

#ifdef __cplusplus
}
#endif
#endif
