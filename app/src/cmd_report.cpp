// `softgi report`: every technique over its quality ladder on a set of scenes, against a converged
// ground truth, as a page (index.html), results.json and results.csv (docs/reports.md). Each
// (scene, technique, backend, rung, frame) is a job whose result is a file: --jobs N runs them in N
// processes, --shard I/N one share, `softgi report merge` joins shares, and a run resumes from the
// jobs it finds finished.
#include <CLI/CLI.hpp>
#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <optional>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "commands.hpp"
#include "frame_output.hpp"
#include "output_dir.hpp"
#include "report.hpp"
#include "report_html.hpp"
#include "softgi/progress.hpp"
#include "softgi/render/technique.hpp"
#include "softgi/scene/builtin.hpp"

extern char** environ;

namespace fs = std::filesystem;

namespace softgi::app {

namespace {

struct ReportArgs {
  std::string scenes = "spheres", techniques = "all", backends, out, budget = "quick", device, shard, frames, rungs;
  int width = 0, height = 0, timed_frames = 0, warmup_frames = -1, max_spp = 0, pt_max_spp = 0, jobs = 1, fit_proxies = 0;
  int emit_slurm = 0;
  double target_noise = 0.0;
  unsigned seed = 1;
  bool no_page = false, references_only = false;
  std::string bench_json;  // bench_techniques' JSON, shown on the page
  // merge
  std::vector<std::string> shard_dirs;
};

// --scenes, --techniques, --backend, --budget and its overrides, checked before anything renders.
report::Settings read_settings(const ReportArgs& a) {
  register_builtin();
  report::Settings s;
  if (a.scenes == "all") {
    for (const auto& b : scene::builtin_scenes()) s.scenes.push_back(b.name);
  } else {
    s.scenes = split_list(a.scenes);
  }
  if (s.scenes.empty()) throw std::invalid_argument("--scenes: no scene named");
  s.techniques = a.techniques == "all" ? render::technique_names() : split_list(a.techniques);
  if (s.techniques.empty()) throw std::invalid_argument("--techniques: no technique named");
  for (const auto& t : s.techniques) render::create_technique(t);  // unknown names fail here
  s.backends = parse_backends(a.backends.empty() ? render::reference_backend_name() : a.backends);
  s.budget = report::budget_named(a.budget);
  report::Budget& b = s.budget;
  if (a.width > 0) b.width = a.width;
  if (a.height > 0) b.height = a.height;
  if (!a.frames.empty()) {
    b.frame_times.clear();
    for (const auto& f : split_list(a.frames)) {
      std::size_t used = 0;
      double t = 0.0;
      try {
        t = std::stod(f, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (used != f.size() || !std::isfinite(t)) throw std::invalid_argument("--frames: '" + f + "' is not a finite time in seconds");
      b.frame_times.push_back(t);
    }
    if (b.frame_times.empty()) throw std::invalid_argument("--frames: no time given");
  }
  if (a.timed_frames > 0) b.timed_frames = a.timed_frames;
  if (a.warmup_frames >= 0) b.warmup_frames = a.warmup_frames;
  if (a.target_noise != 0.0) {
    if (!(a.target_noise > 0.0) || !std::isfinite(a.target_noise))
      throw std::invalid_argument("--target-noise must be finite and > 0");
    b.target_noise = a.target_noise;
  }
  if (a.max_spp > 0) {
    if (a.max_spp % 2 || a.max_spp < b.min_spp)
      throw std::invalid_argument("--max-spp " + std::to_string(a.max_spp) + ": must be even and at least the first round's " +
                                  std::to_string(b.min_spp));
    b.max_spp = a.max_spp;
  }
  if (a.pt_max_spp > 0) b.pt_max_spp = a.pt_max_spp;
  if (!a.rungs.empty()) {
    if (a.rungs != "all" && a.rungs != "ends") throw std::invalid_argument("--rungs '" + a.rungs + "': expected all or ends");
    b.every_rung = a.rungs == "all";
  }
  s.seed = a.seed;
  s.fit_proxies = a.fit_proxies;
  s.device = a.device;
  // Loading each scene here also names a missing or malformed scene before anything renders.
  for (const auto& spec : s.scenes)
    if (scene::is_static(load_cli_scene("report", spec, 0))) s.static_scenes.push_back(spec);
  return s;
}

// "I/N" with 0 <= I < N.
std::pair<int, int> parse_shard(const std::string& text) {
  const std::size_t slash = text.find('/');
  int i = -1, n = 0;
  try {
    std::size_t ui = 0, un = 0;
    if (slash == std::string::npos) throw std::invalid_argument("");
    i = std::stoi(text.substr(0, slash), &ui);
    n = std::stoi(text.substr(slash + 1), &un);
    if (ui != slash || un != text.size() - slash - 1) throw std::invalid_argument("");
  } catch (const std::exception&) {
    throw std::invalid_argument("--shard '" + text + "': expected I/N with 0 <= I < N (e.g. 0/4)");
  }
  if (n < 1 || i < 0 || i >= n) throw std::invalid_argument("--shard '" + text + "': expected I/N with 0 <= I < N (e.g. 0/4)");
  return {i, n};
}

// The arguments that give the same settings, for the processes --jobs starts and the Slurm script.
std::vector<std::string> settings_arguments(const ReportArgs& a) {
  std::vector<std::string> v = {"report", "--scenes", a.scenes, "--techniques", a.techniques, "--budget", a.budget, "--out", a.out,
                                "--seed", std::to_string(a.seed)};
  auto add = [&](const char* flag, const std::string& value) {
    if (!value.empty()) v.insert(v.end(), {flag, value});
  };
  auto add_int = [&](const char* flag, int value, int unset) {
    if (value != unset) v.insert(v.end(), {flag, std::to_string(value)});
  };
  add("--backend", a.backends);
  add("--device", a.device);
  add("--frames", a.frames);
  add("--rungs", a.rungs);
  add("--bench-json", a.bench_json);
  add_int("--width", a.width, 0);
  add_int("--height", a.height, 0);
  add_int("--timed-frames", a.timed_frames, 0);
  add_int("--warmup-frames", a.warmup_frames, -1);
  add_int("--max-spp", a.max_spp, 0);
  add_int("--pt-max-spp", a.pt_max_spp, 0);
  add_int("--fit-proxies", a.fit_proxies, 0);
  if (a.target_noise != 0.0) {
    std::ostringstream os;
    os.precision(17);
    os << a.target_noise;
    v.insert(v.end(), {"--target-noise", os.str()});
  }
  return v;
}

std::string command_line(const std::vector<std::string>& args) {
  std::string c = "softgi";
  for (const auto& a : args) c += " " + shell_quote(a);
  return c;
}

// The plan of a run, kept in DIR so that merge knows what was asked and which jobs are missing.
Json plan_json(const report::Settings& s, const std::vector<report::Job>& jobs, const std::string& command) {
  Json ids = Json::array();
  for (const auto& j : jobs) ids.push_back(j.id);
  return {{"softgi_version", softgi_version()}, {"command", command}, {"settings", report::settings_json(s)},
          {"settings_hash", report::settings_hash(s)}, {"jobs", ids}};
}

// Settings back from a plan (report.json) written by another process or shard.
report::Settings settings_from_plan(const Json& plan) {
  const Json& j = plan.at("settings");
  report::Settings s;
  s.scenes = j.at("scenes").get<std::vector<std::string>>();
  s.techniques = j.at("techniques").get<std::vector<std::string>>();
  s.backends = j.at("backends").get<std::vector<std::string>>();
  s.budget = report::budget_named(j.at("budget").get<std::string>());
  report::Budget& b = s.budget;
  b.width = j.at("width");
  b.height = j.at("height");
  b.frame_times = j.at("frame_times").get<std::vector<double>>();
  b.timed_frames = j.at("timed_frames");
  b.warmup_frames = j.at("warmup_frames");
  b.target_noise = j.at("target_noise");
  b.min_spp = j.at("min_spp");
  b.max_spp = j.at("max_spp");
  b.pt_max_spp = j.at("pt_max_spp");
  b.every_rung = j.at("every_rung");
  s.seed = j.at("seed");
  s.fit_proxies = j.at("fit_proxies");
  s.device = j.at("device");
  s.static_scenes = j.value("static_scenes", std::vector<std::string>{});
  return s;
}

// index.html, results.json (the record, last), results.csv and the charting library in lib/.
void write_page(OutputDir& out, const Json& results) {
  const fs::path web = fs::path(scene::assets_dir()) / "web";
  for (const auto& f : report::page_libraries()) {
    const fs::path src = web / f;
    if (!fs::exists(src))
      throw std::runtime_error("report: the charting library file " + src.string() +
                               " is missing; run scripts/fetch-assets.sh (it fetches Vega, Vega-Lite and vega-embed)");
    std::ifstream in(src, std::ios::binary);
    std::ostringstream ss;
    ss << in.rdbuf();
    out.write_text("lib/" + f, ss.str());
  }
  out.write_text("index.html", report::page_html(results));
  out.write_text("results.csv", report::csv_table(results));
  out.finish(results);
}

// Starts `n` processes of this program, each running share k/n of the jobs, and waits for them;
// `tick` is called about twice a second meanwhile.
void run_processes(const ReportArgs& a, int n, const fs::path& logs, const std::function<void()>& tick) {
  std::vector<pid_t> pids;
  fs::create_directories(logs);
  const std::string exe = fs::read_symlink("/proc/self/exe").string();
  for (int k = 0; k < n; ++k) {
    std::vector<std::string> args = settings_arguments(a);
    args.insert(args.end(), {"--shard", std::to_string(k) + "/" + std::to_string(n), "--no-page", "--quiet-progress",
                             "--concurrent-jobs", std::to_string(n)});
    args.insert(args.begin(), exe);
    std::vector<char*> argv;
    for (auto& s : args) argv.push_back(s.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    const std::string log = (logs / ("process_" + std::to_string(k) + ".log")).string();
    posix_spawn_file_actions_addopen(&fa, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&fa, 1, 2);
    pid_t pid = 0;
    const int rc = posix_spawn(&pid, exe.c_str(), &fa, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&fa);
    if (rc != 0) throw std::runtime_error("report: cannot start a worker process (" + std::string(std::strerror(rc)) + ")");
    pids.push_back(pid);
  }
  std::string failed;
  std::size_t running = pids.size();
  std::vector<bool> done(pids.size(), false);
  while (running > 0) {
    for (std::size_t k = 0; k < pids.size(); ++k) {
      if (done[k]) continue;
      int status = 0;
      const pid_t r = waitpid(pids[k], &status, WNOHANG);
      if (r == 0) continue;
      done[k] = true;
      --running;
      if (r < 0 || !WIFEXITED(status) || WEXITSTATUS(status) != 0)
        failed += " " + (logs / ("process_" + std::to_string(k) + ".log")).string();
    }
    if (tick) tick();
    if (running > 0) std::this_thread::sleep_for(std::chrono::milliseconds(500));
  }
  if (!failed.empty()) throw std::runtime_error("report: worker process(es) failed; see" + failed);
}

// --bench-json FILE, read and checked before any work; its text, to be copied into DIR.
std::string read_bench_json(const std::string& path) {
  if (path.empty()) return {};
  report::bench_results(path);  // a file that is not bench_techniques' JSON fails here, naming it
  std::ifstream in(path);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

void run_report(const ReportArgs& a, bool quiet, int concurrent_jobs) {
  const report::Settings s = read_settings(a);
  const std::string bench = read_bench_json(a.bench_json);
  if (a.jobs < 1 || a.jobs > 256) throw std::invalid_argument("--jobs " + std::to_string(a.jobs) + ": expected 1 to 256");
  if (a.jobs > 1 && !a.shard.empty()) throw std::invalid_argument("--jobs and --shard: a shard runs in one process");
  std::pair<int, int> shard{0, 1};
  if (!a.shard.empty()) shard = parse_shard(a.shard);
  const std::vector<report::Job> plan = report::plan_jobs(s);
  std::vector<std::string> args = settings_arguments(a);
  const std::string command = command_line(args);

  OutputDir out(a.out, "--out", "results.json");
  // Worker processes of --jobs share DIR with the process that started them, which wrote the plan.
  const bool worker = concurrent_jobs > 1 && a.jobs == 1;
  if (!worker) out.write_json("report.json", plan_json(s, plan, command));
  if (!bench.empty() && !worker) out.write_text(report::kBenchFile, bench);

  if (a.emit_slurm > 0) {
    // A job array of N shards writing into DIR (a shared file system), then the merge that writes the page.
    const int n = a.emit_slurm;
    std::vector<std::string> shard_args = args;
    shard_args.insert(shard_args.end(), {"--shard", "${SLURM_ARRAY_TASK_ID}/" + std::to_string(n), "--no-page", "--quiet-progress"});
    std::string shard_cmd = "softgi";
    for (const auto& x : shard_args) shard_cmd += " " + (x.rfind("${", 0) == 0 ? "\"" + x + "\"" : shell_quote(x));
    std::ostringstream sb;
    sb << "#!/bin/bash\n"
       << "# softgi report as a Slurm job array: " << plan.size() << " jobs in " << n << " shards, written by\n#   " << command
       << " --emit-slurm " << n << "\n"
       << "# Submit with slurm/submit.sh (the array, then the merge that writes index.html once every shard is done).\n"
       << "#SBATCH --job-name=softgi-report\n"
       << "#SBATCH --array=0-" << n - 1 << "\n"
       << "#SBATCH --ntasks=1\n"
       << "#SBATCH --cpus-per-task=${SOFTGI_SLURM_CPUS:-4}\n"
       << "#SBATCH --output=" << shell_quote((fs::path(a.out) / "logs" / "slurm-%A_%a.out").string()) << "\n"
       << "set -euo pipefail\n"
       << shard_cmd << "\n";
    std::ostringstream sub;
    sub << "#!/bin/bash\n"
        << "# Submits the shards of slurm/report.sbatch, then `softgi report merge` once all have succeeded.\n"
        << "set -euo pipefail\n"
        << "here=\"$(cd \"$(dirname \"${BASH_SOURCE[0]}\")\" && pwd)\"\n"
        << "mkdir -p " << shell_quote((fs::path(a.out) / "logs").string()) << "\n"
        << "array=$(sbatch --parsable \"$here/report.sbatch\")\n"
        << "sbatch --dependency=afterok:\"$array\" --job-name=softgi-report-merge --output="
        << shell_quote((fs::path(a.out) / "logs" / "merge-%j.out").string()) << " --wrap="
        << shell_quote("softgi report merge --out " + shell_quote(a.out)) << "\n"
        << "echo \"submitted array $array and its merge\"\n";
    out.write_text("slurm/report.sbatch", sb.str());
    out.write_text("slurm/submit.sh", sub.str());
    fs::permissions(out.path("slurm/submit.sh"), fs::perms::owner_exec | fs::perms::group_exec | fs::perms::others_exec,
                    fs::perm_options::add);
    std::cerr << "report: wrote " << out.path("slurm/report.sbatch") << " (" << plan.size() << " jobs, " << n
              << " array tasks); submit with " << out.path("slurm/submit.sh") << "\n";
    return;
  }

  std::vector<report::Job> mine;
  for (std::size_t i = 0; i < plan.size(); ++i)
    if (static_cast<int>(i % shard.second) == shard.first) mine.push_back(plan[i]);
  std::cerr << "report: " << plan.size() << " jobs planned (" << s.scenes.size() << " scene(s), " << s.techniques.size()
            << " technique(s), " << s.backends.size() << " backend(s), " << s.budget.frame_times.size() << " frame(s)"
            << (s.static_scenes.empty() ? std::string()
                                        : ", one for each of " + std::to_string(s.static_scenes.size()) + " static scene(s)")
            << ")";
  if (shard.second > 1) std::cerr << "; shard " << shard.first << "/" << shard.second << " runs " << mine.size();
  std::cerr << "\n";

  report::Runner runner(s, a.out, concurrent_jobs);
  // Phase 1: the converged references of every scene and frame the jobs need, before the jobs, so
  // that processes running jobs side by side only read them. Nothing here is timed.
  {
    ProgressBar bar("report: references", !quiet);
    runner.prepare_references(mine, [&](int k, int n) {
      bar.update(static_cast<double>(k) / n, std::to_string(k) + "/" + std::to_string(n));
    });
  }
  if (a.references_only) {
    std::cerr << "report: the references are in " << a.out << "; the same command without --references-only measures the rest\n";
    return;
  }
  // Phase 2: the path tracer's equal-time curves. They are timed, so they run with the jobs, after
  // the long untimed phase.
  {
    ProgressBar bar("report: path tracer", !quiet);
    runner.prepare_curves(mine, [&](int k, int n) {
      bar.update(static_cast<double>(k) / n, std::to_string(k) + "/" + std::to_string(n) + " curves");
    });
  }
  // Phase 3: the jobs, resumed from those DIR holds finished.
  std::vector<report::Job> todo;
  for (const auto& j : mine)
    if (!runner.finished(j)) todo.push_back(j);
  if (todo.size() < mine.size())
    std::cerr << "report: resuming: " << mine.size() - todo.size() << " of " << mine.size() << " jobs already finished in "
              << a.out << "\n";
  int failures = 0;
  if (a.jobs > 1 && todo.size() > 1) {
    ProgressBar bar("report: jobs", !quiet);
    const int n = std::min<int>(a.jobs, static_cast<int>(todo.size()));
    // Only the jobs not seen finished yet are read again on each tick.
    std::vector<const report::Job*> pending;
    for (const auto& j : todo) pending.push_back(&j);
    run_processes(a, n, fs::path(a.out) / "logs", [&] {
      std::erase_if(pending, [&](const report::Job* j) { return runner.finished(*j); });
      const int k = static_cast<int>(todo.size() - pending.size());
      bar.update(static_cast<double>(k) / todo.size(), std::to_string(k) + "/" + std::to_string(todo.size()) + " jobs");
    });
    bar.update(1.0, std::to_string(todo.size()) + "/" + std::to_string(todo.size()) + " jobs");
  } else if (!todo.empty()) {
    ProgressBar bar("report: jobs", !quiet);
    for (std::size_t k = 0; k < todo.size(); ++k) {
      const Json r = runner.run(todo[k]);
      if (!r["error"].is_null()) {
        ++failures;
        std::cerr << "\nreport: " << todo[k].id << " FAILED: " << r["error"].get<std::string>() << "\n";
      }
      bar.update(static_cast<double>(k + 1) / todo.size(),
                 std::to_string(k + 1) + "/" + std::to_string(todo.size()) + " jobs, last " + todo[k].id);
    }
  }
  if (!a.no_page) {
    Json results = report::assemble_results(a.out, s, plan, command);
    results["settings"]["concurrent_jobs"] = a.jobs;
    const std::size_t missing = results["missing_jobs"].size();
    write_page(out, results);
    std::cerr << "report: wrote " << out.path("index.html") << ", results.json and results.csv (" << results["points"].size()
              << " points" << (missing ? ", " + std::to_string(missing) + " jobs not finished yet" : std::string()) << ")\n";
  }
  if (failures > 0) throw std::runtime_error("report: " + std::to_string(failures) + " job(s) failed (their errors are in the page)");
}

// Joins shards' directories into DIR (jobs, images, references) and writes the page.
void run_merge(const std::string& out_dir, const std::vector<std::string>& shard_dirs, const std::string& bench_json) {
  const std::string bench = read_bench_json(bench_json);
  register_builtin();
  std::optional<Json> plan;
  std::vector<fs::path> sources;
  for (const auto& d : shard_dirs) sources.emplace_back(d);
  sources.emplace_back(out_dir);  // DIR's own report.json when the shards wrote there
  for (const auto& d : sources) {
    const fs::path p = d / "report.json";
    if (!fs::exists(p)) {
      if (d != fs::path(out_dir)) throw std::invalid_argument("report merge: " + d.string() + " holds no report.json (not a report directory)");
      continue;
    }
    std::ifstream in(p);
    Json j;
    try {
      j = Json::parse(in);
    } catch (const std::exception& e) {
      throw std::invalid_argument("report merge: " + p.string() + " is not valid JSON: " + e.what());
    }
    if (!plan) {
      plan = j;
    } else if (j.value("settings_hash", "") != (*plan).value("settings_hash", "") || j["jobs"] != (*plan)["jobs"]) {
      throw std::invalid_argument("report merge: " + p.string() + " is a report of other settings or jobs than " +
                                  (sources.front() / "report.json").string());
    }
  }
  if (!plan) throw std::invalid_argument("report merge: no report.json in " + out_dir + " and no shard directory given");
  OutputDir out(out_dir, "--out", "results.json");
  out.write_json("report.json", *plan);
  if (!bench.empty()) out.write_text(report::kBenchFile, bench);
  for (const auto& d : shard_dirs) {
    std::error_code ec;
    if (fs::equivalent(d, out_dir, ec)) continue;
    for (const char* sub : {"jobs", "images", "references"}) {
      if (!fs::exists(fs::path(d) / sub)) continue;
      fs::create_directories(fs::path(out_dir) / sub);
      fs::copy(fs::path(d) / sub, fs::path(out_dir) / sub, fs::copy_options::recursive | fs::copy_options::overwrite_existing);
    }
  }
  const report::Settings s = settings_from_plan(*plan);
  const std::vector<report::Job> jobs = report::plan_jobs(s);
  Json results = report::assemble_results(out_dir, s, jobs, (*plan).value("command", ""));
  results["merged_from"] = shard_dirs;
  const std::size_t missing = results["missing_jobs"].size();
  write_page(out, results);
  std::cerr << "report merge: wrote " << out.path("index.html") << " (" << results["points"].size() << " points"
            << (missing ? ", " + std::to_string(missing) + " planned jobs missing" : std::string()) << ")\n";
}

void register_report(CLI::App& app) {
  auto a = std::make_shared<ReportArgs>();
  auto quiet = std::make_shared<bool>(false);
  auto concurrent = std::make_shared<int>(1);
  CLI::App* sub = app.add_subcommand("report",
                                     "Sweep every technique over its quality ladder on a set of scenes against a converged ground "
                                     "truth: DIR/index.html, results.json, results.csv (docs/reports.md)");
  sub->add_option("--scenes", a->scenes, "comma-separated scenes (built-in names or files), or all (default spheres)");
  sub->add_option("--techniques", a->techniques, "comma-separated techniques, or all (default)");
  sub->add_option("--backend", a->backends, "comma-separated backends (default: the reference backend); " + backends_help());
  sub->add_option("--device", a->device, "Vulkan device: index or name substring");
  sub->add_option("--out", a->out, "the report's directory");
  sub->add_option("--budget", a->budget, "quick (CI, a first look) or full (an evaluation); docs/reports.md lists both");
  sub->add_option("--width", a->width, "image width (default: the budget's)")->check(CLI::Range(8, 4096));
  sub->add_option("--height", a->height, "image height (default: the camera's aspect)")->check(CLI::Range(8, 4096));
  sub->add_option("--frames", a->frames, "comma-separated animation times in seconds (default: the budget's)");
  sub->add_option("--timed-frames", a->timed_frames, "frames whose median is a setting's time (default: the budget's)")
      ->check(CLI::Range(1, 1000));
  sub->add_option("--warmup-frames", a->warmup_frames, "untimed frames before them (default: the budget's)")->check(CLI::Range(0, 1000));
  sub->add_option("--rungs", a->rungs, "all or ends (the ladder's first and last) (default: the budget's)");
  sub->add_option("--target-noise", a->target_noise, "the reference's remaining noise as relMSE (default: the budget's)");
  sub->add_option("--max-spp", a->max_spp, "cap on the reference's samples per pixel (default: the budget's)")->check(CLI::Range(2, 1 << 20));
  sub->add_option("--pt-max-spp", a->pt_max_spp, "the path tracer's equal-time curve goes up to this (default: the budget's)")
      ->check(CLI::Range(1, 1 << 20));
  sub->add_option("--seed", a->seed, "the references' random seed (default 1)");
  sub->add_option("--fit-proxies", a->fit_proxies, "fit N proxy spheres to every closed mesh without any (scene files)")
      ->check(CLI::Range(0, 4096));
  sub->add_option("--jobs", a->jobs, "run the jobs in N processes (times then share the CPU; the page says so)");
  sub->add_option("--shard", a->shard, "run share I of N of the jobs (0 <= I < N), for a cluster; join with `report merge`");
  sub->add_option("--bench-json", a->bench_json,
                  "the comparative benchmark suite's results (bench_techniques --benchmark_out=F --benchmark_out_format=json), copied into DIR and shown on the page");
  sub->add_flag("--no-page", a->no_page, "write the jobs' results only (a shard; `report merge` writes the page)");
  sub->add_flag("--references-only", a->references_only,
                "render the untimed ground truth (converged references) and stop; a later run without it measures the "
                "timed part (path tracer's curves, jobs) on a quiet machine");
  sub->add_option("--emit-slurm", a->emit_slurm, "write DIR/slurm/report.sbatch (a job array of N shards) and submit.sh; renders nothing")
      ->check(CLI::Range(1, 100000));
  sub->add_flag("--quiet-progress", *quiet, "no progress bars (worker processes)")->group("");
  sub->add_option("--concurrent-jobs", *concurrent, "jobs running side by side (worker processes)")->group("");
  CLI::App* merge = sub->add_subcommand("merge", "join shard directories into one report: DIR's index.html from every shard's jobs");
  merge->add_option("--out", a->out, "the merged report's directory")->required();
  merge->add_option("shards", a->shard_dirs, "shard directories (none: DIR holds them already)");
  merge->add_option("--bench-json", a->bench_json, "bench_techniques' results (--benchmark_out_format=json) to show on the page");
  merge->callback([a] { run_merge(a->out, a->shard_dirs, a->bench_json); });
  sub->require_subcommand(0, 1);
  sub->callback([sub, a, quiet, concurrent] {
    if (sub->got_subcommand("merge")) return;
    if (a->out.empty()) throw std::invalid_argument("report: --out DIR is required");
    run_report(*a, *quiet, a->jobs > 1 ? a->jobs : *concurrent);
  });
}
const CommandRegistrar registrar(register_report);

}  // namespace

}  // namespace softgi::app
