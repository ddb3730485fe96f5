// The JSON scene file and proxy files (docs/scene_format.md): a complete file loads into exactly
// the values written; each kind of bad input gets an error naming the file, the JSON path and the value.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <glm/gtc/constants.hpp>
#include <glm/gtc/quaternion.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "softgi/image.hpp"
#include "softgi/io/image_io.hpp"
#include "softgi/io/scene_file.hpp"
#include "softgi/scene/builtin.hpp"
#include "softgi/scene/scene.hpp"
#include "test_support.hpp"

namespace {

using softgi::scene::Scene;
using softgi::test::GltfBuilder;
using softgi::test::ScratchDir;
using json = nlohmann::json;
namespace io = softgi::io;

// Values parsed from decimal text into float: exact when compared with the same literal as float.
constexpr float kExact = 0.0f;
// Rotations built from angles (euler_deg, cos/sin of float angles): a few float ulps.
constexpr float kRotationTolerance = 1e-6f;

template <typename F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "(no exception)";
}

// Parses `doc` as scene.json in `dir` and returns the error message.
std::string scene_error(const ScratchDir& dir, const json& doc) {
  softgi::test::write_text(dir.file("scene.json"), doc.dump(1));
  return error_of([&] { io::load_scene_file(dir.file("scene.json")); });
}
std::string text_error(const std::string& text) {
  return error_of([&] { io::parse_scene_json(text, ".", "scene.json"); });
}

#define EXPECT_CONTAINS(haystack, needle) \
  EXPECT_NE((haystack).find(needle), std::string::npos) << "message: " << (haystack) << "\nexpected to contain: " << (needle)

void write_quad_glb(const std::string& path, double node_y = 0.0) {
  GltfBuilder b;
  const int p = b.floats({-1, 0, -1, 1, 0, -1, 1, 0, 1, -1, 0, 1}, "VEC3", 3);
  const int n = b.floats({0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0}, "VEC3", 3);
  const int i = b.ushorts({0, 2, 1, 0, 3, 2}, "SCALAR", 1);
  b.doc["meshes"] = {{{"name", "quad"}, {"primitives", {{{"attributes", {{"POSITION", p}, {"NORMAL", n}}}, {"indices", i}}}}}};
  b.doc["nodes"] = {{{"name", "quad"}, {"mesh", 0}, {"translation", {0.0, node_y, 0.0}}}};
  b.write_glb(path);
}

json full_scene() {
  return json::parse(R"({
    "name": "test scene",
    "description": "one of everything",
    "camera": {"position": [0, 2, 5], "target": [0, 0.5, 0], "up": [0, 1, 0], "fov_y_deg": 40, "width": 320, "height": 200},
    "environment": {"sky": {"zenith": [0.1, 0.2, 0.9], "horizon": [0.7, 0.8, 0.9], "ground": [0.3, 0.3, 0.2],
                            "sun_direction": [0, 2, 0], "sun_radius_deg": 2, "sun_radiance": [40, 30, 20]},
                    "intensity": 1.5, "rotation_deg": 90},
    "objects": [
      {"name": "floor", "mesh": "builtin:plane", "size": [10, 6], "material": {"albedo": [0.5, 0.6, 0.7]}},
      {"name": "ball", "mesh": "builtin:sphere", "radius": 0.5, "segments": 16,
       "transform": {"translation": [0, 0.5, 0], "rotation": [0, 0, 0, 2], "scale": 2},
       "material": {"albedo": [0.9, 0.1, 0.1], "phong_ns": 32, "glossy": 0.25},
       "proxies": [{"center": [0, 0, 0], "radius": 0.5}, {"center": [0, 0.1, 0], "radius": 0.25}]},
      {"name": "crate", "mesh": "builtin:box", "size": [1, 2, 3], "transform": {"euler_deg": [0, 90, 0], "scale": [1, 2, 1]}},
      {"name": "quad", "mesh": "quad.glb", "transform": {"translation": [3, 0, 0]}, "material": {"albedo": [0.2, 0.2, 0.2]}}
    ],
    "lights": [{"name": "lamp", "position": [0, 3, 0], "radius": 0.2, "radiance": [20, 10, 5]},
               {"position": [0, 1, 0], "object": "ball"}],
    "animation": {"name": "bounce", "loop": false, "channels": [
      {"object": "ball", "path": "translation", "times": [0, 0.5, 1], "values": [[0, 0.5, 0], [0, 1.5, 0], [0, 0.5, 0]]},
      {"object": 2, "path": "rotation", "interpolation": "step", "times": [0, 2], "values": [[0, 0, 0, 1], [0, 0, 0, -3]]}]}
  })");
}

