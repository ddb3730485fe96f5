// Mean value coordinates (Ju, Schaefer, Warren 2005) and skin binding of sphere centres
// (paper 004 section 6.2, Animation).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "meshes.hpp"
#include "softgi/proxies/binding.hpp"

namespace softgi::proxies {
namespace {

// Linear precision of MVC holds exactly for closed meshes; what is left is double rounding over a
// few thousand triangles, amplified near the surface (measured <= 4e-12 down to 1e-8 from a face; a
// transcription of Ju, Schaefer and Warren 2005's asin/half-angle pseudo-code missed by 1e-6 at 1e-6 from a face). In
// mesh units.
constexpr double kReproduceTol = 1e-9;
constexpr double kSumTol = 1e-9;

void expect_reproduces(const TriMesh& m, const glm::vec3& x, const char* what) {
  const std::vector<double> w = mean_value_coordinates(x, m.positions, m.triangles);
  ASSERT_EQ(w.size(), m.positions.size());
  double sum = 0.0;
  glm::dvec3 rebuilt(0.0);
  for (size_t i = 0; i < w.size(); ++i) {
    ASSERT_TRUE(std::isfinite(w[i]));
    sum += w[i];
    rebuilt += w[i] * glm::dvec3(m.positions[i]);
  }
  EXPECT_NEAR(sum, 1.0, kSumTol) << what;
  EXPECT_NEAR(glm::length(rebuilt - glm::dvec3(x)), 0.0, kReproduceTol)
      << what << " at " << x.x << " " << x.y << " " << x.z;
}

TEST(MeanValueCoordinates, ReproducePointsInACube) {
  const TriMesh cube = test::box_mesh({-1, -1, -1}, {1, 1, 1});
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> U(-0.999f, 0.999f);
  for (int i = 0; i < 200; ++i) expect_reproduces(cube, {U(rng), U(rng), U(rng)}, "random interior");
  expect_reproduces(cube, {0, 0, 0}, "centre");
  // Near and on the surface (the robust branches).
  expect_reproduces(cube, {1.0f - 1e-6f, 0.3f, -0.2f}, "1e-6 below a face");
  expect_reproduces(cube, {1.0f, 0.3f, -0.2f}, "on a face");
  expect_reproduces(cube, {1.0f, 1.0f, 0.5f}, "on an edge");
  expect_reproduces(cube, {0.25f, 0.25f, -1.0f}, "on a face, on a triangle's diagonal");
  const std::vector<double> at_vertex = mean_value_coordinates({1, 1, 1}, cube.positions, cube.triangles);
  EXPECT_EQ(at_vertex[7], 1.0);
}

TEST(MeanValueCoordinates, PositiveInsideAConvexMesh) {
  // MVC are positive inside convex polyhedra (Floater et al. 2005).
  const TriMesh cube = test::box_mesh({-1, -1, -1}, {1, 1, 1});
  const std::vector<double> w = mean_value_coordinates({0.2f, -0.4f, 0.7f}, cube.positions, cube.triangles);
  for (double x : w) EXPECT_GT(x, 0.0);
}

TEST(MeanValueCoordinates, ReproducePointsInANonConvexBlob) {
  const TriMesh blob = test::blob_mesh(24, 48);
  std::mt19937 rng(2);
  std::uniform_real_distribution<float> U(-0.6f, 0.6f);
  for (int i = 0; i < 30; ++i) expect_reproduces(blob, {U(rng), U(rng), U(rng)}, "blob interior");
  // Up in an ear (a lobe near +z) and close to a vertex of the surface.
  expect_reproduces(blob, {0.0f, 0.0f, 1.5f}, "in the lobe");
  const glm::vec3 v = blob.positions[200];
  expect_reproduces(blob, v * (1.0f - 1e-5f), "just inside a vertex");
}

TEST(MeanValueCoordinates, RejectsBadInput) {
  const TriMesh cube = test::box_mesh({-1, -1, -1}, {1, 1, 1});
  EXPECT_THROW(mean_value_coordinates({0, std::nanf(""), 0}, cube.positions, cube.triangles), std::invalid_argument);
  std::vector<glm::uvec3> bad = cube.triangles;
  bad[0].x = 100;
  EXPECT_THROW(mean_value_coordinates({0, 0, 0}, cube.positions, bad), std::invalid_argument);
  EXPECT_THROW(mean_value_coordinates({0, 0, 0}, {}, {}), std::invalid_argument);
}

// A bar along x from 0 to 2 with bone 0 on the left half and bone 1 on the right half, blended
// linearly over the middle station.
scene::Mesh two_bone_bar() {
  const TriMesh bar = test::bar_mesh(2.0f, 0.2f, 8);
  scene::Mesh m;
  m.name = "bar";
  m.positions = bar.positions;
  m.triangles = bar.triangles;
  for (const glm::vec3& p : m.positions) {
    const float w1 = std::clamp((p.x - 0.75f) / 0.5f, 0.0f, 1.0f);
    m.joints.push_back(glm::u16vec4(0, 1, 0, 0));
    m.weights.push_back(glm::vec4(1.0f - w1, w1, 0.0f, 0.0f));
    m.normals.push_back(glm::vec3(0, 1, 0));
  }
  return m;
}

TEST(BindToSkin, TwoBoneBar) {
  const scene::Mesh mesh = two_bone_bar();
  scene::ProxySet proxies;
  proxies.spheres = {{{0.2f, 0.0f, 0.0f}, 0.3f}, {{1.0f, 0.0f, 0.0f}, 0.3f}, {{1.8f, 0.05f, -0.05f}, 0.3f}};
  const double err = bind_to_skin(proxies, mesh);
  // Two bones only: nothing is dropped, so the reduction is exact.
  EXPECT_NEAR(err, 0.0, 1e-6);
  ASSERT_EQ(proxies.joints.size(), 3u);
  ASSERT_EQ(proxies.weights.size(), 3u);
  for (size_t i = 0; i < 3; ++i) {
    const glm::vec4 w = proxies.weights[i];
    EXPECT_NEAR(w.x + w.y + w.z + w.w, 1.0, 1e-6);
    for (int k = 0; k < 4; ++k) {
      EXPECT_GE(w[k], 0.0f);
      if (w[k] > 0.0f) {
        EXPECT_LE(proxies.joints[i][k], 1);
      }
    }
  }
  auto weight_of = [&](size_t i, int bone) {
    float s = 0.0f;
    for (int k = 0; k < 4; ++k)
      if (proxies.joints[i][k] == bone) s += proxies.weights[i][k];
    return s;
  };
  EXPECT_GT(weight_of(0, 0), 0.8f) << "a centre in the left half follows bone 0";
  EXPECT_GT(weight_of(2, 1), 0.8f) << "a centre in the right half follows bone 1";
  // The bar and its weights are mirror-symmetric about x = 1.
  EXPECT_NEAR(weight_of(1, 0), 0.5f, 1e-5);
  EXPECT_NEAR(weight_of(1, 1), 0.5f, 1e-5);
  // Translating bone 1 by t moves every vertex v by w_v1 t; the MVC-deformed centre moves by
  // sum_v mvc_v w_v1 t, which the bone weights must reproduce exactly.
  const glm::dvec3 t(0.3, -0.7, 0.2);
  for (size_t i = 0; i < 3; ++i) {
    const std::vector<double> mvc = mean_value_coordinates(proxies.spheres[i].center, mesh.positions, mesh.triangles);
    glm::dvec3 moved(0.0);
    for (size_t v = 0; v < mesh.positions.size(); ++v)
      moved += mvc[v] * (glm::dvec3(mesh.positions[v]) + static_cast<double>(mesh.weights[v].y) * t);
    const glm::dvec3 by_bones = glm::dvec3(proxies.spheres[i].center) + static_cast<double>(weight_of(i, 1)) * t;
    EXPECT_NEAR(glm::length(moved - by_bones), 0.0, 1e-5) << i;
  }
}

TEST(BindToSkin, ReducesToFourBones) {
  // Six bones with overlapping smooth falloffs along a bar: a centre sees all six.
  const TriMesh bar = test::bar_mesh(3.0f, 0.2f, 12);
  scene::Mesh mesh;
  mesh.name = "six-bone bar";
  mesh.positions = bar.positions;
  mesh.triangles = bar.triangles;
  for (const glm::vec3& p : mesh.positions) {
    // Each vertex: its 4 nearest bones (bone b centred at x = 0.25 + 0.5 b), weights by distance.
    std::vector<std::pair<float, int>> d;
    for (int b = 0; b < 6; ++b) d.emplace_back(std::abs(p.x - (0.25f + 0.5f * b)), b);
    std::sort(d.begin(), d.end());
    glm::vec4 w(0.0f);
    glm::u16vec4 j(0);
    for (int k = 0; k < 4; ++k) {
      j[k] = static_cast<std::uint16_t>(d[k].second);
      w[k] = 1.0f / (0.1f + d[k].first);
    }
    mesh.joints.push_back(j);
    mesh.weights.push_back(w / (w.x + w.y + w.z + w.w));
    mesh.normals.push_back(glm::vec3(0, 1, 0));
  }
  scene::ProxySet proxies;
  proxies.spheres = {{{1.5f, 0.0f, 0.0f}, 0.4f}, {{0.3f, 0.1f, 0.0f}, 0.2f}};
  const double err = bind_to_skin(proxies, mesh);
  EXPECT_GT(err, 0.0) << "six bones reduced to four cannot rebuild the centre exactly";
  EXPECT_LT(err, 0.25) << "dropping the two lightest bones moves the centre by a fraction of a bone spacing";
  for (size_t i = 0; i < 2; ++i) {
    const glm::vec4 w = proxies.weights[i];
    EXPECT_NEAR(w.x + w.y + w.z + w.w, 1.0, 1e-6);
    EXPECT_GE(w.x, w.y);
    EXPECT_GE(w.y, w.z);
    EXPECT_GE(w.z, w.w);
  }
  // The middle sphere follows the middle bones most.
  EXPECT_TRUE(proxies.joints[0].x == 2 || proxies.joints[0].x == 3);
}

TEST(BindToSkin, RejectsUnskinnedMeshes) {
  scene::Mesh mesh = two_bone_bar();
  scene::ProxySet proxies;
  proxies.spheres = {{{0.2f, 0.0f, 0.0f}, 0.3f}};
  scene::Mesh unskinned = mesh;
  unskinned.joints.clear();
  unskinned.weights.clear();
  EXPECT_THROW(bind_to_skin(proxies, unskinned), std::invalid_argument);
  scene::Mesh short_weights = mesh;
  short_weights.weights.pop_back();
  EXPECT_THROW(bind_to_skin(proxies, short_weights), std::invalid_argument);
  scene::Mesh zero = mesh;
  zero.weights[3] = glm::vec4(0.0f);
  EXPECT_THROW(bind_to_skin(proxies, zero), std::invalid_argument);
}

}  // namespace
}  // namespace softgi::proxies
