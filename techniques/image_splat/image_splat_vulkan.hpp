// Image-space proxy accumulation (paper 000) on the Vulkan backend: the GPU passes of image_splat,
// reading the same host-side frame resources as the CPU passes (image_splat_internal.hpp) and
// producing the same structures, so that the backends can be compared pass by pass. The per-tile
// blocker lists are SHEXP's (common::BlockerList) and the log table a (clamped) common::ZhTable, so the
// accumulation and the exponential reuse SHEXP's shaders (shaders/common/*.comp); only the host
// dispatch for image_splat's resources lives here. Tables are the CPU's own floats, uploaded once per
// device and kept in the vulkan::Context's cache. Not installed; include by path.
#pragma once

#include <functional>
#include <memory>
#include <vector>

#include "image_splat_internal.hpp"
#include "softgi/render/frame.hpp"

namespace softgi::techniques::image_splat {

// Eq. 4's exponent summed per receiver over its tile's blocker list (paper 004 eqs. 34, 38 and the
// replacement rules of section 6.2), one invocation per receiver, with accumulate_log_range's
// per-pair cut where it applies (pair_cut_factor). Writes the record's counters.
void vulkan_accumulate_log(render::FrameContext& ctx, const Settings& s, const ShadowTables& t, const ReceiverBuffer& r,
                           const ProxyBins& bins, const std::string& out);

// exponentiate on the GPU: HYB, OL and PS* (paper 004 section 4, as common::exp_batch); the exact
// exponential (eq. 28, the reference) runs the CPU pass under "vulkan" too.
bool vulkan_exp_supports(ExpMode m);
void vulkan_exponentiate(render::FrameContext& ctx, const Settings& s, const ShadowTables& t, const std::string& in,
                         const std::string& out);


// shade_direct's kernels on the GPU (shaders/common/shade.comp): the surface pixels gather O_p with
// the eq. 11 weights and are shaded (product, spherical lights, clamp) in one dispatch; the robust
// misses and the shaded fallback's coarse receivers with their own visibility in another.
DirectKernels vulkan_direct_kernels(render::FrameContext& ctx);

// Registers the kernels above for the Vulkan backend (register_device_kernels).
void register_vulkan_kernels();

}  // namespace softgi::techniques::image_splat