TEST(io_scene_file, FullSceneLoadsTheWrittenValues) {
  ScratchDir dir;
  write_quad_glb(dir.file("quad.glb"));
  softgi::test::write_text(dir.file("scene.json"), full_scene().dump(2));
  const Scene s = io::load_scene_file(dir.file("scene.json"));
  EXPECT_EQ(s.name, "test scene");
  EXPECT_EQ(s.source, dir.file("scene.json"));
  EXPECT_EQ(s.camera.position, glm::vec3(0, 2, 5));
  EXPECT_EQ(s.camera.target, glm::vec3(0, 0.5f, 0));
  EXPECT_EQ(s.camera.fov_y_deg, 40.0f);
  EXPECT_EQ(s.camera.width, 320);
  EXPECT_EQ(s.camera.height, 200);
  const auto& e = s.environment;
  EXPECT_EQ(e.kind, softgi::scene::Environment::Kind::Sky);
  EXPECT_EQ(e.zenith, glm::vec3(0.1f, 0.2f, 0.9f));
  EXPECT_EQ(e.sun_direction, glm::vec3(0, 1, 0));  // normalised
  EXPECT_NEAR(e.sun_radius, glm::radians(2.0f), kRotationTolerance);
  EXPECT_EQ(e.sun_radiance, glm::vec3(40, 30, 20));
  EXPECT_EQ(e.intensity, 1.5f);
  EXPECT_NEAR(e.rotation_y, glm::half_pi<float>(), kRotationTolerance);

  // Nodes: floor, ball, crate, quad (object), quad (glTF node under it).
  ASSERT_EQ(s.nodes.size(), 5u);
  EXPECT_EQ(s.nodes[1].name, "ball");
  EXPECT_EQ(s.nodes[1].translation, glm::vec3(0, 0.5f, 0));
  EXPECT_EQ(s.nodes[1].rotation, glm::quat(1, 0, 0, 0));  // [0, 0, 0, 2] normalised
  EXPECT_EQ(s.nodes[1].scale, glm::vec3(2));
  EXPECT_EQ(s.nodes[2].scale, glm::vec3(1, 2, 1));
  EXPECT_EQ(s.nodes[4].parent, 3);
  EXPECT_EQ(s.nodes[3].translation, glm::vec3(3, 0, 0));
  ASSERT_EQ(s.meshes.size(), 4u);
  glm::vec3 lo(1e9f), hi(-1e9f);
  for (const auto& p : s.meshes[std::size_t(s.nodes[0].mesh)].positions) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  EXPECT_EQ(lo, glm::vec3(-5, 0, -3));  // plane 10 x 6
  EXPECT_EQ(hi, glm::vec3(5, 0, 3));
  EXPECT_EQ(s.meshes[std::size_t(s.nodes[2].mesh)].positions.size(), 6u * 17u * 17u);  // box: 16 x 16 quads per face
  const auto& ball_mat = s.materials[std::size_t(s.meshes[std::size_t(s.nodes[1].mesh)].material)];
  EXPECT_EQ(ball_mat.albedo, glm::vec3(0.9f, 0.1f, 0.1f));
  EXPECT_EQ(ball_mat.phong_ns, 32.0f);
  EXPECT_EQ(ball_mat.glossy, 0.25f);
  EXPECT_EQ(s.materials[std::size_t(s.meshes[3].material)].albedo, glm::vec3(0.2f));  // override of a glTF material

  ASSERT_EQ(s.proxies.size(), 1u);
  EXPECT_EQ(s.proxies[0].node, 1);
  ASSERT_EQ(s.proxies[0].spheres.size(), 2u);
  EXPECT_EQ(s.proxies[0].spheres[1].center, glm::vec3(0, 0.1f, 0));
  EXPECT_EQ(s.proxies[0].spheres[1].radius, 0.25f);
  EXPECT_EQ(s.proxies[0].albedo, ball_mat.albedo);

  ASSERT_EQ(s.lights.size(), 2u);
  EXPECT_EQ(s.lights[0].name, "lamp");
  EXPECT_EQ(s.lights[0].radiance, glm::vec3(20, 10, 5));
  EXPECT_EQ(s.lights[1].node, 1);
  EXPECT_EQ(s.lights[1].radius, 0.1f);  // default

  ASSERT_EQ(s.clips.size(), 1u);
  EXPECT_EQ(s.active_clip, 0);
  const auto& clip = s.clips[0];
  EXPECT_EQ(clip.name, "bounce");
  EXPECT_FALSE(clip.loop);
  EXPECT_EQ(clip.duration, 2.0f);
  EXPECT_EQ(clip.channels[0].node, 1);
  EXPECT_EQ(clip.channels[0].values[1], glm::vec4(0, 1.5f, 0, 0));
  EXPECT_EQ(clip.channels[1].node, 2);
  EXPECT_EQ(clip.channels[1].interp, softgi::scene::AnimationChannel::Interp::Step);
  EXPECT_EQ(clip.channels[1].values[1], glm::vec4(0, 0, 0, -1));
}

