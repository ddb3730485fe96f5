// The self-shadowing replacement rules of paper 004 section 6.2 (Figure 5): what a blocker sphere
// becomes for one receiver. The one definition that the accumulation techniques
// (techniques/common/accumulation.hpp, whose vector kernels are tested against it) and the
// reference renderer's proxy blockers (softgi/reference/reference.hpp) both apply.
//
// Per receiver p with outward normal N and tangent plane T_p, for a blocker S = (P, r) with signed
// centre height h = (P - p).N:
//  - p inside S: S is eliminated if its centre is behind T_p (h <= 0), else shrunk about its centre
//    until tangent to T_p, i.e. radius h. That sphere touches T_p at q1 = P - h N.
//  - p outside S: eliminated if S lies entirely behind T_p (h <= -r); unaltered if entirely in front
//    (h >= r); otherwise replaced by S', the sphere with diameter q0 q1, where q0 = P + r N is the
//    point of S farthest in front of T_p and q1 = q0 projected onto T_p = P - h N: radius (h + r)/2,
//    tangent to T_p at q1.
//  - Every replacement is therefore a sphere tangent to T_p at q1; only its radius rho differs. The
//    paper removes the jump of the radius as p leaves S "by gradually scaling up the radius of S' as
//    a function of p's distance to S along the tangent plane", with a scale factor a of
//    x = (|p - q1| - d)/d, d = sqrt(r^2 - (r - |q1 - q0|)^2) = sqrt(r^2 - h^2) the radius of the disc
//    S cuts from T_p (|p - q1| - d is p's distance to S along T_p).
//
// The extracted text prints a = max(1, x). That factor is 1 for every p within d of S and grows
// without bound beyond, so it neither removes the jump at the boundary of S (inside: radius
// max(h, 0); just outside: (h + r)/2) nor keeps a distant sphere's angular size finite. The factor
// that does scale up gradually is t = clamp(x, 0, 1) (min(1, x), 0 on the boundary); applied to S'
// alone it still jumps when the centre is in front of T_p (inside: radius h; just outside: 0).
// The reading used by default, by SHEXP and by the reference alike:
//  - Continuous: rho = max(h, 0) + t ((h + r)/2 - max(h, 0)). For a centre behind T_p (h <= 0, the
//    case of Figure 5's blue sphere) it is exactly t (h + r)/2, the paper's factor on S'; for a
//    centre in front it blends from the shrunk sphere to S'. At t = 0 it equals the inside rule for
//    both signs of h, at distance >= d it is the paper's S', and it is continuous in p.
// The other readings stay selectable for comparison:
//  - Clamped: rho = t (h + r)/2 outside, the inside rule inside (continuous when the centre is behind
//    T_p, a jump when it is in front).
//  - Printed: rho = max(1, x) (h + r)/2 outside, as extracted (a jump at the boundary; rho can
//    exceed r, so the sphere can outgrow S).
//  - InsideOnly: the inside rule only; a sphere that p is outside of is left whole even where it
//    reaches below T_p (no horizon adjustment: paper 001 section 8.1 names that adjustment as an
//    error source, and this reading measures its share; it jumps at the boundary of S).
//  - Off: spheres unaltered (every receiver inside a sphere is fully shadowed).
// A sphere that rounding shrank below 1e-6 of its radius is eliminated (a receiver lying on its own
// proxy sphere otherwise sees a direction of pure noise).
#pragma once

#include <glm/glm.hpp>

namespace softgi::proxies {

enum class ReplacementRule { Off, Continuous, Clamped, Printed, InsideOnly };
inline constexpr ReplacementRule kDefaultReplacementRule = ReplacementRule::Continuous;

struct AdjustedSphere {
  glm::vec3 center{0.0f};
  float radius = 0.0f;  // 0: eliminated
};

// The sphere (center, radius) as receiver p with unit normal n sees it under `rule`.
AdjustedSphere apply_replacement_rule(ReplacementRule rule, const glm::vec3& p, const glm::vec3& n,
                                      const glm::vec3& center, float radius);

}  // namespace softgi::proxies
