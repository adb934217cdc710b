/* fuzz_glb.c: libFuzzer target for the glb reader (container, JSON, accessors). Any input must give
 * a status, never a crash, leak or undefined behaviour; seeds in fuzz/corpus/fuzz_glb/. */
#include "crease/mesh_io.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    cr_error err;
    cr_mesh *m = NULL;
    cr_glb_read_mem(data, size, "fuzz.glb", &m, &err);
    cr_mesh_destroy(m);
    return 0;
}
