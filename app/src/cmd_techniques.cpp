// `softgi techniques`: the registered techniques and their parameters, from their descriptions.
#include <CLI/CLI.hpp>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "frame_output.hpp"
#include "softgi/render/technique.hpp"
#include "softgi/techniques/registry.hpp"

namespace softgi::app {

namespace {

void run_techniques(bool json) {
  register_builtin();
  nlohmann::json all = nlohmann::json::array();
  for (const auto& name : render::technique_names()) {
    auto t = render::create_technique(name);
    const render::ParamSet p = render::default_params(*t);
    if (!json) {
      std::cout << name << ": " << t->description() << "\n" << p.describe();
      continue;
    }
    nlohmann::json params = nlohmann::json::array();
    for (const auto& d : p.descs()) {
      nlohmann::json jd = {{"name", d.name}, {"type", render::to_string(d.type)}, {"default", d.default_value}, {"help", d.help}};
      if (d.type == render::ParamType::Int || d.type == render::ParamType::Float) {
        jd["min"] = d.min;
        jd["max"] = d.max;
        jd["sweep_log"] = d.sweep_log;
      }
      if (d.type == render::ParamType::Enum) jd["choices"] = d.choices;
      params.push_back(jd);
    }
    all.push_back({{"name", name}, {"description", t->description()}, {"params", params}});
  }
  if (json) std::cout << all.dump(1) << "\n";
}

void register_techniques(CLI::App& app) {
  auto json = std::make_shared<bool>(false);
  CLI::App* sub = app.add_subcommand("techniques", "List the registered techniques and their parameters");
  sub->add_flag("--json", *json, "print JSON");
  sub->callback([json] { run_techniques(*json); });
}
const CommandRegistrar registrar(register_techniques);

}  // namespace

}  // namespace softgi::app
