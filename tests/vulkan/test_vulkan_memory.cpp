// Memory limits on the Vulkan backend: the device's per-buffer and per-allocation limits and its
// memory total refuse a frame before its first pass, naming the buffer, its size and the limit; the
// rasteriser's targets are in the estimate; an image too large for one allocation is an error
// naming the image, never a driver error.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <memory>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "softgi/backends/vulkan/backend.hpp"
#include "softgi/backends/vulkan/context.hpp"
#include "softgi/render/backend.hpp"
#include "softgi/render/common_passes.hpp"
#include "softgi/scene/builtin.hpp"
#include "vulkan_test_util.hpp"

using namespace softgi;
using render::MemoryItem;
using render::MemoryPlace;

namespace {

// One pass writing "final", with a host implementation and a "vulkan" one (so that device items
// count), declaring the items it is given; `ran` counts executions.
class Declared final : public render::Technique {
 public:
  explicit Declared(std::vector<MemoryItem> items) : items_(std::move(items)) {}
  std::string name() const override { return "declared"; }
  std::string description() const override { return "a frame of declared device memory"; }
  std::vector<render::ParamDesc> params() const override { return {}; }
  render::PassGraph plan(const scene::Scene&, const render::ParamSet&, std::set<std::string>&) override {
    render::PassGraph g;
    int* ran = &ran_;
    render::PassFn fn = [ran](render::FrameContext& c) {
      ++*ran;
      c.put<Image>(render::kFinal, Image(c.width, c.height));
    };
    g.add({"declared", {}, {}, {render::kFinal}, "fills the final image", {{render::kHostImpl, fn}, {backends::vulkan::kBackendName, fn}}});
    return g;
  }
  std::vector<MemoryItem> estimate_memory(const scene::Scene&, const render::ParamSet&, int, int) const override {
    return items_;
  }
  int ran() const { return ran_; }

 private:
  std::vector<MemoryItem> items_;
  int ran_ = 0;
};

render::RenderRequest request(int w, int h) {
  render::RenderRequest r;
  r.width = w;
  r.height = h;
  return r;
}

class ScopedNoLimit {
 public:
  ScopedNoLimit() {
    if (const char* v = std::getenv("SOFTGI_MEMORY_LIMIT")) old_ = v, had_ = true;
    unsetenv("SOFTGI_MEMORY_LIMIT");
  }
  ~ScopedNoLimit() {
    if (had_) setenv("SOFTGI_MEMORY_LIMIT", old_.c_str(), 1);
  }

 private:
  std::string old_;
  bool had_ = false;
};

}  // namespace

using VulkanMemory = softgi::testing::ValidatedTest;

TEST_F(VulkanMemory, LimitsAreTheDevicesOwn) {
  ScopedNoLimit env;
  backends::VulkanBackend vk(ctx_);
  const render::MemoryLimits l = vk.memory_limits();
  const backends::vulkan::DeviceInfo& d = ctx().device_info();
  EXPECT_EQ(l.max_storage_buffer, d.limits.maxStorageBufferRange);
  EXPECT_EQ(l.max_allocation, d.max_allocation_bytes);
  EXPECT_GT(d.max_allocation_bytes, 0u) << "the device reports no maxMemoryAllocationSize";
  EXPECT_EQ(l.device_is_host_memory, d.type == VK_PHYSICAL_DEVICE_TYPE_CPU);
  // A GPU's total is its device-local heap; a CPU device's memory is the host's.
  if (!l.device_is_host_memory) EXPECT_EQ(l.device, d.device_local_bytes);
  else EXPECT_EQ(l.device, 0u);
  EXPECT_GT(l.host, 0u);
}

