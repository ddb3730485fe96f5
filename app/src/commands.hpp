#pragma once

#include <functional>
#include <string>
#include <vector>

namespace CLI {
class App;
}

namespace softgi::app {

// Each cmd_*.cpp registers its subcommand with a static CommandRegistrar; main() adds them all.
// A subcommand's callback runs the command; errors propagate as exceptions and main() turns them
// into one "softgi: error: ..." line and exit status 1.
using RegisterFn = void (*)(CLI::App&);
std::vector<RegisterFn>& command_registry();
struct CommandRegistrar {
  explicit CommandRegistrar(RegisterFn fn) { command_registry().push_back(fn); }
};

// What every command that renders a scene takes to name it: --scene SPEC (required) and
// --fit-proxies N (proxy spheres fitted to every closed mesh that has none, cached on disk; for a
// bare glTF/GLB, which brings no proxies of its own).
struct SceneArgs {
  std::string spec;
  int fit_proxies = 0;
};
void add_scene_options(CLI::App& sub, SceneArgs& args);

}  // namespace softgi::app
