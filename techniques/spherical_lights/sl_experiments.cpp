// Paper 001's figures and frame-rate table as experiments (`softgi experiment --list`;
// docs/experiments.md). Each compares spherical lights with SHEXP (shadows only, a registered
// technique) on the paper's validation scenes.
#include <string>
#include <vector>

#include "softgi/render/experiment_def.hpp"

namespace softgi::techniques::spherical_lights {

namespace {

// Spherical lights (per-sphere and per-object blocking, and shadows only) beside SHEXP, errors of
// `image` against the full and the order-4 SH ground truth.
render::ExperimentDef validation(const std::string& name, const std::string& title, const std::string& paper, const std::string& scene,
                                 double time, render::ExperimentImage image) {
  render::ExperimentDef e;
  e.name = name;
  e.title = title;
  e.paper = paper;
  e.scene = scene;
  e.time = time;
  e.width = e.height = 512;
  e.quick_width = e.quick_height = 48;
  e.variants = {{"sl", "spherical_lights", {}},
                {"sl_per_object", "spherical_lights", {"blocking=per_object"}},
                {"sl_shadows_only", "spherical_lights", {"indirect=false"}},
                {"shexp", "shexp", {}}};
  e.baseline = "sl";
  e.image = image;
  e.reference_orders = {0, 4};
  // Section 8.5's table: per-object against per-sphere blocking, shadows only against shadows plus
  // indirect light.
  e.ratios = {{"sl", "sl_per_object"}, {"sl", "sl_shadows_only"}};
  return e;
}

}  // namespace

std::vector<render::ExperimentDef> experiments() {
  using render::ExperimentImage;
  const std::string fig8 = "Figure 8: our solution against a path-traced reference (VRay irradiance maps), absolute "
                           "difference x2; error from the SL intensity approximation and SH truncation (one sphere), "
                           "blocker accumulation (several), precomputed occlusion and proxy volume (model).";
  std::vector<render::ExperimentDef> d;
  d.push_back(validation("sl_fig8_sphere", "One sphere on a plane (paper 001 Figure 8, row 1)", fig8, "sphere_plane", 0.0,
                         ExperimentImage::Final));
  d.push_back(validation("sl_fig8_spheres", "Several spheres (paper 001 Figure 8, row 2)", fig8, "spheres", 0.0, ExperimentImage::Final));
  d.push_back(validation("sl_fig8_model", "A model, the bunny (paper 001 Figure 8, row 3)", fig8, "bunny", 0.0, ExperimentImage::Final));
  d.push_back(validation("sl_fig8_benchmark", "Several animated objects (paper 001 Figure 8, row 4; section 8.5)", fig8, "assembly", 1.0,
                         ExperimentImage::Final));
  const std::string fig9 = "Figure 9: soft deformations, a bending cylinder; small error at 90 degrees, darker bands under "
                           "the cylinder at 180 degrees where non-emitting parts of the SLs become visible.";
  d.push_back(validation("sl_fig9_bend90", "Bending cylinder at 90 degrees (paper 001 Figure 9, row 1)", fig9, "bend", 1.0,
                         ExperimentImage::Indirect));
  d.push_back(validation("sl_fig9_bend180", "Bending cylinder at 180 degrees (paper 001 Figure 9, row 2)", fig9, "bend", 2.0,
                         ExperimentImage::Indirect));
  const std::string fig10 = "Figure 10: a box with one SL blurs the high frequencies of its reflected light (too weak near "
                            "the edges); eight SLs are closer to the reference.";
  d.push_back(validation("sl_fig10_box1", "Box with one SL (paper 001 Figure 10b)", fig10, "box1", 0.0, ExperimentImage::Indirect));
  d.push_back(validation("sl_fig10_box8", "Box with eight SLs (paper 001 Figure 10c)", fig10, "box8", 0.0, ExperimentImage::Indirect));
  return d;
}

}  // namespace softgi::techniques::spherical_lights
