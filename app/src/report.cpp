// The jobs of `softgi report` (report.hpp) and the results they assemble into (docs/reports.md).
#include "report.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <set>
#include <sstream>
#include <stdexcept>

#include <unistd.h>

#include "cached_reference.hpp"
#include "error_terms.hpp"
#include "softgi/io/image_io.hpp"
#include "softgi/io/reference_cache.hpp"
#include "softgi/metrics/flip.hpp"
#include "softgi/metrics/image_metrics.hpp"
#include "softgi/metrics/reference_noise.hpp"
#include "softgi/reference/converge.hpp"
#include "softgi/render/camera.hpp"
#include "softgi/render/gbuffer.hpp"
#include "softgi/render/technique.hpp"

namespace fs = std::filesystem;

namespace softgi::app::report {

namespace {

// Successive frames of the timed run are this far apart in animation time (a 30 Hz animation), so
// that every timed frame pays the per-frame updates (refits) of a running animation.
constexpr double kFrameStep = 1.0 / 30.0;
// The path tracer's equal-time curve draws its samples from a seed of its own, independent of the
// reference's two halves (seed and half_b_seed(seed)), so that its noise counts as its error.
constexpr unsigned kPathTracerSeedOffset = 0x2545F491u;
// Bumped when what a job measures changes, so that resumed runs do not mix old and new results.
constexpr int kJobVersion = 2;
// Key prefix of the references with the proxy spheres alone as blockers (+ the SH order).
const std::string kProxiesOnlyKey = "proxies_only_sh";

const double kEpsilon = metrics::MetricOptions{}.relmse_epsilon;

// The seed of reference `key`. The error budget compares references with each other, and the noise
// correction of two noisy images holds for independent noise: with one seed they would draw the same
// samples, their noise would largely cancel in the difference and the correction would remove noise
// that is not there (negative errors). "full" keeps the user's seed (softgi reference --seed).
unsigned reference_seed(unsigned seed, const std::string& key) {
  if (key == "full") return seed;
  std::uint32_t h = 2166136261u;  // FNV-1a
  for (unsigned char c : key) h = (h ^ c) * 16777619u;
  return seed ^ (h | 1u);
}

std::string fmt_time(double t) {
  std::ostringstream os;
  os << std::setprecision(6) << t;
  return os.str();
}

Json number_or_null(double v) { return std::isfinite(v) ? Json(v) : Json(nullptr); }

double median(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

std::string read_text(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + p.string());
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// A temporary beside `p` that no other process writing the same file (shards sharing DIR) uses.
fs::path temporary_for(const fs::path& p) {
  return p.parent_path() / (p.stem().string() + ".tmp" + std::to_string(::getpid()) + p.extension().string());
}

// Writes through a temporary and a rename: a reader never sees half a file.
void write_text_atomic(const fs::path& p, const std::string& text) {
  fs::create_directories(p.parent_path());
  const fs::path tmp = temporary_for(p);
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out << text;
    if (!out.flush()) {
      std::error_code ec;
      fs::remove(tmp, ec);
      throw std::runtime_error("cannot write " + p.string());
    }
  }
  fs::rename(tmp, p);
}
void write_json_atomic(const fs::path& p, const Json& j) { write_text_atomic(p, j.dump(2) + "\n"); }
// An image file through a temporary of this process (io's writers choose the format by the extension).
template <class Write>
void write_image_atomic(const fs::path& p, Write&& write) {
  fs::create_directories(p.parent_path());
  const fs::path tmp = temporary_for(p);
  try {
    write(tmp.string());
  } catch (...) {
    std::error_code ec;
    fs::remove(tmp, ec);
    throw;
  }
  fs::rename(tmp, p);
}
void write_exr_atomic(const fs::path& p, const Image& img) {
  write_image_atomic(p, [&](const std::string& t) { io::write_exr(t, img); });
}
void write_png_atomic(const fs::path& p, const Image& img) {
  write_image_atomic(p, [&](const std::string& t) { io::write_png(t, img); });
}

std::optional<Json> read_json_if_complete(const fs::path& p) {
  std::error_code ec;
  if (!fs::exists(p, ec)) return std::nullopt;
  try {
    return Json::parse(read_text(p));
  } catch (const std::exception&) {
    return std::nullopt;  // an unreadable result is measured again
  }
}

// The three components of a reference as stored in the report: each half and their mean.
struct RefImages {
  Image a[3], b[3];  // final, direct, indirect
  Json meta;
};
const char* const kComponents[3] = {"final", "direct", "indirect"};

}  // namespace

// --- Settings and plan ---------------------------------------------------------------------------

Budget budget_named(const std::string& name) {
  Budget b;
  b.name = name;
  if (name == "quick") {
    // CI and a first look: small images, the ladder's two ends, one frame, a loose ground truth.
    b.width = 64;
    b.frame_times = {0.0};
    b.timed_frames = 3;
    b.warmup_frames = 1;
    b.target_noise = 2e-3;
    b.min_spp = 16;
    b.max_spp = 256;
    b.pt_max_spp = 64;
    b.every_rung = false;
  } else if (name == "full") {
    // An evaluation section: every rung at three animation times, nine timed frames, a ground truth
    // that resolves errors down to 1e-3 (its noise a tenth of that).
    b.width = 256;
    b.frame_times = {0.0, 0.5, 1.0};
    b.timed_frames = 9;
    b.warmup_frames = 2;
    b.target_noise = 1e-4;
    b.min_spp = 64;
    b.max_spp = 4096;
    b.pt_max_spp = 1024;
    b.every_rung = true;
  } else {
    throw std::invalid_argument("--budget '" + name + "': expected quick or full");
  }
  return b;
}

Json settings_json(const Settings& s) {
  const Budget& b = s.budget;
  return {{"scenes", s.scenes},
          {"techniques", s.techniques},
          {"backends", s.backends},
          {"budget", b.name},
          {"width", b.width},
          {"height", b.height},
          {"frame_times", b.frame_times},
          {"timed_frames", b.timed_frames},
          {"warmup_frames", b.warmup_frames},
          {"target_noise", b.target_noise},
          {"min_spp", b.min_spp},
          {"max_spp", b.max_spp},
          {"pt_max_spp", b.pt_max_spp},
          {"every_rung", b.every_rung},
          {"seed", s.seed},
          {"fit_proxies", s.fit_proxies},
          {"device", s.device},
          {"static_scenes", s.static_scenes}};
}

std::string settings_hash(const Settings& s) {
  Json j = settings_json(s);
  j["job_version"] = kJobVersion;
  j["softgi_version"] = softgi_version();
  // Which scenes, techniques and backends a run covers does not change a job's result.
  j.erase("scenes");
  j.erase("techniques");
  j.erase("backends");
  j.erase("static_scenes");
  return io::reference_cache_key(0, j.dump());
}

std::string scene_label(const std::string& spec) {
  std::string stem = fs::path(spec).filename().string();
  std::string out;
  for (char c : stem) out += (std::isalnum(static_cast<unsigned char>(c)) || c == '-') ? c : '_';
  return out.empty() ? "scene" : out;
}

std::string frame_label(double t) { return fmt_time(t).insert(0, 1, 't'); }

std::vector<double> frame_times_of(const Settings& s, const std::string& spec) {
  const auto& st = s.static_scenes;
  if (s.budget.frame_times.empty() || std::find(st.begin(), st.end(), spec) == st.end()) return s.budget.frame_times;
  return {s.budget.frame_times.front()};
}

std::vector<Job> plan_jobs(const Settings& s) {
  std::vector<Job> jobs;
  std::set<std::string> labels;
  for (const auto& spec : s.scenes) {
    const std::string label = scene_label(spec);
    if (!labels.insert(label).second)
      throw std::invalid_argument("--scenes: two scenes share the name '" + label + "' (" + spec + ")");
    for (double t : frame_times_of(s, spec))
      for (const auto& tech : s.techniques) {
        const auto technique = render::create_technique(tech);
        const auto ladder = render::default_params(*technique).ladder();
        std::vector<int> rungs;
        for (int k = 0; k < static_cast<int>(ladder.size()); ++k)
          if (s.budget.every_rung || k == 0 || k + 1 == static_cast<int>(ladder.size())) rungs.push_back(k);
        for (const auto& backend : s.backends)
          for (int k : rungs) {
            Job j;
            j.scene = spec;
            j.scene_label = label;
            j.technique = tech;
            j.backend = backend;
            j.rung = k;
            j.rungs = static_cast<int>(ladder.size());
            j.frame_time = t;
            j.assignments = ladder[k];
            j.id = label + "." + tech + "." + backend + ".r" + std::to_string(k) + "." + frame_label(t);
            jobs.push_back(std::move(j));
          }
      }
  }
  return jobs;
}

// --- Runner --------------------------------------------------------------------------------------

struct Runner::Impl {
  Settings settings;
  fs::path dir;
  int concurrent_jobs = 1;
  std::string hash;
  std::map<std::string, scene::Scene> scenes;  // by spec
  std::map<std::string, std::unique_ptr<render::Backend>> backends;
  std::map<std::string, Mask> surfaces;  // by "<scene label>/<frame label>"
  std::map<std::string, RefImages> refs;  // by "<scene label>/<frame label>/<key>"

