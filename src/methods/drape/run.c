/* run.c: the drape method as one call (cr_drape_run): its def (names, defaults, the
 * field tables its options and checks come from, validation), training (train.c), the
 * surface at the output resolution, its measures (depth inside the object, grid facets)
 * and the outputs a user opens (OBJ, glb, PNGs, the loss log). */
#include "drape_internal.h"

#include "crease/drape_sampling.h"
#include "crease/mesh_io.h"

#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

static const uint32_t DRAPE_DEF_COOKIE = 0x44525045u; /* "DRPE" */

static const char *const variant_names[CR_DRAPE_VARIANT_COUNT] = {"mesh", "inr-mesh", "inr-uniform",
                                                                  "inr-adaptive"};
static const char *const scene_names[CR_DRAPE_SCENE_COUNT] = {"ball", "torus", "prism", "table",
                                                              "object"};

const char *cr_drape_variant_name(cr_drape_variant v) {
    return (int)v >= 0 && v < CR_DRAPE_VARIANT_COUNT ? variant_names[v] : "?";
}

cr_status cr_drape_variant_parse(const char *name, cr_drape_variant *out, cr_error *err) {
    for (int i = 0; i < CR_DRAPE_VARIANT_COUNT; i++)
        if (strcmp(name, variant_names[i]) == 0) {
            *out = (cr_drape_variant)i;
            return CR_OK;
        }
    return CR_FAIL(err, CR_ERR_INVALID,
                   "--variant: unknown variant '%s' (expected mesh, inr-mesh, inr-uniform or "
                   "inr-adaptive)",
                   name);
}

const char *cr_drape_scene_name(cr_drape_scene s) {
    return (int)s >= 0 && s < CR_DRAPE_SCENE_COUNT ? scene_names[s] : "?";
}

cr_status cr_drape_scene_parse(const char *name, cr_drape_scene *out, cr_error *err) {
    for (int i = 0; i < CR_DRAPE_OBJECT; i++)
        if (strcmp(name, scene_names[i]) == 0) {
            *out = (cr_drape_scene)i;
            return CR_OK;
        }
    return CR_FAIL(err, CR_ERR_INVALID,
                   "--scene: unknown scene '%s' (expected ball, torus, prism or table; "
                   "--object FILE for a mesh)",
                   name);
}

cr_drape_def cr_drape_default_def(cr_drape_scene scene) {
    int soft = scene == CR_DRAPE_TORUS || scene == CR_DRAPE_PRISM;
    cr_drape_def d = {
        .scene = scene,
        .variant = CR_DRAPE_INR_ADAPTIVE,
        .cloth_size = 0.0f, /* from the object */
        .gap = -1.0f,       /* from the cloth's size */
        .mesh_res = 128,
        .w = {.strain = 0.005f, .bend = 0.0005f, .gravity = 2.0f, .collision = soft ? 1e6f : 1e7f},
        .point_mass = 1e-4f,
        .gravity = 9.81f,
        .collision_eps = 0.002f,
        .collision = CR_DRAPE_COLLIDE_VERTEX,
        .side = 0.001f,
        .pin = 1.0f,
        .grid_levels = 2,
        .grid_resolution = 100,
        .grid_features = 3,
        .grid_interp = CR_GRID_BSPLINE, /* C2: no grid facets (docs/drape.md) */
        .mlp_hidden = 64,
        .mlp_layers = 4,
        .softplus_beta = 10.0f,
        .lr = 0.0005f,
        .lr_final = -1.0f,
        .settle_epochs = 250,
        .beta2 = 0.999f,
        .clip = 3.0f,
        .epochs = 15000,
        .samples = 1024,
        .pdf_grid = 32,
        .pdf_gamma = 0.9f,
        .mu = 0.5f,
        .lloyd_iterations = 2,
        .pdf_every = 5,
        .pdf_collision = 1.0f,
        .eval_res = 128,
        .eval_every = 50,
        .converge_window = 2000,
        .converge_tol = 0.01f,
        .stop_at_converged = 1,
        .seed = 1,
        .out_res = 256,
        .render_size = 1024,
        .checkpoint_every = 250,
        .cookie = DRAPE_DEF_COOKIE,
    };
    return d;
}

/* The def's fields by group: their ranges (cr_drape_def_validate) and the options of
 * `crease drape` with their help (CLI_KEYS). Ranges a field's meaning narrows further
 * (grid_resolution by grid_levels, lr_final by lr, the auto values of cloth_size and
 * lr_final) are checked by hand below. */