TEST(io_scene_file, EmptyObjectIsAnEmptySceneWithDefaults) {
  const Scene s = io::parse_scene_json("{}", ".", "dir/empty.json");
  EXPECT_EQ(s.name, "empty");
  EXPECT_TRUE(s.meshes.empty() && s.nodes.empty() && s.lights.empty());
  EXPECT_EQ(s.active_clip, -1);
  const softgi::scene::Scene defaults;
  EXPECT_EQ(s.camera.position, defaults.camera.position);
  EXPECT_EQ(s.camera.width, defaults.camera.width);
  EXPECT_EQ(s.environment.kind, softgi::scene::Environment::Kind::Sky);
  EXPECT_EQ(s.environment.sun_radiance, defaults.environment.sun_radiance);
}

TEST(io_scene_file, EnvironmentMapIsRead) {
  ScratchDir dir;
  softgi::Image img(4, 2, glm::vec3(0.5f, 1.0f, 2.0f));
  img.at(3, 1) = glm::vec3(7.0f);
  softgi::io::write_exr(dir.file("env.exr"), img);
  const Scene s = io::parse_scene_json(R"({"environment": {"map": "env.exr", "intensity": 2, "rotation_deg": 180}})",
                                       dir.path().string(), "m.json");
  const auto& e = s.environment;
  EXPECT_EQ(e.kind, softgi::scene::Environment::Kind::Map);
  EXPECT_EQ(e.map_path, dir.file("env.exr"));
  ASSERT_EQ(e.map_width, 4);
  ASSERT_EQ(e.map_height, 2);
  EXPECT_EQ(e.map_rgb[0], 0.5f);
  EXPECT_EQ(e.map_rgb[3 * 7 + 2], 7.0f);  // pixel (3, 1)
  EXPECT_EQ(e.intensity, 2.0f);
  EXPECT_NEAR(e.rotation_y, glm::pi<float>(), kRotationTolerance);
  EXPECT_TRUE(s.notices.empty());
  // A negative texel (lossy HDR compression rings below zero) is clamped to 0 and noted, naming the map
  // (test_environment_file.cpp has the details).
  img.at(1, 0).y = -1.0f;
  softgi::io::write_exr(dir.file("neg.exr"), img);
  const Scene n = io::parse_scene_json(R"({"environment": {"map": "neg.exr"}})", dir.path().string(), "m.json");
  EXPECT_EQ(n.environment.map_rgb[3 * 1 + 1], 0.0f);
  ASSERT_EQ(n.notices.size(), 1u);
  EXPECT_CONTAINS(n.notices[0], "environment map '" + dir.file("neg.exr") + "': 1 negative pixel component (lowest -1 at pixel (1, 0))");
}

TEST(io_scene_file, EulerDegreesAreExtrinsicXYZ) {
  const Scene s = io::parse_scene_json(
      R"({"objects": [{"mesh": "builtin:box", "transform": {"euler_deg": [90, 90, 0]}}]})", ".", "e.json");
  // X first: +y -> +z; then Y by 90: +z -> +x.
  const glm::vec3 v = s.nodes[0].rotation * glm::vec3(0, 1, 0);
  EXPECT_NEAR(v.x, 1.0f, kRotationTolerance);
  EXPECT_NEAR(v.y, 0.0f, kRotationTolerance);
  EXPECT_NEAR(v.z, 0.0f, kRotationTolerance);
}

// Volume enclosed by a closed mesh (divergence theorem): positive only when every triangle faces out.
double signed_volume(const softgi::scene::Mesh& m) {
  double v = 0.0;
  for (const auto& t : m.triangles) {
    v += glm::dot(glm::dvec3(m.positions[t[0]]), glm::cross(glm::dvec3(m.positions[t[1]]), glm::dvec3(m.positions[t[2]]))) / 6.0;
  }
  return v;
}

