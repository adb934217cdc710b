/* model.c: epnet's scene, networks, losses and rollout (paper 004, sec. 3); its inputs
 * and reference are data.c's.
 *
 * E-Net (after NCS): a static encoder of the pose (joints 1..21 axis-angle
 * and the up direction in the root's frame), a dynamic encoder of the joint
 * and root velocities followed by a GRU over the sequence, an RB encoder,
 * and a decoder to per-vertex offsets in the garment's canonical (rest)
 * space, applied through the garment's own linear blend skinning:
 *     x_t[v] = A_t[v] (p[v] + d_t[v]) + b_t[v]
 * with A_t, b_t the skin-weighted joint transforms of frame t (linear in the
 * offsets, so the tape sees one mul and one sum).
 * P-Net: encode-process-decode on the hinge graph, one frame at a time;
 * node features [rb_prev, d, |d|, |d| - yield, yield] with d the elastic
 * strain theta - theta_bar - rb_prev, edge features the offsets of the two
 * hinges' midpoints, deformed and rest, and [dt, k_b, yield]. The decoder's
 * last layer starts at zero (the authors'), and its output is a strain
 * correction c bounded by PNET_CORR: the increment is Eq. 4-5's rule applied to
 * d + c. It is fitted as the authors' is: L1 on the RB it gives from the
 * target's RB of the frame before plus noise, inactive hinges down-weighted.
 * Losses (Eq. 1-2, 6): Baraff-Witkin stretch and shear, bending with rest
 * theta_bar + RB, gravity, collision, and the implicit-Euler inertia over
 * three consecutive predicted frames, all through losses.h, per frame. */
#include "epnet_internal.h"

#include "crease/diffgeo.h"
#include "crease/motion.h"
#include "crease/nn_checkpoint.h"
#include "crease/phys_sim.h"

#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define EPNET_COOKIE 0x45504e31u
#define PNET_ACTIVE                                                                                \
    1e-4f              /* rad: a hinge whose target RB is past this is active in P-Net's           \
                          loss (the authors' active_threshold) */
#define PNET_CORR 0.2f /* bound of P-Net's strain correction, rad */

const char *const cr_epnet_term_names[CR_EPNET_NTERMS] = {"stretch", "shear",     "bending",
                                                          "gravity", "collision", "inertia",
                                                          "pinning", "zero_rest", "rest_response"};

/* The training clips: the first five of the earlier rounds, plus reach, lean
 * and stretch, which cover the held-out raise_arms' and bend's range of arm
 * and torso poses (one arm at a time, other depths, through the front)
 * without being those motions. */
static const char *const default_motions[] = {"walk", "squat", "twist", "dance",
                                              "jump", "reach", "lean",  "stretch"};

void cr_epnet_material(cr_material *out) {
    cr_error e;
    cr_material_preset("cotton", out, &e);
    snprintf(out->name, sizeof out->name, "epnet");
    out->density = 0.2; /* kg/m^2, the authors' */
    out->membrane = CR_MEMBRANE_BARAFF_WITKIN;
    out->bw_stretch = 2.0 * 10.0;     /* the authors' 10 A (|w| - 1)^2 is k_s/2 with k_s 20 */
    out->bw_shear = 2.0 * 1.0;        /* 1 A (w_u . w_v)^2 */
    out->bending = 0.002;             /* k_e/2 = 0.002 l^2 / (8 (A1 + A2)): the authors' */
    out->collision_thickness = 0.004; /* 4 mm */
    /* the authors' 10 (eps - d)^2 has the force 0.08 N at contact; the cubic
     * k (eps - d)^3 matches it there with k = 0.08 / (3 eps^2) */
    out->collision_stiffness = 0.08 / (3.0 * 0.004 * 0.004);
    out->yield_angle = 0.52;
    out->plastic_gain = 1.0;
}

cr_epnet_def cr_epnet_default_def(void) {
    cr_epnet_def d;
    memset(&d, 0, sizeof d);
    d.garment = "tshirt";
    d.garment_vertices = 600;
    d.body = "normal";
    d.motions = default_motions;
    d.nmotions = (int)(sizeof default_motions / sizeof default_motions[0]);
    d.frames = 60;
    d.fps = 30;
    cr_epnet_material(&d.material);
    d.w_stretch = d.w_shear = d.w_bending = d.w_gravity = d.w_collision = d.w_inertia = 1.0;
    d.w_pin = 100.0;
    d.sharpness = 50;
    d.w_zero_rest = 2.0;     /* the authors' zero_rest_consistency weight */
    d.w_rest_response = 5.0; /* the authors' rest_response weight */
    d.static_widths[0] = 32, d.static_widths[1] = 64, d.nstatic = 2;
    d.dynamic_width = 32;
    d.gru_hidden = 64;
    d.rb_widths[0] = 32, d.nrb = 1;
    d.decoder_width = 128;
    d.decoder_layers = 2;
    d.pnet_latent = 16;
    d.pnet_hidden_layers = 1;
    d.pnet_steps = 3;
    d.cycles = 4;
    d.enet_epochs = 40;
    d.pnet_epochs = 20;
    d.pnet_frames = 4;
    d.enet_lr = 1e-3f;
    d.pnet_lr = 1e-3f;
    d.pnet_rb_noise = 0.05;        /* rad, the authors' */
    d.pnet_inactive_weight = 0.03; /* the authors' */
    d.pnet_val_motion = "run";     /* neither trained on nor evaluated */
    d.pnet_patience = 5;
    d.seed = 1;
    d.cookie = EPNET_COOKIE;
    return d;
}

/* The def's whole-number and rate fields: their ranges (check_def) and the options of
 * `crease epnet train` with their help (CLI_KEYS). The double-valued weights stay the
 * command's own rows: parsed as floats they are what model.json holds, which a resume
 * compares key by key. */
#define EK(...) CR_CONFIG_KEY(cr_epnet_def, __VA_ARGS__)
static const cr_config_key def_keys[] = {
    EK(garment_vertices, CR_CFG_INT, 100, 100000, "--vertices", "N", "garment vertex count"),
    EK(frames, CR_CFG_INT, 3, 10000, "--frames", "N", "frames per clip"),
    EK(cycles, CR_CFG_INT, 1, 100, "--cycles", "N", "curriculum cycles"),
    EK(enet_epochs, CR_CFG_INT, 0, 100000, "--epochs", "N", "E-Net epochs per cycle"),
    EK(pnet_epochs, CR_CFG_INT, 0, 100000, "--pnet-epochs", "N", "P-Net epochs per cycle"),
    EK(baseline, CR_CFG_BOOL, 0, 1, "--baseline", NULL,
       "RB fixed at zero, no P-Net (PBNS/SNUG/NCS)"),
    EK(enet_lr, CR_CFG_FLOAT, 1e-7, 1, "--lr", "R", "E-Net Adam learning rate"),
    EK(seed, CR_CFG_U64, 0, 1e9, "--seed", "S", "initial weights and shuffles"),
    EK(resume, CR_CFG_BOOL, 0, 1, "--resume", NULL, "continue from DIR's checkpoints"),
};
#undef EK

