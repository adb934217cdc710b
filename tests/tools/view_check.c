/* view_check.c: the helper of tests/view.sh and scripts/bench_view.sh.
 *
 *   view_check stats A.png X0 Y0 X1 Y1     share of pixels in the box that differ
 *                                           from the box's most common colour
 *   view_check diff A.png B.png X0 Y0 X1 Y1  share of pixels in the box that differ
 *   view_check npy OUT.npy T V             a float32 (T,V) array: (t + 1) * v / (T V)
 *   view_check dist A.pc2 B.pc2 OUT.npy    float32 (T,V) distance between the two, m
 *   view_check wave OUT.pc2 N T            a PC2 of an N x N cloth of 1 m at y = 1.2
 *                                           waving for T frames (the rest mesh is
 *                                           `crease primitive plane --res N-1`'s grid)
 *
 * Prints one number (stats, diff); exit 1 on a bad file. Not part of the library. */
#include "crease/mesh_io.h"
#include "crease/npz.h"

#include <math.h>
#include <png.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static unsigned char *load(const char *path, int *w, int *h) {
    png_image img;
    memset(&img, 0, sizeof img);
    img.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_file(&img, path)) {
        fprintf(stderr, "view_check: %s: %s\n", path, img.message);
        return NULL;
    }
    img.format = PNG_FORMAT_RGBA;
    unsigned char *px = malloc(PNG_IMAGE_SIZE(img));
    if (!px || !png_image_finish_read(&img, NULL, px, 0, NULL)) {
        fprintf(stderr, "view_check: %s: %s\n", path, img.message);
        free(px);
        return NULL;
    }
    *w = (int)img.width;
    *h = (int)img.height;
    return px;
}

static void clip(int w, int h, int *b) {
    b[0] = b[0] < 0 ? 0 : b[0];
    b[1] = b[1] < 0 ? 0 : b[1];
    b[2] = b[2] > w ? w : b[2];
    b[3] = b[3] > h ? h : b[3];
}

int main(int argc, char **argv) {
    if (argc == 7 && strcmp(argv[1], "stats") == 0) {
        int w, h, b[4];
        unsigned char *a = load(argv[2], &w, &h);
        if (!a) return 1;
        for (int k = 0; k < 4; k++)
            b[k] = atoi(argv[3 + k]);
        clip(w, h, b);
        /* The background: the most common of the first row's colours, good enough for a
         * flat-coloured page; count pixels that differ from it. */
        uint32_t bg = 0;
        int best = -1;
        for (int x = b[0]; x < b[2]; x += 7) {
            uint32_t c;
            memcpy(&c, a + 4 * ((size_t)b[1] * w + x), 4);
            int n = 0;
            for (int x2 = b[0]; x2 < b[2]; x2++)
                n += memcmp(&c, a + 4 * ((size_t)b[1] * w + x2), 4) == 0;
            if (n > best) best = n, bg = c;
        }
        long diff = 0, all = 0;
        for (int y = b[1]; y < b[3]; y++)
            for (int x = b[0]; x < b[2]; x++, all++)
                diff += memcmp(&bg, a + 4 * ((size_t)y * w + x), 4) != 0;
        printf("%.6f\n", all ? (double)diff / (double)all : 0.0);
        free(a);
        return 0;
    }
    if (argc == 8 && strcmp(argv[1], "diff") == 0) {
        int w, h, w2, h2, b[4];
        unsigned char *a = load(argv[2], &w, &h), *c = load(argv[3], &w2, &h2);
        if (!a || !c || w != w2 || h != h2) return 1;
        for (int k = 0; k < 4; k++)
            b[k] = atoi(argv[4 + k]);
        clip(w, h, b);
        long diff = 0, all = 0;
        for (int y = b[1]; y < b[3]; y++)
            for (int x = b[0]; x < b[2]; x++, all++) {
                size_t i = 4 * ((size_t)y * w + x);
                diff += memcmp(a + i, c + i, 4) != 0;
            }
        printf("%.6f\n", all ? (double)diff / (double)all : 0.0);
        free(a);
        free(c);
        return 0;
    }
    if (argc == 5 && strcmp(argv[1], "npy") == 0) {
        int64_t shape[2] = {atoi(argv[3]), atoi(argv[4])};
        float *v = malloc((size_t)(shape[0] * shape[1]) * sizeof(float));
        if (!v) return 1;
        for (int64_t t = 0; t < shape[0]; t++)
            for (int64_t i = 0; i < shape[1]; i++)
                v[t * shape[1] + i] = (float)((t + 1) * i) / (float)(shape[0] * shape[1]);
        cr_error err = {0};
        cr_status st = cr_npy_write(argv[2], CR_NPY_F32, 2, shape, v, &err);
        free(v);
        if (st != CR_OK) fprintf(stderr, "view_check: %s\n", err.msg);
        return st != CR_OK;
    }
    if (argc == 5 && strcmp(argv[1], "dist") == 0) {
        cr_pc2 a = {0}, b = {0};
        cr_error err = {0};
        cr_status st = cr_pc2_read(argv[2], &a, &err);
        if (st == CR_OK) st = cr_pc2_read(argv[3], &b, &err);
        if (st == CR_OK && (a.nv != b.nv || a.nframes != b.nframes))
            st = CR_FAIL(&err, CR_ERR_SHAPE, "%s and %s differ in shape", argv[2], argv[3]);
        float *d = st == CR_OK ? malloc((size_t)a.nframes * a.nv * sizeof(float)) : NULL;
        if (st == CR_OK && !d) st = CR_ERR_MEMORY;
        for (int64_t i = 0; st == CR_OK && i < (int64_t)a.nframes * a.nv; i++) {
            double s2 = 0;
            for (int k = 0; k < 3; k++) {
                double x = (double)a.frames[3 * i + k] - (double)b.frames[3 * i + k];
                s2 += x * x;
            }
            d[i] = (float)sqrt(s2);
        }
        int64_t shape[2] = {a.nframes, a.nv};
        if (st == CR_OK) st = cr_npy_write(argv[4], CR_NPY_F32, 2, shape, d, &err);
        if (st != CR_OK) fprintf(stderr, "view_check: %s\n", err.msg);
        free(d);
        cr_pc2_free(&a);
        cr_pc2_free(&b);
        return st != CR_OK;
    }
    if (argc == 5 && strcmp(argv[1], "wave") == 0) {
        int n = atoi(argv[3]), nt = atoi(argv[4]);
        if (n < 2 || nt < 1) return 1;
        float *f = malloc((size_t)nt * n * n * 3 * sizeof(float));
        if (!f) return 1;
        for (int t = 0; t < nt; t++)
            for (int j = 0; j < n; j++)
                for (int i = 0; i < n; i++) {
                    float x = -0.5f + (float)i / (float)(n - 1),
                          z = -0.5f + (float)j / (float)(n - 1);
                    float *p = f + 3 * ((size_t)t * n * n + (size_t)j * n + i);
                    p[0] = x;
                    p[1] = 1.2f + 0.05f * sinf(12.0f * x + 0.2f * (float)t) * cosf(9.0f * z);
                    p[2] = z;
                }
        cr_error err = {0};
        cr_status st = cr_pc2_write(argv[2], f, n * n, nt, 0.0f, 1.0f, &err);
        free(f);
        if (st != CR_OK) fprintf(stderr, "view_check: %s\n", err.msg);
        return st != CR_OK;
    }
    fprintf(stderr, "usage: view_check stats|diff|npy|wave ... (see the file's header)\n");
    return 2;
}
