// Self-shadowing replacement rules (paper 004 section 6.2; the four readings are documented at
// common::ReplacementRule in techniques/common/accumulation.hpp). A line-by-line port of the scalar
// reference shexp::apply_replacement_rule (techniques/shexp/geometry.cpp), for shaders that need the
// adjusted sphere itself (its centre and radius), not only the accumulate_log kernel's inline form.
// Expects softgi_shared.h included (kRule* = the enum's values). Returns (centre, radius), radius 0 =
// eliminated.
vec4 apply_replacement_rule(uint rule, vec3 p, vec3 n, vec3 center, float radius) {
  if (rule == kRuleOff) return vec4(center, radius);
  const float r = radius;
  const vec3 cp = center - p;
  const float h = dot(cp, n);
  if (h >= r) return vec4(center, r);  // entirely in front (p is then outside S)
  const bool inside = dot(cp, cp) < r * r;
  if (rule == kRuleInsideOnly && !inside) return vec4(center, r);
  const vec3 q1 = center - h * n;
  const float rin = max(h, 0.0);               // inside: shrunk to tangency, or eliminated
  const float rout = max(0.5 * (h + r), 0.0);  // S' with diameter q0 q1; 0 when entirely behind
  const float d = sqrt(max(0.0, r * r - h * h));
  const float dmin = 1e-6 * r;
  const float ratio = (length(p - q1) - d) / max(d, dmin);
  float rho = 0.0;
  if (rule == kRuleContinuous) {
    const float t = inside ? 0.0 : clamp(ratio, 0.0, 1.0);
    rho = rin + t * (rout - rin);
  } else if (rule == kRuleClamped) {
    rho = inside ? rin : clamp(ratio, 0.0, 1.0) * rout;
  } else if (rule == kRulePrinted) {
    rho = inside ? rin : (d > dmin ? max(1.0, ratio) : 1.0) * rout;
  } else if (rule == kRuleInsideOnly) {
    rho = rin;
  }
  if (!(rho > 1e-6 * r)) rho = 0.0;
  return vec4(q1 + rho * n, rho);
}
