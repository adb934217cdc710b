/* fuzz_glb_seq.c: libFuzzer target for the glb sequence reader (morph targets, the weld
 * map, the animation's frame rate). Any input must give a status, never a crash, leak or
 * undefined behaviour; seeds in fuzz/corpus/fuzz_glb_seq/. */
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
    return 0;
}
