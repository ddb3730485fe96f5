// Point-proxy voxels (paper 002): the proxy count is unbiased on a mesh of tiny triangles, the hash
// and sort give each proxy exactly one cell, the visibility filter never takes a list across a
// depth or normal discontinuity, dense marching finds the voxels a brute-force ray caster sees,
// gathering against the closed form of a radiant disc, the lights' depth maps against a blocker, and
// whole frames on built-in scenes.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <limits>
#include <map>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "../../techniques/point_voxels/pv_core.hpp"
#include "softgi/backends/cpu_backend.hpp"
#include "softgi/render/backend.hpp"
#include "softgi/reference/reference.hpp"
#include "softgi/render/common_passes.hpp"
#include "softgi/scene/builtin.hpp"
#include "softgi/techniques/registry.hpp"

using namespace softgi;
using namespace softgi::techniques::point_voxels;

namespace {

constexpr double kPi = 3.14159265358979323846;

// A node with this mesh and one diffuse material.
int add_object(scene::Scene& s, scene::Mesh m, glm::vec3 albedo = glm::vec3(0.5f)) {
  scene::Material mat;
  mat.albedo = albedo;
  s.materials.push_back(mat);
  m.material = static_cast<int>(s.materials.size()) - 1;
  s.meshes.push_back(std::move(m));
  scene::Node n;
  n.name = "n" + std::to_string(s.nodes.size());
  n.mesh = static_cast<int>(s.meshes.size()) - 1;
  s.nodes.push_back(n);
  return static_cast<int>(s.nodes.size()) - 1;
}

// A w x w grid of quads (2 triangles each) spanning [0, size]^2 in x, z at height y, normal +y
// (or -y when down).
scene::Mesh grid_mesh(int w, float size, float y, bool down = false) {
  scene::Mesh m;
  m.name = "grid";
  for (int j = 0; j <= w; ++j)
    for (int i = 0; i <= w; ++i) {
      m.positions.push_back({size * i / w, y, size * j / w});
      m.normals.push_back({0.0f, down ? -1.0f : 1.0f, 0.0f});
    }
  for (int j = 0; j < w; ++j)
    for (int i = 0; i < w; ++i) {
      const unsigned a = j * (w + 1) + i, b = a + 1, c = a + (w + 1), d = c + 1;
      if (down) {
        m.triangles.push_back({a, b, c});
        m.triangles.push_back({b, d, c});
      } else {
        m.triangles.push_back({a, c, b});
        m.triangles.push_back({b, c, d});
      }
    }
  return m;
}

// An axis-aligned box, faces pointing inwards (a room) or outwards, 2 triangles per face.
scene::Mesh box(glm::vec3 lo, glm::vec3 hi, bool inward) {
  scene::Mesh m;
  m.name = "box";
  for (int a = 0; a < 3; ++a)
    for (int side = 0; side < 2; ++side) {
      const int ua = (a + 1) % 3, va = (a + 2) % 3;
      glm::vec3 n(0.0f);
      n[a] = (side ? 1.0f : -1.0f) * (inward ? -1.0f : 1.0f);
      const unsigned base = static_cast<unsigned>(m.positions.size());
      for (int k = 0; k < 4; ++k) {
        glm::vec3 p;
        p[a] = side ? hi[a] : lo[a];
        p[ua] = (k & 1) ? hi[ua] : lo[ua];
        p[va] = (k & 2) ? hi[va] : lo[va];
        m.positions.push_back(p);
        m.normals.push_back(n);
      }
      for (auto t : {glm::uvec3(0, 1, 3), glm::uvec3(0, 3, 2)}) {
        glm::uvec3 tri = t + base;
        const glm::vec3 g = glm::cross(m.positions[tri.y] - m.positions[tri.x], m.positions[tri.z] - m.positions[tri.x]);
        if (glm::dot(g, n) < 0.0f) std::swap(tri.y, tri.z);
        m.triangles.push_back(tri);
      }
    }
  return m;
}

}  // namespace

// Section 3.1: 80000 triangles each expecting 0.05 proxies get their proxies only from the Russian
// roulette; the total is a sum of independent-looking Bernoulli draws with mean 4000 and standard
// deviation sqrt(80000 * 0.05 * 0.95) = 61.6. Tolerance 4 sigma: a correct sampler fails it with
// probability 6e-5; dropping the roulette (floor only) gives 0, a roulette without the area
// (always one proxy) 80000.
TEST(PointProxies, CountIsUnbiasedForAMeshOfManyTinyTriangles) {
  scene::Scene s;
  add_object(s, grid_mesh(200, 2.0f, 0.0f));
  const auto posed = scene::evaluate(s, 0.0);
  const double triangles = 80000.0, expected_per_triangle = 0.05;
  const ProxySampling ps = sample_point_proxies(posed, triangles * expected_per_triangle);
  EXPECT_NEAR(ps.total_area, 4.0, 1e-3);
  const double sigma = std::sqrt(triangles * expected_per_triangle * (1.0 - expected_per_triangle));
  EXPECT_NEAR(static_cast<double>(ps.samples.size()), triangles * expected_per_triangle, 4.0 * sigma);
  EXPECT_EQ(ps.roulette_triangles, 80000u);
  // The same triangles draw the same proxies: the roulette hashes positions, not a frame's state.
  EXPECT_EQ(sample_point_proxies(posed, 4000.0).samples.size(), ps.samples.size());
}

