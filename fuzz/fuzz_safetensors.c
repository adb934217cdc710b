/* fuzz_safetensors.c: libFuzzer target for the safetensors reader (from memory) and
 * the by-name copy into a parameter store. Any input must give a status, never a
 * crash, leak, oversized allocation or undefined behaviour; seeds in
 * fuzz/corpus/fuzz_safetensors/. */
#include "crease/nn_checkpoint.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    cr_error err;
    cr_safetensors st;
    if (cr_safetensors_read_mem(data, size, "fuzz.safetensors", &st, &err) != CR_OK) return 0;
    cr_nn_params *p = NULL;
    cr_tensor *w;
    if (cr_nn_params_create(&p, &err) == CR_OK &&
        cr_nn_params_add(p, "w", 2, (int64_t[]){2, 2}, &w, &err) == CR_OK) {
        cr_safetensors_to_params(&st, "fuzz.safetensors", p, 1, &err);
        cr_safetensors_to_params(&st, "fuzz.safetensors", p, 0, &err);
    }
    cr_nn_params_destroy(p);
    cr_safetensors_meta(&st, "__metadata__");
    cr_safetensors_free(&st);
    return 0;
}
