// Parameters more than one technique has, described once: each factory returns the description
// (name, range, help) with the technique's own default, and each reader parses and checks the value
// with one message. Techniques list them in params() beside their own. Not installed; include by
// path (techniques/common/...).
#pragma once

#include <string>
#include <vector>

#include "accumulation.hpp"
#include "softgi/render/params.hpp"

namespace softgi::techniques::common::params {

// "order": SH order n of lighting, visibility and shading, in [kMinOrder, kMaxOrder].
render::ParamDesc order(int def, const std::string& what);
// "exp": the SH exponential (paper 004 section 4.3) among `choices` (a subset of hyb, ol, ps*, ps,
// exact, plus a technique's own), default hyb; `help` says what the choices mean.
render::ParamDesc exp(std::vector<std::string> choices, const std::string& help);
// "window_h": cosine window size h (paper 004 section 7): -1 = 2n, 0 = no window, else >= 1.
render::ParamDesc window_h(double def = -1.0);
// "log_threshold": eigenvalue clip of the SH log, times the largest (paper 004 eq. 32).
render::ParamDesc log_threshold(double def = 0.02);
// "table_resolution": samples in theta of the ZH tables (paper 004: 256).
render::ParamDesc table_resolution(int def = 256);
// "self_shadow_rules" and "replacement_rule" (paper 004 section 6.2; readings in accumulation.hpp).
render::ParamDesc self_shadow_rules(bool def = true);
render::ParamDesc replacement_rule(const std::string& def = "continuous");
// "analytic_lights": shade the scene's spherical lights (paper 004 section 7, Analytic Lights).
render::ParamDesc analytic_lights(bool def = true);
// "receiver_clusters": Lloyd clusters of per-vertex receivers (0 = one per ~300 vertices, paper 004
// section 6.3; receivers.hpp).
render::ParamDesc receiver_clusters();
// "hierarchy": sphere-hierarchy cuts per receiver cluster (paper 004 section 6.3); `help` says what
// they cut in this technique. "theta_max_deg": the cut's angular threshold (paper 004 eq. 36).
render::ParamDesc hierarchy(const std::string& help);
render::ParamDesc theta_max_deg();
// "kernel": the accumulation kernels' instruction set (auto = the best this CPU runs).
render::ParamDesc kernel(const std::string& def = "auto");

// Readers: std::invalid_argument naming the parameter and the value.
// window_h resolved for shading order n: -1 gives 2n (section 7: h = 2n works well), 0 stays 0.
double read_window_h(const render::ParamSet& p, int order);
// The rule in force: Off when self_shadow_rules is off, else replacement_rule's.
ReplacementRule read_replacement_rule(const render::ParamSet& p);
// The instruction set to run; an explicit one this CPU lacks is an error naming what it supports.
KernelIsa read_kernel(const render::ParamSet& p);

}  // namespace softgi::techniques::common::params
