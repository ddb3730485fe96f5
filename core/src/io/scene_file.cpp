// The JSON scene file and the proxy-set file (docs/scene_format.md), through nlohmann-json 3.11.
//
// Every error names the file, the JSON path of the field and the offending value:
//   scene.json: objects[2].transform.translation[1]: expected a finite number, got "nan"
// Unknown keys and duplicate keys are errors, so a typo never passes silently.
#include "softgi/io/scene_file.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <map>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <glm/gtc/constants.hpp>
#include <glm/gtc/quaternion.hpp>

#include "softgi/io/gltf.hpp"
#include "softgi/io/image_io.hpp"
#include "softgi/scene/builtin.hpp"

namespace softgi::io {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

// Sanity limits: beyond these a file is broken, not big. Resolution and coordinates match
// scene::validate (16384 pixels, 1e6 m) so the file's own error, with its JSON path, comes first.
constexpr std::size_t kMaxFileBytes = 64u << 20;  // a scene file references meshes; it does not hold them
constexpr int kMaxDepth = 64;                      // JSON nesting
constexpr int kMaxResolution = 16384;
constexpr double kMaxCoordinate = 1e6;  // metres
constexpr double kMaxRadiance = 1e9;
constexpr std::size_t kMaxObjects = 10000;
constexpr std::size_t kMaxLights = 10000;
constexpr std::size_t kMaxSpheres = 100000;
// A fit's cost grows with its sphere count; sets beyond this are fitted with `softgi fit-proxies`.
constexpr long long kMaxFitSpheres = 4096;
constexpr std::size_t kMaxChannels = 10000;
constexpr std::size_t kMaxKeys = 1000000;
constexpr int kMaxSegments = 1024;
// Built-in planes and boxes are grids of segments x segments quads per face: fine enough by default
// for per-vertex receivers to show a proxy's shadow (64 over a 1 m plane: 1.6 cm spacing).
constexpr int kPlaneSegments = 64, kBoxSegments = 16, kMaxGridSegments = 1024;
constexpr std::size_t kMaxStringBytes = 4096;
constexpr std::size_t kShownChars = 60;  // longest value excerpt quoted in an error

constexpr const char* kProxyFormat = "softgi-proxies";
// Version 2 added the optional per-sphere "albedo"; version 1 files read as before.
constexpr int kProxyVersion = 2;

// ---- values in error messages ----

std::string excerpt(const std::string& s) {
  std::string out;
  for (unsigned char c : s) {
    if (out.size() >= kShownChars) {
      out += "...";
      break;
    }
    if (c == '"' || c == '\\') {
      out += '\\';
      out += char(c);
    } else if (c < 0x20 || c == 0x7f) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02x", c);
      out += buf;
    } else {
      out += char(c);
    }
  }
  return "\"" + out + "\"";
}

// A short rendering of a JSON value; containers are summarised (never dumped whole: they may be
// huge or deeply nested).
std::string show(const json& v) {
  switch (v.type()) {
    case json::value_t::null: return "null";
    case json::value_t::boolean: return v.get<bool>() ? "true" : "false";
    case json::value_t::string: return excerpt(v.get_ref<const std::string&>());
    case json::value_t::number_integer: return std::to_string(v.get<std::int64_t>());
    case json::value_t::number_unsigned: return std::to_string(v.get<std::uint64_t>());
    case json::value_t::number_float: {
      const double d = v.get<double>();
      if (std::isnan(d)) return "nan";
      if (std::isinf(d)) return d > 0 ? "inf" : "-inf";
      std::ostringstream s;
      s.precision(9);
      s << d;
      return s.str();
    }
    case json::value_t::array: return "an array of " + std::to_string(v.size()) + (v.size() == 1 ? " element" : " elements");
    case json::value_t::object: return "an object with " + std::to_string(v.size()) + (v.size() == 1 ? " key" : " keys");
    default: return "a value of unsupported type";
  }
}

std::string number_text(double d) {
  std::ostringstream s;
  s.precision(9);
  s << d;
  return s.str();
}

std::size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> prev(b.size() + 1), cur(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) prev[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    cur[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
    }
    std::swap(prev, cur);
  }
  return prev[b.size()];
}

std::string child(const std::string& path, const std::string& key) { return path.empty() ? key : path + "." + key; }
std::string child(const std::string& path, std::size_t i) { return path + "[" + std::to_string(i) + "]"; }

// ---- the reader: typed access with errors naming file, JSON path and value ----

class Reader {
 public:
  Reader(std::string file, std::string base_dir) : file_(std::move(file)), base_dir_(std::move(base_dir)) {}

  [[noreturn]] void fail(const std::string& path, const std::string& what) const {
    throw std::runtime_error(file_ + ": " + (path.empty() ? std::string() : path + ": ") + what);
  }
  // `what` is a whole phrase ("expected a string", "duplicate object name"); the value follows.
  [[noreturn]] void fail(const std::string& path, const std::string& what, const json& got) const {
    fail(path, what + ", got " + show(got));
  }

  // Parses with a nesting limit and duplicate-key detection.
  json parse(const std::string& text) const {
    if (text.size() > kMaxFileBytes) {
      fail("", "file of " + std::to_string(text.size()) + " bytes exceeds the " + std::to_string(kMaxFileBytes >> 20) +
                   " MiB limit for scene files");
    }
    struct Frame {
      bool array = false;
      std::size_t index = 0;
      std::string key;
      std::set<std::string> keys;
    };
    std::vector<Frame> stack;
    auto path_of = [&stack]() {
      std::string p;
      for (std::size_t i = 0; i + 1 < stack.size(); ++i) p = stack[i].array ? child(p, stack[i].index) : child(p, stack[i].key);
      return p;
    };
    auto completed = [&stack]() {
      if (!stack.empty() && stack.back().array) ++stack.back().index;
    };
    json::parser_callback_t cb = [&](int depth, json::parse_event_t event, json& parsed) -> bool {
      switch (event) {
        case json::parse_event_t::object_start:
        case json::parse_event_t::array_start:
          if (depth >= kMaxDepth) fail(path_of(), "JSON nested deeper than " + std::to_string(kMaxDepth) + " levels");
          stack.push_back(Frame{event == json::parse_event_t::array_start, 0, {}, {}});
          break;
        case json::parse_event_t::key: {
          const std::string& k = parsed.get_ref<const std::string&>();
          if (!stack.back().keys.insert(k).second) {
            std::string p = path_of();
            fail(p, "duplicate key " + excerpt(k));
          }
          stack.back().key = k;
          break;
        }
        case json::parse_event_t::object_end:
        case json::parse_event_t::array_end:
          stack.pop_back();
          completed();
          break;
        case json::parse_event_t::value:
          completed();
          break;
      }
      return true;
    };
    try {
      return json::parse(text, cb, true, false);
    } catch (const json::exception& e) {
      // Syntax errors ("[json.exception.parse_error.101] parse error at line 3, column 5: ...") and
      // number overflow ("[json.exception.out_of_range.406] number overflow parsing '1e999'").
      std::string what = e.what();
      if (auto pos = what.find("] "); pos != std::string::npos) what = what.substr(pos + 2);
      fail("", "invalid JSON: " + what);
    }
  }

