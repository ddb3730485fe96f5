// `softgi experiment NAME --out DIR [--quick]`: the measurements behind paper figures, as a small
// data-driven runner. An experiment is a list of variants (technique + parameters) on one scene at
// one resolution, sharing one ground truth per lighting; per variant a warm-up frame, the median of
// K timed frames (per pass too), errors against the ground truth and against a designated baseline
// variant, images and error maps. Results: DIR/index.md and DIR/results.json (docs/experiments.md).
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <iomanip>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "cached_reference.hpp"
#include "../../techniques/image_splat/splat_math.hpp"
#include "commands.hpp"
#include "experiment.hpp"
#include "frame_output.hpp"
#include "output_dir.hpp"
#include "softgi/io/scene_file.hpp"
#include "softgi/metrics/image_metrics.hpp"
#include "softgi/metrics/reference_noise.hpp"
#include "softgi/reference/reference.hpp"
#include "softgi/render/camera.hpp"
#include "softgi/render/common_passes.hpp"
#include "softgi/render/gbuffer.hpp"
#include "softgi/render/technique.hpp"
#include "softgi/techniques/registry.hpp"

namespace softgi::app {

namespace {

namespace ex = experiment;

// Frames are rendered 1/30 s apart (a running 30 Hz animation: per-frame proxy and BVH refits, no
// one-time setup in the timed frames); the last timed frame is at the experiment's time, where the
// ground truth is rendered.
constexpr double kFrameStep = 1.0 / 30.0;
// Silhouettes (Figure 7): a relative eye-space depth jump between 4-neighbours above this is a
// depth discontinuity. On the built-in ground planes seen from their cameras, neighbouring pixels of
// one surface differ by under 1 % at 512 pixels (about 6 % at 64 pixels: the --quick size); the
// character in front of the ground differs by far more than 10 %.
constexpr double kSilhouetteDepthJump = 0.1;
// Bands around the discontinuities in which the error share is reported: "a few pixels" (2) and the
// footprint of one coarse receiver at the largest receiver scale (8).
constexpr int kSilhouetteRadii[] = {2, 8};
// Figure 5 (top): order-3 operators (the paper's indirect order), sin(theta) from 0.05 to 0.95.
constexpr int kOperatorCurveOrder = 3;
constexpr double kOperatorCurveAlphaMin = 0.05, kOperatorCurveAlphaMax = 0.95;

using Compared = render::ExperimentImage;
using Region = render::ExperimentRegion;
using VariantDef = render::ExperimentVariant;
using ExperimentDef = render::ExperimentDef;

// Every registered technique's experiments, in registration order; names are unique.
std::vector<ExperimentDef> experiment_defs() {
  register_builtin();
  std::vector<ExperimentDef> d;
  for (const auto& t : render::technique_names())
    for (auto& e : render::create_technique(t)->experiments()) {
      for (const auto& other : d)
        if (other.name == e.name) throw std::logic_error("experiment '" + e.name + "' declared twice (technique " + t + ")");
      d.push_back(std::move(e));
    }
  return d;
}

std::string experiment_names() {
  std::string s;
  for (const auto& e : experiment_defs()) s += (s.empty() ? "" : ", ") + e.name;
  return s;
}

const ExperimentDef& find_experiment(const std::string& name) {
  static const std::vector<ExperimentDef> defs = experiment_defs();
  for (const auto& e : defs)
    if (e.name == name) return e;
  throw std::invalid_argument("experiment: unknown experiment '" + name + "' (known: " + experiment_names() + ")");
}

struct ExperimentArgs {
  std::string name, out;
  bool quick = false, list = false;
  int frames = 3, spp = 64;
  unsigned seed = 1;
  std::vector<std::string> overrides;  // --param NAME=VALUE for every variant whose technique has NAME
  std::string backend, device;         // the variants' backend ("" = the reference backend) and its device
};

std::string fmt(double v, int precision = 4) {
  if (std::isnan(v)) return "-";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  std::ostringstream os;
  os << std::setprecision(precision) << v;
  return os.str();
}
std::string ms(double seconds) {
  std::ostringstream os;
  os << std::fixed << std::setprecision(seconds < 0.01 ? 2 : 1) << seconds * 1e3;
  return os.str();
}
std::string pct(double fraction) { return fmt(100.0 * fraction, 3) + " %"; }
Json num(double v) { return std::isfinite(v) ? Json(v) : Json(v > 0 ? "inf" : std::isnan(v) ? "nan" : "-inf"); }

Json metrics_json(const metrics::Metrics& m) {
  return {{"relmse", num(m.relmse)}, {"ssim", num(m.ssim)}, {"rmse", num(m.rmse)}, {"psnr", num(m.psnr)},
          {"max_abs", num(m.max_abs)}, {"pixels", m.pixels}};
}

std::function<void(double)> progress_printer(const std::string& what) {
  auto next = std::make_shared<int>(0);
  return [what, next](double f) {
    const int p = static_cast<int>(f * 100.0);
    if (p < *next) return;
    std::cerr << "experiment: " << what << ": " << p << "%\n";
    *next = (p / 10 + 1) * 10;
  };
}

std::string ref_key(int order) { return order == 0 ? "full" : "sh" + std::to_string(order); }
std::string ref_label(int order) {
  return order == 0 ? "full environment" : "order-" + std::to_string(order) + " SH lighting";
}

struct Variant {
  VariantDef def;
  std::unique_ptr<render::Technique> technique;
  render::ParamSet params;
  std::string settings, error;
  render::FrameResult frame;  // the last timed frame (at the experiment's time)
  double warmup_seconds = 0.0, median_seconds = 0.0;
  std::vector<double> frame_seconds;
  std::vector<std::pair<std::string, double>> pass_median;  // in execution order
  std::map<std::string, metrics::Metrics> vs_ref;           // keyed by reference key
  metrics::Metrics vs_baseline;
  bool has_baseline = false;
  double rse_ref = NAN, rse_baseline = NAN;  // relative squared error over the region
  std::vector<double> silhouette_share;      // per kSilhouetteRadii, of the error against the baseline
  const Image& compared() const {
    return image == Compared::Indirect ? frame.indirect : frame.final_image;
  }
  Compared image = Compared::Final;
};

// The scene's camera turned about its target by `deg` degrees around its up axis.
scene::Scene orbited(const scene::Scene& sc, double deg) {
  scene::Scene out = sc;
  const glm::dvec3 target(sc.camera.target), up = glm::normalize(glm::dvec3(sc.camera.up));
  const glm::dvec3 d = glm::dvec3(sc.camera.position) - target;
  const double a = deg * 3.14159265358979323846 / 180.0, c = std::cos(a), s = std::sin(a);
  // Rodrigues' rotation of d about `up`.
  const glm::dvec3 r = d * c + glm::cross(up, d) * s + up * glm::dot(up, d) * (1.0 - c);
  out.camera.position = glm::vec3(target + r);
  return out;
}

// Noise-corrected errors as JSON: corrected value, raw, noise and the 95 % interval each.
Json temporal_json(const std::vector<metrics::NoiseCorrectedError>& v) {
  Json a = Json::array();
  for (const auto& e : v)
    a.push_back({{"corrected", num(e.corrected)}, {"raw", num(e.raw)}, {"noise", num(e.noise)}, {"ci95", {num(e.ci_low), num(e.ci_high)}}});
  return a;
}

// One variant's frames along the camera path and their frame-to-frame changes.
struct PathRun {
  std::vector<double> change;  // relMSE of frame k + 1 against frame k
  std::vector<metrics::NoiseCorrectedError> temporal;  // metrics::temporal_error of each step
  double mean_change = NAN, mean_temporal = NAN;
};

struct Reference {
  int order = 0;
  bool cached = false;  // served by the reference cache
  reference::ReferenceResult result;
  const Image& compared(Compared c) const { return c == Compared::Indirect ? result.indirect : result.final_image; }
};

// Median per pass over the timed frames (passes matched by name; a pass missing from some frame
// is reported over the frames that ran it).
std::vector<std::pair<std::string, double>> pass_medians(const std::vector<render::FrameResult>& frames) {
  std::vector<std::pair<std::string, double>> out;
  if (frames.empty()) return out;
  for (const auto& p : frames.back().passes) {
    std::vector<double> t;
    for (const auto& f : frames)
      for (const auto& q : f.passes)
        if (q.name == p.name) t.push_back(q.wall_seconds);
    out.emplace_back(p.name, ex::median(t));
  }
  return out;
}

void write_operator_curve(OutputDir& out, Json& j, std::ostringstream& md) {
  // operator_error_curve samples sin(theta) = k / samples, k = 1..samples: 20 gives 0.05, 0.10,
  // ..., 1; the figure's range [0.05, 0.95] keeps 19 of them.
  constexpr int kSamples = 20;
  const auto curve = techniques::image_splat::operator_error_curve(kOperatorCurveOrder, kSamples);
  Json rows = Json::array();
  ex::Series point{{0.85f, 0.1f, 0.1f}, {}, {}}, averaged{{0.1f, 0.35f, 0.85f}, {}, {}}, poly{{0.1f, 0.65f, 0.2f}, {}, {}};
  ex::Series point_abs = point, averaged_abs = averaged, poly_abs = poly;
  double y_max = 0.0, y_max_abs = 0.0;
  md << "## Operator error (Figure 5, top)\n\n"
     << "Frobenius norm of (operator - exact operator M(theta)) at SH order " << kOperatorCurveOrder
     << ", absolute and relative to ||M||_F (`image_splat::operator_error_curve`). Plot: relative error over sin(theta); "
     << "red = point-sampled, blue = averaged (D by quadrature), green = averaged with the paper's polynomial D "
     << "(blue lies under green where the fit is exact to the plot's resolution): [relative](operator_error.png), "
     << "[absolute](operator_error_abs.png).\n\n"
     << "| sin theta | point abs | point rel | averaged abs | averaged rel | averaged_poly abs | averaged_poly rel |\n"
     << "|---|---|---|---|---|---|---|\n";
  for (const auto& r : curve) {
    if (r.alpha < kOperatorCurveAlphaMin - 1e-9 || r.alpha > kOperatorCurveAlphaMax + 1e-9) continue;
    rows.push_back({{"alpha", r.alpha},
                    {"point_abs", num(r.point_abs)},
                    {"point_rel", num(r.point_rel)},
                    {"averaged_abs", num(r.averaged_abs)},
                    {"averaged_rel", num(r.averaged_rel)},
                    {"averaged_poly_abs", num(r.averaged_poly_abs)},
                    {"averaged_poly_rel", num(r.averaged_poly_rel)}});
    md << "| " << fmt(r.alpha, 3) << " | " << fmt(r.point_abs) << " | " << fmt(r.point_rel) << " | " << fmt(r.averaged_abs)
       << " | " << fmt(r.averaged_rel) << " | " << fmt(r.averaged_poly_abs) << " | " << fmt(r.averaged_poly_rel) << " |\n";
    point.x.push_back(r.alpha), point.y.push_back(r.point_rel);
    averaged.x.push_back(r.alpha), averaged.y.push_back(r.averaged_rel);
    if (r.averaged_poly_rel >= 0.0) poly.x.push_back(r.alpha), poly.y.push_back(r.averaged_poly_rel);
    point_abs.x.push_back(r.alpha), point_abs.y.push_back(r.point_abs);
    averaged_abs.x.push_back(r.alpha), averaged_abs.y.push_back(r.averaged_abs);
    if (r.averaged_poly_abs >= 0.0) poly_abs.x.push_back(r.alpha), poly_abs.y.push_back(r.averaged_poly_abs);
    for (double v : {r.point_rel, r.averaged_rel, r.averaged_poly_rel})
      if (std::isfinite(v)) y_max = std::max(y_max, v);
    for (double v : {r.point_abs, r.averaged_abs, r.averaged_poly_abs})
      if (std::isfinite(v)) y_max_abs = std::max(y_max_abs, v);
  }
  if (rows.empty()) throw std::runtime_error("experiment: operator_error_curve returned no sample in [0.05, 0.95]");
  md << "\n";
  // Two plots, relative and absolute error; y axes end at the next "nice" value (1, 2 or 5 times a
  // power of ten) above the largest error shown.
  auto axes_for = [](double largest) {
    ex::PlotAxes axes;
    axes.x_min = 0.0, axes.x_max = 1.0, axes.x_step = 0.1;
    const double decade = std::pow(10.0, std::floor(std::log10(std::max(largest, 1e-12))));
    double top = 10.0 * decade;
    for (double m : {1.0, 2.0, 5.0})
      if (m * decade >= largest) {
        top = m * decade;
        break;
      }
    axes.y_max = top;
    axes.y_step = top / 5.0;
    return axes;
  };
  out.write_png_display("operator_error.png", ex::line_plot({point, averaged, poly}, axes_for(y_max)));
  out.write_png_display("operator_error_abs.png", ex::line_plot({point_abs, averaged_abs, poly_abs}, axes_for(y_max_abs)));
  j["operator_error"] = {{"order", kOperatorCurveOrder},
                         {"plot_relative", "operator_error.png"},
                         {"plot_absolute", "operator_error_abs.png"},
                         {"samples", rows}};
}

// One run of an experiment, step by step (arguments and variants, regions, rendering, references,
// metrics, writing); the members are what the steps hand on.
class ExperimentRunner {
 public:
  ExperimentRunner(const ExperimentArgs& args, const ExperimentDef& def, bool spp_given, bool frames_given)
      : args(args),
        def(def),
        spp(args.quick && !spp_given ? 4 : args.spp),
        frames(args.quick && !frames_given ? 1 : args.frames),
        w(args.quick ? def.quick_width : def.width),
        h(args.quick ? def.quick_height : def.height) {}

