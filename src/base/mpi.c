/* mpi.c: the one file that calls MPI (crease/base_mpi.h). */
#include "crease/base_mpi.h"

#include <stdlib.h>
#include <string.h>

#ifdef CREASE_HAVE_MPI
#include <mpi.h>
#endif

/* mpi_started: 0 before init, 1 outside MPI (one rank), 2 after MPI_Init. */
static int mpi_rank = 0, mpi_size = 1, mpi_started = 0;

int cr_mpi_available(void) {
#ifdef CREASE_HAVE_MPI
    return 1;
#else
    return 0;
#endif
}

int cr_mpi_rank(void) {
    return mpi_rank;
}

int cr_mpi_size(void) {
    return mpi_size;
}

/* The rank count a launcher announced in the environment, or 1. */
static int launched_size(void) {
    const char *vars[] = {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_SIZE", "SLURM_NTASKS"};
    for (size_t i = 0; i < sizeof vars / sizeof vars[0]; i++) {
        const char *v = getenv(vars[i]);
        if (v && atoi(v) > 1) {
            /* SLURM_NTASKS is set for a whole allocation, also for a single
             * process started by sbatch's script: count it only under srun. */
            if (i == 3 && !getenv("SLURM_STEP_ID")) continue;
            return atoi(v);
        }
    }
    return 1;
}

cr_status cr_mpi_init(int *argc, char ***argv, cr_error *err) {
    if (mpi_started) return CR_OK;
    int n = launched_size();
#ifdef CREASE_HAVE_MPI
    /* A process not started as one of several ranks stays out of MPI: a
     * singleton MPI_Init costs time, and Open MPI's allocations it never
     * frees would be leaks under the sanitizers in every command. */
    if (n <= 1) {
        mpi_started = 1;
        return CR_OK;
    }
    int provided = 0;
    if (MPI_Init_thread(argc, argv, MPI_THREAD_FUNNELED, &provided) != MPI_SUCCESS)
        return CR_FAIL(err, CR_ERR_IO, "mpi: MPI_Init_thread failed");
    MPI_Comm_rank(MPI_COMM_WORLD, &mpi_rank);
    MPI_Comm_size(MPI_COMM_WORLD, &mpi_size);
    mpi_started = 2;
    return CR_OK;
#else
    (void)argc, (void)argv;
    if (n > 1)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "mpi: launched as one of %d ranks, but this crease was built without MPI "
                       "(configure with libopenmpi-dev installed and without -DCREASE_MPI=OFF)",
                       n);
    mpi_started = 1;
    return CR_OK;
#endif
}

void cr_mpi_finalize(void) {
#ifdef CREASE_HAVE_MPI
    if (mpi_started == 2) MPI_Finalize();
#endif
    mpi_started = 0, mpi_rank = 0, mpi_size = 1;
}

cr_status cr_mpi_barrier(cr_error *err) {
#ifdef CREASE_HAVE_MPI
    if (mpi_size > 1 && MPI_Barrier(MPI_COMM_WORLD) != MPI_SUCCESS)
        return CR_FAIL(err, CR_ERR_IO, "mpi: MPI_Barrier failed");
#else
    (void)err;
#endif
    return CR_OK;
}

cr_status cr_mpi_broadcast(void *buf, size_t bytes, int root, cr_error *err) {
#ifdef CREASE_HAVE_MPI
    if (mpi_size > 1 && MPI_Bcast(buf, (int)bytes, MPI_BYTE, root, MPI_COMM_WORLD) != MPI_SUCCESS)
        return CR_FAIL(err, CR_ERR_IO, "mpi: MPI_Bcast of %zu bytes from rank %d failed", bytes,
                       root);
#else
    (void)buf, (void)bytes, (void)root, (void)err;
#endif
    return CR_OK;
}

cr_status cr_mpi_allreduce_sum(float *buf, int64_t n, cr_error *err) {
#ifdef CREASE_HAVE_MPI
    if (mpi_size <= 1 || n <= 0) return CR_OK;
    int64_t bucket = n < CR_MPI_BUCKET ? n : CR_MPI_BUCKET;
    float *all = NULL;
    if (mpi_rank == 0) {
        all = cr_malloc(sizeof(float) * (size_t)bucket * (size_t)mpi_size, err);
        if (!all) return err ? err->status : CR_ERR_MEMORY;
    }
    cr_status st = CR_OK;
    for (int64_t off = 0; off < n && st == CR_OK; off += bucket) {
        int m = (int)(n - off < bucket ? n - off : bucket);
        if (MPI_Gather(buf + off, m, MPI_FLOAT, all, m, MPI_FLOAT, 0, MPI_COMM_WORLD) !=
            MPI_SUCCESS) {
            st = CR_FAIL(err, CR_ERR_IO, "mpi: MPI_Gather of %d floats failed", m);
            break;
        }
        if (mpi_rank == 0)
            for (int i = 0; i < m; i++) {
                float s = all[i];
                for (int r = 1; r < mpi_size; r++)
                    s += all[(size_t)r * (size_t)m + (size_t)i];
                buf[off + i] = s;
            }
        if (MPI_Bcast(buf + off, m, MPI_FLOAT, 0, MPI_COMM_WORLD) != MPI_SUCCESS)
            st = CR_FAIL(err, CR_ERR_IO, "mpi: MPI_Bcast of %d floats failed", m);
    }
    free(all);
    return st;
#else
    (void)buf, (void)n, (void)err;
    return CR_OK;
#endif
}

cr_status cr_mpi_gather(const void *send, size_t bytes, void *recv, int root, cr_error *err) {
#ifdef CREASE_HAVE_MPI
    if (mpi_size > 1) {
        if (MPI_Gather(send, (int)bytes, MPI_BYTE, recv, (int)bytes, MPI_BYTE, root,
                       MPI_COMM_WORLD) != MPI_SUCCESS)
            return CR_FAIL(err, CR_ERR_IO, "mpi: MPI_Gather of %zu bytes to rank %d failed", bytes,
                           root);
        return CR_OK;
    }
#else
    (void)err;
#endif
    if (root == 0 && recv != send) memmove(recv, send, bytes);
    return CR_OK;
}
