#pragma once

#include <functional>
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

}  // namespace softgi::app
