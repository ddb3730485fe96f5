// The Vulkan implementation of the shared "gbuffer" and "receiver_gbuffer" passes: a graphics
// pipeline (shaders/gbuffer/gbuffer_raster.{vert,frag}) rasterises every posed object's triangles
// (world-space positions and normals uploaded per frame; objects are skinned on the CPU by
// scene::evaluate) into a visibility buffer (object, primitive, barycentrics), a compute pass
// (gbuffer_resolve.comp) turns each pixel of it into position, depth and normal, and the result is
// read back into a render::GBuffer with the meaning of every plane of the CPU G-buffer
// (backends/cpu/gbuffer_cpu.cpp):
//
//   position, depth  resolve pass: w p0 + b1 p1 + b2 p2 of the triangle's posed corners (fetched
//                    from the same vertex arrays), depth (p - e) . E (paper 000 section 4)
//   normal           resolve pass: the CPU's rule (interpolated vertex normal, normalised, turned
//                    to the side of the geometric normal that faces the viewer)
//   object, primitive, barycentric
//                    rasterised: per-corner weights (1,0,0), (0,1,0), (0,0,1), perspective-correct
//   albedo           host, after readback, from (object, primitive, b1, b2) with the reference's rule
//                    (material x texture x vertex colour). Why host: Texture::sample is a bilinear
//                    filter on float texels with repeat wrap; a GPU sampler quantises its bilinear
//                    weights (Vulkan guarantees 4 bits of sub-texel precision, lavapipe has 8) and
//                    would need every texture uploaded. Evaluating the one CPU function at the
//                    rasterised barycentrics makes albedo differ from the CPU only through them.
//   view_dir         host: -PinholeCamera::direction of the pixel (hits), the direction itself for
//                    background; a function of the pixel alone, so the same float operations as the CPU.
//
// Projection: vulkan::clip_from_world (softgi/backends/vulkan/projection.hpp), reverse Z with an
// infinite far plane; the near plane is kNearRelative of the farthest vertex.
#include "gbuffer_raster.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include <glm/glm.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include "gbuffer_shared.h"
#include "softgi/backends/vulkan/backend.hpp"
#include "softgi/backends/vulkan/context.hpp"
#include "softgi/backends/vulkan/gbuffer_device.hpp"
#include "softgi/backends/vulkan/projection.hpp"
#include "softgi/render/camera.hpp"
#include "softgi/render/common_passes.hpp"
#include "softgi/render/frame.hpp"
#include "softgi/render/gbuffer.hpp"
#include "softgi/shaders/gbuffer/gbuffer_raster_frag.h"
#include "softgi/shaders/gbuffer/gbuffer_raster_vert.h"
#include "softgi/shaders/gbuffer/gbuffer_resolve_comp.h"

