#include "session.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <iostream>
#include <stdexcept>

#include <glm/glm.hpp>

#include "frame_output.hpp"
#include "output_dir.hpp"
#include "softgi/render/camera.hpp"

namespace softgi::viewer {

const char* to_string(View v) {
  switch (v) {
    case View::Final: return "final";
    case View::Direct: return "direct";
    case View::Indirect: return "indirect";
    case View::Error: return "error";
  }
  return "final";
}

View parse_view(const std::string& s) {
  for (View v : {View::Final, View::Direct, View::Indirect, View::Error})
    if (s == to_string(v)) return v;
  throw std::invalid_argument("view '" + s + "': expected final, direct, indirect or error");
}

namespace {
bool finite3(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

glm::vec3 vec3_of(const Json& j, const std::string& what) {
  if (!j.is_array() || j.size() != 3 || !j[0].is_number() || !j[1].is_number() || !j[2].is_number())
    throw std::invalid_argument(what + ": expected [x, y, z], got " + j.dump());
  return {j[0].get<float>(), j[1].get<float>(), j[2].get<float>()};
}
}  // namespace

Session::Session(const SessionOptions& o) {
  app::register_builtin();
  backend_name_ = o.backend.empty() ? render::reference_backend_name() : app::check_backend(o.backend);
  device_ = o.device;
  if (!device_.empty() && !render::backend_info(backend_name_).selects_device)
    throw std::invalid_argument("--device '" + device_ + "': the " + backend_name_ + " backend selects no device");
  app::check_distinct_params(o.params);
  make_pane(0, o.technique, o.params);
  set_size(o.width, o.height);
  set_time(o.time);
  set_speed(o.speed);
  set_fixed_dt(o.fixed_dt);
  playing_ = o.play;
  backend();  // device errors before the scene is loaded
  load_scene(o.scene, o.fit_proxies);
}

Session::~Session() = default;

void Session::make_pane(int i, const std::string& technique, const std::vector<std::string>& assignments) {
  Pane p;
  p.technique = render::create_technique(technique);
  p.params = app::technique_params(*p.technique, assignments);
  panes_[i] = std::move(p);
  dirty_ = true;
}

// --- Scene and camera ---------------------------------------------------------------------------

void Session::load_scene(const std::string& spec, int fit_proxies) {
  scene::Scene sc = app::load_cli_scene("softgi-viewer", spec, fit_proxies);
  render::make_pinhole_camera(sc, width_, height_, "scene '" + spec + "'");  // its camera is usable
  scene_ = std::move(sc);
  scene_camera_ = scene_.camera;
  spec_ = spec;
  fit_proxies_ = fit_proxies;
  if (duration() > 0.0 && time_ > duration() && !scene_.clips.empty() && scene_.clips[0].loop) time_ = std::fmod(time_, duration());
  ++camera_version_;
  dirty_ = true;
}

void Session::set_camera(const scene::Camera& c) {
  scene::Scene probe;
  probe.camera = c;
  if (!finite3(c.position) || !finite3(c.target) || !finite3(c.up)) throw std::invalid_argument("camera: position, target and up must be finite");
  render::make_pinhole_camera(probe, width_, height_, "camera");  // position != target, up, fov
  scene_.camera.position = c.position;
  scene_.camera.target = c.target;
  scene_.camera.up = c.up;
  scene_.camera.fov_y_deg = c.fov_y_deg;
  ++camera_version_;
  dirty_ = true;
}

void Session::reset_camera() { set_camera(scene_camera_); }

void Session::orbit(float yaw_deg, float pitch_deg) {
  scene::Camera c = scene_.camera;
  const glm::vec3 up = glm::normalize(c.up);
  glm::vec3 off = c.position - c.target;
  const float r = glm::length(off);
  // Yaw: rotate about the up hint.
  const float yaw = glm::radians(yaw_deg);
  off = off * std::cos(yaw) + glm::cross(up, off) * std::sin(yaw) + up * glm::dot(up, off) * (1.0f - std::cos(yaw));
  // Pitch: change the elevation above the plane normal to `up`, 1 degree short of either pole.
  const float elev = std::asin(std::clamp(glm::dot(off, up) / r, -1.0f, 1.0f));
  const float limit = glm::radians(89.0f);
  const float new_elev = std::clamp(elev + glm::radians(pitch_deg), -limit, limit);
  glm::vec3 flat = off - up * glm::dot(off, up);
  if (glm::length(flat) < 1e-6f * r) flat = glm::cross(up, glm::vec3(1, 0, 0));
  flat = glm::normalize(flat);
  off = (flat * std::cos(new_elev) + up * std::sin(new_elev)) * r;
  c.position = c.target + off;
  set_camera(c);
}

void Session::pan(float dx, float dy) {
  scene::Camera c = scene_.camera;
  const glm::vec3 fwd = glm::normalize(c.target - c.position);
  const glm::vec3 right = glm::normalize(glm::cross(fwd, c.up));
  const glm::vec3 up = glm::cross(right, fwd);
  const float view_h = 2.0f * glm::length(c.target - c.position) * std::tan(glm::radians(c.fov_y_deg) * 0.5f);
  const glm::vec3 d = (right * dx + up * dy) * view_h;
  c.position += d;
  c.target += d;
  set_camera(c);
}

void Session::zoom(float factor) {
  if (!(factor > 0.0f) || !std::isfinite(factor)) throw std::invalid_argument("zoom: factor must be finite and > 0");
  scene::Camera c = scene_.camera;
  c.position = c.target + (c.position - c.target) * factor;
  set_camera(c);
}

void Session::fly(float right_amount, float up_amount, float forward_amount) {
  scene::Camera c = scene_.camera;
  const glm::vec3 fwd = glm::normalize(c.target - c.position);
  const glm::vec3 right = glm::normalize(glm::cross(fwd, c.up));
  const glm::vec3 up = glm::cross(right, fwd);
  const float dist = glm::length(c.target - c.position);
  const glm::vec3 d = (right * right_amount + up * up_amount + fwd * forward_amount) * dist;
  c.position += d;
  c.target += d;
  set_camera(c);
}

// --- Animation ----------------------------------------------------------------------------------

void Session::set_time(double t) {
  if (!std::isfinite(t)) throw std::invalid_argument("time: must be finite");
  time_ = t;
  dirty_ = true;
}

void Session::set_speed(double s) {
  if (!std::isfinite(s)) throw std::invalid_argument("speed: must be finite");
  speed_ = s;
}

void Session::set_fixed_dt(double dt) {
  if (!std::isfinite(dt) || dt < 0.0) throw std::invalid_argument("fixed time step: must be finite and >= 0");
  fixed_dt_ = dt;
}

double Session::duration() const {
  if (scene_.active_clip < 0 || scene_.active_clip >= static_cast<int>(scene_.clips.size())) return 0.0;
  return scene_.clips[static_cast<std::size_t>(scene_.active_clip)].duration;
}

void Session::advance(double wall_seconds) {
  if (!playing_) return;
  double t = time_ + (fixed_dt_ > 0.0 ? fixed_dt_ : wall_seconds * speed_);
  const double d = duration();
  if (d > 0.0) {
    t = std::fmod(t, d);
    if (t < 0.0) t += d;
  }
  time_ = t;
  dirty_ = true;
}

// --- Techniques, parameters, backend ------------------------------------------------------------

void Session::set_technique(const std::string& name, int pane) { make_pane(pane, name, {}); }

void Session::set_param(const std::string& name, const std::string& value, int pane) {
  Pane& p = panes_[pane];
  try {
    p.params.set(name, value);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument("parameter of technique '" + p.technique->name() + "': " + e.what());
  }
  dirty_ = true;
}

void Session::reset_params(int pane) {
  panes_[pane].params = render::default_params(*panes_[pane].technique);
  dirty_ = true;
}

render::Backend& Session::backend() {
  auto it = backends_.find(backend_name_);
  if (it == backends_.end()) {
    const bool selects = render::backend_info(backend_name_).selects_device;
    it = backends_.emplace(backend_name_, app::make_backend(backend_name_, selects ? device_ : "", "softgi-viewer")).first;
  }
  return *it->second;
}

void Session::set_backend(const std::string& name) {
  const std::string previous = backend_name_;
  backend_name_ = app::check_backend(name);
  try {
    backend();
  } catch (...) {
    backend_name_ = previous;  // a backend that cannot start leaves the session on the one it had
    throw;
  }
  dirty_ = true;
}

void Session::set_split(const std::string& technique) {
  if (technique.empty()) {
    split_ = false;
    panes_[1] = Pane{};
  } else {
    make_pane(1, technique, {});
    split_ = true;
  }
  dirty_ = true;
}

void Session::set_exposure(float e) {
  if (!(e > 0.0f) || !std::isfinite(e)) throw std::invalid_argument("exposure: must be finite and > 0");
  exposure_ = e;
}

void Session::set_size(int width, int height) {
  if (width < 1 || height < 1 || width > 16384 || height > 16384)
    throw std::invalid_argument("size " + std::to_string(width) + "x" + std::to_string(height) + ": each side must be 1..16384");
  width_ = width;
  height_ = height;
  dirty_ = true;
}

// --- Frames -------------------------------------------------------------------------------------

void Session::render() {
  render::RenderRequest req;
  req.time = time_;
  req.width = width_;
  req.height = height_;
  for (int i = 0; i < (split_ ? 2 : 1); ++i) {
    Pane& p = panes_[i];
    const std::string before = p.error;
    req.outputs = {"final"};
    if (overlay_)
      for (const auto& o : p.technique->overlay_outputs()) req.outputs.push_back(o);
    try {
      // The shown frame's buffers go to the backend's pool for this one (a failed render shows no
      // image anyway).
      backend().recycle(std::move(p.result));
      p.result = backend().render(*p.technique, scene_, p.params, req);
      if (p.result.final_image.empty()) throw std::runtime_error("the technique produced no final image");
      p.overlay = overlay_ ? p.technique->overlay(p.result) : render::OverlayGeometry{};
      p.error.clear();
      p.rendered_time = time_;
    } catch (const std::exception& e) {
      p.result = render::FrameResult{};
      p.overlay = {};
      p.error = p.technique->name() + " on " + backend_name_ + ": " + e.what();
      if (p.error != before) std::cerr << "softgi-viewer: error: " << p.error << "\n";
    }
  }
  dirty_ = false;
}

std::uint64_t Session::view_key() const {
  // Mixes the camera's version, the clock and the size; the scene's identity is its spec.
  std::uint64_t h = std::hash<std::string>{}(spec_);
  auto mix = [&h](std::uint64_t v) { h ^= v + 0x9e3779b97f4a7c15ull + (h << 6) + (h >> 2); };
  mix(camera_version_);
  mix(std::hash<double>{}(time_));
  mix(static_cast<std::uint64_t>(width_) << 32 | static_cast<std::uint64_t>(height_));
  return h;
}

void Session::capture(const std::string& dir) const {
  const Pane& p = panes_[0];
  if (p.result.final_image.empty())
    throw std::runtime_error("screenshot: no frame to write" + (p.error.empty() ? std::string() : " (the last one failed: " + p.error + ")"));
  app::OutputDir out(dir, "--screenshot", "record.json");
  const app::Json images = app::write_frame_images(out, p.result);
  auto& self = const_cast<Session&>(*this);  // backend() creates lazily; it exists after a frame
  out.finish(app::render_record("viewer", spec_, fit_proxies_, scene_, *p.technique, self.backend(), p.params, p.rendered_time,
                                p.result.final_image.width, p.result.final_image.height, images, p.result, dir));
}

// --- Settings -----------------------------------------------------------------------------------

Json Session::settings() const {
  auto params_of = [](const Pane& p) {
    Json j = Json::object();
    for (const auto& [n, v] : p.params.values()) j[n] = v;
    return j;
  };
  Json j = {{"scene", spec_},
            {"fit_proxies", fit_proxies_},
            {"camera", app::camera_json(scene_.camera)},
            {"time", time_},
            {"playing", playing_},
            {"speed", speed_},
            {"fixed_dt", fixed_dt_},
            {"size", {width_, height_}},
            {"backend", backend_name_},
            {"technique", panes_[0].technique->name()},
            {"params", params_of(panes_[0])},
            {"view", to_string(view_)},
            {"overlay", overlay_},
            {"exposure", exposure_}};
  if (split_) j["split"] = {{"technique", panes_[1].technique->name()}, {"params", params_of(panes_[1])}};
  return j;
}

void Session::load_settings(const Json& j) {
  if (!j.is_object()) throw std::invalid_argument("settings: expected a JSON object");
  static const std::vector<std::string> known = {"scene", "fit_proxies", "camera", "time", "playing", "speed", "fixed_dt", "size",
                                                 "backend", "technique", "params", "view", "overlay", "exposure", "split"};
  for (const auto& [k, v] : j.items())
    if (std::find(known.begin(), known.end(), k) == known.end()) throw std::invalid_argument("settings: unknown key '" + k + "'");
  auto apply_params = [this](const Json& params, int pane) {
    if (!params.is_object()) throw std::invalid_argument("settings: 'params' must be an object");
    for (const auto& [n, v] : params.items()) set_param(n, v.is_string() ? v.get<std::string>() : v.dump(), pane);
  };
  if (j.contains("size")) set_size(j["size"].at(0).get<int>(), j["size"].at(1).get<int>());
  if (j.contains("scene")) load_scene(j["scene"].get<std::string>(), j.value("fit_proxies", 0));
  if (j.contains("camera")) {
    const Json& cj = j["camera"];
    scene::Camera c = scene_.camera;
    if (cj.contains("position")) c.position = vec3_of(cj["position"], "settings: camera.position");
    if (cj.contains("target")) c.target = vec3_of(cj["target"], "settings: camera.target");
    if (cj.contains("up")) c.up = vec3_of(cj["up"], "settings: camera.up");
    if (cj.contains("fov_y_deg")) c.fov_y_deg = cj["fov_y_deg"].get<float>();
    set_camera(c);
  }
  if (j.contains("time")) set_time(j["time"].get<double>());
  if (j.contains("playing")) set_playing(j["playing"].get<bool>());
  if (j.contains("speed")) set_speed(j["speed"].get<double>());
  if (j.contains("fixed_dt")) set_fixed_dt(j["fixed_dt"].get<double>());
  if (j.contains("backend")) set_backend(j["backend"].get<std::string>());
  if (j.contains("technique")) set_technique(j["technique"].get<std::string>());
  if (j.contains("params")) apply_params(j["params"], 0);
  if (j.contains("view")) set_view(parse_view(j["view"].get<std::string>()));
  if (j.contains("overlay")) set_overlay(j["overlay"].get<bool>());
  if (j.contains("exposure")) set_exposure(j["exposure"].get<float>());
  if (j.contains("split")) {
    const Json& s = j["split"];
    if (s.is_null()) {
      set_split("");
    } else {
      set_split(s.at("technique").get<std::string>());
      if (s.contains("params")) apply_params(s["params"], 1);
    }
  }
  dirty_ = true;
}

}  // namespace softgi::viewer
