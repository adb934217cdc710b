/* runtime_loop.c: a game loop's use of crease: stream a motion (a BVH, an
 * AMASS .npz or a clip name) frame by frame through a method's runtime and
 * write the garment as an animated glb (morph targets, which Blender and
 * three.js play).
 *
 *   example_runtime_loop swingar MODEL GARMENT MOTION OUT.glb [BODY]
 *   example_runtime_loop epnet MODEL_DIR MOTION OUT.glb [BODY]
 *     MODEL      a model from `crease swingar train`; GARMENT an OBJ, PLY or glb
 *                garment (UVs not needed), fitted to the body
 *     MODEL_DIR  a folder from `crease epnet train` (the garment is its own)
 *     MOTION     a .bvh or .npz file (retargeted onto the body, eased in from the
 *                rest pose over 1 s) or a clip name (crease motion --list); at
 *                30 fps, or the epnet model's rate
 *     BODY       slim, normal, heavy or an SMPL-family FILE.npz[:betas] (default:
 *                normal for swingar, the model's for epnet)
 *
 * Everything the loop needs is made before it (cr_*_runtime_open); a step
 * allocates nothing. The loop prints the frames per second it ran at.
 */
#include "crease/body.h"
#include "crease/epnet.h"
#include "crease/mesh_io.h"
#include "crease/motion.h"
#include "crease/swingar.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* one method's runtime behind one step */
typedef struct runtime {
    cr_swingar_runtime *swingar;
    cr_epnet_runtime *epnet;
} runtime;

static cr_status step(runtime *rt, const float *pose, const float *root, float *out,
                      cr_error *err) {
    return rt->swingar ? cr_swingar_runtime_step(rt->swingar, pose, root, out, err)
                       : cr_epnet_runtime_step(rt->epnet, pose, root, out, err);
}

int main(int argc, char **argv) {
    const int swingar = argc > 1 && strcmp(argv[1], "swingar") == 0;
    const int epnet = argc > 1 && strcmp(argv[1], "epnet") == 0;
    if (!(swingar && argc >= 6) && !(epnet && argc >= 5)) {
        fprintf(stderr,
                "usage: %s swingar MODEL GARMENT MOTION OUT.glb [BODY]\n"
                "       %s epnet MODEL_DIR MOTION OUT.glb [BODY]\n",
                argv[0], argv[0]);
        return 2;
    }
    const char *motion = argv[swingar ? 4 : 3], *out_path = argv[swingar ? 5 : 4];
    const char *body = argc > (swingar ? 6 : 5) ? argv[swingar ? 6 : 5] : NULL;
    cr_error err = {0};
    runtime rt = {0};
    cr_body_model *b = NULL;
    cr_motion *mo = NULL;
    float *frames = NULL;
    cr_status st = swingar ? cr_swingar_runtime_open(argv[2], argv[3], body, 0, &rt.swingar, &err)
                           : cr_epnet_runtime_open(argv[2], body, NULL, &rt.epnet, &err);
    /* the motion, retargeted onto the body (the mannequin when none is named) */
    if (st == CR_OK && body) st = cr_body_resolve(body, &b, &err);
    if (st == CR_OK) {
        cr_motion_resolve_def rd = cr_motion_resolve_default_def();
        rd.body = b;
        if (epnet) rd.fps = cr_epnet_get_def(cr_epnet_runtime_model(rt.epnet))->fps;
        st = cr_motion_resolve(motion, &rd, &mo, NULL, &err);
    }
    const cr_mesh *rest = swingar ? cr_swingar_runtime_rest(rt.swingar) : NULL;
    if (epnet && rt.epnet) rest = cr_epnet_runtime_rest(rt.epnet);
    const int32_t V = rest ? rest->nv : 0, T = mo ? mo->nframes : 0;
    if (st == CR_OK && !(frames = malloc(sizeof(float) * (size_t)T * V * 3)))
        st = CR_FAIL(&err, CR_ERR_MEMORY, "out of memory for %d frames", T);
    /* the loop: one pose in, the garment's vertices out */
    double t0 = cr_time_now();
    for (int32_t t = 0; st == CR_OK && t < T; t++)
        st = step(&rt, mo->poses + (size_t)t * CR_NJOINTS * 3, mo->trans + 3 * t,
                  frames + (size_t)t * V * 3, &err);
    double seconds = cr_time_now() - t0;
    if (st == CR_OK) st = cr_glb_write_sequence(out_path, rest, frames, T, mo->fps, &err);
    if (st == CR_OK)
        printf("%s: %d frames of a %d-vertex garment in %.2f s (%.1f frames/s), written to %s\n",
               argv[1], T, V, seconds, seconds > 0 ? T / seconds : 0.0, out_path);
    else
        fprintf(stderr, "%s: %s\n", argv[0], err.msg);
    free(frames);
    cr_motion_destroy(mo);
    cr_body_model_destroy(b);
    cr_swingar_runtime_destroy(rt.swingar);
    cr_epnet_runtime_destroy(rt.epnet);
    return st == CR_OK ? 0 : 1;
}