// Large triangles get floor(n) Halton points plus the roulette's remainder, uniformly on the
// triangle: on a grid of 8 quads with 1000 proxies the count is within the roulette's spread (at most
// 128 triangles draw a remainder: 4 sigma < 23) and the mean position is the grid's centre within
// 0.5 % of its size (Halton points are far more even than that).
TEST(PointProxies, LargeTrianglesAreSampledUniformly) {
  scene::Scene s;
  add_object(s, grid_mesh(8, 1.0f, 0.0f));
  const auto posed = scene::evaluate(s, 0.0);
  const ProxySampling ps = sample_point_proxies(posed, 1000.0);
  EXPECT_NEAR(static_cast<double>(ps.samples.size()), 1000.0, 23.0);
  const PosedProxies p = pose_proxies(s, posed, ps, 1.0);
  glm::dvec3 mean(0.0);
  for (const auto& q : p.position) mean += glm::dvec3(q);
  mean /= static_cast<double>(p.size());
  EXPECT_NEAR(mean.x, 0.5, 5e-3);
  EXPECT_NEAR(mean.z, 0.5, 5e-3);
  // The VPL area is the area each proxy stands for whatever the disc's size; at disc_scale 1 the disc
  // has exactly that area.
  EXPECT_NEAR(p.patch_area * ps.density, 1.0, 1e-5);
  EXPECT_NEAR(3.14159265f * p.radius * p.radius * ps.density, 1.0, 1e-5);
  const PosedProxies wide = pose_proxies(s, posed, ps, 1.5);
  EXPECT_EQ(wide.patch_area, p.patch_area);
  EXPECT_NEAR(wide.radius, 1.5f * p.radius, 1e-6f);
  for (const auto& n : p.normal) ASSERT_NEAR(n.y, 1.0f, 1e-6f);
}

TEST(PointProxies, BadTargetsAndEmptyScenesAreErrors) {
  scene::Scene s;
  add_object(s, grid_mesh(2, 1.0f, 0.0f));
  const auto posed = scene::evaluate(s, 0.0);
  EXPECT_THROW(sample_point_proxies(posed, 0.0), std::invalid_argument);
  EXPECT_THROW(sample_point_proxies(posed, std::nan("")), std::invalid_argument);
  EXPECT_THROW(sample_point_proxies(scene::PosedScene{}, 100.0), std::invalid_argument);
}

// Eq. 1 is a bijection from cells to [0, cells); after sorting, every proxy sits in exactly one
// cell's range, the one its position hashes to, and the permutation is a permutation.
TEST(VoxelGrid, HashAndSortGiveEachProxyExactlyOneCell) {
  PosedProxies p;
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-3.0f, 5.0f);
  for (int i = 0; i < 5000; ++i) {
    p.position.push_back({u(rng), 0.5f * u(rng), 2.0f * u(rng)});
    p.normal.push_back({0.0f, 1.0f, 0.0f});
    p.albedo.push_back(glm::vec3(static_cast<float>(i)));  // identifies the proxy after sorting
    p.radiance.push_back(glm::vec3(0.0f));
  }
  p.radius = 0.01f;
  const std::vector<glm::vec3> before = p.position;
  std::vector<std::uint32_t> perm;
  const VoxelGrid g = build_voxel_grid(p, glm::ivec3(3, 4, 5), &perm);
  std::set<std::uint32_t> hashes;
  for (int z = 0; z < 5; ++z)
    for (int y = 0; y < 4; ++y)
      for (int x = 0; x < 3; ++x) {
        const std::uint32_t h = g.hash({x, y, z});
        EXPECT_EQ(h, static_cast<std::uint32_t>(z * 3 * 4 + y * 3 + x));
        hashes.insert(h);
      }
  EXPECT_EQ(hashes.size(), 60u);
  EXPECT_EQ(*hashes.rbegin(), 59u);
  ASSERT_EQ(g.start.size(), 61u);
  EXPECT_EQ(g.start.front(), 0u);
  EXPECT_EQ(g.start.back(), 5000u);
  std::vector<int> seen(5000, 0);
  for (std::uint32_t k = 0; k < 60; ++k)
    for (std::uint32_t i = g.start[k]; i < g.start[k + 1]; ++i) {
      ASSERT_EQ(g.key[i], k);
      ASSERT_EQ(g.hash(g.cell_of(p.position[i])), k);
      // The proxy lies inside its cell's box (up to rounding at the faces).
      const glm::ivec3 c = g.cell_of(p.position[i]);
      const glm::vec3 lo = g.lo + glm::vec3(c) * g.cell, hi = lo + g.cell;
      for (int a = 0; a < 3; ++a) {
        ASSERT_GE(p.position[i][a], lo[a] - 1e-4f);
        ASSERT_LE(p.position[i][a], hi[a] + 1e-4f);
      }
      const auto id = static_cast<std::size_t>(p.albedo[i].x);
      ASSERT_EQ(perm[i], id);
      ASSERT_EQ(p.position[i], before[id]);
      ++seen[id];
    }
  for (int s : seen) ASSERT_EQ(s, 1);
}

// Eq. 4 on a buffer whose left half is at depth 1 and right half at depth 2 (same normal), then on
// one whose halves face different ways (same depth): no list crosses the edge, and within a half the
// lists spread to every pixel of the window.
TEST(VisibilityFilter, NeverTakesAListAcrossADepthOrNormalDiscontinuity) {
  const int w = 16, h = 8;
  PixelLists in;
  in.width = w;
  in.height = h;
  in.offset.assign(w * h + 1, 0);
  std::vector<float> depth(w * h);
  std::vector<glm::vec3> normal(w * h, glm::vec3(0.0f, 0.0f, 1.0f));
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const int p = y * w + x;
      const bool left = x < w / 2;
      depth[p] = left ? 1.0f : 2.0f;
      // Sparse lists: every third pixel saw a voxel of its own half.
      if ((x + y) % 3 == 0) in.voxel.push_back(left ? 100 + y : 200 + y);
      in.offset[p + 1] = static_cast<std::uint32_t>(in.voxel.size());
    }
  FilterOptions opt;  // 7 x 7, paper
  auto check = [&](const PixelLists& out) {
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const int p = y * w + x;
        const bool left = x < w / 2;
        ASSERT_GT(out.count(p), 0u) << "pixel " << x << "," << y << " got nothing from its own surface";
        for (std::uint32_t e = out.offset[p]; e < out.offset[p + 1]; ++e) {
          const int v = out.voxel[e];
          ASSERT_EQ(v / 100, left ? 1 : 2) << "pixel " << x << "," << y << " took voxel " << v << " across the edge";
          ASSERT_LE(std::abs(v % 100 - y), opt.radius_y);
        }
      }
  };
  check(visibility_filter(in, depth.data(), normal.data(), opt));
  // Normals: both halves at depth 1, the right half facing +x.
  for (int y = 0; y < h; ++y)
    for (int x = w / 2; x < w; ++x) {
      depth[y * w + x] = 1.0f;
      normal[y * w + x] = {1.0f, 0.0f, 0.0f};
    }
  check(visibility_filter(in, depth.data(), normal.data(), opt));
  // Radius 0: the filter is the identity.
  FilterOptions none;
  none.radius_x = none.radius_y = 0;
  const PixelLists same = visibility_filter(in, depth.data(), normal.data(), none);
  EXPECT_EQ(same.voxel, in.voxel);
  EXPECT_EQ(same.offset, in.offset);
}

