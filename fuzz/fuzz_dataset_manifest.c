/* fuzz_dataset_manifest.c: libFuzzer target for a dataset's manifest.json
 * reader (cr_dataset_parse), and the lookups every reader of a dataset
 * makes. Any input must give a status, never a crash, leak or undefined
 * behaviour; seeds in fuzz/corpus/fuzz_dataset_manifest/. */
#include "crease/dataset.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    cr_error err;
    cr_dataset_manifest m;
    if (cr_dataset_parse((const char *)data, size, "fuzz", &m, &err) == CR_OK) {
        for (int32_t i = 0; i < m.nsequences; i++) {
            const cr_dataset_sequence_entry *q = &m.sequences[i];
            cr_dataset_find_garment(&m, q->garment, q->body, q->res);
            cr_dataset_find_body(&m, q->body);
            cr_dataset_find_sequence(&m, q->garment, q->res, q->body, q->motion);
            char path[64];
            cr_dataset_path(&m, q->garment_pc2, path, sizeof path, &err);
        }
        cr_dataset_find_id(&m, NULL);
    }
    cr_dataset_manifest_free(&m);
    return 0;
}
