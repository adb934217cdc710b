/* cmd_dataset.c: `crease dataset`: simulate garments on moving bodies with the
 * reference simulator and write a self-describing dataset (crease/dataset.h). */
#include "cli.h"

#include "crease/base_mpi.h"
#include "crease/dataset.h"
#include "crease/phys_sim.h"

#include <stdlib.h>
#include <string.h>

void help_dataset(void) {
    printf("usage: crease dataset --garments G1,G2 --motions M1,M2 [options] -o DIR\n\n"
           "Simulate every combination of garment, motion, body and resolution with the\n"
           "reference simulator (docs/physics.md) and write a dataset the training commands\n"
           "read: manifest.json, bodies and their posed sequences, rest garments with skinning\n"
           "weights and low/high correspondences, and one garment sequence per combination\n"
           "(docs/datasets.md). Runs are resumable: finished sequences are skipped, so the\n"
           "same command completes an interrupted run. Sequences run in parallel; one that\n"
           "fails is reported and skipped.\n\n"
           "options:\n"
           "  --garments LIST      tshirt, longsleeve, skirt, dress, trousers, vest, jumpsuit, or\n"
           "                       variants TYPE:key=value:... (keys: crease garment --help;\n"
           "                       seed=N draws a random variant, e.g. dress:seed=3,\n"
           "                       tshirt:length=0.8:sleeve=1.2), or outfits of variants\n"
           "                       worn over each other, innermost first, joined by +\n"
           "                       (tshirt+vest: one garment of two layers, simulated with\n"
           "                       self-contact on unless --self-contact off), or garment\n"
           "                       files (.obj, .ply, .glb; UVs not needed) fitted to each\n"
           "                       body as given, at one --res (required)\n"
           "  --garment-variants N each listed garment becomes N random variants\n"
           "                       GARMENT:seed=S+k, k = 0 .. N-1, S the --seed (at most 64 in\n"
           "                       all); the manifest gives each one's parameters and spec\n"
           "  --motions LIST       clips (crease motion --list), .npz/.bvh files or rigged\n"
           "                       CHAR.glb[:MAP] (their own animation) (required)\n"
           "  --bodies LIST        mannequin presets (slim, normal, heavy; default normal) or\n"
           "                       SMPL-family files FILE.npz[:beta:beta...] (betas by ':'\n"
           "                       here, as the list is comma-separated) or rigged\n"
           "                       characters CHAR.glb[:MAP], named in the dataset by the\n"
           "                       file's base name and betas (or map)\n"
           "  --res LIST           low and/or high (default low)\n"
           "  --low-vertices N     vertices of a low-resolution garment (default 2000)\n"
           "  --high-vertices N    vertices of a high-resolution garment (default 8000)\n"
           "  --frames N           frames simulated per sequence (default 150)\n"
           "  --fps F              frames per second (default 30); motion files are resampled\n"
           "                       to it (the manifest gives each motion's source_fps)\n"
           "  --scale S            metres per BVH unit of the motion files (default: the rig's\n"
           "                       known unit or inferred from its height)\n"
           "  --start-frame N, --end-frame N  the frames of each motion file used (default\n"
           "                       all; a calibration T-pose frame 0 is dropped unless\n"
           "                       --start-frame is given)\n"
           "  --ease-in S          motion files start at the rest pose, where garments are\n"
           "                       fitted, and ease into their first frame over S s (default 1)\n"
           "  --ground MODE        clip (default), frame or none: motion files grounded on the\n"
           "                       mannequin's feet\n"
           "  --material M         cotton (default), silk, denim or knit\n"
           "  --plastic            plastic bending (epnet's ground truth)\n" CLI_TWIN_HELP
           "                       (a twin dataset: every sequence of the same def re-run so;\n"
           "                       crease eval scores it against the original as a prediction)\n"
           "  --solver S           newton (default: Newton + CHOLMOD, the converged reference)\n"
           "                       or vbd (vertex block descent, no "
           "factorisation)\n" CLI_SELF_CONTACT_HELP
           "  --max-collider-step M  frames where the body moves further than M metres run\n"
           "                       more substeps (default 0.15; 0: always one)\n"
           "  --seed S             recorded in the manifest; the first variant seed of\n"
           "                       --garment-variants (default 1)\n"
           "  -o DIR               the dataset folder (required)\n"
           "  --quiet              no progress bars\n"
           "  --json               end with a JSON summary on stdout\n\n"
           "Exit code 1 when a sequence failed (the others are written).\n");
}

