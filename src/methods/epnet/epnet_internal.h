/* epnet_internal.h: the model's state, shared by model.c and train.c. */
#ifndef CREASE_EPNET_INTERNAL_H
#define CREASE_EPNET_INTERNAL_H

#include "crease/body.h"
#include "crease/epnet.h"
#include "crease/garment.h"
#include "crease/losses.h"
#include "crease/nn.h"
#include "crease/nn_graph.h"
#include "crease/nn_layers.h"
#include "crease/nn_optim.h"
#include "crease/phys_energies.h"
#include "crease/render.h"
#include "crease/skeleton.h"

enum { EP_STATIC_IN = 66, EP_DYN_IN = 69 };

struct cr_epnet {
    cr_epnet_def def;
    char garment_name[1024], body_name[1024]; /* a type or a garment file; a preset or a model */
    cr_body_model *body;
    cr_garment *garment;
    cr_topology *topo;
    int32_t nv, nh;
    int64_t ne;
    int32_t *send, *recv; /* (E) hinge graph */
    float *theta_bar;     /* (H) rest mesh angles, rad */
    int32_t *pin, npin;   /* pinned vertices (def.pin_top) */
    float *pin_mask;      /* (V) 1 on pinned vertices */
    cr_membrane *membrane;
    cr_bending *bending;
    cr_gravity *gravity;
    cr_loss_collider *collider;
    /* networks */
    cr_nn_ctx *ctx;
    cr_nn_params *pe, *pp; /* E-Net, P-Net parameters */
    cr_mlp *enc_static, *enc_dyn, *enc_rb, *dec;
    cr_rnn_cell gru;
    cr_mpnn *pnet;
    cr_optim *opt_e, *opt_p;
    cr_rng rng;
};

struct cr_epnet_seq {
    int32_t T, vb;
    float *A;                 /* (T,V,3,3) garment skinning rotation-scale per vertex */
    float *b;                 /* (T,V,3) and offset, m */
    float *body;              /* (T,Vb,3) posed body, m */
    float *stat;              /* (T,EP_STATIC_IN) */
    float *dyn;               /* (T,EP_DYN_IN) */
    const cr_mesh *body_rest; /* the body the sequence was posed with (borrowed from m or own) */
    cr_body_model *own_body;  /* set when the sequence uses another body preset */
};

/* E-Net forward on the whole sequence: positions (T,V,3) on the tape. rb (T,H)
 * the RB after each frame, or NULL: frame t is given rb[t-1] (frame 0 zero). */
cr_tensor *cr_epnet_enet_forward_(cr_epnet *m, const cr_epnet_seq *s, const float *rb);
/* E-Net's training loss on s with RB rb (T,H) or NULL, on m->ctx's tape (no
 * reset): the scalar, and each weighted term in parts (CR_EPNET_NTERMS). */
cr_tensor *cr_epnet_enet_loss_(cr_epnet *m, const cr_epnet_seq *s, const float *rb,
                               cr_tensor **parts);
/* The paired terms' unweighted means (each (), on the tape): zero rest
 * mean r(x0)^2 and rest response mean (r(x_rb) - r(x0) - rb)^2, with
 * r(x) = theta(x) - theta_bar (b's rest angles), wrapped. x_rb, x0 (B,V,3);
 * rb (B,H) rad; x_rb NULL: no RB, the response is zero. */
void cr_epnet_paired_terms_(cr_nn_ctx *c, const cr_bending *b, cr_tensor *x_rb, cr_tensor *x0,
                            cr_tensor *rb, cr_tensor **zero, cr_tensor **resp);
/* The training loss's terms of given positions pos (T,V,3) with RB rb (T,H) or NULL. */
cr_status cr_epnet_losses_of_(cr_epnet *m, const cr_epnet_seq *s, const float *pos, const float *rb,
                              cr_epnet_losses *out, cr_error *err);
