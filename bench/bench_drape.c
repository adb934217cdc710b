/* bench_drape.c: the drape method's figures.
 *
 *   throughput  epochs/s and local structures/s of the default model
 *               (inr-adaptive and inr-uniform on the ball, 100 epochs)
 *   table2      the paper's Table 2: epochs and training time until the
 *               convergence criterion holds, inr-uniform vs inr-adaptive, on
 *               ball, torus and prism (paper: 14900/11950, 20500/17650,
 *               13950/8450 epochs)
 *   fidelity    each variant against a reference quasi-static drape of the
 *               same scene by the physics simulator (`crease drape-static`'s
 *               procedure: settle dynamically, then a static solve): Chamfer
 *               distance, deepest penetration, RMS mean curvature and its
 *               spectrum by wavelength, next to the reference's own
 *
 * References are read from REFS/<object><N>/final.obj (what `crease
 * drape-static --object sphere|torus|prism --res N [--coarse 128] -o
 * REFS/<object><N>` writes) and simulated and written there when missing.
 *
 * Usage: bench_drape [--only throughput|table2|fidelity] [--scenes ball,torus,prism]
 *                    [--cap N] [--samples N] [--fidelity-epochs N] [--refs DIR]
 *                    [--ref-res N] [--seed S] [--seeds N]
 * (defaults: all parts, cap 6000 epochs, 1024 samples, 2500 fidelity epochs,
 * refs drape_references, ref-res 256, seed 1, 1 seed; --seeds N runs Table 2
 * on seeds S .. S + N - 1 and reports means, spread and wins). The OpenBLAS kernel matters little
 * here (docs/drape.md); the figures name the one that ran.
 */
#include "crease/drape.h"
#include "crease/mesh_io.h"
#include "crease/scene.h"

#include "bench_stats.h"

#include <cblas.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { MAX_FRAMES = 150 };
static const char *const USAGE =
    "usage: bench_drape [--only throughput|table2|fidelity] [--scenes ball,torus,prism]\n"
    "                   [--cap N] [--samples N] [--fidelity-epochs N] [--refs DIR]\n"
    "                   [--ref-res N] [--seed S] [--seeds N]\n"
    "  throughput  epochs/s and structures/s of the default model on the ball\n"
    "  table2      epochs to convergence, uniform vs adaptive sampling (the paper's Table 2);\n"
    "              --seeds N: seeds S .. S + N - 1, with means, spread and wins\n"
    "  fidelity    each variant against the physics reference's quasi-static drape\n"
    "defaults: all parts, cap 6000, 1024 structures, 2500 fidelity epochs,\n"
    "refs drape_references, ref-res 256, seed 1, 1 seed\n";
#define COARSE_RES 128 /* vertices per side that settle dynamically */

typedef struct bench_opts {
    const char *only;
    const char *scenes;
    int cap, samples, fidelity_epochs, ref_res;
    const char *refs;
    uint64_t seed;
    int seeds; /* table2: seeds seed .. seed + seeds - 1 */
} bench_opts;

static const char *object_of(cr_drape_scene s) {
    return s == CR_DRAPE_BALL ? "sphere" : s == CR_DRAPE_TORUS ? "torus" : "prism";
}

static int wants(const bench_opts *o, const char *part) {
    return !o->only || strcmp(o->only, part) == 0;
}

static int scene_listed(const bench_opts *o, cr_drape_scene s) {
    return strstr(o->scenes, cr_drape_scene_name(s)) != NULL;
}

static void fail(const cr_error *err) {
    fprintf(stderr, "bench_drape: %s\n", err->msg);
    exit(1);
}

/* ------------------------------------------------------- throughput -- */

static void throughput(const bench_opts *o) {
    printf("== throughput (ball, default model, %d structures per epoch, %d threads)\n", o->samples,
           cr_thread_count());
    const cr_drape_variant vs[2] = {CR_DRAPE_INR_ADAPTIVE, CR_DRAPE_INR_UNIFORM};
    for (int k = 0; k < 2; k++) {
        cr_drape_def d = cr_drape_default_def(CR_DRAPE_BALL);
        d.variant = vs[k];
        d.samples = o->samples;
        d.epochs = 100;
        d.eval_every = 1000000; /* only the start and the end */
        d.quiet = 1;
        d.seed = o->seed;
        cr_drape_result r;
        cr_error err = {0};
        if (cr_drape_run(&d, &r, NULL, &err) != CR_OK) fail(&err);
        printf("%-13s %7.2f epochs/s  %9.0f structures/s  (%.2f s for %d epochs)\n",
               cr_drape_variant_name(vs[k]), r.epochs / r.seconds,
               (double)r.epochs * d.samples / r.seconds, r.seconds, r.epochs);
    }
}