  // Every variant's technique and parameters first: an unknown name fails before anything renders;
  // then the scene and the output folder.
  void make_variants() {
  check_distinct_params(args.overrides);
  std::vector<bool> override_used(args.overrides.size(), false);
  for (const auto& vd0 : def.variants) {
    Variant v;
    v.def = vd0;
    VariantDef& vd = v.def;
    // --param overrides go after the experiment's own assignments, to the techniques that have them.
    v.technique = render::create_technique(vd.technique);
    const render::ParamSet defaults = render::default_params(*v.technique);
    for (std::size_t k = 0; k < args.overrides.size(); ++k) {
      const std::string& a = args.overrides[k];
      const auto eq = a.find('=');
      if (eq == std::string::npos || eq == 0)
        throw std::invalid_argument("--param '" + a + "': expected NAME=VALUE");
      if (defaults.has(a.substr(0, eq))) {
        vd.params.push_back(a);
        override_used[k] = true;
      }
    }
    v.image = def.image;
    v.params = technique_params(*v.technique, vd.params);
    for (const auto& a : vd.params) v.settings += (v.settings.empty() ? "" : ", ") + a;
    if (v.settings.empty()) v.settings = "defaults";
    vars.push_back(std::move(v));
  }
  for (std::size_t k = 0; k < args.overrides.size(); ++k)
    if (!override_used[k]) {
      std::string techs;
      for (const auto& v : vars)
        if (techs.find(v.def.technique) == std::string::npos) techs += (techs.empty() ? "" : ", ") + v.def.technique;
      throw std::invalid_argument("--param '" + args.overrides[k] + "': unknown parameter for every technique of experiment '" +
                                  def.name + "' (" + techs + ")");
    }
  for (std::size_t i = 0; i < vars.size(); ++i)
    if (vars[i].def.label == def.baseline) baseline = static_cast<int>(i);
  if (!def.baseline.empty() && baseline < 0)
    throw std::logic_error("experiment '" + def.name + "': baseline '" + def.baseline + "' is no variant");

  out.emplace(args.out, "--out", "results.json");  // before the scene and the frames
  sc = io::load_scene(def.scene);
  print_scene_notices("experiment", sc);
  render::make_pinhole_camera(sc, w, h, "experiment");
  std::cerr << "experiment: " << def.name << ": scene '" << sc.name << "' at " << w << "x" << h << ", " << vars.size()
            << " variant(s), " << frames << " timed frame(s) each, reference " << spp << " spp\n";

  }

