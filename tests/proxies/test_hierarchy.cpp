// Sphere hierarchies (paper 004 section 6.3): conservative bounds, branching, animation refit.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "softgi/progress.hpp"
#include "softgi/proxies/hierarchy.hpp"

namespace softgi::proxies {
namespace {

// Builds in this binary run quietly (a loaded machine or a sanitizer build would pass the 1 s
// delay); the progress tests below install their own handler.
class QuietProgress : public ::testing::Environment {
 public:
  void SetUp() override {
    ProgressSettings s;
    s.enabled = false;
    set_progress_settings(s);
  }
};
const auto* const kQuiet = ::testing::AddGlobalTestEnvironment(new QuietProgress);

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
    const SphereHierarchy h = SphereHierarchy::build(leaves, 4);
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
  const SphereHierarchy h = SphereHierarchy::build(leaves, 4);
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
  SphereHierarchy h = SphereHierarchy::build(leaves, 4);
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
  SphereHierarchy h = SphereHierarchy::build(leaves, 4);
  expect_nested(h);
  for (auto& s : leaves) s.center *= 1.5f;
  h.update(leaves);
  expect_nested(h);
}

// --- awkward sets: conservative bounds, every leaf once, branching kept -------------------------

// Sets that stress the clustering: many equal spheres (one closest cluster for all of them),
// coincident centres with different radii, points (radius 0), and centres spread over 30 orders
// of magnitude.
enum class Kind { Uniform, Duplicates, Coincident, ZeroRadii, HugeRange, Mixed };
const char* kind_name(Kind k) {
  switch (k) {
    case Kind::Uniform: return "uniform";
    case Kind::Duplicates: return "duplicates";
    case Kind::Coincident: return "coincident centres";
    case Kind::ZeroRadii: return "zero radii";
    case Kind::HugeRange: return "huge coordinate range";
    case Kind::Mixed: return "mixed";
  }
  return "?";
}

std::vector<scene::Sphere> awkward_spheres(Kind kind, int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> U(-1.0f, 1.0f), R(0.0f, 0.3f), E(-15.0f, 15.0f);
  std::vector<scene::Sphere> s = random_spheres(n, seed);
  switch (kind) {
    case Kind::Uniform: break;
    case Kind::Duplicates:  // three distinct spheres, repeated
      for (int i = 0; i < n; ++i) s[i] = s[i % 3];
      break;
    case Kind::Coincident:  // one centre, every radius different
      for (auto& x : s) x.center = {0.25f, -0.5f, 1.0f};
      break;
    case Kind::ZeroRadii:
      for (auto& x : s) x.radius = 0.0f;
      break;
    case Kind::HugeRange:  // |coordinates| from 1e-15 to 1e15, radii proportional to the magnitude
      for (auto& x : s) {
        const float m = std::pow(10.0f, E(rng));
        x = {{m * U(rng), m * U(rng), m * U(rng)}, m * R(rng)};
      }
      break;
    case Kind::Mixed:  // a quarter each: uniform, copies of one sphere, zero radii, far away
      for (int i = 0; i < n; ++i) {
        if (i % 4 == 1) s[i] = s[0];
        if (i % 4 == 2) s[i].radius = 0.0f;
        if (i % 4 == 3) s[i].center *= 1e6f;
      }
      break;
  }
  return s;
}

// Walks the tree from the root: every node is reached once, every leaf index 0..n-1 appears
// exactly once, and every internal node has 2..max_children children.
void expect_tree_shape(const SphereHierarchy& h, int n, int max_children, const std::string& what) {
  const auto& nodes = h.nodes();
  ASSERT_GE(h.root(), 0) << what;
  std::vector<int> reached(nodes.size(), 0), leaf_seen(n, 0);
  std::vector<int> stack{h.root()};
  while (!stack.empty()) {
    const int id = stack.back();
    stack.pop_back();
    ASSERT_EQ(reached[id]++, 0) << what << ": node " << id << " reached twice";
    const SphereNode& nd = nodes[id];
    if (nd.children.empty()) {
      ASSERT_GE(nd.leaf, 0) << what;
      ASSERT_LT(nd.leaf, n) << what;
      ++leaf_seen[nd.leaf];
    } else {
      EXPECT_EQ(nd.leaf, -1) << what;
      EXPECT_GE(nd.children.size(), 2u) << what << ": node " << id;
      EXPECT_LE(static_cast<int>(nd.children.size()), max_children) << what << ": node " << id;
    }
    stack.insert(stack.end(), nd.children.begin(), nd.children.end());
  }
  for (size_t i = 0; i < nodes.size(); ++i) EXPECT_EQ(reached[i], 1) << what << ": node " << i << " not in the tree";
  for (int i = 0; i < n; ++i) ASSERT_EQ(leaf_seen[i], 1) << what << ": leaf " << i;
}

// The default cap on children (HierarchyBuildOptions::max_children = 0).
constexpr int kDefaultMaxChildren = 4 * 4;

TEST(SphereHierarchy, AwkwardSetsStayConservativeAndKeepTheirShape) {
  // Default options up to 300 spheres; from 1000 on, no Powell and fewer Lloyd iterations keep
  // the test quick under sanitizers (the huge range drains clusters for all 50 iterations, about
  // 1 s at 1000 spheres in Release). Neither option affects conservativeness (the radius is
  // recomputed from the final centre and rounded up) or the shape checks.
  for (Kind kind : {Kind::Uniform, Kind::Duplicates, Kind::Coincident, Kind::ZeroRadii, Kind::HugeRange, Kind::Mixed}) {
    for (int n : {1, 2, 3, 5, 17, 64, 300, 1000, 5000}) {
      if (n == 5000 && kind != Kind::HugeRange && kind != Kind::Mixed) continue;  // the two that mix all cases
      const std::string what = std::string(kind_name(kind)) + ", n = " + std::to_string(n);
      const std::vector<scene::Sphere> leaves = awkward_spheres(kind, n, 100 + n);
      HierarchyBuildOptions o;
      if (n >= 1000) {
        o.fit_evaluations = 0;
        o.lloyd_iterations = 5;
      }
      const SphereHierarchy h = SphereHierarchy::build(leaves, o);
      EXPECT_TRUE(h.bounds_are_conservative()) << what;
      expect_nested(h);
      expect_tree_shape(h, n, kDefaultMaxChildren, what);
      for (const scene::Sphere& s : leaves) ASSERT_TRUE(contains(h.nodes()[h.root()].bound, s)) << what;
      if (n >= 64) {
        // About n / 4 clusters per level. Emptied clusters and promoted single children move the
        // average up, capped clusters split into groups of about 4 move it down (measured
        // 3.5-4.9 over these sets; the huge range, whose small spheres all share one closest
        // cluster, is the low end).
        EXPECT_GE(h.average_branching(), 3.0) << what;
        EXPECT_LE(h.average_branching(), 5.0) << what;
      }
    }
  }
}

TEST(SphereHierarchy, BranchingAndChildCapFollowTheOptions) {
  const std::vector<scene::Sphere> leaves = random_spheres(1000, 5);
  for (int b : {2, 3, 8}) {
    HierarchyBuildOptions o;
    o.branching = b;
    const SphereHierarchy h = SphereHierarchy::build(leaves, o);
    expect_tree_shape(h, 1000, 4 * b, "branching " + std::to_string(b));
    EXPECT_TRUE(h.bounds_are_conservative()) << b;
    // Near the requested ratio (measured: 2.48, 3.23, 7.94; with two members a cluster empties
    // more easily, so branching 2 drifts up most).
    EXPECT_GE(h.average_branching(), 0.9 * b) << b;
    EXPECT_LE(h.average_branching(), 1.3 * b) << b;
  }
  // Lloyd alone gives clusters of up to 11 children on this set (measured with the cap off); a cap
  // of 8 splits the larger ones.
  HierarchyBuildOptions capped;
  capped.max_children = 8;
  const SphereHierarchy hc = SphereHierarchy::build(leaves, capped);
  expect_tree_shape(hc, 1000, 8, "max_children 8");
  EXPECT_TRUE(hc.bounds_are_conservative());
  // Equal spheres tie for every cluster centre; ties keep the seed groups of 4 they were dealt.
  const std::vector<scene::Sphere> same(2000, scene::Sphere{{1, 2, 3}, 0.5f});
  const SphereHierarchy h = SphereHierarchy::build(same, 4);
  expect_tree_shape(h, 2000, 5, "2000 equal spheres");  // 125 spheres over 31 seeds: 4 or 5
  EXPECT_TRUE(h.bounds_are_conservative());
  EXPECT_EQ(h.nodes()[h.root()].bound.radius, 0.5f) << "equal spheres bound themselves exactly";
}

TEST(SphereHierarchy, BuildIsDeterministic) {
  const std::vector<scene::Sphere> leaves = random_spheres(300, 8);
  const SphereHierarchy a = SphereHierarchy::build(leaves, 4), b = SphereHierarchy::build(leaves, 4);
  ASSERT_EQ(a.nodes().size(), b.nodes().size());
  for (size_t i = 0; i < a.nodes().size(); ++i) {
    EXPECT_EQ(a.nodes()[i].children, b.nodes()[i].children) << i;
    EXPECT_EQ(a.nodes()[i].bound.center, b.nodes()[i].bound.center) << i;
    EXPECT_EQ(a.nodes()[i].bound.radius, b.nodes()[i].bound.radius) << i;
  }
}

TEST(SphereHierarchy, HundredThousandLeavesBuild) {
  // Completion and shape at the size of a large crowd; the build's speed is measured by
  // bench/bench_hierarchy.cpp. The cheapest options keep this quick under sanitizers.
  const int n = 100000;
  const std::vector<scene::Sphere> leaves = awkward_spheres(Kind::Uniform, n, 42);
  HierarchyBuildOptions o;
  o.lloyd_iterations = 1;
  o.fit_evaluations = 0;
  const SphereHierarchy h = SphereHierarchy::build(leaves, o);
  expect_tree_shape(h, n, kDefaultMaxChildren, "100k");
  EXPECT_TRUE(h.bounds_are_conservative());
  EXPECT_GE(h.average_branching(), 3.5);
  EXPECT_LE(h.average_branching(), 5.0);
  EXPECT_LE(h.depth(), 12);  // log_4(1e5) = 8.3 levels above the leaves
}

// --- progress reporting --------------------------------------------------------------------------

// Sets the process-wide progress settings for one test and restores them after.
struct ProgressCapture {
  ProgressSettings saved = progress_settings();
  std::vector<ProgressEvent> events;
  std::vector<std::string> labels;
  explicit ProgressCapture(double delay) {
    ProgressSettings s;
    s.delay_seconds = delay;
    s.handler = [this](const ProgressEvent& e) {
      events.push_back(e);
      labels.emplace_back(e.label);
    };
    set_progress_settings(s);
  }
  ~ProgressCapture() { set_progress_settings(saved); }
};

TEST(SphereHierarchy, BuildReportsProgressPastTheDelayOnly) {
  const std::vector<scene::Sphere> leaves = random_spheres(1000, 3);
  {
    // Default delay (1 s): a build well under a second says nothing.
    ProgressCapture cap(1.0);
    SphereHierarchy::build(random_spheres(50, 3), 4);
    EXPECT_TRUE(cap.events.empty());
  }
  ProgressCapture cap(0.0);
  SphereHierarchy::build(leaves, 4);
  ASSERT_GE(cap.events.size(), 2u);
  EXPECT_EQ(cap.labels.front(), "sphere hierarchy over 1000 spheres");
  for (size_t i = 1; i < cap.events.size(); ++i) EXPECT_GE(cap.events[i].fraction, cap.events[i - 1].fraction) << i;
  for (size_t i = 0; i + 1 < cap.events.size(); ++i) EXPECT_FALSE(cap.events[i].done) << i;
  EXPECT_TRUE(cap.events.back().done);
  EXPECT_EQ(cap.events.back().fraction, 1.0);
}

TEST(SphereHierarchy, RejectsBadInput) {
  EXPECT_THROW(SphereHierarchy::build({}, 4), std::invalid_argument);
  EXPECT_THROW(SphereHierarchy::build(random_spheres(5, 1), 1), std::invalid_argument);
  std::vector<scene::Sphere> bad = random_spheres(5, 1);
  bad[2].radius = std::nanf("");
  EXPECT_THROW(SphereHierarchy::build(bad, 4), std::invalid_argument);
  SphereHierarchy h = SphereHierarchy::build(random_spheres(8, 1), 4);
  EXPECT_THROW(h.update(random_spheres(9, 1)), std::invalid_argument);
  // Options out of range name the option and the value.
  auto message = [](const HierarchyBuildOptions& o) {
    try {
      SphereHierarchy::build(random_spheres(8, 1), o);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  HierarchyBuildOptions o;
  o.max_children = 5;
  EXPECT_NE(message(o).find("max_children = 5"), std::string::npos) << message(o);
  o = {};
  o.lloyd_iterations = 0;
  EXPECT_NE(message(o).find("lloyd_iterations = 0"), std::string::npos) << message(o);
  o = {};
  o.fit_evaluations = 10;
  EXPECT_NE(message(o).find("fit_evaluations = 10"), std::string::npos) << message(o);
  o = {};
  o.branching = 65;
  EXPECT_NE(message(o).find("branching = 65"), std::string::npos) << message(o);
}

}  // namespace
}  // namespace softgi::proxies
