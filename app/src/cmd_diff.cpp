// `softgi diff TEST REFERENCE`: image metrics between a test image and a reference, plus error maps.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <string>

#include "commands.hpp"
#include "output_dir.hpp"
#include "softgi/io/image_io.hpp"
#include "softgi/metrics/flip.hpp"
#include "softgi/metrics/image_metrics.hpp"
#include "softgi/metrics/reference_noise.hpp"

namespace softgi::app {

namespace {

// A mask file's pixel is counted when its brightest channel exceeds half (after sRGB linearisation,
// white = 1, black = 0), so 8-bit black/white masks and float masks read the same.
constexpr float kMaskThreshold = 0.5f;

struct DiffArgs {
  std::string test, reference;
  std::string metric = "all";
  std::string mask, map, signed_map;
  double relmse_epsilon = metrics::MetricOptions{}.relmse_epsilon;
  double psnr_peak = 0.0;
  double map_scale = 0.0;
  bool json = false;
  std::vector<std::string> halves;  // two independent halves of the reference: its noise taken out of relMSE
  // FLIP (docs/metrics.md#flip).
  std::string flip = "auto";  // ldr, hdr, or auto: LDR-FLIP when both files are 8-bit display formats
  std::string flip_map;
  double ppd = metrics::kFlipDefaultPpd;
  std::string tone_mapper = "aces";
  std::optional<double> start_exposure, stop_exposure;
  int exposures = 0;
};

// Display-referred formats, read as sRGB and linearised by read_image: LDR-FLIP compares them as shown.
bool display_format(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".bmp" || ext == ".tga" || ext == ".gif";
}

// LDR-FLIP takes the stored sRGB values; read_image decoded them (IEC 61966-2-1), so encode back. Values
// outside [0, 1] (an HDR file given --flip ldr) stay outside, and flip_ldr names the first of them.
Image srgb_encoded(const Image& linear) {
  Image out = linear;
  for (glm::vec3& p : out.rgb)
    for (int c = 0; c < 3; ++c) {
      const float v = p[c];
      p[c] = v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
    }
  return out;
}

metrics::FlipToneMapper parse_tone_mapper(const std::string& name) {
  if (name == "aces") return metrics::FlipToneMapper::aces;
  if (name == "hable") return metrics::FlipToneMapper::hable;
  return metrics::FlipToneMapper::reinhard;
}

Mask read_mask(const std::string& path) {
  const Image img = io::read_image(path);
  Mask m;
  m.width = img.width;
  m.height = img.height;
  m.on.resize(img.rgb.size());
  for (std::size_t i = 0; i < img.rgb.size(); ++i) {
    const glm::vec3& p = img.rgb[i];
    m.on[i] = std::max({p.r, p.g, p.b}) > kMaskThreshold ? 1 : 0;
  }
  return m;
}

// The peak compare() uses when none is given: the reference's largest channel value over counted pixels
// (0 when the reference is black there). Only for reporting; compare() has already validated the inputs.
double reference_peak(const Image& ref, const Mask& mask) {
  double peak = 0.0;
  for (std::size_t i = 0; i < ref.rgb.size(); ++i) {
    if (!mask.on.empty() && !mask.on[i]) continue;
    const glm::vec3& p = ref.rgb[i];
    peak = std::max(peak, static_cast<double>(std::max({p.r, p.g, p.b})));
  }
  return peak;
}

// JSON has no infinity: an infinite PSNR (identical images) is written as the string "inf" ("-inf" for
// a black reference), which e.g. Python's float() parses.
nlohmann::json json_number(double v) {
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  return v;
}

void check_option(const char* flag, double v, bool zero_allowed) {
  if (std::isfinite(v) && (v > 0.0 || (zero_allowed && v == 0.0))) return;
  std::ostringstream os;
  os << flag << " must be a finite number " << (zero_allowed ? ">= 0" : "> 0") << ", got " << v;
  throw std::invalid_argument(os.str());
}

void run_diff(const DiffArgs& args) {
  check_option("--epsilon", args.relmse_epsilon, false);
  check_option("--peak", args.psnr_peak, true);
  check_option("--map-scale", args.map_scale, true);
  // The map files are checked before the images are read.
  if (!args.map.empty() && args.map == args.signed_map)
    throw std::invalid_argument("--map and --signed-map name the same file '" + args.map + "'");
  for (const std::string* other : {&args.map, &args.signed_map})
    if (!args.flip_map.empty() && args.flip_map == *other)
      throw std::invalid_argument("--flip-map names the same file '" + args.flip_map + "' as another map");
  std::optional<OutputFile> map, signed_map, flip_map;
  if (!args.map.empty()) map.emplace(args.map, "--map");
  if (!args.flip_map.empty()) flip_map.emplace(args.flip_map, "--flip-map");
  if (!args.signed_map.empty()) signed_map.emplace(args.signed_map, "--signed-map");
  const Image test = io::read_image(args.test);
  const Image ref = io::read_image(args.reference);
  if (test.width != ref.width || test.height != ref.height)
    throw std::invalid_argument("image sizes differ: " + args.test + " is " + std::to_string(test.width) + "x" +
                                std::to_string(test.height) + ", reference " + args.reference + " is " +
                                std::to_string(ref.width) + "x" + std::to_string(ref.height));
  Mask mask;
  if (!args.mask.empty()) {
    mask = read_mask(args.mask);
    if (mask.width != test.width || mask.height != test.height)
      throw std::invalid_argument("mask " + args.mask + " is " + std::to_string(mask.width) + "x" +
                                  std::to_string(mask.height) + ", images are " + std::to_string(test.width) + "x" +
                                  std::to_string(test.height));
    if (std::none_of(mask.on.begin(), mask.on.end(), [](std::uint8_t v) { return v != 0; }))
      throw std::invalid_argument("mask " + args.mask + " selects no pixels (no pixel brighter than 0.5)");
  }
  metrics::MetricOptions opt;
  opt.relmse_epsilon = args.relmse_epsilon;
  opt.psnr_peak = args.psnr_peak;
  const metrics::Metrics m = metrics::compare(test, ref, mask, opt);
  std::optional<metrics::NoiseCorrectedError> nc;
  if (!args.halves.empty()) {
    const Image a = io::read_image(args.halves[0]), b = io::read_image(args.halves[1]);
    nc = metrics::noise_corrected_relmse(test, a, b, mask, opt.relmse_epsilon);
  }
  const double peak = args.psnr_peak > 0.0 ? args.psnr_peak : reference_peak(ref, mask);

  const bool all = args.metric == "all";
  auto want = [&](const char* name) { return all || args.metric == name; };
  std::optional<metrics::FlipResult> flip;
  bool flip_hdr = false;
  if (want("flip") || !args.flip_map.empty()) {
    flip_hdr = args.flip == "hdr" || (args.flip == "auto" && !(display_format(args.test) && display_format(args.reference)));
    metrics::FlipOptions fo;
    fo.ppd = args.ppd;
    if (flip_hdr) {
      fo.tone_mapper = parse_tone_mapper(args.tone_mapper);
      fo.start_exposure = args.start_exposure;
      fo.stop_exposure = args.stop_exposure;
      fo.num_exposures = args.exposures;
      // Renders of a model against an empty background are mostly black; the fallback is reported below.
      fo.positive_median_fallback = true;
      flip = metrics::flip_hdr(test, ref, fo);
    } else {
      if (args.start_exposure || args.stop_exposure || args.exposures != 0)
        throw std::invalid_argument("--start-exposure, --stop-exposure and --exposures apply to HDR-FLIP only (--flip hdr)");
      flip = metrics::flip_ldr(srgb_encoded(test), srgb_encoded(ref), fo);
    }
  }
  const double flip_value = flip ? metrics::flip_mean(*flip, mask) : 0.0;
  if (flip_map) {
    flip_map->write([&](const std::string& p) { io::write_png_display(p, metrics::flip_error_map(*flip)); });
  }

  double map_scale = 0.0;
  if (!args.map.empty() || !args.signed_map.empty()) map_scale = metrics::error_map_scale(test, ref, args.map_scale);
  if (map) map->write([&](const std::string& p) { io::write_png_display(p, metrics::error_map(test, ref, map_scale)); });
  if (signed_map)
    signed_map->write([&](const std::string& p) { io::write_png_display(p, metrics::signed_error_map(test, ref, map_scale)); });

  if (args.json) {
    nlohmann::json j;
    j["test"] = args.test;
    j["reference"] = args.reference;
    j["width"] = test.width;
    j["height"] = test.height;
    j["pixels"] = m.pixels;
    if (!args.mask.empty()) j["mask"] = args.mask;
    if (want("rmse")) j["rmse"] = m.rmse;
    if (want("relmse")) {
      j["relmse"] = m.relmse;
      j["relmse_epsilon"] = opt.relmse_epsilon;
    }
    if (nc && want("relmse")) {
      j["relmse_noise_corrected"] = {{"halves", args.halves},     {"raw", nc->raw},         {"reference_noise", nc->noise},
                                     {"corrected", nc->corrected}, {"ci95", {nc->ci_low, nc->ci_high}},
                                     {"below_noise_floor", nc->below_noise_floor()}};
    }
    if (want("psnr")) {
      j["psnr"] = json_number(m.psnr);
      j["psnr_peak"] = peak;
    }
    if (want("ssim")) j["ssim"] = m.ssim;
    if (flip) {
      nlohmann::json f = {{"mean", flip_value}, {"variant", flip_hdr ? "hdr" : "ldr"}, {"ppd", args.ppd}};
      if (flip_hdr) {
        f["tone_mapper"] = args.tone_mapper;
        f["start_exposure"] = flip->start_exposure;
        f["stop_exposure"] = flip->stop_exposure;
        f["exposures"] = flip->exposures;
        f["stop_from_positive_median"] = flip->stop_from_positive_median;
      }
      if (!args.flip_map.empty()) f["map"] = args.flip_map;
      j["flip"] = f;
    }
    j["max_abs"] = m.max_abs;
    if (!args.map.empty()) j["map"] = args.map;
    if (!args.signed_map.empty()) j["signed_map"] = args.signed_map;
    if (!args.map.empty() || !args.signed_map.empty()) j["map_scale"] = map_scale;
    std::cout << j.dump(1) << "\n";
    return;
  }
  std::cout << std::setprecision(6);
  std::cout << "test       " << args.test << " (" << test.width << "x" << test.height << ")\n"
            << "reference  " << args.reference << "\n"
            << "pixels     " << m.pixels << (args.mask.empty() ? "" : " (mask " + args.mask + ")") << "\n";
  if (want("rmse")) std::cout << "rmse       " << m.rmse << "\n";
  if (want("relmse")) std::cout << "relmse     " << m.relmse << "  (epsilon " << opt.relmse_epsilon << ")\n";
  if (nc && want("relmse"))
    std::cout << "relmse, reference noise removed  " << nc->corrected << "  95% [" << nc->ci_low << ", " << nc->ci_high
              << "]  (against the halves' mean " << nc->raw << ", of which their noise " << nc->noise << ")"
              << (nc->below_noise_floor() ? "  below the reference's noise floor" : "") << "\n";
  if (want("psnr"))
    std::cout << "psnr       " << m.psnr << " dB  (peak " << peak
              << (args.psnr_peak > 0.0 ? ", given" : " = reference max") << ")\n";
  if (want("ssim")) std::cout << "ssim       " << m.ssim << "\n";
  if (flip) {
    std::cout << "flip       " << flip_value << "  (" << (flip_hdr ? "HDR-FLIP" : "LDR-FLIP") << ", " << args.ppd
              << " pixels per degree";
    if (flip_hdr)
      std::cout << ", " << args.tone_mapper << ", " << flip->exposures.size() << " exposures from " << flip->start_exposure
                << " to " << flip->stop_exposure
                << (flip->stop_from_positive_median ? " (stop from the median of the non-black pixels: over half the "
                                                      "reference is black)"
                                                    : "");
    std::cout << ")\n";
    if (!args.flip_map.empty()) std::cout << "flip map   " << args.flip_map << "  (magma, black = 0, pale yellow = 1)\n";
  }
  std::cout << "max_abs    " << m.max_abs << "\n";
  const std::string scale_note = args.map_scale > 0.0 ? " (given)" : " (99th percentile of |luminance difference|)";
  if (!args.map.empty()) std::cout << "map        " << args.map << "  scale " << map_scale << scale_note << "\n";
  if (!args.signed_map.empty())
    std::cout << "signed map " << args.signed_map << "  scale " << map_scale << scale_note << "\n";
}

void register_diff(CLI::App& app) {
  auto args = std::make_shared<DiffArgs>();
  CLI::App* sub = app.add_subcommand("diff", "Compare a test image with a reference: RMSE, relMSE, PSNR, SSIM, error maps");
  sub->add_option("test", args->test, "test image (EXR, HDR, PNG, ...)")->required()->check(CLI::ExistingFile);
  sub->add_option("reference", args->reference, "reference image, same size")->required()->check(CLI::ExistingFile);
  sub->add_option("--metric", args->metric, "metric to print: all, rmse, relmse, psnr, ssim or flip")
      ->check(CLI::IsMember({"all", "rmse", "relmse", "psnr", "ssim", "flip"}));
  sub->add_option("--mask", args->mask, "mask image: pixels brighter than 0.5 are counted")->check(CLI::ExistingFile);
  sub->add_option("--map", args->map, "write a false-colour map of |luminance difference| (PNG)");
  sub->add_option("--signed-map", args->signed_map, "write a signed map: blue = test darker, red = test brighter (PNG)");
  sub->add_option("--map-scale", args->map_scale, "luminance difference shown as full colour (0: 99th percentile)");
  sub->add_option("--epsilon", args->relmse_epsilon, "relMSE epsilon: (a-b)^2 / (b^2 + epsilon), > 0");
  sub->add_option("--peak", args->psnr_peak, "PSNR peak (0: the reference's largest channel value)");
  sub->add_option("--halves", args->halves,
                  "two independent halves of the reference (same renderer and spp, other seeds): also print relMSE against "
                  "their mean with the reference's own noise removed, and its 95% interval")
      ->expected(2)
      ->check(CLI::ExistingFile);
  sub->add_option("--flip", args->flip,
                  "FLIP variant: ldr, hdr, or auto (LDR-FLIP when both files are PNG/JPEG/BMP/TGA/GIF, else HDR-FLIP)")
      ->check(CLI::IsMember({"auto", "ldr", "hdr"}));
  sub->add_option("--flip-map", args->flip_map, "write FLIP's per-pixel error through the magma map (PNG)");
  sub->add_option("--ppd", args->ppd, "FLIP observer: pixels per degree (default 67.02: 0.7 m from a 0.7 m wide 4K display)");
  sub->add_option("--tone-mapper", args->tone_mapper, "HDR-FLIP tone mapper: aces, hable or reinhard")
      ->check(CLI::IsMember({"aces", "hable", "reinhard"}));
  sub->add_option("--start-exposure", args->start_exposure, "HDR-FLIP start exposure, log2 (default: from the reference)");
  sub->add_option("--stop-exposure", args->stop_exposure, "HDR-FLIP stop exposure, log2 (default: from the reference)");
  sub->add_option("--exposures", args->exposures, "HDR-FLIP exposure count (0: max(2, ceil(stop - start)))");
  sub->add_flag("--json", args->json, "print JSON instead of text");
  sub->callback([args] { run_diff(*args); });
}
const CommandRegistrar registrar(register_diff);

}  // namespace

}  // namespace softgi::app
