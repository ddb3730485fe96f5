// Proxy sets fitted on demand, with a disk cache (softgi/io/proxy_fit.hpp).
#include "softgi/io/proxy_fit.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "fnv.hpp"
#include "softgi/io/scene_file.hpp"
#include "softgi/proxies/binding.hpp"

namespace softgi::io {

namespace fs = std::filesystem;

proxies::FitOptions ProxyFitSpec::options() const {
  proxies::FitOptions o;
  o.spheres = spheres;
  o.seed = seed;
  o.max_iterations = iterations;
  o.grid_resolution = grid;
  return o;
}

std::string proxy_cache_dir() {
  auto env = [](const char* name) -> std::string {
    const char* v = std::getenv(name);
    return v ? std::string(v) : std::string();
  };
  const std::string own = env("SOFTGI_CACHE_DIR");
  if (own == "off") return "";
  if (!own.empty()) return own;
  if (const std::string xdg = env("XDG_CACHE_HOME"); !xdg.empty()) return (fs::path(xdg) / "softgi").string();
  if (const std::string home = env("HOME"); !home.empty()) return (fs::path(home) / ".cache" / "softgi").string();
  return "";
}

namespace {

const scene::Mesh& node_mesh(const scene::Scene& s, int node) {
  if (node < 0 || node >= static_cast<int>(s.nodes.size()) || s.nodes[node].mesh < 0 ||
      s.nodes[node].mesh >= static_cast<int>(s.meshes.size()))
    throw std::invalid_argument("proxy fit: node " + std::to_string(node) + " of scene '" + s.name + "' has no mesh");
  return s.meshes[s.nodes[node].mesh];
}

std::string node_label(const scene::Scene& s, int node) {
  return "node " + std::to_string(node) + " '" + s.nodes[node].name + "'";
}

// Deterministic points in a triangle, as barycentrics (b1, b2): the centroids of the n^2 congruent
// triangles of its n-fold edge subdivision. They cover it evenly, and their mean is the triangle's
// centroid, so the average of a function linear over the triangle (vertex colours) is exact.
void triangle_points(int n, std::vector<glm::vec2>& out) {
  out.clear();
  const float inv = 1.0f / static_cast<float>(n);
  for (int i = 0; i < n; ++i)
    for (int j = 0; i + j < n; ++j) {
      out.emplace_back((i + 1.0f / 3.0f) * inv, (j + 1.0f / 3.0f) * inv);                    // upright
      if (i + j < n - 1) out.emplace_back((i + 2.0f / 3.0f) * inv, (j + 2.0f / 3.0f) * inv);  // inverted
    }
}

}  // namespace

std::uint64_t proxy_fit_key(const scene::Scene& scene, int node, const ProxyFitSpec& spec) {
  const scene::Mesh& m = node_mesh(scene, node);
  Fnv f;
  f.pod(kProxyFitVersion);
  f.pod(spec.spheres);
  f.pod(spec.seed);
  f.pod(spec.iterations);
  f.pod(spec.grid);
  f.vec(m.positions);
  f.vec(m.triangles);
  f.vec(m.joints);
  f.vec(m.weights);
  f.vec(m.uvs);
  f.vec(m.colors);
  if (m.material >= 0 && m.material < static_cast<int>(scene.materials.size())) {
    const scene::Material& mat = scene.materials[m.material];
    f.pod(mat.albedo);
    if (mat.albedo_texture >= 0 && mat.albedo_texture < static_cast<int>(scene.textures.size())) {
      const scene::Texture& t = scene.textures[mat.albedo_texture];
      f.pod(t.width);
      f.pod(t.height);
      f.vec(t.texels);
    }
  }
  return f.h;
}

void average_surface_albedo(const scene::Scene& scene, int node, scene::ProxySet& set) {
  const scene::Mesh& mesh = node_mesh(scene, node);
  scene::PosedObject rest;  // surface_albedo reads only the material and the source mesh
  rest.node = node;
  rest.mesh = scene.nodes[node].mesh;
  rest.material = mesh.material;
  rest.source = &mesh;
  const scene::Texture* tex = nullptr;
  if (mesh.material >= 0 && mesh.material < static_cast<int>(scene.materials.size())) {
    const int t = scene.materials[mesh.material].albedo_texture;
    if (t >= 0 && t < static_cast<int>(scene.textures.size()) && mesh.uvs.size() == mesh.positions.size()) tex = &scene.textures[t];
  }
  const std::size_t ns = set.spheres.size();
  std::vector<glm::dvec3> sum(ns, glm::dvec3(0.0));
  std::vector<double> area(ns, 0.0);
  glm::dvec3 total(0.0);
  double total_area = 0.0;
  std::vector<glm::vec2> pts;
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const glm::uvec3 tri = mesh.triangles[t];
    const glm::dvec3 a(mesh.positions[tri.x]), b(mesh.positions[tri.y]), c(mesh.positions[tri.z]);
    const double A = 0.5 * glm::length(glm::cross(b - a, c - a));
    if (!(A > 0.0) || !std::isfinite(A)) continue;
    // Enough samples that each texel the triangle covers in UV space is seen about once (a texture
    // varies per texel; a constant factor needs one sample).
    int n = 1;
    if (tex) {
      const glm::dvec2 ua(mesh.uvs[tri.x]), ub(mesh.uvs[tri.y]), uc(mesh.uvs[tri.z]);
      const glm::dvec2 e1 = ub - ua, e2 = uc - ua;
      const double uv_area = 0.5 * std::abs(e1.x * e2.y - e1.y * e2.x);
      const double texels = uv_area * tex->width * tex->height;
      n = std::clamp(static_cast<int>(std::ceil(std::sqrt(2.0 * std::max(texels, 0.0)))), 1, 32);
    } else if (mesh.colors.size() == mesh.positions.size()) {
      n = 1;  // colours vary linearly over a triangle: its centroid gives their average
    }
    triangle_points(n, pts);
    glm::dvec3 acc(0.0);
    for (const glm::vec2& p : pts) acc += glm::dvec3(scene::surface_albedo(scene, rest, t, p.x, p.y));
    const glm::dvec3 mean = acc / static_cast<double>(pts.size());
    total += A * mean;
    total_area += A;
    // The triangle's segment: the sphere its centroid is deepest inside (the fit bounds every
    // centroid), else the one whose surface is nearest.
    const glm::dvec3 centroid = (a + b + c) / 3.0;
    std::size_t best = 0;
    double best_depth = -1e300;
    for (std::size_t k = 0; k < ns; ++k) {
      const double depth = set.spheres[k].radius - glm::length(glm::dvec3(set.spheres[k].center) - centroid);
      if (depth > best_depth) {
        best_depth = depth;
        best = k;
      }
    }
    if (ns) {
      sum[best] += A * mean;
      area[best] += A;
    }
  }
  const glm::vec3 overall = total_area > 0.0 ? glm::vec3(total / total_area) : rest.material >= 0 && rest.material < static_cast<int>(scene.materials.size())
                                                                                       ? scene.materials[rest.material].albedo
                                                                                       : glm::vec3(0.8f);
  set.albedo = overall;
  set.sphere_albedo.assign(ns, overall);
  for (std::size_t k = 0; k < ns; ++k)
    if (area[k] > 0.0) set.sphere_albedo[k] = glm::vec3(sum[k] / area[k]);
}

