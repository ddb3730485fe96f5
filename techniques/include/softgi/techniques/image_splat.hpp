// Image-space proxy accumulation: soft shadows and indirect light from sphere proxies splatted to a
// low-resolution receiver buffer (paper 000, Sloan et al. 2007).
#pragma once

#include <memory>

#include "softgi/render/technique.hpp"

namespace softgi::techniques::image_splat {
std::unique_ptr<render::Technique> create();
}  // namespace softgi::techniques::image_splat
