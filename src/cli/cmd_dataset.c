/* cmd_dataset.c: `crease dataset`: simulate garments on moving bodies with the
 * reference simulator and write a self-describing dataset (crease/dataset.h). */
#include "cli.h"
#include "crease/dataset.h"

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
           "  --garments LIST      tshirt, longsleeve, skirt, dress, trousers, vest (required)\n"
           "  --motions LIST       clips (crease motion --list) or .npz/.bvh files (required)\n"
           "  --bodies LIST        mannequin presets: slim, normal, heavy (default normal)\n"
           "  --res LIST           low and/or high (default low)\n"
           "  --low-vertices N     vertices of a low-resolution garment (default 2000)\n"
           "  --high-vertices N    vertices of a high-resolution garment (default 8000)\n"
           "  --frames N           frames simulated per sequence (default 150)\n"
           "  --fps F              frames per second (default 30)\n"
           "  --material M         cotton (default), silk, denim or knit\n"
           "  --plastic            plastic bending (epnet's ground truth)\n"
           "  --max-collider-step M  frames where the body moves further than M metres run\n"
           "                       more substeps (default 0.15; 0: always one)\n"
           "  --seed S             recorded in the manifest (default 1)\n"
           "  -o DIR               the dataset folder (required)\n"
           "  --quiet              no progress bars\n"
           "  --json               end with a JSON summary on stdout\n\n"
           "Exit code 1 when a sequence failed (the others are written).\n");
}

enum { MAX_LIST_CHARS = 4096 };

/* Split "a,b,c" (copied into buf) into items; returns the count or -1. */
static int split_list(const char *opt, const char *s, char *buf, const char **items) {
    if (strlen(s) >= MAX_LIST_CHARS) {
        cli_usage("dataset", "%s: list too long", opt);
        return -1;
    }
    strcpy(buf, s);
    int n = 0;
    for (char *tok = strtok(buf, ","); tok; tok = strtok(NULL, ",")) {
        if (n == CR_DATASET_MAX_ITEMS) {
            cli_usage("dataset", "%s: at most %d items", opt, CR_DATASET_MAX_ITEMS);
            return -1;
        }
        items[n++] = tok;
    }
    if (n == 0) cli_usage("dataset", "%s: empty list", opt);
    return n > 0 ? n : -1;
}

typedef struct list_opt {
    const char *name;
    char buf[MAX_LIST_CHARS];
    const char *items[CR_DATASET_MAX_ITEMS];
    int n;
} list_opt;

