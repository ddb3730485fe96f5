#include "viewer.hpp"

#include <GLFW/glfw3.h>
#include <imgui.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>
#include <fstream>
#include <iostream>
#include <sstream>
#include <stdexcept>

#include "ground_truth.hpp"
#include "softgi/io/image_io.hpp"
#include "softgi/metrics/image_metrics.hpp"
#include "softgi/render/camera.hpp"
#include "softgi/scene/builtin.hpp"

namespace softgi::viewer {

namespace {

using clock_type = std::chrono::steady_clock;

// The image a view shows; empty when the technique does not produce that component (the pane is
// then drawn black and labelled, never silently replaced by another component).
const Image& view_image(const render::FrameResult& r, View v) {
  switch (v) {
    case View::Direct: return r.direct;
    case View::Indirect: return r.indirect;
    default: return r.final_image;
  }
}

Json read_json_file(const std::string& path, const std::string& what) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(what + " '" + path + "': cannot open");
  try {
    return Json::parse(in);
  } catch (const Json::parse_error& e) {
    throw std::runtime_error(what + " '" + path + "': not valid JSON: " + e.what());
  }
}

// The keys a script action may have; each action is one object with one of them (plus its value).
const std::vector<std::string>& action_keys() {
  static const std::vector<std::string> keys = {"scene",  "technique", "backend",  "param",   "reset_params", "camera",
                                                "time",   "play",      "speed",    "fixed_dt", "frames",      "view",
                                                "split",  "overlay",   "exposure", "size",    "resize",       "minimise",
                                                "capture", "window_shot", "save_settings", "load_settings"};
  return keys;
}

}  // namespace

void check_script(const Json& script) {
  const Json& actions = script.is_object() && script.contains("actions") ? script["actions"] : script;
  if (!actions.is_array()) throw std::invalid_argument("script: expected {\"actions\": [...]} or an array of actions");
  for (std::size_t i = 0; i < actions.size(); ++i) {
    const Json& a = actions[i];
    if (!a.is_object() || a.size() != 1)
      throw std::invalid_argument("script: action " + std::to_string(i) + " must be an object with one key, got " + a.dump());
    const std::string key = a.begin().key();
    if (std::find(action_keys().begin(), action_keys().end(), key) == action_keys().end()) {
      std::string known;
      for (const auto& k : action_keys()) known += (known.empty() ? "" : ", ") + k;
      throw std::invalid_argument("script: action " + std::to_string(i) + ": unknown action '" + key + "' (known: " + known + ")");
    }
  }
}

namespace {

class Viewer {
 public:
  explicit Viewer(const ViewerOptions& o) : opt_(o), session_(o.session), display_(o.display) {
    if (!o.settings.empty()) session_.load_settings(read_json_file(o.settings, "--settings"));
    if (o.ground_truth) gt_ = std::make_unique<GroundTruth>(o.ground_truth_spp);
    std::snprintf(settings_path_, sizeof settings_path_, "%s", "viewer-settings.json");
    std::snprintf(scene_path_, sizeof scene_path_, "%s", session_.scene_spec().c_str());
  }

  // One frame: input, clock, render when something changed, interface, present.
  void step(bool input) {
    const auto now = clock_type::now();
    const double dt = std::chrono::duration<double>(now - last_step_).count();
    last_step_ = now;
    display_.begin_frame();
    if (input) handle_input(dt);
    session_.advance(dt);
    if (session_.dirty()) {
      const auto t0 = clock_type::now();
      session_.render();
      const double s = std::chrono::duration<double>(clock_type::now() - t0).count();
      frame_ms_.push_back(static_cast<float>(s * 1e3));
      if (frame_ms_.size() > 240) frame_ms_.pop_front();
      ++frames_rendered_;
      image_stale_ = true;
    }
    // While the clock runs every frame is a new view: a reference would be cancelled before its first
    // pass, so none is started (and the one in progress stops) until the animation pauses.
    if (gt_ && session_.playing()) gt_->cancel();
    if (gt_ && !session_.playing()) gt_->request(session_.view_key(), session_.scene(), session_.time(), session_.width(), session_.height());
    update_error();
    if (image_stale_) upload_image();
    draw_interface();
    draw_overlay();
    draw_labels();
    display_.end_frame();
    step_ms_.push_back(static_cast<float>(std::chrono::duration<double>(clock_type::now() - now).count() * 1e3));
    if (step_ms_.size() > 240) step_ms_.pop_front();
    ++steps_;
  }

  void run_interactive() {
    while (!display_.should_close()) {
      try {
        // Nothing to render and no reference converging: sleep until input (or 50 ms) instead of
        // spinning on the swapchain.
        if (!session_.dirty() && !(gt_ && gt_->busy())) display_.wait_events(0.05);
        step(true);
      } catch (const std::exception& e) {
        // A lost display device ends the session; anything else is shown and the viewer goes on.
        const std::string what = e.what();
        std::cerr << "softgi-viewer: error: " << what << "\n";
        if (what.find("device was lost") != std::string::npos || what.find("display:") == 0) throw;
        action_error_ = what;
      }
    }
  }