TEST(io_scene_file, BuiltinMeshesAreClosedAndFaceOutwards) {
  const Scene s = io::parse_scene_json(R"({"objects": [
      {"mesh": "builtin:box", "size": [1, 2, 3]},
      {"mesh": "builtin:sphere", "radius": 2, "segments": 64},
      {"mesh": "builtin:plane", "size": 2}]})",
                                       ".", "b.json");
  // The divergence-theorem volume of the box is exact up to float rounding of the corners.
  constexpr double kVolumeRounding = 1e-6;
  EXPECT_NEAR(signed_volume(s.meshes[0]), 6.0, kVolumeRounding);
  // A 64 x 32 UV sphere inscribed in r = 2 loses about 1% of the ball's volume (chord sag); both
  // bounds fail when the winding is inverted (negative volume).
  const double ball = 4.0 / 3.0 * M_PI * 8.0;
  EXPECT_LT(signed_volume(s.meshes[1]), ball);
  EXPECT_GT(signed_volume(s.meshes[1]), 0.98 * ball);
  for (std::size_t i = 0; i < s.meshes[1].positions.size(); ++i) {
    EXPECT_NEAR(glm::length(s.meshes[1].positions[i] - 2.0f * s.meshes[1].normals[i]), 0.0f, 1e-5f);
  }
  for (const auto& t : s.meshes[2].triangles) {
    const auto& p = s.meshes[2].positions;
    EXPECT_GT(glm::cross(p[t[1]] - p[t[0]], p[t[2]] - p[t[0]]).y, 0.0f);
  }
}

TEST(io_scene_file, ProxiesJsonRoundTripIsExact) {
  ScratchDir dir;
  softgi::scene::ProxySet ps;
  ps.name = "rig";
  ps.node = 3;
  ps.albedo = glm::vec3(0.1f, 0.7f, 0.3f);
  ps.outside_volume_ratio = 0.125;
  ps.spheres = {{glm::vec3(0.1f, -2.5f, 1e-3f), 0.3f}, {glm::vec3(1.0f / 3.0f, 2.0f, 0.0f), 1.7f}};
  ps.joints = {glm::u16vec4(0, 1, 0, 0), glm::u16vec4(2, 0, 0, 0)};
  ps.weights = {glm::vec4(0.25f, 0.75f, 0, 0), glm::vec4(1, 0, 0, 0)};
  io::write_proxies_json(dir.file("p.json"), ps);
  const auto back = io::read_proxies_json(dir.file("p.json"));
  EXPECT_EQ(back.name, ps.name);
  EXPECT_EQ(back.node, ps.node);
  EXPECT_EQ(back.albedo, ps.albedo);
  EXPECT_EQ(back.outside_volume_ratio, ps.outside_volume_ratio);
  ASSERT_EQ(back.spheres.size(), 2u);
  for (int i = 0; i < 2; ++i) {
    EXPECT_EQ(back.spheres[i].center, ps.spheres[i].center);
    EXPECT_NEAR(back.spheres[i].radius, ps.spheres[i].radius, kExact);
  }
  EXPECT_EQ(back.joints, ps.joints);
  EXPECT_EQ(back.weights, ps.weights);
  EXPECT_FALSE(std::filesystem::exists(dir.file("p.json.tmp")));
}

TEST(io_scene_file, ProxyFileIsAttachedToItsObject) {
  ScratchDir dir;
  write_quad_glb(dir.file("quad.glb"));
  softgi::scene::ProxySet ps;
  ps.spheres = {{glm::vec3(0.0f), 1.5f}};
  ps.albedo = glm::vec3(0.5f);
  std::filesystem::create_directories(dir.path() / "proxies");
  io::write_proxies_json(dir.file("proxies/quad.json"), ps);
  const Scene s = io::parse_scene_json(
      R"({"objects": [{"mesh": "builtin:plane"}, {"name": "q", "mesh": "quad.glb", "proxies": "proxies/quad.json"}]})",
      dir.path().string(), "s.json");
  ASSERT_EQ(s.proxies.size(), 1u);
  EXPECT_EQ(s.proxies[0].name, "q");
  EXPECT_EQ(s.proxies[0].node, 2);  // the glTF mesh node under object node 1
  EXPECT_EQ(s.nodes[2].mesh, 1);
  EXPECT_EQ(s.proxies[0].spheres[0].radius, 1.5f);
}

