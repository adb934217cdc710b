/* main.c: `crease <command> ...`: dispatch to one file per command. */
#include "cli.h"

#include "crease/base_mpi.h"

#include <string.h>

static const cli_command commands[] = {
    {"info", "counts, bounds, manifoldness, UVs and triangle quality of a mesh", cmd_info,
     help_info, NULL},
    {"convert", "convert a mesh between OBJ, PLY, glb and PC2 by extension", cmd_convert,
     help_convert, NULL},
    {"render", "render meshes to PNG (wireframe, colour maps, turntables)", cmd_render, help_render,
     NULL},
    {"primitive", "write a primitive mesh with UVs (sphere, torus, prism, plane, ...)",
     cmd_primitive, help_primitive, NULL},
    {"fit", "regress a deformation over UV with mlp, pe or grid models (drape paper, Table 1)",
     cmd_fit, help_fit, NULL},
    {"simulate", "simulate a garment on a body or object (implicit Euler, Newton, CHOLMOD)",
     cmd_simulate, help_simulate, NULL},
    {"drape-static", "quasi-static drape of a square cloth over an object", cmd_drape_static,
     help_drape_static, NULL},
    {"motion", "write a procedural motion clip, or convert a BVH or AMASS motion to .npz",
     cmd_motion, help_motion, NULL},
    {"body", "write the procedural mannequin (slim, normal, heavy; height, girth, chest, hips)",
     cmd_body, help_body, NULL},
    {"pose-body", "skin the mannequin through a motion clip or file, write PC2 or animated .glb",
     cmd_pose_body, help_pose_body, NULL},
    {"dataset", "simulate garments on moving bodies into a dataset (resumable, parallel)",
     cmd_dataset, help_dataset, NULL},
    {"drape", "drape a cloth over an object with an implicit neural surface (drape paper)",
     cmd_drape, help_drape, NULL},
    {"gdsr",
     "garment dynamic super-resolution: train on low/high pairs, run on a clip (gdsr paper)",
     cmd_gdsr, help_gdsr, (const char *const[]){"train", "run", NULL}},
    {"epnet", "self-supervised garment dynamics with persistent wrinkles (epnet paper)", cmd_epnet,
     help_epnet, (const char *const[]){"train", NULL}},
    {"garment", "build a garment fitted to the mannequin (tshirt, dress, ...) or fit a user's",
     cmd_garment, help_garment, NULL},
    {"eval", "compare a predicted garment sequence with a reference by every paper's metrics",
     cmd_eval, help_eval, NULL},
    {"view", "write an offline HTML page that plays sequences side by side (or --serve it)",
     cmd_view, help_view, NULL},
    {"swingar", "train SwinGar's one-model-for-many-garments estimator, or animate a garment",
     cmd_swingar, help_swingar, (const char *const[]){"train", "measure", NULL}},
    {"swingar-sdf", "train or measure SwinGar's body SDF", cmd_swingar_sdf, help_swingar_sdf,
     (const char *const[]){"train", NULL}},
};
enum { COMMAND_COUNT = sizeof commands / sizeof commands[0] };

static void usage(FILE *to) {
    fprintf(to,
            "crease %s: neural garment simulation with fine and persistent wrinkles\n\n"
            "usage: crease <command> [options]\n\ncommands:\n",
            "0.1.0");
    for (int i = 0; i < COMMAND_COUNT; i++)
        fprintf(to, "  %-12s %s\n", commands[i].name, commands[i].summary);
    fprintf(to, "\nEvery command takes --help, and --json to end with one JSON summary on "
                "stdout.\nExit codes: 0 success, 1 bad input, 2 usage error.\n");
}

int main(int argc, char **argv) {
    cr_parallel_choose_wait_policy(argv);
    if (argc < 2) {
        usage(stderr);
        return CLI_USAGE;
    }
    if (cli_is_help(argv[1]) || strcmp(argv[1], "help") == 0) {
        if (argc > 2)
            for (int i = 0; i < COMMAND_COUNT; i++)
                if (strcmp(argv[2], commands[i].name) == 0) {
                    commands[i].help();
                    return CLI_OK;
                }
        usage(stdout);
        return CLI_OK;
    }
    if (strcmp(argv[1], "--version") == 0) {
        printf("crease 0.1.0\n");
        return CLI_OK;
    }
    for (int i = 0; i < COMMAND_COUNT; i++)
        if (strcmp(argv[1], commands[i].name) == 0) {
            int documented = 0;
            for (const char *const *d = commands[i].documented; argc > 2 && d && *d; d++)
                documented |= strcmp(argv[2], *d) == 0;
            for (int k = 2; k < argc && !documented; k++)
                if (cli_is_help(argv[k])) {
                    commands[i].help();
                    return CLI_OK;
                }
            /* Under mpirun/srun every rank runs the command; built without MPI,
             * a launch with several ranks is refused here. */
            cr_error err = {0};
            if (cr_mpi_init(&argc, &argv, &err) != CR_OK) {
                fprintf(stderr, "crease: %s\n", err.msg);
                return CLI_BAD_INPUT;
            }
            int rc = commands[i].run(argc - 1, argv + 1);
            cr_mpi_finalize();
            return rc == CLI_HELP ? CLI_OK : rc;
        }
    fprintf(stderr, "crease: unknown command '%s'\n\n", argv[1]);
    usage(stderr);
    return CLI_USAGE;
}