// Eq. 4 against its definition written out (a std::set per pixel over the accepted window) on
// random buffers: background pixels, two depth layers, tilted normals, lists with repeats within and
// across neighbours, voxel indices from a small grid and from one beyond the marked range. The
// filter must give exactly the sorted union, and the field filter exactly the mean over the same
// neighbours; malformed lists are refused by name.
TEST(VisibilityFilter, EqualsTheUnionOverTheAcceptedWindowWrittenOut) {
  std::mt19937 rng(7);
  // (first index, count): a small grid, the default 8^3, and indices beyond the filter's marked range.
  for (const auto& [base, voxels] : {std::pair<std::int32_t, std::int32_t>{0, 40}, {0, 512}, {(1 << 24) - 20, 40}}) {
    for (const int radius : {0, 1, 3}) {
      const int w = 23, h = 17;
      const std::size_t np = static_cast<std::size_t>(w) * h;
      PixelLists in;
      in.width = w;
      in.height = h;
      in.offset.assign(np + 1, 0);
      std::vector<float> depth(np);
      std::vector<glm::vec3> normal(np);
      std::uniform_real_distribution<float> u(0.0f, 1.0f);
      std::uniform_int_distribution<std::int32_t> pick(base, base + voxels - 1);
      for (std::size_t p = 0; p < np; ++p) {
        const float r = u(rng);
        depth[p] = r < 0.15f ? std::numeric_limits<float>::infinity() : (r < 0.6f ? 1.0f : 1.5f) + 0.02f * u(rng);
        normal[p] = glm::normalize(glm::vec3(0.6f * (u(rng) - 0.5f), 0.6f * (u(rng) - 0.5f), 1.0f));
        if (std::isfinite(depth[p])) {
          std::vector<std::int32_t> list;
          const int n = static_cast<int>(u(rng) * 12.0f);
          for (int k = 0; k < n; ++k) list.push_back(k % 4 == 3 && !list.empty() ? list.back() : pick(rng));
          std::sort(list.begin(), list.end());
          list.erase(std::unique(list.begin(), list.end()), list.end());
          in.voxel.insert(in.voxel.end(), list.begin(), list.end());
        }
        in.offset[p + 1] = static_cast<std::uint32_t>(in.voxel.size());
      }
      FilterOptions opt;
      opt.radius_x = radius;
      opt.radius_y = radius + 1;
      const PixelLists out = visibility_filter(in, depth.data(), normal.data(), opt);
      std::vector<float> field(np * 2), mean(np * 2);
      for (float& f : field) f = u(rng);
      filter_field(field.data(), 2, w, h, depth.data(), normal.data(), opt, mean.data());
      ASSERT_EQ(out.offset.size(), np + 1);
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
          const std::size_t p = static_cast<std::size_t>(y) * w + x;
          std::set<std::int32_t> want;
          double sum[2] = {0.0, 0.0};
          int taken = 0;
          if (std::isfinite(depth[p]))
            for (int j = std::max(0, y - opt.radius_y); j <= std::min(h - 1, y + opt.radius_y); ++j)
              for (int i = std::max(0, x - opt.radius_x); i <= std::min(w - 1, x + opt.radius_x); ++i) {
                const std::size_t q = static_cast<std::size_t>(j) * w + i;
                const bool same = std::isfinite(depth[q]) &&
                                  std::abs(depth[q] - depth[p]) <= static_cast<float>(opt.depth_threshold) * depth[p] &&
                                  glm::dot(normal[p], normal[q]) >= static_cast<float>(opt.normal_threshold);
                if (q != p && !same) continue;
                want.insert(in.voxel.begin() + in.offset[q], in.voxel.begin() + in.offset[q + 1]);
                for (int c = 0; c < 2; ++c) sum[c] += field[q * 2 + c];
                ++taken;
              }
          const std::vector<std::int32_t> got(out.voxel.begin() + out.offset[p], out.voxel.begin() + out.offset[p + 1]);
          ASSERT_EQ(got, std::vector<std::int32_t>(want.begin(), want.end()))
              << "pixel " << x << "," << y << ", voxels from " << base << ", radius " << radius;
          // The filter sums in float: n <= 7 x 9 values in [0, 1) lose at most n ulps of the sum,
          // so the mean is within 63 x 2^-24 (4e-6) of the double one.
          for (int c = 0; c < 2; ++c)
            ASSERT_NEAR(mean[p * 2 + c], taken ? sum[c] / taken : 0.0, 1e-5) << "pixel " << x << "," << y;
        }
    }
  }
  PixelLists bad;
  bad.width = 2;
  bad.height = 1;
  bad.offset = {0, 1};
  bad.voxel = {3};
  const std::vector<float> depth(2, 1.0f);
  const std::vector<glm::vec3> normal(2, glm::vec3(0.0f, 0.0f, 1.0f));
  auto refused = [&](const PixelLists& l, const std::string& what) {
    try {
      visibility_filter(l, depth.data(), normal.data(), FilterOptions{});
      ADD_FAILURE() << "accepted lists with " << what;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
  };
  refused(bad, "2 list offsets");
  bad.offset = {0, 1, 1};
  bad.voxel = {-4};
  refused(bad, "negative voxel index -4");
}

namespace {

// Nearest triangle hit (Moller-Trumbore), brute force over every posed triangle.
bool nearest_hit(const scene::PosedScene& posed, const glm::vec3& o, const glm::vec3& d, glm::vec3& hit) {
  float best = 1e30f;
  for (const auto& obj : posed.objects)
    for (const auto& t : obj.source->triangles) {
      const glm::vec3 a = obj.positions[t.x], e1 = obj.positions[t.y] - a, e2 = obj.positions[t.z] - a;
      const glm::vec3 pv = glm::cross(d, e2);
      const float det = glm::dot(e1, pv);
      if (std::abs(det) < 1e-12f) continue;
      const glm::vec3 tv = o - a;
      const float u = glm::dot(tv, pv) / det;
      if (u < 0.0f || u > 1.0f) continue;
      const glm::vec3 qv = glm::cross(tv, e1);
      const float v = glm::dot(d, qv) / det;
      if (v < 0.0f || u + v > 1.0f) continue;
      const float tt = glm::dot(e2, qv) / det;
      if (tt > 1e-4f && tt < best) best = tt;
    }
  if (best >= 1e30f) return false;
  hit = o + best * d;
  return true;
}

}  // namespace

