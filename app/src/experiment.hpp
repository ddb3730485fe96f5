// What `softgi experiment` measures beyond metrics::compare: region masks from the G-buffer, error
// shares, relative squared error, medians of frame times, and a plain line plot drawn into an Image
// (no plotting library is available). docs/experiments.md describes how the results are read.
#pragma once

#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "softgi/image.hpp"
#include "softgi/render/gbuffer.hpp"
#include "softgi/scene/scene.hpp"

namespace softgi::app::experiment {

// Median of a non-empty sample (mean of the two middle values for an even count). Throws on empty.
double median(std::vector<double> v);

// The G-buffer's surface pixels (hits).
Mask surface_mask(const render::GBuffer& gb);

// The ground plane's pixels, for paper 000 Figure 5 ("relative squared error over the ground plane
// receiver"): the pixels showing the posed object whose node is named `ground_node`; when no object
// has that node name, the object seen in the most pixels. `chosen` receives how it was picked.
Mask object_mask(const render::GBuffer& gb, const scene::Scene& scene, const scene::PosedScene& posed,
                 const std::string& ground_node, std::string& chosen);

// Depth discontinuities of the display G-buffer: pixels p with a 4-neighbour q where exactly one of
// p, q is background, or both are surface and |z_p - z_q| > rel_jump * min(z_p, z_q) (eye-space
// depth). Returns the surface pixels within Chebyshev distance `radius` of such a pixel.
Mask silhouette_band(const render::GBuffer& gb, double rel_jump, int radius);

// Number of selected pixels (an empty mask selects every pixel of a w x h image).
long long count(const Mask& m, int w, int h);

// Sum over the masked pixels and channels of (a - b)^2, and of b^2, in double.
struct SquaredSums {
  double diff = 0.0, ref = 0.0;
};
SquaredSums squared_sums(const Image& a, const Image& b, const Mask& mask);

// Relative squared error sum |a - b|^2 / sum |b|^2 over the mask (b the reference); +inf where
// b is black over the mask and a is not, 0 where both are.
double relative_squared_error(const Image& a, const Image& b, const Mask& mask);

// Share of the squared error sum over `outer` that lies in `inner` (inner should be a subset of
// outer); 0 when there is no error at all.
double error_share(const Image& a, const Image& b, const Mask& inner, const Mask& outer);

// Pixels of `img` outside the mask set to black (error maps then show the counted pixels only).
Image masked(Image img, const Mask& m);

// A line plot: white background, grid lines at every x_step / y_step, axes, tick labels drawn with a
// built-in 3x5 digit font, one coloured polyline with square markers per series. Values outside
// [y_min, y_max] are clipped to the frame. Display-referred (write with io::write_png_display).
struct Series {
  glm::vec3 colour{0.0f};
  std::vector<double> x, y;
};
struct PlotAxes {
  double x_min = 0.0, x_max = 1.0, x_step = 0.1;
  double y_min = 0.0, y_max = 1.0, y_step = 0.1;
  int width = 640, height = 400;
};
Image line_plot(const std::vector<Series>& series, const PlotAxes& axes);

}  // namespace softgi::app::experiment
