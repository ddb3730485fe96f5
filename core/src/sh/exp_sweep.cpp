#include "softgi/sh/exp_sweep.hpp"

#include <cmath>
#include <random>

#include "softgi/sh/tables.hpp"

namespace softgi::sh {

std::vector<double> cap_log_vector(int order, double theta, const Vec3<double>& dir, double log_threshold) {
  std::vector<double> zh = cap_log_zh(order, theta, log_threshold);
  std::vector<double> f(num_coeffs(order));
  zh_rotate(order, zh.data(), dir, f.data());
  return f;
}

namespace {
double norm_hat(const std::vector<double>& f) {
  double s = 0;
  for (std::size_t i = 1; i < f.size(); ++i) s += f[i] * f[i];
  return std::sqrt(s);
}
Vec3<double> random_dir(std::mt19937& rng, bool upper) {
  std::normal_distribution<double> n;
  Vec3<double> d = normalize(Vec3<double>{n(rng), n(rng), n(rng)});
  if (upper && d.z < 0) d.z = -d.z;
  return d;
}
}  // namespace

std::vector<LogVisInput> single_cap_sweep(int order, double step_deg, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::vector<LogVisInput> out;
  for (double deg = 1.0; deg <= 89.0 + 1e-9; deg += step_deg) {
    LogVisInput in;
    in.max_theta = deg * kPi / 180.0;
    in.f = cap_log_vector(order, in.max_theta, random_dir(rng, false));
    in.norm = norm_hat(in.f);
    out.push_back(std::move(in));
  }
  return out;
}

std::vector<LogVisInput> cap_sum_sweep(int order, const std::vector<int>& counts, double min_deg, double max_deg,
                                       int repeats, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> uth(min_deg * kPi / 180.0, max_deg * kPi / 180.0);
  std::vector<LogVisInput> out;
  // Cache cap logs on a fine theta grid: the sweep needs thousands of caps.
  const int grid = 512;
  std::vector<std::vector<double>> zh(grid);
  for (int k = 0; k < grid; ++k) zh[k] = cap_log_zh(order, (kPi / 2) * k / (grid - 1));
  for (int m : counts) {
    for (int r = 0; r < repeats; ++r) {
      LogVisInput in;
      in.caps = m;
      in.f.assign(num_coeffs(order), 0.0);
      std::vector<double> tmp(num_coeffs(order));
      for (int c = 0; c < m; ++c) {
        double th = uth(rng);
        int k = static_cast<int>(std::lround(th / (kPi / 2) * (grid - 1)));
        in.max_theta = std::max(in.max_theta, (kPi / 2) * k / (grid - 1));
        zh_rotate(order, zh[k].data(), random_dir(rng, true), tmp.data());
        for (int i = 0; i < num_coeffs(order); ++i) in.f[i] += tmp[i];
      }
      in.norm = norm_hat(in.f);
      out.push_back(std::move(in));
    }
  }
  return out;
}

double reconstruction_error(int order, const double* a, const double* b) {
  static const SphereQuadrature q = make_sphere_quadrature(24);  // 1152 directions
  std::vector<double> d(num_coeffs(order));
  for (int i = 0; i < num_coeffs(order); ++i) d[i] = a[i] - b[i];
  double e = 0;
  for (const auto& s : q.dirs) e = std::max(e, std::abs(reconstruct(order, d.data(), s)));
  return e;
}

}  // namespace softgi::sh