namespace softgi::backends {

namespace {

namespace vk = softgi::backends::vulkan;
using glm::vec3;
constexpr float kInf = std::numeric_limits<float>::infinity();
// Near plane as a fraction of the farthest vertex's eye depth: with reverse float depth the ratio
// of near to far costs no precision, and 1e-6 clips only geometry closer to the eye than a
// millionth of the scene's depth range.
constexpr float kNearRelative = 1e-6f;
// Target sets (attachments, framebuffer, readback) kept per buffer size and pass: the display
// G-buffer and one receiver buffer per frame, plus slack for a changed resolution. The display's
// are its own even where a receiver buffer has its size, since its resolved planes serve later
// passes of the frame (vulkan::DeviceGBuffer).
constexpr std::size_t kMaxTargetSizes = 4;

// std140 mirror of GbFrame (shaders/gbuffer/gbuffer_common.glsl).
struct GbFrame {
  glm::mat4 clip_from_world;
  glm::vec4 eye, forward, right, up;
  glm::vec4 image;   // display width, display height, scale, tan_half_fov_y
  glm::vec4 image2;  // aspect
};
static_assert(sizeof(GbFrame) == 160, "GbFrame must match the std140 block of gbuffer_common.glsl");
// std430 push-constant block GbDraw (gbuffer_raster.frag).
struct GbDraw {
  std::int32_t object = -1;
  std::uint32_t first_triangle = 0;
  std::uint32_t has_normals = 0;
};
static_assert(sizeof(GbDraw) == 12);
// std430 push-constant block GbResolve (gbuffer_resolve.comp).
struct GbResolve {
  std::uint32_t width = 0, height = 0;
};

constexpr std::array<VkFormat, gpu::kGbColorAttachments> kColorFormats = {
    VK_FORMAT_R32G32_SINT,    // kGbOutIds
    VK_FORMAT_R32G32_SFLOAT,  // kGbOutBarycentric
};
constexpr std::array<std::uint32_t, gpu::kGbColorAttachments> kTexelBytes = {8, 8};
// The resolve pass's outputs: position and depth, normal and depth (vec4 each).
constexpr std::size_t kResolvedTexelBytes = 2 * sizeof(glm::vec4);
constexpr VkFormat kDepthFormat = VK_FORMAT_D32_SFLOAT;

// Size-independent objects: layout (from SPIR-V reflection), render pass, pipeline (viewport and
// scissor are dynamic, so one pipeline serves every buffer size).
struct RasterPipeline {
  std::unique_ptr<vk::PipelineLayout> layout;
  vk::Owned<VkRenderPass> render_pass;
  vk::Owned<VkPipeline> pipeline;
};

// Per buffer size: attachments, framebuffer, host-visible readback buffers (the attachments'
// copies, which the resolve pass reads) and the resolve pass's outputs, in device memory (later
// passes of the frame read the display's there: vulkan::DeviceGBuffer) with host copies to read
// them back through where that memory is not mapped (a discrete GPU).
struct Targets {
  std::uint32_t width = 0, height = 0;
  bool display = false;
  std::array<vk::Image, gpu::kGbColorAttachments> color;
  vk::Image depth;
  vk::Owned<VkFramebuffer> framebuffer;
  std::array<vk::Buffer, gpu::kGbColorAttachments> readback;
  vk::Buffer position_depth, normal;
  vk::Buffer position_depth_host, normal_host;  // empty where position_depth and normal are mapped
  std::size_t bytes() const {
    const std::size_t n = static_cast<std::size_t>(width) * height;
    std::size_t b = n * (4 + kResolvedTexelBytes);  // depth, resolved planes
    if (position_depth_host) b += n * kResolvedTexelBytes;
    for (std::size_t a = 0; a < kTexelBytes.size(); ++a) b += 2 * n * kTexelBytes[a];
    return b;
  }
};

// What the pass keeps in the Context's cache from frame to frame.
struct RasterState {
  std::mutex m;
  std::unique_ptr<RasterPipeline> pipe;
  std::unique_ptr<vk::ComputePipeline> resolve;
  std::vector<std::unique_ptr<Targets>> targets;  // most recently used last
  vk::Buffer positions, normals, indices, frame, objects;
  // The frame (FrameContext::id) whose display G-buffer the display targets resolved last, 0: none.
  std::uint64_t display_frame = 0;
};

std::span<const std::uint32_t> words(const std::uint32_t* w, std::size_t bytes) { return {w, bytes / sizeof(std::uint32_t)}; }

std::unique_ptr<RasterPipeline> make_pipeline(vk::Context& ctx) {
  const auto vs_words = words(gbuffer_gbuffer_raster_vert, sizeof(gbuffer_gbuffer_raster_vert));
  const auto fs_words = words(gbuffer_gbuffer_raster_frag, sizeof(gbuffer_gbuffer_raster_frag));
  const vk::ShaderReflection rv = vk::reflect_spirv(vs_words), rf = vk::reflect_spirv(fs_words);
  auto p = std::make_unique<RasterPipeline>();
  p->layout = std::make_unique<vk::PipelineLayout>(ctx, std::vector<vk::ShaderReflection>{rv, rf}, "gbuffer_raster");

  // The colour attachments are copied to the readback buffers; depth only serves the draw.
  p->render_pass = vk::create_render_pass(ctx, {"gbuffer_raster", {kColorFormats.begin(), kColorFormats.end()}, kDepthFormat, false});
  const VkRenderPass render_pass = p->render_pass.get();

  vk::Owned<VkShaderModule> vs = ctx.create_shader_module(vs_words, "gbuffer_raster.vert");
  vk::Owned<VkShaderModule> fs = ctx.create_shader_module(fs_words, "gbuffer_raster.frag");
  VkPipelineDepthStencilStateCreateInfo ds{VK_STRUCTURE_TYPE_PIPELINE_DEPTH_STENCIL_STATE_CREATE_INFO};
  ds.depthTestEnable = VK_TRUE;
  ds.depthWriteEnable = VK_TRUE;
  ds.depthCompareOp = VK_COMPARE_OP_GREATER;  // reverse Z: nearer is larger
  vk::GraphicsPipelineDesc gd;
  gd.name = "gbuffer_raster";
  gd.layout = p->layout->handle();
  gd.render_pass = render_pass;
  gd.vertex = vs.get();
  gd.fragment = fs.get();
  gd.vertex_entry = rv.entry_point;
  gd.fragment_entry = rf.entry_point;
  gd.cull = VK_CULL_MODE_NONE;  // two-sided surfaces: the ray caster hits both sides
  gd.depth = &ds;
  gd.blend.assign(gpu::kGbColorAttachments, vk::write_all_channels());
  // One sample at the pixel centre, like one ray.
  p->pipeline = vk::create_graphics_pipeline(ctx, gd);
  return p;
}

std::unique_ptr<Targets> make_targets(vk::Context& ctx, const RasterPipeline& pipe, std::uint32_t w, std::uint32_t h, bool display) {
  auto t = std::make_unique<Targets>();
  t->width = w;
  t->height = h;
  t->display = display;
  const std::string size = std::to_string(w) + "x" + std::to_string(h);
  std::array<VkImageView, gpu::kGbColorAttachments + 1> views{};
  for (std::uint32_t a = 0; a < gpu::kGbColorAttachments; ++a) {
    t->color[a] = ctx.create_image(w, h, kColorFormats[a], VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT,
                                   VK_IMAGE_ASPECT_COLOR_BIT, "gbuffer_raster attachment " + std::to_string(a) + " " + size);
    t->readback[a] = ctx.create_buffer(static_cast<VkDeviceSize>(w) * h * kTexelBytes[a],
                                       VK_BUFFER_USAGE_TRANSFER_DST_BIT | VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, vk::MemoryKind::Host,
                                       "gbuffer_raster readback " + std::to_string(a) + " " + size);
    views[a] = t->color[a].view();
  }
  const VkDeviceSize plane = static_cast<VkDeviceSize>(w) * h * sizeof(glm::vec4);
  const VkBufferUsageFlags resolved = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT;
  t->position_depth = ctx.create_buffer(plane, resolved, vk::MemoryKind::Device, "gbuffer_raster resolved position " + size);
  t->normal = ctx.create_buffer(plane, resolved, vk::MemoryKind::Device, "gbuffer_raster resolved normal " + size);
  if (!t->position_depth.mapped() || !t->normal.mapped()) {
    t->position_depth_host = ctx.create_buffer(plane, VK_BUFFER_USAGE_TRANSFER_DST_BIT, vk::MemoryKind::Host,
                                               "gbuffer_raster resolved position readback " + size);
    t->normal_host = ctx.create_buffer(plane, VK_BUFFER_USAGE_TRANSFER_DST_BIT, vk::MemoryKind::Host,
                                       "gbuffer_raster resolved normal readback " + size);
  }
  t->depth = ctx.create_image(w, h, kDepthFormat, VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT, VK_IMAGE_ASPECT_DEPTH_BIT,
                              "gbuffer_raster depth " + size);
  views[gpu::kGbColorAttachments] = t->depth.view();
  t->framebuffer = vk::create_framebuffer(ctx, pipe.render_pass.get(), {views.begin(), views.end()}, w, h, "gbuffer_raster");
  return t;
}

Targets& targets_for(vk::Context& ctx, RasterState& st, std::uint32_t w, std::uint32_t h, bool display) {
  auto it = std::find_if(st.targets.begin(), st.targets.end(),
                         [&](const auto& t) { return t->width == w && t->height == h && t->display == display; });
  if (it != st.targets.end()) {
    std::rotate(it, it + 1, st.targets.end());  // most recently used last
    return *st.targets.back();
  }
  if (st.targets.size() >= kMaxTargetSizes) st.targets.erase(st.targets.begin());  // the submissions using it completed
  st.targets.push_back(make_targets(ctx, *st.pipe, w, h, display));
  return *st.targets.back();
}

struct Draw {
  GbDraw push;
  std::uint32_t triangles = 0;
};

struct RasterStats {
  long long pixels = 0, hits = 0, triangles = 0, draws = 0;
  double upload_bytes = 0.0, near_plane = 0.0, gather_seconds = 0.0, raster_gpu_seconds = -1.0, readback_seconds = 0.0;
  std::size_t held_bytes = 0;
};

bool drawn(const scene::PosedObject& o) { return o.source && !o.source->triangles.empty() && !o.positions.empty(); }

// The one rasterisation of the Vulkan backend: a buffer of ceil(W/s) x ceil(H/s) pixels whose pixel
// (x, y) holds what the display camera sees through display point ((x + 0.5) s, (y + 0.5) s).
// `display`: the frame's display G-buffer, whose resolved planes stay on the device for its later
// passes (publish_display_planes).
render::GBuffer rasterise(render::FrameContext& fc, int scale, unsigned planes, const char* who, bool display, RasterStats& stats) {
  using clock = std::chrono::steady_clock;
  const render::PinholeCamera cam = render::make_pinhole_camera(fc.scene, fc.width, fc.height, who);
  const int bw = (fc.width + scale - 1) / scale, bh = (fc.height + scale - 1) / scale;
  const std::size_t n = static_cast<std::size_t>(bw) * bh;
  const auto t0 = clock::now();

  // Every drawn object's posed vertices and triangles, concatenated (indices made global).
  std::vector<float> positions, normals;
  std::vector<std::uint32_t> indices;
  std::vector<Draw> draws;
  // Per posed object (by its index): first triangle in `indices`, has vertex normals.
  std::vector<glm::uvec2> objects(std::max<std::size_t>(fc.posed.objects.size(), 1), glm::uvec2(0u));
  float max_depth = 0.0f;
  std::size_t vertex_total = 0, triangle_total = 0;
  for (const scene::PosedObject& o : fc.posed.objects)
    if (drawn(o)) {
      vertex_total += o.positions.size();
      triangle_total += o.source->triangles.size();
    }
  // Vertex numbers (3 per triangle) and global indices are 32-bit in the draw and the shaders.
  if (3 * triangle_total > std::numeric_limits<std::uint32_t>::max() || vertex_total > std::numeric_limits<std::uint32_t>::max())
    throw std::invalid_argument(std::string(who) + ": " + std::to_string(triangle_total) + " triangles and " +
                                std::to_string(vertex_total) + " vertices exceed the 32-bit vertex numbering of the Vulkan G-buffer");
  positions.reserve(3 * vertex_total);
  normals.reserve(3 * vertex_total);
  indices.reserve(3 * triangle_total);
  for (std::size_t oi = 0; oi < fc.posed.objects.size(); ++oi) {
    const scene::PosedObject& o = fc.posed.objects[oi];
    if (!drawn(o)) continue;
    const auto base = static_cast<std::uint32_t>(positions.size() / 3);
    for (std::size_t v = 0; v < o.positions.size(); ++v) {
      const vec3& p = o.positions[v];
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
        throw std::invalid_argument(std::string(who) + ": mesh '" + o.source->name + "': posed vertex " + std::to_string(v) +
                                    " is not finite");
      positions.insert(positions.end(), {p.x, p.y, p.z});
      max_depth = std::max(max_depth, cam.depth(p));
    }
    const bool has_normals = o.normals.size() == o.positions.size();
    for (std::size_t v = 0; v < o.positions.size(); ++v) {
      const vec3 nv = has_normals ? o.normals[v] : vec3(0.0f);
      normals.insert(normals.end(), {nv.x, nv.y, nv.z});
    }
    Draw d;
    d.push.object = static_cast<std::int32_t>(oi);
    d.push.first_triangle = static_cast<std::uint32_t>(indices.size() / 3);
    d.push.has_normals = has_normals ? 1u : 0u;
    d.triangles = static_cast<std::uint32_t>(o.source->triangles.size());
    objects[oi] = glm::uvec2(d.push.first_triangle, d.push.has_normals);
    const auto& tris = o.source->triangles;
    for (std::size_t t = 0; t < tris.size(); ++t)
      for (int k = 0; k < 3; ++k) {
        if (tris[t][k] >= o.positions.size())
          throw std::invalid_argument(std::string(who) + ": mesh '" + o.source->name + "': triangle " + std::to_string(t) +
                                      " has vertex index " + std::to_string(tris[t][k]) + " >= " +
                                      std::to_string(o.positions.size()));
        indices.push_back(base + tris[t][k]);
      }
    draws.push_back(d);
  }
  stats.gather_seconds = std::chrono::duration<double>(clock::now() - t0).count();
  stats.pixels = static_cast<long long>(n);
  stats.triangles = static_cast<long long>(triangle_total);
  stats.draws = static_cast<long long>(draws.size());

  // The CPU G-buffer's ray of each pixel (PinholeCamera::buffer_direction, to the bit), from screen
  // coordinates worked out once per column and row; only the view_dir plane needs it.
  const render::BufferRays rays(cam, bw, bh, scale);
  auto ray = [&](int x, int y) { return rays.direction(x, y); };

  // Nothing in front of the camera: every pixel is background (no GPU work); the background's view
  // directions where the frame holds that plane.
  if (draws.empty() || !(max_depth > 0.0f)) {
    render::GBuffer gb = render::GBuffer::background(bw, bh, scale, &fc.pool(), planes);
    if (gb.planes & render::kGBufferViewDir)
      for (int y = 0; y < bh; ++y)
        for (int x = 0; x < bw; ++x) gb.view_dir[static_cast<std::size_t>(y) * bw + x] = ray(x, y);
    return gb;
  }
  const float near_plane = kNearRelative * max_depth;
  stats.near_plane = near_plane;

  vk::Context& ctx = vk::context_of(fc);
  auto state = ctx.cached<RasterState>("gbuffer_raster.state", [] { return std::make_shared<RasterState>(); });
  std::lock_guard<std::mutex> lock(state->m);
  if (!state->pipe) state->pipe = make_pipeline(ctx);
  if (!state->resolve)
    state->resolve = std::make_unique<vk::ComputePipeline>(ctx, words(gbuffer_gbuffer_resolve_comp, sizeof(gbuffer_gbuffer_resolve_comp)),
                                                           "gbuffer_resolve");
  const RasterPipeline& pipe = *state->pipe;
  Targets& tg = targets_for(ctx, *state, static_cast<std::uint32_t>(bw), static_cast<std::uint32_t>(bh), display);
  if (display) state->display_frame = 0;  // until this frame's planes are resolved and read back

  const VkBufferUsageFlags storage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
  const std::size_t pos_bytes = positions.size() * sizeof(float), idx_bytes = indices.size() * sizeof(std::uint32_t);
  ctx.ensure_buffer(state->positions, pos_bytes, storage, vk::MemoryKind::Device, "gbuffer_raster positions");
  ctx.ensure_buffer(state->normals, pos_bytes, storage, vk::MemoryKind::Device, "gbuffer_raster normals");
  ctx.ensure_buffer(state->indices, idx_bytes, storage, vk::MemoryKind::Device, "gbuffer_raster indices");
  const std::size_t obj_bytes = objects.size() * sizeof(glm::uvec2);
  ctx.ensure_buffer(state->objects, obj_bytes, storage, vk::MemoryKind::Device, "gbuffer_raster objects");
  ctx.ensure_buffer(state->frame, sizeof(GbFrame), VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT, vk::MemoryKind::Host, "gbuffer_raster frame");
  ctx.upload(state->positions, positions.data(), pos_bytes);
  ctx.upload(state->normals, normals.data(), pos_bytes);
  ctx.upload(state->indices, indices.data(), idx_bytes);
  ctx.upload(state->objects, objects.data(), obj_bytes);
  GbFrame frame{};
  frame.clip_from_world = vk::clip_from_world(cam, bw, bh, scale, near_plane);
  frame.eye = glm::vec4(cam.position, 0.0f);
  frame.forward = glm::vec4(cam.forward, 0.0f);
  frame.right = glm::vec4(cam.right, 0.0f);
  frame.up = glm::vec4(cam.up, 0.0f);
  frame.image = glm::vec4(static_cast<float>(cam.width), static_cast<float>(cam.height), static_cast<float>(scale), cam.tan_half_fov_y);
  frame.image2 = glm::vec4(cam.aspect, 0.0f, 0.0f, 0.0f);
  std::memcpy(state->frame.mapped(), &frame, sizeof frame);
  ctx.note_transfer(sizeof frame, 0);
  stats.upload_bytes = static_cast<double>(2 * pos_bytes + idx_bytes + obj_bytes + sizeof frame);

  const vk::SubmitResult sr = ctx.submit(
      [&](vk::Recorder& r) {
        r.barrier();  // the uploads (a staging copy on devices without host-visible device memory)
        r.begin_timer("rasterise");
        std::array<VkClearValue, gpu::kGbColorAttachments + 1> clear{};
        clear[gpu::kGbOutIds].color.int32[0] = -1;  // background: object -1, primitive -1
        clear[gpu::kGbOutIds].color.int32[1] = -1;
        clear[gpu::kGbColorAttachments].depthStencil = {0.0f, 0};  // reverse Z: 0 is infinitely far
        VkRenderPassBeginInfo bi{VK_STRUCTURE_TYPE_RENDER_PASS_BEGIN_INFO};
        bi.renderPass = pipe.render_pass.get();
        bi.framebuffer = tg.framebuffer.get();
        bi.renderArea = {{0, 0}, {tg.width, tg.height}};
        bi.clearValueCount = static_cast<std::uint32_t>(clear.size());
        bi.pClearValues = clear.data();
        const VkDescriptorSet set = r.descriptor_set(*pipe.layout, 0,
                                                     {vk::Bind::buffer_at(gpu::kGbBindFrame, state->frame),
                                                      vk::Bind::texels_at(gpu::kGbBindPositions, state->positions, VK_FORMAT_R32_SFLOAT),
                                                      vk::Bind::texels_at(gpu::kGbBindNormals, state->normals, VK_FORMAT_R32_SFLOAT),
                                                      vk::Bind::texels_at(gpu::kGbBindIndices, state->indices, VK_FORMAT_R32_UINT)});
        VkCommandBuffer cmd = r.cmd();
        vkCmdBeginRenderPass(cmd, &bi, VK_SUBPASS_CONTENTS_INLINE);
        vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, pipe.pipeline.get());
        vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, pipe.layout->handle(), 0, 1, &set, 0, nullptr);
        const VkViewport viewport{0.0f, 0.0f, static_cast<float>(tg.width), static_cast<float>(tg.height), 0.0f, 1.0f};
        const VkRect2D scissor{{0, 0}, {tg.width, tg.height}};
        vkCmdSetViewport(cmd, 0, 1, &viewport);
        vkCmdSetScissor(cmd, 0, 1, &scissor);
        if (pipe.layout->push_constant_size() != sizeof(GbDraw))
          throw std::logic_error("gbuffer_raster: the shaders' push constant block has " +
                                 std::to_string(pipe.layout->push_constant_size()) + " bytes, GbDraw " +
                                 std::to_string(sizeof(GbDraw)));
        for (const Draw& d : draws) {
          vkCmdPushConstants(cmd, pipe.layout->handle(), pipe.layout->push_constant_stages(), 0, sizeof(GbDraw), &d.push);
          vkCmdDraw(cmd, 3 * d.triangles, 1, 3 * d.push.first_triangle, 0);
        }
        vkCmdEndRenderPass(cmd);
        for (std::uint32_t a = 0; a < gpu::kGbColorAttachments; ++a) {
          VkBufferImageCopy c{};
          c.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
          c.imageExtent = {tg.width, tg.height, 1};
          vkCmdCopyImageToBuffer(cmd, tg.color[a].handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, tg.readback[a].handle(), 1, &c);
        }
        r.barrier();  // copies -> the resolve pass's reads
        const GbResolve push{tg.width, tg.height};
        // The resolve computes the surface planes only: a G-buffer without them skips it.
        if (planes & render::kGBufferSurface)
          r.dispatch(*state->resolve,
                     {vk::Bind::buffer_at(gpu::kGbBindFrame, state->frame),
                      vk::Bind::texels_at(gpu::kGbBindPositions, state->positions, VK_FORMAT_R32_SFLOAT),
                      vk::Bind::texels_at(gpu::kGbBindNormals, state->normals, VK_FORMAT_R32_SFLOAT),
                      vk::Bind::texels_at(gpu::kGbBindIndices, state->indices, VK_FORMAT_R32_UINT),
                      vk::Bind::buffer_at(gpu::kGbBindObjects, state->objects),
                      vk::Bind::buffer_at(gpu::kGbBindIds, tg.readback[gpu::kGbOutIds]),
                      vk::Bind::buffer_at(gpu::kGbBindBarycentric, tg.readback[gpu::kGbOutBarycentric]),
                      vk::Bind::buffer_at(gpu::kGbBindPositionDepth, tg.position_depth), vk::Bind::buffer_at(gpu::kGbBindNormal, tg.normal)},
                     push, state->resolve->groups_x(n));
        if ((planes & render::kGBufferSurface) && tg.position_depth_host) {
          r.barrier();  // resolve -> the copies the host reads
          r.copy(tg.position_depth, tg.position_depth_host, n * sizeof(glm::vec4));
          r.copy(tg.normal, tg.normal_host, n * sizeof(glm::vec4));
        }
        r.end_timer();
        r.barrier();  // resolve -> host reads
      },
      who);
  for (const auto& [label, seconds] : sr.timers)
    if (label == "rasterise") stats.raster_gpu_seconds = seconds;

