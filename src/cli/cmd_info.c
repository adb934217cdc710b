/* cmd_info.c: `crease info MESH`: counts, bounds, manifoldness, boundary
 * loops, UV presence and triangle quality of a mesh. */
#include "cli.h"
#include "crease/diffgeo.h"
#include "crease/mesh_io.h"
#include "crease/topology.h"

#include <string.h>

void help_info(void) {
    printf("usage: crease info MESH [--json]\n\n"
           "Describe a mesh (.obj, .ply, .glb): vertex, face, edge and UV counts, bounds,\n"
           "whether it is a manifold (and the first defect when not), boundary loops,\n"
           "Euler characteristic and triangle quality (minimum angles).\n\n"
           "options:\n"
           "  --json   print one JSON object on stdout instead of the text report\n");
}

static void print_report(const char *path, const cr_mesh *m, const cr_topology *t,
                         const cr_quality_stats *q, const float lo[3], const float hi[3],
                         int manifold, const char *why) {
    printf("%s\n", path);
    printf("  vertices %d, faces %d, edges %d, UVs %d%s\n", m->nv, m->nf, t->ne, m->nuv,
           cr_mesh_has_uv(m) ? "" : " (no UVs)");
    printf("  bounds   [%.4g %.4g %.4g] .. [%.4g %.4g %.4g] m\n", lo[0], lo[1], lo[2], hi[0], hi[1],
           hi[2]);
    printf("  manifold %s%s%s\n", manifold ? "yes" : "no", manifold ? "" : ": ",
           manifold ? "" : why);
    printf("  boundary %d loop%s, %d edges; Euler characteristic %lld\n", t->nloop,
           t->nloop == 1 ? "" : "s", t->n_boundary_edges,
           (long long)cr_topology_euler_characteristic(t));
    printf("  min angle: smallest %.2f deg, mean %.2f deg, 1st percentile %.2f deg, "
           "%.2f%% above 20 deg\n",
           q->min_deg, q->mean_deg, q->p01_deg, 100.0 * q->frac_above_20);
}

static cJSON *report_json(const char *path, const cr_mesh *m, const cr_topology *t,
                          const cr_quality_stats *q, const float lo[3], const float hi[3],
                          int manifold, const char *why) {
    cJSON *j = cJSON_CreateObject();
    cJSON_AddStringToObject(j, "command", "info");
    cJSON_AddStringToObject(j, "input", path);
    cJSON_AddNumberToObject(j, "vertices", m->nv);
    cJSON_AddNumberToObject(j, "faces", m->nf);
    cJSON_AddNumberToObject(j, "edges", t->ne);
    cJSON_AddNumberToObject(j, "uvs", m->nuv);
    cJSON_AddBoolToObject(j, "has_uv", cr_mesh_has_uv(m));
    cJSON *b = cJSON_AddObjectToObject(j, "bounds");
    cJSON_AddItemToObject(b, "min", cli_json_float_array(lo, 3));
    cJSON_AddItemToObject(b, "max", cli_json_float_array(hi, 3));
    cJSON_AddBoolToObject(j, "manifold", manifold);
    if (!manifold) cJSON_AddStringToObject(j, "manifold_error", why);
    cJSON_AddNumberToObject(j, "nonmanifold_edges", t->n_nonmanifold_edges);
    cJSON_AddNumberToObject(j, "nonmanifold_vertices", t->n_nonmanifold_vertices);
    cJSON_AddNumberToObject(j, "inconsistent_edges", t->n_inconsistent_edges);
    cJSON_AddNumberToObject(j, "boundary_loops", t->nloop);
    cJSON_AddNumberToObject(j, "boundary_edges", t->n_boundary_edges);
    cJSON_AddNumberToObject(j, "euler_characteristic", (double)cr_topology_euler_characteristic(t));
    cJSON_AddNumberToObject(j, "min_angle_deg", q->min_deg);
    cJSON_AddNumberToObject(j, "mean_min_angle_deg", q->mean_deg);
    cJSON_AddNumberToObject(j, "p01_min_angle_deg", q->p01_deg);
    cJSON_AddNumberToObject(j, "fraction_min_angle_above_20deg", q->frac_above_20);
    return j;
}

int cmd_info(int argc, char **argv) {
    const char *pos[1];
    int npos = 0, json = 0;
    const cli_opt opts[] = {CLI_FLAG("--json", &json), CLI_END};
    int rc = cli_parse("info", argc, argv, opts, pos, 1, &npos);
    if (rc != CLI_OK) return rc;
    if (npos == 0) return cli_usage("info", "missing MESH");
    const char *path = pos[0];
    cr_error err = {0};
    cr_mesh *m = NULL;
    cr_topology *t = NULL;
    cr_quality_stats q;
    if (cr_mesh_read(path, &m, &err) != CR_OK) return cli_fail(&err);
    cr_status st = cr_topology_build(m, &t, &err);
    if (st == CR_OK) st = cr_mesh_quality_stats(m, &q, &err);
    if (st != CR_OK) {
        cr_mesh_destroy(m);
        return cli_fail(&err);
    }
    float lo[3], hi[3];
    cr_mesh_bounds(m, lo, hi);
    cr_error why = {0};
    int manifold = cr_topology_require_manifold(t, path, &why) == CR_OK;
    if (json)
        cli_json_print(report_json(path, m, t, &q, lo, hi, manifold, why.msg));
    else
        print_report(path, m, t, &q, lo, hi, manifold, why.msg);
    cr_topology_destroy(t);
    cr_mesh_destroy(m);
    return CLI_OK;
}