  int run_batch() {
    for (int i = 0; i < opt_.frames; ++i) step(false);
    if (session_.dirty()) session_.render();
    session_.capture(opt_.screenshot);
    std::cerr << "softgi-viewer: wrote " << opt_.screenshot << "\n";
    if (!opt_.window_shot.empty()) window_shot(opt_.window_shot);
    return finish();
  }

  int run_script(const Json& script) {
    const Json& actions = script.is_object() ? script.at("actions") : script;
    step(false);
    for (std::size_t i = 0; i < actions.size(); ++i) {
      try {
        apply(actions[i]);
      } catch (const std::exception& e) {
        throw std::runtime_error("script: action " + std::to_string(i) + " " + actions[i].dump() + ": " + e.what());
      }
    }
    return finish();
  }

 private:
  int finish() {
    for (int i = 0; i < (session_.split() ? 2 : 1); ++i)
      if (!session_.pane(i).error.empty()) {
        std::cerr << "softgi-viewer: error: the last frame failed: " << session_.pane(i).error << "\n";
        return 1;
      }
    report_rate();
    if (display_.validation_messages() > 0) {
      std::cerr << "softgi-viewer: error: " << display_.validation_messages() << " validation message(s) on the display device\n";
      return 1;
    }
    return 0;
  }

  static float median_of(const std::deque<float>& d) {
    std::vector<float> v(d.begin(), d.end());
    std::sort(v.begin(), v.end());
    return v.empty() ? 0.0f : v[v.size() / 2];
  }

  // The render time alone, and the whole step (render, interface, upload, present) of the frames that
  // rendered: what a user sees as the frame rate.
  void report_rate() const {
    if (frame_ms_.empty()) return;
    const float render = median_of(frame_ms_);
    std::deque<float> rendering_steps;
    for (std::size_t i = 0; i < step_ms_.size(); ++i)
      if (step_ms_[i] >= render * 0.5f) rendering_steps.push_back(step_ms_[i]);
    const float step = median_of(rendering_steps.empty() ? step_ms_ : rendering_steps);
    std::cerr << "softgi-viewer: " << frames_rendered_ << " frames rendered (" << session_.pane(0).technique->name() << " on "
              << session_.backend_name() << ", " << session_.width() << "x" << session_.height() << "): median " << render
              << " ms per frame, " << 1e3 / render << " frames/s; with the window " << step << " ms, " << 1e3 / step << " frames/s; "
              << display_.swapchain_recreations() << " swapchain recreations\n";
  }

  // --- Script actions -------------------------------------------------------------------------
  void run_frames(int n) {
    for (int i = 0; i < n; ++i) step(false);
  }

  void apply(const Json& a) {
    const std::string key = a.begin().key();
    const Json& v = a.begin().value();
    if (key == "scene") {
      session_.load_scene(v.get<std::string>());
    } else if (key == "technique") {
      session_.set_technique(v.get<std::string>());
    } else if (key == "backend") {
      session_.set_backend(v.get<std::string>());
    } else if (key == "param") {
      if (v.is_string()) {
        const std::string s = v.get<std::string>();
        const auto eq = s.find('=');
        if (eq == std::string::npos) throw std::invalid_argument("'param' expects \"name=value\"");
        session_.set_param(s.substr(0, eq), s.substr(eq + 1));
      } else {
        for (const auto& [n, x] : v.items()) session_.set_param(n, x.is_string() ? x.get<std::string>() : x.dump());
      }
    } else if (key == "reset_params") {
      session_.reset_params();
    } else if (key == "camera") {
      if (!v.is_object()) throw std::invalid_argument("'camera' expects an object");
      for (const auto& [op, x] : v.items()) {
        if (op == "orbit") session_.orbit(x.at(0).get<float>(), x.at(1).get<float>());
        else if (op == "pan") session_.pan(x.at(0).get<float>(), x.at(1).get<float>());
        else if (op == "zoom") session_.zoom(x.get<float>());
        else if (op == "fly") session_.fly(x.at(0).get<float>(), x.at(1).get<float>(), x.at(2).get<float>());
        else if (op == "reset") session_.reset_camera();
        else throw std::invalid_argument("camera: unknown operation '" + op + "' (orbit, pan, zoom, fly, reset)");
      }
    } else if (key == "time") {
      session_.set_time(v.get<double>());
    } else if (key == "play") {
      session_.set_playing(v.get<bool>());
    } else if (key == "speed") {
      session_.set_speed(v.get<double>());
    } else if (key == "fixed_dt") {
      session_.set_fixed_dt(v.get<double>());
    } else if (key == "frames") {
      run_frames(v.get<int>());
    } else if (key == "view") {
      session_.set_view(parse_view(v.get<std::string>()));
      image_stale_ = true;
    } else if (key == "split") {
      session_.set_split(v.is_null() ? std::string() : v.get<std::string>());
    } else if (key == "overlay") {
      session_.set_overlay(v.get<bool>());
    } else if (key == "exposure") {
      session_.set_exposure(v.get<float>());
      image_stale_ = true;
    } else if (key == "size") {
      session_.set_size(v.at(0).get<int>(), v.at(1).get<int>());
    } else if (key == "resize") {
      display_.resize(v.at(0).get<int>(), v.at(1).get<int>());
      run_frames(2);  // the window system answers the request between frames
    } else if (key == "minimise") {
      display_.iconify();
      run_frames(std::max(1, v.get<int>()));
      display_.restore();
      run_frames(1);
    } else if (key == "capture") {
      if (session_.dirty()) step(false);
      session_.capture(v.get<std::string>());
      std::cerr << "softgi-viewer: wrote " << v.get<std::string>() << "\n";
    } else if (key == "window_shot") {
      window_shot(v.get<std::string>());
    } else if (key == "save_settings") {
      write_settings(v.get<std::string>());
    } else if (key == "load_settings") {
      session_.load_settings(read_json_file(v.get<std::string>(), "settings"));
    }
  }