ProxyFitOutcome fit_node_proxies(const scene::Scene& scene, int node, const ProxyFitSpec& spec, const std::string& cache_dir) {
  const scene::Mesh& mesh = node_mesh(scene, node);
  const std::uint64_t key = proxy_fit_key(scene, node, spec);
  // Without a disk cache, a fit is still made once per process (tests and sweeps load the same
  // scene many times).
  static std::mutex memo_mutex;
  static std::map<std::uint64_t, ProxyFitOutcome> memo;
  if (cache_dir.empty()) {
    std::lock_guard<std::mutex> lock(memo_mutex);
    if (auto it = memo.find(key); it != memo.end()) {
      ProxyFitOutcome o = it->second;
      o.from_cache = true;
      o.seconds = 0.0;
      o.set.node = node;
      o.set.name = scene.nodes[node].name;
      return o;
    }
  }
  auto remember = [&](const ProxyFitOutcome& o) {
    if (cache_dir.empty()) {
      std::lock_guard<std::mutex> lock(memo_mutex);
      memo.emplace(key, o);
    }
    return o;
  };
  ProxyFitOutcome out;
  char name[32];
  std::snprintf(name, sizeof name, "%016llx.json", static_cast<unsigned long long>(key));
  if (!cache_dir.empty()) {
    out.cache_file = (fs::path(cache_dir) / "proxies" / name).string();
    std::error_code ec;
    if (fs::is_regular_file(out.cache_file, ec)) {
      try {
        out.set = read_proxies_json(out.cache_file);
        if (!out.set.spheres.empty() && out.set.sphere_albedo.size() == out.set.spheres.size() &&
            out.set.joints.empty() == !mesh.skinned()) {
          out.from_cache = true;
          out.E = out.set.outside_volume_ratio;
          out.set.node = node;
          out.set.name = scene.nodes[node].name;
          return remember(out);
        }
      } catch (const std::exception&) {
        // A corrupt or foreign entry is refitted and replaced below.
      }
    }
  }
  const proxies::TriMesh tri = proxies::trimesh_of(mesh);
  try {
    proxies::mesh_volume(tri);
  } catch (const std::exception& e) {
    throw std::invalid_argument("proxy fit: " + node_label(scene, node) + " of scene '" + scene.name + "': " + e.what());
  }
  const auto t0 = std::chrono::steady_clock::now();
  const proxies::FitResult fit = proxies::fit_sphere_set(tri, spec.options());
  out.set = scene::ProxySet{};
  out.set.name = scene.nodes[node].name;
  out.set.node = node;
  out.set.spheres = fit.spheres;
  out.set.outside_volume_ratio = fit.E;
  out.E = fit.E;
  if (mesh.skinned()) proxies::bind_to_skin(out.set, mesh);
  average_surface_albedo(scene, node, out.set);
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!out.cache_file.empty()) {
    std::error_code ec;
    fs::create_directories(fs::path(out.cache_file).parent_path(), ec);
    try {
      if (!ec) write_proxies_json(out.cache_file, out.set);
    } catch (const std::exception&) {
      // An unwritable cache costs a refit next time, nothing else.
    }
    if (ec || !fs::is_regular_file(out.cache_file, ec)) out.cache_file.clear();
  }
  return remember(out);
}

