/* bench_sim.c: seconds per frame of the reference simulator at 30 fps with
 * the default substeps, and where the time goes (assembly, factorisation,
 * triangular solves, collision queries).
 *
 * Scenes:
 *   sphere  a 1 m cotton square of 128 x 128 vertices dropped from 4 cm above
 *           a sphere of radius 0.3 m (96 x 48 UV sphere);
 *   tube    an open cylinder of cotton (radius 0.15 m, height 0.6 m: a
 *           sleeve or skirt) of about 5k, 10k and 40k vertices, its top ring
 *           pinned, with a capsule (radius 0.08 m, length 0.4 m) inside it
 *           swinging about the top like a leg (0.15 rad at 0.8 Hz) and
 *           pushing the cloth around;
 *   tall    a 25 x 100 cm cotton strip of 50 x 200 vertices stood on its lower
 *           edge 1 cm above the ground (a 4 x 4 m box) and tipped 0.2 rad: it
 *           falls and piles onto itself (the self-contact scene); tall2k5 the
 *           same strip at 25 x 100 vertices (1 cm edges: mesh neighbours
 *           within the self-contact query radius at rest).
 * The first frames of a scene include its setup transient; the split is
 * summed over the frames finished (cr_scene_run, the loop `crease simulate`
 * and the datasets use). Threads: all, or the second argument.
 *
 * Usage: bench_sim [scene] [threads] [frames] [--solver newton|vbd|compare]
 *                  [--vbd-iterations N] [--vbd-collision-scale S] [--vbd-tolerance T]
 *                  [--vbd-coarse N] [--vbd-coarse-refresh K] [--reference FILE]
 *                  [--self-contact on|off]
 *   scene: all (default), sphere, tube5k, tube10k, tube40k, tall, tall2k5 (the
 *   tall ones not in all)
 *   frames: 30 by default (10 for tube40k)
 *   --solver: newton (default) or vbd times that solver; compare runs a
 *   converged Newton reference (newton_tol 1e-5 m/s, no relative
 *   tolerance, 40 iterations), the same from a start moved by 10 um (the
 *   scene's sensitivity), Newton at its default cap of 8, VBD at its
 *   defaults and VBD with the coarse correction, and prints each one's mean
 *   and largest vertex distance to the reference after the last frame.
 *   --vbd-iterations N: the VBD runs' sweeps per substep (default the
 *   simulator's, 30); --vbd-collision-scale S: their collider penalty's
 *   factor (default 10; 1 is the material's, Newton's); --vbd-tolerance T:
 *   their stopping tolerance, cr_sim_def.vbd_tol, m/s (a sweep moving no
 *   vertex further than T h stops the substep; default newton_tol's 1e-3).
 *   --vbd-coarse N, --vbd-coarse-refresh K: compare's corrected VBD run
 *   (default every 2 sweeps, the factor reused for 3 corrections).
 *   --reference FILE: compare reads its converged reference from FILE when
 *   it is there, else writes it there, and skips the 10 um run; keep one
 *   file per scene and frame count.
 *   --self-contact on|off: cloth self-contact (default off); the split then
 *   shows its detection (pairs, BVH refits, the assembly rebuilt for them).
 * `bench_sim tube10k 2 1500` is the stability run (1,500 frames).
 */
#include "crease/bvh.h"
#include "crease/primitives.h"
#include "crease/scene.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Long runs (the 1,500-frame tube) show progress every 100 frames. */
static cr_status progress(void *ctx, const cr_sim *sim, const cr_sim_report *rep,
                          const cr_scene_run_stats *st, cr_error *err) {
    (void)sim, (void)rep, (void)err;
    if (st->frames % 100 == 0) {
        printf("sim %s: frame %d, %.3f s/frame so far, max penetration %.2f mm\n",
               (const char *)ctx, st->frames, st->seconds / st->frames,
               1e3 * st->max_penetration_m);
        fflush(stdout);
    }
    return CR_OK;
}

static int solver_mode = 0;  /* 0 newton, 1 vbd, 2 compare */
static int self_contact = 0; /* --self-contact on */
static int vbd_sweeps = 0;   /* --vbd-iterations N; 0: the simulator's default */
static double vbd_collision_scale = 0; /* --vbd-collision-scale S; 0: the default */
static double vbd_tol = 0;             /* --vbd-tolerance T (m/s); 0: the default */
static const char *reference_cache = NULL; /* --reference FILE: compare's reference */
static int coarse_every = 2, coarse_refresh = 3; /* compare's VBD + coarse run */