  // The masks errors are taken over.
  void measure_regions() {
  // The display G-buffer once, on the reference backend: the surface, ground and silhouette masks.
  // The variants are timed on --backend (default: the reference backend).
  backend_ptr = render::create_backend(render::reference_backend_name());
  render::Backend& backend = *backend_ptr;
  const std::string variants_on = args.backend.empty() ? render::reference_backend_name() : args.backend;
  if (variants_on != backend.name()) variants_ptr = make_backend(variants_on, args.device, "experiment");
  const scene::PosedScene posed = scene::evaluate(sc, def.time);
  {
    render::RenderRequest greq;
    greq.time = def.time;
    greq.width = w;
    greq.height = h;
    gb = std::move(render::render_gbuffer(backend, sc, greq).gbuffer);
  }
  surface = ex::surface_mask(gb);
  if (ex::count(surface, w, h) == 0) throw std::runtime_error("experiment: scene '" + sc.name + "' shows no surface");
  region_desc = "surface pixels (G-buffer hits)";
  region = surface;
  if (def.region == Region::Ground) {
    std::string chosen;
    region = ex::object_mask(gb, sc, posed, "ground", chosen);
    region_desc = "ground-plane pixels: " + chosen;
  }
  region_pixels = ex::count(region, w, h);
  if (def.silhouettes)
    for (int r : kSilhouetteRadii) bands.push_back(ex::silhouette_band(gb, kSilhouetteDepthJump, r));

  }

