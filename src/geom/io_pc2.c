/* io_pc2.c: PC2 point caches (Blender's and 3ds Max's vertex animation format).
 *
 * Layout, little endian: char[12] "POINTCACHE2\0", int32 version (1), int32
 * points, float start frame, float sample rate, int32 samples, then float32
 * x y z per point per sample (sample-major). The reader checks the declared
 * size against the bytes present before allocating, and refuses non-finite
 * positions and trailing bytes. Vertex order is whatever the writer's mesh
 * used, which is what Blender's Mesh Cache modifier expects.
 *
 * Reference: Blender's io_import_pc2 / Mesh Cache modifier
 * (source/blender/modifiers/intern/MOD_meshcache_pc2.cc).
 */
#include "crease/mesh_io.h"
#include "geom/io_text.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { PC2_HEADER = 32 };
static const char pc2_magic[12] = "POINTCACHE2"; /* with its NUL */

void cr_pc2_free(cr_pc2 *p) {
    if (!p) return;
    free(p->frames);
    memset(p, 0, sizeof *p);
}

cr_status cr_pc2_read_mem(const void *data, size_t len, const char *source, cr_pc2 *out,
                          cr_error *err) {
    memset(out, 0, sizeof *out);
    const unsigned char *d = data;
    if (len < PC2_HEADER)
        return CR_FAIL(err, CR_ERR_PARSE, "%s: %zu bytes, expected a 32-byte PC2 header", source,
                       len);
    if (memcmp(d, pc2_magic, sizeof pc2_magic) != 0)
        return CR_FAIL(err, CR_ERR_PARSE, "%s: byte 0: expected 'POINTCACHE2\\0' (not a PC2 file)",
                       source);
    int32_t version = (int32_t)io_le32(d + 12), nv = (int32_t)io_le32(d + 16);
    float start = io_f32(io_le32(d + 20)), rate = io_f32(io_le32(d + 24));
    int32_t nframes = (int32_t)io_le32(d + 28);
    if (version != 1)
        return CR_FAIL(err, CR_ERR_UNSUPPORTED, "%s: byte 12: version %d, expected 1", source,
                       version);
    if (nv < 1 || nframes < 1)
        return CR_FAIL(err, CR_ERR_PARSE,
                       "%s: byte 16: %d points and %d samples, expected at least one of each",
                       source, nv, nframes);
    if (!isfinite(start) || !isfinite(rate) || rate <= 0)
        return CR_FAIL(err, CR_ERR_PARSE,
                       "%s: byte 20: start frame %g and sample rate %g, expected finite and a "
                       "positive rate",
                       source, start, rate);
    uint64_t points = (uint64_t)nv * (uint64_t)nframes; /* < 2^62 */
    uint64_t have = len - PC2_HEADER;
    uint64_t need = points <= have / 12 ? 12 * points : UINT64_MAX;
    if (need != have)
        return CR_FAIL(err, CR_ERR_PARSE,
                       "%s: byte 32: header declares %d points x %d samples (12 bytes each), "
                       "but %llu bytes of positions follow",
                       source, nv, nframes, (unsigned long long)have);
    float *f = cr_malloc((size_t)need, err);
    if (!f) return CR_ERR_MEMORY;
    for (uint64_t i = 0; i < need / 4; i++) {
        f[i] = io_f32(io_le32(d + PC2_HEADER + 4 * i));
        if (!isfinite(f[i])) {
            free(f);
            uint64_t p = i / 3;
            return CR_FAIL(err, CR_ERR_NAN, "%s: byte %llu: sample %llu point %llu is not finite",
                           source, (unsigned long long)(PC2_HEADER + 4 * i),
                           (unsigned long long)(p / (uint64_t)nv),
                           (unsigned long long)(p % (uint64_t)nv));
        }
    }
    out->nv = nv;
    out->nframes = nframes;
    out->start_frame = start;
    out->sample_rate = rate;
    out->frames = f;
    return CR_OK;
}

cr_status cr_pc2_read(const char *path, cr_pc2 *out, cr_error *err) {
    memset(out, 0, sizeof *out);
    char *buf;
    size_t len;
    CR_TRY(cr_file_read_all(path, &buf, &len, err));
    cr_status st = cr_pc2_read_mem(buf, len, path, out, err);
    free(buf);
    return st;
}

cr_status cr_pc2_write(const char *path, const float *frames, int32_t nv, int32_t nframes,
                       float start_frame, float sample_rate, cr_error *err) {
    if (nv < 1 || nframes < 1 || !frames)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "%s: expected at least one point and one frame, got "
                       "V=%d, T=%d",
                       path, nv, nframes);
    if (!isfinite(start_frame) || !isfinite(sample_rate) || sample_rate <= 0)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "%s: start frame %g and sample rate %g: expected finite and a positive "
                       "rate",
                       path, start_frame, sample_rate);
    size_t n = (size_t)nv * (size_t)nframes * 3;
    for (size_t i = 0; i < n; i++)
        if (!isfinite(frames[i]))
            return CR_FAIL(err, CR_ERR_NAN, "%s: frame %zu point %zu is not finite", path,
                           i / 3 / (size_t)nv, i / 3 % (size_t)nv);
    unsigned char head[PC2_HEADER];
    memcpy(head, pc2_magic, sizeof pc2_magic);
    io_put_le32(head + 12, 1);
    io_put_le32(head + 16, (uint32_t)nv);
    io_put_le32(head + 20, io_f32_bits(start_frame));
    io_put_le32(head + 24, io_f32_bits(sample_rate));
    io_put_le32(head + 28, (uint32_t)nframes);
    cr_atomic_file f;
    CR_TRY(cr_atomic_open(&f, path, err));
    if (fwrite(head, 1, sizeof head, f.fp) != sizeof head || !cr_io_write_f32le(f.fp, frames, n)) {
        cr_atomic_abort(&f);
        return CR_FAIL(err, CR_ERR_IO, "%s: write failed", path);
    }
    return cr_atomic_commit(&f, err);
}
