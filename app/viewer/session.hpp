// What the viewer shows and how it got there, without the window: scene, camera, animation
// clock, technique and parameters (one pane, or two side by side), backend, the last frames, and
// the actions that change them. The interface, the mouse and keys, batch mode and JSON scripts all
// go through these actions, so a scripted session is a session a user could have clicked through.
#pragma once

#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "softgi/render/backend.hpp"
#include "softgi/render/frame.hpp"
#include "softgi/render/params.hpp"
#include "softgi/render/technique.hpp"
#include "softgi/scene/scene.hpp"

namespace softgi::viewer {

using Json = nlohmann::ordered_json;

enum class View { Final, Direct, Indirect, Error };
const char* to_string(View v);
View parse_view(const std::string& s);  // throws std::invalid_argument naming the value and the choices

struct SessionOptions {
  std::string scene = "spheres";
  int fit_proxies = 0;
  std::string technique = "shexp";
  std::string backend;  // "": the reference backend
  std::string device;   // Vulkan device (index or name substring)
  std::vector<std::string> params;
  double time = 0.0;
  bool play = false;
  double speed = 1.0;
  double fixed_dt = 0.0;  // > 0: each frame advances the clock by this (repeatable captures); 0: by wall time
  int width = 512, height = 512;  // render resolution
};

// One technique with its parameters and last frame.
struct Pane {
  std::unique_ptr<render::Technique> technique;
  render::ParamSet params;
  render::FrameResult result;  // last frame (empty images before the first, or after an error)
  render::OverlayGeometry overlay;  // of `result`, when the overlay is on
  std::string error;           // why the last frame failed ("" when it rendered)
  double rendered_time = 0.0;  // the clock when `result` was rendered
};

class Session {
 public:
  // Loads the scene and creates the technique and backend; errors (unknown names, bad parameters,
  // missing files) throw std::invalid_argument / std::runtime_error naming what was wrong.
  explicit Session(const SessionOptions& options);
  ~Session();

  // --- Scene and camera -------------------------------------------------------------------------
  void load_scene(const std::string& spec, int fit_proxies = 0);
  const scene::Scene& scene() const { return scene_; }
  const std::string& scene_spec() const { return spec_; }
  int fit_proxies() const { return fit_proxies_; }
  const scene::Camera& camera() const { return scene_.camera; }
  void set_camera(const scene::Camera& c);  // validated: finite, position != target, fov in (0, 179)
  void reset_camera();                      // the scene's own camera
  // Orbit about the target (degrees of yaw about the up hint, of pitch towards it, kept 1 degree
  // short of the poles).
  void orbit(float yaw_deg, float pitch_deg);
  // Moves position and target together across the view: dx, dy in view heights at the target.
  void pan(float dx, float dy);
  // Distance to the target times `factor` (> 0).
  void zoom(float factor);
  // Moves position and target together by (right, up, forward) in units of the distance to the
  // target (fly mode, WASD/QE).
  void fly(float right, float up, float forward);

  // --- Animation --------------------------------------------------------------------------------
  double time() const { return time_; }
  void set_time(double t);  // finite
  bool playing() const { return playing_; }
  void set_playing(bool p) { playing_ = p; }
  double speed() const { return speed_; }
  void set_speed(double s);  // finite
  double fixed_dt() const { return fixed_dt_; }
  void set_fixed_dt(double dt);  // >= 0
  // The active clip's length in seconds (0 for a static scene).
  double duration() const;
  // Advances the clock when playing: by fixed_dt, or by wall_seconds x speed; wraps at the clip's end.
  void advance(double wall_seconds);

  // --- Techniques, parameters, backend ----------------------------------------------------------
  void set_technique(const std::string& name, int pane = 0);  // parameters reset to defaults
  void set_param(const std::string& name, const std::string& value, int pane = 0);
  void reset_params(int pane = 0);
  void set_backend(const std::string& name);
  const std::string& backend_name() const { return backend_name_; }
  render::Backend& backend();
  // A second technique beside the first ("" closes the split view).
  void set_split(const std::string& technique);
  bool split() const { return split_; }
  const Pane& pane(int i) const { return panes_[static_cast<std::size_t>(i)]; }
  Pane& pane(int i) { return panes_[static_cast<std::size_t>(i)]; }

  // --- What is shown ----------------------------------------------------------------------------
  View view() const { return view_; }
  void set_view(View v) { view_ = v; }
  bool overlay() const { return overlay_; }
  // Draws the proxies over the image: the scene's proxy spheres, and what the technique's
  // overlay() adds (its frames then also return Technique::overlay_outputs()).
  void set_overlay(bool on) {
    if (on != overlay_) dirty_ = true;
    overlay_ = on;
  }
  float exposure() const { return exposure_; }
  void set_exposure(float e);  // finite, > 0
  int width() const { return width_; }
  int height() const { return height_; }
  void set_size(int width, int height);  // 1..16384

  // --- Frames -----------------------------------------------------------------------------------
  // Something changed since the last frame (or the clock runs): render() has work to do.
  bool dirty() const { return dirty_ || playing_; }
  // Renders every pane at the current state. A frame that fails keeps the error in Pane::error
  // (and prints it on stderr once); the session goes on.
  void render();
  // A number that changes whenever what the ground truth depends on changes (scene, camera, time,
  // size): a progressive reference of an older key is stale.
  std::uint64_t view_key() const;

  // Writes pane 0's last frame to DIR: final/direct/indirect as EXR and PNG and a record.json of
  // the form `softgi render` writes, whose command_line renders the same frame. Throws when there
  // is no frame or a file could not be written.
  void capture(const std::string& dir) const;

  // Settings as JSON (scene, camera, clock, technique and parameters, backend, view) and back.
  Json settings() const;
  void load_settings(const Json& j);

 private:
  void make_pane(int i, const std::string& technique, const std::vector<std::string>& assignments);

  scene::Scene scene_;
  scene::Camera scene_camera_;
  std::string spec_;
  int fit_proxies_ = 0;
  double time_ = 0.0, speed_ = 1.0, fixed_dt_ = 0.0;
  bool playing_ = false;
  std::string backend_name_, device_;
  std::map<std::string, std::unique_ptr<render::Backend>> backends_;
  Pane panes_[2];
  bool split_ = false;
  View view_ = View::Final;
  bool overlay_ = false;
  float exposure_ = 1.0f;
  int width_ = 512, height_ = 512;
  bool dirty_ = true;
  std::uint64_t camera_version_ = 0;
};

}  // namespace softgi::viewer
