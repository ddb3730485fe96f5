#include "ground_truth.hpp"

#include <chrono>

#include "softgi/reference/reference.hpp"

namespace softgi::viewer {

namespace {
// Thrown from the pass callback to abandon a render whose view is gone.
struct Cancelled {};
}  // namespace

GroundTruth::GroundTruth(int max_spp) : max_spp_(max_spp), thread_([this] { worker(); }) {}

GroundTruth::~GroundTruth() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
    pending_.reset();
  }
  cancel_ = true;
  wake_.notify_all();
  thread_.join();
}

void GroundTruth::request(std::uint64_t key, const scene::Scene& scene, double time, int width, int height) {
  std::lock_guard<std::mutex> lock(mutex_);
  if ((running_ && running_key_ == key) || (pending_ && pending_->key == key) || (!running_ && estimate_.key == key && estimate_.spp > 0))
    return;
  Job j;
  j.key = key;
  j.scene = std::make_shared<const scene::Scene>(scene);
  j.time = time;
  j.width = width;
  j.height = height;
  pending_ = std::move(j);
  if (running_) cancel_ = true;
  wake_.notify_all();
}

void GroundTruth::cancel() {
  std::lock_guard<std::mutex> lock(mutex_);
  pending_.reset();
  if (running_) cancel_ = true;
}

std::optional<GroundTruth::Estimate> GroundTruth::latest(std::uint64_t key) const {
  std::lock_guard<std::mutex> lock(mutex_);
  if (estimate_.key != key || estimate_.spp == 0) return std::nullopt;
  return estimate_;
}

int GroundTruth::spp(std::uint64_t key) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return estimate_.key == key ? estimate_.spp : 0;
}

bool GroundTruth::busy() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return running_ || pending_.has_value();
}

std::string GroundTruth::error() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return error_;
}

void GroundTruth::worker() {
  for (;;) {
    Job job;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [this] { return stop_ || pending_.has_value(); });
      if (stop_) return;
      job = std::move(*pending_);
      pending_.reset();
      running_ = true;
      running_key_ = job.key;
      cancel_ = false;
      estimate_ = Estimate{};
      estimate_.key = job.key;
      error_.clear();
    }
    const auto t0 = std::chrono::steady_clock::now();
    reference::ReferenceOptions opt;
    opt.spp = max_spp_;
    opt.time = job.time;
    opt.width = job.width;
    opt.height = job.height;
    try {
      reference::render_reference(*job.scene, opt, {}, [&](int spp_done, const reference::ReferenceResult& running) {
        if (cancel_) throw Cancelled{};
        std::lock_guard<std::mutex> lock(mutex_);
        estimate_.spp = spp_done;
        estimate_.final_image = running.final_image;
        estimate_.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      });
    } catch (const Cancelled&) {
    } catch (const std::exception& e) {
      std::lock_guard<std::mutex> lock(mutex_);
      error_ = e.what();
    }
    std::lock_guard<std::mutex> lock(mutex_);
    running_ = false;
  }
}

}  // namespace softgi::viewer
