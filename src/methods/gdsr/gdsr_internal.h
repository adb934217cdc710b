/* gdsr_internal.h: what the gdsr files share. */
#ifndef CREASE_GDSR_INTERNAL_H
#define CREASE_GDSR_INTERNAL_H

#include "crease/gdsr.h"
#include "crease/nn_graph.h"
#include "crease/nn_layers.h"
#include "crease/phys_energies.h"
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

/* The regularisers of regularise.c, built once from the rest high mesh. */
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
} gdsr_reg;

cr_status cr_gdsr_reg_create(const cr_mesh *high, gdsr_reg *r, cr_error *err);
void cr_gdsr_reg_free(gdsr_reg *r); /* zeroes it; a zeroed struct is a no-op */
/* The four terms of the output x (V,3) against the reference ref (V,3), each
 * a scalar mean (unweighted): stretch, shear, bending toward ref's dihedral
 * angles, L1 of the Laplacian of x - ref. */
void cr_gdsr_reg_terms(cr_nn_ctx *ctx, gdsr_reg *r, cr_tensor *x, const float *ref,
                       cr_tensor **stretch, cr_tensor **shear, cr_tensor **bend, cr_tensor **lap);

/* The model def as JSON (heap string) and back. */
char *cr_gdsr_model_def_json(const cr_gdsr_model_def *def);
cr_status cr_gdsr_model_def_from_json(const char *json, cr_gdsr_model_def *def, cr_error *err);

#endif
