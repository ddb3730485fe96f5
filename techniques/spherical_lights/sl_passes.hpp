// Spherical lights' frame resources and settings (paper 001, Guerrero, Jeschke and Wimmer 2008),
// shared by the host passes (spherical_lights.cpp), the receiver kernel (sl_indirect.cpp) and the
// tests. Not installed; include by path.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "../common/accumulation.hpp"
#include "../common/cuts.hpp"
#include "../common/receivers.hpp"
#include "softgi/proxies/hierarchy.hpp"
#include "sl_precompute.hpp"
#include "sl_tables.hpp"
#include "softgi/render/frame.hpp"
#include "softgi/render/params.hpp"
#include "softgi/sh/exp_log.hpp"

namespace softgi::techniques::spherical_lights {

using namespace ::softgi::techniques::common;

// Graph inputs besides the shared ones.
inline constexpr const char* kBlockerSpheres = "blocker_spheres";
inline constexpr const char* kSphericalLights = "spherical_lights";
// Resources written by the passes.
inline constexpr const char* kTables = "sl.tables";
inline constexpr const char* kLightTables = "sl.light_tables";
inline constexpr const char* kSlData = "sl.data";              // per-object precomputation (section 4)
inline constexpr const char* kSlPose = "sl.pose";              // this frame's SLs and sample points (section 7.1)
inline constexpr const char* kSampleLog = "sl.sample_log_visibility";
inline constexpr const char* kSampleVisibility = "sl.sample_visibility";
inline constexpr const char* kSampleRadiance = "sl.sample_radiance";  // L_p per sample point (section 5.1)
inline constexpr const char* kIntensity = "sl.intensity";      // L^c_S per SL (section 5.2, eq. 11)
inline constexpr const char* kSlCuts = "sl.cuts";              // per receiver cluster, the SLs it sums (section 7.3)
inline constexpr const char* kShadowCuts = "sl.shadow_cuts";   // per receiver cluster, its shadows' blockers (section 7.3)
// Per SlData object, the blockers of its SLs' sample points (section 7.3; list_of_cluster per object).
inline constexpr const char* kSampleShadowCuts = "sl.sample_shadow_cuts";
inline constexpr const char* kReceivers = "sl.receivers";
inline constexpr const char* kLogVisibility = "sl.log_visibility";
inline constexpr const char* kVisibility = "sl.visibility";
inline constexpr const char* kDirectShading = "sl.direct_shading";
inline constexpr const char* kIndirectShading = "sl.indirect_shading";

// Section 7.2: the order in which blocker SLs darken an SL.
enum class Blocking { PerSphere, PerObject };

// How the receiver pass integrates each SL's light. Sh: the paper's average radiance times average
// visibility (eqs. 12-24). RayCast: a reference for that approximation, the same posed SLs,
// intensities and replacement rules integrated exactly by cosine-weighted rays against the spheres.
enum class IndirectVisibility { Sh, RayCast };

struct Settings {
  int order = 4;
  sh::ExpMethod exp = sh::ExpMethod::HYB;
  double window_h = 0.0;  // resolved (0 = off)
  ReplacementRule rule = ReplacementRule::Continuous;
  int table_resolution = 256;
  double log_threshold = 0.02;
  bool lights = true;
  KernelIsa isa = KernelIsa::Scalar;
  Blocking blocking = Blocking::PerSphere;
  bool indirect = true;
  int clusters = 0;  // receiver clusters (0 = automatic)
  bool hierarchy = true;  // section 7.3
  bool shadow_hierarchy = false;  // section 7.3: the shadows from cuts (paper 004's, with ratio vectors)
  bool reflection_ratios = true;  // eq. 25
  bool lights_as_sls = true;      // section 7.3 local lights; false: paper 004's analytic lights
  double theta_max = 0.0;
  IndirectVisibility visibility = IndirectVisibility::Sh;
  int ray_strata = 64;            // RayCast: ray_strata^2 stratified cosine-weighted directions per receiver
  PrecomputeOptions pre;          // pre.intersecting: the paper's precomputed occlusion, or at run time (RayCast only)
};
// Throws std::invalid_argument naming the parameter.
Settings read_settings(const render::ParamSet& p);

struct Tables {
  int order = 0;
  std::shared_ptr<const sh::ShTables> sh;  // cap log and OL tables (paper 004 section 6.1)
  ZhTable log;                             // float copy for the kernels
  WeightTable weight;                      // w_theta of eqs. 16-17 (section 6.1)
  std::size_t bytes() const { return sh->bytes() + log.bytes() + weight.bytes(); }
};
std::shared_ptr<const Tables> make_tables(int order, int resolution, double log_threshold);

// Per proxy set with emission: its precomputation and the posed object it belongs to.
struct SlObject {
  int set = -1;     // index into Scene::proxies / PosedScene::proxies
  int object = -1;  // index into PosedScene::objects
  std::shared_ptr<const ObjectSls> data;  // leaves, and the parents as groups
  // Section 7.3: the hierarchy over the rest-pose leaves (null without one) and, per tree node, the
  // index into data->groups of an inner node (-1 for a leaf, which is node.leaf of data->sls).
  std::shared_ptr<const proxies::SphereHierarchy> tree;
  std::vector<int> node_group;
};
struct SlData {
  std::vector<SlObject> objects;
  std::size_t bytes() const;
};

// This frame's spherical lights, flattened over objects (section 7.1), and the posed sample points.
struct SlPose {
  int order = 0;
  std::vector<glm::vec3> centre;   // posed proxy sphere
  std::vector<float> radius;
  std::vector<glm::mat3> rotation;  // rest (mesh) frame -> world: the SL's average rotation
  std::vector<int> object;          // index into SlData::objects
  std::vector<glm::vec3> object_centre;  // per SlData object: mean of its SLs' centres (section 8.4)
  // Per SL, the same-object SLs (flat indices) intersecting it: ignored as its blockers (section 6.2).
  std::vector<std::vector<int>> intersecting;
  ReceiverSoA samples;                       // every SL's sample points, SL by SL
  std::vector<std::size_t> sample_begin;     // per SL, its range in `samples` (size SLs + 1)
  std::vector<const float*> basis;           // per sample point: (4 pi/N) Y_j, n^2 floats (eq. 10)
  std::vector<const float*> albedo;          // per SL: c_S, 3 x n^2 channel-major (section 4.2)
  BlockerList blockers;                      // every leaf SL, as blockers (sections 5.1 and 6)
  // Section 7.3: the first `leaves` SLs are the proxy spheres; the rest are the parents of each
  // object's SL hierarchy (none without one), with the leaves below each and, per object, its tree
  // posed (refit to this frame's leaves) and the SL of every tree node.
  std::size_t leaves = 0;
  std::vector<std::vector<int>> leaves_below;  // per SL: the leaf SLs it bounds (itself for a leaf)
  std::vector<std::shared_ptr<const proxies::SphereHierarchy>> trees;  // per SlData object (null: none)
  std::vector<std::vector<int>> node_sl;       // per SlData object: tree node -> flat SL index
  std::size_t size() const { return radius.size(); }
  std::size_t bytes() const;
};

// The SLs that a receiver cluster sums (eq. 14): every leaf, or its cut of the SL hierarchies
// (section 7.3, the criterion of paper 004 eq. 36), with the reflection ratio of each (eq. 25).
struct SlList {
  std::vector<int> sl;                         // flat SL indices into SlPose
  std::vector<std::vector<int>> intersecting;  // per entry: the entries of its own object whose spheres intersect it
  std::vector<glm::vec3> ratio;                // per entry: t of eq. 25 per colour channel (1 for leaves)
};
struct SlCuts {
  std::vector<SlList> lists;
  std::vector<int> list_of_cluster;  // per receiver cluster (VertexReceivers::clusters)
  std::size_t bytes() const;
};
// Every leaf SL with its precomputed intersecting lists and ratio 1 (no hierarchy).
SlList flat_sl_list(const SlPose& pose);

// The two sets of receivers that the blocker accumulation, the exponential and the diffuse shading
// run over: the SLs' sample points (section 5.1) and the scene's vertices (section 6, direct light).
enum class Stage { Samples, Receivers };
inline const char* log_resource(Stage s) { return s == Stage::Samples ? kSampleLog : kLogVisibility; }
inline const char* visibility_resource(Stage s) { return s == Stage::Samples ? kSampleVisibility : kVisibility; }

struct Field {  // per receiver or sample point, order^2 floats
  int order = 0;
  std::vector<float> v;
};

struct Intensity {  // per SL: L^c_S = L_S * c_S (eq. 11), 3 x n^2 floats channel-major
  int order = 0;
  std::vector<float> v;
};

using Receivers = common::VertexReceivers;

struct Shading {  // per receiver: E/pi (unit albedo)
  std::vector<glm::vec3> value;
};

// --- Backend kernels ---------------------------------------------------------------------------
// A backend's implementations of the GPU passes, reading and writing the same frame resources as the
// host passes. accumulate / exponentiate: a stage's log-space blocker accumulation (HYB and OL);
// shade: common::ShadeKernel; intensity: section 5.2 (eqs. 10-11); indirect: section 6.
struct DeviceKernels {
  std::function<void(const Settings&, render::FrameContext&, Stage)> accumulate;
  std::function<void(const Settings&, render::FrameContext&, Stage)> exponentiate;
  common::ShadeKernel shade;
  std::function<void(const Settings&, render::FrameContext&)> intensity;
  std::function<void(const Settings&, render::FrameContext&)> indirect;
};
// Registers (or replaces) `backend`'s kernels; plan() adds them to every graph it builds after.
void register_device_kernels(const std::string& backend, DeviceKernels kernels);
// The Vulkan backend's kernels (sl_vulkan.cpp; softgi::techniques_vulkan only).
void register_vulkan_kernels();

// --- The receiver kernel of section 6 -----------------------------------------------------------
// Per receiver p with normal N: L^I_p / rho = sum_i Lbar_i Vbar_i (eqs. 13-15), Lbar_i = w_theta . L^c
// (eqs. 16-18, rotated into the SL's frame), Vbar_i = rho_N . (exp(S_i) - exp(S_i + G_i)) (eqs. 21-24)
// with S_i the summed log vectors of the SLs before S_i in `blocking` order, the intersecting SLs of
// its own object left out. rho_N = clamped cosine / pi, so the result is E/pi like the direct shading.
struct IndirectStats {
  long long lights = 0;        // SL-receiver pairs shaded (after the replacement rules)
  long long eliminated = 0;    // SL-receiver pairs the rules removed
  long long clamped = 0;       // Vbar below 0 set to 0
  long long exps = 0;
  double exp_flops = 0.0;      // floating-point operations of the exponentials' SH squares and products
  long long rays = 0;          // RayCast: rays cast
};
void accumulate_indirect(const Settings& s, const Tables& t, const SlPose& pose, const Intensity& lc, const SlList& list,
                         const ReceiverSoA& rec, std::size_t begin, std::size_t end, glm::vec3* out, IndirectStats& stats);

// RayCast (a reference for the two functions above): per receiver, E/pi = (1/pi) int L(w) max(0, N.w) dw
// over ray_strata^2 stratified cosine-weighted directions, L(w) the intensity L^c of the SL a
// ray hits at the point of that SL's sphere it sees (in the SL's rest frame). The replacement rules
// adjust the spheres the rays are tested against, as for Sh. With the paper's precomputed occlusion
// an SL counts where no SL in front of it blocks it except the intersecting SLs of its own object
// (which it ignores, section 6.2); with the occlusion at run time (`pre.intersecting`) only the
// nearest SL a ray hits counts. Every leaf SL, no hierarchy (its cut and ratios are Sh's).
void accumulate_indirect_ray_cast(const Settings& s, const SlPose& pose, const Intensity& lc, const ReceiverSoA& rec, std::size_t begin,
                                  std::size_t end, glm::vec3* out, IndirectStats& stats);

// The same for one receiver with each list entry's terms returned: vbar[e] (0 where the rules
// eliminated it) and lbar[e], its average radiance times its ratio.
void indirect_terms(const Settings& s, const Tables& t, const SlPose& pose, const Intensity& lc, const SlList& list, const glm::vec3& p,
                    const glm::vec3& n, std::vector<float>& vbar, std::vector<glm::vec3>& lbar);
// Over every leaf (flat_sl_list).
void indirect_terms(const Settings& s, const Tables& t, const SlPose& pose, const Intensity& lc, const glm::vec3& p,
                    const glm::vec3& n, std::vector<float>& vbar, std::vector<glm::vec3>& lbar);

// Section 7.3, local lights "treated like SLs with user-defined intensity distributions": the
// scene's spherical lights as SLs of constant intensity (their radiance), each darkened by every leaf
// SL and light closer to p (eqs. 21-24): the sum of radiance x Vbar (E/pi) at receiver (p, n). Without
// a pose (no proxies), the lights' own caps.
glm::vec3 local_lights_term(const Settings& s, const Tables& t, const SlPose* pose, const std::vector<scene::SphericalLight>& lights,
                            const glm::vec3& p, const glm::vec3& n);
// local_lights_term of receivers [begin, end) of rec, each added to out[i - begin]: the same floats,
// the receivers' exponentials in one batch.
void add_local_lights(const Settings& s, const Tables& t, const SlPose* pose, const std::vector<scene::SphericalLight>& lights,
                      const ReceiverSoA& rec, std::size_t begin, std::size_t end, glm::vec3* out);

// Section 7.3: the cut of every object's SL hierarchy for a receiver cluster bounded by (pR, rR)
// (nodes with r < sin(theta_max)(|c - pR| - rR) taken whole, paper 004 eq. 36), the intersecting
// entries of each object, and each parent's reflection ratio (eq. 25) at the receiver (pstar, nstar):
// the summed Lbar Vbar of the leaves below it, computed over every leaf, over its own Lbar Vbar in
// the cut, per channel (1 where the parent contributes nothing, at most kMaxReflectionRatio).
inline constexpr float kMaxReflectionRatio = 8.0f;
SlList sl_cut(const Settings& s, const Tables& t, const SlPose& pose, const Intensity& lc, const SlList& flat, const glm::vec3& pR,
              float rR, const glm::vec3& pstar, const glm::vec3& nstar);

}  // namespace softgi::techniques::spherical_lights
