// Linked into every test binary: registers the backends and techniques the binary links, before any
// test runs (the registries are function-local statics, safe to fill during static initialisation).
#include "softgi/backends/cpu_backend.hpp"
#include "softgi/techniques/registry.hpp"
#ifdef SOFTGI_TESTS_VULKAN
#include "softgi/backends/vulkan/backend.hpp"
#endif

namespace {
const bool registered = [] {
  softgi::backends::register_cpu_backend();
  softgi::techniques::register_all();
#ifdef SOFTGI_TESTS_VULKAN
  softgi::backends::register_vulkan_backend();
  softgi::techniques::register_vulkan_kernels();
#endif
  return true;
}();
}  // namespace