int fit_missing_proxies(scene::Scene& scene, const ProxyFitSpec& spec, const std::string& cache_dir) {
  int added = 0;
  const int n = static_cast<int>(scene.nodes.size());
  for (int node = 0; node < n; ++node) {
    if (scene.nodes[node].mesh < 0) continue;
    bool has = false;
    for (const auto& p : scene.proxies) has = has || p.node == node;
    if (has) continue;
    const proxies::TriMesh tri = proxies::trimesh_of(node_mesh(scene, node));
    try {
      proxies::mesh_volume(tri);
    } catch (const std::exception& e) {
      scene.notices.push_back("no proxies fitted to " + node_label(scene, node) + ": " + e.what() +
                              " (it still receives shadows; it casts none)");
      continue;
    }
    ProxyFitOutcome o = fit_node_proxies(scene, node, spec, cache_dir);
    std::ostringstream os;
    os.precision(3);
    os << (o.from_cache ? "proxies of " : "fitted proxies to ") << node_label(scene, node) << ": " << o.set.spheres.size()
       << " spheres, E = " << o.E;
    if (o.from_cache)
      os << ", read from the cache " << o.cache_file;
    else
      os << ", " << o.seconds << " s" << (o.cache_file.empty() ? " (not cached)" : ", cached as " + o.cache_file);
    scene.notices.push_back(os.str());
    scene.proxies.push_back(std::move(o.set));
    ++added;
  }
  return added;
}

}  // namespace softgi::io
