/* crease/npz.h: NumPy .npy arrays and .npz archives, read and written.
 *
 * An .npz is a zip archive of .npy members (np.savez stores them,
 * np.savez_compressed deflates them). This is the format AMASS motions and
 * SMPL-style body models are usually shared in, so crease reads it without
 * Python:
 *
 *   cr_npz *z = NULL;
 *   CR_TRY(cr_npz_open("walk.npz", &z, err));
 *   cr_npy poses = {0};
 *   cr_status st = cr_npz_get(z, "poses", CR_NPY_AS_F32, &poses, err); // poses.f32: (T, 156)
 *   ...
 *   cr_npy_free(&poses);
 *   cr_npz_close(z);
 *
 * Supported: zip members stored or deflated (zlib), ZIP64 extra fields on
 * members (np.savez writes them); .npy versions 1.0, 2.0 and 3.0; dtypes
 * '<f4' '<f8' '<i4' '<i8' '<u4' and their big-endian '>' forms; C and
 * Fortran order (Fortran is transposed to C order on reading); shapes of up
 * to CR_NPY_MAX_DIMS dimensions, scalars included. Arrays are converted on
 * reading to float32, float64 or int32, whichever the caller asks for.
 * Left out: other dtypes (strings, objects, structured, bool, 8- and
 * 16-bit), pickles, encrypted members, split archives and archives over
 * 65,535 members or 4 GiB of central directory (the ZIP64 end record).
 * Such members are listed but refused by name when asked for, so an AMASS
 * file's 'gender' string does not stop its 'poses' from loading.
 *
 * Hostile input: sizes are checked against the bytes present before any
 * allocation; a deflated member may not declare more than deflate can
 * expand its compressed bytes to (1032:1) nor inflate past what it
 * declared, which bounds zip bombs; CRC-32s are checked; conversion to
 * float refuses non-finite values, conversion to int32 refuses values out
 * of range. Messages name the archive, the member and the byte or element.
 *
 * Writing goes through a temporary file and a rename (cr_atomic_open), and
 * produces little-endian C-order arrays in version 1.0 headers padded to 64
 * bytes, as numpy does, so np.load reads them.
 *
 * References: numpy's NEP 1 (the .npy format, numpy/lib/format.py);
 * PKWARE APPNOTE.TXT 6.3 (zip); RFC 1951 (deflate).
 */
#ifndef CREASE_NPZ_H
#define CREASE_NPZ_H

#include "crease/base.h"

#ifdef __cplusplus
extern "C" {
#endif

enum { CR_NPY_MAX_DIMS = 8 };

/* Element types crease reads and writes (little endian in files it writes). */
typedef enum cr_npy_dtype {
    CR_NPY_F32 = 0, /* '<f4' */
    CR_NPY_F64,     /* '<f8' */
    CR_NPY_I32,     /* '<i4' */
    CR_NPY_I64,     /* '<i8' */
    CR_NPY_U32,     /* '<u4' */
    CR_NPY_DTYPE_COUNT
} cr_npy_dtype;

/* What an array is converted to on reading. */
typedef enum cr_npy_as {
    CR_NPY_AS_F32 = 0, /* non-finite values and floats past FLT_MAX are refused */
    CR_NPY_AS_F64,     /* non-finite values are refused; integers past 2^53 round */
    CR_NPY_AS_I32      /* integer dtypes only, values must fit int32 */
} cr_npy_as;

/* One array as read. Exactly one of f32, f64, i32 is set (the one asked
 * for); the struct owns it. */
typedef struct cr_npy {
    cr_npy_dtype dtype; /* as stored in the file */
    int32_t ndim;       /* 0 for a scalar */
    int64_t shape[CR_NPY_MAX_DIMS];
    int64_t count; /* product of shape (1 for a scalar) */
    float *f32;    /* (count) C order, when read as CR_NPY_AS_F32 */
    double *f64;   /* (count) C order, when read as CR_NPY_AS_F64 */
    int32_t *i32;  /* (count) C order, when read as CR_NPY_AS_I32 */
} cr_npy;

/* The dtype's name as it appears in .npy headers ("<f4", ...). */
const char *cr_npy_dtype_str(cr_npy_dtype dtype);

/* Parse one .npy image of `len` bytes. `source` names it in messages. */
cr_status cr_npy_parse(const void *data, size_t len, const char *source, cr_npy_as as, cr_npy *out,
                       cr_error *err);
cr_status cr_npy_read(const char *path, cr_npy_as as, cr_npy *out, cr_error *err);
/* Free the values and zero the struct; NULL and zeroed structs are fine. */
void cr_npy_free(cr_npy *a);

/* The .npy image of `data` (host-order values of `dtype`, C order, product
 * of shape elements) in a new buffer (*out, caller frees). ndim 0 encodes a
 * scalar. */
cr_status cr_npy_encode(cr_npy_dtype dtype, int32_t ndim, const int64_t *shape, const void *data,
                        unsigned char **out, size_t *out_len, cr_error *err);
/* The same written to a .npy file. */
cr_status cr_npy_write(const char *path, cr_npy_dtype dtype, int32_t ndim, const int64_t *shape,
                       const void *data, cr_error *err);

/* --------------------------------------------------------------- reading -- */

typedef struct cr_npz cr_npz; /* an open archive: its bytes and member table */

cr_status cr_npz_open(const char *path, cr_npz **out, cr_error *err);
/* Open an archive held in memory; the bytes are copied. */
cr_status cr_npz_open_mem(const void *data, size_t len, const char *source, cr_npz **out,
                          cr_error *err);
void cr_npz_close(cr_npz *z);

/* Members in archive order; names without their ".npy" suffix. */
int32_t cr_npz_count(const cr_npz *z);
const char *cr_npz_name(const cr_npz *z, int32_t i);
int cr_npz_has(const cr_npz *z, const char *name);
/* Read member `name` (without ".npy") as an array. CR_ERR_PARSE naming the
 * members the archive does have when it has no such member. */
cr_status cr_npz_get(const cr_npz *z, const char *name, cr_npy_as as, cr_npy *out, cr_error *err);

/* --------------------------------------------------------------- writing -- */

typedef struct cr_npz_writer cr_npz_writer;

/* Start an archive at `path` (written to a temporary name until commit).
 * deflate = 1 compresses members like np.savez_compressed (a member is
 * stored when deflating would not shrink it); 0 stores them like np.savez. */
cr_status cr_npz_writer_open(const char *path, int deflate, cr_npz_writer **out, cr_error *err);
/* Add array `name` (".npy" is appended); arguments as cr_npy_write. */
cr_status cr_npz_writer_add(cr_npz_writer *w, const char *name, cr_npy_dtype dtype, int32_t ndim,
                            const int64_t *shape, const void *data, cr_error *err);
/* Add a member with the given bytes as they are, under the exact `name`
 * (e.g. a hand-made .npy of a dtype crease does not write). */
cr_status cr_npz_writer_add_raw(cr_npz_writer *w, const char *name, const void *bytes, size_t len,
                                cr_error *err);
/* Write the central directory and rename into place. Frees `w` whatever
 * happens; on failure the temporary file is removed. */
cr_status cr_npz_writer_commit(cr_npz_writer *w, cr_error *err);
/* Drop the archive and its temporary file; NULL is fine. */
void cr_npz_writer_abort(cr_npz_writer *w);

#ifdef __cplusplus
}
#endif
#endif