  // The window as presented (image and interface) to a PNG.
  void window_shot(const std::string& path) {
    display_.request_window_shot();
    step(false);
    const DisplayImage shot = display_.take_window_shot();
    if (shot.rgba.empty()) throw std::runtime_error("window shot '" + path + "': no frame was presented (minimised window?)");
    Image img(shot.width, shot.height);
    for (std::size_t i = 0; i < img.rgb.size(); ++i)
      img.rgb[i] = glm::vec3(shot.rgba[4 * i], shot.rgba[4 * i + 1], shot.rgba[4 * i + 2]) / 255.0f;
    io::write_png_display(path, img);
    std::cerr << "softgi-viewer: wrote " << path << "\n";
  }

  void write_settings(const std::string& path) const {
    const std::string tmp = path + ".tmp";
    {
      std::ofstream out(tmp);
      out << session_.settings().dump(2) << "\n";
      if (!out) throw std::runtime_error("settings '" + path + "': cannot write");
    }
    if (std::rename(tmp.c_str(), path.c_str()) != 0) {
      std::remove(tmp.c_str());
      throw std::runtime_error("settings '" + path + "': cannot write");
    }
  }

  // --- Input ----------------------------------------------------------------------------------
  void handle_input(double dt) {
    ImGuiIO& io = ImGui::GetIO();
    try {
      if (!io.WantCaptureMouse) {
        const ImVec2 d = io.MouseDelta;
        if (ImGui::IsMouseDragging(ImGuiMouseButton_Left) && (d.x != 0 || d.y != 0)) session_.orbit(-d.x * 0.3f, d.y * 0.3f);
        if ((ImGui::IsMouseDragging(ImGuiMouseButton_Right) || ImGui::IsMouseDragging(ImGuiMouseButton_Middle)) && (d.x != 0 || d.y != 0)) {
          const float h = std::max(1.0f, display_.image_rect().h / std::max(1.0f, io.DisplayFramebufferScale.y));
          session_.pan(-d.x / h, d.y / h);
        }
        if (io.MouseWheel != 0.0f) session_.zoom(std::pow(0.9f, io.MouseWheel));
      }
      if (!io.WantCaptureKeyboard) {
        if (ImGui::IsKeyPressed(ImGui::GetKeyIndex(ImGuiKey_Space))) session_.set_playing(!session_.playing());
        if (ImGui::IsKeyPressed(GLFW_KEY_R)) session_.reset_camera();
        if (ImGui::IsKeyPressed(GLFW_KEY_F)) fly_mode_ = !fly_mode_;
        if (fly_mode_) {
          const float s = static_cast<float>(std::min(dt, 0.25)) * fly_speed_;
          float r = 0, u = 0, f = 0;
          if (ImGui::IsKeyDown(GLFW_KEY_W)) f += s;
          if (ImGui::IsKeyDown(GLFW_KEY_S)) f -= s;
          if (ImGui::IsKeyDown(GLFW_KEY_D)) r += s;
          if (ImGui::IsKeyDown(GLFW_KEY_A)) r -= s;
          if (ImGui::IsKeyDown(GLFW_KEY_E)) u += s;
          if (ImGui::IsKeyDown(GLFW_KEY_Q)) u -= s;
          if (r != 0 || u != 0 || f != 0) session_.fly(r, u, f);
        }
      }
      if (ImGui::IsKeyPressed(GLFW_KEY_F12)) screenshot();
    } catch (const std::exception& e) {
      action_error_ = e.what();
    }
  }

  void screenshot() {
    char name[512];
    std::snprintf(name, sizeof name, "%s/%s-%s-%03d", opt_.screenshot_dir.c_str(), session_.scene().name.c_str(),
                  session_.pane(0).technique->name().c_str(), screenshot_count_++);
    session_.capture(name);
    status_ = std::string("wrote ") + name;
    std::cerr << "softgi-viewer: " << status_ << "\n";
  }

  // --- Images ---------------------------------------------------------------------------------
  void update_error() {
    if (!gt_) return;
    const std::uint64_t key = session_.view_key();
    const int spp = gt_->spp(key);
    if (spp == 0) {
      gt_spp_shown_ = 0;
      return;
    }
    if (spp == gt_spp_shown_ && frames_rendered_ == error_frame_) return;
    const auto est = gt_->latest(key);
    if (!est) return;
    gt_image_ = est->final_image;
    gt_spp_shown_ = est->spp;
    error_frame_ = frames_rendered_;
    for (int i = 0; i < 2; ++i) {
      errors_[i] = {};
      const Pane& p = session_.pane(i);
      if (i == 1 && !session_.split()) continue;
      if (p.result.final_image.width != gt_image_.width || p.result.final_image.height != gt_image_.height) continue;
      try {
        errors_[i].m = metrics::compare(p.result.final_image, gt_image_);
        errors_[i].valid = true;
      } catch (const std::exception& e) {
        errors_[i].error = e.what();
      }
    }
    if (session_.view() == View::Error) image_stale_ = true;
  }