const cr_config_key *cr_epnet_def_keys(int *n) {
    *n = (int)(sizeof def_keys / sizeof def_keys[0]);
    return def_keys;
}

/* ------------------------------------------------------------ create -- */

static cr_status make_mlp(cr_nn_params *P, const char *name, int in, const int *w, int nw, int out,
                          cr_act out_act, cr_rng *rng, cr_mlp **mlp, cr_error *err) {
    cr_mlp_def d = cr_mlp_default_def();
    d.nlayers = nw + (out > 0 ? 1 : 0);
    d.widths[0] = in;
    for (int i = 0; i < nw; i++)
        d.widths[i + 1] = w[i];
    if (out > 0) d.widths[nw + 1] = out;
    d.act = CR_ACT_RELU;
    d.out_act = out_act;
    return cr_mlp_create(&d, P, name, rng, mlp, err);
}

static cr_status check_def(const cr_epnet_def *d, cr_error *err) {
    if (d->cookie != EPNET_COOKIE)
        return CR_FAIL(err, CR_ERR_INVALID, "epnet: def not made by cr_epnet_default_def");
    if (d->nstatic < 1 || d->nstatic > CR_EPNET_MAX_LAYERS || d->nrb < 1 ||
        d->nrb > CR_EPNET_MAX_LAYERS)
        return CR_FAIL(err, CR_ERR_INVALID, "epnet: static/rb encoder layers must be 1..%d",
                       CR_EPNET_MAX_LAYERS);
    if (d->decoder_layers < 1 || d->decoder_layers > CR_EPNET_MAX_LAYERS)
        return CR_FAIL(err, CR_ERR_INVALID, "epnet: decoder_layers %d not in 1..%d",
                       d->decoder_layers, CR_EPNET_MAX_LAYERS);
    CR_TRY(cr_config_check(def_keys, (int)(sizeof def_keys / sizeof def_keys[0]), d, "epnet", err));
    if (d->nmotions < 1 || d->nmotions > CR_EPNET_MAX_MOTIONS)
        return CR_FAIL(err, CR_ERR_INVALID, "epnet: %d motions, expected 1..%d", d->nmotions,
                       CR_EPNET_MAX_MOTIONS);
    if (!(d->pin_top >= 0) || !(d->w_pin >= 0))
        return CR_FAIL(err, CR_ERR_INVALID, "epnet: pin_top %g and w_pin %g must be >= 0",
                       d->pin_top, d->w_pin);
    if (!(d->w_zero_rest >= 0) || !(d->w_rest_response >= 0))
        return CR_FAIL(err, CR_ERR_INVALID, "epnet: paired weights %g and %g must be >= 0",
                       d->w_zero_rest, d->w_rest_response);
    if (!(d->pnet_rb_noise >= 0) || !(d->pnet_inactive_weight >= 0) || d->pnet_patience < 1)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "epnet: P-Net noise %g and inactive weight %g must be >= 0, patience %d "
                       ">= 1",
                       d->pnet_rb_noise, d->pnet_inactive_weight, d->pnet_patience);
    if (!(d->material.yield_angle >= 0))
        return CR_FAIL(err, CR_ERR_INVALID, "epnet: yield angle %g < 0", d->material.yield_angle);
    return CR_OK;
}

/* The vertices within pin_top of the rest garment's highest point. */
static cr_status make_pins(cr_epnet *m, cr_error *err) {
    const cr_mesh *g = m->garment->mesh;
    m->pin_mask = cr_calloc((size_t)m->nv, sizeof(float), err);
    m->pin = cr_calloc((size_t)m->nv, sizeof(int32_t), err);
    if (!m->pin_mask || !m->pin) return CR_ERR_MEMORY;
    if (m->def.pin_top <= 0) return CR_OK;
    float top = -INFINITY;
    for (int32_t v = 0; v < m->nv; v++)
        top = fmaxf(top, g->pos[3 * v + 1]);
    for (int32_t v = 0; v < m->nv; v++)
        if (g->pos[3 * v + 1] >= top - (float)m->def.pin_top)
            m->pin_mask[v] = 1.0f, m->pin[m->npin++] = v;
    return CR_OK;
}

/* The tape's arena: P-Net's step holds a few dozen (E, latent) tensors per
 * message-passing step (the edge MLPs' inputs, activations and gradients),
 * so it grows with the hinge graph's E edges; a fixed 512 MiB ran out at the
 * authors' latent 128 on the 535-vertex t-shirt (40,106 edges). */
static size_t epnet_arena_bytes(const cr_epnet_def *def, int64_t nedges) {
    const double per_step =
        4.0 * (double)nedges * def->pnet_latent * (8.0 + 4.0 * def->pnet_hidden_layers);
    const double need = per_step * (def->pnet_steps + 3); /* measured: 1,525 MiB of 1,880 */
    const double floor_bytes = (double)((size_t)512 << 20);
    return (size_t)(need > floor_bytes ? need : floor_bytes);
}

/* A garment of def->garment's type at def->garment_vertices, or the garment
 * mesh file it names (fitted to the body; UVs not needed: nothing of epnet's
 * reads them). */
static cr_status make_garment(const cr_epnet_def *def, const cr_body_model *body, cr_garment **out,
                              cr_error *err) {
    char ext[16];
    cr_path_ext(def->garment, ext, sizeof ext);
    if (!strcmp(ext, "obj") || !strcmp(ext, "ply") || !strcmp(ext, "glb")) {
        cr_garment_user_def ud = cr_garment_user_default_def();
        return cr_garment_load_user(def->garment, &ud, body, out, err);
    }
    cr_garment_type gt;
    CR_TRY(cr_garment_type_parse(def->garment, &gt, err));
    cr_garment_def gd = cr_garment_default_def(gt);
    gd.target_vertices = def->garment_vertices;
    return cr_garment_create(&gd, body, out, err);
}

