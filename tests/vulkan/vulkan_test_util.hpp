// Shared by tests/vulkan: a validated context whose validation log is checked after the context is
// destroyed (so that leaked objects, reported at vkDestroyDevice, fail the test too).
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "softgi/backends/vulkan/backend.hpp"
#include "softgi/backends/vulkan/context.hpp"
#include "softgi/render/pass_graph.hpp"

namespace softgi::testing {

// What `backend` runs for pass `p`: its own implementation, else the host one.
inline const render::PassFn& impl_on(const render::PassDesc& p, const std::string& backend) {
  auto it = p.impl.find(backend);
  return it != p.impl.end() ? it->second : p.impl.at(render::kHostImpl);
}

inline std::shared_ptr<backends::vulkan::Context> validated_context(double fence_timeout_seconds = 120.0) {
  backends::vulkan::ContextOptions o;
  o.validation = 1;
  o.fence_timeout_seconds = fence_timeout_seconds;
  return std::make_shared<backends::vulkan::Context>(o);
}

// Holds a validated context for one test and fails the test on any validation warning or error,
// including those reported while the context is destroyed.
class ValidatedTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ctx_ = validated_context();
    log_ = ctx_->validation_log();
  }
  void TearDown() override {
    ctx_.reset();
    EXPECT_EQ(log_->problems(), 0u) << log_->summary();
  }
  backends::vulkan::Context& ctx() { return *ctx_; }
  std::shared_ptr<backends::vulkan::Context> ctx_;
  std::shared_ptr<backends::vulkan::ValidationLog> log_;
};

// A validated context shared by the tests of one parameterised suite (created once per suite, as
// the pipelines and tables it caches are), with the validation log checked after it is destroyed.
// Tag: the deriving suite, so that every suite has its own context.
template <class Tag>
class ValidatedParamSuite : public ::testing::TestWithParam<std::string> {
 protected:
  static void SetUpTestSuite() {
    ctx_ = validated_context();
    log_ = ctx_->validation_log();
  }
  static void TearDownTestSuite() {
    ctx_.reset();
    EXPECT_EQ(log_->problems(), 0u) << log_->summary();
  }
  static inline std::shared_ptr<backends::vulkan::Context> ctx_;
  static inline std::shared_ptr<backends::vulkan::ValidationLog> log_;
};

// --- Backend parity of the passes that run SHEXP's shaders (test_shexp_parity, test_image_splat_parity)
// Tolerances, per receiver, relative to the largest coefficient of the receiver's CPU vector.
// accumulate_log: the backends evaluate the same float formulas in a different order (the GPU sums
// blockers one receiver at a time with unfused multiply-adds -- lavapipe does not fuse fma -- the
// CPU kernel 16 receivers at a time with fused ones and refined reciprocal square roots), so sums
// over up to a few hundred blockers differ by a few ulps of the largest partial sum; and asin(r/d)
// is ill-conditioned where r/d -> 1 (a receiver touching its blocker): one float ulp of r/d moves
// theta by up to sqrt(2 ulp) ~ 5e-4 rad, a fraction of a table row, so those receivers' vectors
// differ by a few 1e-4 of their size. Observed on lavapipe: at most 5e-4 (crowd, order 4).
constexpr double kAccumulateRelTol = 2e-3;
// exponentiate: each of the s <= 8 HYB squarings doubles the relative error of its input, and the OL
// a, b and the DC factor are evaluated in float on the GPU, in double on the CPU. Observed: <= 8e-5.
constexpr double kExpRelTol = 5e-4;
// image_splat's accumulate_indirect (test_image_splat_parity2, test_image_splat_splats):
// Per receiver, |gpu - cpu| over the three channels relative to the receiver's largest CPU channel
// (floored at kFloorFraction of the largest). Both backends evaluate the same float formulas on the
// same table floats, in a different order and with different primitives: the GPU's asin is the SHEXP kernel's
// Abramowitz-Stegun polynomial (|error| <= 2e-8) where the CPU calls std::asin, and asin(r/d) is
// ill-conditioned where r/d -> 1, which the replacement rule makes common (the adjusted sphere is
// tangent to the receiver's tangent plane: a receiver near the tangent point sees r/d near 1): one
// ulp of r/d moves theta by up to sqrt(2 ulp) ~ 5e-4 rad, a fraction of a table row (pi/2/255 rad);
// the basis is the SHEXP recurrence on the GPU, sh::eval_basis on the CPU (a few ulps); lavapipe does
// not fuse multiply-adds. Sums of up to a few hundred proxies: the bound of the accumulate_log
// parity test, whose error sources these are.
constexpr double kIndirectRelTol = 2e-3;
// omega_p = sum of F_0 from the same table row pairs: the asin conditioning above only.
constexpr double kOmegaRelTol = 2e-3;
// Receivers whose vector is this small relative to the scene's largest are compared against that
// largest instead (absolute cancellation noise of sums whose terms have the scene's scale).
constexpr double kFloorFraction = 1e-4;

struct Compared {
  double worst = 0.0;  // max over rows of |gpu - cpu|_inf / max(|cpu|_inf, floor)
  std::size_t worst_index = 0;
};

// Row-wise comparison of two row-major arrays of `width` columns; the floor is kFloorFraction of
// the largest |cpu| value. A non-finite difference counts as 1e30.
inline Compared compare_rows(const std::vector<float>& cpu, const std::vector<float>& gpu, std::size_t width) {
  EXPECT_EQ(cpu.size(), gpu.size());
  double scale = 0.0;
  for (float v : cpu) scale = std::max(scale, static_cast<double>(std::abs(v)));
  Compared c;
  const std::size_t rows = width ? std::min(cpu.size(), gpu.size()) / width : 0;
  for (std::size_t i = 0; i < rows; ++i) {
    double mag = 0.0, diff = 0.0;
    for (std::size_t k = 0; k < width; ++k) {
      mag = std::max(mag, static_cast<double>(std::abs(cpu[i * width + k])));
      const double d = std::abs(static_cast<double>(gpu[i * width + k]) - cpu[i * width + k]);
      diff = std::isfinite(d) ? std::max(diff, d) : 1e30;
    }
    const double rel = diff / std::max(mag, kFloorFraction * scale + 1e-30);
    if (rel > c.worst) {
      c.worst = rel;
      c.worst_index = i;
    }
  }
  return c;
}

}  // namespace softgi::testing
