// Frame memory: the closed forms of the image-sized resources, estimates that grow with the
// resolution exactly as those resources do, limits from the machine or declared (a backend option,
// SOFTGI_MEMORY_LIMIT), and frames refused before their first pass with an error naming the
// resource, its size and the limit.
#include <gtest/gtest.h>
#include <sys/mman.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <ostream>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "softgi/backends/cpu_backend.hpp"
#include "softgi/render/backend.hpp"
#include "softgi/render/common_passes.hpp"
#include "softgi/scene/builtin.hpp"

using namespace softgi;
using render::MemoryItem;
using render::MemoryPlace;

namespace {

constexpr std::size_t kMiB = std::size_t{1} << 20;

// Sets an environment variable for one test and restores it after.
class ScopedEnv {
 public:
  ScopedEnv(const char* name, const char* value) : name_(name) {
    if (const char* old = std::getenv(name)) {
      had_ = true;
      old_ = old;
    }
    if (value) setenv(name, value, 1);
    else unsetenv(name);
  }
  ~ScopedEnv() {
    if (had_) setenv(name_.c_str(), old_.c_str(), 1);
    else unsetenv(name_.c_str());
  }

 private:
  std::string name_, old_;
  bool had_ = false;
};

std::size_t item_bytes(const render::FrameMemory& m, const std::string& name) {
  for (const auto& it : m.items)
    if (it.name == name) return it.bytes;
  return 0;
}
bool has_item(const render::FrameMemory& m, const std::string& name) {
  for (const auto& it : m.items)
    if (it.name == name) return true;
  return false;
}

render::FrameMemory estimate(render::Backend& b, const std::string& technique, const scene::Scene& sc, int w, int h,
                             const std::vector<std::pair<std::string, std::string>>& set = {}) {
  auto t = render::create_technique(technique);
  render::ParamSet p = render::default_params(*t);
  for (const auto& [k, v] : set) p.set(k, v);
  render::RenderRequest req;
  req.width = w;
  req.height = h;
  return b.estimate_memory(*t, sc, p, req);
}

// A technique of one host pass writing "final", whose estimate is whatever the test declares;
// `ran` counts its pass's executions (a refused frame runs none).
class Declared final : public render::Technique {
 public:
  explicit Declared(std::vector<MemoryItem> items) : items_(std::move(items)) {}
  std::string name() const override { return "declared"; }
  std::string description() const override { return "a frame of declared memory"; }
  std::vector<render::ParamDesc> params() const override { return {}; }
  render::PassGraph plan(const scene::Scene&, const render::ParamSet&, std::set<std::string>&) override {
    render::PassGraph g;
    int* ran = &ran_;
    g.add({"declared", {}, {}, {render::kFinal}, "fills the final image", render::host_impl([ran](render::FrameContext& c) {
             ++*ran;
             c.put<Image>(render::kFinal, Image(c.width, c.height));
           })});
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

// Two host passes: "fresh" maps `bytes` of new anonymous memory and writes one byte per page (every
// page faults once), "warm" writes the same count of pages of a buffer the test touched already.
class Touching final : public render::Technique {
 public:
  Touching(std::size_t bytes, unsigned char* warm) : bytes_(bytes), warm_(warm) {}
  std::string name() const override { return "touching"; }
  std::string description() const override { return "touches fresh and resident memory"; }
  std::vector<render::ParamDesc> params() const override { return {}; }
  render::PassGraph plan(const scene::Scene&, const render::ParamSet&, std::set<std::string>&) override {
    render::PassGraph g;
    const std::size_t bytes = bytes_;
    unsigned char* warm = warm_;
    const std::size_t page = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
    g.add({"fresh", {}, {}, {"touched"}, "touches fresh pages", render::host_impl([bytes, page](render::FrameContext& c) {
             void* m = mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
             if (m == MAP_FAILED) throw std::runtime_error("mmap failed");
             madvise(m, bytes, MADV_NOHUGEPAGE);  // one fault per base page, not per huge page
             auto* b = static_cast<volatile unsigned char*>(m);
             for (std::size_t i = 0; i < bytes; i += page) b[i] = 1;
             munmap(m, bytes);
             c.put<int>("touched", 1);
           })});
    g.add({"warm", {"touched"}, {}, {render::kFinal}, "touches resident pages", render::host_impl([bytes, page, warm](render::FrameContext& c) {
             auto* b = static_cast<volatile unsigned char*>(warm);
             for (std::size_t i = 0; i < bytes; i += page) b[i] = 2;
             c.put<Image>(render::kFinal, Image(c.width, c.height));
           })});
    return g;
  }
  std::vector<MemoryItem> estimate_memory(const scene::Scene&, const render::ParamSet&, int, int) const override { return {}; }

 private:
  std::size_t bytes_;
  unsigned char* warm_;
};

render::RenderRequest request(int w, int h) {
  render::RenderRequest r;
  r.width = w;
  r.height = h;
  return r;
}

}  // namespace

TEST(FrameMemory, ClosedFormsOfTheSharedResources) {
  // GBuffer: position, normal, albedo, view_dir (3 floats each), depth, object, primitive (4 bytes
  // each), barycentric (2 floats) = 68 bytes per pixel; Image: 3 floats.
  EXPECT_EQ(render::gbuffer_bytes(640, 480), std::size_t{68} * 640 * 480);
  EXPECT_EQ(render::image_bytes(640, 480), std::size_t{12} * 640 * 480);
  EXPECT_EQ(render::gbuffer_bytes(16384, 16384), std::size_t{68} * 16384 * 16384);  // no 32-bit overflow
  // What GBuffer::background allocates is what gbuffer_bytes says (GBuffer::bytes() counts the same planes).
  EXPECT_EQ(render::GBuffer::background(37, 23).bytes(), render::gbuffer_bytes(37, 23));
  // Plane groups left out: 16 bytes of visibility planes always, 28 for the surface (position,
  // normal, depth), 12 each for albedo and view_dir; allocated and counted alike.
  using render::kGBufferAlbedo, render::kGBufferSurface, render::kGBufferViewDir, render::kGBufferVisibility;
  EXPECT_EQ(render::gbuffer_bytes(10, 10, kGBufferVisibility), std::size_t{16} * 100);
  EXPECT_EQ(render::gbuffer_bytes(10, 10, kGBufferSurface), std::size_t{44} * 100);
  EXPECT_EQ(render::gbuffer_bytes(10, 10, kGBufferAlbedo | kGBufferViewDir), std::size_t{40} * 100);
  for (unsigned planes = 0; planes <= render::kGBufferAll; ++planes) {
    const render::GBuffer g = render::GBuffer::background(37, 23, 1, nullptr, planes);
    EXPECT_EQ(g.bytes(), render::gbuffer_bytes(37, 23, planes)) << planes;
    EXPECT_EQ(g.planes, planes);
    render::FramePool pool;
    EXPECT_EQ(render::GBuffer::background(37, 23, 1, &pool, planes).bytes(), render::gbuffer_bytes(37, 23, planes)) << planes;
  }
  EXPECT_EQ(render::scaled_size(1023, 2), 512);
  EXPECT_EQ(render::scaled_size(1024, 8), 128);
  EXPECT_EQ(render::scaled_size(1025, 8), 129);
}

TEST(FrameMemory, TransientItemsCountOnlyForTheirLargestPass) {
  render::FrameMemory m;
  m.items = {{"a", 100, MemoryPlace::Host, "", false, false, false},
             {"b", 40, MemoryPlace::Host, "p", true, false, false},
             {"c", 30, MemoryPlace::Host, "q", true, false, false},
             {"d", 25, MemoryPlace::Host, "q", true, false, false},
             {"e", 7, MemoryPlace::Device, "p", false, true, false}};
  EXPECT_EQ(m.bytes(MemoryPlace::Host), 100u + 55u);  // q's scratch (30 + 25) outweighs p's (40)
  EXPECT_EQ(m.bytes(MemoryPlace::Device), 7u);
  ASSERT_NE(m.largest(MemoryPlace::Host), nullptr);
  EXPECT_EQ(m.largest(MemoryPlace::Host)->name, "a");
}

// The per-pixel part of each estimate is the closed form of the resources its passes allocate:
// between two resolutions the estimate grows by exactly (bytes per pixel) x (added pixels), the
// per-vertex part (the same scene) cancels.
TEST(FrameMemory, ShexpEstimateGrowsWithTheImageSizedResources) {
  const scene::Scene sc = scene::make_builtin("spheres");
  backends::CpuBackend cpu;
  const auto small = estimate(cpu, "shexp", sc, 320, 240), large = estimate(cpu, "shexp", sc, 1280, 960);
  // G-buffer 16 (the planes to_image reads: object, primitive, barycentric), the direct image 12
  // (moved into the frame's result, not copied), the final image 12.
  const std::size_t per_pixel = 16 + 12 + 12;
  EXPECT_EQ(large.bytes(MemoryPlace::Host) - small.bytes(MemoryPlace::Host), per_pixel * (1280 * 960 - 320 * 240));
  EXPECT_EQ(item_bytes(large, render::kGBuffer),
            render::gbuffer_bytes(1280, 960, render::kGBufferVisibility));
  // A frame that hands the G-buffer over as an output holds every plane.
  render::RenderRequest with_gbuffer;
  with_gbuffer.width = 1280;
  with_gbuffer.height = 960;
  with_gbuffer.outputs = {render::kFinal, render::kGBuffer};
  auto t = render::create_technique("shexp");
  EXPECT_EQ(item_bytes(cpu.estimate_memory(*t, sc, render::default_params(*t), with_gbuffer), render::kGBuffer),
            render::gbuffer_bytes(1280, 960));
  EXPECT_EQ(item_bytes(large, render::kFinal), render::image_bytes(1280, 960));
  // The per-vertex receivers: 6 floats and 3 indices per vertex of the scene.
  EXPECT_EQ(item_bytes(large, "shexp.receivers"), render::scene_vertex_count(sc) * 36);
  EXPECT_GT(render::scene_vertex_count(sc), 0u);
  // The CPU backend runs no device kernels: no device item is counted there.
  EXPECT_EQ(large.bytes(MemoryPlace::Device), 0u);
}

TEST(FrameMemory, ImageSplatEstimateGrowsWithDisplayAndReceiverPixels) {
  const scene::Scene sc = scene::make_builtin("spheres");
  backends::CpuBackend cpu;
  // Sizes divisible by the receiver scale (2), so that receiver pixels are exactly a quarter.
  const auto small = estimate(cpu, "image_splat", sc, 320, 240), large = estimate(cpu, "image_splat", sc, 1280, 960);
  // Per display pixel: G-buffer 56 (every plane but view_dir: shade_direct takes the background's
  // rays from the camera), final 12, eq. 11 taps + weights + miss flag 33, surface index 4,
  // upsampled indirect 12, direct and indirect images 24, and the largest pass scratch 12 (shade_direct's
  // irradiance of the surface pixels, shade_indirect's copy of the upsampled indirect). Per receiver pixel (order 4: 16 floats per vector): receiver G-buffer
  // 68, receivers 32, log occlusion 64, O_p 64 and its coarse copy 64, indirect sums 16 and shading 12.
  const std::size_t per_display = 56 + 12 + 33 + 4 + 12 + 24 + 12, per_receiver = 68 + 32 + 64 + 64 + 64 + 16 + 12;
  const std::size_t dp = 1280 * 960 - 320 * 240, dc = 640 * 480 - 160 * 120;
  EXPECT_EQ(large.bytes(MemoryPlace::Host) - small.bytes(MemoryPlace::Host), per_display * dp + per_receiver * dc);
  EXPECT_EQ(item_bytes(large, render::kReceiverGBuffer), render::gbuffer_bytes(640, 480));
  EXPECT_EQ(item_bytes(large, render::kGBuffer), render::gbuffer_bytes(1280, 960, render::kGBufferSurface | render::kGBufferAlbedo));
  // receiver_scale 4: a sixteenth of the receiver pixels.
  const auto s4 = estimate(cpu, "image_splat", sc, 1280, 960, {{"receiver_scale", "4"}});
  EXPECT_EQ(item_bytes(s4, render::kReceiverGBuffer), render::gbuffer_bytes(320, 240));
}

TEST(FrameMemory, PassesTheGraphLeavesOutAreNotCounted) {
  const scene::Scene sc = scene::make_builtin("spheres");
  backends::CpuBackend cpu;
  const auto with = estimate(cpu, "image_splat", sc, 256, 256), without = estimate(cpu, "image_splat", sc, 256, 256, {{"indirect", "false"}});
  EXPECT_TRUE(has_item(with, "image_splat.indirect_sums"));
  EXPECT_FALSE(has_item(without, "image_splat.indirect_sums"));
  EXPECT_FALSE(has_item(without, render::kIndirect));
  EXPECT_LT(without.bytes(MemoryPlace::Host), with.bytes(MemoryPlace::Host));
}

TEST(FrameMemory, ParsesSizes) {
  EXPECT_EQ(render::parse_memory_size("4GiB", "x"), std::size_t{4} << 30);
  EXPECT_EQ(render::parse_memory_size("4G", "x"), std::size_t{4} << 30);
  EXPECT_EQ(render::parse_memory_size("512 MiB", "x"), std::size_t{512} << 20);
  EXPECT_EQ(render::parse_memory_size("1.5GB", "x"), std::size_t{1500000000});
  EXPECT_EQ(render::parse_memory_size("65536", "x"), std::size_t{65536});
  EXPECT_EQ(render::parse_memory_size("64k", "x"), std::size_t{65536});
  for (const char* bad : {"", "lots", "-1G", "4 parsecs", "0", "1e400"}) {
    try {
      render::parse_memory_size(bad, "SOFTGI_MEMORY_LIMIT");
      ADD_FAILURE() << "'" << bad << "' parsed";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("SOFTGI_MEMORY_LIMIT"), std::string::npos) << e.what();
    }
  }
  EXPECT_EQ(render::format_bytes(std::size_t{3} << 30), "3.0 GiB");
  EXPECT_EQ(render::format_bytes(512), "512 bytes");
}

// A declared limit (the backend option) refuses a frame whose estimate does not fit, before any
// pass runs, naming the largest resource, its size and the limit.
TEST(FrameMemory, DeclaredLimitRefusesTheFrameBeforeTheFirstPass) {
  ScopedEnv env("SOFTGI_MEMORY_LIMIT", nullptr);
  const scene::Scene sc = scene::make_builtin("spheres");
  auto cpu = render::create_backend("cpu", render::BackendOptions{"", -1, 16 * kMiB});
  EXPECT_EQ(cpu->memory_limit(), 16 * kMiB);
  // 1024 x 1024: the G-buffer alone is 16 MiB (the planes SHEXP reads), the direct and final
  // images 12 MiB each: the largest item is the G-buffer.
  try {
    render_frame(*cpu, "shexp", sc, nullptr, request(1024, 1024));
    FAIL() << "a 1024x1024 frame fitted into 16 MiB";
  } catch (const render::FrameMemoryError& e) {
    const std::string msg = e.what();
    EXPECT_EQ(e.resource(), render::kGBuffer);
    EXPECT_EQ(e.bytes(), render::gbuffer_bytes(1024, 1024, render::kGBufferVisibility));
    EXPECT_EQ(e.limit(), 16 * kMiB);
    for (const char* part : {"render: shexp at 1024x1024 needs about", "of host memory", "'gbuffer' 16.0 MiB",
                             "the cpu backend has 16.0 MiB available", "declared limit"})
      EXPECT_NE(msg.find(part), std::string::npos) << "no '" << part << "' in: " << msg;
  }
  // A frame that fits renders under the same limit (spheres' per-vertex resources are 6 MiB).
  const render::FrameResult small = render_frame(*cpu, "shexp", sc, nullptr, request(64, 48));
  EXPECT_FALSE(small.final_image.empty());

  Declared t({{"the declared buffer", 17 * kMiB, MemoryPlace::Host, "", false, false, false}});
  EXPECT_THROW(cpu->render(t, sc, render::ParamSet(), request(8, 8)), render::FrameMemoryError);
  EXPECT_EQ(t.ran(), 0);
}

TEST(FrameMemory, EnvironmentVariableDeclaresTheLimit) {
  const scene::Scene sc = scene::make_builtin("spheres");
  backends::CpuBackend cpu;
  {
    ScopedEnv env("SOFTGI_MEMORY_LIMIT", "8MiB");
    const render::MemoryLimits l = cpu.memory_limits();
    EXPECT_EQ(l.host, 8 * kMiB);
    EXPECT_TRUE(l.declared);
    try {
      render_frame(cpu, "image_splat", sc, nullptr, request(512, 512));
      FAIL() << "a 512x512 image_splat frame fitted into 8 MiB";
    } catch (const render::FrameMemoryError& e) {
      EXPECT_NE(std::string(e.what()).find("(SOFTGI_MEMORY_LIMIT=8MiB)"), std::string::npos) << e.what();
      EXPECT_EQ(e.limit(), 8 * kMiB);
    }
    // The backend option takes precedence over the variable.
    cpu.set_memory_limit(std::size_t{1} << 40);
    EXPECT_NO_THROW(render_frame(cpu, "image_splat", sc, nullptr, request(64, 48)));
    cpu.set_memory_limit(0);
  }
  {
    ScopedEnv env("SOFTGI_MEMORY_LIMIT", "none");
    EXPECT_FALSE(cpu.memory_limits().checked);
    Declared t({{"an exabyte", std::size_t{1} << 60, MemoryPlace::Host, "", false, false, false}});
    EXPECT_NO_THROW(cpu.render(t, sc, render::ParamSet(), request(8, 8)));  // nothing is refused
    EXPECT_EQ(t.ran(), 1);
  }
  {
    ScopedEnv env("SOFTGI_MEMORY_LIMIT", "plenty");
    try {
      render_frame(cpu, "shexp", sc, nullptr, request(64, 48));
      FAIL() << "SOFTGI_MEMORY_LIMIT=plenty accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("SOFTGI_MEMORY_LIMIT: 'plenty'"), std::string::npos) << e.what();
    }
  }
}

// The machine's own limit: deterministic only for a frame no machine has memory for.
TEST(FrameMemory, MachineLimitRefusesAnExabyte) {
  ScopedEnv env("SOFTGI_MEMORY_LIMIT", nullptr);
  const scene::Scene sc = scene::make_builtin("spheres");
  backends::CpuBackend cpu;
  const render::MemoryLimits l = cpu.memory_limits();
  ASSERT_GT(l.host, 0u) << "no MemAvailable in /proc/meminfo and no process limit";
  EXPECT_FALSE(l.declared);
  EXPECT_FALSE(l.host_source.empty());
  Declared t({{"an exabyte", std::size_t{1} << 60, MemoryPlace::Host, "", false, false, false}});
  const auto t0 = std::chrono::steady_clock::now();
  try {
    cpu.render(t, sc, render::ParamSet(), request(8, 8));
    FAIL() << "an exabyte fitted";
  } catch (const render::FrameMemoryError& e) {
    EXPECT_EQ(e.resource(), "an exabyte");
    EXPECT_NE(std::string(e.what()).find("(largest: 'an exabyte' 1048576.0 TiB"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(l.host_source), std::string::npos) << e.what();
  }
  EXPECT_EQ(t.ran(), 0);
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 5.0);
  // The frames the tests and experiments render fit with the real limit.
  EXPECT_NO_THROW(render_frame(cpu, "image_splat", sc, nullptr, request(256, 192)));
}

// Device limits, as a device backend reports them: one storage buffer over the per-buffer range,
// one allocation over the per-allocation size, totals with device memory shared with the host.
TEST(FrameMemory, DeviceLimitsNameTheBufferAndTheLimit) {
  render::FrameMemory m;
  m.technique = "t";
  m.backend = "gpu";
  m.width = 16;
  m.height = 16;
  m.items = {{"host part", 10 * kMiB, MemoryPlace::Host, "", false, false, false},
             {"big storage", 200 * kMiB, MemoryPlace::Device, "", false, true, false},
             {"big image", 300 * kMiB, MemoryPlace::Device, "", false, false, false}};
  render::MemoryLimits l;
  l.host = 1024 * kMiB;
  l.host_source = "test";
  l.device = 1024 * kMiB;
  l.device_source = "heap";
  l.max_storage_buffer = 128 * kMiB;
  try {
    render::check_frame_memory(m, l, "dev0");
    FAIL() << "a 200 MiB storage buffer passed a 128 MiB range";
  } catch (const render::FrameMemoryError& e) {
    EXPECT_EQ(e.resource(), "big storage");
    EXPECT_EQ(e.limit(), 128 * kMiB);
    EXPECT_NE(std::string(e.what()).find("maxStorageBufferRange"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("device 'dev0'"), std::string::npos) << e.what();
  }
  l.max_storage_buffer = 256 * kMiB;
  l.max_allocation = 256 * kMiB;
  try {
    render::check_frame_memory(m, l);
    FAIL() << "a 300 MiB image passed a 256 MiB allocation limit";
  } catch (const render::FrameMemoryError& e) {
    EXPECT_EQ(e.resource(), "big image");
    EXPECT_NE(std::string(e.what()).find("maxMemoryAllocationSize"), std::string::npos) << e.what();
  }
  l.max_allocation = 0;
  EXPECT_NO_THROW(render::check_frame_memory(m, l));
  // 500 MiB of device items (550 with the margin) over a 512 MiB device.
  l.device = 512 * kMiB;
  EXPECT_THROW(render::check_frame_memory(m, l), render::FrameMemoryError);
  // Device memory that is host memory: host and device items together against the host's limit.
  l.device = 0;
  l.device_is_host_memory = true;
  l.host = 520 * kMiB;
  try {
    render::check_frame_memory(m, l);
    FAIL() << "510 MiB of host and device items passed 520 MiB with the margin";
  } catch (const render::FrameMemoryError& e) {
    EXPECT_EQ(e.resource(), "big image");
    EXPECT_NE(std::string(e.what()).find("host and device"), std::string::npos) << e.what();
  }
  l.device_is_host_memory = false;
  EXPECT_NO_THROW(render::check_frame_memory(m, l));
}

// PassRecord::page_faults counts the faults of fresh memory in the pass that touches it: every page
// of a new mapping in "fresh" (not fewer: other threads can only add), and far fewer in "warm",
// whose pages were resident before the frame (the bound leaves room for other threads' faults; it
// fails if the counter were taken over the frame instead of the pass, or not at all).
TEST(FrameMemory, PassRecordsCountThePageFaultsOfFreshMemory) {
  const std::size_t page = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
  const std::size_t pages = 4096, bytes = pages * page;
  std::vector<unsigned char> warm(bytes, 1);  // resident: every page written here
  Touching t(bytes, warm.data());
  auto cpu = render::create_backend("cpu");
  const render::FrameResult r = cpu->render(t, scene::make_builtin("spheres"), render::ParamSet(), request(8, 8));
  const render::PassRecord* fresh = nullptr;
  const render::PassRecord* resident = nullptr;
  for (const auto& p : r.passes) {
    if (p.name == "fresh") fresh = &p;
    if (p.name == "warm") resident = &p;
  }
  ASSERT_TRUE(fresh && resident);
  ASSERT_GE(render::minor_page_faults(), 0) << "this platform counts no page faults";
  EXPECT_GE(fresh->page_faults, static_cast<long long>(pages));
  EXPECT_LT(resident->page_faults, static_cast<long long>(pages / 8));
}

// --- measurement: the estimate against the resident set a frame adds ---------------------------------

// Not a check (disabled; docs/backends.md, "How close it is", quotes what it prints): one frame of
// the CPU backend with default parameters, its estimate against the growth of the resident set over
// it (VmRSS before Backend::render, VmHWM after, the peak reset first through /proc/self/clear_refs).
// Run one configuration per process, for memory a frame frees stays with the allocator and would hide
// the next frame's growth:
//   for c in shexp_spheres_512 shexp_spheres_2048 ...; do
//     build/tests/softgi_tests_render --gtest_also_run_disabled_tests --gtest_filter="*MeasureResidentGrowth*/$c"; done
namespace {

struct ResidentCase {
  const char* technique;
  const char* scene;
  int size;
};
void PrintTo(const ResidentCase& c, std::ostream* os) { *os << c.technique << " on " << c.scene << " at " << c.size; }

std::size_t status_kib(const char* field) {
  std::FILE* f = std::fopen("/proc/self/status", "r");
  if (!f) return 0;
  char line[256];
  std::size_t v = 0;
  const std::size_t len = std::strlen(field);
  while (std::fgets(line, sizeof line, f))
    if (std::strncmp(line, field, len) == 0) v = std::strtoull(line + len, nullptr, 10);
  std::fclose(f);
  return v;
}

class FrameMemoryMeasure : public ::testing::TestWithParam<ResidentCase> {};

TEST_P(FrameMemoryMeasure, DISABLED_MeasureResidentGrowth) {
  const ResidentCase c = GetParam();
  const scene::Scene sc = scene::make_builtin(c.scene);
  backends::CpuBackend cpu;
  const render::FrameMemory m = estimate(cpu, c.technique, sc, c.size, c.size);
  auto t = render::create_technique(c.technique);
  const render::ParamSet p = render::default_params(*t);
  if (std::FILE* f = std::fopen("/proc/self/clear_refs", "w")) {  // "5": reset the peak resident set
    std::fputs("5", f);
    std::fclose(f);
  }
  const std::size_t before = status_kib("VmRSS:");
  const render::FrameResult r = cpu.render(*t, sc, p, request(c.size, c.size));
  const std::size_t peak = status_kib("VmHWM:");
  ASSERT_GT(peak, before) << "VmRSS/VmHWM unreadable";
  const double est = static_cast<double>(m.bytes(MemoryPlace::Host)) / 1e6, grown = static_cast<double>(peak - before) * 1024.0 / 1e6;
  std::printf("%s, %s, %dx%d: estimate %.1f MB, resident growth %.1f MB, ratio %.2f (whole process peak %.1f MB)\n", c.technique,
              c.scene, c.size, c.size, est, grown, est / grown, static_cast<double>(peak) * 1024.0 / 1e6);
  EXPECT_FALSE(r.final_image.empty());
}

INSTANTIATE_TEST_SUITE_P(Frames, FrameMemoryMeasure,
                         ::testing::Values(ResidentCase{"shexp", "spheres", 512}, ResidentCase{"shexp", "spheres", 2048},
                                           ResidentCase{"shexp", "character", 512}, ResidentCase{"shexp", "character", 2048},
                                           ResidentCase{"image_splat", "spheres", 512}, ResidentCase{"image_splat", "spheres", 2048},
                                           ResidentCase{"image_splat", "character", 512},
                                           ResidentCase{"image_splat", "character", 2048}),
                         [](const ::testing::TestParamInfo<ResidentCase>& i) {
                           return std::string(i.param.technique) + "_" + i.param.scene + "_" + std::to_string(i.param.size);
                         });

}  // namespace
