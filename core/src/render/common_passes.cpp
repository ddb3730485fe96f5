#include "softgi/render/common_passes.hpp"

#include <algorithm>
#include <limits>
#include <map>
#include <stdexcept>
#include <mutex>
#include <set>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "softgi/image.hpp"
#include "softgi/render/frame.hpp"
#include "softgi/render/gbuffer.hpp"

namespace softgi::render {

std::size_t GBuffer::bytes() const {
  return (position.size() + normal.size() + albedo.size() + view_dir.size()) * sizeof(glm::vec3) +
         depth.size() * sizeof(float) + (object.size() + primitive.size()) * sizeof(std::int32_t) +
         barycentric.size() * sizeof(glm::vec2);
}

GBuffer GBuffer::background(int w, int h, int scale, FramePool* pool, unsigned planes) {
  if (pool) {
    GBuffer gb = for_overwrite(w, h, scale, *pool, planes);
    for (std::size_t i = 0; i < gb.object.size(); ++i) gb.set_background(i, glm::vec3(0.0f));
    return gb;
  }
  GBuffer gb;
  gb.width = w;
  gb.height = h;
  gb.scale = scale;
  gb.planes = planes & kGBufferAll;
  const std::size_t n = static_cast<std::size_t>(std::max(w, 0)) * static_cast<std::size_t>(std::max(h, 0));
  if (planes & kGBufferSurface) {
    gb.position.assign(n, glm::vec3(0.0f));
    gb.normal.assign(n, glm::vec3(0.0f));
    gb.depth.assign(n, std::numeric_limits<float>::infinity());
  }
  if (planes & kGBufferAlbedo) gb.albedo.assign(n, glm::vec3(0.0f));
  gb.object.assign(n, -1);
  gb.primitive.assign(n, -1);
  gb.barycentric.assign(n, glm::vec2(0.0f));
  if (planes & kGBufferViewDir) gb.view_dir.assign(n, glm::vec3(0.0f));
  return gb;
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

void add_receiver_gbuffer_pass(PassGraph& g) {
  g.add_input(kScene);
  // gbuffer is an optional read: at scale 1 the receiver buffer is a copy of it (no second trace),
  // and reading it orders this pass after the display G-buffer.
  g.add({"receiver_gbuffer", {kScene}, {kGBuffer}, {kReceiverGBuffer},
         "receiver setup (paper 000 section 4): position, normal, eye-space depth at 1/receiver_scale resolution", {}});
}

void run_receiver_gbuffer_pass(FrameContext& ctx, const std::function<GBuffer(int scale)>& produce) {
  if (!ctx.params.has("receiver_scale"))
    throw std::invalid_argument("receiver_gbuffer: the technique declares no parameter 'receiver_scale'");
  const int requested = ctx.params.get_int("receiver_scale");
  if (requested < 1)
    throw std::invalid_argument("receiver_gbuffer: parameter 'receiver_scale' = " + std::to_string(requested) + " must be at least 1");
  // A frame smaller than the scale (a 1x1 frame at the default 2) gets the largest scale that still
  // leaves a whole receiver pixel, halving so a power of two stays one.
  int s = requested;
  while (s > 1 && s > std::max(ctx.width, ctx.height)) s /= 2;
  if (s != requested)
    ctx.warn("receiver_scale " + std::to_string(requested) + " exceeds the " + std::to_string(ctx.width) + "x" +
             std::to_string(ctx.height) + " frame; the receiver buffer uses scale " + std::to_string(s));
  PassRecord& rec = ctx.record();
  rec.counters["scale"] = s;
  rec.counters["requested_scale"] = requested;
  GBuffer gb;
  // The display G-buffer itself, when it holds every plane: no second trace.
  if (s == 1 && ctx.has(kGBuffer) && ctx.get<GBuffer>(kGBuffer).has(kGBufferAll)) {
    gb = ctx.get<GBuffer>(kGBuffer);
    gb.scale = 1;
    std::size_t hits = 0;
    for (std::size_t i = 0; i < gb.object.size(); ++i) hits += gb.hit(i);
    rec.counters["copied"] = 1.0;
    rec.counters["rays"] = 0.0;
    rec.counters["hits"] = static_cast<double>(hits);
  } else {
    gb = produce(s);
    rec.counters["copied"] = 0.0;
  }
  rec.bytes = gb.bytes();
  ctx.put<GBuffer>(kReceiverGBuffer, std::move(gb));
}

void register_gbuffer_pass_impls(const std::string& backend, const GBufferProducer& produce, const GBufferPublisher& publish) {
  register_shared_pass_impl("gbuffer", backend, [produce, publish](FrameContext& ctx) {
    std::size_t held = 0;
    GBuffer gb = produce(ctx, 1, "gbuffer", held);
    ctx.record().bytes = gb.bytes() + held;
    ctx.put<GBuffer>(kGBuffer, std::move(gb));
    if (publish) publish(ctx);
  });
  register_shared_pass_impl("receiver_gbuffer", backend, [produce](FrameContext& ctx) {
    run_receiver_gbuffer_pass(ctx, [&](int s) {
      std::size_t held = 0;
      return produce(ctx, s, "receiver_gbuffer", held);
    });
  });
}

void add_compose_pass(PassGraph& g) {
  PassDesc p{"compose", {kDirect}, {kIndirect}, {kFinal}, "final = direct + indirect", {}};
  // Composition is the same on every backend that produces CPU-side images.
  // One parallel pass that reads each input once and writes the sum (no copy of direct first).
  // bytes_moved: the planes read and written once each, for the benchmarks' bandwidth shares.
  PassFn fn = [](FrameContext& ctx) {
    const Image& d = ctx.get<Image>(kDirect);
    const Image* ind = ctx.has(kIndirect) ? &ctx.get<Image>(kIndirect) : nullptr;
    if (ind && ind->rgb.size() != d.rgb.size())
      throw std::logic_error("compose: direct is " + std::to_string(d.width) + "x" + std::to_string(d.height) + ", indirect " +
                             std::to_string(ind->width) + "x" + std::to_string(ind->height));
    Image out = ctx.pool().image_for_overwrite(d.width, d.height);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, d.rgb.size(), std::size_t(1) << 14), [&](const tbb::blocked_range<std::size_t>& r) {
      if (ind)
        for (std::size_t i = r.begin(); i != r.end(); ++i) out.rgb[i] = d.rgb[i] + ind->rgb[i];
      else
        std::copy(d.rgb.begin() + static_cast<std::ptrdiff_t>(r.begin()), d.rgb.begin() + static_cast<std::ptrdiff_t>(r.end()),
                  out.rgb.begin() + static_cast<std::ptrdiff_t>(r.begin()));
    });
    const std::size_t plane = out.rgb.size() * sizeof(glm::vec3);
    ctx.record().bytes = plane;
    ctx.record().counters["bytes_moved"] = static_cast<double>((ind ? 3 : 2) * plane);
    ctx.put<Image>(kFinal, std::move(out));
  };
  p.impl = host_impl(fn);  // the Vulkan backend's images are host images too (read back by their passes)
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