/* After a run: its final positions (V,3), for compare; owned here. */
static double *last_positions = NULL;

static int run(const char *name, const cr_mesh *garment, const cr_sim_def *def, int frames) {
    cr_error err = {0};
    cr_sim *s = NULL;
    double t0 = cr_time_now();
    if (cr_sim_create(def, garment, &s, &err) != CR_OK) {
        fprintf(stderr, "bench_sim: %s: %s\n", name, err.msg);
        return 1;
    }
    double setup = cr_time_now() - t0;
    cr_scene_run_stats st;
    cr_status status = cr_scene_run(s, frames, NULL, progress, (void *)name, &st, &err);
    int stopped = status != CR_OK;
    if (stopped) printf("sim %s: stopped at frame %d: %s\n", name, st.frames, err.msg);
    double n = st.frames > 0 ? (double)st.frames : 1.0, tot = st.seconds > 0 ? st.seconds : 1;
    printf("sim %s V=%d solver %s: %.3f s/frame over %d frames (setup %.2f s)\n", name, garment->nv,
           cr_sim_solver_name(def->solver), st.seconds / n, st.frames, setup);
    printf("sim %s split: assembly %.0f%%, factorisation %.0f%%, solves %.0f%%, collision "
           "%.0f%%, self-contact %.0f%%, other %.0f%%\n",
           name, 100 * st.seconds_assembly / tot, 100 * st.seconds_factor / tot,
           100 * st.seconds_solve / tot, 100 * st.seconds_collision / tot,
           100 * st.seconds_self_contact / tot,
           100 *
               (tot - st.seconds_assembly - st.seconds_factor - st.seconds_solve -
                st.seconds_collision - st.seconds_self_contact) /
               tot);
    if (def->self_contact)
        printf("sim %s self-contact: %.3f s/frame detecting, %.1f detections and %.0f pairs per "
               "frame\n",
               name, st.seconds_self_contact / n, st.self_contact_detections / n,
               st.self_contact_pairs / n);
    printf("sim %s per frame: %.1f Newton iterations, %.1f factorisations, %.0f VBD vertex "
           "re-queries; %lld capped substeps, %lld VBD retries, %lld backoffs, max penetration "
           "before projection %.2f mm, %s\n",
           name, st.newton_iterations / n, st.factorisations / n, st.vbd_requeries / n,
           st.newton_capped, st.vbd_retries,
           st.backoffs, 1e3 * st.max_penetration_m, stopped ? "DIVERGED" : "no divergence");
    fflush(stdout);
    free(last_positions);
    last_positions = malloc(sizeof(double) * 3 * (size_t)garment->nv);
    if (last_positions)
        memcpy(last_positions, cr_sim_positions(s), sizeof(double) * 3 * (size_t)garment->nv);
    cr_sim_destroy(s);
    return stopped;
}

/* The command line's VBD options, on a def whose solver is VBD. */
static void vbd_options(cr_sim_def *d) {
    if (d->solver != CR_SIM_SOLVER_VBD) return;
    if (vbd_sweeps > 0) d->vbd_iterations = vbd_sweeps;
    if (vbd_collision_scale > 0) d->vbd_collision_scale = vbd_collision_scale;
    if (vbd_tol > 0) d->vbd_tol = vbd_tol;
}

/* compare's reference positions from --reference's file, when it holds nv
 * vertices (*cached set), else NULL. The file is raw doubles: the caller
 * keeps it to one scene, thread count and frame count. */
static double *load_reference(int32_t nv, int *cached) {
    *cached = 0;
    FILE *f = fopen(reference_cache, "rb");
    if (!f) return NULL;
    double *ref = malloc(sizeof(double) * 3 * (size_t)nv);
    if (ref && fread(ref, sizeof(double), 3 * (size_t)nv, f) == 3 * (size_t)nv &&
        fgetc(f) == EOF) {
        *cached = 1;
        printf("bench_sim: the converged reference read from %s\n", reference_cache);
    } else {
        fprintf(stderr, "bench_sim: %s is not a reference of %d vertices; computing it\n",
                reference_cache, nv);
        free(ref);
        ref = NULL;
    }
    fclose(f);
    return ref;
}

static void save_reference(const double *ref, int32_t nv) {
    cr_error err = {0};
    cr_atomic_file f;
    if (cr_atomic_open(&f, reference_cache, &err) != CR_OK) {
        fprintf(stderr, "bench_sim: %s\n", err.msg);
        return;
    }
    if (fwrite(ref, sizeof(double), 3 * (size_t)nv, f.fp) != 3 * (size_t)nv) {
        fprintf(stderr, "bench_sim: could not write %s\n", reference_cache);
        cr_atomic_abort(&f);
        return;
    }
    if (cr_atomic_commit(&f, &err) != CR_OK) fprintf(stderr, "bench_sim: %s\n", err.msg);
}

