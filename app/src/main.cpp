// softgi command-line tool. Every subcommand reports bad input as one clear line on stderr and a
// non-zero exit status.
#include <CLI/CLI.hpp>
#include <exception>
#include <iostream>

#include "commands.hpp"

namespace softgi::app {
std::vector<RegisterFn>& command_registry() {
  static std::vector<RegisterFn> registry;
  return registry;
}
}  // namespace softgi::app

int main(int argc, char** argv) {
  CLI::App app{"softgi: real-time soft global illumination techniques, compared"};
  app.require_subcommand(1);
  for (auto fn : softgi::app::command_registry()) fn(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const std::exception& e) {
    std::cerr << "softgi: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
