// `softgi report` (docs/reports.md): the sweep of every technique over its quality ladder on a set of
// scenes, as independent jobs whose results are files in the report's directory, so that a run can be
// split into shards, spread over processes and resumed.
#pragma once

#include <map>
#include <memory>
#include <string>
#include <vector>

#include "frame_output.hpp"
#include "softgi/image.hpp"
#include "softgi/render/backend.hpp"
#include "softgi/render/params.hpp"
#include "softgi/scene/scene.hpp"

namespace softgi::app::report {

// How much a report measures: image size, animation times, frames per timing, how converged the
// ground truth is, how far the path tracer's own error curve goes.
struct Budget {
  std::string name;                 // "quick" or "full"
  int width = 0, height = 0;        // 0 height: the camera's aspect
  std::vector<double> frame_times;  // animation times each setting is measured at
  int timed_frames = 3;             // the time of a setting is the median of these
  int warmup_frames = 1;            // untimed frames before them
  double target_noise = 1e-3;       // the reference's remaining noise (relMSE it may add)
  int min_spp = 16, max_spp = 256;  // first round and cap of the reference's convergence
  int pt_max_spp = 64;              // the path tracer's equal-time curve: 1, 2, 4, ... up to this
  bool every_rung = true;           // false: the ladder's first and last rungs only
};
// The named budget; std::invalid_argument for another name.
Budget budget_named(const std::string& name);

struct Settings {
  std::vector<std::string> scenes;      // specs as --scene takes them
  std::vector<std::string> techniques;  // registered names
  std::vector<std::string> backends;
  Budget budget;
  unsigned seed = 1;  // of the references (their second halves and the path tracer's curve derive from it)
  int fit_proxies = 0;
  std::string device;
  // Scenes (specs) that nothing moves in (scene::is_static): measured at the first frame time
  // only, since every other time would repeat its images and its times.
  std::vector<std::string> static_scenes;
};
Json settings_json(const Settings& s);
// Identifies what a job's result depends on besides the job itself: a finished job of another
// hash is measured again (resume) and shards of other hashes are not merged.
std::string settings_hash(const Settings& s);

// One (scene, technique, backend, rung, frame) point.
struct Job {
  std::string id;  // "<scene>.<technique>.<backend>.r<rung>.t<frame>", a file name
  std::string scene, scene_label, technique, backend;
  int rung = 0, rungs = 1;
  double frame_time = 0.0;
  render::ParamSet::Rung assignments;
};
// Every job, in a fixed order (scene, frame, technique, backend, rung): shard I of N takes jobs
// I, I + N, ...
std::vector<Job> plan_jobs(const Settings& s);
// The animation times a scene is measured at: the budget's, or its first alone for a static scene.
std::vector<double> frame_times_of(const Settings& s, const std::string& spec);
// A scene spec as a file-name part ("spheres", "my_scene_gltf").
std::string scene_label(const std::string& spec);
std::string frame_label(double t);  // "t0", "t0.5"

// Runs jobs and the references they need, in one process; results go to DIR (report_dir) as
// files: references/<scene>/<frame>/..., jobs/<id>.json, images/<id>/...
class Runner {
 public:
  Runner(Settings settings, std::string dir, int concurrent_jobs);
  ~Runner();
  Runner(const Runner&) = delete;
  Runner& operator=(const Runner&) = delete;

  // The converged references (with halves) of every scene and frame of `jobs`; rendered or read
  // back. Nothing in them is timed. `done(k, n)` after each.
  void prepare_references(const std::vector<Job>& jobs, const std::function<void(int, int)>& done);
  // The path tracer's equal-time curve of every scene and frame of `jobs` (timed, like the jobs);
  // rendered or read back, after prepare_references. `done(k, n)` after each.
  void prepare_curves(const std::vector<Job>& jobs, const std::function<void(int, int)>& done);
  // Whether DIR holds a finished result of `job` under these settings.
  bool finished(const Job& job) const;
  // Measures the job and writes jobs/<id>.json; a failing render is recorded in it, not thrown.
  Json run(const Job& job);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// results.json from DIR's finished jobs and references: the points (with Pareto flags and the
// equal-time comparison filled in), the scenes, the jobs of the plan not finished yet.
Json assemble_results(const std::string& dir, const Settings& settings, const std::vector<Job>& plan,
                      const std::string& command);

// The file in DIR that holds the comparative benchmark suite's results (a copy of --bench-json);
// assemble_results puts bench_results() of it under "bench" when it is there.
inline constexpr const char* kBenchFile = "bench_techniques.json";
// The comparative benchmark suite's output (bench/bench_techniques --benchmark_out=F
// --benchmark_out_format=json) as the page shows it: one row per (scene, backend, technique) with its
// time per frame in ms (Google Benchmark's real_time of the run: the mean of its frames; the median
// over repetitions where the run was repeated), its ratio to the fastest technique of that scene and
// backend, the mean ms of every pass, the bytes moved per frame and the passes left out; rows that
// failed keep their error. Also the run's context (host, CPUs, date, build type). Throws
// std::runtime_error naming the file for one that is missing, not JSON, or not that program's output.
Json bench_results(const std::string& path);

}  // namespace softgi::app::report
