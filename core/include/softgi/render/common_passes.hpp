// Passes shared by every technique. A technique adds them to its graph; their implementations come
// from the backend libraries, registered per (pass, backend) so that core stays free of Embree and
// Vulkan.
#pragma once

#include <cstddef>
#include <functional>
#include <string>

#include "softgi/render/pass_graph.hpp"
#include "softgi/scene/scene.hpp"

#include <set>

namespace softgi::render {

// Resource names used by the shared passes.
inline constexpr const char* kScene = "scene";                  // input: the posed scene
inline constexpr const char* kGBuffer = "gbuffer";              // GBuffer
inline constexpr const char* kReceiverGBuffer = "receiver_gbuffer";  // GBuffer at 1/scale resolution
inline constexpr const char* kDirect = "direct";                // Image: shadowed direct radiance
inline constexpr const char* kIndirect = "indirect";            // Image: indirect radiance
inline constexpr const char* kFinal = "final";                  // Image: direct + indirect
inline constexpr const char* kMovingObjects = "moving_objects"; // input; empty for a static scene
inline constexpr const char* kReradiatingProxies = "reradiating_proxies";  // input; empty when no proxy re-radiates

// "gbuffer": reads scene, writes gbuffer.
void add_gbuffer_pass(PassGraph& g);
// "receiver_gbuffer" (paper 000 section 4, receiver setup): reads scene (and gbuffer optionally,
// which it copies when the scale is 1), writes receiver_gbuffer: a GBuffer of ceil(W/s) x ceil(H/s)
// pixels with scale s from the integer parameter "receiver_scale" of the frame's ParamSet (a
// technique that adds this pass declares that parameter).
void add_receiver_gbuffer_pass(PassGraph& g);
// The body every backend's "receiver_gbuffer" implementation shares: reads and checks the scale
// (errors name the parameter and the frame size), copies the display G-buffer at scale 1 when the
// frame has one, else calls produce(scale) (the backend's tracer or rasteriser, which records its
// own counters); records scale, copied and bytes, and puts the result.
class FrameContext;
struct GBuffer;
void run_receiver_gbuffer_pass(FrameContext& ctx, const std::function<GBuffer(int scale)>& produce);
// A backend's G-buffer renderer: the G-buffer at 1/scale of the display resolution for the pass
// named `pass`, the backend's counters recorded; held_bytes: what the backend keeps for the next
// frame (device buffers, BVHs), counted in the "gbuffer" pass's bytes.
using GBufferProducer = std::function<GBuffer(FrameContext& ctx, int scale, const char* pass, std::size_t& held_bytes)>;
// Called after the "gbuffer" pass has put the display G-buffer (kGBuffer): a device backend stores
// its device copy there (FrameContext::put_device), which the host put() would have dropped.
using GBufferPublisher = std::function<void(FrameContext& ctx)>;
// Registers `backend`'s "gbuffer" (scale 1; bytes: the G-buffer plus held_bytes) and
// "receiver_gbuffer" (run_receiver_gbuffer_pass) implementations around one renderer.
void register_gbuffer_pass_impls(const std::string& backend, const GBufferProducer& produce,
                                 const GBufferPublisher& publish = {});
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
