// Paper 001 sections 4.2 and 5.2: segments, sample points, albedo SH and Voronoi basis sums.
#include "sl_precompute.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>

#include "sl_raycast.hpp"
#include "softgi/sh/sh.hpp"

namespace softgi::techniques::spherical_lights {

namespace {

constexpr double kPi = sh::kPi;

[[noreturn]] void fail(const scene::ProxySet& set, const std::string& what) {
  throw std::invalid_argument("spherical_lights::precompute_object: proxy set '" + set.name + "': " + what);
}

bool finite(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

// Solid-angle primitive of a cube face at (x, y) (face at distance 1): texel solid angle is its
// inclusion-exclusion over the texel's corners.
double cube_area(double x, double y) { return std::atan2(x * y, std::sqrt(x * x + y * y + 1.0)); }

glm::vec3 cube_direction(int face, double u, double v) {
  const int axis = face / 2;
  glm::dvec3 d(0.0);
  d[axis] = face % 2 == 0 ? 1.0 : -1.0;
  d[(axis + 1) % 3] = u;
  d[(axis + 2) % 3] = v;
  return glm::vec3(glm::normalize(d));
}

}  // namespace

std::vector<glm::vec3> geodesic_directions(int frequency) {
  if (frequency < 1)
    throw std::invalid_argument("spherical_lights::geodesic_directions: frequency " + std::to_string(frequency) + " < 1");
  const double phi = 0.5 * (1.0 + std::sqrt(5.0));
  std::vector<glm::dvec3> ico;
  for (double a : {-1.0, 1.0})
    for (double b : {-phi, phi}) {
      ico.push_back({0.0, a, b});
      ico.push_back({a, b, 0.0});
      ico.push_back({b, 0.0, a});
    }
  // Edges have length 2 in these coordinates; faces are the triangles of edges.
  auto edge = [&](std::size_t i, std::size_t j) { return std::abs(glm::length(ico[i] - ico[j]) - 2.0) < 1e-9; };
  std::vector<std::array<std::size_t, 2>> edges;
  std::vector<std::array<std::size_t, 3>> faces;
  for (std::size_t i = 0; i < 12; ++i)
    for (std::size_t j = i + 1; j < 12; ++j) {
      if (!edge(i, j)) continue;
      edges.push_back({i, j});
      for (std::size_t k = j + 1; k < 12; ++k)
        if (edge(i, k) && edge(j, k)) faces.push_back({i, j, k});
    }
  const int f = frequency;
  std::vector<glm::vec3> out;
  out.reserve(static_cast<std::size_t>(10 * f * f + 2));
  for (const auto& v : ico) out.push_back(glm::vec3(glm::normalize(v)));
  for (const auto& e : edges)
    for (int t = 1; t < f; ++t) out.push_back(glm::vec3(glm::normalize(double(f - t) * ico[e[0]] + double(t) * ico[e[1]])));
  for (const auto& fc : faces)
    for (int i = 1; i < f; ++i)
      for (int j = 1; i + j < f; ++j)
        out.push_back(glm::vec3(glm::normalize(double(i) * ico[fc[0]] + double(j) * ico[fc[1]] + double(f - i - j) * ico[fc[2]])));
  return out;
}

std::vector<glm::dvec3> stratified_directions(int strata, unsigned seed) {
  if (strata < 1)
    throw std::invalid_argument("spherical_lights::stratified_directions: strata " + std::to_string(strata) + " < 1");
  std::mt19937 rng(seed);
  auto uniform = [&] { return (static_cast<double>(rng()) + 0.5) * (1.0 / 4294967296.0); };  // (0, 1)
  std::vector<glm::dvec3> out;
  out.reserve(static_cast<std::size_t>(strata) * strata);
  for (int a = 0; a < strata; ++a)
    for (int b = 0; b < strata; ++b) {
      const double u = (a + uniform()) / strata, v = (b + uniform()) / strata;
      const double z = 1.0 - 2.0 * u, r = std::sqrt(std::max(0.0, 1.0 - z * z)), ph = 2.0 * kPi * v;
      out.push_back({r * std::cos(ph), r * std::sin(ph), z});
    }
  return out;
}

int nearest_direction(const std::vector<glm::vec3>& directions, const glm::dvec3& w) {
  int best = 0;
  double best_dot = -std::numeric_limits<double>::infinity();
  for (std::size_t j = 0; j < directions.size(); ++j) {
    const double d = glm::dot(glm::dvec3(directions[j]), w);
    if (d > best_dot) {
      best_dot = d;
      best = static_cast<int>(j);
    }
  }
  return best;
}

VoronoiBasis voronoi_basis_sums(const std::vector<glm::vec3>& directions, int order, int strata, unsigned seed) {
  sh::check_order(order, "spherical_lights::voronoi_basis_sums");
  if (directions.empty()) throw std::invalid_argument("spherical_lights::voronoi_basis_sums: no directions");
  const int n2 = order * order;
  const std::vector<glm::dvec3> samples = stratified_directions(strata, seed);
  VoronoiBasis b;
  b.order = order;
  b.total = static_cast<int>(samples.size());
  b.sums.assign(directions.size() * n2, 0.0);
  b.counts.assign(directions.size(), 0);
  std::array<double, sh::kMaxCoeffs> y{};
  const double scale = 4.0 * kPi / b.total;  // eq. 9's Monte Carlo weight, folded into Y_j
  for (const glm::dvec3& w : samples) {
    const int j = nearest_direction(directions, w);
    sh::eval_basis(order, sh::Vec3<double>{w.x, w.y, w.z}, y.data());
    for (int i = 0; i < n2; ++i) b.sums[static_cast<std::size_t>(j) * n2 + i] += scale * y[i];
    ++b.counts[j];
  }
  return b;
}

double sl_distance(const glm::vec3& p, const scene::Sphere& s) {
  return glm::length(glm::dvec3(p) - glm::dvec3(s.center)) / s.radius;
}

int nearest_sl(const std::vector<scene::Sphere>& spheres, const glm::vec3& p) {
  int best = 0;
  double best_d = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < spheres.size(); ++i) {
    const double d = sl_distance(p, spheres[i]);
    if (d < best_d) {
      best_d = d;
      best = static_cast<int>(i);
    }
  }
  return best;
}

bool in_segment(const std::vector<scene::Sphere>& spheres, std::size_t i, const glm::vec3& p) {
  double best = std::numeric_limits<double>::infinity();
  for (const auto& s : spheres) best = std::min(best, sl_distance(p, s));
  return sl_distance(p, spheres[i]) <= (1.0 + 1e-5) * best;
}

std::size_t ObjectSls::bytes() const {
  std::size_t b = directions.size() * sizeof(glm::vec3);
  for (const auto* list : {&sls, &groups})
    for (const auto& s : *list) {
    b += sizeof(scene::Sphere) + sizeof(SampleOutcomes);
    b += s.sample_positions.size() * sizeof(glm::vec3) + s.sample_normals.size() * sizeof(glm::vec3);
    b += s.sample_direction.size() * sizeof(int) + s.sample_case.size() * sizeof(SampleCase);
    b += s.basis_sums.size() * sizeof(float) + s.albedo_sh.size() * sizeof(float);
    b += s.vertices.size() * sizeof(std::uint32_t) + s.intersecting.size() * sizeof(int);
    }
  return b;
}

ObjectSls precompute_object(const scene::Scene& scene, int object_node, const scene::ProxySet& set,
                            const PrecomputeOptions& options, const std::vector<SlGroup>* groups) {
  // --- input checks ---
  if (options.order < 1 || options.order > sh::kMaxOrder)
    fail(set, "order " + std::to_string(options.order) + " outside [1, " + std::to_string(sh::kMaxOrder) + "]");
  if (options.geodesic_frequency < 1) fail(set, "geodesic_frequency " + std::to_string(options.geodesic_frequency) + " < 1");
  if (options.cubemap_resolution < 1) fail(set, "cubemap_resolution " + std::to_string(options.cubemap_resolution) + " < 1");
  if (options.projection_strata < 1) fail(set, "projection_strata " + std::to_string(options.projection_strata) + " < 1");
  if (object_node < 0 || object_node >= static_cast<int>(scene.nodes.size()))
    fail(set, "node " + std::to_string(object_node) + " out of range (" + std::to_string(scene.nodes.size()) + " nodes)");
  if (set.node >= 0 && set.node != object_node)
    fail(set, "bounds node " + std::to_string(set.node) + ", not node " + std::to_string(object_node));
  const int mesh_index = scene.nodes[object_node].mesh;
  if (mesh_index < 0 || mesh_index >= static_cast<int>(scene.meshes.size()))
    fail(set, "node '" + scene.nodes[object_node].name + "' has no mesh");
  const scene::Mesh& mesh = scene.meshes[mesh_index];
  if (mesh.triangles.empty() || mesh.positions.empty()) fail(set, "mesh '" + mesh.name + "' has no triangles");
  for (std::size_t v = 0; v < mesh.positions.size(); ++v)
    if (!finite(mesh.positions[v])) fail(set, "mesh '" + mesh.name + "': vertex " + std::to_string(v) + " is not finite");
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t)
    for (int k = 0; k < 3; ++k)
      if (mesh.triangles[t][k] >= mesh.positions.size())
        fail(set, "mesh '" + mesh.name + "': triangle " + std::to_string(t) + " has a vertex out of range");
  if (set.spheres.empty()) fail(set, "no spheres");
  for (std::size_t i = 0; i < set.spheres.size(); ++i) {
    const scene::Sphere& s = set.spheres[i];
    if (!finite(s.center) || !std::isfinite(s.radius) || !(s.radius > 0.0f))
      fail(set, "sphere " + std::to_string(i) + " has centre (" + std::to_string(s.center.x) + ", " +
                    std::to_string(s.center.y) + ", " + std::to_string(s.center.z) + ") radius " +
                    std::to_string(s.radius) + " (needs finite values and radius > 0)");
  }

