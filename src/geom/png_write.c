/* png_write.c: cr_image to an 8-bit RGB PNG file with libpng, written atomically.
 *
 * libpng reports errors by calling an error callback that must not return;
 * ours copies the message and longjmps back to cr_image_write_png, which
 * turns it into a cr_status and removes the temporary file. The image is
 * tagged sRGB (perceptual intent), which is what the renderer produces.
 *
 * Leaves out: reading (tests use libpng's simplified API directly), other
 * bit depths, alpha, metadata text chunks.
 * Reference: libpng manual, "Setjmp/longjmp issues" and "Writing".
 */
#include "crease/render.h"

#include <png.h>
#include <setjmp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct png_err_ctx {
    char msg[256];
} png_err_ctx;

static void on_png_error(png_structp png, png_const_charp msg) {
    png_err_ctx *ctx = png_get_error_ptr(png);
    snprintf(ctx->msg, sizeof ctx->msg, "%s", msg);
    png_longjmp(png, 1);
}

/* Warnings (e.g. about ancillary chunks) do not stop the write and are not
 * worth a log line for images we build ourselves. */
static void on_png_warning(png_structp png, png_const_charp msg) {
    (void)png, (void)msg;
}

cr_status cr_image_write_png(const cr_image *img, const char *path, cr_error *err) {
    if (!img || !img->rgb || img->width < 1 || img->height < 1)
        return CR_FAIL(err, CR_ERR_INVALID, "%s: empty image (%dx%d)", path ? path : "(null)",
                       img ? img->width : 0, img ? img->height : 0);
    if (!path || !path[0]) return CR_FAIL(err, CR_ERR_INVALID, "PNG path is empty");
    png_bytep *rows = cr_malloc((size_t)img->height * sizeof *rows, err);
    if (!rows) return err ? err->status : CR_ERR_MEMORY;
    for (int y = 0; y < img->height; y++)
        rows[y] = img->rgb + (size_t)y * img->width * 3;

    cr_atomic_file f;
    cr_status st = cr_atomic_open(&f, path, err);
    if (st != CR_OK) {
        free(rows);
        return st;
    }
    png_err_ctx ectx = {{0}};
    png_structp png =
        png_create_write_struct(PNG_LIBPNG_VER_STRING, &ectx, on_png_error, on_png_warning);
    png_infop info = png ? png_create_info_struct(png) : NULL;
    if (!png || !info) {
        png_destroy_write_struct(&png, &info);
        cr_atomic_abort(&f);
        free(rows);
        return CR_FAIL(err, CR_ERR_MEMORY, "%s: cannot start libpng", path);
    }
    /* Nothing set between here and a longjmp is read afterwards except
     * through `png`, `info`, `rows` and `f`, which are fixed before setjmp. */
    if (setjmp(png_jmpbuf(png))) {
        png_destroy_write_struct(&png, &info);
        cr_atomic_abort(&f);
        free(rows);
        return CR_FAIL(err, CR_ERR_IO, "%s: PNG write failed: %s", path, ectx.msg);
    }
    png_init_io(png, f.fp);
    png_set_IHDR(png, info, (png_uint_32)img->width, (png_uint_32)img->height, 8,
                 PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT,
                 PNG_FILTER_TYPE_DEFAULT);
    png_set_sRGB(png, info, PNG_sRGB_INTENT_PERCEPTUAL);
    png_write_info(png, info);
    png_write_image(png, rows);
    png_write_end(png, info);
    png_destroy_write_struct(&png, &info);
    free(rows);
    return cr_atomic_commit(&f, err);
}
