// image_splat (paper 000) on the Vulkan backend: the indirect accumulation (section 5) as a compute
// shader (shaders/image_splat/accumulate_indirect.comp), reading the same host-side frame resources
// as the CPU pass and producing the same IndirectSums. Not installed; include by path.
#pragma once

#include <memory>

#include "image_splat_internal.hpp"
#include "softgi/render/frame.hpp"

namespace softgi::techniques::image_splat {

// Every operator runs on the GPU: point-sampled (eq. 13), averaged_poly and averaged (eq. 15), and
// exact (eqs. 16-17: per pair the two SH rotations and the M blocks, on the evaluator's uploaded M
// and Q floats). False only for a value outside IndirectOperator, which then runs the CPU pass
// (and its error) under "vulkan".
bool vulkan_indirect_supported(IndirectOperator op);
// IndirectEvaluator::accumulate over every tile's proxy list, one invocation per receiver, on the
// evaluator's own tables (IndirectEvaluator::tables()). The same input checks and messages as the
// CPU evaluator; writes the CPU pass's record counters plus kernel_gpu_seconds.
std::shared_ptr<IndirectSums> vulkan_accumulate_indirect(render::FrameContext& ctx, const ReceiverBuffer& r, const ProxyBins& bins,
                                                         const IndirectEvaluator& ev);

}  // namespace softgi::techniques::image_splat
