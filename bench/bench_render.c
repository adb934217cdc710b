/* bench_render.c: software rasteriser throughput on a ~100k-triangle torus at 1024x1024.
 *
 * Times cr_render_scene (normals, projection, binning, scan, shading, filter;
 * no PNG) with supersampling 1 and 2, wireframe off and on, and, when a path
 * is given, one PNG write. Prints the median of a few frames after a warm-up.
 *
 *   bench_render [sample.png]   also writes the ss=2 wireframe frame there
 */
#include "crease/primitives.h"
#include "crease/render.h"

#include <stdio.h>
#include <stdlib.h>

enum { FRAMES = 7 };

static int by_value(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

int main(int argc, char **argv) {
    cr_error err = {0};
    cr_mesh *torus = NULL;
    /* 500 x 100 quads, two triangles each: 100,000 triangles. */
    if (cr_prim_torus(1.0f, 0.35f, 500, 100, &torus, &err) != CR_OK) {
        fprintf(stderr, "bench_render: %s\n", err.msg);
        return 1;
    }
    cr_render_object obj = {.mesh = torus, .color = {0.85f, 0.45f, 0.25f}};
    printf("render bench: %d triangles, %d threads\n", torus->nf, cr_thread_count());
    for (int ss = 1; ss <= 2; ss++)
        for (int wire = 0; wire <= 1; wire++) {
            cr_render_def def = cr_render_default_def();
            def.supersample = ss;
            def.wireframe = wire;
            double ms[FRAMES];
            cr_image img = {0};
            for (int k = -1; k < FRAMES; k++) {
                cr_image_free(&img);
                double t0 = cr_time_now();
                if (cr_render_scene(&def, &obj, 1, &img, &err) != CR_OK) {
                    fprintf(stderr, "bench_render: %s\n", err.msg);
                    return 1;
                }
                if (k >= 0) ms[k] = 1e3 * (cr_time_now() - t0);
            }
            qsort(ms, FRAMES, sizeof ms[0], by_value);
            printf("render %d tris %dx%d ss=%d%s: %.1f ms (median of %d, min %.1f)\n", torus->nf,
                   def.width, def.height, ss, wire ? " wireframe" : "", ms[FRAMES / 2], FRAMES,
                   ms[0]);
            if (ss == 2 && wire && argc > 1) {
                const char *path = argv[1];
                double t0 = cr_time_now();
                if (cr_image_write_png(&img, path, &err) != CR_OK) {
                    fprintf(stderr, "bench_render: %s\n", err.msg);
                    return 1;
                }
                printf("png write %dx%d: %.1f ms (%s)\n", img.width, img.height,
                       1e3 * (cr_time_now() - t0), path);
            }
            cr_image_free(&img);
        }
    cr_mesh_destroy(torus);
    return 0;
}