/* ----------------------------------------------------------- table 2 -- */

/* One Table 2 run: the convergence epoch (-1: not within the cap). */
static int table2_run(const bench_opts *o, cr_drape_scene scene, cr_drape_variant v,
                      uint64_t seed, int paper) {
    cr_drape_def d = cr_drape_default_def(scene);
    d.variant = v;
    d.samples = o->samples;
    d.epochs = o->cap;
    d.stop_at_converged = 1;
    d.quiet = 1;
    d.seed = seed;
    cr_drape_result r;
    cr_error err = {0};
    if (cr_drape_run(&d, &r, NULL, &err) != CR_OK) fail(&err);
    char e[32], t[32];
    if (r.converged_epoch >= 0) {
        snprintf(e, sizeof e, "%d", r.converged_epoch);
        snprintf(t, sizeof t, "%.1f", r.converged_seconds);
    } else {
        snprintf(e, sizeof e, ">%d", r.epochs);
        snprintf(t, sizeof t, ">%.1f", r.seconds);
    }
    printf("%-6s %-13s %5llu %9s %9d %12s %12.4g\n", cr_drape_scene_name(scene),
           cr_drape_variant_name(v), (unsigned long long)seed, e, paper, t, r.terms.total);
    fflush(stdout);
    return r.converged_epoch;
}

/* Per scene, both variants on seeds seed .. seed + seeds - 1. One run's
 * convergence epoch moves by a thousand or more with the last bits of the
 * arithmetic (docs/drape.md, "Table 2, five seeds"), so with several seeds
 * the summary gives the means, their spread and in how many seeds adaptive
 * sampling converged first; runs that did not converge within the cap count
 * as the cap. */
static void table2(const bench_opts *o) {
    const cr_drape_scene scenes[3] = {CR_DRAPE_BALL, CR_DRAPE_TORUS, CR_DRAPE_PRISM};
    const int paper[3][2] = {{14900, 11950}, {20500, 17650}, {13950, 8450}};
    const cr_drape_variant vs[2] = {CR_DRAPE_INR_UNIFORM, CR_DRAPE_INR_ADAPTIVE};
    printf("== Table 2: epochs to convergence (cap %d, %d structures per epoch, %d seed%s)\n",
           o->cap, o->samples, o->seeds, o->seeds > 1 ? "s" : "");
    printf("%-6s %-13s %5s %9s %9s %12s %12s\n", "scene", "variant", "seed", "epochs", "paper",
           "seconds", "energy");
    for (int s = 0; s < 3; s++) {
        if (!scene_listed(o, scenes[s])) continue;
        double *ep = calloc(2 * (size_t)o->seeds, sizeof *ep);
        if (!ep) exit(1);
        int ahead = 0;
        for (int i = 0; i < o->seeds; i++) {
            for (int k = 0; k < 2; k++) {
                int e = table2_run(o, scenes[s], vs[k], o->seed + (uint64_t)i, paper[s][k]);
                ep[k * o->seeds + i] = e >= 0 ? e : o->cap;
            }
            ahead += ep[o->seeds + i] < ep[i];
        }
        double mu[2], sd[2];
        for (int k = 0; k < 2; k++)
            bench_mean_sd(ep + k * o->seeds, o->seeds, &mu[k], &sd[k]);
        const char *name = cr_drape_scene_name(scenes[s]);
        const double want = 100.0 * (paper[s][0] - paper[s][1]) / paper[s][0];
        if (o->seeds == 1)
            printf("%-6s adaptive needs %.0f%% fewer epochs (paper %.0f%%)\n", name,
                   100.0 * (mu[0] - mu[1]) / mu[0], want);
        else
            printf("%-6s mean uniform %.0f (sd %.0f), adaptive %.0f (sd %.0f): %.0f%% fewer "
                   "(paper %.0f%%), adaptive first in %d of %d seeds\n",
                   name, mu[0], sd[0], mu[1], sd[1], 100.0 * (mu[0] - mu[1]) / mu[0], want, ahead,
                   o->seeds);
        free(ep);
    }
}