cr_status cr_epnet_create(const cr_epnet_def *def, cr_epnet **out, cr_error *err) {
    *out = NULL;
    CR_TRY(check_def(def, err));
    cr_epnet *m = cr_calloc(1, sizeof *m, err);
    if (!m) return CR_ERR_MEMORY;
    m->def = *def;
    snprintf(m->garment_name, sizeof m->garment_name, "%s", def->garment);
    snprintf(m->body_name, sizeof m->body_name, "%s", def->body);
    m->def.garment = m->garment_name, m->def.body = m->body_name;
    m->def.out_dir = NULL;
    m->def.motions = NULL, m->def.nmotions = 0; /* the training set is train.c's */
    m->def.pnet_val_motion = NULL;
    cr_status st = cr_body_resolve(def->body, &m->body, err);
    if (st == CR_OK) st = make_garment(def, m->body, &m->garment, err);
    if (st == CR_OK) st = cr_topology_build(m->garment->mesh, &m->topo, err);
    if (st == CR_OK) {
        m->nv = m->garment->mesh->nv, m->nh = m->topo->nh;
        st = cr_epnet_hinge_graph(m->topo, &m->send, &m->recv, &m->ne, err);
    }
    const cr_material *mat = &def->material;
    if (st == CR_OK) st = cr_membrane_create(m->garment->mesh, 0, 1.0f, mat, &m->membrane, err);
    if (st == CR_OK) st = cr_bending_create(m->garment->mesh, m->topo, mat, 1, &m->bending, err);
    if (st == CR_OK)
        st = cr_gravity_create(m->garment->mesh, mat, (double[]){0, -9.81, 0}, &m->gravity, err);
    if (st == CR_OK) {
        const cr_mesh *bm = m->body->rest;
        st = cr_loss_collider_create(bm->pos, bm->nv, bm->tri, bm->nf, &m->collider, err);
        /* the thickness held over the faces, as the simulator holds it */
        if (st == CR_OK)
            st = cr_loss_collider_set_edges(m->collider, m->topo->edge, m->topo->ne, m->nv, err);
    }
    if (st == CR_OK) {
        m->theta_bar = cr_malloc(sizeof(float) * (size_t)(m->nh > 0 ? m->nh : 1), err);
        if (!m->theta_bar)
            st = CR_ERR_MEMORY;
        else {
            const double *r = cr_bending_rest_angles(m->bending);
            for (int32_t h = 0; h < m->nh; h++)
                m->theta_bar[h] = (float)r[h];
        }
    }
    if (st == CR_OK) st = make_pins(m, err);
    cr_nn_ctx_def cd = cr_nn_ctx_default_def();
    cd.arena_bytes = epnet_arena_bytes(def, m->ne);
    if (st == CR_OK) st = cr_nn_ctx_create(&cd, &m->ctx, err);
    if (st == CR_OK) st = cr_nn_params_create(&m->pe, err);
    if (st == CR_OK) st = cr_nn_params_create(&m->pp, err);
    m->rng = cr_rng_make(def->seed, 0);
    if (st == CR_OK) {
        const int lat =
            def->static_widths[def->nstatic - 1] + def->gru_hidden + def->rb_widths[def->nrb - 1];
        int dw[CR_EPNET_MAX_LAYERS], dyw[2] = {def->dynamic_width, def->dynamic_width};
        for (int i = 0; i < def->decoder_layers; i++)
            dw[i] = def->decoder_width;
        st = make_mlp(m->pe, "enet.static", EP_STATIC_IN, def->static_widths, def->nstatic, 0,
                      CR_ACT_RELU, &m->rng, &m->enc_static, err);
        if (st == CR_OK)
            st = make_mlp(m->pe, "enet.dynamic", EP_DYN_IN, dyw, 2, 0, CR_ACT_RELU, &m->rng,
                          &m->enc_dyn, err);
        if (st == CR_OK)
            st = make_mlp(m->pe, "enet.rb", m->nh, def->rb_widths, def->nrb, 0, CR_ACT_RELU,
                          &m->rng, &m->enc_rb, err);
        if (st == CR_OK)
            st = make_mlp(m->pe, "enet.decoder", lat, dw, def->decoder_layers, 3 * m->nv,
                          CR_ACT_NONE, &m->rng, &m->dec, err);
        cr_rnn_def rd = cr_rnn_default_def();
        rd.input = def->dynamic_width, rd.hidden = def->gru_hidden;
        if (st == CR_OK) st = cr_gru_cell_create(&rd, m->pe, "enet.gru", &m->rng, &m->gru, err);
    }
    if (st == CR_OK) {
        /* start near the skinned template: the offsets' layer is scaled down */
        cr_tensor *w = m->dec->layer[m->dec->def.nlayers - 1].weight;
        for (int64_t i = 0; i < w->numel; i++)
            w->data[i] *= 0.02f;
        cr_mpnn_def pd = cr_mpnn_default_def();
        pd.node_in = 5, pd.edge_in[0] = 9, pd.node_out = 1;
        pd.latent = def->pnet_latent, pd.steps = def->pnet_steps;
        pd.hidden_layers = def->pnet_hidden_layers;
        st = cr_mpnn_create(&pd, m->pp, "pnet", &m->rng, &m->pnet, err);
    }
    if (st == CR_OK) {
        char name[64];
        for (int i = 15; i >= 0; i--) {
            snprintf(name, sizeof name, "pnet.decoder.%d.weight", i);
            cr_tensor *w = cr_nn_params_find(m->pp, name);
            if (w) {
                cr_init_zero(w);
                snprintf(name, sizeof name, "pnet.decoder.%d.bias", i);
                if ((w = cr_nn_params_find(m->pp, name))) cr_init_zero(w);
                break;
            }
        }
        cr_optim_def od = cr_optim_default_def(CR_OPTIM_ADAM);
        od.lr.base = def->enet_lr;
        st = cr_optim_create(&od, m->pe, &m->opt_e, err);
        od.lr.base = def->pnet_lr;
        if (st == CR_OK) st = cr_optim_create(&od, m->pp, &m->opt_p, err);
    }
    if (st != CR_OK) {
        cr_epnet_destroy(m);
        return st;
    }
    *out = m;
    return CR_OK;
}

void cr_epnet_destroy(cr_epnet *m) {
    if (!m) return;
    cr_optim_destroy(m->opt_e), cr_optim_destroy(m->opt_p);
    cr_mlp_destroy(m->enc_static), cr_mlp_destroy(m->enc_dyn), cr_mlp_destroy(m->enc_rb);
    cr_mlp_destroy(m->dec);
    cr_mpnn_destroy(m->pnet);
    cr_nn_params_destroy(m->pe), cr_nn_params_destroy(m->pp);
    cr_nn_ctx_destroy(m->ctx);
    cr_loss_collider_destroy(m->collider);
    cr_gravity_destroy(m->gravity), cr_bending_destroy(m->bending);
    cr_membrane_destroy(m->membrane);
    free(m->theta_bar), free(m->send), free(m->recv), free(m->pin), free(m->pin_mask);
    cr_topology_destroy(m->topo);
    cr_garment_destroy(m->garment);
    cr_body_model_destroy(m->body);
    free(m);
}

