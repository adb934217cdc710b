/* crease/nn_checkpoint.h: safetensors files and training checkpoints.
 *
 * safetensors (https://github.com/huggingface/safetensors, the format PyTorch
 * users load with safetensors.torch.load_file):
 *
 *   [8 bytes]  N, little-endian u64: header length
 *   [N bytes]  UTF-8 JSON object: name -> {"dtype": "F32", "shape": [..],
 *              "data_offsets": [begin, end]}, plus an optional
 *              "__metadata__": {string: string}; may end in spaces
 *   [rest]     the data buffer; offsets are relative to its start, tensors
 *              are little-endian, row-major (C order), and together cover it
 *              exactly, with no holes or overlaps
 *
 * Writing: every tensor as F32, header keys in the order given (a store's
 * order of addition), "__metadata__" first, the header padded with spaces so
 * the data starts 8-byte aligned; written to a temporary file and renamed.
 *
 * Reading validates everything before trusting it: the header length against
 * the file size before allocating, UTF-8 and JSON well-formedness, each
 * entry's fields, dtype, shape product * dtype size == end - begin, offsets
 * in range, contiguous and non-overlapping, no duplicate names, metadata
 * values all strings. Errors name the file (or the `source` given for memory)
 * and the tensor. Dtypes: F32 is read as is; F64, F16 and BF16 are converted
 * to float32 (F64 rounds to nearest); the integer, bool and 8-bit float dtypes
 * (I8..I64, U8..U64, BOOL, F8_E4M3, F8_E5M2) are validated but their data is
 * not loaded (data NULL), so a PyTorch state dict with integer buffers still
 * reads; loading such a tensor into a parameter fails with CR_ERR_UNSUPPORTED.
 * Any other dtype is refused.
 *
 * Checkpoints are one safetensors file: the model's parameters under their
 * own names, the optimiser state under "optim.<buffer>.<name>" (buffers "m"
 * and "v" for Adam(W), "momentum" for SGD) and, in __metadata__, decimal
 * strings for the integers (epoch, step, seed, the RNG's seed, stream,
 * counter and used count, the optimiser's step count), the loss printed with
 * 9 significant digits (which round-trips a float exactly), the optimiser's
 * kind and a free-form config JSON string. Floats are stored bit for bit, so
 * training resumed from a checkpoint is bit-identical to training that never
 * stopped. safetensors.torch.load_file reads a checkpoint as it reads any
 * weights file; the optim.* tensors come along and are easy to filter out.
 *
 * Leaves out: writing dtypes other than F32, memory-mapping (files are read
 * into memory), tensors of more than CR_ST_MAX_DIMS dimensions.
 */
#ifndef CREASE_NN_CHECKPOINT_H
#define CREASE_NN_CHECKPOINT_H

#include "crease/nn.h"
#include "crease/nn_optim.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---------------------------------------------------------- safetensors -- */

enum { CR_ST_MAX_DIMS = 8 };

typedef enum cr_st_dtype {
    CR_ST_F32 = 0,
    CR_ST_F64,
    CR_ST_F16,
    CR_ST_BF16,
    CR_ST_BOOL,
    CR_ST_U8,
    CR_ST_I8,
    CR_ST_U16,
    CR_ST_I16,
    CR_ST_U32,
    CR_ST_I32,
    CR_ST_U64,
    CR_ST_I64,
    CR_ST_F8_E4M3,
    CR_ST_F8_E5M2,
    CR_ST_DTYPE_COUNT
} cr_st_dtype;

const char *cr_st_dtype_name(cr_st_dtype dt); /* the spec's spelling: "F32", "BF16", ... */

/* One tensor. Reading fills every field (data NULL for dtypes that are not
 * converted); writing uses name, ndim, shape and data (numel floats) and
 * ignores dtype and numel (always F32). */
typedef struct cr_st_tensor {
    const char *name;
    cr_st_dtype dtype;
    int ndim;
    int64_t shape[CR_ST_MAX_DIMS];
    int64_t numel;
    float *data; /* (numel) row-major */
} cr_st_tensor;

typedef struct cr_st_meta {
    const char *key;
    const char *value;
} cr_st_meta;

/* A file read into memory. Tensors come in data-offset order; every string
 * and float belongs to the struct (free with cr_safetensors_free). */
typedef struct cr_safetensors {
    int ntensors;
    cr_st_tensor *tensors;
    int nmeta;
    cr_st_meta *meta;
    char *strings_; /* owned storage */
    float *floats_;
} cr_safetensors;