  // Checks `v` is an object whose keys are all in `allowed`.
  void object(const json& v, const std::string& path, std::initializer_list<const char*> allowed) const {
    if (!v.is_object()) fail(path, "expected an object", v);
    for (auto it = v.begin(); it != v.end(); ++it) {
      bool known = false;
      for (const char* a : allowed) known = known || it.key() == a;
      if (known) continue;
      std::string list, best;
      std::size_t best_d = 3;  // suggest only close matches
      for (const char* a : allowed) {
        list += (list.empty() ? "" : ", ") + std::string(a);
        const std::size_t d = edit_distance(it.key(), a);
        if (d < best_d) {
          best_d = d;
          best = a;
        }
      }
      fail(child(path, it.key()), "unknown key " + excerpt(it.key()) +
                                      (best.empty() ? std::string() : " (did you mean \"" + best + "\"?)") +
                                      "; allowed keys: " + list);
    }
  }

  double number(const json& v, const std::string& path, double lo, double hi, bool lo_open = false) const {
    std::string range(lo_open ? "(" : "[");
    range.append(number_text(lo)).append(", ").append(number_text(hi)).append("]");
    if (!v.is_number()) fail(path, "expected a finite number in " + range, v);
    const double d = v.get<double>();
    if (!std::isfinite(d)) fail(path, "expected a finite number in " + range, v);
    if (d < lo || d > hi || (lo_open && d == lo)) fail(path, "expected a number in " + range, v);
    return d;
  }
  float real(const json& v, const std::string& path, double lo, double hi, bool lo_open = false) const {
    return static_cast<float>(number(v, path, lo, hi, lo_open));
  }

  std::int64_t integer(const json& v, const std::string& path, std::int64_t lo, std::int64_t hi) const {
    std::string range("[");
    range.append(std::to_string(lo)).append(", ").append(std::to_string(hi)).append("]");
    if (v.is_number_integer() || v.is_number_unsigned()) {
      if (v.is_number_unsigned() && v.get<std::uint64_t>() > std::uint64_t(hi)) fail(path, "expected an integer in " + range, v);
      const std::int64_t i = v.is_number_unsigned() ? std::int64_t(v.get<std::uint64_t>()) : v.get<std::int64_t>();
      if (i < lo || i > hi) fail(path, "expected an integer in " + range, v);
      return i;
    }
    if (v.is_number_float()) {
      const double d = v.get<double>();
      if (std::isfinite(d) && d == std::floor(d) && d >= double(lo) && d <= double(hi)) return std::int64_t(d);
    }
    fail(path, "expected an integer in " + range, v);
  }

  bool boolean(const json& v, const std::string& path) const {
    if (!v.is_boolean()) fail(path, "expected true or false", v);
    return v.get<bool>();
  }

  const std::string& string(const json& v, const std::string& path, bool allow_empty = false) const {
    if (!v.is_string()) fail(path, "expected a string", v);
    const std::string& s = v.get_ref<const std::string&>();
    if (!allow_empty && s.empty()) fail(path, "expected a non-empty string", v);
    if (s.size() > kMaxStringBytes) fail(path, "string longer than " + std::to_string(kMaxStringBytes) + " bytes", v);
    return s;
  }

  const json& array(const json& v, const std::string& path, std::size_t min_n, std::size_t max_n) const {
    if (!v.is_array()) fail(path, "expected an array", v);
    if (v.size() < min_n || v.size() > max_n) {
      fail(path, "expected an array of " + (min_n == max_n ? std::to_string(min_n)
                                                          : std::to_string(min_n) + " to " + std::to_string(max_n)) +
                     " elements", v);
    }
    return v;
  }

  template <int N>
  glm::vec<N, float> vec(const json& v, const std::string& path, double lo, double hi) const {
    array(v, path, N, N);
    glm::vec<N, float> out;
    for (int k = 0; k < N; ++k) out[k] = real(v[std::size_t(k)], child(path, std::size_t(k)), lo, hi);
    return out;
  }
  glm::vec3 position(const json& v, const std::string& path) const { return vec<3>(v, path, -kMaxCoordinate, kMaxCoordinate); }
  glm::vec3 colour(const json& v, const std::string& path, double hi) const { return vec<3>(v, path, 0.0, hi); }
  glm::vec3 direction(const json& v, const std::string& path) const {
    const glm::vec3 d = vec<3>(v, path, -kMaxCoordinate, kMaxCoordinate);
    const float len = glm::length(d);
    if (!(len > 1e-6f)) fail(path, "expected a non-zero direction", v);
    return d / len;
  }
  // A number or an array of N numbers (per-axis sizes, scales).
  template <int N>
  glm::vec<N, float> size(const json& v, const std::string& path, double lo, double hi, bool lo_open) const {
    if (v.is_number()) return glm::vec<N, float>(real(v, path, lo, hi, lo_open));
    array(v, path, N, N);
    glm::vec<N, float> out;
    for (int k = 0; k < N; ++k) out[k] = real(v[std::size_t(k)], child(path, std::size_t(k)), lo, hi, lo_open);
    return out;
  }

  std::string resolve(const std::string& p) const {
    fs::path fp(p);
    if (fp.is_absolute() || base_dir_.empty()) return fp.lexically_normal().string();
    return (fs::path(base_dir_) / fp).lexically_normal().string();
  }

  const std::string& file() const { return file_; }

 private:
  std::string file_, base_dir_;
};

// ---- built-in meshes ----

