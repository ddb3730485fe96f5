// Parameter descriptions and pass-graph compilation, run on the null backend.
#include <gtest/gtest.h>

#include <algorithm>

#include "softgi/render/backend.hpp"
#include "softgi/render/params.hpp"
#include "softgi/render/pass_graph.hpp"

using namespace softgi::render;

namespace {
std::vector<ParamDesc> sample_params() {
  return {ParamDesc::integer("order", 4, 3, 6, "SH order"),
          ParamDesc::real("theta_max_deg", 25.0, 5.0, 60.0, "hierarchy cut angle"),
          ParamDesc::boolean("hierarchy", true, "use the sphere hierarchy"),
          ParamDesc::choice("exp", "hyb", {"hyb", "ol", "ps*"}, "SH exponential")};
}

bool contains(const std::vector<std::string>& v, const std::string& s) { return std::find(v.begin(), v.end(), s) != v.end(); }
}  // namespace

TEST(Params, QualityLadderComesFromTheDescriptions) {
  ParamSet plain(sample_params());
  ASSERT_EQ(plain.ladder().size(), 1u);  // no ladder: one rung, the defaults
  EXPECT_TRUE(plain.ladder()[0].empty());

  std::vector<ParamDesc> d = sample_params();
  d[0] = d[0].with_ladder({"3", "4", "6"});
  d[1] = d[1].with_ladder({"40", "25.0", "1e1"});
  ParamSet p(d);
  const auto rungs = p.ladder();
  ASSERT_EQ(rungs.size(), 3u);
  using A = std::pair<std::string, std::string>;
  EXPECT_EQ(rungs[0], (ParamSet::Rung{A{"order", "3"}, A{"theta_max_deg", "40"}}));
  EXPECT_EQ(rungs[1], (ParamSet::Rung{A{"order", "4"}, A{"theta_max_deg", "25"}}));  // canonical text
  EXPECT_EQ(rungs[2], (ParamSet::Rung{A{"order", "6"}, A{"theta_max_deg", "10"}}));
  for (const auto& rung : rungs)
    for (const auto& [name, value] : rung) EXPECT_NO_THROW(p.set(name, value));

  // A ladder that breaks its own description, or rungs that do not line up, is the describer's bug.
  auto expect_logic = [](std::vector<ParamDesc> bad, const std::string& needle) {
    try {
      ParamSet q(std::move(bad));
      ADD_FAILURE() << "accepted a ladder that should fail with '" << needle << "'";
    } catch (const std::logic_error& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  std::vector<ParamDesc> out_of_range = sample_params();
  out_of_range[0] = out_of_range[0].with_ladder({"3", "9"});
  expect_logic(out_of_range, "quality ladder of 'order'");
  std::vector<ParamDesc> ragged = sample_params();
  ragged[0] = ragged[0].with_ladder({"3", "4"});
  ragged[3] = ragged[3].with_ladder({"ol", "hyb", "ps*"});
  expect_logic(ragged, "'exp' has 3 rungs, 'order' has 2");
}

TEST(Params, DefaultsParseAndValidate) {
  ParamSet p(sample_params());
  EXPECT_EQ(p.get_int("order"), 4);
  EXPECT_DOUBLE_EQ(p.get_float("theta_max_deg"), 25.0);
  EXPECT_TRUE(p.get_bool("hierarchy"));
  EXPECT_EQ(p.get_enum("exp"), "hyb");
  p.set_assignment("order=6");
  p.set_assignment("exp=ps*");
  p.set("hierarchy", "off");
  EXPECT_EQ(p.get_int("order"), 6);
  EXPECT_EQ(p.get_enum("exp"), "ps*");
  EXPECT_FALSE(p.get_bool("hierarchy"));
  auto vals = p.values();
  ASSERT_EQ(vals.size(), 4u);
  EXPECT_EQ(vals[0], (std::pair<std::string, std::string>{"order", "6"}));
}

TEST(Params, BadValuesNameParameterAndValue) {
  ParamSet p(sample_params());
  auto expect_msg = [&](const std::string& assignment, const std::string& needle) {
    try {
      p.set_assignment(assignment);
      ADD_FAILURE() << assignment << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  expect_msg("order=9", "order");
  expect_msg("order=4.5", "not an integer");
  expect_msg("theta_max_deg=nan", "not finite");
  expect_msg("theta_max_deg=1e9", "out of range");
  expect_msg("exp=taylor", "taylor");
  expect_msg("hierarchy=maybe", "not a boolean");
  expect_msg("nosuch=1", "unknown parameter 'nosuch'");
  expect_msg("order", "name=value");
  EXPECT_EQ(p.get_int("order"), 4);  // failed assignments change nothing
}

TEST(Params, SweepsComeFromTheDescription) {
  ParamSet p(sample_params());
  auto orders = p.sweep_values("order", 4);
  EXPECT_EQ(orders, (std::vector<std::string>{"3", "4", "5", "6"}));
  EXPECT_EQ(p.sweep_values("exp", 3), (std::vector<std::string>{"hyb", "ol", "ps*"}));
  EXPECT_EQ(p.sweep_values("hierarchy", 3), (std::vector<std::string>{"false", "true"}));
  auto th = p.sweep_values("theta_max_deg", 3);
  ASSERT_EQ(th.size(), 3u);
  EXPECT_EQ(th.front(), "5");
  EXPECT_EQ(th.back(), "60");
  for (const auto& v : th) EXPECT_NO_THROW(p.set("theta_max_deg", v));
  EXPECT_NE(p.describe().find("theta_max_deg (float, [5, 60], default 25)"), std::string::npos) << p.describe();
}

namespace {
// A graph shaped like SHEXP's: shared G-buffer, per-frame proxy update, shadow and indirect
// accumulation, exponentiation, shading and composition.
PassGraph sample_graph() {
  PassGraph g;
  g.add_input("scene");
  g.add({"gbuffer", {"scene"}, {}, {"gbuffer"}, "", {}});
  g.add({"proxy_update", {"scene", "moving_objects"}, {}, {"proxies_moved"}, "", {}});
  g.add({"blocker_list", {"scene"}, {"proxies_moved"}, {"blockers"}, "", {}});
  g.add({"accumulate_log", {"gbuffer", "blockers"}, {}, {"log_visibility"}, "", {}});
  g.add({"exponentiate", {"log_visibility"}, {}, {"visibility"}, "", {}});
  g.add({"shade_direct", {"gbuffer"}, {"visibility"}, {"direct"}, "", {}});
  g.add({"accumulate_indirect", {"gbuffer", "blockers", "reradiating_proxies"}, {}, {"indirect"}, "", {}});
  g.add({"debug_view", {"log_visibility"}, {}, {"debug"}, "", {}});
  g.add({"compose", {"direct"}, {"indirect"}, {"final"}, "", {}});
  g.add_input("moving_objects");
  g.add_input("reradiating_proxies");
  return g;
}
std::vector<std::string> names(const PassGraph& g, const CompiledGraph& c) {
  std::vector<std::string> out;
  for (int i : c.order) out.push_back(g.passes()[i].name);
  return out;
}
}  // namespace

TEST(PassGraph, LeavesOutWhatTheSceneDoesNotNeed) {
  PassGraph g = sample_graph();
  // Everything present: every pass but the unrequested debug view runs, in dependency order.
  auto all = g.compile({"final"});
  auto order = names(g, all);
  EXPECT_EQ(order, (std::vector<std::string>{"gbuffer", "proxy_update", "blocker_list", "accumulate_log", "exponentiate",
                                             "shade_direct", "accumulate_indirect", "compose"}));
  ASSERT_EQ(all.pruned.size(), 1u);
  EXPECT_EQ(all.pruned[0].name, "debug_view");
  // Static scene, no re-radiating proxies: no proxy update, no indirect pass; compose still runs.
  auto lean = g.compile({"final"}, {"moving_objects", "reradiating_proxies"});
  order = names(g, lean);
  EXPECT_FALSE(contains(order, "proxy_update"));
  EXPECT_FALSE(contains(order, "accumulate_indirect"));
  EXPECT_TRUE(contains(order, "compose"));
  EXPECT_TRUE(lean.empty.count("indirect"));
  bool reason_named = false;
  for (const auto& p : lean.pruned)
    if (p.name == "accumulate_indirect") reason_named = p.reason.find("reradiating_proxies") != std::string::npos;
  EXPECT_TRUE(reason_named);
  // Only direct requested: compose and the indirect pass are not needed.
  order = names(g, g.compile({"direct"}));
  EXPECT_FALSE(contains(order, "compose"));
  EXPECT_FALSE(contains(order, "accumulate_indirect"));
}

TEST(PassGraph, StructuralErrorsNameTheCulprit) {
  PassGraph g = sample_graph();
  EXPECT_THROW(g.compile({"nosuch"}), std::invalid_argument);
  PassGraph dup = sample_graph();
  dup.add({"other_writer", {"scene"}, {}, {"direct"}, "", {}});
  try {
    dup.compile({"final"});
    ADD_FAILURE() << "two writers accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("other_writer"), std::string::npos);
  }
  PassGraph missing;
  missing.add({"a", {"ghost"}, {}, {"x"}, "", {}});
  EXPECT_THROW(missing.compile({"x"}), std::invalid_argument);
  PassGraph cyc;
  cyc.add({"a", {"y"}, {}, {"x"}, "", {}});
  cyc.add({"b", {"x"}, {}, {"y"}, "", {}});
  EXPECT_THROW(cyc.compile({"x"}), std::invalid_argument);
  EXPECT_THROW(g.add({"gbuffer", {}, {}, {}, "", {}}), std::invalid_argument);
}