  void render_variants() {
  // Variants: a warm-up frame, then `frames` timed frames 1/30 s apart ending at def.time.
  render::Backend& backend = variants_ptr ? *variants_ptr : *backend_ptr;
  for (std::size_t k = 0; k < vars.size(); ++k) {
    Variant& v = vars[k];
    std::cerr << "experiment: [" << k + 1 << "/" << vars.size() << "] " << v.def.label << ": " << v.def.technique << " ("
              << v.settings << ")\n";
    try {
      render::RenderRequest req;
      req.width = w;
      req.height = h;
      req.outputs = {"final"};
      if (def.image == Compared::Indirect) req.outputs = {"final", "indirect"};
      req.time = def.time - frames * kFrameStep;
      {
        render::FrameResult warm = backend.render(*v.technique, sc, v.params, req);
        v.warmup_seconds = warm.total_seconds;
        backend.recycle(std::move(warm));  // the timed frames reuse its buffers, as a sequence would
      }
      std::vector<render::FrameResult> timed;
      for (int f = frames - 1; f >= 0; --f) {
        req.time = def.time - f * kFrameStep;
        render::FrameResult frame = backend.render(*v.technique, sc, v.params, req);
        v.frame_seconds.push_back(frame.total_seconds);
        if (f == 0) {
          timed.push_back(std::move(frame));
          break;
        }
        // Only the last frame's images are measured: the others keep their pass records, and their
        // buffers go back to the backend for the next frame.
        render::FrameResult records;
        records.passes = std::move(frame.passes);
        timed.push_back(std::move(records));
        backend.recycle(std::move(frame));
      }
      v.median_seconds = ex::median(v.frame_seconds);
      v.pass_median = pass_medians(timed);
      v.frame = std::move(timed.back());
      print_frame_warnings("experiment", v.frame);
      const Image& img = v.compared();
      if (img.empty())
        throw std::runtime_error(std::string("produced no ") + (def.image == Compared::Indirect ? "indirect" : "final") +
                                 " image (pruned? check the technique's parameters)");
      if (img.width != w || img.height != h)
        throw std::runtime_error("image is " + std::to_string(img.width) + "x" + std::to_string(img.height) + ", expected " +
                                 std::to_string(w) + "x" + std::to_string(h));
      std::cerr << "experiment:   median " << ms(v.median_seconds) << " ms per frame (warm-up " << ms(v.warmup_seconds)
                << " ms)\n";
    } catch (const std::exception& e) {
      v.error = e.what();
      failures.push_back(v.def.label + ": " + v.error);
      std::cerr << "experiment:   FAILED: " << v.error << "\n";
    }
  }
  if (baseline >= 0 && !vars[baseline].error.empty())
    throw std::runtime_error("experiment '" + def.name + "': the baseline variant '" + def.baseline +
                             "' failed: " + vars[baseline].error);

  }

  void render_references() {
  // Ground truth: real geometry as blockers, one-bounce indirect, every sample through the pixel
  // centre (the visibility of the one-sample G-buffer), as `softgi compare` renders it.
  for (int n : def.reference_orders) {
    Reference r;
    r.order = n;
    reference::ReferenceOptions opt;
    opt.spp = spp;
    opt.blockers = reference::ReferenceOptions::Blockers::Geometry;
    opt.light_sh_order = n;
    opt.indirect = true;
    opt.time = def.time;
    opt.seed = args.seed;
    opt.width = w;
    opt.height = h;
    opt.jitter = false;
    r.result = cached_reference(sc, opt, progress_printer("reference, " + ref_label(n)), r.cached);
    out->write_image_pair("reference_" + ref_key(n), r.result.final_image);
    if (def.image == Compared::Indirect) out->write_image_pair("reference_" + ref_key(n) + "_indirect", r.result.indirect);
    std::cerr << "experiment: reference, " << ref_label(n) << ": " << fmt(r.result.seconds, 3) << " s"
              << (r.cached ? " (cached: the time of the render that made it)" : "") << "\n";
    refs.push_back(std::move(r));
  }

  }

  void measure() {
  // Errors, images, error maps.
  const Image* base_img = baseline >= 0 ? &vars[baseline].compared() : nullptr;
  for (auto& v : vars) {
    if (!v.error.empty()) continue;
    const std::string dir = v.def.label + "/";
    out->write_image_pair(dir + "final", v.frame.final_image);
    if (!v.frame.direct.empty()) out->write_image_pair(dir + "direct", v.frame.direct);
    if (!v.frame.indirect.empty()) out->write_image_pair(dir + "indirect", v.frame.indirect);
    const Image& img = v.compared();
    try {
      for (const auto& r : refs) {
        const Image& ref = r.compared(def.image);
        v.vs_ref[ref_key(r.order)] = metrics::compare(img, ref, region);
        if (&r == &refs.front()) v.rse_ref = ex::relative_squared_error(img, ref, region);
        out->write_png_display(dir + "error_" + ref_key(r.order) + ".png",
                               metrics::error_map(ex::masked(img, region), ex::masked(ref, region)));
      }
      if (base_img && &img != base_img) {
        v.vs_baseline = metrics::compare(img, *base_img, region);
        v.has_baseline = true;
        v.rse_baseline = ex::relative_squared_error(img, *base_img, region);
        out->write_png_display(dir + "error_baseline.png",
                               metrics::error_map(ex::masked(img, region), ex::masked(*base_img, region)));
        for (const Mask& band : bands) v.silhouette_share.push_back(ex::error_share(img, *base_img, band, region));
      }
    } catch (const std::exception& e) {
      v.error = std::string("metrics: ") + e.what();
      failures.push_back(v.def.label + ": " + v.error);
    }
  }
  }

