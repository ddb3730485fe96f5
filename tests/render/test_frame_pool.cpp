// The frame pool (render/frame_pool.hpp): what it hands back and when it lets go, and that frames
// rendered from recycled buffers are the frames rendered without it, for every technique.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "softgi/render/backend.hpp"
#include "softgi/render/frame_pool.hpp"
#include "softgi/render/gbuffer.hpp"
#include "softgi/render/technique.hpp"
#include "softgi/scene/builtin.hpp"

using namespace softgi;
using render::FramePool;

TEST(FramePool, GivenBufferIsTakenBackWithItsStorage) {
  FramePool pool;
  pool.set_mode(FramePool::Mode::On);
  std::vector<float> v(1000, 1.0f);
  const float* data = v.data();
  pool.give(std::move(v));
  EXPECT_EQ(pool.stats().held_bytes, 1000 * sizeof(float));
  std::vector<float> w = pool.take_for_overwrite<float>(900);
  EXPECT_EQ(w.data(), data);
  EXPECT_EQ(w.size(), 900u);
  EXPECT_EQ(pool.stats().held_bytes, 0u);
  EXPECT_EQ(pool.stats().reused, 1u);
  // Another element type never shares storage.
  pool.give(std::move(w));
  std::vector<std::int32_t> i = pool.take_for_overwrite<std::int32_t>(900);
  EXPECT_EQ(pool.stats().allocated, 1u);
  EXPECT_EQ(pool.stats().held_bytes, 1000 * sizeof(float));
}

TEST(FramePool, BestFitWithinTheSlack) {
  FramePool pool;
  pool.set_mode(FramePool::Mode::On);
  std::vector<glm::vec3> a(100), b(200), big(100000);
  const glm::vec3 *pa = a.data(), *pb = b.data();
  pool.give(std::move(b));
  pool.give(std::move(a));
  pool.give(std::move(big));
  EXPECT_EQ(pool.take_for_overwrite<glm::vec3>(150).data(), pb);  // the only one of 150 or more within 4x
  EXPECT_EQ(pool.take_for_overwrite<glm::vec3>(90).data(), pa);   // the smallest that fits
  // 10 elements would pin the 100000-element buffer: a new one instead.
  const std::size_t allocated = pool.stats().allocated;
  pool.take_for_overwrite<glm::vec3>(10);
  EXPECT_EQ(pool.stats().allocated, allocated + 1);
  EXPECT_EQ(pool.stats().held_bytes, 100000 * sizeof(glm::vec3));
}

// A buffer the pool allocated serves the next frame's slightly larger request (an animated scene's
// receiver count grows by a few per cent): without the headroom that request allocates again.
TEST(FramePool, NewBuffersHaveHeadroomForAGrowingRequest) {
  FramePool pool;
  pool.set_mode(FramePool::Mode::On);
  const std::size_t n = 100000;
  std::vector<float> v = pool.take_for_overwrite<float>(n);
  EXPECT_EQ(v.size(), n);
  EXPECT_EQ(v.capacity(), n + n / FramePool::kHeadroom);
  const float* data = v.data();
  pool.give(std::move(v));
  std::vector<float> w = pool.take_for_overwrite<float>(n + n / (2 * FramePool::kHeadroom));
  EXPECT_EQ(w.data(), data);
  EXPECT_EQ(pool.stats().allocated, 1u);
  EXPECT_EQ(pool.stats().reused, 1u);
  // Without a pool, takes are plain allocations of what is asked.
  pool.set_mode(FramePool::Mode::Off);
  EXPECT_EQ(pool.take_for_overwrite<float>(n).capacity(), n);
}

TEST(FramePool, TakeFillsAndPoisonMarksUnwrittenElements) {
  FramePool pool;
  pool.set_mode(FramePool::Mode::Poison);
  pool.give(std::vector<float>(64, 0.0f));
  const std::vector<float> f = pool.take_for_overwrite<float>(64);
  for (float x : f) EXPECT_TRUE(std::isnan(x));
  const std::vector<std::int32_t> i = pool.take_for_overwrite<std::int32_t>(8);
  for (std::int32_t x : i) EXPECT_EQ(x, 0x5a5a5a5a);
  const Image img = pool.image(4, 3, glm::vec3(0.5f));
  for (const glm::vec3& p : img.rgb) EXPECT_EQ(p, glm::vec3(0.5f));
}

