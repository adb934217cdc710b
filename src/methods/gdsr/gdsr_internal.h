/* gdsr_internal.h: what the gdsr files share. */
#ifndef CREASE_GDSR_INTERNAL_H
#define CREASE_GDSR_INTERNAL_H

#include "crease/bvh.h"
#include "crease/gdsr.h"
#include "crease/nn_graph.h"
#include "crease/nn_layers.h"
#include "crease/phys_energies.h"
#include "crease/render.h"
#include "crease/topology.h"

#define CR_GDSR_COOKIE 0x67647372u

struct cr_gdsr_model {
    cr_gdsr_model_def def;
    cr_nn_params *params;
    cr_mpnn *net;    /* H */
    cr_mlp *dec;     /* E: 3 decoder_features -> 9 */
    cr_mlp *gen;     /* A's generator: 3 hyper_features -> P */
    int64_t nparams; /* P: the WIRE target's floats per triangle */
};

/* Column k of m's triangles: (F) the k-th corner of every face (malloc'd;
 * NULL when out of memory). */
int32_t *cr_gdsr_tri_column(const cr_mesh *m, int k);

/* m rendered by def into out with each layer (cr_gdsr_mesh_layers) in its own
 * cloth colour: a single garment blue, an outfit's second layer tan, then
 * green and mauve (layers past four take the last). compare.png's panels. */
cr_status cr_gdsr_render_layers(const cr_render_def *def, const cr_mesh *m, cr_image *out,
                                cr_error *err);

/* The regularisers of regularise.c, built once from a rest mesh (the high
 * one for the output, the low one for C^). */
typedef struct gdsr_reg {
    cr_membrane *membrane; /* Baraff-Witkin, unit stiffnesses, rest = the rest mesh laid flat */
    cr_topology *topo;
    cr_bending *bending;  /* k_b = 1 */
    double membrane_norm; /* 2 / total rest area */
    double bending_norm;  /* 1 / hinges */
    int32_t nv;
    int64_t lap_n; /* directed 1-ring edges */
    int32_t *lap_snd, *lap_rcv;
    float *lap_inv_deg; /* (V) */
    float *theta_ref;   /* (H) scratch: the reference's dihedral angles */
    double *xd;         /* (V,3) scratch */
    int32_t nf;
    int32_t *corner[3];   /* (F) each triangle's vertices */
    float *cu[3], *cv[3]; /* (F) w_u = sum_i cu[i] x_i, w_v likewise (from Dm^-1) */
    float *strain_ref;    /* (F,3) scratch: |w_u|, |w_v|, w_u . w_v of the reference */
} gdsr_reg;

cr_status cr_gdsr_reg_create(const cr_mesh *high, gdsr_reg *r, cr_error *err);
void cr_gdsr_reg_free(gdsr_reg *r); /* zeroes it; a zeroed struct is a no-op */
/* The four terms of the output x (V,3) against the reference ref (V,3), each
 * a scalar mean (unweighted): stretch, shear, bending toward ref's dihedral
 * angles, L1 of the Laplacian of x - ref. */
void cr_gdsr_reg_terms(cr_nn_ctx *ctx, gdsr_reg *r, cr_tensor *x, const float *ref,
                       cr_tensor **stretch, cr_tensor **shear, cr_tensor **bend, cr_tensor **lap);
/* Eq. 16-18 / 21-23: the output's strain against the reference's, mean over
 * triangles of ||w_u(x)| - |w_u(ref)|| + ||w_v(x)| - |w_v(ref)|| +
 * |w_u.w_v(x) - w_u.w_v(ref)| (w from the rest mesh laid flat, as crease eval's
 * e_u, e_v, e_uv). A scalar. */
cr_tensor *cr_gdsr_reg_strain_l1(cr_nn_ctx *ctx, gdsr_reg *r, cr_tensor *x, const float *ref);
/* k_b/2 (theta(x) - theta(ref))^2, mean over hinges (NULL when out of memory). */
cr_tensor *cr_gdsr_reg_bend(cr_nn_ctx *ctx, gdsr_reg *r, cr_tensor *x, const float *ref);
/* Eq. 15's smoothing: the mean over (V,3) of the squared uniform Laplacian
 * of x itself (not of an error). A scalar. */
cr_tensor *cr_gdsr_reg_smooth(cr_nn_ctx *ctx, const gdsr_reg *r, cr_tensor *x);

