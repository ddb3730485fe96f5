// The lights' depth maps of point-proxy voxels (paper 002 Figure 2a) rasterised on the Vulkan
// device: a depth-only graphics pipeline (shaders/point_voxels/depth_raster.vert) draws the posed
// triangles into each face of every local light's cube map and into the sun's directional map, each
// face's depth attachment is copied to a buffer and depth_resolve.comp turns its values into the
// depths of the CPU's software rasteriser (rasterize_cube_depth, rasterize_ortho_depth). The maps
// stay on the device for the VPL lighting; the host copy (for the direct pass) is read back only
// when asked for.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "pv_passes.hpp"
#include "pv_vulkan.hpp"
#include "../common/accumulation_vulkan.hpp"
#include "softgi/backends/vulkan/backend.hpp"
#include "softgi/backends/vulkan/context.hpp"
#include "pv_shared.h"

namespace spv {
#include "softgi/shaders/point_voxels/depth_raster_vert.h"
#include "softgi/shaders/point_voxels/depth_resolve_comp.h"
}  // namespace spv

namespace softgi::techniques::point_voxels {

namespace vk = backends::vulkan;
using namespace common::gpu_passes;

namespace {

constexpr VkFormat kDepthFormat = VK_FORMAT_D32_SFLOAT;

struct RasterPush {
  glm::vec4 center_near;
  glm::ivec4 mode_axes;
  glm::vec4 params, u_lo, v_lo, dir, extent;
};
static_assert(sizeof(RasterPush) == 112);

// The depth-only pipeline and, per map size, its attachment and framebuffer.
struct DepthRaster {
  std::mutex m;
  std::unique_ptr<vk::PipelineLayout> layout;
  vk::Owned<VkRenderPass> render_pass;
  vk::Owned<VkPipeline> pipeline;
  std::uint32_t size = 0;
  vk::Image depth;
  vk::Owned<VkFramebuffer> framebuffer;
  vk::Buffer corners, raw;
  std::uint64_t corners_hash = 0;
  PipelineCache compute;
};

void make_pipeline(vk::Context& ctx, DepthRaster& r) {
  const auto vs_words = words(spv::point_voxels_depth_raster_vert);
  const vk::ShaderReflection rv = vk::reflect_spirv(vs_words);
  r.layout = std::make_unique<vk::PipelineLayout>(ctx, std::vector<vk::ShaderReflection>{rv}, "point_voxels depth_raster");
  // Depth only, copied to the raw buffer after each face.
  r.render_pass = vk::create_render_pass(ctx, {"point_voxels depth_raster", {}, kDepthFormat, true});
  const VkRenderPass render_pass = r.render_pass.get();

  vk::Owned<VkShaderModule> vs = ctx.create_shader_module(vs_words, "point_voxels depth_raster.vert");
  VkPipelineDepthStencilStateCreateInfo ds{VK_STRUCTURE_TYPE_PIPELINE_DEPTH_STENCIL_STATE_CREATE_INFO};
  ds.depthTestEnable = VK_TRUE;
  ds.depthWriteEnable = VK_TRUE;
  ds.depthCompareOp = VK_COMPARE_OP_GREATER;  // cube faces; the directional map is drawn with the depth flipped to match
  vk::GraphicsPipelineDesc gd;
  gd.name = "point_voxels depth_raster";
  gd.layout = r.layout->handle();
  gd.render_pass = render_pass;
  gd.vertex = vs.get();
  gd.vertex_entry = rv.entry_point;
  gd.cull = VK_CULL_MODE_NONE;  // both sides cast shadows, as on the CPU
  gd.depth = &ds;
  // One sample: the texel centre, as the CPU's coverage test.
  r.pipeline = vk::create_graphics_pipeline(ctx, gd);
}

void make_target(vk::Context& ctx, DepthRaster& r, std::uint32_t size) {
  r.framebuffer.reset();
  r.depth = ctx.create_image(size, size, kDepthFormat, VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT,
                             VK_IMAGE_ASPECT_DEPTH_BIT, "point_voxels depth map " + std::to_string(size) + "^2");
  const VkImageView view = r.depth.view();
  r.framebuffer = vk::create_framebuffer(ctx, r.render_pass.get(), {view}, size, size, "point_voxels depth_raster");
  r.size = size;
}

// One map (`count` faces) drawn face by face, each face copied to the raw buffer at its place.
void record_faces(vk::Recorder& rec, DepthRaster& r, const std::vector<RasterPush>& faces, float clear, std::uint32_t corners) {
  VkCommandBuffer cmd = rec.cmd();
  const VkDescriptorSet set = rec.descriptor_set(*r.layout, 0, {vk::Bind::buffer_at(gpu::kPvRasterBindCorners, r.corners)});
  for (std::size_t f = 0; f < faces.size(); ++f) {
    VkClearValue cv{};
    cv.depthStencil.depth = clear;
    VkRenderPassBeginInfo bi{VK_STRUCTURE_TYPE_RENDER_PASS_BEGIN_INFO};
    bi.renderPass = r.render_pass.get();
    bi.framebuffer = r.framebuffer.get();
    bi.renderArea.extent = {r.size, r.size};
    bi.clearValueCount = 1;
    bi.pClearValues = &cv;
    vkCmdBeginRenderPass(cmd, &bi, VK_SUBPASS_CONTENTS_INLINE);
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, r.pipeline.get());
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, r.layout->handle(), 0, 1, &set, 0, nullptr);
    const VkViewport viewport{0.0f, 0.0f, static_cast<float>(r.size), static_cast<float>(r.size), 0.0f, 1.0f};
    const VkRect2D scissor{{0, 0}, {r.size, r.size}};
    vkCmdSetViewport(cmd, 0, 1, &viewport);
    vkCmdSetScissor(cmd, 0, 1, &scissor);
    vkCmdPushConstants(cmd, r.layout->handle(), r.layout->push_constant_stages(), 0, sizeof(RasterPush), &faces[f]);
    if (corners) vkCmdDraw(cmd, corners, 1, 0, 0);
    vkCmdEndRenderPass(cmd);
    VkBufferImageCopy copy{};
    copy.bufferOffset = static_cast<VkDeviceSize>(f) * r.size * r.size * sizeof(float);
    copy.imageSubresource = {VK_IMAGE_ASPECT_DEPTH_BIT, 0, 0, 1};
    copy.imageExtent = {r.size, r.size, 1};
    vkCmdCopyImageToBuffer(cmd, r.depth.handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, r.raw.handle(), 1, &copy);
  }
}

}  // namespace

