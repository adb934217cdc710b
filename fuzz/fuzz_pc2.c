/* fuzz_pc2.c: libFuzzer target for the PC2 point-cache reader. Any input must give a
 * status, never a crash, leak or undefined behaviour; seeds in fuzz/corpus/fuzz_pc2/. */
#include "crease/mesh_io.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    cr_error err;
    cr_pc2 pc;
    cr_pc2_read_mem(data, size, "fuzz.pc2", &pc, &err);
    cr_pc2_free(&pc);
    return 0;
}
