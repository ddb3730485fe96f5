// What a paper figure measures, as data: the scene, the variants (a technique and parameter
// overrides each), the image and region the errors are taken over, the references and the ratios to
// report. Techniques declare their own experiments (Technique::experiments); `softgi experiment`
// runs any of them the same way (docs/experiments.md).
#pragma once

#include <string>
#include <vector>

namespace softgi::render {

struct ExperimentVariant {
  std::string label, technique;
  std::vector<std::string> params;  // "name=value" over the technique's defaults
};
struct ExperimentRatio {
  std::string a, b;  // variant labels: time(a) / time(b) and error(b) / error(a)
};
enum class ExperimentImage { Final, Indirect };
enum class ExperimentRegion { Surface, Ground };

struct ExperimentDef {
  std::string name, title, paper;  // paper: the figure and what it reports
  std::string scene;
  int width = 512, height = 512, quick_width = 48, quick_height = 48;
  double time = 0.0;
  std::vector<ExperimentVariant> variants;
  std::string baseline;  // label of the variant every other one is also compared with
  ExperimentImage image = ExperimentImage::Final;
  ExperimentRegion region = ExperimentRegion::Surface;
  std::vector<int> reference_orders = {0};  // 0 = full environment, n = its order-n SH projection
  bool silhouettes = false;                 // error shares in bands around depth discontinuities
  bool operator_curve = false;              // paper 000 Figure 5's operator error curve
  std::vector<ExperimentRatio> ratios;
  // Temporal stability over a camera path: the camera turned about its target by each of these
  // azimuths (degrees, about its up axis), one frame each, and the frame-to-frame change of each
  // variant's compared image against the reference's (docs/experiments.md).
  std::vector<double> camera_orbit_deg;
};

}  // namespace softgi::render