_Static_assert(CLI_LIST_MAX_ITEMS == CR_DATASET_MAX_ITEMS, "a list option holds a dataset axis");

int cmd_dataset(int argc, char **argv) {
    static cli_list lists[4]; /* garments, motions, bodies, res */
    for (int i = 0; i < 4; i++)
        lists[i].n = 0;
    cr_dataset_def def = cr_dataset_default_def();
    int json = 0, seed = (int)def.seed, npos = 0, step_given = 0, variants = 0;
    cli_motion_file mf = cli_motion_file_default(1.0f); /* motion files' options */
    float max_step = 0.0f; /* parsed as a float, as the option always was */
    const char *solver = NULL, *self_contact = NULL;
    float self_contact_thickness = 0.0f;
    cli_twin twin = {0};
    const cli_opt opts[] = {
        CLI_CUSTOM("--garments", cli_parse_list, &lists[0], 1),
        CLI_CUSTOM("--motions", cli_parse_list, &lists[1], 1),
        CLI_CUSTOM("--bodies", cli_parse_list, &lists[2], 1),
        CLI_CUSTOM("--res", cli_parse_list, &lists[3], 1),
        CLI_OUTPUT(&def.out_dir),
        CLI_INT("--frames", &def.frames, 1, 100000),
        CLI_INT("--low-vertices", &def.low_vertices, 500, 100000),
        CLI_INT("--high-vertices", &def.high_vertices, 500, 100000),
        CLI_FLOAT("--fps", &def.fps, 0.01, 1000),
        CLI_STR("--material", &def.material),
        CLI_INT("--seed", &seed, 0, 2147483647L),
        CLI_INT("--garment-variants", &variants, 1, CR_DATASET_MAX_ITEMS),
        {.name = "--max-collider-step",
         .kind = CLI_OPT_FLOAT,
         .dst = &max_step,
         .lo = 0,
         .hi = 10,
         .seen = &step_given},
        CLI_CHOICE("--solver", &solver, cli_solvers),
        CLI_SELF_CONTACT_OPTS(&self_contact, &self_contact_thickness),
        CLI_FLAG("--plastic", &def.plastic),
        CLI_TWIN_OPTS(&twin),
        CLI_FLAG("--quiet", &def.quiet),
        CLI_FLAG("--json", &json),
        CLI_MOTION_FILE_OPTS(&mf),
        CLI_END,
    };
    int rc = cli_parse("dataset", argc, argv, opts, NULL, 0, &npos);
    if (rc != CLI_OK) return rc;
    def.seed = (uint64_t)seed;
    cli_twin_get(&twin, &def.twin);
    cli_motion_file_defs(&mf, &def.motion_import, &def.motion_prepare);
    if (step_given) def.max_collider_step = max_step;
    def.solver = cr_sim_solver_parse(solver ? solver : "newton");
    def.self_contact = cli_self_contact(self_contact);
    def.self_thickness = self_contact_thickness;
    if (!def.out_dir) return cli_usage("dataset", "missing -o DIR");
    if (lists[0].n == 0) return cli_usage("dataset", "missing --garments LIST");
    if (variants > 0) {
        /* GARMENT -> GARMENT:seed=S, GARMENT:seed=S+1, ... */
        static char expanded[CR_DATASET_MAX_ITEMS][160];
        static const char *items[CR_DATASET_MAX_ITEMS];
        if ((long)lists[0].n * variants > CR_DATASET_MAX_ITEMS)
            return cli_usage("dataset", "--garment-variants %d of %d garments: at most %d in all",
                             variants, lists[0].n, CR_DATASET_MAX_ITEMS);
        int n = 0;
        for (int g = 0; g < lists[0].n; g++)
            for (int k = 0; k < variants; k++, n++) {
                if (strstr(lists[0].items[g], "seed="))
                    return cli_usage("dataset", "--garment-variants: '%s' already has a seed",
                                     lists[0].items[g]);
                snprintf(expanded[n], sizeof expanded[n], "%.120s:seed=%lld", lists[0].items[g],
                         (long long)seed + k);
                items[n] = expanded[n];
            }
        memcpy(lists[0].items, items, (size_t)n * sizeof items[0]);
        lists[0].n = n;
    }
    if (lists[1].n == 0) return cli_usage("dataset", "missing --motions LIST");
    static const char *const normal[] = {"normal"}, *const low[] = {"low"};
    def.garments = lists[0].items, def.ngarments = lists[0].n;
    def.motions = lists[1].items, def.nmotions = lists[1].n;
    def.bodies = lists[2].n ? lists[2].items : normal, def.nbodies = lists[2].n ? lists[2].n : 1;
    def.res = lists[3].n ? lists[3].items : low, def.nres = lists[3].n ? lists[3].n : 1;
    cr_error err = {0};
    cr_dataset_result r;
    if (cr_dataset_generate(&def, &r, &err) != CR_OK) return cli_fail(&err);
    /* Under MPI rank 0 reports for all ranks; the others only exit. */
    if (cr_mpi_rank() != 0) return r.failed > 0 ? CLI_BAD_INPUT : CLI_OK;
    fprintf(stderr,
            "dataset: %d sequences in %s: %d simulated, %d already done, %d failed (%.1f s)\n",
            r.sequences, def.out_dir, r.done, r.skipped, r.failed, r.seconds);
    for (int g = 0; g < r.ngarments; g++) {
        fprintf(stderr,
                "  %-10s most vertices inside the body on a frame: %.3f%% (in a substep before "
                "the simulator's projection: %.3f%%)\n",
                def.garments[g], 100.0 * r.max_inside_share[g],
                100.0 * r.max_inside_share_solver[g]);
        fprintf(stderr,
                "  %-10s most crossing triangle pairs on a frame: %lld (as built, at rest: "
                "%lld); %d of %d sequences failed; %.1f s\n",
                def.garments[g], (long long)r.max_crossings[g], (long long)r.rest_crossings[g],
                r.failed_by_garment[g], r.sequences / r.ngarments, r.seconds_by_garment[g]);
    }
    if (r.done + r.skipped > 0)
        fprintf(stderr, "view: crease view %s -o %s/view\n", def.out_dir, def.out_dir);
    if (json) {
        cJSON *j = cJSON_CreateObject();
        cJSON_AddStringToObject(j, "command", "dataset");
        cJSON_AddStringToObject(j, "output", def.out_dir);
        cJSON_AddNumberToObject(j, "sequences", r.sequences);
        cJSON_AddNumberToObject(j, "done", r.done);
        cJSON_AddNumberToObject(j, "skipped", r.skipped);
        cJSON_AddNumberToObject(j, "failed", r.failed);
        cJSON_AddNumberToObject(j, "seconds", r.seconds);
        cli_twin_json(j, &def.twin);
        cJSON *share = cJSON_AddObjectToObject(j, "max_inside_share");
        cJSON *solver = cJSON_AddObjectToObject(j, "max_inside_share_solver");
        cJSON *cross = cJSON_AddObjectToObject(j, "max_crossings");
        cJSON *rest = cJSON_AddObjectToObject(j, "rest_crossings");
        cJSON *failed = cJSON_AddObjectToObject(j, "failed_by_garment");
        cJSON *secs = cJSON_AddObjectToObject(j, "seconds_by_garment");
        for (int g = 0; g < r.ngarments; g++) {
            cJSON_AddNumberToObject(share, def.garments[g], r.max_inside_share[g]);
            cJSON_AddNumberToObject(solver, def.garments[g], r.max_inside_share_solver[g]);
            cJSON_AddNumberToObject(cross, def.garments[g], (double)r.max_crossings[g]);
            cJSON_AddNumberToObject(rest, def.garments[g], (double)r.rest_crossings[g]);
            cJSON_AddNumberToObject(failed, def.garments[g], r.failed_by_garment[g]);
            cJSON_AddNumberToObject(secs, def.garments[g], r.seconds_by_garment[g]);
        }
        cli_json_print(j);
    }
    return r.failed ? CLI_BAD_INPUT : CLI_OK;
}
