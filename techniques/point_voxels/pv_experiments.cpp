// Paper 002's table and figures as experiments (`softgi experiment --list`; docs/experiments.md and
// docs/techniques/point_voxels.md): Table 1's per-stage times at two marching sizes, Figures 5 and 6
// as errors against the path-traced ground truth, the visibility filter's value, the shadow-ray
// count, and light leaking through a thin wall.
#include <string>
#include <vector>

#include "softgi/render/experiment_def.hpp"

namespace softgi::techniques::point_voxels {

namespace {

// The paper's settings per scene (section 4): 24k proxies on 6^3 voxels for the Cornell box, 170k on
// 20^3 for Sponza (here `atrium`); the visibility at 512 / s, the gathering at 256^2 of 512^2.
const std::vector<std::string> kCornell = {"proxy_count=24000", "grid=6"};
const std::vector<std::string> kSponza = {"proxy_count=170000", "grid=20"};

std::vector<std::string> with(std::vector<std::string> a, const std::vector<std::string>& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

render::ExperimentDef base(const std::string& name, const std::string& title, const std::string& paper, const std::string& scene,
                           render::ExperimentImage image) {
  render::ExperimentDef e;
  e.name = name;
  e.title = title;
  e.paper = paper;
  e.scene = scene;
  e.width = e.height = 512;
  e.quick_width = e.quick_height = 48;
  e.image = image;
  e.reference_orders = {0};
  return e;
}

}  // namespace

std::vector<render::ExperimentDef> experiments() {
  using render::ExperimentImage;
  std::vector<render::ExperimentDef> d;
  const std::string table1 = "Table 1: per-stage times (voxelisation, ray marching, visibility filter, illumination, upsampling) "
                             "at marching sizes 64^2 and 128^2 for the Cornell box (24k proxies, 6^3 voxels) and 128^2 for "
                             "Sponza (170k proxies, 20^3 voxels); 2.3, 1.4 and 1.3 fps on a GTX 670.";
  {
    auto e = base("pv_table1_cornell", "Per-stage times, Cornell box (paper 002 Table 1)", table1, "cornell_glossy", ExperimentImage::Final);
    e.variants = {{"march64", "point_voxels", with(kCornell, {"march_scale=8"})},
                  {"march128", "point_voxels", with(kCornell, {"march_scale=4"})}};
    e.baseline = "march128";
    e.ratios = {{"march128", "march64"}};
    d.push_back(e);
  }
  {
    auto e = base("pv_table1_atrium", "Per-stage times, the Sponza stand-in (paper 002 Table 1)", table1, "atrium", ExperimentImage::Final);
    e.variants = {{"march64", "point_voxels", with(kSponza, {"march_scale=8"})},
                  {"march128", "point_voxels", with(kSponza, {"march_scale=4"})}};
    e.baseline = "march128";
    e.ratios = {{"march128", "march64"}};
    d.push_back(e);
  }
  const std::string fig5 = "Figure 5: the Cornell box with a glossy floor (Ns = 50) against a ray-traced reference of 1024 "
                           "gathering rays per deferred pixel and against ISM; ours about 2 fps.";
  for (auto image : {ExperimentImage::Final, ExperimentImage::Indirect}) {
    const bool ind = image == ExperimentImage::Indirect;
    auto e = base(ind ? "pv_fig5_indirect" : "pv_fig5", ind ? "Glossy Cornell box, indirect light (paper 002 Figure 5)"
                                                             : "Glossy Cornell box (paper 002 Figure 5)",
                  fig5, "cornell_glossy", image);
    e.variants = {{"pv", "point_voxels", with(kCornell, {"march_scale=4"})},
                  {"pv_eq7", "point_voxels", with(kCornell, {"march_scale=4", "glossy_weight=eq7"})},
                  {"image_splat", "image_splat", {}},
                  {"spherical_lights", "spherical_lights", {}}};
    e.baseline = "pv";
    d.push_back(e);
  }
  {
    auto e = base("pv_fig6", "Glossiness Ns = 10 to 50, indirect light (paper 002 Figure 6)",
                  "Figure 6: glossy reflections of a dragon and a textured wall under glossiness Ns = 10 to 50 are "
                  "faithfully conveyed.",
                  "glossy_sweep", ExperimentImage::Indirect);
    e.variants = {{"pv", "point_voxels", {"march_scale=4"}},
                  {"pv_eq7", "point_voxels", {"march_scale=4", "glossy_weight=eq7"}},
                  {"pv_sh_only", "point_voxels", {"march_scale=4", "near_range=0"}}};
    e.baseline = "pv";
    d.push_back(e);
  }
  {
    auto e = base("pv_filter", "The visibility filter's value (paper 002 section 3.2)",
                  "Section 3.2: the sparse visibility test causes discontinuous visibility records; the visibility filter "
                  "(7 x 7 in the paper) unions the neighbours' lists under depth and normal constraints.",
                  "cornell_glossy", ExperimentImage::Indirect);
    e.variants = {{"no_filter", "point_voxels", with(kCornell, {"march_scale=4", "filter_radius=0"})},
                  {"filter3", "point_voxels", with(kCornell, {"march_scale=4", "filter_radius=1"})},
                  {"filter7", "point_voxels", with(kCornell, {"march_scale=4", "filter_radius=3"})}};
    e.baseline = "filter7";
    e.ratios = {{"filter7", "no_filter"}, {"filter7", "filter3"}};
    d.push_back(e);
  }
  {
    auto e = base("pv_rays", "Error against the number of shadow rays per pixel (paper 002 section 3.1)",
                  "Section 4, Discussion: by sharing occluded voxels the filter reduces the number of shadow rays needed.",
                  "cornell_glossy", ExperimentImage::Indirect);
    for (int r : {4, 8, 16, 32, 64})
      e.variants.push_back({"rays" + std::to_string(r), "point_voxels", with(kCornell, {"march_scale=4", "rays=" + std::to_string(r)})});
    e.variants.push_back({"rays8_no_filter", "point_voxels", with(kCornell, {"march_scale=4", "rays=8", "filter_radius=0"})});
    e.baseline = "rays64";
    e.ratios = {{"rays64", "rays8"}, {"rays8", "rays8_no_filter"}};
    d.push_back(e);
  }
  {
    // Over the right half's floor (the node named `ground`), where the reference has no light at all:
    // every error there is leaked light.
    auto e = base("pv_leak", "Light leaking through a thin wall",
                  "Voxel-based indirect light leaks through walls thinner than a voxel (the best-known failure of voxel "
                  "GI); the paper's visibility is resolved per voxel.",
                  "thin_wall", ExperimentImage::Indirect);
    e.region = render::ExperimentRegion::Ground;
    e.variants = {{"grid6", "point_voxels", {"grid=6"}},
                  {"grid12", "point_voxels", {"grid=12"}},
                  {"grid24", "point_voxels", {"grid=24"}},
                  {"grid12_sh_only", "point_voxels", {"grid=12", "near_range=0"}}};
    e.baseline = "grid12";
    d.push_back(e);
  }
  {
    // Section 4, Limitations: the sparse rays start from the low-resolution G-buffer, so the voxels
    // they find change with the viewpoint and the indirect light flickers; the filter smooths most of
    // it. 0.1 degree steps move the image about a pixel (45 degree field of view over 512 pixels).
    auto e = base("pv_temporal", "Temporal stability over a camera path",
                  "Section 4, Limitations: shadow rays cast from the low-resolution G-buffer change with the viewpoint, which "
                  "causes flickering during viewpoint animation; the visibility filter smooths most of it.",
                  "cornell_glossy", ExperimentImage::Indirect);
    e.variants = {{"no_filter", "point_voxels", with(kCornell, {"filter_radius=0"})},
                  {"filter3x3", "point_voxels", with(kCornell, {"filter_radius=1"})},
                  {"filter7x7", "point_voxels", with(kCornell, {"filter_radius=3"})}};
    e.baseline = "filter7x7";
    e.camera_orbit_deg = {0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7};
    d.push_back(e);
  }
  return d;
}

}  // namespace softgi::techniques::point_voxels