  const auto t1 = clock::now();
  const auto* pd = static_cast<const glm::vec4*>((tg.position_depth_host ? tg.position_depth_host : tg.position_depth).mapped());
  const auto* nm = static_cast<const glm::vec4*>((tg.normal_host ? tg.normal_host : tg.normal).mapped());
  const auto* ids = static_cast<const glm::ivec2*>(tg.readback[gpu::kGbOutIds].mapped());
  const auto* bc = static_cast<const glm::vec2*>(tg.readback[gpu::kGbOutBarycentric].mapped());
  // Every pixel written once, background or hit, rows on every core. A pixel naming what the frame
  // did not draw is an error naming the first such pixel.
  render::GBuffer gb = render::GBuffer::for_overwrite(bw, bh, scale, fc.pool(), planes);
  const std::size_t npix = static_cast<std::size_t>(bw) * static_cast<std::size_t>(bh);
  std::atomic<std::size_t> first_bad{npix};
  const long long hits = tbb::parallel_reduce(
      tbb::blocked_range<int>(0, bh, 8), 0LL,
      [&](const tbb::blocked_range<int>& rows, long long count) {
        for (int y = rows.begin(); y != rows.end(); ++y)
          for (int x = 0; x < bw; ++x) {
            const std::size_t i = static_cast<std::size_t>(y) * bw + x;
            const int oi = ids[i].x;
            if (oi < 0) {
              gb.set_background(i, gb.planes & render::kGBufferViewDir ? ray(x, y) : glm::vec3(0.0f));
              continue;
            }
            const int prim = ids[i].y;
            if (oi >= static_cast<int>(fc.posed.objects.size()) || !drawn(fc.posed.objects[oi]) || prim < 0 ||
                prim >= static_cast<int>(fc.posed.objects[oi].source->triangles.size())) {
              std::size_t seen = first_bad.load();
              while (i < seen && !first_bad.compare_exchange_weak(seen, i)) {
              }
              gb.set_background(i, glm::vec3(0.0f));
              continue;
            }
            if (gb.planes & render::kGBufferSurface) {
              gb.position[i] = vec3(pd[i]);
              gb.depth[i] = pd[i].w;
              gb.normal[i] = vec3(nm[i]);
            }
            gb.object[i] = oi;
            gb.primitive[i] = prim;
            gb.barycentric[i] = bc[i];
            if (gb.planes & render::kGBufferAlbedo)
              gb.albedo[i] = scene::surface_albedo(fc.scene, fc.posed.objects[oi], static_cast<std::size_t>(prim), bc[i].x, bc[i].y);
            if (gb.planes & render::kGBufferViewDir) gb.view_dir[i] = -ray(x, y);
            ++count;
          }
        return count;
      },
      std::plus<long long>());
  if (const std::size_t i = first_bad.load(); i < npix) {
    const int x = static_cast<int>(i % static_cast<std::size_t>(bw)), y = static_cast<int>(i / static_cast<std::size_t>(bw));
    throw std::logic_error(std::string(who) + ": pixel (" + std::to_string(x) + ", " + std::to_string(y) + ") read back object " +
                           std::to_string(ids[i].x) + " primitive " + std::to_string(ids[i].y) + ", which the frame did not draw");
  }
  stats.readback_seconds = std::chrono::duration<double>(clock::now() - t1).count();
  if (display && (gb.planes & render::kGBufferSurface)) state->display_frame = fc.id();
  // The readback targets read through their mapping: ids and barycentrics, and the resolved
  // position-depth and normal where the frame's G-buffer holds the surface planes.
  ctx.note_transfer(0, static_cast<std::size_t>(bw) * bh *
                           ((gb.planes & render::kGBufferSurface ? 2 * sizeof(glm::vec4) : 0) + sizeof(glm::ivec2) + sizeof(glm::vec2)));
  stats.hits = hits;
  std::size_t held = state->positions.size() + state->normals.size() + state->indices.size() + state->objects.size() + state->frame.size();
  for (const auto& t : state->targets) held += t->bytes();
  stats.held_bytes = held;
  return gb;
}