  const int n = options.order, n2 = n * n;
  const std::vector<scene::Sphere>& spheres = set.spheres;
  const bool has_normals = mesh.normals.size() == mesh.positions.size();

  ObjectSls out;
  out.proxy_set = set.name;
  out.node = object_node;
  out.mesh = mesh_index;
  out.order = n;
  out.directions = geodesic_directions(options.geodesic_frequency);
  out.basis = voronoi_basis_sums(out.directions, n, options.projection_strata, options.seed);
  out.sls.resize(spheres.size());

  const TriangleBvh bvh(mesh.positions, mesh.triangles);

  // Segments (eq. 2): each vertex's nearest light, and per light the triangles with a vertex in its segment.
  std::vector<std::vector<char>> in_set(spheres.size(), std::vector<char>(mesh.triangles.size(), 0));
  std::vector<std::vector<char>> vertex_in(spheres.size(), std::vector<char>(mesh.positions.size(), 0));
  for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
    out.sls[nearest_sl(spheres, mesh.positions[v])].vertices.push_back(static_cast<std::uint32_t>(v));
    for (std::size_t i = 0; i < spheres.size(); ++i) vertex_in[i][v] = in_segment(spheres, i, mesh.positions[v]);
  }
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t)
    for (std::size_t i = 0; i < spheres.size(); ++i) {
      const glm::uvec3 tri = mesh.triangles[t];
      if (vertex_in[i][tri.x] || vertex_in[i][tri.y] || vertex_in[i][tri.z]) {
        in_set[i][t] = 1;
        out.sls[i].triangles.push_back(static_cast<std::uint32_t>(t));
      }
    }

  auto hit_point = [&](const RayHit& h) {
    const glm::uvec3 tri = mesh.triangles[h.triangle];
    const float b0 = 1.0f - h.b1 - h.b2;
    return b0 * mesh.positions[tri.x] + h.b1 * mesh.positions[tri.y] + h.b2 * mesh.positions[tri.z];
  };
  // The interpolated vertex normal, turned to the side the winding calls outside.
  auto hit_normal = [&](const RayHit& h) {
    const glm::uvec3 tri = mesh.triangles[h.triangle];
    const glm::vec3 g = glm::cross(mesh.positions[tri.y] - mesh.positions[tri.x], mesh.positions[tri.z] - mesh.positions[tri.x]);
    glm::vec3 nrm(0.0f);
    if (has_normals) {
      const float b0 = 1.0f - h.b1 - h.b2;
      nrm = b0 * mesh.normals[tri.x] + h.b1 * mesh.normals[tri.y] + h.b2 * mesh.normals[tri.z];
    }
    const float len = glm::length(nrm);
    if (!(len > 1e-6f)) return glm::normalize(g);
    nrm /= len;
    return glm::dot(nrm, g) < 0.0f ? -nrm : nrm;
  };

  scene::PosedObject rest;  // rest pose for scene::surface_albedo
  rest.node = object_node;
  rest.mesh = mesh_index;
  rest.material = mesh.material;
  rest.source = &mesh;

  // Cube-map texel directions and exact solid angles (shared by every light).
  const int R = options.cubemap_resolution;
  std::vector<glm::vec3> texel_dir;
  std::vector<double> texel_sa;
  std::vector<double> texel_y;
  texel_dir.reserve(6 * R * R);
  for (int face = 0; face < 6; ++face)
    for (int j = 0; j < R; ++j)
      for (int i = 0; i < R; ++i) {
        const double u0 = 2.0 * i / R - 1.0, u1 = 2.0 * (i + 1) / R - 1.0;
        const double v0 = 2.0 * j / R - 1.0, v1 = 2.0 * (j + 1) / R - 1.0;
        texel_dir.push_back(cube_direction(face, 0.5 * (u0 + u1), 0.5 * (v0 + v1)));
        texel_sa.push_back(cube_area(u0, v0) - cube_area(u0, v1) - cube_area(u1, v0) + cube_area(u1, v1));
      }
  texel_y.resize(texel_dir.size() * n2);
  for (std::size_t k = 0; k < texel_dir.size(); ++k) {
    const glm::dvec3 d(texel_dir[k]);
    sh::eval_basis(n, sh::Vec3<double>{d.x, d.y, d.z}, texel_y.data() + k * n2);
  }

  // One light: centre c, segment membership seg(p), triangle set tri_in(t).
  std::vector<RayHit> hits, back_hits;
  auto compute_light = [&](SphericalLightData& L, const glm::vec3& c, const auto& seg, const auto& tri_in) {
    // Sample points (section 4.2, three cases).
    for (std::size_t j = 0; j < out.directions.size(); ++j) {
      const glm::vec3 w = out.directions[j];
      bvh.all_hits(c, w, hits);
      const RayHit* chosen = nullptr;
      SampleCase kind = SampleCase::BackHit;
      if (!hits.empty()) {
        for (auto it = hits.rbegin(); it != hits.rend(); ++it)  // farthest first
          if (it->back && seg(hit_point(*it))) {
            chosen = &*it;
            break;
          }
        if (chosen) ++L.outcomes.back_hit;
        else ++L.outcomes.occluded;  // case 2: another light covers this direction (precomputed occlusion)
      } else {
        bvh.all_hits(c, -w, hits);  // case 3: centre outside; the opposite ray's front sides
        kind = SampleCase::OppositeFront;
        for (const RayHit& h : hits)
          if (!h.back && seg(hit_point(h))) {
            chosen = &h;
            break;
          }
        if (chosen) ++L.outcomes.opposite_front;
        else ++L.outcomes.missed;
      }
      if (!chosen) continue;
      L.sample_positions.push_back(hit_point(*chosen));
      L.sample_normals.push_back(hit_normal(*chosen));
      L.sample_direction.push_back(static_cast<int>(j));
      L.sample_case.push_back(kind);
      for (int k = 0; k < n2; ++k) L.basis_sums.push_back(static_cast<float>(out.basis.sums[j * n2 + k]));
    }

    // Albedo SH (end of section 4.2): back faces of the triangle set with the inverted depth test
    // (farthest), else the front faces behind the camera (the opposite ray, nearest), else nothing.
    std::vector<double> albedo(3 * n2, 0.0);
    for (std::size_t k = 0; k < texel_dir.size(); ++k) {
      bvh.all_hits(c, texel_dir[k], hits);
      const RayHit* chosen = nullptr;
      for (auto it = hits.rbegin(); it != hits.rend(); ++it)
        if (it->back && tri_in(it->triangle)) {
          chosen = &*it;
          break;
        }
      if (!chosen) {
        bvh.all_hits(c, -texel_dir[k], back_hits);
        for (const RayHit& h : back_hits)
          if (!h.back && tri_in(h.triangle)) {
            chosen = &h;
            break;
          }
      }
      if (!chosen) continue;
      const glm::vec3 a = scene::surface_albedo(scene, rest, chosen->triangle, chosen->b1, chosen->b2);
      for (int ch = 0; ch < 3; ++ch)
        for (int q = 0; q < n2; ++q) albedo[ch * n2 + q] += texel_sa[k] * a[ch] * texel_y[k * n2 + q];
    }
    L.albedo_sh.assign(albedo.begin(), albedo.end());
  };

  for (std::size_t i = 0; i < spheres.size(); ++i) {
    SphericalLightData& L = out.sls[i];
    L.sphere = spheres[i];
    const glm::vec3 c = spheres[i].center;
    for (std::size_t j = 0; j < spheres.size(); ++j)
      if (j != i && glm::length(c - spheres[j].center) < spheres[i].radius + spheres[j].radius)
        L.intersecting.push_back(static_cast<int>(j));
    if (options.intersecting == IntersectingOcclusion::Precomputed) {
      compute_light(L, c, [&](const glm::vec3& p) { return in_segment(spheres, i, p); },
                    [&](std::uint32_t t) { return in_set[i][t] != 0; });
    } else {
      // Occlusion at run time: the surface behind an intersecting light's segment is this light's
      // too, and the receivers decide per direction which of the two they see.
      auto seg = [&](const glm::vec3& p) {
        if (in_segment(spheres, i, p)) return true;
        for (int j : L.intersecting)
          if (in_segment(spheres, static_cast<std::size_t>(j), p)) return true;
        return false;
      };
      auto tri = [&](std::uint32_t t) {
        if (in_set[i][t]) return true;
        for (int j : L.intersecting)
          if (in_set[j][t]) return true;
        return false;
      };
      compute_light(L, c, seg, tri);
    }
  }

  // Groups (paper 001 section 7.3, parent SLs of a hierarchy): the same rules with the union of the
  // leaves' segments and triangle sets.
  if (groups) {
    out.groups.resize(groups->size());
    for (std::size_t g = 0; g < groups->size(); ++g) {
      const SlGroup& grp = (*groups)[g];
      if (!finite(grp.sphere.center) || !(grp.sphere.radius > 0.0f) || !std::isfinite(grp.sphere.radius))
        fail(set, "group " + std::to_string(g) + " has a bad sphere");
      std::vector<char> member(spheres.size(), 0);
      for (int leaf : grp.leaves) {
        if (leaf < 0 || leaf >= static_cast<int>(spheres.size()))
          fail(set, "group " + std::to_string(g) + " names leaf " + std::to_string(leaf) + " of " + std::to_string(spheres.size()));
        member[leaf] = 1;
      }
      SphericalLightData& L = out.groups[g];
      L.sphere = grp.sphere;
      for (int leaf : grp.leaves) L.vertices.insert(L.vertices.end(), out.sls[leaf].vertices.begin(), out.sls[leaf].vertices.end());
      std::sort(L.vertices.begin(), L.vertices.end());
      auto seg = [&](const glm::vec3& p) {
        for (std::size_t i = 0; i < spheres.size(); ++i)
          if (member[i] && in_segment(spheres, i, p)) return true;
        return false;
      };
      auto tri = [&](std::uint32_t t) {
        for (std::size_t i = 0; i < spheres.size(); ++i)
          if (member[i] && in_set[i][t]) return true;
        return false;
      };
      compute_light(L, grp.sphere.center, seg, tri);
    }
  }
  return out;
}

}  // namespace softgi::techniques::spherical_lights
