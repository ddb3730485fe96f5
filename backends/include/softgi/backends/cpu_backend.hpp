// The CPU reference backend: runs each pass's "cpu" implementation; the shared G-buffer pass traces
// primary rays with Embree. Passes parallelise with TBB over both cores.
#pragma once

#include "softgi/render/backend.hpp"

namespace softgi::backends {

class CpuBackend : public render::Backend {
 public:
  CpuBackend();  // registers the CPU implementations of the shared passes (once per process)
  std::string name() const override { return "cpu"; }
};

// Implemented in backends/cpu/gbuffer_embree.cpp.
void register_cpu_shared_passes();

}  // namespace softgi::backends