// A grid of (segments + 1)^2 vertices on one face: centre c, half-axes du and dv, normal n = du x dv
// direction. Per-vertex receivers (SHEXP) shade at vertices, so a face must be tessellated finely
// enough for a shadow to fall between them.
void add_grid_face(scene::Mesh& m, glm::vec3 c, glm::vec3 du, glm::vec3 dv, glm::vec3 n, int segments) {
  const auto base = std::uint32_t(m.positions.size());
  for (int i = 0; i <= segments; ++i)
    for (int j = 0; j <= segments; ++j) {
      const float a = float(i) / float(segments), b = float(j) / float(segments);
      m.positions.push_back(c + (2.0f * a - 1.0f) * du + (2.0f * b - 1.0f) * dv);
      m.normals.push_back(n);
      m.uvs.emplace_back(a, b);
    }
  const auto at = [&](int i, int j) { return base + std::uint32_t(i * (segments + 1) + j); };
  for (int i = 0; i < segments; ++i)
    for (int j = 0; j < segments; ++j) {
      // Wound so that (b - a) x (c - a) is along du x dv.
      m.triangles.emplace_back(at(i, j), at(i + 1, j), at(i + 1, j + 1));
      m.triangles.emplace_back(at(i, j), at(i + 1, j + 1), at(i, j + 1));
    }
}

scene::Mesh make_plane(glm::vec2 size, int segments) {
  scene::Mesh m;
  m.name = "builtin:plane";
  // du x dv = +z x +x = +y: counter-clockwise seen from above.
  add_grid_face(m, glm::vec3(0.0f), glm::vec3(0, 0, 0.5f * size.y), glm::vec3(0.5f * size.x, 0, 0), glm::vec3(0, 1, 0), segments);
  return m;
}

// UV sphere: `segments` around, segments/2 rings; normals are exact (position / radius).
scene::Mesh make_sphere(float radius, int segments) {
  scene::Mesh m;
  m.name = "builtin:sphere";
  const int rings = std::max(2, segments / 2);
  for (int i = 0; i <= rings; ++i) {
    const float theta = glm::pi<float>() * float(i) / float(rings);
    for (int j = 0; j <= segments; ++j) {
      const float phi = glm::two_pi<float>() * float(j) / float(segments);
      const glm::vec3 n(std::sin(theta) * std::cos(phi), std::cos(theta), std::sin(theta) * std::sin(phi));
      m.positions.push_back(radius * n);
      m.normals.push_back(n);
      m.uvs.emplace_back(float(j) / float(segments), float(i) / float(rings));
    }
  }
  auto at = [segments](int i, int j) { return std::uint32_t(i * (segments + 1) + j); };
  for (int i = 0; i < rings; ++i) {
    for (int j = 0; j < segments; ++j) {
      // Wound so that (b - a) x (c - a) points outwards; the pole rows have one triangle per quad.
      if (i != 0) m.triangles.emplace_back(at(i, j), at(i, j + 1), at(i + 1, j + 1));
      if (i != rings - 1) m.triangles.emplace_back(at(i, j), at(i + 1, j + 1), at(i + 1, j));
    }
  }
  return m;
}

scene::Mesh make_box(glm::vec3 size, int segments) {
  scene::Mesh m;
  m.name = "builtin:box";
  const glm::vec3 h = 0.5f * size;
  for (int axis = 0; axis < 3; ++axis) {
    for (int sign = -1; sign <= 1; sign += 2) {
      glm::vec3 n(0.0f), u(0.0f), v(0.0f);
      n[axis] = float(sign);
      u[(axis + 1) % 3] = 1.0f;
      v[(axis + 2) % 3] = 1.0f;
      if (sign < 0) std::swap(u, v);  // keep u x v = n, so the winding faces outwards
      add_grid_face(m, n * h, u * h, v * h, n, segments);
    }
  }
  return m;
}

// ---- shared pieces of the scene and proxy formats ----

scene::Sphere read_sphere(const Reader& r, const json& v, const std::string& path, bool allow_skin) {
  if (allow_skin) {
    r.object(v, path, {"center", "radius", "joints", "weights", "albedo"});
  } else {
    r.object(v, path, {"center", "radius"});
  }
  if (!v.contains("center")) r.fail(path, "missing key \"center\"");
  if (!v.contains("radius")) r.fail(path, "missing key \"radius\"");
  scene::Sphere s;
  s.center = r.position(v["center"], child(path, "center"));
  s.radius = r.real(v["radius"], child(path, "radius"), 0.0, kMaxCoordinate, true);
  return s;
}

// Shortest decimal that reads back as the same float, as a JSON number (0.8f is written 0.8).
json float_json(float f) {
  char buf[32];
  auto res = std::to_chars(buf, buf + sizeof buf, f);
  return json(std::strtod(std::string(buf, res.ptr).c_str(), nullptr));
}
json vec_json(const float* v, int n) {
  json a = json::array();
  for (int k = 0; k < n; ++k) a.push_back(float_json(v[k]));
  return a;
}

std::string read_text(const std::string& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw std::runtime_error(path + ": no such file");
  if (!fs::is_regular_file(path, ec)) throw std::runtime_error(path + ": not a regular file");
  const auto size = fs::file_size(path, ec);
  if (ec) throw std::runtime_error(path + ": cannot read size: " + ec.message());
  if (size > kMaxFileBytes) {
    throw std::runtime_error(path + ": file of " + std::to_string(size) + " bytes exceeds the " +
                             std::to_string(kMaxFileBytes >> 20) + " MiB limit");
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(path + ": cannot open for reading");
  std::ostringstream s;
  s << in.rdbuf();
  if (in.bad()) throw std::runtime_error(path + ": read error");
  return s.str();
}

void write_text_atomic(const std::string& path, const std::string& text) {
  if (path.empty()) throw std::runtime_error("cannot write to an empty path");
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw std::runtime_error(path + ": cannot open " + tmp + " for writing");
    out << text;
    out.flush();
    if (!out) {
      std::error_code ec;
      fs::remove(tmp, ec);
      throw std::runtime_error(path + ": write failed");
    }
  }
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) {
    std::error_code ignored;
    fs::remove(tmp, ignored);
    throw std::runtime_error(path + ": cannot rename " + tmp + " into place: " + ec.message());
  }
}

