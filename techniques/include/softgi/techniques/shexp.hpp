// SHEXP: soft shadows from sphere-set blockers by SH exponentiation (paper 004, Ren et al. 2006).
#pragma once

#include <memory>

#include "softgi/render/technique.hpp"

namespace softgi::techniques::shexp {
std::unique_ptr<render::Technique> create();
}  // namespace softgi::techniques::shexp