  // Temporal stability over def.camera_orbit_deg (the paper's limitation: the sparse rays' origins
  // and directions change with the viewpoint, so the voxels found change from frame to frame): each
  // variant's compared image at every camera, and the reference's as two independent halves, so
  // that its frame-to-frame change can be measured with its own noise taken out.
  void measure_camera_path() {
  if (def.camera_orbit_deg.size() < 2) return;
  render::Backend& backend = variants_ptr ? *variants_ptr : *backend_ptr;
  const std::size_t n = def.camera_orbit_deg.size();
  std::vector<scene::Scene> scenes;
  for (double deg : def.camera_orbit_deg) scenes.push_back(orbited(sc, deg));
  std::vector<std::pair<Image, Image>> halves;
  for (std::size_t k = 0; k < n; ++k) {
    std::pair<Image, Image> hk;
    for (int half = 0; half < 2; ++half) {
      reference::ReferenceOptions opt;
      opt.spp = std::max(1, spp / 2);
      opt.blockers = reference::ReferenceOptions::Blockers::Geometry;
      opt.light_sh_order = 0;
      opt.indirect = true;
      opt.time = def.time;
      // Every frame's halves have seeds of their own: frames sharing a seed would share their noise
      // (the camera barely moves), and the noise estimates below take the frames' noises as independent.
      opt.seed = args.seed + 7919u * static_cast<unsigned>(half + 1) + 104729u * static_cast<unsigned>(k + 1);
      opt.width = w;
      opt.height = h;
      opt.jitter = false;
      bool cached = false;
      const auto r = cached_reference(scenes[k], opt,
                                      progress_printer("camera path reference " + std::to_string(k + 1) + "/" + std::to_string(n) +
                                                       (half == 0 ? " (half a)" : " (half b)")),
                                      cached);
      (half == 0 ? hk.first : hk.second) = def.image == Compared::Indirect ? r.indirect : r.final_image;
    }
    halves.push_back(std::move(hk));
  }
  double sum = 0.0;
  for (std::size_t k = 0; k + 1 < n; ++k) {
    path_ref_change.push_back(metrics::noise_corrected_relmse_between(halves[k + 1].first, halves[k + 1].second, halves[k].first,
                                                                      halves[k].second));
    sum += path_ref_change.back().corrected;
  }
  path_ref_mean = sum / static_cast<double>(n - 1);
  out->write_image_pair("camera_path/reference_0", metrics::mean_of_halves(halves[0].first, halves[0].second));
  out->write_png_display("camera_path/reference_change_0_1.png",
                         metrics::error_map(metrics::mean_of_halves(halves[1].first, halves[1].second),
                                            metrics::mean_of_halves(halves[0].first, halves[0].second)));
  path_runs.assign(vars.size(), PathRun{});
  for (std::size_t vi = 0; vi < vars.size(); ++vi) {
    Variant& v = vars[vi];
    if (!v.error.empty()) continue;
    std::cerr << "experiment: camera path, " << v.def.label << "\n";
    std::vector<Image> frames;
    try {
      for (std::size_t k = 0; k < n; ++k) {
        render::RenderRequest req;
        req.width = w;
        req.height = h;
        req.time = def.time;
        req.outputs = {"final"};
        if (def.image == Compared::Indirect) req.outputs = {"final", "indirect"};
        render::FrameResult f = backend.render(*v.technique, scenes[k], v.params, req);
        frames.push_back(def.image == Compared::Indirect ? std::move(f.indirect) : std::move(f.final_image));
      }
    } catch (const std::exception& e) {
      v.error = std::string("camera path: ") + e.what();
      failures.push_back(v.def.label + ": " + v.error);
      continue;
    }
    PathRun& run = path_runs[vi];
    double total = 0.0, total_t = 0.0;
    for (std::size_t k = 0; k + 1 < n; ++k) {
      run.change.push_back(metrics::compare(frames[k + 1], frames[k]).relmse);
      run.temporal.push_back(metrics::temporal_error(frames[k], frames[k + 1], halves[k].first, halves[k].second, halves[k + 1].first,
                                                     halves[k + 1].second, {}, metrics::MetricOptions{}.relmse_epsilon));
      total += run.change.back();
      total_t += run.temporal.back().corrected;
    }
    run.mean_change = total / static_cast<double>(n - 1);
    run.mean_temporal = total_t / static_cast<double>(n - 1);
    out->write_image_pair("camera_path/" + v.def.label + "_0", frames[0]);
    out->write_png_display("camera_path/" + v.def.label + "_change_0_1.png", metrics::error_map(frames[1], frames[0]));
  }
  }