scene::ProxySet parse_proxies(const Reader& r, const json& root) {
  r.object(root, "", {"format", "version", "name", "node", "albedo", "outside_volume_ratio", "spheres"});
  if (!root.contains("format")) r.fail("", "missing key \"format\" (expected \"" + std::string(kProxyFormat) + "\")");
  if (r.string(root["format"], "format") != kProxyFormat) {
    r.fail("format", "expected \"" + std::string(kProxyFormat) + "\"", root["format"]);
  }
  if (!root.contains("version")) r.fail("", "missing key \"version\"");
  r.integer(root["version"], "version", 1, kProxyVersion);
  scene::ProxySet ps;
  if (root.contains("name")) ps.name = r.string(root["name"], "name", true);
  if (root.contains("node")) ps.node = int(r.integer(root["node"], "node", -1, 1 << 24));
  if (root.contains("albedo")) ps.albedo = r.colour(root["albedo"], "albedo", 1.0);
  if (root.contains("outside_volume_ratio")) {
    const json& e = root["outside_volume_ratio"];
    // -1 marks "unknown", as in scene::ProxySet.
    ps.outside_volume_ratio = e.is_number() && e.get<double>() == -1.0 ? -1.0 : r.number(e, "outside_volume_ratio", 0.0, 1e9);
  }
  if (!root.contains("spheres")) r.fail("", "missing key \"spheres\"");
  const json& arr = r.array(root["spheres"], "spheres", 1, kMaxSpheres);
  for (std::size_t i = 0; i < arr.size(); ++i) {
    const std::string p = child("spheres", i);
    ps.spheres.push_back(read_sphere(r, arr[i], p, true));
    if (i > 0 && arr[i].contains("albedo") != !ps.sphere_albedo.empty())
      r.fail(p, "either every sphere has \"albedo\" or none does");
    if (arr[i].contains("albedo")) ps.sphere_albedo.push_back(r.colour(arr[i]["albedo"], child(p, "albedo"), 1.0));
    const bool has_j = arr[i].contains("joints"), has_w = arr[i].contains("weights");
    if (has_j != has_w) r.fail(p, "\"joints\" and \"weights\" must be given together");
    if (i > 0 && has_j != !ps.joints.empty()) r.fail(p, "either every sphere has \"joints\" and \"weights\" or none does");
    if (has_j) {
      const glm::vec4 j = r.vec<4>(arr[i]["joints"], child(p, "joints"), 0, 65535);
      for (int k = 0; k < 4; ++k) {
        if (j[k] != std::floor(j[k])) r.fail(child(child(p, "joints"), std::size_t(k)), "expected an integer joint index", arr[i]["joints"][std::size_t(k)]);
      }
      ps.joints.emplace_back(j);
      const glm::vec4 w = r.vec<4>(arr[i]["weights"], child(p, "weights"), 0.0, 1.0);
      const float sum = w.x + w.y + w.z + w.w;
      // The same tolerance as scene::validate's weight-sum check (8-bit quantised weights).
      if (std::fabs(sum - 1.0f) > 1e-2f) r.fail(child(p, "weights"), "weights sum to " + number_text(sum) + ", expected 1");
      ps.weights.push_back(w / sum);
    }
  }
  return ps;
}

// ---- the scene file ----

struct Object {
  std::string name;
  int node = -1;        // the object's own node (parent of a glTF file's roots)
  int mesh_node = -1;   // first node with a mesh: what proxies follow by default
  int first_file_node = -1, file_nodes = 0;  // the nodes a glTF file added, in load_gltf's order
  std::vector<int> materials;
};

// An object's "proxies": {"fit": N, ...}: fitted once the whole file has parsed (and only when
// LoadOptions::fit_proxies), so a file's syntax errors come before seconds of fitting.
struct PendingFit {
  std::string path;         // JSON path of the "proxies" field, for errors
  std::string object;
  std::vector<int> nodes;   // the object's nodes with a mesh
  ProxyFitSpec spec;
};

class SceneParser {
 public:
  SceneParser(const Reader& r, scene::Scene& s) : r_(r), s_(s) {}
  std::vector<PendingFit> fits;

  void run(const json& root) {
    r_.object(root, "", {"name", "description", "camera", "environment", "objects", "lights", "animation"});
    if (root.contains("name")) s_.name = r_.string(root["name"], "name");
    if (root.contains("description")) r_.string(root["description"], "description", true);
    if (root.contains("camera")) camera(root["camera"], "camera");
    if (root.contains("environment")) environment(root["environment"], "environment");
    if (root.contains("objects")) {
      const json& arr = r_.array(root["objects"], "objects", 0, kMaxObjects);
      for (std::size_t i = 0; i < arr.size(); ++i) object(arr[i], child("objects", i));
    }
    if (root.contains("lights")) {
      const json& arr = r_.array(root["lights"], "lights", 0, kMaxLights);
      for (std::size_t i = 0; i < arr.size(); ++i) light(arr[i], child("lights", i));
    }
    if (root.contains("animation")) animation(root["animation"], "animation");
  }

 private:
  const Reader& r_;
  scene::Scene& s_;
  std::vector<Object> objects_;

  void camera(const json& v, const std::string& path) {
    r_.object(v, path, {"position", "target", "up", "fov_y_deg", "width", "height"});
    scene::Camera& c = s_.camera;
    if (v.contains("position")) c.position = r_.position(v["position"], child(path, "position"));
    if (v.contains("target")) c.target = r_.position(v["target"], child(path, "target"));
    if (v.contains("up")) c.up = r_.direction(v["up"], child(path, "up"));
    if (v.contains("fov_y_deg")) c.fov_y_deg = r_.real(v["fov_y_deg"], child(path, "fov_y_deg"), 0.0, 179.0, true);
    if (v.contains("width")) c.width = int(r_.integer(v["width"], child(path, "width"), 1, kMaxResolution));
    if (v.contains("height")) c.height = int(r_.integer(v["height"], child(path, "height"), 1, kMaxResolution));
    const glm::vec3 d = c.target - c.position;
    if (!(glm::length(d) > 1e-6f)) r_.fail(path, "target equals position");
    if (!(glm::length(glm::cross(glm::normalize(d), c.up)) > 1e-4f)) {
      r_.fail(child(path, "up"), "is parallel to the view direction (target - position)");
    }
  }

