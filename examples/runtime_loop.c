/* runtime_loop.c: a game loop's use of crease: stream a motion (a BVH, an
 * AMASS .npz or a clip name) frame by frame through a method's runtime and
 * write the garment as an animated glb (morph targets, which Blender and
 * three.js play).
 *
 *   example_runtime_loop swingar MODEL GARMENT MOTION OUT.glb [BODY]
 *   example_runtime_loop epnet MODEL_DIR MOTION OUT.glb [BODY]
 *   example_runtime_loop gdsr MODEL DATASET MOTION OUT.glb [BODY]
 *     MODEL      a model from `crease swingar train`; GARMENT an OBJ, PLY or glb
 *                garment (UVs not needed), fitted to the body
 *     MODEL_DIR  a folder from `crease epnet train` (the garment is its own)
 *     gdsr       a model from `crease gdsr train` and the `crease dataset --res
 *                low,high` folder holding its t-shirt pair on BODY: each frame the
 *                simulator (Newton, cotton) steps the low garment on the posed
 *                body, then gdsr makes the high one from it
 *     MOTION     a .bvh or .npz file (retargeted onto the body, eased in from the
 *                rest pose over 1 s) or a clip name (crease motion --list); at
 *                30 fps, or the epnet model's rate
 *     BODY       slim, normal, heavy or an SMPL-family FILE.npz[:betas] (default:
 *                normal for swingar and gdsr, the model's for epnet)
 *
 * Everything the loop needs is made before it (cr_*_runtime_open); a step
 * allocates nothing. The loop prints the frames per second it ran at (for
 * gdsr the low simulation's step and gdsr's together).
 */
#include "crease/body.h"
#include "crease/epnet.h"
#include "crease/gdsr.h"
#include "crease/mesh_io.h"
#include "crease/motion.h"
#include "crease/phys_sim.h"
#include "crease/swingar.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* one method's runtime behind one step; gdsr's input is the low garment
 * simulated on the posed body (posed (T,Vb,3)), one frame a step */
typedef struct runtime {
    cr_swingar_runtime *swingar;
    cr_epnet_runtime *epnet;
    cr_gdsr_runtime *gdsr;
    cr_sim *sim;
    const float *posed;
    float *low; /* (Vl,3) */
} runtime;

static cr_status step(runtime *rt, int32_t t, const float *pose, const float *root, float *out,
                      cr_error *err) {
    if (rt->swingar) return cr_swingar_runtime_step(rt->swingar, pose, root, out, err);
    if (rt->epnet) return cr_epnet_runtime_step(rt->epnet, pose, root, out, err);
    if (t > 0) CR_TRY(cr_sim_step(rt->sim, NULL, err)); /* frame 0: the rest */
    cr_sim_positions_f(rt->sim, rt->low);
    const int64_t Vb = cr_gdsr_runtime_body_vertices(rt->gdsr);
    return cr_gdsr_runtime_step(rt->gdsr, rt->low, rt->posed + (size_t)t * Vb * 3, out, err);
}

/* gdsr's low simulation: Newton at the motion's rate on the posed body */
static cr_status open_gdsr(runtime *rt, const char *model, const char *dataset, const char *body,
                           const cr_body_model *b, const cr_motion *mo, float **posed,
                           cr_error *err) {
    CR_TRY(cr_gdsr_runtime_open(model, dataset, "tshirt", body, NULL, &rt->gdsr, err));
    const cr_mesh *lo = cr_gdsr_runtime_low_rest(rt->gdsr);
    if (b->rest->nv != cr_gdsr_runtime_body_vertices(rt->gdsr))
        return CR_FAIL(err, CR_ERR_SHAPE, "%s: its body has %d vertices, %s has %d", dataset,
                       cr_gdsr_runtime_body_vertices(rt->gdsr), body, b->rest->nv);
    CR_TRY(cr_body_pose_motion(b, mo, posed, err));
    rt->posed = *posed;
    if (!(rt->low = malloc(sizeof(float) * 3 * (size_t)lo->nv)))
        return CR_FAIL(err, CR_ERR_MEMORY, "out of memory");
    cr_sim_def sd = cr_sim_default_def();
    CR_TRY(cr_material_preset("cotton", &sd.material, err));
    sd.dt = 1.0 / mo->fps;
    sd.collider = b->rest;
    sd.collider_frames = *posed;
    sd.collider_nframes = mo->nframes;
    return cr_sim_create(&sd, lo, &rt->sim, err);
}

