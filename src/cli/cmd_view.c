/* cmd_view.c: `crease view SEQ... -o DIR`: an offline HTML page that plays
 * garment and body sequences side by side (docs/view.md). Parse, one call
 * (cr_view_write: the panels read, quantised and written with the page,
 * crease/view.h), report; `--serve` serves the page (view_serve.c). */
#include "cli.h"
#include "crease/view.h"

#include <string.h>

int view_serve(const char *dir, int port);

enum { MAX_PANELS = CR_VIEW_MAX_PANELS };

void help_view(void) {
    cr_view_def d = cr_view_default_def();
    printf("usage: crease view SEQ... -o DIR [options]\n"
           "       crease view --serve DIR [--port N]\n\n"
           "Write DIR/index.html, a page that plays the sequences side by side in a browser,\n"
           "offline, on one timeline (play/pause, scrub, step, speed, loop) with one orbit\n"
           "camera. Each SEQ is one panel: parts joined by '+', garment first:\n"
           "  sim.glb                    a glb sequence crease wrote (or a static glb)\n"
           "  sim.glb+body.glb           a garment and its body, drawn together\n"
           "  sim.pc2@garment.obj        a PC2 point cache and its rest mesh (without @MESH:\n"
           "                             the .obj of the same name beside it)\n"
           "  sphere.obj                 a static mesh (.obj, .ply, .glb)\n"
           "  sphere, torus, prism, box  the named objects of crease simulate --object\n"
           "  DATA/sequences/ID, DATA    a crease dataset's sequence (DATA: its first) with\n"
           "                             its body\n\n"
           "options:\n"
           "  -o DIR             output directory: index.html, three.min.js, OrbitControls.js,\n"
           "                     and data/ when the sequences are too large to embed\n"
           "  --label TEXT       the next panel's label (repeat, in panel order; default:\n"
           "                     the garment's file name)\n"
           "  --color-by PATH    colour the next panel's garment by a per-vertex scalar: a\n"
           "                     float .npy of shape (T,V) or (V), or a directory holding\n"
           "                     %s (float32 (T,V), m, docs/view.md); '-' skips a panel\n"
           "  --range LO HI      the colour bar's range (default 0 to the largest value)\n"
           "  --fps F            frames per second (default: the first glb's, else 30)\n"
           "  --embed-max MIB    embed the sequences in index.html up to this size (default %g)\n"
           "  --three DIR        where three.js lies (default %s,\n"
           "                     Debian's libjs-three)\n"
           "  --serve            serve DIR on http://127.0.0.1:PORT/ after writing (or alone\n"
           "                     with DIR); stops on Ctrl-C\n"
           "  --port N           the port to serve on (default 8130; 0 picks a free one)\n"
           "  --json             end with a JSON summary on stdout\n",
           CR_VIEW_COLOR_FILE, (double)d.embed_max_mib, d.three_dir);
}

typedef struct view_list {
    const char *v[MAX_PANELS];
    int n;
} view_list;

static int parse_append(const char *cmd, const char *opt, const char *const *values, void *dst) {
    view_list *l = dst;
    if (l->n >= MAX_PANELS) return cli_usage(cmd, "%s: at most %d", opt, MAX_PANELS);
    l->v[l->n++] = values[0];
    return CLI_OK;
}

static int parse_range(const char *cmd, const char *opt, const char *const *values, void *dst) {
    float *r = dst;
    if (!cli_parse_float(cmd, opt, values[0], -1e30, 1e30, &r[0]) ||
        !cli_parse_float(cmd, opt, values[1], -1e30, 1e30, &r[1]))
        return CLI_USAGE;
    if (!(r[1] > r[0]))
        return cli_usage(cmd, "%s expects LO < HI, got %s %s", opt, values[0], values[1]);
    return CLI_OK;
}

int cmd_view(int argc, char **argv) {
    cr_view_def d = cr_view_default_def();
    view_list labels = {0}, colors = {0};
    int serve = 0, port = 8130, json = 0;
    const char *pos[MAX_PANELS + 1];
    int npos = 0;
    const cli_opt opts[] = {
        CLI_OUTPUT(&d.out_dir),
        CLI_CUSTOM("--label", parse_append, &labels, 1),
        CLI_CUSTOM("--color-by", parse_append, &colors, 1),
        {.name = "--range",
         .kind = CLI_OPT_CUSTOM,
         .fn = parse_range,
         .dst = d.range,
         .nvalues = 2,
         .seen = &d.range_set},
        CLI_FLOAT("--fps", &d.fps, 0.01, 100000),
        CLI_FLOAT("--embed-max", &d.embed_max_mib, 0, 4096),
        CLI_STR("--three", &d.three_dir),
        CLI_FLAG("--serve", &serve),
        CLI_INT("--port", &port, 0, 65535),
        CLI_FLAG("--json", &json),
        CLI_END,
    };
    int rc = cli_parse("view", argc, argv, opts, pos, MAX_PANELS + 1, &npos);
    if (rc != CLI_OK) return rc;
    if (serve && npos == 1 && !d.out_dir) return view_serve(pos[0], port);
    if (npos == 0) return cli_usage("view", "expected at least one sequence");
    if (npos > MAX_PANELS) return cli_usage("view", "at most %d panels", MAX_PANELS);
    if (!d.out_dir) return cli_usage("view", "missing -o DIR");
    if (labels.n > npos || colors.n > npos)
        return cli_usage("view", "%d --label and %d --color-by for %d panels", labels.n, colors.n,
                         npos);
    d.panels = pos, d.npanels = npos;
    d.labels = labels.v, d.nlabels = labels.n;
    d.colors = colors.v, d.ncolors = colors.n;
    cr_view_report r;
    cr_error err = {0};
    if (cr_view_write(&d, &r, &err) != CR_OK) return cli_fail(&err);
    fprintf(stderr, "view: wrote %s: %d panel%s, %d frames at %g fps, %.1f MiB of sequences %s\n",
            r.page, r.panels, r.panels > 1 ? "s" : "", r.frames, (double)r.fps,
            r.data_bytes / 1048576.0,
            r.embedded ? "embedded (opens from file://)"
                       : "in data/ (serve it: crease view --serve)");
    if (json) {
        cJSON *j = cJSON_CreateObject();
        cJSON_AddStringToObject(j, "command", "view");
        cJSON_AddStringToObject(j, "page", r.page);
        cJSON_AddNumberToObject(j, "panels", r.panels);
        cJSON_AddNumberToObject(j, "frames", r.frames);
        cJSON_AddNumberToObject(j, "fps", r.fps);
        cJSON_AddNumberToObject(j, "data_bytes", r.data_bytes);
        cJSON_AddBoolToObject(j, "embedded", r.embedded);
        cli_json_print(j);
    }
    return serve ? view_serve(d.out_dir, port) : CLI_OK;
}
