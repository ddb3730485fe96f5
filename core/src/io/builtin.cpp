// Built-in scenes (docs/scenes.md): procedural geometry, animation clips and proxy sphere sets, plus
// `bunny`, which loads the asset set's GLB (hence this file lives in the io library).
#include "softgi/scene/builtin.hpp"

#include <glm/gtc/matrix_transform.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <functional>
#include <limits>
#include <map>
#include <mutex>
#include <stdexcept>

#include "softgi/io/gltf.hpp"
#include "softgi/io/scene_file.hpp"
#include "softgi/proxies/sphere_fit.hpp"

namespace softgi::scene {

namespace {

constexpr float kPi = 3.14159265358979323846f;
constexpr float kDeg = kPi / 180.0f;

// --- small builders -------------------------------------------------------------------------------

int add_material(Scene& s, const std::string& name, glm::vec3 albedo) {
  Material m;
  m.name = name;
  m.albedo = albedo;
  s.materials.push_back(m);
  return static_cast<int>(s.materials.size()) - 1;
}

int add_mesh(Scene& s, Mesh m) {
  s.meshes.push_back(std::move(m));
  return static_cast<int>(s.meshes.size()) - 1;
}

int add_node(Scene& s, const std::string& name, int parent, glm::vec3 t, glm::quat r = glm::quat(1.0f, 0.0f, 0.0f, 0.0f),
             int mesh = -1) {
  Node n;
  n.name = name;
  n.parent = parent;
  n.translation = t;
  n.rotation = r;
  n.mesh = mesh;
  s.nodes.push_back(n);
  return static_cast<int>(s.nodes.size()) - 1;
}

glm::quat axis_angle(glm::vec3 axis, float angle) { return glm::angleAxis(angle, glm::normalize(axis)); }
glm::quat yaw(float a) { return axis_angle({0.0f, 1.0f, 0.0f}, a); }
glm::vec4 qv(const glm::quat& q) { return {q.x, q.y, q.z, q.w}; }

// Appends a triangle wound counter-clockwise as seen from the side its vertex normals point to.
void add_tri(Mesh& m, unsigned a, unsigned b, unsigned c) {
  const glm::vec3 n = glm::cross(m.positions[b] - m.positions[a], m.positions[c] - m.positions[a]);
  const glm::vec3 hint = m.normals[a] + m.normals[b] + m.normals[c];
  if (glm::dot(n, hint) < 0.0f) std::swap(b, c);
  m.triangles.push_back({a, b, c});
}

// A flat nu x nv vertex grid spanning origin + [0,1] axis_u + [0,1] axis_v, facing `normal`.
void append_grid(Mesh& m, glm::vec3 origin, glm::vec3 axis_u, glm::vec3 axis_v, int nu, int nv, glm::vec3 normal) {
  const unsigned base = static_cast<unsigned>(m.positions.size());
  for (int j = 0; j < nv; ++j)
    for (int i = 0; i < nu; ++i) {
      const float u = static_cast<float>(i) / (nu - 1), v = static_cast<float>(j) / (nv - 1);
      m.positions.push_back(origin + u * axis_u + v * axis_v);
      m.normals.push_back(normal);
      m.uvs.push_back({u, v});
    }
  for (int j = 0; j + 1 < nv; ++j)
    for (int i = 0; i + 1 < nu; ++i) {
      const unsigned a = base + j * nu + i, b = a + 1, c = a + nu, d = c + 1;
      add_tri(m, a, b, d);
      add_tri(m, a, d, c);
    }
}

Mesh ground_plane(int vertices_per_side, float width, int material) {
  Mesh m;
  m.name = "ground";
  m.material = material;
  append_grid(m, {-0.5f * width, 0.0f, -0.5f * width}, {width, 0.0f, 0.0f}, {0.0f, 0.0f, width}, vertices_per_side,
              vertices_per_side, {0.0f, 1.0f, 0.0f});
  return m;
}

// UV sphere centred at the origin: vertices on the sphere, so the analytic sphere bounds the mesh.
Mesh uv_sphere(const std::string& name, float radius, int segments, int rings, int material) {
  Mesh m;
  m.name = name;
  m.material = material;
  m.positions.push_back({0.0f, radius, 0.0f});
  m.normals.push_back({0.0f, 1.0f, 0.0f});
  for (int i = 1; i < rings; ++i) {
    const float th = kPi * i / rings;
    for (int j = 0; j < segments; ++j) {
      const float ph = 2.0f * kPi * j / segments;
      const glm::vec3 n(std::sin(th) * std::cos(ph), std::cos(th), -std::sin(th) * std::sin(ph));
      m.positions.push_back(radius * n);
      m.normals.push_back(n);
    }
  }
  m.positions.push_back({0.0f, -radius, 0.0f});
  m.normals.push_back({0.0f, -1.0f, 0.0f});
  const unsigned south = static_cast<unsigned>(m.positions.size()) - 1;
  auto ring = [&](int i, int j) { return 1u + static_cast<unsigned>((i - 1) * segments + (j % segments)); };
  for (int j = 0; j < segments; ++j) {
    add_tri(m, 0, ring(1, j), ring(1, j + 1));
    add_tri(m, south, ring(rings - 1, j + 1), ring(rings - 1, j));
  }
  for (int i = 1; i + 1 < rings; ++i)
    for (int j = 0; j < segments; ++j) {
      add_tri(m, ring(i, j), ring(i + 1, j), ring(i + 1, j + 1));
      add_tri(m, ring(i, j), ring(i + 1, j + 1), ring(i, j + 1));
    }
  return m;
}

// Closed box centred at the origin, each face an n x n grid with its flat normal.
Mesh box_mesh(const std::string& name, glm::vec3 half, int n, int material) {
  Mesh m;
  m.name = name;
  m.material = material;
  for (int axis = 0; axis < 3; ++axis)
    for (int sign = -1; sign <= 1; sign += 2) {
      glm::vec3 normal(0.0f);
      normal[axis] = static_cast<float>(sign);
      const int a1 = (axis + 1) % 3, a2 = (axis + 2) % 3;
      glm::vec3 origin = -half, du(0.0f), dv(0.0f);
      origin[axis] = sign * half[axis];
      du[a1] = 2.0f * half[a1];
      dv[a2] = 2.0f * half[a2];
      append_grid(m, origin, du, dv, n, n, normal);
    }
  return m;
}

// Volume enclosed by a closed, outward-wound mesh (divergence theorem).
double closed_volume(const Mesh& m) {
  double v = 0.0;
  for (const auto& t : m.triangles)
    v += glm::dot(glm::dvec3(m.positions[t[0]]), glm::cross(glm::dvec3(m.positions[t[1]]), glm::dvec3(m.positions[t[2]]))) / 6.0;
  return v;
}

// Keyframed channel sampled from a function of clip time at `keys` + 1 uniform times over [0, duration].
AnimationChannel sampled_channel(int node, AnimationChannel::Path path, float duration, int keys,
                                 const std::function<glm::vec4(float)>& f) {
  AnimationChannel ch;
  ch.node = node;
  ch.path = path;
  for (int k = 0; k <= keys; ++k) {
    const float t = duration * k / keys;
    ch.times.push_back(t);
    ch.values.push_back(f(t));
  }
  return ch;
}

Environment default_sky() { return Environment{}; }

// --- spheres ----------------------------------------------------------------------------------------

Scene make_spheres() {
  Scene s;
  s.name = "spheres";
  s.source = "builtin:spheres";
  const int ground_mat = add_material(s, "ground", glm::vec3(0.7f));
  add_node(s, "ground", -1, glm::vec3(0.0f), glm::quat(1.0f, 0.0f, 0.0f, 0.0f), add_mesh(s, ground_plane(128, 8.0f, ground_mat)));

  constexpr float kDuration = 12.0f;
  constexpr int kKeys = 96;  // chord error of the circular paths: R (1 - cos(pi / 96)) < 1.1 mm for R = 2 m
  AnimationClip clip;
  clip.name = "orbit";
  clip.duration = kDuration;
  clip.loop = true;

  struct SphereSpec {
    const char* name;
    float radius;
    glm::vec3 albedo;
    float orbit_radius, revolutions, phase, bounce;  // bounce: hop height (m), 3 hops per loop
  };
  const SphereSpec specs[] = {
      {"sphere_large", 0.5f, {0.8f, 0.45f, 0.2f}, 1.1f, 1.0f, 0.0f, 0.0f},
      {"sphere_medium", 0.32f, {0.2f, 0.45f, 0.8f}, 2.0f, -1.0f, 2.1f, 0.0f},
      {"sphere_small", 0.2f, {0.85f, 0.85f, 0.85f}, 2.6f, 2.0f, 4.2f, 0.35f},
      {"sphere_tiny", 0.12f, {0.3f, 0.75f, 0.3f}, 0.35f, 0.0f, 0.0f, 0.25f},
  };
  for (const auto& sp : specs) {
    const int mat = add_material(s, sp.name, sp.albedo);
    const int mesh = add_mesh(s, uv_sphere(sp.name, sp.radius, 64, 32, mat));
    auto position = [sp](float t) {
      const float a = sp.phase + 2.0f * kPi * sp.revolutions * t / kDuration;
      // Hops: |sin| arcs, three per loop; the tiny sphere hops in place beside the large one.
      const float hop = sp.bounce * std::abs(std::sin(3.0f * kPi * t / kDuration));
      glm::vec3 p(sp.orbit_radius * std::cos(a), sp.radius + hop, -sp.orbit_radius * std::sin(a));
      if (sp.revolutions == 0.0f) p += glm::vec3(-1.6f, 0.0f, 1.0f);
      return p;
    };
    const int node = add_node(s, sp.name, -1, position(0.0f), glm::quat(1.0f, 0.0f, 0.0f, 0.0f), mesh);
    clip.channels.push_back(sampled_channel(node, AnimationChannel::Path::Translation, kDuration, kKeys,
                                            [&](float t) { return glm::vec4(position(t), 0.0f); }));
    // The proxy is the sphere itself: one sphere of the exact radius at the node's origin.
    ProxySet ps;
    ps.name = sp.name;
    ps.node = node;
    ps.spheres.push_back({glm::vec3(0.0f), sp.radius});
    ps.albedo = sp.albedo;
    const double sphere_volume = 4.0 / 3.0 * 3.14159265358979323846 * std::pow(static_cast<double>(sp.radius), 3);
    ps.outside_volume_ratio = sphere_volume / closed_volume(s.meshes[mesh]) - 1.0;
    s.proxies.push_back(ps);
  }
  s.clips.push_back(clip);
  s.active_clip = 0;
  s.camera.position = {0.0f, 2.4f, 5.6f};
  s.camera.target = {0.0f, 0.3f, 0.0f};
  s.camera.fov_y_deg = 45.0f;
  s.environment = default_sky();
  return s;
}

// --- cornell ----------------------------------------------------------------------------------------

// Bounding spheres of a box's cells: the box is cut into near-cubic cells, twice as many per axis as
// it is multiples of its shortest side long (a short cube gives its 8 octants, the 1:2:1 tall box
// 2 x 4 x 2), and each cell gets its circumscribed sphere. Covers the box exactly; E is about 1.7
// (a cube's circumsphere has pi sqrt(3) / 2 = 2.72 times its volume, partly shared between cells).
std::vector<Sphere> box_cell_spheres(glm::vec3 half) {
  const float shortest = std::min({half.x, half.y, half.z});
  glm::ivec3 cells;
  for (int a = 0; a < 3; ++a) cells[a] = 2 * std::max(1, static_cast<int>(std::lround(half[a] / shortest)));
  const glm::vec3 cell = 2.0f * half / glm::vec3(cells);
  const float radius = 0.5f * glm::length(cell);
  std::vector<Sphere> out;
  for (int i = 0; i < cells.x; ++i)
    for (int j = 0; j < cells.y; ++j)
      for (int k = 0; k < cells.z; ++k)
        out.push_back({-half + cell * (glm::vec3(i, j, k) + 0.5f), radius});
  return out;
}

Scene make_cornell() {
  Scene s;
  s.name = "cornell";
  s.source = "builtin:cornell";
  // Reflectances of the measured Cornell box, as commonly tabulated for RGB renderers.
  const int white = add_material(s, "white", {0.73f, 0.73f, 0.73f});
  const int red = add_material(s, "red", {0.63f, 0.065f, 0.05f});
  const int green = add_material(s, "green", {0.14f, 0.45f, 0.091f});

  // Interior x in [-1, 1], y in [0, 2], z in [-1, 1]; the +z side is open towards the camera.
  constexpr int kWallVerts = 32;
  struct Wall {
    const char* name;
    glm::vec3 origin, du, dv, normal;
    int material;
  };
  const Wall walls[] = {
      {"floor", {-1, 0, -1}, {2, 0, 0}, {0, 0, 2}, {0, 1, 0}, white},
      {"ceiling", {-1, 2, -1}, {2, 0, 0}, {0, 0, 2}, {0, -1, 0}, white},
      {"back_wall", {-1, 0, -1}, {2, 0, 0}, {0, 2, 0}, {0, 0, 1}, white},
      {"left_wall", {-1, 0, -1}, {0, 2, 0}, {0, 0, 2}, {1, 0, 0}, red},
      {"right_wall", {1, 0, -1}, {0, 2, 0}, {0, 0, 2}, {-1, 0, 0}, green},
  };
  for (const auto& w : walls) {
    Mesh m;
    m.name = w.name;
    m.material = w.material;
    append_grid(m, w.origin, w.du, w.dv, kWallVerts, kWallVerts, w.normal);
    add_node(s, w.name, -1, glm::vec3(0.0f), glm::quat(1.0f, 0.0f, 0.0f, 0.0f), add_mesh(s, std::move(m)));
  }

  // The two blocks of the original box (tall one at the back left turned about +17 degrees, short one
  // at the front right turned about -17 degrees), scaled to this 2 m box.
  const glm::vec3 tall_half(0.3f, 0.6f, 0.3f), short_half(0.3f, 0.3f, 0.3f);
  const int tall = add_node(s, "tall_box", -1, {-0.33f, 0.6f, -0.3f}, yaw(17.0f * kDeg),
                            add_mesh(s, box_mesh("tall_box", tall_half, 9, white)));
  const int short_box = add_node(s, "short_box", -1, {0.35f, 0.3f, 0.33f}, yaw(-17.0f * kDeg),
                                 add_mesh(s, box_mesh("short_box", short_half, 9, white)));
  for (auto [node, half] : {std::pair{tall, tall_half}, std::pair{short_box, short_half}}) {
    ProxySet ps;
    ps.name = s.nodes[node].name;
    ps.node = node;
    ps.spheres = box_cell_spheres(half);
    ps.albedo = s.materials[white].albedo;
    s.proxies.push_back(ps);
  }
  // The walls get no proxies: a sphere set bounding a thin 2 m x 2 m wall either has a few huge spheres
  // that swallow the whole interior (every receiver would sit inside a blocker) or hundreds of small
  // ones; the papers' proxies stand for compact movable blockers, and the walls are receivers.

  constexpr float kDuration = 10.0f;
  AnimationClip clip;
  clip.name = "light_and_box";
  clip.duration = kDuration;
  const int light_node = add_node(s, "ceiling_light", -1, {0.3f, 1.75f, 0.0f});
  auto light_pos = [](float t) {
    const float a = 2.0f * kPi * t / kDuration;
    return glm::vec4(0.3f * std::cos(a), 1.75f, -0.3f * std::sin(a), 0.0f);
  };
  clip.channels.push_back(sampled_channel(light_node, AnimationChannel::Path::Translation, kDuration, 64, light_pos));
  clip.channels.push_back(sampled_channel(short_box, AnimationChannel::Path::Rotation, kDuration, 64, [](float t) {
    return qv(yaw((-17.0f + 20.0f * std::sin(2.0f * kPi * t / kDuration)) * kDeg));
  }));
  s.clips.push_back(clip);
  s.active_clip = 0;

  SphericalLight light;
  light.name = "ceiling_light";
  light.node = light_node;
  light.position = glm::vec3(0.0f);  // node space
  light.radius = 0.12f;
  // Irradiance under it at 1.75 m: pi L (R/d)^2 ~ 1.5, comparable to the sky seen through the front.
  light.radiance = glm::vec3(100.0f, 90.0f, 75.0f);
  s.lights.push_back(light);

  s.camera.position = {0.0f, 1.0f, 3.5f};
  s.camera.target = {0.0f, 1.0f, 0.0f};
  s.camera.fov_y_deg = 45.0f;
  s.environment = default_sky();
  return s;
}

// --- character ----------------------------------------------------------------------------------------

// Skeleton in the bind (rest) pose, character space: standing at the origin on y = 0, facing +z, its
// left on +x, arms down. Joint positions in metres.
struct BoneDef {
  const char* name;
  int parent;
  glm::vec3 joint;
};
enum Bone { Pelvis, Spine, Chest, Neck, Head, UpperArmL, ForearmL, UpperArmR, ForearmR, ThighL, ShinL, FootL, ThighR, ShinR, FootR, kBones };
const BoneDef kSkeleton[kBones] = {
    {"pelvis", -1, {0.0f, 0.95f, 0.0f}},          {"spine", Pelvis, {0.0f, 1.07f, 0.0f}},
    {"chest", Spine, {0.0f, 1.22f, 0.0f}},        {"neck", Chest, {0.0f, 1.43f, 0.0f}},
    {"head", Neck, {0.0f, 1.53f, 0.0f}},          {"upperarm.L", Chest, {0.19f, 1.40f, 0.0f}},
    {"forearm.L", UpperArmL, {0.21f, 1.12f, 0.0f}}, {"upperarm.R", Chest, {-0.19f, 1.40f, 0.0f}},
    {"forearm.R", UpperArmR, {-0.21f, 1.12f, 0.0f}}, {"thigh.L", Pelvis, {0.095f, 0.92f, 0.0f}},
    {"shin.L", ThighL, {0.10f, 0.50f, 0.0f}},      {"foot.L", ShinL, {0.10f, 0.09f, -0.01f}},
    {"thigh.R", Pelvis, {-0.095f, 0.92f, 0.0f}},   {"shin.R", ThighR, {-0.10f, 0.50f, 0.0f}},
    {"foot.R", ShinR, {-0.10f, 0.09f, -0.01f}},
};

// A tapered capsule (convex hull of two balls) rigidly on `bone`, blending into the parent bone near
// the bone's own joint and into `tail_child` near that child's joint.
struct CapsuleDef {
  int bone;
  glm::vec3 a;
  float ra;
  glm::vec3 b;
  float rb;
  bool blend_head;  // blend into the parent around this bone's joint
  int tail_child;   // blend into this child around its joint (-1: none)
  int colour;       // 0 shirt, 1 trousers, 2 skin, 3 shoes
};
const CapsuleDef kCapsules[] = {
    {Pelvis, {0.0f, 0.89f, 0.0f}, 0.135f, {0.0f, 1.02f, 0.0f}, 0.125f, false, Spine, 1},
    {Spine, {0.0f, 1.07f, 0.0f}, 0.12f, {0.0f, 1.22f, 0.0f}, 0.13f, true, Chest, 0},
    {Chest, {0.0f, 1.22f, 0.0f}, 0.135f, {0.0f, 1.36f, 0.0f}, 0.13f, true, Neck, 0},
    {Chest, {-0.15f, 1.37f, 0.0f}, 0.07f, {0.15f, 1.37f, 0.0f}, 0.07f, false, -1, 0},  // shoulders
    {Neck, {0.0f, 1.43f, 0.0f}, 0.05f, {0.0f, 1.53f, 0.0f}, 0.045f, true, Head, 2},
    {Head, {0.0f, 1.60f, 0.015f}, 0.095f, {0.0f, 1.67f, 0.005f}, 0.09f, true, -1, 2},
    {UpperArmL, {0.19f, 1.40f, 0.0f}, 0.05f, {0.21f, 1.12f, 0.0f}, 0.042f, true, ForearmL, 0},
    {ForearmL, {0.21f, 1.12f, 0.0f}, 0.04f, {0.225f, 0.80f, 0.02f}, 0.033f, true, -1, 2},
    {UpperArmR, {-0.19f, 1.40f, 0.0f}, 0.05f, {-0.21f, 1.12f, 0.0f}, 0.042f, true, ForearmR, 0},
    {ForearmR, {-0.21f, 1.12f, 0.0f}, 0.04f, {-0.225f, 0.80f, 0.02f}, 0.033f, true, -1, 2},
    {ThighL, {0.095f, 0.92f, 0.0f}, 0.08f, {0.10f, 0.50f, 0.0f}, 0.056f, true, ShinL, 1},
    {ShinL, {0.10f, 0.50f, 0.0f}, 0.054f, {0.10f, 0.10f, -0.01f}, 0.04f, true, FootL, 1},
    {FootL, {0.10f, 0.075f, -0.045f}, 0.045f, {0.10f, 0.035f, 0.15f}, 0.034f, true, -1, 3},
    {ThighR, {-0.095f, 0.92f, 0.0f}, 0.08f, {-0.10f, 0.50f, 0.0f}, 0.056f, true, ShinR, 1},
    {ShinR, {-0.10f, 0.50f, 0.0f}, 0.054f, {-0.10f, 0.10f, -0.01f}, 0.04f, true, FootR, 1},
    {FootR, {-0.10f, 0.075f, -0.045f}, 0.045f, {-0.10f, 0.035f, 0.15f}, 0.034f, true, -1, 3},
};

// Smooth skin weights at rest-pose point p of capsule c: half weight to the neighbour at the joint,
// fading to zero over a blend length of 0.5 r + 2 cm inside the bone (smoothstep).
struct Influence {
  glm::u16vec4 joints{0};
  glm::vec4 weights{0.0f};
};
Influence capsule_weights(const CapsuleDef& c, const glm::vec3& p) {
  auto smooth = [](float e, float x) {
    const float t = std::clamp(x / e, 0.0f, 1.0f);
    return t * t * (3.0f - 2.0f * t);
  };
  const glm::vec3 u = glm::normalize(c.b - c.a);
  float w_parent = 0.0f, w_child = 0.0f;
  if (c.blend_head && kSkeleton[c.bone].parent >= 0)
    w_parent = 0.5f * (1.0f - smooth(0.5f * c.ra + 0.02f, glm::dot(p - kSkeleton[c.bone].joint, u)));
  if (c.tail_child >= 0) w_child = 0.5f * (1.0f - smooth(0.5f * c.rb + 0.02f, glm::dot(kSkeleton[c.tail_child].joint - p, u)));
  Influence inf;
  inf.joints = {static_cast<std::uint16_t>(c.bone), static_cast<std::uint16_t>(std::max(0, kSkeleton[c.bone].parent)),
                static_cast<std::uint16_t>(std::max(0, c.tail_child)), 0};
  inf.weights = {1.0f - w_parent - w_child, w_parent, w_child, 0.0f};
  return inf;
}

// Tangent angle of the hull of balls (a, ra), (b, rb) with |b - a| = len: the cone's normals make
// angle beta with the radial direction, sin beta = (ra - rb) / len.
float capsule_beta(float ra, float rb, float len) { return std::asin(std::clamp((ra - rb) / len, -1.0f, 1.0f)); }

// Cross-section radius of the capsule hull at axial coordinate x (0 at a, len at b).
float capsule_rho(float ra, float rb, float len, float x) {
  const float sb = (ra - rb) / len, cb = std::sqrt(std::max(0.0f, 1.0f - sb * sb));
  const float xa = ra * sb, xb = len + rb * sb;  // axial positions of the tangent circles
  if (x <= xa) return std::sqrt(std::max(0.0f, ra * ra - x * x));
  if (x >= xb) return std::sqrt(std::max(0.0f, rb * rb - (x - len) * (x - len)));
  return ra * cb + (rb * cb - ra * cb) * (x - xa) / (xb - xa);
}

void orthonormal_frame(const glm::vec3& u, glm::vec3& e1, glm::vec3& e2) {
  const glm::vec3 h = std::abs(u.y) < 0.9f ? glm::vec3(0.0f, 1.0f, 0.0f) : glm::vec3(1.0f, 0.0f, 0.0f);
  e1 = glm::normalize(glm::cross(h, u));
  e2 = glm::cross(u, e1);
}

// Appends the capsule's surface: latitude rings psi in [-pi/2, pi/2] with normals
// n = cos psi * radial + sin psi * u, on ball a for psi <= beta and on ball b above, plus rings along
// the cone so that the skin bends smoothly. All vertices lie on the hull, which is convex, so every
// triangle lies inside it.
void append_capsule(Mesh& m, const CapsuleDef& c, const glm::vec3& colour) {
  constexpr int kSegments = 16, kCapRings = 5;
  constexpr float kConeSpacing = 0.03f;  // metres between cone rings
  const float len = glm::length(c.b - c.a);
  const glm::vec3 u = (c.b - c.a) / len;
  glm::vec3 e1, e2;
  orthonormal_frame(u, e1, e2);
  const float beta = capsule_beta(c.ra, c.rb, len);
  struct Ring {
    glm::vec3 centre;
    float radius;     // of the ball the ring lies on
    float psi;
  };
  std::vector<Ring> rings;
  for (int i = 1; i <= kCapRings; ++i) rings.push_back({c.a, c.ra, -0.5f * kPi + (beta + 0.5f * kPi) * i / kCapRings});
  const int cone = std::max(1, static_cast<int>(std::ceil(len * std::cos(beta) / kConeSpacing)));
  // Cone rings: interpolate the tangent circle of a to that of b (same normal, psi = beta).
  for (int k = 1; k < cone; ++k) {
    const float f = static_cast<float>(k) / cone;
    rings.push_back({c.a + f * (c.b - c.a), c.ra + f * (c.rb - c.ra), beta});
  }
  for (int i = 0; i < kCapRings; ++i) rings.push_back({c.b, c.rb, beta + (0.5f * kPi - beta) * i / kCapRings});

  auto push = [&](const glm::vec3& p, const glm::vec3& n) {
    m.positions.push_back(p);
    m.normals.push_back(n);
    m.colors.push_back(colour);
    const Influence inf = capsule_weights(c, p);
    m.joints.push_back(inf.joints);
    m.weights.push_back(inf.weights);
    return static_cast<unsigned>(m.positions.size()) - 1;
  };
  const unsigned south = push(c.a - c.ra * u, -u);
  std::vector<unsigned> first(rings.size());
  for (std::size_t r = 0; r < rings.size(); ++r) {
    first[r] = static_cast<unsigned>(m.positions.size());
    for (int j = 0; j < kSegments; ++j) {
      const float ph = 2.0f * kPi * j / kSegments;
      const glm::vec3 radial = std::cos(ph) * e1 + std::sin(ph) * e2;
      const glm::vec3 n = std::cos(rings[r].psi) * radial + std::sin(rings[r].psi) * u;
      push(rings[r].centre + rings[r].radius * n, n);
    }
  }
  const unsigned north = push(c.b + c.rb * u, u);
  for (int j = 0; j < kSegments; ++j) {
    const unsigned j1 = (j + 1) % kSegments;
    add_tri(m, south, first[0] + j1, first[0] + j);
    add_tri(m, north, first.back() + j, first.back() + j1);
  }
  for (std::size_t r = 0; r + 1 < rings.size(); ++r)
    for (int j = 0; j < kSegments; ++j) {
      const unsigned j1 = (j + 1) % kSegments;
      add_tri(m, first[r] + j, first[r] + j1, first[r + 1] + j1);
      add_tri(m, first[r] + j, first[r + 1] + j1, first[r + 1] + j);
    }
}

// Spheres along the capsule axis bounding its hull: centres c_k evenly spaced on [a, b]; sphere k bounds
// the part of the hull whose axial coordinate lies in its slab [x_k - d/2, x_k + d/2] (the end slabs
// reach the poles), radius = max over that slab of sqrt((x - x_k)^2 + rho(x)^2), found by dense
// sampling of the exact cross-section radius rho and padded by 1e-4 relative against sampling error.
std::vector<Sphere> capsule_spheres(const CapsuleDef& c, int count) {
  const float len = glm::length(c.b - c.a);
  std::vector<Sphere> out;
  const float d = len / (count - 1);
  for (int k = 0; k < count; ++k) {
    const float xk = d * k;
    const float lo = k == 0 ? -c.ra : xk - 0.5f * d, hi = k == count - 1 ? len + c.rb : xk + 0.5f * d;
    float r2 = 0.0f;
    constexpr int kSamples = 2048;
    for (int i = 0; i <= kSamples; ++i) {
      const float x = lo + (hi - lo) * i / kSamples;
      const float rho = capsule_rho(c.ra, c.rb, len, x);
      r2 = std::max(r2, (x - xk) * (x - xk) + rho * rho);
    }
    out.push_back({c.a + (c.b - c.a) * (xk / len), std::sqrt(r2) * (1.0f + 1e-4f)});
  }
  return out;
}

// Spheres per capsule: spacing at most 3 mean radii (a limb sphere is then about 1.8 times the limb
// radius), at least two; about 46 spheres per character.
int capsule_sphere_count(const CapsuleDef& c) {
  const float len = glm::length(c.b - c.a);
  return std::max(2, 1 + static_cast<int>(std::ceil(len / (3.0f * 0.5f * (c.ra + c.rb)))));
}

struct CharacterTemplate {
  Mesh mesh;
  ProxySet proxies;  // node filled per instance
  std::vector<glm::mat4> inverse_bind;
};

CharacterTemplate build_character_template(const std::array<glm::vec3, 4>& palette) {
  CharacterTemplate ct;
  ct.mesh.name = "character";
  for (const auto& c : kCapsules) append_capsule(ct.mesh, c, palette[c.colour]);
  // Proxy spheres bound to bones with the skin weights of their centres; coincident spheres of
  // adjoining capsules (same centre, same influences: at knees and elbows) merge into the larger.
  for (const auto& c : kCapsules) {
    for (const Sphere& sp : capsule_spheres(c, capsule_sphere_count(c))) {
      const Influence inf = capsule_weights(c, sp.center);
      bool merged = false;
      for (std::size_t k = 0; k < ct.proxies.spheres.size() && !merged; ++k) {
        Sphere& o = ct.proxies.spheres[k];
        if (glm::length(o.center - sp.center) > 1e-5f) continue;
        // Same influence set (possibly in another slot order) with the same weights.
        bool same = true;
        for (int a = 0; a < 4 && same; ++a) {
          if (inf.weights[a] == 0.0f) continue;
          bool found = false;
          for (int b = 0; b < 4; ++b)
            if (ct.proxies.joints[k][b] == inf.joints[a] && std::abs(ct.proxies.weights[k][b] - inf.weights[a]) < 1e-4f) found = true;
          same = found;
        }
        if (same) {
          o.radius = std::max(o.radius, sp.radius);
          merged = true;
        }
      }
      if (merged) continue;
      ct.proxies.spheres.push_back(sp);
      ct.proxies.joints.push_back(inf.joints);
      ct.proxies.weights.push_back(inf.weights);
    }
  }
  glm::vec3 mean(0.0f);
  for (const auto& col : ct.mesh.colors) mean += col;
  ct.proxies.albedo = mean / static_cast<float>(ct.mesh.colors.size());
    // Bind pose: every joint frame is a pure translation to its joint, so inverse_bind = translate(-joint).
  for (const auto& b : kSkeleton) {
    glm::mat4 m(1.0f);
    m[3] = glm::vec4(-b.joint, 1.0f);
    ct.inverse_bind.push_back(m);
  }
  return ct;
}

// Walking gait as joint rotations (degrees) of the gait phase p in [0, 1): thighs swing +-22 degrees in
// antiphase, knees flex up to 55 degrees early in the swing, ankles and arms follow, the pelvis sways.
// Rotation signs: R_x(-a) swings a limb that points down (or a foot that points forward) forwards/up.
struct GaitPose {
  glm::quat rot[kBones];
  float pelvis_drop = 0.0f;
};
GaitPose gait_pose(float p) {
  GaitPose g;
  for (auto& q : g.rot) q = glm::quat(1.0f, 0.0f, 0.0f, 0.0f);
  const float w = 2.0f * kPi * p;
  const glm::vec3 X(1.0f, 0.0f, 0.0f), Y(0.0f, 1.0f, 0.0f), Z(0.0f, 0.0f, 1.0f);
  for (int side = 0; side < 2; ++side) {
    const float ws = w + side * kPi;
    const float swing = 22.0f * std::sin(ws);
    const float c = std::max(0.0f, std::cos(ws + 0.2f));
    const float knee = 5.0f + 50.0f * c * c;
    const float ankle = 8.0f * std::sin(ws) - 0.25f * (knee - 5.0f);
    const int thigh = side == 0 ? ThighL : ThighR, shin = side == 0 ? ShinL : ShinR, foot = side == 0 ? FootL : FootR;
    g.rot[thigh] = axis_angle(X, -swing * kDeg);
    g.rot[shin] = axis_angle(X, knee * kDeg);
    g.rot[foot] = axis_angle(X, -ankle * kDeg);
    // Arms swing against the leg of their side, slightly abducted; elbows flex more when forward.
    const float arm = -18.0f * std::sin(ws);
    const float elbow = 15.0f + 12.0f * std::max(0.0f, -std::sin(ws));
    const float abduct = side == 0 ? 6.0f : -6.0f;
    const int upper = side == 0 ? UpperArmL : UpperArmR, fore = side == 0 ? ForearmL : ForearmR;
    g.rot[upper] = axis_angle(Z, abduct * kDeg) * axis_angle(X, -arm * kDeg);
    g.rot[fore] = axis_angle(X, -elbow * kDeg);
  }
  g.rot[Pelvis] = axis_angle(Y, 5.0f * std::sin(w) * kDeg) * axis_angle(Z, 3.0f * std::sin(2.0f * w) * kDeg);
  g.rot[Spine] = axis_angle(Y, -3.0f * std::sin(w) * kDeg);
  g.rot[Chest] = axis_angle(Y, -3.0f * std::sin(w) * kDeg) * axis_angle(X, 4.0f * kDeg);
  g.rot[Head] = axis_angle(Y, 2.0f * std::sin(w) * kDeg);
  // The pelvis drops by the height of the body's lowest point in this pose (forward kinematics with
  // the pelvis at its rest height; a capsule's lowest point is the lower of its balls' bottoms), so
  // the planted foot touches y = 0 at every key instead of floating or sinking.
  glm::mat4 world[kBones];
  for (int b = 0; b < kBones; ++b) {
    const BoneDef& d = kSkeleton[b];
    const glm::mat4 local = glm::translate(glm::mat4(1.0f), d.parent >= 0 ? d.joint - kSkeleton[d.parent].joint : d.joint) * glm::mat4_cast(g.rot[b]);
    world[b] = d.parent >= 0 ? world[d.parent] * local : local;
  }
  float lowest = std::numeric_limits<float>::infinity();
  for (const auto& c : kCapsules) {
    const glm::mat4 m = world[c.bone] * glm::translate(glm::mat4(1.0f), -kSkeleton[c.bone].joint);  // bind -> posed
    lowest = std::min({lowest, (m * glm::vec4(c.a, 1.0f)).y - c.ra, (m * glm::vec4(c.b, 1.0f)).y - c.rb});
  }
  g.pelvis_drop = lowest;
  return g;
}

struct WalkerSpec {
  std::string name;
  glm::vec3 centre;      // of the circular path
  float path_radius;
  bool clockwise;
  int gait_cycles;       // per clip
  float phase;           // gait phase offset in [0, 1)
  float path_phase;      // starting angle on the circle (radians)
  glm::vec3 shirt;
};

// Adds one walking character (skeleton nodes, skinned mesh, proxy set, clip channels).
void add_walker(Scene& s, AnimationClip& clip, const WalkerSpec& w, int material) {
  const std::array<glm::vec3, 4> palette = {w.shirt, glm::vec3(0.18f, 0.2f, 0.3f), glm::vec3(0.8f, 0.6f, 0.48f), glm::vec3(0.1f)};
  CharacterTemplate ct = build_character_template(palette);
  const float duration = clip.duration;
  const int keys = w.gait_cycles * 32;  // 32 keys per gait cycle: feet within about 1 cm of the ground between keys
  auto path_angle = [&](float t) { return w.path_phase + (w.clockwise ? -1.0f : 1.0f) * 2.0f * kPi * t / duration; };
  auto root_pos = [&](float t) {
    const float a = path_angle(t);
    return w.centre + w.path_radius * glm::vec3(std::cos(a), 0.0f, -std::sin(a));
  };
  auto root_rot = [&](float t) {
    const float a = path_angle(t), sgn = w.clockwise ? -1.0f : 1.0f;
    const glm::vec3 f = sgn * glm::vec3(-std::sin(a), 0.0f, -std::cos(a));  // direction of travel
    return yaw(std::atan2(f.x, f.z));
  };
  auto phase_at = [&](float t) {
    const float p = w.phase + w.gait_cycles * t / duration;
    return p - std::floor(p);
  };

  const int root = add_node(s, w.name, -1, root_pos(0.0f), root_rot(0.0f));
  int bone_node[kBones];
  for (int b = 0; b < kBones; ++b) {
    const BoneDef& def = kSkeleton[b];
    const glm::vec3 local = def.parent >= 0 ? def.joint - kSkeleton[def.parent].joint : def.joint;
    bone_node[b] = add_node(s, w.name + "/" + def.name, def.parent >= 0 ? bone_node[def.parent] : root, local);
  }
  Skin skin;
  skin.name = w.name;
  for (int b = 0; b < kBones; ++b) skin.joints.push_back(bone_node[b]);
  skin.inverse_bind = ct.inverse_bind;
  s.skins.push_back(skin);
  ct.mesh.name = w.name;
  ct.mesh.material = material;
  const int mesh_node = add_node(s, w.name + "/mesh", root, glm::vec3(0.0f), glm::quat(1.0f, 0.0f, 0.0f, 0.0f), add_mesh(s, std::move(ct.mesh)));
  s.nodes[mesh_node].skin = static_cast<int>(s.skins.size()) - 1;
  ct.proxies.name = w.name;
  ct.proxies.node = mesh_node;
  s.proxies.push_back(std::move(ct.proxies));

  using P = AnimationChannel::Path;
  clip.channels.push_back(sampled_channel(root, P::Translation, duration, keys, [&](float t) { return glm::vec4(root_pos(t), 0.0f); }));
  clip.channels.push_back(sampled_channel(root, P::Rotation, duration, keys, [&](float t) { return qv(root_rot(t)); }));
  clip.channels.push_back(sampled_channel(bone_node[Pelvis], P::Translation, duration, keys, [&](float t) {
    return glm::vec4(kSkeleton[Pelvis].joint - glm::vec3(0.0f, gait_pose(phase_at(t)).pelvis_drop, 0.0f), 0.0f);
  }));
  for (int b = 0; b < kBones; ++b) {
    if (b == Neck) continue;  // never rotated by the gait
    clip.channels.push_back(sampled_channel(bone_node[b], P::Rotation, duration, keys, [&](float t) { return qv(gait_pose(phase_at(t)).rot[b]); }));
  }
}

Scene make_character() {
  Scene s;
  s.name = "character";
  s.source = "builtin:character";
  const int ground_mat = add_material(s, "ground", glm::vec3(0.7f));
  add_node(s, "ground", -1, glm::vec3(0.0f), glm::quat(1.0f, 0.0f, 0.0f, 0.0f), add_mesh(s, ground_plane(128, 8.0f, ground_mat)));
  const int body = add_material(s, "body", glm::vec3(1.0f));  // albedo from the vertex colours
  AnimationClip clip;
  clip.name = "walk";
  clip.duration = 9.6f;  // eight 1.2 s gait cycles, one lap of a 1.2 m circle (0.79 m/s)
  add_walker(s, clip, {"walker", glm::vec3(0.0f), 1.2f, false, 8, 0.0f, 0.0f, {0.7f, 0.25f, 0.2f}}, body);
  s.clips.push_back(clip);
  s.active_clip = 0;
  s.camera.position = {0.0f, 1.7f, 4.6f};
  s.camera.target = {0.0f, 0.8f, 0.0f};
  s.camera.fov_y_deg = 45.0f;
  s.environment = default_sky();
  return s;
}

Scene make_crowd() {
  Scene s;
  s.name = "crowd";
  s.source = "builtin:crowd";
  const int ground_mat = add_material(s, "ground", glm::vec3(0.7f));
  add_node(s, "ground", -1, glm::vec3(0.0f), glm::quat(1.0f, 0.0f, 0.0f, 0.0f), add_mesh(s, ground_plane(128, 14.0f, ground_mat)));
  const int body = add_material(s, "body", glm::vec3(1.0f));
  AnimationClip clip;
  clip.name = "crowd_walk";
  clip.duration = 9.6f;
  const glm::vec3 shirts[] = {{0.7f, 0.25f, 0.2f}, {0.2f, 0.4f, 0.7f}, {0.25f, 0.6f, 0.3f}, {0.75f, 0.7f, 0.25f}, {0.55f, 0.3f, 0.6f},
                              {0.8f, 0.8f, 0.8f},  {0.3f, 0.65f, 0.65f}, {0.75f, 0.45f, 0.2f}, {0.4f, 0.4f, 0.45f}};
  // A 3 x 3 grid of circular paths 3.6 m apart (radii <= 1.2 m keep walkers >= 1.2 m apart); radii, directions, cadences and phases differ.
  int k = 0;
  for (int i = -1; i <= 1; ++i)
    for (int j = -1; j <= 1; ++j, ++k) {
      WalkerSpec w;
      w.name = "walker" + std::to_string(k);
      w.centre = glm::vec3(3.6f * i, 0.0f, 3.6f * j);
      w.path_radius = 0.9f + 0.1f * static_cast<float>((k * 5) % 4);
      w.clockwise = (k % 2) == 1;
      w.gait_cycles = 7 + (k % 3);
      w.phase = std::fmod(0.37f * k, 1.0f);
      w.path_phase = 0.7f * k;
      w.shirt = shirts[k];
      add_walker(s, clip, w, body);
    }
  s.clips.push_back(clip);
  s.active_clip = 0;
  s.camera.position = {0.0f, 7.5f, 12.5f};
  s.camera.target = {0.0f, 0.5f, 0.0f};
  s.camera.fov_y_deg = 45.0f;
  s.environment = default_sky();
  return s;
}

// --- validation scenes of paper 001 (spherical lights, section 8.2, figures 8-10; section 8.5) --------

// A ground plane of the usual kind (8 m, 128 x 128 vertices, albedo 0.7) under the default sky.
void add_ground(Scene& s, float width = 8.0f) {
  const int ground_mat = add_material(s, "ground", glm::vec3(0.7f));
  add_node(s, "ground", -1, glm::vec3(0.0f), glm::quat(1.0f, 0.0f, 0.0f, 0.0f), add_mesh(s, ground_plane(128, width, ground_mat)));
}

void set_view(Scene& s, glm::vec3 position, glm::vec3 target) {
  s.camera.position = position;
  s.camera.target = target;
  s.camera.fov_y_deg = 45.0f;
  s.environment = default_sky();
}

// A rigid object: material, mesh and node; its proxy set (node space spheres) gets the material's albedo.
int add_rigid(Scene& s, const std::string& name, glm::vec3 albedo, Mesh mesh, glm::vec3 t, glm::quat r, std::vector<Sphere> spheres,
              double outside_volume_ratio = -1.0) {
  mesh.material = add_material(s, name, albedo);
  const int node = add_node(s, name, -1, t, r, add_mesh(s, std::move(mesh)));
  ProxySet ps;
  ps.name = name;
  ps.node = node;
  ps.spheres = std::move(spheres);
  ps.albedo = albedo;
  ps.outside_volume_ratio = outside_volume_ratio;
  s.proxies.push_back(std::move(ps));
  return node;
}

double sphere_volume(float r) { return 4.0 / 3.0 * 3.14159265358979323846 * std::pow(static_cast<double>(r), 3); }

// Figure 8, first row: one diffuse sphere on the plane, its proxy the sphere itself (the method's
// optimal case). Static.
Scene make_sphere_plane() {
  Scene s;
  s.name = "sphere_plane";
  s.source = "builtin:sphere_plane";
  add_ground(s);
  constexpr float kRadius = 0.5f;
  Mesh m = uv_sphere("sphere", kRadius, 64, 32, 0);
  const double e = sphere_volume(kRadius) / closed_volume(m) - 1.0;
  add_rigid(s, "sphere", {0.9f, 0.12f, 0.08f}, std::move(m), {0.0f, kRadius, 0.0f}, glm::quat(1.0f, 0.0f, 0.0f, 0.0f),
            {{glm::vec3(0.0f), kRadius}}, e);
  set_view(s, {0.0f, 1.5f, 3.4f}, {0.0f, 0.35f, 0.0f});
  return s;
}

// Figure 10: a 0.8 m cube on the plane turned 30 degrees about +y (two faces towards the camera and the
// sun), bounded by one sphere (its circumsphere, `box1`) or by its 8 octants' circumspheres (`box8`).
// Static.
constexpr float kBoxHalf = 0.4f;
constexpr float kBoxYaw = 30.0f * kDeg;
Scene make_box(bool octants) {
  Scene s;
  s.name = octants ? "box8" : "box1";
  s.source = "builtin:" + s.name;
  add_ground(s);
  const glm::vec3 half(kBoxHalf);
  std::vector<Sphere> spheres = octants ? box_cell_spheres(half) : std::vector<Sphere>{{glm::vec3(0.0f), glm::length(half)}};
  const double e = octants ? -1.0 : sphere_volume(glm::length(half)) / (8.0 * std::pow(static_cast<double>(kBoxHalf), 3)) - 1.0;
  add_rigid(s, "box", {0.15f, 0.35f, 0.85f}, box_mesh("box", half, 9, 0), {0.0f, kBoxHalf, 0.0f}, yaw(kBoxYaw), std::move(spheres), e);
  set_view(s, {0.0f, 1.6f, 3.6f}, {0.0f, 0.4f, 0.0f});
  return s;
}
Scene make_box1() { return make_box(false); }
Scene make_box8() { return make_box(true); }

// A capped cylinder standing on its base, skinned to a chain of bones along its axis (+y at rest):
// bone 0 spans [0, base], bones 1..bend_bones each `bone` long above it, so length = base +
// bend_bones * bone. Bones 1..n each turn by angle / n about their joint, bending the cylinder in its
// local x-y plane towards +x; at angle pi the last bone points straight down, its end at height
// base - bone (the joint heights are symmetric about the middle of the bend), the two legs
// bone * sum_i sin(i pi / n) apart.
//
// Weights: within bone / 2 of a joint a point blends the two bones meeting there, half and half at the
// joint, fading (smoothstep) to its own bone at the midpoints between joints; below the first joint's
// blend zone it is rigid on bone 0, above the last's rigid on the last bone. So every blended point
// mixes two bones that both keep that joint fixed, and its posed position stays within its rest
// distance of the posed joint (a convex combination of two points at that distance). Hence the
// proxies: one sphere centred on each joint bounding the slab of half-width bone / 2 around it, plus
// one sphere over each rigid end slab on its bone, bound the mesh in every bent state, not only at
// rest (n + 2 spheres).
//
// Six bend bones turn 30 degrees each at the full bend. Linear blending pulls the inside of each joint
// towards it (the inner surface reaches r cos(a / 2) from a joint turning by a, where the straight
// bones would meet at r / cos(a / 2)), so the inside of the 180 degree arch is scalloped: its
// distance from the bend's centre varies by 1.8 cm on the 0.15 m cylinder, 4.1 cm with four bones
// of 45 degrees.
struct BendSpec {
  float radius = 0.15f;
  float base = 0.4f;
  float bone = 0.2f;
  int bend_bones = 6;
  float length() const { return base + bend_bones * bone; }
  float joint(int i) const { return base + (i - 1) * bone; }  // height of joint i = 1..bend_bones (origin of bone i)
  // Distance between the legs' axes at the full bend (pi).
  float span() const {
    float x = 0.0f;
    for (int i = 1; i < bend_bones; ++i) x += bone * std::sin(kPi * i / bend_bones);
    return x;
  }
};

struct BoneWeights {
  glm::u16vec4 joints{0};
  glm::vec4 weights{0.0f};
};
BoneWeights bend_weights(const BendSpec& b, float y) {
  const float h = 0.5f * b.bone;
  BoneWeights out;
  out.weights = {1.0f, 0.0f, 0.0f, 0.0f};
  // Own bone: the one containing y.
  const int own = std::clamp(static_cast<int>(std::floor((y - b.base) / b.bone)) + 1, 0, b.bend_bones);
  out.joints[0] = static_cast<std::uint16_t>(own);
  for (int i = 1; i <= b.bend_bones; ++i) {
    const float s = y - b.joint(i);
    if (std::abs(s) >= h) continue;
    const float x = std::abs(s) / h, smooth = x * x * (3.0f - 2.0f * x);
    const float w_other = 0.5f * (1.0f - smooth);
    const int a = s >= 0.0f ? i : i - 1, other = s >= 0.0f ? i - 1 : i;  // the two bones meeting at joint i
    out.joints = {static_cast<std::uint16_t>(a), static_cast<std::uint16_t>(other), 0, 0};
    out.weights = {1.0f - w_other, w_other, 0.0f, 0.0f};
  }
  return out;
}

Mesh bend_cylinder_mesh(const std::string& name, const BendSpec& b, int material) {
  constexpr int kSegments = 32;
  constexpr float kRingSpacing = 0.025f;  // smooth bending between joints
  const float len = b.length();
  const int rings = 1 + static_cast<int>(std::ceil(len / kRingSpacing));
  Mesh m;
  m.name = name;
  m.material = material;
  auto push = [&](glm::vec3 p, glm::vec3 n) {
    m.positions.push_back(p);
    m.normals.push_back(n);
    const BoneWeights w = bend_weights(b, p.y);
    m.joints.push_back(w.joints);
    m.weights.push_back(w.weights);
    return static_cast<unsigned>(m.positions.size()) - 1;
  };
  auto radial = [](int j) {
    const float ph = 2.0f * kPi * j / kSegments;
    return glm::vec3(std::cos(ph), 0.0f, -std::sin(ph));
  };
  // Side: rings at heights 0..len with radial normals.
  std::vector<unsigned> first(rings);
  for (int i = 0; i < rings; ++i) {
    const float y = len * i / (rings - 1);
    first[i] = static_cast<unsigned>(m.positions.size());
    for (int j = 0; j < kSegments; ++j) push(b.radius * radial(j) + glm::vec3(0.0f, y, 0.0f), radial(j));
  }
  for (int i = 0; i + 1 < rings; ++i)
    for (int j = 0; j < kSegments; ++j) {
      const unsigned j1 = (j + 1) % kSegments;
      add_tri(m, first[i] + j, first[i] + j1, first[i + 1] + j1);
      add_tri(m, first[i] + j, first[i + 1] + j1, first[i + 1] + j);
    }
  // Flat caps: a centre and a rim of their own with the cap's normal.
  for (int cap = 0; cap < 2; ++cap) {
    const float y = cap == 0 ? 0.0f : len;
    const glm::vec3 n(0.0f, cap == 0 ? -1.0f : 1.0f, 0.0f);
    const unsigned centre = push({0.0f, y, 0.0f}, n);
    const unsigned rim = static_cast<unsigned>(m.positions.size());
    for (int j = 0; j < kSegments; ++j) push(b.radius * radial(j) + glm::vec3(0.0f, y, 0.0f), n);
    for (int j = 0; j < kSegments; ++j) add_tri(m, centre, rim + j, rim + (j + 1) % kSegments);
  }
  return m;
}

// The proxy spheres of the comment above BendSpec, with the weights of their centres.
void bend_proxies(const BendSpec& b, ProxySet& ps) {
  const float h = 0.5f * b.bone, r2 = b.radius * b.radius;
  auto add = [&](float y, float half_slab) {
    ps.spheres.push_back({{0.0f, y, 0.0f}, std::sqrt(half_slab * half_slab + r2) * (1.0f + 1e-5f)});
    const BoneWeights w = bend_weights(b, y);
    ps.joints.push_back(w.joints);
    ps.weights.push_back(w.weights);
  };
  const float low = b.joint(1) - h, high = b.joint(b.bend_bones) + h, len = b.length();
  add(0.5f * low, 0.5f * low);
  for (int i = 1; i <= b.bend_bones; ++i) add(b.joint(i), h);
  add(0.5f * (high + len), 0.5f * (len - high));
}

// Adds a bending cylinder at `base_pos` (its local frame turned by `heading` about +y): root node,
// bone chain, skin, skinned mesh and proxy set; `angle(t)` (radians, total bend) keyed on the bend
// bones' rotations into `clip` with `keys` + 1 uniform keys.
void add_bend(Scene& s, AnimationClip& clip, const std::string& name, const BendSpec& b, glm::vec3 base_pos, float heading,
              glm::vec3 albedo, int keys, const std::function<float(float)>& angle) {
  const int material = add_material(s, name, albedo);
  const int root = add_node(s, name, -1, base_pos, yaw(heading));
  Skin skin;
  skin.name = name;
  int parent = root;
  float parent_len = 0.0f, start = 0.0f;
  for (int i = 0; i <= b.bend_bones; ++i) {
    const int node = add_node(s, name + "/bone" + std::to_string(i), parent, {0.0f, parent_len, 0.0f});
    skin.joints.push_back(node);
    glm::mat4 ib(1.0f);
    ib[3] = glm::vec4(0.0f, -start, 0.0f, 1.0f);
    skin.inverse_bind.push_back(ib);
    parent = node;
    parent_len = i == 0 ? b.base : b.bone;
    start += parent_len;
  }
  s.skins.push_back(skin);
  const int mesh_node = add_node(s, name + "/mesh", root, glm::vec3(0.0f), glm::quat(1.0f, 0.0f, 0.0f, 0.0f),
                                 add_mesh(s, bend_cylinder_mesh(name, b, material)));
  s.nodes[mesh_node].skin = static_cast<int>(s.skins.size()) - 1;
  ProxySet ps;
  ps.name = name;
  ps.node = mesh_node;
  ps.albedo = albedo;
  bend_proxies(b, ps);
  s.proxies.push_back(std::move(ps));
  for (int i = 1; i <= b.bend_bones; ++i)
    clip.channels.push_back(sampled_channel(skin.joints[i], AnimationChannel::Path::Rotation, clip.duration, keys, [&](float t) {
      return qv(axis_angle({0.0f, 0.0f, -1.0f}, angle(t) / static_cast<float>(b.bend_bones)));
    }));
}

// Figure 9: a cylinder (radius 0.15 m, 1.6 m long, 7 bones) standing on the plane bends into an arch:
// straight at t = 0, 90 degrees at t = 1 s, 180 degrees at t = 2 s (the free end 0.2 m above the
// ground, the legs' axes 0.75 m apart), held to the end of the 3 s clip (no loop).
Scene make_bend() {
  Scene s;
  s.name = "bend";
  s.source = "builtin:bend";
  add_ground(s);
  AnimationClip clip;
  clip.name = "bend";
  clip.duration = 3.0f;
  clip.loop = false;
  const BendSpec b;
  // Base placed so that the 180 degree arch is centred on x = 0.
  add_bend(s, clip, "cylinder", b, {-0.5f * b.span(), 0.0f, 0.0f}, 0.0f, {0.2f, 0.7f, 0.25f}, 12,
           [](float t) { return 0.5f * kPi * std::clamp(t, 0.0f, 2.0f); });
  s.clips.push_back(clip);
  s.active_clip = 0;
  set_view(s, {0.6f, 1.5f, 3.9f}, {0.0f, 0.75f, 0.0f});
  return s;
}

// Section 8.5's benchmarking scene, in spirit: several moving and deforming objects of different
// shapes and colours on the plane, which never intersect each other (8 s loop).
Scene make_assembly() {
  Scene s;
  s.name = "assembly";
  s.source = "builtin:assembly";
  add_ground(s);
  constexpr float kT = 8.0f;
  constexpr int kKeys = 64;  // every 0.125 s
  AnimationClip clip;
  clip.name = "assembly";
  clip.duration = kT;
  clip.loop = true;
  using P = AnimationChannel::Path;
  const glm::quat id(1.0f, 0.0f, 0.0f, 0.0f);
  auto w = [](float t) { return 2.0f * kPi * t / kT; };

  // A red ball rolling back and forth along x in front (turning about -z by its travel / radius).
  {
    constexpr float r = 0.35f;
    auto x = [&](float t) { return 1.7f * std::sin(w(t)); };
    const int n = add_rigid(s, "ball_red", {0.85f, 0.15f, 0.1f}, uv_sphere("ball_red", r, 48, 24, 0), {x(0.0f), r, 0.9f}, id, {{glm::vec3(0.0f), r}});
    clip.channels.push_back(sampled_channel(n, P::Translation, kT, kKeys, [&](float t) { return glm::vec4(x(t), r, 0.9f, 0.0f); }));
    clip.channels.push_back(sampled_channel(n, P::Rotation, kT, kKeys, [&](float t) { return qv(axis_angle({0.0f, 0.0f, -1.0f}, x(t) / r)); }));
  }
  // A blue ball sliding on a 0.6 m circle at the back left.
  {
    constexpr float r = 0.25f;
    auto p = [&](float t) { return glm::vec4(-2.0f + 0.6f * std::cos(w(t)), r, -1.0f - 0.6f * std::sin(w(t)), 0.0f); };
    const int n = add_rigid(s, "ball_blue", {0.15f, 0.3f, 0.85f}, uv_sphere("ball_blue", r, 48, 24, 0), glm::vec3(p(0.0f)), id, {{glm::vec3(0.0f), r}});
    clip.channels.push_back(sampled_channel(n, P::Translation, kT, kKeys, p));
  }
  // A small green ball hopping in place, four hops per loop.
  {
    constexpr float r = 0.2f;
    auto p = [&](float t) { return glm::vec4(1.2f, r + 0.45f * std::abs(std::sin(2.0f * w(t))), -0.3f, 0.0f); };
    const int n = add_rigid(s, "ball_green", {0.25f, 0.75f, 0.25f}, uv_sphere("ball_green", r, 48, 24, 0), glm::vec3(p(0.0f)), id, {{glm::vec3(0.0f), r}});
    clip.channels.push_back(sampled_channel(n, P::Translation, kT, kKeys, p));
  }
  // A yellow 0.6 m crate sliding along z on the right, swinging +-20 degrees about +y (octant proxies).
  {
    const glm::vec3 half(0.3f);
    auto p = [&](float t) { return glm::vec4(2.2f, half.y, -1.3f + 0.7f * std::sin(w(t) + 1.0f), 0.0f); };
    const int n = add_rigid(s, "crate", {0.85f, 0.7f, 0.15f}, box_mesh("crate", half, 9, 0), glm::vec3(p(0.0f)), id, box_cell_spheres(half));
    clip.channels.push_back(sampled_channel(n, P::Translation, kT, kKeys, p));
    clip.channels.push_back(sampled_channel(n, P::Rotation, kT, kKeys, [&](float t) { return qv(yaw(20.0f * kDeg * std::sin(2.0f * w(t)))); }));
  }
  // A purple 0.4 x 0.8 x 0.4 m pillar turning once per loop at the left; proxies: the circumspheres of
  // its four 0.4 x 0.2 x 0.4 m layers (box_cell_spheres would take 16).
  {
    const glm::vec3 half(0.2f, 0.4f, 0.2f);
    std::vector<Sphere> layers;
    for (int i = 0; i < 4; ++i) layers.push_back({{0.0f, -half.y + 0.5f * half.y * (i + 0.5f), 0.0f}, glm::length(glm::vec3(half.x, 0.25f * half.y, half.z))});
    const int n = add_rigid(s, "pillar", {0.55f, 0.25f, 0.65f}, box_mesh("pillar", half, 9, 0), {-1.1f, half.y, 0.0f}, id, std::move(layers));
    clip.channels.push_back(sampled_channel(n, P::Rotation, kT, 32, [&](float t) { return qv(yaw(w(t))); }));
  }
  // An orange cylinder at the back bending into an arch and back (0 -> 180 -> 0 degrees).
  {
    BendSpec b;
    b.radius = 0.12f;
    b.base = 0.3f;
    b.bone = 0.15f;
    add_bend(s, clip, "arm", b, {-0.3f, 0.0f, -1.2f}, 0.0f, {0.9f, 0.45f, 0.1f}, kKeys,
             [&](float t) { return 0.5f * kPi * (1.0f - std::cos(w(t))); });
  }
  s.clips.push_back(clip);
  s.active_clip = 0;
  set_view(s, {0.0f, 2.5f, 5.8f}, {0.0f, 0.2f, -0.5f});
  return s;
}

// --- bunny ---------------------------------------------------------------------------------------------

// The 32-sphere fit takes seconds; it is deterministic, so one fit per process and model file
// (keyed by path, size and modification time) serves every make_builtin("bunny").
Scene make_bunny() {
  const std::string path = assets_dir() + "/models/bunny.glb";
  if (!std::filesystem::exists(path))
    throw std::runtime_error("built-in scene 'bunny' needs " + path +
                             ", which is missing: run scripts/fetch-assets.sh (or point SOFTGI_ASSETS at the asset folder)");
  Scene s;
  s.name = "bunny";
  s.source = "builtin:bunny";
  const io::GltfImport imp = io::load_gltf(path, s);
  int mesh_node = -1;
  for (int i = 0; i < static_cast<int>(s.nodes.size()); ++i)
    if (s.nodes[i].mesh >= 0) {
      mesh_node = i;
      break;
    }
  if (mesh_node < 0) throw std::runtime_error(path + ": no mesh found for built-in scene 'bunny'");
  s.clips.clear();  // the file has none; the scene's own turntable clip follows
  s.active_clip = -1;

  // Stand the model on the ground at the origin, about 1 m tall, turning about its vertical axis.
  const Bounds rest = bounds(evaluate(s, 0.0));
  const glm::vec3 size = rest.hi - rest.lo;
  const float scale = 1.0f / std::max(size.y, 1e-6f);
  const glm::vec3 foot((rest.lo.x + rest.hi.x) * 0.5f, rest.lo.y, (rest.lo.z + rest.hi.z) * 0.5f);
  const int turntable = add_node(s, "bunny", -1, glm::vec3(0.0f));
  const int offset = add_node(s, "bunny_offset", turntable, -scale * foot);
  s.nodes[offset].scale = glm::vec3(scale);
  for (int r : imp.root_nodes) s.nodes[r].parent = offset;

  const int ground_mat = add_material(s, "ground", glm::vec3(0.7f));
  add_node(s, "ground", -1, glm::vec3(0.0f), glm::quat(1.0f, 0.0f, 0.0f, 0.0f), add_mesh(s, ground_plane(128, 8.0f, ground_mat)));

  AnimationClip clip;
  clip.name = "turntable";
  clip.duration = 20.0f;
  clip.channels.push_back(sampled_channel(turntable, AnimationChannel::Path::Rotation, clip.duration, 8,
                                          [&](float t) { return qv(yaw(2.0f * kPi * t / clip.duration)); }));
  s.clips.push_back(clip);
  s.active_clip = static_cast<int>(s.clips.size()) - 1;

  // Proxies: the 32-sphere fit of paper 004 section 6.2, from the fit cache (keyed by the mesh and
  // the fitting code's version, so a changed asset or fit is never read stale) or fitted now.
  io::ProxyFitSpec spec;
  spec.spheres = 32;
  io::ProxyFitOutcome fit = io::fit_node_proxies(s, mesh_node, spec, io::proxy_cache_dir());
  fit.set.name = "bunny";
  s.proxies.push_back(std::move(fit.set));

  s.camera.position = {0.0f, 0.8f, 2.8f};
  s.camera.target = {0.0f, 0.45f, 0.0f};
  s.camera.fov_y_deg = 45.0f;
  s.environment = default_sky();
  return s;
}

// --- scenes of paper 002 (point-proxy voxels, Chen et al. 2014: Figures 1, 5 and 6) -------------------

// An environment that emits nothing: the scene's local lights are its only light (the paper's
// setting; the background renders black).
Environment dark_environment() {
  Environment e;
  e.zenith = e.horizon = e.ground = glm::vec3(0.0f);
  e.sun_radiance = glm::vec3(0.0f);
  return e;
}

int add_glossy_material(Scene& s, const std::string& name, glm::vec3 albedo, float ns, float glossy) {
  const int m = add_material(s, name, albedo);
  s.materials[m].phong_ns = ns;
  s.materials[m].glossy = glossy;
  return m;
}

// A checkerboard of `checks` x `checks` squares in two colours (linear RGB), 8 texels per square.
int add_checker_texture(Scene& s, const std::string& name, int checks, glm::vec3 a, glm::vec3 b) {
  Texture t;
  t.name = name;
  t.width = t.height = 8 * checks;
  t.texels.resize(static_cast<std::size_t>(t.width) * t.height);
  for (int y = 0; y < t.height; ++y)
    for (int x = 0; x < t.width; ++x) t.texels[static_cast<std::size_t>(y) * t.width + x] = ((x / 8 + y / 8) % 2) ? a : b;
  s.textures.push_back(std::move(t));
  return static_cast<int>(s.textures.size()) - 1;
}

// A spherical light fixed in world space.
void add_point_light(Scene& s, const std::string& name, glm::vec3 position, float radius, glm::vec3 radiance) {
  SphericalLight l;
  l.name = name;
  l.position = position;
  l.radius = radius;
  l.radiance = radiance;
  s.lights.push_back(l);
}

// A vertical cylinder (axis +y from y = 0 to height), open at both ends: the columns of `atrium`.
Mesh cylinder_mesh(const std::string& name, float radius, float height, int segments, int rings, int material) {
  Mesh m;
  m.name = name;
  m.material = material;
  for (int i = 0; i <= rings; ++i)
    for (int j = 0; j <= segments; ++j) {
      const float a = 2.0f * kPi * j / segments;
      const glm::vec3 n(std::cos(a), 0.0f, std::sin(a));
      m.positions.push_back(radius * n + glm::vec3(0.0f, height * i / rings, 0.0f));
      m.normals.push_back(n);
      m.uvs.push_back({static_cast<float>(j) / segments, static_cast<float>(i) / rings});
    }
  for (int i = 0; i < rings; ++i)
    for (int j = 0; j < segments; ++j) {
      const unsigned a = i * (segments + 1) + j, b = a + 1, c = a + (segments + 1), d = c + 1;
      add_tri(m, a, b, d);
      add_tri(m, a, d, c);
    }
  return m;
}

// An arch between two columns: the lower (intrados) surface of a half ring of radius `radius` in the
// xy plane centred at the origin, `depth` deep along z, facing its centre, plus the flat wall above
// it up to y = top (the spandrel), facing +z and -z. Built in the arch's own frame.
Mesh arch_mesh(const std::string& name, float radius, float depth, float top, int segments, int material) {
  Mesh m;
  m.name = name;
  m.material = material;
  // Intrados: points (r cos a, r sin a, z), normal towards the centre.
  for (int j = 0; j <= segments; ++j) {
    const float a = kPi * j / segments;
    const glm::vec3 d(std::cos(a), std::sin(a), 0.0f);
    for (float z : {-0.5f * depth, 0.5f * depth}) {
      m.positions.push_back(radius * d + glm::vec3(0.0f, 0.0f, z));
      m.normals.push_back(-d);
    }
  }
  for (int j = 0; j < segments; ++j) {
    const unsigned a = 2 * j, b = a + 1, c = a + 2, d = a + 3;
    add_tri(m, a, c, d);
    add_tri(m, a, d, b);
  }
  // Spandrels on both faces: each ring point joined to the point straight above it at y = top.
  for (float side : {-1.0f, 1.0f}) {
    const unsigned base = static_cast<unsigned>(m.positions.size());
    const glm::vec3 n(0.0f, 0.0f, side);
    for (int j = 0; j <= segments; ++j) {
      const float a = kPi * j / segments;
      const glm::vec3 p(radius * std::cos(a), radius * std::sin(a), side * 0.5f * depth);
      m.positions.push_back(p);
      m.normals.push_back(n);
      m.positions.push_back({p.x, top, p.z});
      m.normals.push_back(n);
    }
    for (int j = 0; j < segments; ++j) {
      const unsigned a = base + 2 * j, b = a + 1, c = a + 2, d = a + 3;
      add_tri(m, a, c, d);
      add_tri(m, a, d, b);
    }
  }
  return m;
}

// Figures 1a and 5: the Cornell box of `cornell`, static, lit only by a small spherical light under
// the ceiling, with a glossy floor (Phong exponent Ns = 50, the paper's).
Scene make_cornell_glossy() {
  Scene s = make_cornell();
  s.name = "cornell_glossy";
  s.source = "builtin:cornell_glossy";
  s.clips.clear();
  s.active_clip = -1;
  const int floor_mat = add_glossy_material(s, "glossy_floor", {0.73f, 0.73f, 0.73f}, 50.0f, 0.5f);
  for (auto& n : s.nodes)
    if (n.name == "floor") s.meshes[n.mesh].material = floor_mat;
  // The light hangs at the ceiling's centre; its node keeps the rest pose.
  s.lights[0].radius = 0.06f;
  s.lights[0].radiance = glm::vec3(520.0f, 470.0f, 400.0f);  // ~2 W/m^2 on the floor below
  for (auto& n : s.nodes)
    if (n.name == "ceiling_light") n.translation = {0.0f, 1.7f, 0.0f};
  s.environment = dark_environment();
  return s;
}

// Figure 6: five glossy floor strips with Ns = 10, 20, 30, 40, 50 (left to right) under a local light,
// reflecting a textured back wall, an orange sphere and a blue box standing on them.
Scene make_glossy_sweep() {
  Scene s;
  s.name = "glossy_sweep";
  s.source = "builtin:glossy_sweep";
  for (int k = 0; k < 5; ++k) {
    const float ns = 10.0f * (k + 1);
    const int mat = add_glossy_material(s, "strip_ns" + std::to_string(static_cast<int>(ns)), glm::vec3(0.7f), ns, 0.6f);
    Mesh m;
    m.name = "strip" + std::to_string(k);
    m.material = mat;
    append_grid(m, {-2.0f + 0.8f * k, 0.0f, -1.2f}, {0.8f, 0.0f, 0.0f}, {0.0f, 0.0f, 2.4f}, 9, 25, {0.0f, 1.0f, 0.0f});
    add_node(s, k == 2 ? "ground" : m.name, -1, glm::vec3(0.0f), glm::quat(1.0f, 0.0f, 0.0f, 0.0f), add_mesh(s, std::move(m)));
  }
  const int wall_mat = add_material(s, "checker_wall", glm::vec3(1.0f));
  s.materials[wall_mat].albedo_texture = add_checker_texture(s, "checker", 8, {0.75f, 0.7f, 0.6f}, {0.15f, 0.2f, 0.45f});
  Mesh wall;
  wall.name = "back_wall";
  wall.material = wall_mat;
  append_grid(wall, {-2.0f, 0.0f, -1.2f}, {4.0f, 0.0f, 0.0f}, {0.0f, 2.0f, 0.0f}, 33, 17, {0.0f, 0.0f, 1.0f});
  add_node(s, "back_wall", -1, glm::vec3(0.0f), glm::quat(1.0f, 0.0f, 0.0f, 0.0f), add_mesh(s, std::move(wall)));
  constexpr float kR = 0.35f;
  add_rigid(s, "sphere", {0.9f, 0.45f, 0.1f}, uv_sphere("sphere", kR, 48, 24, 0), {-0.6f, kR, -0.4f}, glm::quat(1.0f, 0.0f, 0.0f, 0.0f),
            {{glm::vec3(0.0f), kR}});
  const glm::vec3 half(0.25f, 0.4f, 0.25f);
  add_rigid(s, "box", {0.15f, 0.3f, 0.8f}, box_mesh("box", half, 9, 0), {0.8f, half.y, -0.5f}, yaw(25.0f * kDeg), box_cell_spheres(half));
  add_point_light(s, "light", {0.0f, 2.2f, 0.9f}, 0.08f, glm::vec3(400.0f));
  s.camera.position = {0.0f, 1.3f, 3.4f};
  s.camera.target = {0.0f, 0.35f, -0.3f};
  s.camera.fov_y_deg = 50.0f;
  s.environment = dark_environment();
  return s;
}

// Figure 1c's stand-in for Crytek Sponza (which cannot be shipped): a 16 m x 6 m roofless court with a
// glossy floor (Ns = 50), two colonnades of six columns joined by arches carrying an upper wall, a
// textured back wall, lit by the sky and a sun that reaches the floor between the colonnades. The
// paper's setting for Sponza is 170k point proxies on a 20^3 grid.
Scene make_atrium() {
  Scene s;
  s.name = "atrium";
  s.source = "builtin:atrium";
  const float len = 16.0f, half_w = 3.0f, col_r = 0.22f, col_h = 3.0f, spacing = len / 6.0f;
  const int floor_mat = add_glossy_material(s, "marble", {0.6f, 0.58f, 0.55f}, 50.0f, 0.35f);
  Mesh floor;
  floor.name = "ground";
  floor.material = floor_mat;
  append_grid(floor, {-0.5f * len, 0.0f, -half_w - 1.5f}, {len, 0.0f, 0.0f}, {0.0f, 0.0f, 2.0f * half_w + 3.0f}, 65, 37, {0.0f, 1.0f, 0.0f});
  add_node(s, "ground", -1, glm::vec3(0.0f), glm::quat(1.0f, 0.0f, 0.0f, 0.0f), add_mesh(s, std::move(floor)));
  const int stone = add_material(s, "stone", {0.7f, 0.62f, 0.5f});
  const int red_stone = add_material(s, "red_stone", {0.65f, 0.25f, 0.18f});
  // Side walls behind the colonnades (the aisles' outer walls), facing the court.
  for (float side : {-1.0f, 1.0f}) {
    Mesh w;
    w.name = side < 0 ? "wall_north" : "wall_south";
    w.material = side < 0 ? red_stone : stone;
    const float z = side * (half_w + 1.5f);
    append_grid(w, {-0.5f * len, 0.0f, z}, {len, 0.0f, 0.0f}, {0.0f, 5.5f, 0.0f}, 65, 23, {0.0f, 0.0f, -side});
    add_node(s, w.name, -1, glm::vec3(0.0f), glm::quat(1.0f, 0.0f, 0.0f, 0.0f), add_mesh(s, std::move(w)));
  }
  const int wall_mat = add_material(s, "tapestry", glm::vec3(1.0f));
  s.materials[wall_mat].albedo_texture = add_checker_texture(s, "tapestry", 12, {0.7f, 0.6f, 0.35f}, {0.25f, 0.1f, 0.1f});
  Mesh back;
  back.name = "back_wall";
  back.material = wall_mat;
  append_grid(back, {-0.5f * len, 0.0f, -half_w - 1.5f}, {0.0f, 0.0f, 2.0f * half_w + 3.0f}, {0.0f, 5.5f, 0.0f}, 37, 23, {1.0f, 0.0f, 0.0f});
  add_node(s, "back_wall", -1, glm::vec3(0.0f), glm::quat(1.0f, 0.0f, 0.0f, 0.0f), add_mesh(s, std::move(back)));
  // Colonnades: columns with stacked-sphere proxies (each sphere bounds a slice of the column) and
  // arches between neighbours, under an upper wall band (the arches' spandrels reach y = 4.2).
  const float arch_r = 0.5f * spacing - col_r;
  for (float side : {-1.0f, 1.0f}) {
    const float z = side * half_w;
    for (int c = 0; c <= 6; ++c) {
      const float x = -0.5f * len + spacing * c;
      const std::string name = std::string(side < 0 ? "col_n" : "col_s") + std::to_string(c);
      std::vector<Sphere> slices;
      for (int k = 0; k < 6; ++k) {
        const float h = col_h / 6.0f;
        slices.push_back({{0.0f, h * (k + 0.5f), 0.0f}, std::sqrt(col_r * col_r + 0.25f * h * h)});
      }
      add_rigid(s, name, {0.75f, 0.72f, 0.66f}, cylinder_mesh(name, col_r, col_h, 20, 6, 0), {x, 0.0f, z},
                glm::quat(1.0f, 0.0f, 0.0f, 0.0f), std::move(slices));
      if (c == 6) continue;
      const std::string an = std::string(side < 0 ? "arch_n" : "arch_s") + std::to_string(c);
      add_node(s, an, -1, {x + 0.5f * spacing, col_h, z}, glm::quat(1.0f, 0.0f, 0.0f, 0.0f),
               add_mesh(s, arch_mesh(an, arch_r, 2.0f * col_r, arch_r + 1.2f, 16, stone)));
    }
  }
  s.camera.position = {7.2f, 1.7f, 0.0f};
  s.camera.target = {-2.0f, 1.6f, 0.0f};
  s.camera.fov_y_deg = 60.0f;
  s.environment = default_sky();
  s.environment.sun_direction = glm::normalize(glm::vec3(-0.35f, 0.75f, 0.35f));
  return s;
}

// Light leaking, the best-known failure of voxel GI: a room open at the front, split by a 2 cm wall
// from floor to ceiling and from the back to the opening, lit by a spherical light in its left half
// only. No path of one bounce reaches the right half (every segment between the halves crosses the
// wall), so whatever indirect light a technique puts there leaked. The right half's floor is the
// node named `ground` (the region experiments measure); the environment is dark.
Scene make_thin_wall() {
  Scene s;
  s.name = "thin_wall";
  s.source = "builtin:thin_wall";
  const int white = add_material(s, "white", glm::vec3(0.75f));
  const int warm = add_material(s, "warm", {0.8f, 0.55f, 0.3f});
  struct Quad {
    const char* name;
    glm::vec3 origin, du, dv, normal;
    int material, nu, nv;
  };
  const Quad quads[] = {
      {"floor_left", {-2.0f, 0.0f, -1.5f}, {1.99f, 0.0f, 0.0f}, {0.0f, 0.0f, 3.0f}, {0, 1, 0}, warm, 17, 25},
      {"ground", {0.01f, 0.0f, -1.5f}, {1.99f, 0.0f, 0.0f}, {0.0f, 0.0f, 3.0f}, {0, 1, 0}, white, 17, 25},
      {"ceiling", {-2.0f, 2.5f, -1.5f}, {4.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 3.0f}, {0, -1, 0}, white, 33, 25},
      {"back_wall", {-2.0f, 0.0f, -1.5f}, {4.0f, 0.0f, 0.0f}, {0.0f, 2.5f, 0.0f}, {0, 0, 1}, white, 33, 21},
      {"left_wall", {-2.0f, 0.0f, -1.5f}, {0.0f, 2.5f, 0.0f}, {0.0f, 0.0f, 3.0f}, {1, 0, 0}, white, 21, 25},
      {"right_wall", {2.0f, 0.0f, -1.5f}, {0.0f, 2.5f, 0.0f}, {0.0f, 0.0f, 3.0f}, {-1, 0, 0}, white, 21, 25},
  };
  for (const auto& q : quads) {
    Mesh m;
    m.name = q.name;
    m.material = q.material;
    append_grid(m, q.origin, q.du, q.dv, q.nu, q.nv, q.normal);
    add_node(s, q.name, -1, glm::vec3(0.0f), glm::quat(1.0f, 0.0f, 0.0f, 0.0f), add_mesh(s, std::move(m)));
  }
  add_node(s, "divider", -1, {0.0f, 1.25f, 0.0f}, glm::quat(1.0f, 0.0f, 0.0f, 0.0f),
           add_mesh(s, box_mesh("divider", {0.01f, 1.25f, 1.5f}, 13, white)));
  add_point_light(s, "light", {-1.0f, 2.1f, 0.0f}, 0.06f, glm::vec3(450.0f, 420.0f, 380.0f));
  s.camera.position = {0.0f, 1.25f, 5.2f};
  s.camera.target = {0.0f, 1.0f, 0.0f};
  s.camera.fov_y_deg = 50.0f;
  s.environment = dark_environment();
  return s;
}

struct Entry {
  BuiltinInfo info;
  Scene (*make)();
};
const std::vector<Entry>& registry() {
  static const std::vector<Entry> entries = {
      {{"spheres", "ground plane and four UV spheres of different radii orbiting and hopping; proxies equal the spheres", false}, make_spheres},
      {{"cornell", "Cornell box open to the sky, two blocks (box proxies: cell spheres), spherical light circling under the ceiling", false}, make_cornell},
      {{"character", "procedural skinned humanoid (15 bones) walking a circle on a ground plane; bone-bound proxy spheres", false}, make_character},
      {{"crowd", "nine walking characters on circular paths with different cadences and phases", false}, make_crowd},
      {{"sphere_plane", "one diffuse red sphere resting on a ground plane, static; its proxy is the sphere", false}, make_sphere_plane},
      {{"box1", "a 0.8 m cube on a ground plane, static; one proxy sphere (its circumsphere)", false}, make_box1},
      {{"box8", "the box1 cube bounded by its 8 octant spheres, static", false}, make_box8},
      {{"bend", "skinned cylinder (7 bones) bending from straight (t = 0) to 90 (t = 1 s) and 180 degrees (t = 2 s); 8 bone-bound proxy spheres", false}, make_bend},
      {{"assembly", "six moving objects (rolling, sliding, hopping balls, a crate, a turning pillar, a bending cylinder) that never touch", false}, make_assembly},
      {{"cornell_glossy", "the Cornell box, static, lit only by a small light under the ceiling, glossy floor (Ns = 50; paper 002 Figures 1a and 5)", false}, make_cornell_glossy},
      {{"glossy_sweep", "five glossy floor strips, Ns = 10 to 50, reflecting a textured wall, a sphere and a box under a local light (paper 002 Figure 6)", false}, make_glossy_sweep},
      {{"atrium", "roofless 16 m court with two colonnades, arches, a textured wall and a glossy floor under sky and sun (stand-in for Crytek Sponza, paper 002 Figure 1c)", false}, make_atrium},
      {{"thin_wall", "room split by a 2 cm wall, lit in its left half only: indirect light in the right half is leaked light", false}, make_thin_wall},
      {{"bunny", "Stanford bunny (asset set, Draco GLB) turning on a ground plane; 32-sphere proxy fit", true}, make_bunny},
  };
  return entries;
}

}  // namespace

std::vector<BuiltinInfo> builtin_scenes() {
  std::vector<BuiltinInfo> out;
  for (const auto& e : registry()) out.push_back(e.info);
  return out;
}

Scene make_builtin(const std::string& name) {
  for (const auto& e : registry())
    if (e.info.name == name) return e.make();
  std::string known;
  for (const auto& e : registry()) known += (known.empty() ? "" : ", ") + e.info.name;
  throw std::invalid_argument("unknown built-in scene '" + name + "' (known: " + known + ")");
}

}  // namespace softgi::scene
