// A small triangle BVH with an all-hits ray query, for the spherical lights' precomputation (paper 001
// section 4.2: rays from each light's centre, every intersection with the object's surface). Median
// split on the longest centroid axis (O(n log n) build), leaves of <= 4 triangles. Not installed;
// include by path.
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include <glm/glm.hpp>

namespace softgi::techniques::spherical_lights {

struct RayHit {
  float t = 0.0f;           // origin + t dir (dir need not be unit)
  std::uint32_t triangle = 0;
  float b1 = 0.0f, b2 = 0.0f;  // barycentrics of vertices 1 and 2 (scene::surface_albedo's b1, b2)
  bool back = false;        // dot(dir, cross(v1 - v0, v2 - v0)) > 0: the ray leaves through this side
};

// Moller-Trumbore in double, hits with t in (t_min, t_max). Barycentrics may undershoot 0 by 1e-9 so
// that a ray through a shared edge or vertex hits both triangles rather than neither.
bool intersect_triangle(const glm::vec3& origin, const glm::vec3& dir, const glm::vec3& v0, const glm::vec3& v1,
                        const glm::vec3& v2, float t_min, float t_max, RayHit& hit);

class TriangleBvh {
 public:
  TriangleBvh() = default;
  TriangleBvh(std::span<const glm::vec3> positions, std::span<const glm::uvec3> triangles);

  // Every hit with t in (t_min, t_max), appended to out (cleared first) in ascending t, ties by triangle.
  void all_hits(const glm::vec3& origin, const glm::vec3& dir, std::vector<RayHit>& out, float t_min = 0.0f,
                float t_max = std::numeric_limits<float>::infinity()) const;

  std::size_t triangle_count() const { return tris_.size(); }
  std::size_t node_count() const { return nodes_.size(); }

 private:
  struct Node {
    glm::vec3 lo{0.0f};
    std::uint32_t index = 0;  // leaf: first entry of order_; inner: right child (left is this + 1)
    glm::vec3 hi{0.0f};
    std::uint32_t count = 0;  // > 0: leaf
  };
  std::uint32_t build(std::uint32_t begin, std::uint32_t end, std::vector<glm::vec3>& centroids);

  std::vector<glm::vec3> pos_;
  std::vector<glm::uvec3> tris_;
  std::vector<std::uint32_t> order_;
  std::vector<Node> nodes_;
};

}  // namespace softgi::techniques::spherical_lights
