// SHEXP's frame resources and settings, shared by the CPU passes (shexp.cpp) and the Vulkan
// passes (shexp_vulkan.cpp). Not installed; include by path.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
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

using Receivers = common::VertexReceivers;

struct HierarchyRes {
  std::vector<const proxies::SphereHierarchy*> trees;  // one per proxy set (null where empty)
};

using Cuts = common::ClusterCuts;

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

// --- Backend kernels ---------------------------------------------------------------------------
// A backend's implementations of SHEXP's GPU passes, reading and writing the same frame resources
// as the host passes. accumulate: eqs. 8, 34, 38 with the replacement rules of section 6.2;
// exponentiate for the methods exp_supports accepts (the others run the host pass); shade: the
// shade pass's kernel (common::ShadeKernel).
struct DeviceKernels {
  std::function<void(const Settings&, render::FrameContext&)> accumulate;
  std::function<bool(Mode)> exp_supports;
  std::function<void(const Settings&, render::FrameContext&)> exponentiate;
  common::ShadeKernel shade;
};
// Registers (or replaces) `backend`'s kernels; plan() adds them to every graph it builds after.
void register_device_kernels(const std::string& backend, DeviceKernels kernels);

// The Vulkan kernels (shexp_vulkan.cpp, in softgi::techniques_vulkan). accumulate_log: one
// invocation per receiver; exponentiate: HYB, OL, PS* and PS (the exact exponential, eq. 28, is the
// host pass's).
void vulkan_accumulate(const Settings& s, render::FrameContext& ctx);
bool vulkan_exp_supports(Mode m);
void vulkan_exponentiate(const Settings& s, render::FrameContext& ctx);
void register_vulkan_kernels();

}  // namespace softgi::techniques::shexp