/* compare's converged reference: tolerance 1e-5 m/s, no relative one, 40
 * iterations. */
static void converge(cr_sim_def *d) {
    d->solver = CR_SIM_SOLVER_NEWTON;
    d->newton_tol = 1e-5, d->newton_rtol = 0.0, d->newton_max_iterations = 40;
}

/* Mean and largest distance of pos, less a translation shift, from ref (V,3
 * each). */
static void distance(const double *pos, const double *ref, int32_t nv, const double shift[3],
                     double *mean, double *worst) {
    *mean = 0.0, *worst = 0.0;
    for (int64_t i = 0; i < 3 * (int64_t)nv; i += 3) {
        double dx = pos[i] - shift[0] - ref[i], dy = pos[i + 1] - shift[1] - ref[i + 1],
               dz = pos[i + 2] - shift[2] - ref[i + 2];
        double r = sqrt(dx * dx + dy * dy + dz * dz);
        *mean += r / nv;
        *worst = fmax(*worst, r);
    }
}

/* One scene with the chosen solver, or compare's runs: the converged
 * reference, then each variant's distance to it after the last frame. The
 * first variant is the reference again from a start moved 10 um along x:
 * where the scene amplifies small differences (cloth dropped centred on a
 * sphere chooses a side to slide to), that distance is the floor below
 * which no solver's distance says anything. */
static int run_mode(const char *name, const cr_mesh *garment, const cr_sim_def *base, int frames) {
    cr_sim_def d = *base;
    d.self_contact = self_contact;
    if (solver_mode < 2) {
        d.solver = solver_mode == 1 ? CR_SIM_SOLVER_VBD : CR_SIM_SOLVER_NEWTON;
        vbd_options(&d);
        return run(name, garment, &d, frames);
    }
    int rc = 0, cached = 0;
    double *ref = reference_cache ? load_reference(garment->nv, &cached) : NULL;
    if (!cached) {
        converge(&d);
        rc = run(name, garment, &d, frames);
        ref = last_positions;
        last_positions = NULL;
        if (!ref) return 1;
        if (reference_cache) save_reference(ref, garment->nv);
    }
    /* The floor's start, only when the floor runs (not with --reference). */
    const double nudge = 1e-5;
    cr_error err = {0};
    cr_mesh *moved = NULL;
    if (!reference_cache) {
        if (cr_mesh_clone(garment, &moved, &err) != CR_OK) {
            fprintf(stderr, "bench_sim: %s: %s\n", name, err.msg);
            free(ref);
            return 1;
        }
        for (int32_t v = 0; v < moved->nv; v++)
            moved->pos[3 * v] += (float)nudge;
    }
    char coarse_name[64];
    snprintf(coarse_name, sizeof coarse_name, "vbd with coarse every %d, refresh %d,",
             coarse_every, coarse_refresh);
    const char *variant[] = {"newton (converged, start moved 10 um)", "newton (capped at 8)",
                             "vbd", coarse_name};
    for (int k = moved ? 0 : 1; k < 4; k++) {
        d = *base;
        d.self_contact = self_contact;
        double shift[3] = {0, 0, 0};
        d.solver = k < 2 ? CR_SIM_SOLVER_NEWTON : CR_SIM_SOLVER_VBD;
        if (k == 0) converge(&d), shift[0] = nudge;
        if (k == 3) d.vbd_coarse_every = coarse_every, d.vbd_coarse_refresh = coarse_refresh;
        vbd_options(&d);
        rc |= run(name, k == 0 ? moved : garment, &d, frames);
        if (!last_positions) continue;
        double mean, worst;
        distance(last_positions, ref, garment->nv, shift, &mean, &worst);
        char sweeps[32] = "";
        if (k >= 2) snprintf(sweeps, sizeof sweeps, " (%d sweeps)", d.vbd_iterations);
        printf("sim %s accuracy %s%s after %d frames: mean %.2f mm, largest %.2f mm from "
               "converged Newton\n",
               name, variant[k], sweeps, frames, 1e3 * mean, 1e3 * worst);
    }
    cr_mesh_destroy(moved);
    free(ref);
    return rc;
}