int main(int argc, char **argv) {
    const int swingar = argc > 1 && strcmp(argv[1], "swingar") == 0;
    const int epnet = argc > 1 && strcmp(argv[1], "epnet") == 0;
    const int gdsr = argc > 1 && strcmp(argv[1], "gdsr") == 0;
    if (!((swingar || gdsr) && argc >= 6) && !(epnet && argc >= 5)) {
        fprintf(stderr,
                "usage: %s swingar MODEL GARMENT MOTION OUT.glb [BODY]\n"
                "       %s epnet MODEL_DIR MOTION OUT.glb [BODY]\n"
                "       %s gdsr MODEL DATASET MOTION OUT.glb [BODY]\n",
                argv[0], argv[0], argv[0]);
        return 2;
    }
    const int k = epnet ? 3 : 4; /* MOTION's place */
    const char *motion = argv[k], *out_path = argv[k + 1];
    const char *body = argc > k + 2 ? argv[k + 2] : gdsr ? "normal" : NULL;
    cr_error err = {0};
    runtime rt = {0};
    cr_body_model *b = NULL;
    cr_motion *mo = NULL;
    float *frames = NULL, *posed = NULL;
    cr_status st = swingar ? cr_swingar_runtime_open(argv[2], argv[3], body, 0, &rt.swingar, &err)
                   : epnet ? cr_epnet_runtime_open(argv[2], body, NULL, &rt.epnet, &err)
                           : CR_OK;
    /* the motion, retargeted onto the body (the mannequin when none is named) */
    if (st == CR_OK && body) st = cr_body_resolve(body, &b, &err);
    if (st == CR_OK) {
        cr_motion_resolve_def rd = cr_motion_resolve_default_def();
        rd.body = b;
        if (epnet) rd.fps = cr_epnet_get_def(cr_epnet_runtime_model(rt.epnet))->fps;
        st = cr_motion_resolve(motion, &rd, &mo, NULL, &err);
    }
    if (st == CR_OK && gdsr) st = open_gdsr(&rt, argv[2], argv[3], body, b, mo, &posed, &err);
    const cr_mesh *rest = swingar ? cr_swingar_runtime_rest(rt.swingar) : NULL;
    if (epnet && rt.epnet) rest = cr_epnet_runtime_rest(rt.epnet);
    if (gdsr && rt.gdsr) rest = cr_gdsr_runtime_rest(rt.gdsr);
    const int32_t V = rest ? rest->nv : 0, T = mo ? mo->nframes : 0;
    if (st == CR_OK && !(frames = malloc(sizeof(float) * (size_t)T * V * 3)))
        st = CR_FAIL(&err, CR_ERR_MEMORY, "out of memory for %d frames", T);
    /* the loop: one pose in (gdsr: the low simulation's frame), the garment's vertices out */
    double t0 = cr_time_now();
    for (int32_t t = 0; st == CR_OK && t < T; t++)
        st = step(&rt, t, mo->poses + (size_t)t * CR_NJOINTS * 3, mo->trans + 3 * t,
                  frames + (size_t)t * V * 3, &err);
    double seconds = cr_time_now() - t0;
    if (st == CR_OK) st = cr_glb_write_sequence(out_path, rest, frames, T, mo->fps, &err);
    if (st == CR_OK)
        printf("%s: %d frames of a %d-vertex garment in %.2f s (%.1f frames/s), written to %s\n",
               argv[1], T, V, seconds, seconds > 0 ? T / seconds : 0.0, out_path);
    else
        fprintf(stderr, "%s: %s\n", argv[0], err.msg);
    free(frames);
    free(posed);
    free(rt.low);
    cr_sim_destroy(rt.sim);
    cr_gdsr_runtime_destroy(rt.gdsr);
    cr_motion_destroy(mo);
    cr_body_model_destroy(b);
    cr_swingar_runtime_destroy(rt.swingar);
    cr_epnet_runtime_destroy(rt.epnet);
    return st == CR_OK ? 0 : 1;
}