TEST(io_scene_file, ProxyFileNodeSelectsAmongTheFilesMeshNodes) {
  ScratchDir dir;
  GltfBuilder b;
  const int p = b.floats({-1, 0, 0, 1, 0, 0, 0, 1, 0}, "VEC3", 3);
  const int n = b.floats({0, 0, 1, 0, 0, 1, 0, 0, 1}, "VEC3", 3);
  b.doc["meshes"] = {{{"primitives", {{{"attributes", {{"POSITION", p}, {"NORMAL", n}}}}}}}};
  b.doc["nodes"] = {{{"name", "first"}, {"mesh", 0}}, {{"name", "second"}, {"mesh", 0}}};
  b.write_glb(dir.file("two.glb"));
  softgi::scene::ProxySet ps;
  ps.spheres = {{glm::vec3(0.0f), 1.0f}};
  ps.node = 1;  // "second", as fit-proxies numbers the file's nodes
  io::write_proxies_json(dir.file("second.json"), ps);
  const Scene s = io::parse_scene_json(R"({"objects": [{"mesh": "builtin:box"}, {"mesh": "two.glb", "proxies": "second.json"}]})",
                                       dir.path().string(), "s.json");
  ASSERT_EQ(s.proxies.size(), 1u);
  EXPECT_EQ(s.nodes[std::size_t(s.proxies[0].node)].name, "second");
}

TEST(io_scene_file, GltfClipChosenByNameOrIndex) {
  ScratchDir dir;
  GltfBuilder b;
  const int p = b.floats({-1, 0, 0, 1, 0, 0, 0, 1, 0}, "VEC3", 3);
  const int n = b.floats({0, 0, 1, 0, 0, 1, 0, 0, 1}, "VEC3", 3);
  const int t = b.floats({0, 1}, "SCALAR", 1);
  const int v = b.floats({0, 0, 0, 0, 1, 0}, "VEC3", 3);
  b.doc["meshes"] = {{{"primitives", {{{"attributes", {{"POSITION", p}, {"NORMAL", n}}}}}}}};
  b.doc["nodes"] = {{{"mesh", 0}}};
  b.doc["animations"] = {
      {{"name", "hop"},
       {"channels", {{{"sampler", 0}, {"target", {{"node", 0}, {"path", "translation"}}}}}},
       {"samplers", {{{"input", t}, {"output", v}}}}},
      {{"name", "slide"},
       {"channels", {{{"sampler", 0}, {"target", {{"node", 0}, {"path", "translation"}}}}}},
       {"samplers", {{{"input", t}, {"output", v}}}}}};
  b.write_glb(dir.file("tri.glb"));
  Scene s = io::parse_scene_json(R"({"objects": [{"mesh": "tri.glb"}], "animation": {"clip": "slide", "loop": false}})",
                                 dir.path().string(), "s.json");
  EXPECT_EQ(s.active_clip, 1);
  EXPECT_FALSE(s.clips[1].loop);
  s = io::parse_scene_json(R"({"objects": [{"mesh": "tri.glb"}], "animation": {"clip": 0}})", dir.path().string(), "s.json");
  EXPECT_EQ(s.active_clip, 0);
  // Without "animation" the scene is static even when the file has clips.
  s = io::parse_scene_json(R"({"objects": [{"mesh": "tri.glb"}]})", dir.path().string(), "s.json");
  EXPECT_EQ(s.active_clip, -1);
  const std::string e = error_of([&] {
    io::parse_scene_json(R"({"objects": [{"mesh": "tri.glb"}], "animation": {"clip": "run"}})", dir.path().string(), "s.json");
  });
  EXPECT_CONTAINS(e, "s.json: animation.clip: expected the name of a clip (hop, slide), got \"run\"");
  // The same file twice: two clips called "hop"; the name no longer says which.
  const std::string amb = error_of([&] {
    io::parse_scene_json(R"({"objects": [{"mesh": "tri.glb"}, {"name": "b", "mesh": "tri.glb"}], "animation": {"clip": "hop"}})",
                         dir.path().string(), "s.json");
  });
  EXPECT_CONTAINS(amb, "s.json: animation.clip: the name is ambiguous: clips 0, 2 are all called so");
  s = io::parse_scene_json(R"({"objects": [{"mesh": "tri.glb"}, {"name": "b", "mesh": "tri.glb"}], "animation": {"clip": 2}})",
                           dir.path().string(), "s.json");
  EXPECT_EQ(s.active_clip, 2);
}