  void upload_image() {
    image_stale_ = false;
    const int panes = session_.split() ? 2 : 1;
    std::vector<std::vector<std::uint8_t>> parts;
    int w = 0, h = 0;
    error_scale_ = 0.0;
    for (int i = 0; i < panes; ++i) {
      const Pane& p = session_.pane(i);
      const Image& img = view_image(p.result, session_.view());
      if (!p.result.final_image.empty()) w = p.result.final_image.width, h = p.result.final_image.height;
      if (img.empty()) {
        parts.emplace_back();
        continue;
      }
      if (session_.view() == View::Error && !gt_image_.empty() && gt_image_.width == img.width && gt_image_.height == img.height) {
        // One scale for both panes, so that the same colour means the same error.
        if (error_scale_ == 0.0) error_scale_ = metrics::error_map_scale(session_.pane(0).result.final_image, gt_image_);
        parts.push_back(io::display_bytes(metrics::error_map(p.result.final_image, gt_image_, error_scale_), 1.0f, false, 4));
      } else {
        parts.push_back(io::display_bytes(img, session_.exposure(), true, 4));
      }
    }
    if (w == 0) {
      display_.set_image({});
      return;
    }
    DisplayImage out;
    out.width = w * panes;
    out.height = h;
    out.rgba.assign(static_cast<std::size_t>(out.width) * h * 4, 0);
    for (int i = 0; i < panes; ++i) {
      if (parts[i].size() != static_cast<std::size_t>(w) * h * 4) continue;  // a failed pane stays black
      for (int y = 0; y < h; ++y)
        std::copy_n(parts[i].begin() + static_cast<std::ptrdiff_t>(y) * w * 4, w * 4,
                    out.rgba.begin() + (static_cast<std::ptrdiff_t>(y) * out.width + static_cast<std::ptrdiff_t>(i) * w) * 4);
    }
    display_.set_image(std::move(out));
  }

  // --- Interface ------------------------------------------------------------------------------
  static void help_marker(const std::string& text) {
    if (!text.empty() && ImGui::IsItemHovered()) ImGui::SetTooltip("%s", text.c_str());
  }

  template <class F>
  void guarded(F&& f) {
    try {
      f();
      action_error_.clear();
    } catch (const std::exception& e) {
      action_error_ = e.what();
      std::cerr << "softgi-viewer: error: " << action_error_ << "\n";
    }
  }

  // Widgets generated from a technique's parameter descriptions.
  void param_widgets(int pane_index) {
    Pane& p = session_.pane(pane_index);
    for (const auto& d : p.params.descs()) {
      ImGui::PushID(d.name.c_str());
      switch (d.type) {
        case render::ParamType::Enum: {
          const std::string cur = p.params.get_enum(d.name);
          if (ImGui::BeginCombo(d.name.c_str(), cur.c_str())) {
            for (const auto& c : d.choices)
              if (ImGui::Selectable(c.c_str(), c == cur)) guarded([&] { session_.set_param(d.name, c, pane_index); });
            ImGui::EndCombo();
          }
          break;
        }
        case render::ParamType::Bool: {
          bool v = p.params.get_bool(d.name);
          if (ImGui::Checkbox(d.name.c_str(), &v)) guarded([&] { session_.set_param(d.name, v ? "true" : "false", pane_index); });
          break;
        }
        case render::ParamType::Int: {
          int v = p.params.get_int(d.name);
          const int lo = static_cast<int>(d.min), hi = static_cast<int>(d.max);
          const bool changed = (hi - lo) <= 4096 ? ImGui::SliderInt(d.name.c_str(), &v, lo, hi)
                                                 : ImGui::SliderInt(d.name.c_str(), &v, lo, hi, "%d", ImGuiSliderFlags_Logarithmic);
          if (changed)
            guarded([&] { session_.set_param(d.name, std::to_string(std::clamp(v, lo, hi)), pane_index); });
          break;
        }
        case render::ParamType::Float: {
          float v = static_cast<float>(p.params.get_float(d.name));
          const float lo = static_cast<float>(d.min), hi = static_cast<float>(d.max);
          const ImGuiSliderFlags flags = d.sweep_log && lo > 0.0f ? ImGuiSliderFlags_Logarithmic : 0;
          if (ImGui::SliderFloat(d.name.c_str(), &v, lo, hi, "%.4g", flags)) {
            std::ostringstream os;
            os.precision(9);
            os << std::clamp(v, lo, hi);
            guarded([&] { session_.set_param(d.name, os.str(), pane_index); });
          }
          break;
        }
      }
      help_marker(d.help);
      ImGui::PopID();
    }
    if (ImGui::Button("Reset to defaults")) session_.reset_params(pane_index);
  }

