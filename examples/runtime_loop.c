/* runtime_loop.c: a game loop's use of crease: stream a motion (a BVH, an
 * AMASS .npz or a clip name) frame by frame through SwinGar's runtime and
 * write the garment as an animated glb (morph targets, which Blender and
 * three.js play).
 *
 *   example_runtime_loop MODEL GARMENT MOTION OUT.glb [BODY]
 *     MODEL    a model from `crease swingar train`
 *     GARMENT  an OBJ, PLY or glb garment (UVs not needed), fitted to the body
 *     MOTION   a .bvh or .npz file (retargeted onto the body, 30 fps, eased in
 *              from the rest pose over 1 s) or a clip name (crease motion --list)
 *     BODY     slim, normal (default), heavy or an SMPL-family FILE.npz[:betas]
 *
 * Everything the loop needs is made before it (cr_swingar_runtime_open); a
 * step allocates nothing. The loop prints the frames per second it ran at.
 */
#include "crease/body.h"
#include "crease/mesh_io.h"
#include "crease/motion.h"
#include "crease/swingar.h"

#include <stdio.h>
#include <stdlib.h>

int main(int argc, char **argv) {
    if (argc < 5) {
        fprintf(stderr, "usage: %s MODEL GARMENT MOTION OUT.glb [BODY]\n", argv[0]);
        return 2;
    }
    const char *body = argc > 5 ? argv[5] : "normal";
    cr_error err = {0};
    cr_swingar_runtime *rt = NULL;
    cr_body_model *b = NULL;
    cr_motion *mo = NULL;
    float *frames = NULL;
    cr_status st = cr_swingar_runtime_open(argv[1], argv[2], body, 0, &rt, &err);
    /* the motion, retargeted onto the body the garment was fitted on */
    if (st == CR_OK) st = cr_body_resolve(body, &b, &err);
    if (st == CR_OK) {
        cr_motion_resolve_def rd = cr_motion_resolve_default_def();
        rd.body = b;
        st = cr_motion_resolve(argv[3], &rd, &mo, NULL, &err);
    }
    const int32_t V = rt ? cr_swingar_runtime_vertices(rt) : 0, T = mo ? mo->nframes : 0;
    if (st == CR_OK && !(frames = malloc(sizeof(float) * (size_t)T * V * 3)))
        st = CR_FAIL(&err, CR_ERR_MEMORY, "out of memory for %d frames", T);
    /* the loop: one pose in, the garment's vertices out */
    double t0 = cr_time_now();
    for (int32_t t = 0; st == CR_OK && t < T; t++)
        st = cr_swingar_runtime_step(rt, mo->poses + (size_t)t * CR_NJOINTS * 3, mo->trans + 3 * t,
                                     frames + (size_t)t * V * 3, &err);
    double seconds = cr_time_now() - t0;
    if (st == CR_OK)
        st = cr_glb_write_sequence(argv[4], cr_swingar_runtime_rest(rt), frames, T, mo->fps, &err);
    if (st == CR_OK)
        printf("%d frames of a %d-vertex garment in %.2f s (%.1f frames/s), written to %s\n", T, V,
               seconds, seconds > 0 ? T / seconds : 0.0, argv[4]);
    else
        fprintf(stderr, "%s: %s\n", argv[0], err.msg);
    free(frames);
    cr_motion_destroy(mo);
    cr_body_model_destroy(b);
    cr_swingar_runtime_destroy(rt);
    return st == CR_OK ? 0 : 1;
}
