// `softgi reference`: the ray-traced one-bounce ground truth of a scene (docs/reference.md).
//   softgi reference --scene NAME|FILE [--spp N] [--blockers geometry|proxies|proxies_only] [--light full|sh:N]
//                    [--frame t] [--width W] [--height H] [--seed S] [--convergence] --out DIR
// writes DIR/final.exr, direct.exr, indirect.exr, final.png and reference.json (and, with
// --convergence, convergence.json: error against the final image at spp = 1, 2, 4, ..., N).
#include <sys/resource.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <memory>
#include <optional>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "commands.hpp"
#include "frame_output.hpp"
#include "output_dir.hpp"
#include "softgi/io/image_io.hpp"
#include "softgi/io/scene_file.hpp"
#include "softgi/metrics/image_metrics.hpp"
#include "softgi/progress.hpp"
#include "softgi/reference/converge.hpp"
#include "softgi/reference/reference.hpp"
#include "softgi/sh/sh.hpp"

namespace softgi::app {

namespace {

namespace fs = std::filesystem;

struct ReferenceArgs {
  SceneArgs scene;
  std::string out, blockers = "geometry", light = "full";
  int spp = 64, width = 0, height = 0;
  double time = 0.0;
  unsigned seed = 1;
  bool convergence = false, no_indirect = false, no_jitter = false, quiet = false;
  float exposure = 1.0f;
  // Render until the reference's own noise adds at most this relMSE (none: a fixed --spp).
  std::optional<double> target_noise;
  int max_spp = reference::ConvergeOptions{}.max_spp;
  bool spp_given = false;
};

// "full" -> 0, "sh:N" -> N in 1..kMaxOrder; anything else is an error naming the value.
int parse_light(const std::string& s) {
  if (s == "full") return 0;
  const std::string bad = "--light must be 'full' or 'sh:N' with N in 1.." + std::to_string(sh::kMaxOrder) + ", got '" + s + "'";
  if (s.rfind("sh:", 0) != 0 || s.size() < 4 || s.size() > 5) throw std::invalid_argument(bad);
  int n = 0;
  for (std::size_t i = 3; i < s.size(); ++i) {
    if (s[i] < '0' || s[i] > '9') throw std::invalid_argument(bad);
    n = n * 10 + (s[i] - '0');
  }
  if (n < 1 || n > sh::kMaxOrder) throw std::invalid_argument(bad);
  return n;
}


// User + system CPU seconds of this process: with other jobs on the machine, CPU time per sample is
// a steadier measure than wall time.
double cpu_seconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) + 1e-6 * static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

nlohmann::json channel_means(const Image& img) {
  glm::dvec3 s(0.0);
  for (const auto& p : img.rgb) s += glm::dvec3(p);
  s /= std::max<std::size_t>(1, img.rgb.size());
  return {s.x, s.y, s.z};
}

void run_reference(const ReferenceArgs& args) {
  if (args.spp <= 0) throw std::invalid_argument("--spp must be >= 1, got " + std::to_string(args.spp));
  if (args.width < 0 || args.height < 0)
    throw std::invalid_argument("--width/--height must be >= 1, got " + std::to_string(args.width) + "x" + std::to_string(args.height));
  if (!std::isfinite(args.time)) throw std::invalid_argument("--frame must be a finite time in seconds");
  if (!(args.exposure > 0.0f) || !std::isfinite(args.exposure))
    throw std::invalid_argument("--exposure must be a finite number > 0");
  reference::ReferenceOptions opt;
  if (args.blockers == "geometry") opt.blockers = reference::ReferenceOptions::Blockers::Geometry;
  else if (args.blockers == "proxies") opt.blockers = reference::ReferenceOptions::Blockers::Proxies;
  else if (args.blockers == "proxies_only") opt.blockers = reference::ReferenceOptions::Blockers::ProxiesOnly;
  else throw std::invalid_argument("--blockers must be 'geometry', 'proxies' or 'proxies_only', got '" + args.blockers + "'");
  opt.light_sh_order = parse_light(args.light);
  opt.spp = args.spp;
  opt.time = args.time;
  opt.seed = args.seed;
  opt.width = args.width;
  opt.height = args.height;
  opt.indirect = !args.no_indirect;
  opt.jitter = !args.no_jitter;

  const bool converge = args.target_noise.has_value();
  if (converge && args.convergence)
    throw std::invalid_argument("--target-noise and --convergence do not combine (--convergence studies one fixed --spp)");
  reference::ConvergeOptions copt;
  if (converge) {
    copt.target_noise = *args.target_noise;
    copt.max_spp = args.max_spp;
    if (args.spp_given) copt.min_spp = args.spp;
    // Checked here as well as in the library, so that bad options fail before the output folder exists.
    if (!std::isfinite(copt.target_noise) || copt.target_noise <= 0.0)
      throw std::invalid_argument("--target-noise must be a finite number > 0, got " + std::to_string(copt.target_noise));
    if (copt.min_spp < 2 || copt.min_spp % 2 != 0)
      throw std::invalid_argument("with --target-noise, --spp (the first round, both halves) must be even and >= 2, got " +
                                  std::to_string(copt.min_spp));
    if (copt.max_spp < copt.min_spp || copt.max_spp % 2 != 0)
      throw std::invalid_argument("--max-spp must be even and >= the first round's " + std::to_string(copt.min_spp) +
                                  " spp, got " + std::to_string(copt.max_spp));
  }

  OutputDir out(args.out, "--out", "reference.json");  // before the scene and the render
  const scene::Scene sc = load_cli_scene("reference", args.scene.spec, args.scene.fit_proxies);

  struct PassRecord {
    int spp;
    double seconds;
    long long rays;
    Image final_image;
  };
  std::vector<PassRecord> passes;
  reference::PassCallback on_pass;
  if (args.convergence)
    on_pass = [&](int spp, const reference::ReferenceResult& r) { passes.push_back({spp, r.seconds, r.rays, r.final_image}); };
  const double cpu0 = cpu_seconds();
  reference::ReferenceResult res;
  std::optional<reference::ConvergedReference> conv;
  if (converge) {
    // One bar per round: the next round's sample count is known only when the last one has ended.
    std::unique_ptr<ProgressBar> bar;
    int bar_round = -1;
    conv = reference::render_converged_reference(sc, opt, copt, [&](int round, int spp, double f) {
      if (round != bar_round) {
        bar = std::make_unique<ProgressBar>("reference " + sc.name + " round " + std::to_string(round + 1) + " (" +
                                                std::to_string(spp) + " spp)",
                                            !args.quiet);
        bar_round = round;
      }
      bar->update(f);
    });
    res = conv->result;
    opt.spp = res.spp;
  } else {
    ProgressBar bar("reference " + sc.name, !args.quiet);
    res = reference::render_reference(sc, opt, [&](double f) { bar.update(f); }, on_pass);
  }
  const double cpu = cpu_seconds() - cpu0;

  out.write_exr("final.exr", res.final_image);
  out.write_exr("direct.exr", res.direct);
  out.write_exr("indirect.exr", res.indirect);
  out.write_png("final.png", res.final_image, args.exposure);
  if (conv) {
    // The halves, for `softgi diff --halves` to take the reference's noise out of an error.
    out.write_exr("half_a.exr", conv->half_a.final_image);
    out.write_exr("half_b.exr", conv->half_b.final_image);
  }

  Json j;
  j["scene"] = scene_json(sc, args.scene.spec);
  j["options"] = {{"spp", opt.spp},
                  {"blockers", args.blockers},
                  {"light", args.light},
                  {"light_sh_order", opt.light_sh_order},
                  {"indirect", opt.indirect},
                  {"jitter", opt.jitter},
                  {"time", opt.time},
                  {"seed", opt.seed},
                  {"width", res.final_image.width},
                  {"height", res.final_image.height}};
  j["seconds"] = res.seconds;
  j["setup_seconds"] = res.setup_seconds;
  j["seconds_per_sample"] = res.seconds_per_sample;
  j["rays"] = res.rays;
  j["rays_per_second"] = res.seconds > res.setup_seconds ? res.rays / (res.seconds - res.setup_seconds) : 0.0;
  j["cpu_seconds"] = cpu;
  j["cpu_seconds_per_sample"] = cpu / opt.spp;
  j["threads"] = std::thread::hardware_concurrency();
  if (conv) {
    Json rounds = Json::array();
    for (const auto& r : conv->rounds) rounds.push_back({{"spp", r.spp}, {"noise", r.noise}, {"seconds", r.seconds}});
    j["converge"] = {{"target_noise", copt.target_noise},
                     {"max_spp", copt.max_spp},
                     {"relmse_epsilon", copt.relmse_epsilon},
                     {"noise", conv->noise},
                     {"converged", conv->converged},
                     {"pixels", conv->pixels},
                     {"seeds", {opt.seed, reference::half_b_seed(opt.seed)}},
                     {"halves", {"half_a.exr", "half_b.exr"}},
                     {"rounds", rounds}};
  }
  j["mean"] = {{"final", channel_means(res.final_image)}, {"direct", channel_means(res.direct)}, {"indirect", channel_means(res.indirect)}};

  if (args.convergence) {
    // Error of each power-of-two estimate against the final image. The estimate at k samples shares
    // its samples with the final one at N, so for an unbiased estimator E|X_k - X_N|^2 =
    // sigma^2 (1/k - 1/N) while E|X_k - truth|^2 = sigma^2 / k: *_vs_truth_estimate rescales by
    // 1 / (1 - k/N). The final image's own error is estimated as half that of the N/2 estimate.
    Json rows = Json::array();
    double half_mse = -1.0, half_rel = -1.0;
    for (const PassRecord& p : passes) {
      const metrics::Metrics m = metrics::compare(p.final_image, res.final_image);
      Json row = {{"spp", p.spp},   {"seconds", p.seconds}, {"rays", p.rays},
                  {"rmse", m.rmse}, {"relmse", m.relmse},   {"psnr", std::isinf(m.psnr) ? Json("inf") : Json(m.psnr)},
                  {"ssim", m.ssim}};
      if (p.spp < opt.spp) {
        const double scale = 1.0 / (1.0 - static_cast<double>(p.spp) / opt.spp);
        row["rmse_vs_truth_estimate"] = m.rmse * std::sqrt(scale);
        row["relmse_vs_truth_estimate"] = m.relmse * scale;
        if (2 * p.spp == opt.spp) {
          half_mse = m.rmse * m.rmse * scale;
          half_rel = m.relmse * scale;
        }
      }
      rows.push_back(row);
    }
    Json c;
    c["scene"] = sc.name;
    c["options"] = j["options"];
    c["reference_spp"] = opt.spp;
    c["metric"] = "metrics::compare(estimate at spp, final image at reference_spp)";
    c["passes"] = rows;
    if (half_mse >= 0.0) {
      c["final_rmse_estimate"] = std::sqrt(half_mse / 2.0);
      c["final_relmse_estimate"] = half_rel / 2.0;
    }
    out.write_json("convergence.json", c);
  }
  out.finish(j);  // the record last: it lists what was written (outputs.written)

  std::cout << "softgi reference: " << sc.name << " " << res.final_image.width << "x" << res.final_image.height << ", " << opt.spp
            << " spp, " << std::fixed << std::setprecision(2) << res.seconds << " s (" << std::setprecision(4)
            << res.seconds_per_sample << " s per sample pass, " << std::setprecision(1) << res.rays / 1e6 << " Mrays) -> "
            << args.out << "\n";
  if (conv) {
    std::cout << std::defaultfloat << std::setprecision(4) << "  noise " << conv->noise << " (relMSE it adds, target "
              << copt.target_noise << ") after " << conv->rounds.size() << " round(s)\n";
    if (!conv->converged)
      std::cerr << "softgi reference: warning: the noise target " << copt.target_noise << " was not reached at --max-spp "
                << copt.max_spp << " (noise " << conv->noise << "); errors below about " << 10.0 * conv->noise
                << " are under this reference's noise floor\n";
  }
}

void register_reference(CLI::App& app) {
  auto args = std::make_shared<ReferenceArgs>();
  CLI::App* sub = app.add_subcommand("reference", "ray-traced one-bounce ground truth (Embree) of a scene");
  add_scene_options(*sub, args->scene);
  sub->add_option("--out,-o", args->out, "output directory (created)")->required();
  sub->add_option("--spp", args->spp, "samples per pixel (default 64; with --target-noise the first round's, default 16)")
      ->each([args](const std::string&) { args->spp_given = true; });
  sub->add_option("--target-noise", args->target_noise,
                  "render two halves, more samples each round, until the reference's noise adds at most this relMSE "
                  "(writes half_a.exr and half_b.exr)");
  sub->add_option("--max-spp", args->max_spp, "with --target-noise: the most samples per pixel (default 4096)");
  sub->add_option("--blockers", args->blockers, "what casts shadows: geometry | proxies (proxy spheres, and the objects without proxies) | proxies_only (the proxy spheres alone, the blockers a sphere-proxy technique sees) (default geometry)");
  sub->add_option("--light", args->light, "full | sh:N (the environment's order-N SH projection)");
  sub->add_option("--frame,--time", args->time, "animation time in seconds (default 0)");
  // The same range as `render` and `compare`: 0 is no size (omit the option for the camera's).
  sub->add_option("--width", args->width, "image width (default: the scene camera's)")->check(CLI::Range(1, 16384));
  sub->add_option("--height", args->height, "image height (default: the scene camera's)")->check(CLI::Range(1, 16384));
  sub->add_option("--seed", args->seed, "random seed (default 1)");
  sub->add_option("--exposure", args->exposure, "exposure scale of final.png (default 1)");
  sub->add_flag("--convergence", args->convergence, "record error against the final image at spp 1, 2, 4, ... in convergence.json");
  sub->add_flag("--no-indirect", args->no_indirect, "direct light only");
  sub->add_flag("--no-jitter", args->no_jitter, "every sample through the pixel centre");
  sub->add_flag("--quiet,-q", args->quiet, "no progress bar");
  sub->callback([args] { run_reference(*args); });
}
const CommandRegistrar registrar(register_reference);

}  // namespace

}  // namespace softgi::app