/* The wrinkle loss of wrinkle.c (Eq. 20 with a fixed filter bank in place
 * of VGG): the output's and the reference's normal maps over the UV chart,
 * through oriented first and second differences at CR_GDSR_WRINKLE_SCALES
 * scales, compared by L1. Built once from the rest high mesh. */
enum { CR_GDSR_WRINKLE_SCALES = 3, CR_GDSR_WRINKLE_TAPS = 9 };
typedef struct gdsr_wrinkle {
    int32_t nv, nf, side;
    int32_t *corner[3]; /* (F) each triangle's vertices */
    int64_t ntex;       /* texels on the chart */
    int32_t *tex_v[3];  /* (ntex) the corners of each texel's triangle */
    float *tex_b[3];    /* (ntex) its barycentrics */
    /* per scale, the texels whose eight neighbours at that step are on the
     * chart: tap 0 the texel, taps 2d+1 / 2d+2 its + / - neighbour along
     * direction d (rows, columns, both diagonals), as indices into the texels */
    int64_t nvalid[CR_GDSR_WRINKLE_SCALES];
    int32_t *tap[CR_GDSR_WRINKLE_SCALES][CR_GDSR_WRINKLE_TAPS];
    int32_t *valid_px[CR_GDSR_WRINKLE_SCALES]; /* (nvalid) row * side + column of each */
    int32_t *tex_px;                           /* (ntex) row * side + column of each texel */
    int32_t *scratch;                          /* (ntex) patch member indices */
} gdsr_wrinkle;

/* A square crop of the normal map: rows r0 .. r0 + side - 1, columns c0 ... */
typedef struct gdsr_patch {
    int32_t r0, c0, side;
} gdsr_patch;

/* side: the normal map is side^2 texels over the UV bounds (needs UVs). */
cr_status cr_gdsr_wrinkle_create(const cr_mesh *high, int side, gdsr_wrinkle *w, cr_error *err);
void cr_gdsr_wrinkle_free(gdsr_wrinkle *w); /* zeroes it; a zeroed struct is a no-op */
/* Unit normals (ntex,3) of x (V,3) at the texels: area-weighted vertex
 * normals interpolated by the texel's barycentrics, normalised (crease
 * eval's normal map before its (n + 1) / 2). */
cr_tensor *cr_gdsr_wrinkle_normals(cr_nn_ctx *ctx, const gdsr_wrinkle *w, cr_tensor *x);
/* n patches (Eq. 20-24's P) of side x side texels (at most the map's side),
 * each around a chart texel drawn uniformly (so every patch holds garment)
 * and moved inside the map. */
void cr_gdsr_wrinkle_draw_patches(const gdsr_wrinkle *w, int n, int side, cr_rng *rng,
                                  gdsr_patch *out);
/* Eq. 24's mean over the patches of Eq. 20's feature term: per patch the
 * sum over scales of the mean |R(x) - R(ref)| over the filter responses R at
 * the patch's texels (a patch with none at a scale skips it). patches NULL
 * or npatches 0: the whole chart as one patch. energy 1: per patch and
 * scale the mean over the 24 responses of |RMS(R(x)) - RMS(R(ref))|, the
 * RMS over the patch's texels (phase-free). A scalar. */
cr_tensor *cr_gdsr_wrinkle_loss(cr_nn_ctx *ctx, const gdsr_wrinkle *w, cr_tensor *x,
                                const float *ref, const gdsr_patch *patches, int npatches,
                                int energy);

/* The model def as JSON (heap string) and back; reading refuses unknown,
 * ill-typed and missing fields (CR_ERR_PARSE naming `source` and the field). */
char *cr_gdsr_model_def_json(const cr_gdsr_model_def *def);
cr_status cr_gdsr_model_def_from_json(const char *json, const char *source, cr_gdsr_model_def *def,
                                      cr_error *err);
/* The first stored field where a and b differ (its values into *va, *vb), or
 * NULL when they agree. */
const char *cr_gdsr_model_def_differ(const cr_gdsr_model_def *a, const cr_gdsr_model_def *b,
                                     double *va, double *vb);

/* collide.c. Push points of x (n,3) with signed distance below eps out
 * along the body's normal; returns how many were inside (sd < 0) before.
 * The push of each point is written to push (may be NULL). sd (n), nrm
 * (n,3) scratch. */
int64_t cr_gdsr_push_out(const cr_bvh *b, float *x, int64_t n, float eps, float *sd, float *nrm,
                         float *push);
