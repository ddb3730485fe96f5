#include "softgi/backends/cpu_backend.hpp"

#include <mutex>

namespace softgi::backends {

CpuBackend::CpuBackend() {
  static std::once_flag once;
  std::call_once(once, register_cpu_shared_passes);
}

}  // namespace softgi::backends
