// Every technique softgi ships, registered with render::register_technique.
#pragma once

namespace softgi::techniques {
// Idempotent; the CLI, viewer, tests and benchmarks call it before reading the registry.
void register_all();
}  // namespace softgi::techniques
