// Spherical lights: proxy spheres as blockers and as low-frequency secondary lights, shadowed
// one-bounce diffuse indirect light (paper 001, Guerrero, Jeschke and Wimmer 2008).
#pragma once

#include <memory>

#include "softgi/render/technique.hpp"

namespace softgi::techniques::spherical_lights {
std::unique_ptr<render::Technique> create();
}  // namespace softgi::techniques::spherical_lights
