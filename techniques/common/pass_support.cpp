#include "pass_support.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "softgi/sh/sh.hpp"

namespace softgi::techniques::common {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

namespace {
bool finite(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }
}  // namespace

void blocker_spheres_input(const std::string& technique, const std::string& effects, const scene::Scene& scene,
                           const std::string& resource, render::PassGraph& graph, std::set<std::string>& empty) {
  graph.add_input(resource);
  bool spheres = false;
  for (const auto& p : scene.proxies) spheres = spheres || !p.spheres.empty();
  if (!spheres) empty.insert(resource);
  graph.warn_if_empty(resource, "scene '" + scene.name + "' has no proxy spheres, so " + technique + " renders it without " +
                                    effects + " (give its objects \"proxies\" in a scene file, or pass --fit-proxies N)");
}

void warn_coarse_receivers(const std::string& technique, render::FrameContext& ctx) {
  std::vector<float> radii;
  for (const auto& set : ctx.posed.proxies)
    for (const auto& sp : set)
      if (std::isfinite(sp.radius) && sp.radius > 0.0f) radii.push_back(sp.radius);
  if (radii.empty()) return;
  std::nth_element(radii.begin(), radii.begin() + radii.size() / 2, radii.end());
  const double median = radii[radii.size() / 2];
  for (const auto& o : ctx.posed.objects) {
    if (!o.source) continue;
    double sum = 0.0;
    std::size_t edges = 0;
    for (const glm::uvec3& t : o.source->triangles) {
      if (t.x >= o.positions.size() || t.y >= o.positions.size() || t.z >= o.positions.size()) continue;
      const glm::vec3 a = o.positions[t.x], b = o.positions[t.y], c = o.positions[t.z];
      sum += static_cast<double>(glm::length(b - a)) + glm::length(c - b) + glm::length(a - c);
      edges += 3;
    }
    if (!edges) continue;
    const double mean = sum / static_cast<double>(edges);
    if (!(mean > median)) continue;
    const std::string name = o.node >= 0 && o.node < static_cast<int>(ctx.scene.nodes.size()) ? ctx.scene.nodes[o.node].name : "?";
    std::ostringstream os;
    os.precision(3);
    os << "object '" << name << "' (node " << o.node << ") has edges of " << mean << " m on average, longer than the median radius "
       << median << " m of the proxy spheres that shade it: " << technique
       << " shades at vertices, so its shadows there are blocky or missing (tessellate it finer; builtin:plane and builtin:box "
          "take \"segments\")";
    ctx.warn(os.str());
  }
}

void check_proxy_spheres(const std::string& technique, const render::FrameContext& ctx, bool check_albedo) {
  for (std::size_t s = 0; s < ctx.posed.proxies.size(); ++s)
    for (std::size_t i = 0; i < ctx.posed.proxies[s].size(); ++i) {
      const scene::Sphere& sp = ctx.posed.proxies[s][i];
      if (!(sp.radius >= 0.0f) || !std::isfinite(sp.radius) || !finite(sp.center)) {
        const std::string name = s < ctx.scene.proxies.size() ? ctx.scene.proxies[s].name : std::to_string(s);
        std::ostringstream os;
        os << technique << ": proxy set '" << name << "' of scene '" << ctx.scene.name << "': sphere " << i << " at time "
           << ctx.posed.time << " has centre (" << sp.center.x << ", " << sp.center.y << ", " << sp.center.z << ") and radius "
           << sp.radius << " (expected finite values, radius >= 0)";
        throw std::invalid_argument(os.str());
      }
    }
  if (!check_albedo) return;
  for (const scene::ProxySet& set : ctx.scene.proxies)
    for (std::size_t k = 0; k <= set.sphere_albedo.size(); ++k) {
      const bool whole = k == set.sphere_albedo.size();
      const glm::vec3 a = whole ? set.albedo : set.sphere_albedo[k];
      if (!finite(a) || a.x < 0.0f || a.y < 0.0f || a.z < 0.0f) {
        std::ostringstream os;
        os << technique << ": proxy set '" << set.name << "' of scene '" << ctx.scene.name << "' has "
           << (whole ? std::string("albedo") : "sphere " + std::to_string(k) + " albedo") << " (" << a.x << ", " << a.y << ", "
           << a.z << ") (expected finite values >= 0)";
        throw std::invalid_argument(os.str());
      }
    }
}

std::string environment_signature(const scene::Environment& env) {
  std::ostringstream key;
  const auto v3 = [&key](const glm::vec3& v) { key << v.x << ',' << v.y << ',' << v.z << '|'; };
  key.precision(9);
  key << &env << '|' << static_cast<int>(env.kind) << '|' << env.map_path << '|' << env.intensity << '|' << env.rotation_y << '|'
      << env.sun_radius << '|' << env.map_rgb.size() << '|';
  for (const glm::vec3& v : {env.zenith, env.horizon, env.ground, env.sun_direction, env.sun_radiance}) v3(v);
  return key.str();
}

std::vector<glm::vec3> windowed_environment_sh(const std::string& technique, const scene::Scene& scene, int order,
                                               double window_h) {
  std::vector<glm::vec3> L = scene::environment_sh(scene.environment, order);
  if (window_h > 0.0)  // paper 004 section 7: window the lighting
    for (int l = 0; l < order; ++l)
      for (int m = -l; m <= l; ++m) L[sh::index(l, m)] *= static_cast<float>(sh::window_factor(l, window_h));
  for (const auto& v : L)
    if (!finite(v))
      throw std::invalid_argument(technique + ": the environment of scene '" + scene.name + "' has a non-finite SH projection");
  return L;
}

std::shared_ptr<const sh::ShTables> accumulation_tables(int order, int resolution, double log_threshold) {
  sh::TableOptions opt;
  opt.order = order;
  opt.resolution = resolution;
  opt.log_threshold = log_threshold;
  opt.measure_error = false;
  return std::make_shared<const sh::ShTables>(opt);
}

std::shared_ptr<const common::LightLobeTable> LightTableCache::get(int order, double window_h, bool& cached) {
  const auto key = std::make_pair(order, window_h);
  {
    std::lock_guard<std::mutex> lock(m_);
    auto it = tables_.find(key);
    if (it != tables_.end()) {
      cached = true;
      return it->second;
    }
  }
  cached = false;
  auto t = std::make_shared<const common::LightLobeTable>(common::make_light_lobe_table(order, kRowsTheta, kRowsF, window_h));
  std::lock_guard<std::mutex> lock(m_);
  tables_[key] = t;
  return t;
}

void LightTableCache::run_pass(int order, double window_h, render::FrameContext& ctx, const std::string& resource) {
  bool cached = false;
  auto t = get(order, window_h, cached);
  auto& rec = ctx.record();
  rec.counters["cached"] = cached;
  rec.counters["lights"] = static_cast<double>(ctx.posed.lights.size());
  rec.counters["max_fit_error"] = t->max_fit_error;
  rec.bytes = t->bytes();
  ctx.put<std::shared_ptr<const common::LightLobeTable>>(resource, std::move(t));
}

}  // namespace softgi::techniques::common
