/* gdsr_internal.h: what the gdsr files share. */
#ifndef CREASE_GDSR_INTERNAL_H
#define CREASE_GDSR_INTERNAL_H

#include "crease/gdsr.h"
#include "crease/nn_graph.h"
#include "crease/nn_layers.h"

#define CR_GDSR_COOKIE 0x67647372u

struct cr_gdsr_model {
    cr_gdsr_model_def def;
    cr_nn_params *params;
    cr_mpnn *net;    /* H */
    cr_mlp *dec;     /* E: 3 decoder_features -> 9 */
    cr_mlp *gen;     /* A's generator: 3 hyper_features -> P */
    int64_t nparams; /* P: the WIRE target's floats per triangle */
};

/* The model def as JSON (heap string) and back. */
char *gdsr_model_def_json(const cr_gdsr_model_def *def);
cr_status gdsr_model_def_from_json(const char *json, cr_gdsr_model_def *def, cr_error *err);

#endif