/* ---------------------------------------------------------- fidelity -- */

/* drape-static's procedure: settle dynamically until the RMS speed is below
 * CR_SCENE_SETTLED_SPEED (at most MAX_FRAMES frames), then a static solve;
 * above COARSE_RES vertices per side, `crease drape-static --coarse
 * COARSE_RES`: the coarse cloth settles and the fine one solves statically
 * from its rest shape. */
static cr_status simulate_reference(const char *object, int res, const char *path, cr_error *err) {
    cr_mesh *obj = NULL, *cloth = NULL;
    cr_sim *sim = NULL;
    cr_sim_def def = cr_sim_default_def();
    cr_scene_settle_stats coarse = {0}, fine = {0};
    int refine = res > COARSE_RES;
    cr_status st = cr_material_preset("cotton", &def.material, err);
    if (st == CR_OK) st = cr_scene_object_create(object, &obj, err);
    def.collider = obj;
    if (st == CR_OK) st = cr_scene_cloth_above(obj, res, 1.0f, 0.05f, &cloth, err);
    if (st == CR_OK && refine)
        st = cr_scene_settle_coarse(&def, obj, COARSE_RES, 1.0f, 0.05f, MAX_FRAMES,
                                    CR_SCENE_SETTLED_SPEED, NULL, NULL, cloth, res, &coarse, err);
    if (st == CR_OK) st = cr_sim_create(&def, cloth, &sim, err);
    if (st == CR_OK)
        st = cr_scene_settle(sim, refine ? 0 : MAX_FRAMES, CR_SCENE_SETTLED_SPEED, NULL, NULL,
                             &fine, err);
    if (st == CR_OK) {
        if (refine)
            fprintf(stderr,
                    "bench_drape: %dx%d coarse stage: %d frames, %lld Newton iterations, "
                    "%.1f s\n",
                    COARSE_RES, COARSE_RES, coarse.settle_frames, coarse.newton, coarse.seconds);
        fprintf(stderr, "bench_drape: %dx%d reference: %d frames, %lld Newton iterations, %.1f s\n",
                res, res, fine.settle_frames, fine.newton, fine.seconds);
        cr_sim_positions_f(sim, cloth->pos);
        st = cr_mesh_write(path, cloth, err);
    }
    cr_sim_destroy(sim);
    cr_mesh_destroy(cloth);
    cr_mesh_destroy(obj);
    return st;
}

static void print_fidelity(const char *name, const cr_drape_fidelity *f) {
    /* The reference has no Chamfer distance to itself (NaN). */
    if (isnan(f->chamfer_m))
        printf("%-13s %10s", name, "-");
    else
        printf("%-13s %10.2f", name, 1e3 * f->chamfer_m);
    printf(" %9.3f %8.2f", 1e3 * f->max_penetration_m, f->h_rms);
    for (int b = 0; b < CR_DRAPE_H_BANDS; b++)
        printf(" %7.3f", f->h_band[b]);
    printf("\n");
}