const cr_mesh *cr_epnet_garment(const cr_epnet *m) {
    return m->garment->mesh;
}
const cr_epnet_def *cr_epnet_get_def(const cr_epnet *m) {
    return &m->def;
}
const cr_mesh *cr_epnet_body(const cr_epnet *m) {
    return m->body->rest;
}
int32_t cr_epnet_hinge_count(const cr_epnet *m) {
    return m->nh;
}
const float *cr_epnet_rest_angles(const cr_epnet *m) {
    return m->theta_bar;
}
int64_t cr_epnet_param_count(const cr_epnet *m, int pnet) {
    return cr_nn_params_numel(pnet ? m->pp : m->pe);
}

/* E-Net's decoder and the garment's skinning for frames t0..t0+T-1: the
 * static code hs (T,.) and the GRU's hg (T,.) with the RB code of rb (T,H)
 * (NULL: zero) to offsets in canonical space, then
 * x = A (p + d) + b, positions (T,V,3). One copy for the whole-sequence
 * forward and the rollout's frame. */
static cr_tensor *enet_decode(cr_epnet *m, const cr_epnet_seq *s, int64_t t0, int64_t T,
                              cr_tensor *hs, cr_tensor *hg, const float *rb) {
    cr_nn_ctx *c = m->ctx;
    const int64_t V = m->nv, H = m->nh;
    cr_tensor *r =
        rb ? cr_nn_from(c, 2, (int64_t[]){T, H}, rb) : cr_nn_zeros(c, 2, (int64_t[]){T, H});
    cr_tensor *hr = cr_mlp_forward(c, m->enc_rb, r);
    cr_tensor *z = cr_nn_concat(c, 3, (cr_tensor *[]){hs, hg, hr}, 1);
    cr_tensor *d = cr_nn_reshape(c, cr_mlp_forward(c, m->dec, z), 4, (int64_t[]){T, V, 1, 3});
    cr_tensor *p = cr_nn_from(c, 4, (int64_t[]){1, V, 1, 3}, m->garment->mesh->pos);
    cr_tensor *A = cr_nn_wrap(c, 4, (int64_t[]){T, V, 3, 3}, s->A + (size_t)t0 * V * 9);
    cr_tensor *x = cr_nn_sum_axis(c, cr_nn_mul(c, A, cr_nn_add(c, d, p)), 3, 0); /* (T,V,3) */
    return cr_nn_add(c, x, cr_nn_wrap(c, 3, (int64_t[]){T, V, 3}, s->b + (size_t)t0 * V * 3));
}

/* E-Net's RB input per frame, (T,H) in step memory: frame t is given rb[t-1]
 * (the RB after the frame before) and frame 0 zero, the lag inference has.
 * NULL when rb is NULL or that input is zero throughout (the first cycle), so
 * the paired terms skip their second pass. */
static const float *rb_input(cr_epnet *m, int64_t T, const float *rb) {
    const int64_t H = m->nh;
    if (!rb) return NULL;
    int any = 0;
    for (int64_t i = 0; i < (T - 1) * H && !any; i++)
        any = rb[i] != 0.0f;
    if (!any) return NULL;
    float *in = cr_nn_scratch(m->ctx, "epnet RB input", sizeof(float) * (size_t)(T * H));
    if (!in) return NULL;
    memset(in, 0, sizeof(float) * (size_t)H);
    memcpy(in + H, rb, sizeof(float) * (size_t)((T - 1) * H));
    return in;
}

/* E-Net on the whole sequence with the RB input rb_in (T,H) (NULL: zero), as
 * given (no lag added); the pose codes hs (T,.) and hg (T,.) out, which do
 * not depend on RB. */
static cr_tensor *enet_full(cr_epnet *m, const cr_epnet_seq *s, const float *rb_in, cr_tensor **hs,
                            cr_tensor **hg) {
    cr_nn_ctx *c = m->ctx;
    const int64_t T = s->T;
    cr_tensor *st = cr_nn_from(c, 2, (int64_t[]){T, EP_STATIC_IN}, s->stat);
    cr_tensor *dy = cr_nn_from(c, 2, (int64_t[]){T, EP_DYN_IN}, s->dyn);
    *hs = cr_mlp_forward(c, m->enc_static, st);
    cr_tensor *hd = cr_mlp_forward(c, m->enc_dyn, dy);
    hd = cr_nn_reshape(c, hd, 3, (int64_t[]){T, 1, m->def.dynamic_width});
    cr_tensor *g = cr_gru_forward(c, &m->gru, hd, NULL, NULL);
    *hg = cr_nn_reshape(c, g, 2, (int64_t[]){T, m->def.gru_hidden});
    return enet_decode(m, s, 0, T, *hs, *hg, rb_in);
}

cr_tensor *cr_epnet_enet_forward_(cr_epnet *m, const cr_epnet_seq *s, const float *rb) {
    cr_tensor *hs = NULL, *hg = NULL;
    return enet_full(m, s, rb_input(m, s->T, rb), &hs, &hg);
}

void cr_epnet_paired_terms_(cr_nn_ctx *c, const cr_bending *b, cr_tensor *x_rb, cr_tensor *x0,
                            cr_tensor *rb, cr_tensor **zero, cr_tensor **resp) {
    cr_tensor *r0 = cr_loss_hinge_residual(c, b, 1.0, x0, NULL); /* (B,H) theta - theta_bar */
    *zero = cr_nn_mean(c, cr_nn_square(c, r0));
    if (!x_rb) {
        *resp = cr_nn_zeros(c, 1, (int64_t[]){1});
        return;
    }
    cr_tensor *rr = cr_loss_hinge_residual(c, b, 1.0, x_rb, NULL);
    cr_tensor *e = cr_nn_sub(c, cr_nn_sub(c, rr, r0), rb);
    *resp = cr_nn_mean(c, cr_nn_square(c, e));
}

void cr_epnet_frame_angles_(const cr_epnet *m, const float *pos, double *x, double *th,
                            float *theta) {
    for (int64_t i = 0; i < 3 * (int64_t)m->nv; i++)
        x[i] = pos[i];
    cr_bending_angles(m->bending, x, th);
    for (int32_t h = 0; h < m->nh; h++)
        theta[h] = (float)th[h];
}

void cr_epnet_angles_(const cr_epnet *m, const float *pos, int32_t T, float *theta) {
    const int32_t V = m->nv, H = m->nh;
    double *x = malloc(sizeof(double) * 3 * (size_t)V),
           *th = malloc(sizeof(double) * (size_t)(H + 1));
    if (!x || !th) {
        free(x), free(th);
        memset(theta, 0, sizeof(float) * (size_t)T * H);
        return;
    }
    for (int32_t t = 0; t < T; t++)
        cr_epnet_frame_angles_(m, pos + (size_t)t * V * 3, x, th, theta + (size_t)t * H);
    free(x), free(th);
}

void cr_epnet_angles(const cr_epnet *m, const float *pos, int32_t T, float *theta) {
    cr_epnet_angles_(m, pos, T, theta);
}

