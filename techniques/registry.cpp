#include "softgi/techniques/registry.hpp"

#include <mutex>

#include "softgi/render/technique.hpp"
#include "softgi/techniques/image_splat.hpp"
#include "softgi/techniques/point_voxels.hpp"
#include "softgi/techniques/shexp.hpp"
#include "softgi/techniques/spherical_lights.hpp"

namespace softgi::techniques {

void register_all() {
  static std::once_flag once;
  std::call_once(once, [] {
    render::register_technique("shexp", [] { return shexp::create(); });
    render::register_technique("image_splat", [] { return image_splat::create(); });
    render::register_technique("spherical_lights", [] { return spherical_lights::create(); });
    render::register_technique("point_voxels", [] { return point_voxels::create(); });
  });
}

}  // namespace softgi::techniques
