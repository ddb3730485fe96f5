// The scene model: texture and environment lookups, the environment's SH projection, posing at
// time t (node hierarchy, glTF keyframes, linear-blend skinning, proxies and lights that follow),
// structural validation, bounds.
#include "softgi/scene/scene.hpp"

#include "sky_run.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "softgi/scene/builtin.hpp"
#include "softgi/sh/quadrature.hpp"
#include "softgi/sh/rotation.hpp"
#include "softgi/sh/sh.hpp"

namespace softgi::scene {

namespace {

constexpr double kPi = sh::kPi;

// Rotation about +y by angle a (right-handed, as glm::angleAxis(a, +y)):
// (x, y, z) -> (x cos a + z sin a, y, -x sin a + z cos a).
glm::vec3 rotate_y(const glm::vec3& d, float a) {
  if (a == 0.0f) return d;
  const float c = std::cos(a), s = std::sin(a);
  return {c * d.x + s * d.z, d.y, -s * d.x + c * d.z};
}

sh::Mat3 rotation_y_mat3(double a) {
  const double c = std::cos(a), s = std::sin(a);
  return {{{c, 0.0, s}, {0.0, 1.0, 0.0}, {-s, 0.0, c}}};
}

// The sky without its sun: ground below the horizon; above it the horizon colour blends into the
// zenith colour with smoothstep(y) = 3y^2 - 2y^3 of y = sin(elevation). Being a cubic in y, the
// gradient is projected exactly by Gauss-Legendre nodes in y (environment_sh).
glm::vec3 sky_gradient(const Environment& env, float y) {
  if (y < 0.0f) return env.ground;
  const float yc = std::min(y, 1.0f);
  const float s = yc * yc * (3.0f - 2.0f * yc);
  return env.horizon + (env.zenith - env.horizon) * s;
}

glm::vec3 safe_normalize(const glm::vec3& v, const glm::vec3& fallback) {
  const float len = glm::length(v);
  return (len > 0.0f && std::isfinite(len)) ? v / len : fallback;
}

// Largest axis scale of an affine transform: the radius factor that keeps a transformed sphere a bound.
float max_scale(const glm::mat4& m) {
  return std::sqrt(std::max({glm::dot(glm::vec3(m[0]), glm::vec3(m[0])), glm::dot(glm::vec3(m[1]), glm::vec3(m[1])),
                             glm::dot(glm::vec3(m[2]), glm::vec3(m[2]))}));
}

glm::mat3 normal_matrix(const glm::mat4& m) { return glm::transpose(glm::inverse(glm::mat3(m))); }

glm::vec3 map_texel(const Environment& env, int u, int v) {
  const float* p = env.map_rgb.data() + (static_cast<std::size_t>(v) * env.map_width + u) * 3;
  return {p[0], p[1], p[2]};
}

// Bilinear lookup in the lat-long map, inverse of sh::latlong_direction: pixel (u, v) centre holds
// theta = pi (v + 1/2) / H from +y and phi = 2 pi (u + 1/2) / W with d = (sin t cos p, cos t, -sin t sin p).
// Wraps in u, clamps in v. This is sh::LatLongFilter::Bilinear, the function environment_sh projects:
// renderers that read radiance() and techniques that read the SH light see the same map at any size.
glm::vec3 map_lookup(const Environment& env, const glm::vec3& d) {
  const int w = env.map_width, h = env.map_height;
  if (w <= 0 || h <= 0 || env.map_rgb.size() != static_cast<std::size_t>(w) * h * 3) return glm::vec3(0.0f);
  const double theta = std::acos(std::clamp(static_cast<double>(d.y), -1.0, 1.0));
  double phi = std::atan2(-static_cast<double>(d.z), static_cast<double>(d.x));
  if (phi < 0.0) phi += 2.0 * kPi;
  if (!std::isfinite(theta) || !std::isfinite(phi)) return glm::vec3(0.0f);
  const double x = phi * w / (2.0 * kPi) - 0.5;
  const double y = theta * h / kPi - 0.5;
  const double x0 = std::floor(x), y0 = std::floor(y);
  const float fx = static_cast<float>(x - x0), fy = static_cast<float>(y - y0);
  int u0 = static_cast<int>(x0) % w;
  if (u0 < 0) u0 += w;
  const int u1 = (u0 + 1) % w;
  const int v0 = std::clamp(static_cast<int>(y0), 0, h - 1);
  const int v1 = std::clamp(static_cast<int>(y0) + 1, 0, h - 1);
  const glm::vec3 top = map_texel(env, u0, v0) * (1.0f - fx) + map_texel(env, u1, v0) * fx;
  const glm::vec3 bottom = map_texel(env, u0, v1) * (1.0f - fx) + map_texel(env, u1, v1) * fx;
  return top * (1.0f - fy) + bottom * fy;
}

}  // namespace

// --- Texture, Node, Environment -------------------------------------------------------------------

glm::vec3 Texture::sample(glm::vec2 uv) const {
  // validate() rejects such textures; a neutral multiplier keeps a render of an unvalidated scene defined.
  if (width <= 0 || height <= 0 || texels.size() != static_cast<std::size_t>(width) * height) return glm::vec3(1.0f);
  auto wrap01 = [](float t) -> double {
    if (!std::isfinite(t)) return 0.0;
    const double d = static_cast<double>(t);
    return d - std::floor(d);  // in [0, 1): keeps the integer conversion below in range for any uv
  };
  const double x = wrap01(uv.x) * width - 0.5, y = wrap01(uv.y) * height - 0.5;
  const double x0 = std::floor(x), y0 = std::floor(y);
  const float fx = static_cast<float>(x - x0), fy = static_cast<float>(y - y0);
  const int u0 = (static_cast<int>(x0) + width) % width, u1 = (u0 + 1) % width;
  const int v0 = (static_cast<int>(y0) + height) % height, v1 = (v0 + 1) % height;
  auto at = [&](int u, int v) { return texels[static_cast<std::size_t>(v) * width + u]; };
  return (at(u0, v0) * (1.0f - fx) + at(u1, v0) * fx) * (1.0f - fy) + (at(u0, v1) * (1.0f - fx) + at(u1, v1) * fx) * fy;
}

glm::mat4 Node::local() const {
  glm::mat4 m = glm::mat4_cast(rotation);
  m[0] *= scale.x;
  m[1] *= scale.y;
  m[2] *= scale.z;
  m[3] = glm::vec4(translation, 1.0f);
  return m;
}

EnvironmentRadiance::EnvironmentRadiance(const Environment& env)
    : env_(&env),
      rotated_(-env.rotation_y != 0.0f),
      cos_r_(std::cos(-env.rotation_y)),
      sin_r_(std::sin(-env.rotation_y)),
      sun_(safe_normalize(env.sun_direction, glm::vec3(0.0f, 1.0f, 0.0f))),
      cos_sun_(std::cos(env.sun_radius)) {}

glm::vec3 EnvironmentRadiance::operator()(const glm::vec3& dir) const {
  const Environment& env = *env_;
  // The map/sky is turned by rotation_y about +y: world direction d sees the content at R^-1 d
  // (rotate_y's arithmetic).
  const glm::vec3 d = rotated_ ? glm::vec3(cos_r_ * dir.x + sin_r_ * dir.z, dir.y, -sin_r_ * dir.x + cos_r_ * dir.z) : dir;
  if (env.kind == Environment::Kind::Map) return env.intensity * map_lookup(env, d);
  if (env.sun_radius > 0.0f && glm::dot(d, sun_) >= cos_sun_) return env.intensity * env.sun_radiance;
  return env.intensity * sky_gradient(env, d.y);
}

void EnvironmentRadiance::operator()(const glm::vec3* dir, std::size_t n, glm::vec3* out) const {
  const Environment& env = *env_;
  if (env.kind == Environment::Kind::Map) {
    for (std::size_t k = 0; k < n; ++k) out[k] = (*this)(dir[k]);
    return;
  }
  if (n == 0) return;
  static_assert(sizeof(glm::vec3) == 3 * sizeof(float));
  detail::SkyParams p;
  p.rotated = rotated_;
  p.cos_r = cos_r_;
  p.sin_r = sin_r_;
  p.sun = env.sun_radius > 0.0f;
  p.sun_x = sun_.x;
  p.sun_y = sun_.y;
  p.sun_z = sun_.z;
  p.cos_sun = cos_sun_;
  p.intensity = env.intensity;
  for (int c = 0; c < 3; ++c) {
    p.zenith[c] = env.zenith[c];
    p.horizon[c] = env.horizon[c];
    p.ground[c] = env.ground[c];
    p.sun_radiance[c] = env.sun_radiance[c];
  }
  detail::sky_run(p, &dir[0].x, n, &out[0].x);
}

glm::vec3 Environment::radiance(const glm::vec3& dir) const { return EnvironmentRadiance(*this)(dir); }

std::vector<glm::vec3> environment_sh(const Environment& env, int order) {
  sh::check_order(order, "scene::environment_sh");
  const int n2 = sh::num_coeffs(order);
  std::vector<glm::vec3> out(n2, glm::vec3(0.0f));
  if (!std::isfinite(env.intensity) || !std::isfinite(env.rotation_y)) {
    std::ostringstream os;
    os << "environment_sh: intensity " << env.intensity << " / rotation_y " << env.rotation_y << " is not finite";
    throw std::invalid_argument(os.str());
  }

  if (env.kind == Environment::Kind::Map) {
    const int w = env.map_width, h = env.map_height;
    if (w <= 0 || h <= 0 || env.map_rgb.size() != static_cast<std::size_t>(w) * h * 3) {
      std::ostringstream os;
      os << "environment_sh: map '" << env.map_path << "' is " << w << "x" << h << " with " << env.map_rgb.size()
         << " floats (expected width * height * 3 > 0)";
      throw std::invalid_argument(os.str());
    }
    // Integrates map_lookup's bilinear reconstruction exactly over every texel (not centre samples),
    // so a 1x1 or 2x1 map projects as correctly as a 512x256 one.
    std::vector<double> c = sh::project_latlong(order, env.map_rgb.data(), w, h, 3, sh::LatLongFilter::Bilinear);  // channel-major
    if (env.rotation_y != 0.0f) {
      // ShRotation(R) gives f'(s) = f(R^T s): the map turned by R = R_y(rotation_y), as radiance() reads it.
      const sh::ShRotation rot(order, rotation_y_mat3(env.rotation_y));
      std::vector<double> tmp(n2);
      for (int ch = 0; ch < 3; ++ch) {
        rot.apply(c.data() + ch * n2, tmp.data());
        std::copy(tmp.begin(), tmp.end(), c.begin() + ch * n2);
      }
    }
    for (int i = 0; i < n2; ++i)
      out[i] = env.intensity * glm::vec3(static_cast<float>(c[i]), static_cast<float>(c[n2 + i]), static_cast<float>(c[2 * n2 + i]));
    return out;
  }

  std::vector<glm::dvec3> acc(n2, glm::dvec3(0.0));
  std::array<double, sh::kMaxCoeffs> y{};
  auto add = [&](const glm::dvec3& d, const glm::dvec3& value) {
    sh::eval_basis(order, sh::Vec3<double>{d.x, d.y, d.z}, y.data());
    for (int i = 0; i < n2; ++i) acc[i] += value * y[i];
  };

  // Sky without sun: symmetric about +y, a cubic in y above the horizon and constant below, so a
  // Gauss-Legendre rule in y on each hemisphere (exact to degree 2*kNodes - 1 >= 3 + (order - 1)) times
  // uniform azimuth (exact for the |m| <= order - 1 trigonometric terms) integrates it exactly.
  constexpr int kNodes = 16;
  const int n_phi = 2 * order + 2;
  const sh::GaussLegendre& gl = sh::gauss_legendre(kNodes);
  for (int hemi = 0; hemi < 2; ++hemi) {
    for (int k = 0; k < kNodes; ++k) {
      // Map [-1, 1] onto [0, 1] (upper) or [-1, 0] (lower).
      const double yy = hemi == 0 ? 0.5 * (gl.nodes[k] + 1.0) : 0.5 * (gl.nodes[k] - 1.0);
      const double wy = 0.5 * gl.weights[k] * 2.0 * kPi / n_phi;
      const double r = std::sqrt(std::max(0.0, 1.0 - yy * yy));
      const glm::dvec3 value = glm::dvec3(sky_gradient(env, static_cast<float>(yy))) * wy;
      for (int j = 0; j < n_phi; ++j) {
        const double phi = 2.0 * kPi * (j + 0.5) / n_phi;
        add({r * std::cos(phi), yy, r * std::sin(phi)}, value);
      }
    }
  }

  // Sun disk: it replaces the sky inside the cap, so add int_cap (sun - sky) y. A product rule in
  // polar coordinates about the sun axis (Gauss-Legendre in mu = cos, uniform azimuth) integrates the
  // constant sun term exactly (y restricted to the cap is a polynomial in mu times trigonometric terms
  // in the azimuth); the sky term is smooth inside the cap except when the disk straddles the horizon,
  // where the 32 x 64 samples resolve the step to far below 1e-3 of the sun energy.
  if (env.sun_radius > 0.0f) {
    const glm::dvec3 a = glm::dvec3(safe_normalize(rotate_y(env.sun_direction, env.rotation_y), glm::vec3(0.0f, 1.0f, 0.0f)));
    const glm::dvec3 helper = std::abs(a.y) < 0.9 ? glm::dvec3(0.0, 1.0, 0.0) : glm::dvec3(1.0, 0.0, 0.0);
    const glm::dvec3 e1 = glm::normalize(glm::cross(helper, a));
    const glm::dvec3 e2 = glm::cross(a, e1);
    const double mu0 = std::cos(static_cast<double>(env.sun_radius));
    constexpr int kCapNodes = 32, kCapPhi = 64;
    const sh::GaussLegendre& gc = sh::gauss_legendre(kCapNodes);
    const glm::dvec3 sun = glm::dvec3(env.sun_radiance);
    for (int k = 0; k < kCapNodes; ++k) {
      const double mu = mu0 + (1.0 - mu0) * 0.5 * (gc.nodes[k] + 1.0);
      const double w = (1.0 - mu0) * 0.5 * gc.weights[k] * 2.0 * kPi / kCapPhi;
      const double s = std::sqrt(std::max(0.0, 1.0 - mu * mu));
      for (int j = 0; j < kCapPhi; ++j) {
        const double phi = 2.0 * kPi * (j + 0.5) / kCapPhi;
        const glm::dvec3 d = mu * a + s * (std::cos(phi) * e1 + std::sin(phi) * e2);
        add(d, (sun - glm::dvec3(sky_gradient(env, static_cast<float>(d.y)))) * w);
      }
    }
  }
  for (int i = 0; i < n2; ++i) out[i] = glm::vec3(acc[i] * static_cast<double>(env.intensity));
  return out;
}

std::string assets_dir() {
  const char* env = std::getenv("SOFTGI_ASSETS");
  if (env != nullptr && env[0] != '\0') return env;
  return std::string(SOFTGI_SOURCE_DIR) + "/assets";
}

// --- evaluate ---------------------------------------------------------------------------------------

namespace {

struct Trs {
  glm::vec3 t{0.0f};
  glm::quat r{1.0f, 0.0f, 0.0f, 0.0f};
  glm::vec3 s{1.0f};
  glm::mat4 matrix() const {
    Node n;
    n.translation = t;
    n.rotation = r;
    n.scale = s;
    return n.local();
  }
};

glm::quat quat_of(const glm::vec4& xyzw) { return glm::quat(xyzw.w, xyzw.x, xyzw.y, xyzw.z); }

// Shortest-arc spherical linear interpolation of unit quaternions (glTF 2.0 animation: "spherical
// linear interpolation"); near-parallel keys fall back to normalised lerp.
glm::quat slerp_shortest(glm::quat a, glm::quat b, float u) {
  a = glm::normalize(a);
  b = glm::normalize(b);
  float c = glm::dot(a, b);
  if (c < 0.0f) {
    b = -b;
    c = -c;
  }
  if (c > 0.9995f) return glm::normalize(a * (1.0f - u) + b * u);
  const float theta = std::acos(std::min(c, 1.0f));
  const float st = std::sin(theta);
  return glm::normalize(a * (std::sin((1.0f - u) * theta) / st) + b * (std::sin(u * theta) / st));
}

// Value of a channel at clip time tc (already wrapped or clamped): constant before the first and after
// the last key, otherwise linear (slerp for rotations) or step between the bracketing keys.
glm::vec4 sample_channel(const AnimationChannel& ch, float tc) {
  const auto& times = ch.times;
  if (tc <= times.front()) return ch.values.front();
  if (tc >= times.back()) return ch.values.back();
  const std::size_t hi = static_cast<std::size_t>(std::upper_bound(times.begin(), times.end(), tc) - times.begin());
  const std::size_t lo = hi - 1;
  if (ch.interp == AnimationChannel::Interp::Step) return ch.values[lo];
  const float span = times[hi] - times[lo];
  const float u = span > 0.0f ? std::clamp((tc - times[lo]) / span, 0.0f, 1.0f) : 0.0f;
  if (ch.path == AnimationChannel::Path::Rotation) {
    const glm::quat q = slerp_shortest(quat_of(ch.values[lo]), quat_of(ch.values[hi]), u);
    return {q.x, q.y, q.z, q.w};
  }
  return ch.values[lo] * (1.0f - u) + ch.values[hi] * u;
}

// Whether a clip changes anything over time (some channel has two different key values).
bool clip_varies(const AnimationClip& clip) {
  for (const auto& ch : clip.channels)
    for (std::size_t k = 1; k < ch.values.size(); ++k)
      if (ch.values[k] != ch.values[0]) return true;
  return false;
}

[[noreturn]] void fail_eval(const std::string& msg) { throw std::invalid_argument("scene::evaluate: " + msg); }

}  // namespace

bool is_static(const Scene& scene) {
  if (scene.active_clip < 0 || scene.active_clip >= static_cast<int>(scene.clips.size())) return true;
  return !clip_varies(scene.clips[scene.active_clip]);
}

PosedScene evaluate(const Scene& scene, double t) {
  if (!std::isfinite(t)) {
    std::ostringstream os;
    os << "time t = " << t << " is not finite";
    fail_eval(os.str());
  }
  PosedScene posed;
  posed.time = t;
  const int n_nodes = static_cast<int>(scene.nodes.size());

  std::vector<Trs> local(n_nodes);
  for (int i = 0; i < n_nodes; ++i) local[i] = {scene.nodes[i].translation, scene.nodes[i].rotation, scene.nodes[i].scale};

  bool varies = false;
  if (scene.active_clip >= 0) {
    if (scene.active_clip >= static_cast<int>(scene.clips.size()))
      fail_eval("active_clip " + std::to_string(scene.active_clip) + " is out of range (" +
                std::to_string(scene.clips.size()) + " clips)");
    const AnimationClip& clip = scene.clips[scene.active_clip];
    varies = clip_varies(clip);
    double tc = t;
    if (clip.duration > 0.0f) {
      const double dur = clip.duration;
      if (clip.loop) {
        tc = std::fmod(t, dur);
        if (tc < 0.0) tc += dur;
      } else {
        tc = std::clamp(t, 0.0, dur);
      }
    } else {
      tc = 0.0;
    }
    for (const auto& ch : clip.channels) {
      if (ch.node < 0 || ch.node >= n_nodes)
        fail_eval("clip '" + clip.name + "': channel node " + std::to_string(ch.node) + " is out of range");
      if (ch.times.empty() || ch.times.size() != ch.values.size())
        fail_eval("clip '" + clip.name + "': channel of node " + std::to_string(ch.node) + " has " +
                  std::to_string(ch.times.size()) + " times and " + std::to_string(ch.values.size()) + " values");
      const glm::vec4 v = sample_channel(ch, static_cast<float>(tc));
      Trs& l = local[ch.node];
      switch (ch.path) {
        case AnimationChannel::Path::Translation: l.t = glm::vec3(v); break;
        case AnimationChannel::Path::Rotation: l.r = glm::normalize(quat_of(v)); break;
        case AnimationChannel::Path::Scale: l.s = glm::vec3(v); break;
      }
    }
  }

  // World transforms, parents first (memoised walk up; a chain longer than the node count is a cycle).
  posed.node_world.assign(n_nodes, glm::mat4(1.0f));
  std::vector<char> done(n_nodes, 0);
  std::vector<int> chain;
  for (int i = 0; i < n_nodes; ++i) {
    chain.clear();
    int k = i;
    while (k >= 0 && !done[k]) {
      chain.push_back(k);
      if (static_cast<int>(chain.size()) > n_nodes) fail_eval("node '" + scene.nodes[i].name + "' has a cyclic parent chain");
      const int p = scene.nodes[k].parent;
      if (p < -1 || p >= n_nodes) fail_eval("node '" + scene.nodes[k].name + "': parent " + std::to_string(p) + " is out of range");
      k = p;
    }
    for (auto it = chain.rbegin(); it != chain.rend(); ++it) {
      const int p = scene.nodes[*it].parent;
      posed.node_world[*it] = (p >= 0 ? posed.node_world[p] : glm::mat4(1.0f)) * local[*it].matrix();
      done[*it] = 1;
    }
  }

  bool moved = false;
  for (int i = 0; i < n_nodes && !moved; ++i) {
    const Node& n = scene.nodes[i];
    moved = local[i].t != n.translation || local[i].s != n.scale || glm::abs(glm::dot(local[i].r, glm::normalize(n.rotation))) < 1.0f - 1e-6f;
  }
  posed.animated = varies || moved;

  // Joint matrices per skin: world(joint) * inverse_bind (glTF 2.0 skinning).
  std::vector<std::vector<glm::mat4>> joint_mats(scene.skins.size());
  std::vector<std::vector<glm::mat3>> joint_normal(scene.skins.size());
  std::vector<std::vector<float>> joint_scale(scene.skins.size());
  auto skin_mats = [&](int s) {
    if (s < 0 || s >= static_cast<int>(scene.skins.size())) fail_eval("skin " + std::to_string(s) + " is out of range");
    if (joint_mats[s].empty() && !scene.skins[s].joints.empty()) {
      const Skin& skin = scene.skins[s];
      if (skin.inverse_bind.size() != skin.joints.size())
        fail_eval("skin '" + skin.name + "' has " + std::to_string(skin.joints.size()) + " joints and " +
                  std::to_string(skin.inverse_bind.size()) + " inverse bind matrices");
      for (std::size_t j = 0; j < skin.joints.size(); ++j) {
        const int jn = skin.joints[j];
        if (jn < 0 || jn >= n_nodes) fail_eval("skin '" + skin.name + "': joint node " + std::to_string(jn) + " is out of range");
        const glm::mat4 m = posed.node_world[jn] * skin.inverse_bind[j];
        joint_mats[s].push_back(m);
        joint_normal[s].push_back(normal_matrix(m));
        joint_scale[s].push_back(max_scale(m));
      }
    }
  };

  for (int i = 0; i < n_nodes; ++i) {
    const Node& node = scene.nodes[i];
    if (node.mesh < 0) continue;
    if (node.mesh >= static_cast<int>(scene.meshes.size()))
      fail_eval("node '" + node.name + "': mesh " + std::to_string(node.mesh) + " is out of range");
    const Mesh& mesh = scene.meshes[node.mesh];
    PosedObject obj;
    obj.node = i;
    obj.mesh = node.mesh;
    obj.material = mesh.material;
    obj.source = &mesh;
    const std::size_t nv = mesh.positions.size();
    if (mesh.normals.size() != nv)
      fail_eval("mesh '" + mesh.name + "' has " + std::to_string(nv) + " positions and " + std::to_string(mesh.normals.size()) + " normals");
    obj.positions.resize(nv);
    obj.normals.resize(nv);
    const glm::mat4& world = posed.node_world[i];
    const glm::mat3 world_n = normal_matrix(world);
    const bool skinned = node.skin >= 0 && mesh.skinned();
    if (skinned) {
      skin_mats(node.skin);
      const auto& jm = joint_mats[node.skin];
      const auto& jn = joint_normal[node.skin];
      if (mesh.joints.size() != nv || mesh.weights.size() != nv)
        fail_eval("mesh '" + mesh.name + "': joints/weights sizes do not match its " + std::to_string(nv) + " vertices");
      for (std::size_t v = 0; v < nv; ++v) {
        const glm::vec4 p(mesh.positions[v], 1.0f);
        glm::vec3 pos(0.0f), nrm(0.0f);
        float wsum = 0.0f;
        for (int k = 0; k < 4; ++k) {
          const float w = mesh.weights[v][k];
          if (w == 0.0f) continue;
          const unsigned j = mesh.joints[v][k];
          if (j >= jm.size()) fail_eval("mesh '" + mesh.name + "': vertex " + std::to_string(v) + " joint " + std::to_string(j) + " is out of range");
          pos += w * glm::vec3(jm[j] * p);
          nrm += w * (jn[j] * mesh.normals[v]);
          wsum += w;
        }
        if (wsum > 0.0f) {
          obj.positions[v] = pos / wsum;
          obj.normals[v] = safe_normalize(nrm, safe_normalize(world_n * mesh.normals[v], mesh.normals[v]));
        } else {  // no influences: stays with its node
          obj.positions[v] = glm::vec3(world * p);
          obj.normals[v] = safe_normalize(world_n * mesh.normals[v], mesh.normals[v]);
        }
      }
    } else {
      for (std::size_t v = 0; v < nv; ++v) {
        obj.positions[v] = glm::vec3(world * glm::vec4(mesh.positions[v], 1.0f));
        obj.normals[v] = safe_normalize(world_n * mesh.normals[v], mesh.normals[v]);
      }
    }
    posed.objects.push_back(std::move(obj));
  }

  // Proxies (paper 004 section 6.2, Animation): centres follow their node rigidly or are skinned with
  // the sphere's bone weights; radii are kept (scaled only by the transform's largest axis scale).
  posed.proxies.reserve(scene.proxies.size());
  for (const ProxySet& ps : scene.proxies) {
    std::vector<Sphere> out(ps.spheres.size());
    if (ps.node < -1 || ps.node >= n_nodes) fail_eval("proxy set '" + ps.name + "': node " + std::to_string(ps.node) + " is out of range");
    const Node* node = ps.node >= 0 ? &scene.nodes[ps.node] : nullptr;
    const bool skinned = node != nullptr && node->skin >= 0 && !ps.joints.empty();
    const glm::mat4 world = node != nullptr ? posed.node_world[ps.node] : glm::mat4(1.0f);
    const float wscale = max_scale(world);
    if (skinned) {
      skin_mats(node->skin);
      if (ps.joints.size() != ps.spheres.size() || ps.weights.size() != ps.spheres.size())
        fail_eval("proxy set '" + ps.name + "': joints/weights sizes do not match its " + std::to_string(ps.spheres.size()) + " spheres");
    }
    for (std::size_t k = 0; k < ps.spheres.size(); ++k) {
      const Sphere& s = ps.spheres[k];
      const glm::vec4 c(s.center, 1.0f);
      if (skinned) {
        const auto& jm = joint_mats[node->skin];
        const auto& js = joint_scale[node->skin];
        glm::vec3 pos(0.0f);
        float wsum = 0.0f, scale = 0.0f;
        for (int q = 0; q < 4; ++q) {
          const float w = ps.weights[k][q];
          if (w == 0.0f) continue;
          const unsigned j = ps.joints[k][q];
          if (j >= jm.size()) fail_eval("proxy set '" + ps.name + "': sphere " + std::to_string(k) + " joint " + std::to_string(j) + " is out of range");
          pos += w * glm::vec3(jm[j] * c);
          scale += w * js[j];
          wsum += w;
        }
        if (wsum > 0.0f) {
          out[k] = {pos / wsum, s.radius * scale / wsum};
          continue;
        }
      }
      out[k] = {glm::vec3(world * c), s.radius * wscale};
    }
    posed.proxies.push_back(std::move(out));
  }

  posed.lights.reserve(scene.lights.size());
  for (const SphericalLight& l : scene.lights) {
    SphericalLight w = l;
    if (l.node >= 0) {
      if (l.node >= n_nodes) fail_eval("light '" + l.name + "': node " + std::to_string(l.node) + " is out of range");
      const glm::mat4& m = posed.node_world[l.node];
      w.position = glm::vec3(m * glm::vec4(l.position, 1.0f));
      w.radius = l.radius * max_scale(m);
    }
    posed.lights.push_back(w);
  }
  return posed;
}

Bounds bounds(const PosedScene& posed) {
  Bounds b;
  for (const auto& o : posed.objects)
    for (const auto& p : o.positions) {
      b.lo = glm::min(b.lo, p);
      b.hi = glm::max(b.hi, p);
    }
  return b;
}

// --- validate -----------------------------------------------------------------------------------------

namespace {

// A normal counts as unit when its length is within 1e-2 of 1: normals decoded from 8- or 10-bit
// quantised glTF/Draco attributes are within a few 1e-3; anything further is a wrong normal.
constexpr float kUnitNormalTolerance = 1e-2f;
// Quaternions (node rotations, rotation keys) are renormalised when used; this only rejects garbage.
constexpr float kUnitQuatTolerance = 1e-2f;
// Skin weights must sum to 1 (glTF 2.0: "within a tolerance"); 1e-2 admits 8-bit normalised weights.
constexpr float kWeightSumTolerance = 1e-2f;
// Sanity limits: beyond these the input is broken, not big.
constexpr std::size_t kMaxTriangles = 50'000'000;
constexpr std::size_t kMaxVertices = 50'000'000;
constexpr float kMaxCoordinate = 1e6f;  // metres
// Node scales (and scale keys): each |component| in [1e-6, 1e6], the range scene files accept. A
// finite float scale such as 1e30 would otherwise overflow the world bounds and every length
// computed from them.
constexpr float kMinScale = 1e-6f, kMaxScale = 1e6f;
// Composed rest-pose (world) transforms: a chain of in-range nodes can still multiply past float
// range (ten nested scales of 1e6 give 1e60). World axis scales stay in [1e-9, 1e9] and world
// translations within 1e12 m, so a vertex (within kMaxCoordinate of its node) lands within ~1e15 m,
// whose square (1e30) and sums of a few such products (bounds, camera framing, ray setup) stay far
// below float's 3.4e38; the inverse scale enters normals (normal_matrix), hence the lower limit.
constexpr double kMinWorldScale = 1e-9, kMaxWorldScale = 1e9, kMaxWorldTranslation = 1e12;
constexpr int kMaxTextureSize = 16384;
// A triangle has zero area when |e1 x e2| <= kZeroAreaRelative * (longest edge)^2: exact zero and
// float-collinear slivers alike, independent of the mesh's scale.
constexpr float kZeroAreaRelative = 1e-7f;

std::string q(const std::string& s) { return "'" + s + "'"; }
std::string str(const glm::vec3& v) {
  std::ostringstream os;
  os << "(" << v.x << ", " << v.y << ", " << v.z << ")";
  return os.str();
}
std::string str(const glm::vec4& v) {
  std::ostringstream os;
  os << "(" << v.x << ", " << v.y << ", " << v.z << ", " << v.w << ")";
  return os.str();
}
std::string str(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}
bool finite(const glm::vec2& v) { return std::isfinite(v.x) && std::isfinite(v.y); }
bool finite(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }
bool finite(const glm::vec4& v) { return finite(glm::vec3(v)) && std::isfinite(v.w); }
bool finite(const glm::mat4& m) { return finite(m[0]) && finite(m[1]) && finite(m[2]) && finite(m[3]); }
bool nonneg(const glm::vec3& v) { return v.x >= 0.0f && v.y >= 0.0f && v.z >= 0.0f; }

[[noreturn]] void bad(const std::string& part, const std::string& what) {
  throw std::invalid_argument(part + ": " + what);
}

void check_colour(const std::string& part, const std::string& field, const glm::vec3& c) {
  if (!finite(c) || !nonneg(c)) bad(part, field + " " + str(c) + " must be finite and non-negative");
}

bool in_scale_range(const glm::vec3& s) {
  for (int k = 0; k < 3; ++k)
    if (!(std::abs(s[k]) >= kMinScale && std::abs(s[k]) <= kMaxScale)) return false;
  return true;
}

// The rest-pose world transform of every node, composed in double (parents are acyclic and in
// range: validate checked both first). A node whose world transform leaves the limits is named
// together with the topmost ancestor that already does, since that is where the chain overflows.
void check_world_transforms(const Scene& scene) {
  const int n = static_cast<int>(scene.nodes.size());
  std::vector<glm::dmat4> world(static_cast<std::size_t>(n));
  std::vector<char> done(static_cast<std::size_t>(n), 0), out(static_cast<std::size_t>(n), 0);
  std::vector<std::string> why(static_cast<std::size_t>(n));
  std::vector<int> chain;
  for (int i = 0; i < n; ++i) {
    chain.clear();
    for (int k = i; k >= 0 && !done[k]; k = scene.nodes[k].parent) chain.push_back(k);
    for (auto it = chain.rbegin(); it != chain.rend(); ++it) {
      const Node& node = scene.nodes[*it];
      // Node::local() in double: T * R * S.
      const glm::dquat r(node.rotation.w, node.rotation.x, node.rotation.y, node.rotation.z);
      glm::dmat4 local = glm::mat4_cast(glm::normalize(r));
      for (int c = 0; c < 3; ++c) local[c] *= double(node.scale[c]);
      local[3] = glm::dvec4(glm::dvec3(node.translation), 1.0);
      world[*it] = (node.parent >= 0 ? world[node.parent] : glm::dmat4(1.0)) * local;
      done[*it] = 1;
      const glm::dmat4& w = world[*it];
      for (int c = 0; c < 3 && why[*it].empty(); ++c) {
        const double len = glm::length(glm::dvec3(w[c]));
        if (!(len >= kMinWorldScale && len <= kMaxWorldScale))
          why[*it] = "world axis scale " + str(len) + " is outside [" + str(kMinWorldScale) + ", " + str(kMaxWorldScale) + "]";
      }
      const glm::dvec3 t(w[3]);
      if (why[*it].empty() && !(std::abs(t.x) <= kMaxWorldTranslation && std::abs(t.y) <= kMaxWorldTranslation &&
                                std::abs(t.z) <= kMaxWorldTranslation))
        why[*it] = "world translation (" + str(t.x) + ", " + str(t.y) + ", " + str(t.z) + ") is beyond " +
                   str(kMaxWorldTranslation) + " m";
      out[*it] = !why[*it].empty();
    }
    if (!out[i]) continue;
    int top = i;
    while (scene.nodes[top].parent >= 0 && out[scene.nodes[top].parent]) top = scene.nodes[top].parent;
    const Node& t = scene.nodes[top];
    std::string msg = why[top] + " (its translation " + str(t.translation) + ", scale " + str(t.scale);
    if (t.parent >= 0) msg += ", under parent " + q(scene.nodes[t.parent].name) + " (index " + std::to_string(t.parent) + ")";
    bad("node " + q(t.name) + " (index " + std::to_string(top) + ")", msg + ")");
  }
}

}  // namespace

void validate(const Scene& scene) {
  const int n_nodes = static_cast<int>(scene.nodes.size());
  const int n_meshes = static_cast<int>(scene.meshes.size());
  const int n_materials = static_cast<int>(scene.materials.size());
  const int n_textures = static_cast<int>(scene.textures.size());
  const int n_skins = static_cast<int>(scene.skins.size());

  std::size_t total_triangles = 0, total_vertices = 0;
  for (int mi = 0; mi < n_meshes; ++mi) {
    const Mesh& m = scene.meshes[mi];
    const std::string part = "mesh " + q(m.name) + " (index " + std::to_string(mi) + ")";
    const std::size_t nv = m.positions.size();
    total_triangles += m.triangles.size();
    total_vertices += nv;
    if (total_triangles > kMaxTriangles) bad(part, "scene has more than " + std::to_string(kMaxTriangles) + " triangles (absurd size)");
    if (total_vertices > kMaxVertices) bad(part, "scene has more than " + std::to_string(kMaxVertices) + " vertices (absurd size)");
    if (nv == 0) bad(part, "has no vertices");
    if (m.triangles.empty()) bad(part, "has no triangles");
    if (m.normals.size() != nv) bad(part, "has " + std::to_string(nv) + " positions but " + std::to_string(m.normals.size()) + " normals (one per vertex required)");
    if (!m.uvs.empty() && m.uvs.size() != nv) bad(part, "has " + std::to_string(m.uvs.size()) + " uvs for " + std::to_string(nv) + " vertices");
    if (!m.colors.empty() && m.colors.size() != nv) bad(part, "has " + std::to_string(m.colors.size()) + " colors for " + std::to_string(nv) + " vertices");
    if (m.joints.size() != m.weights.size() || (!m.joints.empty() && m.joints.size() != nv))
      bad(part, "has " + std::to_string(m.joints.size()) + " joints and " + std::to_string(m.weights.size()) + " weights for " + std::to_string(nv) + " vertices");
    if (m.material < 0 || m.material >= n_materials)
      bad(part, "material " + std::to_string(m.material) + " is out of range (scene has " + std::to_string(n_materials) + " materials)");
    for (std::size_t v = 0; v < nv; ++v) {
      const glm::vec3& p = m.positions[v];
      if (!finite(p)) bad(part, "positions[" + std::to_string(v) + "] = " + str(p) + " is not finite");
      if (glm::any(glm::greaterThan(glm::abs(p), glm::vec3(kMaxCoordinate))))
        bad(part, "positions[" + std::to_string(v) + "] = " + str(p) + " is beyond " + str(kMaxCoordinate) + " m (absurd size)");
      const glm::vec3& n = m.normals[v];
      if (!finite(n)) bad(part, "normals[" + std::to_string(v) + "] = " + str(n) + " is not finite");
      const float len = glm::length(n);
      if (std::abs(len - 1.0f) > kUnitNormalTolerance)
        bad(part, "normals[" + std::to_string(v) + "] = " + str(n) + " has length " + str(len) + " (unit length required)");
      if (!m.uvs.empty() && !finite(m.uvs[v])) bad(part, "uvs[" + std::to_string(v) + "] is not finite");
      if (!m.colors.empty()) check_colour(part, "colors[" + std::to_string(v) + "]", m.colors[v]);
      if (!m.weights.empty()) {
        const glm::vec4& w = m.weights[v];
        if (!finite(w) || w.x < 0.0f || w.y < 0.0f || w.z < 0.0f || w.w < 0.0f)
          bad(part, "weights[" + std::to_string(v) + "] = " + str(w) + " must be finite and non-negative");
        const float sum = w.x + w.y + w.z + w.w;
        if (std::abs(sum - 1.0f) > kWeightSumTolerance)
          bad(part, "weights[" + std::to_string(v) + "] = " + str(w) + " sums to " + str(sum) + " (must sum to 1)");
      }
    }
    for (std::size_t t = 0; t < m.triangles.size(); ++t) {
      const glm::uvec3& tri = m.triangles[t];
      for (int k = 0; k < 3; ++k)
        if (tri[k] >= nv)
          bad(part, "triangle " + std::to_string(t) + " index " + std::to_string(tri[k]) + " is out of range (" + std::to_string(nv) + " vertices)");
      const glm::vec3 a = m.positions[tri[0]], b = m.positions[tri[1]], c = m.positions[tri[2]];
      const float longest2 = std::max({glm::dot(b - a, b - a), glm::dot(c - b, c - b), glm::dot(a - c, a - c)});
      const float cross = glm::length(glm::cross(b - a, c - a));
      if (!(cross > kZeroAreaRelative * longest2))
        bad(part, "triangle " + std::to_string(t) + " (" + std::to_string(tri[0]) + ", " + std::to_string(tri[1]) + ", " +
                      std::to_string(tri[2]) + ") has zero area");
    }
  }

  for (int i = 0; i < n_materials; ++i) {
    const Material& m = scene.materials[i];
    const std::string part = "material " + q(m.name) + " (index " + std::to_string(i) + ")";
    if (!finite(m.albedo) || !nonneg(m.albedo) || m.albedo.x > 1.0f || m.albedo.y > 1.0f || m.albedo.z > 1.0f)
      bad(part, "albedo " + str(m.albedo) + " must be in [0, 1]");
    if (m.albedo_texture < -1 || m.albedo_texture >= n_textures)
      bad(part, "albedo_texture " + std::to_string(m.albedo_texture) + " is out of range (" + std::to_string(n_textures) + " textures)");
    if (!std::isfinite(m.phong_ns) || m.phong_ns < 0.0f) bad(part, "phong_ns " + str(m.phong_ns) + " must be finite and >= 0");
    if (!std::isfinite(m.glossy) || m.glossy < 0.0f || m.glossy > 1.0f) bad(part, "glossy " + str(m.glossy) + " must be in [0, 1]");
  }

  for (int i = 0; i < n_textures; ++i) {
    const Texture& t = scene.textures[i];
    const std::string part = "texture " + q(t.name) + " (index " + std::to_string(i) + ")";
    if (t.width <= 0 || t.height <= 0 || t.width > kMaxTextureSize || t.height > kMaxTextureSize)
      bad(part, "size " + std::to_string(t.width) + "x" + std::to_string(t.height) + " is outside 1.." + std::to_string(kMaxTextureSize));
    if (t.texels.size() != static_cast<std::size_t>(t.width) * t.height)
      bad(part, "has " + std::to_string(t.texels.size()) + " texels for " + std::to_string(t.width) + "x" + std::to_string(t.height));
    for (std::size_t k = 0; k < t.texels.size(); ++k)
      if (!finite(t.texels[k]) || !nonneg(t.texels[k])) bad(part, "texels[" + std::to_string(k) + "] = " + str(t.texels[k]) + " must be finite and non-negative");
  }

  for (int i = 0; i < n_nodes; ++i) {
    const Node& n = scene.nodes[i];
    const std::string part = "node " + q(n.name) + " (index " + std::to_string(i) + ")";
    if (n.parent < -1 || n.parent >= n_nodes || n.parent == i)
      bad(part, "parent " + std::to_string(n.parent) + " is out of range (" + std::to_string(n_nodes) + " nodes)");
    if (n.mesh < -1 || n.mesh >= n_meshes) bad(part, "mesh " + std::to_string(n.mesh) + " is out of range (" + std::to_string(n_meshes) + " meshes)");
    if (n.skin < -1 || n.skin >= n_skins) bad(part, "skin " + std::to_string(n.skin) + " is out of range (" + std::to_string(n_skins) + " skins)");
    if (!finite(n.translation) || glm::any(glm::greaterThan(glm::abs(n.translation), glm::vec3(kMaxCoordinate))))
      bad(part, "translation " + str(n.translation) + " must be finite and within " + str(kMaxCoordinate) + " m");
    const glm::vec4 r(n.rotation.x, n.rotation.y, n.rotation.z, n.rotation.w);
    if (!finite(r) || std::abs(glm::length(r) - 1.0f) > kUnitQuatTolerance) bad(part, "rotation (x, y, z, w) " + str(r) + " is not a unit quaternion");
    if (!finite(n.scale) || n.scale.x == 0.0f || n.scale.y == 0.0f || n.scale.z == 0.0f)
      bad(part, "scale " + str(n.scale) + " must be finite and non-zero");
    if (!in_scale_range(n.scale))
      bad(part, "scale " + str(n.scale) + ": each |component| must be in [" + str(kMinScale) + ", " + str(kMaxScale) + "]");
    if (n.skin >= 0 && n.mesh >= 0) {
      const Mesh& m = scene.meshes[n.mesh];
      const std::size_t nj = scene.skins[n.skin].joints.size();
      for (std::size_t v = 0; v < m.joints.size(); ++v)
        for (int k = 0; k < 4; ++k)
          if (m.weights[v][k] != 0.0f && m.joints[v][k] >= nj)
            bad(part, "mesh " + q(m.name) + " vertex " + std::to_string(v) + " uses joint " + std::to_string(m.joints[v][k]) +
                          " but skin " + q(scene.skins[n.skin].name) + " has " + std::to_string(nj) + " joints");
    }
  }
  // Cycles in the parent chains.
  for (int i = 0; i < n_nodes; ++i) {
    int k = i, steps = 0;
    while (k >= 0) {
      if (++steps > n_nodes) bad("node " + q(scene.nodes[i].name) + " (index " + std::to_string(i) + ")", "parent chain has a cycle");
      k = scene.nodes[k].parent;
    }
  }

  check_world_transforms(scene);

  for (int i = 0; i < n_skins; ++i) {
    const Skin& s = scene.skins[i];
    const std::string part = "skin " + q(s.name) + " (index " + std::to_string(i) + ")";
    if (s.joints.empty()) bad(part, "has no joints");
    if (s.inverse_bind.size() != s.joints.size())
      bad(part, "has " + std::to_string(s.joints.size()) + " joints but " + std::to_string(s.inverse_bind.size()) + " inverse_bind matrices");
    for (std::size_t j = 0; j < s.joints.size(); ++j) {
      if (s.joints[j] < 0 || s.joints[j] >= n_nodes) bad(part, "joints[" + std::to_string(j) + "] = " + std::to_string(s.joints[j]) + " is out of range");
      if (!finite(s.inverse_bind[j])) bad(part, "inverse_bind[" + std::to_string(j) + "] is not finite");
    }
  }

  for (std::size_t ci = 0; ci < scene.clips.size(); ++ci) {
    const AnimationClip& c = scene.clips[ci];
    const std::string part = "clip " + q(c.name) + " (index " + std::to_string(ci) + ")";
    if (!std::isfinite(c.duration) || c.duration < 0.0f) bad(part, "duration " + str(c.duration) + " must be finite and >= 0");
    for (std::size_t k = 0; k < c.channels.size(); ++k) {
      const AnimationChannel& ch = c.channels[k];
      const std::string cpart = part + " channel " + std::to_string(k);
      if (ch.node < 0 || ch.node >= n_nodes) bad(cpart, "node " + std::to_string(ch.node) + " is out of range (" + std::to_string(n_nodes) + " nodes)");
      if (ch.times.empty()) bad(cpart, "has no keyframes");
      if (ch.times.size() != ch.values.size())
        bad(cpart, "has " + std::to_string(ch.times.size()) + " times but " + std::to_string(ch.values.size()) + " values");
      for (std::size_t j = 0; j < ch.times.size(); ++j) {
        if (!std::isfinite(ch.times[j]) || ch.times[j] < 0.0f) bad(cpart, "times[" + std::to_string(j) + "] = " + str(ch.times[j]) + " must be finite and >= 0");
        if (j > 0 && !(ch.times[j] > ch.times[j - 1]))
          bad(cpart, "times[" + std::to_string(j) + "] = " + str(ch.times[j]) + " is not greater than times[" + std::to_string(j - 1) + "] = " + str(ch.times[j - 1]) + " (must strictly increase)");
        const glm::vec4& v = ch.values[j];
        if (!finite(v)) bad(cpart, "values[" + std::to_string(j) + "] = " + str(v) + " is not finite");
        if (ch.path == AnimationChannel::Path::Rotation && std::abs(glm::length(v) - 1.0f) > kUnitQuatTolerance)
          bad(cpart, "values[" + std::to_string(j) + "] = " + str(v) + " is not a unit quaternion (x, y, z, w)");
        if (ch.path == AnimationChannel::Path::Scale && (v.x == 0.0f || v.y == 0.0f || v.z == 0.0f))
          bad(cpart, "values[" + std::to_string(j) + "] = " + str(v) + " is a zero scale");
        if (ch.path == AnimationChannel::Path::Scale && !in_scale_range(glm::vec3(v)))
          bad(cpart, "values[" + std::to_string(j) + "] = " + str(v) + " is a scale outside |component| in [" + str(kMinScale) +
                         ", " + str(kMaxScale) + "]");
        if (ch.path == AnimationChannel::Path::Translation && glm::any(glm::greaterThan(glm::abs(glm::vec3(v)), glm::vec3(kMaxCoordinate))))
          bad(cpart, "values[" + std::to_string(j) + "] = " + str(v) + " is beyond " + str(kMaxCoordinate) + " m (absurd size)");
      }
    }
  }
  if (scene.active_clip < -1 || scene.active_clip >= static_cast<int>(scene.clips.size()))
    bad("scene " + q(scene.name), "active_clip " + std::to_string(scene.active_clip) + " is out of range (" + std::to_string(scene.clips.size()) + " clips)");

  for (std::size_t pi = 0; pi < scene.proxies.size(); ++pi) {
    const ProxySet& p = scene.proxies[pi];
    const std::string part = "proxy set " + q(p.name) + " (index " + std::to_string(pi) + ")";
    if (p.node < -1 || p.node >= n_nodes) bad(part, "node " + std::to_string(p.node) + " is out of range (" + std::to_string(n_nodes) + " nodes)");
    check_colour(part, "albedo", p.albedo);
    if (!p.sphere_albedo.empty() && p.sphere_albedo.size() != p.spheres.size())
      bad(part, "has " + std::to_string(p.sphere_albedo.size()) + " sphere albedos for " + std::to_string(p.spheres.size()) + " spheres");
    for (std::size_t k = 0; k < p.sphere_albedo.size(); ++k) check_colour(part, "sphere_albedo[" + std::to_string(k) + "]", p.sphere_albedo[k]);
    if (p.joints.size() != p.weights.size() || (!p.joints.empty() && p.joints.size() != p.spheres.size()))
      bad(part, "has " + std::to_string(p.joints.size()) + " joints and " + std::to_string(p.weights.size()) + " weights for " + std::to_string(p.spheres.size()) + " spheres");
    std::size_t nj = 0;
    if (!p.joints.empty()) {
      if (p.node < 0 || scene.nodes[p.node].skin < 0) bad(part, "has per-sphere joints but its node " + std::to_string(p.node) + " has no skin");
      nj = scene.skins[scene.nodes[p.node].skin].joints.size();
    }
    for (std::size_t k = 0; k < p.spheres.size(); ++k) {
      const Sphere& s = p.spheres[k];
      if (!finite(s.center) || glm::any(glm::greaterThan(glm::abs(s.center), glm::vec3(kMaxCoordinate))))
        bad(part, "spheres[" + std::to_string(k) + "].center " + str(s.center) + " must be finite and within " + str(kMaxCoordinate) + " m");
      if (!std::isfinite(s.radius) || s.radius <= 0.0f || s.radius > kMaxCoordinate)
        bad(part, "spheres[" + std::to_string(k) + "].radius " + str(s.radius) + " must be finite and in (0, " + str(kMaxCoordinate) + "]");
      if (!p.joints.empty()) {
        const glm::vec4& w = p.weights[k];
        if (!finite(w) || w.x < 0.0f || w.y < 0.0f || w.z < 0.0f || w.w < 0.0f || std::abs(w.x + w.y + w.z + w.w - 1.0f) > kWeightSumTolerance)
          bad(part, "weights[" + std::to_string(k) + "] = " + str(w) + " must be non-negative and sum to 1");
        for (int j = 0; j < 4; ++j)
          if (w[j] != 0.0f && p.joints[k][j] >= nj)
            bad(part, "joints[" + std::to_string(k) + "] uses joint " + std::to_string(p.joints[k][j]) + " of a skin with " + std::to_string(nj) + " joints");
      }
    }
  }

  {
    const Camera& c = scene.camera;
    const std::string part = "camera";
    if (!finite(c.position) || !finite(c.target) || !finite(c.up)) bad(part, "position/target/up must be finite");
    if (glm::length(c.target - c.position) <= 0.0f) bad(part, "target " + str(c.target) + " equals position " + str(c.position));
    if (glm::length(glm::cross(c.target - c.position, c.up)) <= 1e-6f * glm::length(c.target - c.position) * glm::length(c.up))
      bad(part, "up " + str(c.up) + " is parallel to the view direction (or zero)");
    if (!std::isfinite(c.fov_y_deg) || c.fov_y_deg <= 0.0f || c.fov_y_deg >= 180.0f) bad(part, "fov_y_deg " + str(c.fov_y_deg) + " must be in (0, 180)");
    if (c.width < 1 || c.height < 1 || c.width > kMaxTextureSize || c.height > kMaxTextureSize)
      bad(part, "size " + std::to_string(c.width) + "x" + std::to_string(c.height) + " is outside 1.." + std::to_string(kMaxTextureSize));
  }

  {
    const Environment& e = scene.environment;
    const std::string part = "environment";
    if (!std::isfinite(e.intensity) || e.intensity < 0.0f) bad(part, "intensity " + str(e.intensity) + " must be finite and >= 0");
    if (!std::isfinite(e.rotation_y)) bad(part, "rotation_y " + str(e.rotation_y) + " is not finite");
    if (e.kind == Environment::Kind::Sky) {
      check_colour(part, "zenith", e.zenith);
      check_colour(part, "horizon", e.horizon);
      check_colour(part, "ground", e.ground);
      check_colour(part, "sun_radiance", e.sun_radiance);
      if (!finite(e.sun_direction) || std::abs(glm::length(e.sun_direction) - 1.0f) > kUnitNormalTolerance)
        bad(part, "sun_direction " + str(e.sun_direction) + " must be a unit vector");
      if (!std::isfinite(e.sun_radius) || e.sun_radius < 0.0f || e.sun_radius > 0.5f * static_cast<float>(kPi))
        bad(part, "sun_radius " + str(e.sun_radius) + " must be in [0, pi/2] radians");
    } else {
      const std::string mpart = "environment map " + q(e.map_path);
      if (e.map_width <= 0 || e.map_height <= 0 || e.map_width > 65536 || e.map_height > 65536)
        bad(mpart, "size " + std::to_string(e.map_width) + "x" + std::to_string(e.map_height) + " is not a valid lat-long map");
      if (e.map_rgb.size() != static_cast<std::size_t>(e.map_width) * e.map_height * 3)
        bad(mpart, "has " + std::to_string(e.map_rgb.size()) + " floats for " + std::to_string(e.map_width) + "x" + std::to_string(e.map_height) + "x3");
      // Radiance is never negative. A scene file's map has been clamped by its loader (lossy HDR
      // compression rings below zero; the loader reports it in Scene::notices); a map built in code
      // that still holds a negative value is a bug of its maker, and an error here.
      for (std::size_t k = 0; k < e.map_rgb.size(); ++k)
        if (!std::isfinite(e.map_rgb[k]) || e.map_rgb[k] < 0.0f)
          bad(mpart, "pixel (" + std::to_string(k / 3 % e.map_width) + ", " + std::to_string(k / 3 / e.map_width) + ") channel " +
                         std::to_string(k % 3) + " = " + str(e.map_rgb[k]) + " must be finite and non-negative");
    }
  }

  for (std::size_t i = 0; i < scene.lights.size(); ++i) {
    const SphericalLight& l = scene.lights[i];
    const std::string part = "light " + q(l.name) + " (index " + std::to_string(i) + ")";
    if (!finite(l.position) || glm::any(glm::greaterThan(glm::abs(l.position), glm::vec3(kMaxCoordinate))))
      bad(part, "position " + str(l.position) + " must be finite and within " + str(kMaxCoordinate) + " m");
    if (!std::isfinite(l.radius) || l.radius <= 0.0f) bad(part, "radius " + str(l.radius) + " must be finite and > 0");
    check_colour(part, "radiance", l.radiance);
    if (l.node < -1 || l.node >= n_nodes) bad(part, "node " + std::to_string(l.node) + " is out of range (" + std::to_string(n_nodes) + " nodes)");
  }
}

namespace {
const Material& material_of(const Scene& sc, const PosedObject& obj) {
  static const Material kDefault{};
  return obj.material >= 0 && obj.material < static_cast<int>(sc.materials.size()) ? sc.materials[obj.material] : kDefault;
}
}  // namespace

bool constant_albedo(const Scene& sc, const PosedObject& obj, glm::vec3& albedo) {
  // The branches of surface_albedo that read the point: a texture with uvs, vertex colours.
  const Material& m = material_of(sc, obj);
  albedo = m.albedo;
  if (!obj.source) return true;
  const Mesh& mesh = *obj.source;
  const bool textured = m.albedo_texture >= 0 && m.albedo_texture < static_cast<int>(sc.textures.size()) &&
                        mesh.uvs.size() == mesh.positions.size();
  return !textured && mesh.colors.size() != mesh.positions.size();
}

glm::vec3 surface_albedo(const Scene& sc, const PosedObject& obj, std::size_t prim, float b1, float b2) {
  const Material& m = material_of(sc, obj);
  glm::vec3 albedo = m.albedo;
  if (!obj.source || prim >= obj.source->triangles.size()) return albedo;
  const Mesh& mesh = *obj.source;
  const glm::uvec3 tri = mesh.triangles[prim];
  const float b0 = 1.0f - b1 - b2;
  if (m.albedo_texture >= 0 && m.albedo_texture < static_cast<int>(sc.textures.size()) && mesh.uvs.size() == mesh.positions.size())
    albedo *= sc.textures[m.albedo_texture].sample(b0 * mesh.uvs[tri.x] + b1 * mesh.uvs[tri.y] + b2 * mesh.uvs[tri.z]);
  if (mesh.colors.size() == mesh.positions.size())
    albedo *= b0 * mesh.colors[tri.x] + b1 * mesh.colors[tri.y] + b2 * mesh.colors[tri.z];
  return albedo;
}

}  // namespace softgi::scene
