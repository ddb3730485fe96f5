// Backend-specific kernels of a technique, registered per backend by the library that implements
// them (the Vulkan kernels live in softgi::techniques_vulkan, so that softgi::techniques builds and
// links without Vulkan). A technique's plan() adds each registered backend's kernels to its passes
// (PassDesc::impl); passes without one run their host implementation everywhere. Not installed;
// include by path (techniques/common/...).
#pragma once

#include <mutex>
#include <string>
#include <utility>
#include <vector>

namespace softgi::techniques::common {

template <class Kernels>
class DeviceKernelRegistry {
 public:
  // Registering a backend again replaces its kernels (registration functions are idempotent).
  void add(const std::string& backend, Kernels k) {
    std::lock_guard<std::mutex> lock(m_);
    for (auto& [name, kernels] : entries_)
      if (name == backend) {
        kernels = std::move(k);
        return;
      }
    entries_.emplace_back(backend, std::move(k));
  }
  std::vector<std::pair<std::string, Kernels>> all() const {
    std::lock_guard<std::mutex> lock(m_);
    return entries_;
  }

 private:
  mutable std::mutex m_;
  std::vector<std::pair<std::string, Kernels>> entries_;
};

}  // namespace softgi::techniques::common
