#include "softgi/render/common_passes.hpp"

#include <map>
#include <mutex>
#include <set>

#include "softgi/image.hpp"
#include "softgi/render/frame.hpp"
#include "softgi/render/gbuffer.hpp"

namespace softgi::render {

std::size_t GBuffer::bytes() const {
  return position.size() * sizeof(glm::vec3) * 4 + depth.size() * sizeof(float) + object.size() * 8 +
         barycentric.size() * sizeof(glm::vec2);
}

namespace {
std::mutex& impl_mutex() {
  static std::mutex m;
  return m;
}
std::map<std::pair<std::string, std::string>, PassFn>& impls() {
  static std::map<std::pair<std::string, std::string>, PassFn> m;
  return m;
}
}  // namespace

void register_shared_pass_impl(const std::string& pass, const std::string& backend, PassFn fn) {
  std::lock_guard<std::mutex> lock(impl_mutex());
  impls()[{pass, backend}] = std::move(fn);
}

const PassFn* find_shared_pass_impl(const std::string& pass, const std::string& backend) {
  std::lock_guard<std::mutex> lock(impl_mutex());
  auto it = impls().find({pass, backend});
  return it == impls().end() ? nullptr : &it->second;
}

void add_gbuffer_pass(PassGraph& g) {
  g.add_input(kScene);
  g.add({"gbuffer", {kScene}, {}, {kGBuffer}, "primary visibility: position, normal, depth, albedo, ids, barycentrics", {}});
}

void add_compose_pass(PassGraph& g) {
  PassDesc p{"compose", {kDirect}, {kIndirect}, {kFinal}, "final = direct + indirect", {}};
  // Composition is the same on every backend that produces CPU-side images.
  PassFn fn = [](FrameContext& ctx) {
    const Image& d = ctx.get<Image>(kDirect);
    Image out = d;
    if (ctx.has(kIndirect)) {
      const Image& ind = ctx.get<Image>(kIndirect);
      for (std::size_t i = 0; i < out.rgb.size(); ++i) out.rgb[i] += ind.rgb[i];
    }
    ctx.record().bytes = out.rgb.size() * sizeof(glm::vec3);
    ctx.put<Image>(kFinal, std::move(out));
  };
  p.impl["cpu"] = fn;
  g.add(std::move(p));
}

void add_scene_facts(const scene::Scene& scene, std::set<std::string>& empty) {
  bool moving = scene.active_clip >= 0 && scene.active_clip < static_cast<int>(scene.clips.size()) &&
                !scene.clips[scene.active_clip].channels.empty();
  if (!moving) empty.insert(kMovingObjects);
  bool reradiating = false;
  for (const auto& p : scene.proxies) reradiating = reradiating || !p.spheres.empty();
  if (!reradiating) empty.insert(kReradiatingProxies);
}

}  // namespace softgi::render
