// Proxy sets fitted on demand: scene files' "proxies": {"fit": N}, --fit-proxies for bare glTF,
// the disk cache and its key, and the surface albedo the proxies re-radiate with.
#include <gtest/gtest.h>

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "softgi/io/proxy_fit.hpp"
#include "softgi/io/scene_file.hpp"
#include "softgi/scene/scene.hpp"
#include "test_support.hpp"

namespace io = softgi::io;
using softgi::scene::Scene;
using softgi::test::ScratchDir;

namespace {

using softgi::test::error_of;

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

std::string notices_of(const Scene& s) {
  std::string all;
  for (const auto& n : s.notices) all += n + "\n";
  return all;
}

io::LoadOptions cached_in(const ScratchDir& dir) {
  io::LoadOptions o;
  o.cache_dir = dir.file("cache");
  return o;
}

// Every vertex of the object's mesh is inside one of the set's spheres (the fit bounds the mesh).
void expect_bounds_mesh(const Scene& s, const softgi::scene::ProxySet& ps) {
  const auto& m = s.meshes[std::size_t(s.nodes[std::size_t(ps.node)].mesh)];
  for (const auto& p : m.positions) {
    bool inside = false;
    for (const auto& sp : ps.spheres) inside = inside || glm::length(p - sp.center) <= sp.radius * (1.0f + 1e-5f);
    ASSERT_TRUE(inside) << "vertex (" << p.x << ", " << p.y << ", " << p.z << ") outside every sphere";
  }
}

}  // namespace

TEST(io_proxy_fit, SceneFileFitBoundsTheObjectAndCachesIt) {
  ScratchDir dir;
  const std::string text = R"({"objects": [{"name": "floor", "mesh": "builtin:plane", "size": 4},
      {"name": "crate", "mesh": "builtin:box", "size": [1, 0.5, 0.5], "segments": 2, "proxies": {"fit": 3, "grid": 8}}]})";
  const Scene s = io::parse_scene_json(text, dir.path().string(), "s.json", cached_in(dir));
  ASSERT_EQ(s.proxies.size(), 1u);
  EXPECT_EQ(s.proxies[0].name, "crate");
  EXPECT_EQ(s.nodes[std::size_t(s.proxies[0].node)].name, "crate");
  EXPECT_GE(s.proxies[0].spheres.size(), 1u);
  EXPECT_LE(s.proxies[0].spheres.size(), 3u);
  EXPECT_EQ(s.proxies[0].sphere_albedo.size(), s.proxies[0].spheres.size());
  expect_bounds_mesh(s, s.proxies[0]);
  EXPECT_TRUE(contains(notices_of(s), "s.json: objects[1].proxies: fitted")) << notices_of(s);
  // The second load reads the entry the first wrote, and gets the same spheres.
  const Scene again = io::parse_scene_json(text, dir.path().string(), "s.json", cached_in(dir));
  EXPECT_TRUE(contains(notices_of(again), "from the cache")) << notices_of(again);
  ASSERT_EQ(again.proxies.size(), 1u);
  ASSERT_EQ(again.proxies[0].spheres.size(), s.proxies[0].spheres.size());
  for (std::size_t i = 0; i < s.proxies[0].spheres.size(); ++i) {
    EXPECT_EQ(again.proxies[0].spheres[i].center, s.proxies[0].spheres[i].center);
    EXPECT_EQ(again.proxies[0].spheres[i].radius, s.proxies[0].spheres[i].radius);
  }
  // Off, the object gets no proxies and a notice says so.
  io::LoadOptions off = cached_in(dir);
  off.fit_proxies = false;
  const Scene none = io::parse_scene_json(text, dir.path().string(), "s.json", off);
  EXPECT_TRUE(none.proxies.empty());
  EXPECT_TRUE(contains(notices_of(none), "skipped")) << notices_of(none);
}

TEST(io_proxy_fit, CorruptCacheEntryIsRefitted) {
  ScratchDir dir;
  const std::string text = R"({"objects": [{"name": "crate", "mesh": "builtin:box", "segments": 1, "proxies": {"fit": 2, "grid": 8}}]})";
  const Scene s = io::parse_scene_json(text, dir.path().string(), "s.json", cached_in(dir));
  std::vector<std::filesystem::path> entries;
  for (const auto& e : std::filesystem::recursive_directory_iterator(dir.file("cache")))
    if (e.is_regular_file()) entries.push_back(e.path());
  ASSERT_EQ(entries.size(), 1u);
  softgi::test::write_text(entries[0].string(), "{ not json");
  const Scene again = io::parse_scene_json(text, dir.path().string(), "s.json", cached_in(dir));
  EXPECT_TRUE(contains(notices_of(again), "fitted")) << notices_of(again);
  ASSERT_EQ(again.proxies.size(), 1u);
  EXPECT_EQ(again.proxies[0].spheres.size(), s.proxies[0].spheres.size());
  EXPECT_NO_THROW(io::read_proxies_json(entries[0].string()));  // replaced by a whole entry
}

