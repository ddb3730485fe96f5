// The viewer's loop: window, session, interface, ground truth, and the batch and script modes
// that run it without input.
#pragma once

#include <string>

#include "display.hpp"
#include "session.hpp"

namespace softgi::viewer {

struct ViewerOptions {
  SessionOptions session;
  DisplayOptions display;
  int frames = 0;                 // batch mode: frames to run before the screenshot
  std::string screenshot;         // batch mode: where the screenshot goes (a directory)
  std::string window_shot;        // batch mode: the window as presented, interface included (PNG)
  std::string script;             // a JSON file of actions run without input
  std::string settings;           // settings loaded at start (JSON)
  std::string screenshot_dir = "screenshots";  // F12 and the button write here, one folder per shot
  bool ground_truth = true;       // the progressive reference of the current view
  int ground_truth_spp = 1024;
};

// Runs the viewer; returns the process exit status. Interactive unless `frames`/`script` is set.
// Batch and script runs return non-zero when a frame failed, a capture could not be written, or
// the validation layer reported anything.
int run_viewer(const ViewerOptions& options);

// The actions a script holds, one JSON object each (docs/viewer.md lists them). Exposed for tests.
void check_script(const Json& script);

}  // namespace softgi::viewer
