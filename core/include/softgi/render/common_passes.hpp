// Passes shared by every technique. A technique adds them to its graph; their implementations come
// from the backend libraries, registered per (pass, backend) so that core stays free of Embree and
// Vulkan.
#pragma once

#include <string>

#include "softgi/render/pass_graph.hpp"
#include "softgi/scene/scene.hpp"

#include <set>

namespace softgi::render {

// Resource names used by the shared passes.
inline constexpr const char* kScene = "scene";                  // input: the posed scene
inline constexpr const char* kGBuffer = "gbuffer";              // GBuffer
inline constexpr const char* kDirect = "direct";                // Image: shadowed direct radiance
inline constexpr const char* kIndirect = "indirect";            // Image: indirect radiance
inline constexpr const char* kFinal = "final";                  // Image: direct + indirect
inline constexpr const char* kMovingObjects = "moving_objects"; // input; empty for a static scene
inline constexpr const char* kReradiatingProxies = "reradiating_proxies";  // input; empty when no proxy re-radiates

// "gbuffer": reads scene, writes gbuffer.
void add_gbuffer_pass(PassGraph& g);
// "compose": reads direct (required) and indirect (optional), writes final.
void add_compose_pass(PassGraph& g);

// Backend libraries register the implementations of shared passes; Backend::execute_pass falls
// back to them when a pass carries no implementation of its own.
void register_shared_pass_impl(const std::string& pass, const std::string& backend, PassFn fn);
const PassFn* find_shared_pass_impl(const std::string& pass, const std::string& backend);

// Scene facts for the empty set of Technique::plan: kMovingObjects when nothing is animated,
// kReradiatingProxies when the scene has no proxy set.
void add_scene_facts(const scene::Scene& scene, std::set<std::string>& empty);

}  // namespace softgi::render
