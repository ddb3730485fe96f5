#include "shared_params.hpp"

#include <stdexcept>
#include <utility>

namespace softgi::techniques::common::params {

using render::ParamDesc;

ParamDesc order(int def, const std::string& what) { return ParamDesc::integer("order", def, kMinOrder, kMaxOrder, "SH order n of " + what); }

ParamDesc exp(std::vector<std::string> choices, const std::string& help) {
  return ParamDesc::choice("exp", "hyb", std::move(choices), help);
}

ParamDesc window_h(double def) {
  return ParamDesc::real("window_h", def, -1.0, 64.0, "cosine window size h (paper 004 section 7): -1 = 2n, 0 = no window");
}

ParamDesc log_threshold(double def) {
  return ParamDesc::real("log_threshold", def, 0.001, 0.5, "eigenvalue clip of the SH log, times the largest (paper 004 eq. 32)");
}

ParamDesc table_resolution(int def) {
  return ParamDesc::integer("table_resolution", def, 16, 4096, "samples in theta of the ZH tables (paper 004: 256)");
}

ParamDesc self_shadow_rules(bool def) {
  return ParamDesc::boolean("self_shadow_rules", def, "replacement rules for spheres near the receiver (paper 004 section 6.2)");
}

ParamDesc replacement_rule(const std::string& def) {
  return ParamDesc::choice("replacement_rule", def, {"continuous", "clamped", "printed", "inside_only"},
                           "reading of the scale factor a of paper 004 section 6.2 (docs/techniques/shexp.md)");
}

ParamDesc analytic_lights(bool def) {
  return ParamDesc::boolean("analytic_lights", def, "shade the scene's spherical lights (paper 004 section 7, Analytic Lights)");
}

ParamDesc receiver_clusters() {
  return ParamDesc::integer("receiver_clusters", 0, 0, 1 << 20, "Lloyd receiver clusters (0 = one per ~300 vertices, paper 004 section 6.3)");
}

ParamDesc hierarchy(const std::string& help) { return ParamDesc::boolean("hierarchy", true, help); }

ParamDesc theta_max_deg() {
  return ParamDesc::real("theta_max_deg", 25.0, 1.0, 60.0, "eq. 36 angular threshold of the hierarchy cut (paper 004: 20-30)");
}

ParamDesc kernel(const std::string& def) {
  return ParamDesc::choice("kernel", def, {"auto", "avx512", "avx2", "scalar"}, "instruction set of the CPU kernels vectorised across receivers (accumulation, exponentiation, indirect light)");
}

double read_window_h(const render::ParamSet& p, int order) {
  const double h = p.get_float("window_h");
  if (h > 0.0 && h < 1.0)
    throw std::invalid_argument("parameter 'window_h': " + p.get_text("window_h") + " would zero every band above 0 (expected -1, 0 or >= 1)");
  return h < 0.0 ? 2.0 * order : h;
}

ReplacementRule read_replacement_rule(const render::ParamSet& p) {
  return p.get_bool("self_shadow_rules") ? parse_replacement_rule(p.get_enum("replacement_rule")) : ReplacementRule::Off;
}

KernelIsa read_kernel(const render::ParamSet& p) {
  const std::string& k = p.get_enum("kernel");
  const KernelIsa isa = k == "auto" ? best_kernel_isa() : k == "avx512" ? KernelIsa::Avx512 : k == "avx2" ? KernelIsa::Avx2 : KernelIsa::Scalar;
  if (!kernel_isa_supported(isa))
    throw std::invalid_argument("parameter 'kernel': this CPU cannot run '" + k + "' (it supports up to " +
                                std::string(to_string(best_kernel_isa())) + ")");
  return isa;
}

}  // namespace softgi::techniques::common::params