void raster_counters(render::PassRecord& rec, const RasterStats& st) {
  rec.counters["rays"] = static_cast<double>(st.pixels);  // one sample per pixel centre, as the CPU's one ray
  rec.counters["hits"] = static_cast<double>(st.hits);
  rec.counters["triangles"] = static_cast<double>(st.triangles);
  rec.counters["draws"] = static_cast<double>(st.draws);
  rec.counters["upload_bytes"] = st.upload_bytes;
  rec.counters["near_plane"] = st.near_plane;
  rec.counters["gather_seconds"] = st.gather_seconds;
  rec.counters["readback_seconds"] = st.readback_seconds;
  if (st.raster_gpu_seconds >= 0.0) rec.counters["raster_gpu_seconds"] = st.raster_gpu_seconds;
}

// The "gbuffer" and "receiver_gbuffer" renderer. Paper 000 section 4, receiver setup: the receiver
// buffer at 1/s of the display resolution per axis (the CPU pass's contract:
// backends/cpu/gbuffer_cpu.cpp). Held: the device buffers and attachments kept for the next frame.
render::GBuffer produce_gbuffer(render::FrameContext& fc, int s, const char* pass, std::size_t& held) {
  RasterStats st;
  // The display G-buffer holds the planes the frame's passes read; a receiver buffer holds all.
  const bool display = s == 1 && std::string(pass) == "gbuffer";
  const unsigned planes = display ? fc.gbuffer_planes() : render::kGBufferAll;
  render::GBuffer gb = rasterise(fc, s, planes, pass, display, st);
  raster_counters(fc.record(), st);
  held = st.held_bytes;
  return gb;
}

}  // namespace