  void environment(const json& v, const std::string& path) {
    r_.object(v, path, {"sky", "map", "intensity", "rotation_deg"});
    scene::Environment& e = s_.environment;
    if (v.contains("sky") == v.contains("map")) r_.fail(path, "expected exactly one of \"sky\" or \"map\"");
    if (v.contains("intensity")) e.intensity = r_.real(v["intensity"], child(path, "intensity"), 0.0, 1e6);
    if (v.contains("rotation_deg")) {
      e.rotation_y = glm::radians(r_.real(v["rotation_deg"], child(path, "rotation_deg"), -360.0, 360.0));
    }
    if (v.contains("sky")) {
      const std::string p = child(path, "sky");
      const json& sky = v["sky"];
      r_.object(sky, p, {"zenith", "horizon", "ground", "sun_direction", "sun_radius_deg", "sun_radiance"});
      e.kind = scene::Environment::Kind::Sky;
      if (sky.contains("zenith")) e.zenith = r_.colour(sky["zenith"], child(p, "zenith"), kMaxRadiance);
      if (sky.contains("horizon")) e.horizon = r_.colour(sky["horizon"], child(p, "horizon"), kMaxRadiance);
      if (sky.contains("ground")) e.ground = r_.colour(sky["ground"], child(p, "ground"), kMaxRadiance);
      if (sky.contains("sun_direction")) e.sun_direction = r_.direction(sky["sun_direction"], child(p, "sun_direction"));
      if (sky.contains("sun_radius_deg")) {
        e.sun_radius = glm::radians(r_.real(sky["sun_radius_deg"], child(p, "sun_radius_deg"), 0.0, 90.0));
      }
      if (sky.contains("sun_radiance")) e.sun_radiance = r_.colour(sky["sun_radiance"], child(p, "sun_radiance"), kMaxRadiance);
    } else {
      const std::string p = child(path, "map");
      const std::string file = r_.resolve(r_.string(v["map"], p));
      e.kind = scene::Environment::Kind::Map;
      e.map_path = file;
      EnvironmentMap map;
      try {
        map = read_environment_map(file, static_cast<float>(kMaxRadiance));
      } catch (const std::exception& ex) {
        r_.fail(p, ex.what());
      }
      e.map_width = map.width;
      e.map_height = map.height;
      e.map_rgb = std::move(map.rgb);
      if (map.negative_clamped > 0) {
        std::ostringstream s;
        s.precision(3);
        s << "environment map '" << file << "': " << map.negative_clamped << " negative pixel component"
          << (map.negative_clamped == 1 ? "" : "s") << " (lowest " << map.lowest << " at pixel (" << map.lowest_x << ", "
          << map.lowest_y << ")) clamped to 0";
        s_.notices.push_back(s.str());
      }
    }
  }

  void transform(const json& v, const std::string& path, scene::Node& node) {
    r_.object(v, path, {"translation", "rotation", "euler_deg", "scale"});
    if (v.contains("translation")) node.translation = r_.position(v["translation"], child(path, "translation"));
    if (v.contains("rotation") && v.contains("euler_deg")) r_.fail(path, "give \"rotation\" or \"euler_deg\", not both");
    if (v.contains("rotation")) {
      const std::string p = child(path, "rotation");
      const glm::vec4 q = r_.vec<4>(v["rotation"], p, -1e6, 1e6);
      const float len = glm::length(q);
      if (!(len > 1e-6f)) r_.fail(p, "expected a non-zero quaternion (x, y, z, w)", v["rotation"]);
      node.rotation = glm::quat(q.w / len, q.x / len, q.y / len, q.z / len);
    }
    if (v.contains("euler_deg")) {
      const glm::vec3 a = glm::radians(r_.vec<3>(v["euler_deg"], child(path, "euler_deg"), -360.0, 360.0));
      // Extrinsic X, then Y, then Z (docs/scene_format.md).
      node.rotation = glm::angleAxis(a.z, glm::vec3(0, 0, 1)) * glm::angleAxis(a.y, glm::vec3(0, 1, 0)) *
                      glm::angleAxis(a.x, glm::vec3(1, 0, 0));
    }
    if (v.contains("scale")) {
      const std::string p = child(path, "scale");
      const glm::vec3 s = r_.size<3>(v["scale"], p, -kMaxCoordinate, kMaxCoordinate, false);
      for (int k = 0; k < 3; ++k) {
        if (!(std::fabs(s[k]) >= 1e-6f)) r_.fail(v["scale"].is_array() ? child(p, std::size_t(k)) : p, "expected a non-zero scale", v["scale"].is_array() ? v["scale"][std::size_t(k)] : v["scale"]);
      }
      node.scale = s;
    }
  }

