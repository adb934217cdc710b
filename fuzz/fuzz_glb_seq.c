/* fuzz_glb_seq.c: libFuzzer target for the glb sequence reader (morph targets, the weld
 * map, the animation's frame rate) and the character reader (a skinned file's skeleton
 * and skin, posed at rest and by one frame of its identity motion). Any input must give
 * a status, never a crash, leak or undefined behaviour; seeds in fuzz/corpus/fuzz_glb_seq/. */
#include "crease/mesh_io.h"

#include <stdlib.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    cr_error err;
    cr_mesh *m = NULL;
    float *frames = NULL, fps;
    int32_t n;
    cr_glb_read_sequence_mem(data, size, "fuzz.glb", &m, &frames, &n, &fps, &err);
    cr_mesh_destroy(m);
    free(frames);
    cr_glb_character *c = NULL;
    if (cr_glb_read_character_mem(data, size, "fuzz.glb", &c, &err) == CR_OK) {
        float *rot = calloc((size_t)c->skin.njoints * 4, sizeof(float)), tr[3] = {0, 0, 0};
        for (int32_t j = 0; rot && j < c->skin.njoints; j++)
            rot[4 * j + 3] = 1.0f;
        const cr_glb_skin_motion still = {1, 30.0f, rot, tr};
        float *posed = NULL;
        if (rot) cr_glb_character_pose(c, &still, &posed, &err);
        free(posed);
        free(rot);
    }
    cr_glb_character_destroy(c);
    return 0;
}