void gbuffer_raster_memory(const std::vector<const render::PassDesc*>& passes, const scene::Scene& scene,
                           const render::ParamSet& params, int width, int height, bool resolved_readback,
                           std::vector<render::MemoryItem>& items) {
  bool display = false;
  int receiver_scale = 0;
  for (const render::PassDesc* p : passes) {
    if (p->name == "gbuffer") display = true;
    if (p->name == "receiver_gbuffer") receiver_scale = params.has("receiver_scale") ? params.get_int("receiver_scale") : 1;
  }
  // At scale 1 the receiver buffer is a copy of the display G-buffer: nothing is rasterised.
  if (receiver_scale == 1 && display) receiver_scale = 0;
  if (!display && receiver_scale == 0) return;
  auto targets = [&](const char* pass, int scale) {
    const int w = render::scaled_size(width, scale), h = render::scaled_size(height, scale);
    const std::size_t n = render::pixel_count(w, h);
    const std::string size = std::to_string(w) + "x" + std::to_string(h);
    for (std::size_t a = 0; a < kTexelBytes.size(); ++a) {
      items.push_back({"gbuffer_raster attachment " + std::to_string(a) + " " + size, n * kTexelBytes[a], render::MemoryPlace::Device,
                       pass, false, false});
      items.push_back({"gbuffer_raster readback " + std::to_string(a) + " " + size, n * kTexelBytes[a], render::MemoryPlace::Device,
                       pass, false, false});
    }
    items.push_back({"gbuffer_raster depth " + size, n * sizeof(float), render::MemoryPlace::Device, pass, false, false});
    items.push_back({"gbuffer_raster resolved position " + size, n * sizeof(glm::vec4), render::MemoryPlace::Device, pass, false, false});
    items.push_back({"gbuffer_raster resolved normal " + size, n * sizeof(glm::vec4), render::MemoryPlace::Device, pass, false, false});
    if (resolved_readback) {
      items.push_back({"gbuffer_raster resolved position readback " + size, n * sizeof(glm::vec4), render::MemoryPlace::Device, pass, false,
                       false});
      items.push_back({"gbuffer_raster resolved normal readback " + size, n * sizeof(glm::vec4), render::MemoryPlace::Device, pass, false,
                       false});
    }
  };
  if (display) targets("gbuffer", 1);
  if (receiver_scale > 0) targets("receiver_gbuffer", receiver_scale);
  // Every object's vertices and triangles, uploaded once for both passes (rasterise()).
  std::size_t vertices = 0, triangles = 0;
  for (const auto& node : scene.nodes)
    if (node.mesh >= 0 && node.mesh < static_cast<int>(scene.meshes.size())) {
      vertices += scene.meshes[node.mesh].positions.size();
      triangles += scene.meshes[node.mesh].triangles.size();
    }
  const char* pass = display ? "gbuffer" : "receiver_gbuffer";
  items.push_back({"gbuffer_raster positions", vertices * 3 * sizeof(float), render::MemoryPlace::Device, pass, false, true});
  items.push_back({"gbuffer_raster normals", vertices * 3 * sizeof(float), render::MemoryPlace::Device, pass, false, true});
  items.push_back({"gbuffer_raster indices", triangles * 3 * sizeof(std::uint32_t), render::MemoryPlace::Device, pass, false, true});
}

