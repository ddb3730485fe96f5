// A machine limit the benchmarks take shares of (FMA peak, memory bandwidth), measured once per
// process: the best of five runs when first asked for, unless a benchmark of the limit itself has
// already raised it with a better figure.
#pragma once

#include <algorithm>

namespace softgi::bench {

class MeasuredLimit {
 public:
  template <class Measure>
  double get(Measure&& measure) {
    if (value_ <= 0.0)
      for (int i = 0; i < 5; ++i) value_ = std::max(value_, measure());
    return value_;
  }
  void raise(double v) { value_ = std::max(value_, v); }

 private:
  double value_ = 0.0;
};

}  // namespace softgi::bench