#define DK(...) CR_CONFIG_KEY(cr_drape_def, __VA_ARGS__)
#define WEIGHT(name, field, hi)                                                                    \
    { name, CR_CFG_FLOAT, offsetof(cr_drape_def, w.field), 0, 0, hi, NULL, NULL, NULL }
static const cr_config_key scene_keys[] = {
    DK(cloth_size, CR_CFG_FLOAT, 0, 1e3, "--cloth-size", "S",
       "side of the square cloth, m (default: 1 on the built-in scenes, 5/3 of the object's "
       "larger horizontal extent with --object)"),
};
static const cr_config_key training_keys[] = {
    DK(epochs, CR_CFG_INT, 1, 1e8, "--epochs", "N",
       "cap on epochs (a run stops at convergence first, see --stop)"),
    DK(samples, CR_CFG_INT, 1, 1 << 22, "--samples", "N", "local structures per epoch"),
    DK(lr, CR_CFG_FLOAT, 1e-12, 10, "--lr", "R", "Adam learning rate"),
    DK(lr_final, CR_CFG_FLOAT, -1e30, 10, "--lr-final", "R",
       "anneal to R by the last epoch (cosine; default -1, any negative: none)"),
    DK(settle_epochs, CR_CFG_INT, 0, 1e8, "--settle", "N",
       "without --lr-final: N epochs at lr/10 after convergence (or the last N before the cap), "
       "so contacts settle (0: constant lr)"),
    DK(beta2, CR_CFG_FLOAT, 0, 0.999999, "--beta2", "B", "Adam's second-moment decay"),
    DK(clip, CR_CFG_FLOAT, 0, 1e6, "--clip", "C",
       "clip the gradient norm at C times its running mean (0: off)"),
    DK(seed, CR_CFG_U64, 0, 2147483647, "--seed", "S", "initialisation, sampling and rotations"),
    DK(resume, CR_CFG_BOOL, 0, 1, "--resume", NULL, "continue from DIR/checkpoint.safetensors"),
    DK(checkpoint_every, CR_CFG_INT, 0, 1e8, "--checkpoint-every", "N",
       "epochs between checkpoints (0: at the end)"),
};
static const cr_config_key loss_keys[] = {
    WEIGHT("w_strain", strain, 1e12),
    WEIGHT("w_bend", bend, 1e12),
    WEIGHT("w_gravity", gravity, 1e12),
    WEIGHT("w_collision", collision, 1e15),
    DK(point_mass, CR_CFG_FLOAT, 0, 1e6, "--point-mass", "M",
       "kg per structure or vertex in the gravity loss"),
    DK(gravity, CR_CFG_FLOAT, -1e3, 1e3, NULL, NULL, NULL),
    DK(collision_eps, CR_CFG_FLOAT, 0, 1, "--eps", "E", "collision threshold, m"),
    DK(side, CR_CFG_FLOAT, 1e-6, 0.1, "--side", "S", "structure side in UV"),
    DK(pin, CR_CFG_FLOAT, 0, 1e12, "--pin", "W",
       "hold the cloth centre's horizontal position with weight W per structure (0: free to "
       "slide off the object)"),
};
static const cr_config_key model_keys[] = {
    DK(grid_levels, CR_CFG_INT, 1, 8, "--grid-levels", "L", "grid encoding levels"),
    DK(grid_resolution, CR_CFG_INT, 1, 4096, "--grid-res", "R",
       "cells per side of the finest level"),
    DK(grid_features, CR_CFG_INT, 1, 64, "--grid-features", "F", "features per grid node"),
    DK(mlp_hidden, CR_CFG_INT, 1, 4096, "--hidden", "W", "MLP width"),
    DK(mlp_layers, CR_CFG_INT, 1, 16, "--layers", "N", "MLP linear layers"),
    DK(softplus_beta, CR_CFG_FLOAT, 0, 1e3, "--softplus", "B",
       "hidden activation softplus with beta B; 0: ReLU"),
    DK(mesh_res, CR_CFG_INT, 2, 2048, "--mesh-res", "N",
       "vertices per side of the mesh variants' grid"),
};
static const cr_config_key sampler_keys[] = {
    DK(pdf_grid, CR_CFG_INT, 2, 1024, "--pdf-grid", "G", "PDF cells per side"),
    DK(pdf_gamma, CR_CFG_FLOAT, 0, 1, "--gamma", "G", "eq. 7 blend"),
    DK(mu, CR_CFG_FLOAT, 0, 1, "--mu", "M", "adaptive share of the samples"),
    DK(lloyd_iterations, CR_CFG_INT, 0, 1000, "--lloyd", "N", "Lloyd iterations"),
    DK(pdf_every, CR_CFG_INT, 1, 1000000, "--pdf-every", "N", "epochs between PDF updates"),
    DK(pdf_collision, CR_CFG_FLOAT, 0, 1e6, "--pdf-collision", "W",
       "the collision term's weight in the PDF, times its training weight (gravity is always "
       "left out)"),
};
static const cr_config_key convergence_keys[] = {
    DK(eval_res, CR_CFG_INT, 2, 1024, "--eval-res", "N", "fixed evaluation structures per side"),
    DK(eval_every, CR_CFG_INT, 1, 1000000, "--eval-every", "N", "epochs between evaluations"),
    DK(converge_window, CR_CFG_INT, 1, 1e8, "--window", "N",
       "converged when the energy fell by less than --tol times its total decrease over the "
       "last N epochs"),
    DK(converge_tol, CR_CFG_FLOAT, 0, 1, "--tol", "T", "that share"),
    DK(stop_at_converged, CR_CFG_BOOL, 0, 1, "--stop", NULL,
       "stop at convergence, after --settle epochs (the default)"),
};
static const cr_config_key output_keys[] = {
    DK(out_res, CR_CFG_INT, 2, 4096, "--res", "N", "output surface vertices per side"),
    DK(render_size, CR_CFG_INT, 16, 8192, "--render-size", "N", "PNG side in pixels"),
    DK(quiet, CR_CFG_BOOL, 0, 1, "--quiet", NULL, "no progress bar"),
};
#undef DK
#undef WEIGHT
#define KEYS(k)                                                                                    \
    { k, (int)(sizeof k / sizeof k[0]) }
