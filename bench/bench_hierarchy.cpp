// Sphere hierarchy construction (paper 004 section 6.3, "Construction and Animation") on proxy
// sets of 1k to 100k spheres, and the quality of the tree it builds:
//  - BM_HierarchyBuild/<n>: SphereHierarchy::build with the default options (branching 4) on a
//    crowd-like proxy set of n spheres (64 per object, objects on a ground grid, so the density
//    stays the same as n grows, as in a larger scene);
//  - counters, computed after the timed loop: nodes, depth, average and largest branching,
//    r_h<k> = mean bounding radius of the nodes of height k (k edges above their deepest leaf),
//    cut = mean number of nodes in the eq. 36 cut (theta_max 25 degrees) of 64 receiver clusters
//    (radius 0.5, on the ground among the objects): the blockers SHEXP processes per cluster, so a
//    looser tree shows up there as a larger cut.
// docs/proxies.md quotes the figures and the command.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "softgi/progress.hpp"
#include "softgi/proxies/hierarchy.hpp"

namespace {
using namespace softgi;

// Objects of 64 spheres (radius 0.12-0.25) on the surface of an upright ellipsoid of about human
// proportions, on a ground grid of 2 m spacing; the last object takes what is left.
std::vector<scene::Sphere> crowd_spheres(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> U(0.0f, 1.0f);
  constexpr int kPerObject = 64;
  const int objects = (n + kPerObject - 1) / kPerObject;
  const int side = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(objects))));
  std::vector<scene::Sphere> s;
  s.reserve(n);
  for (int o = 0; o < objects; ++o) {
    const glm::vec3 base(2.0f * (o % side) + 0.5f * U(rng), 0.9f, 2.0f * (o / side) + 0.5f * U(rng));
    const glm::vec3 axes(0.25f + 0.1f * U(rng), 0.8f + 0.2f * U(rng), 0.2f + 0.1f * U(rng));
    for (int i = 0; i < kPerObject && static_cast<int>(s.size()) < n; ++i) {
      const float z = 2.0f * U(rng) - 1.0f, phi = 2.0f * std::numbers::pi_v<float> * U(rng);
      const float rxy = std::sqrt(std::max(0.0f, 1.0f - z * z));
      s.push_back({base + axes * glm::vec3(rxy * std::cos(phi), z, rxy * std::sin(phi)), 0.12f + 0.13f * U(rng)});
    }
  }
  return s;
}

// Size of the eq. 36 cut of the tree for a receiver cluster bounded by (centre, radius): a node
// subtending less than theta_max over the whole cluster is taken, else its children are visited.
int cut_size(const proxies::SphereHierarchy& h, const glm::dvec3& centre, double radius, double theta_max) {
  const double s = std::sin(theta_max);
  int count = 0;
  std::vector<int> stack{h.root()};
  while (!stack.empty()) {
    const proxies::SphereNode& n = h.nodes()[stack.back()];
    stack.pop_back();
    const double d = glm::length(glm::dvec3(n.bound.center) - centre);
    if (n.children.empty() || n.bound.radius < s * (d - radius)) {
      ++count;
      continue;
    }
    stack.insert(stack.end(), n.children.begin(), n.children.end());
  }
  return count;
}

void quality_counters(benchmark::State& state, const proxies::SphereHierarchy& h, const std::vector<scene::Sphere>& leaves) {
  const auto& nodes = h.nodes();
  // Nodes are stored children first, so heights fill in index order.
  std::vector<int> height(nodes.size(), 0);
  int max_children = 0;
  for (size_t i = 0; i < nodes.size(); ++i) {
    for (int c : nodes[i].children) height[i] = std::max(height[i], height[c] + 1);
    max_children = std::max(max_children, static_cast<int>(nodes[i].children.size()));
  }
  std::vector<double> sum(8, 0.0), count(8, 0.0);
  for (size_t i = 0; i < nodes.size(); ++i)
    if (height[i] >= 1 && height[i] < 8) {
      sum[height[i]] += nodes[i].bound.radius;
      count[height[i]] += 1.0;
    }
  for (int k = 1; k <= 5; ++k)
    if (count[k] > 0) state.counters["r_h" + std::to_string(k)] = sum[k] / count[k];
  state.counters["nodes"] = static_cast<double>(nodes.size());
  state.counters["depth"] = h.depth();
  state.counters["branching"] = h.average_branching();
  state.counters["max_children"] = max_children;
  state.counters["conservative"] = h.bounds_are_conservative();
  // Receiver clusters on the ground (y = 0) spread over the objects' extent.
  glm::vec3 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
  for (const scene::Sphere& s : leaves) {
    lo = glm::min(lo, s.center);
    hi = glm::max(hi, s.center);
  }
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  double cut = 0.0;
  constexpr int kClusters = 64;
  for (int c = 0; c < kClusters; ++c) {
    const glm::dvec3 p(lo.x + (hi.x - lo.x) * U(rng), 0.0, lo.z + (hi.z - lo.z) * U(rng));
    cut += cut_size(h, p, 0.5, 25.0 * std::numbers::pi / 180.0);
  }
  state.counters["cut"] = cut / kClusters;
}

void BM_HierarchyBuild(benchmark::State& state) {
  const std::vector<scene::Sphere> leaves = crowd_spheres(static_cast<int>(state.range(0)), 1);
  proxies::SphereHierarchy h;
  for (auto _ : state) {
    h = proxies::SphereHierarchy::build(leaves);
    benchmark::DoNotOptimize(h.nodes().data());
  }
  quality_counters(state, h, leaves);
}
BENCHMARK(BM_HierarchyBuild)->Arg(1000)->Arg(10000)->Arg(100000)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime();

}  // namespace

int main(int argc, char** argv) {
  // The timed builds would otherwise draw their progress on stderr past the reporter's delay.
  ProgressSettings quiet;
  quiet.enabled = false;
  set_progress_settings(quiet);
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