// Marching with the proxy planes (a cell's discs tested in lanes) finds exactly the voxel of
// marching disc by disc: the same arithmetic per disc. Rays from inside and outside a room of
// proxies, in every direction, grazing ones included, with near and far ranges that cut hits off.
TEST(SparseMarching, ProxyPlanesFindTheVoxelsOfDiscByDisc) {
  scene::Scene s;
  add_object(s, box({-1.0f, 0.0f, -1.0f}, {1.0f, 2.0f, 1.0f}, true));
  add_object(s, box({-0.3f, 0.0f, -0.3f}, {0.3f, 0.8f, 0.3f}, false));
  const auto posed = scene::evaluate(s, 0.0);
  PosedProxies p = pose_proxies(s, posed, sample_point_proxies(posed, 5000.0), 1.5);
  const VoxelGrid g = build_voxel_grid(p, glm::ivec3(5, 4, 3));
  const ProxyPlanes planes = proxy_planes(p);
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  int hits = 0, misses = 0;
  for (int k = 0; k < 20000; ++k) {
    const glm::vec3 o = k % 4 == 0 ? glm::vec3(3.0f * u(rng), 1.0f + 3.0f * u(rng), 3.0f * u(rng))
                                   : glm::vec3(0.95f * u(rng), 1.0f + 0.95f * u(rng), 0.95f * u(rng));
    glm::vec3 d = glm::normalize(glm::vec3(u(rng), u(rng), u(rng)));
    if (k % 5 == 0) d = glm::normalize(glm::vec3(d.x, 1e-7f * d.y, d.z));  // nearly parallel to floor and ceiling
    const float t_min = k % 3 == 0 ? 0.0f : 0.3f * (u(rng) + 1.0f), t_max = k % 7 == 0 ? 0.5f : 1e30f;
    const std::int32_t one = march_ray(g, p, o, d, t_min, t_max);
    ASSERT_EQ(march_ray(g, p, o, d, t_min, t_max, &planes), one) << "ray " << k;
    (one >= 0 ? hits : misses) += 1;
  }
  EXPECT_GT(hits, 5000);
  EXPECT_GT(misses, 1000);
  const ProxyPlanes other = proxy_planes(PosedProxies{});
  EXPECT_THROW(march_ray(g, p, glm::vec3(0.0f, 1.0f, 0.0f), glm::vec3(0.0f, 1.0f, 0.0f), 0.0f, 1e30f, &other), std::invalid_argument);
}

// Section 3.1: a closed 2 m room with a block on the floor; from points on the floor, 4096 marched
// rays against 20000 proxies find every voxel that a brute-force ray caster sees over 8192 other
// directions in more than 0.5 % of them (a voxel seen through a sliver may be missed by any finite
// ray set), and at most 2 % of the marched rays end in a voxel that is not within one cell of a voxel
// the caster sees: the rays that slip between discs into the block (1, 13 and 11 of 4096 from the
// three points at disc_scale 1.5; gaps grow quickly below it).
TEST(SparseMarching, DenseRaysFindEveryVoxelTheReferenceSees) {
  scene::Scene s;
  add_object(s, box({-1.0f, 0.0f, -1.0f}, {1.0f, 2.0f, 1.0f}, true));
  add_object(s, box({-0.3f, 0.0f, -0.3f}, {0.3f, 0.8f, 0.3f}, false));
  const auto posed = scene::evaluate(s, 0.0);
  const ProxySampling ps = sample_point_proxies(posed, 20000.0);
  PosedProxies p = pose_proxies(s, posed, ps, 1.5);
  const VoxelGrid g = build_voxel_grid(p, glm::ivec3(8));
  for (const glm::vec3 o : {glm::vec3(-0.7f, 0.0f, -0.7f), glm::vec3(0.6f, 0.0f, 0.1f), glm::vec3(0.0f, 0.0f, 0.8f)}) {
    const glm::vec3 n(0.0f, 1.0f, 0.0f), org = o + n * (0.25f * p.radius);
    std::map<std::uint32_t, int> reference;
    const int n_ref = 8192;
    for (int k = 0; k < n_ref; ++k) {
      const glm::vec3 d = cosine_direction(n, (k + 0.5f) / n_ref, static_cast<float>(radical_inverse(k + 1, 3)));
      glm::vec3 hit;
      if (nearest_hit(posed, org, d, hit)) ++reference[g.hash(g.cell_of(hit))];
    }
    std::map<std::uint32_t, int> marched;
    const int n_march = 4096;
    for (int k = 0; k < n_march; ++k) {
      const glm::vec3 d = cosine_direction(n, static_cast<float>(radical_inverse(k + 1, 2)), static_cast<float>(radical_inverse(k + 1, 5)));
      const std::int32_t v = march_ray(g, p, org, d, 0.5f * p.radius, 1e30f);
      if (v >= 0) ++marched[static_cast<std::uint32_t>(v)];
    }
    for (const auto& [voxel, count] : reference) {
      if (count > n_ref / 200) {
        EXPECT_TRUE(marched.count(voxel)) << "voxel " << voxel << " seen by " << count << " reference rays";
      }
    }
    auto cell = [&](std::uint32_t k) {
      return glm::ivec3(k % g.dims.x, (k / g.dims.x) % g.dims.y, k / (g.dims.x * g.dims.y));
    };
    int leaked = 0;
    for (const auto& [v, count] : marched) {
      bool near_seen = false;
      for (const auto& [r, rc] : reference) {
        const glm::ivec3 dlt = glm::abs(cell(v) - cell(r));
        near_seen |= dlt.x <= 1 && dlt.y <= 1 && dlt.z <= 1;
      }
      if (!near_seen) leaked += count;
    }
    EXPECT_LE(leaked, n_march / 50) << "rays from " << o.x << ", " << o.z << " ended in voxels no caster ray comes near";
  }
}

