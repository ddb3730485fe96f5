#include <mutex>

#include "image_splat/image_splat_vulkan.hpp"
#include "point_voxels/pv_passes.hpp"
#include "shexp/shexp_passes.hpp"
#include "spherical_lights/sl_passes.hpp"
#include "softgi/techniques/registry.hpp"

namespace softgi::techniques {

void register_vulkan_kernels() {
  register_all();
  static std::once_flag once;
  std::call_once(once, [] {
    shexp::register_vulkan_kernels();
    image_splat::register_vulkan_kernels();
    spherical_lights::register_vulkan_kernels();
    point_voxels::register_vulkan_kernels();
  });
}

}  // namespace softgi::techniques
