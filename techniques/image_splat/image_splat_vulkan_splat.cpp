// image_splat's rasterised splats (paper 000 section 4.1, Figure 3) on the Vulkan backend: shadows
// (splat_log.frag) and indirect light (splat_indirect.frag), through one vertex shader (splat.vert).
#include "image_splat_vulkan_splat.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "../common/accumulation_vulkan.hpp"
#include "image_splat_splat_shared.h"
#include "image_splat_indirect_shared.h"
#include "image_splat_vulkan_binning.hpp"
#include "image_splat_vulkan_shading.hpp"
#include "softgi/backends/vulkan/backend.hpp"
#include "softgi/backends/vulkan/context.hpp"
#include "softgi/backends/vulkan/projection.hpp"
#include "softgi/render/camera.hpp"
#include "softgi_shared.h"

namespace spv {
#include "softgi/shaders/image_splat/splat_gather_comp.h"
#include "softgi/shaders/image_splat/splat_indirect_frag.h"
#include "softgi/shaders/image_splat/splat_log_frag.h"
#include "softgi/shaders/image_splat/splat_vert.h"
}  // namespace spv

namespace softgi::techniques::image_splat {

namespace vk = backends::vulkan;
using namespace common::gpu_passes;

namespace {

constexpr VkFormat kSplatFormat = VK_FORMAT_R32G32B32A32_SFLOAT;

// std430 mirror of splat_log's push constants.
struct SplatPush {
  glm::mat4 clip_from_world;
  glm::vec4 eye_pixel;
  glm::vec4 forward;
  glm::uvec4 sizes;
  glm::vec4 table;
};
static_assert(sizeof(SplatPush) == 128, "splat_log push constants: 128 bytes, the least every device offers");

// The coarsely tessellated sphere of section 4.1: an icosahedron subdivided once (80 triangles),
// wound counter-clockwise about its outward normals, scaled so that every face lies outside the
// unit sphere (its inradius 1), as a triangle list.
std::vector<glm::vec4> unit_hull() {
  const double g = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<glm::dvec3> v = {{-1, g, 0}, {1, g, 0}, {-1, -g, 0}, {1, -g, 0}, {0, -1, g}, {0, 1, g},
                               {0, -1, -g}, {0, 1, -g}, {g, 0, -1}, {g, 0, 1}, {-g, 0, -1}, {-g, 0, 1}};
  for (auto& p : v) p = glm::normalize(p);
  const int faces[20][3] = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                            {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
                            {3, 8, 9},  {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  std::vector<std::array<glm::dvec3, 3>> tris;
  for (const auto& f : faces) {
    const glm::dvec3 a = v[f[0]], b = v[f[1]], c = v[f[2]];
    const glm::dvec3 ab = glm::normalize(a + b), bc = glm::normalize(b + c), ca = glm::normalize(c + a);
    tris.push_back({a, ab, ca});
    tris.push_back({ab, b, bc});
    tris.push_back({ca, bc, c});
    tris.push_back({ab, bc, ca});
  }
  double inradius = 1.0;
  for (auto& t : tris) {
    glm::dvec3 n = glm::cross(t[1] - t[0], t[2] - t[0]);
    if (glm::dot(n, t[0]) < 0.0) {  // outward counter-clockwise
      std::swap(t[1], t[2]);
      n = -n;
    }
    inradius = std::min(inradius, glm::dot(glm::normalize(n), t[0]));
  }
  std::vector<glm::vec4> out;
  // Rounded up by float's rounding of the corners: a relative 1e-6 more than the inradius needs.
  const double scale = (1.0 + 1e-6) / inradius;
  for (const auto& t : tris)
    for (const auto& p : t) out.push_back(glm::vec4(glm::vec3(p * scale), 0.0f));
  return out;
}

// Per attachment count, the attachments of one buffer size and their framebuffer.
struct Targets {
  std::uint32_t width = 0, height = 0;
  std::vector<vk::Image> images;
  vk::Owned<VkFramebuffer> framebuffer;
};

enum class Kind : std::uint32_t { Log, Indirect };

struct SplatState {
  std::mutex m;
  std::unique_ptr<vk::PipelineLayout> log_layout, ind_layout;
  vk::Owned<VkShaderModule> vs, ind_fs;
  std::map<std::uint32_t, vk::Owned<VkShaderModule>> log_fs;  // by order
  std::map<std::uint32_t, vk::Owned<VkRenderPass>> passes;  // by attachment count
  // By (kind, N, rule, attachments or operator, first coefficient).
  std::map<std::array<std::uint32_t, 5>, vk::Owned<VkPipeline>> pipelines;
  std::map<std::uint32_t, Targets> targets;  // by attachment count
  PipelineCache compute;
  vk::Buffer hull, receivers, pixel_receiver;
  std::uint64_t hull_hash = 0, receivers_hash = 0, pr_hash = 0;
  std::uint32_t hull_vertices = 0;
  // Shadows.
  vk::Buffer test, spheres, weights, receiver_pixel, raw, log_out, table;
  std::uint64_t test_hash = 0, spheres_hash = 0, weights_hash = 0, rp_hash = 0;
  std::vector<float> table_host;
  // Indirect light.
  vk::Buffer ind_test, ind_spheres, ind_albedo, ind_raw, pairs;
  std::uint64_t ind_test_hash = 0, ind_spheres_hash = 0, ind_albedo_hash = 0;
  IndirectTableBuffers tables;
};

VkRenderPass render_pass(vk::Context& ctx, SplatState& st, std::uint32_t outs) {
  auto it = st.passes.find(outs);
  if (it != st.passes.end()) return it->second.get();
  // Cleared (the sums start at 0), blended into, copied out after each draw.
  return st.passes.emplace(outs, vk::create_render_pass(ctx, {"image_splat splats", std::vector<VkFormat>(outs, kSplatFormat)})).first->second.get();
}

// The splat pipeline of `kind` for `key` (kind, N, rule, attachments (shadows) or operator
// (indirect light), first coefficient), made on first use.
VkPipeline splat_pipeline(vk::Context& ctx, SplatState& st, const std::array<std::uint32_t, 5>& key, std::uint32_t outs) {
  auto it = st.pipelines.find(key);
  if (it != st.pipelines.end()) return it->second.get();
  const Kind kind = static_cast<Kind>(key[0]);
  const std::uint32_t n = key[1];
  const auto vs_words = words(spv::image_splat_splat_vert);
  const std::span<const std::uint32_t> fs_words =
      kind == Kind::Log ? order_variant(spv::image_splat_splat_log_frag_for(static_cast<int>(n)), static_cast<int>(n), "image_splat splat_log.frag")
                        : words(spv::image_splat_splat_indirect_frag);
  const vk::ShaderReflection rv = vk::reflect_spirv(vs_words), rf = vk::reflect_spirv(fs_words);
  if (!st.vs) st.vs = ctx.create_shader_module(vs_words, "image_splat splat.vert");
  // One layout per kind: every order's splat_log.frag has the same bindings and push constants.
  std::unique_ptr<vk::PipelineLayout>& layout = kind == Kind::Log ? st.log_layout : st.ind_layout;
  if (!layout)
    layout = std::make_unique<vk::PipelineLayout>(ctx, std::vector<vk::ShaderReflection>{rv, rf},
                                                  kind == Kind::Log ? "image_splat splat_log" : "image_splat splat_indirect");
  VkShaderModule fs = VK_NULL_HANDLE;
  if (kind == Kind::Log) {
    auto f = st.log_fs.find(n);
    if (f == st.log_fs.end())
      f = st.log_fs.emplace(n, ctx.create_shader_module(fs_words, "image_splat splat_log.frag (order " + std::to_string(n) + ")")).first;
    fs = f->second.get();
  } else {
    if (!st.ind_fs) st.ind_fs = ctx.create_shader_module(fs_words, "image_splat splat_indirect.frag");
    fs = st.ind_fs.get();
  }
  // Constants 0 (N), 1 (RULE), then 2 (OP, indirect light) or 3 (FIRST, shadows).
  const std::array<std::uint32_t, 4> values = {key[1], key[2], key[3], key[4]};
  const std::array<VkSpecializationMapEntry, 3> entries = {
      {{0, 0, 4}, {1, 4, 4}, kind == Kind::Log ? VkSpecializationMapEntry{3, 12, 4} : VkSpecializationMapEntry{2, 8, 4}}};
  VkSpecializationInfo spec{};
  spec.mapEntryCount = static_cast<std::uint32_t>(entries.size());
  spec.pMapEntries = entries.data();
  spec.dataSize = sizeof(values);
  spec.pData = values.data();
  VkPipelineColorBlendAttachmentState blend{};
  blend.blendEnable = VK_TRUE;  // dst + src: the sum over proxies (section 4: "splat the proxies to the receiver buffer to sum")
  blend.srcColorBlendFactor = blend.dstColorBlendFactor = VK_BLEND_FACTOR_ONE;
  blend.srcAlphaBlendFactor = blend.dstAlphaBlendFactor = VK_BLEND_FACTOR_ONE;
  blend.colorBlendOp = blend.alphaBlendOp = VK_BLEND_OP_ADD;
  blend.colorWriteMask = vk::write_all_channels().colorWriteMask;
  vk::GraphicsPipelineDesc gd;
  gd.name = kind == Kind::Log ? "image_splat splat_log" : "image_splat splat_indirect";
  gd.layout = layout->handle();
  gd.render_pass = render_pass(ctx, st, outs);
  gd.vertex = st.vs.get();
  gd.fragment = fs;
  gd.vertex_entry = rv.entry_point;
  gd.fragment_entry = rf.entry_point;
  gd.fragment_spec = &spec;
  gd.cull = VK_CULL_MODE_FRONT_BIT;  // the hull's far side: one fragment per pixel, eye inside or not
  gd.front_face = VK_FRONT_FACE_COUNTER_CLOCKWISE;  // vulkan::clip_from_world keeps outward counter-clockwise front-facing
  gd.blend.assign(outs, blend);  // one sample: the pixel centre, where the receiver was sampled
  const VkPipeline pipeline = st.pipelines.emplace(key, vk::create_graphics_pipeline(ctx, gd)).first->second.get();
  return pipeline;
}

Targets& targets(vk::Context& ctx, SplatState& st, std::uint32_t outs, std::uint32_t w, std::uint32_t h) {
  Targets& t = st.targets[outs];
  if (t.width == w && t.height == h && t.framebuffer) return t;
  t.framebuffer.reset();
  t.images.clear();
  std::vector<VkImageView> views;
  for (std::uint32_t a = 0; a < outs; ++a) {
    t.images.push_back(ctx.create_image(w, h, kSplatFormat, VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT,
                                        VK_IMAGE_ASPECT_COLOR_BIT, "image_splat splat sums " + std::to_string(a)));
    views.push_back(t.images.back().view());
  }
  t.framebuffer = vk::create_framebuffer(ctx, render_pass(ctx, st, outs), views, w, h, "image_splat splats");
  t.width = w;
  t.height = h;
  return t;
}

// What a device must offer the splats of `pass` ("accumulate_log", "accumulate_indirect"):
// blending into RGBA32F attachments, `outs` of them, a framebuffer of w x h, `texels` texels of
// blended sums in one texel buffer, and (indirect light, which counts its pairs) fragment atomics.
void check_device(vk::Context& dev, const std::string& pass, std::uint32_t w, std::uint32_t h, std::size_t texels, std::uint32_t outs,
                  bool atomics) {
  const std::string who = "image_splat " + pass + " on vulkan (splatting=raster): ";
  const std::string name = "device '" + dev.device_info().name + "'";
  VkFormatProperties fp{};
  vkGetPhysicalDeviceFormatProperties(dev.physical_device(), kSplatFormat, &fp);
  const VkFormatFeatureFlags need =
      VK_FORMAT_FEATURE_COLOR_ATTACHMENT_BIT | VK_FORMAT_FEATURE_COLOR_ATTACHMENT_BLEND_BIT | VK_FORMAT_FEATURE_TRANSFER_SRC_BIT;
  if ((fp.optimalTilingFeatures & need) != need)
    throw std::invalid_argument(who + name + " cannot blend into RGBA32F colour attachments; use splatting=binned");
  const auto& lim = dev.device_info().limits;
  if (w > lim.maxFramebufferWidth || h > lim.maxFramebufferHeight)
    throw std::invalid_argument(who + "a receiver buffer of " + std::to_string(w) + "x" + std::to_string(h) + " exceeds " + name +
                                "'s largest framebuffer (" + std::to_string(lim.maxFramebufferWidth) + "x" +
                                std::to_string(lim.maxFramebufferHeight) + "); use a larger receiver_scale or splatting=binned");
  if (outs > lim.maxColorAttachments)
    throw std::invalid_argument(who + "the order blends into " + std::to_string(outs) + " colour attachments, " + name + " has " +
                                std::to_string(lim.maxColorAttachments) + "; use a lower order or splatting=binned");
  if (texels > lim.maxTexelBufferElements)
    throw std::invalid_argument(who + std::to_string(texels) + " texels of blended sums exceed " + name + "'s texel buffers (" +
                                std::to_string(lim.maxTexelBufferElements) + "); use a larger receiver_scale or splatting=binned");
  if (atomics) {
    VkPhysicalDeviceFeatures f{};
    vkGetPhysicalDeviceFeatures(dev.physical_device(), &f);
    if (!f.fragmentStoresAndAtomics)
      throw std::invalid_argument(who + name + " has no fragmentStoresAndAtomics (the pair count); use splatting=binned");
  }
}

// The splats' view of the frame: the receiver buffer's camera with its near plane under the
// nearest receiver (every pixel ray meets a hull containing its receiver at or beyond the
// receiver), and the receivers and the pixel -> receiver map on the device.
SplatPush frame_push(render::FrameContext& ctx, vk::Context& dev, SplatState& st, const ReceiverBuffer& r, const std::string& pass,
                     std::size_t& uploaded) {
  const render::PinholeCamera cam = render::make_pinhole_camera(ctx.scene, ctx.width, ctx.height, "image_splat " + pass);
  float nearest = std::numeric_limits<float>::infinity(), farthest = 0.0f;
  for (std::size_t i = 0; i < r.soa.size(); ++i) {
    const float z = cam.depth(glm::vec3(r.soa.px[i], r.soa.py[i], r.soa.pz[i]));
    nearest = std::min(nearest, z);
    farthest = std::max(farthest, z);
  }
  float near_plane = 0.5f * nearest;
  if (!(near_plane > 0.0f) || !std::isfinite(near_plane)) near_plane = 1e-6f * std::max(farthest, 1.0f);
  SplatPush push;
  push.clip_from_world = vk::clip_from_world(cam, r.width, r.height, r.scale, near_plane);
  // A buffer pixel's width at unit depth (the same across and down: aspect = W / H).
  const float pixel_width = 2.0f * cam.tan_half_fov_y * static_cast<float>(r.scale) / static_cast<float>(cam.height);
  push.eye_pixel = glm::vec4(cam.position, pixel_width);
  push.forward = glm::vec4(cam.forward, 0.0f);
  push.sizes = glm::uvec4(static_cast<std::uint32_t>(r.width), static_cast<std::uint32_t>(r.soa.size()), 0u, 0u);
  const std::size_t before = dev.transfer_bytes().upload;
  if (!st.hull_vertices) {
    const std::vector<glm::vec4> hull = unit_hull();
    st.hull_vertices = static_cast<std::uint32_t>(hull.size());
    put_if_changed(dev, st.hull, st.hull_hash, hull, "image_splat splat hull");
  }
  upload_receivers(dev, st.receivers, r.soa, "image_splat receivers (splats)", &st.receivers_hash);
  put_if_changed(dev, st.pixel_receiver, st.pr_hash, r.receiver, "image_splat pixel receivers");
  uploaded += dev.transfer_bytes().upload - before;
  return push;
}

// Draws `proxies` splats once per pipeline of `pipes` (each filling `outs` attachments with the next
// coefficients), copying the first `quads` attachments' sums in all to `raw`, one plane of vec4 per
// attachment.
void record_splats(vk::Recorder& rc, vk::Context& dev, SplatState& st, const vk::PipelineLayout& layout, const std::vector<VkPipeline>& pipes,
                   const std::vector<vk::Bind>& binds, const SplatPush& push, std::uint32_t outs, std::uint32_t quads, const ReceiverBuffer& r,
                   std::size_t proxies, const vk::Buffer& raw) {
  const auto w = static_cast<std::uint32_t>(r.width), h = static_cast<std::uint32_t>(r.height);
  const std::size_t pixels = static_cast<std::size_t>(w) * h;
  Targets& tg = targets(dev, st, outs, w, h);
  VkCommandBuffer cmd = rc.cmd();
  const VkDescriptorSet set = rc.descriptor_set(layout, 0, binds);
  for (std::uint32_t d = 0; d < pipes.size(); ++d) {
    std::vector<VkClearValue> clear(outs);
    for (auto& c : clear) c.color = {{0.0f, 0.0f, 0.0f, 0.0f}};
    VkRenderPassBeginInfo bi{VK_STRUCTURE_TYPE_RENDER_PASS_BEGIN_INFO};
    bi.renderPass = render_pass(dev, st, outs);
    bi.framebuffer = tg.framebuffer.get();
    bi.renderArea.extent = {w, h};
    bi.clearValueCount = outs;
    bi.pClearValues = clear.data();
    vkCmdBeginRenderPass(cmd, &bi, VK_SUBPASS_CONTENTS_INLINE);
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, pipes[d]);
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, layout.handle(), 0, 1, &set, 0, nullptr);
    const VkViewport viewport{0.0f, 0.0f, static_cast<float>(w), static_cast<float>(h), 0.0f, 1.0f};
    const VkRect2D scissor{{0, 0}, {w, h}};
    vkCmdSetViewport(cmd, 0, 1, &viewport);
    vkCmdSetScissor(cmd, 0, 1, &scissor);
    vkCmdPushConstants(cmd, layout.handle(), layout.push_constant_stages(), 0, sizeof(SplatPush), &push);
    if (proxies) vkCmdDraw(cmd, st.hull_vertices, static_cast<std::uint32_t>(proxies), 0, 0);
    vkCmdEndRenderPass(cmd);
    for (std::uint32_t a = 0; a < outs && d * outs + a < quads; ++a) {
      VkBufferImageCopy copy{};
      copy.bufferOffset = static_cast<VkDeviceSize>(d * outs + a) * pixels * 4 * sizeof(float);
      copy.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
      copy.imageExtent = {w, h, 1};
      vkCmdCopyImageToBuffer(cmd, tg.images[a].handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, raw.handle(), 1, &copy);
    }
  }
}

std::shared_ptr<SplatState> splat_state(vk::Context& dev) {
  return dev.cached<SplatState>("image_splat.splat", [] { return std::make_shared<SplatState>(); });
}

}  // namespace

void vulkan_splat_log(render::FrameContext& ctx, const Settings& s, const ShadowTables& t, const ReceiverBuffer& r,
                      const common::BlockerList& all, double alpha, const std::string& out) {
  vk::Context& dev = vk::context_of(ctx);
  auto st = splat_state(dev);
  std::lock_guard<std::mutex> lock(st->m);
  const int n = t.order, n2 = n * n;
  if (t.log.order != n || n > static_cast<int>(gpu::kAccumMaxOrder) || all.order != n)
    throw std::logic_error("image_splat accumulate_log on vulkan: log table of order " + std::to_string(t.log.order) + ", proxies of order " +
                           std::to_string(all.order) + " for order " + std::to_string(n));
  const std::size_t count = r.soa.size(), proxies = all.size();
  const std::size_t pixels = static_cast<std::size_t>(r.width) * static_cast<std::size_t>(r.height);
  const std::uint32_t quads = static_cast<std::uint32_t>((n2 + 3) / 4);
  const std::uint32_t outs = std::min(quads, gpu::kSplatMaxAttachments);  // splat_log.frag's for this order
  const std::uint32_t draws = (quads + outs - 1) / outs;
  auto fits = [&](std::size_t bytes, const std::string& what) {
    check_fits(dev, bytes, what, "image_splat accumulate_log", "use fewer proxy spheres, a larger receiver_scale, or splatting=binned");
  };
  fits(static_cast<std::size_t>(quads) * pixels * 4 * sizeof(float), "the blended sums of " + std::to_string(pixels) + " receiver-buffer pixels");
  fits(proxies * (8 + weight_stride(n)) * sizeof(float), "the spheres and band weights of " + std::to_string(proxies) + " proxies");
  fits(count * (n2 + 7) * sizeof(float), "the log vectors of " + std::to_string(count) + " receivers");
  if (count > std::numeric_limits<std::int32_t>::max() / 8 || proxies > std::numeric_limits<std::int32_t>::max() / 8)
    throw std::invalid_argument("image_splat accumulate_log on vulkan: " + std::to_string(count) + " receivers, " + std::to_string(proxies) +
                                " proxies exceed the 32-bit indexing");
  dev.ensure_buffer(st->log_out, std::max<std::size_t>(1, count * n2) * sizeof(float), kStorage, vk::MemoryKind::Device,
                    "image_splat log occlusion (splats)");
  auto& rec = ctx.record();
  rec.counters["receivers"] = static_cast<double>(count);
  rec.counters["proxies"] = static_cast<double>(proxies);
  rec.counters["hard_cut"] = t.hard_cut;
  rec.counters["pair_cut"] = pair_cut_factor(t, s.rule) > 0.0f;
  rec.bytes = count * n2 * sizeof(float);
  if (count == 0) {
    put_device_field<Field>(ctx, out, DeviceField{&st->log_out, 0, n}, st->m, dev);
    return;
  }
  check_device(dev, "accumulate_log", static_cast<std::uint32_t>(r.width), static_cast<std::uint32_t>(r.height),
               static_cast<std::size_t>(quads) * pixels, outs, false);

  std::size_t uploaded = 0;
  SplatPush push = frame_push(ctx, dev, *st, r, "accumulate_log", uploaded);
  push.sizes.z = static_cast<std::uint32_t>(t.log.rows);
  push.table = glm::vec4(t.log.scale, pair_cut_factor(t, s.rule), 0.0f, 0.0f);
  const DeviceProxies in = device_shadow_proxies(all, alpha);
  const std::vector<std::int32_t> receiver_pixel(r.pixel.begin(), r.pixel.end());
  const std::size_t before = dev.transfer_bytes().upload;
  put_if_changed(dev, st->test, st->test_hash, in.test, "image_splat spheres of influence");
  put_if_changed(dev, st->spheres, st->spheres_hash, in.a, "image_splat proxy spheres");
  put_if_changed(dev, st->weights, st->weights_hash, in.b, "image_splat band weights");
  put_if_changed(dev, st->receiver_pixel, st->rp_hash, receiver_pixel, "image_splat receiver pixels");
  upload_if_changed(dev, st->table, st->table_host, t.log.data, "image_splat log ZH table (splats)");
  uploaded += dev.transfer_bytes().upload - before;
  dev.ensure_buffer(st->raw, static_cast<std::size_t>(quads) * pixels * 4 * sizeof(float), kStorage, vk::MemoryKind::Device,
                    "image_splat splat sums");

  const std::vector<vk::Bind> binds = {
      vk::Bind::texels_at(gpu::kSplatBindTest, st->test, VK_FORMAT_R32G32B32A32_SFLOAT),
      vk::Bind::texels_at(gpu::kSplatBindHull, st->hull, VK_FORMAT_R32G32B32A32_SFLOAT),
      vk::Bind::texels_at(gpu::kSplatBindSpheres, st->spheres, VK_FORMAT_R32G32B32A32_SFLOAT),
      vk::Bind::texels_at(gpu::kSplatBindWeights, st->weights, VK_FORMAT_R32G32B32A32_SFLOAT),
      vk::Bind::texels_at(gpu::kSplatBindTable, st->table, VK_FORMAT_R32G32_SFLOAT),
      vk::Bind::buffer_at(gpu::kSplatBindBasis, basis_constants(dev)),
      vk::Bind::texels_at(gpu::kSplatBindReceivers, st->receivers, VK_FORMAT_R32_SFLOAT),
      vk::Bind::texels_at(gpu::kSplatBindPixelReceiver, st->pixel_receiver, VK_FORMAT_R32_SINT)};
  std::vector<VkPipeline> pipes;
  for (std::uint32_t d = 0; d < draws; ++d)
    pipes.push_back(splat_pipeline(dev, *st,
                                   {static_cast<std::uint32_t>(Kind::Log), static_cast<std::uint32_t>(n), static_cast<std::uint32_t>(s.rule), outs,
                                    4 * outs * d},
                                   outs));
  vk::ComputePipeline& gather = pipeline(dev, st->compute, "image_splat.splat_gather", words(spv::image_splat_splat_gather_comp), {});
  struct GatherPush {
    std::uint32_t first, end, n2, pixels;
  };
  const vk::SubmitResult res = dev.submit([&](vk::Recorder& rc) {
    rc.begin_timer("splat_log");
    record_splats(rc, dev, *st, *st->log_layout, pipes, binds, push, outs, quads, r, proxies, st->raw);
    rc.barrier();
    dispatch_chunks<GatherPush>(rc, gather,
                                {vk::Bind::texels_at(gpu::kSplatGatherBindRaw, st->raw, VK_FORMAT_R32G32B32A32_SFLOAT),
                                 vk::Bind::texels_at(gpu::kSplatGatherBindPixel, st->receiver_pixel, VK_FORMAT_R32_SINT),
                                 vk::Bind::buffer_at(gpu::kSplatGatherBindOut, st->log_out)},
                                count, gpu::kSplatGatherGroup, [&](std::uint32_t a, std::uint32_t b) {
                                  return GatherPush{a, b, static_cast<std::uint32_t>(n2), static_cast<std::uint32_t>(pixels)};
                                });
    rc.end_timer();
    rc.barrier();
  }, "image_splat splat_log");
  rec.counters["hull_triangles"] = static_cast<double>(st->hull_vertices / 3);
  rec.counters["splat_draws"] = static_cast<double>(draws);
  rec.counters["attachments"] = static_cast<double>(outs);
  rec.counters["kernel_gpu_seconds"] = timer_seconds(res);
  rec.counters["upload_bytes"] = static_cast<double>(uploaded);
  put_device_field<Field>(ctx, out, DeviceField{&st->log_out, count * n2, n}, st->m, dev);
}

std::shared_ptr<IndirectSums> vulkan_splat_indirect(render::FrameContext& ctx, const ReceiverBuffer& r, const ProxyList& all, double alpha,
                                                    const IndirectEvaluator& ev) {
  // The CPU evaluator's input checks on every proxy (same messages): an empty receiver range checks
  // the list and evaluates nothing.
  ev.accumulate(r.soa, 0, 0, all, nullptr, nullptr);
  vk::Context& dev = vk::context_of(ctx);
  auto st = splat_state(dev);
  std::lock_guard<std::mutex> lock(st->m);
  const std::size_t count = r.soa.size(), proxies = all.size();
  const std::size_t pixels = static_cast<std::size_t>(r.width) * static_cast<std::size_t>(r.height);
  auto fits = [&](std::size_t bytes, const std::string& what) {
    check_fits(dev, bytes, what, "image_splat accumulate_indirect", "use fewer proxy spheres, a larger receiver_scale, or splatting=binned");
  };
  fits(pixels * 4 * sizeof(float), "the blended sums of " + std::to_string(pixels) + " receiver-buffer pixels");
  fits(proxies * 12 * sizeof(float), "the spheres and albedo of " + std::to_string(proxies) + " proxies");
  if (count > std::numeric_limits<std::int32_t>::max() / 8 || proxies > std::numeric_limits<std::int32_t>::max() / 8)
    throw std::invalid_argument("image_splat accumulate_indirect on vulkan: " + std::to_string(count) + " receivers, " +
                                std::to_string(proxies) + " proxies exceed the 32-bit indexing");
  auto sums = std::make_shared<IndirectSums>();
  sums->rgb.assign(count * 3, 0.0f);
  sums->omega.assign(count, 0.0f);
  auto& rec = ctx.record();
  rec.counters["receivers"] = static_cast<double>(count);
  rec.counters["proxies"] = static_cast<double>(proxies);
  rec.bytes = (sums->rgb.size() + sums->omega.size()) * sizeof(float);
  std::size_t uploaded = 0;
  const std::size_t before = dev.transfer_bytes().upload;
  const std::uint32_t op = upload_indirect_tables(dev, st->tables, ev);
  uploaded += dev.transfer_bytes().upload - before;
  if (count == 0) return sums;
  check_device(dev, "accumulate_indirect", static_cast<std::uint32_t>(r.width), static_cast<std::uint32_t>(r.height), pixels, 1, true);

  const IndirectSetup& setup = ev.setup();
  const IndirectEvaluator::TableView tv = ev.tables();
  SplatPush push = frame_push(ctx, dev, *st, r, "accumulate_indirect", uploaded);
  push.sizes.z = static_cast<std::uint32_t>(tv.rows);
  push.table = glm::vec4(tv.scale, setup.eta > 0.0 ? static_cast<float>(setup.eta) : 0.0f, static_cast<float>(setup.reach), 0.0f);
  const DeviceProxies in = device_indirect_proxies(all, alpha);
  const std::size_t before2 = dev.transfer_bytes().upload;
  put_if_changed(dev, st->ind_test, st->ind_test_hash, in.test, "image_splat indirect spheres of influence");
  put_if_changed(dev, st->ind_spheres, st->ind_spheres_hash, in.a, "image_splat indirect proxy spheres");
  put_if_changed(dev, st->ind_albedo, st->ind_albedo_hash, in.b, "image_splat indirect proxy albedo");
  const std::uint32_t zero = 0;
  dev.ensure_buffer(st->pairs, sizeof zero, kStorage, vk::MemoryKind::Host, "image_splat indirect splat pair count");
  dev.upload(st->pairs, &zero, sizeof zero);
  uploaded += dev.transfer_bytes().upload - before2;
  dev.ensure_buffer(st->ind_raw, pixels * 4 * sizeof(float), kStorage, vk::MemoryKind::Host, "image_splat indirect splat sums");

  const std::vector<vk::Bind> binds = {
      vk::Bind::texels_at(gpu::kSplatBindTest, st->ind_test, VK_FORMAT_R32G32B32A32_SFLOAT),
      vk::Bind::texels_at(gpu::kSplatBindHull, st->hull, VK_FORMAT_R32G32B32A32_SFLOAT),
      vk::Bind::buffer_at(gpu::kSplatBindBasis, basis_constants(dev)),
      vk::Bind::texels_at(gpu::kSplatBindReceivers, st->receivers, VK_FORMAT_R32_SFLOAT),
      vk::Bind::texels_at(gpu::kSplatBindPixelReceiver, st->pixel_receiver, VK_FORMAT_R32_SINT),
      vk::Bind::texels_at(gpu::kSplatIndBindProxies, st->ind_spheres, VK_FORMAT_R32G32B32A32_SFLOAT),
      vk::Bind::texels_at(gpu::kSplatIndBindAlbedo, st->ind_albedo, VK_FORMAT_R32G32B32A32_SFLOAT),
      vk::Bind::texels_at(gpu::kSplatIndBindVis, st->tables.vis, VK_FORMAT_R32_SFLOAT),
      vk::Bind::texels_at(gpu::kSplatIndBindDfac, st->tables.dfac, VK_FORMAT_R32_SFLOAT),
      vk::Bind::buffer_at(gpu::kSplatIndBindConsts, st->tables.consts),
      vk::Bind::texels_at(gpu::kSplatIndBindMtab, st->tables.mtab, VK_FORMAT_R32_SFLOAT),
      vk::Bind::texels_at(gpu::kSplatIndBindQrot, st->tables.qrot, VK_FORMAT_R32_SFLOAT),
      vk::Bind::buffer_at(gpu::kSplatIndBindPairs, st->pairs)};
  const VkPipeline pipe = splat_pipeline(
      dev, *st, {static_cast<std::uint32_t>(Kind::Indirect), static_cast<std::uint32_t>(tv.order), static_cast<std::uint32_t>(setup.rule), op, 0u},
      1);
  const vk::SubmitResult res = dev.submit([&](vk::Recorder& rc) {
    rc.begin_timer("splat_indirect");
    record_splats(rc, dev, *st, *st->ind_layout, {pipe}, binds, push, 1, 1, r, proxies, st->ind_raw);
    rc.end_timer();
    rc.barrier();
  }, "image_splat splat_indirect");
  // The sums in receiver order, from the pixels' (read back: the host passes after take them there).
  std::vector<float> raw(pixels * 4);
  std::uint32_t inside = 0;
  dev.download(st->ind_raw, raw.data(), raw.size() * sizeof(float));
  dev.download(st->pairs, &inside, sizeof inside);
  for (std::size_t i = 0; i < count; ++i) {
    const std::size_t px = static_cast<std::size_t>(r.pixel[i]);
    for (int c = 0; c < 3; ++c) sums->rgb[3 * i + c] = raw[4 * px + c];
    sums->omega[i] = raw[4 * px + 3];
  }
  sums->pairs = static_cast<double>(inside);
  rec.counters["pairs_inside_influence"] = static_cast<double>(inside);
  rec.counters["hull_triangles"] = static_cast<double>(st->hull_vertices / 3);
  rec.counters["splat_draws"] = 1.0;
  rec.counters["kernel_gpu_seconds"] = timer_seconds(res);
  rec.counters["upload_bytes"] = static_cast<double>(uploaded);
  return sums;
}

}  // namespace softgi::techniques::image_splat
