// Sphere-set proxies (paper 004 section 6.2-6.3): outside-volume evaluation, the variational fit,
// the octree baseline, mean value coordinates and hierarchy refits, on a synthetic closed blob
// (the bunny timing, which needs the asset set and the glTF loader, is `softgi fit-proxies`, see
// docs/proxies.md).
#include <benchmark/benchmark.h>

#include <cmath>
#include <numbers>
#include <random>

#include "softgi/proxies/binding.hpp"
#include "softgi/proxies/hierarchy.hpp"
#include "softgi/proxies/sphere_fit.hpp"

namespace {
using namespace softgi;

// A closed, non-convex blob (lobes and dents) with 2 * n_lat * n_lon triangles.
proxies::TriMesh blob(int n_lat, int n_lon) {
  proxies::TriMesh m;
  const double pi = std::numbers::pi;
  auto radial = [](double th, double ph) {
    return 1.0 + 0.35 * std::pow(std::max(0.0, std::cos(th)), 6.0) * (1.0 + std::cos(2.0 * ph)) +
           0.12 * std::sin(3.0 * th) * std::cos(3.0 * ph);
  };
  m.positions.push_back({0, 0, static_cast<float>(radial(0, 0))});
  for (int i = 1; i < n_lat; ++i)
    for (int j = 0; j < n_lon; ++j) {
      const double th = pi * i / n_lat, ph = 2 * pi * j / n_lon, r = radial(th, ph);
      m.positions.push_back(glm::vec3(glm::dvec3(r * std::sin(th) * std::cos(ph), r * std::sin(th) * std::sin(ph), r * std::cos(th))));
    }
  m.positions.push_back({0, 0, -static_cast<float>(radial(pi, 0))});
  const unsigned south = static_cast<unsigned>(m.positions.size() - 1);
  auto ring = [&](int i, int j) { return static_cast<unsigned>(1 + (i - 1) * n_lon + (j % n_lon)); };
  for (int j = 0; j < n_lon; ++j) m.triangles.push_back({0, ring(1, j), ring(1, j + 1)});
  for (int i = 1; i < n_lat - 1; ++i)
    for (int j = 0; j < n_lon; ++j) {
      m.triangles.push_back({ring(i, j), ring(i + 1, j), ring(i + 1, j + 1)});
      m.triangles.push_back({ring(i, j), ring(i + 1, j + 1), ring(i, j + 1)});
    }
  for (int j = 0; j < n_lon; ++j) m.triangles.push_back({south, ring(n_lat - 1, j + 1), ring(n_lat - 1, j)});
  return m;
}

// outside_volume_ratio over 64 spheres of radius 0.3 (one BVH build, 64 exact V(S - T)); the blob
// at the bunny's triangle count (about 5.6k).
void BM_OutsideVolume64(benchmark::State& state) {
  const proxies::TriMesh m = blob(53, 53);
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> U(-1.0f, 1.0f);
  std::vector<scene::Sphere> s(64);
  for (auto& x : s) x = {{U(rng), U(rng), U(rng)}, 0.3f};
  for (auto _ : state) benchmark::DoNotOptimize(proxies::outside_volume_ratio(s, m));
  state.counters["triangles"] = static_cast<double>(m.triangles.size());
}
BENCHMARK(BM_OutsideVolume64)->Unit(benchmark::kMillisecond);

// The full variational fit (default options: grid 32, up to 60 iterations) on the bunny-sized blob.
void BM_FitSphereSet(benchmark::State& state) {
  const proxies::TriMesh m = blob(53, 53);
  proxies::FitOptions opt;
  opt.spheres = static_cast<int>(state.range(0));
  double E = 0.0;
  int iterations = 0;
  for (auto _ : state) {
    const proxies::FitResult r = proxies::fit_sphere_set(m, opt);
    E = r.E;
    iterations = r.iterations;
  }
  state.counters["E"] = E;
  state.counters["iterations"] = iterations;
}
BENCHMARK(BM_FitSphereSet)->Arg(16)->Arg(64)->Unit(benchmark::kSecond)->Iterations(1);

void BM_OctreeSphereSet(benchmark::State& state) {
  const proxies::TriMesh m = blob(53, 53);
  double E = 0.0;
  for (auto _ : state) {
    const auto s = proxies::octree_sphere_set(m, static_cast<int>(state.range(0)));
    state.PauseTiming();
    E = proxies::outside_volume_ratio(s, m);
    state.ResumeTiming();
  }
  state.counters["E"] = E;
}
BENCHMARK(BM_OctreeSphereSet)->Arg(64)->Unit(benchmark::kMillisecond);

void BM_MeanValueCoordinates(benchmark::State& state) {
  const proxies::TriMesh m = blob(53, 53);
  for (auto _ : state) benchmark::DoNotOptimize(proxies::mean_value_coordinates({0.1f, 0.2f, 0.3f}, m.positions, m.triangles));
  state.counters["triangles"] = static_cast<double>(m.triangles.size());
}
BENCHMARK(BM_MeanValueCoordinates)->Unit(benchmark::kMicrosecond);

void BM_HierarchyUpdate(benchmark::State& state) {
  std::mt19937 rng(2);
  std::uniform_real_distribution<float> U(-1.0f, 1.0f);
  std::vector<scene::Sphere> leaves(static_cast<size_t>(state.range(0)));
  for (auto& x : leaves) x = {{U(rng), U(rng), U(rng)}, 0.1f};
  proxies::SphereHierarchy h = proxies::SphereHierarchy::build(leaves);
  for (auto _ : state) {
    for (auto& x : leaves) x.center.x += 1e-4f;
    h.update(leaves);
  }
}
BENCHMARK(BM_HierarchyUpdate)->Arg(64)->Arg(1024)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
