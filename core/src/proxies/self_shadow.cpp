// The replacement rules of paper 004 section 6.2 (softgi/proxies/self_shadow.hpp).
#include "softgi/proxies/self_shadow.hpp"

#include <algorithm>
#include <cmath>

namespace softgi::proxies {

AdjustedSphere apply_replacement_rule(ReplacementRule rule, const glm::vec3& p, const glm::vec3& n, const glm::vec3& center,
                                      float radius) {
  if (rule == ReplacementRule::Off) return {center, radius};
  const float r = radius;
  const glm::vec3 cp = center - p;
  const float h = glm::dot(cp, n);
  if (h >= r) return {center, r};  // entirely in front (p is then outside S)
  const bool inside = glm::dot(cp, cp) < r * r;
  if (rule == ReplacementRule::InsideOnly && !inside) return {center, r};
  const glm::vec3 q1 = center - h * n;
  const float rin = std::max(h, 0.0f);                 // inside: shrunk to tangency, or eliminated
  const float rout = std::max(0.5f * (h + r), 0.0f);   // S' with diameter q0 q1; 0 when entirely behind
  const float d = std::sqrt(std::max(0.0f, r * r - h * h));
  const float dmin = 1e-6f * r;
  const float ratio = (glm::length(p - q1) - d) / std::max(d, dmin);
  float rho = 0.0f;
  switch (rule) {
    case ReplacementRule::Continuous: {
      const float t = inside ? 0.0f : std::clamp(ratio, 0.0f, 1.0f);
      rho = rin + t * (rout - rin);
      break;
    }
    case ReplacementRule::Clamped: rho = inside ? rin : std::clamp(ratio, 0.0f, 1.0f) * rout; break;
    case ReplacementRule::Printed: rho = inside ? rin : (d > dmin ? std::max(1.0f, ratio) : 1.0f) * rout; break;
    case ReplacementRule::InsideOnly: rho = rin; break;
    case ReplacementRule::Off: break;
  }
  // A sphere that rounding shrank below 1e-6 of its radius is eliminated (the kernels do the same).
  if (!(rho > 1e-6f * r)) rho = 0.0f;
  return {q1 + rho * n, rho};
}

}  // namespace softgi::proxies