  // The camera path's section of index.md and results.json.
  void write_camera_path(Json& j, std::ostringstream& md) {
  if (path_runs.empty()) return;
  const std::string image_name = def.image == Compared::Indirect ? "indirect" : "final";
  md << "## Temporal stability over a camera path\n\n"
     << "The camera turned about its target by";
  for (double d : def.camera_orbit_deg) md << " " << fmt(d, 3);
  md << " degrees (about its up axis), one frame each. Frame-to-frame change: relMSE of the " << image_name
     << " image of frame k + 1 against frame k, averaged over the " << def.camera_orbit_deg.size() - 1
     << " steps; the reference's with its noise taken out (two independent halves of " << std::max(1, spp / 2)
     << " spp per frame; `metrics::noise_corrected_relmse_between`). Temporal error: mean of ((t_{k+1} - t_k) - (r_{k+1} - r_k))^2 / "
        "(r_k^2 + eps) over the pixels, less what the reference's noise adds: how far the frame-to-frame change departs from the "
        "true one (0 for an error that is the same in every frame; flicker adds to it). Images: [reference, frame 0](camera_path/reference_0.png), "
        "[reference change 0 -> 1](camera_path/reference_change_0_1.png).\n\n"
     << "| variant | mean change | reference's mean change | ratio | temporal error | change per step | temporal error per step | images |\n"
        "|---|---|---|---|---|---|---|---|\n";
  Json jp = {{"orbit_deg", def.camera_orbit_deg}, {"reference_half_spp", std::max(1, spp / 2)}};
  jp["reference_change"] = temporal_json(path_ref_change);
  jp["reference_mean_change"] = num(path_ref_mean);
  Json jv = Json::array();
  for (std::size_t vi = 0; vi < vars.size(); ++vi) {
    const Variant& v = vars[vi];
    const PathRun& r = path_runs[vi];
    if (!v.error.empty() || r.change.empty()) continue;
    std::string steps, tsteps;
    for (double c : r.change) steps += (steps.empty() ? "" : ", ") + fmt(c, 3);
    for (const auto& c : r.temporal) tsteps += (tsteps.empty() ? "" : ", ") + fmt(c.corrected, 3);
    const double ratio = r.mean_change / path_ref_mean;
    md << "| " << v.def.label << " | " << fmt(r.mean_change) << " | " << fmt(path_ref_mean) << " | " << fmt(ratio, 3) << " | "
       << fmt(r.mean_temporal) << " | " << steps << " | " << tsteps << " | [frame 0](camera_path/" << v.def.label
       << "_0.png) · [change 0 -> 1](camera_path/" << v.def.label << "_change_0_1.png) |\n";
    jv.push_back({{"label", v.def.label},
                  {"change", r.change},
                  {"mean_change", num(r.mean_change)},
                  {"ratio_to_reference", num(ratio)},
                  {"temporal_error", temporal_json(r.temporal)},
                  {"mean_temporal_error", num(r.mean_temporal)}});
  }
  md << "\n";
  jp["variants"] = jv;
  j["camera_path"] = jp;
  }

