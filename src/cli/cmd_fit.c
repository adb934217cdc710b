/* cmd_fit.c: `crease fit --model mlp|pe|grid -o DIR`: the drape paper's Table 1. */
#include "cli.h"

#include "crease/base_mpi.h"
#include "crease/uv_fit.h"

#include <string.h>

void help_fit(void) {
    printf("usage: crease fit --model mlp|pe|grid -o DIR [options]\n\n"
           "Supervised regression of a 3-D deformation over UV, the drape paper's Table 1:\n"
           "dz(u,v) = 0.10 sin(4 pi u) sin(4 pi v) + 0.02 sin(16 pi u) sin(16 pi v), trained on a\n"
           "256x256 grid and scored by the relative L2 error on a 512x512 grid. The three models\n"
           "have the paper's sizes: mlp 2-152-152-152-3 (47,427 parameters), pe 18-148-148-148-3\n"
           "(47,363), grid 101x101x3 + 51x51x3 levels -> 6-64-64-64-3 (47,369).\n\n"
           "options:\n"
           "  --model M            mlp, pe or grid (required)\n"
           "  -o DIR               outputs: log.jsonl, checkpoint.safetensors, surface.obj, "
           "surface.png\n"
           "  --epochs N           cap on epochs (default 2000)\n"
           "  --target E           relative L2 error to reach (default 0.01)\n"
           "  --no-stop            keep training after reaching the target\n"
           "  --lr R               Adam learning rate (default 1e-3; grid 1e-2)\n"
           "  --batch B            mini-batch size (default 4096)\n"
           "  --train-res N        training grid side (default 256)\n"
           "  --eval-res N         evaluation grid side (default 512)\n"
           "  --eval-every N       evaluate every N epochs (default 1)\n"
           "  --checkpoint-every N epochs between checkpoints (default 50; 0 never)\n"
           "  --resume             continue from DIR/checkpoint.safetensors\n"
           "  --seed S             initialisation and shuffling seed (default 1)\n"
           "  --quiet              no progress bar\n"
           "  --json               end with a JSON summary on stdout\n");
}

int cmd_fit(int argc, char **argv) {
    cr_fit_def def = cr_fit_default_def(CR_FIT_GRID);
    const char *model = NULL;
    int json = 0, seed = 1, no_stop = 0, npos = 0;
    const cli_opt opts[] = {
        CLI_STR("--model", &model),
        CLI_OUTPUT(&def.out_dir),
        CLI_INT("--epochs", &def.epochs, 1, 100000000),
        CLI_INT("--batch", &def.batch, 1, 1 << 20),
        CLI_INT("--train-res", &def.train_res, 2, 4096),
        CLI_INT("--eval-res", &def.eval_res, 2, 4096),
        CLI_INT("--eval-every", &def.eval_every, 1, 1000000),
        CLI_INT("--checkpoint-every", &def.checkpoint_every, 0, 1000000),
        CLI_INT("--seed", &seed, 0, 2147483647),
        CLI_FLOAT("--lr", &def.lr, 1e-9, 10),
        CLI_FLOAT("--target", &def.target_rel_l2, 1e-9, 10),
        CLI_FLAG("--no-stop", &no_stop),
        CLI_FLAG("--resume", &def.resume),
        CLI_FLAG("--quiet", &def.quiet),
        CLI_FLAG("--json", &json),
        CLI_END,
    };
    int rc = cli_parse("fit", argc, argv, opts, NULL, 0, &npos);
    if (rc != CLI_OK) return rc;
    if (no_stop) def.stop_at_target = 0;
    if (!model) return cli_usage("fit", "missing --model mlp|pe|grid");
    if (!def.out_dir) return cli_usage("fit", "missing -o DIR");
    cr_error err = {0};
    if (cr_fit_model_parse(model, &def.model, &err) != CR_OK)
        return cli_usage("fit", "%s", err.msg);
    def.seed = (uint64_t)seed;
    cr_fit_result r;
    if (cr_fit_run(&def, &r, &err) != CR_OK) return cli_fail(&err);
    if (cr_mpi_rank() != 0) return CLI_OK; /* rank 0 reports for all */
    fprintf(stderr,
            "fit %s: %lld parameters, %d epochs, %.1f s training, rel L2 %.5f; target %.3g %s\n",
            model, (long long)r.params, r.epochs, r.seconds, r.rel_l2, def.target_rel_l2,
            r.epochs_to_target > 0 ? "reached" : "not reached");
    if (json) {
        cJSON *j = cJSON_CreateObject();
        cJSON_AddStringToObject(j, "command", "fit");
        cJSON_AddStringToObject(j, "model", model);
        cJSON_AddNumberToObject(j, "params", (double)r.params);
        cJSON_AddNumberToObject(j, "epochs", r.epochs);
        cJSON_AddNumberToObject(j, "seconds", r.seconds);
        cJSON_AddNumberToObject(j, "eval_seconds", r.eval_seconds);
        cJSON_AddNumberToObject(j, "rel_l2", r.rel_l2);
        cJSON_AddNumberToObject(j, "final_loss", r.final_loss);
        cJSON_AddNumberToObject(j, "target_rel_l2", def.target_rel_l2);
        if (r.epochs_to_target > 0) {
            cJSON_AddNumberToObject(j, "epochs_to_target", r.epochs_to_target);
            cJSON_AddNumberToObject(j, "seconds_to_target", r.seconds_to_target);
        } else {
            cJSON_AddNullToObject(j, "epochs_to_target");
            cJSON_AddNullToObject(j, "seconds_to_target");
        }
        cJSON_AddNumberToObject(j, "resumed_from_epoch", r.resumed_from);
        cJSON_AddNumberToObject(j, "threads", cr_thread_count());
        cJSON_AddStringToObject(j, "output_dir", def.out_dir);
        cJSON_AddStringToObject(j, "surface_png", r.surface_png);
        cli_json_print(j);
    }
    return CLI_OK;
}