// A ray through a disc hits at the plane's t; outside the radius, parallel or behind, it misses.
TEST(SparseMarching, RayDiscIntersection) {
  const glm::vec3 c(0.0f, 1.0f, 0.0f), n(0.0f, -1.0f, 0.0f);
  EXPECT_FLOAT_EQ(ray_disc(glm::vec3(0.0f), {0.0f, 1.0f, 0.0f}, c, n, 0.1f), 1.0f);
  EXPECT_LT(ray_disc(glm::vec3(0.2f, 0.0f, 0.0f), {0.0f, 1.0f, 0.0f}, c, n, 0.1f), 0.0f);
  EXPECT_LT(ray_disc(glm::vec3(0.0f), {1.0f, 0.0f, 0.0f}, c, n, 0.1f), 0.0f);
  EXPECT_LT(ray_disc(glm::vec3(0.0f), {0.0f, -1.0f, 0.0f}, c, n, 0.1f), 0.0f);
}

namespace {

// A disc of radius a at height h facing down, covered by proxies of uniform radiance L on a
// sunflower pattern, in one voxel.
struct RadiantDisc {
  PosedProxies p;
  VoxelGrid g;
};
RadiantDisc radiant_disc(float a, float h, int n, float radiance) {
  RadiantDisc d;
  for (int i = 0; i < n; ++i) {
    const float r = a * std::sqrt((i + 0.5f) / n), phi = 2.39996323f * i;
    d.p.position.push_back({r * std::cos(phi), h, r * std::sin(phi)});
    d.p.normal.push_back({0.0f, -1.0f, 0.0f});
    d.p.albedo.push_back(glm::vec3(1.0f));
    d.p.radiance.push_back(glm::vec3(radiance));
  }
  d.p.radius = a / std::sqrt(static_cast<float>(n));  // n discs of this radius have the disc's area
  d.p.patch_area = 3.14159265f * d.p.radius * d.p.radius;
  d.g = build_voxel_grid(d.p, glm::ivec3(1));
  accumulate_voxel_sh(d.g, d.p);
  return d;
}

}  // namespace

// Eq. 6, near case: the VPLs of a uniformly radiant disc (radius a at height h) give the closed-form
// irradiance on its axis, E = pi L a^2 / (h^2 + a^2). 4000 sunflower-placed VPLs approximate the
// integral to 0.3 %; tolerance 1 %. Without the regularised VPL term the near receiver (h = a / 4) is
// still right to the same accuracy, because A / pi is the on-axis correction of each disc.
TEST(Gathering, DiffuseIndirectOfARadiantDiscMatchesTheClosedForm) {
  const float a = 0.5f, L = 2.0f;
  for (float h : {0.125f, 0.5f, 2.0f}) {
    RadiantDisc d = radiant_disc(a, h, 4000, L);
    Receiver r;
    r.position = glm::vec3(0.0f);
    r.normal = {0.0f, 1.0f, 0.0f};
    Gathered out;
    gather_voxel(d.g, d.p, 0, r, 1e6f, 1.0f, out);
    const double closed = kPi * L * a * a / (h * h + a * a);
    EXPECT_NEAR(out.irradiance.x, closed, 0.01 * closed) << "h = " << h;
    // Weight w of eq. 5 scales linearly.
    Gathered half;
    gather_voxel(d.g, d.p, 0, r, 1e6f, 0.5f, half);
    EXPECT_NEAR(half.irradiance.x, 0.5f * out.irradiance.x, 1e-5f * out.irradiance.x);
  }
}

// Eq. 6, far case: the voxel's order-2 SH of I(w) = L A max(0, n . w) is L A (1/4 + 1/2 n . w), so on
// the axis at distance h the receiver gets exactly (3/4) L A / h^2 (the truncation of the clamped
// cosine to l <= 1, which is what eqs. 2-3 keep); 1e-4 relative for float rounding.
TEST(Gathering, FarVoxelsUseTheirOrderTwoSh) {
  const float a = 0.5f, L = 2.0f, h = 4.0f;
  RadiantDisc d = radiant_disc(a, h, 1000, L);
  Receiver r;
  r.normal = {0.0f, 1.0f, 0.0f};
  Gathered out;
  gather_voxel(d.g, d.p, 0, r, 0.0f, 1.0f, out);
  const double area = kPi * a * a;
  const double dc = std::abs(d.g.centroid[0].y);  // the centroid is on the axis up to the pattern's asymmetry
  EXPECT_NEAR(out.irradiance.x, 0.75 * L * area / (dc * dc), 1e-4 * L * area / (dc * dc));
  // Glossy receiver looking straight at the disc's mirror image: the lobe's peak (ns + 2) / (2 pi).
  r.glossy = 1.0f;
  r.ns = 20.0f;
  r.reflect = {0.0f, 1.0f, 0.0f};
  Gathered g;
  gather_voxel(d.g, d.p, 0, r, 0.0f, 1.0f, g);
  EXPECT_NEAR(g.glossy.x, g.irradiance.x * 22.0 / (2.0 * kPi), 1e-3 * g.irradiance.x);
}

// Figure 2a's depth maps: a light above a plane with a square blocker between them; points under
// the blocker's centre are shadowed, points far from it lit, for the cube map of a local light and
// the directional map of the sun alike.
TEST(LightDepthMaps, BlockerShadowsWhatIsBehindIt) {
  scene::Scene s;
  add_object(s, grid_mesh(4, 4.0f, 0.0f));                     // floor [0, 4]^2
  add_object(s, box({1.8f, 1.0f, 1.8f}, {2.2f, 1.1f, 2.2f}, false));  // blocker under the light
  const auto posed = scene::evaluate(s, 0.0);
  const glm::vec3 up(0.0f, 1.0f, 0.0f);
  const CubeDepthMap cube = rasterize_cube_depth(posed, {2.0f, 2.0f, 2.0f}, 128);
  EXPECT_EQ(cube.visibility({2.0f, 0.0f, 2.0f}, up), 0.0f);
  EXPECT_EQ(cube.visibility({0.5f, 0.0f, 0.5f}, up), 1.0f);
  EXPECT_EQ(cube.visibility({3.5f, 0.0f, 2.0f}, up), 1.0f);
  // The blocker's top face itself is lit (no self-shadowing with the normal offset).
  EXPECT_EQ(cube.visibility({2.0f, 1.1f, 2.0f}, up), 1.0f);
  const OrthoDepthMap sun = rasterize_ortho_depth(posed, up, 256);
  EXPECT_EQ(sun.visibility({2.0f, 0.0f, 2.0f}, up), 0.0f);
  EXPECT_EQ(sun.visibility({0.5f, 0.0f, 3.5f}, up), 1.0f);
  EXPECT_EQ(sun.visibility({2.0f, 1.1f, 2.0f}, up), 1.0f);
  EXPECT_THROW(rasterize_cube_depth(posed, glm::vec3(2.0f), 0), std::invalid_argument);
}

