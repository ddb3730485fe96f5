// Backend-specific kernels of a technique, registered per backend by the library that implements
// them (the Vulkan kernels live in softgi::techniques_vulkan, so that softgi::techniques builds and
// links without Vulkan). A technique's plan() adds each registered backend's kernels to its passes
// (PassDesc::impl); passes without one run their host implementation everywhere. Not installed;
// include by path (techniques/common/...).
#pragma once

#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "softgi/render/pass_graph.hpp"

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

// A pass's implementations: `impl` (its host one) plus, per registered backend, the PassFn make()
// builds from that backend's kernels (none where it returns an empty one: the backend runs the host
// implementation there).
template <class Kernels>
std::map<std::string, render::PassFn> with_kernels(std::map<std::string, render::PassFn> impl,
                                                   const std::vector<std::pair<std::string, Kernels>>& kernels,
                                                   const std::function<render::PassFn(const Kernels&)>& make) {
  for (const auto& [backend, k] : kernels)
    if (render::PassFn f = make(k)) impl[backend] = std::move(f);
  return impl;
}

}  // namespace softgi::techniques::common
