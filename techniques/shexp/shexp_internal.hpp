// SHEXP internals (paper 004, Ren et al. 2006): the pieces of the technique's passes that are
// SHEXP's own (hierarchy cuts with ratio vectors, the product-space
// baseline and the projected reference), on top of the shared accumulation library
// (techniques/common/accumulation.hpp), exposed to tests/shexp and bench/bench_shexp.cpp. Not
// installed; include by path.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "../common/accumulation.hpp"
#include "../common/cuts.hpp"
#include "../common/receivers.hpp"
#include "softgi/proxies/hierarchy.hpp"
#include "softgi/scene/scene.hpp"
#include "softgi/sh/exp_log.hpp"
#include "softgi/sh/sh.hpp"
#include "softgi/sh/tables.hpp"

namespace softgi::techniques::shexp {

// SHEXP's code, tests and benchmarks name the shared library's types unqualified.
using namespace ::softgi::techniques::common;

// ---------------------------------------------------------------------------------------------
// Product-space accumulation (Zhou et al. 2005, paper 004 eq. 6), the baseline: per receiver,
// g = ((1 * g[1]) * g[2]) * ... * g[m], products left to right in blocker-list order, each g[i] the
// cap visibility ZH rotated by eq. 34 with the visibility table G instead of F. Band weights of the
// list are ignored (ratio vectors are defined for log vectors). Returns the number of SH products.
long long accumulate_product(const ZhTable& vis_table, ReplacementRule rule, const ReceiverSoA& rec,
                             std::size_t begin, std::size_t end, const BlockerList& blockers, float* out);
// The order-n projection of the exact binary visibility of the (rule-adjusted) spheres, by a product
// quadrature with `bands` bands (2 bands^2 directions): what no order-n accumulation can beat, for
// error analysis (docs/techniques/shexp.md, Figure 7).
void project_visibility(int order, int bands, ReplacementRule rule, const ReceiverSoA& rec, std::size_t begin,
                        std::size_t end, const BlockerList& blockers, float* out);


}  // namespace softgi::techniques::shexp
