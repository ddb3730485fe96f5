// The last step of the eq. 11 weights (upsample.cpp, paper 000 section 4.2): each display pixel
// keeps the taps of its 2x2 block whose weight is positive, packed to the front of its four slots
// in tap order, and -1 (index) and 0 (weight) in the slots left over. Not installed.
#pragma once

#include <array>
#include <cstdint>

namespace softgi::techniques::common::detail {

// Pixels t = 0 .. n-1 with tap k's coarse index at tap[k * stride + t], its normalised weight at
// weight[k * stride + t] and its unnormalised eq. 11 weight at live[k * stride + t]: tap k is kept
// where live[k * stride + t] > 0 (NaN drops it). Writes out_index[t] and out_weight[t] for every t.
// In AVX-512 vectors where the processor has them (compress and expand of each pixel's lanes),
// else pack_taps_portable.
void pack_taps(const std::int32_t* tap, const float* weight, const float* live, int stride, int n,
               std::array<std::int32_t, 4>* out_index, std::array<float, 4>* out_weight);
// The same, one pixel at a time, on every processor: the definition the vector path is tested against.
void pack_taps_portable(const std::int32_t* tap, const float* weight, const float* live, int stride, int n,
                        std::array<std::int32_t, 4>* out_index, std::array<float, 4>* out_weight);
// Whether pack_taps takes the AVX-512 path on this processor.
bool pack_taps_vectorised();

}  // namespace softgi::techniques::common::detail
