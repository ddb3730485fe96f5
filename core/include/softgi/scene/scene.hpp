// The scene model shared by every technique, the reference renderer and the loaders.
//
// Units and frames: right-handed, +y up (glTF), metres; angles in radians unless a name says _deg.
// Radiance is linear RGB. Directions point away from the receiver (towards the light).
#pragma once

#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>
#include <cstdint>
#include <cstddef>
#include <string>
#include <vector>

namespace softgi::scene {

struct Texture {
  std::string name;
  int width = 0, height = 0;
  std::vector<glm::vec3> texels;  // linear RGB, row 0 at the top (v = 0)
  glm::vec3 sample(glm::vec2 uv) const;  // bilinear, repeat wrap
};

struct Material {
  std::string name = "default";
  glm::vec3 albedo{0.8f};    // diffuse albedo (multiplied by texture and vertex colour)
  int albedo_texture = -1;   // index into Scene::textures
  float phong_ns = 0.0f;     // Phong exponent of a glossy receiver (paper 002); 0 = diffuse only
  float glossy = 0.0f;       // weight of the glossy lobe in [0, 1] (diffuse weight is 1 - glossy)
};

struct Mesh {
  std::string name;
  std::vector<glm::vec3> positions;
  std::vector<glm::vec3> normals;    // required, one per vertex, unit length
  std::vector<glm::vec2> uvs;        // optional
  std::vector<glm::vec3> colors;     // optional per-vertex albedo multiplier
  std::vector<glm::uvec3> triangles;
  int material = 0;
  // Skinning (optional): up to 4 joints per vertex, indices into the node's Skin::joints.
  std::vector<glm::u16vec4> joints;
  std::vector<glm::vec4> weights;
  bool skinned() const { return !joints.empty(); }
};

struct Skin {
  std::string name;
  std::vector<int> joints;                 // node indices
  std::vector<glm::mat4> inverse_bind;     // one per joint
};

struct Node {
  std::string name;
  int parent = -1;
  glm::vec3 translation{0.0f};
  glm::quat rotation{1.0f, 0.0f, 0.0f, 0.0f};  // (w, x, y, z)
  glm::vec3 scale{1.0f};
  int mesh = -1;  // an object: a node with a mesh
  int skin = -1;
  glm::mat4 local() const;
};

// Keyframed animation of node transforms (glTF semantics: linear, step; rotations slerped).
struct AnimationChannel {
  int node = -1;
  enum class Path { Translation, Rotation, Scale } path = Path::Translation;
  enum class Interp { Linear, Step } interp = Interp::Linear;
  std::vector<float> times;        // seconds, strictly increasing
  std::vector<glm::vec4> values;   // xyz for T/S, quaternion (x, y, z, w) for R
};
struct AnimationClip {
  std::string name;
  float duration = 0.0f;
  bool loop = true;  // time wraps modulo duration
  std::vector<AnimationChannel> channels;
};

struct Sphere {
  glm::vec3 center{0.0f};
  float radius = 0.0f;
};

// A sphere set bounding one object (paper 004 section 6.2). Centres are stored in the object's rest
// pose and follow it: rigidly with the node, or skinned through bone weights (section 6.2,
// Animation: mean value coordinates premultiplied by the vertices' bone weights collapse to a few
// bones). Radii stay fixed (times the largest axis scale of the node or joint transforms, 1 for
// rigid motion).
struct ProxySet {
  std::string name;
  int node = -1;                          // the object (node with a mesh) it bounds
  std::vector<Sphere> spheres;            // rest pose, in the node's mesh space
  std::vector<glm::u16vec4> joints;       // optional per-sphere skinning (indices into the skin)
  std::vector<glm::vec4> weights;
  glm::vec3 albedo{0.8f};                 // for re-radiated (indirect) light
  // Optional per-sphere albedo (the surface each sphere stands for, e.g. a textured model's colours
  // averaged over the sphere's segment); empty: every sphere has `albedo`.
  std::vector<glm::vec3> sphere_albedo;
  glm::vec3 albedo_of(std::size_t sphere) const { return sphere < sphere_albedo.size() ? sphere_albedo[sphere] : albedo; }
  double outside_volume_ratio = -1.0;     // E of the fit when known (paper 004 eq. 35 / volume)
};

struct Camera {
  glm::vec3 position{0.0f, 1.0f, 4.0f};
  glm::vec3 target{0.0f, 0.5f, 0.0f};
  glm::vec3 up{0.0f, 1.0f, 0.0f};
  float fov_y_deg = 45.0f;
  int width = 512, height = 512;
};

// Distant lighting: an HDR lat-long map or an analytic sky with a sun disk.
struct Environment {
  enum class Kind { Sky, Map } kind = Kind::Sky;
  // Sky: radiance = mix(horizon, zenith, smoothstep(y)) above the horizon (y = sin elevation,
  // smoothstep(y) = 3y^2 - 2y^3), ground below; inside the sun disk of angular radius sun_radius
  // around sun_direction the radiance is sun_radiance (it replaces the sky there).
  glm::vec3 zenith{0.25f, 0.45f, 0.9f};
  glm::vec3 horizon{0.8f, 0.85f, 0.95f};
  glm::vec3 ground{0.3f, 0.28f, 0.25f};
  glm::vec3 sun_direction = glm::normalize(glm::vec3(0.5f, 0.8f, 0.3f));
  float sun_radius = 0.05f;  // radians (about 2.9 degrees: soft but directional)
  glm::vec3 sun_radiance{60.0f, 55.0f, 48.0f};
  // Map: lat-long, row 0 at the top, mapping of sh::latlong_direction (docs/sh.md); finite and
  // non-negative (validate; the scene-file loader clamps negative components and says so in notices).
  std::string map_path;
  int map_width = 0, map_height = 0;
  std::vector<float> map_rgb;  // width * height * 3
  float intensity = 1.0f;
  float rotation_y = 0.0f;     // rotation of the map/sky about +y, radians
  glm::vec3 radiance(const glm::vec3& dir) const;  // dir unit, world space
};

// Environment::radiance with what does not depend on the direction (the rotation's sine and cosine,
// the sun's unit direction and the cosine of its radius) worked out once: for passes that evaluate
// it per pixel. radiance() is this, so both give the same value to the bit. `env` must outlive it.
class EnvironmentRadiance {
 public:
  explicit EnvironmentRadiance(const Environment& env);
  glm::vec3 operator()(const glm::vec3& dir) const;
  // operator() of dir[0 .. n) into out[0 .. n), the same values to the bit: the sky in vector lanes
  // (scene/sky_run.cpp), a map one direction at a time. For the background pixels of an image.
  void operator()(const glm::vec3* dir, std::size_t n, glm::vec3* out) const;

