/* fuzz_npz.c: libFuzzer target for the .npz reader and what reads through
 * it: every member as float32, float64 and int32, then the archive as a
 * motion and as an SMPL-style body model. Any input must give a status,
 * never a crash, leak or undefined behaviour; seeds in fuzz/corpus/fuzz_npz/. */
#include "crease/motion.h"
#include "crease/npz.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    cr_error err;
    cr_npz *z = NULL;
    if (cr_npz_open_mem(data, size, "fuzz.npz", &z, &err) == CR_OK) {
        for (int32_t i = 0; i < cr_npz_count(z); i++)
            for (int as = CR_NPY_AS_F32; as <= CR_NPY_AS_I32; as++) {
                cr_npy a;
                cr_npz_get(z, cr_npz_name(z, i), (cr_npy_as)as, &a, &err);
                cr_npy_free(&a);
            }
        cr_npz_close(z);
    }
    cr_motion *m = NULL;
    cr_motion_read_npz_mem(data, size, "fuzz.npz", NULL, &m, &err);
    cr_motion_destroy(m);
    float betas[2] = {0.5f, -0.5f};
    cr_body_model body;
    cr_smpl_read_mem(data, size, "fuzz.npz", betas, 2, &body, &err);
    cr_smpl_free(&body);
    return 0;
}
