// A reference rendered until its own noise is small enough to measure the errors it is meant for
// (docs/reference.md, "Rendering until converged").
#pragma once

#include <functional>
#include <vector>

#include "softgi/image.hpp"
#include "softgi/reference/reference.hpp"

namespace softgi::reference {

struct ConvergeOptions {
  // The relMSE that the reference's noise may add to an error measured against it: the `noise` term of
  // metrics::noise_corrected_relmse (docs/metrics.md, "Reference noise"). To resolve errors down to E
  // with the noise below 10 % of them, ask for 0.1 E.
  double target_noise = 1e-3;
  int min_spp = 16;      // samples per pixel of the first round, both halves together (even, >= 2)
  int max_spp = 4096;    // cap on the samples per pixel of a round, both halves together (even)
  double relmse_epsilon = 1e-2;  // the relMSE epsilon the errors will be measured with
  // Pixels the noise is averaged over. Empty: those that received light in either half (an empty
  // background and unlit pixels carry no noise and would only dilute the mean).
  Mask mask;
};

struct ConvergeRound {
  int spp = 0;          // both halves together
  double noise = 0.0;   // the noise term at this round
  double seconds = 0.0; // both halves' wall time
};

struct ConvergedReference {
  // The mean of the halves (direct, indirect, final); spp = both halves' samples, seconds = all rounds.
  ReferenceResult result;
  ReferenceResult half_a, half_b;  // seeds: ReferenceOptions::seed and half_b_seed(seed)
  double noise = 0.0;              // of the last round
  bool converged = false;          // noise <= target_noise (false: max_spp was reached first)
  long long pixels = 0;            // pixels the noise was averaged over
  std::vector<ConvergeRound> rounds;
};

// The pixels that received light in either half: what the noise is averaged over when
// ConvergeOptions::mask is empty.
Mask lit_pixels(const Image& half_a, const Image& half_b);

// The second half's seed: far from the first's, so that references with seeds 1, 2, 3, ... do not share
// halves.
unsigned half_b_seed(unsigned seed);

// Renders two independent halves at min_spp / 2 samples each, estimates the noise of their mean and,
// while it exceeds the target, renders again at the sample count that the 1 / spp law predicts for the
// target (20 % margin, at least twice the last, at most max_spp). Each round renders from scratch (sample
// k of a pixel depends only on (seed, pixel, k), so a round at n samples repeats the previous round's
// first samples exactly); with at least a doubling per round the total is under twice the last round.
// opt.spp is ignored. progress(round, spp, fraction) is called from the calling thread.
// Throws std::invalid_argument naming a bad option (target not finite and > 0, min_spp odd or < 2,
// max_spp odd or below min_spp, bad epsilon, a mask of another size or selecting nothing), besides
// render_reference's errors.
ConvergedReference render_converged_reference(const scene::Scene& scene, const ReferenceOptions& opt,
                                              const ConvergeOptions& converge,
                                              const std::function<void(int round, int spp, double fraction)>& progress = {});

}  // namespace softgi::reference