 private:
  const Environment* env_;
  bool rotated_;
  float cos_r_, sin_r_;  // of -rotation_y
  glm::vec3 sun_;
  float cos_sun_;
};

// Local spherical light source (paper 004 section 7 "Analytic Lights", paper 001 section 7.3).
struct SphericalLight {
  std::string name;
  glm::vec3 position{0.0f};   // world space; in the node's space when node >= 0
  float radius = 0.1f;
  glm::vec3 radiance{10.0f};  // emitted radiance of its surface
  int node = -1;              // optional: moves with this node
};

struct Scene {
  std::string name;
  std::string source;  // file it came from, or "builtin:NAME"
  std::vector<Mesh> meshes;
  std::vector<Material> materials;
  std::vector<Texture> textures;
  std::vector<Node> nodes;
  std::vector<Skin> skins;
  std::vector<AnimationClip> clips;
  int active_clip = -1;  // clip played by evaluate(); -1 = static
  std::vector<ProxySet> proxies;
  Camera camera;
  Environment environment;
  std::vector<SphericalLight> lights;
  // What loading changed in or assumed about the input, one sentence each naming the file and part
  // (flat normals computed, negative radiance clamped): the CLI prints them and records keep them.
  std::vector<std::string> notices;
};

// The scene posed at time t: world-space geometry ready for rendering.
struct PosedObject {
  int node = -1, mesh = -1, material = 0;
  std::vector<glm::vec3> positions, normals;  // world space, skinned
  const Mesh* source = nullptr;               // uvs, colours, triangles
};
struct PosedScene {
  double time = 0.0;
  std::vector<PosedObject> objects;
  std::vector<std::vector<Sphere>> proxies;     // world space, one list per ProxySet
  std::vector<SphericalLight> lights;           // world space
  std::vector<glm::mat4> node_world;            // world transform of every node
  bool animated = false;  // the active clip changes something over time, or the pose differs from the nodes' rest TRS
};

// Albedo of a posed object's surface at barycentrics (b1, b2) of triangle `prim`: material albedo x
// albedo texture at the interpolated uv x interpolated vertex colour. The one rule of the reference
// renderer and of every backend's G-buffer.
glm::vec3 surface_albedo(const Scene& scene, const PosedObject& obj, std::size_t prim, float b1, float b2);
// True when surface_albedo of `obj` is the same at every point (no albedo texture, no vertex
// colours), and then `albedo` is that value, bit for bit: per-pixel passes look it up once per object.
bool constant_albedo(const Scene& scene, const PosedObject& obj, glm::vec3& albedo);

// Poses the scene at time t (seconds) with its active clip: node hierarchy, linear-blend skinning
// of meshes, proxies moved with their node or bones. Throws std::invalid_argument for a
// non-finite t.
PosedScene evaluate(const Scene& scene, double t);

// True when evaluate() gives the same pose at every time: no active clip, or one whose channels
// each hold a single value. Sweeps over animation times measure such a scene once.
bool is_static(const Scene& scene);

// Structural checks with errors that name the part, field and value: indices in range, finite
// values, unit normals, no zero-area triangles, sane sizes. Loaders call it; throws
// std::invalid_argument on the first problem ("mesh 'bunny': triangle 12 has zero area").
void validate(const Scene& scene);

// Order-n SH projection of the environment's radiance, per RGB channel (n*n vec3): for maps the
// exact integral of radiance()'s bilinear lookup over every texel at any map size
// (sh::project_latlong, LatLongFilter::Bilinear), for the sky a fine quadrature (the sun disk is
// supersampled so its energy is exact to 1e-3).
std::vector<glm::vec3> environment_sh(const Environment& env, int order);

// World-space axis-aligned bounds of the posed geometry.
struct Bounds {
  glm::vec3 lo{1e30f}, hi{-1e30f};
};
Bounds bounds(const PosedScene& posed);

}  // namespace softgi::scene
