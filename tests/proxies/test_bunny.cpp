// The variational fit on the real bunny (asset set, scripts/fetch-assets.sh): closed after welding,
// bounded, and far tighter than the octree at the same count (paper 004 Figure 4).
#include <gtest/gtest.h>

#include <filesystem>

#include "softgi/io/gltf.hpp"
#include "softgi/proxies/binding.hpp"
#include "softgi/proxies/sphere_fit.hpp"
#include "softgi/scene/builtin.hpp"

namespace softgi::proxies {
namespace {

TEST(BunnyAsset, FitBoundsItAndBeatsTheOctree) {
  const std::string path = scene::assets_dir() + "/models/bunny.glb";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << path << " is missing: run scripts/fetch-assets.sh";
  scene::Scene s;
  io::load_gltf(path, s);
  ASSERT_FALSE(s.meshes.empty());
  const TriMesh mesh = trimesh_of(s.meshes[0]);
  EXPECT_EQ(mesh.positions.size(), 2826u);
  EXPECT_EQ(mesh.triangles.size(), 5648u);
  EXPECT_GT(mesh_volume(mesh), 0.0);
  // A short fit keeps the test fast; the full measurement is in docs/proxies.md.
  FitOptions opt;
  opt.spheres = 16;
  opt.grid_resolution = 16;
  opt.max_iterations = 8;
  const FitResult r = fit_sphere_set(mesh, opt);
  for (const glm::vec3& v : mesh.positions) {
    bool in = false;
    for (const scene::Sphere& sp : r.spheres) in = in || glm::length(glm::dvec3(v) - glm::dvec3(sp.center)) <= sp.radius;
    ASSERT_TRUE(in) << "vertex " << v.x << " " << v.y << " " << v.z;
  }
  const double octree_E = outside_volume_ratio(octree_sphere_set(mesh, 16), mesh);
  EXPECT_LT(2.0 * r.E, octree_E) << "fit E " << r.E << ", octree E " << octree_E;
  // Mean value coordinates reproduce a fitted centre over the real mesh.
  const std::vector<double> w = mean_value_coordinates(r.spheres[0].center, mesh.positions, mesh.triangles);
  glm::dvec3 x(0.0);
  for (size_t i = 0; i < w.size(); ++i) x += w[i] * glm::dvec3(mesh.positions[i]);
  EXPECT_NEAR(glm::length(x - glm::dvec3(r.spheres[0].center)), 0.0, 1e-9);
}

}  // namespace
}  // namespace softgi::proxies