  // results.json, index.md, images; then the failures, if any.
  void write() {
  render::Backend& backend = variants_ptr ? *variants_ptr : *backend_ptr;
  auto find_var = [&](const std::string& label) -> const Variant* {
    for (const auto& v : vars)
      if (v.def.label == label) return v.error.empty() ? &v : nullptr;
    return nullptr;
  };
  const std::string image_name = def.image == Compared::Indirect ? "indirect" : "final";

  // results.json
  Json j = {{"softgi_version", softgi_version()},
            {"date", utc_now()},
            {"experiment", def.name},
            {"title", def.title},
            {"paper", def.paper},
            {"quick", args.quick},
            {"scene", scene_json(sc, def.scene)},
            {"frame_time", def.time},
            {"resolution", {w, h}},
            {"backend", backend.name()},
            {"device", device_json(backend)},
            {"timed_frames", frames},
            {"param_overrides", args.overrides},
            {"frame_step_seconds", kFrameStep},
            {"compared_image", image_name},
            {"region", {{"description", region_desc}, {"pixels", region_pixels}}},
            {"baseline", def.baseline.empty() ? Json(nullptr) : Json(def.baseline)},
            {"metric_options", {{"relmse_epsilon", metrics::MetricOptions{}.relmse_epsilon}}}};
  Json jrefs = Json::array();
  for (const auto& r : refs)
    jrefs.push_back({{"key", ref_key(r.order)},
                     {"light_sh_order", r.order},
                     {"spp", r.result.spp},
                     {"seconds", r.result.seconds},
                     {"rays", r.result.rays},
                     {"cached", r.cached},
                     {"image", "reference_" + ref_key(r.order) + ".png"}});
  j["references"] = jrefs;
  if (def.silhouettes) {
    Json jb = Json::array();
    for (std::size_t b = 0; b < bands.size(); ++b)
      jb.push_back({{"radius_pixels", kSilhouetteRadii[b]},
                    {"pixels", ex::count(bands[b], w, h)},
                    {"area_share", static_cast<double>(ex::count(bands[b], w, h)) / region_pixels}});
    j["silhouette_bands"] = {{"depth_jump", kSilhouetteDepthJump}, {"bands", jb}};
  }
  Json jvars = Json::array();
  for (const auto& v : vars) {
    Json jv = {{"label", v.def.label}, {"technique", v.def.technique}, {"settings", v.settings}, {"params", params_json(v.params)}};
    if (!v.error.empty()) {
      jv["error"] = v.error;
      jvars.push_back(jv);
      continue;
    }
    jv["median_frame_seconds"] = v.median_seconds;
    jv["frame_seconds"] = v.frame_seconds;
    jv["warmup_frame_seconds"] = v.warmup_seconds;
    Json pm = Json::array();
    for (const auto& [n, t] : v.pass_median) pm.push_back({{"name", n}, {"median_seconds", t}});
    jv["pass_medians"] = pm;
    jv["last_frame"] = frame_json(v.frame);
    Json er = Json::object();
    for (const auto& [k, m] : v.vs_ref) er[k] = metrics_json(m);
    jv["errors_vs_reference"] = er;
    if (!refs.empty()) jv["relative_squared_error_vs_reference"] = num(v.rse_ref);
    if (v.has_baseline) {
      jv["errors_vs_baseline"] = metrics_json(v.vs_baseline);
      jv["relative_squared_error_vs_baseline"] = num(v.rse_baseline);
      if (def.silhouettes) {
        Json s = Json::array();
        for (std::size_t b = 0; b < v.silhouette_share.size(); ++b)
          s.push_back({{"radius_pixels", kSilhouetteRadii[b]}, {"error_share", num(v.silhouette_share[b])}});
        jv["silhouette_error_share"] = s;
      }
    }
    Json images = {{"final", v.def.label + "/final.png"}};
    if (!v.frame.indirect.empty()) images["indirect"] = v.def.label + "/indirect.png";
    for (const auto& r : refs) images["error_" + ref_key(r.order)] = v.def.label + "/error_" + ref_key(r.order) + ".png";
    if (v.has_baseline) images["error_baseline"] = v.def.label + "/error_baseline.png";
    jv["images"] = images;
    jvars.push_back(jv);
  }
  j["variants"] = jvars;

  // index.md
  std::ostringstream md;
  md << "# softgi experiment " << def.name << ": " << def.title << "\n\n"
     << def.paper << "\n\n"
     << "Scene `" << def.scene << "`, " << w << "x" << h << ", t = " << def.time << " s" << (args.quick ? " (--quick sizes)" : "")
     << "; softgi " << softgi_version() << ", " << utc_now() << ", " << backend.name() << " backend. Times: median of " << frames
     << " frame(s) 1/30 s apart after an untimed warm-up frame. Errors on the " << image_name << " image over "
     << region_pixels << " " << region_desc << "; relMSE = mean (a - b)^2 / (b^2 + " << metrics::MetricOptions{}.relmse_epsilon
     << "), RSE = sum (a - b)^2 / sum b^2 (relative squared error).";
  if (!refs.empty()) {
    md << " Ground truth: Embree path tracer, real geometry as blockers, one-bounce indirect, " << spp
       << " spp through each pixel centre, lit by ";
    for (std::size_t i = 0; i < refs.size(); ++i)
      md << (i ? " and by " : "") << "the " << ref_label(refs[i].order) << " ([image](reference_" << ref_key(refs[i].order)
         << ".png), " << fmt(refs[i].result.seconds, 3) << " s)";
    md << ".";
  }
  if (baseline >= 0) md << " Baseline variant: `" << def.baseline << "`.";
  if (!args.overrides.empty()) {
    md << " Overrides (`--param`, for every technique that has the parameter):";
    for (const auto& a : args.overrides) md << " `" << a << "`";
    md << ".";
  }
  md << "\n\n";
  md << "| variant | settings | median (ms) | passes (median ms) |";
  for (const auto& r : refs) md << " relMSE vs " << ref_key(r.order) << " | SSIM vs " << ref_key(r.order) << " |";
  if (!refs.empty()) md << " RSE vs " << ref_key(refs.front().order) << " |";
  if (baseline >= 0) md << " relMSE vs baseline | SSIM vs baseline | RSE vs baseline |";
  md << " images |\n|";
  const int cols = 5 + 2 * static_cast<int>(refs.size()) + (refs.empty() ? 0 : 1) + (baseline >= 0 ? 3 : 0);
  for (int c = 0; c < cols; ++c) md << "---|";
  md << "\n";
  for (const auto& v : vars) {
    md << "| " << v.def.label << " | " << v.def.technique << ": " << v.settings << " | ";
    if (!v.error.empty()) {
      std::string why = v.error;
      for (std::size_t p = why.find('|'); p != std::string::npos; p = why.find('|', p + 2)) why.replace(p, 1, "\\|");
      md << "failed: " << why;
      for (int c = 3; c < cols; ++c) md << " |";
      md << "\n";
      continue;
    }
    std::string passes;
    for (const auto& [n, t] : v.pass_median) passes += (passes.empty() ? "" : ", ") + n + " " + ms(t);
    md << ms(v.median_seconds) << " | " << passes << " |";
    for (const auto& r : refs) {
      const auto& m = v.vs_ref.at(ref_key(r.order));
      md << " " << fmt(m.relmse) << " | " << fmt(m.ssim) << " |";
    }
    if (!refs.empty()) md << " " << fmt(v.rse_ref) << " |";
    if (baseline >= 0) {
      if (v.has_baseline)
        md << " " << fmt(v.vs_baseline.relmse) << " | " << fmt(v.vs_baseline.ssim) << " | " << fmt(v.rse_baseline) << " |";
      else
        md << " (baseline) | | |";
    }
    md << " [" << image_name << "](" << v.def.label << "/" << image_name << ".png)";
    if (!refs.empty()) md << " · [error vs " << ref_key(refs.front().order) << "](" << v.def.label << "/error_" << ref_key(refs.front().order) << ".png)";
    if (v.has_baseline) md << " · [error vs baseline](" << v.def.label << "/error_baseline.png)";
    md << " |\n";
  }
  md << "\n";

  if (!def.ratios.empty()) {
    Json jr = Json::array();
    md << "## Ratios\n\nspeed = median time of A / median time of B (above 1: B is faster); error = relMSE of B / relMSE of A "
          "against each reference (above 1: B is worse).\n\n| A | B | speed (A/B) |";
    for (const auto& r : refs) md << " error vs " << ref_key(r.order) << " (B/A) |";
    md << "\n|---|---|---|";
    for (std::size_t i = 0; i < refs.size(); ++i) md << "---|";
    md << "\n";
    for (const auto& rd : def.ratios) {
      const Variant* a = find_var(rd.a);
      const Variant* b = find_var(rd.b);
      if (!a || !b) {
        md << "| " << rd.a << " | " << rd.b << " | (a variant failed) |";
        for (std::size_t i = 0; i < refs.size(); ++i) md << " |";
        md << "\n";
        continue;
      }
      const double speed = a->median_seconds / b->median_seconds;
      Json jrow = {{"a", rd.a}, {"b", rd.b}, {"speed_a_over_b", num(speed)}};
      md << "| " << rd.a << " | " << rd.b << " | " << fmt(speed, 3) << " |";
      for (const auto& r : refs) {
        const std::string k = ref_key(r.order);
        const double err = b->vs_ref.at(k).relmse / a->vs_ref.at(k).relmse;
        jrow["relmse_b_over_a_vs_" + k] = num(err);
        md << " " << fmt(err, 3) << " |";
      }
      md << "\n";
      jr.push_back(jrow);
    }
    md << "\n";
    j["ratios"] = jr;
  }

  if (def.silhouettes && baseline >= 0) {
    md << "## Error at silhouettes\n\nDepth discontinuities of the display G-buffer: 4-neighbours where exactly one is "
          "background or whose eye-space depths differ by more than "
       << kSilhouetteDepthJump * 100 << " % of the nearer. Share of the squared error against the baseline (`"
       << def.baseline << "`) that lies within r pixels of one, next to the share of the surface those pixels cover.\n\n";
    md << "| variant |";
    for (std::size_t b = 0; b < bands.size(); ++b)
      md << " error share r=" << kSilhouetteRadii[b] << " (area " << pct(static_cast<double>(ex::count(bands[b], w, h)) / region_pixels)
         << ") |";
    md << "\n|---|";
    for (std::size_t b = 0; b < bands.size(); ++b) md << "---|";
    md << "\n";
    for (const auto& v : vars) {
      if (!v.error.empty() || !v.has_baseline) continue;
      md << "| " << v.def.label << " |";
      for (double s : v.silhouette_share) md << " " << pct(s) << " |";
      md << "\n";
    }
    md << "\n";
  }

  if (def.operator_curve) write_operator_curve(*out, j, md);
  write_camera_path(j, md);

  std::string pruned;
  for (const auto& v : vars)
    for (const auto& p : v.frame.pruned) pruned += "- " + v.def.label + ": `" + p.name + "`: " + p.reason + "\n";
  if (!pruned.empty()) md << "Pruned passes:\n\n" << pruned;

  out->write_text("index.md", md.str());
  out->finish(j);  // results.json, the record, last
  std::cerr << "experiment: wrote " << out->path("index.md") << " and " << out->path("results.json") << "\n";

  if (!failures.empty()) {
    std::string msg = "experiment '" + def.name + "': " + std::to_string(failures.size()) + " variant(s) failed:";
    for (const auto& f : failures) msg += " [" + f + "]";
    throw std::runtime_error(msg);
  }
  }