// Built-in planes and boxes are grids (per-vertex receivers need vertices where shadows fall):
// (n + 1)^2 vertices and 2 n^2 triangles per face, every triangle facing along its face normal,
// the face area preserved.
TEST(io_scene_file, BuiltinPlaneAndBoxAreTessellated) {
  for (auto [kind, n, faces] : {std::tuple<const char*, int, int>{"plane", 5, 1}, {"box", 3, 6}, {"plane", 64, 1}}) {
    const std::string seg = n == 64 ? "" : ", \"segments\": " + std::to_string(n);
    const Scene s = io::parse_scene_json(std::string(R"({"objects": [{"mesh": "builtin:)") + kind + "\", \"size\": 2" + seg + "}]}", ".",
                                         "s.json");
    ASSERT_EQ(s.meshes.size(), 1u);
    const auto& m = s.meshes[0];
    EXPECT_EQ(m.positions.size(), std::size_t(faces * (n + 1) * (n + 1))) << kind;
    EXPECT_EQ(m.triangles.size(), std::size_t(faces * 2 * n * n)) << kind;
    double area = 0.0;
    for (const auto& t : m.triangles) {
      const glm::vec3 c = glm::cross(m.positions[t.y] - m.positions[t.x], m.positions[t.z] - m.positions[t.x]);
      area += 0.5 * glm::length(c);
      EXPECT_GT(glm::dot(c, m.normals[t.x]), 0.0f) << kind << ": a triangle faces against its normal";
    }
    EXPECT_NEAR(area, 4.0 * faces, 1e-4 * faces) << kind;  // 2 x 2 faces; float rounding of the grid
  }
  EXPECT_CONTAINS(error_of([] { io::parse_scene_json(R"({"objects": [{"mesh": "builtin:plane", "segments": 0}]})", ".", "s.json"); }),
                  "s.json: objects[0].segments");
}

TEST(io_scene_file, RelativePathsResolveAgainstTheSceneFile) {
  ScratchDir dir;
  std::filesystem::create_directories(dir.path() / "scenes" / "meshes");
  write_quad_glb(dir.file("scenes/meshes/quad.glb"));
  softgi::test::write_text(dir.file("scenes/s.json"), R"({"objects": [{"mesh": "meshes/quad.glb"}]})");
  const Scene s = io::load_scene_file(dir.file("scenes/s.json"));
  EXPECT_EQ(s.meshes.size(), 1u);
  EXPECT_EQ(s.name, "s");
}

// ---- one test per kind of error: file, JSON path and value in the message ----

TEST(io_scene_file, NonFiniteNumber) {
  const std::string e = text_error(R"({"objects": [{"mesh": "builtin:plane", "transform": {"translation": [0, "nan", 0]}}]})");
  EXPECT_CONTAINS(e, "scene.json: objects[0].transform.translation[1]: expected a finite number");
  EXPECT_CONTAINS(e, "got \"nan\"");
  // Overflowing literals are rejected by the JSON reader itself (no path known yet), naming the value.
  EXPECT_CONTAINS(text_error(R"({"camera": {"fov_y_deg": 1e999}})"), "scene.json: invalid JSON: number overflow parsing '1e999'");
}

TEST(io_scene_file, NumberOutOfRange) {
  EXPECT_CONTAINS(text_error(R"({"camera": {"fov_y_deg": 200}})"),
                  "scene.json: camera.fov_y_deg: expected a number in (0, 179], got 200");
  EXPECT_CONTAINS(text_error(R"({"objects": [{"mesh": "builtin:box", "material": {"albedo": [0.5, 1.5, 0]}}]})"),
                  "scene.json: objects[0].material.albedo[1]: expected a number in [0, 1], got 1.5");
  EXPECT_CONTAINS(text_error(R"({"lights": [{"position": [0, 1, 0], "radius": -1}]})"),
                  "scene.json: lights[0].radius: expected a number in (0, 1000000], got -1");
}

TEST(io_scene_file, WrongType) {
  EXPECT_CONTAINS(text_error(R"({"camera": {"width": "wide"}})"),
                  "scene.json: camera.width: expected an integer in [1, 16384], got \"wide\"");
  EXPECT_CONTAINS(text_error(R"({"objects": {"mesh": "builtin:box"}})"),
                  "scene.json: objects: expected an array, got an object with 1 key");
  EXPECT_CONTAINS(text_error(R"({"objects": [{"mesh": "builtin:sphere", "segments": 3.5}]})"),
                  "scene.json: objects[0].segments: expected an integer in [3, 1024], got 3.5");
  EXPECT_CONTAINS(text_error("[1, 2]"), "scene.json: expected an object, got an array of 2 elements");
}

TEST(io_scene_file, UnknownKeyWithSuggestion) {
  const std::string e = text_error(R"({"objects": [{"mesh": "builtin:plane", "tranform": {}}]})");
  EXPECT_CONTAINS(e, "scene.json: objects[0].tranform: unknown key \"tranform\" (did you mean \"transform\"?)");
  EXPECT_CONTAINS(text_error(R"({"environment": {"sky": {"sun_radius": 2}}})"),
                  "scene.json: environment.sky.sun_radius: unknown key \"sun_radius\"");
}

