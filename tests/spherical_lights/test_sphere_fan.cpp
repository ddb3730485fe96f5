// common::sphere_fan, the per-light set-up of the receiver pass (paper 001 eqs. 18 and 21-23) with a
// light per vector lane, against the scalar definitions it restates: apply_replacement_rule,
// sphere_zh_vector and average_radiance, on every instruction set and rule.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>

#include "../../techniques/spherical_lights/sl_passes.hpp"
#include "../../techniques/spherical_lights/sl_tables.hpp"

using namespace softgi;
using namespace softgi::techniques::spherical_lights;
namespace common = softgi::techniques::common;

namespace {

constexpr double kPi = 3.14159265358979323846;

class SphereFanTest : public ::testing::TestWithParam<KernelIsa> {
 protected:
  void SetUp() override {
    if (!kernel_isa_supported(GetParam()))
      GTEST_SKIP() << "this CPU lacks " << (GetParam() == KernelIsa::Avx512 ? "AVX-512F (with AVX2 and FMA)" : "AVX2 and FMA")
                   << ": the " << to_string(GetParam()) << " sphere fan is not tested on it";
  }
};
std::string isa_name(const ::testing::TestParamInfo<KernelIsa>& info) { return to_string(info.param); }

struct Fan {
  std::vector<float> cx, cy, cz, r, L;
  std::vector<int> id;
  std::vector<glm::mat3> rot;
};

// `count` spheres about a receiver at the origin with normal +y: far ones, ones straddling its
// tangent plane, ones containing it, ones behind it, one centred on it; `lights` emitters with random
// rotations and intensities, the spheres drawing their index among them at random.
Fan random_fan(std::size_t count, int lights, int order, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f), pos(0.05f, 1.0f);
  Fan f;
  for (std::size_t j = 0; j < count; ++j) {
    glm::vec3 c(u(rng), u(rng), u(rng));
    float r = 0.3f * pos(rng);
    switch (j % 5) {
      case 0: c *= 4.0f; break;                              // far, either side
      case 1: c = glm::vec3(1.8f * r * c.x, 0.5f * r * c.y, 1.8f * r * c.z); break;  // straddling the tangent plane near p
      case 2: c *= 0.2f, r = 0.5f + 0.5f * pos(rng); break;  // containing p
      case 3: c.y = -std::abs(c.y) - r; break;               // behind it
      default: c *= 2.0f; break;
    }
    if (j == 7) c = glm::vec3(0.0f), r = 0.4f;  // p at the centre: +z of the light's own frame
    f.cx.push_back(c.x);
    f.cy.push_back(c.y);
    f.cz.push_back(c.z);
    f.r.push_back(r);
    f.id.push_back(static_cast<int>(rng() % lights));
  }
  const int n2 = order * order;
  for (int k = 0; k < lights; ++k) {
    const glm::vec3 axis = glm::normalize(glm::vec3(u(rng), u(rng), u(rng)) + glm::vec3(0.0f, 0.0f, 1e-3f));
    f.rot.push_back(glm::mat3(glm::rotate(glm::mat4(1.0f), 3.0f * u(rng), axis)));
    for (int q = 0; q < 3 * n2; ++q) f.L.push_back(q % n2 == 0 ? 2.0f + u(rng) : 0.5f * u(rng));
  }
  return f;
}

common::SphereFan view(const Fan& f, const WeightTable& w) {
  common::SphereFan s;
  s.cx = f.cx.data();
  s.cy = f.cy.data();
  s.cz = f.cz.data();
  s.r = f.r.data();
  s.count = f.r.size();
  s.id = f.id.data();
  s.L = f.L.data();
  s.rot = &f.rot[0][0][0];
  s.weight = w.w.data();
  s.weight_rows = w.rows;
  return s;
}

constexpr ReplacementRule kRules[] = {ReplacementRule::Off, ReplacementRule::Continuous, ReplacementRule::Clamped,
                                      ReplacementRule::Printed, ReplacementRule::InsideOnly};

}  // namespace