namespace {

render::FrameResult render_pv(const scene::Scene& s, const std::vector<std::string>& assignments, int w, int h) {
  techniques::register_all();
  backends::CpuBackend cpu;
  auto t = render::create_technique("point_voxels");
  render::ParamSet p = render::default_params(*t);
  for (const auto& a : assignments) p.set_assignment(a);
  render::RenderRequest req;
  req.width = w;
  req.height = h;
  req.outputs = {"final", "direct", "indirect"};
  return cpu.render(*t, s, p, req);
}

}  // namespace

// Whole frames: finite, non-negative images with indirect light where the Cornell box's walls
// bleed colour, every pass of the method executed, and without indirect light only direct passes.
TEST(PointVoxelsFrame, CornellBoxBleedsTheWallsColours) {
  const scene::Scene s = scene::make_builtin("cornell");
  const auto f = render_pv(s, {"proxy_count=6000", "grid=6", "march_scale=4", "rays=16", "shadow_map_size=128"}, 48, 48);
  for (const auto* img : {&f.final_image, &f.direct, &f.indirect})
    for (const auto& c : img->rgb) {
      ASSERT_TRUE(std::isfinite(c.x) && std::isfinite(c.y) && std::isfinite(c.z));
      ASSERT_GE(std::min({c.x, c.y, c.z}), 0.0f);
    }
  std::set<std::string> ran;
  for (const auto& p : f.passes) ran.insert(p.name);
  for (const char* p : {"proxies", "voxelize", "light_maps", "light_vpls", "march", "filter", "gather", "indirect", "direct", "compose"})
    EXPECT_TRUE(ran.count(p)) << p;
  // The floor near the red (left) wall is redder in the indirect image than near the green one.
  const int y = 44;  // a floor row of the 48 x 48 view
  glm::vec3 left(0.0f), right(0.0f);
  for (int x = 8; x < 16; ++x) left += f.indirect.at(x, y);
  for (int x = 32; x < 40; ++x) right += f.indirect.at(x, y);
  EXPECT_GT(left.x / (left.y + 1e-6f), right.x / (right.y + 1e-6f));
  EXPECT_GT(left.x + right.x, 0.0f);

  const auto d = render_pv(s, {"indirect=false", "shadow_map_size=64", "rays=4"}, 32, 32);
  for (const auto& p : d.passes) EXPECT_NE(p.name, "gather");
  for (const auto& c : d.indirect.rgb) ASSERT_EQ(c, glm::vec3(0.0f));
}

TEST(PointVoxelsFrame, BadParametersNameWhatIsWrong) {
  const scene::Scene s = scene::make_builtin("spheres");
  try {
    render_pv(s, {"gather_scale=8", "march_scale=4"}, 16, 16);
    FAIL() << "expected an error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("gather_scale"), std::string::npos) << e.what();
  }
}

// Eq. 7: the Gaussian peaks at the reflection vector (1 / (sigma sqrt(2 pi))) and falls off away from
// it. softgi applies it relative to that peak: a light at the reflection vector keeps its Phong
// term, one away from it is suppressed further, so the weighted glossy term never exceeds the Phong
// one and the near light's share grows.
TEST(Gathering, Eq7WeightsTheGlossyTermTowardsTheReflectionVector) {
  const float ns = 30.0f, sigma = eq7_sigma(ns, 1.0f);
  EXPECT_NEAR(eq7_weight(1.0f, ns, sigma), 1.0 / (sigma * std::sqrt(2.0 * kPi)), 1e-5);
  EXPECT_LT(eq7_weight(std::cos(0.4f), ns, sigma), 0.5f * eq7_weight(1.0f, ns, sigma));
  Receiver r;
  r.normal = r.reflect = {0.0f, 1.0f, 0.0f};
  r.glossy = 1.0f;
  r.ns = ns;
  r.eq7_sigma = sigma;
  // Two VPLs: one straight above (on the reflection vector), one 20 degrees off it.
  PosedProxies p;
  for (const glm::vec3 pos : {glm::vec3(0.0f, 1.0f, 0.0f), glm::vec3(std::sin(0.35f), std::cos(0.35f), 0.0f)}) {
    p.position.push_back(pos);
    p.normal.push_back(-pos);
    p.albedo.push_back(glm::vec3(1.0f));
    p.radiance.push_back(glm::vec3(1.0f));
  }
  p.radius = 0.01f;
  p.patch_area = 3.14159265f * p.radius * p.radius;
  VoxelGrid grid = build_voxel_grid(p, glm::ivec3(1));
  accumulate_voxel_sh(grid, p);
  Gathered both;
  gather_voxel(grid, p, 0, r, 1e6f, 1.0f, both);
  ASSERT_TRUE(both.eq7);
  // Each light alone: the one on the reflection vector keeps its term exactly.
  PosedProxies on = p, off = p;
  for (PosedProxies* q : {&on, &off}) {
    const std::size_t keep = q == &on ? 0 : 1;
    q->position = {p.position[keep]};
    q->normal = {p.normal[keep]};
    q->albedo = {p.albedo[keep]};
    q->radiance = {p.radiance[keep]};
  }
  VoxelGrid g_on = build_voxel_grid(on, glm::ivec3(1)), g_off = build_voxel_grid(off, glm::ivec3(1));
  accumulate_voxel_sh(g_on, on);
  accumulate_voxel_sh(g_off, off);
  Gathered a, b;
  gather_voxel(g_on, on, 0, r, 1e6f, 1.0f, a);
  gather_voxel(g_off, off, 0, r, 1e6f, 1.0f, b);
  EXPECT_NEAR(a.glossy_term().x, a.glossy.x, 1e-6f * a.glossy.x);
  EXPECT_GT(b.glossy.x, 0.0f);
  EXPECT_LT(b.glossy_term().x, 0.5f * b.glossy.x);
  EXPECT_LE(both.glossy_term().x, both.glossy.x);
  EXPECT_GT(a.glossy_term().x / both.glossy_term().x, a.glossy.x / both.glossy.x);
  // Without eq. 7 the glossy term is the Phong sum.
  r.eq7_sigma = 0.0f;
  Gathered plain;
  gather_voxel(grid, p, 0, r, 1e6f, 1.0f, plain);
  EXPECT_FALSE(plain.eq7);
  EXPECT_EQ(plain.glossy_term(), plain.glossy);
}