TEST(io_scene_file, DuplicateKey) {
  EXPECT_CONTAINS(text_error(R"({"objects": [{"mesh": "builtin:plane"}, {"mesh": "builtin:box", "mesh": "builtin:plane"}]})"),
                  "scene.json: objects[1]: duplicate key \"mesh\"");
}

TEST(io_scene_file, AbsurdSizes) {
  EXPECT_CONTAINS(text_error(R"({"camera": {"width": 100000, "height": 10}})"),
                  "scene.json: camera.width: expected an integer in [1, 16384], got 100000");
  json doc;
  doc["objects"] = json::array();
  for (int i = 0; i < 10001; ++i) doc["objects"].push_back({{"mesh", "builtin:plane"}});
  EXPECT_CONTAINS(text_error(doc.dump()), "scene.json: objects: expected an array of 0 to 10000 elements, got an array of 10001 elements");
  EXPECT_CONTAINS(text_error(R"({"objects": [{"mesh": "builtin:sphere", "segments": 100000}]})"),
                  "scene.json: objects[0].segments: expected an integer in [3, 1024], got 100000");
  EXPECT_CONTAINS(text_error(std::string(100, '[') + std::string(100, ']')), "scene.json: ");
  EXPECT_CONTAINS(text_error(std::string(100, '[') + std::string(100, ']')), "JSON nested deeper than 64 levels");
}

TEST(io_scene_file, MissingRequiredKey) {
  EXPECT_CONTAINS(text_error(R"({"objects": [{"name": "a"}]})"), "scene.json: objects[0]: missing key \"mesh\"");
  EXPECT_CONTAINS(text_error(R"({"lights": [{"radius": 1}]})"), "scene.json: lights[0]: missing key \"position\"");
}

TEST(io_scene_file, SyntaxErrorGivesLineAndColumn) {
  const std::string e = text_error("{\n  \"objects\": [\n    {\"mesh\": \"builtin:plane\",}\n  ]\n}");
  EXPECT_CONTAINS(e, "scene.json: invalid JSON: parse error at line 3, column");
}

TEST(io_scene_file, MissingMeshFile) {
  ScratchDir dir;
  const std::string e = scene_error(dir, json::parse(R"({"objects": [{"mesh": "meshes/gone.glb"}]})"));
  EXPECT_CONTAINS(e, dir.file("scene.json") + ": objects[0].mesh: ");
  EXPECT_CONTAINS(e, "meshes/gone.glb: no such file");
}

TEST(io_scene_file, MissingSceneFile) {
  ScratchDir dir;
  EXPECT_CONTAINS(error_of([&] { io::load_scene_file(dir.file("none.json")); }), "none.json: no such file");
}

TEST(io_scene_file, BadMeshSpecification) {
  EXPECT_CONTAINS(text_error(R"({"objects": [{"mesh": "builtin:torus"}]})"),
                  "scene.json: objects[0].mesh: expected a glTF/GLB path or builtin:plane, builtin:sphere, builtin:box, got \"builtin:torus\"");
  EXPECT_CONTAINS(text_error(R"({"objects": [{"mesh": "builtin:plane", "radius": 2}]})"),
                  "scene.json: objects[0].radius: only meshes builtin:sphere take \"radius\" (mesh is \"builtin:plane\")");
  EXPECT_CONTAINS(text_error(R"({"objects": [{"mesh": "builtin:box", "size": [1, 0, 1]}]})"),
                  "scene.json: objects[0].size[1]: expected a number in (0, 1000000], got 0");
}

TEST(io_scene_file, ConflictingAlternatives) {
  EXPECT_CONTAINS(text_error(R"({"objects": [{"mesh": "builtin:box", "transform": {"rotation": [0, 0, 0, 1], "euler_deg": [0, 0, 0]}}]})"),
                  "scene.json: objects[0].transform: give \"rotation\" or \"euler_deg\", not both");
  EXPECT_CONTAINS(text_error(R"({"environment": {"sky": {}, "map": "x.exr"}})"),
                  "scene.json: environment: expected exactly one of \"sky\" or \"map\"");
  EXPECT_CONTAINS(text_error(R"({"environment": {"intensity": 2}})"),
                  "scene.json: environment: expected exactly one of \"sky\" or \"map\"");
  EXPECT_CONTAINS(text_error(R"({"objects": [{"mesh": "builtin:box", "transform": {"rotation": [0, 0, 0, 0]}}]})"),
                  "scene.json: objects[0].transform.rotation: expected a non-zero quaternion (x, y, z, w), got an array of 4 elements");
}