namespace {

// After the "gbuffer" pass's put: the resolved normal and depth of this frame's display G-buffer as
// the device copy of render::kGBuffer, tied to the host planes just put.
void publish_display_planes(render::FrameContext& fc) {
  vk::Context& ctx = vk::context_of(fc);
  auto state = ctx.cached<RasterState>("gbuffer_raster.state", [] { return std::make_shared<RasterState>(); });
  std::lock_guard<std::mutex> lock(state->m);
  if (state->display_frame != fc.id()) return;
  const render::GBuffer& gb = fc.get<render::GBuffer>(render::kGBuffer);
  // The display's target set of the G-buffer's size: the one this frame's rasterisation resolved into.
  const auto it = std::find_if(state->targets.begin(), state->targets.end(), [&](const auto& t) {
    return t->display && static_cast<int>(t->width) == gb.width && static_cast<int>(t->height) == gb.height;
  });
  if (it == state->targets.end() || !(gb.planes & render::kGBufferSurface)) return;
  const Targets& tg = **it;
  fc.put_device<vk::DeviceGBuffer>(render::kGBuffer, vk::DeviceGBuffer{&tg.normal, &tg.position_depth, gb.width, gb.height, gb.depth.data(),
                                                                        gb.normal.data(), gb.position.data()});
}

}  // namespace

void register_gbuffer_raster_passes() {
  render::register_gbuffer_pass_impls(vulkan::kBackendName, produce_gbuffer, publish_display_planes);
}

}  // namespace softgi::backends
