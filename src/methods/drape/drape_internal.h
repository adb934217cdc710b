/* drape_internal.h (private): what the drape method's files share: the
 * scene, batches of local structures with their rest data, the mesh losses
 * of the mesh variants, the loss plot and the bitmap text it uses.
 *
 * Shapes: N structures, P = 6N structure vertices, E edges, H hinges,
 * V mesh vertices, G PDF cells per side.
 */
#ifndef CREASE_METHODS_DRAPE_INTERNAL_H
#define CREASE_METHODS_DRAPE_INTERNAL_H

#include "crease/drape.h"
#include "crease/render.h"
#include "crease/topology.h"

/* ------------------------------------------------------------ scene -- */

typedef struct drape_scene {
    cr_mesh *object;     /* the collider, Y up */
    cr_bvh *bvh;         /* over object */
    cr_mesh *rest;       /* the rest cloth (square plane at mesh_res, or the user's) */
    int square;          /* 1: the built-in square cloth (chart = all of [0,1]^2) */
    float metres_per_uv; /* sqrt(3-D area / UV area) of the rest cloth */
    float cloth_size;    /* square cloth: its side and drop height, m (0 for a user's cloth) */
    float drop_height;
    int32_t open_edges; /* boundary edges of the object: > 0, it has no inside to measure */
} drape_scene;

cr_status cr_drape_scene_create(const cr_drape_def *def, drape_scene *s, cr_error *err);
void cr_drape_scene_free(drape_scene *s);

/* ------------------------------------------------------- structures -- */

/* The losses' shared part: the weights and the two per-point energies, whose
 * data do not depend on the elements (phys/drape_gravity.c,
 * drape_collision.c). The batches and the mesh losses own their edges and
 * hinges. Owned energies; def and the BVH are borrowed. */
typedef struct drape_loss_ctx {
    const cr_drape_def *def;       /* weights def->w, mass, g, eps, collision mode */
    cr_drape_gravity *gravity;     /* m g y per point */
    cr_drape_collision *collision; /* min(s - eps, 0)^2 per point against the object */
} drape_loss_ctx;

cr_status cr_drape_loss_ctx_create(const cr_drape_def *def, const cr_bvh *object,
                                   drape_loss_ctx *out, cr_error *err);
void cr_drape_loss_ctx_free(drape_loss_ctx *lc);

/* The four terms, strain, bend, gravity, collision, at positions x (P,3)
 * through the generic loss op: each an energy (1), or with per_element its
 * elements' energies ((E), (H), (P), (P)). Gravity and collision take P from
 * x (this sets their counts: one caller at a time per drape_loss_ctx; the
 * terms already on the tape are not affected). NULL entries on error (the
 * context records it). */
void cr_drape_loss_terms(cr_nn_ctx *ctx, const drape_loss_ctx *lc, const cr_drape_strain *strain,
                         const cr_drape_bend *bend, cr_tensor *x, int per_element, cr_tensor *t[4]);
/* The weights of the four terms: w, with gravity over the six vertices of a
 * structure when per_structure (eq. 24 at the structure's mean height). */
void cr_drape_loss_weights(const cr_drape_weights *w, int per_structure, float out[4]);

/* A batch of local structures ready for the losses. Index arrays address
 * the batch's own vertex rows (structure k owns rows 6k..6k+5). */
typedef struct drape_batch {
    int64_t n;               /* structures kept (all six vertices on the chart) */
    int64_t cap;             /* structures allocated */
    float *uv;               /* (P,2) */
    float *p0;               /* (P,3) rest positions, m */
    float *rest;             /* (9N) rest edge lengths, m */
    int32_t *edges;          /* (9N,2) */
    int32_t *hinges;         /* (3N,4) */
    int32_t *source;         /* (N) index of each kept structure among the centres given */
    cr_drape_strain *strain; /* the 9N edges with their rest lengths (eq. 19) */
    cr_drape_bend *bend;     /* the 3N face pairs (eq. 22) */
    /* scratch for building */
    float *all_uv;  /* (cap*6,2) */
    float *all_p0;  /* (cap*6,3) */
    uint8_t *valid; /* (cap*6) */
} drape_batch;

cr_status cr_drape_batch_alloc(drape_batch *b, int64_t cap, cr_error *err);
void cr_drape_batch_free(drape_batch *b);
/* Structures at centres (N,2) with angles theta (N); with `inset`, centres in
 * [0,1]^2 are first mapped affinely onto [r, 1-r]^2, r = 2 side / sqrt(3), so
 * every vertex of every structure lies on a full square chart. Structures
 * with a vertex off the chart or a rest edge of zero length are dropped.
 * Fills the batch's strain and bend elements (no allocation: cap was). */
cr_status cr_drape_batch_build(drape_batch *b, const cr_drape_model *m, const float *centre,
                               const float *theta, int64_t n, float side, int inset, cr_error *err);

/* The batch's weighted loss at positions x (P,3) as a scalar tensor (the sum
 * over structures); terms_out (4, may be NULL) gets the weighted strain,
 * bend, gravity and collision sums as scalar tensors. */
cr_tensor *cr_drape_batch_loss(cr_nn_ctx *ctx, const drape_loss_ctx *lc, const drape_batch *b,
                               cr_tensor *x, cr_tensor **terms_out);