TEST(FramePool, LeftoversAreFreedAfterKeepFrames) {
  FramePool pool;
  pool.set_mode(FramePool::Mode::On);
  pool.give(std::vector<float>(4096));
  for (unsigned f = 0; f < FramePool::kKeepFrames; ++f) {
    pool.end_frame();
    EXPECT_GT(pool.stats().held_bytes, 0u) << "after " << f + 1 << " frame(s)";
  }
  pool.end_frame();
  EXPECT_EQ(pool.stats().held_bytes, 0u);
}

TEST(FramePool, OffModeHoldsNothing) {
  FramePool pool;
  pool.set_mode(FramePool::Mode::Off);
  pool.give(std::vector<float>(4096));
  EXPECT_EQ(pool.stats().held_bytes, 0u);
  EXPECT_EQ(pool.take_for_overwrite<float>(16).size(), 16u);
}

TEST(FramePool, EnvironmentSelectsTheModeAndRefusesOthers) {
  const char* old = std::getenv("SOFTGI_FRAME_POOL");
  const std::string saved = old ? old : "";
  setenv("SOFTGI_FRAME_POOL", "off", 1);
  EXPECT_EQ(FramePool().mode(), FramePool::Mode::Off);
  setenv("SOFTGI_FRAME_POOL", "poison", 1);
  EXPECT_EQ(FramePool().mode(), FramePool::Mode::Poison);
  setenv("SOFTGI_FRAME_POOL", "sometimes", 1);
  try {
    FramePool p;
    ADD_FAILURE() << "a bad SOFTGI_FRAME_POOL was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("SOFTGI_FRAME_POOL is 'sometimes'"), std::string::npos) << e.what();
  }
  if (old)
    setenv("SOFTGI_FRAME_POOL", saved.c_str(), 1);
  else
    unsetenv("SOFTGI_FRAME_POOL");
}

namespace {

// Bitwise equality of two images (the pool changes where memory comes from, never a value).
std::string first_difference(const Image& a, const Image& b) {
  if (a.width != b.width || a.height != b.height) return "sizes differ";
  for (std::size_t i = 0; i < a.rgb.size(); ++i)
    if (std::memcmp(&a.rgb[i], &b.rgb[i], sizeof(glm::vec3)) != 0)
      return "pixel " + std::to_string(i) + ": " + std::to_string(a.rgb[i].x) + " vs " + std::to_string(b.rgb[i].x);
  return "";
}

}  // namespace

// Every registered technique renders a sequence (background pixels included, the camera's frame
// growing between frames so that buffers of other sizes pass through the pool) from poisoned
// recycled buffers: a pass that takes a buffer for overwrite and leaves an element unwritten would
// show NaN or 0x5a garbage there. The frames must equal those of a backend without a pool, bit for
// bit (tolerance: none, the same arithmetic runs on the same inputs).
TEST(FramePool, RecycledFramesEqualUnpooledFramesForEveryTechnique) {
  const scene::Scene sc = scene::make_builtin("character");
  const int sizes[][2] = {{48, 40}, {48, 40}, {64, 40}, {48, 40}};
  for (const std::string& name : render::technique_names()) {
    SCOPED_TRACE(name);
    auto pooled = render::create_backend(render::reference_backend_name());
    auto plain = render::create_backend(render::reference_backend_name());
    pooled->frame_pool().set_mode(FramePool::Mode::Poison);
    plain->frame_pool().set_mode(FramePool::Mode::Off);
    auto ta = render::create_technique(name), tb = render::create_technique(name);
    const render::ParamSet pa = render::default_params(*ta), pb = render::default_params(*tb);
    render::RenderRequest req;
    req.outputs = {"final", "direct", "indirect"};
    std::size_t reused = 0;
    for (int f = 0; f < 4; ++f) {
      req.width = sizes[f][0];
      req.height = sizes[f][1];
      req.time = 0.1 * f;
      render::FrameResult a = pooled->render(*ta, sc, pa, req);
      const render::FrameResult b = plain->render(*tb, sc, pb, req);
      for (auto [label, ia, ib] : {std::tuple{"final", &a.final_image, &b.final_image}, {"direct", &a.direct, &b.direct},
                                   {"indirect", &a.indirect, &b.indirect}}) {
        EXPECT_EQ(first_difference(*ia, *ib), "") << label << ", frame " << f;
      }
      pooled->recycle(std::move(a));
      reused = pooled->frame_pool().stats().reused;
    }
    // The pool was used: later frames took buffers back (else this test checks nothing).
    EXPECT_GT(reused, 0u);
    EXPECT_EQ(plain->frame_pool().stats().reused, 0u);
  }
}