  void technique_combo(const char* label, int pane_index, bool allow_none) {
    const std::string cur = pane_index == 1 && !session_.split() ? "(none)" : session_.pane(pane_index).technique->name();
    if (ImGui::BeginCombo(label, cur.c_str())) {
      if (allow_none && ImGui::Selectable("(none)", cur == "(none)")) guarded([&] { session_.set_split(""); });
      for (const auto& n : render::technique_names())
        if (ImGui::Selectable(n.c_str(), n == cur))
          guarded([&] { pane_index == 1 ? session_.set_split(n) : session_.set_technique(n, pane_index); });
      ImGui::EndCombo();
    }
  }

  void draw_interface() {
    ImGui::SetNextWindowPos(ImVec2(8, 8), ImGuiCond_FirstUseEver);
    ImGui::SetNextWindowSize(ImVec2(380, 0), ImGuiCond_FirstUseEver);
    ImGui::Begin("softgi");
    if (ImGui::CollapsingHeader("Scene", ImGuiTreeNodeFlags_DefaultOpen)) {
      const std::string cur = session_.scene_spec();
      if (ImGui::BeginCombo("built-in", cur.c_str())) {
        for (const auto& b : scene::builtin_scenes())
          if (ImGui::Selectable(b.name.c_str(), b.name == cur)) guarded([&] { session_.load_scene(b.name); });
        ImGui::EndCombo();
      }
      ImGui::InputText("file", scene_path_, sizeof scene_path_);
      help_marker("a scene file (.json) or a glTF/GLB file");
      ImGui::SameLine();
      if (ImGui::Button("Load")) guarded([&] { session_.load_scene(scene_path_, fit_proxies_); });
      ImGui::InputInt("fit proxies", &fit_proxies_);
      help_marker("spheres fitted to each closed mesh that has none (a bare glTF brings no proxies); 0: none");
      fit_proxies_ = std::clamp(fit_proxies_, 0, 4096);
      if (ImGui::Button("Reset camera (R)")) guarded([&] { session_.reset_camera(); });
      ImGui::SameLine();
      ImGui::Checkbox("fly (F, WASD/QE)", &fly_mode_);
      ImGui::TextDisabled("drag: orbit; right/middle drag: pan; wheel: zoom");
    }
    if (ImGui::CollapsingHeader("Animation", ImGuiTreeNodeFlags_DefaultOpen)) {
      if (ImGui::Button(session_.playing() ? "Pause (space)" : "Play (space)")) session_.set_playing(!session_.playing());
      const double dur = session_.duration();
      float t = static_cast<float>(session_.time());
      if (ImGui::SliderFloat("time", &t, 0.0f, dur > 0.0 ? static_cast<float>(dur) : 10.0f, "%.3f s")) guarded([&] { session_.set_time(t); });
      float speed = static_cast<float>(session_.speed());
      if (ImGui::SliderFloat("speed", &speed, -4.0f, 4.0f, "%.2fx")) guarded([&] { session_.set_speed(speed); });
      float fdt = static_cast<float>(session_.fixed_dt());
      if (ImGui::InputFloat("fixed step", &fdt, 0.0f, 0.0f, "%.4f s")) guarded([&] { session_.set_fixed_dt(std::max(0.0f, fdt)); });
      help_marker("> 0: each frame advances the clock by this much (repeatable captures); 0: by wall time x speed");
    }
    if (ImGui::CollapsingHeader("Technique", ImGuiTreeNodeFlags_DefaultOpen)) {
      technique_combo("technique", 0, false);
      help_marker(session_.pane(0).technique->description());
      if (ImGui::BeginCombo("backend", session_.backend_name().c_str())) {
        for (const auto& n : render::backend_names())
          if (ImGui::Selectable(n.c_str(), n == session_.backend_name())) guarded([&] { session_.set_backend(n); });
        ImGui::EndCombo();
      }
      param_widgets(0);
    }
    if (ImGui::CollapsingHeader("View", ImGuiTreeNodeFlags_DefaultOpen)) {
      int v = static_cast<int>(session_.view());
      bool changed = ImGui::RadioButton("final", &v, 0);
      ImGui::SameLine();
      changed |= ImGui::RadioButton("direct", &v, 1);
      ImGui::SameLine();
      changed |= ImGui::RadioButton("indirect", &v, 2);
      ImGui::SameLine();
      changed |= ImGui::RadioButton("error", &v, 3);
      if (changed) session_.set_view(static_cast<View>(v)), image_stale_ = true;
      bool overlay = session_.overlay();
      if (ImGui::Checkbox("proxies over the image", &overlay)) session_.set_overlay(overlay);
      help_marker("the scene's proxy spheres at the current time, and the technique's own proxies and voxels where it has them");
      if (session_.overlay())
        for (int i = 0; i < (session_.split() ? 2 : 1); ++i)
          if (!overlay_note_[i].empty()) ImGui::TextDisabled("%s: %s", session_.pane(i).technique->name().c_str(), overlay_note_[i].c_str());
      float exposure = session_.exposure();
      if (ImGui::SliderFloat("exposure", &exposure, 0.05f, 20.0f, "%.2f", ImGuiSliderFlags_Logarithmic))
        guarded([&] { session_.set_exposure(exposure); }), image_stale_ = true;
      int size[2] = {session_.width(), session_.height()};
      if (ImGui::InputInt2("render size", size, ImGuiInputTextFlags_EnterReturnsTrue)) guarded([&] { session_.set_size(size[0], size[1]); });
      technique_combo("beside it", 1, true);
      help_marker("a second technique at the same camera, time and backend, shown to the right");
      if (session_.split() && ImGui::TreeNode("its parameters")) {
        param_widgets(1);
        ImGui::TreePop();
      }
    }
    if (ImGui::CollapsingHeader("Files", ImGuiTreeNodeFlags_DefaultOpen)) {
      if (ImGui::Button("Screenshot (F12)")) guarded([&] { screenshot(); });
      help_marker("final/direct/indirect EXR and PNG and record.json under " + opt_.screenshot_dir);
      ImGui::InputText("settings", settings_path_, sizeof settings_path_);
      if (ImGui::Button("Save settings")) guarded([&] { write_settings(settings_path_); status_ = std::string("saved ") + settings_path_; });
      ImGui::SameLine();
      if (ImGui::Button("Load settings")) guarded([&] { session_.load_settings(read_json_file(settings_path_, "settings")); });
    }
    for (int i = 0; i < (session_.split() ? 2 : 1); ++i)
      if (!session_.pane(i).error.empty()) ImGui::TextColored(ImVec4(1, 0.4f, 0.4f, 1), "frame failed: %s", session_.pane(i).error.c_str());
    if (!action_error_.empty()) ImGui::TextColored(ImVec4(1, 0.4f, 0.4f, 1), "%s", action_error_.c_str());
    if (!status_.empty()) ImGui::TextDisabled("%s", status_.c_str());
    // The image goes between the two panels (when the window is wide enough for all three).
    const float fb = ImGui::GetIO().DisplayFramebufferScale.x;
    const float left = ImGui::IsWindowCollapsed() ? 0.0f : (ImGui::GetWindowPos().x + ImGui::GetWindowSize().x + 8.0f) * fb;
    ImGui::End();

    const ImVec2 display = ImGui::GetIO().DisplaySize;
    ImGui::SetNextWindowPos(ImVec2(display.x - 8, 8), ImGuiCond_Always, ImVec2(1, 0));
    ImGui::SetNextWindowSize(ImVec2(320, 0), ImGuiCond_FirstUseEver);
    ImGui::Begin("frame");
    draw_error_panel();
    draw_timings();
    const float right = ImGui::IsWindowCollapsed() ? 0.0f : (display.x - ImGui::GetWindowPos().x + 8.0f) * fb;
    ImGui::End();
    display_.set_margins(left, right);
  }