// The near case summed in lanes over VPL planes against the VPLs one at a time: random VPLs in a
// 3 x 2 x 2 grid (voxels of 0 to a few dozen VPLs, so a voxel's last lanes run into its neighbour's
// VPLs and, for the last voxel, into the planes' padding), random receivers, some facing away, some
// sitting on a VPL (d = 0), some glossy (the Phong lobe, and eq. 7's weights; their powers and
// Gaussians in lanes are 2^(ns log2 c) and a polynomial 2^x); far voxels are the SH case either way.
TEST(Gathering, ProxyPlanesSumTheNearVplsAsOneAtATime) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  PosedProxies p;
  for (int i = 0; i < 149; ++i) {
    p.position.push_back({1.5f * u(rng), u(rng), u(rng)});
    p.normal.push_back(glm::normalize(glm::vec3(u(rng), u(rng), u(rng)) + glm::vec3(0.0f, 0.0f, 0.1f)));
    p.albedo.push_back(glm::vec3(0.5f));
    p.radiance.push_back({0.5f + 0.5f * u(rng), 0.3f, 1.0f + u(rng)});
  }
  p.radius = 0.05f;
  p.patch_area = 0.004f;
  VoxelGrid grid = build_voxel_grid(p, glm::ivec3(3, 2, 2));
  accumulate_voxel_sh(grid, p);
  const ProxyPlanes planes = proxy_planes(p);
  ASSERT_EQ(planes.size, p.size());
  // Planes made before the proxies were lit, then given their radiance: the same planes.
  PosedProxies unlit = p;
  unlit.radiance.clear();
  ProxyPlanes lit_later = proxy_planes(unlit);
  EXPECT_EQ(lit_later.lr, std::vector<float>(p.size() + kProxyLanes, 0.0f));
  set_radiance(lit_later, p);
  for (const auto& [a, b] : {std::pair{&lit_later.lr, &planes.lr}, {&lit_later.lg, &planes.lg}, {&lit_later.lb, &planes.lb},
                             {&lit_later.px, &planes.px}, {&lit_later.nz, &planes.nz}})
    EXPECT_EQ(*a, *b);
  EXPECT_THROW(set_radiance(lit_later, unlit), std::invalid_argument);
  int compared = 0, glossy_compared = 0, eq7_compared = 0;
  float worst_glossy = 0.0f;
  std::uint32_t largest = 0;  // VPLs of the fullest voxel
  for (std::size_t c = 0; c < grid.cells(); ++c) largest = std::max(largest, grid.start[c + 1] - grid.start[c]);
  for (int k = 0; k < 200; ++k) {
    Receiver r;
    r.position = k % 10 == 0 ? p.position[static_cast<std::size_t>(k) % p.size()] : glm::vec3(1.5f * u(rng), u(rng), u(rng));
    r.normal = glm::normalize(glm::vec3(u(rng), u(rng), u(rng)) + glm::vec3(0.0f, 0.0f, 0.1f));
    r.glossy = k % 3 == 0 ? 0.5f : 0.0f;
    r.ns = k % 2 == 0 ? 20.0f : 200.0f;
    r.eq7_sigma = k % 9 == 0 ? eq7_sigma(r.ns, 1.0f) : 0.0f;
    r.reflect = k % 4 == 0 ? r.normal : glm::normalize(glm::vec3(u(rng), u(rng), u(rng)) + glm::vec3(0.0f, 0.0f, 0.1f));
    for (std::int32_t v = 0; v < static_cast<std::int32_t>(grid.cells()); ++v)
      for (const float near : {1e6f, 0.5f}) {
        Gathered one, lanes;
        gather_voxel(grid, p, v, r, near, 0.75f, one);
        gather_voxel(grid, p, v, r, near, 0.75f, lanes, &planes);
        if (r.glossy > 0.0f) {
          // Every term is non-negative, so each sum bounds its terms. c^ns has condition number ns
          // in c: the lanes' cosine c comes from w |w|^-1 where the one-at-a-time loop divides by
          // |w|, a couple of ulps (2^-23 relative each) apart, and 2^(ns log2 c) rounds log2 c to its
          // own ulps, which the power multiplies by ns as well; the series add a few ulps: (2 ns + 8)
          // 2^-23 of a term. Eq. 7's Gaussian exp(-x^2 / 2) of x = |1 - c^ns| / sigma multiplies that
          // by up to 1 + 1 / sigma^2 (its derivative in c^ns, relative, is at most x / sigma).
          const float pow_rel = (2.0f * r.ns + 8.0f) * 0x1p-23f;
          const float eq7_rel = r.eq7_sigma > 0.0f ? pow_rel * (1.0f + 1.0f / (r.eq7_sigma * r.eq7_sigma)) : 0.0f;
          // Non-negative terms summed in another order, each cosine off by an ulp or so: a float's
          // half ulp per term added, and a few ulps per term.
          const float order_rel = static_cast<float>(largest + 8) * 0x1p-24f;
          for (int c = 0; c < 3; ++c) {
            ASSERT_NEAR(lanes.irradiance[c], one.irradiance[c], order_rel * one.irradiance[c] + 1e-7f) << "receiver " << k << ", voxel " << v;
            ASSERT_NEAR(lanes.glossy[c], one.glossy[c], (order_rel + pow_rel) * one.glossy[c] + 1e-7f) << "receiver " << k << ", voxel " << v;
            ASSERT_NEAR(lanes.weighted[c], one.weighted[c], (order_rel + pow_rel + eq7_rel) * one.weighted[c] + 1e-7f)
                << "receiver " << k << ", voxel " << v;
            if (one.glossy[c] > 1e-4f) worst_glossy = std::max(worst_glossy, std::abs(lanes.glossy[c] - one.glossy[c]) / one.glossy[c]);
          }
          ASSERT_EQ(lanes.eq7, one.eq7) << "receiver " << k << ", voxel " << v;
          glossy_compared += one.glossy != glm::vec3(0.0f);
          eq7_compared += one.weighted != glm::vec3(0.0f);
          continue;
        }
        // Positive terms summed in another order: a few ulps per VPL of the sum (1e-5 relative for
        // at most ~40 VPLs a voxel here). The cosines come from dot products with and without
        // normalising: near grazing, their error is some ulps of |w|, not of the cosine, so each
        // term may be off by ulps of its magnitude without the cosines, L A / (d^2 + A / pi)
        // (1e-6 of their sum M, about 16 ulps). A lost or doubled lane moves the sum by far more.
        glm::vec3 m(0.0f);
        if (glm::length(grid.centroid[static_cast<std::size_t>(v)] - r.position) < near)
          for (std::uint32_t i = grid.start[static_cast<std::size_t>(v)]; i < grid.start[static_cast<std::size_t>(v) + 1]; ++i) {
            const glm::vec3 w = p.position[i] - r.position;
            m += glm::abs(p.radiance[i]) * (0.75f * p.patch_area / (glm::dot(w, w) + p.patch_area / 3.14159265f));
          }
        for (int c = 0; c < 3; ++c)
          ASSERT_NEAR(lanes.irradiance[c], one.irradiance[c], 1e-5f * std::abs(one.irradiance[c]) + 1e-6f * m[c])
              << "receiver " << k << ", voxel " << v << ", channel " << c;
        compared += one.irradiance != glm::vec3(0.0f);
      }
  }
  EXPECT_GT(compared, 500);
  EXPECT_GT(glossy_compared, 100);
  EXPECT_GT(eq7_compared, 20);
  std::printf("near VPLs in lanes: %d diffuse, %d glossy and %d eq. 7 sums compared (fullest voxel %u VPLs); worst glossy "
              "difference %.3g relative (of sums above 1e-4)\n", compared, glossy_compared, eq7_compared, largest, static_cast<double>(worst_glossy));
  PosedProxies fewer = p;
  fewer.position.pop_back();
  fewer.normal.pop_back();
  fewer.albedo.pop_back();
  fewer.radiance.pop_back();
  Gathered g;
  Receiver r;
  EXPECT_THROW(gather_voxel(grid, fewer, 0, r, 1e6f, 1.0f, g, &planes), std::invalid_argument);
}

