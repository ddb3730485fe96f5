// Reference renders through the disk cache (softgi/io/reference_cache.hpp), for compare and
// experiment: the same scene, frame and options are rendered once.
#pragma once

#include <functional>
#include <string>

#include "softgi/reference/converge.hpp"
#include "softgi/reference/reference.hpp"

namespace softgi::app {

// Bumped whenever render_reference's images change for the same inputs, so that entries written by
// an older renderer are not served.
inline constexpr int kReferenceRendererVersion = 1;

// render_reference, or the cached images of an earlier identical render (`cached` says which; the
// result's seconds are then the original render's). A cache entry that cannot be read is rendered
// again, with a line on stderr saying why.
reference::ReferenceResult cached_reference(const scene::Scene& scene, const reference::ReferenceOptions& opt,
                                            const std::function<void(double)>& progress, bool& cached);

// render_converged_reference through the same cache: its two halves are entries of their own, keyed by
// the options and the convergence settings (target, first round, cap, epsilon, and the mask's size and
// content when there is one). A hit returns the halves, their mean and the noise recomputed from them
// over the same pixels (rounds empty; result.seconds is the original render's, all rounds).
reference::ConvergedReference cached_converged_reference(
    const scene::Scene& scene, const reference::ReferenceOptions& opt, const reference::ConvergeOptions& converge,
    const std::function<void(int round, int spp, double fraction)>& progress, bool& cached);

}  // namespace softgi::app
