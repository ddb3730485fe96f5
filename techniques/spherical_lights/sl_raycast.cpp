#include "sl_raycast.hpp"

#include <algorithm>
#include <cmath>

namespace softgi::techniques::spherical_lights {

namespace {
constexpr std::uint32_t kLeafSize = 4;
constexpr double kEdgeSlack = 1e-9;
}  // namespace

bool intersect_triangle(const glm::vec3& origin, const glm::vec3& dir, const glm::vec3& v0, const glm::vec3& v1,
                        const glm::vec3& v2, float t_min, float t_max, RayHit& hit) {
  const glm::dvec3 o(origin), d(dir), a(v0);
  const glm::dvec3 e1 = glm::dvec3(v1) - a, e2 = glm::dvec3(v2) - a;
  const glm::dvec3 p = glm::cross(d, e2);
  const double det = glm::dot(e1, p);
  if (det == 0.0 || !std::isfinite(det)) return false;  // parallel to the plane (or degenerate)
  const double inv = 1.0 / det;
  const glm::dvec3 s = o - a;
  const double u = glm::dot(s, p) * inv;
  if (u < -kEdgeSlack || u > 1.0 + kEdgeSlack) return false;
  const glm::dvec3 q = glm::cross(s, e1);
  const double v = glm::dot(d, q) * inv;
  if (v < -kEdgeSlack || u + v > 1.0 + kEdgeSlack) return false;
  const double t = glm::dot(e2, q) * inv;
  if (!(t > t_min && t < t_max)) return false;
  hit.t = static_cast<float>(t);
  hit.b1 = static_cast<float>(std::clamp(u, 0.0, 1.0));
  hit.b2 = static_cast<float>(std::clamp(v, 0.0, 1.0 - static_cast<double>(hit.b1)));
  hit.back = glm::dot(d, glm::cross(e1, e2)) > 0.0;
  return true;
}

TriangleBvh::TriangleBvh(std::span<const glm::vec3> positions, std::span<const glm::uvec3> triangles)
    : pos_(positions.begin(), positions.end()), tris_(triangles.begin(), triangles.end()) {
  if (tris_.empty()) return;
  std::vector<glm::vec3> centroids(tris_.size());
  order_.resize(tris_.size());
  for (std::size_t i = 0; i < tris_.size(); ++i) {
    centroids[i] = (pos_[tris_[i].x] + pos_[tris_[i].y] + pos_[tris_[i].z]) / 3.0f;
    order_[i] = static_cast<std::uint32_t>(i);
  }
  nodes_.reserve(2 * tris_.size() / kLeafSize + 1);
  build(0, static_cast<std::uint32_t>(tris_.size()), centroids);
}

std::uint32_t TriangleBvh::build(std::uint32_t begin, std::uint32_t end, std::vector<glm::vec3>& centroids) {
  const std::uint32_t id = static_cast<std::uint32_t>(nodes_.size());
  nodes_.emplace_back();
  glm::vec3 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
  glm::vec3 clo = lo, chi = hi;
  for (std::uint32_t i = begin; i < end; ++i) {
    const glm::uvec3 t = tris_[order_[i]];
    for (int k = 0; k < 3; ++k) {
      lo = glm::min(lo, pos_[t[k]]);
      hi = glm::max(hi, pos_[t[k]]);
    }
    clo = glm::min(clo, centroids[order_[i]]);
    chi = glm::max(chi, centroids[order_[i]]);
  }
  // Pad by a relative epsilon so that float slab tests never cull a hit on the box's faces.
  const glm::vec3 pad = 1e-5f * (hi - lo) + 1e-6f * glm::max(glm::abs(lo), glm::abs(hi)) + 1e-30f;
  nodes_[id].lo = lo - pad;
  nodes_[id].hi = hi + pad;
  const glm::vec3 ext = chi - clo;
  if (end - begin <= kLeafSize || std::max({ext.x, ext.y, ext.z}) <= 0.0f) {
    nodes_[id].index = begin;
    nodes_[id].count = end - begin;
    return id;
  }
  const int axis = ext.x >= ext.y && ext.x >= ext.z ? 0 : (ext.y >= ext.z ? 1 : 2);
  const std::uint32_t mid = begin + (end - begin) / 2;
  std::nth_element(order_.begin() + begin, order_.begin() + mid, order_.begin() + end,
                   [&](std::uint32_t a, std::uint32_t b) { return centroids[a][axis] < centroids[b][axis]; });
  build(begin, mid, centroids);
  const std::uint32_t right = build(mid, end, centroids);
  nodes_[id].index = right;
  return id;
}

void TriangleBvh::all_hits(const glm::vec3& origin, const glm::vec3& dir, std::vector<RayHit>& out, float t_min,
                           float t_max) const {
  out.clear();
  if (nodes_.empty()) return;
  // A zero component becomes a tiny one: finite reciprocals keep the slab test free of 0 * inf.
  glm::vec3 inv;
  for (int k = 0; k < 3; ++k) {
    const float d = dir[k] == 0.0f ? 1e-30f : dir[k];
    inv[k] = 1.0f / d;
  }
  std::uint32_t stack[128];
  int top = 0;
  stack[top++] = 0;
  RayHit hit;
  while (top > 0) {
    const Node& n = nodes_[stack[--top]];
    const glm::vec3 t0 = (n.lo - origin) * inv, t1 = (n.hi - origin) * inv;
    const glm::vec3 tn = glm::min(t0, t1), tf = glm::max(t0, t1);
    const float enter = std::max({tn.x, tn.y, tn.z, t_min}), leave = std::min({tf.x, tf.y, tf.z, t_max});
    if (!(enter <= leave * (1.0f + 1e-6f) + 1e-30f)) continue;
    if (n.count > 0) {
      for (std::uint32_t i = n.index; i < n.index + n.count; ++i) {
        const glm::uvec3 t = tris_[order_[i]];
        if (intersect_triangle(origin, dir, pos_[t.x], pos_[t.y], pos_[t.z], t_min, t_max, hit)) {
          hit.triangle = order_[i];
          out.push_back(hit);
        }
      }
    } else {
      stack[top++] = n.index;
      stack[top++] = static_cast<std::uint32_t>(&n - nodes_.data()) + 1;
    }
  }
  std::sort(out.begin(), out.end(),
            [](const RayHit& a, const RayHit& b) { return a.t < b.t || (a.t == b.t && a.triangle < b.triangle); });
}

}  // namespace softgi::techniques::spherical_lights