  void object(const json& v, const std::string& path) {
    r_.object(v, path, {"name", "mesh", "size", "radius", "segments", "transform", "material", "proxies"});
    Object obj;
    obj.name = v.contains("name") ? r_.string(v["name"], child(path, "name")) : "object" + std::to_string(objects_.size());
    for (const Object& o : objects_) {
      if (o.name == obj.name) r_.fail(child(path, "name"), "duplicate object name", json(obj.name));
    }
    if (!v.contains("mesh")) r_.fail(path, "missing key \"mesh\" (a glTF/GLB file or builtin:plane, builtin:sphere, builtin:box)");
    const std::string mesh_path = child(path, "mesh");
    const std::string& mesh = r_.string(v["mesh"], mesh_path);

    scene::Node node;
    node.name = obj.name;
    if (v.contains("transform")) transform(v["transform"], child(path, "transform"), node);
    s_.nodes.push_back(node);
    obj.node = int(s_.nodes.size()) - 1;

    const bool builtin = mesh.rfind("builtin:", 0) == 0;
    const std::string kind = builtin ? mesh.substr(8) : std::string();
    auto only_for = [&](const char* key, std::initializer_list<const char*> kinds) {
      if (!v.contains(key)) return;
      bool ok = false;
      std::string list;
      for (const char* k : kinds) {
        ok = ok || kind == k;
        list += (list.empty() ? "builtin:" : " or builtin:") + std::string(k);
      }
      if (!ok) r_.fail(child(path, key), "only meshes " + list + " take \"" + key + "\" (mesh is " + excerpt(mesh) + ")");
    };
    only_for("size", {"plane", "box"});
    only_for("radius", {"sphere"});
    only_for("segments", {"sphere", "plane", "box"});

    if (builtin) {
      scene::Mesh m;
      if (kind == "plane") {
        m = make_plane(v.contains("size") ? r_.size<2>(v["size"], child(path, "size"), 0.0, kMaxCoordinate, true) : glm::vec2(1.0f),
                       v.contains("segments") ? int(r_.integer(v["segments"], child(path, "segments"), 1, kMaxGridSegments)) : kPlaneSegments);
      } else if (kind == "sphere") {
        const float radius = v.contains("radius") ? r_.real(v["radius"], child(path, "radius"), 0.0, kMaxCoordinate, true) : 0.5f;
        const int segments = v.contains("segments") ? int(r_.integer(v["segments"], child(path, "segments"), 3, kMaxSegments)) : 32;
        m = make_sphere(radius, segments);
      } else if (kind == "box") {
        m = make_box(v.contains("size") ? r_.size<3>(v["size"], child(path, "size"), 0.0, kMaxCoordinate, true) : glm::vec3(1.0f),
                     v.contains("segments") ? int(r_.integer(v["segments"], child(path, "segments"), 1, kMaxGridSegments)) : kBoxSegments);
      } else {
        r_.fail(mesh_path, "expected a glTF/GLB path or builtin:plane, builtin:sphere, builtin:box", v["mesh"]);
      }
      scene::Material mat;
      mat.name = obj.name;
      s_.materials.push_back(mat);
      m.material = int(s_.materials.size()) - 1;
      obj.materials.push_back(m.material);
      s_.meshes.push_back(std::move(m));
      s_.nodes[std::size_t(obj.node)].mesh = int(s_.meshes.size()) - 1;
      obj.mesh_node = obj.node;
    } else {
      const std::size_t first_mesh = s_.meshes.size(), first_node = s_.nodes.size();
      GltfImport imp;
      try {
        imp = load_gltf(r_.resolve(mesh), s_);
      } catch (const std::exception& ex) {
        r_.fail(mesh_path, ex.what());
      }
      for (int root : imp.root_nodes) s_.nodes[std::size_t(root)].parent = obj.node;
      obj.first_file_node = int(first_node);
      obj.file_nodes = int(s_.nodes.size() - first_node);
      for (std::size_t n = first_node; n < s_.nodes.size(); ++n) {
        if (s_.nodes[n].mesh >= 0) {
          obj.mesh_node = int(n);
          break;
        }
      }
      std::set<int> mats;
      for (std::size_t m = first_mesh; m < s_.meshes.size(); ++m) mats.insert(s_.meshes[m].material);
      obj.materials.assign(mats.begin(), mats.end());
      if (obj.mesh_node < 0) r_.fail(mesh_path, "the file has no mesh in its scene", v["mesh"]);
    }

    if (v.contains("material")) {
      const std::string p = child(path, "material");
      const json& mv = v["material"];
      r_.object(mv, p, {"albedo", "phong_ns", "glossy"});
      for (int mi : obj.materials) {
        scene::Material& m = s_.materials[std::size_t(mi)];
        if (mv.contains("albedo")) m.albedo = r_.colour(mv["albedo"], child(p, "albedo"), 1.0);
        if (mv.contains("phong_ns")) m.phong_ns = r_.real(mv["phong_ns"], child(p, "phong_ns"), 0.0, 1e6);
        if (mv.contains("glossy")) m.glossy = r_.real(mv["glossy"], child(p, "glossy"), 0.0, 1.0);
      }
    }

    if (v.contains("proxies")) {
      const std::string p = child(path, "proxies");
      const json& pv = v["proxies"];
      scene::ProxySet ps;
      if (pv.is_string()) {
        try {
          ps = read_proxies_json(r_.resolve(r_.string(pv, p)));
        } catch (const std::exception& ex) {
          r_.fail(p, ex.what());
        }
      } else if (pv.is_object()) {
        r_.object(pv, p, {"fit", "seed", "iterations", "grid"});
        if (!pv.contains("fit")) r_.fail(p, "missing key \"fit\" (the number of spheres to fit)");
        PendingFit f;
        f.path = p;
        f.object = obj.name;
        f.spec.spheres = int(r_.integer(pv["fit"], child(p, "fit"), 1, kMaxFitSpheres));
        if (pv.contains("seed")) f.spec.seed = unsigned(r_.integer(pv["seed"], child(p, "seed"), 0, 0xffffffffll));
        if (pv.contains("iterations")) f.spec.iterations = int(r_.integer(pv["iterations"], child(p, "iterations"), 1, 100000));
        if (pv.contains("grid")) f.spec.grid = int(r_.integer(pv["grid"], child(p, "grid"), 1, 512));
        if (builtin) {
          f.nodes.push_back(obj.node);
        } else {
          for (int n = obj.first_file_node; n < obj.first_file_node + obj.file_nodes; ++n)
            if (s_.nodes[std::size_t(n)].mesh >= 0) f.nodes.push_back(n);
        }
        fits.push_back(std::move(f));
        objects_.push_back(std::move(obj));
        return;
      } else if (pv.is_array()) {
        r_.array(pv, p, 1, kMaxSpheres);
        for (std::size_t i = 0; i < pv.size(); ++i) ps.spheres.push_back(read_sphere(r_, pv[i], child(p, i), false));
        ps.albedo = s_.materials[std::size_t(obj.materials.front())].albedo;
      } else {
        r_.fail(p, "expected a proxy file name, an array of {\"center\", \"radius\"} or {\"fit\": N}", pv);
      }
      ps.name = obj.name;
      // A proxy file's node index is in io::load_gltf's numbering of the file loaded alone (see
      // gltf.hpp; what `softgi fit-proxies` records); it selects among the object's nodes when it
      // names a mesh node.
      const int file_node = ps.node;
      ps.node = obj.mesh_node;
      if (pv.is_string() && file_node >= 0 && file_node < obj.file_nodes &&
          s_.nodes[std::size_t(obj.first_file_node + file_node)].mesh >= 0) {
        ps.node = obj.first_file_node + file_node;
      }
      if (!ps.joints.empty() && s_.nodes[std::size_t(ps.node)].skin < 0) {
        r_.fail(p, "the spheres carry joints but the object's mesh node is not skinned");
      }
      s_.proxies.push_back(std::move(ps));
    }
    objects_.push_back(std::move(obj));
  }

  int object_node(const json& v, const std::string& path) const {
    if (v.is_string()) {
      for (const Object& o : objects_) {
        if (o.name == v.get_ref<const std::string&>()) return o.node;
      }
      std::string names;
      for (const Object& o : objects_) names += (names.empty() ? "" : ", ") + o.name;
      r_.fail(path, "expected the name of an object (" + (names.empty() ? std::string("there are none") : names) + ")", v);
    }
    if (objects_.empty()) r_.fail(path, "expected an object name or index, but there are no objects", v);
    return objects_[std::size_t(r_.integer(v, path, 0, std::int64_t(objects_.size()) - 1))].node;
  }

  void light(const json& v, const std::string& path) {
    r_.object(v, path, {"name", "position", "radius", "radiance", "object"});
    scene::SphericalLight l;
    l.name = v.contains("name") ? r_.string(v["name"], child(path, "name")) : "light" + std::to_string(s_.lights.size());
    if (!v.contains("position")) r_.fail(path, "missing key \"position\"");
    l.position = r_.position(v["position"], child(path, "position"));
    if (v.contains("radius")) l.radius = r_.real(v["radius"], child(path, "radius"), 0.0, kMaxCoordinate, true);
    if (v.contains("radiance")) l.radiance = r_.colour(v["radiance"], child(path, "radiance"), kMaxRadiance);
    if (v.contains("object")) l.node = object_node(v["object"], child(path, "object"));
    s_.lights.push_back(l);
  }