  const scene::Scene& scene(const std::string& spec) {
    auto it = scenes.find(spec);
    if (it == scenes.end()) it = scenes.emplace(spec, load_cli_scene("report", spec, settings.fit_proxies)).first;
    return it->second;
  }
  render::Backend& backend(const std::string& name) {
    auto it = backends.find(name);
    if (it == backends.end())
      it = backends.emplace(name, make_backend(name, render::backend_info(name).selects_device ? settings.device : "", "report")).first;
    return *it->second;
  }
  void size_of(const scene::Scene& sc, int& w, int& h) const {
    w = settings.budget.width;
    h = settings.budget.height;
    render::resolve_resolution(sc.camera, w, h);
  }
  fs::path frame_dir(const std::string& label, double t) const { return dir / "references" / label / frame_label(t); }

  // The pixels errors are measured over: those the shared G-buffer sees a surface in.
  const Mask& surface(const std::string& spec, double t) {
    const std::string key = scene_label(spec) + "/" + frame_label(t);
    auto it = surfaces.find(key);
    if (it != surfaces.end()) return it->second;
    const scene::Scene& sc = scene(spec);
    int w = 0, h = 0;
    size_of(sc, w, h);
    std::unique_ptr<render::Backend> cpu = render::create_backend(render::reference_backend_name());
    render::RenderRequest req;
    req.time = t;
    req.width = w;
    req.height = h;
    const render::GBufferFrame g = render::render_gbuffer(*cpu, sc, req);
    Mask m{w, h, std::vector<std::uint8_t>(g.gbuffer.object.size(), 0)};
    long long pixels = 0;
    for (std::size_t i = 0; i < m.on.size(); ++i) pixels += (m.on[i] = g.gbuffer.hit(i) ? 1 : 0);
    if (pixels == 0) throw std::runtime_error("report: scene '" + sc.name + "' shows no surface from its camera at t = " + fmt_time(t));
    const fs::path scene_json = dir / "references" / scene_label(spec) / "scene.json";
    if (!fs::exists(scene_json))
      write_json_atomic(scene_json, {{"name", scene_label(spec)}, {"spec", spec}, {"title", sc.name}, {"resolution", {w, h}},
                                     {"surface_pixels", pixels}, {"has_proxies", !sc.proxies.empty()},
                                     {"static", scene::is_static(sc)}});
    return surfaces.emplace(key, std::move(m)).first->second;
  }

