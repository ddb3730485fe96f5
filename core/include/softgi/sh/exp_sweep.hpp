// Reproducible test inputs for the SH exponential and the error measure used by tests, benchmarks
// and docs: log-visibility vectors of single caps and of sums of random caps (paper 004 eq. 8).
#pragma once

#include <cstdint>
#include <vector>

#include "softgi/sh/sh.hpp"

namespace softgi::sh {

struct LogVisInput {
  std::vector<double> f;  // n*n log-visibility coefficients
  int caps = 1;           // number of caps summed
  double max_theta = 0;   // largest cap half-angle (radians)
  double norm = 0;        // ||f^|| (DC excluded)
};

// One cap of half-angle theta about `dir`: the tabulated log ZH (eqs. 30-32) turned by eq. 34.
std::vector<double> cap_log_vector(int order, double theta, const Vec3<double>& dir, double log_threshold = 0.02);

// Single caps of 1..89 degrees (step `step_deg`), each about a pseudo-random direction.
std::vector<LogVisInput> single_cap_sweep(int order, double step_deg = 1.0, std::uint32_t seed = 1);

// Sums of m caps, m in `counts`, half-angles uniform in [min_deg, max_deg], directions uniform in the
// upper hemisphere (blockers above a receiver's tangent plane), `repeats` inputs per m.
std::vector<LogVisInput> cap_sum_sweep(int order, const std::vector<int>& counts, double min_deg, double max_deg,
                                       int repeats, std::uint32_t seed = 2);

// Max over a fixed dense set of directions of |a~(s) - b~(s)|: the reconstruction error the
// accuracy targets of docs/sh.md are stated in.
double reconstruction_error(int order, const double* a, const double* b);
// Mean value of the reconstructed function: DC / sqrt(4 pi).
inline double mean_value(const double* g) { return g[0] / kSqrt4Pi; }

}  // namespace softgi::sh