/* Scratch of cr_gdsr_relax_push over V vertices. */
typedef struct cr_gdsr_relax_scratch {
    float *sd, *nrm; /* (V), (V,3) */
    float *d, *dn;   /* (V,3) each */
    float *x0, *lb;  /* (V,3), (V): the positions and distances after the first push;
                        lb NULL: every vertex in doubt is queried (x0 unused) */
    int32_t *idx;    /* (V) */
    uint8_t *moved;  /* (V) */
} cr_gdsr_relax_scratch;

/* Push x (V,3), the mesh of t, out to eps, spread its displacement from
 * raw by `iters` Jacobi steps of the uniform Laplacian on the moved
 * vertices and their one-ring, each followed by a push out, then push out
 * once more the vertices that moved (0 iterations: the per-vertex push,
 * twice). After the first push every vertex's distance bounds where it can
 * be later in the call, so the later pushes query only vertices that may
 * lie within eps of the body (the same result as querying them all). */
void cr_gdsr_relax_push(const cr_bvh *b, const cr_topology *t, const float *raw, float *x,
                        float eps, int iters, const cr_gdsr_relax_scratch *s);

/* cr_gdsr_features with the vertex normals' scratch nrm (Vl,3) given (NULL:
 * zero normals), so that a runtime step allocates nothing. */
void cr_gdsr_features_(const cr_mesh *low, const cr_gdsr_graph *g, const cr_gdsr_frame_in *in,
                       float sigma_b, float *nrm, float *node, float *edge0, float *edge1);

/* One frame's features for model md on d (the roll-out's, the runtime's
 * and training's): cr_gdsr_features_ and, with layer edges in the model and
 * two layers or more, this frame's layer edges (set 2 of g, found at in->c)
 * and their features into *e2, grown (realloc) past *e2cap when needed. */
cr_status cr_gdsr_frame_features_(const cr_gdsr_data *d, const cr_gdsr_model_def *md,
                                  cr_gdsr_graph *g, const cr_gdsr_frame_in *in, float *nrm,
                                  float *node, float *e0, float *e1, float **e2, int64_t *e2cap,
                                  cr_error *err);

/* Validation (train.c): the sums of the vertex distances (m) of the model's
 * raw roll-out and of upsampling to the reference over clips first.. of d,
 * frames 2.. (the model's), and their count, added to s, su, n. */
cr_status cr_gdsr_validate(cr_gdsr_model *m, const cr_gdsr_data *d, int first, double *s,
                           double *su, int64_t *n, cr_error *err);

/* Layer collisions (Eq. 27, collide.c): exterior coarse vertices of C^
 * (Vl,3) within gamma of their partner on a layer under theirs and closer
 * than sigma along the normal there are pushed out along it to sigma (in
 * place), the push carried to x (Vh,3) through Eq. 1, then the high
 * vertices whose nearest coarse vertex was pushed are pushed by Eq. 27. The
 * partner: surface 0, the nearest vertex and its normal (the paper's);
 * surface 1, the closest point on the layer's triangles and the normal
 * there, none where that point is on the layer's open edge. Returns the
 * coarse vertices pushed (fine_pushed, may be NULL: the high ones), -1 with
 * err set on failure; 0 for a single layer. */
int64_t cr_gdsr_layer_push(const cr_gdsr_data *d, float *chat, float *x, float sigma, float gamma,
                           int surface, int64_t *fine_pushed, cr_error *err);

/* measure.c: one row of gdsr run's table, the prediction pred (T,Vh,3) of clip cl against
 * its high reference from frame 2 on, into table[name] (and its log line); with an outfit
 * the layer crossings too. */
struct cJSON;
void cr_gdsr_measure_header_(void); /* the table's header line, logged */
cr_status cr_gdsr_measure_row_(const cr_gdsr_data *d, const cr_gdsr_clip *cl, const float *pred,
                               const char *name, struct cJSON *table, cr_error *err);
/* The edge-face crossings between the layers of frames 2.. of x (T,Vh,3): their mean and
 * largest count a frame and the frames with any, into o. */
cr_status cr_gdsr_measure_crossings_(const cr_gdsr_data *d, const float *x, int32_t T,
                                     struct cJSON *o, const char *name, cr_error *err);
/* E_u, E_v, E_uv of every frame of gdsr and of upsampling: out/strain.csv, out/strain.png
 * and j's "strain" (the last frame against frame 2's: the drift). */
cr_status cr_gdsr_measure_strain_(const cr_gdsr_data *d, const cr_gdsr_clip *cl,
                                  const cr_gdsr_rollout_result *r, const char *out, struct cJSON *j,
                                  cr_error *err);

#endif