 private:
  const ExperimentArgs& args;
  const ExperimentDef& def;
  const int spp, frames, w, h;
  std::vector<Variant> vars;
  int baseline = -1;
  scene::Scene sc;
  std::unique_ptr<render::Backend> backend_ptr;   // the reference backend
  std::unique_ptr<render::Backend> variants_ptr;  // --backend, when it is another
  render::GBuffer gb;
  Mask surface, region;
  std::string region_desc;
  long long region_pixels = 0;
  std::vector<Mask> bands;
  std::vector<std::string> failures;
  std::vector<Reference> refs;
  std::vector<PathRun> path_runs;          // per variant, along def.camera_orbit_deg
  std::vector<metrics::NoiseCorrectedError> path_ref_change;  // the reference's, noise removed
  double path_ref_mean = NAN;
  std::optional<OutputDir> out;  // DIR and its record, results.json
};

void run_experiment(const ExperimentArgs& args, bool spp_given, bool frames_given) {
  if (args.list) {
    for (const auto& e : experiment_defs()) std::cout << e.name << "  " << e.title << "\n";
    return;
  }
  if (args.name.empty()) throw std::invalid_argument("experiment: no experiment named (known: " + experiment_names() + ")");
  if (args.out.empty()) throw std::invalid_argument("experiment: --out is required");
  register_builtin();
  if (!args.backend.empty()) check_backend(args.backend);
  if (!args.device.empty() && !render::backend_info(args.backend.empty() ? render::reference_backend_name() : args.backend).selects_device)
    throw std::invalid_argument("--device '" + args.device + "': the " +
                                (args.backend.empty() ? render::reference_backend_name() : args.backend) + " backend selects no device");

  ExperimentRunner run(args, find_experiment(args.name), spp_given, frames_given);
  run.make_variants();
  run.measure_regions();
  run.render_variants();
  run.render_references();
  run.measure();
  run.measure_camera_path();
  run.write();
}

void register_experiment(CLI::App& app) {
  auto args = std::make_shared<ExperimentArgs>();
  CLI::App* sub = app.add_subcommand(
      "experiment", "Run a named measurement (paper figures): variants, times, errors, images, index.md, results.json");
  sub->add_option("name", args->name, "experiment: " + experiment_names());
  sub->add_option("--out", args->out, "output directory");
  CLI::Option* spp = sub->add_option("--spp", args->spp, "reference samples per pixel (default 64; 4 with --quick)")
                         ->check(CLI::Range(1, 1 << 20));
  CLI::Option* frames =
      sub->add_option("--frames", args->frames, "timed frames per variant, median reported (default 3; 1 with --quick)")
          ->check(CLI::Range(1, 1000));
  sub->add_flag("--quick", args->quick, "tiny sizes and few samples (tests)");
  sub->add_option("--seed", args->seed, "reference random seed (default 1)");
  sub->add_option("--param", args->overrides,
                  "NAME=VALUE for every variant whose technique has parameter NAME, after the experiment's own (repeatable)");
  sub->add_flag("--list", args->list, "list the experiments");
  sub->add_option("--backend", args->backend, "backend the variants are timed on (the masks and references use the reference backend): " +
                                                  backends_help());
  sub->add_option("--device", args->device, "device of a backend that selects one (name substring or index)");
  sub->callback([args, spp, frames] { run_experiment(*args, spp->count() > 0, frames->count() > 0); });
}
const CommandRegistrar registrar(register_experiment);

}  // namespace

}  // namespace softgi::app