/* Forward only, on the host: the weighted terms summed over the batch into
 * sums[4] (added to), and each structure's weighted total into
 * per_structure (N, may be NULL). x (P,3) are the batch's positions. */
cr_status cr_drape_batch_eval(cr_nn_ctx *ctx, const drape_loss_ctx *lc, const drape_batch *b,
                              const float *x, double sums[4], float *per_structure, cr_error *err);

/* -------------------------------------------------------- mesh losses -- */

/* The mesh variants' elements and weights: the rest mesh's unique edges with
 * rest lengths and its hinges; weights rescaled to estimate the structure
 * losses' energy per area (docs/drape.md). */
typedef struct drape_mesh_losses {
    int32_t ne, nh;
    int32_t *edges;          /* (E,2) */
    float *rest;             /* (E) m */
    int32_t *hinges;         /* (H,4) */
    cr_drape_strain *strain; /* the edges with their rest lengths */
    cr_drape_bend *bend;     /* the hinges */
    cr_drape_weights w;
} drape_mesh_losses;

cr_status cr_drape_mesh_losses_create(const cr_drape_def *def, const drape_scene *s,
                                      drape_mesh_losses *out, cr_error *err);
void cr_drape_mesh_losses_free(drape_mesh_losses *ml);

/* ------------------------------------------------------------ model -- */

/* For the mesh variants: the (V,3) positions of the rest mesh's vertices as
 * a differentiable tensor (the free vertices, or the INR at their UVs). */
cr_tensor *cr_drape_model_vertices(cr_nn_ctx *ctx, cr_drape_model *m);
/* Forward only: positions at uv (N,2) with rest positions p0 (N,3), in chunks. */
cr_status cr_drape_model_eval(cr_nn_ctx *ctx, cr_drape_model *m, const float *uv, const float *p0,
                              int64_t n, float *x, cr_error *err);
const cr_uv_lookup *cr_drape_model_lookup(const cr_drape_model *m);

/* ---------------------------------------------------------- outputs -- */

/* The learned surface as a mesh: a res x res plane over the square chart, or
 * the rest cloth's own triangulation for a user cloth. */
cr_status cr_drape_surface_mesh(cr_nn_ctx *ctx, cr_drape_model *m, const drape_scene *s, int res,
                                cr_mesh **out, cr_error *err);
/* Deepest vertex of `surface` inside the object, m (0 when none). */
double cr_drape_max_penetration(const cr_bvh *object, const cr_mesh *surface);
/* Cloth (blue) over the object (grey) into `img` (new). */
cr_status cr_drape_render(const cr_mesh *surface, const cr_mesh *object, int size, cr_image *img,
                          cr_error *err);

/* One loss-log record. */
typedef struct drape_log_row {
    int epoch;
    double seconds;
    cr_drape_terms eval;  /* mean weighted terms per fixed structure */
    cr_drape_terms train; /* mean weighted terms of the last training batch */
} drape_log_row;

/* Loss curves: strain, bend and collision on a log axis above, gravity and
 * the potential (strain + bend + gravity) on a linear axis below. */
cr_status cr_drape_plot_losses(const drape_log_row *rows, int n, const char *path, cr_error *err);

/* ------------------------------------------------------------ training -- */

struct cr_drape_sampler;
struct cr_optim;
/* A training run's state (train.c), what run.c writes the outputs from. */
typedef struct drape_run {
    const cr_drape_def *def;
    drape_scene scene;
    cr_drape_model *model;
    struct cr_optim *opt;
    cr_nn_ctx *ctx;
    cr_rng rng;
    drape_loss_ctx lc;
    int structures; /* 1: local-structure variants */
    int drawn;      /* 1 once centre holds this run's samples */
    struct cr_drape_sampler *sampler;
    drape_batch train, cells;
    drape_batch *eval; /* (ceil(M / EVAL_BATCH)) the fixed structures, built once */
    int neval_batches, eval_built;
    float *centre, *theta;           /* (N,2), (N) this epoch's samples */
    float *cell_loss;                /* (G*G) */
    float *cell_theta;               /* (G*G) */
    float *eval_centre, *eval_theta; /* (M,2), (M) fixed */
    int64_t neval;
    float *x;             /* (6 max(N, G*G, EVAL_BATCH), 3) host positions */
    float *per_structure; /* (max(N, G*G, EVAL_BATCH)) */
    drape_mesh_losses ml;
    drape_log_row *rows;
    int nrows, caprows;
    cr_drape_terms train_terms; /* last epoch's, mean per structure (per vertex for meshes) */
    double grad_mean;           /* running mean of the clipped gradient norm; 0 before the first */
    int pinned;                 /* 1: the chart centre is held horizontally */
    float pin_uv[2], pin_p0[3]; /* the pinned UV point and its rest position */
    char ckpt_path[1024], log_path[1024];
} drape_run;

/* Set up (or resume from def->out_dir's checkpoint) and train to convergence or the cap;
 * res gets the epochs, timings, convergence and the first evaluation. r holds the trained
 * state either way: free it with cr_drape_train_free_. */
cr_status cr_drape_train_(const cr_drape_def *def, drape_run *r, cr_drape_result *res,
                          cr_error *err);
/* The checkpoint with res's figures (out_dir/checkpoint.safetensors). */
cr_status cr_drape_checkpoint_(drape_run *r, const cr_drape_result *res, cr_error *err);
void cr_drape_train_free_(drape_run *r);

#endif
