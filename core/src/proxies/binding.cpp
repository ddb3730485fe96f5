// Proxies that follow skinned animation (paper 004 section 6.2, Animation): mean value coordinates
// of each sphere centre over the rest-pose mesh, premultiplied by the vertices' bone weights.
#include "softgi/proxies/binding.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <stdexcept>
#include <string>

namespace softgi::proxies {

namespace {
using glm::dvec3;

std::string vstr(const glm::vec3& v) {
  return "(" + std::to_string(v.x) + ", " + std::to_string(v.y) + ", " + std::to_string(v.z) + ")";
}

void check_mesh(const std::vector<glm::vec3>& positions, const std::vector<glm::uvec3>& triangles, const std::string& who) {
  if (positions.empty() || triangles.empty())
    throw std::invalid_argument(who + ": the mesh is empty (" + std::to_string(positions.size()) + " vertices, " +
                                std::to_string(triangles.size()) + " triangles)");
  for (size_t i = 0; i < positions.size(); ++i)
    if (!std::isfinite(positions[i].x) || !std::isfinite(positions[i].y) || !std::isfinite(positions[i].z))
      throw std::invalid_argument(who + ": vertex " + std::to_string(i) + " is not finite " + vstr(positions[i]));
  for (size_t t = 0; t < triangles.size(); ++t)
    for (int k = 0; k < 3; ++k)
      if (triangles[t][k] >= positions.size())
        throw std::invalid_argument(who + ": triangle " + std::to_string(t) + " references vertex " +
                                    std::to_string(triangles[t][k]) + " but the mesh has " +
                                    std::to_string(positions.size()) + " vertices");
}
}  // namespace

// Ju, Schaefer, Warren 2005, "Mean value coordinates for closed triangular meshes", Figure 4:
//   w_i += (theta_i - c_{i+1} theta_{i-1} - c_{i-1} theta_{i+1}) / (d_i sin(theta_{i+1}) s_{i-1})
// with theta_i the arc opposite u_i of the spherical triangle (u_1, u_2, u_3) and c_i, s_i the
// cosine and signed sine of its angle at u_i. Their pseudo-code derives c_i from the arcs by the
// half-angle formula and theta from asin, which loses half the digits when x is near a face (arcs
// near pi); here the arcs come from atan2 and the angles from the normals of the great circles,
// which keeps full precision to within ~1e-8 of the surface. Points on a triangle (its solid angle
// is a full hemisphere: pi - h below rounding) get its barycentric weights; triangles whose plane
// holds x contribute nothing.
std::vector<double> mean_value_coordinates(const glm::vec3& x, const std::vector<glm::vec3>& positions,
                                           const std::vector<glm::uvec3>& triangles) {
  check_mesh(positions, triangles, "mean_value_coordinates");
  if (!std::isfinite(x.x) || !std::isfinite(x.y) || !std::isfinite(x.z))
    throw std::invalid_argument("mean_value_coordinates: the point " + vstr(x) + " is not finite");
  const dvec3 xd(x);
  const size_t n = positions.size();
  dvec3 lo(positions[0]), hi(positions[0]);
  for (const glm::vec3& p : positions) {
    lo = glm::min(lo, dvec3(p));
    hi = glm::max(hi, dvec3(p));
  }
  // Distances below this (relative to the mesh size) mean x sits on a vertex.
  const double kOnVertex = 1e-12 * std::max(glm::length(hi - lo), 1e-300);
  // pi - h below this: x lies on the triangle (h, half the arc sum, is pi - O(dist^2) near it).
  constexpr double kOnTriangle = 1e-14;
  // |s_i| below this: x lies in the triangle's plane outside it; its contribution vanishes.
  constexpr double kCoplanar = 1e-14;

  std::vector<double> d(n), w(n, 0.0);
  std::vector<dvec3> u(n);
  for (size_t j = 0; j < n; ++j) {
    const dvec3 v = dvec3(positions[j]) - xd;
    d[j] = glm::length(v);
    if (d[j] < kOnVertex) {
      w[j] = 1.0;
      return w;
    }
    u[j] = v / d[j];
  }
  double total = 0.0;
  for (const glm::uvec3& t : triangles) {
    const unsigned id[3] = {t.x, t.y, t.z};
    const dvec3* U[3] = {&u[id[0]], &u[id[1]], &u[id[2]]};
    double theta[3], c[3], s[3];
    for (int i = 0; i < 3; ++i) {
      const dvec3 &a = *U[(i + 1) % 3], &b = *U[(i + 2) % 3];
      theta[i] = 2.0 * std::atan2(glm::length(a - b), glm::length(a + b));
    }
    const double h = 0.5 * (theta[0] + theta[1] + theta[2]);
    if (std::numbers::pi - h < kOnTriangle) {
      // x on this triangle: barycentric weights sin(theta_i) d_{i-1} d_{i+1}.
      std::vector<double> b(n, 0.0);
      double sum = 0.0;
      for (int i = 0; i < 3; ++i) {
        const double wi = std::sin(theta[i]) * d[id[(i + 2) % 3]] * d[id[(i + 1) % 3]];
        b[id[i]] += wi;
        sum += wi;
      }
      for (double& v : b) v /= sum;
      return b;
    }
    const double sign = glm::dot(*U[0], glm::cross(*U[1], *U[2])) >= 0.0 ? 1.0 : -1.0;
    bool skip = false;
    for (int i = 0; i < 3; ++i) {
      // Angle at u_i between the great circles towards u_{i+1} and u_{i-1}.
      const dvec3 n1 = glm::cross(*U[i], *U[(i + 1) % 3]), n2 = glm::cross(*U[i], *U[(i + 2) % 3]);
      const double l1 = glm::length(n1), l2 = glm::length(n2);
      if (!(l1 > 0.0 && l2 > 0.0)) {
        skip = true;
        break;
      }
      c[i] = glm::dot(n1, n2) / (l1 * l2);
      s[i] = sign * glm::length(glm::cross(n1, n2)) / (l1 * l2);
      if (!(std::abs(s[i]) > kCoplanar)) skip = true;
    }
    if (skip) continue;
    for (int i = 0; i < 3; ++i) {
      const int ip = (i + 1) % 3, im = (i + 2) % 3;
      const double wi = (theta[i] - c[ip] * theta[im] - c[im] * theta[ip]) / (d[id[i]] * std::sin(theta[ip]) * s[im]);
      w[id[i]] += wi;
      total += wi;
    }
  }
  if (!(std::abs(total) > 0.0) || !std::isfinite(total))
    throw std::invalid_argument("mean_value_coordinates: the weights at " + vstr(x) +
                                " do not normalise (sum " + std::to_string(total) + "); is the mesh closed?");
  for (double& v : w) v /= total;
  return w;
}

double bind_to_skin(scene::ProxySet& proxies, const scene::Mesh& mesh) {
  const std::string who = "bind_to_skin: mesh '" + mesh.name + "'";
  if (!mesh.skinned()) throw std::invalid_argument(who + " has no joints/weights");
  if (mesh.joints.size() != mesh.positions.size() || mesh.weights.size() != mesh.positions.size())
    throw std::invalid_argument(who + ": " + std::to_string(mesh.joints.size()) + " joint and " +
                                std::to_string(mesh.weights.size()) + " weight entries for " +
                                std::to_string(mesh.positions.size()) + " vertices");
  check_mesh(mesh.positions, mesh.triangles, who);
  std::vector<double> vsum(mesh.positions.size());
  for (size_t v = 0; v < mesh.positions.size(); ++v) {
    const glm::vec4& wv = mesh.weights[v];
    double sum = 0.0;
    for (int k = 0; k < 4; ++k) {
      if (!std::isfinite(wv[k]) || wv[k] < 0.0f)
        throw std::invalid_argument(who + ": vertex " + std::to_string(v) + " has bone weight " + std::to_string(wv[k]) +
                                    "; expected finite and >= 0");
      sum += wv[k];
    }
    if (!(sum > 0.0)) throw std::invalid_argument(who + ": vertex " + std::to_string(v) + " has all bone weights zero");
    vsum[v] = sum;
  }
  proxies.joints.assign(proxies.spheres.size(), glm::u16vec4(0));
  proxies.weights.assign(proxies.spheres.size(), glm::vec4(0.0f));
  double worst = 0.0;
  for (size_t i = 0; i < proxies.spheres.size(); ++i) {
    const glm::vec3 x = proxies.spheres[i].center;
    const std::vector<double> mvc = mean_value_coordinates(x, mesh.positions, mesh.triangles);
    // Per bone: weight B_b = sum_v mvc_v w_vb and anchor moment q_b = sum_v mvc_v w_vb p_v, so that
    // x = sum_b q_b and sum_b B_b = 1 (the MVC reproduce x exactly).
    std::map<int, std::pair<double, dvec3>> bone;
    for (size_t v = 0; v < mesh.positions.size(); ++v) {
      if (mvc[v] == 0.0) continue;
      for (int k = 0; k < 4; ++k) {
        if (mesh.weights[v][k] == 0.0f) continue;
        const double wb = mvc[v] * mesh.weights[v][k] / vsum[v];
        auto& [B, q] = bone[mesh.joints[v][k]];
        B += wb;
        q += wb * dvec3(mesh.positions[v]);
      }
    }
    std::vector<std::pair<double, int>> order;
    for (const auto& [b, acc] : bone) order.emplace_back(acc.first, b);
    std::sort(order.begin(), order.end(), [](const auto& a, const auto& b) {
      return a.first != b.first ? a.first > b.first : a.second < b.second;
    });
    // The 4 largest positive weights, renormalised.
    double kept = 0.0;
    int count = 0;
    for (; count < 4 && count < static_cast<int>(order.size()) && order[count].first > 0.0; ++count) kept += order[count].first;
    if (!(kept > 0.0))
      throw std::invalid_argument(who + ": sphere " + std::to_string(i) + " at " + vstr(x) + " gets no positive bone weight");
    // Reduction error: the centre rebuilt from the kept bones' anchors y_b = q_b / B_b with the
    // renormalised weights, against x (with all bones it is exactly x).
    dvec3 rebuilt(0.0);
    for (int k = 0; k < count; ++k) {
      const auto& [B, q] = bone[order[k].second];
      const double wk = order[k].first / kept;
      proxies.joints[i][k] = static_cast<std::uint16_t>(order[k].second);
      proxies.weights[i][k] = static_cast<float>(wk);
      rebuilt += wk * (q / B);
    }
    worst = std::max(worst, glm::length(rebuilt - dvec3(x)));
  }
  return worst;
}

}  // namespace softgi::proxies
