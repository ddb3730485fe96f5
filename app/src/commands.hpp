#pragma once

namespace CLI {
class App;
}

namespace softgi::app {
// Each registers one subcommand whose callback runs the command; errors propagate as exceptions.
void register_tables(CLI::App& app);
}  // namespace softgi::app
