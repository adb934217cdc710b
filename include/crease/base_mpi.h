/* crease/base_mpi.h: the only door to MPI (docs/mpi.md). Built with MPI
 * (CMake finds it; -DCREASE_MPI=OFF leaves it out) these calls wrap
 * MPI_COMM_WORLD; without it the process is rank 0 of 1, every collective
 * is a copy or nothing, and cr_mpi_init refuses a launch by mpirun/srun with
 * more than one rank (it would run the same job N times over). With MPI, a
 * process not launched as one of several ranks does not initialise MPI
 * either: it is rank 0 of 1 as without it.
 *
 *   CR_TRY(cr_mpi_init(&argc, &argv, err));
 *   ... cr_mpi_rank(), cr_mpi_size(), collectives ...
 *   cr_mpi_finalize();
 *
 * Collectives return CR_ERR_IO naming the MPI call when it fails.
 */
#ifndef CREASE_BASE_MPI_H
#define CREASE_BASE_MPI_H

#include "crease/base.h"

#ifdef __cplusplus
extern "C" {
#endif

/* 1 when the library was built with MPI. */
int cr_mpi_available(void);
/* Initialise (MPI_Init_thread, funneled) once; CR_ERR_INVALID when built
 * without MPI but launched as one of several ranks (Open MPI, PMI, PMIx or
 * SLURM environment), naming the rank count. */
cr_status cr_mpi_init(int *argc, char ***argv, cr_error *err);
void cr_mpi_finalize(void);
int cr_mpi_rank(void); /* 0 before init */
int cr_mpi_size(void); /* 1 before init */
cr_status cr_mpi_barrier(cr_error *err);
/* bytes from root's buf to every rank's buf. */
cr_status cr_mpi_broadcast(void *buf, size_t bytes, int root, cr_error *err);
/* In place: every rank's buf becomes the sum over ranks, added in rank order
 * 0, 1, ..., N-1 in buckets of CR_MPI_BUCKET floats (gathered to rank 0,
 * summed there, broadcast): the result is the same bits on every rank and
 * in every run with the same rank count. */
enum { CR_MPI_BUCKET = 1 << 16 };
cr_status cr_mpi_allreduce_sum(float *buf, int64_t n, cr_error *err);
/* Each rank's `bytes` of send into root's recv (size * bytes, rank order);
 * recv is only written on root. For small results (ints, figures). */
cr_status cr_mpi_gather(const void *send, size_t bytes, void *recv, int root, cr_error *err);

#ifdef __cplusplus
}
#endif
#endif
