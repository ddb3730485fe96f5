// image_splat's two accumulations as the paper draws them (paper 000 section 4.1, Figure 3): each
// proxy's sphere of influence rasterised into the receiver buffer as a coarsely tessellated sphere
// (shaders/image_splat/splat.vert), each covered pixel's receiver tested against the sphere and
// given the proxy's log occlusion vector (splat_log.frag) or indirect light (splat_indirect.frag),
// and the proxies summed by additive blending. The alternative to accumulating over binned tile
// lists (accumulate_log.comp, accumulate_indirect.comp): the same per-pair arithmetic
// (accum_log_pair.glsl, indirect_pair.glsl), the same pairs (every pair the lists hold beyond these
// reads exactly 0 from the clamped table or fails the per-pair cut), summed in the same proxy order.
// Includes the Vulkan headers: include only from *_vulkan*.cpp.
#pragma once

#include <memory>
#include <string>

#include "image_splat_internal.hpp"
#include "softgi/render/frame.hpp"

namespace softgi::techniques::image_splat {

// Writes the log occlusion of every receiver of `r` as resource `out` (device copy, host copy
// deferred), from the flat shadow list `all` whose spheres of influence have support alpha
// `alpha` (influence_radius). Throws std::invalid_argument naming the device where it cannot blend
// into float attachments or the buffers exceed its limits.
void vulkan_splat_log(render::FrameContext& ctx, const Settings& s, const ShadowTables& t, const ReceiverBuffer& r,
                      const common::BlockerList& all, double alpha, const std::string& out);
// The indirect sums of every receiver of `r` (IndirectEvaluator::accumulate's, section 5) from the
// flat list `all` of re-radiating proxies whose spheres of influence have support alpha `alpha`,
// splatted the same way into one RGBA32F attachment (rgb, omega). The CPU evaluator's input checks
// and messages; std::invalid_argument as vulkan_splat_log.
std::shared_ptr<IndirectSums> vulkan_splat_indirect(render::FrameContext& ctx, const ReceiverBuffer& r, const ProxyList& all, double alpha,
                                                    const IndirectEvaluator& ev);

}  // namespace softgi::techniques::image_splat