static const struct {
    const cr_config_key *keys;
    int n;
} key_groups[CR_DRAPE_KEY_GROUPS] = {KEYS(scene_keys), KEYS(training_keys), KEYS(loss_keys),
                                     KEYS(model_keys), KEYS(sampler_keys),  KEYS(convergence_keys),
                                     KEYS(output_keys)};
#undef KEYS

const cr_config_key *cr_drape_def_keys(cr_drape_key_group g, int *n) {
    CR_ASSERT((int)g >= 0 && g < CR_DRAPE_KEY_GROUPS);
    *n = key_groups[g].n;
    return key_groups[g].keys;
}

cr_status cr_drape_def_validate(const cr_drape_def *d, cr_error *err) {
    CR_ASSERT(d && d->cookie == DRAPE_DEF_COOKIE);
    if ((int)d->scene < 0 || d->scene >= CR_DRAPE_SCENE_COUNT)
        return CR_FAIL(err, CR_ERR_INVALID, "drape: scene %d out of range", (int)d->scene);
    if ((int)d->variant < 0 || d->variant >= CR_DRAPE_VARIANT_COUNT)
        return CR_FAIL(err, CR_ERR_INVALID, "drape: variant %d out of range", (int)d->variant);
    if (d->scene == CR_DRAPE_OBJECT && !d->object_path)
        return CR_FAIL(err, CR_ERR_INVALID, "drape: the object scene needs an object mesh file");
    for (int g = 0; g < CR_DRAPE_KEY_GROUPS; g++)
        CR_TRY(cr_config_check(key_groups[g].keys, key_groups[g].n, d, "drape", err));
    if (d->cloth_size != 0.0f && d->cloth_size < 1e-3f)
        return CR_FAIL(err, CR_ERR_INVALID, "drape: cloth_size %g under 1 mm (0: from the object)",
                       (double)d->cloth_size);
    if (!(d->gap < 0.0f) && !(d->gap <= 1e3f))
        return CR_FAIL(err, CR_ERR_INVALID, "drape: gap %g outside [0, 1000] (< 0: from the cloth)",
                       (double)d->gap);
    if (d->collision != CR_DRAPE_COLLIDE_VERTEX && d->collision != CR_DRAPE_COLLIDE_SDF)
        return CR_FAIL(err, CR_ERR_INVALID, "drape: collision mode %d out of range",
                       (int)d->collision);
    if (d->grid_resolution < 1 << (d->grid_levels - 1))
        return CR_FAIL(err, CR_ERR_INVALID,
                       "drape: grid_resolution %d under 2^(grid_levels - 1) = %d",
                       d->grid_resolution, 1 << (d->grid_levels - 1));
    if ((int)d->grid_interp < 0 || d->grid_interp >= CR_GRID_INTERP_COUNT)
        return CR_FAIL(err, CR_ERR_INVALID, "drape: grid_interp %d out of range",
                       (int)d->grid_interp);
    if (d->lr_final >= 0.0f && d->lr_final > d->lr)
        return CR_FAIL(err, CR_ERR_INVALID, "drape: lr_final %g above lr %g (< 0: no cosine)",
                       (double)d->lr_final, (double)d->lr);
    if (d->out_dir && strlen(d->out_dir) > 900)
        return CR_FAIL(err, CR_ERR_INVALID, "drape: output directory name longer than 900 bytes");
    if (d->resume && !d->out_dir)
        return CR_FAIL(err, CR_ERR_INVALID, "drape: resuming needs an output directory");
    return CR_OK;
}