/* Frames start..start+n-1 of x; detached: the implicit-Euler form, where
 * frame t minimises its incremental potential with the two frames before it
 * held fixed, instead of the whole path's acceleration being penalised. */
static cr_tensor *past(cr_nn_ctx *c, cr_tensor *x, int64_t start, int64_t n, int detach) {
    cr_tensor *p = cr_nn_slice(c, x, 0, start, n);
    return detach ? cr_nn_detach(c, p) : p;
}

/* Pinning: sum over the pinned vertices of |x - skinned|^2 per frame (m^2),
 * summed over the frames (the caller's weight divides by T). */
static cr_tensor *pin_term(cr_epnet *m, const cr_epnet_seq *s, cr_tensor *x) {
    cr_nn_ctx *c = m->ctx;
    const int64_t T = s->T, V = m->nv;
    if (m->npin == 0) return cr_nn_zeros(c, 1, (int64_t[]){1});
    cr_tensor *target = cr_nn_new(c, 3, (int64_t[]){T, V, 3});
    if (!target) return NULL;
    for (int32_t t = 0; t < T; t++)
        cr_epnet_skinned_frame_(m, s, t, target->data + (size_t)t * V * 3);
    cr_tensor *mask = cr_nn_wrap(c, 3, (int64_t[]){1, V, 1}, m->pin_mask);
    return cr_nn_sum(c, cr_nn_mul(c, cr_nn_square(c, cr_nn_sub(c, x, target)), mask));
}

/* The loss of positions x (T,V,3) given the RB input rb_in (T,H) (NULL: zero;
 * the bending rest of frame t is theta_bar + rb_in[t]) and the paired terms
 * (unweighted means, each NULL: zero). */
static cr_tensor *enet_loss(cr_epnet *m, const cr_epnet_seq *s, cr_tensor *x, const float *rb_in,
                            cr_tensor *zero_rest, cr_tensor *rest_response, cr_tensor **parts) {
    cr_nn_ctx *c = m->ctx;
    const int64_t T = s->T, H = m->nh, V = m->nv;
    const cr_epnet_def *d = &m->def;
    cr_tensor *rest = cr_nn_new(c, 2, (int64_t[]){T, H});
    if (rest)
        for (int64_t t = 0; t < T; t++)
            for (int64_t h = 0; h < H; h++)
                rest->data[t * H + h] = m->theta_bar[h] + (rb_in ? rb_in[t * H + h] : 0.0f);
    cr_energy_term ts, tsh, tg;
    cr_membrane_term_part(m->membrane, CR_MEMBRANE_STRETCH, &ts);
    cr_membrane_term_part(m->membrane, CR_MEMBRANE_SHEAR, &tsh);
    cr_gravity_term(m->gravity, &tg);
    cr_tensor *body = cr_nn_wrap(c, 3, (int64_t[]){T, s->vb, 3}, s->body);
    cr_tensor *terms[CR_EPNET_NTERMS] = {
        cr_loss_energy(c, &ts, x),
        cr_loss_energy(c, &tsh, x),
        cr_loss_bending(c, m->bending, 1.0, x, rest),
        cr_loss_energy(c, &tg, x),
        cr_loss_collision(c, m->collider, &d->material, 1.0, x, body),
        cr_loss_inertia(c, cr_gravity_masses(m->gravity), (int32_t)V, 1.0 / d->fps, 1.0,
                        cr_nn_slice(c, x, 0, 2, T - 2),
                        past(c, x, 1, T - 2, d->experimental.inertia_detach),
                        past(c, x, 0, T - 2, d->experimental.inertia_detach)),
        pin_term(m, s, x),
        zero_rest ? zero_rest : cr_nn_zeros(c, 1, (int64_t[]){1}),
        rest_response ? rest_response : cr_nn_zeros(c, 1, (int64_t[]){1}),
    };
    const float w[CR_EPNET_NTERMS] = {
        (float)(d->w_stretch / T), (float)(d->w_shear / T),     (float)(d->w_bending / T),
        (float)(d->w_gravity / T), (float)(d->w_collision / T), (float)(d->w_inertia / T),
        (float)(d->w_pin / T),     (float)d->w_zero_rest,       (float)d->w_rest_response};
    return cr_loss_weighted_sum(c, terms, w, CR_EPNET_NTERMS, parts);
}

static void read_parts(cr_tensor *loss, cr_tensor **parts, cr_epnet_losses *out) {
    if (!out) return;
    out->total = loss ? loss->data[0] : NAN;
    for (int k = 0; k < CR_EPNET_NTERMS; k++)
        out->term[k] = parts[k] ? parts[k]->data[0] : NAN;
}

cr_status cr_epnet_losses_of_(cr_epnet *m, const cr_epnet_seq *s, const float *pos, const float *rb,
                              cr_epnet_losses *out, cr_error *err) {
    cr_nn_ctx_reset(m->ctx);
    cr_nn_ctx_set_grad_enabled(m->ctx, 0);
    cr_tensor *x = cr_nn_from(m->ctx, 3, (int64_t[]){s->T, m->nv, 3}, pos);
    cr_tensor *parts[CR_EPNET_NTERMS] = {0};
    cr_tensor *loss = x ? enet_loss(m, s, x, rb_input(m, s->T, rb), NULL, NULL, parts) : NULL;
    CR_TRY(cr_nn_ctx_error(m->ctx, err));
    read_parts(loss, parts, out);
    return CR_OK;
}

cr_tensor *cr_epnet_enet_loss_(cr_epnet *m, const cr_epnet_seq *s, const float *rb,
                               cr_tensor **parts) {
    cr_nn_ctx *c = m->ctx;
    const cr_epnet_def *d = &m->def;
    const int64_t T = s->T, H = m->nh;
    const float *rin = rb_input(m, T, rb);
    cr_tensor *hs = NULL, *hg = NULL, *zero = NULL, *resp = NULL;
    cr_tensor *x = enet_full(m, s, rin, &hs, &hg);
    if (!x) return NULL;
    if (!d->baseline && (d->w_zero_rest > 0 || d->w_rest_response > 0)) {
        /* the paired terms on the last frame; the pose codes do not depend on
         * RB, so the pass at RB = 0 is the decoder's alone */
        cr_tensor *xl = cr_nn_slice(c, x, 0, T - 1, 1);
        cr_tensor *x0 = xl, *r = NULL;
        if (rin) {
            x0 = enet_decode(m, s, T - 1, 1, cr_nn_slice(c, hs, 0, T - 1, 1),
                             cr_nn_slice(c, hg, 0, T - 1, 1), NULL);
            r = cr_nn_from(c, 2, (int64_t[]){1, H}, rin + (T - 1) * H);
        }
        cr_epnet_paired_terms_(c, m->bending, rin ? xl : NULL, x0, r, &zero, &resp);
    }
    return enet_loss(m, s, x, rin, zero, resp, parts);
}