std::vector<float> sun_header(const Lights& L) {
  std::vector<float> header(gpu::kPvSunHeader, 0.0f);
  if (!L.sun) return header;
  const OrthoDepthMap& m = L.sun_map;
  const float h[] = {m.dir.x, m.dir.y, m.dir.z, m.u.x, m.u.y, m.u.z, m.v.x, m.v.y, m.v.z, m.lo.x, m.lo.y, m.extent.x, m.extent.y,
                     static_cast<float>(m.size)};
  std::copy(std::begin(h), std::end(h), header.begin());
  return header;
}

void vulkan_light_maps(const Settings& s, render::FrameContext& ctx, std::shared_ptr<Lights> L, LightBuffers& out) {
  vk::Context& dev = vk::context_of(ctx);
  auto r = dev.cached<DepthRaster>("point_voxels.depth_raster", [] { return std::make_shared<DepthRaster>(); });
  std::lock_guard<std::mutex> lock(r->m);
  const auto size = static_cast<std::uint32_t>(s.shadow_map_size);
  const auto& lim = dev.device_info().limits;
  if (size > lim.maxImageDimension2D || size > lim.maxFramebufferWidth || size > lim.maxFramebufferHeight)
    throw std::invalid_argument("point_voxels light_maps on vulkan: parameter 'shadow_map_size' " + std::to_string(size) + " exceeds device '" +
                                dev.device_info().name + "''s largest framebuffer (" + std::to_string(lim.maxFramebufferWidth) + ")");
  const std::size_t face = static_cast<std::size_t>(size) * size;
  const std::size_t cube_floats = L->local.size() * 6 * face, sun_floats = L->sun ? face : 0;
  check_fits(dev, 6 * face * sizeof(float), "a cube depth map of " + std::to_string(size) + "^2 texels per face",
             "point_voxels light_maps", "use a smaller shadow_map_size, or --backend cpu");
  check_fits(dev, cube_floats * sizeof(float), "the cube depth maps of " + std::to_string(L->local.size()) + " lights", "point_voxels light_maps",
             "use a smaller shadow_map_size, or --backend cpu");

  // The posed triangles' corners, 3 per triangle; the directional map's depth range from the vertices.
  std::vector<glm::vec4> corners;
  float z_lo = std::numeric_limits<float>::infinity(), z_hi = -z_lo;
  for (const auto& obj : ctx.posed.objects) {
    if (!obj.source) continue;
    for (const auto& t : obj.source->triangles)
      for (int k = 0; k < 3; ++k) {
        if (t[k] >= obj.positions.size())
          throw std::invalid_argument("point_voxels light_maps on vulkan: mesh '" + obj.source->name + "' has a vertex index " +
                                      std::to_string(t[k]) + " >= " + std::to_string(obj.positions.size()));
        const glm::vec3 p = obj.positions[t[k]];
        corners.push_back(glm::vec4(p, 1.0f));
        if (L->sun) {
          const float z = -glm::dot(p, L->sun_map.dir);
          z_lo = std::min(z_lo, z);
          z_hi = std::max(z_hi, z);
        }
      }
  }
  if (corners.size() > std::numeric_limits<std::uint32_t>::max())
    throw std::invalid_argument("point_voxels light_maps on vulkan: " + std::to_string(corners.size() / 3) + " triangles exceed 32-bit vertex numbering");
  check_fits(dev, corners.size() * sizeof(glm::vec4), "the corners of " + std::to_string(corners.size() / 3) + " triangles",
             "point_voxels light_maps", "use a simpler scene, or --backend cpu");
  // Padded so that no vertex sits on the clip planes of the [0, 1] depth range.
  const float pad = std::max(1e-4f, 1e-3f * (z_hi - z_lo));
  z_lo -= pad;
  z_hi += pad;

  if (!r->pipeline) make_pipeline(dev, *r);
  if (r->size != size) make_target(dev, *r, size);
  const std::size_t before = dev.transfer_bytes().upload;
  upload_bytes_if_changed(dev, r->corners, r->corners_hash, corners.data(), corners.size() * sizeof(glm::vec4), "point_voxels triangle corners");
  const std::size_t uploaded = dev.transfer_bytes().upload - before;
  dev.ensure_buffer(r->raw, 6 * face * sizeof(float), kStorage, vk::MemoryKind::Device, "point_voxels depth map texels");
  dev.ensure_buffer(out.cube, std::max<std::size_t>(4, cube_floats) * sizeof(float), kStorage, vk::MemoryKind::Device, "point_voxels cube depth maps");
  dev.ensure_buffer(out.sun, (gpu::kPvSunHeader + std::max<std::size_t>(1, sun_floats)) * sizeof(float), kStorage, vk::MemoryKind::Device,
                    "point_voxels sun depth map");
  const std::vector<float> header = sun_header(*L);
  dev.upload(out.sun, header.data(), header.size() * sizeof(float));
  out.cube_hash = out.sun_hash = 0;

  vk::ComputePipeline& resolve = pipeline(dev, r->compute, "pv.depth_resolve", words(spv::point_voxels_depth_resolve_comp), {});
  struct Resolve {
    std::uint32_t first, end, mode, out_offset;
    float near, z_lo, z_range;
  };
  const auto n_corners = static_cast<std::uint32_t>(corners.size());
  double secs = 0.0;
  auto run_map = [&](const std::vector<RasterPush>& faces, float clear, const Resolve& res, const vk::Buffer& target, const std::string& what) {
    const vk::SubmitResult sr = dev.submit([&](vk::Recorder& rec) {
      rec.begin_timer("light_maps");
      record_faces(rec, *r, faces, clear, n_corners);
      rec.barrier();
      dispatch_chunks<Resolve>(rec, resolve, {vk::Bind::buffer_at(gpu::kPvResolveBindRaw, r->raw), vk::Bind::buffer_at(gpu::kPvResolveBindOut, target)},
                               faces.size() * face, gpu::kPvGroup, [&](std::uint32_t a, std::uint32_t b) {
                                 Resolve q = res;
                                 q.first = a;
                                 q.end = b;
                                 return q;
                               });
      rec.end_timer();
      rec.barrier();
    }, what);
    secs += std::max(0.0, sr.gpu_seconds);
  };
  for (std::size_t l = 0; l < L->local.size(); ++l) {
    std::vector<RasterPush> faces(6);
    for (int f = 0; f < 6; ++f) {
      const int a = f / 2;
      RasterPush& p = faces[static_cast<std::size_t>(f)];
      p.center_near = glm::vec4(L->local[l].center, kCubeNear);
      p.mode_axes = glm::ivec4(static_cast<int>(gpu::kPvRasterCube), a, (a + 1) % 3, (a + 2) % 3);
      p.params = glm::vec4(f % 2 == 0 ? 1.0f : -1.0f, 0.0f, 0.0f, 0.0f);
    }
    run_map(faces, 0.0f, Resolve{0, 0, gpu::kPvRasterCube, static_cast<std::uint32_t>(l * 6 * face), kCubeNear, 0.0f, 0.0f}, out.cube,
            "point_voxels cube depth map");
  }
  if (L->sun) {
    const OrthoDepthMap& m = L->sun_map;
    RasterPush p;
    p.center_near = glm::vec4(0.0f);
    p.mode_axes = glm::ivec4(static_cast<int>(gpu::kPvRasterOrtho), 0, 0, 0);
    // Drawn as 1 - the normalised depth so that the pipeline's GREATER keeps the nearest (cleared to 0).
    p.params = glm::vec4(z_hi, -1.0f / (z_hi - z_lo), 0.0f, 0.0f);
    p.u_lo = glm::vec4(m.u, m.lo.x);
    p.v_lo = glm::vec4(m.v, m.lo.y);
    p.dir = glm::vec4(m.dir, 0.0f);
    p.extent = glm::vec4(m.extent, 0.0f, 0.0f);
    run_map({p}, 0.0f, Resolve{0, 0, gpu::kPvRasterOrtho, gpu::kPvSunHeader, 0.0f, z_hi, -(z_hi - z_lo)}, out.sun, "point_voxels sun depth map");
  }
  auto& rec = ctx.record();
  rec.counters["triangles"] = static_cast<double>(corners.size() / 3);
  rec.counters["maps_texels"] = static_cast<double>(cube_floats + sun_floats);
  rec.counters["kernel_gpu_seconds"] = secs;
  rec.counters["upload_bytes"] = static_cast<double>(uploaded);
  rec.bytes = L->bytes() + (cube_floats + sun_floats) * sizeof(float) + corners.size() * sizeof(glm::vec4);
}

}  // namespace softgi::techniques::point_voxels