static void fidelity(const bench_opts *o) {
    const cr_drape_scene scenes[3] = {CR_DRAPE_BALL, CR_DRAPE_TORUS, CR_DRAPE_PRISM};
    printf("== fidelity against the reference drape (%d epochs each, reference %dx%d)\n",
           o->fidelity_epochs, o->ref_res, o->ref_res);
    for (int s = 0; s < 3; s++) {
        if (!scene_listed(o, scenes[s])) continue;
        char dir[1024], path[1200];
        snprintf(dir, sizeof dir, "%s/%s%d", o->refs, object_of(scenes[s]), o->ref_res);
        snprintf(path, sizeof path, "%s/final.obj", dir);
        cr_error err = {0};
        cr_mesh *ref = NULL, *object = NULL;
        if (cr_mesh_read(path, &ref, &err) != CR_OK) {
            fprintf(stderr, "bench_drape: simulating the %s reference (%dx%d) into %s\n",
                    object_of(scenes[s]), o->ref_res, o->ref_res, path);
            if (cr_mkdir_p(dir, &err) != CR_OK) fail(&err);
            if (simulate_reference(object_of(scenes[s]), o->ref_res, path, &err) != CR_OK)
                fail(&err);
            if (cr_mesh_read(path, &ref, &err) != CR_OK) fail(&err);
        }
        if (cr_drape_scene_object(scenes[s], NULL, &object, &err) != CR_OK) fail(&err);
        printf("-- %s (reference %s)\n", cr_drape_scene_name(scenes[s]), path);
        printf("%-13s %10s %9s %8s", "surface", "chamfer_mm", "pen_mm", "H_rms");
        for (int b = 0; b < CR_DRAPE_H_BANDS; b++) {
            char band[32];
            if (b == 0)
                snprintf(band, sizeof band, ">%.0fcm", 100 * cr_eval_h_band_edges_m[1]);
            else
                snprintf(band, sizeof band, "%.0f-%.0fcm", 100 * cr_eval_h_band_edges_m[b + 1],
                         100 * cr_eval_h_band_edges_m[b]);
            printf(" %7s", band);
        }
        printf("\n");
        cr_drape_fidelity f;
        if (cr_drape_fidelity_measure(ref, NULL, object, &f, &err) != CR_OK) fail(&err);
        print_fidelity("reference", &f);
        for (int v = 0; v < CR_DRAPE_VARIANT_COUNT; v++) {
            cr_drape_def d = cr_drape_default_def(scenes[s]);
            d.variant = (cr_drape_variant)v;
            d.samples = o->samples;
            d.epochs = o->fidelity_epochs;
            d.stop_at_converged = 0; /* equal epochs for every variant */
            d.quiet = 1;
            d.seed = o->seed;
            cr_drape_result r;
            cr_mesh *surface = NULL;
            if (cr_drape_run(&d, &r, &surface, &err) != CR_OK) fail(&err);
            if (cr_drape_fidelity_measure(surface, ref, object, &f, &err) != CR_OK) fail(&err);
            print_fidelity(cr_drape_variant_name(d.variant), &f);
            fflush(stdout);
            cr_mesh_destroy(surface);
        }
        cr_mesh_destroy(ref);
        cr_mesh_destroy(object);
    }
}

int main(int argc, char **argv) {
    cr_parallel_choose_wait_policy(argv);
    bench_opts o = {.scenes = "ball,torus,prism",
                    .cap = 6000,
                    .samples = 1024,
                    .fidelity_epochs = 2500,
                    .ref_res = 256,
                    .refs = "drape_references",
                    .seed = 1,
                    .seeds = 1};
    for (int i = 1; i < argc; i += 2) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) {
            printf("%s", USAGE);
            return 0;
        }
        if (!v) {
            fprintf(stderr, "bench_drape: %s needs a value\n", a);
            return 2;
        }
        if (strcmp(a, "--only") == 0)
            o.only = v;
        else if (strcmp(a, "--scenes") == 0)
            o.scenes = v;
        else if (strcmp(a, "--cap") == 0)
            o.cap = atoi(v);
        else if (strcmp(a, "--samples") == 0)
            o.samples = atoi(v);
        else if (strcmp(a, "--fidelity-epochs") == 0)
            o.fidelity_epochs = atoi(v);
        else if (strcmp(a, "--refs") == 0)
            o.refs = v;
        else if (strcmp(a, "--ref-res") == 0)
            o.ref_res = atoi(v);
        else if (strcmp(a, "--seed") == 0)
            o.seed = (uint64_t)atoll(v);
        else if (strcmp(a, "--seeds") == 0)
            o.seeds = atoi(v);
        else {
            fprintf(stderr, "bench_drape: unknown option %s\n", a);
            return 2;
        }
    }
    if (o.cap < 1 || o.samples < 1 || o.fidelity_epochs < 1 || o.ref_res < 2 || o.seeds < 1 ||
        o.seeds > 1000) {
        fprintf(stderr, "bench_drape: counts must be positive\n");
        return 2;
    }
    printf("threads %d, OpenBLAS core type %s\n", cr_thread_count(), openblas_get_corename());
    if (wants(&o, "throughput")) throughput(&o);
    if (wants(&o, "table2")) table2(&o);
    if (wants(&o, "fidelity")) fidelity(&o);
    return 0;
}
