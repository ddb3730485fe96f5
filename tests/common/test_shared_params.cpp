// The parameters techniques share are described once (techniques/common/shared_params.hpp): every
// registered technique that has one of them shows the same description, and one reader checks it.
#include <gtest/gtest.h>

#include <set>
#include <stdexcept>
#include <string>

#include "../../techniques/common/shared_params.hpp"
#include "softgi/render/technique.hpp"

using namespace softgi;
namespace cp = softgi::techniques::common::params;

namespace {
// Name, type, range and help of a description: what "described once" keeps equal (defaults and, for
// order and exp, the help and choices are each technique's own).
std::string shape(const render::ParamDesc& d) {
  std::string s = d.name + "|" + render::to_string(d.type) + "|" + std::to_string(d.min) + "|" + std::to_string(d.max) + "|";
  if (d.name != "exp") {
    for (const auto& c : d.choices) s += c + ",";
    if (d.name != "order") s += "|" + d.help;
  }
  return s;
}
}  // namespace

TEST(SharedParams, EveryTechniqueShowsTheOneDescription) {
  const std::map<std::string, render::ParamDesc> shared = {
      {"order", cp::order(4, "x")},          {"exp", cp::exp({"hyb"}, "x")},
      {"window_h", cp::window_h()},          {"log_threshold", cp::log_threshold()},
      {"table_resolution", cp::table_resolution()}, {"self_shadow_rules", cp::self_shadow_rules()},
      {"replacement_rule", cp::replacement_rule()}, {"analytic_lights", cp::analytic_lights()},
      {"kernel", cp::kernel()}};
  std::map<std::string, int> seen;
  for (const auto& name : render::technique_names()) {
    const auto t = render::create_technique(name);
    for (const auto& d : t->params()) {
      auto it = shared.find(d.name);
      if (it == shared.end()) continue;
      EXPECT_EQ(shape(d), shape(it->second)) << name << ": parameter '" << d.name << "' is described apart";
      ++seen[d.name];
    }
  }
  // Both accumulation techniques have all nine.
  for (const auto& [n, d] : shared) EXPECT_GE(seen[n], 2) << n;
}

TEST(SharedParams, ReadersResolveAndRejectWithTheParameterNamed) {
  render::ParamSet p({cp::window_h(), cp::self_shadow_rules(), cp::replacement_rule(), cp::kernel()});
  EXPECT_EQ(cp::read_window_h(p, 4), 8.0);  // -1: 2n
  p.set("window_h", "0");
  EXPECT_EQ(cp::read_window_h(p, 4), 0.0);
  p.set("window_h", "0.5");
  try {
    cp::read_window_h(p, 4);
    ADD_FAILURE() << "window_h = 0.5 accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("'window_h'"), std::string::npos) << e.what();
  }
  EXPECT_EQ(cp::read_replacement_rule(p), techniques::common::ReplacementRule::Continuous);
  p.set("replacement_rule", "printed");
  EXPECT_EQ(cp::read_replacement_rule(p), techniques::common::ReplacementRule::Printed);
  p.set("self_shadow_rules", "false");
  EXPECT_EQ(cp::read_replacement_rule(p), techniques::common::ReplacementRule::Off);
  p.set("kernel", "scalar");
  EXPECT_EQ(cp::read_kernel(p), techniques::common::KernelIsa::Scalar);
  p.set("kernel", "auto");
  EXPECT_EQ(cp::read_kernel(p), techniques::common::best_kernel_isa());
}

// softgi report sweeps each technique over the quality ladder its descriptions declare: every
// registered technique has one of at least two rungs, and every rung is a setting the technique
// accepts (ParamSet's constructor has checked each value against its description already).
TEST(SharedParams, EveryTechniqueDeclaresAQualityLadder) {
  for (const auto& name : render::technique_names()) {
    const auto t = render::create_technique(name);
    render::ParamSet p = render::default_params(*t);
    const auto rungs = p.ladder();
    EXPECT_GE(rungs.size(), 2u) << name << " declares no quality ladder";
    for (const auto& rung : rungs) {
      EXPECT_FALSE(rung.empty()) << name;
      for (const auto& [param, value] : rung) EXPECT_NO_THROW(p.set(param, value)) << name << ": " << param << "=" << value;
    }
  }
}