TEST(io_scene_file, BadReferences) {
  EXPECT_CONTAINS(text_error(R"({"objects": [{"name": "a", "mesh": "builtin:box"}], "lights": [{"position": [0, 1, 0], "object": "b"}]})"),
                  "scene.json: lights[0].object: expected the name of an object (a), got \"b\"");
  EXPECT_CONTAINS(text_error(R"({"objects": [{"name": "a", "mesh": "builtin:box"}, {"name": "a", "mesh": "builtin:box"}]})"),
                  "scene.json: objects[1].name: duplicate object name, got \"a\"");
  EXPECT_CONTAINS(text_error(R"({"objects": [{"mesh": "builtin:box"}], "animation": {"clip": 0}})"),
                  "scene.json: animation.clip: no glTF file in the scene has animations, got 0");
}

TEST(io_scene_file, KeyframesMustIncrease) {
  EXPECT_CONTAINS(
      text_error(R"({"objects": [{"name": "a", "mesh": "builtin:box"}], "animation": {"channels": [
        {"object": "a", "path": "translation", "times": [0, 1, 1], "values": [[0, 0, 0], [1, 0, 0], [2, 0, 0]]}]}})"),
      "scene.json: animation.channels[0].times[2]: expected a time greater than the previous key's 1, got 1");
  EXPECT_CONTAINS(
      text_error(R"({"objects": [{"name": "a", "mesh": "builtin:box"}], "animation": {"channels": [
        {"object": "a", "path": "translation", "times": [0, 1], "values": [[0, 0, 0]]}]}})"),
      "scene.json: animation.channels[0].values: expected an array of 2 elements, got an array of 1 element");
}

TEST(io_scene_file, ProxyFileErrorsNameBothFiles) {
  ScratchDir dir;
  softgi::test::write_text(dir.file("p.json"), R"({"format": "softgi-proxies", "version": 1, "spheres": [{"center": [0, 0, 0], "radius": -1}]})");
  const std::string e = scene_error(dir, json::parse(R"({"objects": [{"mesh": "builtin:sphere", "proxies": "p.json"}]})"));
  EXPECT_CONTAINS(e, dir.file("scene.json") + ": objects[0].proxies: " + dir.file("p.json") +
                         ": spheres[0].radius: expected a number in (0, 1000000], got -1");
  softgi::test::write_text(dir.file("q.json"), R"({"version": 1, "spheres": []})");
  EXPECT_CONTAINS(error_of([&] { io::read_proxies_json(dir.file("q.json")); }), "q.json: missing key \"format\"");
}

TEST(io_scene_file, ValidationErrorsNameTheFile) {
  ScratchDir dir;
  write_quad_glb(dir.file("far.glb"), 2e6);  // a node 2000 km away: scene::validate rejects it
  const std::string e = scene_error(dir, json::parse(R"({"objects": [{"mesh": "far.glb"}]})"));
  EXPECT_CONTAINS(e, dir.file("scene.json") + ": node 'quad'");
  EXPECT_CONTAINS(e, "translation");
}

TEST(io_scene_file, LoadSceneDispatches) {
  ScratchDir dir;
  // Built-in names, with and without the prefix.
  const auto builtins = softgi::scene::builtin_scenes();
  for (const auto& b : builtins) {
    if (b.needs_assets) continue;
    EXPECT_EQ(io::load_scene(b.name).name, softgi::scene::make_builtin(b.name).name);
    EXPECT_EQ(io::load_scene("builtin:" + b.name).name, softgi::scene::make_builtin(b.name).name);
    break;
  }
  // A scene file and a bare GLB.
  write_quad_glb(dir.file("quad.glb"));
  softgi::test::write_text(dir.file("one.json"), R"({"name": "one", "objects": [{"mesh": "quad.glb"}]})");
  EXPECT_EQ(io::load_scene(dir.file("one.json")).name, "one");
  const Scene g = io::load_scene(dir.file("quad.glb"));
  EXPECT_EQ(g.meshes.size(), 1u);
  EXPECT_EQ(g.camera.target, glm::vec3(0.0f));  // framed on the quad's centre
  // Unknown: the error lists the built-ins.
  const std::string e = error_of([] { io::load_scene("no_such_scene"); });
  EXPECT_CONTAINS(e, "unknown scene 'no_such_scene'");
  if (!builtins.empty()) {
    EXPECT_CONTAINS(e, builtins.front().name);
  }
}

}  // namespace