// Every output against the scalar functions. Tolerances: the fan takes asin from a polynomial
// (|error| <= 2e-8, kernel_body.hpp) and sums in another order, so each value may differ from the
// scalar one by float rounding of its own size; 2e-5 of the value's scale is a few hundred ulps and far
// below what any rule or table error changes (a rule's rho differs from the next rule's by 10 % or
// more on the straddling spheres). Whether a light is alive is exact except within 1e-5 of its radius
// of the boundary p = surface, where the two roundings may fall either side.
TEST_P(SphereFanTest, MatchesTheScalarRulesLogVectorsAndAverageRadiance) {
  const KernelIsa isa = GetParam();
  for (int order : {3, 4, 6}) {
    const auto tables = make_tables(order, 256, 0.02);
    const int n2 = order * order;
    const Fan f = random_fan(37, 5, order, 11u + order);  // 37: a partial last block at 8 and 16 lanes
    const common::SphereFan s = view(f, tables->weight);
    const glm::vec3 p(0.0f), n(0.0f, 1.0f, 0.0f);
    for (ReplacementRule rule : kRules) {
      SCOPED_TRACE(std::string("order ") + std::to_string(order) + ", rule " + common::to_string(rule));
      std::vector<float> g(s.count * n2 + 1, -7.0f), key(s.count + 1, -7.0f), rgb(3 * s.count + 1, -7.0f);
      std::vector<std::uint8_t> alive(s.count + 1, 9);
      common::sphere_fan(isa, tables->log, rule, p, n, s, g.data(), key.data(), alive.data(), rgb.data());
      EXPECT_EQ(g.back(), -7.0f);
      EXPECT_EQ(key.back(), -7.0f);
      EXPECT_EQ(rgb.back(), -7.0f);
      EXPECT_EQ(alive.back(), 9);
      int alive_count = 0;
      std::vector<float> ref(n2);
      for (std::size_t j = 0; j < s.count; ++j) {
        const glm::vec3 c(f.cx[j], f.cy[j], f.cz[j]);
        const AdjustedSphere adj = apply_replacement_rule(rule, p, n, c, f.r[j]);
        const float dist = glm::length(adj.center - p);
        const bool want = adj.radius > 0.0f && dist > adj.radius;
        const bool borderline = std::abs(dist - adj.radius) < 1e-5f * f.r[j];
        ASSERT_TRUE(alive[j] == 0 || alive[j] == 1) << "sphere " << j;
        if (!borderline) {
          EXPECT_EQ(alive[j] != 0, want) << "sphere " << j;
        }
        if (alive[j] && want) {
          ++alive_count;
          EXPECT_NEAR(key[j], dist - adj.radius, 2e-5f * std::max(1.0f, dist)) << "sphere " << j;
          common::sphere_zh_vector(tables->log, p, adj.center, adj.radius, nullptr, ref.data());
          for (int q = 0; q < n2; ++q) EXPECT_NEAR(g[j * n2 + q], ref[q], 2e-5f * std::max(1.0f, std::abs(ref[q]))) << "sphere " << j << " coefficient " << q;
        }
        // The average radiance (eq. 18) of the light as given, alive or not.
        const glm::vec3 d = p - c;
        const float D = glm::length(d);
        const float theta = D > f.r[j] ? std::asin(std::min(1.0f, f.r[j] / D)) : static_cast<float>(kPi / 2);
        const glm::vec3 dl = D > 0.0f ? glm::transpose(f.rot[f.id[j]]) * (d / D) : glm::vec3(0.0f, 0.0f, 1.0f);
        for (int ch = 0; ch < 3; ++ch) {
          const float* L = f.L.data() + (static_cast<std::size_t>(f.id[j]) * 3 + ch) * n2;
          float scale = 0.0f;
          for (int q = 0; q < n2; ++q) scale += std::abs(L[q]);
          EXPECT_NEAR(rgb[3 * j + ch], average_radiance(tables->weight, L, dl, theta), 2e-5f * scale) << "sphere " << j << " channel " << ch;
        }
      }
      EXPECT_GT(alive_count, 10);  // the comparison above saw most spheres
      if (rule != ReplacementRule::Off) {
        EXPECT_LT(alive_count, static_cast<int>(s.count));  // and some eliminated
      }
    }
  }
}

// Without emission the fan writes no radiance; an empty list writes nothing; inputs it cannot use are
// refused by name.
TEST_P(SphereFanTest, OptionalEmissionEmptyListsAndBadInputs) {
  const KernelIsa isa = GetParam();
  const auto tables = make_tables(4, 256, 0.02);
  const Fan f = random_fan(20, 3, 4, 5u);
  common::SphereFan s = view(f, tables->weight);
  s.L = nullptr;
  std::vector<float> g(20 * 16), key(20);
  std::vector<std::uint8_t> alive(20);
  const glm::vec3 p(0.0f), n(0.0f, 1.0f, 0.0f);
  EXPECT_NO_THROW(common::sphere_fan(isa, tables->log, ReplacementRule::Continuous, p, n, s, g.data(), key.data(), alive.data(), nullptr));
  common::SphereFan empty;
  EXPECT_NO_THROW(common::sphere_fan(isa, tables->log, ReplacementRule::Continuous, p, n, empty, nullptr, nullptr, nullptr, nullptr));
  s = view(f, tables->weight);
  try {
    common::sphere_fan(isa, tables->log, ReplacementRule::Continuous, p, n, s, g.data(), key.data(), alive.data(), nullptr);
    ADD_FAILURE() << "emission without an output was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("emission"), std::string::npos) << e.what();
  }
  common::ZhTable bad = tables->log;
  bad.order = 2;
  EXPECT_THROW(common::sphere_fan(isa, bad, ReplacementRule::Continuous, p, n, s, g.data(), key.data(), alive.data(), nullptr),
               std::invalid_argument);
}

INSTANTIATE_TEST_SUITE_P(Isa, SphereFanTest, ::testing::Values(KernelIsa::Scalar, KernelIsa::Avx2, KernelIsa::Avx512), isa_name);