  void draw_error_panel() {
    if (!ImGui::CollapsingHeader("Error against the ground truth", ImGuiTreeNodeFlags_DefaultOpen)) return;
    if (!gt_) {
      ImGui::TextDisabled("ground truth off (--no-ground-truth, or batch mode without --ground-truth)");
      return;
    }
    const int spp = gt_->spp(session_.view_key());
    ImGui::Text("reference: %d / %d spp%s", spp, gt_->max_spp(), gt_->busy() ? " (rendering)" : "");
    if (!gt_->error().empty()) ImGui::TextColored(ImVec4(1, 0.4f, 0.4f, 1), "reference failed: %s", gt_->error().c_str());
    for (int i = 0; i < (session_.split() ? 2 : 1); ++i) {
      if (errors_[i].valid)
        ImGui::Text("%s: relMSE %.4g  SSIM %.4f", session_.pane(i).technique->name().c_str(), errors_[i].m.relmse, errors_[i].m.ssim);
      else if (!errors_[i].error.empty())
        ImGui::TextColored(ImVec4(1, 0.4f, 0.4f, 1), "%s", errors_[i].error.c_str());
    }
    ImGui::TextDisabled("against the running estimate: its own noise is counted as error until it converges");
    if (session_.view() == View::Error && error_scale_ > 0.0) draw_colour_bar();
  }

  // The error map's colours from 0 to its scale, made by the same function that colours the map.
  void draw_colour_bar() {
    const int n = 64;
    Image ramp(n, 1), zero(n, 1);
    for (int i = 0; i < n; ++i) ramp.at(i, 0) = glm::vec3(static_cast<float>(error_scale_ * i / (n - 1)));
    const Image colours = metrics::error_map(ramp, zero, error_scale_);
    const ImVec2 p = ImGui::GetCursorScreenPos();
    const float w = ImGui::GetContentRegionAvail().x, h = 14.0f;
    ImDrawList* dl = ImGui::GetWindowDrawList();
    for (int i = 0; i < n; ++i) {
      const glm::vec3 c = colours.at(i, 0);
      dl->AddRectFilled(ImVec2(p.x + w * i / n, p.y), ImVec2(p.x + w * (i + 1) / n + 1, p.y + h),
                        IM_COL32(static_cast<int>(std::clamp(c.x, 0.f, 1.f) * 255), static_cast<int>(std::clamp(c.y, 0.f, 1.f) * 255),
                                 static_cast<int>(std::clamp(c.z, 0.f, 1.f) * 255), 255));
    }
    ImGui::Dummy(ImVec2(w, h));
    ImGui::Text("0");
    ImGui::SameLine(std::max(0.0f, w - 90.0f));
    ImGui::Text("%.3g |dL|", error_scale_);
  }