/* ---------------------------------------------------------- outputs -- */

static cr_status write_outputs(drape_run *r, cr_drape_result *res, const cr_mesh *surface,
                               cr_error *err) {
    const char *dir = r->def->out_dir;
    snprintf(res->obj_path, sizeof res->obj_path, "%s/drape.obj", dir);
    snprintf(res->glb_path, sizeof res->glb_path, "%s/drape.glb", dir);
    snprintf(res->png_path, sizeof res->png_path, "%s/drape.png", dir);
    snprintf(res->loss_png, sizeof res->loss_png, "%s/loss.png", dir);
    memcpy(res->log_path, r->log_path, sizeof res->log_path);
    memcpy(res->checkpoint_path, r->ckpt_path, sizeof res->checkpoint_path);
    CR_TRY(cr_mesh_write(res->obj_path, surface, err));
    CR_TRY(cr_mesh_write(res->glb_path, surface, err));
    cr_image img = {0};
    CR_TRY(cr_drape_render(surface, r->scene.object, r->def->render_size, &img, err));
    cr_status st = cr_image_write_png(&img, res->png_path, err);
    cr_image_free(&img);
    CR_TRY(st);
    CR_TRY(cr_drape_plot_losses(r->rows, r->nrows, res->loss_png, err));
    if (r->sampler) {
        snprintf(res->sampler_png, sizeof res->sampler_png, "%s/sampler.png", dir);
        CR_TRY(cr_drape_sampler_write_png(r->sampler, r->centre, r->drawn ? r->def->samples : 0,
                                          res->sampler_png, 512, err));
    }
    return CR_OK;
}

cr_status cr_drape_run(const cr_drape_def *def, cr_drape_result *res, cr_mesh **surface,
                       cr_error *err) {
    if (surface) *surface = NULL;
    CR_TRY(cr_drape_def_validate(def, err));
    memset(res, 0, sizeof *res);
    res->converged_epoch = -1;
    res->converged_seconds = -1.0;
    drape_run r;
    cr_status st = cr_drape_train_(def, &r, res, err);
    cr_mesh *out = NULL;
    if (st == CR_OK) st = cr_drape_surface_mesh(r.ctx, r.model, &r.scene, def->out_res, &out, err);
    if (st == CR_OK)
        res->max_penetration_m =
            r.scene.open_edges ? NAN : cr_drape_max_penetration(r.scene.bvh, out);
    /* the square cloth's output is cr_prim_plane's grid, rows of out_res vertices along u */
    res->facet_ratio = NAN;
    if (st == CR_OK && r.scene.square)
        res->facet_ratio = cr_drape_facet_ratio(
            out->pos, def->out_res, def->out_res,
            def->variant == CR_DRAPE_MESH ? def->mesh_res - 1 : def->grid_resolution);
    res->cloth_size_m = r.scene.cloth_size, res->drop_height_m = r.scene.drop_height;
    if (st == CR_OK && def->out_dir) st = cr_drape_checkpoint_(&r, res, err);
    if (st == CR_OK && def->out_dir) st = write_outputs(&r, res, out, err);
    if (st == CR_OK && surface)
        *surface = out;
    else
        cr_mesh_destroy(out);
    cr_drape_train_free_(&r);
    return st;
}