cr_status cr_safetensors_read(const char *path, cr_safetensors *out, cr_error *err);
/* `source` names the buffer in messages. */
cr_status cr_safetensors_read_mem(const void *data, size_t size, const char *source,
                                  cr_safetensors *out, cr_error *err);
void cr_safetensors_free(cr_safetensors *st); /* zeroes *st; a zeroed struct is a no-op */
const cr_st_tensor *cr_safetensors_find(const cr_safetensors *st, const char *name);
const char *cr_safetensors_meta(const cr_safetensors *st, const char *key); /* NULL if absent */

/* Write n tensors (names unique, non-empty, UTF-8, not "__metadata__") and
 * nmeta metadata pairs (keys unique). Atomic. */
cr_status cr_safetensors_write(const char *path, const cr_st_tensor *tensors, int n,
                               const cr_st_meta *meta, int nmeta, cr_error *err);

/* Every parameter of the store under its name, in order of addition. */
cr_status cr_safetensors_save_params(const char *path, cr_nn_params *p, const cr_st_meta *meta,
                                     int nmeta, cr_error *err);

/* Whether st's tensor `name` can fill x: present (else CR_ERR_PARSE), of x's
 * shape (CR_ERR_SHAPE naming both shapes), of a float dtype
 * (CR_ERR_UNSUPPORTED) and finite (CR_ERR_NAN naming the element). Messages
 * name `source` and the tensor. One pass over the values. */
cr_status cr_safetensors_check_tensor(const cr_safetensors *st, const char *source,
                                      const char *name, const cr_tensor *x, cr_error *err);

/* Copy tensors into the store by name. Every parameter must pass
 * cr_safetensors_check_tensor. Tensors the store lacks fail with
 * CR_ERR_INVALID unless allow_extra. Nothing is written to the store unless
 * everything matches. `source` names the file in messages. */
cr_status cr_safetensors_to_params(const cr_safetensors *st, const char *source, cr_nn_params *p,
                                   int allow_extra, cr_error *err);
cr_status cr_safetensors_load_params(const char *path, cr_nn_params *p, int allow_extra,
                                     cr_error *err);

/* ---------------------------------------------------------- checkpoints -- */

/* Training metadata. On a successful load, config_json is a heap copy the
 * caller frees with free() (NULL when the checkpoint has none); on save it is
 * read (may be NULL). */
typedef struct cr_checkpoint_meta {
    int64_t epoch;
    int64_t step;      /* the caller's step counter (the optimiser keeps its own) */
    uint64_t seed;     /* the run's seed */
    cr_rng rng;        /* generator state: resumes mid-block exactly */
    float loss;        /* last loss, bit-exact through the decimal string */
    char *config_json; /* the run's configuration, stored verbatim */
} cr_checkpoint_meta;

/* Write the model, the optimiser's state (opt may be NULL: weights only) and
 * the metadata (may be NULL) into one safetensors file, atomically. */
cr_status cr_checkpoint_save(const char *path, cr_nn_params *model, cr_optim *opt,
                             const cr_checkpoint_meta *meta, cr_error *err);

/* Restore what cr_checkpoint_save wrote into a store with the same parameter
 * names and shapes and, when opt is not NULL, an optimiser of the same kind
 * made on that store (moments and step count; the hyper-parameters stay those
 * of opt's def, so a run may resume with a changed learning rate). meta (may
 * be NULL) receives the metadata. Fails without changing anything when the
 * file does not match: unknown or missing tensors, other shapes, a
 * non-finite value (CR_ERR_NAN), an optimiser of another kind, or opt given
 * but no optimiser state saved
 * (model, opt and *meta are then untouched). Tensors named "optim.*" are
 * skipped when opt is NULL, so a checkpoint also loads as plain weights. */
cr_status cr_checkpoint_load(const char *path, cr_nn_params *model, cr_optim *opt,
                             cr_checkpoint_meta *meta, cr_error *err);

/* ------------------------------------------------------- training log -- */

/* Cut the log at `path` back to the epochs a checkpoint holds, so a run
 * resumed from epoch `epoch` (0: a fresh run, the log is emptied) appends
 * exactly one line per epoch: keeps the lines whose "epoch" is at most
 * `epoch`, in epoch order, the last one of an epoch logged twice, and drops
 * the rest (epochs logged past the checkpoint by a killed run, a line cut
 * short, anything unreadable). A missing file is created. Atomic; CR_ERR_IO
 * names the file. For logs whose rows the checkpoint does not hold (drape's
 * does, and rewrites its log from them). */
cr_status cr_train_log_cut(const char *path, int64_t epoch, cr_error *err);

#ifdef __cplusplus
}
#endif
#endif
