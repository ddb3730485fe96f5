// A scene built in code for the backend tests: a square ground plane y = 0 and a tessellated sphere
// posed by its node's translation, seen by a camera above the plane. Everything a test checks is
// known in closed form from these constants.
#pragma once

#include <cmath>
#include <cstdlib>
#include <optional>
#include <stdexcept>
#include <string>

#include <glm/glm.hpp>

#include "softgi/backends/cpu_backend.hpp"
#include "softgi/render/common_passes.hpp"
#include "softgi/render/frame.hpp"
#include "softgi/render/gbuffer.hpp"
#include "softgi/render/params.hpp"
#include "softgi/scene/scene.hpp"

namespace softgi::testing {

inline constexpr double kPi = 3.14159265358979323846;

struct PlaneSphere {
  static constexpr float kHalfSize = 2.0f;  // plane spans [-2, 2] x [-2, 2] in x, z
  static constexpr float kRadius = 0.5f;
  static constexpr int kStacks = 24, kSlices = 48;
  static glm::vec3 center() { return {0.3f, 0.7f, -0.2f}; }
  static glm::vec3 plane_albedo() { return {0.5f, 0.6f, 0.7f}; }
  static glm::vec3 sphere_albedo() { return {0.9f, 0.2f, 0.1f}; }
  // Per-vertex colour of the plane, linear in (x, z), so barycentric interpolation reproduces it exactly.
  static glm::vec3 plane_color(const glm::vec3& p) {
    return {0.5f + 0.2f * p.x / kHalfSize, 0.7f, 0.6f + 0.3f * p.z / kHalfSize};
  }
  // Largest distance between the true sphere and a point of its tessellation, relative to the
  // radius: the centre of a quad cell (half its diagonal angle), 1 - cos(angle / 2).
  static double sagitta() {
    const double dphi = 2.0 * kPi / kSlices, dtheta = kPi / kStacks;
    return 1.0 - std::cos(0.5 * std::sqrt(dphi * dphi + dtheta * dtheta));
  }
};

inline scene::Scene make_plane_sphere_scene(int width = 128, int height = 96) {
  using P = PlaneSphere;
  scene::Scene s;
  s.name = "plane_sphere";
  s.source = "test";
  s.materials.resize(2);
  s.materials[0].name = "plane";
  s.materials[0].albedo = P::plane_albedo();
  s.materials[1].name = "sphere";
  s.materials[1].albedo = P::sphere_albedo();

  scene::Mesh plane;
  plane.name = "plane";
  const float h = P::kHalfSize;
  plane.positions = {{-h, 0, -h}, {-h, 0, h}, {h, 0, h}, {h, 0, -h}};
  plane.normals.assign(4, glm::vec3(0, 1, 0));
  for (const auto& p : plane.positions) plane.colors.push_back(P::plane_color(p));
  plane.triangles = {{0, 1, 2}, {0, 2, 3}};  // counter-clockwise seen from +y
  plane.material = 0;

  scene::Mesh sphere;  // centred at the origin; its node moves it to center()
  sphere.name = "sphere";
  sphere.material = 1;
  for (int i = 0; i <= P::kStacks; ++i) {
    const float theta = static_cast<float>(kPi) * i / P::kStacks;
    for (int j = 0; j <= P::kSlices; ++j) {
      const float phi = 2.0f * static_cast<float>(kPi) * j / P::kSlices;
      const glm::vec3 n(std::sin(theta) * std::cos(phi), std::cos(theta), -std::sin(theta) * std::sin(phi));
      sphere.positions.push_back(P::kRadius * n);
      sphere.normals.push_back(n);
    }
  }
  const int row = P::kSlices + 1;
  for (int i = 0; i < P::kStacks; ++i)
    for (int j = 0; j < P::kSlices; ++j) {
      const unsigned a = i * row + j, b = a + row, c = b + 1, d = a + 1;
      if (i != 0) sphere.triangles.push_back({a, b, d});  // no zero-area triangles at the poles
      if (i != P::kStacks - 1) sphere.triangles.push_back({d, b, c});
    }
  s.meshes = {plane, sphere};
  scene::Node n0;
  n0.name = "plane";
  n0.mesh = 0;
  scene::Node n1;
  n1.name = "sphere";
  n1.mesh = 1;
  n1.translation = P::center();
  s.nodes = {n0, n1};
  s.camera.position = {0.0f, 2.0f, 3.0f};
  s.camera.target = {0.0f, 0.4f, 0.0f};
  s.camera.fov_y_deg = 50.0f;
  s.camera.width = width;
  s.camera.height = height;
  return s;
}

// The sphere rises by 0.3 over one second (a one-clip animation of its node).
inline scene::Scene animated(scene::Scene sc) {
  scene::AnimationClip clip;
  clip.name = "rise";
  clip.duration = 1.0f;
  clip.loop = false;
  scene::AnimationChannel ch;
  ch.node = 1;
  ch.times = {0.0f, 1.0f};
  ch.values = {glm::vec4(PlaneSphere::center(), 0.0f), glm::vec4(PlaneSphere::center() + glm::vec3(0, 0.3f, 0), 0.0f)};
  clip.channels.push_back(ch);
  sc.clips.push_back(clip);
  sc.active_clip = 0;
  return sc;
}

// One proxy sphere equal to the sphere, bound to its node.
inline scene::Scene with_proxies(scene::Scene sc) {
  scene::ProxySet ps;
  ps.name = "sphere";
  ps.node = 1;
  ps.spheres.push_back({glm::vec3(0.0f), PlaneSphere::kRadius});
  sc.proxies.push_back(ps);
  return sc;
}

// Nearest positive hit of the ray o + t d with the plane y = 0 inside the square.
inline std::optional<float> hit_plane(const glm::vec3& o, const glm::vec3& d) {
  if (d.y == 0.0f) return std::nullopt;
  const float t = -o.y / d.y;
  if (!(t > 0.0f)) return std::nullopt;
  const glm::vec3 p = o + t * d;
  if (std::abs(p.x) > PlaneSphere::kHalfSize || std::abs(p.z) > PlaneSphere::kHalfSize) return std::nullopt;
  return t;
}

// Distance from the sphere centre to the ray's line (d unit).
inline float ray_center_distance(const glm::vec3& o, const glm::vec3& d) {
  const glm::vec3 oc = PlaneSphere::center() - o;
  return glm::length(oc - glm::dot(oc, d) * d);
}

// Sets SOFTGI_CPU_VISIBILITY (the CPU G-buffer's visibility method) for the scope; "" unsets it
// (the default). Restores what was there.
class ScopedVisibility {
 public:
  explicit ScopedVisibility(const std::string& v) {
    if (const char* old = std::getenv("SOFTGI_CPU_VISIBILITY")) saved_ = old, had_ = true;
    if (v.empty())
      unsetenv("SOFTGI_CPU_VISIBILITY");
    else
      setenv("SOFTGI_CPU_VISIBILITY", v.c_str(), 1);
  }
  ~ScopedVisibility() {
    if (had_)
      setenv("SOFTGI_CPU_VISIBILITY", saved_.c_str(), 1);
    else
      unsetenv("SOFTGI_CPU_VISIBILITY");
  }
  ScopedVisibility(const ScopedVisibility&) = delete;
  ScopedVisibility& operator=(const ScopedVisibility&) = delete;

