// softgi-viewer: an interactive window on every registered technique and backend, with batch and
// script modes that run without input (docs/viewer.md).
#include <CLI/CLI.hpp>

#include <exception>
#include <iostream>
#include <sstream>

#include "frame_output.hpp"
#include "viewer.hpp"

namespace {

void parse_size(const std::string& text, int& w, int& h) {
  char x = 0;
  std::istringstream is(text);
  if (!(is >> w >> x >> h) || x != 'x' || !is.eof() || w < 1 || h < 1 || w > 16384 || h > 16384)
    throw std::invalid_argument("--size '" + text + "': expected WxH, each side 1..16384 (e.g. 512x512)");
}

}  // namespace

int main(int argc, char** argv) {
  using namespace softgi;
  CLI::App app{"softgi-viewer: soft global illumination techniques in a window, switched live"};
  viewer::ViewerOptions o;
  std::string size = "512x512", window;
  bool gt = false, no_gt = false;
  app.add_option("--scene", o.session.scene, "built-in scene name, scene file or glTF/GLB file (default: spheres)");
  app.add_option("--fit-proxies", o.session.fit_proxies, "fit N proxy spheres to every closed mesh without proxies")
      ->check(CLI::Range(1, 4096));
  app.add_option("--technique", o.session.technique, "technique (default: shexp; softgi techniques lists them)");
  app.add_option("--backend", o.session.backend, "backend: " + app::backends_help());
  app.add_option("--device", o.session.device, "Vulkan device: index or name substring");
  app.add_option("--param", o.session.params, "technique parameter NAME=VALUE (repeatable)");
  app.add_option("--time", o.session.time, "animation time in seconds (default 0)");
  app.add_flag("--play", o.session.play, "start the animation playing (batch mode: frames advance the clock)");
  app.add_option("--fixed-dt", o.session.fixed_dt, "advance the clock by this many seconds per frame (repeatable captures)")
      ->check(CLI::Range(0.0, 1e6));
  app.add_option("--size", size, "render size WxH (default 512x512)");
  app.add_option("--window", window, "window size WxH (default: the render size plus room for the panel)");
  app.add_option("--frames", o.frames, "batch mode: run N frames without input, write --screenshot and exit")
      ->check(CLI::Range(1, 1000000));
  app.add_option("--screenshot", o.screenshot, "batch mode: directory for the frame (EXR, PNG, record.json)");
  app.add_option("--window-shot", o.window_shot, "batch mode: also write the whole window, interface included, as PNG");
  app.add_option("--script", o.script, "run a JSON file of actions without input and exit (docs/viewer.md)");
  app.add_option("--settings", o.settings, "load settings saved by the viewer (JSON) at start");
  app.add_option("--screenshot-dir", o.screenshot_dir, "where F12 and the Screenshot button write (default: screenshots)");
  app.add_flag("--ground-truth", gt, "render the progressive ground truth in batch and script modes too");
  app.add_flag("--no-ground-truth", no_gt, "no progressive ground truth (interactive mode)");
  app.add_option("--ground-truth-spp", o.ground_truth_spp, "samples per pixel the ground truth stops at (default 1024)")
      ->check(CLI::Range(1, 1 << 20));
  app.add_flag("--validation", o.display.validation,
               "Khronos validation layer on the display's device (the render backend follows SOFTGI_VULKAN_VALIDATION)");
  app.footer(app::techniques_help());
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  try {
    parse_size(size, o.session.width, o.session.height);
    if (window.empty()) {
      o.display.width = o.session.width + 400;
      o.display.height = std::max(o.session.height, 700);
    } else {
      try {
        parse_size(window, o.display.width, o.display.height);
      } catch (const std::invalid_argument&) {
        throw std::invalid_argument("--window '" + window + "': expected WxH, each side 1..16384");
      }
    }
    if (gt && no_gt) throw std::invalid_argument("--ground-truth and --no-ground-truth contradict each other");
    if (o.frames > 0 && o.screenshot.empty()) throw std::invalid_argument("--frames needs --screenshot DIR (where the frame goes)");
    if (!o.screenshot.empty() && o.frames == 0) throw std::invalid_argument("--screenshot needs --frames N (batch mode)");
    if (!o.window_shot.empty() && o.frames == 0) throw std::invalid_argument("--window-shot needs --frames N (batch mode)");
    if (o.frames > 0 && !o.script.empty()) throw std::invalid_argument("--frames and --script are two batch modes: choose one");
    const bool batch = o.frames > 0 || !o.script.empty();
    o.ground_truth = gt || (!batch && !no_gt);
    if (const char* v = std::getenv("SOFTGI_VULKAN_VALIDATION"); v && std::string(v) == "1") o.display.validation = true;
    return viewer::run_viewer(o);
  } catch (const std::exception& e) {
    std::cerr << "softgi-viewer: error: " << e.what() << "\n";
    return 1;
  }
}
