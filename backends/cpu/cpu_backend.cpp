#include "softgi/backends/cpu_backend.hpp"

#include <memory>
#include <mutex>

namespace softgi::backends {

void register_cpu_shared_passes();  // gbuffer_cpu.cpp

void register_cpu_backend() {
  static std::once_flag once;
  std::call_once(once, [] {
    render::BackendInfo info;
    info.name = cpu::kBackendName;
    info.description = "CPU reference: host code on every core (TBB), rasterised or Embree primary visibility";
    info.unavailable = [] { return std::string(); };
    info.create = [](const render::BackendOptions& o) -> std::unique_ptr<render::Backend> {
      auto b = std::make_unique<CpuBackend>();
      b->set_memory_limit(o.memory_limit);
      return b;
    };
    render::register_backend(std::move(info));
    register_cpu_shared_passes();
  });
}

}  // namespace softgi::backends
