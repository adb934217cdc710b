/* cpu_backend.c: the CPU backend table, pointing at the kernels in
 * cpu_*.c. A constant table: no state, safe from any thread. */
#include "nn/cpu/cpu.h"

static const cr_nn_backend cpu_backend = {
    .name = "cpu",
    .fill = nn_cpu_fill,
    .copy = nn_cpu_copy,
    .unary_forward = nn_cpu_unary_forward,
    .unary_backward = nn_cpu_unary_backward,
    .binary = nn_cpu_binary,
    .sum_all = nn_cpu_sum_all,
    .sum_axis = nn_cpu_sum_axis,
    .expand_axis_acc = nn_cpu_expand_axis_acc,
    .reduce_to_shape_acc = nn_cpu_reduce_to_shape_acc,
    .gemm = nn_cpu_gemm,
    .gemm_batched = nn_cpu_gemm_batched,
    .grouped_forward = nn_cpu_grouped_forward,
    .grouped_backward = nn_cpu_grouped_backward,
    .copy2d = nn_cpu_copy2d,
    .gather_rows = nn_cpu_gather_rows,
    .scatter_rows = nn_cpu_scatter_rows,
    .index_check = nn_cpu_index_check,
    .csr_build = nn_cpu_csr_build,
    .segment_sum_rows = nn_cpu_segment_sum_rows,
    .segment_softmax_forward = nn_cpu_segment_softmax_forward,
    .segment_softmax_backward = nn_cpu_segment_softmax_backward,
    .layer_norm_forward = nn_cpu_layer_norm_forward,
    .layer_norm_backward = nn_cpu_layer_norm_backward,
    .cross_forward = nn_cpu_cross_forward,
    .cross_backward = nn_cpu_cross_backward,
    .dot_forward = nn_cpu_dot_forward,
    .dot_backward = nn_cpu_dot_backward,
    .norm_forward = nn_cpu_norm_forward,
    .norm_backward = nn_cpu_norm_backward,
    .normalize_forward = nn_cpu_normalize_forward,
    .normalize_backward = nn_cpu_normalize_backward,
};

const cr_nn_backend *nn_backend_cpu(void) {
    return &cpu_backend;
}