/* P-Net over the proxy's positions ppos (T,V,3) and angles pth (T,H), each
 * increment through the ratchet d: RB (T,H) out (cr_epnet_infer's step 2). */
cr_status cr_epnet_pnet_proxy_(cr_epnet *m, const float *ppos, const float *pth, int32_t T,
                               const cr_epnet_ratchet_def *d, float *R, cr_error *err);
/* Angles (T,H) of positions (T,V,3). */
void cr_epnet_angles_(const cr_epnet *m, const float *pos, int32_t T, float *theta);
/* One frame's angles (H) of positions (V,3), with caller scratch x (3V) and th (H + 1). */
void cr_epnet_frame_angles_(const cr_epnet *m, const float *pos, double *x, double *th,
                            float *theta);
/* One frame's E-Net inputs from the pose (22,3) and root (3) on a body with rest
 * joints (22,3): static (EP_STATIC_IN) and dynamic (EP_DYN_IN; zero when prev_pose is
 * NULL, frame 0) inputs, the garment's per-vertex skinning A (V,3,3) and b (V,3). */
void cr_epnet_frame_inputs_(const cr_epnet *m, const float *joints, const float *pose,
                            const float *tr, const float *prev_pose, const float *prev_tr,
                            float *stat, float *dyn, float *A, float *b);
/* E-Net's frame t of s from GRU state h_prev ((1,G) or NULL: zero): *h_out
 * the new state, and x[k] (1,V,3) the positions for each of the n RB inputs
 * rb[k] (H, or NULL: zero), the encoders and the GRU run once. On m->ctx; 0
 * with its error set. */
int cr_epnet_enet_frame_(cr_epnet *m, const cr_epnet_seq *s, int32_t t, int n,
                         const float *const *rb, cr_tensor *h_prev, cr_tensor **h_out,
                         cr_tensor **x);
/* The infer def's checks (cookie, warm-up, mode, the proxy's ratchet). */
cr_status cr_epnet_infer_check_(const cr_epnet_infer_def *d, cr_error *err);
/* P-Net's increment of one frame from positions pos (V,3) and angles th (H)
 * through the ratchet d (history hist (H), scratch strain (H)) onto the RB r (H). */
cr_status cr_epnet_pnet_ratchet_frame_(cr_epnet *m, const float *pos, const float *th,
                                       const cr_epnet_ratchet_def *d, uint32_t *hist, float *strain,
                                       float *r, cr_error *err);
/* cr_epnet_infer's proxy and zero-RB modes: the runtime stepped over s's frames. */
cr_status cr_epnet_runtime_infer_(cr_epnet *m, const cr_epnet_seq *s, const cr_epnet_infer_def *d,
                                  float *pos, float *theta, float *rb, cr_error *err);
/* The GRU state hstate (G) after `warmup` frames from the rest pose into frame 0 of s. */
cr_status cr_epnet_warm_up_(cr_epnet *m, const cr_epnet_seq *s, int32_t warmup, float *hstate,
                            cr_error *err);
/* P-Net's RB increment (H) of a frame from positions (V,3), angles (H) and the RB
 * before (H). On m->ctx. */
cr_tensor *cr_epnet_pnet_forward_(cr_epnet *m, const float *pos, const float *theta,
                                  const float *rb_prev);
/* The garment at pos (V,3) over the body (its rest mesh's faces at positions body), size x
 * size pixels seen from yaw_deg; scalar (V, may be NULL) colours the garment over
 * [-0.5, 0.5] rad (run.c; `run`'s pictures and `measure`'s side by side). */
cr_status cr_epnet_render_(const cr_epnet *m, const float *pos, const float *body,
                           const cr_mesh *body_rest, const float *scalar, int size, float yaw_deg,
                           cr_image *img, cr_error *err);

/* data.c: the garment's skinned positions (V,3) of frame t of s: A_t[v] p[v] + b_t[v]. */
void cr_epnet_skinned_frame_(const cr_epnet *m, const cr_epnet_seq *s, int32_t t, float *out);

#endif
