// Point-proxy voxels: point proxies hashed into voxels as VPLs, sparse shadow rays, the visibility
// filter, VPL and SH gathering with glossy indirect light (paper 002, Chen et al. 2014).
#pragma once

#include <memory>

#include "softgi/render/technique.hpp"

namespace softgi::techniques::point_voxels {
std::unique_ptr<render::Technique> create();
}  // namespace softgi::techniques::point_voxels
