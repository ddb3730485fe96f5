// Every technique softgi ships, registered with render::register_technique.
#pragma once

namespace softgi::techniques {
// Idempotent; the CLI, viewer, tests and benchmarks call it before reading the registry.
void register_all();
// The Vulkan kernels of every technique (softgi::techniques_vulkan), added to the pass graphs the
// techniques build for the Vulkan backend. Idempotent; calls register_all().
void register_vulkan_kernels();
}  // namespace softgi::techniques