cr_status cr_epnet_enet_step(cr_epnet *m, const cr_epnet_seq *s, const float *rb, int train,
                             cr_epnet_losses *out, cr_error *err) {
    cr_nn_ctx_reset(m->ctx);
    cr_nn_ctx_set_grad_enabled(m->ctx, train);
    cr_tensor *parts[CR_EPNET_NTERMS] = {0};
    cr_tensor *loss = cr_epnet_enet_loss_(m, s, rb, parts);
    CR_TRY(cr_nn_ctx_error(m->ctx, err));
    read_parts(loss, parts, out);
    if (!train) return CR_OK;
    cr_nn_params_zero_grad(m->pe);
    CR_TRY(cr_nn_backward(m->ctx, loss, err));
    CR_TRY(cr_clip_grad_norm(m->pe, 10.0f, NULL, err));
    return cr_optim_step(m->opt_e, err);
}

/* ------------------------------------------------------------- P-Net -- */

/* Node (H,5) and edge (E,9) features of frame t from positions pos (V,3),
 * angles theta (H) and the previous RB rb_prev (H); mid: scratch of 6H
 * floats (the hinges' edge midpoints, posed and at rest). */
static void pnet_features(const cr_epnet *m, const float *pos, const float *theta,
                          const float *rb_prev, float *mid, float *node, float *edge) {
    const int32_t H = m->nh;
    const double y = m->def.material.yield_angle;
    const float *rest = m->garment->mesh->pos;
    const int32_t *hg = m->topo->hinge;
    for (int32_t h = 0; h < H; h++) {
        const double d = theta[h] - m->theta_bar[h] - rb_prev[h];
        float *n = node + 5 * (size_t)h;
        n[0] = rb_prev[h], n[1] = (float)d, n[2] = (float)fabs(d), n[3] = (float)(fabs(d) - y);
        n[4] = (float)y;
        for (int k = 0; k < 3; k++) {
            mid[6 * h + k] = 0.5f * (pos[3 * hg[4 * h] + k] + pos[3 * hg[4 * h + 1] + k]);
            mid[6 * h + 3 + k] = 0.5f * (rest[3 * hg[4 * h] + k] + rest[3 * hg[4 * h + 1] + k]);
        }
    }
    const float dt = 1.0f / m->def.fps, stiff = (float)(m->def.material.bending * 100.0);
    for (int64_t e = 0; e < m->ne; e++) {
        const float *ma = mid + 6 * (size_t)m->send[e], *mb = mid + 6 * (size_t)m->recv[e];
        float *f = edge + 9 * (size_t)e;
        for (int k = 0; k < 6; k++) /* dm, posed then at rest */
            f[k] = 10.0f * (ma[k] - mb[k]);
        f[6] = dt, f[7] = stiff, f[8] = (float)y;
    }
}

/* P-Net's increment (H) of one frame, on the tape, in Eq. 4-5's own form:
 * the network predicts a bounded correction c (|c| < PNET_CORR rad) to the
 * elastic strain d = theta - theta_bar - rb_prev, and the increment is the
 * rule applied to d + c. So RB only moves when the corrected strain passes
 * the yield, and never past theta - theta_bar -/+ (yield + PNET_CORR): long
 * rollouts cannot drift (an unconstrained increment accumulated 1.55 rad
 * over 1,000 walking frames). With c = 0 (the zeroed decoder at start) it
 * is the plastic rule on E-Net's angles. */
cr_tensor *cr_epnet_pnet_forward_(cr_epnet *m, const float *pos, const float *theta,
                                  const float *rb_prev) {
    cr_nn_ctx *c = m->ctx;
    const int64_t H = m->nh;
    float *node = cr_nn_scratch(c, "epnet node features", sizeof(float) * 5 * (size_t)H);
    float *edge = cr_nn_scratch(c, "epnet edge features", sizeof(float) * 9 * (size_t)(m->ne + 1));
    float *dd = cr_nn_scratch(c, "epnet strain", sizeof(float) * (size_t)H);
    float *mid = cr_nn_scratch(c, "epnet midpoints", sizeof(float) * 6 * (size_t)H);
    if (!node || !edge || !dd || !mid) return NULL;
    pnet_features(m, pos, theta, rb_prev, mid, node, edge);
    for (int64_t h = 0; h < H; h++)
        dd[h] = node[5 * h + 1];
    cr_nn_graph g = {.nodes = H, .edges = m->ne, .senders = m->send, .receivers = m->recv};
    cr_tensor *xn = cr_nn_wrap(c, 2, (int64_t[]){H, 5}, node);
    cr_tensor *xe = cr_nn_wrap(c, 2, (int64_t[]){m->ne, 9}, edge);
    cr_tensor *y = cr_mpnn_forward(c, m->pnet, xn, &g, (cr_tensor *[]){xe}, NULL);
    cr_tensor *corr =
        cr_nn_mul_scalar(c, cr_nn_tanh(c, cr_nn_reshape(c, y, 1, (int64_t[]){H})), PNET_CORR);
    cr_tensor *d = cr_nn_add(c, cr_nn_wrap(c, 1, (int64_t[]){H}, dd), corr);
    const float yl = (float)m->def.material.yield_angle;
    /* sign(d) max(|d| - y, 0) = relu(d - y) - relu(-d - y) */
    cr_tensor *over =
        cr_nn_sub(c, cr_nn_relu(c, cr_nn_add_scalar(c, d, -yl)),
                  cr_nn_relu(c, cr_nn_add_scalar(c, cr_nn_mul_scalar(c, d, -1.0f), -yl)));
    if (m->def.sharpness > 0) {
        cr_tensor *gate =
            cr_nn_sigmoid(c, cr_nn_mul_scalar(c, cr_nn_add_scalar(c, cr_nn_abs(c, d), -yl),
                                              (float)m->def.sharpness));
        over = cr_nn_mul(c, over, gate);
    }
    return cr_nn_mul_scalar(c, over, (float)m->def.material.plastic_gain);
}

