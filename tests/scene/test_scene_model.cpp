// Tests of the scene model (core/src/scene/scene.cpp): validation messages, posing (hierarchy,
// keyframes, slerp, looping, skinning), environment lookups and their SH projection.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include "softgi/scene/scene.hpp"
#include "softgi/sh/quadrature.hpp"
#include "softgi/sh/sh.hpp"

namespace {

namespace scene = softgi::scene;
namespace sh = softgi::sh;
using glm::vec3;
using glm::vec4;

// --- Tolerances ---------------------------------------------------------------------------------
// Posing runs in float: a handful of 4x4 products on O(1) coordinates, ~1e-7 each.
constexpr float kPoseTol = 1e-5f;
// Rotation angles recovered from float quaternions: acos near 1 loses half the digits of float.
constexpr float kAngleTolRad = 1e-3f;
// Lat-long lookup at a pixel centre returns that texel: the direction passes through float, so the
// neighbours' bilinear weights are ~1e-5 (x ~ 64 pixels times a float rounding), times texel
// differences of at most 4 (times intensity 2).
constexpr float kTexelTol = 1e-3f;
// Sky SH against closed forms: the quadrature is exact for these integrands; what remains is float
// output rounding of O(1)..O(10) coefficients (relative 1e-7) and double accumulation.
constexpr float kShExactRel = 1e-5f;
// Sky SH against an independent midpoint rule (2048 y-rows split at the horizon x 256 azimuths):
// the midpoint rule's error is O(h^2) ~ 1e-6 for the smooth gradient.
constexpr float kShMidpointTol = 1e-4f;
// A piecewise-constant 256 x 128 map of a linear function projects to its band-1 coefficients with
// an O(pixel^2) error; ~1e-4 here, 2e-3 leaves margin without hiding a wrong rotation direction
// (which gives O(0.1) errors for the 0.7 rad turn used).
constexpr float kMapShTol = 2e-3f;

// A small valid scene: a unit right triangle pair (a quad) on a node, one material.
scene::Scene quad_scene() {
  scene::Scene s;
  s.name = "quad";
  scene::Mesh m;
  m.name = "quad";
  m.positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  m.normals = std::vector<vec3>(4, vec3(0, 0, 1));
  m.triangles = {{0, 1, 2}, {0, 2, 3}};
  s.meshes.push_back(m);
  s.materials.push_back(scene::Material{});
  scene::Node n;
  n.name = "quad_node";
  n.mesh = 0;
  s.nodes.push_back(n);
  return s;
}

void expect_invalid(const scene::Scene& s, const std::vector<std::string>& needles, const std::string& label) {
  try {
    scene::validate(s);
    ADD_FAILURE() << label << ": validate() accepted the scene";
  } catch (const std::invalid_argument& e) {
    const std::string msg = e.what();
    for (const auto& n : needles) EXPECT_NE(msg.find(n), std::string::npos) << label << ": message lacks '" << n << "': " << msg;
  }
}

TEST(SceneValidate, AcceptsValidScene) { EXPECT_NO_THROW(scene::validate(quad_scene())); }

TEST(SceneValidate, RejectsEachKindOfBadInput) {
  struct Case {
    const char* label;
    std::function<void(scene::Scene&)> mutate;
    std::vector<std::string> needles;
  };
  const float nan = std::nanf("");
  const float inf = INFINITY;
  const std::vector<Case> cases = {
      {"index out of range", [](scene::Scene& s) { s.meshes[0].triangles[1] = {0, 2, 7}; }, {"mesh 'quad'", "triangle 1", "7", "out of range"}},
      {"NaN position", [&](scene::Scene& s) { s.meshes[0].positions[2].y = nan; }, {"mesh 'quad'", "positions[2]", "nan", "not finite"}},
      {"Inf normal", [&](scene::Scene& s) { s.meshes[0].normals[1].x = inf; }, {"normals[1]", "inf", "not finite"}},
      {"non-unit normal", [](scene::Scene& s) { s.meshes[0].normals[3] = vec3(0, 0, 0.5f); }, {"normals[3]", "length 0.5"}},
      {"zero-area triangle", [](scene::Scene& s) { s.meshes[0].positions[2] = vec3(0.5f, 0, 0); s.meshes[0].positions[3] = vec3(0, 1, 0); },
       {"mesh 'quad'", "triangle 0", "zero area"}},
      {"repeated index", [](scene::Scene& s) { s.meshes[0].triangles[1] = {0, 2, 2}; }, {"triangle 1", "(0, 2, 2)", "zero area"}},
      {"absurd coordinate", [](scene::Scene& s) { s.meshes[0].positions[1].x = 3e6f; }, {"positions[1]", "3e+06", "absurd"}},
      {"normal count", [](scene::Scene& s) { s.meshes[0].normals.pop_back(); }, {"4 positions but 3 normals"}},
      {"no triangles", [](scene::Scene& s) { s.meshes[0].triangles.clear(); }, {"mesh 'quad'", "no triangles"}},
      {"material index", [](scene::Scene& s) { s.meshes[0].material = 3; }, {"material 3", "out of range"}},
      {"albedo above 1", [](scene::Scene& s) { s.materials[0].albedo = vec3(1.5f, 0.2f, 0.2f); }, {"material 'default'", "albedo", "1.5"}},
      {"node mesh", [](scene::Scene& s) { s.nodes[0].mesh = 4; }, {"node 'quad_node'", "mesh 4"}},
      {"node NaN translation", [&](scene::Scene& s) { s.nodes[0].translation.z = nan; }, {"node 'quad_node'", "translation"}},
      {"zero scale", [](scene::Scene& s) { s.nodes[0].scale = vec3(1, 0, 1); }, {"node 'quad_node'", "scale (1, 0, 1)"}},
      {"parent cycle",
       [](scene::Scene& s) {
         scene::Node a, b;
         a.name = "a";
         b.name = "b";
         a.parent = 2;
         b.parent = 1;
         s.nodes.push_back(a);
         s.nodes.push_back(b);
       },
       {"node 'a'", "cycle"}},
      {"weights do not sum to 1",
       [](scene::Scene& s) {
         s.meshes[0].joints = std::vector<glm::u16vec4>(4, glm::u16vec4(0));
         s.meshes[0].weights = std::vector<vec4>(4, vec4(1, 0, 0, 0));
         s.meshes[0].weights[2] = vec4(0.5f, 0.2f, 0, 0);
       },
       {"weights[2]", "sums to 0.7"}},
      {"keyframe times",
       [](scene::Scene& s) {
         scene::AnimationClip c;
         c.name = "clip";
         c.duration = 1;
         scene::AnimationChannel ch;
         ch.node = 0;
         ch.times = {0.0f, 0.5f, 0.5f};
         ch.values = {vec4(0), vec4(1), vec4(2)};
         c.channels.push_back(ch);
         s.clips.push_back(c);
       },
       {"clip 'clip'", "channel 0", "times[2] = 0.5", "strictly increase"}},
      {"rotation key not unit",
       [](scene::Scene& s) {
         scene::AnimationClip c;
         c.name = "spin";
         scene::AnimationChannel ch;
         ch.node = 0;
         ch.path = scene::AnimationChannel::Path::Rotation;
         ch.times = {0.0f};
         ch.values = {vec4(0, 0, 0, 2)};
         c.channels.push_back(ch);
         s.clips.push_back(c);
       },
       {"clip 'spin'", "values[0]", "unit quaternion"}},
      {"active clip", [](scene::Scene& s) { s.active_clip = 2; }, {"active_clip 2", "out of range"}},
      {"proxy radius",
       [](scene::Scene& s) {
         scene::ProxySet p;
         p.name = "blockers";
         p.node = 0;
         p.spheres = {{vec3(0), 0.5f}, {vec3(1), -0.1f}};
         s.proxies.push_back(p);
       },
       {"proxy set 'blockers'", "spheres[1].radius -0.1"}},
      {"proxy NaN centre",
       [&](scene::Scene& s) {
         scene::ProxySet p;
         p.name = "blockers";
         p.spheres = {{vec3(0, nan, 0), 0.5f}};
         s.proxies.push_back(p);
       },
       {"proxy set 'blockers'", "spheres[0].center"}},
      {"camera fov", [](scene::Scene& s) { s.camera.fov_y_deg = 180.0f; }, {"camera", "fov_y_deg 180"}},
      {"camera target", [](scene::Scene& s) { s.camera.target = s.camera.position; }, {"camera", "equals position"}},
      {"environment map size",
       [](scene::Scene& s) {
         s.environment.kind = scene::Environment::Kind::Map;
         s.environment.map_path = "sky.exr";
         s.environment.map_width = 4;
         s.environment.map_height = 2;
         s.environment.map_rgb.assign(20, 1.0f);
       },
       {"environment map 'sky.exr'", "20 floats", "4x2x3"}},
      {"environment map NaN",
       [&](scene::Scene& s) {
         s.environment.kind = scene::Environment::Kind::Map;
         s.environment.map_path = "sky.exr";
         s.environment.map_width = 4;
         s.environment.map_height = 2;
         s.environment.map_rgb.assign(24, 1.0f);
         s.environment.map_rgb[3 * 5 + 1] = nan;
       },
       {"environment map 'sky.exr'", "pixel (1, 1) channel 1", "nan"}},
      {"sun direction", [](scene::Scene& s) { s.environment.sun_direction = vec3(0, 2, 0); }, {"environment", "sun_direction (0, 2, 0)"}},
      {"negative intensity", [](scene::Scene& s) { s.environment.intensity = -1.0f; }, {"environment", "intensity -1"}},
      {"light radius",
       [](scene::Scene& s) {
         scene::SphericalLight l;
         l.name = "lamp";
         l.radius = 0.0f;
         s.lights.push_back(l);
       },
       {"light 'lamp'", "radius 0"}},
      {"texture size",
       [](scene::Scene& s) {
         scene::Texture t;
         t.name = "albedo.png";
         t.width = 2;
         t.height = 2;
         t.texels.assign(3, vec3(0.5f));
         s.textures.push_back(t);
       },
       {"texture 'albedo.png'", "3 texels", "2x2"}},
      {"skin joint out of range",
       [](scene::Scene& s) {
         scene::Node j;
         j.name = "joint";
         s.nodes.push_back(j);
         scene::Skin sk;
         sk.name = "rig";
         sk.joints = {1};
         sk.inverse_bind = {glm::mat4(1.0f)};
         s.skins.push_back(sk);
         s.nodes[0].skin = 0;
         s.meshes[0].joints = std::vector<glm::u16vec4>(4, glm::u16vec4(0));
         s.meshes[0].weights = std::vector<vec4>(4, vec4(1, 0, 0, 0));
         s.meshes[0].joints[1] = glm::u16vec4(5, 0, 0, 0);
       },
       {"mesh 'quad' vertex 1", "joint 5", "skin 'rig' has 1 joints"}},
  };
  for (const auto& c : cases) {
    scene::Scene s = quad_scene();
    c.mutate(s);
    expect_invalid(s, c.needles, c.label);
  }
}

// --- evaluate -----------------------------------------------------------------------------------

vec3 apply(const glm::mat4& m, const vec3& p) { return vec3(m * vec4(p, 1.0f)); }

void expect_near(const vec3& a, const vec3& b, float tol, const std::string& what) {
  EXPECT_LE(glm::length(a - b), tol) << what << ": (" << a.x << ", " << a.y << ", " << a.z << ") vs (" << b.x << ", " << b.y << ", " << b.z << ")";
}

float angle_about(const glm::quat& q) { return 2.0f * std::acos(std::min(1.0f, std::abs(q.w))); }

// A parent node (translated, turned) with a mesh child, plus a clip whose keys at t = 0 equal the rest pose.
scene::Scene hierarchy_scene() {
  scene::Scene s = quad_scene();
  scene::Node parent;
  parent.name = "parent";
  parent.translation = vec3(1, 2, 3);
  parent.rotation = glm::angleAxis(0.5f, vec3(0, 1, 0));
  parent.scale = vec3(2.0f);
  s.nodes.push_back(parent);
  s.nodes[0].parent = 1;
  s.nodes[0].translation = vec3(0.5f, 0, 0);
  s.nodes[0].rotation = glm::angleAxis(0.3f, vec3(1, 0, 0));
  scene::AnimationClip c;
  c.name = "move";
  c.duration = 2.0f;
  scene::AnimationChannel t;
  t.node = 1;
  t.times = {0.0f, 2.0f};
  t.values = {vec4(1, 2, 3, 0), vec4(3, 2, 3, 0)};
  c.channels.push_back(t);
  scene::AnimationChannel r;
  r.node = 0;
  r.path = scene::AnimationChannel::Path::Rotation;
  const glm::quat q0 = s.nodes[0].rotation, q1 = glm::angleAxis(1.3f, vec3(1, 0, 0));
  r.times = {0.0f, 1.0f};
  r.values = {vec4(q0.x, q0.y, q0.z, q0.w), vec4(q1.x, q1.y, q1.z, q1.w)};
  c.channels.push_back(r);
  s.clips.push_back(c);
  s.active_clip = 0;
  return s;
}

TEST(SceneEvaluate, RestPoseAtTimeZeroWhereClipIsIdentity) {
  const scene::Scene s = hierarchy_scene();
  ASSERT_NO_THROW(scene::validate(s));
  const scene::PosedScene p = scene::evaluate(s, 0.0);
  // Hand-composed world transform of the quad: parent TRS times child TRS.
  const glm::mat4 parent = glm::translate(glm::mat4(1.0f), vec3(1, 2, 3)) * glm::mat4_cast(glm::angleAxis(0.5f, vec3(0, 1, 0))) *
                           glm::scale(glm::mat4(1.0f), vec3(2.0f));
  const glm::mat4 child = glm::translate(glm::mat4(1.0f), vec3(0.5f, 0, 0)) * glm::mat4_cast(glm::angleAxis(0.3f, vec3(1, 0, 0)));
  ASSERT_EQ(p.objects.size(), 1u);
  for (std::size_t v = 0; v < 4; ++v)
    expect_near(p.objects[0].positions[v], apply(parent * child, s.meshes[0].positions[v]), kPoseTol, "vertex " + std::to_string(v));
  const vec3 n = glm::normalize(glm::mat3(parent * child) * vec3(0, 0, 1));
  expect_near(p.objects[0].normals[0], n, kPoseTol, "normal");
  EXPECT_TRUE(p.animated) << "the clip moves the parent over time";

  scene::Scene still = s;
  still.active_clip = -1;
  const scene::PosedScene q = scene::evaluate(still, 5.0);
  EXPECT_FALSE(q.animated);
  for (std::size_t v = 0; v < 4; ++v) expect_near(q.objects[0].positions[v], p.objects[0].positions[v], kPoseTol, "static pose");
}

TEST(SceneEvaluate, IsStaticWhenNoChannelChangesAValue) {
  scene::Scene s = hierarchy_scene();
  EXPECT_FALSE(scene::is_static(s)) << "its clip moves the parent";
  // Every channel held at its first value: a clip that plays but moves nothing.
  for (auto& ch : s.clips[s.active_clip].channels)
    for (auto& v : ch.values) v = ch.values.front();
  EXPECT_TRUE(scene::is_static(s));
  const scene::PosedScene a = scene::evaluate(s, 0.0), b = scene::evaluate(s, 1.3);
  for (std::size_t v = 0; v < 4; ++v) EXPECT_EQ(a.objects[0].positions[v], b.objects[0].positions[v]) << "vertex " << v;
  s.active_clip = -1;
  EXPECT_TRUE(scene::is_static(s));
}

TEST(SceneEvaluate, LinearTranslationAndSlerpMidpoint) {
  const scene::Scene s = hierarchy_scene();
  const scene::PosedScene p = scene::evaluate(s, 0.5);
  // Translation: lerp of (1,2,3) -> (3,2,3) over 2 s at t = 0.5.
  expect_near(vec3(p.node_world[1][3]), vec3(1.5f, 2, 3), kPoseTol, "parent translation");
  // Rotation: slerp of 0.3 -> 1.3 rad about x at the midpoint is 0.8 rad about x.
  const glm::mat4 local = glm::inverse(p.node_world[1]) * p.node_world[0];
  const glm::quat q = glm::quat_cast(glm::mat3(local));
  EXPECT_NEAR(angle_about(q), 0.8f, kAngleTolRad);
  expect_near(glm::normalize(vec3(q.x, q.y, q.z)) * (q.w < 0 ? -1.0f : 1.0f), vec3(1, 0, 0), kAngleTolRad, "rotation axis");
}

TEST(SceneEvaluate, SlerpIsSphericalAndTakesTheShortArc) {
  // 160 degrees about y: at u = 1/4 slerp gives exactly 40 degrees; a normalised lerp would give 33.4.
  scene::Scene s = quad_scene();
  scene::AnimationClip c;
  c.duration = 1.0f;
  scene::AnimationChannel r;
  r.node = 0;
  r.path = scene::AnimationChannel::Path::Rotation;
  const glm::quat q1 = glm::angleAxis(glm::radians(160.0f), vec3(0, 1, 0));
  r.times = {0.0f, 1.0f};
  r.values = {vec4(0, 0, 0, 1), vec4(q1.x, q1.y, q1.z, q1.w)};
  c.channels.push_back(r);
  s.clips.push_back(c);
  s.active_clip = 0;
  const glm::quat a = glm::quat_cast(glm::mat3(scene::evaluate(s, 0.25).node_world[0]));
  EXPECT_NEAR(angle_about(a), glm::radians(40.0f), kAngleTolRad);
  // The same end key stored as -q1 (the same rotation): the short arc is still 160 degrees.
  s.clips[0].channels[0].values[1] = -s.clips[0].channels[0].values[1];
  const glm::quat b = glm::quat_cast(glm::mat3(scene::evaluate(s, 0.25).node_world[0]));
  EXPECT_NEAR(angle_about(b), glm::radians(40.0f), kAngleTolRad);
}

TEST(SceneEvaluate, StepInterpolationHoldsTheLeftKey) {
  scene::Scene s = quad_scene();
  scene::AnimationClip c;
  c.duration = 3.0f;
  scene::AnimationChannel t;
  t.node = 0;
  t.interp = scene::AnimationChannel::Interp::Step;
  t.times = {0.0f, 1.0f, 2.0f};
  t.values = {vec4(0, 0, 0, 0), vec4(1, 0, 0, 0), vec4(2, 0, 0, 0)};
  c.channels.push_back(t);
  s.clips.push_back(c);
  s.active_clip = 0;
  EXPECT_EQ(scene::evaluate(s, 0.99).node_world[0][3].x, 0.0f);
  EXPECT_EQ(scene::evaluate(s, 1.0).node_world[0][3].x, 1.0f);
  EXPECT_EQ(scene::evaluate(s, 1.7).node_world[0][3].x, 1.0f);
  EXPECT_EQ(scene::evaluate(s, 2.5).node_world[0][3].x, 2.0f);  // after the last key: held
}

TEST(SceneEvaluate, LoopWrapsAndNonLoopClamps) {
  scene::Scene s = hierarchy_scene();
  auto x_at = [&](double t) { return scene::evaluate(s, t).node_world[1][3].x; };
  // Loop of 2 s: t and t +- 2k pose alike, negative times included.
  EXPECT_NEAR(x_at(2.5), x_at(0.5), kPoseTol);
  EXPECT_NEAR(x_at(0.5), 1.5f, kPoseTol);
  EXPECT_NEAR(x_at(-0.5), x_at(1.5), kPoseTol);
  EXPECT_NEAR(x_at(41.25), x_at(1.25), kPoseTol);
  EXPECT_NEAR(x_at(2.0), 1.0f, kPoseTol) << "t = duration wraps to 0";
  s.clips[0].loop = false;
  EXPECT_NEAR(x_at(7.0), 3.0f, kPoseTol) << "clamped to the end";
  EXPECT_NEAR(x_at(-1.0), 1.0f, kPoseTol) << "clamped to the start";
  EXPECT_THROW(scene::evaluate(s, std::nan("")), std::invalid_argument);
  EXPECT_THROW(scene::evaluate(s, INFINITY), std::invalid_argument);
}

// Two bones: root joint at the origin (translated to (1, 0, 0) when posed), child joint at (0, 1, 0)
// turned 90 degrees about +z. Vertices on the root bone, on the child, and half-and-half at the joint.
TEST(SceneEvaluate, TwoBoneLinearBlendSkinningMatchesHandComputation) {
  scene::Scene s;
  s.materials.push_back(scene::Material{});
  scene::Mesh m;
  m.name = "limb";
  m.positions = {{0.1f, 0.5f, 0}, {0.1f, 1.5f, 0}, {0.1f, 1.0f, 0}, {-0.1f, 1.0f, 0}};
  m.normals = std::vector<vec3>(4, vec3(1, 0, 0));
  m.triangles = {{0, 1, 3}, {1, 2, 3}};
  m.joints = std::vector<glm::u16vec4>(4, glm::u16vec4(0, 1, 0, 0));
  m.weights = {vec4(1, 0, 0, 0), vec4(0, 1, 0, 0), vec4(0.5f, 0.5f, 0, 0), vec4(0.5f, 0.5f, 0, 0)};
  s.meshes.push_back(m);
  scene::Node root, child, holder;
  root.name = "root";
  root.translation = vec3(1, 0, 0);
  child.name = "child";
  child.parent = 0;
  child.translation = vec3(0, 1, 0);
  child.rotation = glm::angleAxis(glm::radians(90.0f), vec3(0, 0, 1));
  holder.name = "skinned";
  holder.mesh = 0;
  holder.skin = 0;
  holder.translation = vec3(5, 5, 5);  // glTF: a skinned mesh ignores its node's transform
  s.nodes = {root, child, holder};
  scene::Skin skin;
  skin.name = "rig";
  skin.joints = {0, 1};
  skin.inverse_bind = {glm::mat4(1.0f), glm::translate(glm::mat4(1.0f), vec3(0, -1, 0))};  // bind: joints at origin and (0,1,0)
  s.skins.push_back(skin);
  scene::ProxySet ps;
  ps.name = "limb";
  ps.node = 2;
  ps.spheres = {{vec3(0, 1, 0), 0.2f}, {vec3(0.1f, 1.0f, 0), 0.1f}};
  ps.joints = {glm::u16vec4(1, 0, 0, 0), glm::u16vec4(0, 1, 0, 0)};
  ps.weights = {vec4(1, 0, 0, 0), vec4(0.5f, 0.5f, 0, 0)};
  s.proxies.push_back(ps);
  ASSERT_NO_THROW(scene::validate(s));

  const scene::PosedScene p = scene::evaluate(s, 0.0);
  ASSERT_EQ(p.objects.size(), 1u);
  const auto& pos = p.objects[0].positions;
  const auto& nrm = p.objects[0].normals;
  // Root bone only: translated by (1, 0, 0).
  expect_near(pos[0], vec3(1.1f, 0.5f, 0), kPoseTol, "root-bound vertex");
  // Child bone: (0.1, 1.5) - joint = (0.1, 0.5), turned 90 deg about z -> (-0.5, 0.1), + joint (1, 1) -> (0.5, 1.1).
  expect_near(pos[1], vec3(0.5f, 1.1f, 0), kPoseTol, "child-bound vertex");
  // Blend: root gives (1.1, 1.0), child gives (1.0, 1.1); halfway (1.05, 1.05).
  expect_near(pos[2], vec3(1.05f, 1.05f, 0), kPoseTol, "blended vertex");
  // Normals: (1,0,0) stays on the root, turns to (0,1,0) on the child, renormalised halfway.
  expect_near(nrm[0], vec3(1, 0, 0), kPoseTol, "root normal");
  expect_near(nrm[1], vec3(0, 1, 0), kPoseTol, "child normal");
  expect_near(nrm[2], glm::normalize(vec3(1, 1, 0)), kPoseTol, "blended normal (unit)");
  // Proxies follow the same weights; radii are kept.
  ASSERT_EQ(p.proxies.size(), 1u);
  expect_near(p.proxies[0][0].center, vec3(1, 1, 0), kPoseTol, "sphere at the child joint");
  expect_near(p.proxies[0][1].center, vec3(1.05f, 1.05f, 0), kPoseTol, "blended sphere");
  EXPECT_NEAR(p.proxies[0][0].radius, 0.2f, kPoseTol);
  EXPECT_NEAR(p.proxies[0][1].radius, 0.1f, kPoseTol);
  EXPECT_FALSE(p.animated) << "no clip: the nodes keep their rest TRS (the bind pose differs, but nothing moves with t)";
}

TEST(SceneEvaluate, RigidProxiesAndLightsFollowTheirNode) {
  scene::Scene s = hierarchy_scene();
  scene::ProxySet ps;
  ps.name = "quad";
  ps.node = 0;
  ps.spheres = {{vec3(0.5f, 0.5f, 0), 0.75f}};
  s.proxies.push_back(ps);
  scene::SphericalLight l;
  l.name = "lamp";
  l.node = 1;
  l.position = vec3(0, 1, 0);
  l.radius = 0.1f;
  s.lights.push_back(l);
  ASSERT_NO_THROW(scene::validate(s));
  const scene::PosedScene p = scene::evaluate(s, 0.7);
  expect_near(p.proxies[0][0].center, apply(p.node_world[0], vec3(0.5f, 0.5f, 0)), kPoseTol, "rigid proxy centre");
  EXPECT_NEAR(p.proxies[0][0].radius, 1.5f, kPoseTol) << "radius scaled by the parent's uniform scale 2";
  expect_near(p.lights[0].position, apply(p.node_world[1], vec3(0, 1, 0)), kPoseTol, "light position");
  EXPECT_NEAR(p.lights[0].radius, 0.2f, kPoseTol);
  const scene::Bounds b = scene::bounds(p);
  for (const auto& v : p.objects[0].positions)
    EXPECT_TRUE(glm::all(glm::lessThanEqual(b.lo, v)) && glm::all(glm::lessThanEqual(v, b.hi)));
}

// --- Texture ------------------------------------------------------------------------------------

TEST(SceneTexture, BilinearWithRepeatWrap) {
  scene::Texture t;
  t.width = 2;
  t.height = 2;
  t.texels = {vec3(0), vec3(1), vec3(2), vec3(3)};  // row 0 at the top (v = 0)
  expect_near(t.sample({0.25f, 0.25f}), vec3(0), kPoseTol, "texel centre (0,0)");
  expect_near(t.sample({0.75f, 0.75f}), vec3(3), kPoseTol, "texel centre (1,1)");
  expect_near(t.sample({0.5f, 0.25f}), vec3(0.5f), kPoseTol, "between texels");
  // u = 0: halfway between texel 0 and, wrapped, texel 1.
  expect_near(t.sample({0.0f, 0.25f}), vec3(0.5f), kPoseTol, "wrap in u");
  expect_near(t.sample({1.25f, -0.75f}), vec3(0), kPoseTol, "repeat outside [0,1]");
}

// --- Environment --------------------------------------------------------------------------------

scene::Environment test_map(int w, int h) {
  scene::Environment e;
  e.kind = scene::Environment::Kind::Map;
  e.map_width = w;
  e.map_height = h;
  e.map_rgb.resize(static_cast<std::size_t>(w) * h * 3);
  for (int v = 0; v < h; ++v)
    for (int u = 0; u < w; ++u) {
      float* p = e.map_rgb.data() + (static_cast<std::size_t>(v) * w + u) * 3;
      p[0] = static_cast<float>(u) / w;  // values in [0, 1): the wrap neighbour differs by < 1
      p[1] = static_cast<float>(v) / h;
      p[2] = static_cast<float>((u * 7 + v * 3) % 5);
    }
  return e;
}

vec3 latlong(int u, int v, int w, int h) {
  const auto d = sh::latlong_direction(u, v, w, h);
  return vec3(static_cast<float>(d.x), static_cast<float>(d.y), static_cast<float>(d.z));
}

TEST(SceneEnvironment, MapLookupRoundTripsEveryPixelCentre) {
  constexpr int W = 64, H = 32;
  scene::Environment e = test_map(W, H);
  e.intensity = 2.0f;
  for (int v = 0; v < H; ++v)
    for (int u = 0; u < W; ++u) {
      const vec3 got = e.radiance(latlong(u, v, W, H));
      const float* p = e.map_rgb.data() + (static_cast<std::size_t>(v) * W + u) * 3;
      ASSERT_LE(glm::length(got - 2.0f * vec3(p[0], p[1], p[2])), kTexelTol) << "pixel (" << u << ", " << v << ")";
    }
  // Halfway between two columns: bilinear mean.
  const auto d = sh::latlong_direction(10.5, 7, W, H);
  EXPECT_NEAR(e.radiance(vec3(d.x, d.y, d.z)).x, 2.0f * 10.5f / W, kTexelTol);
  // Rotation by k pixel columns: a world direction sees the column k to its left (phi - rotation).
  e.rotation_y = static_cast<float>(2.0 * sh::kPi * 3 / W);
  for (int u : {0, 1, 5, 40, 63}) {
    const vec3 got = e.radiance(latlong(u, 9, W, H));
    EXPECT_NEAR(got.x, 2.0f * static_cast<float>((u - 3 + W) % W) / W, kTexelTol) << "rotated lookup at column " << u;
  }
}

TEST(SceneEnvironment, ConstantSkyProjectsToSqrt4PiInDc) {
  scene::Environment e;
  const vec3 c(0.3f, 0.6f, 1.2f);
  e.zenith = e.horizon = e.ground = e.sun_radiance = c;
  e.rotation_y = 0.4f;
  for (int order : {2, 4, 8}) {
    const auto L = scene::environment_sh(e, order);
    ASSERT_EQ(L.size(), static_cast<std::size_t>(order * order));
    for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(L[0][ch], sh::kSqrt4Pi * c[ch], kShExactRel * sh::kSqrt4Pi * c[ch]);
    for (int i = 1; i < order * order; ++i) EXPECT_LE(glm::length(L[i]), kShExactRel * sh::kSqrt4Pi) << "coefficient " << i;
  }
  // A constant map projects the same way (exact pixel solid angles).
  scene::Environment m;
  m.kind = scene::Environment::Kind::Map;
  m.map_width = 32;
  m.map_height = 16;
  m.map_rgb.clear();
  for (int k = 0; k < 32 * 16; ++k) m.map_rgb.insert(m.map_rgb.end(), {c.x, c.y, c.z});
  m.rotation_y = 1.1f;
  const auto Lm = scene::environment_sh(m, 3);
  for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(Lm[0][ch], sh::kSqrt4Pi * c[ch], kShExactRel * sh::kSqrt4Pi * c[ch]);
  EXPECT_THROW(scene::environment_sh(e, 0), std::invalid_argument);
  EXPECT_THROW(scene::environment_sh(e, 9), std::invalid_argument);
}

// The sun replaces a constant sky inside its disk: SH = sky + (sun - sky) * cap, with the cap's ZH
// g_l = 2 pi int_{cos a}^1 y_l0(mu) dmu turned to the sun direction (ZH rotation rule).
TEST(SceneEnvironment, SunDiskEnergyMatchesTheClosedFormCap) {
  scene::Environment e;
  const vec3 sky(0.5f, 0.5f, 0.5f), sun(60.0f, 55.0f, 48.0f);
  e.zenith = e.horizon = e.ground = sky;
  e.sun_radiance = sun;
  e.sun_radius = 0.05f;
  e.sun_direction = glm::normalize(vec3(0.5f, 0.8f, 0.3f));
  e.rotation_y = 0.9f;
  constexpr int order = 6;
  const auto L = scene::environment_sh(e, order);
  const double mu0 = std::cos(static_cast<double>(e.sun_radius));
  std::vector<double> g(order);
  for (int l = 0; l < order; ++l) {
    g[l] = 2.0 * sh::kPi * sh::integrate([&](double mu) {
             std::vector<double> y(order * order);
             sh::eval_basis(order, sh::Vec3<double>{std::sqrt(std::max(0.0, 1.0 - mu * mu)), 0.0, mu}, y.data());
             return y[sh::index(l, 0)];
           }, mu0, 1.0);
  }
  // World sun direction: sun_direction turned by rotation_y about +y.
  const glm::vec3 a = glm::vec3(glm::angleAxis(e.rotation_y, vec3(0, 1, 0)) * e.sun_direction);
  std::vector<double> cap(order * order);
  sh::zh_rotate(order, g.data(), sh::Vec3<double>{a.x, a.y, a.z}, cap.data());
  for (int ch = 0; ch < 3; ++ch) {
    const double sun_dc = (sun[ch] - sky[ch]) * cap[0];
    for (int i = 0; i < order * order; ++i) {
      const double expected = (i == 0 ? sh::kSqrt4Pi * sky[ch] : 0.0) + (sun[ch] - sky[ch]) * cap[i];
      EXPECT_NEAR(L[i][ch], expected, 1e-3 * sun_dc + kShExactRel * std::abs(expected)) << "coefficient " << i << " channel " << ch;
    }
  }
  // The rotated sky equals the unrotated sky with the sun direction turned.
  scene::Environment f = e;
  f.rotation_y = 0.0f;
  f.sun_direction = a;
  const auto Lf = scene::environment_sh(f, order);
  for (int i = 0; i < order * order; ++i) EXPECT_LE(glm::length(L[i] - Lf[i]), 1e-4f * glm::length(Lf[0]));
  // And radiance() agrees: the sun is at the turned direction.
  EXPECT_EQ(e.radiance(a), sun);
  EXPECT_EQ(e.radiance(glm::normalize(e.sun_direction)) == sun, false);
}

// The gradient sky (no sun) against an independent midpoint rule in (y, phi) with the horizon on a
// row boundary: dOmega = dy dphi, so the rule is equal-area and converges as O(h^2).
TEST(SceneEnvironment, GradientSkyMatchesMidpointQuadrature) {
  scene::Environment e;
  e.sun_radius = 0.0f;
  constexpr int order = 5, n_y = 2048, n_phi = 256;
  const auto L = scene::environment_sh(e, order);
  std::vector<glm::dvec3> ref(order * order, glm::dvec3(0.0));
  std::vector<double> y(order * order);
  const double dy = 2.0 / n_y, dphi = 2.0 * sh::kPi / n_phi;
  for (int i = 0; i < n_y; ++i) {
    const double yy = -1.0 + (i + 0.5) * dy;
    const double r = std::sqrt(1.0 - yy * yy);
    for (int j = 0; j < n_phi; ++j) {
      const double phi = (j + 0.5) * dphi;
      const vec3 d(static_cast<float>(r * std::cos(phi)), static_cast<float>(yy), static_cast<float>(r * std::sin(phi)));
      const glm::dvec3 value = glm::dvec3(e.radiance(d)) * dy * dphi;
      sh::eval_basis(order, sh::Vec3<double>{r * std::cos(phi), yy, r * std::sin(phi)}, y.data());
      for (int k = 0; k < order * order; ++k) ref[k] += value * y[k];
    }
  }
  for (int k = 0; k < order * order; ++k)
    for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(L[k][ch], ref[k][ch], kShMidpointTol) << "coefficient " << k << " channel " << ch;
}

// A map holding the linear function f(d) = 1 + 0.5 x + 0.3 z, turned by rotation_y: its band-1
// coefficients must be those of f(R^T d), the convention radiance() reads the map with.
TEST(SceneEnvironment, RotatedMapProjectionFollowsRadianceConvention) {
  constexpr int W = 256, H = 128;
  scene::Environment e;
  e.kind = scene::Environment::Kind::Map;
  e.map_width = W;
  e.map_height = H;
  for (int v = 0; v < H; ++v)
    for (int u = 0; u < W; ++u) {
      const auto d = sh::latlong_direction(u, v, W, H);
      const float f = static_cast<float>(1.0 + 0.5 * d.x + 0.3 * d.z);
      e.map_rgb.insert(e.map_rgb.end(), {f, f, f});
    }
  e.rotation_y = 0.7f;
  const auto L = scene::environment_sh(e, 2);
  // f(R^T d) = 1 + 0.5 (R^T d).x + 0.3 (R^T d).z = 1 + g . d with g = R (0.5, 0, 0.3).
  const vec3 g = glm::angleAxis(e.rotation_y, vec3(0, 1, 0)) * vec3(0.5f, 0.0f, 0.3f);
  const float c1 = std::sqrt(4.0f * static_cast<float>(sh::kPi) / 3.0f);  // y_1m = sqrt(3/4pi) * (y, z, x)
  EXPECT_NEAR(L[0].x, sh::kSqrt4Pi, kMapShTol);
  EXPECT_NEAR(L[sh::index(1, -1)].x, c1 * g.y, kMapShTol);
  EXPECT_NEAR(L[sh::index(1, 0)].x, c1 * g.z, kMapShTol);
  EXPECT_NEAR(L[sh::index(1, 1)].x, c1 * g.x, kMapShTol);
  // radiance() of the same map reads f(R^T d).
  const vec3 d = glm::normalize(vec3(0.3f, 0.4f, -0.8f));
  EXPECT_NEAR(e.radiance(d).x, 1.0f + glm::dot(g, d), 1e-2f);
}

}  // namespace
