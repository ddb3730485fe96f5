// image_splat (paper 000) on the Vulkan backend: the indirect accumulation (section 5) as a compute
// shader (shaders/image_splat/accumulate_indirect.comp), reading the same host-side frame resources
// as the CPU pass and producing the same IndirectSums. Includes the Vulkan headers: include only
// from *_vulkan*.cpp and tests/vulkan.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "image_splat_internal.hpp"
#include "softgi/backends/vulkan/context.hpp"
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

// The evaluator's tables on a device (IndirectEvaluator::tables(): visibility ZH, D factors, M and Q
// blocks, L~ with the band factors), as indirect_pair.glsl binds them.
struct IndirectTableBuffers {
  std::vector<float> vis_host, dfac_host, consts_host, mtab_host, qrot_host;
  backends::vulkan::Buffer vis, dfac, consts, mtab, qrot;
};
// Checks the operator and, for the exact one, the tables' layout (std::logic_error), uploads the
// tables whose floats changed, and returns the shaders' operator code (kIndOp*).
std::uint32_t upload_indirect_tables(backends::vulkan::Context& dev, IndirectTableBuffers& b, const IndirectEvaluator& ev);

}  // namespace softgi::techniques::image_splat
