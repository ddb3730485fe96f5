// Progress of long setup work on stderr (include/softgi/progress.hpp).
#include "softgi/progress.hpp"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iomanip>
#include <iostream>
#include <mutex>
#include <optional>
#include <sstream>

namespace softgi {

ProgressBar::ProgressBar(std::string label, bool enabled, clock::time_point start)
    : label_(std::move(label)), enabled_(enabled), tty_(isatty(fileno(stderr)) != 0), start_(start) {}

void ProgressBar::update(double f, std::string_view detail) {
  if (!enabled_) return;
  f = std::clamp(std::isfinite(f) ? f : 0.0, 0.0, 1.0);
  const double t = std::chrono::duration<double>(clock::now() - start_).count();
  if (tty_) {
    if (f < 1.0 && t - last_draw_ < 0.1) return;
    last_draw_ = t;
    constexpr int kWidth = 30;
    const int filled = static_cast<int>(f * kWidth);
    std::ostringstream os;
    os << "\r" << label_ << " [" << std::string(filled, '#') << std::string(kWidth - filled, '-') << "] " << std::setw(3)
       << static_cast<int>(100.0 * f) << "%  ";
    if (!detail.empty()) os << detail << "  ";
    os << std::fixed << std::setprecision(1) << t << " s";
    if (f > 0.0 && f < 1.0) os << "  eta " << t * (1.0 - f) / f << " s";
    os << "   ";
    std::cerr << os.str() << std::flush;
    open_line_ = f < 1.0;
    if (f >= 1.0) std::cerr << "\n";
  } else {
    const int decile = static_cast<int>(f * 10.0 + 1e-9);
    if (decile <= last_decile_) return;
    last_decile_ = decile;
    // Formatted apart: the stream's flags (fixed, precision) stay as the caller had them.
    std::ostringstream os;
    os << label_ << " " << decile * 10 << "%";
    if (!detail.empty()) os << " " << detail;
    os << " (" << std::fixed << std::setprecision(1) << t << " s)\n";
    std::cerr << os.str();
  }
}

void ProgressBar::abandon() {
  if (!enabled_ || !open_line_) return;
  std::cerr << "\n";
  open_line_ = false;
}

namespace {
std::mutex g_settings_mutex;
ProgressSettings& settings_ref() {
  static ProgressSettings s;
  return s;
}
}  // namespace

void set_progress_settings(ProgressSettings settings) {
  std::lock_guard<std::mutex> lock(g_settings_mutex);
  settings_ref() = std::move(settings);
}

ProgressSettings progress_settings() {
  std::lock_guard<std::mutex> lock(g_settings_mutex);
  return settings_ref();
}

struct Progress::Impl {
  using clock = std::chrono::steady_clock;
  std::string label;
  ProgressSettings settings = progress_settings();
  clock::time_point start = clock::now();
  mutable std::mutex m;
  double fraction = 0.0;
  double last_event = -1.0;
  bool shown = false, finished = false;
  std::optional<ProgressBar> bar;

  void emit(double t, bool done) {
    shown = true;
    if (settings.handler) {
      settings.handler(ProgressEvent{label, fraction, t, done});
      return;
    }
    if (!bar) bar.emplace(label, true, start);
    if (done && fraction < 1.0) {
      bar->abandon();
    } else {
      bar->update(fraction);
    }
  }
};

Progress::Progress(std::string label) : impl_(std::make_unique<Impl>()) { impl_->label = std::move(label); }

Progress::~Progress() {
  Impl& p = *impl_;
  std::lock_guard<std::mutex> lock(p.m);
  if (p.finished || !p.shown) return;
  // Left early (by an exception or without done()): end where the work stopped.
  p.finished = true;
  try {
    p.emit(std::chrono::duration<double>(Impl::clock::now() - p.start).count(), true);
  } catch (...) {
    // A handler that throws must not end the process from a destructor.
  }
}

void Progress::update(double fraction) {
  Impl& p = *impl_;
  if (!p.settings.enabled) return;
  std::lock_guard<std::mutex> lock(p.m);
  if (p.finished) return;
  if (std::isfinite(fraction)) p.fraction = std::clamp(std::max(p.fraction, fraction), 0.0, 1.0);
  const double t = std::chrono::duration<double>(Impl::clock::now() - p.start).count();
  if (t < p.settings.delay_seconds) return;
  // At most about 10 events a second; the stderr bar throttles itself the same way.
  if (p.shown && t - p.last_event < 0.1) return;
  p.last_event = t;
  p.emit(t, false);
}

void Progress::done() {
  Impl& p = *impl_;
  if (!p.settings.enabled) return;
  std::lock_guard<std::mutex> lock(p.m);
  if (p.finished) return;
  p.finished = true;
  p.fraction = 1.0;
  const double t = std::chrono::duration<double>(Impl::clock::now() - p.start).count();
  // Work that ended within the delay stays silent; work that was shown, or that took longer than
  // the delay without an update in between, ends with its 100 % line.
  if (p.shown || t >= p.settings.delay_seconds) p.emit(t, true);
}

bool Progress::shown() const {
  std::lock_guard<std::mutex> lock(impl_->m);
  return impl_->shown;
}

}  // namespace softgi
