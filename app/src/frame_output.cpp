#include "frame_output.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <ctime>
#include <iostream>
#include <map>
#include <mutex>
#include <sstream>
#include <stdexcept>

#include "softgi/backends/cpu_backend.hpp"
#include "softgi/backends/vulkan/backend.hpp"
#include "softgi/io/scene_file.hpp"
#include "commands.hpp"
#include "softgi/render/common_passes.hpp"
#include "softgi/techniques/registry.hpp"

#ifndef SOFTGI_VERSION
#define SOFTGI_VERSION "unknown"
#endif

namespace softgi::app {

void register_builtin() {
  static std::once_flag once;
  std::call_once(once, [] {
    backends::register_cpu_backend();
    backends::register_vulkan_backend();
    techniques::register_vulkan_kernels();  // and every technique
  });
}

namespace {
std::string backend_list() {
  std::string known;
  for (const auto& n : render::backend_names()) known += (known.empty() ? "" : ", ") + n;
  return known;
}
}  // namespace

std::string check_backend(const std::string& name) {
  register_builtin();
  try {
    render::backend_info(name);
  } catch (const std::invalid_argument&) {
    throw std::invalid_argument("--backend: unknown backend '" + name + "' (available: " + backend_list() + ")");
  }
  return name;
}

std::vector<std::string> split_list(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  for (std::string item; std::getline(ss, item, ',');) {
    item.erase(0, item.find_first_not_of(" \t"));
    item.erase(item.find_last_not_of(" \t") + 1);
    if (!item.empty()) out.push_back(item);
  }
  return out;
}

std::vector<std::string> parse_backends(const std::string& list) {
  std::vector<std::string> out;
  for (const std::string& item : split_list(list)) {
    check_backend(item);
    if (std::find(out.begin(), out.end(), item) != out.end()) throw std::invalid_argument("--backend: '" + item + "' listed twice");
    out.push_back(item);
  }
  if (out.empty()) throw std::invalid_argument("--backend: no backend given (available: " + backend_list() + ")");
  return out;
}

std::unique_ptr<render::Backend> make_backend(const std::string& name, const std::string& device, const std::string& command) {
  check_backend(name);
  render::BackendOptions o;
  o.device = device;
  if (!device.empty() && !render::backend_info(name).selects_device)
    throw std::invalid_argument("--device '" + device + "': the " + name + " backend selects no device");
  std::unique_ptr<render::Backend> b = render::backend_info(name).create(o);
  const auto d = b->device_record();
  if (!d.empty())
    std::cerr << command << ": " << name << " device " << d.at("index") << ": " << d.at("name") << " [" << d.at("type") << "; "
              << d.at("driver") << " " << d.at("driver_info") << "; Vulkan " << d.at("api_version") << "; validation "
              << d.at("validation") << "]\n";
  return b;
}

std::string backends_help() {
  register_builtin();
  std::string out;
  for (const auto& n : render::backend_names()) out += (out.empty() ? "" : ", ") + n + " (" + render::backend_info(n).description + ")";
  return out + "; default: " + render::reference_backend_name();
}

Json device_json(const render::Backend& backend) {
  Json j = Json::object();
  for (const auto& [k, v] : backend.device_record()) j[k] = v;
  return j;
}

void check_distinct_params(const std::vector<std::string>& assignments) {
  std::map<std::string, std::string> seen;
  for (const auto& a : assignments) {
    const std::string name = a.substr(0, a.find('='));
    auto [it, fresh] = seen.emplace(name, a);
    if (!fresh)
      throw std::invalid_argument("--param '" + name + "' given twice ('" + it->second + "' and '" + a + "'): say which value you mean");
  }
}

render::ParamSet technique_params(const render::Technique& t, const std::vector<std::string>& assignments) {
  render::ParamSet p = render::default_params(t);
  for (const auto& a : assignments) {
    try {
      p.set_assignment(a);
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument("--param for technique '" + t.name() + "': " + e.what());
    }
  }
  return p;
}

int sh_order_of(const render::ParamSet& p) {
  if (p.has("order") && p.desc("order").type == render::ParamType::Int) return p.get_int("order");
  return kDefaultShOrder;
}

Json params_json(const render::ParamSet& params) {
  Json j = Json::object();
  for (const auto& [name, text] : params.values()) {
    switch (params.desc(name).type) {
      case render::ParamType::Int: j[name] = params.get_int(name); break;
      case render::ParamType::Float: j[name] = params.get_float(name); break;
      case render::ParamType::Bool: j[name] = params.get_bool(name); break;
      case render::ParamType::Enum: j[name] = text; break;
    }
  }
  return j;
}

Json frame_json(const render::FrameResult& r) {
  Json passes = Json::array();
  for (const auto& p : r.passes) {
    Json jp = {{"name", p.name},
               {"wall_seconds", p.wall_seconds},
               {"bytes", p.bytes},
               {"transfer_bytes", {{"upload", p.transfer.upload}, {"download", p.transfer.download}}}};
    if (p.gpu_seconds >= 0.0) jp["gpu_seconds"] = p.gpu_seconds;
    if (p.page_faults >= 0) jp["page_faults"] = p.page_faults;
    Json c = Json::object();
    for (const auto& [k, v] : p.counters) c[k] = std::isfinite(v) ? Json(v) : Json(nullptr);
    jp["counters"] = c;
    passes.push_back(jp);
  }
  Json pruned = Json::array();
  for (const auto& p : r.pruned) pruned.push_back({{"name", p.name}, {"reason", p.reason}});
  return {{"passes", passes},
          {"pruned", pruned},
          {"total_seconds", r.total_seconds},
          {"bytes", r.bytes()},
          {"transfer_bytes", {{"upload", r.transfer.upload}, {"download", r.transfer.download}}},
          {"peak_rss_bytes", r.peak_rss_bytes},
          {"warnings", r.warnings}};
}

void add_scene_options(CLI::App& sub, SceneArgs& args) {
  sub.add_option("--scene", args.spec, "built-in scene name, scene file or glTF/GLB file")->required();
  sub.add_option("--fit-proxies", args.fit_proxies,
                 "fit N proxy spheres to every closed mesh without proxies (cached in $SOFTGI_CACHE_DIR, else "
                 "$XDG_CACHE_HOME/softgi or ~/.cache/softgi; SOFTGI_CACHE_DIR=off caches nothing)")
      ->check(CLI::Range(1, 4096));
}

scene::Scene load_cli_scene(const std::string& command, const std::string& spec, int fit_proxies) {
  io::LoadOptions opt;
  opt.fit_spheres = fit_proxies;
  scene::Scene sc = io::load_scene(spec, opt);
  print_scene_notices(command, sc);
  return sc;
}

void print_scene_notices(const std::string& command, const scene::Scene& sc) {
  for (const auto& n : sc.notices) std::cerr << command << ": note: " << n << "\n";
}

void print_frame_warnings(const std::string& command, const render::FrameResult& r) {
  for (const auto& w : r.warnings) std::cerr << command << ": warning: " << r.technique << ": " << w << "\n";
}

Json scene_json(const scene::Scene& sc, const std::string& spec) {
  return {{"name", sc.name}, {"source", sc.source}, {"spec", spec}, {"notices", sc.notices}};
}

void add_camera_options(CLI::App& sub, CameraArgs& args) {
  sub.add_option("--camera-position", args.position, "camera position x,y,z (default: the scene camera's)");
  sub.add_option("--camera-target", args.target, "point the camera looks at, x,y,z (default: the scene camera's)");
  sub.add_option("--camera-up", args.up, "camera up hint x,y,z (default: the scene camera's)");
  sub.add_option("--fov", args.fov_y_deg, "vertical field of view in degrees (default: the scene camera's)");
}

namespace {
glm::vec3 parse_vec3(const std::string& text, const std::string& option) {
  const std::vector<std::string> items = split_list(text);
  glm::vec3 v{0.0f};
  std::size_t used = 0;
  bool ok = items.size() == 3;
  for (int k = 0; ok && k < 3; ++k) {
    try {
      v[k] = std::stof(items[k], &used);
      ok = used == items[k].size() && std::isfinite(v[k]);
    } catch (const std::exception&) {
      ok = false;
    }
  }
  if (!ok) throw std::invalid_argument(option + " '" + text + "': expected three finite numbers x,y,z");
  return v;
}
}  // namespace

void apply_camera_args(const CameraArgs& args, scene::Camera& camera) {
  if (!args.position.empty()) camera.position = parse_vec3(args.position, "--camera-position");
  if (!args.target.empty()) camera.target = parse_vec3(args.target, "--camera-target");
  if (!args.up.empty()) camera.up = parse_vec3(args.up, "--camera-up");
  if (args.fov_y_deg != 0.0) {
    if (!(args.fov_y_deg > 0.0 && args.fov_y_deg < 179.0))
      throw std::invalid_argument("--fov " + std::to_string(args.fov_y_deg) + ": expected degrees inside (0, 179)");
    camera.fov_y_deg = static_cast<float>(args.fov_y_deg);
  }
}

std::string format_vec3(const glm::vec3& v) {
  std::ostringstream os;
  os.precision(9);  // a float's round trip
  os << v.x << "," << v.y << "," << v.z;
  return os.str();
}

Json camera_json(const scene::Camera& c) {
  return {{"position", {c.position.x, c.position.y, c.position.z}},
          {"target", {c.target.x, c.target.y, c.target.z}},
          {"up", {c.up.x, c.up.y, c.up.z}},
          {"fov_y_deg", c.fov_y_deg}};
}

std::string shell_quote(const std::string& s) {
  if (!s.empty() && s.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-./,=:") == std::string::npos)
    return s;
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

std::string render_command_line(const std::string& spec, int fit_proxies, const scene::Scene& sc, const std::string& technique,
                                const render::ParamSet& params, const std::string& backend, double time, int width, int height,
                                const std::string& out) {
  std::ostringstream os;
  os.precision(17);
  os << "softgi render --scene " << shell_quote(spec);
  if (fit_proxies) os << " --fit-proxies " << fit_proxies;
  os << " --technique " << shell_quote(technique) << " --backend " << shell_quote(backend);
  std::ostringstream fov;
  fov.precision(9);
  fov << sc.camera.fov_y_deg;
  os << " --camera-position " << format_vec3(sc.camera.position) << " --camera-target " << format_vec3(sc.camera.target)
     << " --camera-up " << format_vec3(sc.camera.up) << " --fov " << fov.str();
  const render::ParamSet defaults(params.descs());
  for (const auto& d : params.descs())
    if (params.get_text(d.name) != defaults.get_text(d.name)) os << " --param " << shell_quote(d.name + "=" + params.get_text(d.name));
  os << " --frame " << time << " --width " << width << " --height " << height << " --out " << shell_quote(out);
  return os.str();
}

Json write_frame_images(OutputDir& out, const render::FrameResult& r) {
  Json images = Json::object();
  auto save = [&](const std::string& name, const Image& img) {
    if (img.empty()) return;
    Json files = Json::object();
    if (out.write_exr(name + ".exr", img)) files["exr"] = name + ".exr";
    if (out.write_png(name + ".png", img)) files["png"] = name + ".png";
    if (!files.empty()) images[name] = files;
  };
  save("final", r.final_image);
  save("direct", r.direct);
  save("indirect", r.indirect);
  return images;
}

Json render_record(const std::string& command, const std::string& spec, int fit_proxies, const scene::Scene& sc,
                   const render::Technique& technique, const render::Backend& backend, const render::ParamSet& params,
                   double time, int width, int height, const Json& images, const render::FrameResult& r, const std::string& out) {
  Json rec = {{"softgi_version", softgi_version()},
              {"date", utc_now()},
              {"command", command},
              {"command_line", render_command_line(spec, fit_proxies, sc, technique.name(), params, backend.name(), time, width, height, out)},
              {"scene", scene_json(sc, spec)},
              {"camera", camera_json(sc.camera)},
              {"technique", technique.name()},
              {"backend", backend.name()},
              {"device", device_json(backend)},
              {"params", params_json(params)},
              {"frame_time", time},
              {"resolution", {width, height}},
              {"images", images}};
  rec.update(frame_json(r));
  std::size_t vertices = 0;
  for (const auto& v : r.vertex_radiance) vertices += v.size();
  if (vertices) rec["vertex_results"] = {{"objects", r.vertex_radiance.size()}, {"vertices", vertices}};
  return rec;
}

std::string softgi_version() { return SOFTGI_VERSION; }

std::string utc_now() {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

std::string techniques_help() {
  register_builtin();
  std::ostringstream os;
  os << "Techniques and their parameters (--param name=value):\n";
  for (const auto& name : render::technique_names()) {
    auto t = render::create_technique(name);
    os << "  " << name << ": " << t->description() << "\n";
    std::istringstream lines(render::default_params(*t).describe());
    for (std::string line; std::getline(lines, line);) os << "  " << line << "\n";
  }
  return os.str();
}

}  // namespace softgi::app
