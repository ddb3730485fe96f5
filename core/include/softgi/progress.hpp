// Progress of long setup work (sphere hierarchy builds, sphere-set fits) on stderr, shown only once
// the work has run for a while, so tests and fast frames stay quiet. A process-wide setting turns
// it off or sends it elsewhere.
#pragma once

#include <chrono>
#include <functional>
#include <memory>
#include <string>
#include <string_view>

namespace softgi {

// A progress line on stderr: on a terminal a bar redrawn at most 10 times a second, with elapsed
// time and an estimate of the time left; otherwise (logs, ctest) one line per 10 %.
class ProgressBar {
 public:
  using clock = std::chrono::steady_clock;
  // `start`: when the work began (elapsed times count from there, also when the bar appears late).
  ProgressBar(std::string label, bool enabled, clock::time_point start = clock::now());
  // fraction in [0, 1]; 1 draws the last state and ends the line. `detail` ("12/40 jobs") follows the
  // percentage.
  void update(double fraction, std::string_view detail = {});
  // Ends a partly drawn terminal line without claiming completion (the work stopped early).
  void abandon();

 private:
  std::string label_;
  bool enabled_, tty_;
  clock::time_point start_;
  double last_draw_ = -1.0;
  int last_decile_ = -1;
  bool open_line_ = false;
};

// One report of a Progress, passed to ProgressSettings::handler.
struct ProgressEvent {
  std::string_view label;
  double fraction = 0.0;  // of the work, in [0, 1]
  double seconds = 0.0;   // since the work started
  bool done = false;      // the last event of this work (fraction 1 unless it stopped early, e.g. threw)
};

// Process-wide settings read by every Progress when it is created.
struct ProgressSettings {
  bool enabled = true;
  // Nothing is reported until the work has run this long; from then on every update is.
  double delay_seconds = 1.0;
  // Empty: a ProgressBar on stderr. Otherwise every event goes here instead (at most about 10 a
  // second per piece of work, plus the last one); it may be called from any thread, one call at a
  // time per Progress.
  std::function<void(const ProgressEvent&)> handler;
};
void set_progress_settings(ProgressSettings settings);
ProgressSettings progress_settings();

// The progress of one piece of work. update() may be called from several threads.
class Progress {
 public:
  explicit Progress(std::string label);
  // Reports the end if anything was shown: 100 % after done(), or where it stopped when the work
  // is left by an exception.
  ~Progress();
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;

  void update(double fraction);
  void done();
  // Whether anything has been reported yet (the work ran past the delay).
  bool shown() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace softgi