  // Reference `key` of a scene and frame: "full", "sh<n>" or "proxies_only_sh<n>", converged (two
  // halves) and kept in DIR; read back when DIR has it.
  const RefImages& reference(const std::string& spec, double t, const std::string& key) {
    const std::string label = scene_label(spec);
    const std::string mkey = label + "/" + frame_label(t) + "/" + key;
    auto it = refs.find(mkey);
    if (it != refs.end()) return it->second;
    const fs::path rdir = frame_dir(label, t) / key;
    RefImages r;
    if (auto meta = read_json_if_complete(rdir / "meta.json"); meta && (*meta).value("settings_hash", "") == hash) {
      r.meta = *meta;
      for (int c = 0; c < 3; ++c) {
        r.a[c] = io::read_image((rdir / (std::string("a_") + kComponents[c] + ".exr")).string());
        r.b[c] = io::read_image((rdir / (std::string("b_") + kComponents[c] + ".exr")).string());
      }
      return refs.emplace(mkey, std::move(r)).first->second;
    }
    const scene::Scene& sc = scene(spec);
    int w = 0, h = 0;
    size_of(sc, w, h);
    reference::ReferenceOptions opt;
    opt.blockers = key.rfind(kProxiesOnlyKey, 0) == 0 ? reference::ReferenceOptions::Blockers::ProxiesOnly
                                                      : reference::ReferenceOptions::Blockers::Geometry;
    const std::size_t sh = key.find("sh");
    opt.light_sh_order = sh == std::string::npos ? 0 : std::stoi(key.substr(sh + 2));
    opt.indirect = true;
    opt.time = t;
    opt.seed = reference_seed(settings.seed, key);
    opt.width = w;
    opt.height = h;
    opt.jitter = false;  // each pixel at its centre: the visibility of the techniques' one-sample G-buffer
    reference::ConvergeOptions co;
    co.target_noise = settings.budget.target_noise;
    co.min_spp = settings.budget.min_spp;
    co.max_spp = settings.budget.max_spp;
    co.relmse_epsilon = kEpsilon;
    co.mask = surface(spec, t);  // the noise where the errors are measured
    bool cached = false;
    const reference::ConvergedReference c = cached_converged_reference(sc, opt, co, {}, cached);
    const Image* ha[3] = {&c.half_a.final_image, &c.half_a.direct, &c.half_a.indirect};
    const Image* hb[3] = {&c.half_b.final_image, &c.half_b.direct, &c.half_b.indirect};
    for (int comp = 0; comp < 3; ++comp) {
      r.a[comp] = *ha[comp];
      r.b[comp] = *hb[comp];
      write_exr_atomic(rdir / (std::string("a_") + kComponents[comp] + ".exr"), r.a[comp]);
      write_exr_atomic(rdir / (std::string("b_") + kComponents[comp] + ".exr"), r.b[comp]);
    }
    write_png_atomic(rdir / "final.png", c.result.final_image);
    const std::string label_text = key == "full" ? std::string("real geometry, full environment")
                             : opt.blockers == reference::ReferenceOptions::Blockers::ProxiesOnly
                                 ? "proxy spheres alone as blockers, order-" + std::to_string(opt.light_sh_order) + " SH light"
                                 : "real geometry, order-" + std::to_string(opt.light_sh_order) + " SH light";
    r.meta = {{"key", key},
              {"label", label_text},
              {"frame_time", t},
              {"spp", c.result.spp},
              {"noise", c.noise},
              {"converged", c.converged},
              {"target_noise", co.target_noise},
              {"seconds", c.result.seconds},
              {"cached", cached},
              {"image", (fs::path("references") / label / frame_label(t) / key / "final.png").generic_string()},
              {"settings_hash", hash}};
    write_json_atomic(rdir / "meta.json", r.meta);  // last: its presence says the entry is complete
    if (!c.converged)
      std::cerr << "report: warning: reference '" << key << "' of " << label << " at t = " << fmt_time(t)
                << " stopped at the cap of " << co.max_spp << " spp with noise " << c.noise << " above the target "
                << co.target_noise << "\n";
    return refs.emplace(mkey, std::move(r)).first->second;
  }