static int bench_sphere(int frames) {
    cr_error err = {0};
    cr_mesh *cloth = NULL, *sphere = NULL;
    if (cr_prim_plane(128, 128, 1.0f, 1.0f, &cloth, &err) != CR_OK ||
        cr_prim_sphere_uv(0.3f, 96, 48, &sphere, &err) != CR_OK) {
        fprintf(stderr, "bench_sim: %s\n", err.msg);
        return 1;
    }
    for (int32_t v = 0; v < cloth->nv; v++)
        cloth->pos[3 * v + 1] = 0.34f;
    cr_sim_def d = cr_sim_default_def();
    cr_material_preset("cotton", &d.material, &err);
    d.collider = sphere;
    int rc = run_mode("sphere128", cloth, &d, frames);
    cr_mesh_destroy(cloth);
    cr_mesh_destroy(sphere);
    return rc;
}

/* The capsule's positions per frame: rotated about the z axis through the
 * pivot (the tube's top centre) by 0.15 sin(2 pi 0.8 t). */
static float *swing_frames(const cr_mesh *cap, float pivot_y, int frames) {
    float *seq = malloc(sizeof(float) * 3 * (size_t)cap->nv * (size_t)frames);
    if (!seq) return NULL;
    for (int f = 0; f < frames; f++) {
        double a = 0.15 * sin(2.0 * M_PI * 0.8 * f / 30.0), c = cos(a), s = sin(a);
        for (int32_t v = 0; v < cap->nv; v++) {
            const float *p = cap->pos + 3 * v;
            float *q = seq + 3 * ((size_t)cap->nv * f + v);
            double x = p[0], y = p[1] - pivot_y;
            q[0] = (float)(c * x - s * y);
            q[1] = (float)(s * x + c * y + pivot_y);
            q[2] = p[2];
        }
    }
    return seq;
}

static int bench_tube(const char *name, int segments, int rings, int frames) {
    cr_error err = {0};
    cr_mesh *tube = NULL, *cap = NULL;
    const float height = 0.6f;
    if (cr_prim_cylinder(0.15f, height, segments, rings, 0, &tube, &err) != CR_OK ||
        cr_prim_capsule(0.08f, 0.4f, 32, 8, &cap, &err) != CR_OK) {
        fprintf(stderr, "bench_sim: %s\n", err.msg);
        return 1;
    }
    /* Capsule hanging from the pivot at the tube's top: its top at 5 cm below. */
    float top = 0.5f * height, cap_half = 0.2f + 0.08f;
    for (int32_t v = 0; v < cap->nv; v++)
        cap->pos[3 * v + 1] += top - 0.05f - cap_half;
    float *seq = swing_frames(cap, top, frames);
    int32_t *pins = malloc(sizeof(int32_t) * (size_t)tube->nv);
    int32_t npins = 0;
    for (int32_t v = 0; v < tube->nv; v++)
        if (tube->pos[3 * v + 1] > top - 1e-4f) pins[npins++] = v;
    cr_sim_def d = cr_sim_default_def();
    cr_material_preset("cotton", &d.material, &err);
    d.pinned = pins, d.npinned = npins;
    d.collider = cap, d.collider_frames = seq, d.collider_nframes = frames;
    int rc = seq ? run_mode(name, tube, &d, frames) : 1;
    free(seq);
    free(pins);
    cr_mesh_destroy(tube);
    cr_mesh_destroy(cap);
    return rc;
}

static int bench_tall(const char *name, int32_t nx, int32_t ny, int frames) {
    cr_error err = {0};
    cr_mesh *cloth = NULL, *ground = NULL;
    if (cr_prim_plane(nx, ny, 0.25f, 1.0f, &cloth, &err) != CR_OK ||
        cr_prim_box(4.0f, 0.2f, 4.0f, 2, &ground, &err) != CR_OK) {
        fprintf(stderr, "bench_sim: %s\n", err.msg);
        return 1;
    }
    for (int32_t v = 0; v < ground->nv; v++)
        ground->pos[3 * v + 1] -= 0.1f; /* its top at y = 0 */
    for (int32_t v = 0; v < cloth->nv; v++) {
        float *p = cloth->pos + 3 * v, h = p[2] + 0.5f;
        p[1] = 0.01f + h * cosf(0.2f);
        p[2] = h * sinf(0.2f);
    }
    cr_sim_def d = cr_sim_default_def();
    cr_material_preset("cotton", &d.material, &err);
    d.collider = ground;
    int rc = run_mode(name, cloth, &d, frames);
    /* Crossing triangle pairs at the end, exactly (what self-contact prevents). */
    float *p = last_positions ? malloc(sizeof(float) * 3 * (size_t)cloth->nv) : NULL;
    cr_bvh *b = NULL;
    if (p) {
        for (int64_t k = 0; k < 3 * (int64_t)cloth->nv; k++)
            p[k] = (float)last_positions[k];
        if (cr_bvh_build(p, cloth->nv, cloth->tri, cloth->nf, &b, &err) == CR_OK)
            printf("sim %s: %lld crossing triangle pairs at the end\n", name,
                   (long long)cr_bvh_self_intersections(b));
    }
    cr_bvh_destroy(b);
    free(p);
    cr_mesh_destroy(cloth);
    cr_mesh_destroy(ground);
    return rc;
}

