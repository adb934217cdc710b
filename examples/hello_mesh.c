/* hello_mesh.c: the smallest use of libcrease through its public headers:
 * make a torus, ask how far a point is from it, and render it to PNG.
 *
 *   example_hello_mesh [out.png]
 */
#include "crease/bvh.h"
#include "crease/primitives.h"
#include "crease/render.h"

#include <math.h>
#include <stdio.h>

int main(int argc, char **argv) {
    const char *out = argc > 1 ? argv[1] : "hello_mesh.png";
    cr_error err = {0};
    cr_mesh *torus = NULL;
    cr_bvh *bvh = NULL;
    if (cr_prim_torus(0.3f, 0.1f, 64, 32, &torus, &err) != CR_OK ||
        cr_bvh_build(torus->pos, torus->nv, torus->tri, torus->nf, &bvh, &err) != CR_OK) {
        fprintf(stderr, "hello_mesh: %s\n", err.msg);
        cr_mesh_destroy(torus);
        return 1;
    }
    const float centre[3] = {0, 0, 0}, on_ring[3] = {0.3f, 0, 0};
    float d_centre, d_ring;
    cr_bvh_signed_distance(bvh, centre, INFINITY, &d_centre, NULL, NULL);
    cr_bvh_signed_distance(bvh, on_ring, INFINITY, &d_ring, NULL, NULL);
    printf("signed distance from the centre: %.4f m (outside)\n", d_centre);
    printf("signed distance from the core of the ring: %.4f m (inside)\n", d_ring);

    cr_render_def def = cr_render_default_def();
    def.width = def.height = 512;
    cr_render_object obj = {.mesh = torus, .color = {0.33f, 0.52f, 0.80f}};
    int rc = 0;
    if (cr_render_to_png(&def, &obj, 1, out, &err) != CR_OK) {
        fprintf(stderr, "hello_mesh: %s\n", err.msg);
        rc = 1;
    } else {
        printf("wrote %s\n", out);
    }
    cr_bvh_destroy(bvh);
    cr_mesh_destroy(torus);
    return rc;
}
