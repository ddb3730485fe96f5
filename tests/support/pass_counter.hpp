// A counter of a frame's pass record by pass and counter name, or -1 where the frame ran no such
// pass (a test then fails on the value, naming what it expected).
#pragma once

#include <string>

#include "softgi/render/frame.hpp"

namespace softgi::test {

inline double pass_counter(const render::FrameResult& r, const std::string& pass, const std::string& counter) {
  for (const auto& pr : r.passes)
    if (pr.name == pass) return pr.counters.at(counter);
  return -1.0;
}

}  // namespace softgi::test