  // The path tracer's error against the full reference after 1, 2, 4, ... samples per pixel, with
  // the time it took to get there (BVH builds and environment tables left out: an interactive path
  // tracer keeps them from frame to frame, as the techniques keep theirs).
  Json path_tracer_curve(const std::string& spec, double t) {
    const std::string label = scene_label(spec);
    const fs::path p = frame_dir(label, t) / "path_tracer.json";
    if (auto j = read_json_if_complete(p); j && (*j).value("settings_hash", "") == hash) return *j;
    const RefImages& full = reference(spec, t, "full");
    const Mask& surf = surface(spec, t);
    const scene::Scene& sc = scene(spec);
    reference::ReferenceOptions opt;
    opt.spp = settings.budget.pt_max_spp;
    opt.indirect = true;
    opt.time = t;
    opt.seed = settings.seed + kPathTracerSeedOffset;
    opt.width = surf.width;
    opt.height = surf.height;
    opt.jitter = false;
    Json curve = Json::array();
    std::vector<std::pair<int, double>> stamps;
    std::vector<metrics::NoiseCorrectedError> errs;
    // Measuring each step's error happens inside the render's timed span: its cost is kept apart and
    // taken out of the later stamps.
    double measuring = 0.0;
    const auto start = std::chrono::steady_clock::now();
    auto since = [](std::chrono::steady_clock::time_point a) {
      return std::chrono::duration<double>(std::chrono::steady_clock::now() - a).count();
    };
    const reference::ReferenceResult r = reference::render_reference(sc, opt, {}, [&](int spp, const reference::ReferenceResult& running) {
      const auto enter = std::chrono::steady_clock::now();
      stamps.emplace_back(spp, since(start) - measuring);
      errs.push_back(metrics::noise_corrected_relmse(running.final_image, full.a[0], full.b[0], surf, kEpsilon));
      measuring += since(enter);
    });
    for (std::size_t i = 0; i < stamps.size(); ++i) {
      const double sampling = stamps[i].second - r.setup_seconds;
      curve.push_back({{"spp", stamps[i].first},
                       {"seconds", std::max(sampling, 0.0)},
                       {"relmse", errs[i].corrected},
                       {"ci_low", errs[i].ci_low},
                       {"ci_high", errs[i].ci_high}});
    }
    Json j = {{"frame_time", t}, {"setup_seconds", r.setup_seconds}, {"curve", curve}, {"settings_hash", hash}};
    write_json_atomic(p, j);
    return j;
  }