TEST(io_proxy_fit, FitOfAnOpenSurfaceIsAnErrorNamingTheField) {
  const std::string e = error_of([] {
    io::LoadOptions o;
    o.cache_dir = "";
    io::parse_scene_json(R"({"objects": [{"name": "floor", "mesh": "builtin:plane", "proxies": {"fit": 4}}]})", ".", "s.json", o);
  });
  EXPECT_TRUE(contains(e, "s.json: objects[0].proxies: no mesh of object 'floor' is closed")) << e;
  EXPECT_TRUE(contains(error_of([] { io::parse_scene_json(R"({"objects": [{"mesh": "builtin:box", "proxies": {"fit": 0}}]})", ".", "s.json"); }),
                       "objects[0].proxies.fit"));
  EXPECT_TRUE(contains(error_of([] { io::parse_scene_json(R"({"objects": [{"mesh": "builtin:box", "proxies": {"fits": 3}}]})", ".", "s.json"); }),
                       "objects[0].proxies"));
}

// The key covers what the fit's result depends on, and nothing else.
TEST(io_proxy_fit, KeyChangesWithTheMeshTheTextureAndTheSpec) {
  Scene s = io::parse_scene_json(R"({"objects": [{"name": "crate", "mesh": "builtin:box", "segments": 2}]})", ".", "s.json");
  const io::ProxyFitSpec spec;
  const auto k0 = io::proxy_fit_key(s, 0, spec);
  EXPECT_EQ(io::proxy_fit_key(s, 0, spec), k0);
  io::ProxyFitSpec more = spec;
  more.spheres += 1;
  EXPECT_NE(io::proxy_fit_key(s, 0, more), k0);
  io::ProxyFitSpec seeded = spec;
  seeded.seed += 1;
  EXPECT_NE(io::proxy_fit_key(s, 0, seeded), k0);
  Scene moved = s;
  moved.meshes[0].positions[7].y += 1e-3f;
  EXPECT_NE(io::proxy_fit_key(moved, 0, spec), k0);
  Scene textured = s;
  textured.textures.push_back({"t", 1, 1, {glm::vec3(0.5f)}});
  textured.materials[std::size_t(textured.meshes[0].material)].albedo_texture = 0;
  const auto kt = io::proxy_fit_key(textured, 0, spec);
  EXPECT_NE(kt, k0);
  textured.textures[0].texels[0] = glm::vec3(0.25f);
  EXPECT_NE(io::proxy_fit_key(textured, 0, spec), kt);
  Scene placed = s;
  placed.nodes[0].translation.x += 3.0f;  // proxies live in the mesh's space
  EXPECT_EQ(io::proxy_fit_key(placed, 0, spec), k0);
}

// A textured surface re-radiates its texture's colours: the proxy albedo is the textured average,
// not the base colour factor. A 2x1 texture (red | blue), bilinear with repeat, averages to exactly
// the mean of its texels over each face's [0, 1]^2 UV square.
TEST(io_proxy_fit, AlbedoIsTheTexturedSurfaceAverage) {
  Scene s = io::parse_scene_json(R"({"objects": [{"name": "crate", "mesh": "builtin:box", "segments": 4}]})", ".", "s.json");
  s.textures.push_back({"rb", 2, 1, {glm::vec3(1, 0, 0), glm::vec3(0, 0, 1)}});
  s.materials[std::size_t(s.meshes[0].material)].albedo = glm::vec3(1.0f);
  s.materials[std::size_t(s.meshes[0].material)].albedo_texture = 0;
  softgi::scene::ProxySet ps;
  ps.node = 0;
  ps.spheres = {{glm::vec3(0.0f), 0.9f}};
  io::average_surface_albedo(s, 0, ps);
  // Tolerance: the per-triangle sample grid integrates the bilinear texture to ~1e-3 here.
  EXPECT_NEAR(ps.albedo.x, 0.5f, 2e-3f);
  EXPECT_NEAR(ps.albedo.y, 0.0f, 1e-6f);
  EXPECT_NEAR(ps.albedo.z, 0.5f, 2e-3f);
  ASSERT_EQ(ps.sphere_albedo.size(), 1u);
  EXPECT_NEAR(ps.sphere_albedo[0].x, 0.5f, 2e-3f);
}