 private:
  std::string saved_;
  bool had_ = false;
};

// The CPU backend's shared G-buffer pass with the given visibility method (ScopedVisibility):
// "gbuffer" at scale 1, else "receiver_gbuffer" at `scale` (no display G-buffer in the frame, so it
// is not copied), holding `planes` (a receiver buffer holds every plane); `rec`: its pass record.
inline render::GBuffer cpu_gbuffer(const scene::Scene& sc, const scene::PosedScene& posed, const char* visibility, int scale,
                                   int w, int h, unsigned planes = render::kGBufferAll, render::PassRecord* rec = nullptr) {
  backends::register_cpu_backend();
  ScopedVisibility v(visibility);
  const std::string pass = scale == 1 ? "gbuffer" : "receiver_gbuffer";
  const render::PassFn* fn = render::find_shared_pass_impl(pass, backends::cpu::kBackendName);
  if (!fn) throw std::logic_error("no CPU " + pass);
  render::ParamSet params({render::ParamDesc::integer("receiver_scale", 1, 1, 64, "receiver buffer scale")});
  params.set("receiver_scale", std::to_string(scale));
  render::FrameResult result;
  render::FrameContext ctx(sc, posed, params, w, h, result);
  ctx.set_gbuffer_planes(planes);
  result.passes.push_back(render::PassRecord{pass});
  (*fn)(ctx);
  if (rec) *rec = result.passes.back();
  return ctx.get<render::GBuffer>(scale == 1 ? render::kGBuffer : render::kReceiverGBuffer);
}

// A silhouette pixel: its 3x3 neighbourhood in g holds more than one object (or background).
inline bool silhouette(const render::GBuffer& g, int x, int y) {
  const int o = g.object[static_cast<std::size_t>(y) * g.width + x];
  for (int dy = -1; dy <= 1; ++dy)
    for (int dx = -1; dx <= 1; ++dx) {
      const int xx = x + dx, yy = y + dy;
      if (xx < 0 || yy < 0 || xx >= g.width || yy >= g.height) continue;
      if (g.object[static_cast<std::size_t>(yy) * g.width + xx] != o) return true;
    }
  return false;
}

}  // namespace softgi::testing