  void draw_timings() {
    if (!ImGui::CollapsingHeader("Timings", ImGuiTreeNodeFlags_DefaultOpen)) return;
    if (!frame_ms_.empty()) {
      std::vector<float> v(frame_ms_.begin(), frame_ms_.end());
      char overlay[64];
      std::snprintf(overlay, sizeof overlay, "last %.1f ms", v.back());
      ImGui::PlotLines("frame ms", v.data(), static_cast<int>(v.size()), 0, overlay, 0.0f, FLT_MAX, ImVec2(0, 60));
    }
    for (int i = 0; i < (session_.split() ? 2 : 1); ++i) {
      const render::FrameResult& r = session_.pane(i).result;
      if (r.passes.empty()) continue;
      ImGui::Text("%s: %.2f ms, %zu passes", session_.pane(i).technique->name().c_str(), r.total_seconds * 1e3, r.passes.size());
      ImGui::PushID(i);
      if (ImGui::BeginTable("passes", 3, ImGuiTableFlags_RowBg | ImGuiTableFlags_SizingStretchProp)) {
        ImGui::TableSetupColumn("pass");
        ImGui::TableSetupColumn("wall ms");
        ImGui::TableSetupColumn("GPU ms");
        ImGui::TableHeadersRow();
        for (const auto& p : r.passes) {
          ImGui::TableNextRow();
          ImGui::TableNextColumn();
          ImGui::TextUnformatted(p.name.c_str());
          ImGui::TableNextColumn();
          ImGui::Text("%.2f", p.wall_seconds * 1e3);
          ImGui::TableNextColumn();
          if (p.gpu_seconds >= 0.0) ImGui::Text("%.2f", p.gpu_seconds * 1e3);
        }
        ImGui::EndTable();
      }
      for (const auto& p : r.pruned) ImGui::TextDisabled("pruned %s: %s", p.name.c_str(), p.reason.c_str());
      for (const auto& w : r.warnings) ImGui::TextColored(ImVec4(1, 0.8f, 0.3f, 1), "%s", w.c_str());
      ImGui::PopID();
    }
  }

  // Each pane's technique (in the split view) and what it cannot show, over the image.
  void draw_labels() {
    const ImageRect rect = display_.image_rect();
    if (rect.w <= 0) return;
    const ImVec2 scale = ImGui::GetIO().DisplayFramebufferScale;
    const int panes = session_.split() ? 2 : 1;
    ImDrawList* dl = ImGui::GetBackgroundDrawList();
    for (int i = 0; i < panes; ++i) {
      const Pane& p = session_.pane(i);
      std::string label = panes > 1 ? p.technique->name() : std::string();
      if (!p.error.empty())
        label += (label.empty() ? "" : ": ") + std::string("frame failed");
      else if (view_image(p.result, session_.view()).empty() && !p.result.final_image.empty())
        label += (label.empty() ? "" : ": ") + std::string("no ") + to_string(session_.view()) + " image";
      else if (session_.view() == View::Error && gt_image_.empty())
        label += (label.empty() ? "" : ": ") + std::string("waiting for the ground truth");
      if (label.empty()) continue;
      const ImVec2 at((rect.x + rect.w * i / panes) / scale.x + 6, rect.y / scale.y + 4);
      dl->AddRectFilled(ImVec2(at.x - 3, at.y - 2), ImVec2(at.x + ImGui::CalcTextSize(label.c_str()).x + 3, at.y + ImGui::GetFontSize() + 2),
                        IM_COL32(0, 0, 0, 160));
      dl->AddText(at, IM_COL32(255, 255, 255, 255), label.c_str());
    }
  }

