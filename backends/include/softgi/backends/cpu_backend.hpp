// The CPU reference backend: runs each pass's host implementation; the shared G-buffer passes
// trace primary rays with Embree. Passes parallelise with TBB over every core.
#pragma once

#include "softgi/render/backend.hpp"

namespace softgi::backends {

namespace cpu {
// The backend's name in the registry, in PassDesc::impl and in run records.
inline constexpr const char* kBackendName = "cpu";
}  // namespace cpu

class CpuBackend : public render::Backend {
 public:
  std::string name() const override { return cpu::kBackendName; }
};

// Registers the backend (render::register_backend; always available) and its Embree
// implementations of the shared "gbuffer" and "receiver_gbuffer" passes. Idempotent.
void register_cpu_backend();

}  // namespace softgi::backends