TEST_F(VulkanMemory, AStorageBufferOverTheRangeIsRefusedBeforeTheFirstPass) {
  ScopedNoLimit env;
  backends::VulkanBackend vk(ctx_);
  const scene::Scene sc = scene::make_builtin("spheres");
  const std::size_t range = ctx().device_info().limits.maxStorageBufferRange;
  Declared t({{"the too-long buffer", range + 4, MemoryPlace::Device, "declared", false, true, false}});
  try {
    vk.render(t, sc, render::ParamSet(), request(8, 8));
    FAIL() << "a storage buffer of maxStorageBufferRange + 4 bytes was accepted";
  } catch (const render::FrameMemoryError& e) {
    const std::string msg = e.what();
    EXPECT_EQ(e.resource(), "the too-long buffer");
    EXPECT_EQ(e.bytes(), range + 4);
    EXPECT_EQ(e.limit(), range);
    EXPECT_NE(msg.find("maxStorageBufferRange"), std::string::npos) << msg;
    EXPECT_NE(msg.find(std::to_string(range + 4) + " bytes"), std::string::npos) << msg;
    EXPECT_NE(msg.find(ctx().device_info().name), std::string::npos) << msg;
  }
  EXPECT_EQ(t.ran(), 0);
  // The same bytes as a host item, and exactly the range as a storage buffer, fit.
  Declared ok({{"a buffer at the range", range, MemoryPlace::Device, "declared", false, true, false}});
  EXPECT_NO_THROW(vk.render(ok, sc, render::ParamSet(), request(8, 8)));
  EXPECT_EQ(ok.ran(), 1);
}

TEST_F(VulkanMemory, OneAllocationOverTheDevicesMaximumIsRefused) {
  ScopedNoLimit env;
  backends::VulkanBackend vk(ctx_);
  const scene::Scene sc = scene::make_builtin("spheres");
  const std::size_t max = ctx().device_info().max_allocation_bytes;
  Declared t({{"the huge image", max + 1, MemoryPlace::Device, "declared", false, false, false}});
  try {
    vk.render(t, sc, render::ParamSet(), request(8, 8));
    FAIL() << "an allocation of maxMemoryAllocationSize + 1 was accepted";
  } catch (const render::FrameMemoryError& e) {
    EXPECT_EQ(e.resource(), "the huge image");
    EXPECT_EQ(e.limit(), max);
    EXPECT_NE(std::string(e.what()).find("maxMemoryAllocationSize"), std::string::npos) << e.what();
  }
  EXPECT_EQ(t.ran(), 0);
}

TEST_F(VulkanMemory, DeclaredLimitCoversHostAndDevice) {
  ScopedNoLimit env;
  const scene::Scene sc = scene::make_builtin("spheres");
  backends::VulkanBackend vk(ctx_);
  vk.set_memory_limit(std::size_t{64} << 20);
  const render::MemoryLimits l = vk.memory_limits();
  EXPECT_TRUE(l.declared);
  EXPECT_EQ(l.host, std::size_t{64} << 20);
  // A GPU's device memory gets the declared total; a CPU device's is the host's, counted there.
  EXPECT_EQ(l.device, l.device_is_host_memory ? 0 : std::size_t{64} << 20);
  // 1024 x 1024 shexp: 104 MiB of host G-buffer and images, 100 MiB of rasteriser targets and
  // readback: over 64 MiB whether device memory is the host's or not.
  try {
    render_frame(vk, "shexp", sc, nullptr, request(1024, 1024));
    FAIL() << "a 1024x1024 frame fitted into 64 MiB";
  } catch (const render::FrameMemoryError& e) {
    EXPECT_EQ(e.limit(), std::size_t{64} << 20);
    EXPECT_NE(std::string(e.what()).find("the vulkan backend (device '" + ctx().device_info().name + "') has 64.0 MiB available"),
              std::string::npos)
        << e.what();
  }
  EXPECT_NO_THROW(render_frame(vk, "shexp", sc, nullptr, request(48, 36)));
}