/* Takes "--name value" out of argv wherever it is; its value, or NULL. */
static const char *take_option(int *argc, char **argv, const char *name) {
    for (int i = 1; i + 1 < *argc; i++)
        if (!strcmp(argv[i], name)) {
            const char *value = argv[i + 1];
            for (int j = i; j + 2 < *argc; j++)
                argv[j] = argv[j + 2];
            *argc -= 2;
            return value;
        }
    return NULL;
}

int main(int argc, char **argv) {
    const char *v;
    if ((v = take_option(&argc, argv, "--self-contact"))) {
        self_contact = !strcmp(v, "on");
        if (!self_contact && strcmp(v, "off")) {
            fprintf(stderr, "bench_sim: --self-contact on|off, got %s\n", v);
            return 2;
        }
    }
    if ((v = take_option(&argc, argv, "--solver"))) {
        solver_mode = !strcmp(v, "vbd") ? 1 : !strcmp(v, "compare") ? 2 : 0;
        if (solver_mode == 0 && strcmp(v, "newton")) {
            fprintf(stderr, "bench_sim: --solver newton|vbd|compare, got %s\n", v);
            return 2;
        }
    }
    if ((v = take_option(&argc, argv, "--vbd-iterations")) && (vbd_sweeps = atoi(v)) < 1) {
        fprintf(stderr, "bench_sim: --vbd-iterations wants a count >= 1, got %s\n", v);
        return 2;
    }
    reference_cache = take_option(&argc, argv, "--reference");
    if ((v = take_option(&argc, argv, "--vbd-coarse")) && (coarse_every = atoi(v)) < 1) {
        fprintf(stderr, "bench_sim: --vbd-coarse wants a sweep count >= 1, got %s\n", v);
        return 2;
    }
    if ((v = take_option(&argc, argv, "--vbd-coarse-refresh")) && (coarse_refresh = atoi(v)) < 1) {
        fprintf(stderr, "bench_sim: --vbd-coarse-refresh wants a count >= 1, got %s\n", v);
        return 2;
    }
    if ((v = take_option(&argc, argv, "--vbd-tolerance")) && !((vbd_tol = atof(v)) > 0.0)) {
        fprintf(stderr, "bench_sim: --vbd-tolerance wants a speed > 0 (m/s), got %s\n", v);
        return 2;
    }
    if ((v = take_option(&argc, argv, "--vbd-collision-scale")) &&
        !((vbd_collision_scale = atof(v)) >= 1.0)) {
        fprintf(stderr, "bench_sim: --vbd-collision-scale wants a number >= 1, got %s\n", v);
        return 2;
    }
    const char *which = argc > 1 ? argv[1] : "all";
    if (argc > 2) cr_set_thread_count(atoi(argv[2]));
    int frames = argc > 3 ? atoi(argv[3]) : 30, big = argc > 3 ? frames : 10;
    if (frames < 1) frames = big = 1;
    cr_sim_def d = cr_sim_default_def();
    printf("sim threads: %d, dt %.4f s, %d substeps\n", cr_thread_count(), d.dt, d.substeps);
    int all = strcmp(which, "all") == 0, rc = 0;
    if (all || !strcmp(which, "sphere")) rc |= bench_sphere(frames);
    if (all || !strcmp(which, "tube5k")) rc |= bench_tube("tube5k", 70, 70, frames);    /* 4,970 */
    if (all || !strcmp(which, "tube10k")) rc |= bench_tube("tube10k", 100, 99, frames); /* 10,000 */
    if (all || !strcmp(which, "tube40k")) rc |= bench_tube("tube40k", 200, 199, big);   /* 40,000 */
    if (!strcmp(which, "tall")) rc |= bench_tall("tall10k", 50, 200, frames);           /* 10,000 */
    if (!strcmp(which, "tall2k5")) rc |= bench_tall("tall2k5", 25, 100, frames);        /* 2,500 */
    return rc;
}
