// Upsampling of receiver-buffer results to display resolution (paper 000 section 4.2, eq. 11).
// Not installed; include by path.
#pragma once

#include <functional>

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <glm/glm.hpp>

namespace softgi::render {
class FrameContext;
class FramePool;
struct GBuffer;
}

namespace softgi::techniques::common {

enum class UpsampleMode {
  Bilateral,  // eq. 11: bilinear x depth x normal^power weights, renormalised
  Bilinear    // plain bilinear over the valid (hit) coarse samples, for comparison (Figure 7)
};
const char* to_string(UpsampleMode m);  // "bilateral", "bilinear"
UpsampleMode parse_upsample_mode(const std::string& s);

// Where no coarse sample matches a display pixel (section 4.2): shade it from the full proxy list
// (robust), interpolate shaded coarse results instead of occlusion vectors (cheap), or keep the
// eq. 11 result as is (none, for comparison).
enum class UpsampleFallback { Robust, Shaded, None };
const char* to_string(UpsampleFallback f);  // "robust", "shaded", "none"
UpsampleFallback parse_upsample_fallback(const std::string& s);

// The receiver plane of one buffer (coarse receiver buffer or display G-buffer), row-major.
struct PlaneView {
  int width = 0, height = 0;
  int scale = 1;                 // pixel (x, y) sits at display point ((x + 0.5) scale, (y + 0.5) scale)
  const float* depth = nullptr;  // eye-space depth z = (p - e) . E; +inf where nothing was hit
  const glm::vec3* normal = nullptr;
};

// The receiver plane of a G-buffer (display or a receiver buffer at its scale); it points into g.
PlaneView plane_view(const render::GBuffer& g);

struct UpsampleOptions {
  UpsampleMode mode = UpsampleMode::Bilateral;
  // w_z = 1 / (epsilon + |z_p - z_i|) with epsilon = epsilon_rel * z_p: relative, so that the
  // weights do not depend on the scene's units.
  double epsilon_rel = 0.01;
  int normal_power = 32;  // w_N = max(0, N_p . N_i)^power (paper: 32)
  // A display pixel is a miss when sum_i w_b,i * w_N,i * epsilon / (epsilon + |z_p - z_i|) (the
  // unnormalised eq. 11 weight relative to a perfect match) is below this.
  double miss_threshold = 0.05;
};

// For every display pixel: the 4 coarse samples (indices into the coarse buffer, -1 = unused) and
// their normalised weights, and whether it is a miss. Background display pixels get no samples.
// Samples with weight 0 are left out and the used ones packed to the front (index[p][0] < 0: none),
// so a display pixel on a coarse pixel centre takes that sample alone (scale 1 is the identity).
struct UpsampleWeights {
  int width = 0, height = 0;
  std::vector<std::array<std::int32_t, 4>> index;
  std::vector<std::array<float, 4>> weight;
  std::vector<std::uint8_t> miss;  // 1: no coarse sample matches (see UpsampleOptions)
  std::size_t misses = 0;
  std::size_t bytes() const;
};
// Display pixel (X, Y) of `fine` sits at coarse coordinate u = (X + 0.5) fine.scale / coarse.scale - 0.5
// (coarse pixel centres at integers); its 2x2 block is floor(u), floor(u) + 1, clamped to the buffer
// (clamp-to-edge). Throws std::invalid_argument for inconsistent sizes (fine width * fine.scale must
// be within less than coarse.scale of coarse width * coarse.scale, and likewise for height; ceil or
// floor of display size / scale both pass), fine.scale > coarse.scale, null pointers, a depth that is
// neither positive finite nor +inf, a non-finite normal on a hit, or bad options.
// `pool`: where the per-pixel planes are taken from (render::FramePool), else allocated.
UpsampleWeights upsample_weights(const PlaneView& coarse, const PlaneView& fine, const UpsampleOptions& opt,
                                 render::FramePool* pool = nullptr);
// Hands w's per-pixel planes to `pool` for a later upsample_weights (w is left empty).
void give(render::FramePool& pool, UpsampleWeights&& w);

// The input rule for one sample i of a buffer: a background depth (+inf), or a positive finite
// depth with a finite normal.
bool upsample_sample_ok(const PlaneView& v, std::size_t i);
// What breaks that rule at sample (x, y) of buffer `name` ("coarse", "fine"), for an error message;
// empty when the sample is fine.
std::string upsample_sample_error(const PlaneView& v, const char* name, int x, int y);

// out[p * channels + c] = sum_k weight[p][k] * in[index[p][k] * channels + c] for every display
// pixel with samples (misses included: their weights are the eq. 11 weights however small, or the
// bilinear ones where all eq. 11 weights vanish); other pixels are left untouched.
void upsample_apply(const UpsampleWeights& w, const float* in, int channels, float* out);
// The same with plain bilinear weights over valid coarse samples (the "shaded" fallback uses these
// on shaded coarse results). With `only` (e.g. &w.miss), only pixels whose entry is non-zero are
// written; background pixels and pixels without a valid coarse sample are left untouched.
void upsample_apply_bilinear(const UpsampleWeights& w, const PlaneView& coarse, const PlaneView& fine, const float* in,
                             int channels, float* out, const std::vector<std::uint8_t>* only = nullptr);

// The two kernels of an upsample pass: the eq. 11 weights and their application to a coarse field.
// The pass body is the technique's; the kernels are this file's on the CPU (cpu_upsample_kernels)
// and compute shaders on Vulkan (vulkan_upsample_kernels, upsample_vulkan.cpp in
// softgi::techniques_vulkan).
struct UpsampleKernels {
  std::function<UpsampleWeights(const PlaneView& coarse, const PlaneView& fine, const UpsampleOptions& opt)> weights;
  std::function<void(const UpsampleWeights& w, const float* in, int channels, float* out)> apply;
};
UpsampleKernels cpu_upsample_kernels(render::FramePool* pool = nullptr);
// upsample_weights on the GPU (shaders/common/upsample_weights.comp): the same checks and result as
// upsample_weights, in float as upsample_weights (other operation orders). `measure` (optional): per display pixel the
// unnormalised eq. 11 weight the miss decision compared with the threshold.
UpsampleWeights vulkan_upsample_weights(render::FrameContext& ctx, const PlaneView& coarse, const PlaneView& fine,
                                        const UpsampleOptions& opt, std::vector<float>* measure = nullptr);
// upsample_apply on the GPU (shaders/common/upsample_apply.comp); the weights stay on the device
// when they are the ones vulkan_upsample_weights computed last.
void vulkan_upsample_apply(render::FrameContext& ctx, const UpsampleWeights& w, const float* in, int channels, float* out);
UpsampleKernels vulkan_upsample_kernels(render::FrameContext& ctx);

}  // namespace softgi::techniques::common