cr_status cr_epnet_pnet_fit(cr_epnet *m, const cr_epnet_seq *s, const float *pos,
                            const float *theta, const float *rb_target, int steps, double *loss,
                            cr_error *err) {
    const int32_t H = m->nh, V = m->nv, T = s->T;
    const cr_epnet_def *d = &m->def;
    float *prev = malloc(sizeof(float) * (size_t)H), *inc = malloc(sizeof(float) * (size_t)H);
    float *w = malloc(sizeof(float) * (size_t)H);
    if (!prev || !inc || !w) {
        free(prev), free(inc), free(w);
        return CR_FAIL(err, CR_ERR_MEMORY, "epnet: out of memory for P-Net targets");
    }
    cr_status st = CR_OK;
    double last = NAN;
    /* one frame on the tape at a time (a frame's graph of E edges holds a
     * few (E, 3L) tensors per step), the gradients summed over the frames */
    const float wf = 1.0f / (float)(d->pnet_frames * (int64_t)H);
    for (int it = 0; st == CR_OK && it < steps; it++) {
        double sum = 0;
        cr_nn_params_zero_grad(m->pp);
        for (int k = 0; st == CR_OK && k < d->pnet_frames; k++) {
            cr_nn_ctx_reset(m->ctx);
            cr_nn_ctx_set_grad_enabled(m->ctx, 1);
            const int32_t t = (int32_t)cr_rng_below(&m->rng, (uint32_t)T);
            /* teacher forcing: the target's RB of the frame before, with noise */
            for (int32_t h = 0; h < H; h++) {
                const float tg = rb_target[(size_t)t * H + h];
                float p = t > 0 ? rb_target[(size_t)(t - 1) * H + h] : 0.0f;
                if (d->pnet_rb_noise > 0) p += (float)(d->pnet_rb_noise * cr_rng_normal(&m->rng));
                prev[h] = p, inc[h] = tg - p;
                w[h] = fabsf(tg) > PNET_ACTIVE ? 1.0f : (float)d->pnet_inactive_weight;
            }
            cr_tensor *y =
                cr_epnet_pnet_forward_(m, pos + (size_t)t * V * 3, theta + (size_t)t * H, prev);
            cr_tensor *e =
                cr_nn_mul(m->ctx, cr_nn_sub(m->ctx, y, cr_nn_from(m->ctx, 1, (int64_t[]){H}, inc)),
                          cr_nn_from(m->ctx, 1, (int64_t[]){H}, w));
            cr_tensor *l = cr_nn_mul_scalar(m->ctx, cr_nn_sum(m->ctx, cr_nn_abs(m->ctx, e)), wf);
            st = cr_nn_ctx_error(m->ctx, err);
            if (st != CR_OK) break;
            sum += l->data[0];
            st = cr_nn_backward(m->ctx, l, err);
        }
        if (st != CR_OK) break;
        last = sum;
        st = cr_clip_grad_norm(m->pp, 10.0f, NULL, err);
        if (st == CR_OK) st = cr_optim_step(m->opt_p, err);
    }
    free(prev), free(inc), free(w);
    if (loss) *loss = last;
    return st;
}

/* ------------------------------------------------------------ rollout -- */

/* E-Net's frame t alone needs the GRU's history, so the rollout runs E-Net
 * over frames 0..t with RB up to t - 1: O(T^2) on the GRU's cheap part;
 * the decoder runs once per frame on the last row only. To keep it O(T),
 * the GRU state is carried frame to frame here. */
int cr_epnet_enet_frame_(cr_epnet *m, const cr_epnet_seq *s, int32_t t, int n,
                         const float *const *rb, cr_tensor *h_prev, cr_tensor **h_out,
                         cr_tensor **x) {
    cr_nn_ctx *c = m->ctx;
    cr_tensor *st =
        cr_nn_from(c, 2, (int64_t[]){1, EP_STATIC_IN}, s->stat + (size_t)t * EP_STATIC_IN);
    cr_tensor *dy = cr_nn_from(c, 2, (int64_t[]){1, EP_DYN_IN}, s->dyn + (size_t)t * EP_DYN_IN);
    cr_tensor *hs = cr_mlp_forward(c, m->enc_static, st);
    cr_tensor *hd = cr_mlp_forward(c, m->enc_dyn, dy);
    cr_tensor *hg = cr_gru_cell_forward(c, &m->gru, hd, h_prev);
    *h_out = hg;
    int ok = hg != NULL;
    for (int k = 0; k < n; k++)
        ok &= (x[k] = enet_decode(m, s, t, 1, hs, hg, rb[k])) != NULL;
    return ok && cr_nn_ctx_error(c, NULL) == CR_OK;
}

/* The GRU state (G) after `warmup` frames that blend the joints from the rest
 * pose to frame 0's with the root held: each frame's joint velocities are
 * frame 0's joint angles / warmup, in the dynamic input's units (seq_create:
 * x 0.1 fps), the root's zero. The decoder does not run: the warm-up only
 * starts the recurrent state (the authors' 20-frame warm-up from the rest pose). */
cr_status cr_epnet_warm_up_(cr_epnet *m, const cr_epnet_seq *s, int32_t warmup, float *hstate,
                            cr_error *err) {
    const int32_t G = m->def.gru_hidden;
    float dyn[EP_DYN_IN] = {0};
    for (int i = 0; i < 63; i++) /* joints 1..21: the static input's first 63 */
        dyn[3 + i] = s->stat[i] / (float)warmup * 0.1f * m->def.fps;
    for (int32_t k = 0; k < warmup; k++) {
        cr_nn_ctx_reset(m->ctx);
        cr_nn_ctx_set_grad_enabled(m->ctx, 0);
        cr_tensor *h0 = k > 0 ? cr_nn_from(m->ctx, 2, (int64_t[]){1, G}, hstate) : NULL;
        cr_tensor *dy = cr_nn_from(m->ctx, 2, (int64_t[]){1, EP_DYN_IN}, dyn);
        cr_tensor *h1 =
            cr_gru_cell_forward(m->ctx, &m->gru, cr_mlp_forward(m->ctx, m->enc_dyn, dy), h0);
        CR_TRY(cr_nn_ctx_error(m->ctx, err));
        memcpy(hstate, h1->data, sizeof(float) * (size_t)G);
    }
    return CR_OK;
}

/* E-Net frame by frame over s (the GRU state carried), after `warmup` frames.
 * Frame t's RB input: the closed loop's RB when use_pnet (P-Net on frame t's
 * angles then gives RB_t), else zero. Outputs (T,...) each may be NULL; rb
 * gets the closed loop's RB. */
