// softgi::Progress: quiet within the delay, throttled, ends at 100 % or where the work stopped,
// off or redirected by the process-wide setting; ProgressBar's stderr lines; the sphere-set fit's
// report.
#include <gtest/gtest.h>

#include <chrono>
#include <iostream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "../proxies/meshes.hpp"
#include "softgi/progress.hpp"
#include "softgi/proxies/sphere_fit.hpp"

namespace softgi {
namespace {

struct Captured {
  std::string label;
  double fraction;
  bool done;
};

// Installs a handler (and delay) for one test, restores the previous settings after.
struct Capture {
  ProgressSettings saved = progress_settings();
  std::vector<Captured> events;
  Capture(double delay, bool enabled = true) {
    ProgressSettings s;
    s.enabled = enabled;
    s.delay_seconds = delay;
    s.handler = [this](const ProgressEvent& e) { events.push_back({std::string(e.label), e.fraction, e.done}); };
    set_progress_settings(s);
  }
  ~Capture() { set_progress_settings(saved); }
};

TEST(Progress, QuietWithinTheDelay) {
  Capture cap(3600.0);
  {
    Progress p("fast work");
    for (int i = 0; i <= 100; ++i) p.update(i / 100.0);
    p.done();
    EXPECT_FALSE(p.shown());
  }
  EXPECT_TRUE(cap.events.empty());
}

TEST(Progress, ReportsPastTheDelayThrottledAndEndsAtOne) {
  Capture cap(0.0);
  {
    Progress p("slow work");
    // 2000 updates within a few milliseconds: the first is reported, the rest fall within the
    // 0.1 s throttle, except that a loaded machine may let a few through.
    for (int i = 0; i < 2000; ++i) p.update(i / 4000.0);
    EXPECT_TRUE(p.shown());
    p.done();
    p.update(0.7);  // after done(): ignored
  }
  ASSERT_GE(cap.events.size(), 2u);
  EXPECT_LE(cap.events.size(), 20u);
  EXPECT_EQ(cap.events.front().label, "slow work");
  EXPECT_FALSE(cap.events.front().done);
  EXPECT_TRUE(cap.events.back().done);
  EXPECT_EQ(cap.events.back().fraction, 1.0);
  for (size_t i = 1; i < cap.events.size(); ++i) EXPECT_GE(cap.events[i].fraction, cap.events[i - 1].fraction);
}

TEST(Progress, FractionsAreClampedAndNeverGoBack) {
  Capture cap(0.0);
  Progress p("clamped");
  p.update(1.5);
  ASSERT_EQ(cap.events.size(), 1u);
  EXPECT_EQ(cap.events[0].fraction, 1.0);
  std::this_thread::sleep_for(std::chrono::milliseconds(120));  // past the throttle
  p.update(0.2);
  ASSERT_EQ(cap.events.size(), 2u);
  EXPECT_EQ(cap.events[1].fraction, 1.0) << "a lower fraction does not move the bar back";
}

TEST(Progress, WorkLeftByAnExceptionEndsWhereItStopped) {
  Capture cap(0.0);
  try {
    Progress p("failing work");
    p.update(0.4);
    throw std::runtime_error("stop");
  } catch (const std::runtime_error&) {
  }
  ASSERT_EQ(cap.events.size(), 2u);
  EXPECT_TRUE(cap.events.back().done);
  EXPECT_DOUBLE_EQ(cap.events.back().fraction, 0.4) << "not reported as complete";
}

TEST(Progress, OffMeansNothingEvenPastTheDelay) {
  Capture cap(0.0, false);
  {
    Progress p("muted");
    p.update(0.5);
    p.done();
  }
  EXPECT_TRUE(cap.events.empty());
}

TEST(Progress, DefaultGoesToStderr) {
  const ProgressSettings saved = progress_settings();
  ProgressSettings s;
  s.delay_seconds = 0.0;
  set_progress_settings(s);
  std::ostringstream err;
  std::streambuf* old = std::cerr.rdbuf(err.rdbuf());
  {
    Progress p("to stderr");
    p.update(0.5);
    p.done();
  }
  std::cerr.rdbuf(old);
  set_progress_settings(saved);
  // A terminal gets a redrawn bar, a pipe one line per 10 %; both name the work and end at 100 %.
  EXPECT_NE(err.str().find("to stderr"), std::string::npos) << err.str();
  EXPECT_NE(err.str().find("100%"), std::string::npos) << err.str();
}

TEST(ProgressBar, DisabledPrintsNothing) {
  std::ostringstream err;
  std::streambuf* old = std::cerr.rdbuf(err.rdbuf());
  ProgressBar bar("quiet", false);
  bar.update(0.5);
  bar.update(1.0);
  std::cerr.rdbuf(old);
  EXPECT_TRUE(err.str().empty());
}

TEST(Progress, SphereSetFitReportsWithoutACallbackOnly) {
  const proxies::TriMesh box = proxies::test::box_mesh({0, 0, 0}, {2, 1, 1});
  proxies::FitOptions opt;
  opt.spheres = 4;
  opt.grid_resolution = 6;
  opt.max_iterations = 4;
  {
    Capture cap(0.0);
    proxies::fit_sphere_set(box, opt);
    ASSERT_GE(cap.events.size(), 2u);
    EXPECT_EQ(cap.events.front().label, "sphere-set fit (4 spheres)");
    EXPECT_TRUE(cap.events.back().done);
    EXPECT_EQ(cap.events.back().fraction, 1.0);
  }
  {
    // A caller following the iterations itself (softgi fit-proxies prints each) gets no bar.
    Capture cap(0.0);
    int calls = 0;
    proxies::fit_sphere_set(box, opt, [&](const proxies::FitProgress&) { ++calls; });
    EXPECT_GT(calls, 0);
    EXPECT_TRUE(cap.events.empty());
  }
}

}  // namespace
}  // namespace softgi
