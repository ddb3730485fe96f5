// `softgi compare`: every registered technique (default parameters) and the ray-traced ground truth
// on one scene; error (relMSE with the reference's own noise removed, SSIM, FLIP) against the
// reference lit by the full environment and by its order-n SH projection; images, error maps,
// compare.json and a Markdown summary.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <iomanip>
#include <iostream>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "cached_reference.hpp"
#include "commands.hpp"
#include "error_terms.hpp"
#include "frame_output.hpp"
#include "output_dir.hpp"
#include "softgi/io/scene_file.hpp"
#include "softgi/metrics/flip.hpp"
#include "softgi/metrics/image_metrics.hpp"
#include "softgi/reference/reference.hpp"
#include "softgi/render/camera.hpp"
#include "softgi/render/common_passes.hpp"
#include "softgi/render/gbuffer.hpp"
#include "softgi/render/technique.hpp"
#include "softgi/techniques/registry.hpp"

namespace softgi::app {

namespace {

// The untimed first frame is rendered this long before the timed one (one frame at 30 Hz).
constexpr double kWarmupFrameSeconds = 1.0 / 30.0;

struct CompareArgs {
  SceneArgs scene;
  std::string out, techniques, backends, device;  // backends: "" = the reference backend
  double frame = 0.0;
  int spp = 64;                       // both halves together; with target_noise, the first round's
  std::optional<double> target_noise;  // render the references until their noise is at most this
  int max_spp = 4096;                 // with target_noise: the cap
  int width = 0, height = 0;
  unsigned seed = 1;
};

std::string fmt(double v, int precision = 4) {
  if (!std::isfinite(v)) return "-";
  std::ostringstream os;
  os << std::setprecision(precision) << v;
  return os.str();
}
std::string ms(double seconds) {
  std::ostringstream os;
  os << std::fixed << std::setprecision(seconds < 0.01 ? 2 : 1) << seconds * 1e3;
  return os.str();
}

Json metrics_json(const metrics::Metrics& m) {
  return {{"relmse", m.relmse}, {"ssim", m.ssim}, {"rmse", m.rmse}, {"psnr", std::isfinite(m.psnr) ? Json(m.psnr) : Json("inf")},
          {"max_abs", m.max_abs}, {"pixels", m.pixels}};
}

// Progress of a long reference render on stderr, every 10 %.
std::function<void(double)> progress_printer(const std::string& what) {
  auto next = std::make_shared<int>(0);
  return [what, next](double f) {
    const int pct = static_cast<int>(f * 100.0);
    if (pct < *next) return;
    std::cerr << "compare: " << what << ": " << pct << "%\n";
    *next = (pct / 10 + 1) * 10;
  };
}

// The image with background pixels set to black: error maps then show (and are scaled by) the
// surface pixels the metrics count.
Image on_surface(Image img, const Mask& surface) {
  for (std::size_t i = 0; i < img.rgb.size(); ++i)
    if (!surface.on[i]) img.rgb[i] = glm::vec3(0.0f);
  return img;
}

struct Reference {
  std::string key, label;  // "full" / "sh4"
  int order = 0;
  bool cached = false;  // served by the reference cache
  reference::ConvergedReference conv;  // two independent halves; conv.result is their mean
  const reference::ReferenceResult& result() const { return conv.result; }
};

struct TechniqueRun {
  std::string name, settings, error;
  std::string backend, label;  // label: output folder and table name (name, or name-backend off the reference backend)
  Json device = Json::object();
  render::ParamSet params;
  render::FrameResult frame;
  double first_frame_seconds = 0.0;
  int order = kDefaultShOrder;
  std::map<std::string, Json> vs_final, vs_direct;  // noise_corrected_errors, keyed by reference key
  double vs_cpu = -1.0;  // relMSE of the final image against the CPU backend's (other backends, when both ran)
};

// What every step of a comparison works on: the techniques, backends, scene and frame size the
// arguments name.
struct CompareSetup {
  std::vector<std::unique_ptr<render::Technique>> techs;
  std::string reference_backend;
  std::vector<std::unique_ptr<render::Backend>> backends_used;
  std::optional<OutputDir> out;  // DIR and its record, compare.json
  scene::Scene sc;
  int w = 0, h = 0;
};

// The surface the errors are measured over: the shared G-buffer on its own, on the reference backend.
struct Surface {
  render::GBufferFrame gbf;
  Mask mask;
  long long pixels = 0;
  const render::PassRecord& gbuffer_pass() const { return gbf.frame.passes.front(); }  // "gbuffer" (then the hand-out)
};

// Step 1, the arguments: every name is checked before anything renders.
CompareSetup read_arguments(const CompareArgs& args) {
  CompareSetup cs;
  register_builtin();
  if (!std::isfinite(args.frame)) throw std::invalid_argument("--frame: time must be finite");
  if (args.spp % 2 != 0)
    throw std::invalid_argument("--spp must be even, got " + std::to_string(args.spp) +
                                ": the reference is two independent halves of spp / 2 samples, so that its noise can be removed");
  if (args.target_noise && !(*args.target_noise > 0.0 && std::isfinite(*args.target_noise)))
    throw std::invalid_argument("--target-noise must be a finite relMSE > 0");
  if (args.target_noise && (args.max_spp % 2 != 0 || args.max_spp < args.spp))
    throw std::invalid_argument("--max-spp must be even and at least --spp (" + std::to_string(args.spp) + "), got " +
                                std::to_string(args.max_spp));
  std::vector<std::string> names = args.techniques.empty() ? render::technique_names() : split_list(args.techniques);
  if (names.empty()) throw std::invalid_argument("compare: no technique to compare (--techniques is empty or none is registered)");
  for (const auto& n : names) cs.techs.push_back(render::create_technique(n));  // unknown names fail here
  cs.reference_backend = render::reference_backend_name();
  const std::string& reference_backend = cs.reference_backend;
  const std::vector<std::string> backend_names = parse_backends(args.backends.empty() ? reference_backend : args.backends);
  bool selects_device = false;
  for (const auto& b : backend_names) selects_device = selects_device || render::backend_info(b).selects_device;
  if (!args.device.empty() && !selects_device)
    throw std::invalid_argument("--device '" + args.device + "': none of the backends asked for selects a device");
  cs.out.emplace(args.out, "--out", "compare.json");  // before the devices, the scene and the frames
  for (const auto& b : backend_names)
    cs.backends_used.push_back(make_backend(b, render::backend_info(b).selects_device ? args.device : "", "compare"));

  cs.sc = load_cli_scene("compare", args.scene.spec, args.scene.fit_proxies);
  cs.w = args.width;
  cs.h = args.height;
  render::resolve_resolution(cs.sc.camera, cs.w, cs.h);
  render::make_pinhole_camera(cs.sc, cs.w, cs.h, "compare");
  std::cerr << "compare: scene '" << cs.sc.name << "' at " << cs.w << "x" << cs.h << ", t = " << args.frame << " s, "
            << cs.techs.size() << " technique(s), reference " << args.spp << " spp\n";

  return cs;
}

// Step 2, the surface mask.
Surface measure_surface(const CompareSetup& cs, const CompareArgs& args) {
  const scene::Scene& sc = cs.sc;
  const int w = cs.w, h = cs.h;
  Surface surf;
  // The shared G-buffer once on its own, on the reference backend: its cost, and the surface mask
  // errors are measured over.
  {
    std::unique_ptr<render::Backend> ref = render::create_backend(cs.reference_backend);
    render::RenderRequest greq;
    greq.time = args.frame;
    greq.width = w;
    greq.height = h;
    surf.gbf = render::render_gbuffer(*ref, sc, greq);
  }
  const render::GBuffer& gb = surf.gbf.gbuffer;
  Mask& surface = surf.mask;
  surface = Mask{w, h, std::vector<std::uint8_t>(gb.object.size(), 0)};
  long long& surface_pixels = surf.pixels;
  for (std::size_t i = 0; i < gb.object.size(); ++i) {
    surface.on[i] = gb.hit(i) ? 1 : 0;
    surface_pixels += surface.on[i];
  }
  if (surface_pixels == 0) throw std::runtime_error("compare: scene '" + sc.name + "' shows no surface from its camera");
  const render::PassRecord& gbr = surf.gbuffer_pass();
  std::cerr << "compare: G-buffer " << ms(gbr.wall_seconds) << " ms, " << surface_pixels << " surface pixels\n";

  return surf;
}

// Step 3, the variants: every technique on every backend, a warm-up frame then the timed one.
std::vector<TechniqueRun> render_variants(const CompareSetup& cs, const CompareArgs& args, std::set<int>& orders) {
  const scene::Scene& sc = cs.sc;
  const int w = cs.w, h = cs.h;
  const auto& techs = cs.techs;
  const auto& backends_used = cs.backends_used;
  const std::string& reference_backend = cs.reference_backend;
  // Techniques: one warm-up frame (one-time setup such as tables), then the timed frame; on every
  // backend asked for (each technique instance keeps per-backend-independent state only).
  std::vector<TechniqueRun> runs;
  for (std::size_t bi = 0; bi < backends_used.size(); ++bi) {
    for (std::size_t k = 0; k < techs.size(); ++k) {
      render::Backend& backend = *backends_used[bi];
      render::Technique& t = *techs[k];
      TechniqueRun run;
      run.name = t.name();
      run.backend = backend.name();
      run.label = run.backend == reference_backend ? run.name : run.name + "-" + run.backend;
      run.device = device_json(backend);
      run.params = render::default_params(t);
      run.order = sh_order_of(run.params);
      for (const auto& [pn, pv] : run.params.values()) run.settings += (run.settings.empty() ? "" : ", ") + pn + "=" + pv;
      std::cerr << "compare: [" << bi * techs.size() + k + 1 << "/" << techs.size() * backends_used.size() << "] " << run.name
                << " on " << run.backend << " (" << run.settings << ")\n";
      render::RenderRequest req;
      req.time = args.frame;
      req.width = w;
      req.height = h;
      req.outputs = {"final"};
      try {
        // The warm-up frame is the previous frame of a 30 Hz animation, so the timed frame pays the
        // per-frame updates (proxy refits, BVH refits) of a running animation and no one-time setup.
        render::RenderRequest warm = req;
        warm.time = args.frame - kWarmupFrameSeconds;
        render::FrameResult first = backend.render(t, sc, run.params, warm);
        run.first_frame_seconds = first.total_seconds;
        backend.recycle(std::move(first));
        run.frame = backend.render(t, sc, run.params, req);
        print_frame_warnings("compare", run.frame);
        if (run.frame.final_image.width != w || run.frame.final_image.height != h)
          throw std::runtime_error("final image is " + std::to_string(run.frame.final_image.width) + "x" +
                                   std::to_string(run.frame.final_image.height) + ", expected " + std::to_string(w) + "x" +
                                   std::to_string(h));
        orders.insert(run.order);
        std::cerr << "compare:   " << ms(run.frame.total_seconds) << " ms per frame (first frame " << ms(run.first_frame_seconds)
                  << " ms)\n";
      } catch (const std::exception& e) {
        run.error = e.what();
        std::cerr << "compare:   FAILED: " << run.error << "\n";
      }
      runs.push_back(std::move(run));
    }
  }

  return runs;
}

// Step 4, the ground truth.
std::vector<Reference> render_references(const CompareSetup& cs, const CompareArgs& args, const std::set<int>& orders,
                                         const Surface& surf, OutputDir& out) {
  const int w = cs.w, h = cs.h;
  const scene::Scene& sc = cs.sc;
  // Ground truth: real geometry as blockers, un-jittered (each pixel sampled at its centre, as the
  // techniques' G-buffer is), lit by the full environment and by each SH order in use.
  std::vector<Reference> refs;
  refs.push_back({"full", "full environment", 0, {}});
  for (int n : orders) refs.push_back({"sh" + std::to_string(n), "order-" + std::to_string(n) + " SH lighting", n, {}});
  // Two independent halves, so that the reference's own noise can be taken out of every error
  // (docs/metrics.md, "Reference noise"): one round of --spp samples, or rounds until the noise is at
  // most --target-noise over the surface pixels, the pixels the errors are measured over.
  reference::ConvergeOptions co;
  co.mask = surf.mask;
  co.target_noise = args.target_noise.value_or(std::numeric_limits<double>::max());
  co.min_spp = args.spp;
  co.max_spp = args.target_noise ? args.max_spp : args.spp;
  co.relmse_epsilon = metrics::MetricOptions{}.relmse_epsilon;
  for (auto& ref : refs) {
    reference::ReferenceOptions opt;
    opt.blockers = reference::ReferenceOptions::Blockers::Geometry;
    opt.light_sh_order = ref.order;
    opt.indirect = true;
    opt.time = args.frame;
    opt.seed = args.seed;
    opt.width = w;
    opt.height = h;
    opt.jitter = false;
    auto progress = progress_printer("reference, " + ref.label);
    ref.conv = cached_converged_reference(
        sc, opt, co, [&](int round, int, double f) { progress(args.target_noise ? std::min(1.0, 0.5 * (round + f)) : f); }, ref.cached);
    out.write_image_pair("reference_" + ref.key, ref.result().final_image);
    std::cerr << "compare: reference, " << ref.label << ": " << ref.result().spp << " spp, noise " << fmt(ref.conv.noise, 3)
              << (args.target_noise && !ref.conv.converged ? " (above --target-noise: --max-spp came first)" : "") << ", "
              << fmt(ref.result().seconds, 3) << " s" << (ref.cached ? " (cached: the time of the render that made it)" : "")
              << "\n";
  }
  return refs;
}

// Step 5, the metrics of each run against the references, and its images and record.
Json measure_runs(std::vector<TechniqueRun>& runs, const std::vector<Reference>& refs, const Surface& surf, const CompareSetup& cs,
                  const CompareArgs& args, OutputDir& out, std::vector<std::string>& failures) {
  const scene::Scene& sc = cs.sc;
  const int w = cs.w, h = cs.h;
  const Mask& surface = surf.mask;
  const std::string& reference_backend = cs.reference_backend;
  auto ref_for_order = [&](int n) -> const Reference& {
    for (const auto& r : refs)
      if (r.order == n) return r;
    return refs.front();
  };

  // Errors and per-technique outputs.
  Json jtechs = Json::array();
  for (auto& run : runs) {
    Json jt = {{"name", run.name}, {"backend", run.backend}, {"device", run.device}, {"params", params_json(run.params)},
               {"sh_order", run.order}};
    if (!run.error.empty()) {
      jt["error"] = run.error;
      failures.push_back(run.label + ": " + run.error);
      jtechs.push_back(jt);
      continue;
    }
    // Images the record lists are those written (a failed one is in compare.json's outputs.missing).
    Json images = Json::object();
    auto save = [&](const char* name, const Image& img) {
      const std::string base = run.label + "/" + name;
      if (!img.empty() && out.write_image_pair(base, img)) images[name] = base + ".png";
    };
    save("final", run.frame.final_image);
    save("direct", run.frame.direct);
    save("indirect", run.frame.indirect);
    Json errors = Json::object(), direct_errors = Json::object();
    try {
      for (const Reference* ref : {static_cast<const Reference*>(&refs.front()), &ref_for_order(run.order)}) {
        if (run.vs_final.count(ref->key)) continue;
        const reference::ConvergedReference& c = ref->conv;
        run.vs_final[ref->key] = errors[ref->key] =
            noise_corrected_errors(run.frame.final_image, c.half_a.final_image, c.half_b.final_image, surface);
        const std::string map = run.label + "/error_" + ref->key + ".png";
        if (out.write_png_display(map, metrics::error_map(on_surface(run.frame.final_image, surface),
                                                          on_surface(ref->result().final_image, surface))))
          images["error_" + ref->key] = map;
        if (!run.frame.direct.empty())
          run.vs_direct[ref->key] = direct_errors[ref->key] =
              noise_corrected_errors(run.frame.direct, c.half_a.direct, c.half_b.direct, surface);
      }
    } catch (const std::exception& e) {
      run.error = std::string("metrics: ") + e.what();
      jt["error"] = run.error;
      failures.push_back(run.label + ": " + run.error);
    }
    // The same technique on the CPU backend, when both ran: how far the backends' images differ.
    if (run.backend != reference_backend)
      for (const auto& other : runs)
        if (other.name == run.name && other.backend == reference_backend && other.error.empty()) {
          const metrics::Metrics m = metrics::compare(run.frame.final_image, other.frame.final_image, surface);
          jt["vs_cpu_backend"] = metrics_json(m);
          run.vs_cpu = m.relmse;
        }
    jt["frame_seconds"] = run.frame.total_seconds;
    jt["first_frame_seconds"] = run.first_frame_seconds;
    jt.update(frame_json(run.frame));
    jt["errors_final"] = errors;
    jt["errors_direct"] = direct_errors;
    jt["images"] = images;
    Json rec = jt;
    rec["softgi_version"] = softgi_version();
    rec["date"] = utc_now();
    rec["command"] = "compare";
    rec["scene"] = sc.name;
    rec["backend"] = run.backend;
    rec["frame_time"] = args.frame;
    rec["resolution"] = {w, h};
    out.write_json(run.label + "/record.json", rec);
    jtechs.push_back(jt);
  }

  return jtechs;
}

// Step 6, the writing: the Markdown summary, then compare.json, the record, last.
void write_results(const std::vector<TechniqueRun>& runs, const std::vector<Reference>& refs, const Surface& surf,
                   const CompareSetup& cs, const CompareArgs& args, const Json& jtechs, OutputDir& out) {
  const scene::Scene& sc = cs.sc;
  const int w = cs.w, h = cs.h;
  const long long surface_pixels = surf.pixels;
  const render::PassRecord& gbr = surf.gbuffer_pass();
  const std::string& reference_backend = cs.reference_backend;
  Json jrefs = Json::array();
  for (const auto& r : refs)
    jrefs.push_back({{"key", r.key},
                     {"light_sh_order", r.order},
                     {"spp", r.result().spp},
                     {"noise", r.conv.noise},
                     {"target_noise", args.target_noise ? Json(*args.target_noise) : Json(nullptr)},
                     {"converged", r.conv.converged},
                     {"seconds", r.result().seconds},
                     {"rays", r.result().rays},
                     {"cached", r.cached},
                     {"blockers", "geometry"},
                     {"indirect", true},
                     {"jitter", false},
                     {"image", "reference_" + r.key + ".png"}});
  Json j = {{"softgi_version", softgi_version()},
                      {"date", utc_now()},
                      {"scene", scene_json(sc, args.scene.spec)},
                      {"frame_time", args.frame},
                      {"resolution", {w, h}},
                      {"surface_pixels", surface_pixels},
                      {"metric_options", {{"relmse_epsilon", metrics::MetricOptions{}.relmse_epsilon}, {"mask", "surface pixels"}}},
                      {"gbuffer", {{"wall_seconds", gbr.wall_seconds}, {"counters", gbr.counters}, {"bytes", gbr.bytes}}},
                      {"references", jrefs},
                      {"techniques", jtechs}};

  // The Markdown summary.
  std::ostringstream md;
  md << "# softgi compare: " << sc.name << "\n\n"
     << "Scene `" << args.scene.spec << "` (" << sc.source << "), " << w << "x" << h << ", frame t = " << args.frame
     << " s; softgi " << softgi_version() << ", " << utc_now() << ", backend(s): " << (args.backends.empty() ? reference_backend : args.backends) << ".\n\n"
     << "Ground truth: the Embree path tracer with the real geometry as blockers and one-bounce diffuse indirect, "
     << "through each pixel centre (the visibility of the techniques' one-sample G-buffer), as two independent halves; "
     << "lit by the full environment";
  for (std::size_t i = 1; i < refs.size(); ++i) md << " and by its order-" << refs[i].order << " SH projection";
  md << " (";
  for (std::size_t i = 0; i < refs.size(); ++i)
    md << (i ? "; " : "") << refs[i].key << ": " << refs[i].result().spp << " spp, noise " << fmt(refs[i].conv.noise, 3)
       << (args.target_noise && !refs[i].conv.converged ? ", above the target" : "");
  md << "). Every technique runs at its default parameters (all of them in compare.json and its record.json). "
     << "Errors are over the " << surface_pixels << " surface pixels (background excluded); relMSE = mean of "
     << "(a - b)^2 / (b^2 + " << metrics::MetricOptions{}.relmse_epsilon << ") with the reference's own noise removed "
     << "(its 95 % interval in brackets; * where the reference's noise is over 10 % of the error, or the interval "
     << "reaches 0: the reference cannot resolve it, render it with --target-noise), SSIM on luminance x / (1 + x), "
     << "FLIP = HDR-FLIP (Andersson et al. 2021; ACES, 67 pixels per degree), mean over the surface pixels. "
     << "Times are of a second frame, 1/30 s after an untimed first one (which also pays one-time setup; "
     << "its time is in compare.json).\n\n"
     << "Shared G-buffer on its own, BVH built from scratch: " << ms(gbr.wall_seconds) << " ms (" << gbr.bytes / 1024
     << " KiB); in the timed frames it refits or reuses the BVH.\n\n";
  // The noise-corrected relMSE with its interval, or SSIM / FLIP, of one entry of vs_final/vs_direct.
  auto err_cell = [](const std::map<std::string, Json>& vs, const std::string& key, const char* field) {
    auto it = vs.find(key);
    if (it == vs.end() || !it->second.is_object() || !it->second.contains(field) || !it->second[field].is_number()) return std::string("-");
    const Json& e = it->second;
    std::string text = fmt(e[field].get<double>());
    if (std::string(field) == "relmse")
      text += " [" + fmt(e["ci_low"].get<double>(), 3) + ", " + fmt(e["ci_high"].get<double>(), 3) + "]" +
             (e["below_noise_floor"].get<bool>() ? "*" : "");
    return text;
  };
  md << "| technique | total (ms) | time per pass (ms) | relMSE vs full | SSIM vs full | FLIP vs full | relMSE vs SH | SSIM vs SH | images |\n"
     << "|---|---|---|---|---|---|---|---|---|\n";
  for (const auto& run : runs) {
    if (!run.error.empty()) {
      std::string why = run.error;  // a '|' would end the table cell
      for (std::size_t p = why.find('|'); p != std::string::npos; p = why.find('|', p + 2)) why.replace(p, 1, "\\|");
      md << "| " << run.label << " | failed: " << why << " | | | | | | | |\n";
      continue;
    }
    std::string passes;
    for (const auto& p : run.frame.passes)
      passes += (passes.empty() ? "" : ", ") + p.name + " " + ms(p.wall_seconds) + (p.gpu_seconds >= 0.0 ? " (GPU " + ms(p.gpu_seconds) + ")" : "");
    const std::string shk = "sh" + std::to_string(run.order);
    md << "| " << run.label << " | " << ms(run.frame.total_seconds) << " | " << passes << " | " << err_cell(run.vs_final, "full", "relmse")
       << " | " << err_cell(run.vs_final, "full", "ssim") << " | " << err_cell(run.vs_final, "full", "flip") << " | "
       << err_cell(run.vs_final, shk, "relmse") << " (n=" << run.order << ") | " << err_cell(run.vs_final, shk, "ssim")
       << " | [final](" << run.label << "/final.png) · [error vs full](" << run.label
       << "/error_full.png) · [error vs SH](" << run.label << "/error_" << shk << ".png) |\n";
  }
  std::string cross;
  for (const auto& run : runs)
    if (run.vs_cpu >= 0.0) cross += "- " + run.name + " on " + run.backend + " against the CPU backend: relMSE " + fmt(run.vs_cpu) + "\n";
  if (!cross.empty()) md << "\nBackends against each other (final images, surface pixels):\n\n" << cross;
  // Per pass, side by side: a technique on the CPU backend and on each other backend of this run.
  // Fence waits (host time from submission to fence) stand next to the timestamps because some
  // drivers' timestamps do not cover compute work (docs/backends.md, the lavapipe caveat).
  for (const auto& cpu_run : runs) {
    if (cpu_run.backend != reference_backend || !cpu_run.error.empty()) continue;
    for (const auto& other : runs) {
      if (other.name != cpu_run.name || other.backend == reference_backend || !other.error.empty()) continue;
      md << "\n" << cpu_run.name << " per pass, cpu against " << other.backend << " (ms):\n\n"
         << "| pass | cpu wall | " << other.backend << " wall | " << other.backend << " fence wait | " << other.backend
         << " timestamps |\n|---|---|---|---|---|\n";
      std::vector<std::string> pass_names;
      for (const auto& p : cpu_run.frame.passes) pass_names.push_back(p.name);
      for (const auto& p : other.frame.passes)
        if (std::find(pass_names.begin(), pass_names.end(), p.name) == pass_names.end()) pass_names.push_back(p.name);
      const auto find = [](const render::FrameResult& f, const std::string& n) -> const render::PassRecord* {
        for (const auto& p : f.passes)
          if (p.name == n) return &p;
        return nullptr;
      };
      for (const auto& n : pass_names) {
        const render::PassRecord* a = find(cpu_run.frame, n);
        const render::PassRecord* b = find(other.frame, n);
        const auto wait = b ? b->counters.find("gpu_wait_seconds") : decltype(b->counters.end()){};
        const bool has_wait = b && wait != b->counters.end() && wait->second > 0.0;
        md << "| " << n << " | " << (a ? ms(a->wall_seconds) : "-") << " | " << (b ? ms(b->wall_seconds) : "-") << " | "
           << (has_wait ? ms(wait->second) : "-") << " | " << (b && b->gpu_seconds >= 0.0 && has_wait ? ms(b->gpu_seconds) : "-") << " |\n";
      }
      md << "| frame | " << ms(cpu_run.frame.total_seconds) << " | " << ms(other.frame.total_seconds) << " | | |\n\n"
         << "Passes without a fence wait ran no device work (host passes: the same function on both backends).\n";
    }
  }
  bool any_direct = false;
  for (const auto& run : runs) any_direct = any_direct || !run.vs_direct.empty();
  if (any_direct) {
    md << "\nDirect (shadowed) light only, against the reference's direct image:\n\n"
       << "| technique | relMSE vs full | SSIM vs full | relMSE vs SH | SSIM vs SH |\n|---|---|---|---|---|\n";
    for (const auto& run : runs) {
      if (run.vs_direct.empty()) continue;
      const std::string shk = "sh" + std::to_string(run.order);
      md << "| " << run.label << " | " << err_cell(run.vs_direct, "full", "relmse") << " | " << err_cell(run.vs_direct, "full", "ssim")
         << " | " << err_cell(run.vs_direct, shk, "relmse") << " | " << err_cell(run.vs_direct, shk, "ssim") << " |\n";
    }
  }
  md << "\nReferences: ";
  for (std::size_t i = 0; i < refs.size(); ++i)
    md << (i ? " · " : "") << "[" << refs[i].label << "](reference_" << refs[i].key << ".png) (" << fmt(refs[i].result().seconds, 3)
       << " s)";
  md << "\n";
  std::string pruned;
  for (const auto& run : runs)
    for (const auto& p : run.frame.pruned) pruned += "- " + run.label + ": `" + p.name + "`: " + p.reason + "\n";
  if (!pruned.empty()) md << "\nPruned passes:\n\n" << pruned;
  out.write_text("summary.md", md.str());
  out.finish(j);
  std::cerr << "compare: wrote " << out.path("summary.md") << " and " << out.path("compare.json") << "\n";

}

void run_compare(const CompareArgs& args) {
  CompareSetup cs = read_arguments(args);
  const Surface surf = measure_surface(cs, args);
  std::set<int> orders;
  std::vector<TechniqueRun> runs = render_variants(cs, args, orders);
  const std::vector<Reference> refs = render_references(cs, args, orders, surf, *cs.out);
  std::vector<std::string> failures;
  const Json jtechs = measure_runs(runs, refs, surf, cs, args, *cs.out, failures);
  write_results(runs, refs, surf, cs, args, jtechs, *cs.out);
  const scene::Scene& sc = cs.sc;
  if (!failures.empty()) {
    std::string msg = "compare: " + std::to_string(failures.size()) + " technique(s) failed on scene '" + sc.name + "':";
    for (const auto& f : failures) msg += " [" + f + "]";
    throw std::runtime_error(msg);
  }
}

void register_compare(CLI::App& app) {
  auto args = std::make_shared<CompareArgs>();
  CLI::App* sub = app.add_subcommand(
      "compare", "Render a scene with every technique and the ground truth; errors, times, compare.json, summary.md");
  add_scene_options(*sub, args->scene);
  sub->add_option("--out", args->out, "output directory")->required();
  sub->add_option("--frame", args->frame, "animation time in seconds (default 0)");
  sub->add_option("--spp", args->spp,
                  "reference samples per pixel, two independent halves together, so even (default 64); with --target-noise, "
                  "the first round's")
      ->check(CLI::Range(2, 1 << 20));
  sub->add_option("--target-noise", args->target_noise,
                  "render each reference in rounds until its own noise adds at most this relMSE (docs/reference.md); "
                  "default: one round of --spp");
  sub->add_option("--max-spp", args->max_spp, "with --target-noise: the most samples per pixel of a round (default 4096)")
      ->check(CLI::Range(2, 1 << 20));
  sub->add_option("--width", args->width, "image width (default: the scene camera's)")->check(CLI::Range(1, 16384));
  sub->add_option("--height", args->height, "image height (default: the scene camera's)")->check(CLI::Range(1, 16384));
  sub->add_option("--techniques", args->techniques, "comma-separated subset of the registered techniques (default: all)");
  sub->add_option("--seed", args->seed, "reference random seed (default 1)");
  sub->add_option("--backend", args->backends,
                  "comma-separated backends to render the techniques with (several: compared with the first registered, the "
                  "reference); " + backends_help());
  sub->add_option("--device", args->device,
                  "Vulkan device: index or name substring (default: $SOFTGI_VULKAN_DEVICE, else a GPU, else lavapipe)");
  sub->callback([args] { run_compare(*args); });
}
const CommandRegistrar registrar(register_compare);

}  // namespace

}  // namespace softgi::app
