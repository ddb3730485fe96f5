// A progressive ground truth of what the viewer shows, rendered on a thread of its own: the
// reference path tracer (softgi/reference) at 1, 2, 4, ... samples per pixel of the current scene,
// camera, time and size. A new view cancels the render in progress and starts again.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "softgi/image.hpp"
#include "softgi/scene/scene.hpp"

namespace softgi::viewer {

class GroundTruth {
 public:
  explicit GroundTruth(int max_spp = 1024);
  ~GroundTruth();  // cancels and joins
  GroundTruth(const GroundTruth&) = delete;
  GroundTruth& operator=(const GroundTruth&) = delete;

  // Renders `scene` (copied) at `time` and width x height for view `key`, unless that key is
  // already being rendered or done. Whatever ran for an older key is cancelled.
  void request(std::uint64_t key, const scene::Scene& scene, double time, int width, int height);
  // Stops the render in progress (the estimate so far stays readable).
  void cancel();

  struct Estimate {
    std::uint64_t key = 0;
    int spp = 0;
    Image final_image;
    double seconds = 0.0;
  };
  // The latest running estimate for `key`, when there is one.
  std::optional<Estimate> latest(std::uint64_t key) const;
  // The samples per pixel reached for `key` (0: none yet), whether it is still rendering, and the
  // last error ("" when none).
  int spp(std::uint64_t key) const;
  bool busy() const;
  std::string error() const;
  int max_spp() const { return max_spp_; }

 private:
  void worker();

  const int max_spp_;
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  struct Job {
    std::uint64_t key = 0;
    std::shared_ptr<const scene::Scene> scene;
    double time = 0.0;
    int width = 0, height = 0;
  };
  std::optional<Job> pending_;
  std::uint64_t running_key_ = 0;
  bool running_ = false, stop_ = false;
  std::atomic<bool> cancel_{false};
  Estimate estimate_;
  std::string error_;
  std::thread thread_;
};

}  // namespace softgi::viewer
