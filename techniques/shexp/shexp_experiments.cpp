// SHEXP's experiments (`softgi experiment --list`; docs/experiments.md).
#include <string>
#include <vector>

#include "softgi/render/experiment_def.hpp"

namespace softgi::techniques::shexp {

std::vector<render::ExperimentDef> experiments() {
  std::vector<render::ExperimentDef> d;
  {
    render::ExperimentDef e;
    e.name = "shexp_orders";
    e.title = "SHEXP at SH orders 3 to 6 (runner check; paper 004)";
    e.paper = "Not a figure: SHEXP's shadow error and cost as the SH order grows, the highest order as baseline.";
    e.scene = "spheres";
    e.width = e.height = 256;
    e.quick_width = e.quick_height = 40;
    for (int n : {3, 4, 5, 6}) e.variants.push_back({"order" + std::to_string(n), "shexp", {"order=" + std::to_string(n)}});
    e.baseline = "order6";
    e.reference_orders = {0, 4};
    e.ratios = {{"order6", "order3"}};
    d.push_back(e);
  }
  return d;
}

}  // namespace softgi::techniques::shexp