TEST_F(VulkanMemory, EstimateHasTheRasterTargetsAndTheKernelsBuffers) {
  ScopedNoLimit env;
  const scene::Scene sc = scene::make_builtin("spheres");
  backends::VulkanBackend vk(ctx_);
  auto t = render::create_technique("image_splat");
  const render::ParamSet p = render::default_params(*t);
  const render::FrameMemory m = vk.estimate_memory(*t, sc, p, request(640, 480));
  auto bytes = [&](const std::string& name) -> std::size_t {
    for (const auto& it : m.items)
      if (it.name == name) return it.bytes;
    ADD_FAILURE() << "no item '" << name << "'";
    return 0;
  };
  // Attachment 0 (RG32I, the visibility buffer's ids) of the display and of the receiver buffer
  // (receiver_scale 2).
  EXPECT_EQ(bytes("gbuffer_raster attachment 0 640x480"), std::size_t{8} * 640 * 480);
  EXPECT_EQ(bytes("gbuffer_raster attachment 0 320x240"), std::size_t{8} * 320 * 240);
  // The eq. 11 taps: 4 indices per display pixel, one storage buffer.
  EXPECT_EQ(bytes("upsample taps"), std::size_t{16} * 640 * 480);
  // Everything device-side of the display G-buffer per pixel: 20 bytes of attachments and depth,
  // 16 of their readback, 32 of the resolved position, depth and normal, and where the device's
  // buffers are not mapped (a discrete GPU, or SOFTGI_VULKAN_UNMAPPED_DEVICE_MEMORY=1) 32 more for
  // the resolved planes' host copies.
  std::size_t raster = 0;
  for (const auto& it : m.items)
    if (it.place == MemoryPlace::Device && it.name.rfind("gbuffer_raster", 0) == 0 && it.name.find(" 640x480") != std::string::npos)
      raster += it.bytes;
  EXPECT_EQ(raster, std::size_t{ctx_->device_buffers_mapped() ? 68u : 100u} * 640 * 480);
}

// The frame that ran out of memory after 45 s: refused at once, naming a buffer and a limit.
TEST_F(VulkanMemory, TheLargestFrameIsRefusedAtOnce) {
  ScopedNoLimit env;
  const scene::Scene sc = scene::make_builtin("spheres");
  backends::VulkanBackend vk(ctx_);
  int refused = 0;
  for (const char* technique : {"shexp", "image_splat"}) {
    const auto t0 = std::chrono::steady_clock::now();
    {
      // A machine with the memory for it renders the frame: only frames that do not fit are refused.
      auto t = render::create_technique(technique);
      try {
        render::check_frame_memory(vk.estimate_memory(*t, sc, render::default_params(*t), request(16384, 16384)), vk.memory_limits(),
                                   ctx().device_info().name);
        continue;
      } catch (const render::FrameMemoryError&) {
      }
    }
    ++refused;
    try {
      render_frame(vk, technique, sc, nullptr, request(16384, 16384));
      ADD_FAILURE() << technique << " at 16384x16384 was not refused";
    } catch (const render::FrameMemoryError& e) {
      const std::string msg = e.what();
      EXPECT_FALSE(e.resource().empty()) << msg;
      EXPECT_GT(e.bytes(), 0u);
      EXPECT_GT(e.limit(), 0u);
      EXPECT_NE(msg.find("render: " + std::string(technique) + " at 16384x16384 needs"), std::string::npos) << msg;
      EXPECT_NE(msg.find("'" + e.resource() + "'"), std::string::npos) << msg;
    }
    // Planning only: a second at most on any machine (measured: milliseconds).
    EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 5.0) << technique;
  }
  if (refused == 0) GTEST_SKIP() << "device '" << ctx().device_info().name << "' and this host fit both frames at 16384x16384";
}

// Past the estimate, the context itself refuses an image its device cannot allocate in one piece.
TEST_F(VulkanMemory, AnImageOverTheAllocationLimitIsANamedError) {
  const backends::vulkan::DeviceInfo& d = ctx().device_info();
  const std::uint32_t edge = std::min<std::uint32_t>(d.limits.maxImageDimension2D, 16384);
  const std::uint64_t bytes = std::uint64_t{16} * edge * edge;
  if (bytes <= d.max_allocation_bytes)
    GTEST_SKIP() << "an RGBA32F image of " << edge << "x" << edge << " (" << bytes << " bytes) fits one allocation of "
                 << d.max_allocation_bytes << " bytes on '" << d.name << "': nothing to refuse";
  try {
    ctx().create_image(edge, edge, VK_FORMAT_R32G32B32A32_SFLOAT, VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT, VK_IMAGE_ASPECT_COLOR_BIT,
                       "test big image");
    FAIL() << "no error";
  } catch (const std::invalid_argument& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("image 'test big image'"), std::string::npos) << msg;
    EXPECT_NE(msg.find("maxMemoryAllocationSize"), std::string::npos) << msg;
    EXPECT_NE(msg.find(std::to_string(d.max_allocation_bytes) + " bytes"), std::string::npos) << msg;
  }
}
