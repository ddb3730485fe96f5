// SHEXP's frame resources and settings, shared by the CPU passes (shexp.cpp) and the Vulkan
// passes (shexp_vulkan.cpp). Not installed; include by path.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "shexp_internal.hpp"
#include "softgi/render/frame.hpp"
#include "softgi/render/params.hpp"

namespace softgi::techniques::shexp {

// Inputs of SHEXP's graph besides the shared ones: empty when the scene has no blocker sphere / no
// spherical light (or analytic lights are switched off), so the passes that need them are left out.
inline constexpr const char* kBlockerSpheres = "blocker_spheres";
inline constexpr const char* kSphericalLights = "spherical_lights";
// Resources written by SHEXP's passes.
inline constexpr const char* kTables = "shexp.tables";
inline constexpr const char* kLightTables = "shexp.light_tables";
inline constexpr const char* kHierarchy = "shexp.hierarchy";
inline constexpr const char* kProxyPose = "shexp.proxy_pose";
inline constexpr const char* kReceivers = "shexp.receivers";
inline constexpr const char* kCuts = "shexp.cuts";
inline constexpr const char* kLogVisibility = "shexp.log_visibility";
inline constexpr const char* kVisibility = "shexp.visibility";
inline constexpr const char* kShading = "shexp.vertex_shading";

enum class Mode { HYB, OL, PSStar, PS, Exact, Product, Projected };

struct Settings {
  int order = 4, acc_order = 4;
  Mode mode = Mode::HYB;
  int ps_degree = 2;
  bool hierarchy = true, ratio_vectors = true;
  double theta_max = 0.0, theta_min = 0.0;
  int clusters = 0;
  double window_h = 0.0;  // resolved: 0 = off
  bool window_visibility = true;
  ReplacementRule rule = ReplacementRule::Continuous;
  int table_resolution = 256;
  double log_threshold = 0.02;
  bool lights = true;
  KernelIsa isa = KernelIsa::Scalar;
};

// Throws std::invalid_argument naming the parameter.
Settings read_settings(const render::ParamSet& p);

// --- Frame resources ----------------------------------------------------------------------------

struct Tables {
  int acc_order = 0;
  std::shared_ptr<const sh::ShTables> sh;  // cap log / visibility and OL tables at the accumulation order
  ZhTable log, vis;                         // float copies for the hot loops
  std::size_t bytes_used() const {
    return log.bytes() + vis.bytes() + (sh->ol_norm().size() + sh->ol_a().size() + sh->ol_b().size()) * sizeof(double);
  }
};

struct Receivers {
  ReceiverSoA soa;                              // cluster order
  std::vector<int> object, vertex;              // source of each receiver
  std::vector<ReceiverCluster> clusters;
  std::vector<std::vector<std::uint32_t>> index;  // [object][vertex] -> receiver
  std::size_t bytes() const {
    return soa.size() * (6 * sizeof(float) + 3 * sizeof(int)) + clusters.size() * sizeof(ReceiverCluster);
  }
};

struct HierarchyRes {
  std::vector<const proxies::SphereHierarchy*> trees;  // one per proxy set (null where empty)
};

struct Cuts {
  std::vector<BlockerList> lists;
  std::vector<int> list_of_cluster;
  std::size_t bytes() const {
    std::size_t b = list_of_cluster.size() * sizeof(int);
    for (const auto& l : lists) b += l.bytes();
    return b;
  }
};

struct Field {  // per receiver, order^2 floats
  int order = 0;
  std::vector<float> v;
};

struct Shading {
  std::vector<std::vector<glm::vec3>> irradiance;  // E/pi per vertex of every posed object (unit albedo)
  std::vector<glm::vec3> env;                      // the SH light used (order n, windowed)
  int order = 0;
};

// Counters of the accumulation passes: receivers, receiver-blocker pairs, blockers per receiver.
void blocker_counters(render::PassRecord& rec, const Receivers& r, const Cuts& cuts, double& pairs);

// The SH basis-recurrence constants and asin coefficients of the CPU kernel (kernel.cpp), laid out
// as softgi_shared.h's kBasis* offsets: the Vulkan shaders evaluate the basis with the same floats.
std::vector<float> basis_recurrence_constants();

// --- Vulkan implementations (shexp_vulkan.cpp) -----------------------------------------------
// The same passes on the GPU, reading and writing the same frame resources as the CPU passes.
// accumulate_log: eqs. 8, 34, 38 with the replacement rules of section 6.2, one invocation per receiver.
void vulkan_accumulate(const Settings& s, render::FrameContext& ctx);
// exponentiate for the HYB, OL, PS* and PS methods (section 4); the exact exponential (eq. 28, the
// reference) runs the host pass.
bool vulkan_exp_supports(Mode m);
void vulkan_exponentiate(const Settings& s, render::FrameContext& ctx);
// The diffuse shading of receivers on the GPU (shaders/shexp/shade.comp): what shade_batch followed
// by add_lights_and_clamp computes on the CPU, out[i] = max(0, (H(N_i) * g_i) . L + lights), for
// SHEXP's shade pass and image_splat's shade_direct.
struct GpuShade {
  const BatchShade* b = nullptr;  // order, L, hcoef, gwin; b->g: n^2 per receiver (null: unshadowed, or `gather`)
  const LightLobeTable* lights_table = nullptr;  // null: no spherical light shading
  const std::vector<scene::SphericalLight>* lights = nullptr;
  bool zero_normal_empty = false;  // add_lights_and_clamp's flag
  // Paper 000 eq. 11 (image_splat): the visibility of receiver i interpolated from a coarse field,
  // g_i = sum_t weight[pixel[i]][t] coarse[index[pixel[i]][t]] (taps packed to the front, -1 unused;
  // no tap: unshadowed), in place of b->g.
  struct Gather {
    const std::int32_t* pixel = nullptr;               // per receiver
    const std::array<std::int32_t, 4>* index = nullptr;  // per display pixel
    const std::array<float, 4>* weight = nullptr;        // per display pixel
    std::size_t pixels = 0;                              // display pixels
    const float* coarse = nullptr;                       // n^2 per coarse sample
    std::size_t coarse_count = 0;
  };
  const Gather* gather = nullptr;
};
// Shades every receiver of rec into out[0, rec.size()); returns the receivers clamped at 0 and sets
// the pass record's kernel_gpu_seconds.
long long vulkan_shade(render::FrameContext& ctx, const GpuShade& in, const ReceiverSoA& rec, glm::vec3* out);

}  // namespace softgi::techniques::shexp