  void animation(const json& v, const std::string& path) {
    r_.object(v, path, {"clip", "name", "loop", "channels"});
    if (v.contains("clip") == v.contains("channels")) r_.fail(path, "expected exactly one of \"clip\" or \"channels\"");
    if (v.contains("clip")) {
      if (v.contains("name")) r_.fail(child(path, "name"), "\"name\" is for inline channels; a \"clip\" keeps its own name");
      const std::string p = child(path, "clip");
      const json& c = v["clip"];
      if (s_.clips.empty()) r_.fail(p, "no glTF file in the scene has animations", c);
      int index = -1;
      if (c.is_string()) {
        std::string names, matches;
        int count = 0;
        for (std::size_t i = 0; i < s_.clips.size(); ++i) {
          names += (names.empty() ? "" : ", ") + s_.clips[i].name;
          if (s_.clips[i].name == c.get_ref<const std::string&>()) {
            if (index < 0) index = int(i);
            matches += (count++ ? ", " : "") + std::to_string(i);
          }
        }
        if (index < 0) r_.fail(p, "expected the name of a clip (" + names + ")", c);
        // Two files (or one) may name clips alike: a name that picks one of several silently is an error.
        if (count > 1) r_.fail(p, "the name is ambiguous: clips " + matches + " are all called so; give the clip's index", c);
      } else {
        index = int(r_.integer(c, p, 0, std::int64_t(s_.clips.size()) - 1));
      }
      s_.active_clip = index;
      if (v.contains("loop")) s_.clips[std::size_t(index)].loop = r_.boolean(v["loop"], child(path, "loop"));
      return;
    }
    scene::AnimationClip clip;
    clip.name = v.contains("name") ? r_.string(v["name"], child(path, "name")) : "animation";
    if (v.contains("loop")) clip.loop = r_.boolean(v["loop"], child(path, "loop"));
    const std::string cp = child(path, "channels");
    const json& arr = r_.array(v["channels"], cp, 1, kMaxChannels);
    std::size_t total = 0;
    for (std::size_t i = 0; i < arr.size(); ++i) {
      const std::string p = child(cp, i);
      const json& ch = arr[i];
      r_.object(ch, p, {"object", "path", "interpolation", "times", "values"});
      for (const char* key : {"object", "path", "times", "values"}) {
        if (!ch.contains(key)) r_.fail(p, "missing key \"" + std::string(key) + "\"");
      }
      scene::AnimationChannel out;
      out.node = object_node(ch["object"], child(p, "object"));
      const std::string& what = r_.string(ch["path"], child(p, "path"));
      if (what == "translation") {
        out.path = scene::AnimationChannel::Path::Translation;
      } else if (what == "rotation") {
        out.path = scene::AnimationChannel::Path::Rotation;
      } else if (what == "scale") {
        out.path = scene::AnimationChannel::Path::Scale;
      } else {
        r_.fail(child(p, "path"), "expected \"translation\", \"rotation\" or \"scale\"", ch["path"]);
      }
      if (ch.contains("interpolation")) {
        const std::string& interp = r_.string(ch["interpolation"], child(p, "interpolation"));
        if (interp == "linear") {
          out.interp = scene::AnimationChannel::Interp::Linear;
        } else if (interp == "step") {
          out.interp = scene::AnimationChannel::Interp::Step;
        } else {
          r_.fail(child(p, "interpolation"), "expected \"linear\" or \"step\"", ch["interpolation"]);
        }
      }
      const json& times = r_.array(ch["times"], child(p, "times"), 1, kMaxKeys);
      const json& values = r_.array(ch["values"], child(p, "values"), times.size(), times.size());
      total += times.size();
      if (total > kMaxKeys) r_.fail(child(p, "times"), "more than " + std::to_string(kMaxKeys) + " keyframes in the animation");
      for (std::size_t k = 0; k < times.size(); ++k) {
        const std::string tp = child(child(p, "times"), k), vp = child(child(p, "values"), k);
        const float t = r_.real(times[k], tp, 0.0, 1e6);
        if (k > 0 && !(t > out.times.back())) r_.fail(tp, "expected a time greater than the previous key's " + number_text(out.times.back()), times[k]);
        out.times.push_back(t);
        if (out.path == scene::AnimationChannel::Path::Rotation) {
          glm::vec4 q = r_.vec<4>(values[k], vp, -1e6, 1e6);
          const float len = glm::length(q);
          if (!(len > 1e-6f)) r_.fail(vp, "expected a non-zero quaternion (x, y, z, w)", values[k]);
          out.values.push_back(q / len);
        } else if (out.path == scene::AnimationChannel::Path::Scale) {
          const glm::vec3 s = r_.vec<3>(values[k], vp, -kMaxCoordinate, kMaxCoordinate);
          if (!(std::fabs(s.x) >= 1e-6f && std::fabs(s.y) >= 1e-6f && std::fabs(s.z) >= 1e-6f)) {
            r_.fail(vp, "expected a non-zero scale", values[k]);
          }
          out.values.emplace_back(s, 0.0f);
        } else {
          out.values.emplace_back(r_.position(values[k], vp), 0.0f);
        }
      }
      clip.duration = std::max(clip.duration, out.times.back());
      clip.channels.push_back(std::move(out));
    }
    s_.clips.push_back(std::move(clip));
    s_.active_clip = int(s_.clips.size()) - 1;
  }
};

std::string stem_of(const std::string& name) {
  const std::string s = fs::path(name).stem().string();
  return s.empty() ? name : s;
}

}  // namespace

namespace {
// LoadOptions::fit_spheres: proxies for every closed mesh still without a set.
scene::Scene with_fits(scene::Scene s, const LoadOptions& opt) {
  if (opt.fit_spheres > 0) {
    ProxyFitSpec spec;
    spec.spheres = opt.fit_spheres;
    fit_missing_proxies(s, spec, opt.cache_dir);
  }
  return s;
}
}  // namespace

