// `softgi backends`: the registered backends, whether each can run here (and why not), and for a
// backend that selects a device, the devices it sees.
#include <CLI/CLI.hpp>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "frame_output.hpp"
#include "softgi/render/backend.hpp"

namespace softgi::app {

namespace {

void run_backends(bool json) {
  register_builtin();
  nlohmann::ordered_json all = nlohmann::ordered_json::array();
  const std::string reference = render::reference_backend_name();
  for (const auto& name : render::backend_names()) {
    const render::BackendInfo& info = render::backend_info(name);
    const std::string why = info.unavailable ? info.unavailable() : std::string();
    nlohmann::ordered_json j = {{"name", name},
                                {"description", info.description},
                                {"reference", name == reference},
                                {"selects_device", info.selects_device},
                                {"available", why.empty()}};
    if (!why.empty()) j["unavailable_because"] = why;
    if (json) {
      all.push_back(j);
      continue;
    }
    std::cout << name << (name == reference ? " (reference)" : "") << ": " << info.description << "\n  "
              << (why.empty() ? "available" : "unavailable: " + why) << (info.selects_device ? "; selects a device (--device)" : "")
              << "\n";
  }
  if (json) std::cout << all.dump(1) << "\n";
}

void register_backends(CLI::App& app) {
  auto json = std::make_shared<bool>(false);
  CLI::App* sub = app.add_subcommand("backends", "List the registered backends and whether each can run here");
  sub->add_flag("--json", *json, "print JSON");
  sub->callback([json] { run_backends(*json); });
}
const CommandRegistrar registrar(register_backends);

}  // namespace

}  // namespace softgi::app
