// Closed test meshes with known volumes for the proxy tests.
#pragma once

#include <cmath>
#include <numbers>

#include "softgi/proxies/sphere_fit.hpp"

namespace softgi::proxies::test {

// Axis-aligned box, outward winding.
inline TriMesh box_mesh(glm::vec3 lo, glm::vec3 hi) {
  TriMesh m;
  for (int k = 0; k < 8; ++k) m.positions.push_back({k & 1 ? hi.x : lo.x, k & 2 ? hi.y : lo.y, k & 4 ? hi.z : lo.z});
  const int f[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : f) {
    m.triangles.push_back(glm::uvec3(q[0], q[1], q[2]));
    m.triangles.push_back(glm::uvec3(q[0], q[2], q[3]));
  }
  return m;
}

// A box split into nx slabs along x (for skinning tests), outward winding, closed.
inline TriMesh bar_mesh(float length, float half_width, int nx) {
  TriMesh m;
  // Ring of 4 vertices per x station.
  for (int i = 0; i <= nx; ++i) {
    const float x = length * static_cast<float>(i) / static_cast<float>(nx);
    m.positions.push_back({x, -half_width, -half_width});
    m.positions.push_back({x, half_width, -half_width});
    m.positions.push_back({x, half_width, half_width});
    m.positions.push_back({x, -half_width, half_width});
  }
  for (int i = 0; i < nx; ++i)
    for (int k = 0; k < 4; ++k) {
      const unsigned a = 4 * i + k, b = 4 * i + (k + 1) % 4, c = 4 * (i + 1) + (k + 1) % 4, d = 4 * (i + 1) + k;
      m.triangles.push_back({a, b, c});
      m.triangles.push_back({a, c, d});
    }
  const unsigned e = 4 * nx;
  m.triangles.push_back({0, 2, 1});
  m.triangles.push_back({0, 3, 2});
  m.triangles.push_back({e, e + 1, e + 2});
  m.triangles.push_back({e, e + 2, e + 3});
  return m;
}

// UV sphere of radius r (vertices on the sphere), n_lat bands and n_lon segments, outward winding.
// radial(theta, phi) scales the radius (1 for a sphere) to make bumpy, non-convex closed meshes.
template <class Radial>
TriMesh uv_sphere_mesh(float r, int n_lat, int n_lon, Radial radial, glm::vec3 centre = glm::vec3(0.0f)) {
  TriMesh m;
  const double pi = std::numbers::pi;
  m.positions.push_back(centre + glm::vec3(0, 0, r * static_cast<float>(radial(0.0, 0.0))));
  for (int i = 1; i < n_lat; ++i) {
    const double th = pi * i / n_lat;
    for (int j = 0; j < n_lon; ++j) {
      const double ph = 2.0 * pi * j / n_lon;
      const double rr = r * radial(th, ph);
      m.positions.push_back(centre + glm::vec3(static_cast<float>(rr * std::sin(th) * std::cos(ph)),
                                               static_cast<float>(rr * std::sin(th) * std::sin(ph)),
                                               static_cast<float>(rr * std::cos(th))));
    }
  }
  m.positions.push_back(centre + glm::vec3(0, 0, -r * static_cast<float>(radial(pi, 0.0))));
  const unsigned south = static_cast<unsigned>(m.positions.size() - 1);
  auto ring = [&](int i, int j) { return static_cast<unsigned>(1 + (i - 1) * n_lon + (j % n_lon)); };
  for (int j = 0; j < n_lon; ++j) m.triangles.push_back({0, ring(1, j), ring(1, j + 1)});
  for (int i = 1; i < n_lat - 1; ++i)
    for (int j = 0; j < n_lon; ++j) {
      m.triangles.push_back({ring(i, j), ring(i + 1, j), ring(i + 1, j + 1)});
      m.triangles.push_back({ring(i, j), ring(i + 1, j + 1), ring(i, j + 1)});
    }
  for (int j = 0; j < n_lon; ++j) m.triangles.push_back({south, ring(n_lat - 1, j + 1), ring(n_lat - 1, j)});
  return m;
}
inline TriMesh uv_sphere_mesh(float r, int n_lat, int n_lon) {
  return uv_sphere_mesh(r, n_lat, n_lon, [](double, double) { return 1.0; });
}

// A closed, non-convex "bunny-like" blob: a sphere with lobes (ears) and dents.
inline TriMesh blob_mesh(int n_lat = 24, int n_lon = 48) {
  return uv_sphere_mesh(1.0f, n_lat, n_lon, [](double th, double ph) {
    return 1.0 + 0.35 * std::pow(std::max(0.0, std::cos(th)), 6.0) * (1.0 + std::cos(2.0 * ph)) +
           0.12 * std::sin(3.0 * th) * std::cos(3.0 * ph);
  });
}

}  // namespace softgi::proxies::test