  // Proxy spheres of the posed scene, projected with the frame's camera onto each pane.
  void draw_overlay() {
    if (!session_.overlay()) return;
    const Pane& p0 = session_.pane(0);
    if (p0.result.final_image.empty()) return;
    const ImageRect rect = display_.image_rect();
    if (rect.w <= 0) return;
    const int w = p0.result.final_image.width, h = p0.result.final_image.height;
    const render::PinholeCamera cam = render::make_pinhole_camera(session_.scene(), w, h, "overlay");
    if (posed_time_ != p0.rendered_time || posed_key_ != session_.view_key()) {
      posed_ = scene::evaluate(session_.scene(), p0.rendered_time);
      posed_time_ = p0.rendered_time;
      posed_key_ = session_.view_key();
    }
    const ImVec2 scale = ImGui::GetIO().DisplayFramebufferScale;
    const int panes = session_.split() ? 2 : 1;
    const float pane_w = rect.w / static_cast<float>(panes);
    const float px_per_image = pane_w / static_cast<float>(w);
    ImDrawList* dl = ImGui::GetBackgroundDrawList();
    const ImU32 colours[] = {IM_COL32(255, 200, 60, 200), IM_COL32(80, 220, 255, 200), IM_COL32(255, 90, 200, 200)};
    auto project = [&](const glm::vec3& p, float& ix, float& iy, float& z) {
      const glm::vec3 d = p - cam.position;
      z = glm::dot(d, cam.forward);
      ix = (glm::dot(d, cam.right) / (z * cam.tan_half_fov_y * cam.aspect) + 1.0f) * 0.5f * static_cast<float>(w);
      iy = (1.0f - glm::dot(d, cam.up) / (z * cam.tan_half_fov_y)) * 0.5f * static_cast<float>(h);
    };
    auto to_window = [&](int pane, float ix, float iy) {
      return ImVec2((rect.x + pane_w * pane + ix * px_per_image) / scale.x, (rect.y + iy * px_per_image) / scale.y);
    };
    // What each technique adds: its own proxies (discs) and structure (boxes). Capped so that a
    // fine grid or a dense sampling does not stall the interface; the panel says how many are drawn.
    const float near = 1e-3f * glm::length(session_.camera().target - session_.camera().position);
    bool scene_spheres[2] = {true, true};
    for (int pane = 0; pane < panes; ++pane) {
      const Pane& p = session_.pane(pane);
      const render::OverlayGeometry& geo = p.overlay;
      scene_spheres[pane] = geo.scene_spheres;
      const std::size_t max_points = 20000, max_boxes = 4096;
      for (std::size_t i = 0; i < std::min(max_points, geo.points.size()); ++i) {
        float ix, iy, z;
        project(geo.points[i].position, ix, iy, z);
        if (z <= near) continue;
        // A dot per proxy: at their true disc radius the discs overlap by design and hide the image.
        dl->AddCircleFilled(to_window(pane, ix, iy), 1.5f, IM_COL32(120, 255, 120, 140), 6);
      }
      static const int edges[12][2] = {{0, 1}, {2, 3}, {4, 5}, {6, 7}, {0, 2}, {1, 3}, {4, 6}, {5, 7}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};
      for (std::size_t b = 0; b < std::min(max_boxes, geo.boxes.size()); ++b) {
        ImVec2 c[8];
        bool ok = true;
        for (int k = 0; k < 8; ++k) {
          const glm::vec3 corner((k & 1) ? geo.boxes[b].hi.x : geo.boxes[b].lo.x, (k & 2) ? geo.boxes[b].hi.y : geo.boxes[b].lo.y,
                                 (k & 4) ? geo.boxes[b].hi.z : geo.boxes[b].lo.z);
          float ix, iy, z;
          project(corner, ix, iy, z);
          ok = ok && z > near;
          c[k] = to_window(pane, ix, iy);
        }
        if (!ok) continue;
        for (const auto& e : edges) dl->AddLine(c[e[0]], c[e[1]], IM_COL32(255, 255, 255, 70));
      }
      overlay_note_[pane].clear();
      if (!geo.points.empty())
        overlay_note_[pane] += std::to_string(std::min(max_points, geo.points.size())) + " of " + std::to_string(geo.points.size()) + " " + geo.points_label;
      if (!geo.boxes.empty())
        overlay_note_[pane] += (overlay_note_[pane].empty() ? "" : ", ") + std::to_string(std::min(max_boxes, geo.boxes.size())) + " of " +
                               std::to_string(geo.boxes.size()) + " " + geo.boxes_label;
    }
    for (int pane = 0; pane < panes; ++pane) {
      if (!scene_spheres[pane]) continue;
      for (std::size_t set = 0; set < posed_.proxies.size(); ++set)
        for (const auto& sp : posed_.proxies[set]) {
          float ix, iy, z;
          project(sp.center, ix, iy, z);
          if (z <= sp.radius * 0.5f) continue;
          const float ir = sp.radius / (z * cam.tan_half_fov_y) * 0.5f * static_cast<float>(h);
          dl->AddCircle(to_window(pane, ix, iy), ir * px_per_image / scale.x, colours[set % 3], 32, 1.5f);
        }
    }
  }

  const ViewerOptions& opt_;
  Session session_;
  Display display_;
  std::unique_ptr<GroundTruth> gt_;
  Image gt_image_;
  int gt_spp_shown_ = 0;
  long long error_frame_ = -1;
  struct PaneError {
    bool valid = false;
    metrics::Metrics m;
    std::string error;
  } errors_[2];
  double error_scale_ = 0.0;
  std::deque<float> frame_ms_, step_ms_;
  long long frames_rendered_ = 0, steps_ = 0;
  bool image_stale_ = true;
  bool fly_mode_ = false;
  float fly_speed_ = 0.5f;  // distances to the target per second
  int fit_proxies_ = 0;
  int screenshot_count_ = 0;
  std::string action_error_, status_;
  char settings_path_[512] = {};
  char scene_path_[512] = {};
  std::string overlay_note_[2];
  scene::PosedScene posed_;
  double posed_time_ = -1.0;
  std::uint64_t posed_key_ = 0;
  clock_type::time_point last_step_ = clock_type::now();
};

}  // namespace

int run_viewer(const ViewerOptions& options) {
  // A script is read and checked before the window opens: a misspelt action costs nothing.
  Json script;
  if (!options.script.empty()) {
    script = read_json_file(options.script, "--script");
    check_script(script);
  }
  Viewer v(options);
  if (!options.script.empty()) return v.run_script(script);
  if (options.frames > 0) return v.run_batch();
  v.run_interactive();
  return 0;
}

}  // namespace softgi::viewer