// Every built-in scene renders with finite, non-negative images and indirect light somewhere (each
// has a lit surface facing another); small settings keep it quick.
TEST(PointVoxelsFrame, EveryBuiltinSceneRenders) {
  for (const auto& info : scene::builtin_scenes()) {
    SCOPED_TRACE(info.name);
    scene::Scene s;
    try {
      s = scene::make_builtin(info.name);
    } catch (const std::runtime_error& e) {
      if (!info.needs_assets) throw;
      std::cout << "skipping " << info.name << " (its assets are absent: run scripts/fetch-assets.sh): " << e.what() << "\n";
      continue;
    }
    const auto f = render_pv(s, {"proxy_count=3000", "grid=8", "march_scale=2", "gather_scale=1", "rays=16", "shadow_map_size=64", "vpl_env_rays=4"}, 24, 24);
    float indirect = 0.0f;
    for (const auto* img : {&f.final_image, &f.direct, &f.indirect})
      for (const auto& c : img->rgb) {
        ASSERT_TRUE(std::isfinite(c.x) && std::isfinite(c.y) && std::isfinite(c.z));
        ASSERT_GE(std::min({c.x, c.y, c.z}), 0.0f);
      }
    for (const auto& c : f.indirect.rgb) indirect += c.x + c.y + c.z;
    EXPECT_GT(indirect, 0.0f);
  }
}

// The whole method against the path tracer (real geometry, one-bounce indirect, samples through the
// pixel centres as the G-buffer sees them) on the glossy Cornell box lit by its local light, the light
// summed over the image. Direct: the depth-map shadows of the same light, within 2 % (measured
// 0.9995). Indirect: the method's visibility is per voxel and found by sparse rays, so light is
// lost where rays miss visible voxels (measured ratios at 6^3 voxels: 0.86 with 32 rays, 0.95 with
// 64); with 256 rays on the paper's 6^3 grid every visible voxel is found and the estimate converges
// (measured 1.02): within 10 %, which the VPL energy, the far-field SH and the upsampling must keep.
// A VPL emitting from its disc's area instead of the area it stands for (x 2.25) fails both bounds.
TEST(PointVoxelsFrame, LightMatchesTheRayTracedReference) {
  const scene::Scene s = scene::make_builtin("cornell_glossy");
  const int w = 48, h = 48;
  reference::ReferenceOptions ro;
  ro.spp = 256;
  ro.width = w;
  ro.height = h;
  ro.jitter = false;
  const reference::ReferenceResult ref = reference::render_reference(s, ro);
  auto sum = [](const Image& img) {
    double t = 0.0;
    for (const auto& c : img.rgb) t += c.x + c.y + c.z;
    return t;
  };
  const auto f = render_pv(s, {"grid=6", "rays=256", "march_scale=4"}, w, h);
  EXPECT_NEAR(sum(f.direct) / sum(ref.direct), 1.0, 0.02);
  EXPECT_NEAR(sum(f.indirect) / sum(ref.indirect), 1.0, 0.1);
  // Fewer rays lose light, never add it.
  const auto sparse = render_pv(s, {"grid=6", "rays=16", "march_scale=4"}, w, h);
  EXPECT_LT(sum(sparse.indirect), sum(f.indirect));
}
