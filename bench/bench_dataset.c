/* bench_dataset.c: time to generate the default small dataset with
 * `crease dataset`'s defaults: a t-shirt and a skirt (2,000 vertices, the low
 * resolution), on the normal mannequin, through the walk and dance clips,
 * 150 frames each: 4 sequences, 600 simulated frames. Prints the wall time
 * (assets included: bodies, posed sequences, garments) and the wall time per
 * simulated frame (sequences run in parallel, so below one sequence's own
 * seconds per frame).
 *
 * Usage: bench_dataset [OUT_DIR] (default: a new folder under /tmp, kept)
 */
#include "crease/dataset.h"

#include <stdio.h>
#include <stdlib.h>

int main(int argc, char **argv) {
    char tmpl[] = "/tmp/bench_dataset_XXXXXX";
    const char *out = argc > 1 ? argv[1] : mkdtemp(tmpl);
    if (!out) {
        perror("bench_dataset: mkdtemp");
        return 1;
    }
    static const char *const garments[] = {"tshirt", "skirt"};
    static const char *const motions[] = {"walk", "dance"};
    static const char *const bodies[] = {"normal"};
    static const char *const res[] = {"low"};
    cr_dataset_def d = cr_dataset_default_def();
    d.out_dir = out;
    d.garments = garments, d.ngarments = 2;
    d.motions = motions, d.nmotions = 2;
    d.bodies = bodies, d.nbodies = 1;
    d.res = res, d.nres = 1;
    d.quiet = 1;
    cr_dataset_result r;
    cr_error err = {0};
    if (cr_dataset_generate(&d, &r, &err) != CR_OK) {
        fprintf(stderr, "bench_dataset: %s\n", err.msg);
        return 1;
    }
    int64_t frames = (int64_t)r.done * d.frames;
    printf("default small dataset: %d sequences (tshirt, skirt x walk, dance; normal body; %d "
           "vertices; %d frames each) into %s, %d threads\n",
           r.sequences, d.low_vertices, d.frames, out, cr_thread_count());
    printf("%d simulated, %d already there, %d failed: %.1f s in all, %.3f s per simulated "
           "frame of wall time\n",
           r.done, r.skipped, r.failed, r.seconds, frames > 0 ? r.seconds / frames : 0.0);
    for (int g = 0; g < r.ngarments; g++)
        printf("  %-7s most vertices inside the body on a stored frame %.3f%%, in a substep "
               "before projection %.3f%%\n",
               garments[g], 100.0 * r.max_inside_share[g], 100.0 * r.max_inside_share_solver[g]);
    return r.failed ? 1 : 0;
}