static cr_status rollout(cr_epnet *m, const cr_epnet_seq *s, int32_t warmup, int use_pnet,
                         float *pos, float *theta, float *rb, cr_error *err) {
    const int32_t V = m->nv, H = m->nh, T = s->T, G = m->def.gru_hidden;
    float *x = malloc(sizeof(float) * 3 * (size_t)V), *th = malloc(sizeof(float) * (size_t)H);
    float *r = calloc((size_t)H, sizeof(float)), *hstate = calloc((size_t)G, sizeof(float));
    if (!x || !th || !r || !hstate) {
        free(x), free(th), free(r), free(hstate);
        return CR_FAIL(err, CR_ERR_MEMORY, "epnet: out of memory for the rollout");
    }
    cr_status st = warmup > 0 ? cr_epnet_warm_up_(m, s, warmup, hstate, err) : CR_OK;
    for (int32_t t = 0; st == CR_OK && t < T; t++) {
        cr_nn_ctx_reset(m->ctx);
        cr_nn_ctx_set_grad_enabled(m->ctx, 0);
        cr_tensor *h0 =
                      t > 0 || warmup > 0 ? cr_nn_from(m->ctx, 2, (int64_t[]){1, G}, hstate) : NULL,
                  *h1 = NULL;
        const float *rin = r;
        cr_tensor *xt = NULL;
        cr_epnet_enet_frame_(m, s, t, 1, &rin, h0, &h1, &xt);
        st = cr_nn_ctx_error(m->ctx, err);
        if (st != CR_OK) break;
        memcpy(x, xt->data, sizeof(float) * 3 * (size_t)V);
        memcpy(hstate, h1->data, sizeof(float) * (size_t)G);
        cr_epnet_angles_(m, x, 1, th);
        if (use_pnet) {
            cr_nn_ctx_reset(m->ctx);
            cr_tensor *inc = cr_epnet_pnet_forward_(m, x, th, r);
            st = cr_nn_ctx_error(m->ctx, err);
            if (st != CR_OK) break;
            for (int32_t h = 0; h < H; h++)
                r[h] += inc->data[h];
        }
        if (pos) memcpy(pos + (size_t)t * V * 3, x, sizeof(float) * 3 * (size_t)V);
        if (theta) memcpy(theta + (size_t)t * H, th, sizeof(float) * (size_t)H);
        if (rb) memcpy(rb + (size_t)t * H, r, sizeof(float) * (size_t)H);
    }
    free(x), free(th), free(r), free(hstate);
    return st;
}

cr_status cr_epnet_rollout(cr_epnet *m, const cr_epnet_seq *s, int use_pnet, float *pos,
                           float *theta, float *rb, cr_error *err) {
    return rollout(m, s, 0, use_pnet, pos, theta, rb, err);
}

/* The proxy inference: (1) E-Net at RB = 0, the proxy; (2) P-Net over the
 * proxy's positions and angles, frame by frame, each increment through the
 * ratchet and its drive gating (ratchet.c); (3) E-Net with that RB. */
cr_status cr_epnet_pnet_ratchet_frame_(cr_epnet *m, const float *pos, const float *th,
                                       const cr_epnet_ratchet_def *d, uint32_t *hist, float *strain,
                                       float *r, cr_error *err) {
    cr_nn_ctx_reset(m->ctx);
    cr_nn_ctx_set_grad_enabled(m->ctx, 0);
    cr_tensor *inc = cr_epnet_pnet_forward_(m, pos, th, r);
    CR_TRY(cr_nn_ctx_error(m->ctx, err));
    for (int32_t h = 0; h < m->nh; h++)
        strain[h] = th[h] - m->theta_bar[h];
    cr_epnet_ratchet_step(d, strain, inc->data, m->nh, hist, r);
    return CR_OK;
}

cr_status cr_epnet_pnet_proxy_(cr_epnet *m, const float *ppos, const float *pth, int32_t T,
                               const cr_epnet_ratchet_def *d, float *R, cr_error *err) {
    const int32_t V = m->nv, H = m->nh;
    float *r = calloc((size_t)H, sizeof(float)), *strain = malloc(sizeof(float) * (size_t)H);
    uint32_t *hist = calloc((size_t)H, sizeof(uint32_t));
    cr_status st = CR_OK;
    if (!r || !strain || !hist)
        st = CR_FAIL(err, CR_ERR_MEMORY, "epnet: out of memory for P-Net over the proxy");
    for (int32_t t = 0; st == CR_OK && t < T; t++) {
        st = cr_epnet_pnet_ratchet_frame_(m, ppos + (size_t)t * V * 3, pth + (size_t)t * H, d, hist,
                                          strain, r, err);
        if (st == CR_OK) memcpy(R + (size_t)t * H, r, sizeof(float) * (size_t)H);
    }
    free(r), free(strain), free(hist);
    return st;
}

#define INFER_COOKIE 0x45504931u

cr_epnet_infer_def cr_epnet_infer_default_def(void) {
    cr_epnet_infer_def d;
    memset(&d, 0, sizeof d);
    d.mode = CR_EPNET_PROXY;
    d.warmup = 0;
    d.ratchet = cr_epnet_ratchet_default_def();
    d.cookie = INFER_COOKIE;
    return d;
}

cr_status cr_epnet_infer_check_(const cr_epnet_infer_def *d, cr_error *err) {
    if (d->cookie != INFER_COOKIE)
        return CR_FAIL(err, CR_ERR_INVALID, "epnet infer: def not made by its default");
    if (d->warmup < 0 || d->warmup > 100000)
        return CR_FAIL(err, CR_ERR_INVALID, "epnet infer: warm-up %d frames not in 0..100000",
                       d->warmup);
    if (d->mode != CR_EPNET_PROXY && d->mode != CR_EPNET_CLOSED_LOOP && d->mode != CR_EPNET_ZERO_RB)
        return CR_FAIL(err, CR_ERR_INVALID, "epnet infer: unknown mode %d", (int)d->mode);
    return d->mode == CR_EPNET_PROXY ? cr_epnet_ratchet_check(&d->ratchet, err) : CR_OK;
}

cr_status cr_epnet_infer(cr_epnet *m, const cr_epnet_seq *s, const cr_epnet_infer_def *d,
                         float *pos, float *theta, float *rb, cr_error *err) {
    CR_TRY(cr_epnet_infer_check_(d, err));
    if (d->mode == CR_EPNET_CLOSED_LOOP) return rollout(m, s, d->warmup, 1, pos, theta, rb, err);
    return cr_epnet_runtime_infer_(m, s, d, pos, theta, rb, err); /* proxy, zero RB */
}

cr_status cr_epnet_pnet_replay(cr_epnet *m, const float *pos, int32_t T, float *rb, cr_error *err) {
    const int32_t V = m->nv, H = m->nh;
    float *th = malloc(sizeof(float) * (size_t)H), *r = calloc((size_t)H, sizeof(float));
    if (!th || !r) {
        free(th), free(r);
        return CR_FAIL(err, CR_ERR_MEMORY, "epnet: out of memory for the P-Net replay");
    }
    cr_status st = CR_OK;
    for (int32_t t = 0; st == CR_OK && t < T; t++) {
        const float *x = pos + (size_t)t * V * 3;
        cr_epnet_angles_(m, x, 1, th);
        cr_nn_ctx_reset(m->ctx);
        cr_nn_ctx_set_grad_enabled(m->ctx, 0);
        cr_tensor *inc = cr_epnet_pnet_forward_(m, x, th, r);
        st = cr_nn_ctx_error(m->ctx, err);
        if (st != CR_OK) break;
        for (int32_t h = 0; h < H; h++)
            r[h] += inc->data[h];
        memcpy(rb + (size_t)t * H, r, sizeof(float) * (size_t)H);
    }
    free(th), free(r);
    return st;
}
