// Sphere hierarchies (paper 004 section 6.3): conservative bounds, branching, animation refit.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "softgi/proxies/hierarchy.hpp"

namespace softgi::proxies {
namespace {

// Containment is decided in double on float spheres; bounds are rounded up to float, so the check
// needs no slack beyond this relative tolerance of bounds_are_conservative().
constexpr double kContainTol = 1e-6;

bool contains(const scene::Sphere& outer, const scene::Sphere& inner) {
  return glm::length(glm::dvec3(inner.center) - glm::dvec3(outer.center)) + inner.radius <=
         outer.radius * (1.0 + kContainTol);
}

std::vector<scene::Sphere> random_spheres(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> U(-1.0f, 1.0f), R(0.02f, 0.2f);
  std::vector<scene::Sphere> s(n);
  for (auto& x : s) x = {{U(rng), U(rng), 0.5f * U(rng)}, R(rng)};
  return s;
}

TEST(Merge, ClosedForms) {
  // Disjoint: the segment between the far points is a diameter.
  scene::Sphere m = merge({{0, 0, 0}, 1.0f}, {{4, 0, 0}, 0.5f});
  EXPECT_NEAR(m.radius, (4.0 + 1.0 + 0.5) / 2.0, 1e-6);
  EXPECT_NEAR(m.center.x, -1.0 + 2.75, 1e-6);
  EXPECT_NEAR(m.center.y, 0.0, 1e-7);
  // Nested: the outer sphere itself.
  m = merge({{0, 0, 0}, 2.0f}, {{0.5f, 0.5f, 0}, 0.25f});
  EXPECT_EQ(m.radius, 2.0f);
  EXPECT_EQ(m.center, glm::vec3(0.0f));
  m = merge({{0.5f, 0.5f, 0}, 0.25f}, {{0, 0, 0}, 2.0f});
  EXPECT_EQ(m.radius, 2.0f);
  // Identical spheres.
  m = merge({{1, 2, 3}, 0.5f}, {{1, 2, 3}, 0.5f});
  EXPECT_EQ(m.radius, 0.5f);
  // Always conservative, exactly, for random pairs.
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> U(-10.0f, 10.0f), R(0.0f, 3.0f);
  for (int i = 0; i < 1000; ++i) {
    const scene::Sphere a{{U(rng), U(rng), U(rng)}, R(rng)}, b{{U(rng), U(rng), U(rng)}, R(rng)};
    const scene::Sphere s = merge(a, b);
    EXPECT_LE(glm::length(glm::dvec3(a.center) - glm::dvec3(s.center)) + a.radius, s.radius);
    EXPECT_LE(glm::length(glm::dvec3(b.center) - glm::dvec3(s.center)) + b.radius, s.radius);
    // and minimal: no larger than half the far-point distance (+ float rounding).
    const double d = glm::length(glm::dvec3(a.center) - glm::dvec3(b.center));
    EXPECT_LE(s.radius, std::max({(d + a.radius + b.radius) / 2.0, double(a.radius), double(b.radius)}) * (1 + 1e-6));
  }
}

TEST(SphereHierarchy, ConservativeWithBranchingAboutFour) {
  for (int n : {1, 2, 7, 64, 200}) {
    const std::vector<scene::Sphere> leaves = random_spheres(n, 11 + n);
    const SphereHierarchy h = SphereHierarchy::build(leaves, 4, 5);
    EXPECT_TRUE(h.bounds_are_conservative()) << n;
    ASSERT_GE(h.root(), 0);
    int leaf_count = 0;
    for (const SphereNode& node : h.nodes()) leaf_count += node.leaf >= 0;
    EXPECT_EQ(leaf_count, n);
    // The root bounds every leaf.
    for (const scene::Sphere& s : leaves) EXPECT_TRUE(contains(h.nodes()[h.root()].bound, s));
    if (n >= 64) {
      EXPECT_GE(h.average_branching(), 3.0) << n;
      EXPECT_LE(h.average_branching(), 5.0) << n;
      // log_4 n levels above the leaves, within one.
      EXPECT_LE(h.depth(), static_cast<int>(std::ceil(std::log(n) / std::log(4.0))) + 2) << n;
    }
  }
}

// Badoiu-Clarkson iteration for the smallest ball enclosing a set of balls: step 1/(k+1) towards
// the farthest point of the union. Its radius bounds the optimum from above and converges to it.
double badoiu_clarkson_radius(const std::vector<scene::Sphere>& balls, int iterations) {
  glm::dvec3 c(balls[0].center);
  auto farthest = [&](const glm::dvec3& x, glm::dvec3& q) {
    double best = -1.0;
    for (const scene::Sphere& b : balls) {
      const glm::dvec3 d = glm::dvec3(b.center) - x;
      const double len = glm::length(d);
      const double reach = len + b.radius;
      if (reach > best) {
        best = reach;
        q = glm::dvec3(b.center) + (len > 0.0 ? d / len : glm::dvec3(1, 0, 0)) * static_cast<double>(b.radius);
      }
    }
    return best;
  };
  double best = std::numeric_limits<double>::infinity();
  for (int k = 0; k < iterations; ++k) {
    glm::dvec3 q(0.0);
    best = std::min(best, farthest(c, q));
    c += (q - c) / static_cast<double>(k + 2);
  }
  return best;
}

TEST(SphereHierarchy, OptimisedCentresMinimiseTheRadius) {
  // Powell minimises each parent's bounding radius over its children (paper 004 6.3). Reference:
  // the Badoiu-Clarkson bound after 2e5 steps (within ~0.1% of the optimum), and the chain of
  // pairwise merges used during animation, a valid but looser bound.
  const std::vector<scene::Sphere> leaves = random_spheres(100, 2);
  const SphereHierarchy h = SphereHierarchy::build(leaves, 4, 1);
  int tighter = 0, internal = 0;
  for (const SphereNode& node : h.nodes()) {
    if (node.children.empty()) continue;
    ++internal;
    std::vector<scene::Sphere> kids;
    for (int c : node.children) kids.push_back(h.nodes()[c].bound);
    scene::Sphere chain = kids[0];
    for (size_t k = 1; k < kids.size(); ++k) chain = merge(chain, kids[k]);
    EXPECT_LE(node.bound.radius, chain.radius * (1.0 + 1e-6));
    EXPECT_LE(node.bound.radius, badoiu_clarkson_radius(kids, 200000) * (1.0 + 1e-3));
    tighter += node.bound.radius < chain.radius * 0.999;
  }
  EXPECT_GT(tighter, internal / 4) << "optimised centres should often beat pairwise merging";
}

TEST(SphereHierarchy, UpdateAfterMovingLeavesStaysConservative) {
  std::vector<scene::Sphere> leaves = random_spheres(120, 9);
  SphereHierarchy h = SphereHierarchy::build(leaves, 4, 2);
  std::mt19937 rng(4);
  std::uniform_real_distribution<float> U(-0.5f, 0.5f);
  for (int frame = 0; frame < 5; ++frame) {
    for (auto& s : leaves) s.center += glm::vec3(U(rng), U(rng), U(rng));
    h.update(leaves);
    EXPECT_TRUE(h.bounds_are_conservative()) << frame;
    for (const SphereNode& node : h.nodes()) {
      if (node.leaf >= 0) {
        EXPECT_EQ(node.bound.center, leaves[node.leaf].center);
      }
    }
    for (const scene::Sphere& s : leaves) EXPECT_TRUE(contains(h.nodes()[h.root()].bound, s));
  }
}

// Independent of bounds_are_conservative(): every node's bound contains each of its children's
// bounds (which implies containment of all leaves below), and parent links are consistent.
void expect_nested(const SphereHierarchy& h) {
  const auto& nodes = h.nodes();
  for (size_t i = 0; i < nodes.size(); ++i) {
    for (int c : nodes[i].children) {
      EXPECT_EQ(nodes[c].parent, static_cast<int>(i));
      EXPECT_TRUE(contains(nodes[i].bound, nodes[c].bound)) << "node " << i << " child " << c;
    }
    if (nodes[i].leaf >= 0) {
      EXPECT_TRUE(nodes[i].children.empty());
    }
  }
  EXPECT_EQ(nodes[h.root()].parent, -1);
}

TEST(SphereHierarchy, ChildrenNestInParentsAfterBuildAndUpdate) {
  std::vector<scene::Sphere> leaves = random_spheres(150, 21);
  SphereHierarchy h = SphereHierarchy::build(leaves, 4, 3);
  expect_nested(h);
  for (auto& s : leaves) s.center *= 1.5f;
  h.update(leaves);
  expect_nested(h);
}

TEST(SphereHierarchy, RejectsBadInput) {
  EXPECT_THROW(SphereHierarchy::build({}, 4, 1), std::invalid_argument);
  EXPECT_THROW(SphereHierarchy::build(random_spheres(5, 1), 1, 1), std::invalid_argument);
  std::vector<scene::Sphere> bad = random_spheres(5, 1);
  bad[2].radius = std::nanf("");
  EXPECT_THROW(SphereHierarchy::build(bad, 4, 1), std::invalid_argument);
  SphereHierarchy h = SphereHierarchy::build(random_spheres(8, 1), 4, 1);
  EXPECT_THROW(h.update(random_spheres(9, 1)), std::invalid_argument);
}

}  // namespace
}  // namespace softgi::proxies