  Json run(const Job& job);
};

Runner::Runner(Settings settings, std::string dir, int concurrent_jobs) : impl_(std::make_unique<Impl>()) {
  impl_->settings = std::move(settings);
  impl_->dir = dir;
  impl_->concurrent_jobs = concurrent_jobs;
  impl_->hash = settings_hash(impl_->settings);
}
Runner::~Runner() = default;

namespace {
// (scene, frame) -> the reference keys its jobs need.
std::map<std::pair<std::string, double>, std::set<std::string>> references_needed(const std::vector<Job>& jobs) {
  std::map<std::pair<std::string, double>, std::set<std::string>> need;
  for (const auto& j : jobs) {
    const auto t = render::create_technique(j.technique);
    render::ParamSet p = render::default_params(*t);
    for (const auto& [n, v] : j.assignments) p.set(n, v);
    auto& keys = need[{j.scene, j.frame_time}];
    const std::string n = std::to_string(sh_order_of(p));
    keys.insert("full");
    keys.insert("sh" + n);
    if (t->shadow_blockers() == render::ShadowBlockers::SphereProxies) keys.insert(kProxiesOnlyKey + n);
  }
  return need;
}
}  // namespace

void Runner::prepare_references(const std::vector<Job>& jobs, const std::function<void(int, int)>& done) {
  const auto need = references_needed(jobs);
  int total = 0, k = 0;
  for (const auto& [sf, keys] : need) total += static_cast<int>(keys.size());
  for (const auto& [sf, keys] : need) {
    impl_->surface(sf.first, sf.second);
    for (const auto& key : keys) {
      impl_->reference(sf.first, sf.second, key);
      if (done) done(++k, total);
    }
  }
}

void Runner::prepare_curves(const std::vector<Job>& jobs, const std::function<void(int, int)>& done) {
  const auto need = references_needed(jobs);
  int k = 0;
  for (const auto& [sf, keys] : need) {
    impl_->path_tracer_curve(sf.first, sf.second);
    if (done) done(++k, static_cast<int>(need.size()));
  }
}

bool Runner::finished(const Job& job) const {
  auto j = read_json_if_complete(impl_->dir / "jobs" / (job.id + ".json"));
  return j && (*j).value("settings_hash", "") == impl_->hash;
}

Json Runner::run(const Job& job) { return impl_->run(job); }

Json Runner::Impl::run(const Job& job) {
  const Budget& b = settings.budget;
  Json p = {{"id", job.id},          {"scene", job.scene_label}, {"technique", job.technique}, {"backend", job.backend},
            {"rung", job.rung},      {"rungs", job.rungs},       {"frame_time", job.frame_time}, {"settings_hash", hash}};
  try {
    const scene::Scene& sc = scene(job.scene);
    const Mask& surf = surface(job.scene, job.frame_time);
    const auto technique = render::create_technique(job.technique);
    render::ParamSet params = render::default_params(*technique);
    const render::ParamSet defaults = params;
    for (const auto& [n, v] : job.assignments) params.set(n, v);
    Json all = Json::object(), changed = Json::object();
    std::string command = "softgi render --scene " + shell_quote(job.scene) + " --technique " + job.technique + " --backend " + job.backend +
                          " --frame " + fmt_time(job.frame_time) + " --width " + std::to_string(surf.width) + " --height " +
                          std::to_string(surf.height);
    for (const auto& [n, v] : params.values()) {
      all[n] = v;
      if (defaults.get_text(n) != v) {
        changed[n] = v;
        command += " --param " + shell_quote(n + "=" + v);
      }
    }
    command += " --out OUT";
    p["params"] = all;
    p["non_default"] = changed;
    p["command"] = command;

    render::Backend& be = backend(job.backend);
    render::RenderRequest req;
    req.width = surf.width;
    req.height = surf.height;
    req.outputs = {"final"};  // the direct and indirect images come with it
    // Warm-up frames, then the timed frames of a 30 Hz animation ending at the job's time; the last
    // one is the image measured.
    const int n_frames = b.warmup_frames + b.timed_frames;
    std::vector<double> totals;
    std::map<std::string, std::vector<double>> per_pass;
    std::vector<std::string> pass_order;
    render::FrameResult last;
    for (int f = 0; f < n_frames; ++f) {
      req.time = job.frame_time - (n_frames - 1 - f) * kFrameStep;
      render::FrameResult r = be.render(*technique, sc, params, req);
      if (f < b.warmup_frames) {
        be.recycle(std::move(r));  // the timed frames reuse its buffers, as a sequence would
        continue;
      }
      totals.push_back(r.total_seconds);
      for (const auto& pr : r.passes) {
        if (!per_pass.count(pr.name)) pass_order.push_back(pr.name);
        per_pass[pr.name].push_back(pr.wall_seconds);
      }
      if (f + 1 == n_frames)
        last = std::move(r);
      else
        be.recycle(std::move(r));
    }
    p["seconds"] = median(totals);
    p["seconds_min"] = *std::min_element(totals.begin(), totals.end());
    p["seconds_max"] = *std::max_element(totals.begin(), totals.end());
    p["frames"] = b.timed_frames;
    Json passes = Json::array();
    for (const auto& n : pass_order) passes.push_back({{"name", n}, {"seconds", median(per_pass[n])}});
    p["passes"] = passes;
    p["warnings"] = last.warnings;

    // Errors per component against the full reference.
    const int order = sh_order_of(params);
    const RefImages& full = reference(job.scene, job.frame_time, "full");
    const Image* test[3] = {&last.final_image, &last.direct, &last.indirect};
    metrics::FlipResult flip_final;
    Json errors = Json::object();
    for (int c = 0; c < 3; ++c)
      errors[kComponents[c]] = noise_corrected_errors(*test[c], full.a[c], full.b[c], surf, c == 0 ? &flip_final : nullptr);
    p["errors"] = errors;

    // The error budget: each source on its own (docs/reports.md, "Error budget"), with the 95 %
    // interval of each noise-corrected entry beside it.
    const RefImages& shn = reference(job.scene, job.frame_time, "sh" + std::to_string(order));
    Json budget = Json::object(), budget_ci = Json::object();
    auto entry = [&](const char* name, const metrics::NoiseCorrectedError& e) {
      budget[name] = e.corrected;
      budget_ci[name] = {e.ci_low, e.ci_high};
    };
    entry("sh_truncation", metrics::noise_corrected_relmse_between(shn.a[0], shn.b[0], full.a[0], full.b[0], surf, kEpsilon));
    // The same problem as the technique's: its own blockers. For sphere-proxy techniques those are
    // the proxy spheres alone (an object without proxies, a wall, shadows nothing for them, so it
    // counts as proxy geometry, not as the technique's approximation); techniques that shadow with
    // the scene's geometry, or proxies sampled from all of it, have no proxy-geometry entry.
    const RefImages* matching = &shn;
    if (technique->shadow_blockers() == render::ShadowBlockers::SphereProxies) {
      const RefImages& prox = reference(job.scene, job.frame_time, kProxiesOnlyKey + std::to_string(order));
      entry("proxy_geometry", metrics::noise_corrected_relmse_between(prox.a[0], prox.b[0], shn.a[0], shn.b[0], surf, kEpsilon));
      matching = &prox;
    } else {
      budget["proxy_geometry"] = nullptr;
    }
    entry("approximation", metrics::noise_corrected_relmse(last.final_image, matching->a[0], matching->b[0], surf, kEpsilon));
    budget["resolution"] = nullptr;
    if (params.has("receiver_scale") && params.get_int("receiver_scale") != 1) {
      // Both images are the technique's (deterministic): a plain relMSE, no noise to remove.
      render::ParamSet fine = params;
      fine.set("receiver_scale", "1");
      req.time = job.frame_time;
      const render::FrameResult r = be.render(*technique, sc, fine, req);
      budget["resolution"] = metrics::compare(last.final_image, r.final_image, surf).relmse;
    }
    budget["total"] = errors["final"]["relmse"];
    p["budget"] = budget;
    p["budget_ci"] = budget_ci;

    // Images: the final image, its FLIP map against the reference, the components.
    const fs::path idir = dir / "images" / job.id;
    fs::create_directories(idir);
    Json images = {{"final", (fs::path("images") / job.id / "final.png").generic_string()},
                   {"reference", full.meta.value("image", "")}};
    write_png_atomic(idir / "final.png", last.final_image);
    write_exr_atomic(idir / "final.exr", last.final_image);
    if (!flip_final.error.empty()) {
      const Image map = metrics::flip_error_map(flip_final);
      write_image_atomic(idir / "flip_final.png", [&](const std::string& t) { io::write_png_display(t, map); });
      images["flip_map"] = (fs::path("images") / job.id / "flip_final.png").generic_string();
    }
    for (int c = 1; c < 3; ++c)
      if (!test[c]->empty()) {
        write_png_atomic(idir / (std::string(kComponents[c]) + ".png"), *test[c]);
        images[kComponents[c]] = (fs::path("images") / job.id / (std::string(kComponents[c]) + ".png")).generic_string();
      }
    p["images"] = images;
    p["error"] = nullptr;
  } catch (const std::exception& e) {
    p["error"] = e.what();
  }
  p["concurrent_jobs"] = concurrent_jobs;
  write_json_atomic(dir / "jobs" / (job.id + ".json"), p);
  return p;
}

// --- Assembly ------------------------------------------------------------------------------------

namespace {

// log-log interpolation of a decreasing curve: the value at x, NaN outside it.
double curve_at(const Json& curve, double x, const char* xs, const char* ys) {
  for (std::size_t i = 1; i < curve.size(); ++i) {
    const double x0 = curve[i - 1][xs], x1 = curve[i][xs];
    const double y0 = curve[i - 1][ys], y1 = curve[i][ys];
    const bool inside = (x0 <= x && x <= x1) || (x1 <= x && x <= x0);
    if (!inside) continue;
    if (x0 > 0 && x1 > 0 && y0 > 0 && y1 > 0 && x0 != x1) {
      const double f = std::log(x / x0) / std::log(x1 / x0);
      return std::exp(std::log(y0) + f * (std::log(y1) - std::log(y0)));
    }
    return x1 == x0 ? y0 : y0 + (x - x0) / (x1 - x0) * (y1 - y0);
  }
  if (!curve.empty() && curve.back()[xs].get<double>() == x) return curve.back()[ys];
  return std::nan("");
}

// The equal-time comparison of a point (seconds, relMSE e) with the path tracer's curve. Inside the
// curve: log-log interpolation. Beyond its end: the path tracer is the reference's own unbiased
// estimator, so its expected noise-corrected relMSE is c / N at N samples per pixel (the variance
// over the samples), c = N e at the curve's last point; and N samples take the last point's time
// plus the marginal time per sample of its last step (a fixed cost per pass makes time not quite
// proportional to N at a few samples). Such values are flagged as extrapolated. Faster than the
// first point (one sample per pixel) there is no path-tracer image.
Json equal_time(const Json& curve, double s, double e) {
  double at_time = curve_at(curve, s, "seconds", "relmse");
  double to_match = std::nan("");
  for (std::size_t i = 1; i < curve.size() && !std::isfinite(to_match); ++i) {
    const double y0 = curve[i - 1]["relmse"], y1 = curve[i]["relmse"];
    if ((y0 >= e && e >= y1)) {
      Json seg = Json::array({curve[i - 1], curve[i]});
      to_match = curve_at(seg, e, "relmse", "seconds");
    }
  }
  if (!std::isfinite(to_match) && curve.front()["relmse"].get<double>() <= e) to_match = curve.front()["seconds"];
  const Json& last = curve.back();
  const double t_last = last["seconds"], e_last = last["relmse"], n_last = last["spp"];
  bool at_time_extrapolated = false, to_match_extrapolated = false;
  if (curve.size() >= 2 && e_last > 0.0) {
    const Json& prev = curve[curve.size() - 2];
    const double dn = n_last - prev["spp"].get<double>(), dt = t_last - prev["seconds"].get<double>();
    const double per_sample = dn > 0.0 && dt > 0.0 ? dt / dn : std::nan("");
    const double c = n_last * e_last;
    if (std::isfinite(per_sample)) {
      if (!std::isfinite(at_time) && s > t_last) {
        at_time = c / (n_last + (s - t_last) / per_sample);
        at_time_extrapolated = true;
      }
      if (!std::isfinite(to_match) && e < e_last && e > 0.0) {
        to_match = t_last + (c / e - n_last) * per_sample;
        to_match_extrapolated = true;
      }
    }
  }
  return {{"pt_relmse_at_same_time", number_or_null(at_time)},
          {"pt_seconds_to_match", number_or_null(to_match)},
          {"pt_max_seconds", t_last},
          {"extrapolated", {{"pt_relmse_at_same_time", at_time_extrapolated}, {"pt_seconds_to_match", to_match_extrapolated}}}};
}

}  // namespace

Json assemble_results(const std::string& dir_text, const Settings& settings, const std::vector<Job>& plan,
                      const std::string& command) {
  const fs::path dir = dir_text;
  const std::string hash = settings_hash(settings);
  Json points = Json::array();
  Json missing = Json::array();
  for (const auto& job : plan) {
    auto j = read_json_if_complete(dir / "jobs" / (job.id + ".json"));
    if (!j || (*j).value("settings_hash", "") != hash) {
      missing.push_back(job.id);
      continue;
    }
    points.push_back(*j);
  }
  Json scenes = Json::array();
  std::set<std::string> seen;
  for (const auto& job : plan) {
    if (!seen.insert(job.scene_label).second) continue;
    const fs::path sdir = dir / "references" / job.scene_label;
    Json s = read_json_if_complete(sdir / "scene.json").value_or(Json{{"name", job.scene_label}, {"spec", job.scene}});
    Json refs = Json::array(), pts = Json::array();
    for (double t : frame_times_of(settings, job.scene)) {
      const fs::path fdir = sdir / frame_label(t);
      std::error_code ec;
      std::vector<fs::path> keys;
      for (const auto& e : fs::directory_iterator(fdir, ec))
        if (e.is_directory()) keys.push_back(e.path());
      std::sort(keys.begin(), keys.end());
      for (const auto& k : keys)
        if (auto m = read_json_if_complete(k / "meta.json"); m && (*m).value("settings_hash", "") == hash) {
          m->erase("settings_hash");
          refs.push_back(*m);
        }
      if (auto c = read_json_if_complete(fdir / "path_tracer.json"); c && (*c).value("settings_hash", "") == hash) {
        c->erase("settings_hash");
        pts.push_back(*c);
      }
    }
    s["references"] = refs;
    s["path_tracer"] = pts;
    scenes.push_back(s);
  }

  // The Pareto front per scene and frame, and the equal-time comparison with the path tracer.
  auto good = [](const Json& p) { return p["error"].is_null() && p["seconds"].is_number() && p["errors"]["final"].is_object(); };
  for (auto& p : points) {
    p["pareto"] = false;
    p["equal_time"] = nullptr;
    if (!good(p)) continue;
    const double s = p["seconds"], e = p["errors"]["final"]["relmse"];
    bool dominated = false;
    for (const auto& q : points) {
      if (&q == &p || !good(q) || q["scene"] != p["scene"] || q["frame_time"] != p["frame_time"]) continue;
      const double qs = q["seconds"], qe = q["errors"]["final"]["relmse"];
      if (qs <= s && qe <= e && (qs < s || qe < e)) dominated = true;
    }
    p["pareto"] = !dominated;
    for (const auto& sc : scenes) {
      if (sc["name"] != p["scene"]) continue;
      for (const auto& pt : sc["path_tracer"]) {
        if (pt["frame_time"] != p["frame_time"]) continue;
        const Json& curve = pt["curve"];
        if (curve.empty()) continue;
        p["equal_time"] = equal_time(curve, s, e);
      }
    }
  }
  for (auto& p : points) p.erase("settings_hash");
  Json sj = settings_json(settings);
  Json out = {{"softgi_version", softgi_version()}, {"date", utc_now()},  {"command", command},   {"budget", settings.budget.name},
              {"settings", sj},                      {"scenes", scenes},   {"points", points},     {"missing_jobs", missing},
              {"planned_jobs", plan.size()}};
  if (fs::exists(dir / kBenchFile)) out["bench"] = bench_results((dir / kBenchFile).string());
  return out;
}

Json bench_results(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("--bench-json '" + path + "': cannot read");
  Json j;
  try {
    j = Json::parse(in);
  } catch (const Json::parse_error& e) {
    throw std::runtime_error("--bench-json '" + path + "': not JSON: " + e.what());
  }
  if (!j.is_object() || !j.contains("benchmarks") || !j["benchmarks"].is_array())
    throw std::runtime_error("--bench-json '" + path + "': no \"benchmarks\" array (write it with bench_techniques --benchmark_out=F --benchmark_out_format=json)");
  const double to_ms_of[] = {1e-6, 1e-3, 1.0, 1e3};  // ns, us, ms, s
  auto to_ms = [&](const Json& b) {
    const std::string u = b.value("time_unit", "ns");
    const int k = u == "ns" ? 0 : u == "us" ? 1 : u == "ms" ? 2 : u == "s" ? 3 : -1;
    if (k < 0) throw std::runtime_error("--bench-json '" + path + "': unknown time_unit '" + u + "'");
    return b.value("real_time", std::nan("")) * to_ms_of[k];
  };
  // BM_Technique/<scene>/<backend>/<technique>[/iterations:N][/manual_time][_median|...]
  struct Row {
    Json row;
    bool from_median = false;
  };
  std::map<std::string, Row> rows;
  std::vector<std::string> order;
  for (const Json& b : j["benchmarks"]) {
    const std::string name = b.value("run_name", b.value("name", ""));
    if (name.rfind("BM_Technique/", 0) != 0) continue;
    const std::vector<std::string> parts = [&] {
      std::vector<std::string> out;
      std::stringstream ss(name);
      for (std::string item; std::getline(ss, item, '/');) out.push_back(item);
      return out;
    }();
    if (parts.size() < 4) throw std::runtime_error("--bench-json '" + path + "': benchmark name '" + name + "' is not BM_Technique/scene/backend/technique");
    const std::string key = parts[1] + "/" + parts[2] + "/" + parts[3];
    const bool aggregate = b.value("run_type", "iteration") == "aggregate";
    if (aggregate && b.value("aggregate_name", "") != "median") continue;
    auto it = rows.find(key);
    if (it != rows.end() && (it->second.from_median || !aggregate)) continue;  // one row: the median, else the first run
    if (it == rows.end()) order.push_back(key);
    Json r = {{"scene", parts[1]}, {"backend", parts[2]}, {"technique", parts[3]}};
    if (b.value("error_occurred", false)) {
      r["error"] = b.value("error_message", "failed");
      r["ms"] = nullptr;
    } else {
      r["error"] = nullptr;
      r["ms"] = number_or_null(to_ms(b));
      r["repetitions"] = b.value("repetitions", 1);
      Json passes = Json::object();
      for (const auto& [k, v] : b.items())
        if (k.rfind("ms:", 0) == 0 && v.is_number()) passes[k.substr(3)] = v;
      r["passes"] = passes;
      for (const char* c : {"upload_MB", "download_MB", "pruned_passes"})
        if (b.contains(c)) r[c] = b[c];
    }
    rows[key] = {r, aggregate};
  }
  // Ratios to the fastest technique of each scene and backend.
  std::map<std::string, double> fastest;
  for (const auto& [key, r] : rows)
    if (r.row["ms"].is_number()) {
      const std::string g = r.row["scene"].get<std::string>() + "/" + r.row["backend"].get<std::string>();
      const double ms = r.row["ms"];
      if (!fastest.count(g) || ms < fastest[g]) fastest[g] = ms;
    }
  Json out_rows = Json::array();
  for (const auto& key : order) {
    Json r = rows[key].row;
    const std::string g = r["scene"].get<std::string>() + "/" + r["backend"].get<std::string>();
    r["x_fastest"] = r["ms"].is_number() && fastest[g] > 0.0 ? Json(r["ms"].get<double>() / fastest[g]) : Json(nullptr);
    out_rows.push_back(r);
  }
  if (out_rows.empty()) throw std::runtime_error("--bench-json '" + path + "': no BM_Technique benchmarks (is it bench_techniques' output?)");
  Json ctx = Json::object();
  const Json& c = j.value("context", Json::object());
  for (const char* k : {"date", "host_name", "num_cpus", "mhz_per_cpu", "library_build_type", "executable"})
    if (c.contains(k)) ctx[k] = c[k];
  return {{"source", kBenchFile}, {"context", ctx}, {"rows", out_rows}};
}

}  // namespace softgi::app::report