scene::Scene parse_scene_json(const std::string& text, const std::string& base_dir, const std::string& name_for_errors,
                              const LoadOptions& opt) {
  const Reader r(name_for_errors, base_dir);
  const json root = r.parse(text);
  scene::Scene s;
  s.name = stem_of(name_for_errors);
  s.source = name_for_errors;
  SceneParser parser(r, s);
  parser.run(root);
  try {
    scene::validate(s);
  } catch (const std::exception& e) {
    throw std::runtime_error(name_for_errors + ": " + e.what());
  }
  for (const PendingFit& f : parser.fits) {
    if (!opt.fit_proxies) {
      s.notices.push_back(name_for_errors + ": " + f.path + ": proxy fit of object '" + f.object + "' skipped (fitting is off)");
      continue;
    }
    int fitted = 0;
    std::string open;
    for (int node : f.nodes) {
      try {
        proxies::mesh_volume(proxies::trimesh_of(s.meshes[std::size_t(s.nodes[std::size_t(node)].mesh)]));
      } catch (const std::exception& e) {
        open += std::string(open.empty() ? "" : "; ") + "node '" + s.nodes[std::size_t(node)].name + "': " + e.what();
        continue;
      }
      ProxyFitOutcome o;
      try {
        o = fit_node_proxies(s, node, f.spec, opt.cache_dir);
      } catch (const std::exception& e) {
        r.fail(f.path, e.what());
      }
      std::ostringstream os;
      os.precision(3);
      os << name_for_errors << ": " << f.path << ": " << (o.from_cache ? "read " : "fitted ") << o.set.spheres.size()
         << " spheres to node '" << s.nodes[std::size_t(node)].name << "' (E = " << o.E << ")"
         << (o.from_cache ? " from the cache " + o.cache_file : "");
      if (!o.from_cache) os << " in " << o.seconds << " s" << (o.cache_file.empty() ? "" : ", cached as " + o.cache_file);
      s.notices.push_back(os.str());
      o.set.name = f.object;
      s.proxies.push_back(std::move(o.set));
      ++fitted;
    }
    if (!fitted) r.fail(f.path, "no mesh of object '" + f.object + "' is closed, so there is nothing to fit (" + open + ")");
  }
  return with_fits(std::move(s), opt);
}

scene::Scene load_scene_file(const std::string& path, const LoadOptions& opt) {
  const std::string text = read_text(path);
  const fs::path parent = fs::path(path).parent_path();
  return parse_scene_json(text, (parent.empty() ? fs::path(".") : parent).string(), path, opt);
}

scene::Scene load_scene(const std::string& spec, const LoadOptions& opt) {
  if (spec.empty()) throw std::runtime_error("empty scene name: expected a built-in scene or a scene file");
  if (spec.rfind("builtin:", 0) == 0) return with_fits(scene::make_builtin(spec.substr(8)), opt);
  std::string names;
  for (const scene::BuiltinInfo& b : scene::builtin_scenes()) {
    if (b.name == spec) return with_fits(scene::make_builtin(spec), opt);
    names += (names.empty() ? "" : ", ") + b.name;
  }
  std::error_code ec;
  if (!fs::exists(spec, ec)) {
    throw std::runtime_error("unknown scene '" + spec + "': not a built-in scene (" + names + ") and no such file");
  }
  std::string ext = fs::path(spec).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  if (ext != ".gltf" && ext != ".glb") return load_scene_file(spec, opt);

  // A bare glTF/GLB: its nodes under the default sky, its first animation playing, and a camera
  // framing the rest pose.
  scene::Scene s;
  s.name = stem_of(spec);
  s.source = spec;
  const GltfImport imp = load_gltf(spec, s);
  if (!imp.clips.empty()) s.active_clip = imp.clips.front();
  const scene::Bounds b = scene::bounds(scene::evaluate(s, 0.0));
  if (b.lo.x <= b.hi.x) {
    const glm::vec3 centre = 0.5f * (b.lo + b.hi);
    const float radius = std::max(0.5f * glm::length(b.hi - b.lo), 1e-3f);
    const float dist = radius / std::sin(glm::radians(0.5f * s.camera.fov_y_deg));
    s.camera.target = centre;
    s.camera.position = centre + dist * glm::normalize(glm::vec3(0.0f, 0.35f, 1.0f));
  }
  try {
    scene::validate(s);
  } catch (const std::exception& e) {
    throw std::runtime_error(spec + ": " + e.what());
  }
  return with_fits(std::move(s), opt);
}

void write_proxies_json(const std::string& path, const scene::ProxySet& proxies) {
  json root;
  root["format"] = kProxyFormat;
  root["version"] = kProxyVersion;
  root["name"] = proxies.name;
  root["node"] = proxies.node;
  root["albedo"] = vec_json(&proxies.albedo.x, 3);
  if (proxies.outside_volume_ratio >= 0.0) root["outside_volume_ratio"] = proxies.outside_volume_ratio;
  const bool skinned = !proxies.joints.empty();
  if (skinned && (proxies.joints.size() != proxies.spheres.size() || proxies.weights.size() != proxies.spheres.size())) {
    throw std::runtime_error(path + ": proxy set has " + std::to_string(proxies.joints.size()) + " joints and " +
                             std::to_string(proxies.weights.size()) + " weights for " +
                             std::to_string(proxies.spheres.size()) + " spheres");
  }
  json spheres = json::array();
  for (std::size_t i = 0; i < proxies.spheres.size(); ++i) {
    const scene::Sphere& s = proxies.spheres[i];
    if (!std::isfinite(s.center.x) || !std::isfinite(s.center.y) || !std::isfinite(s.center.z) || !std::isfinite(s.radius)) {
      throw std::runtime_error(path + ": sphere " + std::to_string(i) + " is not finite; refusing to write it");
    }
    json js;
    js["center"] = vec_json(&s.center.x, 3);
    js["radius"] = float_json(s.radius);
    if (skinned) {
      js["joints"] = {proxies.joints[i].x, proxies.joints[i].y, proxies.joints[i].z, proxies.joints[i].w};
      js["weights"] = vec_json(&proxies.weights[i].x, 4);
    }
    if (!proxies.sphere_albedo.empty()) {
      if (proxies.sphere_albedo.size() != proxies.spheres.size())
        throw std::runtime_error(path + ": proxy set has " + std::to_string(proxies.sphere_albedo.size()) + " sphere albedos for " +
                                 std::to_string(proxies.spheres.size()) + " spheres");
      js["albedo"] = vec_json(&proxies.sphere_albedo[i].x, 3);
    }
    spheres.push_back(std::move(js));
  }
  root["spheres"] = std::move(spheres);
  write_text_atomic(path, root.dump(1, ' ', false, json::error_handler_t::replace) + "\n");
}

scene::ProxySet read_proxies_json(const std::string& path) {
  const std::string text = read_text(path);
  const Reader r(path, fs::path(path).parent_path().string());
  return parse_proxies(r, r.parse(text));
}

}  // namespace softgi::io
