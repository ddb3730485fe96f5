// Spherical lights (paper 001): the average-radiance weight of section 6.1, tabulated as ZH by the
// angular radius theta of the light at the receiver, and its rotated ZH dot product (eq. 18). Not
// installed; include by path.
#pragma once

#include <cstddef>
#include <vector>

#include <glm/glm.hpp>

#include "softgi/sh/tables.hpp"

namespace softgi::techniques::spherical_lights {

// cos gamma of paper 001 eq. 17: the cosine between the surface normal at a point x of the light's
// sphere and the direction from x to the receiver p, clamped at 0 (back-facing from p). alpha is the
// angle at the centre between x and the axis centre -> p, theta the light's angular radius at p
// (|p - c| = r / sin theta). Closed form of eq. 17:
//   cos gamma = max(0, (cos alpha - sin theta) / sqrt(1 - 2 sin theta cos alpha + sin^2 theta)),
// 1 at alpha = 0 (theta < pi/2), max(0, cos alpha) at theta = 0, 0 everywhere at theta = pi/2.
double cos_gamma(double theta, double alpha);

// ZH coefficients of the normalised weight of eq. 16,
//   w_theta(alpha) = max(0, cos gamma(theta, alpha)) / int_S max(0, cos gamma) d omega_S,
// about +z, bands 0..order-1. ZH normalisation: w_l = int_S2 w_theta(omega) y_l0(omega) d omega with
// the orthonormal real SH of softgi::sh (y_l0 = sqrt((2l+1)/(4 pi)) P_l(cos alpha)). So w_0 = y_00 =
// 1/sqrt(4 pi) for every theta, and turned to axis d the weight's SH vector is
// f_lm = sqrt(4 pi/(2l+1)) w_l y_lm(d) (sh::zh_rotate). Limits: theta = 0 gives the ZH of
// max(0, cos alpha)/pi, theta = pi/2 a delta at alpha = 0 (w_l = y_l0(+z)). The SH core's
// sh::spherical_light_weight_zh(order, sin theta), in double. Throws std::invalid_argument for a bad
// order or theta.
std::vector<double> weight_zh(int order, double theta);

// w_theta tabulated at rows angles theta_k = k (pi/2)/(rows - 1), k = 0..rows-1, in float.
struct WeightTable {
  int order = 0, rows = 0;
  std::vector<float> w;  // rows x order: w[k * order + l] = w_l(theta_k) (normalisation of weight_zh)
  // out_w[0..order) = w_l(theta), linear in theta between rows, theta clamped to [0, pi/2].
  void lookup(float theta, float* out_w) const;
  std::size_t bytes() const { return w.size() * sizeof(float); }
};
// Throws std::invalid_argument unless 1 <= order <= sh::kMaxOrder and rows >= 2.
WeightTable make_weight_table(int order, int rows);
// The float copy of the core's table (sh::ShTables::sl_weight(), sampled in theta).
WeightTable weight_table_from(const sh::Table1D& table, int order);

// The average radiance of a light towards a receiver, eq. 18: L_bar = w_theta . L^c with w_theta
// rotated to dir_local, i.e. sum_l w_l(theta) sqrt(4 pi/(2l+1)) sum_m y_lm(dir_local) L_lm.
//  L: t.order^2 SH coefficients (softgi::sh basis) of the light's intensity in its own frame;
//  dir_local: unit direction from the light's centre to the receiver, in that frame;
//  theta: the light's angular radius at the receiver (asin(r / distance)).
float average_radiance(const WeightTable& t, const float* L, const glm::vec3& dir_local, float theta);

}  // namespace softgi::techniques::spherical_lights