int cmd_dataset(int argc, char **argv) {
    static const char *const names[4] = {"--garments", "--motions", "--bodies", "--res"};
    static list_opt lists[4];
    for (int i = 0; i < 4; i++)
        lists[i].name = names[i], lists[i].n = 0;
    cr_dataset_def def = cr_dataset_default_def();
    int json = 0;
    cli_args a = cli_args_make(argc, argv);
    const char *v;
    while (!cli_args_done(&a)) {
        const char *opt = cli_args_next(&a);
        int matched = 0;
        for (int i = 0; i < 4 && !matched; i++)
            if (!strcmp(opt, lists[i].name)) {
                matched = 1;
                if (!(v = cli_args_value(&a, opt)) ||
                    (lists[i].n = split_list(opt, v, lists[i].buf, lists[i].items)) < 0)
                    return CLI_USAGE;
            }
        if (matched) continue;
        if (!strcmp(opt, "-o") || !strcmp(opt, "--output")) {
            if (!(def.out_dir = cli_args_value(&a, opt))) return CLI_USAGE;
        } else if (!strcmp(opt, "--frames")) {
            if (!(v = cli_args_value(&a, opt)) ||
                !cli_parse_int("dataset", opt, v, 1, 100000, &def.frames))
                return CLI_USAGE;
        } else if (!strcmp(opt, "--low-vertices")) {
            if (!(v = cli_args_value(&a, opt)) ||
                !cli_parse_int("dataset", opt, v, 500, 100000, &def.low_vertices))
                return CLI_USAGE;
        } else if (!strcmp(opt, "--high-vertices")) {
            if (!(v = cli_args_value(&a, opt)) ||
                !cli_parse_int("dataset", opt, v, 500, 100000, &def.high_vertices))
                return CLI_USAGE;
        } else if (!strcmp(opt, "--fps")) {
            if (!(v = cli_args_value(&a, opt)) ||
                !cli_parse_float("dataset", opt, v, 0.01, 1000, &def.fps))
                return CLI_USAGE;
        } else if (!strcmp(opt, "--material")) {
            if (!(def.material = cli_args_value(&a, opt))) return CLI_USAGE;
        } else if (!strcmp(opt, "--seed")) {
            int seed = 0;
            if (!(v = cli_args_value(&a, opt)) ||
                !cli_parse_int("dataset", opt, v, 0, 2147483647L, &seed))
                return CLI_USAGE;
            def.seed = (uint64_t)seed;
        } else if (!strcmp(opt, "--max-collider-step")) {
            float m = 0.0f;
            if (!(v = cli_args_value(&a, opt)) || !cli_parse_float("dataset", opt, v, 0, 10, &m))
                return CLI_USAGE;
            def.max_collider_step = m;
        } else if (!strcmp(opt, "--plastic")) {
            def.plastic = 1;
        } else if (!strcmp(opt, "--quiet")) {
            def.quiet = 1;
        } else if (!strcmp(opt, "--json")) {
            json = 1;
        } else {
            return cli_usage("dataset", "unknown option '%s'", opt);
        }
    }
    if (!def.out_dir) return cli_usage("dataset", "missing -o DIR");
    if (lists[0].n == 0) return cli_usage("dataset", "missing --garments LIST");
    if (lists[1].n == 0) return cli_usage("dataset", "missing --motions LIST");
    static const char *const normal[] = {"normal"}, *const low[] = {"low"};
    def.garments = lists[0].items, def.ngarments = lists[0].n;
    def.motions = lists[1].items, def.nmotions = lists[1].n;
    def.bodies = lists[2].n ? lists[2].items : normal, def.nbodies = lists[2].n ? lists[2].n : 1;
    def.res = lists[3].n ? lists[3].items : low, def.nres = lists[3].n ? lists[3].n : 1;
    cr_error err = {0};
    cr_dataset_result r;
    if (cr_dataset_generate(&def, &r, &err) != CR_OK) return cli_fail(&err);
    fprintf(stderr, "dataset: %d sequences in %s: %d simulated, %d already done, %d failed (%.1f s)\n",
            r.sequences, def.out_dir, r.done, r.skipped, r.failed, r.seconds);
    for (int g = 0; g < r.ngarments; g++)
        fprintf(stderr,
                "  %-10s most vertices inside the body on a frame: %.3f%% (in a substep before "
                "the simulator's projection: %.3f%%)\n",
                def.garments[g], 100.0 * r.max_inside_share[g],
                100.0 * r.max_inside_share_solver[g]);
    if (json) {
        cJSON *j = cJSON_CreateObject();
        cJSON_AddStringToObject(j, "command", "dataset");
        cJSON_AddStringToObject(j, "output", def.out_dir);
        cJSON_AddNumberToObject(j, "sequences", r.sequences);
        cJSON_AddNumberToObject(j, "done", r.done);
        cJSON_AddNumberToObject(j, "skipped", r.skipped);
        cJSON_AddNumberToObject(j, "failed", r.failed);
        cJSON_AddNumberToObject(j, "seconds", r.seconds);
        cJSON *share = cJSON_AddObjectToObject(j, "max_inside_share");
        cJSON *solver = cJSON_AddObjectToObject(j, "max_inside_share_solver");
        for (int g = 0; g < r.ngarments; g++) {
            cJSON_AddNumberToObject(share, def.garments[g], r.max_inside_share[g]);
            cJSON_AddNumberToObject(solver, def.garments[g], r.max_inside_share_solver[g]);
        }
        cli_json_print(j);
    }
    return r.failed ? CLI_BAD_INPUT : CLI_OK;
}