// Each sphere takes the colour of the surface it stands for: an elongated box, red at x < 0 and blue
// at x > 0 (vertex colours), bounded by two spheres, one per half.
TEST(io_proxy_fit, EachSphereAveragesItsOwnSegment) {
  Scene s = io::parse_scene_json(R"({"objects": [{"name": "bar", "mesh": "builtin:box", "size": [4, 1, 1], "segments": 8}]})", ".",
                                 "s.json");
  auto& m = s.meshes[0];
  m.colors.clear();
  for (const auto& p : m.positions) m.colors.push_back(p.x < 0.0f ? glm::vec3(1, 0, 0) : glm::vec3(0, 0, 1));
  s.materials[std::size_t(m.material)].albedo = glm::vec3(1.0f);
  softgi::scene::ProxySet ps;
  ps.node = 0;
  ps.spheres = {{glm::vec3(-1.0f, 0, 0), 1.3f}, {glm::vec3(1.0f, 0, 0), 1.3f}};
  io::average_surface_albedo(s, 0, ps);
  ASSERT_EQ(ps.sphere_albedo.size(), 2u);
  // Closed form per half (area 9: four 2 x 1 sides and a 1 x 1 end). The vertices at x = 0 are blue,
  // so on each side of the left half three 0.5-wide columns are red and the column next to x = 0
  // blends linearly to blue (average 1/2): red = (4 (1.5 + 0.25) + 1) / 9 = 8/9, blue 1/9. The right
  // half is all blue. Linear colours are averaged exactly (float rounding only).
  EXPECT_NEAR(ps.sphere_albedo[0].x, 8.0f / 9.0f, 1e-5f);
  EXPECT_NEAR(ps.sphere_albedo[0].z, 1.0f / 9.0f, 1e-5f);
  EXPECT_NEAR(ps.sphere_albedo[1].z, 1.0f, 1e-5f);
  EXPECT_NEAR(ps.sphere_albedo[1].x, 0.0f, 1e-5f);
  // The set's albedo is the whole surface's: red 8 of 18 area units, blue 10.
  EXPECT_NEAR(ps.albedo.x, 4.0f / 9.0f, 1e-5f);
  EXPECT_NEAR(ps.albedo.z, 5.0f / 9.0f, 1e-5f);
}

// A bare glTF brings no proxies; --fit-proxies N (LoadOptions::fit_spheres) fits every closed mesh
// and says which meshes got none.
TEST(io_proxy_fit, BareGltfGetsProxiesForItsClosedMeshes) {
  ScratchDir dir;
  softgi::test::GltfBuilder b;
  // A tetrahedron (closed, outward winding) and a single open triangle.
  const int tp = b.floats({0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1}, "VEC3", 3);
  const int tn = b.floats({-0.577f, -0.577f, -0.577f, 1, 0, 0, 0, 1, 0, 0, 0, 1}, "VEC3", 3);
  const int ti = b.ushorts({0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3}, "SCALAR", 1);
  const int op = b.floats({2, 0, 0, 3, 0, 0, 2, 1, 0}, "VEC3", 3);
  const int on = b.floats({0, 0, 1, 0, 0, 1, 0, 0, 1}, "VEC3", 3);
  using nlohmann::json;
  const json tet = {{"attributes", {{"POSITION", tp}, {"NORMAL", tn}}}, {"indices", ti}};
  const json sheet = {{"attributes", {{"POSITION", op}, {"NORMAL", on}}}};
  b.doc["meshes"] = json::array({json{{"primitives", json::array({tet})}}, json{{"primitives", json::array({sheet})}}});
  b.doc["nodes"] = json::array({json{{"name", "tet"}, {"mesh", 0}}, json{{"name", "sheet"}, {"mesh", 1}}});
  b.doc["scenes"] = json::array({json{{"nodes", json::array({0, 1})}}});
  b.doc["scene"] = 0;
  b.write_glb(dir.file("m.glb"));
  io::LoadOptions opt = cached_in(dir);
  EXPECT_TRUE(io::load_scene(dir.file("m.glb"), opt).proxies.empty());
  opt.fit_spheres = 2;
  const Scene s = io::load_scene(dir.file("m.glb"), opt);
  ASSERT_EQ(s.proxies.size(), 1u);
  EXPECT_EQ(s.nodes[std::size_t(s.proxies[0].node)].name, "tet");
  expect_bounds_mesh(s, s.proxies[0]);
  const std::string n = notices_of(s);
  EXPECT_TRUE(contains(n, "fitted proxies to node")) << n;
  EXPECT_TRUE(contains(n, "no proxies fitted to node 1 'sheet'")) << n;
}
