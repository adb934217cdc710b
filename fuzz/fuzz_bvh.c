/* fuzz_bvh.c: libFuzzer target for the BVH motion loader (parsing, joint
 * mapping, frame conversion). Any input must give a status, never a crash,
 * leak or undefined behaviour; seeds in fuzz/corpus/fuzz_bvh/. */
#include "crease/motion.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    cr_error err;
    cr_motion *m = NULL;
    cr_motion_read_bvh_mem(data, size, "fuzz.bvh", NULL, &m, &err);
    cr_motion_destroy(m);
    return 0;
}
