/* test_base_mpi.c: crease/base_mpi.h outside a launcher (the 2-rank runs
 * are tests/cli_mpi.sh): rank 0 of 1, collectives leave the data as one
 * rank's; an sbatch script's SLURM_NTASKS without srun is one rank; a build
 * without MPI refuses a launch as one of several ranks, naming the count. */
#include "crease/base_mpi.h"
#include "test.h"

#include <stdlib.h>
#include <string.h>

/* Sets (value) or unsets (NULL) name; returns its old value, copied. */
static char *swap_env(const char *name, const char *value) {
    const char *old = getenv(name);
    char *keep = old ? strdup(old) : NULL;
    if (value)
        setenv(name, value, 1);
    else
        unsetenv(name);
    return keep;
}

static void restore_env(const char *name, char *old) {
    if (old)
        setenv(name, old, 1);
    else
        unsetenv(name);
    free(old);
}

CR_TEST(base_mpi, one_rank_collectives) {
    cr_error err = {0};
    char *ompi = swap_env("OMPI_COMM_WORLD_SIZE", NULL);
    CR_CHECK_OK(cr_mpi_init(NULL, NULL, &err), &err);
    CR_CHECK_OK(cr_mpi_init(NULL, NULL, &err), &err); /* twice is once */
    CR_CHECK(cr_mpi_rank() == 0 && cr_mpi_size() == 1);
    float g[5] = {1.5f, -2.0f, 0.0f, 3.25f, 1e-30f};
    const float want[5] = {1.5f, -2.0f, 0.0f, 3.25f, 1e-30f};
    CR_CHECK_OK(cr_mpi_allreduce_sum(g, 5, &err), &err);
    CR_CHECK(memcmp(g, want, sizeof g) == 0);
    CR_CHECK_OK(cr_mpi_broadcast(g, sizeof g, 0, &err), &err);
    CR_CHECK(memcmp(g, want, sizeof g) == 0);
    int32_t mine[3] = {7, 8, 9}, all[3] = {0};
    CR_CHECK_OK(cr_mpi_gather(mine, sizeof mine, all, 0, &err), &err);
    CR_CHECK(all[0] == 7 && all[1] == 8 && all[2] == 9);
    CR_CHECK_OK(cr_mpi_barrier(&err), &err);
    cr_mpi_finalize();
    CR_CHECK(cr_mpi_rank() == 0 && cr_mpi_size() == 1);
    restore_env("OMPI_COMM_WORLD_SIZE", ompi);
}

CR_TEST(base_mpi, sbatch_script_is_one_rank) {
    cr_error err = {0};
    char *ntasks = swap_env("SLURM_NTASKS", "4"), *step = swap_env("SLURM_STEP_ID", NULL);
    char *ompi = swap_env("OMPI_COMM_WORLD_SIZE", NULL);
    CR_CHECK_OK(cr_mpi_init(NULL, NULL, &err), &err);
    CR_CHECK(cr_mpi_size() == 1);
    cr_mpi_finalize();
    restore_env("SLURM_NTASKS", ntasks), restore_env("SLURM_STEP_ID", step);
    restore_env("OMPI_COMM_WORLD_SIZE", ompi);
}

CR_TEST(base_mpi, without_mpi_refuses_several_ranks) {
    if (cr_mpi_available()) return; /* with MPI such a launch is MPI_Init: cli_mpi.sh */
    cr_error err = {0};
    char *ompi = swap_env("OMPI_COMM_WORLD_SIZE", "3");
    CR_CHECK(cr_mpi_init(NULL, NULL, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "one of 3 ranks") != NULL);
    CR_CHECK(cr_mpi_size() == 1);
    cr_mpi_finalize();
    restore_env("OMPI_COMM_WORLD_SIZE", ompi);
}
