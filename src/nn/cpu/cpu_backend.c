/* cpu_backend.c: the CPU backend table, pointing at the kernels in
 * cpu_*.c. A constant table: no state, safe from any thread. */
#include "nn/cpu/cpu.h"

static const cr_nn_backend cpu_backend = {
    .name = "cpu",
    .fill = cr_nn_cpu_fill,
    .copy = cr_nn_cpu_copy,
    .unary_forward = cr_nn_cpu_unary_forward,
    .unary_backward = cr_nn_cpu_unary_backward,
    .binary = cr_nn_cpu_binary,
    .sum_all = cr_nn_cpu_sum_all,
    .sum_axis = cr_nn_cpu_sum_axis,
    .expand_axis_acc = cr_nn_cpu_expand_axis_acc,
    .reduce_to_shape_acc = cr_nn_cpu_reduce_to_shape_acc,
    .gemm = cr_nn_cpu_gemm,
    .gemm_batched = cr_nn_cpu_gemm_batched,
    .grouped_forward = cr_nn_cpu_grouped_forward,
    .grouped_backward = cr_nn_cpu_grouped_backward,
    .bias_act_forward = cr_nn_cpu_bias_act_forward,
    .act_bias_backward = cr_nn_cpu_act_bias_backward,
    .copy2d = cr_nn_cpu_copy2d,
    .gather_rows = cr_nn_cpu_gather_rows,
    .scatter_rows = cr_nn_cpu_scatter_rows,
    .index_check = cr_nn_cpu_index_check,
    .csr_build = cr_nn_cpu_csr_build,
    .segment_sum_rows = cr_nn_cpu_segment_sum_rows,
    .segment_softmax_forward = cr_nn_cpu_segment_softmax_forward,
    .segment_softmax_backward = cr_nn_cpu_segment_softmax_backward,
    .gat_attend_scratch = cr_nn_cpu_gat_attend_scratch,
    .gat_attend_forward = cr_nn_cpu_gat_attend_forward,
    .lstm_gates_forward = cr_nn_cpu_lstm_gates_forward,
    .mpnn_block_scratch = cr_nn_cpu_mpnn_block_scratch,
    .mpnn_block_forward = cr_nn_cpu_mpnn_block_forward,
    .wire_points_forward = cr_nn_cpu_wire_points_forward,
    .layer_norm_forward = cr_nn_cpu_layer_norm_forward,
    .layer_norm_backward = cr_nn_cpu_layer_norm_backward,
    .cross_forward = cr_nn_cpu_cross_forward,
    .cross_backward = cr_nn_cpu_cross_backward,
    .dot_forward = cr_nn_cpu_dot_forward,
    .dot_backward = cr_nn_cpu_dot_backward,
    .norm_forward = cr_nn_cpu_norm_forward,
    .norm_backward = cr_nn_cpu_norm_backward,
    .normalize_forward = cr_nn_cpu_normalize_forward,
    .normalize_backward = cr_nn_cpu_normalize_backward,
};

const cr_nn_backend *cr_nn_backend_cpu(void) {
    return &cpu_backend;
}
